"""The only files the studio reads: those under one folder, named relative to it.

A path typed into the page is data from the network: an absolute path, a ``..`` step or a
symlink that leads out of the folder is refused with a message naming the path and the
folder, before anything is opened.
"""

from __future__ import annotations

from pathlib import Path, PurePosixPath

from rigmap.errors import RigmapError


class StudioFileError(RigmapError, ValueError):
    """A requested path the studio will not open (outside its folder, or missing)."""


class ServedFolder:
    """Resolve names relative to ``root``; nothing outside it is ever returned."""

    def __init__(self, root):
        root = Path(root).expanduser()
        if not root.is_dir():
            raise StudioFileError(f"--folder {root}: not a folder")
        self.root = root.resolve()

    def resolve(self, requested: str, *, kind: str = "path") -> Path:
        """``requested`` (relative, ``/``-separated) as a path under the folder.

        ``kind`` ("file", "folder" or "path") says what must exist there."""
        text = str(requested).strip()
        if not text:
            raise StudioFileError("no path given")
        if "\x00" in text:
            raise StudioFileError(f"{text!r}: not a path")
        posix = PurePosixPath(text.replace("\\", "/"))
        if posix.is_absolute() or Path(text).is_absolute() or Path(text).drive:
            raise StudioFileError(
                f"{text!r}: absolute paths are refused; name a path inside {self.root}"
            )
        if ".." in posix.parts:
            raise StudioFileError(f"{text!r}: '..' is refused; name a path inside {self.root}")
        path = (self.root / Path(*posix.parts)).resolve()
        if not path.is_relative_to(self.root):
            raise StudioFileError(f"{text!r}: leads outside {self.root} (a symlink out)")
        if not path.exists():
            raise StudioFileError(f"{text!r}: no such {kind} in {self.root}")
        if kind == "file" and not path.is_file():
            raise StudioFileError(f"{text!r}: not a file")
        if kind == "folder" and not path.is_dir():
            raise StudioFileError(f"{text!r}: not a folder")
        return path

    def relative(self, path: Path) -> str:
        return Path(path).resolve().relative_to(self.root).as_posix()

    def folders_with(self, filename: str, *, limit: int = 200) -> list[str]:
        """Folders under the root holding ``filename`` (e.g. every ``rigmap map`` output:
        ``summary.json``), relative, sorted; symlinked folders leading out are skipped."""
        found = []
        for hit in sorted(self.root.rglob(filename)):
            folder = hit.parent.resolve()
            if folder.is_relative_to(self.root) and ".dvc" not in hit.parts:
                found.append(self.relative(folder))
            if len(found) >= limit:
                break
        return found
