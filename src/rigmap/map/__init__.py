"""Map motion from another source onto a rig (paper §6.3): mocap, joint tracks, effectors.

- :mod:`rigmap.map.tracks`: named joint positions over time (:class:`JointTracks`), read
  from BVH, parquet, npz or CSV, checked for gaps and bad values;
- :mod:`rigmap.map.joint_map`: skeleton correspondence as data (``conf/retarget/*.yaml``):
  source joint names to rig joints, axes and handedness, scale from bone lengths, and the
  rebuild of the rig's mapped joints along the source's bone directions;
- :mod:`rigmap.map.skeleton_match`: a BVH skeleton's joints matched to the roles a rig's
  retarget map needs (hierarchy, rest pose, naming conventions), written as a retarget map;
  its T-pose and glitch frames found.
"""

from rigmap.map.joint_map import MappedTargets, RetargetMap, RetargetMapError
from rigmap.map.tracks import JointTracks, TracksError, read_tracks, tracks_from_bvh

__all__ = [
    "JointTracks",
    "MappedTargets",
    "RetargetMap",
    "RetargetMapError",
    "TracksError",
    "read_tracks",
    "tracks_from_bvh",
]
