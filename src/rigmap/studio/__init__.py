"""``rigmap studio``: the three papers' interactive tools in the browser (issue #43).

Review (:mod:`.review_view`: a ``rigmap map`` output played back beside its source) and
Edit (:mod:`.edit_view`: an edit authored, learned, propagated and fixed) are views of one
3D scene served by viser (a maintained three.js client with transform gizmos and GUI
widgets, driven from Python: the rig math stays in this process), picked from a menu. Pose
(drag effectors, the partial-input mapping and refinement answer: :mod:`.pose_driver`) and
Play (latent synthesis driven live, and by a game of noughts and crosses:
:mod:`.play_session`) have small WebGL pages of their own (:mod:`.page_server`), because
their drags and frames must reach the screen within 50 ms and on a 1/24 s schedule.

:class:`.app.Studio` binds 127.0.0.1 by default; files are read only through
:class:`.served_folder.ServedFolder` and written only under the output folder. The views
take plain objects; :mod:`rigmap.app.studio` builds them from config.
"""
