"""Small JSON and YAML files a user writes by hand (targets, retarget maps): read with errors
that name the file, never executing anything (``yaml.safe_load``)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import yaml


def read_data_file(path: str | os.PathLike, what: str, error: type[Exception]) -> Any:
    """The parsed contents of a ``.json``, ``.yaml`` or ``.yml`` file (by its suffix).

    A missing file is ``FileNotFoundError`` naming ``what``; unparsable text is ``error``
    naming the file and the parser's complaint.
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{what} {path} is a folder, not a file")
    if not path.is_file():
        raise FileNotFoundError(f"{what} {path} does not exist")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as problem:
        raise error(
            f"{path}: not a text {what} (not UTF-8: {problem.reason} at byte {problem.start})"
        ) from None
    if path.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as problem:
            raise error(f"{path}: not valid JSON ({problem})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as problem:
        raise error(f"{path}: not valid YAML ({problem})") from None
