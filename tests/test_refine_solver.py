"""The batched Cholesky solver against the per-frame SVD one, on real rig problems (#16).

The problems are the drift test's: a few frames of a built-in rig's test
clips are the truth, their poses the targets, the start is the truth off by
half a training std per control, and steps are damped in training stds.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.animation.library import build_corpus
from rigmap.evaluation.metrics import control_std
from rigmap.refine import (
    ComputedJacobian,
    Damping,
    JacobianReuse,
    PredictedJacobian,
    chiaverini_damping,
    damped_least_squares,
    damped_solver,
    jacobian,
    rig_colouring,
    smallest_singular_value,
)
from rigmap.refine.block_cholesky import block_structure
from rigmap.refine.jacobian_reuse import anchor_frames, broyden_update

FRAMES = 4


class Problem:
    def __init__(self, rig):
        train = build_corpus(rig, "train", seed=0).table[rig.used_controls].to_numpy(float)
        test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
        self.rig = rig
        self.std = control_std(train)
        # consecutive frames, as refinement sees a clip
        self.truth = test[40 : 40 + FRAMES]
        rng = np.random.default_rng(0)
        self.start = self.truth + 0.5 * self.std * rng.standard_normal(self.truth.shape)
        self.target = rig.evaluate(rig.expand_used(self.truth))
        self.J = jacobian(rig, rig.expand_used(self.start)) * self.std  # ∂x/∂z

    def refine(self, **settings):
        settings.setdefault("source", ComputedJacobian(self.rig))
        return damped_least_squares(
            self.rig,
            settings.pop("start", self.start),
            settings.pop("target", self.target),
            settings.pop("source"),
            tolerance=1e-4,
            max_iterations=3,
            control_scale=self.std,
            keep_in_range=True,
            **settings,
        )


_PROBLEMS: dict[str, Problem] = {}


@pytest.fixture(params=["quadruped", "biped"])
def problem(request) -> Problem:
    rig = request.getfixturevalue(request.param)
    if rig.name not in _PROBLEMS:
        _PROBLEMS[rig.name] = Problem(rig)
    return _PROBLEMS[rig.name]


@pytest.mark.parametrize("damping", [Damping(0.3), Damping(None, 1.0, 1.0)])
def test_cholesky_step_is_the_svd_step(problem, damping):
    """To 1e-6 with a given λ; with the automatic one, as close as the λ estimate (~1e-3)."""
    residual = (
        problem.target - problem.rig.evaluate(problem.rig.expand_used(problem.start))
    ).reshape(FRAMES, -1)
    exact = damped_solver(problem.J, damping, "svd")
    cheap = damped_solver(problem.J, damping, "cholesky")
    close = 1e-6 if not damping.automatic else 5e-3
    np.testing.assert_allclose(cheap.damping, exact.damping, rtol=close)
    step = exact.solve(residual)
    assert np.abs(step).max() > 0.1  # a real step, in training stds
    np.testing.assert_allclose(cheap.solve(residual), step, atol=close * np.abs(step).max())
    rows = np.array([1, 3])  # a subset of the factorised frames
    np.testing.assert_allclose(
        cheap.solve(residual[rows], rows), step[rows], atol=close * np.abs(step).max()
    )


@pytest.mark.parametrize("damping", [Damping(0.3), Damping(None, 1.0, 1.0), Damping(0.0)])
def test_block_cholesky_step_is_the_svd_step(problem, damping):
    """The compact block solver (coloured Jacobian: exact zeros outside the pattern) = SVD."""
    colouring = rig_colouring(problem.rig)
    Y = problem.rig.expand_used(problem.start)
    J = jacobian(problem.rig, Y, differences="forward", colouring=colouring) * problem.std
    blocks, coupling = block_structure((J != 0).any(axis=0))
    assert len(blocks) >= 2 and len(coupling) < J.shape[2] // 3  # a real block structure
    covered = np.concatenate([c for _, c in blocks] + [coupling])
    assert len(covered) == len(set(covered.tolist()))  # every column in one place at most
    residual = (problem.target - problem.rig.evaluate(Y)).reshape(FRAMES, -1)
    exact = damped_solver(J, damping, "svd")
    block = damped_solver(J, damping, "block_cholesky")
    np.testing.assert_allclose(block.damping, exact.damping, rtol=1e-6)
    step = exact.solve(residual)
    assert np.abs(step).max() > 0.1
    np.testing.assert_allclose(block.solve(residual), step, atol=1e-6 * np.abs(step).max())
    rows = np.array([2, 0])
    np.testing.assert_allclose(
        block.solve(residual[rows], rows), step[rows], atol=1e-6 * np.abs(step).max()
    )


def test_block_structure_splits_disjoint_columns_and_couples_wide_ones():
    pattern = np.zeros((10, 6), dtype=bool)
    pattern[0:3, 0] = pattern[1:4, 1] = True  # one block (rows shared)
    pattern[5:8, 2] = True  # another
    pattern[:, 3] = True  # touches every row: coupling
    # column 4 is zero everywhere, column 5 touches row 9 alone
    pattern[9, 5] = True
    blocks, coupling = block_structure(pattern)
    assert coupling.tolist() == [3]
    found = sorted((r.tolist(), c.tolist()) for r, c in blocks)
    assert found == [([0, 1, 2, 3], [0, 1]), ([5, 6, 7], [2]), ([9], [5])]


@pytest.mark.parametrize("solver", ["cholesky", "block_cholesky"])
def test_batched_refinement_gives_the_per_frame_result(problem, solver):
    """Whole batch (Cholesky) = each frame alone (SVD, the original solver), to 1e-6.

    The Jacobian is the rig's exact one (autodiff): a finite difference divides the
    rig's rounding by its 1e-6 step, and a batch of another size rounds differently in
    the last bits on some CPUs (measured: 3e-6 apart after 3 iterations on the biped)."""
    exact = ComputedJacobian(problem.rig, method="autodiff", sparsity="coloured")
    batched = problem.refine(damping=0.3, solver=solver, source=exact)
    for frame in range(FRAMES):
        alone = problem.refine(
            damping=0.3,
            solver="svd",
            source=exact,
            start=problem.start[frame : frame + 1],
            target=problem.target[frame : frame + 1],
        )
        np.testing.assert_allclose(batched.Y_used[frame], alone.Y_used[0], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(
            batched.joint_error[frame], alone.joint_error[0], rtol=1e-6, atol=1e-6
        )
    assert batched.joint_error.mean() < 0.05 * batched.initial_joint_error.mean()


@pytest.mark.parametrize("solver", ["cholesky", "block_cholesky"])
def test_automatic_refinement_matches_the_svd_one(problem, solver):
    exact = problem.refine(damping="auto", solver="svd")
    cheap = problem.refine(damping="auto", solver=solver)
    np.testing.assert_allclose(cheap.Y_used, exact.Y_used, atol=1e-2)  # training stds
    np.testing.assert_allclose(cheap.joint_error, exact.joint_error, rtol=0.05, atol=1e-6)
    assert exact.rig_evaluations == cheap.rig_evaluations


def test_cheap_smallest_singular_value_gives_lambda_within_ten_percent(problem):
    """On the rig's Jacobians (σ_min = 0) and on well-posed parts of them (0 < σ_min < ε)."""
    used = np.flatnonzero(np.abs(problem.J).max(axis=(0, 1)) > 1e-3)
    strongest = used[np.argsort(-np.abs(problem.J[:, :, used]).sum(axis=(0, 1)))[:30]]
    for J in (problem.J, problem.J[:, :, strongest]):
        exact_sigma = np.linalg.svd(J, compute_uv=False)[:, -1]
        epsilon = 1.0 if exact_sigma.max() < 1e-6 else 2.0 * float(exact_sigma.max())
        Jt = torch.as_tensor(J)
        normal = torch.bmm(Jt.transpose(1, 2), Jt) + epsilon**2 * torch.eye(J.shape[2])
        sigma = smallest_singular_value(Jt, torch.linalg.cholesky(normal)).numpy()
        assert (sigma >= exact_sigma - 1e-9).all()  # an estimate from above
        exact_lambda = chiaverini_damping(exact_sigma, epsilon, 1.0)
        cheap_lambda = chiaverini_damping(sigma, epsilon, 1.0)
        assert exact_lambda.min() > 0.5  # the rule damps: not a trivial λ = 0 case
        np.testing.assert_allclose(cheap_lambda, exact_lambda, rtol=0.1)


def test_forward_differences_agree_with_central_ones(problem):
    Y = problem.rig.expand_used(problem.start[:2])
    central = jacobian(problem.rig, Y)
    forward = jacobian(problem.rig, Y, differences="forward", chunk=None)
    assert np.abs(forward - central).max() < 1e-4 * np.abs(central).max()
    source = ComputedJacobian(problem.rig, differences="forward")
    assert source(Y, problem.target[:2])[1] == 2 * (len(problem.rig.used_controls) + 1)


@pytest.mark.parametrize("update", ["keep", "broyden"])
def test_jacobian_reuse_spends_fewer_rig_evaluations_and_still_refines(problem, update):
    full = problem.refine(damping="auto")
    reuse = JacobianReuse(share_every=2, update=update)
    forward = ComputedJacobian(problem.rig, differences="forward")
    shared = problem.refine(damping="auto", source=forward, reuse=reuse)
    print(
        update,
        full.rig_evaluations,
        shared.rig_evaluations,
        full.joint_error.mean(),
        shared.joint_error.mean(),
        shared.initial_joint_error.mean(),
    )
    assert shared.rig_evaluations < 0.5 * full.rig_evaluations
    assert shared.joint_error.mean() < 0.5 * shared.initial_joint_error.mean()


def test_carried_jacobians_refine_a_clip_as_well_as_recomputed_ones_for_far_fewer_evaluations(
    problem,
):
    """``jacobian_update: carry`` on 12 consecutive frames of a real test clip.

    The start is a regressor-like guess: off by a bias shared along the clip plus a little
    jitter per frame. Refined in order, each frame from the previous frame's Jacobian and
    pose, the clip ends within 0.01 cm² (ours) of the full recompute's mean joint error, at
    under a quarter of its rig evaluations (on the wolf: 35 instead of 310 per frame).
    """
    rig, std = problem.rig, problem.std
    test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
    truth = test[40:52]
    rng = np.random.default_rng(0)
    start = truth + 0.3 * std * rng.standard_normal(std.shape)
    start += 0.1 * std * rng.standard_normal(truth.shape)
    target = rig.evaluate(rig.expand_used(truth))
    settings = dict(start=start, target=target, damping="auto", solver="block_cholesky")
    source = ComputedJacobian(rig, differences="forward", sparsity="coloured")
    full = problem.refine(source=source, **settings)
    carried = problem.refine(source=source, reuse=JacobianReuse(update="carry"), **settings)
    assert carried.rig_evaluations < 0.25 * full.rig_evaluations
    assert carried.joint_error.mean() < full.joint_error.mean() + 0.01
    assert carried.joint_error.mean() < 0.01 * carried.initial_joint_error.mean()
    np.testing.assert_array_equal(carried.initial_joint_error, full.initial_joint_error)
    assert carried.iterations.max() <= 3
    with pytest.raises(ValueError, match="share_every must be 1"):
        JacobianReuse(share_every=2, update="carry")


def test_broyden_update_is_exact_along_the_step():
    rng = np.random.default_rng(1)
    J, dy, dx = rng.normal(size=(3, 5, 4)), rng.normal(size=(3, 4)), rng.normal(size=(3, 5))
    dy[2] = 0.0
    updated = broyden_update(J, dy, dx)
    np.testing.assert_allclose(np.einsum("frc,fc->fr", updated[:2], dy[:2]), dx[:2])
    np.testing.assert_array_equal(updated[2], J[2])  # no step: unchanged
    orthogonal = np.array([dy[0, 1], -dy[0, 0], 0.0, 0.0])
    np.testing.assert_allclose(updated[0] @ orthogonal, J[0] @ orthogonal)


def test_anchor_frames_are_every_kth_and_each_frame_takes_the_nearest():
    anchors, nearest = anchor_frames(np.array([0, 1, 2, 3, 4, 5, 6, 9]), 3)
    np.testing.assert_array_equal(anchors, [0, 3, 6])
    np.testing.assert_array_equal(anchors[nearest], [0, 0, 3, 3, 3, 6, 6, 6])


def test_predicted_jacobian_is_factorised_once(problem):
    calls = []

    class Model:
        def predict(self, features):
            calls.append(len(features))
            return problem.J / problem.std

    source = PredictedJacobian(Model(), features=np.zeros((FRAMES, 1)))
    result = problem.refine(damping="auto", source=source)
    assert calls == [FRAMES] and result.iterations.max() >= 2
    assert result.rig_evaluations == FRAMES + int(result.iterations.sum())


def test_replayed_traces_give_the_eager_positions(problem):
    """Padded to a trace size (and split at the largest): the same positions, in order."""
    rig = problem.rig
    rng = np.random.default_rng(1)
    used = rig.controls.used_indices
    Y = np.repeat(rig.controls.defaults[None], 37, axis=0)
    Y[:, used] = rng.uniform(rig.controls.lower[used], rig.controls.upper[used], (37, len(used)))
    eager = rig.evaluate(Y)
    with rig.replaying_traces():
        replayed = rig.evaluate(Y)
        one = rig.evaluate(Y[5])
    np.testing.assert_allclose(replayed, eager, rtol=0, atol=1e-9)
    np.testing.assert_allclose(one, eager[5], rtol=0, atol=1e-9)
    assert not rig._replay  # the context restores eager evaluation


def test_a_traced_rig_gets_jacobian_chunks_of_its_preferred_size(problem):
    """While traces replay, finite differences send at most ``poses_per_call`` poses a call."""
    from rigmap.rigs.engine.torch_rig import TRACED_POSES_PER_CALL

    class Recording:
        def __init__(self, rig):
            self.rig, self.sizes = rig, []

        def evaluate(self, Y):
            self.sizes.append(len(Y))
            return self.rig.evaluate(Y)

        def __getattr__(self, name):
            return getattr(self.rig, name)

    rig = problem.rig
    assert rig.poses_per_call is None
    recording = Recording(rig)
    source = ComputedJacobian(recording, differences="forward", sparsity="coloured")
    Y = np.repeat(rig.controls.defaults[None], 40, axis=0)
    per_pose = source.cost_per_pose()  # probes the rig's pattern (its own evaluations)
    assert 40 * per_pose > TRACED_POSES_PER_CALL  # more than one call's worth
    recording.sizes.clear()
    with rig.replaying_traces():
        assert rig.poses_per_call == TRACED_POSES_PER_CALL
        traced, _ = source(Y, None)
    assert max(recording.sizes) <= TRACED_POSES_PER_CALL and len(recording.sizes) >= 2
    assert sum(recording.sizes) == 40 * per_pose
    np.testing.assert_allclose(traced, source(Y, None)[0], rtol=0, atol=1e-6)


def test_traced_block_refinement_is_the_eager_one(problem):
    source = ComputedJacobian(problem.rig, differences="forward", sparsity="coloured")
    eager = problem.refine(damping="auto", solver="block_cholesky", source=source)
    traced = problem.refine(damping="auto", solver="block_cholesky", source=source, traced=True)
    np.testing.assert_allclose(traced.Y_used, eager.Y_used, rtol=0, atol=1e-9)
    assert traced.rig_evaluations == eager.rig_evaluations
    assert traced.joint_error.mean() < 0.05 * traced.initial_joint_error.mean()


def test_refinement_runs_numpy_blas_on_its_thread_count(problem):
    """``threads`` pins numpy's BLAS threads too (a learned Jacobian's GPR product runs there)."""
    from threadpoolctl import threadpool_info

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    outside = blas_threads()
    assert outside, "numpy has no BLAS library threadpoolctl can see"
    seen = []

    class Recording(ComputedJacobian):
        def __call__(self, *args, **kwargs):
            seen.append(blas_threads())
            return super().__call__(*args, **kwargs)

    for threads, expected in ((1, 1), (None, None)):
        seen.clear()
        source = Recording(problem.rig, differences="forward", sparsity="coloured")
        problem.refine(damping="auto", solver="block_cholesky", source=source, threads=threads)
        assert seen, "the source was never called"
        wanted = [expected] * len(outside) if expected else outside
        assert all(counts == wanted for counts in seen), (threads, seen)
    assert blas_threads() == outside  # restored after the refinement
