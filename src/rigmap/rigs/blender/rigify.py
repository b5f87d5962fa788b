"""The built-in Blender rigs: Rigify's human and wolf, and any user .blend with an armature.

``rigify_human`` and ``rigify_wolf`` are generated from the metarigs that ship
with Blender's Rigify the first time they are asked for, then cached as .blend
files (see :mod:`.cache`). Their presets, in ``rigify_presets.yaml`` beside this
module, say which controls animators key (§6.1) and which deform bones count as
joints (the face is left out); the Hydra files ``conf/rig/rigify_*.yaml`` spell out
the same options.
"""

from __future__ import annotations

import copy
import time
from importlib import resources
from pathlib import Path

import yaml

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

#: the presets' file, beside this module: every value in it is a name, a glob or a range
PRESETS_FILE = "rigify_presets.yaml"


def _read_presets() -> dict[str, dict]:
    """The presets of ``PRESETS_FILE`` by rig name (data, so kept out of the code)."""
    text = resources.files("rigmap.rigs.blender").joinpath(PRESETS_FILE).read_text("utf-8")
    presets = yaml.safe_load(text) or {}
    if sorted(presets) != ["rigify_human", "rigify_wolf"]:
        raise ValueError(f"{PRESETS_FILE}: expected presets rigify_human and rigify_wolf")
    return presets


_PRESETS = _read_presets()
RIGIFY_HUMAN: dict = _PRESETS["rigify_human"]
RIGIFY_WOLF: dict = _PRESETS["rigify_wolf"]

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
