"""Rig evaluation through Ray against the local Blender pool: the wolf, poses/s, one JSON.

The same control vectors go through the local pool (2 worker processes) and through Ray
actors (1, then 2) on a local Ray head; the outputs must be byte-identical. ``ratio`` is
Ray's poses/s over the local pool's at the same worker count, and the per-pose overhead
is what Ray adds to a pose: (1/ray - 1/local) poses/s at 2 actors. Start-up (Blender
loading the .blend in each actor) is timed apart from evaluation.

Usage: python benchmarks/distributed.py [--poses 20000] [--address local]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

from rig_eval import random_controls  # benchmarks/ is on sys.path when run as a script
from rigmap.rigs.blender.ray_pool import ensure_ray
from rigmap.rigs.blender.rigify import build_rigify_wolf


def timed_pose(rig, Y) -> tuple[float, object]:
    rig.pose(Y[:8])  # start the workers (load the .blend) outside the timing
    start = time.perf_counter()
    pose = rig.pose(Y)
    return time.perf_counter() - start, pose


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--poses", type=int, default=20_000)
    parser.add_argument("--address", default="local", help="Ray address (local: a new head)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    ray = ensure_ray(args.address, num_cpus=args.workers)
    result: dict = {
        "rig": "rigify_wolf",
        "poses": args.poses,
        "machine": {
            "cpus": ray.cluster_resources().get("CPU"),
            "python": platform.python_version(),
        },
        "ray": ray.__version__,
    }
    with build_rigify_wolf(workers=args.workers) as wolf:
        Y = random_controls(wolf, args.poses)
        seconds, reference = timed_pose(wolf, Y)
        result["local"] = {"workers": args.workers, "seconds": seconds,
                           "poses_per_s": args.poses / seconds}  # fmt: skip
        for actors in range(1, args.workers + 1):
            wolf.use_executor({"kind": "ray", "actors": actors, "address": args.address})
            start = time.perf_counter()
            wolf.pool.start()
            started = time.perf_counter() - start
            seconds, pose = timed_pose(wolf, Y)
            identical = all(
                a.tobytes() == b.tobytes() for a, b in zip(reference, pose, strict=True)
            )
            result[f"ray_{actors}"] = {
                "actors": actors,
                "startup_seconds": started,
                "seconds": seconds,
                "poses_per_s": args.poses / seconds,
                "byte_identical_to_local": identical,
            }
            wolf.use_executor({"kind": "local"})
    local_rate = result["local"]["poses_per_s"]
    top = result[f"ray_{args.workers}"]["poses_per_s"]
    one = result["ray_1"]["poses_per_s"]
    result["ratio"] = top / local_rate  # Ray at N actors over the local pool at N workers
    result["ratio_1_actor"] = one / (local_rate / args.workers)  # over one local worker's share
    result["scaling_1_to_n"] = top / one
    result["overhead_ms_per_pose"] = 1000.0 * (1.0 / top - 1.0 / local_rate)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
