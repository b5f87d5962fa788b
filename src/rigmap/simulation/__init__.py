"""Fig. 9 of the paper with a real simulator: a mesh rig's rest mesh simulated as a soft body
in Blender (:mod:`.soft_body`), written as per-frame vertices (:mod:`.sim_file`), mapped back
onto the rig (:mod:`.vertex_mapping`), scored (:mod:`.metrics`, :mod:`.interpenetration`) and
drawn (:mod:`.figure`). Its job is :mod:`rigmap.app.simulate` (``rigmap simulate``, the
``simulate`` stage); docs/simulation.md."""
