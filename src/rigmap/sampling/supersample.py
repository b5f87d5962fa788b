"""Drawing extra control vectors and posing them with the rig, resumably (§5.2).

The paper's Maya rig needed about an hour for 100 000 samples; a rig in a DCC
is slow here too, so the work is split into chunks and each finished chunk is
saved on its own. All ``n`` vectors are drawn up front from the seed, so a
run restarted after a kill draws exactly the same vectors, keeps the chunks
whose saved controls match, evaluates only the rest and writes the same file.

Output ``<dir>/<sampler>.npz`` (written atomically, byte-identical for the same
inputs; chunks live in ``<dir>/<sampler>.chunks/`` until the end):

- ``controls`` ``(n, C_used)``: used-control values after clamping (cm, rad, …)
- ``positions`` ``(n, J, 3)``: joint positions relative to the COG (rig units, cm)
- ``cog`` ``(n, 3)`` and ``cog_rotation`` ``(n, 3, 3)``: the COG's world placement
- ``control_names`` / ``joint_names``; ``lower`` / ``upper``: the limits clamped to
- ``n_clamped`` (values moved onto a limit), ``n_rows_clamped``,
  ``n_clamped_per_control``
- ``meta``: JSON text — rig, sampler and its hyper-parameters, seed, counts.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from rigmap.errors import RigmapError
from rigmap.memory import check_memory
from rigmap.sampling.base import Sampler, SamplerInputError, SamplerNotFittedError, check_count
from rigmap.sampling.clamping import clamp_to_limits
from rigmap.sampling.reproducible_npz import (
    NpzFileError,
    leftover_temporaries,
    read_npz,
    save_npz_atomically,
)
from rigmap.store import json_ready

DEFAULT_CHUNK_SIZE = 10_000
FILE_FORMAT_VERSION = 1


class SupersampleError(RigmapError, ValueError):
    """The runner was given something it cannot use, or the rig returned bad poses."""


@dataclass(frozen=True)
class SupersampleResult:
    """What a run did; the counts are also in the file's ``meta``."""

    path: Path
    n_samples: int
    n_clamped: int
    n_rows_clamped: int
    n_chunks: int
    chunks_evaluated: int
    """Chunks this run sent to the rig."""
    chunks_resumed: int
    """Chunks taken from an earlier, interrupted run."""


def supersample(
    rig,
    sampler: Sampler,
    n: int,
    path: str | os.PathLike,
    *,
    seed: int,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    lower=None,
    upper=None,
    progress: bool = True,
    option: str = "n",
) -> SupersampleResult:
    """Draw ``n`` vectors with a fitted ``sampler``, clamp, pose with ``rig``, save to ``path``.

    ``lower``/``upper`` (one value per used control) default to the rig's
    range for those controls (``rig.controls.lower/upper``) — the protocol has
    no separate hard limits. ``chunk_size`` only changes how work is split,
    never the file's content. ``option`` names ``n`` in errors (the stage's ``budget.samples``).
    """
    path = Path(path)
    if path.suffix != ".npz":
        raise SupersampleError(f"supersample output must be a .npz file, got {str(path)!r}")
    used = np.asarray(rig.controls.used_indices)
    _check_sampler(sampler, rig, used.size)
    n = check_count(n, "supersample")
    check_supersample_memory(rig, n, option)
    chunk_size = _check_positive_int(chunk_size, "chunk_size")
    seed = _check_seed(seed)
    limits_given = lower is not None or upper is not None
    lower = rig.controls.lower[used] if lower is None else lower
    upper = rig.controls.upper[used] if upper is None else upper

    drawn = sampler.sample(n, np.random.default_rng(seed))
    clamped = clamp_to_limits(drawn, lower, upper, copy=False)
    del drawn
    controls = clamped.values
    n_samples = len(controls)
    chunk_folder = path.parent / f"{path.stem}.chunks"
    posed, evaluated, resumed = _pose_in_chunks(
        rig, sampler, controls, chunk_folder, chunk_size, progress
    )
    meta = _samples_meta(rig, sampler, seed, n, n_samples, limits_given, clamped)
    for stale in leftover_temporaries(path):
        stale.unlink(missing_ok=True)
    save_npz_atomically(
        path,
        {
            "controls": controls,
            "positions": posed["positions"],
            "cog": posed["cog"],
            "cog_rotation": posed["cog_rotation"],
            "control_names": np.array([rig.controls.names[i] for i in used], dtype=str),
            "joint_names": np.array(list(rig.joint_names), dtype=str),
            "lower": np.asarray(lower, dtype=np.float64),
            "upper": np.asarray(upper, dtype=np.float64),
            "n_clamped": np.int64(clamped.n_values),
            "n_rows_clamped": np.int64(clamped.n_rows),
            "n_clamped_per_control": clamped.per_control.astype(np.int64),
            "meta": np.array(json.dumps(meta, sort_keys=True)),
        },
    )
    shutil.rmtree(chunk_folder)
    return SupersampleResult(
        path=path,
        n_samples=n_samples,
        n_clamped=clamped.n_values,
        n_rows_clamped=clamped.n_rows,
        n_chunks=len(range(0, n_samples, chunk_size)),
        chunks_evaluated=evaluated,
        chunks_resumed=resumed,
    )


def _samples_meta(rig, sampler, seed, n, n_samples, limits_given, clamped) -> dict:
    """The samples file's ``meta``: rig, sampler and its hyper-parameters, seed, counts."""
    return {
        "format": FILE_FORMAT_VERSION,
        "rig": rig.name,
        "length_unit": getattr(rig, "length_unit", "cm"),
        "rotation_unit": "radians",
        "sampler": sampler.name,
        "sampler_class": f"{type(sampler).__module__}.{type(sampler).__name__}",
        "sampler_params": json_ready(sampler.get_params(), nonfinite_to_null=False),
        "seed": seed,
        "n_requested": n,
        "n_samples": n_samples,
        "limits": "given" if limits_given else "rig controls lower/upper",
        "n_clamped": clamped.n_values,
        "n_rows_clamped": clamped.n_rows,
    }


def supersample_bytes(rig, n: int) -> int:
    """Bytes a run of ``n`` samples holds at its peak (ours, an estimate): the drawn and the
    clamped controls, and the posed arrays (positions, COG, its rotation) twice, as chunks
    and in the file's concatenation."""
    controls = len(rig.controls.used_indices)
    posed = 3 * rig.n_joints + 3 + 9
    return 8 * int(n) * (2 * controls + 2 * posed)


def check_supersample_memory(rig, n: int, option: str = "n") -> None:
    """Refuse ``n`` samples that would not fit in the available memory, before drawing."""
    check_memory(supersample_bytes(rig, n), option, n, f"{n} samples of rig {rig.name!r}")


def _pose_in_chunks(
    rig, sampler: Sampler, controls: np.ndarray, chunk_folder: Path, chunk_size: int, progress
) -> tuple[dict[str, np.ndarray], int, int]:
    """Positions, COG and COG rotation of every control vector, chunk by chunk.

    Each finished chunk is saved in ``chunk_folder``; a chunk an earlier run left
    for the same rig and controls is reused. Returns the arrays and how many
    chunks were evaluated and resumed.
    """
    n_samples = len(controls)
    n_joints = len(rig.joint_names)
    posed = {
        "positions": np.empty((n_samples, n_joints, 3)),
        "cog": np.empty((n_samples, 3)),
        "cog_rotation": np.empty((n_samples, 3, 3)),
    }
    chunk_folder.mkdir(parents=True, exist_ok=True)
    rig_id = _rig_fingerprint(rig)
    evaluated = resumed = 0
    with tqdm(
        total=n_samples,
        unit="sample",
        desc=f"supersample {rig.name}/{sampler.name}",
        disable=not progress,
    ) as bar:
        for index, start in enumerate(range(0, n_samples, chunk_size)):
            rows = slice(start, min(start + chunk_size, n_samples))
            chunk_file = chunk_folder / f"chunk_{index:06d}.npz"
            finished = _load_finished_chunk(chunk_file, controls[rows], rig_id)
            if finished is None:
                finished = _pose_chunk(rig, controls[rows], n_joints, index, rows)
                save_npz_atomically(
                    chunk_file,
                    {"rig": rig_id, "controls": controls[rows], **finished},
                )
                evaluated += 1
            else:
                resumed += 1
            for key, values in posed.items():
                values[rows] = finished[key]
            del finished
            bar.update(rows.stop - rows.start)
            bar.set_postfix(resumed=resumed, refresh=False)
    return posed, evaluated, resumed


def load_samples(path: str | os.PathLike) -> dict:
    """A finished samples file as a dict of arrays, with ``meta`` parsed from JSON."""
    arrays = read_npz(path, ("controls", "positions", "meta"), what="samples file")
    try:
        arrays["meta"] = json.loads(str(arrays["meta"]))
    except ValueError as error:
        raise NpzFileError(f"samples file {path}: its meta is not JSON ({error})") from None
    return arrays


def _pose_chunk(rig, controls: np.ndarray, n_joints: int, index: int, rows: slice) -> dict:
    pose = rig.pose(rig.expand_used(controls))
    chunk = {
        "positions": np.asarray(pose.positions, dtype=np.float64),
        "cog": np.asarray(pose.cog, dtype=np.float64),
        "cog_rotation": np.asarray(pose.cog_rotation, dtype=np.float64),
    }
    m = len(controls)
    where = f"rig {rig.name!r}, chunk {index} (samples {rows.start}..{rows.stop - 1})"
    for key, shape in (
        ("positions", (m, n_joints, 3)),
        ("cog", (m, 3)),
        ("cog_rotation", (m, 3, 3)),
    ):
        if chunk[key].shape != shape:
            raise SupersampleError(
                f"{where}: pose {key} has shape {chunk[key].shape}, expected {shape}"
            )
        if not np.isfinite(chunk[key]).all():
            sample = rows.start + int(np.argwhere(~np.isfinite(chunk[key]))[0][0])
            raise SupersampleError(
                f"{where}: pose {key} contains NaN or infinity at sample {sample}"
            )
    return chunk


def _load_finished_chunk(chunk_file: Path, controls: np.ndarray, rig_id: str) -> dict | None:
    """A chunk from an earlier run, if it belongs to this rig and exactly these controls."""
    if not chunk_file.exists():
        return None
    try:
        with np.load(chunk_file, allow_pickle=False) as data:
            if str(data["rig"]) != rig_id or not np.array_equal(data["controls"], controls):
                return None
            return {key: data[key] for key in ("positions", "cog", "cog_rotation")}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return None  # unreadable: evaluate it again


FINGERPRINT_PROBES = 8  # ours: enough random poses that a changed offset or mechanism shows
FINGERPRINT_SEED = 20_170_001  # ours: a fixed seed, so every run probes the same controls
FINGERPRINT_DECIMALS = 4  # ours: joint positions rounded to 1e-4 of the rig's unit (1 µm in cm)


def _rig_fingerprint(rig) -> str:
    """Identifies the rig's interface *and behaviour*: chunks of another rig are not reused.

    Names alone miss a changed rig (a moved joint offset, a new mechanism): the hash also
    covers the joint positions of a fixed seeded probe set of control vectors (the
    defaults, then points half-way from the defaults to uniform draws in the soft
    ranges), rounded to ``FINGERPRINT_DECIMALS`` so last-bit noise does not count.
    """
    controls = rig.controls
    lower, upper = np.asarray(controls.lower), np.asarray(controls.upper)
    defaults = np.asarray(controls.defaults, dtype=np.float64)
    draws = np.random.default_rng(FINGERPRINT_SEED).uniform(
        size=(FINGERPRINT_PROBES - 1, defaults.size)
    )
    probe = np.vstack([defaults, defaults + 0.5 * (lower + draws * (upper - lower) - defaults)])
    positions = np.asarray(rig.evaluate(probe), dtype=np.float64)
    rounded = np.round(positions, FINGERPRINT_DECIMALS) + 0.0  # + 0.0: no negative zeros
    description = {
        "name": rig.name,
        "controls": list(controls.names),
        "used": np.asarray(controls.used_indices).tolist(),
        "joints": list(rig.joint_names),
        "probe_decimals": FINGERPRINT_DECIMALS,
    }
    digest = hashlib.sha256(json.dumps(description).encode())
    digest.update(np.ascontiguousarray(rounded).tobytes())
    return digest.hexdigest()


def _check_sampler(sampler, rig, n_used: int) -> None:
    if not isinstance(sampler, Sampler):
        raise SupersampleError(
            f"supersample: sampler must be a rigmap.sampling.Sampler, got {type(sampler).__name__}"
        )
    if not hasattr(sampler, "n_controls_"):
        raise SamplerNotFittedError(
            f"supersample: {type(sampler).__name__} is not fitted; fit it on the corpus first"
        )
    if sampler.n_controls_ != n_used:
        raise SupersampleError(
            f"supersample: {type(sampler).__name__} was fitted on {sampler.n_controls_} controls "
            f"but rig {rig.name!r} has {n_used} used controls"
        )


def _check_positive_int(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise SamplerInputError(f"supersample: {what} must be an integer >= 1, got {value!r}")
    return int(value)


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise SamplerInputError(f"supersample: seed must be an integer >= 0, got {seed!r}")
    return int(seed)
