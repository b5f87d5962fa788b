"""Run a short bpy script in a Blender process of its own (the worker environment's Python).

Tests that read a .blend back independently of the worker protocol use it: the script
gets the arguments after its name and writes JSON to the last one.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from rigmap.rigs.blender.environment import WORKER_SCRIPT, find_blender


def run_bpy(script: str, *args: str, folder: Path, timeout: float = 300.0):
    """Run ``script`` with ``args`` and an output path; returns the JSON it wrote there."""
    path, out = folder / "bpy_script.py", folder / "bpy_script_out.json"
    path.write_text(script)
    blender = find_blender()
    argv = [str(blender.executable), str(path)]
    if blender.kind == "blender":
        argv = [str(blender.executable), "-b", "--factory-startup", "--python", str(path), "--"]
    subprocess.run([*argv, *map(str, args), str(out)], check=True, capture_output=True,
                   timeout=timeout, cwd=WORKER_SCRIPT.parent)  # fmt: skip
    data = json.loads(out.read_text())
    path.unlink()
    out.unlink()
    return data
