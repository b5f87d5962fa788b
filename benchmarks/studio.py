"""`rigmap studio`'s Pose view measured in a real browser (issue #43); prints JSON.

The studio serves the project's own pipeline data (``data/<rig>/corpus`` and ``poses``, as
``make reproduce`` writes them; ``--data`` names another clone's) and Chromium (Debian's,
through Playwright; software WebGL, no GPU) drags an effector's gizmo with real mouse
events: ``--drags`` moves (default 200) in gestures of 40, one move per 60 ms (viser's gizmo
sends at most one update per 50 ms while dragging). Each move's latency is measured in the
page's clock, from its ``pointermove`` event to the first animation frame showing the pose
it caused (:mod:`rigmap.studio.probe`). Reported per rig (biped: full-body IK from seven
effectors, hand; face: FaceIK, a landmark): latency p50 / p95 / max (ms), the server's own
pose time p50 / p95 (ms) and the distance reached; the issue's bar is p95 <= 50 ms.

    .venv/bin/python benchmarks/studio.py [--rigs biped face] [--drags 200] [--data DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GESTURE = 40  # moves per press-and-release (ours)
JOINTS = {"biped": "hand_l"}  # the dragged effector (else the rig's first)


def measure(studio, rig: str, drags: int) -> dict:
    sys.path.insert(0, str(ROOT / "tests"))
    from browser import chromium_page
    from rigmap.studio import probe

    view = studio.views["Pose"]
    view.rig_menu.value = rig
    joint = JOINTS.get(rig, view.session.effectors[0])
    first = view.record.count
    latencies = []
    with chromium_page(studio.url) as page:
        box = probe.canvas_box(page)
        probe.watch_poses(page)
        time.sleep(1.0)
        while len(latencies) < drags:
            start = probe.gizmo_point(view, joint, box)
            n = min(GESTURE, drags - len(latencies))
            latencies += probe.timed_drag(page, start, probe.wiggle(start, n))
    pose_ms = np.array(view.record.pose_ms[1:])[-(view.record.count - first) :]
    lat = np.array(latencies)
    return {
        "rig": rig,
        "effector": joint,
        "drags": len(lat),
        "latency_ms_p50": float(np.percentile(lat, 50)),
        "latency_ms_p95": float(np.percentile(lat, 95)),
        "latency_ms_max": float(lat.max()),
        "under_50ms_share": float((lat <= 50).mean()),
        "server_pose_ms_p50": float(np.percentile(pose_ms, 50)),
        "server_pose_ms_p95": float(np.percentile(pose_ms, 95)),
        "distance_cm_last": view.record.distance_cm,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["biped", "face"])
    parser.add_argument("--drags", type=int, default=200)
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    args = parser.parse_args()
    from rigmap.app.studio import build_studio

    with redirect_stdout(sys.stderr):  # viser's banner: stdout is the JSON
        models = Path(tempfile.mkdtemp(prefix="studio-bench-"))
        studio = build_studio(
            rigs=args.rigs,
            overrides=[f"paths.data={args.data}", f"paths.models={models}"],
            config_dir=ROOT / "conf",
            folder=ROOT,
            out=models / "out",
            host="127.0.0.1",
            port=0,
        )
        try:
            rows = [measure(studio, rig, args.drags) for rig in args.rigs]
        finally:
            studio.stop()
    print(
        json.dumps(
            {
                "benchmark": "studio pose drag latency",
                "pace_ms": 60,
                "load_average": os.getloadavg(),
                "cpus": os.cpu_count(),
                "rigs": rows,
            },
            indent=1,
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
