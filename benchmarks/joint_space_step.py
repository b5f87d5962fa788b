"""The joint-space fit's step through the rig: reference, structured and compiled; prints JSON.

One step of ``JointSpaceNetworkRegressor``'s joint-space phase, as it runs: a
``SquashedNetwork`` (2 x 512 ReLU, the conf/regressor/nn_joint_space defaults, float32)
maps 128 rows of joint positions to controls, the rig poses them, the mean squared joint
error goes back through the rig and the network, and the fit's fused Adam steps. Per rig and engine
(``reference``: ``STRUCTURED`` off; ``structured``: the default; ``compiled``:
``COMPILED`` on, :mod:`rigmap.rigs.engine.compiled`), the engines alternating in one process
on one torch thread, the median of ``--repeats``; also the rig alone (forward and backward
of the positions' sum) at 128 rows float32 and 100 rows float64, and each compiled graph's
first call (recording plus inductor's compile, cold or from its on-disk cache).

    PYTHONPATH=src .venv/bin/python benchmarks/joint_space_step.py [--rigs quadruped] [--repeats 15]
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from contextlib import contextmanager

import numpy as np
import torch

from rig_pass import BUILDERS, run_cli  # benchmarks/: the rig-pass benchmarks' front end
from rigmap.regression.joint_space_network import SquashedNetwork
from rigmap.regression.network import _adam
from rigmap.rigs.engine import torch_rig
from rigmap.rigs.engine.structured import check_controls

ENGINES = ("reference", "structured", "compiled")


@contextmanager
def engine(name: str):
    """Every pass inside runs the named engine through ``TorchRig``'s switches."""
    before = torch_rig.STRUCTURED, torch_rig.COMPILED
    torch_rig.STRUCTURED, torch_rig.COMPILED = name != "reference", name == "compiled"
    try:
        yield
    finally:
        torch_rig.STRUCTURED, torch_rig.COMPILED = before


def timed(runs: dict[str, Callable[[], None]], repeats: int) -> dict:
    """Median ms of each engine's run, alternating, after one untimed warm-up each (whose
    time is reported as ``first_call_s``: it holds the compiled engine's compile)."""
    samples: dict[str, list[float]] = {name: [] for name in runs}
    first = {}
    for name, run in runs.items():
        with engine(name):
            started = time.perf_counter()
            run()
            first[name] = round(time.perf_counter() - started, 2)
    for _ in range(repeats):
        for name, run in runs.items():
            with engine(name):
                started = time.perf_counter()
                run()
                samples[name].append(time.perf_counter() - started)
    medians = {name: statistics.median(s) for name, s in samples.items()}
    out = {f"{name}_ms": round(1e3 * m, 3) for name, m in medians.items()}
    out["first_call_s"] = first
    for name in runs:
        if name != "reference":
            out[f"{name}_speedup"] = round(medians["reference"] / medians[name], 2)
    if "compiled" in runs:
        out["compiled_over_structured"] = round(medians["structured"] / medians["compiled"], 2)
    return out


def rig_alone(rig, Y: np.ndarray, dtype: torch.dtype, name: str) -> Callable[[], None]:
    def run() -> None:
        y = torch.as_tensor(Y, dtype=dtype).requires_grad_(True)
        pose = rig.compiled_pose(y, len(Y)) if name == "compiled" else rig._pose_torch(y)
        pose.positions.sum().backward()

    return run


def fit_step(rig, Y: np.ndarray) -> Callable[[], None]:
    """One joint-space step (network, rig, loss, backward, Adam) on ``Y``'s poses."""
    generator = torch.Generator().manual_seed(0)
    with torch.no_grad():
        pose = rig.reference_pose(torch.as_tensor(Y, dtype=torch.float32))
        target = torch.cat([pose.positions, pose.cog[:, None]], dim=1)
    inputs = target.reshape(len(target), -1)
    controls = rig.controls
    network = SquashedNetwork(inputs.shape[1], 512, 2, len(controls.defaults), generator)
    network.set_scales(
        inputs.mean(0).double(),
        inputs.std(0).double() + 1.0,
        controls.lower,
        controls.upper,
        controls.defaults,
        np.ones(len(controls.defaults)),
        np.ones(len(controls.defaults)),
    )
    optimizer = _adam(list(network.parameters()), 1e-4)  # the fit's (fused) Adam

    def run() -> None:
        optimizer.zero_grad(set_to_none=True)
        posed = rig._pose_torch(network(inputs))
        points = torch.cat([posed.positions, posed.cog[:, None]], dim=1)
        ((points - target) ** 2).mean().backward()
        optimizer.step()

    return run


def measure(name: str, repeats: int) -> dict:
    rigs = {e: BUILDERS[name]() for e in ENGINES}  # each engine its own rig and caches
    Y128 = check_controls(rigs["reference"].controls, 128, seed=0)
    Y100 = check_controls(rigs["reference"].controls, 100, seed=1)
    out = {}
    out["rig_forward_backward_128_float32"] = timed(
        {e: rig_alone(rigs[e], Y128, torch.float32, e) for e in ENGINES}, repeats
    )
    out["rig_forward_backward_100_float64"] = timed(
        {e: rig_alone(rigs[e], Y100, torch.float64, e) for e in ENGINES}, repeats
    )
    out["fit_step_128_float32"] = timed({e: fit_step(rigs[e], Y128) for e in ENGINES}, repeats)
    return out


if __name__ == "__main__":
    run_cli(__doc__.splitlines()[0], measure, repeats=15)
