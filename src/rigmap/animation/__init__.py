"""Animation in rig space: keys, curves, clips, the animator corpus, and BVH motion capture.

The corpus the inverse mapping learns from is keyframed animation on a rig's controls
(§6.1); motion capture (BVH) is the kind of input the learned mapping then retargets.
"""

from rigmap.animation.bvh import BVHError, BVHMotion, parse_bvh, read_bvh
from rigmap.animation.clip import CLIP_FPS, Clip, check_known_controls
from rigmap.animation.corpus import (
    CORPUS_FORMAT,
    Corpus,
    CorpusError,
    SoftRangeWarning,
    corpus_table,
    read_corpus,
    validate_clips,
    write_corpus,
)
from rigmap.animation.keyframes import (
    INTERPOLATIONS,
    FCurve,
    Key,
    KeyframeError,
    auto_clamped_slopes,
)

__all__ = [
    "CLIP_FPS",
    "CORPUS_FORMAT",
    "INTERPOLATIONS",
    "BVHError",
    "BVHMotion",
    "Clip",
    "Corpus",
    "CorpusError",
    "FCurve",
    "Key",
    "KeyframeError",
    "SoftRangeWarning",
    "auto_clamped_slopes",
    "check_known_controls",
    "corpus_table",
    "parse_bvh",
    "read_bvh",
    "read_corpus",
    "validate_clips",
    "write_corpus",
]
