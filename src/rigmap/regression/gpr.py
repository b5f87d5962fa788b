"""Gaussian process regression for the inverse rig mapping (paper §4.1-4.2).

The prediction is the regularised GP mean of Eq. 6,
``y* = K* (K + theta1 I)^-1 Y``, for every output at once. Fitting has two
parts, both from the paper:

- **length-scale line search** (§4.1.1): candidate values spaced regularly in
  log scale over a range; for each, 10 times train on a random half of the
  data and validate on the other half; keep the value with the lowest mean
  error;
- **greedy subsampling** (§4.2): start from the rest pose, add a few farthest
  points (Eq. 7), then repeatedly the point the current GP predicts worst
  (Eq. 10) until ``n_points`` are chosen.

The multiquadric Gram matrix is indefinite, so every solve is an LU
factorisation, with a least-squares fallback when the matrix is numerically
singular — never Cholesky.

The subsampling never refits from scratch. Adding support point ``p`` to a GP
is one step of Gaussian elimination on ``G = K + theta1 I`` over all
candidates: with ``u = G[:, p] - L (L[p] / d)`` the new column of the partial
``L D L^T`` factor and ``d_p = u[p]`` its (signed) pivot, every candidate's
residual updates as ``R -= u (R[p] / d_p)``. The residual at a candidate is
then exactly ``y - K_xS (K_SS + theta1 I)^-1 Y_S``, the error of Eq. 10. Each
addition costs ``O(N (m + D + C))`` for ``N`` candidates, ``m`` points so far,
``D`` inputs and ``C`` outputs; memory is ``8 N n_points`` bytes for the
factor, which is why ``max_candidates`` bounds ``N``.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
import scipy.linalg
from scipy.linalg import blas, lapack
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from rigmap.errors import RigmapError
from rigmap.regression.kernels import GramColumns, Kernel, MultiquadricKernel, kernel_from_dict
from rigmap.rigs.base import RigInputError

# A dimension whose spread is below this fraction of the largest one is centred
# but not scaled: scaling it would blow round-off noise up to unit variance.
_MIN_RELATIVE_STD = 1e-6
# LU solutions with a reciprocal condition number below this are not trusted.
_MIN_RCOND = 1e-13
# Below this the fitted model warns that its predictions may amplify round-off.
_WARN_RCOND = 1e-12
# A pivot this small relative to its kernel diagonal means the candidate is
# numerically a combination of the chosen points; it is skipped.
_PIVOT_TOLERANCE = 1e-12
_PREDICT_CHUNK = 8192


# --------------------------------------------------------------------------- errors
class RegressionInputError(RigInputError):
    """Inputs given to a regressor have the wrong shape or bad values."""


class ModelMismatchError(RigmapError, ValueError):
    """A saved model does not belong to the rig or data it is used with."""


class ModelFileError(RigmapError, ValueError):
    """A model folder is incomplete, corrupt or of another kind of model."""


# --------------------------------------------------------------------------- fingerprint
@dataclass(frozen=True)
class ModelFingerprint:
    """What a fitted model expects, so it refuses inputs or rigs it was not made for.

    ``control_names`` names the outputs (the rig's used controls for an inverse
    mapping); ``rig_name`` is the rig the training data came from. Both are
    optional: synthetic problems have neither.
    """

    input_dim: int
    output_dim: int
    rig_name: str | None = None
    control_names: tuple[str, ...] | None = None

    @classmethod
    def build(
        cls,
        input_dim: int,
        output_dim: int,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> ModelFingerprint:
        if control_names is not None:
            control_names = tuple(str(n) for n in control_names)
            if len(control_names) != output_dim:
                raise RegressionInputError(
                    f"control_names: expected {output_dim} names (one per output column), "
                    f"got {len(control_names)}"
                )
        return cls(int(input_dim), int(output_dim), rig_name, control_names)

    def describe(self, model: str) -> str:
        return f"{model} fitted for rig {self.rig_name!r}" if self.rig_name else model

    def check_inputs(self, X: Any, model: str) -> tuple[np.ndarray, bool]:
        """``X`` as a finite float64 ``(M, input_dim)`` array, and whether it was one row."""
        X = as_float_array(X, f"{self.describe(model)}: inputs")
        squeeze = X.ndim == 1
        if squeeze:
            X = X[None]
        if X.ndim != 2 or X.shape[1] != self.input_dim:
            raise RegressionInputError(
                f"{self.describe(model)}: expected inputs of shape (M, {self.input_dim}) "
                f"or ({self.input_dim},), got {tuple(np.shape(X))}"
            )
        check_finite(X, f"{self.describe(model)}: inputs")
        return X, squeeze

    def check_rig(self, rig: Any, source: str) -> None:
        """Raise unless ``rig`` (a Rig or a rig name) is the one this model was fitted for."""
        if rig is None:
            return
        name = rig if isinstance(rig, str) else getattr(rig, "name", None)
        if self.rig_name is not None and name != self.rig_name:
            raise ModelMismatchError(
                f"{source} was fitted for rig {self.rig_name!r}, but it is used with rig {name!r}"
            )
        rig_controls = None if isinstance(rig, str) else getattr(rig, "control_names", None)
        if rig_controls is not None and self.control_names is not None:
            missing = [n for n in self.control_names if n not in set(rig_controls)]
            if missing:
                raise ModelMismatchError(
                    f"{source} predicts controls the rig {name!r} does not have: {missing[:5]}"
                    f"{' …' if len(missing) > 5 else ''} ({len(missing)} of "
                    f"{len(self.control_names)})"
                )

    def to_dict(self) -> dict[str, Any]:
        return {
            "input_dim": self.input_dim,
            "output_dim": self.output_dim,
            "rig_name": self.rig_name,
            "control_names": list(self.control_names) if self.control_names else None,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelFingerprint:
        names = data.get("control_names")
        return cls(
            int(data["input_dim"]),
            int(data["output_dim"]),
            data.get("rig_name"),
            tuple(names) if names else None,
        )


def as_float_array(values: Any, where: str) -> np.ndarray:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise RegressionInputError(f"{where}: expected a numeric array, got {error}") from None
    if array.dtype.kind not in "fiub":
        raise RegressionInputError(f"{where}: expected numbers, got dtype {array.dtype}")
    return array.astype(np.float64, copy=False)


def check_finite(array: np.ndarray, where: str) -> None:
    if not np.isfinite(array).all():
        row, column = np.argwhere(~np.isfinite(array))[0][:2]
        raise RegressionInputError(
            f"{where} contain NaN or infinity (first at row {row}, column {column}); "
            "expected finite numbers"
        )


def check_training_data(X: Any, Y: Any, model: str) -> tuple[np.ndarray, np.ndarray]:
    """Finite 2-D ``X (N, D)`` and ``Y (N, C)`` with the same number of rows."""
    X = as_float_array(X, f"{model}.fit: inputs X")
    Y = as_float_array(Y, f"{model}.fit: targets Y")
    if Y.ndim == 1:
        Y = Y[:, None]
    if X.ndim != 2:
        raise RegressionInputError(f"{model}.fit: expected inputs X of shape (N, D), got {X.shape}")
    if Y.ndim != 2:
        raise RegressionInputError(
            f"{model}.fit: expected targets Y of shape (N, C) or (N,), got {Y.shape}"
        )
    if len(X) != len(Y):
        raise RegressionInputError(
            f"{model}.fit: X has {len(X)} rows but Y has {len(Y)}; expected one target row "
            "per input row"
        )
    if len(X) == 0 or X.shape[1] == 0 or Y.shape[1] == 0:
        raise RegressionInputError(
            f"{model}.fit: expected non-empty data, got X {X.shape} and Y {Y.shape}"
        )
    check_finite(X, f"{model}.fit: inputs X")
    check_finite(Y, f"{model}.fit: targets Y")
    return X, Y


# --------------------------------------------------------------------------- normalisation
def column_scale(values: np.ndarray, shared: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Mean and spread per column (or one spread for all columns when ``shared``)."""
    mean = values.mean(axis=0)
    if shared:
        spread = float(np.sqrt(np.mean((values - mean) ** 2)))
        std = np.full(values.shape[1], spread if spread > 0 else 1.0)
        return mean, std
    std = values.std(axis=0)
    floor = _MIN_RELATIVE_STD * float(std.max(initial=0.0))
    std = np.where((std > floor) & (std > 0), std, 1.0)
    return mean, std


# --------------------------------------------------------------------------- linear algebra
class Solution(NamedTuple):
    """Weights of Eq. 6, the solver that produced them and the LU's reciprocal condition."""

    weights: np.ndarray
    solver: str
    rcond: float


def solve_regularized(K: np.ndarray, Y: np.ndarray, regularization: float) -> Solution:
    """``(K + theta1 I)^-1 Y`` by LU; least squares when LU is numerically singular.

    With an indefinite kernel (multiquadric) ``+ theta1 I`` can also move a
    negative eigenvalue of ``K`` *onto* zero; the condition estimate catches
    that as well as plain rank deficiency.
    """
    A = K + regularization * np.eye(len(K))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        with np.errstate(all="ignore"):
            lu, pivots = scipy.linalg.lu_factor(A, check_finite=False)
            rcond, _ = lapack.dgecon(lu, float(np.abs(A).sum(axis=0).max()), norm="1")
            rcond = float(rcond) if np.isfinite(rcond) else 0.0
            if rcond > _MIN_RCOND:
                W = scipy.linalg.lu_solve((lu, pivots), Y, check_finite=False)
                if np.isfinite(W).all():
                    return Solution(W, "lu", rcond)
    W = scipy.linalg.lstsq(A, Y, cond=1e-12, check_finite=False)[0]
    return Solution(W, "lstsq", rcond)


# --------------------------------------------------------------------------- length-scale search
def length_scale_cv_errors(
    X: np.ndarray,
    Y: np.ndarray,
    kernel: Kernel,
    regularization: float,
    length_scales: np.ndarray,
    splits: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Mean validation error for each length scale (§4.1.1).

    The same ``splits`` random halves are used for every candidate so the
    comparison is not blurred by which half was drawn. The error is the mean
    squared error over the validation rows and the given output columns.
    """
    n = len(X)
    if n < 4:
        raise RegressionInputError(
            f"length-scale search needs at least 4 samples to split in halves, got {n}"
        )
    statistic = kernel.statistic(X, X)
    halves = [rng.permutation(n) for _ in range(splits)]
    errors = np.empty(len(length_scales))
    for i, length_scale in enumerate(length_scales):
        candidate = kernel.with_length_scale(float(length_scale))
        split_errors = []
        for order in halves:
            train, validate = order[: n - n // 2], order[n - n // 2 :]
            K_train = candidate.from_statistic(statistic[np.ix_(train, train)])
            K_validate = candidate.from_statistic(statistic[np.ix_(validate, train)])
            with np.errstate(all="ignore"):
                W = solve_regularized(K_train, Y[train], regularization).weights
                error = float(np.mean((K_validate @ W - Y[validate]) ** 2))
            split_errors.append(error if np.isfinite(error) else np.inf)
        errors[i] = float(np.mean(split_errors))
    return errors


# --------------------------------------------------------------------------- subsampling
@dataclass
class Subsample:
    """The chosen support rows (in the order picked) and the worst error at each greedy step."""

    indices: np.ndarray
    max_errors: np.ndarray
    skipped: int


def greedy_subsample(
    X: np.ndarray,
    Y: np.ndarray,
    kernel: Kernel,
    regularization: float,
    n_points: int,
    rest_index: int = 0,
    n_farthest: int = 10,
    progress: bool = False,
) -> Subsample:
    """§4.2 on (normalised) data: rest pose, farthest points (Eq. 7), worst-predicted (Eq. 10).

    See the module docstring for the incremental elimination that makes each
    addition cheap. Candidates whose pivot vanishes (duplicates of chosen
    points, to round-off) are skipped; the result then has fewer points only if
    every remaining candidate is such a duplicate.
    """
    n = len(X)
    target = min(int(n_points), n)
    factor = np.empty((n, target))
    pivots = np.empty(target)
    residual = np.asfortranarray(Y, dtype=np.float64).copy(order="F")  # for in-place BLAS ger
    kernel_column = GramColumns(kernel, X)
    available = np.ones(n, dtype=bool)
    nearest_sq = np.full(n, np.inf)  # squared distance to the closest chosen point
    chosen: list[int] = []
    max_errors: list[float] = []
    skipped = 0
    bar = tqdm(total=target, desc="GPR subsampling", unit="pt", disable=not progress, leave=False)
    while len(chosen) < target and available.any():
        step = len(chosen)
        worst_error = None
        if step == 0:
            index = rest_index
        elif step <= n_farthest:
            index = int(np.argmax(np.where(available, nearest_sq, -1.0)))
        else:
            errors = np.einsum("ij,ij->i", residual, residual)
            errors[~available] = -1.0
            index = int(np.argmax(errors))
            worst_error = float(np.sqrt(errors[index]))
        available[index] = False
        column = kernel_column(index)
        scale = abs(column[index]) + regularization
        column[index] += regularization
        if step:
            column -= factor[:, :step] @ (factor[index, :step] / pivots[:step])
        pivot = column[index]
        if not np.isfinite(pivot) or abs(pivot) <= _PIVOT_TOLERANCE * scale:
            skipped += 1
            continue
        factor[:, step] = column
        pivots[step] = pivot
        # residual -= column ⊗ residual[index] / pivot, in place
        blas.dger(-1.0 / pivot, column, residual[index].copy(), a=residual, overwrite_a=True)
        residual[index] = 0.0
        if step < n_farthest:
            delta = X - X[index]
            np.minimum(nearest_sq, np.einsum("ij,ij->i", delta, delta), out=nearest_sq)
        chosen.append(index)
        if worst_error is not None:
            max_errors.append(worst_error)
        bar.update(1)
    bar.close()
    return Subsample(np.asarray(chosen, dtype=np.int64), np.asarray(max_errors), skipped)


# --------------------------------------------------------------------------- model files
def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same folder and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, 0o644)  # mkstemp makes 0600; model files are for everyone to read
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_model_files(
    folder: str | os.PathLike, stem: str, payload: bytes, payload_suffix: str, meta: dict
) -> Path:
    """Payload first, then the JSON that names it and its hash (the JSON is the commit).

    A save interrupted between the two leaves a payload whose hash the old JSON
    does not match, which ``read_model_meta``/``read_payload`` report instead of
    loading mixed files.
    """
    folder = Path(folder)
    payload_path = folder / f"{stem}{payload_suffix}"
    write_atomic(payload_path, payload)
    meta = {**meta, "payload": payload_path.name, "payload_sha256": _sha256(payload)}
    write_atomic(folder / f"{stem}.json", (json.dumps(meta, indent=2) + "\n").encode())
    return folder


def read_model_files(folder: str | os.PathLike, stem: str, kind: str) -> tuple[dict, bytes]:
    """The JSON metadata and the verified payload bytes of a saved model."""
    folder = Path(folder)
    meta_path = folder / f"{stem}.json"
    if not meta_path.is_file():
        present = sorted(p.name for p in folder.glob("*.json")) if folder.is_dir() else []
        raise ModelFileError(
            f"{folder}: no {kind} model here (expected {meta_path.name}"
            f"{'; found ' + ', '.join(present) if present else ''})"
        )
    try:
        meta = json.loads(meta_path.read_text())
    except json.JSONDecodeError as error:
        raise ModelFileError(f"{meta_path}: not valid JSON ({error})") from None
    if meta.get("kind") != kind:
        raise ModelFileError(
            f"{meta_path}: field 'kind' is {meta.get('kind')!r}, expected {kind!r}"
        )
    payload_path = folder / str(meta.get("payload", ""))
    if not payload_path.is_file():
        raise ModelFileError(f"{meta_path}: its data file {payload_path.name!r} is missing")
    payload = payload_path.read_bytes()
    if _sha256(payload) != meta.get("payload_sha256"):
        raise ModelFileError(
            f"{payload_path}: contents do not match the hash in {meta_path.name} "
            "(an interrupted save, or files from two different models)"
        )
    return meta, payload


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def arrays_to_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    import io

    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def arrays_from_bytes(payload: bytes, where: str, names: Sequence[str]) -> dict[str, np.ndarray]:
    import io

    with np.load(io.BytesIO(payload), allow_pickle=False) as data:
        missing = [n for n in names if n not in data.files]
        if missing:
            raise ModelFileError(f"{where}: arrays {missing} are missing (have {data.files})")
        return {n: data[n] for n in names}


# --------------------------------------------------------------------------- the regressor
OutputScale = Literal["per_output", "shared"]


class GaussianProcessRegressor:
    """GPR inverse mapping: joint positions ``(N, D)`` -> controls ``(N, C)`` (§4.1-4.2).

    Parameters (the paper's values are the defaults):

    - ``kernel``: a ``rigmap.regression.kernels`` object (multiquadric, Eq. 1).
    - ``regularization``: ``theta1`` of Eq. 6, added to the Gram diagonal.
    - ``n_points``: support points kept by greedy subsampling; ``None`` keeps
      every training row (no subsampling).
    - ``search_length_scale``: run the §4.1.1 line search; if false the
      kernel's own ``length_scale`` is used.
    - ``length_scale_range``, ``n_length_scales``: candidates spaced regularly in
      log scale over the range (the paper's range is 1e-4..1e2 and says
      "regularly"; 25 values = 4 per decade is our choice). ``None``: the
      kernel's own ``search_range`` (the paper's for the multiquadric).
    - ``cv_splits``: random half-splits per candidate (10 in the paper).
    - ``search_points``: rows used by the search, drawn at random from the
      data; the paper does not say which set it cross-validates, and the
      subsampling already needs a length scale, so the search runs first on a
      random subset as large as the model (``None``: ``n_points``, or all rows).
    - ``cv_max_outputs``: output columns the CV error is measured on (a seeded
      random subset of the non-constant ones; ``None`` = all). Matters for the
      learned Jacobian's tens of thousands of outputs.
    - ``n_farthest``: farthest points added after the rest pose (Eq. 7; the
      paper's "several").
    - ``max_candidates``: rows the greedy step may pick from (a seeded random
      pool that always keeps the rest pose); bounds memory at
      ``8 * max_candidates * n_points`` bytes. ``None`` = every row.
    - ``normalize``: standardise inputs and outputs by mean and std (the GP
      mean then reverts to the data mean, not zero, far from the data).
    - ``output_scale``: ``"per_output"`` std, or one ``"shared"`` std for all
      outputs (for outputs of one kind, like Jacobian entries). Output scaling
      changes only the error used to choose points and length scales: the
      prediction is linear in ``Y``.
    - ``seed``: for the CV halves, the search subset and the candidate pool.
    - ``progress``: show a progress bar while subsampling.
    - ``fit_threads``: BLAS threads while fitting (``None``: the library's
      default). Fitting is hundreds of small LU solves and matrix-vector
      products, which one thread does faster than two on a busy 2-core machine
      (measured 10x); prediction is untouched and uses every thread.
    """

    name = "gpr"  # the regressor config group's choice
    kind = "gpr"
    file_stem = "gpr"

    def __init__(
        self,
        kernel: Kernel | None = None,
        regularization: float = 1e-5,
        n_points: int | None = 750,
        search_length_scale: bool = True,
        length_scale_range: Sequence[float] | None = None,
        n_length_scales: int = 25,
        cv_splits: int = 10,
        search_points: int | None = None,
        cv_max_outputs: int | None = 256,
        n_farthest: int = 10,
        max_candidates: int | None = 20_000,
        normalize: bool = True,
        output_scale: OutputScale = "per_output",
        seed: int = 0,
        progress: bool = False,
        fit_threads: int | None = 1,
    ):
        self.kernel = kernel
        self.regularization = regularization
        self.n_points = n_points
        self.search_length_scale = search_length_scale
        self.length_scale_range = length_scale_range
        self.n_length_scales = n_length_scales
        self.cv_splits = cv_splits
        self.search_points = search_points
        self.cv_max_outputs = cv_max_outputs
        self.n_farthest = n_farthest
        self.max_candidates = max_candidates
        self.normalize = normalize
        self.output_scale = output_scale
        self.seed = seed
        self.progress = progress
        self.fit_threads = fit_threads

    # ------------------------------------------------------------------ sklearn-style params
    _PARAM_NAMES = (
        "regularization",
        "n_points",
        "search_length_scale",
        "length_scale_range",
        "n_length_scales",
        "cv_splits",
        "search_points",
        "cv_max_outputs",
        "n_farthest",
        "max_candidates",
        "normalize",
        "output_scale",
        "seed",
        "progress",
        "fit_threads",
    )

    def get_params(self) -> dict[str, Any]:
        params = {name: getattr(self, name) for name in self._PARAM_NAMES}
        params["length_scale_range"] = [float(v) for v in self.search_range]
        params["kernel"] = self._kernel().to_dict()
        return params

    def __repr__(self) -> str:
        return (
            f"GaussianProcessRegressor(kernel={self._kernel()!r}, "
            f"regularization={self.regularization}, n_points={self.n_points})"
        )

    def _kernel(self) -> Kernel:
        return self.kernel if self.kernel is not None else MultiquadricKernel()

    @property
    def search_range(self) -> tuple[float, float]:
        """The length-scale search range: ``length_scale_range``, else the kernel's."""
        chosen = self.length_scale_range
        if chosen is None:
            chosen = getattr(self._kernel(), "search_range", MultiquadricKernel.search_range)
        low, high = chosen
        return float(low), float(high)

    def _check_params(self) -> None:
        if not isinstance(self._kernel(), Kernel):
            raise ValueError(
                f"GaussianProcessRegressor: kernel must be a rigmap.regression.kernels.Kernel, "
                f"got {type(self.kernel).__name__}"
            )
        if not (np.isfinite(self.regularization) and self.regularization >= 0):
            raise ValueError(
                f"GaussianProcessRegressor: regularization must be >= 0, got {self.regularization}"
            )
        if self.n_points is not None and int(self.n_points) < 1:
            raise ValueError(
                f"GaussianProcessRegressor: n_points must be >= 1, got {self.n_points}"
            )
        low, high = self.search_range
        if not (0 < low <= high and np.isfinite(high)):
            raise ValueError(
                "GaussianProcessRegressor: length_scale_range must be (low, high) with "
                f"0 < low <= high, got {(low, high)}"
            )
        if int(self.n_length_scales) < 1 or int(self.cv_splits) < 1:
            raise ValueError(
                "GaussianProcessRegressor: n_length_scales and cv_splits must be >= 1, got "
                f"{self.n_length_scales} and {self.cv_splits}"
            )
        if self.output_scale not in ("per_output", "shared"):
            raise ValueError(
                "GaussianProcessRegressor: output_scale must be 'per_output' or 'shared', "
                f"got {self.output_scale!r}"
            )

    # ------------------------------------------------------------------ fit
    def fit(
        self,
        X: Any,
        Y: Any,
        *,
        rest_index: int = 0,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> GaussianProcessRegressor:
        """Search the length scale, subsample, and solve for the weights.

        ``rest_index`` is the row of the rest pose, where subsampling starts.
        ``rig_name`` and ``control_names`` (one per column of ``Y``) are stored
        so the model later refuses other rigs.
        """
        self._check_params()
        X, Y2 = check_training_data(X, Y, "GaussianProcessRegressor")
        n = len(X)
        if not 0 <= int(rest_index) < n:
            raise RegressionInputError(
                f"GaussianProcessRegressor.fit: rest_index must be a row of X (0..{n - 1}), "
                f"got {rest_index}"
            )
        rng = np.random.default_rng(self.seed)
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y2.shape[1], rig_name, control_names)
        self._output_was_vector = np.ndim(Y) == 1

        if self.normalize:
            self.x_mean_, self.x_std_ = column_scale(X)
            self.y_mean_, self.y_std_ = column_scale(Y2, shared=self.output_scale == "shared")
        else:
            self.x_mean_, self.x_std_ = np.zeros(X.shape[1]), np.ones(X.shape[1])
            self.y_mean_, self.y_std_ = np.zeros(Y2.shape[1]), np.ones(Y2.shape[1])
        Xn = (X - self.x_mean_) / self.x_std_
        Yn = (Y2 - self.y_mean_) / self.y_std_
        with threadpool_limits(limits=self.fit_threads, user_api="blas"):
            self._fit_standardised(Xn, Yn, int(rest_index), rng)
        if self.rcond_ < _WARN_RCOND:
            warnings.warn(
                f"GaussianProcessRegressor: the support system is nearly singular (reciprocal "
                f"condition {self.rcond_:.1e}, solver {self.solver_}); predictions may be "
                "unstable — try another regularization or length-scale range",
                RuntimeWarning,
                stacklevel=2,
            )
        return self

    def _fit_standardised(
        self, Xn: np.ndarray, Yn: np.ndarray, rest_index: int, rng: np.random.Generator
    ) -> None:
        """Length-scale search, subsampling and the final solve, on standardised data."""
        n = len(Xn)
        kernel = self._kernel()
        target = n if self.n_points is None else min(int(self.n_points), n)
        clock = time.perf_counter()
        if self.search_length_scale:
            kernel = self._search(Xn, Yn, kernel, target, rng)
        else:
            self.length_scales_ = np.array([kernel.length_scale])
            self.cv_errors_ = np.array([np.nan])
        self.kernel_ = kernel
        self.length_scale_ = kernel.length_scale
        search_s, clock = time.perf_counter() - clock, time.perf_counter()

        if target >= n:
            order = np.r_[rest_index, np.delete(np.arange(n), rest_index)]
            self.support_indices_ = order.astype(np.int64)
            self.selection_errors_ = np.empty(0)
        else:
            pool = self._candidate_pool(n, rest_index, rng)
            subsample = greedy_subsample(
                Xn[pool],
                Yn[pool],
                kernel,
                self.regularization,
                target,
                rest_index=int(np.flatnonzero(pool == rest_index)[0]),
                n_farthest=int(self.n_farthest),
                progress=self.progress,
            )
            self.support_indices_ = pool[subsample.indices]
            self.selection_errors_ = subsample.max_errors
        subsample_s, clock = time.perf_counter() - clock, time.perf_counter()
        support = self.support_indices_
        if np.array_equal(support, np.arange(n)):  # every row, in order: no copies (Jacobians)
            self.support_inputs_, support_targets = Xn, Yn
        else:
            self.support_inputs_, support_targets = Xn[support], Yn[support]
        solution = solve_regularized(
            kernel(self.support_inputs_), support_targets, self.regularization
        )
        self.weights_, self.solver_, self.rcond_ = solution
        self.fit_seconds_ = {
            "length_scale_search": search_s,
            "subsampling": subsample_s,
            "solve": time.perf_counter() - clock,
        }

    def _search(
        self, Xn: np.ndarray, Yn: np.ndarray, kernel: Kernel, target: int, rng: np.random.Generator
    ) -> Kernel:
        low, high = self.search_range
        self.length_scales_ = np.geomspace(low, high, int(self.n_length_scales))
        size = min(len(Xn), int(self.search_points) if self.search_points else target)
        rows = np.sort(rng.choice(len(Xn), size=size, replace=False))
        columns = np.arange(Yn.shape[1])
        if self.cv_max_outputs is not None and len(columns) > int(self.cv_max_outputs):
            varying = np.flatnonzero(Yn.std(axis=0) > 0)
            pool = varying if len(varying) else columns
            count = min(len(pool), int(self.cv_max_outputs))
            columns = np.sort(rng.choice(pool, size=count, replace=False))
        self.cv_errors_ = length_scale_cv_errors(
            Xn[rows],
            Yn[np.ix_(rows, columns)],
            kernel,
            self.regularization,
            self.length_scales_,
            int(self.cv_splits),
            rng,
        )
        if not np.isfinite(self.cv_errors_).any():
            raise RuntimeError(
                "GaussianProcessRegressor: every length scale in "
                f"{self.search_range} gave a non-finite validation error"
            )
        best = float(self.length_scales_[int(np.nanargmin(self.cv_errors_))])
        return kernel.with_length_scale(best)

    def _candidate_pool(self, n: int, rest_index: int, rng: np.random.Generator) -> np.ndarray:
        if self.max_candidates is None or n <= int(self.max_candidates):
            return np.arange(n)
        others = np.delete(np.arange(n), rest_index)
        drawn = rng.choice(others, size=int(self.max_candidates) - 1, replace=False)
        return np.sort(np.r_[rest_index, drawn])

    # ------------------------------------------------------------------ predict
    def predict(self, X: Any) -> np.ndarray:
        """Eq. 6 for a batch ``(M, D)`` (or one ``(D,)`` row); chunked to bound memory."""
        self._check_fitted()
        X, squeeze = self.fingerprint_.check_inputs(X, "GaussianProcessRegressor")
        out = np.empty((len(X), self.fingerprint_.output_dim))
        for start in range(0, len(X), _PREDICT_CHUNK):
            Xn = (X[start : start + _PREDICT_CHUNK] - self.x_mean_) / self.x_std_
            out[start : start + _PREDICT_CHUNK] = (
                self.kernel_(Xn, self.support_inputs_) @ self.weights_
            )
        out *= self.y_std_
        out += self.y_mean_
        if self._output_was_vector:
            out = out[:, 0]
        return out[0] if squeeze else out

    def support_points(self) -> np.ndarray:
        """The chosen support poses in the caller's (unnormalised) units, in picking order."""
        self._check_fitted()
        return self.support_inputs_ * self.x_std_ + self.x_mean_

    def _check_fitted(self) -> None:
        if not hasattr(self, "weights_"):
            raise RuntimeError("GaussianProcessRegressor is not fitted: call fit(X, Y) first")

    # ------------------------------------------------------------------ save / load
    _ARRAY_NAMES = (
        "x_mean",
        "x_std",
        "y_mean",
        "y_std",
        "support_inputs",
        "support_indices",
        "weights",
        "length_scales",
        "cv_errors",
        "selection_errors",
    )

    def save(self, folder: str | os.PathLike) -> Path:
        """Write ``gpr.json`` and ``gpr.npz`` into ``folder`` (created if needed)."""
        meta, arrays = self.state()
        meta = {"kind": self.kind, "format_version": 1, **meta}
        return write_model_files(folder, self.file_stem, arrays_to_bytes(arrays), ".npz", meta)

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> GaussianProcessRegressor:
        """Read a saved model; with ``rig`` (a Rig or its name), refuse a model of another rig."""
        meta, payload = read_model_files(folder, cls.file_stem, cls.kind)
        source = f"GPR model in {folder}"
        ModelFingerprint.from_dict(meta["fingerprint"]).check_rig(rig, source)
        arrays = arrays_from_bytes(payload, source, cls._ARRAY_NAMES)
        return cls.from_state(meta, arrays, source)

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able metadata and the arrays of a fitted model (for models that embed a GPR)."""
        self._check_fitted()
        meta = {
            "params": self.get_params(),
            "kernel": self.kernel_.to_dict(),
            "fingerprint": self.fingerprint_.to_dict(),
            "output_was_vector": bool(self._output_was_vector),
            "solver": self.solver_,
            "rcond": float(self.rcond_),
            "length_scale": float(self.length_scale_),
        }
        arrays = {name: getattr(self, f"{name}_") for name in self._ARRAY_NAMES}
        return meta, arrays

    @classmethod
    def from_state(
        cls, meta: dict[str, Any], arrays: dict[str, np.ndarray], source: str
    ) -> GaussianProcessRegressor:
        """Rebuild a fitted model from ``state()``; array shapes must match the fingerprint."""
        try:
            fingerprint = ModelFingerprint.from_dict(meta["fingerprint"])
            params = dict(meta["params"])
            model = cls(kernel=kernel_from_dict(params.pop("kernel")), **params)
            model.kernel_ = kernel_from_dict(meta["kernel"])
            model.length_scale_ = float(meta["length_scale"])
            model.solver_ = str(meta["solver"])
            model.rcond_ = float(meta["rcond"])
            model._output_was_vector = bool(meta["output_was_vector"])
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        n_support = len(arrays["support_inputs"])
        expected = {
            "x_mean": (fingerprint.input_dim,),
            "x_std": (fingerprint.input_dim,),
            "y_mean": (fingerprint.output_dim,),
            "y_std": (fingerprint.output_dim,),
            "weights": (n_support, fingerprint.output_dim),
            "support_inputs": (n_support, fingerprint.input_dim),
        }
        for name, shape in expected.items():
            if arrays[name].shape != shape:
                raise ModelFileError(
                    f"{source}: array {name!r} has shape {arrays[name].shape}, expected {shape} "
                    "from the model's fingerprint"
                )
        model.fingerprint_ = fingerprint
        for name in cls._ARRAY_NAMES:
            setattr(model, f"{name}_", arrays[name])
        return model
