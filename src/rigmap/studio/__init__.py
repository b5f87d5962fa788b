"""``rigmap studio``: the three papers' interactive tools in the browser (issue #43).

One 3D scene served by viser (a maintained three.js client with transform gizmos and GUI
widgets, driven from Python: the rig math stays in this process) with views picked from a
menu: :mod:`.pose_view` (drag effectors, the partial-input mapping and refinement answer),
:mod:`.review_view` (a ``rigmap map`` output played back beside its source),
:mod:`.edit_view` (an edit authored, learned, propagated and fixed) and :mod:`.play_view`
(latent synthesis driven live, and by a game of noughts and crosses).

:class:`.app.Studio` binds 127.0.0.1 by default; files are read only through
:class:`.served_folder.ServedFolder` and written only under the output folder. The views
take plain objects; :mod:`rigmap.app.studio` builds them from config.
"""
