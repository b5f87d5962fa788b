"""What every supersampling strategy shares: the estimator contract and input checks.

A sampler learns a distribution over the *used* controls from the animator
corpus (``fit``) and draws new control vectors from it (``sample``); the rig
then turns them into poses (paper §5.2). Hyper-parameters live in ``__init__``
and are only stored there (scikit-learn style), so a Hydra config maps one to
one onto a sampler and ``get_params`` can record it next to the samples.
"""

from __future__ import annotations

import inspect
from typing import ClassVar

import numpy as np

from rigmap.errors import RigmapError

# Variances below this fraction of the largest are round-off: the corpus does
# not move along that direction at all.
RELATIVE_RANK_TOLERANCE = 1e-12


class SamplerInputError(RigmapError, ValueError):
    """A corpus, a sample count or a random generator a sampler cannot use."""


class SamplerNotFittedError(RigmapError, RuntimeError):
    """``sample`` was called before ``fit``."""


class Sampler:
    """Base class: validates input, then defers to ``_fit`` / ``_sample``.

    Fitted attributes end in an underscore; ``n_controls_`` is the number of
    used controls the sampler was fitted on.
    """

    #: the one name: the ``sampler`` config choice, the samples file's stem, the model id part
    name: ClassVar[str] = ""
    #: Fewest corpus frames the strategy can estimate its model from.
    min_corpus_frames: ClassVar[int] = 1
    #: row of the paper's Table 2 (the built-in strategies' order); ``None`` for others
    paper_row: ClassVar[int | None] = None
    #: the label reports print (rigmap.catalog); ``None``: the name
    title: ClassVar[str | None] = None
    #: a strategy the paper does not have (the report marks its row)
    extra: ClassVar[bool] = False

    def __init__(self) -> None:
        """No hyper-parameters (strategies that have some store them, scikit-learn style)."""

    def fit(self, Y_corpus) -> Sampler:
        """Learn the strategy's model from ``(N, C_used)`` corpus control values."""
        corpus = check_corpus(Y_corpus, type(self).__name__, self.min_corpus_frames)
        self._fit(corpus)
        self.n_controls_ = corpus.shape[1]
        return self

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``(n, C_used)`` float64 control vectors drawn with ``rng``."""
        if not hasattr(self, "n_controls_"):
            raise SamplerNotFittedError(
                f"{type(self).__name__} is not fitted yet; call fit(Y_corpus) before sample()"
            )
        n = check_count(n, type(self).__name__)
        if not isinstance(rng, np.random.Generator):
            raise SamplerInputError(
                f"{type(self).__name__}.sample: rng must be a numpy.random.Generator "
                f"(e.g. numpy.random.default_rng(seed)), got {type(rng).__name__}"
            )
        samples = np.ascontiguousarray(self._sample(n, rng), dtype=np.float64)
        if samples.ndim != 2 or samples.shape[1] != self.n_controls_:
            raise RuntimeError(
                f"{type(self).__name__} drew shape {samples.shape}, "
                f"expected (n, {self.n_controls_}): a bug in the strategy"
            )
        return samples

    def get_params(self) -> dict:
        """The ``__init__`` hyper-parameters and their current values."""
        signature = inspect.signature(type(self).__init__)
        return {
            name: getattr(self, name)
            for name, parameter in signature.parameters.items()
            if name != "self" and parameter.kind is not inspect.Parameter.VAR_KEYWORD
        }

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={_short_repr(v)}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({params})"

    # --- for subclasses ---------------------------------------------------
    def _fit(self, corpus: np.ndarray) -> None:
        raise NotImplementedError

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError


class CorpusGaussianSampler(Sampler):
    """A Gaussian around the corpus mean: unit normal draws spread by ``_spread``, then
    shifted by the mean. The univariate and multivariate strategies differ only in the
    spread (per-control standard deviations, or a factor of the full covariance)."""

    min_corpus_frames = 2

    def _fit(self, corpus: np.ndarray) -> None:
        self.mean_ = corpus.mean(axis=0)
        self._fit_spread(corpus)

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        samples = self._spread(rng.standard_normal((n, self.mean_.size)))
        samples += self.mean_
        return samples

    def _fit_spread(self, corpus: np.ndarray) -> None:
        raise NotImplementedError

    def _spread(self, draws: np.ndarray) -> np.ndarray:
        """``(n, C)`` unit normal draws as offsets from the mean (may reuse ``draws``)."""
        raise NotImplementedError


def sampler_classes() -> list[type[Sampler]]:
    """Every imported sampler class that has a ``name`` (built-in ones and any other)."""
    found, pending = [], list(Sampler.__subclasses__())
    while pending:
        cls = pending.pop(0)
        pending += cls.__subclasses__()
        if cls.name:
            found.append(cls)
    return found


def check_corpus(Y_corpus, who: str, min_frames: int = 1) -> np.ndarray:
    """The corpus as a finite ``(N, C)`` float64 array with at least ``min_frames`` rows."""
    Y = np.asarray(Y_corpus)
    if Y.dtype.kind not in "fiu":
        raise SamplerInputError(
            f"{who}.fit: corpus must hold numbers (used-control values), got dtype {Y.dtype}"
        )
    if Y.ndim != 2:
        hint = " (one frame? pass Y[None])" if Y.ndim == 1 else ""
        raise SamplerInputError(
            f"{who}.fit: corpus must be a 2-D array (frames, used controls), "
            f"got shape {Y.shape}{hint}"
        )
    n_frames, n_controls = Y.shape
    if n_frames == 0:
        raise SamplerInputError(f"{who}.fit: corpus is empty (0 frames, shape {Y.shape})")
    if n_controls == 0:
        raise SamplerInputError(f"{who}.fit: corpus has no controls (shape {Y.shape})")
    if n_frames < min_frames:
        raise SamplerInputError(
            f"{who}.fit: needs at least {min_frames} corpus frames, got {n_frames}"
        )
    Y = np.asarray(Y, dtype=np.float64)
    if not np.isfinite(Y).all():
        row, column = np.argwhere(~np.isfinite(Y))[0]
        raise SamplerInputError(
            f"{who}.fit: corpus contains NaN or infinity "
            f"(first at frame {row}, control column {column}: {Y[row, column]})"
        )
    return Y


def check_count(n, who: str) -> int:
    """A non-negative integer number of samples."""
    if isinstance(n, bool) or not isinstance(n, int | np.integer):
        raise SamplerInputError(
            f"{who}: number of samples must be an integer >= 0, got {n!r} ({type(n).__name__})"
        )
    if n < 0:
        raise SamplerInputError(f"{who}: number of samples must be >= 0, got {n}")
    return int(n)


def check_bounds(values, n_controls: int, what: str, who: str) -> np.ndarray:
    """A ``(C,)`` float64 vector of per-control bounds (infinity allowed, NaN not)."""
    if values is None:
        raise SamplerInputError(f"{who}: {what} is required, got None")
    array = np.asarray(values, dtype=np.float64)
    if array.shape != (n_controls,):
        raise SamplerInputError(
            f"{who}: {what} must have one value per used control, shape ({n_controls},), "
            f"got shape {array.shape}"
        )
    if np.isnan(array).any():
        column = np.flatnonzero(np.isnan(array))[0]
        raise SamplerInputError(f"{who}: {what} contains NaN (first at control column {column})")
    return array


def check_lower_upper(lower: np.ndarray, upper: np.ndarray, who: str) -> None:
    bad = np.flatnonzero(lower > upper)
    if bad.size:
        i = bad[0]
        raise SamplerInputError(
            f"{who}: lower bound above upper bound for {bad.size} control(s), "
            f"first at column {i}: lower {lower[i]} > upper {upper[i]}"
        )


def sign_convention(components: np.ndarray) -> np.ndarray:
    """Flip each row so its largest-magnitude entry is positive.

    Eigen/singular vectors are defined up to sign; fixing it keeps the samples
    drawn from a seed the same whichever LAPACK produced the vectors.
    """
    largest = np.argmax(np.abs(components), axis=1)
    signs = np.sign(components[np.arange(len(components)), largest])
    signs[signs == 0] = 1.0
    return components * signs[:, None]


def _short_repr(value) -> str:
    if isinstance(value, np.ndarray):
        return f"array(shape={value.shape})"
    return repr(value)
