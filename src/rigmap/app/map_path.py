"""The ``map_path`` stage (paper Fig. 7): a walk looped, bent along a path over terrain, mapped.

Runs ``rigmap map`` (:func:`rigmap.app.map_job.map_from_config`) with the stage file's
``map`` options (``conf/map_path/stage.yaml``: the corpus clip, the path, the terrain, the
loop) into ``data/<rig>/map_path/<clip>/`` (its map model in ``data/<rig>/map_path/model/``),
then writes through :class:`rigmap.store.Layout`: ``metrics/<rig>/map_path/<name>.json``
(joint error of the rig against the edited joints; foot skate and penetration of the edit
and of the rig), ``<name>.csv`` (per-frame joint error) and
``reports/figures/map_path_<rig>.png``.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rigmap.app.map_job import Log, map_from_config
from rigmap.errors import RigmapError
from rigmap.store import Layout, atomic_file, json_ready, write_json_atomic
from rigmap.store.layout import MAP_STAGE_MODEL

MAP_PATH = "map_path"  # the stage's folder under data/<rig> and metrics/<rig>
STAGE_FILE = "stage.yaml"  # conf/map_path/stage.yaml


class MapPathStageError(RigmapError, ValueError):
    """A map_path stage file that names no clip edit."""


def stage_options(config_dir: str | os.PathLike) -> dict:
    """``conf/map_path/stage.yaml`` as a plain mapping, checked."""
    from omegaconf import OmegaConf

    path = Path(config_dir) / MAP_PATH / STAGE_FILE
    options = OmegaConf.to_container(OmegaConf.load(path), resolve=True)
    if not isinstance(options, dict) or not options.get("name") or not options.get("map"):
        raise MapPathStageError(f"{path}: expected name: <stem> and map: {{path: ..., ...}}")
    if not (options["map"] or {}).get("path"):
        raise MapPathStageError(f"{path}: map.path is missing (the stage bends along a path)")
    return options


def map_path(
    config: Mapping[str, Any], *, config_dir: str | os.PathLike, log: Log = print
) -> list[Path]:
    """The stage: see the module docstring. Returns the files written."""
    options = stage_options(config_dir)
    layout = Layout.from_paths(config.get("paths"))
    rig_name = config["rig"]["name"]
    data = layout.app_data(rig_name, MAP_PATH)
    clip_config = {
        **config,
        "map": {**config["map"], **options["map"]},
        "out": str(data),
        "model_cache": str(data / MAP_STAGE_MODEL),
    }
    (mapped,) = map_from_config(clip_config, config_dir=config_dir, log=log)
    record = json_ready(
        {**_read_json(mapped.folder / "path_edit.json"), "outputs": str(mapped.folder)}
    )
    folder = layout.app_metrics(rig_name, MAP_PATH)
    figure = layout.figures() / f"{MAP_PATH}_{rig_name}.png"
    figure.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(figure, suffix=".png") as temporary:
        shutil.copyfile(mapped.folder / "path_edit.png", temporary)
    csv = folder / f"{options['name']}.csv"
    csv.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(csv, suffix=".csv") as temporary:
        shutil.copyfile(mapped.folder / "path_frames.csv", temporary)
    return [write_json_atomic(folder / f"{options['name']}.json", record), csv, figure]


def _read_json(path: Path) -> dict:
    import json

    return json.loads(path.read_text())
