"""The inductor-compiled structured pass against the step-by-step reference."""

from __future__ import annotations

import pytest
import torch
from torch.fx.experimental.proxy_tensor import make_fx

from rigmap.rigs import load
from rigmap.rigs.engine import torch_rig
from rigmap.rigs.engine.compiled import CompiledPass, elementwise_products
from rigmap.rigs.engine.structured import check_controls
from rigmap.rigs.engine.torch_rig import TorchRig

TOLERANCE = 1e-10
#: the compiled graphs' size here (ours: small, so a 5-row batch pads and an 11-row one chunks)
SIZE = 8


def _controls(rig, n: int, seed: int) -> torch.Tensor:
    return torch.as_tensor(check_controls(rig.controls, n, seed), dtype=torch.float64)


def _loss(pose, target: torch.Tensor) -> torch.Tensor:
    return ((pose.positions + pose.cog[:, None] - target) ** 2).mean()


@pytest.mark.parametrize("n", [5, SIZE, 11])
def test_compiled_poses_and_joint_loss_gradients_equal_the_reference(n):
    """One compile (quadruped, float64) serves the padded, exact and chunked batches."""
    rig = load("quadruped")
    Y = _controls(rig, n, 20 + n)
    target = (lambda p: p.positions + p.cog[:, None])(rig.reference_pose(_controls(rig, n, 40)))
    gradients = []
    for compiled in (True, False):
        Yg = Y.clone().requires_grad_(True)
        pose = rig.compiled_pose(Yg, SIZE) if compiled else rig.reference_pose(Yg)
        assert pose.positions.shape[0] == n
        (gradient,) = torch.autograd.grad(_loss(pose, target.detach()), Yg)
        gradients.append((pose, gradient))
    (got, got_gradient), (want, want_gradient) = gradients
    for a, b in zip(got, want, strict=True):
        torch.testing.assert_close(a.detach(), b.detach(), rtol=0, atol=TOLERANCE)
    assert want_gradient.abs().max() > 1e-3  # the loss moves with the controls
    torch.testing.assert_close(got_gradient, want_gradient, rtol=0, atol=TOLERANCE)


def test_the_switch_sends_small_nonempty_batches_to_the_compiled_pass(quadruped, monkeypatch):
    calls = []
    monkeypatch.setattr(
        TorchRig, "compiled_pose", lambda self, Y, size: calls.append(("compiled", len(Y)))
    )
    monkeypatch.setattr(
        TorchRig, "structured_pose", lambda self, Y: calls.append(("structured", len(Y)))
    )
    Y = _controls(quadruped, 6, 9)
    quadruped._pose_torch(Y)
    assert calls == [("structured", 6)]  # off by default
    monkeypatch.setattr(torch_rig, "COMPILED", True)
    quadruped._pose_torch(Y)
    quadruped._pose_torch(Y[:0])
    assert calls == [("structured", 6), ("compiled", 6), ("structured", 0)]


def test_a_compiled_pass_needs_a_positive_size(quadruped):
    with pytest.raises(ValueError, match="size must be at least 1"):
        CompiledPass(quadruped, 0)


def test_small_batched_products_become_elementwise_and_keep_their_values():
    """The 3 x 3 product is rewritten (equal to rounding), the 8-wide one stays a ``bmm``."""
    generator = torch.Generator().manual_seed(0)
    A, B = (torch.randn(6, 3, 3, dtype=torch.float64, generator=generator) for _ in range(2))
    C, D = (torch.randn(6, 8, 8, dtype=torch.float64, generator=generator) for _ in range(2))
    graph = make_fx(lambda a, b, c, d: (a @ b @ a[..., :1], c @ d))(A, B, C, D)
    assert elementwise_products(graph, 4) == 2
    kinds = [node.target for node in graph.graph.nodes if node.op == "call_function"]
    assert kinds.count(torch.ops.aten.bmm.default) == 1
    got = graph(A, B, C, D)
    torch.testing.assert_close(got[0], A @ B @ A[..., :1], rtol=0, atol=1e-14)
    torch.testing.assert_close(got[1], C @ D, rtol=0, atol=0)


def test_the_recorded_graph_does_not_depend_on_the_eager_passes_before_it(monkeypatch):
    """The structured pass builds tables per batch size on first use; recorded inside the
    graph they would give another graph (and a cold compile) in a process whose rig already
    ran eagerly at that size before. Both rigs here record the same code."""
    from rigmap.rigs.characters.quadruped import build_quadruped
    from rigmap.rigs.engine import compiled

    codes = []
    monkeypatch.setattr(compiled.torch, "compile", lambda graph, **_: codes.append(graph.code))
    fresh, used = build_quadruped(), build_quadruped()
    with torch.no_grad():
        used.structured_pose(_controls(used, SIZE, 1).float())  # the size it records at
    for rig in (fresh, used):
        CompiledPass(rig, SIZE).graph(torch.float32)
    assert len(codes) == 2 and codes[0] == codes[1]
