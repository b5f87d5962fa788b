"""Write the skeleton matching's retarget maps for both CMU BVH conversions of ../shared/mocap/.

    python scripts/match_cmu_skeletons.py [--mocap ../shared/mocap] [--out conf/retarget/matched]

For each conversion (``cmu_131``: the 3ds-Max-friendly one, ``cmu_hahne``: B. Hahne's
MotionBuilder-friendly one) and each rig with a ``roles`` table in
``conf/map/default.yaml`` it writes ``<out>/<conversion>_<rig>.yaml``, what ``rigmap map``
would match and save for a clip of that conversion, and prints the files as JSON. The
files are usable as ``map.retarget=matched/<conversion>_<rig>``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import yaml

from rigmap.animation.bvh import read_bvh
from rigmap.map.skeleton_match import check_roles, match_bvh
from rigmap.map.tracks import tracks_from_motion
from rigmap.store import write_text_atomic

ROOT = Path(__file__).resolve().parents[1]
CONVERSIONS = {"cmu_131": "cmu_131_01_walk.bvh", "cmu_hahne": "cmu_07_01.bvh"}
CREDIT = (
    "The data used in this project was obtained from mocap.cs.cmu.edu.",
    "The database was created with funding from NSF EIA-0196217.",
)


def rig_roles(config: Path = ROOT / "conf" / "map" / "default.yaml") -> dict[str, dict]:
    """Each rig's ``roles`` table from the map config."""
    rigs = yaml.safe_load(config.read_text())["rigs"]
    return {
        name: check_roles(name, section["roles"], f"{config}: rigs.{name}.roles")
        for name, section in rigs.items()
        if section.get("roles")
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mocap", type=Path, default=ROOT.parent / "shared" / "mocap")
    parser.add_argument("--out", type=Path, default=ROOT / "conf" / "retarget" / "matched")
    args = parser.parse_args()
    written = []
    for conversion, clip in CONVERSIONS.items():
        motion = read_bvh(args.mocap / clip)
        positions = tracks_from_motion(motion, clip).positions
        for rig, roles in rig_roles().items():
            with tempfile.TemporaryDirectory() as scratch:
                matched = match_bvh(
                    motion,
                    positions,
                    rig,
                    roles,
                    source=clip,
                    notes=CREDIT,
                    draft=Path(scratch) / "draft.yaml",
                )
            path = args.out / f"{conversion}_{rig}.yaml"
            write_text_atomic(path, matched.text)
            written.append(
                {
                    "file": str(path.relative_to(ROOT)),
                    "match": matched.describe(),
                    "frames": matched.frames.describe(),
                }
            )
    print(json.dumps(written, indent=2))


if __name__ == "__main__":
    main()
