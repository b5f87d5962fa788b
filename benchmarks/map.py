"""Speed of ``rigmap map`` and ``rigmap pose`` on the biped; prints JSON.

- map: frames/s of :func:`rigmap.map.clip.map_clip` on a stretch of the CMU walk
  (``../shared/mocap/cmu_131_01_walk.bvh`` at 30 fps), regression only and with
  refinement, with the seconds split into prediction, refinement and key reduction;
- pose: poses/s of :func:`rigmap.map.effectors.pose_from_effectors` from the 7 effectors
  (hips, chest, head, hands, feet) of test-corpus poses, one pose per call as an
  interactive tool calls it (regression only, refined as ``rigmap pose`` refines, and
  refined with one forward-difference Jacobian kept for every iteration), and all poses
  in one call; with the cost of one rig evaluation of a single pose, which bounds the
  interactive rate (every pose needs at least one, to place the rig's joints). CPU
  seconds are printed beside wall seconds: on a loaded machine they are the better guess
  of the idle rate.

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

    from rigmap.cli import compose_config
    from rigmap.stage.runner import stage_config

    paths = [f"paths.data={args.data}", f"paths.models={args.models}"]
    cfg = compose_config(["rig=biped", *paths, *overrides], ROOT / "conf", config_name="map")
    return OmegaConf.to_container(stage_config(cfg), resolve=True)


def _model(rig, config, subset_name, retarget=None):
    from rigmap.map.app import subset_for
    from rigmap.map.subset_model import obtain_subset_model
    from rigmap.store import Layout

    subset = subset_for(config["map"], rig, retarget, subset_name)
    layout = Layout.from_paths(config["paths"])
    return obtain_subset_model(rig, subset, layout, config["regressor"], log=lambda _: None)


def bench_map(rig, args) -> dict:
    from rigmap.map.app import _read_clip, map_settings, retarget_map
    from rigmap.map.clip import map_clip

    config = _config(args, "map.first_frame=240", f"map.frames={args.frames}")
    retarget = retarget_map(config["map"], rig.name, ROOT / "conf")
    targets = _read_clip(WALK, retarget, rig, config["map"])
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


def _effector_targets(rig, subset, n: int, data: str) -> np.ndarray:
    """World positions of the subset's joints on ``n`` test-corpus frames (animator poses)."""
    from rigmap.animation.posing import PoseTable
    from rigmap.store import Layout

    poses = PoseTable.read(Layout(data=Path(data)).poses(rig.name, "test"), rig=rig.name,
                           n_joints=rig.n_joints, split="test")  # fmt: skip
    world = np.asarray(poses.positions()) + np.asarray(poses.cog())[:, None, :]
    picks = np.linspace(0, len(world) - 1, n).round().astype(int)
    return world[picks][:, subset.columns(rig)]


def bench_pose(rig, args) -> dict:
    from rigmap.map.app import map_settings

    config = _config(args)
    model = _model(rig, config, "effectors")
    targets = _effector_targets(rig, model.mapping.subset, args.poses, args.data)
    base = dataclasses.replace(map_settings(config["map"], rig.name), feet=())
    wall, cpu = _one_evaluation(rig)
    out = {"effectors": list(model.mapping.subset.joints), "poses": len(targets),
           "one_rig_evaluation_of_one_pose_s": wall,
           "one_rig_evaluation_of_one_pose_cpu_s": cpu}  # fmt: skip
    variants = (
        ("regression_only", 0, "per_iteration"),
        ("refined", args.iterations, "per_iteration"),
        ("refined_one_forward_jacobian", args.iterations, "once"),
    )
    for label, iterations, jacobian in variants:
        settings = dataclasses.replace(base, refine_iterations=iterations)
        pose = _poser(rig, model, settings, jacobian)
        pose(targets[:1])  # warm-up
        load = os.getloadavg()[0]
        started, cpu_started = time.perf_counter(), time.process_time()
        errors = [pose(targets[k : k + 1])[0] for k in range(len(targets))]
        one_by_one, one_by_one_cpu = (
            time.perf_counter() - started,
            time.process_time() - cpu_started,
        )
        started = time.perf_counter()
        pose(targets)
        batched = time.perf_counter() - started
        out[label] = {"refine_iterations": iterations, "jacobian": jacobian,
                      "poses_per_second_one_per_call": len(targets) / one_by_one,
                      "poses_per_cpu_second_one_per_call": len(targets) / one_by_one_cpu,
                      "poses_per_second_batched": len(targets) / batched,
                      "target_distance_rms_cm_median": float(np.median(errors)),
                      "load_average_1min": load}  # fmt: skip
    return out


def _poser(rig, model, settings, jacobian: str):
    """``targets -> per-pose distance (cm)``: :func:`pose_from_effectors` as ``rigmap pose``
    runs it (``per_iteration``: central differences at every iteration), or the same guess
    refined with one forward-difference Jacobian at the guess, kept for every iteration
    (``once``: n_used + 1 rig evaluations instead of 2 n_used per iteration)."""
    from rigmap.map.clip import held_controls
    from rigmap.map.effectors import pose_from_effectors
    from rigmap.map.world_subset_rig import WorldSubsetRig
    from rigmap.refine import ComputedJacobian, damped_least_squares

    if jacobian == "per_iteration":
        return lambda batch: pose_from_effectors(
            rig, model.mapping, batch, settings, control_std=model.control_std,
            hold_values=model.hold_values)[1]  # fmt: skip
    view = WorldSubsetRig(rig, model.mapping.subset.joints)
    held = held_controls(rig, settings.hold)
    scale = np.asarray(model.control_std, dtype=np.float64).copy()
    scale[held] = 0.0

    def pose(batch):
        Y = model.mapping.predict(batch)
        Y[:, held] = model.hold_values[held]
        source = ComputedJacobian(view, differences="forward", per_iteration=False)
        result = damped_least_squares(view, Y, batch, source, damping=settings.damping,
                                      max_iterations=settings.refine_iterations,
                                      control_scale=scale, keep_in_range=True)  # fmt: skip
        reached = np.asarray(view.evaluate(rig.expand_used(result.Y_used)))
        return np.sqrt(((reached - batch) ** 2).sum(axis=2).mean(axis=1))

    return pose


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
    parser.add_argument("--poses", type=int, default=20, help="effector poses")
    parser.add_argument("--iterations", type=int, default=3, help="refinement iterations")
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
