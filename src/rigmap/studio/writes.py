"""The only place the studio writes: files under its output folder, each written whole."""

from __future__ import annotations

from pathlib import Path, PurePosixPath

from rigmap.store import json_ready, write_json_atomic
from rigmap.studio.served_folder import StudioFileError


class OutputFolder:
    """``root`` (created when first written); names are relative and stay inside it."""

    def __init__(self, root):
        self.root = Path(root).expanduser().resolve()
        if self.root.exists() and not self.root.is_dir():
            raise StudioFileError(f"--out {self.root}: exists and is not a folder")

    def path(self, relative: str) -> Path:
        parts = PurePosixPath(relative).parts
        if PurePosixPath(relative).is_absolute() or ".." in parts or not parts:
            raise StudioFileError(f"{relative!r}: not a name inside {self.root}")
        path = self.root.joinpath(*parts)
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.parent.resolve().is_relative_to(self.root):
            raise StudioFileError(f"{relative!r}: leads outside {self.root}")
        return path

    def new_folder(self, prefix: str) -> Path:
        """A folder ``<prefix>_<n>`` that does not exist yet (n = 1, 2, …), created."""
        n = 1
        while self.path(f"{prefix}_{n}").exists():
            n += 1
        folder = self.path(f"{prefix}_{n}")
        folder.mkdir()
        return folder

    def write_json(self, relative: str, document) -> Path:
        return write_json_atomic(self.path(relative), json_ready(document))

    def relative(self, path: Path) -> str:
        return Path(path).resolve().relative_to(self.root).as_posix()
