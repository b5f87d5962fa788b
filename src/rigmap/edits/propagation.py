"""Learning an edit from example pairs and propagating it to other clips (§3, §4).

:class:`EditModel` ``fit`` takes example pairs — a source clip (its joint positions and
target track) and the artist's edited track of it, same frames — and fits the two GP
predictors of §4.1 on the training-std-scaled channels: the configuration GP from the
kinematic features ``x(k)`` to the edited track, the acceleration GP from the
acceleration features ``x(a)`` to its second differences (per frame², interior frames
of each clip). ``apply`` predicts both on a new source clip and combines them with the
source in the banded solve of Eqs 7–12 (:func:`rigmap.edits.combine.combine`).

``residual=True`` makes both GPs predict the edit (target − source) instead of the
target, added back to the source, with a zero prior mean (far from the examples: no
edit): ours, not the paper's, measured against it. With the paper's targets a clip
unlike the examples loses its own detail (the GP's mean is an average of training
frames) unless the variance is large enough for the regulariser to take over.
The joints the features read, the weights and the mask are the caller's; the paper
gives no weights, the defaults (all 1) are :class:`rigmap.edits.combine.Weights`'.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from rigmap.edits.combine import Weights, accelerations, combine
from rigmap.edits.features import acceleration_features, kinematic_features
from rigmap.edits.gp import Prediction, SharedGP
from rigmap.edits.mls import MovingLeastSquares
from rigmap.edits.representation import ChannelScale, TargetError, TargetTrack
from rigmap.regression import model_io
from rigmap.regression.errors import ModelFileError


@dataclass(frozen=True)
class FeatureJoints:
    """Which joints the features read: all ``feature`` joints, and root/left/right indices
    (of the full joint list) that place the heading frame."""

    feature: tuple[int, ...]
    root: int
    left: int
    right: int


@dataclass(frozen=True, eq=False)
class SourceClip:
    """A clip the model reads: world joint positions ``(F, J, 3)`` and its target track."""

    positions: np.ndarray
    track: TargetTrack

    def __post_init__(self) -> None:
        positions = np.asarray(self.positions, dtype=np.float64)
        if positions.ndim != 3 or len(positions) != self.track.n_frames:
            raise TargetError(
                f"{self.track.source}: {positions.shape[:1]} frames of joint "
                f"positions for {self.track.n_frames} frames of track"
            )
        if not np.isfinite(positions).all():
            frame, joint = np.argwhere(~np.isfinite(positions).all(axis=2))[0]
            raise TargetError(f"{self.track.source}: joint {joint} is not finite at frame {frame}")
        object.__setattr__(self, "positions", positions)

    def features(self, joints: FeatureJoints) -> tuple[np.ndarray, np.ndarray]:
        """``x(k)`` and ``x(a)`` of every frame (§4.5, :mod:`rigmap.edits.features`)."""
        p = self.positions
        chosen = list(joints.feature)
        kinematic = kinematic_features(
            p, self.track.fps, root=joints.root, left=joints.left, right=joints.right
        )
        n = len(p)
        kinematic = kinematic.reshape(n, 3, p.shape[1], 3)[:, :, chosen].reshape(n, -1)
        acceleration = acceleration_features(p, self.track.fps, root=joints.root)
        acceleration = acceleration.reshape(n, p.shape[1], 3)[:, chosen].reshape(n, -1)
        return kinematic, acceleration


ESTIMATORS = ("gp", "mls")


class EditModel:
    """The two GPs of an edit, and the combined solve that applies them (module docstring)."""

    fit_threads = 2  # the two GPs side by side; 1: one after the other in the caller's
    # thread (benchmarks/edits.py)

    def __init__(
        self,
        joints: FeatureJoints,
        weights: Weights | None = None,
        residual: bool = False,
        max_iterations: int = 100,
        gp_method: str = "lbfgs",
        estimator: str = "gp",
        input_scale: str = "global",
    ):
        if estimator not in ESTIMATORS:
            raise TargetError(f"unknown edit estimator {estimator!r}; expected one of {ESTIMATORS}")
        self.joints = joints
        self.weights = weights or Weights()
        self.residual = residual
        self.max_iterations = max_iterations
        self.gp_method = gp_method  # how the GPs are fitted (rigmap.edits.gp's METHODS)
        self.estimator = estimator  # "gp" (§4.1) or "mls" (§4.4, rigmap.edits.mls)
        self.input_scale = input_scale  # the GPs' feature scaling (rigmap.edits.gp)

    def fit(
        self, pairs: list[tuple], scale: ChannelScale, mirror=None, warm_start: bool = False
    ) -> EditModel:
        """Fit both GPs on example ``(source, edited track)`` pairs (and their mirrors, with
        a :class:`rigmap.edits.mirror.Mirror`: §7.1 doubles the training data so).

        A pair may carry a third element, the frames of the clip that are examples (a
        boolean mask or indices: the frames an artist fixed, §3): the features still see
        the whole clip, the configuration GP those frames, the acceleration GP the fixed
        frames whose both neighbours are fixed too. ``warm_start`` starts each GP's
        hyper-parameter search from this model's last fit (ours; the paper refits from its
        initial values, and "suspect[s] that it could be possible [to] reuse
        hyperparameters for new data", §7.1)."""
        if not pairs:
            raise TargetError("an edit needs at least one example pair")
        if mirror is not None:
            pairs = mirror.pairs(pairs)
        xk, yk, xa, ya = [], [], [], []
        for pair in pairs:
            source, edited = pair[:2]
            _check_pair(source.track, edited)
            kinematic, acceleration = source.features(self.joints)
            target = scale.scaled(edited)
            if self.residual:
                target = target - scale.scaled(source.track)
            chosen = _frame_mask(pair[2] if len(pair) > 2 else None, source.track)
            inner = chosen[1:-1] & chosen[:-2] & chosen[2:]
            xk.append(kinematic[chosen])
            yk.append(target[chosen])
            xa.append(acceleration[1:-1][inner])
            ya.append(accelerations(target)[inner])
        self.scale = scale
        center = not self.residual  # an offset's prior is no edit
        data = ((np.vstack(xk), np.vstack(yk)), (np.vstack(xa), np.vstack(ya)))
        # the two fits are independent: one thread each, so a 2-core machine fits both in
        # the time of the slower: the objective's LAPACK/BLAS calls release the GIL
        # (dpotrf in SciPy's wrapper, dpotri, dpotrs and dsyrk through rigmap.edits.nogil;
        # with SciPy's wrappers of those three, up to s28, the fits took turns in them).
        # BLAS is held at one thread
        # around both: threadpoolctl's limit is process-wide, so a fit that ended first
        # restored the default under the other one mid-fit, which then ran some BLAS calls
        # threaded; its rounding, and on an ill-conditioned fit its optimum, changed from
        # run to run (arm_swing's acceleration GP: length scale 22.7883799659080 or ...108)
        starts = [None, None]
        if warm_start and hasattr(self, "kinematic_gp_") and self.estimator == "gp":
            starts = [
                {"length_scale": gp.length_scale_, "signal": gp.signal_, "noise": gp.noise_}
                for gp in (self.kinematic_gp_, self.acceleration_gp_)
            ]
        jobs = [
            (self._estimator(center).fit, X, Y, start)
            for (X, Y), start in zip(data, starts, strict=True)
        ]
        with threadpool_limits(limits=1, user_api="blas"):
            if self.fit_threads == 1:  # one after the other, in this thread
                fits = [fit(X, Y, initial=start) for fit, X, Y, start in jobs]
            else:
                with ThreadPoolExecutor(max_workers=self.fit_threads) as pool:
                    futures = [pool.submit(fit, X, Y, initial=start) for fit, X, Y, start in jobs]
                    fits = [f.result() for f in futures]
        self.kinematic_gp_, self.acceleration_gp_ = fits
        return self

    def _estimator(self, center: bool):
        if self.estimator == "mls":
            return MovingLeastSquares()
        return SharedGP(
            self.max_iterations, center=center, method=self.gp_method, input_scale=self.input_scale
        )

    def predict(self, source: SourceClip) -> tuple[Prediction, Prediction]:
        """The two GPs' predictions on a clip, in scaled channels (targets, not offsets)."""
        if not hasattr(self, "kinematic_gp_"):
            raise TargetError("this EditModel is not fitted: call fit(pairs, scale) first")
        kinematic, acceleration = source.features(self.joints)
        k = self.kinematic_gp_.predict(kinematic)
        a = self.acceleration_gp_.predict(acceleration[1:-1])
        if self.residual:
            scaled = self.scale.scaled(source.track)
            k = Prediction(k.mean + scaled, k.variance)
            a = Prediction(a.mean + accelerations(scaled), a.variance)
        return k, a

    def apply(
        self,
        source: SourceClip,
        weights: Weights | None = None,
        masked: np.ndarray | None = None,
        predictions: tuple[Prediction, Prediction] | None = None,
    ) -> TargetTrack:
        """The edited track of a new source clip: Eq. 12's banded solve per channel
        (``predictions`` from :meth:`predict`, to solve one clip with several weights)."""
        k, a = predictions or self.predict(source)
        scaled = self.scale.scaled(source.track)
        priors = (self.kinematic_gp_.prior_variance, self.acceleration_gp_.prior_variance)
        solution = combine(
            scaled,
            k.mean,
            k.variance,
            a.mean,
            a.variance,
            weights or self.weights,
            masked=masked,
            priors=priors,
        )
        return source.track.with_values(
            self.scale.unscaled(solution), source=f"{source.track.source} (propagated)"
        )


def _frame_mask(frames, track: TargetTrack) -> np.ndarray:
    n = track.n_frames
    if frames is None:
        return np.ones(n, dtype=bool)
    frames = np.asarray(frames)
    if frames.dtype == bool:
        if frames.shape != (n,):
            raise TargetError(f"{track.source}: a frame mask of {frames.shape} for {n} frames")
        return frames
    if frames.size and (frames.min() < 0 or frames.max() >= n):
        raise TargetError(f"{track.source}: example frames outside 0..{n - 1}")
    mask = np.zeros(n, dtype=bool)
    mask[frames.astype(int)] = True
    return mask


def _check_pair(source: TargetTrack, edited: TargetTrack) -> None:
    if edited.n_frames != source.n_frames:
        raise TargetError(
            f"example pair {source.source!r}: the edited clip has "
            f"{edited.n_frames} frames, the source {source.n_frames} (§3: "
            "source and target clips have the same number of frames)"
        )
    if edited.channels != source.channels:
        raise TargetError(
            f"example pair {source.source!r}: the edited clip's channels are "
            "not the source's (a different skeleton or rig)"
        )


EDIT_KIND, FORMAT_VERSION = "edit_model", 1
#: the arrays of an edit model (``kinematic_`` and ``acceleration_`` GPs each add theirs):
#: D target channels, J feature joints; values as the fit made them (float64)
EDIT_SCHEMA = {
    "channels": ("U", ("D",)),
    "std": ("f", ("D",)),
    "feature_joints": ("i", ("J",)),
    "heading_joints": ("i", (3,)),
    "residual": ("b", ()),
    "estimator": ("U", ()),
    "input_scale": ("U", ()),
    "max_iterations": ("i", ()),
    "weights": ("f", (4,)),
}
#: one GP's arrays, by estimator: N examples of F features (k MLS components)
GP_SCHEMA = {
    "gp": {
        "X_": ("f", ("N", "F")),
        "Y_": ("f", ("N", "D")),
        "x_mean_": ("f", ("F",)),
        "x_std_": ("f", ("F",)),
        "y_mean_": ("f", ("D",)),
        "factor": ("f", ("N", "N")),
        "alpha": ("f", ("N", "D")),
        "hyper": ("f", (5,)),
    },
    "mls": {
        "x_mean_": ("f", ("F",)),
        "x_std_": ("f", ("F",)),
        "basis_": ("f", ("F", "k")),
        "A_": ("f", ("N", "k")),
        "B_": ("f", ("N", "D")),
        "hyper": ("f", (4,)),
    },
}


def save_model(model: EditModel, path) -> None:
    """``<name>.npz`` of plain arrays, then ``<name>.json`` (kind, version, payload hash)
    beside it: arrays + JSON, read by :func:`load_model`; nothing is pickled."""
    arrays = {f"kinematic_{k}": v for k, v in model.kinematic_gp_.state().items()}
    arrays |= {f"acceleration_{k}": v for k, v in model.acceleration_gp_.state().items()}
    j, w = model.joints, model.weights
    arrays |= {
        "channels": np.array(model.scale.channels),
        "std": model.scale.std,
        "feature_joints": np.array(j.feature),
        "heading_joints": np.array([j.root, j.left, j.right]),
        "residual": np.array(model.residual),
        "estimator": np.array(model.estimator),
        "input_scale": np.array(model.input_scale),
        "max_iterations": np.array(model.max_iterations),
        "weights": np.array(
            [w.kinematic, w.kinematic_regularizer, w.acceleration, w.acceleration_regularizer]
        ),
    }
    path = Path(path)
    meta = {"kind": EDIT_KIND, "format_version": FORMAT_VERSION, "estimator": model.estimator}
    model_io.write_model_files(
        path.parent, path.stem, model_io.arrays_to_bytes(arrays), path.suffix, meta
    )


def load_model(path) -> EditModel:
    """An :class:`EditModel` saved by :func:`save_model` (``path``: its ``.npz``); every
    array checked against :data:`EDIT_SCHEMA`, a bad file one :class:`ModelFileError`."""
    path = Path(path)
    meta, payload = model_io.read_model_files(path.parent, path.stem, EDIT_KIND)
    where = str(path.with_suffix(".json"))
    estimator = meta.get("estimator")
    if meta.get("format_version") != FORMAT_VERSION or estimator not in GP_SCHEMA:
        raise ModelFileError(
            f"{where}: expected format_version {FORMAT_VERSION} and an estimator of "
            f"{sorted(GP_SCHEMA)}, got {meta.get('format_version')!r} and {estimator!r}"
        )
    gp = {
        f"{w}_{k}": v
        for w in ("kinematic", "acceleration")
        for k, v in GP_SCHEMA[estimator].items()
    }
    data = model_io.arrays_from_bytes(payload, where, [*EDIT_SCHEMA, *gp])
    sizes = model_io.check_arrays(data, EDIT_SCHEMA, where)
    for which in ("kinematic", "acceleration"):
        own = {k: v for k, v in gp.items() if k.startswith(which)}
        model_io.check_arrays(data, own, f"{where} ({which} GP)", {"D": sizes["D"]})
    if str(data["estimator"]) != estimator:
        raise ModelFileError(
            f"{where}: estimator {estimator!r} but the arrays say {str(data['estimator'])!r}"
        )
    return _model_from_arrays(data, estimator)


def _model_from_arrays(data: dict[str, np.ndarray], estimator: str) -> EditModel:
    root, left, right = (int(v) for v in data["heading_joints"])
    joints = FeatureJoints(tuple(int(v) for v in data["feature_joints"]), root, left, right)
    model = EditModel(
        joints,
        Weights(*(float(w) for w in data["weights"])),
        bool(data["residual"]),
        int(data["max_iterations"]),
        estimator=estimator,
        input_scale=str(data["input_scale"]),
    )
    model.scale = ChannelScale(tuple(str(c) for c in data["channels"]), data["std"].copy())
    kind = MovingLeastSquares if estimator == "mls" else SharedGP
    for which in ("kinematic", "acceleration"):
        state = {k[len(which) + 1 :]: data[k] for k in data if k.startswith(which)}
        setattr(model, f"{which}_gp_", kind.from_state(state))
    return model
