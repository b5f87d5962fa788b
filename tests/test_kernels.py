"""Kernels: Gram matrices against their formulas, stability, parameters and round trips."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.regression.kernels import (
    GaussianKernel,
    GramColumns,
    LinearKernel,
    MultiquadricKernel,
    PolynomialKernel,
    kernel_classes,
    kernel_from_dict,
    squared_distances,
)

FORMULAS = {
    "multiquadric": lambda a, b, k: np.sqrt(np.sum((a - b) ** 2) + k.length_scale**2),
    "gaussian": lambda a, b, k: np.exp(-np.sum((a - b) ** 2) / (2 * k.length_scale**2)),
    "linear": lambda a, b, k: a @ b / k.length_scale**2 + k.offset,
    "polynomial": lambda a, b, k: (a @ b / k.length_scale**2 + k.offset) ** k.degree,
}

ALL_KERNELS = [
    MultiquadricKernel(0.7),
    GaussianKernel(1.3),
    LinearKernel(2.0, offset=0.5),
    PolynomialKernel(1.5, degree=3, offset=1.0),
]


@pytest.mark.parametrize("kernel", ALL_KERNELS, ids=lambda k: k.name)
def test_gram_matrix_matches_the_formula_pair_by_pair(kernel):
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=(6, 4)), rng.normal(size=(5, 4))
    expected = np.array([[FORMULAS[kernel.name](a, b, kernel) for b in B] for a in A])
    np.testing.assert_allclose(kernel(A, B), expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(kernel.diag(A), np.diag(kernel(A)), rtol=1e-12)
    np.testing.assert_allclose(kernel.from_statistic(kernel.statistic(A, B)), kernel(A, B))


def test_squared_distances_never_negative_for_far_away_near_duplicates():
    # Rows far from the origin and 1e-9 apart: the norm expansion cancels
    # catastrophically, and must be clipped at zero rather than go negative.
    rng = np.random.default_rng(1)
    base = 1e4 + rng.normal(size=(1, 30))
    A = base + 1e-9 * rng.normal(size=(50, 30))
    direct = ((A[:, None, :] - A[None, :, :]) ** 2).sum(axis=2)
    for B in (A, A.copy()):  # the same array, and an equal copy
        D2 = squared_distances(A, B)
        assert D2.min() >= 0.0
        np.testing.assert_allclose(D2, direct, rtol=0, atol=1e-20)
    K = MultiquadricKernel(1e-4)(A)
    np.testing.assert_array_equal(np.diag(K), 1e-4)
    np.testing.assert_allclose(K, np.sqrt(direct + 1e-8), rtol=1e-12)


def test_multiquadric_gram_matrix_is_indefinite_so_cholesky_fails():
    rng = np.random.default_rng(2)
    K = MultiquadricKernel(0.5)(rng.normal(size=(20, 3)))
    eigenvalues = np.linalg.eigvalsh(K)
    assert (eigenvalues > 0).sum() == 1  # conditionally positive definite: one positive
    assert (eigenvalues < 0).sum() == 19
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(K + 1e-5 * np.eye(20))


def test_with_length_scale_returns_a_new_kernel_and_keeps_other_parameters():
    kernel = PolynomialKernel(1.0, degree=4, offset=2.0)
    other = kernel.with_length_scale(0.25)
    assert other.length_scale == 0.25 and kernel.length_scale == 1.0
    assert (other.degree, other.offset) == (4, 2.0)
    assert type(other) is PolynomialKernel


@pytest.mark.parametrize("kernel", ALL_KERNELS, ids=lambda k: k.name)
def test_dict_round_trip(kernel):
    data = kernel.to_dict()
    assert data["name"] == kernel.name
    assert kernel_from_dict(data) == kernel


def test_every_kernel_is_known_by_name():
    names = {"gaussian", "linear", "multiquadric", "polynomial", "sum", "scale"}
    assert names <= set(kernel_classes())
    assert kernel_from_dict({"name": "gaussian", "length_scale": 2}) == GaussianKernel(2.0)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: MultiquadricKernel(0.0), "length_scale must be a positive number"),
        (lambda: GaussianKernel(-1.0), "length_scale must be a positive number"),
        (lambda: GaussianKernel(float("nan")), "length_scale must be a positive number"),
        (lambda: PolynomialKernel(degree=0), "degree must be an integer >= 1"),
        (lambda: PolynomialKernel(degree=2.5), "degree must be an integer >= 1"),
        (lambda: LinearKernel(offset=-1.0), "offset must be a number >= 0"),
        (lambda: kernel_from_dict({"name": "laplace"}), "unknown kernel 'laplace'"),
        (
            lambda: kernel_from_dict({"name": "gaussian", "degree": 2}),
            "it takes \\['length_scale'\\]",
        ),
        (lambda: kernel_from_dict({"length_scale": 1.0}), "no 'name' field"),
    ],
)
def test_bad_parameters_are_named(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_numpy_and_integer_parameters_become_plain_floats():
    kernel = MultiquadricKernel(np.float32(0.5))
    assert type(kernel.length_scale) is float
    assert PolynomialKernel(degree=np.int64(3)).degree == 3


@pytest.mark.parametrize("kernel", ALL_KERNELS, ids=lambda k: k.name)
def test_gram_columns_match_the_full_gram_matrix(kernel):
    rng = np.random.default_rng(3)
    A = rng.normal(size=(40, 5)) + 3.0
    columns = GramColumns(kernel, A)
    full = kernel(A)
    for i in (0, 17, 39):
        np.testing.assert_allclose(columns(i), full[:, i], rtol=1e-12, atol=1e-12)
