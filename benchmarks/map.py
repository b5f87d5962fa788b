"""Speed of ``rigmap map`` and ``rigmap pose`` on the biped; prints JSON.

- map: frames/s of :func:`rigmap.map.clip.map_clip` on a stretch of the CMU walk
  (``../shared/mocap/cmu_131_01_walk.bvh`` at 30 fps), regression only and with
  refinement, with the seconds split into prediction, refinement and key reduction;
- pose: poses/s of ``rigmap pose`` from the 7 effectors (hips, chest, head, hands, feet)
  along a drag (consecutive test-corpus frames), one pose per call as an interactive tool
  calls it: regression only, ``map.pose_mode=batch`` (each pose refined from its guess,
  :func:`rigmap.map.effectors.pose_from_effectors`) and ``map.pose_mode=drag``
  (:class:`rigmap.map.interactive_pose.InteractivePoser`, with its Jacobian carried from
  pose to pose and fresh for every pose), each ``--repeats`` times, with the distance each
  reaches and the cost of one rig evaluation of a single pose. CPU seconds are printed
  beside wall seconds: on a loaded machine they are the better guess of the idle rate.

The machine may be shared, so the 1-minute load average is printed beside the numbers.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/map.py [--frames 48] [--poses 20] \\
        [--data data] [--models models] [--iterations 3]

The map models are fitted on ``<data>/biped/corpus`` and ``poses`` (train split, written
by the animate and pose stages) and cached in ``<models>/biped/map-<subset>/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"


def _config(args, *overrides: str) -> dict:
    from omegaconf import OmegaConf

    from rigmap.app.stage import stage_config
    from rigmap.cli import compose_config

    paths = [f"paths.data={args.data}", f"paths.models={args.models}"]
    cfg = compose_config(["rig=biped", *paths, *overrides], ROOT / "conf", config_name="map")
    return OmegaConf.to_container(stage_config(cfg), resolve=True)


def _model(rig, config, subset_name, retarget=None):
    from rigmap.app.map_job import subset_for
    from rigmap.map.subset_model import obtain_subset_model
    from rigmap.store import Layout

    subset = subset_for(config["map"], rig, retarget, subset_name)
    layout = Layout.from_paths(config["paths"])
    return obtain_subset_model(rig, subset, layout, config["regressor"], log=lambda _: None)


def bench_map(rig, args) -> dict:
    from rigmap.app.map_job import map_settings, read_clips
    from rigmap.map.clip import map_clip

    config = _config(args, "map.first_frame=240", f"map.frames={args.frames}")
    out = Path(args.models) / "bench_map_out"  # where a matched skeleton's map would go
    (targets,), retarget = read_clips([WALK], rig, config["map"], ROOT / "conf", out, print)
    model = _model(rig, config, "mocap", retarget)
    out = {"clip": WALK.name, "frames": len(targets.positions), "fps_of_clip": targets.fps}
    for label, iterations in (("regression_only", 0), ("refined", args.iterations)):
        settings = dataclasses.replace(map_settings(config["map"], rig.name),
                                       refine_iterations=iterations)  # fmt: skip
        load = os.getloadavg()[0]
        started, cpu_started = time.perf_counter(), time.process_time()
        result = map_clip(rig, targets, model.mapping, settings, control_std=model.control_std,
                          hold_values=model.hold_values)  # fmt: skip
        seconds, cpu = time.perf_counter() - started, time.process_time() - cpu_started
        error = result.frame_error_cm
        out[label] = {"refine_iterations": iterations, "seconds": seconds,
                      "frames_per_second": len(error) / seconds,
                      "frames_per_cpu_second": len(error) / cpu,
                      "frames_per_second_without_key_reduction":
                          len(error) / (seconds - result.seconds["keys_s"]),
                      "parts_s": result.seconds,
                      "joint_error_rms_cm": float(np.sqrt((error**2).mean())),
                      "load_average_1min": load}  # fmt: skip
    return out


def _drag_targets(rig, subset, n: int, data: str) -> np.ndarray:
    """World positions of the subset's joints on the first ``n`` frames of the first test
    clip, in order: an animator's drag moving all seven effectors at once, at the clip's
    frame rate (the target moves about 3 cm per frame, 13 cm at the 90th percentile)."""
    from rigmap.animation.posing import PoseTable
    from rigmap.store import Layout

    poses = PoseTable.read(Layout(data=Path(data)).poses(rig.name, "test"), rig=rig.name,
                           n_joints=rig.n_joints, split="test")  # fmt: skip
    names = poses.table["clip"].to_numpy()
    first = np.flatnonzero(names == names[0])[:n]
    world = np.asarray(poses.positions()) + np.asarray(poses.cog())[:, None, :]
    return world[first][:, subset.columns(rig)]


def bench_pose(rig, args) -> dict:
    """Every variant poses the same drag, one pose per call as an interactive tool calls it."""
    from rigmap.app.map_job import map_settings

    config = _config(args)
    model = _model(rig, config, "effectors")
    targets = _drag_targets(rig, model.mapping.subset, args.poses, args.data)
    base = dataclasses.replace(map_settings(config["map"], rig.name), feet=(), prior_weight=0.0)
    wall, cpu = _one_evaluation(rig)
    out = {"effectors": list(model.mapping.subset.joints), "poses": len(targets),
           "one_rig_evaluation_of_one_pose_s": wall,
           "one_rig_evaluation_of_one_pose_cpu_s": cpu}  # fmt: skip
    variants = (
        ("regression_only", "batch", 0, None),
        ("batch_refined", "batch", args.iterations, None),  # map.pose_mode=batch
        ("drag", "drag", None, True),  # map.pose_mode=drag, rigmap pose's default
        ("drag_fresh_jacobian", "drag", None, False),  # map.drag.carry_jacobian=false
    )
    for label, mode, iterations, carry in variants:
        settings = dataclasses.replace(base, refine_iterations=iterations or 0)
        rates, cpu_rates, loads = [], [], []
        for _ in range(args.repeats):  # the machine is shared: the spread says how much
            pose = _poser(rig, model, settings, mode, carry)
            pose(targets[0])  # warm-up (the drag mode's traces are built here)
            loads.append(os.getloadavg()[0])
            started, cpu_started = time.perf_counter(), time.process_time()
            results = [pose(target) for target in targets[1:]]
            rates.append(len(results) / (time.perf_counter() - started))
            cpu_rates.append(len(results) / (time.process_time() - cpu_started))
        distances = np.array([d for d, _ in results])
        out[label] = {"mode": mode, "refine_iterations": iterations, "carry_jacobian": carry,
                      "poses_per_second_median": float(np.median(rates)),
                      "poses_per_second_repeats": rates,
                      "poses_per_cpu_second_median": float(np.median(cpu_rates)),
                      "rig_evaluations_per_pose": float(np.mean([e for _, e in results])),
                      "target_distance_rms_cm_median": float(np.median(distances)),
                      "target_distance_rms_cm_p90": float(np.percentile(distances, 90)),
                      "load_average_1min": loads}  # fmt: skip
    return out


def _poser(rig, model, settings, mode: str, carry: bool | None):
    """``target (K, 3) -> (distance cm, rig evaluations)``: ``rigmap pose`` in ``mode``."""
    from rigmap.map.effectors import pose_from_effectors
    from rigmap.map.interactive_pose import InteractivePoser

    if mode == "drag":
        poser = InteractivePoser(rig, model.mapping, control_std=model.control_std,
                                 hold_values=model.hold_values, hold=settings.hold,
                                 damping=settings.damping, carry_jacobian=carry)  # fmt: skip

        def drag(target):
            result = poser(target)
            return result.distance_cm, result.rig_evaluations

        return drag

    def batch(target):
        _, distance, seconds = pose_from_effectors(
            rig, model.mapping, target[None], settings, control_std=model.control_std,
            hold_values=model.hold_values)  # fmt: skip
        return float(distance[0]), 1 + seconds.get("refine_rig_evaluations", 0.0)

    return batch


def _one_evaluation(rig) -> tuple[float, float]:
    """Median wall and CPU seconds of one rig evaluation of one pose."""
    Y = rig.controls.defaults[None]
    rig.evaluate(Y)
    wall, cpu = [], []
    for _ in range(10):
        started, cpu_started = time.perf_counter(), time.process_time()
        rig.evaluate(Y)
        wall.append(time.perf_counter() - started)
        cpu.append(time.process_time() - cpu_started)
    return float(np.median(wall)), float(np.median(cpu))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=48, help="mapped frames of the walk")
    parser.add_argument(
        "--poses", type=int, default=90, help="poses of the drag (at most the first test clip)"
    )
    parser.add_argument("--iterations", type=int, default=3, help="refinement iterations")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each pose variant")
    parser.add_argument("--data", default="data")
    parser.add_argument("--models", default="models")
    parser.add_argument("--only", choices=["map", "pose"], default=None, help="one part only")
    args = parser.parse_args()
    from rigmap.rigs import load

    rig = load("biped")
    report = {"rig": rig.name, "cpus": os.cpu_count()}
    if args.only in (None, "map"):
        report["map"] = bench_map(rig, args)
    if args.only in (None, "pose"):
        report["pose"] = bench_pose(rig, args)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
