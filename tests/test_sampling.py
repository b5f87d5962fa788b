"""The six supersampling strategies compared with the corpus they were fitted on (Table 2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hydra.utils import instantiate
from omegaconf import OmegaConf
from scipy.spatial import cKDTree

from rigmap.app.objects import sampler_from_node, sampler_name
from rigmap.sampling import (
    SAMPLERS,
    GaussianMixtureSampler,
    MultivariateGaussianSampler,
    NoExtraSamples,
    PCAGaussianSampler,
    SamplerInputError,
    SamplerNotFittedError,
    UniformSampler,
    UnivariateGaussianSampler,
    available,
    clamp_to_limits,
    make_sampler,
)

CONF = Path(__file__).resolve().parents[1] / "conf" / "sampler"
N_CONTROLS = 12
N_CLUSTERS = 3


def animator_like_corpus(seed: int = 0, frames_per_cluster: int = 200) -> np.ndarray:
    """Three clusters of poses, each moving 12 controls through 3 shared latent factors.

    Like animation: controls move together (low rank, correlated), poses group
    by activity (clusters), plus a little independent jitter.
    """
    rng = np.random.default_rng(seed)
    clusters = []
    for _ in range(N_CLUSTERS):
        mixing = rng.normal(size=(3, N_CONTROLS))
        centre = 6.0 * rng.normal(size=N_CONTROLS)
        latent = rng.normal(size=(frames_per_cluster, 3))
        jitter = 0.05 * rng.normal(size=(frames_per_cluster, N_CONTROLS))
        clusters.append(centre + latent @ mixing + jitter)
    return np.concatenate(clusters)


@pytest.fixture(scope="module")
def corpus() -> np.ndarray:
    return animator_like_corpus()


def rng(seed: int = 1) -> np.random.Generator:
    return np.random.default_rng(seed)


def relative_error(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(estimate - truth) / np.linalg.norm(truth))


# --- each strategy ---------------------------------------------------------


def test_registry_lists_the_six_strategies_of_table_2():
    assert available() == [
        "none",
        "uniform",
        "univariate_gaussian",
        "multivariate_gaussian",
        "gmm",
        "pca_gaussian",
    ]
    for name, cls in SAMPLERS.items():
        assert isinstance(make_sampler(name), cls)
        assert cls.name == name


def test_none_gives_an_empty_draw_of_the_corpus_width(corpus):
    samples = NoExtraSamples().fit(corpus).sample(1000, rng())
    assert samples.shape == (0, N_CONTROLS)
    assert samples.dtype == np.float64


def test_uniform_within_corpus_range_reaches_its_edges(corpus):
    samples = UniformSampler().fit(corpus).sample(20_000, rng())
    low, high = corpus.min(axis=0), corpus.max(axis=0)
    assert samples.shape == (20_000, N_CONTROLS)
    assert (samples >= low).all() and (samples <= high).all()
    width = high - low
    np.testing.assert_array_less(samples.min(axis=0) - low, 0.01 * width)
    np.testing.assert_array_less(high - samples.max(axis=0), 0.01 * width)
    # flat: each tenth of the range holds about a tenth of the samples
    tenths = np.floor((samples - low) / width * 10).clip(0, 9)
    fractions = np.stack([(tenths == k).mean(axis=0) for k in range(10)])
    np.testing.assert_allclose(fractions, 0.1, atol=0.015)


def test_uniform_within_a_given_soft_range(corpus):
    lower = np.full(N_CONTROLS, -2.0)
    upper = np.linspace(1.0, 12.0, N_CONTROLS)
    sampler = UniformSampler(range="soft", lower=lower, upper=upper).fit(corpus)
    samples = sampler.sample(20_000, rng())
    assert (samples >= lower).all() and (samples <= upper).all()
    np.testing.assert_allclose(samples.mean(axis=0), (lower + upper) / 2, atol=0.1)
    np.testing.assert_allclose(samples.std(axis=0), (upper - lower) / np.sqrt(12), rtol=0.03)


def test_uniform_soft_range_errors_name_what_is_missing(corpus):
    with pytest.raises(SamplerInputError, match="range='soft' needs lower and upper"):
        UniformSampler(range="soft").fit(corpus)
    with pytest.raises(SamplerInputError, match=r"shape \(12,\), got shape \(3,\)"):
        UniformSampler(range="soft", lower=[0, 0, 0], upper=np.ones(N_CONTROLS)).fit(corpus)
    with pytest.raises(SamplerInputError, match="lower bound above upper bound"):
        UniformSampler(range="soft", lower=np.ones(N_CONTROLS), upper=np.zeros(N_CONTROLS)).fit(
            corpus
        )
    with pytest.raises(SamplerInputError, match="range must be one of"):
        UniformSampler(range="box").fit(corpus)


def test_univariate_gaussian_matches_per_control_mean_and_std(corpus):
    samples = UnivariateGaussianSampler().fit(corpus).sample(40_000, rng())
    std = corpus.std(axis=0, ddof=1)
    np.testing.assert_allclose(samples.mean(axis=0), corpus.mean(axis=0), atol=0.03 * std.max())
    np.testing.assert_allclose(samples.std(axis=0), std, rtol=0.02)
    # ... and ignores how controls move together, unlike the corpus
    corpus_correlation = np.corrcoef(corpus, rowvar=False)
    sample_correlation = np.corrcoef(samples, rowvar=False)
    off_diagonal = ~np.eye(N_CONTROLS, dtype=bool)
    assert np.abs(corpus_correlation[off_diagonal]).max() > 0.5
    assert np.abs(sample_correlation[off_diagonal]).max() < 0.03


def test_multivariate_gaussian_covariance_matches_the_corpus(corpus):
    samples = MultivariateGaussianSampler().fit(corpus).sample(50_000, rng())
    covariance = np.cov(corpus, rowvar=False)
    assert relative_error(np.cov(samples, rowvar=False), covariance) < 0.03
    np.testing.assert_allclose(
        samples.mean(axis=0), corpus.mean(axis=0), atol=0.05 * np.sqrt(covariance.diagonal()).max()
    )


def test_multivariate_gaussian_survives_a_singular_covariance(corpus):
    # a constant control and a control that is an exact copy of another
    degenerate = np.column_stack([corpus, np.full(len(corpus), 3.5), corpus[:, 0]])
    samples = MultivariateGaussianSampler().fit(degenerate).sample(5_000, rng())
    np.testing.assert_allclose(samples[:, N_CONTROLS], 3.5, atol=1e-9)
    np.testing.assert_allclose(samples[:, N_CONTROLS + 1], samples[:, 0], atol=1e-9)


def test_gmm_has_the_configured_number_of_components(corpus):
    assert GaussianMixtureSampler().n_components == 25  # the paper's value
    sampler = GaussianMixtureSampler(n_components=7, random_state=3).fit(corpus)
    assert sampler.n_components_ == 7
    assert sampler.means_.shape == (7, N_CONTROLS)
    assert sampler.weights_.shape == (7,)
    np.testing.assert_allclose(sampler.weights_.sum(), 1.0)
    assert sampler.mixture_.covariances_.shape == (7, N_CONTROLS, N_CONTROLS)


def test_gmm_with_three_components_finds_the_three_clusters(corpus):
    sampler = GaussianMixtureSampler(n_components=N_CLUSTERS, n_init=2).fit(corpus)
    true_centres = corpus.reshape(N_CLUSTERS, -1, N_CONTROLS).mean(axis=1)
    distance = np.linalg.norm(true_centres[:, None] - sampler.means_[None], axis=2)
    assert distance.min(axis=1).max() < 0.5  # corpus spread is ~6 per control
    np.testing.assert_allclose(np.sort(sampler.weights_), 1 / 3, atol=0.01)
    samples = sampler.sample(30_000, rng())
    assert relative_error(np.cov(samples, rowvar=False), np.cov(corpus, rowvar=False)) < 0.05


def test_strategies_fitted_on_the_corpus_keep_a_constant_control_constant(corpus):
    with_constant = np.column_stack([corpus, np.full(len(corpus), 0.75)])
    for sampler in (
        UnivariateGaussianSampler(),
        MultivariateGaussianSampler(),
        GaussianMixtureSampler(n_components=3),
        PCAGaussianSampler(),
        UniformSampler(),
    ):
        samples = sampler.fit(with_constant).sample(1_000, rng())
        np.testing.assert_allclose(samples[:, -1], 0.75, atol=1e-12, err_msg=repr(sampler))


@pytest.mark.parametrize("covariance_type", ["full", "tied", "diag", "spherical"])
def test_gmm_samples_every_covariance_type(corpus, covariance_type):
    sampler = GaussianMixtureSampler(n_components=3, covariance_type=covariance_type).fit(corpus)
    samples = sampler.sample(20_000, rng())
    assert samples.shape == (20_000, N_CONTROLS)
    np.testing.assert_allclose(samples.mean(axis=0), corpus.mean(axis=0), atol=0.3)


def test_pca_gaussian_samples_lie_closer_to_the_corpus_than_uniform_samples(corpus):
    tree = cKDTree(corpus)
    distances = {}
    for name in ("uniform", "pca_gaussian"):
        samples = make_sampler(name).fit(corpus).sample(4_000, rng())
        distances[name] = tree.query(samples)[0].mean()
    assert distances["pca_gaussian"] < 0.75 * distances["uniform"], distances


def test_pca_gaussian_whitened_offset_has_the_corpus_covariance(corpus):
    # Mixture of corpus frames plus N(0, scale² Σ): covariance Σ_frames + scale² Σ.
    scale = 0.5
    samples = PCAGaussianSampler(scale=scale).fit(corpus).sample(50_000, rng())
    expected = np.cov(corpus, rowvar=False, ddof=0) + scale**2 * np.cov(corpus, rowvar=False)
    assert relative_error(np.cov(samples, rowvar=False), expected) < 0.03


def test_pca_gaussian_raw_offset_is_isotropic_in_control_units(corpus):
    scale = 0.5
    sampler = PCAGaussianSampler(scale=scale, whiten=False).fit(corpus)
    np.testing.assert_allclose(sampler.offset_std_, scale)
    samples = sampler.sample(50_000, rng())
    expected = np.cov(corpus, rowvar=False, ddof=0) + scale**2 * np.eye(N_CONTROLS)
    assert relative_error(np.cov(samples, rowvar=False), expected) < 0.03


def test_pca_gaussian_with_zero_scale_returns_corpus_frames(corpus):
    samples = PCAGaussianSampler(scale=0.0).fit(corpus).sample(500, rng())
    distance, _ = cKDTree(corpus).query(samples)
    np.testing.assert_allclose(distance, 0.0, atol=1e-9)
    # every frame can be chosen: 500 draws from 600 frames hit many distinct ones
    assert len(np.unique(samples, axis=0)) > 300


@pytest.mark.parametrize("whiten", [True, False])
def test_pca_gaussian_keeps_controls_the_corpus_never_moves(corpus, whiten):
    with_constant = np.column_stack([corpus, np.full(len(corpus), -1.25)])
    samples = PCAGaussianSampler(whiten=whiten).fit(with_constant).sample(2_000, rng())
    np.testing.assert_allclose(samples[:, -1], -1.25, atol=1e-9)


def test_pca_gaussian_truncation_moves_frames_only_along_kept_axes(corpus):
    sampler = PCAGaussianSampler(scale=2.0, n_components=2).fit(corpus)
    assert sampler.components_.shape == (2, N_CONTROLS)
    samples = sampler.sample(2_000, rng())

    # Outside the kept plane a sample is exactly its chosen frame: the parts of
    # samples orthogonal to the plane coincide with those of corpus frames.
    def off_plane(Y):
        centred = Y - sampler.mean_
        return centred - (centred @ sampler.components_.T) @ sampler.components_

    distance, _ = cKDTree(off_plane(corpus)).query(off_plane(samples))
    np.testing.assert_allclose(distance, 0.0, atol=1e-9)
    in_plane_spread = ((samples - sampler.mean_) @ sampler.components_.T).std(axis=0)
    assert (in_plane_spread > 1.0).all()  # ... while they do move in the plane
    fraction = PCAGaussianSampler(n_components=0.9).fit(corpus)
    variance = np.linalg.svd(corpus - corpus.mean(0), compute_uv=False) ** 2
    needed = int(np.searchsorted(np.cumsum(variance) / variance.sum(), 0.9) + 1)
    assert fraction.components_.shape[0] == needed


# --- reproducibility --------------------------------------------------------


@pytest.mark.parametrize(
    "name", ["uniform", "univariate_gaussian", "multivariate_gaussian", "gmm", "pca_gaussian"]
)
def test_the_same_seed_draws_the_same_samples(corpus, name):
    options = {"n_components": 3} if name == "gmm" else {}
    first = make_sampler(name, **options).fit(corpus)
    second = make_sampler(name, **options).fit(corpus)
    np.testing.assert_array_equal(first.sample(300, rng(7)), second.sample(300, rng(7)))
    assert not np.array_equal(first.sample(300, rng(7)), first.sample(300, rng(8)))


# --- clamping ------------------------------------------------------------------


def test_clamping_counts_values_rows_and_controls():
    Y = np.array(
        [
            [0.0, 5.0, 0.5],  # one value too high
            [-2.0, 1.0, 3.0],  # one too low, one too high
            [0.2, 0.3, 0.4],  # inside
            [1.0, -1.0, 9.0],  # on the limits (not clamped) and one too high
        ]
    )
    lower = np.array([-1.0, -1.0, -np.inf])
    upper = np.array([1.0, 1.0, 2.0])
    result = clamp_to_limits(Y, lower, upper)
    assert result.n_values == 4
    assert result.n_rows == 3
    np.testing.assert_array_equal(result.per_control, [1, 1, 2])
    np.testing.assert_array_equal(
        result.values,
        [[0.0, 1.0, 0.5], [-1.0, 1.0, 2.0], [0.2, 0.3, 0.4], [1.0, -1.0, 2.0]],
    )
    assert Y[0, 1] == 5.0  # the input is untouched by default


def test_clamping_in_place_and_bad_limits():
    Y = np.array([[3.0, -3.0]])
    result = clamp_to_limits(Y, [-1, -1], [1, 1], copy=False)
    assert result.values is Y and Y.tolist() == [[1.0, -1.0]]
    with pytest.raises(SamplerInputError, match="lower bound above upper bound"):
        clamp_to_limits(Y, [2, 0], [1, 1])
    with pytest.raises(SamplerInputError, match=r"shape \(2,\), got shape \(3,\)"):
        clamp_to_limits(Y, [0, 0, 0], [1, 1])
    with pytest.raises(SamplerInputError, match="Y contains NaN"):
        clamp_to_limits(np.array([[np.nan, 0.0]]), [0, 0], [1, 1])


# --- bad input -----------------------------------------------------------------


@pytest.mark.parametrize("name", available())
def test_bad_corpora_get_clear_errors(name):
    sampler = make_sampler(name)
    with pytest.raises(SamplerInputError, match="corpus is empty"):
        sampler.fit(np.empty((0, 4)))
    with pytest.raises(SamplerInputError, match=r"2-D array .* got shape \(4,\)"):
        sampler.fit(np.zeros(4))
    with pytest.raises(SamplerInputError, match=r"got shape \(2, 3, 4\)"):
        sampler.fit(np.zeros((2, 3, 4)))
    bad = np.ones((30, 4))
    bad[17, 2] = np.nan
    with pytest.raises(SamplerInputError, match=r"NaN or infinity .*frame 17, control column 2"):
        sampler.fit(bad)
    with pytest.raises(SamplerInputError, match="must hold numbers"):
        sampler.fit(np.array([["a", "b"], ["c", "d"]]))


@pytest.mark.parametrize("name", available())
def test_bad_sample_requests_get_clear_errors(corpus, name):
    sampler = make_sampler(name, **({"n_components": 3} if name == "gmm" else {}))
    with pytest.raises(SamplerNotFittedError, match="call fit"):
        sampler.sample(10, rng())
    sampler.fit(corpus)
    with pytest.raises(SamplerInputError, match="must be >= 0, got -1"):
        sampler.sample(-1, rng())
    with pytest.raises(SamplerInputError, match="must be an integer"):
        sampler.sample(2.5, rng())
    with pytest.raises(SamplerInputError, match=r"numpy\.random\.Generator"):
        sampler.sample(10, 42)
    assert sampler.sample(0, rng()).shape == (0, N_CONTROLS)


def test_strategies_that_estimate_spread_need_two_frames():
    for cls in (UnivariateGaussianSampler, MultivariateGaussianSampler, PCAGaussianSampler):
        with pytest.raises(SamplerInputError, match="at least 2 corpus frames, got 1"):
            cls().fit(np.zeros((1, 3)))


def test_gmm_needs_as_many_frames_as_components(corpus):
    with pytest.raises(SamplerInputError, match="25 mixture components need at least 25"):
        GaussianMixtureSampler().fit(corpus[:10])
    with pytest.raises(SamplerInputError, match="covariance_type must be one of"):
        GaussianMixtureSampler(n_components=2, covariance_type="banded").fit(corpus)


def test_pca_gaussian_rejects_bad_hyper_parameters(corpus):
    with pytest.raises(SamplerInputError, match="scale must be a finite number >= 0"):
        PCAGaussianSampler(scale=-1.0).fit(corpus)
    with pytest.raises(SamplerInputError, match="n_components must be"):
        PCAGaussianSampler(n_components=1.5).fit(corpus)


def test_unknown_sampler_names_the_available_ones():
    with pytest.raises(KeyError, match=r"unknown sampler 'latin_hypercube'.*pca_gaussian"):
        make_sampler("latin_hypercube")
    with pytest.raises(TypeError, match=r"'uniform' .*unexpected keyword argument 'scale'"):
        make_sampler("uniform", scale=2.0)


# --- Hydra configs ----------------------------------------------------------------


@pytest.mark.parametrize("name", available())
def test_each_config_builds_its_strategy_with_the_class_defaults(name):
    config = OmegaConf.load(CONF / f"{name}.yaml")
    assert "name" not in config  # the class knows its name; the yaml does not restate it
    assert sampler_name(config) == name
    sampler = instantiate(config, _convert_="all")
    assert type(sampler) is SAMPLERS[name]
    assert sampler.get_params() == type(sampler)().get_params()
    assert type(sampler_from_node(**config)) is SAMPLERS[name]  # the app layer's door agrees


def test_config_target_must_match_its_name():
    with pytest.raises(ValueError, match=r"PCAGaussianSampler' is the 'pca_gaussian' sampler"):
        sampler_from_node("gmm", _target_="rigmap.sampling.PCAGaussianSampler")
    # Hydra's instantiate would get the class itself from _target_
    assert isinstance(
        sampler_from_node("gmm", _target_="rigmap.sampling.GaussianMixtureSampler", n_components=2),
        GaussianMixtureSampler,
    )


def test_the_library_make_sampler_refuses_a_config_node():
    with pytest.raises(TypeError, match=r"rigmap\.app\.objects\.sampler_from_node"):
        make_sampler("gmm", _target_="rigmap.sampling.GaussianMixtureSampler")
