"""Map motion from another source onto a rig (paper §6.3): mocap, joint tracks, effectors.

- :mod:`rigmap.map.tracks`: named joint positions over time (:class:`JointTracks`), read
  from BVH, parquet, npz or CSV, checked for gaps and bad values;
- :mod:`rigmap.map.joint_map`: skeleton correspondence as data (:class:`JointMap`, read from
  the retarget maps ``conf/retarget/*.yaml``):
  source joint names to rig joints, axes and handedness, scale from bone lengths, and the
  rebuild of the rig's mapped joints along the source's bone directions;
- :mod:`rigmap.map.skeleton_match`: a BVH skeleton's joints matched to the roles a rig's
  retarget map needs (hierarchy, rest pose, naming conventions), written as a retarget map;
  its T-pose and glitch frames found.

The jobs that read config (``rigmap map``/``pose``, the map stages) are in :mod:`rigmap.app`;
serving a map model over MLflow is :mod:`rigmap.tracking.map_model`.
"""

from rigmap.map.joint_map import JointMap, JointMapError, MappedTargets
from rigmap.map.tracks import JointTracks, TracksError, read_tracks, tracks_from_bvh

__all__ = [
    "JointMap",
    "JointMapError",
    "JointTracks",
    "MappedTargets",
    "TracksError",
    "read_tracks",
    "tracks_from_bvh",
]
