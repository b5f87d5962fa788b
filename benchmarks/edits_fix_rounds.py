"""Incremental refinement with fixes handed in as files, on real takes (issue #40); JSON.

Ikemoto et al.'s loop (§3, Fig 2) as an artist runs it with rigmap's commands: learn an
edit from one example pair (``rigmap edits learn``), apply it to another take, correct a
stretch of the result and hand the corrected frames in as a BVH file (``rigmap edits
fix``, which refits and prints the frames to fix next), five rounds.

The artist's edit (ours): both upper arms raised by an angle that grows with the walk's
speed, 15° at 0.9 m/s or slower to 30° at 1.9 m/s or faster (root speed smoothed over
0.5 s), written through the BVH channels. Learned on three walk cycles of 07_06
(1.21 m/s: about 20° throughout), so on a faster walk the propagated raise falls short.
The artist fixes 07_12 (1.90 m/s), one segment of ``--segment`` frames a round: the
segment ``rigmap edits fix`` suggested last (round 1: the highest-variance segment before
any fix), against segments drawn at random among the unfixed frames (``--seeds`` seeds).
After each round, every take is mapped with ``rigmap edits apply`` and scored against the
artist's edit of it: mean squared joint-position error (cm², root-relative), on 07_12
and on the six walks never fixed (subject 07's other four, subject 08's two).

    PYTHONPATH=src .venv/bin/python benchmarks/edits_fix_rounds.py > result.json
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.spatial.transform import Rotation

from rigmap.animation import read_bvh
from rigmap.animation.bvh import ROTATION_CHANNELS
from rigmap.animation.bvh_write import write_bvh
from rigmap.cli import main as rigmap
from rigmap.edits.pairs import read_clip

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
CM_PER_UNIT = 5.64  # ../shared/mocap/README.md: about 0.0564 m a unit
EXAMPLE, EXAMPLE_FRAMES = "cmu_07_06.bvh", (1, 418)  # the cmu_07 edit subject's examples
FIXED = "cmu_07_12.bvh"
HELD_OUT = ["cmu_07_04.bvh", "cmu_07_05.bvh", "cmu_07_01.bvh", "cmu_07_11.bvh"]
HELD_OUT += ["cmu_08_04.bvh", "cmu_08_07.bvh"]


def raise_degrees(motion) -> np.ndarray:
    """Per frame, the artist's arm raise: 15° at 90 cm/s or slower, 30° from 190 (ours)."""
    root = motion.global_positions()[:, 0] * CM_PER_UNIT
    step = np.r_[0.0, np.hypot(*np.diff(root[:, [0, 2]], axis=0).T)] / motion.frame_time
    speed = uniform_filter1d(step, size=max(1, round(0.5 / motion.frame_time)), mode="nearest")
    return 15.0 + 15.0 * np.clip((speed - 90.0) / 100.0, 0.0, 1.0)


def artist_edit(motion):
    """Both upper arms turned about their parent's z axis by :func:`raise_degrees`."""
    values, degrees = motion.values.copy(), raise_degrees(motion)
    for joint, sign in (("LeftArm", 1.0), ("RightArm", -1.0)):
        j = motion.joint_index(joint)
        names, columns = motion.channels[j], motion.channel_slices()[j]
        rotation = [k for k, c in enumerate(names) if c in ROTATION_CHANNELS]
        order = "".join(names[k][0] for k in rotation).upper()
        index = [columns.start + k for k in rotation]
        old = Rotation.from_euler(order, values[:, index], degrees=True)
        turn = Rotation.from_euler("z", sign * degrees[:, None], degrees=True)
        values[:, index] = (turn * old).as_euler(order, degrees=True)
    return replace(motion, values=values)


def relative_positions(motion) -> np.ndarray:
    positions = motion.global_positions() * CM_PER_UNIT
    return positions - positions[:, :1]


def run(argv: list[str]) -> str:
    """A rigmap command in this process; its printed output (it must succeed)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = rigmap(argv)
    if status != 0:
        raise SystemExit(f"rigmap {' '.join(argv)} exited {status}:\n{out.getvalue()}")
    return out.getvalue()


def scores(model: Path, work: Path, truths: dict, sources: dict) -> dict:
    """Edit error (cm²) of ``rigmap edits apply`` on every take, and copying's."""
    out = work / "applied"
    shutil.rmtree(out, ignore_errors=True)
    run(
        ["edits", "apply", "--model", str(model), "--input", str(work / "takes"), "--out", str(out)]
    )
    errors = {}
    for name, truth in truths.items():
        got = relative_positions(read_bvh(out / name))
        want = relative_positions(truth)[-len(got) :]  # the applied clip has no T-pose
        copy = relative_positions(sources[name])[-len(got) :]
        captured = ~read_clip(MOCAP / name).bad  # a capture glitch has no truth to score
        errors[name] = {
            "edit_error_cm2": float(np.mean(np.sum((got - want)[captured] ** 2, axis=2))),
            "source_error_cm2": float(np.mean(np.sum((copy - want)[captured] ** 2, axis=2))),
        }
    held = [errors[n]["edit_error_cm2"] for n in HELD_OUT]
    return {
        "held_out_cm2": float(np.mean(held)),
        "fixed_take_cm2": errors[FIXED]["edit_error_cm2"],
        "takes": errors,
    }


def random_segment(rng, n_frames: int, fixed: list[tuple[int, int]], segment: int) -> tuple:
    """A segment of file frames 1..n_frames-1 (frame 0 is the T-pose) overlapping no fix."""
    taken = np.zeros(n_frames, bool)
    taken[0] = True
    for start, stop in fixed:
        taken[start:stop] = True
    starts = [s for s in range(1, n_frames - segment + 1) if not taken[s : s + segment].any()]
    start = int(starts[int(rng.integers(len(starts)))])
    return start, start + segment


def play(choice: str, seed: int, args, work: Path, truths: dict, sources: dict) -> dict:
    """Learn, then ``args.rounds`` fixes of 07_12 chosen by ``choice``; scores per round."""
    model = work / f"model_{choice}_{seed}"
    shutil.copytree(work / "learned", model)
    rng = np.random.default_rng(seed)
    rounds = [{"round": 0, "frames": None, **scores(model, work, truths, sources)}]
    fixed: list[tuple[int, int]] = []
    suggestion = work / "first_suggestion"
    next_up = tuple(json.loads(suggestion.read_text()))
    n_frames = len(truths[FIXED].values)
    for k in range(1, args.rounds + 1):
        if choice == "suggested":
            start, stop = next_up
        else:
            start, stop = random_segment(rng, n_frames, fixed, args.segment)
        fixed.append((start, stop))
        path = work / f"fix_{choice}_{seed}_{k}.bvh"
        write_bvh(replace(truths[FIXED], values=truths[FIXED].values[start:stop].copy()), path)
        started = time.perf_counter()
        printed = run(
            [
                "edits",
                "fix",
                "--model",
                str(model),
                "--source",
                str(MOCAP / FIXED),
                "--fixed",
                str(path),
                "--frames",
                f"{start}:{stop}",
                "--suggest",
                "1",
                "--segment",
                str(args.segment),
            ]
        )
        refit_s = time.perf_counter() - started
        next_up = _suggested(printed)
        rounds.append(
            {
                "round": k,
                "frames": [start, stop],
                "refit_and_suggest_s": refit_s,
                **scores(model, work, truths, sources),
            }
        )
    return {"choice": choice, "seed": seed, "rounds": rounds}


def _suggested(printed: str) -> tuple[int, int]:
    """``fix next: frames A:B ...`` → (A, B), file frames."""
    line = next(x for x in printed.splitlines() if x.startswith("fix next: frames"))
    start, stop = (int(v) for v in line.split()[3].split(":"))
    return start, stop


def first_suggestion(work: Path, segment: int) -> tuple[int, int]:
    """Round 1's suggestion: the highest-variance segment of 07_12 before any fix (the
    learned model's configuration variance, as ``rigmap edits fix`` ranks frames)."""
    from rigmap.edits.artist import MODEL_STEM
    from rigmap.edits.incremental import suggest_segments
    from rigmap.edits.propagation import load_model

    model = load_model(work / "learned" / f"{MODEL_STEM}.npz")
    clip = read_clip(MOCAP / FIXED)
    variance = model.predict(clip.source())[0].variance
    (pick,) = suggest_segments([variance], {}, 1, segment)
    return pick.start + clip.start, pick.stop + clip.start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)  # the issue's
    parser.add_argument("--segment", type=int, default=24)  # frames (0.2 s at 120 fps): ours
    parser.add_argument("--seeds", type=int, default=5)  # the issue's
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="rigmap-fix-rounds-") as folder:
        work = Path(folder)
        (work / "takes").mkdir()
        sources = {n: read_bvh(MOCAP / n) for n in [FIXED, *HELD_OUT]}
        truths = {n: artist_edit(m) for n, m in sources.items()}
        for name in sources:
            (work / "takes" / name).symlink_to(MOCAP / name)
        edited = work / "example_edited.bvh"
        write_bvh(artist_edit(read_bvh(MOCAP / EXAMPLE)), edited)
        frames = f"{EXAMPLE_FRAMES[0]}:{EXAMPLE_FRAMES[1]}"
        run(
            [
                "edits",
                "learn",
                "--source",
                str(MOCAP / EXAMPLE),
                "--edited",
                str(edited),
                "--frames",
                frames,
                "--out",
                str(work / "learned"),
            ]
        )
        (work / "first_suggestion").write_text(json.dumps(first_suggestion(work, args.segment)))
        runs = [play("suggested", 0, args, work, truths, sources)]
        runs += [play("random", seed, args, work, truths, sources) for seed in range(args.seeds)]
    print(
        json.dumps(
            {
                "benchmark": "edits_fix_rounds",
                "segment_frames": args.segment,
                "example": f"{EXAMPLE} frames {frames}",
                "fixed_take": FIXED,
                "held_out": HELD_OUT,
                "runs": runs,
                "summary": _summary(runs),
            },
            indent=1,
        )
    )


def _summary(runs: list[dict]) -> list[dict]:
    """Per round: the suggestion's held-out error beside random's median, min and max."""
    suggested = runs[0]["rounds"]
    randoms = [r["rounds"] for r in runs[1:]]
    rows = []
    for k, row in enumerate(suggested):
        held = [r[k]["held_out_cm2"] for r in randoms]
        fixed = [r[k]["fixed_take_cm2"] for r in randoms]
        rows.append(
            {
                "round": k,
                "suggested_held_out_cm2": row["held_out_cm2"],
                "random_held_out_cm2": {
                    "median": float(np.median(held)),
                    "min": min(held),
                    "max": max(held),
                },
                "suggested_below_random_seeds": int(sum(row["held_out_cm2"] < h for h in held)),
                "suggested_fixed_take_cm2": row["fixed_take_cm2"],
                "random_fixed_take_cm2": {
                    "median": float(np.median(fixed)),
                    "min": min(fixed),
                    "max": max(fixed),
                },
            }
        )
    return rows


if __name__ == "__main__":
    main()
