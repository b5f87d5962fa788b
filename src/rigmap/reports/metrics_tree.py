"""Reading the evaluate stages' metrics tree, checking every file the tables need.

Layout (written by ``rigmap.evaluation.metrics``)::

    metrics/<rig>/methods/<method>-<sampler>.json                        Table 1
    metrics/<rig>/per_frame/methods/<method>-<sampler>.csv               its errors per frame
    metrics/<rig>/samplers/nn-<sampler>.json                             Table 2
    metrics/<rig>/kernels/gpr-<kernel>.json                              §7.1 kernels
    metrics/<rig>/sample_sweep/nn-<sampler>-<n>.json   (optional)        error vs. samples
    metrics/<rig>/sample_sweep_joint_space/nn_joint_space-draws-<n>.json   (optional)  the same,
                                                        for the joint-space network's own draws

A missing or malformed file stops the report with an error naming the file,
what was expected and what came; all missing files are listed at once so one
run of the report says everything that is absent.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from rigmap.error_measures import joint_rms
from rigmap.errors import RigmapError
from rigmap.evaluation.metrics import RESULT_FORMAT
from rigmap.reports.settings import ReportSettings
from rigmap.store.layout import Layout, per_frame_file

#: Table 1's rows whose guess is a trained network (re-fitted per replicate seed)
NETWORK_METHODS = (
    "nn",
    "nn_computed_jacobian",
    "nn_learned_jacobian",
    "nn_autodiff_jacobian",
    "nn_joint_space",
    "nn_joint_space_computed_jacobian",
    "nn_joint_space_tuned",
)
_SEED_FOLDER = re.compile(r"^methods_seed(?P<k>[1-9]\d*)$")

NUMBER_KEYS = ("frames", "joint_error", "ground_truth_error", "total_time_s", "fps")
PER_FRAME_COLUMNS = ("clip", "frame", "joint_error", "ground_truth_error")
SWEEP_FOLDER = "sample_sweep"
JOINT_SPACE_SWEEP_FOLDER = "sample_sweep_joint_space"
_JOINT_SPACE_SWEEP_NAME = re.compile(r"^nn_joint_space-draws-(?P<n>\d+)\.json$")
_SWEEP_NAME = re.compile(r"^nn-(?P<sampler>[a-z_]+)-(?P<n>\d+)\.json$")
# relative agreement asked of a per-frame CSV's clip means and its JSON
_CSV_AGREEMENT = 1e-6


class ReportInputError(RigmapError, ValueError):
    """A metrics or corpus file the report needs is missing, unreadable or inconsistent."""


@dataclass(frozen=True)
class Numbers:
    """A method's numbers on one clip or on all test frames (``Average``)."""

    frames: int
    joint_error: float
    ground_truth_error: float
    total_time_s: float
    fps: float
    rig_evaluations: int = 0
    joint_rms_percent_of_height: float | None = None  # None in files written before it

    @property
    def joint_rms(self) -> float:
        """The joint error as a root mean squared joint distance (the rig's length unit)."""
        return joint_rms(self.joint_error)


@dataclass(frozen=True)
class LoadedResult:
    """One metrics JSON: its averages, per-clip numbers (clip order of the file) and unit."""

    path: Path
    rig: str
    method: str
    sampler: str
    length_unit: str
    average: Numbers
    clips: dict[str, Numbers]
    extra: dict

    confidence: dict | None = None  # the metrics JSON's "confidence" record, if measured

    @property
    def csv_path(self) -> Path:
        return per_frame_file(self.path)

    @property
    def novelty_spearman(self) -> float | None:
        """Spearman's ρ of per-frame novelty and joint error, as the evaluation measured it."""
        value = (self.confidence or {}).get("novelty_error_spearman")
        return None if value is None else float(value)

    def per_frame(self) -> pd.DataFrame:
        """The JSON's per-frame CSV, checked against it."""
        return read_per_frame(self.csv_path, self)


@dataclass
class RigMetrics:
    """Everything the tables need about one rig."""

    rig: str
    test_clips: tuple[str, ...]
    methods: dict[str, LoadedResult] = field(default_factory=dict)
    samplers: dict[str, LoadedResult] = field(default_factory=dict)
    kernels: dict[str, LoadedResult] = field(default_factory=dict)
    sweep: dict[str, dict[int, LoadedResult]] = field(default_factory=dict)
    #: the joint-space network against its number of own draws: draws -> result
    joint_space_sweep: dict[int, LoadedResult] = field(default_factory=dict)
    #: Table 1's rows scored on other splits (``heldout``, ``train``): split -> method -> result
    splits: dict[str, dict[str, LoadedResult]] = field(default_factory=dict)
    #: Table 1's network rows re-trained with replicate seeds (issue #36): seed -> method -> result
    replicates: dict[int, dict[str, LoadedResult]] = field(default_factory=dict)

    @property
    def length_unit(self) -> str:
        results = [*self.methods.values(), *self.samplers.values(), *self.kernels.values()]
        units = {r.length_unit for r in results}
        if len(units) != 1:
            raise ReportInputError(
                f"rig {self.rig!r}: metrics files disagree on the length unit: {sorted(units)}"
            )
        return units.pop()


# --------------------------------------------------------------------------- one file
def read_result(
    path: str | Path,
    *,
    rig: str,
    method: str,
    sampler: str,
    clips: Sequence[str] | None = None,
) -> LoadedResult:
    """Read and check one metrics JSON (format, identity, finite numbers, the expected clips)."""
    path = Path(path)
    if not path.is_file():
        raise ReportInputError(f"{path}: metrics file missing ({method} on rig {rig!r})")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ReportInputError(f"{path}: not a readable JSON file ({error})") from None
    if not isinstance(data, dict):
        raise ReportInputError(f"{path}: expected a JSON object, got {type(data).__name__}")
    if data.get("format") != RESULT_FORMAT:
        raise ReportInputError(
            f"{path}: expected format {RESULT_FORMAT!r}, got {data.get('format')!r}"
        )
    for key, wanted in (("rig", rig), ("method", method), ("sampler", sampler)):
        if data.get(key) != wanted:
            raise ReportInputError(
                f"{path}: field {key!r} is {data.get(key)!r} but the file name says {wanted!r}"
            )
    average = _numbers(data.get("average"), f"{path}: average")
    raw_clips = data.get("clips")
    if not isinstance(raw_clips, dict) or not raw_clips:
        raise ReportInputError(f"{path}: expected a non-empty 'clips' object, got {raw_clips!r}")
    per_clip = {
        str(name): _numbers(values, f"{path}: clip {name!r}") for name, values in raw_clips.items()
    }
    if clips is not None:
        missing = [c for c in clips if c not in per_clip]
        unexpected = [c for c in per_clip if c not in clips]
        if missing or unexpected:
            raise ReportInputError(
                f"{path}: expected the test clips {list(clips)}; missing {missing}, "
                f"unexpected {unexpected}"
            )
        per_clip = {c: per_clip[c] for c in clips}
    frames = sum(n.frames for n in per_clip.values())
    if frames != average.frames:
        raise ReportInputError(
            f"{path}: the clips hold {frames} frames but the average says {average.frames}"
        )
    unit = data.get("length_unit")
    if not isinstance(unit, str) or not unit:
        raise ReportInputError(f"{path}: expected a 'length_unit' string, got {unit!r}")
    extra = data.get("extra") if isinstance(data.get("extra"), dict) else {}
    confidence = data.get("confidence") if isinstance(data.get("confidence"), dict) else None
    return LoadedResult(path, rig, method, sampler, unit, average, per_clip, extra, confidence)


def _numbers(values, where: str) -> Numbers:
    if not isinstance(values, dict):
        raise ReportInputError(f"{where}: expected an object of numbers, got {values!r}")
    numbers = {}
    for key in NUMBER_KEYS:
        value = values.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ReportInputError(f"{where}: expected a number for {key!r}, got {value!r}")
        if not math.isfinite(value) or value < 0:
            raise ReportInputError(f"{where}: {key!r} must be finite and >= 0, got {value!r}")
        numbers[key] = value
    if numbers["frames"] < 1 or numbers["total_time_s"] <= 0:
        raise ReportInputError(
            f"{where}: expected frames >= 1 and total_time_s > 0, got {numbers['frames']} frames "
            f"in {numbers['total_time_s']} s"
        )
    evaluations = values.get("rig_evaluations", 0)
    percent = values.get("joint_rms_percent_of_height")
    return Numbers(
        frames=int(numbers["frames"]),
        joint_error=float(numbers["joint_error"]),
        ground_truth_error=float(numbers["ground_truth_error"]),
        total_time_s=float(numbers["total_time_s"]),
        fps=float(numbers["fps"]),
        rig_evaluations=int(evaluations) if isinstance(evaluations, int | float) else 0,
        joint_rms_percent_of_height=_optional_number(percent, where, "joint_rms_percent_of_height"),
    )


def _optional_number(value, where: str, key: str) -> float | None:
    """A number a newer metrics file has and an older one may lack (``None`` then)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ReportInputError(f"{where}: {key!r} must be a finite number, got {value!r}")
    return float(value)


def read_per_frame(path: str | Path, result: LoadedResult) -> pd.DataFrame:
    """A per-frame CSV (clip, frame, joint_error, ground_truth_error) that agrees with its JSON."""
    path = Path(path)
    if not path.is_file():
        raise ReportInputError(f"{path}: per-frame CSV missing (of {result.path})")
    try:
        table = pd.read_csv(path, dtype={"clip": str})
    except (OSError, ValueError) as error:
        raise ReportInputError(f"{path}: not a readable CSV ({error})") from None
    missing = [c for c in PER_FRAME_COLUMNS if c not in table.columns]
    if missing:
        raise ReportInputError(
            f"{path}: expected columns {list(PER_FRAME_COLUMNS)}, missing {missing} "
            f"(got {list(table.columns)})"
        )
    errors = table[["joint_error", "ground_truth_error"]]
    if not errors.map(lambda v: isinstance(v, int | float) and math.isfinite(v)).all().all():
        raise ReportInputError(f"{path}: errors must be finite numbers")
    for clip, numbers in result.clips.items():
        rows = table[table["clip"] == clip]
        if len(rows) != numbers.frames:
            raise ReportInputError(
                f"{path}: clip {clip!r} has {len(rows)} frames but {result.path.name} says "
                f"{numbers.frames}"
            )
        mean = float(rows["joint_error"].mean())
        if not math.isclose(mean, numbers.joint_error, rel_tol=_CSV_AGREEMENT, abs_tol=1e-12):
            raise ReportInputError(
                f"{path}: clip {clip!r} mean joint error {mean!r} disagrees with "
                f"{result.path.name} ({numbers.joint_error!r}); is one of them stale?"
            )
    return table[table["clip"].isin(list(result.clips))].reset_index(drop=True)


# --------------------------------------------------------------------------- the tree
def corpus_clip_names(corpus_file: str | Path) -> tuple[str, ...]:
    """The clip names of a test corpus, in file order."""
    corpus_file = Path(corpus_file)
    if not corpus_file.is_file():
        raise ReportInputError(
            f"{corpus_file}: test corpus missing (the animate stage writes it); the report "
            "takes each rig's test clip names from it"
        )
    try:
        clips = pd.read_parquet(corpus_file, columns=["clip"])["clip"]
    except (OSError, ValueError, KeyError) as error:
        raise ReportInputError(f"{corpus_file}: cannot read its 'clip' column ({error})") from None
    names = tuple(str(c) for c in dict.fromkeys(clips))
    if not names:
        raise ReportInputError(f"{corpus_file}: the test corpus has no clips")
    return names


def expected_files(metrics_root: str | Path, rig: str, settings: ReportSettings) -> list[tuple]:
    """``(table, key, path, method, sampler)`` for every file the tables need on ``rig``."""
    layout = Layout(metrics=metrics_root)
    files = []
    for method in settings.methods_for(rig):
        sampler = settings.method_sampler(method)
        path = layout.metrics_file(rig, "methods", f"{method}-{sampler}")
        files.append(("methods", method, path, method, sampler))
    if rig not in settings.sampler_rigs:
        return files
    for sampler in settings.samplers:
        path = layout.metrics_file(rig, "samplers", f"nn-{sampler}")
        files.append(("samplers", sampler, path, "nn", sampler))
    for kernel in settings.kernels:
        path = layout.metrics_file(rig, "kernels", f"gpr-{kernel}")
        files.append(("kernels", kernel, path, "gpr", "none"))
    return files


def load_metrics(
    metrics_root: str | Path, data_root: str | Path, settings: ReportSettings
) -> dict[str, RigMetrics]:
    """Every rig's metrics; one error listing all missing files if any are absent."""
    missing = []
    for rig in settings.rigs:
        for table, key, path, method, sampler in expected_files(metrics_root, rig, settings):
            if not path.is_file():
                what = {
                    "methods": f"Table 1: {method}",
                    "samplers": f"Table 2: nn trained with sampler {sampler}",
                    "kernels": f"kernel table: gpr with the {key} kernel",
                }[table]
                missing.append(f"{path} ({what})")
            elif table == "methods" and not per_frame_file(path).is_file():
                missing.append(f"{per_frame_file(path)} (per-frame errors of {method})")
    if missing:
        raise ReportInputError(
            f"{len(missing)} metrics file(s) missing under {metrics_root} — the evaluate stages "
            "write them (`dvc repro` or `python pipelines/evaluate.py rig=... evaluate.set=...`); "
            "rigs or rows an experiment does not run belong in the report settings (report.rigs, "
            "report.method_rigs, report.sampler_rigs, report.excluded_methods):\n  "
            + "\n  ".join(missing)
        )
    tree = {}
    for rig in settings.rigs:
        clips = settings.clips or corpus_clip_names(Layout(data=data_root).corpus(rig, "test"))
        metrics = RigMetrics(rig, clips)
        for table, key, path, method, sampler in expected_files(metrics_root, rig, settings):
            result = read_result(path, rig=rig, method=method, sampler=sampler, clips=clips)
            getattr(metrics, table)[key] = result
        metrics.sweep = _read_sweep(Path(metrics_root) / rig / SWEEP_FOLDER, rig, clips)
        metrics.joint_space_sweep = _read_joint_space_sweep(
            Path(metrics_root) / rig / JOINT_SPACE_SWEEP_FOLDER, rig, clips
        )
        metrics.splits = _read_splits(Path(metrics_root) / rig, rig)
        metrics.replicates = read_replicates(Path(metrics_root) / rig, rig, clips)
        tree[rig] = metrics
    return tree


def read_replicates(
    rig_folder: str | Path, rig: str, clips: Sequence[str] | None = None
) -> dict[int, dict[str, LoadedResult]]:
    """A rig's ``methods_seed<k>/<method>-<sampler>.json``: seed -> method -> result (their
    spread is :mod:`rigmap.reports.seed_spread`'s)."""
    folder = Path(rig_folder)
    found: dict[int, dict[str, LoadedResult]] = {}
    for seed_folder in sorted(folder.glob("methods_seed*")) if folder.is_dir() else ():
        match = _SEED_FOLDER.match(seed_folder.name)
        if match is None or not seed_folder.is_dir():
            raise ReportInputError(f"{seed_folder}: expected a folder methods_seed<k> (k >= 1)")
        results = {}
        for path in sorted(seed_folder.glob("*.json")):
            method, _, sampler = path.stem.partition("-")
            if method not in NETWORK_METHODS or not sampler:
                raise ReportInputError(
                    f"{path}: unexpected file; a replicate seed holds network rows "
                    f"<method>-<sampler>.json of {', '.join(NETWORK_METHODS)}"
                )
            results[method] = read_result(
                path, rig=rig, method=method, sampler=sampler, clips=clips
            )
        found[int(match["k"])] = results
    return dict(sorted(found.items()))


def _read_splits(rig_folder: Path, rig: str) -> dict[str, dict[str, LoadedResult]]:
    """Optional ``methods_<split>/<method>-<sampler>.json``: Table 1 rows on another split."""
    found: dict[str, dict[str, LoadedResult]] = {}
    for split in ("heldout", "train"):
        folder = rig_folder / f"methods_{split}"
        for path in sorted(folder.glob("*.json")) if folder.is_dir() else ():
            method, _, sampler = path.stem.partition("-")
            if not sampler:
                raise ReportInputError(
                    f"{path}: unexpected file in {folder}; expected names <method>-<sampler>.json"
                )
            result = read_result(path, rig=rig, method=method, sampler=sampler)
            found.setdefault(split, {})[method] = result
    return found


def _read_joint_space_sweep(folder: Path, rig: str, clips) -> dict[int, LoadedResult]:
    """Optional ``nn_joint_space-draws-<n>.json`` files: the joint-space network with n draws."""
    points: dict[int, LoadedResult] = {}
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else ():
        match = _JOINT_SPACE_SWEEP_NAME.match(path.name)
        if match is None:
            raise ReportInputError(
                f"{path}: unexpected file in {folder}; expected names "
                "nn_joint_space-draws-<draws>.json"
            )
        n = int(match["n"])
        points[n] = read_result(path, rig=rig, method="nn_joint_space", sampler="none", clips=clips)
    return dict(sorted(points.items()))


def _read_sweep(folder: Path, rig: str, clips) -> dict[str, dict[int, LoadedResult]]:
    """Optional ``nn-<sampler>-<n>.json`` files: the network trained with n extra samples."""
    sweep: dict[str, dict[int, LoadedResult]] = {}
    if not folder.is_dir():
        return sweep
    for path in sorted(folder.glob("*.json")):
        match = _SWEEP_NAME.match(path.name)
        if match is None:
            raise ReportInputError(
                f"{path}: unexpected file in {folder}; expected names nn-<sampler>-<samples>.json"
            )
        sampler, n = match["sampler"], int(match["n"])
        result = read_result(path, rig=rig, method="nn", sampler=sampler, clips=clips)
        sweep.setdefault(sampler, {})[n] = result
    return {s: dict(sorted(points.items())) for s, points in sweep.items()}
