"""The partial-input mapping ``rigmap map`` uses: fitted once per rig and joint subset, then cached.

A mocap clip drives only the joints its retarget map names, so the map needs a
:class:`~rigmap.map.partial.SubsetMapping` on exactly those joints. It learns from the
rig's own training data (``data/<rig>/corpus/train.parquet`` and ``poses/train.parquet``,
the same rows as the ``fit`` stage's GPR) and is kept in ``models/<rig>/map-<subset>/``
with ``map_model.json``: the rig's fingerprint, the joint subset, the regressor settings
and a digest of the training files. The next map with the same four reuses it; anything
else refits it (the cache is replaced atomically). A folder named explicitly (``model=``)
is never refitted: one made for another rig, rig version or joint subset is refused.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigmap.config_objects import instantiate_as
from rigmap.errors import RigmapError
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.regression.base import Regressor
from rigmap.regression.fitting import TrainingData, load_training_data, training_files
from rigmap.store import Layout, json_ready, write_folder_atomic, write_json_atomic

RECORD_FILE = "map_model.json"
RECORD_FORMAT = "rigmap.map_model/1"
TRAIN_SAMPLER = "none"  # corpus frames only, as the paper's GPR (§6.1)


class SubsetModelError(RigmapError, ValueError):
    """A cached or named map model that does not belong to this rig, subset or data."""


@dataclass
class SubsetModel:
    """The fitted mapping and the training statistics :func:`rigmap.map.clip.map_clip` needs."""

    mapping: SubsetMapping
    control_std: np.ndarray  # per used control, over the train corpus frames
    hold_values: np.ndarray  # per used control, its corpus median (held controls keep it)
    folder: Path
    refitted: bool


def rig_fingerprint(rig) -> str:
    """A digest of what a mapping depends on in a rig: joints, hierarchy, controls, rest pose.

    Two rigs with the same fingerprint give the same joint positions for the same controls
    at rest, so a mapping fitted on one serves the other.
    """
    rest = rig.pose(rig.controls.defaults[None])
    facts = {
        "name": rig.name,
        "joints": list(rig.joint_names),
        "parents": None if rig.parents is None else [int(p) for p in rig.parents],
        "controls": list(rig.control_names),
        "used": list(rig.used_controls),
        "defaults": np.round(rig.controls.defaults, 6).tolist(),
        "rest": np.round(np.asarray(rest.positions, dtype=np.float64), 4).tolist(),
    }
    return _digest(json.dumps(facts, sort_keys=True).encode())


def training_digest(rig, data_dir: str | os.PathLike) -> str:
    """A digest of the training files' bytes (corpus and poses of the train split)."""
    files = training_files(data_dir, rig.name, TRAIN_SAMPLER)
    digest = hashlib.sha256()
    for role in ("corpus", "poses"):
        path = files[role]
        if not path.is_file():
            raise FileNotFoundError(
                f"{path}: the train {role} of rig {rig.name!r} does not exist; the map model "
                f"learns from it (run `python pipelines/animate.py rig={rig.name}` and "
                f"`python pipelines/pose.py rig={rig.name}`, or `dvc repro pose`)"
            )
        digest.update(path.read_bytes())
    return digest.hexdigest()


def model_folder(layout: Layout, rig_name: str, subset: JointSubset) -> Path:
    """``models/<rig>/map-<subset name>/``: where the map keeps a subset's mapping."""
    return layout.map_model(rig_name, subset.name)


def obtain_subset_model(
    rig,
    subset: JointSubset,
    layout: Layout,
    regressor_config: Mapping[str, Any],
    *,
    folder: str | os.PathLike | None = None,
    cache: str | os.PathLike | None = None,
    log: Callable[[str], None] = print,
) -> SubsetModel:
    """The mapping for ``subset`` on ``rig``: ``folder`` as it is (checked), else the cache
    (``cache``, default ``models/<rig>/map-<subset>/``), refitted when missing or stale."""
    expected = _record(rig, subset, layout, regressor_config)
    data = load_training_data(rig, layout.data, TRAIN_SAMPLER)
    std, median = _statistics(data)
    if folder is not None:
        folder = Path(folder)
        mapping = _load_checked(folder, rig, expected, explicit=True)
        return SubsetModel(mapping, std, median, folder, refitted=False)
    cache = Path(cache) if cache is not None else model_folder(layout, rig.name, subset)
    stale = _stale_reason(cache, expected)
    if stale is None:
        return SubsetModel(
            _load_checked(cache, rig, expected, explicit=False), std, median, cache, refitted=False
        )
    log(f"map model {cache}: {stale}; fitting on {data.corpus_rows} corpus frames")
    mapping = _fit(rig, subset, data, regressor_config)

    def fill(staging: Path) -> None:
        mapping.save(staging)
        write_json_atomic(staging / RECORD_FILE, expected)

    write_folder_atomic(cache, fill)
    return SubsetModel(mapping, std, median, cache, refitted=True)


def _fit(rig, subset: JointSubset, data: TrainingData, regressor_config) -> SubsetMapping:
    regressor = instantiate_as(regressor_config, Regressor, "map.regressor", SubsetModelError)
    options = {
        "rig_name": rig.name,
        "control_names": list(rig.used_controls),
        **regressor.fit_options(rest_index=data.rest_index),
    }
    return SubsetMapping.fit(rig, subset, data.features, data.controls, regressor, **options)


def _statistics(data: TrainingData) -> tuple[np.ndarray, np.ndarray]:
    corpus = data.controls[: data.corpus_rows]
    return corpus.std(axis=0), np.median(corpus, axis=0)


def _record(rig, subset, layout, regressor_config) -> dict:
    return json_ready(
        {
            "format": RECORD_FORMAT,
            "rig": rig.name,
            "rig_fingerprint": rig_fingerprint(rig),
            "subset": subset.to_dict(),
            "regressor": dict(regressor_config),
            "training_digest": training_digest(rig, layout.data),
        }
    )


def _read_record(folder: Path) -> dict | None:
    path = folder / RECORD_FILE
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise SubsetModelError(f"{path}: not valid JSON ({error})") from None
    return record if isinstance(record, dict) else None


def _stale_reason(folder: Path, expected: dict) -> str | None:
    """Why the cache must be refitted, or ``None`` when it matches."""
    if not folder.is_dir():
        return "not fitted yet"
    record = _read_record(folder)
    if record is None:
        return f"no {RECORD_FILE}"
    found = _mismatch(record, expected)
    return None if found is None else found[1]


def _mismatch(record: dict, expected: dict) -> tuple[bool, str] | None:
    """``(belongs elsewhere, why)`` for the first difference: another format, rig, rig
    version or joint subset belongs elsewhere; other settings or data only differ."""
    subset, theirs = expected["subset"], record.get("subset") or {}
    checks = [
        ("format", True, f"format {record.get('format')!r}, expected {RECORD_FORMAT!r}"),
        ("rig", True, f"fitted for rig {record.get('rig')!r}, not {expected['rig']!r}"),
        (
            "rig_fingerprint",
            True,
            f"fitted on another version of rig {expected['rig']!r} (its fingerprint differs)",
        ),
        (
            "subset",
            True,
            f"fitted on joint subset {theirs.get('name')!r} ({theirs.get('joints')}),"
            f" not {subset['name']!r} ({subset['joints']})",
        ),
        ("regressor", False, "fitted with other regressor settings"),
        (
            "training_digest",
            False,
            "fitted on other training data (the train corpus or poses changed)",
        ),
    ]
    for key, elsewhere, reason in checks:
        if record.get(key) != expected[key]:
            return elsewhere, reason
    return None


def _load_checked(folder: Path, rig, expected: dict, *, explicit: bool) -> SubsetMapping:
    """Load ``folder``; a named folder must match rig, fingerprint and joint subset (it may
    have been fitted with other settings or data)."""
    if not folder.is_dir():
        raise FileNotFoundError(f"map model folder {folder} does not exist")
    record = _read_record(folder)
    if record is None:
        raise SubsetModelError(
            f"{folder}: no {RECORD_FILE}; not a map model folder "
            "(rigmap map writes one in models/<rig>/map-<subset>/)"
        )
    found = _mismatch(record, expected)
    if explicit and found is not None and found[0]:
        raise SubsetModelError(f"map model {folder} cannot be used here: {found[1]}")
    return SubsetMapping.load(folder, rig)


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
