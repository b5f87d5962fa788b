"""Generate a Rigify rig from one of the metarigs that ship with Blender, and save it.

Runs inside Blender. Rigify is a core add-on in Blender 5.0 (``addons_core``);
it registers one "add metarig" operator per bundled metarig
(``object.armature_<name>_metarig_add``: human, wolf, horse, cat, ...).
"""

from __future__ import annotations

import time

import addon_utils
import bpy
from keyframes import save_blend
from rig_session import convert_to_euler, matches

RIGIFY_MODULES = ("rigify", "bl_ext.blender_org.rigify")


def enable_rigify() -> str:
    for module in RIGIFY_MODULES:
        try:
            if addon_utils.enable(module, default_set=True) is not None:
                return module
        except ModuleNotFoundError:
            continue
    raise RuntimeError(f"Rigify add-on not found in this Blender (tried {RIGIFY_MODULES})")


def available_metarigs() -> list[str]:
    ops = dir(bpy.ops.object)
    return sorted(
        o[len("armature_") : -len("_metarig_add")] for o in ops if o.endswith("_metarig_add")
    )


def generate(metarig: str, out_path: str, euler_order: str, exclude_bones: list[str]) -> dict:
    """Build ``metarig``'s rig, switch its control bones to Euler, save to ``out_path``."""
    start = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    module = enable_rigify()  # after the reset, which unloads add-ons
    operator = getattr(bpy.ops.object, f"armature_{metarig}_metarig_add", None)
    if operator is None or not operator.poll():
        raise ValueError(
            f"no Rigify metarig {metarig!r} in Blender {bpy.app.version_string}; "
            f"available: {available_metarigs()}"
        )
    operator()
    meta = bpy.context.active_object
    bpy.ops.pose.rigify_generate()
    rig = meta.data.rigify_target_rig
    if rig is None:
        raise RuntimeError(f"Rigify did not generate a rig from metarig {metarig!r}")
    controls = [b.name for b in rig.pose.bones if matches(b.name, ["*"], exclude_bones)]
    converted = convert_to_euler(rig, controls, euler_order)
    rig["rigmap_source"] = f"Rigify {metarig} metarig, Blender {bpy.app.version_string}"
    meta.hide_set(True)
    save_blend(out_path)
    return {
        "metarig": metarig,
        "armature": rig.name,
        "bones": len(rig.pose.bones),
        "metarig_bones": len(meta.data.bones),
        "euler_converted_bones": converted,
        "rigify_module": module,
        "blender_version": bpy.app.version_string,
        "seconds": time.perf_counter() - start,
    }
