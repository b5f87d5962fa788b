"""The default DVC remote checked before ``make push`` / ``make pull``, with a clear error.

DVC's own message for a remote that is not there is "failed to pull data from the cloud"
after listing every missing file; this says which remote, where, and what to do. A local
path remote (the default, ``../rigmap-dvc-remote`` beside the clone) must exist to pull
from and be creatable to push to; any other remote (s3://, ssh://…) is left to DVC.

    python -m rigmap.dvc_remote check pull     # exit 1 with the reason if unusable
"""

from __future__ import annotations

import configparser
import os
import sys
from pathlib import Path

from rigmap.errors import RigmapError


class RemoteUnavailableError(RigmapError, RuntimeError):
    """The default DVC remote is missing, unreadable or not configured."""


def default_remote(project: Path) -> tuple[str, str]:
    """``(name, url)`` of the default remote in ``.dvc/config`` (``.dvc/config.local`` wins)."""
    parser = configparser.ConfigParser()
    read = parser.read([project / ".dvc" / "config", project / ".dvc" / "config.local"])
    if not read:
        raise RemoteUnavailableError(f"{project} is not a DVC project: no .dvc/config")
    name = parser.get("core", "remote", fallback=None)
    # DVC writes the section as ['remote "name"'] (quotes included) or [remote "name"]
    wanted = f'remote "{name}"'
    section = next((s for s in parser.sections() if s.strip("'") == wanted), None)
    if name is None or section is None:
        raise RemoteUnavailableError(
            f"no default DVC remote in {project / '.dvc' / 'config'}: add one with "
            "`dvc remote add -d shared /path/to/folder`"
        )
    return name, parser.get(section, "url")


def check_remote(project: str | os.PathLike, action: str) -> Path | str:
    """The remote's folder (or URL), usable for ``action`` (``push`` or ``pull``)."""
    project = Path(project).resolve()
    name, url = default_remote(project)
    if "://" in url:
        return url  # a cloud or ssh remote: DVC reports its own connection errors
    folder = (project / ".dvc" / url).resolve()  # relative urls are relative to .dvc/
    if action == "pull" and not folder.is_dir():
        raise RemoteUnavailableError(
            f"DVC remote {name!r} ({url} -> {folder}) does not exist: nothing to pull. "
            "Push to it from a clone that has the outputs (make push), or point it at the "
            f"team's copy: dvc remote modify {name} url /path/to/remote"
        )
    if action == "push":
        existing = next(p for p in (folder, *folder.parents) if p.exists())
        if not os.access(existing, os.W_OK):
            raise RemoteUnavailableError(
                f"DVC remote {name!r} ({url} -> {folder}): {existing} is not writable"
            )
    elif not os.access(folder, os.R_OK | os.X_OK):
        raise RemoteUnavailableError(f"DVC remote {name!r} ({folder}) is not readable")
    return folder


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or args[0] != "check" or args[1] not in ("push", "pull"):
        print("usage: python -m rigmap.dvc_remote check push|pull", file=sys.stderr)
        return 2
    try:
        where = check_remote(Path.cwd(), args[1])
    except RemoteUnavailableError as error:
        print(f"rigmap: {error}", file=sys.stderr)
        return 1
    print(f"DVC remote: {where}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
