"""The built-in Blender rigs: Rigify's human and wolf, and any user .blend with an armature.

``rigify_human`` and ``rigify_wolf`` are generated from the metarigs that ship
with Blender's Rigify the first time they are asked for, then cached as .blend
files (see :mod:`.cache`). Their presets below say which controls animators
key (§6.1) and which deform bones count as joints (the face is left out); the
Hydra files ``conf/rig/rigify_*.yaml`` spell out the same options.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

from rigmap.rigs.blender.cache import (
    cache_dir,
    cached_file_ok,
    discard_cached,
    file_lock,
    file_sha256,
    read_json,
    write_json_atomic,
)
from rigmap.rigs.blender.environment import find_blender
from rigmap.rigs.blender.rig import RIGIFY_HELPER_BONES, BlenderRig

# Bumped when generation changes (e.g. a different Euler conversion), to regenerate caches.
GENERATION_VERSION = 1
GENERATION_TIMEOUT_S = 600.0

# The face is left out of the joints (its ~300 bones would cost more than the body), except
# three points that ride on the head so head rotations stay observable: the jaw's base and
# the base of each ear.
_FACE_DEFORM = [
    "DEF-forehead*",
    "DEF-temple*",
    "DEF-brow*",
    "DEF-lid*",
    "DEF-ear.?.*",
    "DEF-tongue*",
    "DEF-chin*",
    "DEF-jaw.*",
    "DEF-cheek*",
    "DEF-nose*",
    "DEF-lip*",
    "DEF-teeth*",
    "DEF-eye*",
]

#: the used controls of the torso every Rigify meta-rig (human and wolf) has: the root
#: places the body on the ground (Blender's X and Y, rigmap X and -Z, and the heading about
#: Blender's Z); lifting and tilting are the torso's, then hips, chest, neck and head
_RIGIFY_TORSO_USED = [
    "root.t[xy]",
    "root.rz",
    "torso.[tr][xyz]",
    "hips.[tr][xyz]",
    "chest.[tr][xyz]",
    "neck.r[xyz]",
    "head.r[xyz]",
]

RIGIFY_HUMAN: dict = {
    "armature": "rig",
    "cog_bone": "torso",
    # the corpus walks the root across the room, crouches the torso and reaches with the IK
    # hands (the biped's motions: rigmap.animation.library.rigify_human)
    "soft_ranges": {
        "root.t[xy]": [-400.0, 400.0],
        "torso.t[xyz]": [-80.0, 80.0],
        "hand_ik.[LR].t[xyz]": [-60.0, 60.0],
        "foot_ik.[LR].t[xyz]": [-45.0, 45.0],
    },
    "joints": {"include": ["DEF-*"], "exclude": _FACE_DEFORM},
    "used": {
        "include": [
            *_RIGIFY_TORSO_USED,
            "spine_fk*.r[xyz]",
            "shoulder.[LR].r[xyz]",
            "hand_ik.[LR].[tr][xyz]",
            "upper_arm_ik.[LR].ry",
            "foot_ik.[LR].[tr][xyz]",
            "foot_heel_ik.[LR].r[xyz]",
            "foot_spin_ik.[LR].r[xyz]",
            "thigh_ik.[LR].ry",
            "upper_arm_fk.[LR].r[xyz]",
            "forearm_fk.[LR].r[xyz]",
            "hand_fk.[LR].r[xyz]",
            "thigh_fk.[LR].r[xyz]",
            "shin_fk.[LR].r[xyz]",
            "foot_fk.[LR].r[xyz]",
            "*.01_master.[LR].r[xyz]",
            "*.01_master.[LR].sy",
            "f_*.0[12].[LR].rx",
            "thumb.0[12].[LR].rx",
            "*_parent.[LR].IK_FK",
            "*_parent.[LR].IK_Stretch",
            "torso.neck_follow",
            "torso.head_follow",
        ],
        "exclude": [],
    },
    "retarget": [
        {"bone": "torso", "type": "COPY_TRANSFORMS", "target": "cog"},
        {"bone": "spine_fk.002", "type": "DAMPED_TRACK", "target": "DEF-spine.003"},
        {"bone": "spine_fk.003", "type": "DAMPED_TRACK", "target": "DEF-spine.004"},
        {"bone": "neck", "type": "DAMPED_TRACK", "target": "DEF-spine.006"},
        {"bone": "hand_ik.L", "type": "COPY_LOCATION", "target": "DEF-hand.L"},
        {"bone": "hand_ik.R", "type": "COPY_LOCATION", "target": "DEF-hand.R"},
        {"bone": "foot_ik.L", "type": "COPY_LOCATION", "target": "DEF-foot.L"},
        {"bone": "foot_ik.R", "type": "COPY_LOCATION", "target": "DEF-foot.R"},
    ],
}

RIGIFY_WOLF: dict = {
    "armature": "rig",
    "cog_bone": "torso",
    # the corpus walks the root across the room and sits the torso down (the dog's motions,
    # 1.3 times larger: rigmap.animation.library.wolf); the default ±30 cm fit a paw
    "soft_ranges": {
        "root.t[xy]": [-400.0, 400.0],
        "torso.t[xyz]": [-80.0, 80.0],
        "*foot_ik.[LR].t[xyz]": [-45.0, 45.0],
    },
    # Paw digits are left out like the face: they would double the bones evaluated per pose.
    "joints": {
        "include": ["DEF-*"],
        "exclude": [*_FACE_DEFORM, "DEF-*_index*", "DEF-*_middle*", "DEF-*_ring*", "DEF-*_pinky*"],
    },
    "used": {
        "include": [
            *_RIGIFY_TORSO_USED,
            "spine_fk.00[45678].r[xyz]",
            "spine.r[xyz]",
            "spine.00[123].r[xyz]",
            "spine_master.003.r[xz]",
            "shoulder.[LR].r[xyz]",
            "front_foot_ik.[LR].[tr][xyz]",
            "front_foot_heel_ik.[LR].r[xyz]",
            "front_thigh_ik.[LR].ry",
            "foot_ik.[LR].[tr][xyz]",
            "foot_heel_ik.[LR].r[xyz]",
            "thigh_ik.[LR].ry",
            "toe.[LR].r[xyz]",
            "front_toe.[LR].r[xyz]",
            "thigh_fk.[LR].r[xyz]",
            "shin_fk.[LR].r[xyz]",
            "foot_fk.[LR].r[xyz]",
            "front_thigh_fk.[LR].r[xyz]",
            "front_shin_fk.[LR].r[xyz]",
            "front_foot_fk.[LR].r[xyz]",
            "*thigh_parent.[LR].IK_FK",
            "*thigh_parent.[LR].IK_Stretch",
            "torso.tail_follow",
            "torso.neck_follow",
            "torso.head_follow",
        ],
        "exclude": [],
    },
    "retarget": [
        {"bone": "torso", "type": "COPY_TRANSFORMS", "target": "cog"},
        {"bone": "spine_fk.006", "type": "DAMPED_TRACK", "target": "DEF-spine.007"},
        {"bone": "spine_fk.007", "type": "DAMPED_TRACK", "target": "DEF-spine.008"},
        {"bone": "neck", "type": "DAMPED_TRACK", "target": "DEF-spine.010"},
        {
            "bone": "front_foot_ik.L",
            "type": "COPY_LOCATION",
            "target": "DEF-front_toe.L",
            "offset": True,
        },
        {
            "bone": "front_foot_ik.R",
            "type": "COPY_LOCATION",
            "target": "DEF-front_toe.R",
            "offset": True,
        },
        {"bone": "foot_ik.L", "type": "COPY_LOCATION", "target": "DEF-toe.L", "offset": True},
        {"bone": "foot_ik.R", "type": "COPY_LOCATION", "target": "DEF-toe.R", "offset": True},
    ],
}

PRESETS = {"rigify_human": ("human", RIGIFY_HUMAN), "rigify_wolf": ("wolf", RIGIFY_WOLF)}


def rigify_blend(metarig: str, *, blender: str | None = None, euler_order: str = "XYZ") -> Path:
    """The cached .blend of Rigify's ``metarig`` rig, generating it the first time."""
    from rigmap.rigs.blender.pool import WorkerPool

    command = find_blender(blender)
    stem = f"rigify_{metarig}-{command.cache_tag}-g{GENERATION_VERSION}-{euler_order}"
    path = cache_dir() / f"{stem}.blend"
    if cached_file_ok(path):
        return path
    with file_lock(cache_dir() / f"{stem}.lock"):
        if cached_file_ok(path):  # another process made it while we waited
            return path
        discard_cached(path)  # truncated, bit-flipped or made before checksums: generate again
        start = time.perf_counter()
        with WorkerPool(
            lambda _slot: command.argv(), workers=1, log_dir=cache_dir() / "logs"
        ) as pool:
            info, _ = pool.call(
                "generate_rigify",
                {
                    "metarig": metarig,
                    "out_path": str(path),
                    "euler_order": euler_order,
                    "exclude_bones": RIGIFY_HELPER_BONES,
                },
                timeout=GENERATION_TIMEOUT_S,
            )
        info = {k: v for k, v in info.items() if k != "ok"}
        info["wall_seconds"] = time.perf_counter() - start
        info["sha256"] = file_sha256(path)
        write_json_atomic(path.with_suffix(".json"), info)
    return path


def generation_info(path: Path) -> dict | None:
    """What generating a cached rig reported (metarig, bones, seconds), if known."""
    return read_json(Path(path).with_suffix(".json"))


def _build_rigify(name: str, options: dict) -> BlenderRig:
    metarig, preset = PRESETS[name]
    merged = {**copy.deepcopy(preset), **options}
    merged.pop("name", None)
    path = merged.pop("path", None) or rigify_blend(
        metarig, blender=merged.get("blender"), euler_order=merged.get("euler_order", "XYZ")
    )
    merged.setdefault(
        "description", f"Blender Rigify {metarig} rig (generated from the {metarig} metarig)"
    )
    return BlenderRig(name, path, **merged)


def build_rigify_human(**options) -> BlenderRig:
    """Rigify's human: IK/FK limbs, B-bone spine, fingers and face; joints without the face."""
    return _build_rigify("rigify_human", options)


def build_rigify_wolf(**options) -> BlenderRig:
    """Rigify's wolf (the quadruped metarig of Rigify's animals): legs, tail, paws, face."""
    return _build_rigify("rigify_wolf", options)


def build_blend_file(**options) -> BlenderRig:
    """Any .blend with an armature: ``path`` required; ``armature``, ``joints``, ``used``…"""
    if not options.get("path"):
        raise ValueError(
            "rig 'blend_file' needs a 'path' option (the .blend file), e.g. "
            "rig=blend_file rig.path=/models/hero.blend rig.armature=rig"
        )
    path = Path(options.pop("path"))
    name = options.pop("name", None) or f"blend_file:{path.stem}"
    if options.get("actions") is not None:
        raise ValueError(
            "rig 'blend_file' with actions is built by rigmap.animation.blend_corpus."
            "build_blend_file (the rig's manifest factory), which imports them first"
        )
    options.pop("actions", None)
    unset = [k for k in ("armature", "cog_bone") if k in options and options[k] is None]
    for key in unset:  # null in a config: BlenderRig's default
        del options[key]
    return BlenderRig(name, path, **options)
