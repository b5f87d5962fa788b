"""Refinement speed: frames/s, rig evaluations per frame and joint error per method; prints JSON.

Each refined method of Table 1 runs on a rig's test clips through the
evaluation runner (``rigmap.evaluation.run_method``: the pipeline's own
timing, warm-up and rig counting) in the same process, once per variant:

- ``old``: the original refinement (per-frame SVD for λ and the step, central
  differences for every control, recomputed for every frame at every iteration,
  torch's own thread count);
- ``today``: the conf/refine defaults before colouring (batched Cholesky with the
  inverse-iteration λ, factorised once for a learned Jacobian; one-sided
  differences; torch's own threads);
- ``today_one_thread``: ``today`` on one torch thread (what colouring alone gains);
- ``new``: the conf/refine defaults (``today`` plus coloured differences —
  structurally independent controls perturbed in one rig evaluation,
  ``rigmap.refine.sparsity`` — and one torch thread);
- ``reuse`` (computed Jacobians only): ``new`` with Jacobians on every 4th frame
  shared with the neighbours, a frame's own recomputed when its error stops falling;
- ``block``: ``new`` with the step solved on the compact Jacobian's blocks
  (``solver: block_cholesky``, ``rigmap.refine.block_cholesky``; the conf/refine default
  since issue #16);
- ``fast``: ``block`` with the built-in rig evaluated by its TorchScript traces
  (``traced: true``);
- ``block_before`` / ``fast_before``: ``block`` / ``fast`` with the code before
  session 27 (``previous_code``: numpy's BLAS on its own threads, forward differences
  evaluate the pose itself again, a traced rig gets 1 720-pose chunks), for a same-run
  comparison;
- ``block_s27`` / ``fast_s27``: ``block`` / ``fast`` with the code of session 27
  (``s27_code``: ``blas_threads`` rescans the thread pools on every entry, the block
  solver reads a batch's pattern by torch, a learned Jacobian is turned on its dense
  prediction, a traced rig pads each batch to one of its per-size traces), for a
  same-run comparison of session 28's changes;
- ``fast_s28``: ``fast`` with the code of session 28 (``s28_code``: the rig's Euler
  matrices and two-axis rotations by axis matrices and batched matmuls again, layered
  chains joint by joint, the control objects' local transforms pose-major), for a same-run
  comparison of session 29's changes;
- ``block_forward``: ``block`` with one-sided differences even where the rig's
  conf asks for central ones (the Blender rigs).
- ``carry``: ``fast`` with a clip's frames refined in order, each from the previous
  frame's Jacobian and refined pose (``jacobian_update: carry``, issue #16);
- ``block_central_recompute``: ``block`` with central differences recomputed at every
  iteration, whatever the rig's conf asks for (the wolf's refinement before session 30).

The variants alternate ``--repeats`` times and the fastest run of each is kept,
with every run's frames/s and their median (the machine may be shared: every
number carries the 1-minute load average around it). A rig's own refine
settings (conf/rig/<rig>.yaml ``_overrides_.method``: the Blender human's central
differences, the wolf's one-sided ones with ``jacobian_update: carry``) apply to every
variant but ``old``, then a variant's ``after_rig``. The JSON gives, per rig, method
and variant: frames/s, rig evaluations per frame, joint error (cm²),
ground-truth error, and the speed-up over ``old``, ``today`` and
``today_one_thread`` where they ran (and, of medians, over a ``_before``, ``_s27`` or
``_s28`` twin).

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/refine.py \\
        --data /tmp/refine_data --models /tmp/refine_models \\
        [--rigs quadruped biped rigify_wolf] [--iterations 3] [--workers 2] \\
        [--frames-per-clip N] [--blender-frames-per-clip 12] [--repeats 1]

Models: ``<models>/<rig>/gpr-none-multiquadric`` (with ``learned_jacobian/``)
and ``<models>/<rig>/nn-none-none`` (or the rig's one ``nn-<sampler>-none``), from
pipelines/fit.py or a quick replication's ``models/``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np

from rigmap.evaluation import RefineSettings, TestSet, run_method
from rigmap.regression import load_learned_jacobian, load_regressor

METHODS = (
    "gpr_learned_jacobian",
    "nn_learned_jacobian",
    "gpr_computed_jacobian",
    "nn_computed_jacobian",
    "nn_autodiff_jacobian",
)

#: today's refinement, and issue #16's (the conf/refine defaults)
VARIANTS = {
    "old": {"solver": "svd", "threads": None},
    "today": {"solver": "cholesky", "differences": "forward", "threads": None},
    # "new" below is main's conf/refine defaults before block_cholesky (issue #16)
    "today_one_thread": {"solver": "cholesky", "differences": "forward", "threads": 1},
    "new": {"solver": "cholesky", "differences": "forward", "sparsity": "coloured"},
    "reuse": {
        "solver": "cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "share_every": 4,
    },
    "block": {"solver": "block_cholesky", "differences": "forward", "sparsity": "coloured"},
    "fast": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "traced": True,
    },
    # block with one-sided differences even where the rig's conf asks for central ones
    # (the Blender rigs: is the float32 step of 1e-3 accurate enough one-sided?)
    "block_forward": {
        "solver": "block_cholesky",
        "sparsity": "coloured",
        "after_rig": {"differences": "forward"},
    },
    # fast with a clip's frames refined in order, each from the previous frame's Jacobian
    # (jacobian_update: carry, issue #16); on a rig whose conf asks for other differences,
    # those
    "carry": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "traced": True,
        "jacobian_update": "carry",
    },
    # the wolf's refinement before session 30 (central differences recomputed at every
    # iteration), whatever its conf now asks for
    "block_central_recompute": {
        "solver": "block_cholesky",
        "sparsity": "coloured",
        "after_rig": {"differences": "central", "jacobian_update": "recompute"},
    },
    # the same settings with this session's changes switched off (see previous_code)
    "block_before": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "before": True,
    },
    "fast_before": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "traced": True,
        "before": True,
    },
    # the same settings with session 28's changes switched off (see s27_code)
    "block_s27": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "before": "s27",
    },
    "fast_s27": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "traced": True,
        "before": "s27",
    },
    # the same settings with session 29's changes switched off (see s28_code)
    "fast_s28": {
        "solver": "block_cholesky",
        "differences": "forward",
        "sparsity": "coloured",
        "traced": True,
        "before": "s28",
    },
}


@contextmanager
def previous_code(active: bool):
    """The refinement code before session 27's changes, for a same-run comparison.

    Switches off, for the duration: refinement's BLAS thread limit (``blas_threads``:
    numpy's OpenBLAS keeps its own threads again), forward differences reusing the residual's
    positions (``ComputedJacobian.uses_base``: the pose evaluated again, n + 1
    evaluations) and a traced rig's preferred batch (``TorchRig.poses_per_call``:
    chunks of ``POSES_PER_CALL`` poses again, padded to the 1 760 trace, with the
    2 048 trace as the split size).
    """
    if not active:
        yield
        return
    from rigmap.refine.sources import ComputedJacobian
    from rigmap.rigs.engine import torch_rig

    refinement = sys.modules["rigmap.refine.damped_least_squares"]
    saved = ComputedJacobian.uses_base, torch_rig.TorchRig.poses_per_call, torch_rig.TRACE_SIZES
    saved_blas = refinement.blas_threads
    refinement.blas_threads = lambda threads: nullcontext()
    ComputedJacobian.uses_base = lambda self: False
    torch_rig.TorchRig.poses_per_call = property(lambda self: None)
    torch_rig.TRACE_SIZES = (*saved[2], 1760, 2048)
    try:
        yield
    finally:
        ComputedJacobian.uses_base, torch_rig.TorchRig.poses_per_call = saved[:2]
        torch_rig.TRACE_SIZES = saved[2]
        refinement.blas_threads = saved_blas


@contextmanager
def s27_code(active: bool):
    """The refinement code of session 27 (before session 28's changes), for a same-run comparison.

    Switches off, for the duration: the cached threadpoolctl controller (``blas_threads``
    scans the loaded libraries on every entry again), numpy's pattern of a batch of
    Jacobians in the block solver (torch's ``ne(0).any(dim=0)`` again), the learned
    Jacobian's turn on its predicted entries (the dense prediction turned by
    ``Placement.jacobians_to_world`` again) and the one trace for every batch size
    (``torch_rig.GENERIC_TRACE``: batches padded to the per-size traces again; those are
    built in the variant's untimed warm-up). Not switched off: a learned Jacobian's
    predictions handed to the solver without a copy when every frame is refined
    (``PredictedJacobian``), and a trace's JIT warm-up at build time
    (``torch_rig.JIT_WARMUP_CALLS``, which cannot be undone once a trace is cached).
    """
    if not active:
        yield
        return
    import torch
    from threadpoolctl import threadpool_limits

    from rigmap.refine import block_cholesky
    from rigmap.regression.mapping import JacobianMapping
    from rigmap.rigs.engine import torch_rig

    refinement = sys.modules["rigmap.refine.damped_least_squares"]

    @contextmanager
    def old_blas_threads(threads):
        if threads is None:
            yield
            return
        with threadpool_limits(limits=int(threads), user_api="blas"):
            yield

    def old_predict(self, X_pose):
        X, single = self._rows(X_pose)
        J = self.learned.predict(self.placement.inputs(X, "learned Jacobian"))
        J = self.placement.jacobians_to_world(J, X)
        return J[0] if single else J

    saved = refinement.blas_threads, block_cholesky.batch_pattern, JacobianMapping.predict
    saved_generic = torch_rig.GENERIC_TRACE
    refinement.blas_threads = old_blas_threads
    block_cholesky.batch_pattern = lambda J: torch.from_numpy(J).ne(0).any(dim=0).numpy()
    JacobianMapping.predict = old_predict
    torch_rig.GENERIC_TRACE = False
    try:
        yield
    finally:
        refinement.blas_threads, block_cholesky.batch_pattern, JacobianMapping.predict = saved
        torch_rig.GENERIC_TRACE = saved_generic


def matmul_rotation_product(rotations):
    """Session 28's product of axis rotations: :func:`axis_rotation` matrices and batched
    matmuls (``R = R_k @ … @ R_1``), the same values as ``rotation_product`` to the last bit."""
    from rigmap.rigs.engine.transforms import axis_rotation

    R = axis_rotation(*rotations[0])
    for angle, axis in rotations[1:]:
        R = axis_rotation(angle, axis) @ R
    return R


@contextmanager
def s28_code(active: bool, rig):
    """The refinement code of session 28 (before session 29's changes), for a same-run comparison.

    Switches off, for the duration: the rig's Euler matrices and two-axis rotations written
    out entry by entry (``transforms.rotation_product``: axis matrices and batched matmuls
    again, :func:`matmul_rotation_product`), a layered FK chain's rotations for all its
    joints at once (``fk_chain.BATCHED_LAYERS``: joint by joint again) and the control
    objects' local transforms control by control (``builder.CONTROL_MAJOR_LOCALS``: the
    pose-major ``(N, K, 3, 3)`` layout again). ``rig``'s traces are
    recorded from the code they replay, so the variant keeps its own trace cache (built in its
    untimed warm-up).
    """
    if not active:
        yield
        return
    from rigmap.rigs.engine import builder
    from rigmap.rigs.features import chain_attributes, fk_chain, foot_roll

    def matmul_euler(angles, order="xyz"):
        return matmul_rotation_product([(angles[..., "xyz".index(a)], a) for a in order])

    inner = getattr(rig, "wrapped", rig)
    caches = ("_traces", "_generic_traces")
    saved_caches = {key: inner.__dict__.pop(key, None) for key in caches}
    inner.__dict__.update(inner.__dict__.pop("_s28_traces", {}))
    modules = (chain_attributes, foot_roll)
    saved = builder.euler_matrix, [m.rotation_product for m in modules]
    builder.euler_matrix = matmul_euler
    fk_chain.BATCHED_LAYERS = builder.CONTROL_MAJOR_LOCALS = False
    for module in modules:
        module.rotation_product = matmul_rotation_product
    try:
        yield
    finally:
        builder.euler_matrix = saved[0]
        fk_chain.BATCHED_LAYERS = builder.CONTROL_MAJOR_LOCALS = True
        for module, product in zip(modules, saved[1], strict=True):
            module.rotation_product = product
        inner.__dict__["_s28_traces"] = {
            k: inner.__dict__.pop(k) for k in caches if k in inner.__dict__
        }
        inner.__dict__.update({k: v for k, v in saved_caches.items() if v is not None})


def rig_refine_overrides(name: str, method: str) -> dict:
    """conf/rig/<name>.yaml's ``_overrides_.method.<method>.refine`` (e.g. central differences)."""
    from omegaconf import OmegaConf

    config = OmegaConf.to_container(OmegaConf.load(f"conf/rig/{name}.yaml"), resolve=False)
    methods = (config.get("_overrides_") or {}).get("method") or {}
    return dict((methods.get(method) or {}).get("refine") or {})


def load_rig(name: str, workers: int):
    from omegaconf import OmegaConf

    from rigmap.rigs import load

    options = OmegaConf.to_container(OmegaConf.load(f"conf/rig/{name}.yaml"), resolve=True)
    options.pop("corpus", None)
    if name.startswith("rigify"):
        options["workers"] = workers
    return load(options)


def measure(rig, method: str, test_set: TestSet, models: dict, variant: str, iterations: int):
    options = dict(VARIANTS[variant])
    before = options.pop("before", False)
    after_rig = options.pop("after_rig", {})
    if variant != "old":
        options.update(rig_refine_overrides(rig.name, method))
    options.update(after_rig)
    settings = RefineSettings(max_iterations=iterations, **options)
    regressor = models["gpr"] if method.startswith("gpr") else models["nn"]
    learned = models["learned"] if "learned" in method else None
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    with previous_code(before is True), s27_code(before == "s27"), s28_code(before == "s28", rig):
        evaluation = run_method(
            rig, method, test_set, regressor=regressor, learned_jacobian=learned, refine=settings
        )
    average = evaluation.result.to_dict()["average"]
    return {
        "method": method,
        "variant": variant,
        "settings": settings.to_dict(),
        "code": {
            True: "before session 27",
            "s27": "session 27 (before session 28)",
            "s28": "session 28 (before session 29)",
        }.get(before, "this commit"),
        "frames": test_set.frames,
        "fps": round(average["fps"], 2),
        "rig_evaluations_per_frame": round(average["rig_evaluations"] / test_set.frames, 1),
        "joint_error_cm2": average["joint_error"],
        "ground_truth_error": average["ground_truth_error"],
        "initial_joint_error_cm2": evaluation.result.extra["initial_joint_error"]["average"],
        "wall_s": round(time.perf_counter() - started, 2),
        "load_average_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],
    }


def network_folder(folder: Path) -> Path:
    """``nn-none-none``, or the rig's one network (the wolf's is ``nn-pca_gaussian-none``)."""
    if (folder / "nn-none-none").is_dir():
        return folder / "nn-none-none"
    found = sorted(folder.glob("nn-*-none"))
    if not found:
        raise SystemExit(f"{folder}: no network model (nn-<sampler>-none) to refine from")
    return found[0]


def benchmark_rig(name: str, args) -> list[dict]:
    rig = load_rig(name, args.workers)
    try:
        folder = args.models / name
        gpr_folder = folder / "gpr-none-multiquadric"
        needs = {m.split("_")[0] for m in args.methods} | {
            "learned" for m in args.methods if "learned" in m
        }
        models = {
            "gpr": load_regressor(gpr_folder, rig=rig) if "gpr" in needs else None,
            "nn": load_regressor(network_folder(folder), rig=rig) if "nn" in needs else None,
            "learned": load_learned_jacobian(gpr_folder / "learned_jacobian", rig=rig)
            if "learned" in needs
            else None,
        }
        frames = args.blender_frames_per_clip if name.startswith("rigify") else args.frames_per_clip
        test_set = TestSet.load(rig, args.data / name).first_frames(frames)
        rows = []
        for method in args.methods:
            if method == "nn_autodiff_jacobian" and not rig.differentiable:
                continue
            variants = [v for v in args.variants if v != "reuse" or "computed" in method]
            best: dict[str, dict] = {}
            runs: dict[str, list[float]] = {v: [] for v in variants}
            for _ in range(args.repeats):  # old and new alternate, so both see the same load
                for variant in variants:
                    row = measure(rig, method, test_set, models, variant, args.iterations)
                    row["rig"] = name
                    print(json.dumps(row), file=sys.stderr, flush=True)
                    runs[variant].append(row["fps"])
                    if variant not in best or row["fps"] > best[variant]["fps"]:
                        best[variant] = row
            for v in variants:  # every repeat's rate and their median beside the best
                best[v]["fps_runs"] = runs[v]
                best[v]["fps_median"] = round(float(np.median(runs[v])), 2)
            for v in variants:
                for suffix in ("before", "s27", "s28"):  # the same settings on the previous code
                    twin = best.get(f"{v}_{suffix}")
                    if twin is not None:
                        best[v][f"speedup_over_{suffix}_median"] = round(
                            best[v]["fps_median"] / twin["fps_median"], 2
                        )
                for base in ("old", "today", "today_one_thread"):
                    if base in best and v != base:
                        best[v][f"speedup_over_{base}"] = round(
                            best[v]["fps"] / best[base]["fps"], 2
                        )
            rows.extend(best[v] for v in variants)
        return rows
    finally:
        close = getattr(rig, "close", None)
        if close is not None:
            close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--models", type=Path, required=True)
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped", "rigify_wolf"])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--variants", nargs="+", default=["old", "today", "new"],
                        choices=list(VARIANTS))  # fmt: skip
    parser.add_argument("--iterations", type=int, default=3, help="the quick experiment's cap")
    parser.add_argument("--workers", type=int, default=2, help="Blender workers")
    parser.add_argument("--frames-per-clip", type=int, default=None)
    parser.add_argument("--blender-frames-per-clip", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=1, help="best of, alternating variants")
    args = parser.parse_args()
    rows = []
    for name in args.rigs:
        rows.extend(benchmark_rig(name, args))
    print(json.dumps({"iterations": args.iterations, "results": rows}, indent=1))


if __name__ == "__main__":
    main()
