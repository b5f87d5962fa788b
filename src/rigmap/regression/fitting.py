"""Fitting an inverse rig mapping from a rig's training data (the ``fit`` stage, ``rigmap fit``).

The training rows, in this order:

1. every frame of the train corpus — keys and the frames interpolated between them (§6.1) —
   with its posed joint positions as inputs and its used controls as targets;
2. the rig's default (rest) pose, as one more row, when no corpus frame is that pose: the
   GPR's greedy subsampling starts from the rest pose (§4.2);
3. the sampler's extra samples (§5.2, ``data/<rig>/samples/<sampler>.npz``); sampler
   ``none`` adds nothing. The paper fits the GPR on the corpus alone (sampler ``none``)
   and the network on the corpus plus samples; other pairings are allowed and named by
   the model folder.

Rows are :func:`~rigmap.regression.features.inverse_features` pose rows (COG-relative
joints plus the COG placement) and the rig's used controls. The fit first finds the rig's
root channels (:func:`~rigmap.regression.placement.find_placement`): the regressor then
learns from inputs and targets that ignore where the character stands and faces, and the
model (an :class:`~rigmap.regression.mapping.InverseMapping`) solves the root channels from
the COG placement when it predicts. A multiquadric GPR also gets the learned Jacobian of
§4.3-4.4: finite-difference Jacobians at its support poses, regressed by a GPR of the same
settings, saved in ``learned_jacobian/`` inside the model folder.

The model folder ``<paths.models>/<rig>/<regressor>-<sampler>-<kernel>/`` (kernel
``none`` for the network) is filled in a hidden sibling folder and renamed into place, so
a killed fit never leaves a half-written model behind.
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigmap.animation.corpus import Corpus
from rigmap.animation.posing import PoseTable
from rigmap.error_measures import control_std, ground_truth_error, joint_error
from rigmap.errors import RigmapError
from rigmap.regression.base import Regressor
from rigmap.regression.features import (
    PLACEMENT_WIDTH,
    default_pose_features,
    feature_names,
    inverse_features,
)
from rigmap.regression.learned_jacobian import learned_jacobian_plan
from rigmap.regression.mapping import InverseMapping, JacobianMapping
from rigmap.regression.placement import Placement, find_placement
from rigmap.sampling.supersample import load_samples
from rigmap.store import Layout, ModelId, json_ready, write_folder_atomic, write_json_atomic

FIT_FORMAT = "rigmap.fit/1"
TRAIN_SPLIT = "train"
LEARNED_JACOBIAN_FOLDER = "learned_jacobian"
# a corpus frame counts as the rest pose when every used control is within this of its default
_REST_TOLERANCE = 1e-9
# corpus frames (evenly spaced, plus the rest pose) at which the root channels are probed
PLACEMENT_PROBES = 4

Log = Callable[[str], None]


class FitInputError(RigmapError, ValueError):
    """The training files of a fit are missing, of another rig, or do not line up."""


def _print(message: str) -> None:
    print(message, flush=True)


# --------------------------------------------------------------------------- training data
@dataclass
class TrainingData:
    """Regression inputs and targets of one rig, with where each row came from."""

    features: np.ndarray  # (N, 3J + 12)
    controls: np.ndarray  # (N, C_used), in rig.used_controls order
    corpus_rows: int  # rows [0, corpus_rows) are corpus frames
    rest_index: int  # the row holding the rest pose
    rest_pose_added: bool  # True: row ``corpus_rows`` is the rig's default pose, added
    rest_pose: str  # a sentence saying which row is the rest pose and why
    sample_rows: int  # the last ``sample_rows`` rows are the sampler's samples
    sources: dict[str, str | None] = field(default_factory=dict)

    @property
    def rows(self) -> int:
        return len(self.features)

    def digest(self) -> str:
        """SHA-256 of the rows (features and controls), so a later stage can tell whether a
        saved fit was trained on exactly these rows."""
        hasher = hashlib.sha256()
        for array in (self.features, self.controls):
            values = np.ascontiguousarray(array, dtype=np.float64)
            hasher.update(repr(values.shape).encode())
            hasher.update(values.tobytes())
        return hasher.hexdigest()


def training_files(data_dir: str | os.PathLike, rig_name: str, sampler: str) -> dict[str, Path]:
    """The files a fit reads: train corpus, train poses and the sampler's samples."""
    layout = Layout(data=Path(data_dir))
    return {
        "corpus": layout.corpus(rig_name, TRAIN_SPLIT),
        "poses": layout.poses(rig_name, TRAIN_SPLIT),
        "samples": layout.samples(rig_name, sampler),
    }


def load_training_data(rig, data_dir: str | os.PathLike, sampler: str) -> TrainingData:
    """Corpus frames, the rest pose if the corpus lacks it, then ``sampler``'s samples.

    Sampler ``none`` draws nothing, so its samples file is not read (nor needed).
    """
    files = training_files(data_dir, rig.name, sampler)
    for role, stage in (("corpus", "animate"), ("poses", "pose")):
        if not files[role].is_file():
            raise FileNotFoundError(
                f"{files[role]}: the train {role} of rig {rig.name!r} does not exist (it is "
                f"the {stage} stage's output: run `python pipelines/{stage}.py rig={rig.name}` "
                f"or `dvc repro {stage}`)"
            )
    corpus = Corpus.read(
        files["corpus"], rig=rig.name, control_names=rig.used_controls, split=TRAIN_SPLIT
    )
    poses = PoseTable.read(files["poses"], rig=rig.name, n_joints=rig.n_joints, split=TRAIN_SPLIT)
    if list(poses.joint_names) != list(rig.joint_names):
        raise FitInputError(
            f"{files['poses']}: joint names differ from rig {rig.name!r}'s (same count, "
            "another order or naming); re-run the pose stage"
        )
    corpus_keys = corpus.table[["clip", "frame"]].to_numpy()
    pose_keys = poses.table[["clip", "frame"]].to_numpy()
    if corpus_keys.shape != pose_keys.shape or not (corpus_keys == pose_keys).all():
        raise FitInputError(
            f"{files['poses']} ({len(pose_keys)} rows) does not hold the frames of "
            f"{files['corpus']} ({len(corpus_keys)} rows) in the same order; the poses are "
            "stale: re-run the pose stage"
        )
    where = str(files["poses"])
    features = [
        inverse_features(
            poses.positions(), poses.cog(), poses.cog_rotation(), n_joints=rig.n_joints, where=where
        )
    ]
    controls = [corpus.values()]
    corpus_rows = len(controls[0])

    rest_index, rest_pose, rest_row = _rest_pose(rig, controls[0], corpus_keys)
    added = rest_row is not None
    if added:
        features.append(rest_row[0])
        controls.append(rest_row[1])

    samples_source = None
    sample_rows = 0
    if sampler != "none":
        sample_features, sample_controls = _read_samples(rig, files["samples"], sampler)
        features.append(sample_features)
        controls.append(sample_controls)
        sample_rows = len(sample_controls)
        samples_source = str(files["samples"])
    return TrainingData(
        features=np.concatenate(features),
        controls=np.concatenate(controls),
        corpus_rows=corpus_rows,
        rest_index=rest_index,
        rest_pose_added=added,
        rest_pose=rest_pose,
        sample_rows=sample_rows,
        sources={
            "corpus": str(files["corpus"]),
            "poses": str(files["poses"]),
            "samples": samples_source,
        },
    )


def _rest_pose(rig, corpus_controls: np.ndarray, corpus_keys: np.ndarray):
    """The row of the rig's default pose: a corpus frame that is it, else one more row.

    Returns the row's index, a sentence saying why, and ``(features, controls)`` of
    the added row (``None`` when a corpus frame is the rest pose).
    """
    defaults = rig.controls.defaults[rig.controls.used_indices]
    distance = np.abs(corpus_controls - defaults).max(axis=1)
    matches = np.flatnonzero(distance <= _REST_TOLERANCE)
    if len(matches):
        rest_index = int(matches[0])
        clip, frame = corpus_keys[rest_index]
        note = f"corpus row {rest_index} (clip {clip!r}, frame {frame}) is the rig's default pose"
        return rest_index, note, None
    rest_index = len(corpus_controls)
    features = default_pose_features(rig)
    note = (
        f"no corpus frame is the rig's default pose (closest differs by "
        f"{distance.min():.3g} in some used control), so the default pose was added as "
        f"row {rest_index}"
    )
    return rest_index, note, (features, defaults[None])


def _read_samples(rig, path: Path, sampler: str) -> tuple[np.ndarray, np.ndarray]:
    if not path.is_file():
        raise FileNotFoundError(
            f"{path}: the {sampler!r} samples of rig {rig.name!r} do not exist (the "
            f"supersample stage's output: run `python pipelines/supersample.py rig={rig.name} "
            f"sampler={sampler}`), or fit with sampler=none"
        )
    try:
        samples = load_samples(path)
    except (OSError, ValueError, KeyError) as error:
        raise FitInputError(f"{path}: not a readable samples file ({error})") from None
    needed = ("controls", "positions", "cog", "cog_rotation", "control_names", "joint_names")
    missing = [key for key in needed if key not in samples]
    if missing:
        raise FitInputError(f"{path}: arrays {missing} are missing (have {sorted(samples)})")
    meta = samples.get("meta", {})
    if meta.get("rig") != rig.name:
        raise FitInputError(
            f"{path}: samples are for rig {meta.get('rig')!r}, expected {rig.name!r}"
        )
    if meta.get("sampler") not in (None, sampler):
        raise FitInputError(
            f"{path}: samples were drawn by sampler {meta.get('sampler')!r}, expected {sampler!r}"
        )
    if list(samples["control_names"]) != list(rig.used_controls):
        raise FitInputError(
            f"{path}: control_names differ from rig {rig.name!r}'s used controls "
            f"({len(samples['control_names'])} vs {len(rig.used_controls)}); re-run supersample"
        )
    if list(samples["joint_names"]) != list(rig.joint_names):
        raise FitInputError(
            f"{path}: joint_names differ from rig {rig.name!r}'s joints "
            f"({len(samples['joint_names'])} vs {rig.n_joints}); re-run supersample"
        )
    controls = np.asarray(samples["controls"], dtype=np.float64)
    if controls.ndim != 2 or controls.shape[1] != len(rig.used_controls):
        raise FitInputError(
            f"{path}: controls have shape {controls.shape}, expected (n, {len(rig.used_controls)})"
        )
    features = inverse_features(
        samples["positions"],
        samples["cog"],
        samples["cog_rotation"],
        n_joints=rig.n_joints,
        where=str(path),
    )
    if not np.isfinite(controls).all():
        raise FitInputError(f"{path}: controls contain NaN or infinity")
    return features, controls


# --------------------------------------------------------------------------- the fit
@dataclass
class FitResult:
    """What a fit produced: the folder written, the models and the ``fit.json`` record."""

    folder: Path
    model: InverseMapping
    learned_jacobian: JacobianMapping | None
    record: dict[str, Any]


def fit_model(
    rig,
    model: Regressor,
    sampler: str,
    layout: Layout,
    config: Mapping[str, Any],
    *,
    started: float | None = None,
    log: Log = _print,
) -> FitResult:
    """Fit the unfitted ``model`` on ``rig``'s corpus and ``sampler``'s samples, write the
    model folder under ``layout``; ``config`` (plain) is recorded in ``fit.json`` as given
    and ``started`` (a ``perf_counter`` time) is when the job began."""
    started = time.perf_counter() if started is None else started
    regressor, kernel_label = model.name, model.kernel_name
    model_id = ModelId(regressor, sampler, kernel_label)
    folder = layout.model(rig.name, model_id)
    log(f"fit {rig.name}: {regressor} (kernel {kernel_label}, sampler {sampler}) -> {folder}")

    data = load_training_data(rig, layout.data, sampler)
    log(
        f"  training rows: {data.rows} = {data.corpus_rows} corpus frames"
        f"{' + 1 rest pose' if data.rest_pose_added else ''} + {data.sample_rows} samples; "
        f"{data.features.shape[1]} inputs -> {data.controls.shape[1]} used controls"
    )
    log(f"  rest pose: {data.rest_pose}")
    placement = placement_of(rig, data)
    log(f"  placement: {placement.describe()}")
    for note in placement.notes:
        log(f"  placement note: {note}")

    seconds: dict[str, float] = {}
    clock = time.perf_counter()
    fitted = fit_regressor(model, rig, data, placement, log=log)
    seconds["model"] = time.perf_counter() - clock
    details = fitted.regressor.fit_facts()

    learned = None
    wanted = learned_jacobian_plan(fitted.regressor)
    if wanted is not None:
        learned, jacobian_details = fit_learned_jacobian(fitted, wanted, rig, data, log=log)
        details["learned_jacobian"] = jacobian_details
        seconds["jacobians"] = jacobian_details["seconds"]["finite_differences"]
        seconds["learned_jacobian"] = jacobian_details["seconds"]["fit"]

    clock = time.perf_counter()
    error = training_error(fitted, rig, data)
    seconds["training_error"] = time.perf_counter() - clock
    seconds["total"] = time.perf_counter() - started
    log(
        f"  training error on {error['rows']} corpus frames: ground truth "
        f"{error['ground_truth_error']:.4g} (std units; the mean predictor scores 1), joint "
        f"{error['joint_error_cm2']:.4g} cm² (mean controls: "
        f"{error['joint_error_cm2_mean_controls']:.4g} cm²)"
    )

    record = {
        **_fit_record(rig, model_id, data, placement, seconds, error),
        **details,
        "config": json_ready(config),
    }

    def fill(staging: Path) -> None:
        fitted.save(staging)
        if learned is not None:
            learned.save(staging / LEARNED_JACOBIAN_FOLDER)
        write_json_atomic(staging / "fit.json", json_ready(record))

    write_folder_atomic(folder, fill)
    log(f"  wrote {folder} in {seconds['total']:.1f} s")
    return FitResult(folder=folder, model=fitted, learned_jacobian=learned, record=record)


def _fit_record(
    rig, model_id: ModelId, data: TrainingData, placement: Placement, seconds, error
) -> dict[str, Any]:
    """The parts of ``fit.json`` every regressor has (the model adds its own facts)."""
    return {
        "format": FIT_FORMAT,
        "rig": rig.name,
        "regressor": model_id.regressor,
        "sampler": model_id.sampler,
        "kernel": model_id.kernel,
        "model_file": f"{model_id.regressor}.json",
        "rows": {
            "total": data.rows,
            "corpus": data.corpus_rows,
            "rest_pose_added": int(data.rest_pose_added),
            "samples": data.sample_rows,
            "sha256": data.digest(),
        },
        "rest_pose": {
            "index": data.rest_index,
            "added": data.rest_pose_added,
            "note": data.rest_pose,
        },
        "seconds": seconds,
        "features": feature_layout(rig, placement),
        "placement": placement.to_dict(),
        "outputs": {"count": len(rig.used_controls), "controls": list(rig.used_controls)},
        "inputs": data.sources,
        "training_error": error,
    }


def placement_of(rig, data: TrainingData) -> Placement:
    """The rig's root channels, probed at the rest pose and a few corpus frames."""
    defaults = rig.controls.defaults[rig.controls.used_indices]
    picks = np.linspace(0, data.corpus_rows - 1, PLACEMENT_PROBES).round().astype(int)
    probes = np.concatenate([defaults[None], data.controls[np.unique(picks)]])
    return find_placement(rig, probes)


def fit_regressor(
    model: Regressor, rig, data: TrainingData, placement: Placement, *, log: Log = _print
) -> InverseMapping:
    """``model.fit`` on the training rows behind ``placement``, with the model's own options."""
    options: dict[str, Any] = {"rig_name": rig.name, "control_names": list(rig.used_controls)}
    options.update(model.fit_options(rest_index=data.rest_index))
    options.update(model.rig_fit_options(rig=rig, placement=placement))
    log(f"  {model.describe_plan(data.rows)}")
    mapping = InverseMapping(model, placement).fit(data.features, data.controls, **options)
    for line in model.describe_result():
        log(f"  {line}")
    return mapping


def fit_learned_jacobian(
    mapping: InverseMapping, wanted, rig, data: TrainingData, *, log: Log = _print
) -> tuple[JacobianMapping, dict[str, Any]]:
    """§4.3-4.4: finite-difference Jacobians at the rows the model names, learned by its model.

    ``wanted`` is ``learned_jacobian_plan(regressor)``: the training rows (the GPR's support
    poses) and the unfitted learned Jacobian; it learns behind the mapping's placement.
    The differences are central and coloured (:mod:`rigmap.refine.sparsity`: controls that
    move disjoint joints perturbed in one rig evaluation, as refinement does): on 300
    quadruped poses 6.1x faster than one control at a time and equal to 6e-11 relative
    (1e-5 on the float32 Blender wolf, its rounding over the step).
    """
    from rigmap.refine import jacobian, rig_colouring

    support, regressor = wanted
    colouring = rig_colouring(rig)
    log(
        f"  finite-difference Jacobians at {len(support)} support poses "
        f"({2 * colouring.n_colours} rig evaluations each: central, {colouring.n_colours} "
        f"colours for {len(rig.used_controls)} controls)"
    )
    clock = time.perf_counter()
    jacobians = jacobian(
        rig, rig.expand_used(data.controls[support]), "finite_difference", colouring=colouring
    )
    fd_seconds = time.perf_counter() - clock
    learned = JacobianMapping(regressor, mapping.placement)
    log(
        f"  learned Jacobian: GPR {len(support)} poses -> {jacobians.shape[1]} x "
        f"{jacobians.shape[2]} Jacobians (after {fd_seconds:.1f} s of finite differences)"
    )
    clock = time.perf_counter()
    learned.fit(
        data.features[support],
        jacobians,
        rig_name=rig.name,
        control_names=list(rig.used_controls),
    )
    fit_seconds = time.perf_counter() - clock
    predicted = learned.predict(data.features[support])
    relative = float(np.linalg.norm(predicted - jacobians) / np.linalg.norm(jacobians))
    log(
        f"  learned Jacobian fitted in {fit_seconds:.1f} s: length scale "
        f"{learned.length_scale_:.3g}, relative error at the support poses {relative:.2e}"
    )
    return learned, {
        "folder": LEARNED_JACOBIAN_FOLDER,
        "poses": len(support),
        "jacobian_shape": [int(jacobians.shape[1]), int(jacobians.shape[2])],
        "method": "finite_difference",
        "colours": colouring.n_colours,
        "length_scale": float(learned.length_scale_),
        "relative_error_at_support": relative,
        "seconds": {"finite_differences": fd_seconds, "fit": fit_seconds},
    }


def training_error(model, rig, data: TrainingData) -> dict[str, Any]:
    """Errors on the corpus frames the model was trained on (§6.1's two measures).

    The ground-truth error is in training-std units, so predicting the corpus mean
    scores 1; the joint error (cm²) comes with that of the mean controls for scale.
    """
    rows = slice(0, data.corpus_rows)
    truth = data.controls[rows]
    predicted = model.predict(data.features[rows])
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    std = control_std(truth)
    gt = ground_truth_error(predicted, truth, std, kinds, names=list(rig.used_controls))
    n_joint_values = 3 * rig.n_joints
    target = data.features[rows, :n_joint_values]
    posed = np.asarray(rig.evaluate(rig.expand_used(predicted)))
    mean_pose = np.asarray(rig.evaluate(rig.expand_used(truth.mean(axis=0, keepdims=True))))
    return {
        "rows": int(data.corpus_rows),
        "ground_truth_error": gt.mean,
        "ground_truth_scored_controls": gt.scored_controls,
        "joint_error_cm2": joint_error(posed, target).mean,
        "joint_error_cm2_mean_controls": joint_error(
            np.broadcast_to(mean_pose.reshape(1, -1), target.shape), target
        ).mean,
    }


def feature_layout(rig, placement: Placement) -> dict[str, Any]:
    """How the model's input columns are laid out (see :func:`inverse_features`)."""
    names = feature_names(list(rig.joint_names))
    return {
        "function": "rigmap.regression.features.inverse_features",
        "width": len(names),
        "regressor_inputs": f"{placement.input_width} columns ({placement.describe()})",
        "n_joints": rig.n_joints,
        "joint_columns": "<joint>.x, <joint>.y, <joint>.z per joint in joint_names order (cm, "
        "relative to the COG)",
        "joint_names": list(rig.joint_names),
        "placement_columns": names[-PLACEMENT_WIDTH:],
    }
