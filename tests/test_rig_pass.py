"""The structured rig pass against the step-by-step reference, on every built-in torch rig."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.rigs import load
from rigmap.rigs.engine import torch_rig
from rigmap.rigs.engine.builder import RigBuilder
from rigmap.rigs.engine.structured import StructuredPass, check_controls
from rigmap.rigs.engine.torch_rig import TorchRig
from rigmap.rigs.engine.transforms import Transform
from rigmap.rigs.features.chain_attributes import chain_attributes
from rigmap.rigs.features.fk_chain import fk_chain

#: every built-in rig evaluated by steps (face and squirrel are mesh rigs, another engine)
RIGS = ("quadruped", "biped")
TOLERANCE = 1e-10


def _controls(rig, n: int, seed: int) -> torch.Tensor:
    return torch.as_tensor(check_controls(rig.controls, n, seed), dtype=torch.float64)


def _positions(rig, Y: torch.Tensor, reference: bool) -> torch.Tensor:
    pose = rig.reference_pose(Y) if reference else rig.structured_pose(Y)
    return pose.positions + pose.cog[:, None]


@pytest.mark.parametrize("name", RIGS)
@pytest.mark.parametrize("seed", [0, 1])
def test_structured_poses_equal_the_reference(name, seed):
    rig = load(name)
    Y = _controls(rig, 9, seed)
    got, want = rig.structured_pose(Y), rig.reference_pose(Y)
    for a, b in zip(got, want, strict=True):
        assert a.shape == b.shape
        torch.testing.assert_close(a, b, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", RIGS)
def test_structured_pass_batches_the_repeated_units(name):
    """The limbs (left with right), the toes or fingers and the control objects run as groups."""
    structured = load(name).structured_pass
    kinds = {}
    for unit, size in zip(structured.units, structured.group_sizes, strict=True):
        step = unit.steps[0] if size > 1 else getattr(unit, "step", unit)
        kinds.setdefault(step.__qualname__.split(".")[0], []).append(size)
    assert kinds["limb"] == [2, 2]
    assert max(kinds["fk_chain"]) >= 8
    assert max(kinds["_world_of"]) >= 10
    assert len(structured.units) < len(load(name)._steps) / 2


@pytest.mark.parametrize("name", RIGS)
def test_autodiff_jacobians_equal_the_reference(name):
    rig = load(name)
    Y = _controls(rig, 2, 3)
    jacobians = [
        torch.autograd.functional.jacobian(
            lambda y, r=reference: _positions(rig, y, r), Y, vectorize=True
        )
        for reference in (False, True)
    ]
    assert jacobians[0].abs().max() > 1e-3  # the controls move the joints
    torch.testing.assert_close(jacobians[0], jacobians[1], rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", RIGS)
def test_finite_difference_jacobians_equal_the_reference(name):
    rig = load(name)
    y = _controls(rig, 1, 4)[0]
    used = torch.as_tensor(rig.controls.used_indices)
    step = 1e-5
    shifts = torch.zeros(len(used), y.shape[0], dtype=torch.float64)
    shifts[torch.arange(len(used)), used] = step
    Y = torch.cat([y + shifts, y - shifts])
    jacobians = []
    for reference in (False, True):
        with torch.no_grad():
            positions = _positions(rig, Y, reference)
        jacobians.append((positions[: len(used)] - positions[len(used) :]) / (2 * step))
    assert jacobians[0].abs().max() > 1e-3
    torch.testing.assert_close(jacobians[0], jacobians[1], rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", RIGS)
def test_joint_loss_gradient_through_the_structured_pass_matches_finite_differences(name):
    rig = load(name)
    Y = _controls(rig, 3, 5)
    target = _positions(rig, _controls(rig, 3, 6), reference=True).detach()

    def loss(y: torch.Tensor) -> torch.Tensor:
        return ((_positions(rig, y, reference=False) - target) ** 2).mean()

    Yg = Y.clone().requires_grad_(True)
    (gradient,) = torch.autograd.grad(loss(Yg), Yg)
    columns = np.random.default_rng(0).choice(rig.controls.used_indices, 12, replace=False)
    step = 1e-4  # central differences: truncation ~h², rounding of a loss of ~1e3 ~1e-13/h
    for column in columns:
        for row in range(Y.shape[0]):
            plus, minus = Y.clone(), Y.clone()
            plus[row, column] += step
            minus[row, column] -= step
            with torch.no_grad():
                numeric = (loss(plus) - loss(minus)) / (2 * step)
            assert float(gradient[row, column]) == pytest.approx(float(numeric), rel=1e-6, abs=1e-6)


def _two_chains(axes: tuple[str, str]) -> TorchRig:
    """Two layered chains that differ in a constant that cannot be folded (the bend axis)."""
    b = RigBuilder("chains", cog="root")
    b.transform_control("root", parent=None, group="root", used="tx ty tz rx ry rz")
    b.joint("root", None)
    for k, axis in enumerate(axes):
        layer = chain_attributes(b, f"c{k}", group="c", bend_axis=axis, side_axis="x")
        fk_chain(
            b,
            [f"c{k}_{i}" for i in range(3)],
            parent="root",
            positions=[(k * 5.0, 10.0 * i, 0.0) for i in range(3)],
            group="c",
            used="rx ry rz",
            layer=layer,
            tip=(k * 5.0, 30.0, 0.0),
            tip_name=f"c{k}_tip",
        )
    return TorchRig(b)


@pytest.mark.parametrize("axes", [("z", "z"), ("z", "y")])
def test_units_that_cannot_fold_run_alone_and_still_equal_the_reference(axes):
    rig = _two_chains(axes)
    sizes = StructuredPass(rig._steps, rig.controls).group_sizes
    assert (max(sizes) == 2) == (axes[0] == axes[1])
    Y = _controls(rig, 5, 7)
    for a, b in zip(rig.structured_pose(Y), rig.reference_pose(Y), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", RIGS)
def test_float32_poses_stay_within_rounding_of_the_reference(name):
    rig = load(name)
    Y = _controls(rig, 64, 8).float()
    for a, b in zip(rig.structured_pose(Y), rig.reference_pose(Y), strict=True):
        assert a.dtype == torch.float32
        torch.testing.assert_close(a, b, rtol=0, atol=1e-3)


def test_small_batches_run_by_structure_and_large_ones_and_traces_by_the_reference(
    quadruped, monkeypatch
):
    calls = []
    monkeypatch.setattr(TorchRig, "structured_pose", lambda self, Y: calls.append(len(Y)))
    Y = _controls(quadruped, torch_rig.STRUCTURED_MAX_POSES + 1, 9)
    quadruped._pose_torch(Y[:5])
    assert calls == [5]
    quadruped._pose_torch(Y)  # above the threshold: the reference, no call recorded
    monkeypatch.setattr(torch_rig, "STRUCTURED", False)
    quadruped._pose_torch(Y[:5])
    assert calls == [5]


def test_a_name_written_twice_keeps_the_reference_order():
    """Two steps of one kind that write the same transform must not be folded or swapped."""
    b = RigBuilder("twice", cog="root")
    b.transform_control("root", parent=None, group="root", used="tx ty tz")
    b.joint("root", None)
    b.joint("marker", "root")
    b.set_rest("marker", (2.0, 0.0, 0.0))

    def carry(offset: float):
        def step(ctx) -> None:
            host = ctx.xf["root"]
            ctx.xf["marker"] = Transform(host.R, host.apply(ctx.const([offset, 0.0, 0.0])))

        return step

    b.step(carry(1.0))
    b.step(carry(2.0))
    rig = TorchRig(b)
    assert max(rig.structured_pass.group_sizes) == 1
    Y = _controls(rig, 4, 10)
    got = rig.structured_pose(Y).positions
    torch.testing.assert_close(got, rig.reference_pose(Y).positions, rtol=0, atol=0)
    torch.testing.assert_close(got[:, 1, 0], torch.full((4,), 2.0, dtype=torch.float64))
