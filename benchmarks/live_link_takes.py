"""What the shared Live Link Face takes hold (issue #41, item 1c); prints JSON.

For each CSV of ``../shared/face/`` (or the files named): its rows, duration, timecode
and sample rates, dropped samples (the gaps, by file line), lost-tracking rows (runs of
lines), duplicated timecodes, the stretches left after resampling to ``--fps`` (30, ours:
the capture's own rate) with holes up to ``--max-gap-s`` interpolated, and the seconds
:func:`rigmap.latent.live_link.read_take` took to parse and check the file.

    .venv/bin/python benchmarks/live_link_takes.py > benchmarks/results/live_link_takes.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from rigmap.latent.live_link import MAX_GAP_S, RESAMPLE_FPS, read_take

FACE = Path(__file__).resolve().parents[2] / "shared" / "face"


def describe(path: Path, fps: float, max_gap_s: float) -> dict:
    start = time.perf_counter()
    take = read_take(path)
    seconds = time.perf_counter() - start
    segments = take.segments(fps, max_gap_s=max_gap_s)
    return {
        **take.report(),
        "read_s": round(seconds, 3),
        "resampled": {
            "fps": fps,
            "frames": sum(len(s.values) for s in segments),
            "segments": [
                {
                    "start_s": round(s.start_s - take.times[0], 4),
                    "frames": len(s.values),
                    "interpolated": s.interpolated,
                }
                for s in segments
            ],
        },
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path, help="CSVs (default ../shared/face/)")
    parser.add_argument("--fps", type=float, default=RESAMPLE_FPS)
    parser.add_argument("--max-gap-s", type=float, default=MAX_GAP_S)
    args = parser.parse_args(argv)
    files = args.files or sorted(FACE.glob("*.csv"))
    if not files:
        print(f"no Live Link Face CSVs in {FACE}", file=sys.stderr)
        return 2
    takes = [describe(path, args.fps, args.max_gap_s) for path in files]
    print(json.dumps({"benchmark": "live_link_takes", "takes": takes}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
