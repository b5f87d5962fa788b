"""The built-in rigs' torch pass: step by step (reference) against by structure; prints JSON.

Old (``TorchRig.reference_pose``: each step once per instance) and new
(``TorchRig.structured_pose``, ``rigmap.rigs.engine.structured``: each unit once for all its
instances, level by level) in the same process, alternating, on one torch thread (what
the pipeline's rig work uses), each time the median of ``--repeats``. Per rig:

- ``forward_backward_100``: positions of 100 random poses (float64 and float32) and the
  gradient of their sum back to the controls (a tuning step's rig part);
- ``forward_512`` / ``forward_16384``: positions without gradient (``TorchRig`` runs
  batches above ``STRUCTURED_MAX_POSES`` = 512 by the reference, since the structured pass
  is slower there);
- ``compiled`` (forward + backward at 100 rows, forward at 16 384 in chunks of
  ``COMPILED_CHUNK``): the structured pass compiled by inductor
  (``TorchRig.compiled_pose``, ``rigmap.rigs.engine.compiled``); its compile is the first,
  untimed call, reported as ``compiled_first_call_s``;
- with ``STRUCTURED`` off (old) and on (new), everything else as the pipeline runs it:
  ``tuning_step_100``, one Adam step of a joint-space network (3 x 256 ReLU, float32,
  ours: a stand-in of ``regression.target_tuning``'s network) through the rig on 100
  frames; ``refinement_100_frames``, computed-Jacobian damped least squares with the
  conf/refine defaults (forward differences, coloured, block Cholesky, auto damping,
  traces) from noisy guesses of 100 random poses, 3 iterations, in frames/s.

    PYTHONPATH=src .venv/bin/python benchmarks/rig_pass.py [--rigs quadruped biped] [--repeats 7]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from collections.abc import Callable
from contextlib import contextmanager

import numpy as np
import torch

from rigmap.refine.damped_least_squares import damped_least_squares
from rigmap.refine.sources import ComputedJacobian
from rigmap.rigs.characters.biped import build_biped
from rigmap.rigs.characters.quadruped import build_quadruped
from rigmap.rigs.engine import torch_rig
from rigmap.rigs.engine.structured import check_controls

BUILDERS = {"quadruped": build_quadruped, "biped": build_biped}
ENGINES = ("old", "new")
#: the compiled pass's graph size for the 16 384-pose forward (ours: one graph, 8 chunks)
COMPILED_CHUNK = 2048
#: conf/refine/computed_jacobian.yaml's settings at the quick experiment's 3 iterations
REFINE = {
    "damping": "auto",
    "keep_in_range": True,
    "tolerance": 1e-4,
    "max_iterations": 3,
    "solver": "block_cholesky",
    "traced": True,
}


@contextmanager
def engine(name: str):
    """Every pass inside runs the reference (``old``) or the structured (``new``) engine."""
    before = torch_rig.STRUCTURED
    torch_rig.STRUCTURED = name == "new"
    try:
        yield
    finally:
        torch_rig.STRUCTURED = before


def timed(runs: dict[str, Callable[[], None]], repeats: int) -> dict:
    """Median seconds of each engine's run, the engines alternating (after one warm-up each)."""
    samples: dict[str, list[float]] = {name: [] for name in runs}
    first: dict[str, float] = {}
    for name, run in runs.items():
        with engine(name):
            started = time.perf_counter()
            run()
            first[name] = time.perf_counter() - started
    for _ in range(repeats):
        for name, run in runs.items():
            with engine(name):
                started = time.perf_counter()
                run()
                samples[name].append(time.perf_counter() - started)
    medians = {name: statistics.median(s) for name, s in samples.items()}
    out = {
        **{f"{name}_ms": round(1e3 * m, 3) for name, m in medians.items()},
        "speedup": round(medians["old"] / medians["new"], 2),
    }
    if "compiled" in medians:
        out["compiled_speedup"] = round(medians["old"] / medians["compiled"], 2)
        out["compiled_first_call_s"] = round(first["compiled"], 1)
    return out


def _pass(rig, engine_name: str, chunk: int | None = None) -> Callable:
    if engine_name == "compiled":
        return lambda Y: rig.compiled_pose(Y, chunk or len(Y))
    return rig.reference_pose if engine_name == "old" else rig.structured_pose


def forward_backward(rig, engine_name: str, Y: np.ndarray, dtype) -> Callable[[], None]:
    def run() -> None:
        y = torch.as_tensor(Y, dtype=dtype).requires_grad_(True)
        _pass(rig, engine_name)(y).positions.sum().backward()

    return run


def forward(rig, engine_name: str, Y: np.ndarray) -> Callable[[], None]:
    def run() -> None:
        with torch.no_grad():
            _pass(rig, engine_name, COMPILED_CHUNK)(torch.from_numpy(Y))

    return run


def tuning_step(rig, Y: np.ndarray) -> Callable[[], None]:
    torch.manual_seed(0)
    n_joints, n_controls = rig.n_joints, Y.shape[1]
    network = torch.nn.Sequential(
        torch.nn.Linear(3 * n_joints, 256),
        torch.nn.ReLU(),
        torch.nn.Linear(256, 256),
        torch.nn.ReLU(),
        torch.nn.Linear(256, n_controls),
    )
    optimizer = torch.optim.Adam(network.parameters(), lr=1e-4)
    with torch.no_grad():
        target = rig._pose_torch(torch.as_tensor(Y, dtype=torch.float32)).positions
    base = torch.as_tensor(Y, dtype=torch.float32)

    def run() -> None:
        optimizer.zero_grad()
        controls = base + network(target.reshape(len(target), -1))
        loss = ((rig._pose_torch(controls).positions - target) ** 2).mean()
        loss.backward()
        optimizer.step()

    return run


def refinement(rig, Y: np.ndarray) -> Callable[[], None]:
    used = rig.controls.used_indices
    target = rig.pose(Y).positions
    rng = np.random.default_rng(1)
    scale = 0.05 * (rig.controls.upper[used] - rig.controls.lower[used])
    guess = Y[:, used] + rng.normal(0.0, 1.0, Y[:, used].shape) * scale
    source = ComputedJacobian(rig, differences="forward", sparsity="coloured")
    settings = {**REFINE, "control_scale": scale}

    def run() -> None:
        damped_least_squares(rig, guess, target, source, **settings)

    return run


def measure(name: str, repeats: int) -> dict:
    rigs = {engine_name: BUILDERS[name]() for engine_name in (*ENGINES, "compiled")}
    Y100 = check_controls(rigs["old"].controls, 100, seed=0)
    Y16k = check_controls(rigs["old"].controls, 16_384, seed=1)
    out = {}
    with_compiled = (*ENGINES, "compiled")
    for label, dtype in (("float64", torch.float64), ("float32", torch.float32)):
        out[f"forward_backward_100_{label}"] = timed(
            {e: forward_backward(rigs[e], e, Y100, dtype) for e in with_compiled}, repeats
        )
    out["forward_512"] = timed({e: forward(rigs[e], e, Y16k[:512]) for e in ENGINES}, repeats)
    out["forward_16384"] = timed({e: forward(rigs[e], e, Y16k) for e in with_compiled}, 3)
    out["tuning_step_100"] = timed({e: tuning_step(rigs[e], Y100) for e in ENGINES}, repeats)
    runs = {e: refinement(rigs[e], Y100) for e in ENGINES}
    result = timed(runs, 3)
    result["old_frames_per_s"] = round(100 / (result["old_ms"] / 1e3), 1)
    result["new_frames_per_s"] = round(100 / (result["new_ms"] / 1e3), 1)
    out["refinement_100_frames"] = result
    return out


def run_cli(description: str, measure_rig: Callable[[str, int], dict], repeats: int) -> None:
    """``--rigs`` and ``--repeats`` from the command line; ``measure_rig(rig, repeats)`` per rig
    on one torch thread, the load before and after; JSON on stdout (the rig-pass benchmarks'
    shared front end)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--rigs", nargs="+", default=list(BUILDERS), choices=list(BUILDERS))
    parser.add_argument("--repeats", type=int, default=repeats)
    args = parser.parse_args()
    torch.set_num_threads(1)
    results = {"torch": torch.__version__, "threads": 1, "load_before": os.getloadavg()[0]}
    for name in args.rigs:
        results[name] = measure_rig(name, args.repeats)
    results["load_after"] = os.getloadavg()[0]
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    run_cli(__doc__.splitlines()[0], measure, repeats=7)
