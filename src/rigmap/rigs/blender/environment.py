"""Where Blender is: the worker environment `make blender` creates, or a Blender executable.

bpy 5.0.1 pins numpy<2, so Blender never runs in rigmap's own environment; it
runs in worker processes started from one of
- ``RIGMAP_BLENDER`` (or a rig's ``blender`` option): a Python that has bpy, or a
  Blender executable (a file named ``blender*``, run as ``blender -b --python``);
- ``.venv-blender/bin/python`` in the project checkout (what `make blender` makes),
  or in the current directory.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from rigmap.errors import RigmapError
from rigmap.store.layout import source_checkout

ENV_VAR = "RIGMAP_BLENDER"
ENV_DIR_NAME = ".venv-blender"
WORKER_SCRIPT = Path(__file__).resolve().parent / "in_blender" / "worker.py"
INSTALL_HINT = (
    "create the Blender worker environment with `make blender` "
    "(runs scripts/setup_blender_env.sh: a Python 3.11 venv with bpy==5.0.1), "
    f"or set {ENV_VAR} to a Python that has bpy or to a Blender executable"
)


class BlenderNotFoundError(RigmapError, RuntimeError):
    """No Blender to start workers with."""


@dataclass(frozen=True)
class BlenderCommand:
    """How to start a worker: a Python with bpy, or a Blender executable."""

    executable: Path
    kind: str  # "python" or "blender"

    def argv(self, *worker_args: str) -> list[str]:
        if self.kind == "python":
            return [str(self.executable), str(WORKER_SCRIPT), *worker_args]
        return [
            str(self.executable),
            "-b",
            "--factory-startup",
            "-noaudio",
            "--python",
            str(WORKER_SCRIPT),
            "--",
            *worker_args,
        ]

    @property
    def cache_tag(self) -> str:
        """Short stable id of this Blender, so caches from different Blenders never mix."""
        return hashlib.sha256(str(self.executable).encode()).hexdigest()[:10]


def default_candidates() -> list[Path]:
    """``.venv-blender/bin/python`` in the checkout an editable install runs from, then in
    the working directory (once, when they are the same folder)."""
    names = [Path(ENV_DIR_NAME) / "bin" / "python"]
    roots = dict.fromkeys([*filter(None, [source_checkout()]), Path.cwd().resolve()])
    return [root / name for root in roots for name in names]


def find_blender(blender: str | os.PathLike | None = None) -> BlenderCommand:
    """The Blender to use, or :class:`BlenderNotFoundError` saying how to install one."""
    if blender is None:
        blender = os.environ.get(ENV_VAR) or None
    if blender is not None:
        path = Path(blender).expanduser()
        if not path.is_file() or not os.access(path, os.X_OK):
            raise BlenderNotFoundError(
                f"Blender given as {str(blender)!r} (option or {ENV_VAR}) is not an executable "
                f"file; {INSTALL_HINT}"
            )
        return _command_for(path)
    for candidate in default_candidates():
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return _command_for(candidate)
    looked = ", ".join(str(c) for c in default_candidates())
    raise BlenderNotFoundError(
        f"no Blender worker environment found (looked at {looked}); {INSTALL_HINT}"
    )


def _command_for(path: Path) -> BlenderCommand:
    # Not resolved: a venv's python is a symlink to the base interpreter, without bpy.
    path = path.absolute()
    kind = "blender" if path.name.lower().startswith("blender") else "python"
    return BlenderCommand(path, kind)


def blender_available(blender: str | os.PathLike | None = None) -> bool:
    try:
        find_blender(blender)
    except BlenderNotFoundError:
        return False
    return True
