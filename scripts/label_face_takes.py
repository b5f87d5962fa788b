"""A heuristic labelling of the shared Live Link Face takes, written as a label YAML.

The takes (``../shared/face/``) come without labels. This marks stretches by what their
curves show, with thresholds of ours read off the curves (not a person's judgement):
smiling (mean MouthSmile over 0.3), frowning (mean BrowDown over 0.2), blinking (mean
EyeBlink over 0.2 in a 1 s window: bursts of blinks or closed eyes), talking (JawOpen's
1 s rolling standard deviation over 0.04), in that order of precedence, each smoothed over
0.5 s; a run is kept if it lasts 1 s or more (gaps under 0.3 s bridged), cut to 8 s at
most; and the range-of-motion take's first 20 s as ``range_of_motion`` (its README says
the shapes come one after another). Writes ``conf/latent/labels/shared_face.yaml``.

    .venv/bin/python scripts/label_face_takes.py [--out conf/latent/labels/shared_face.yaml]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rigmap.latent.live_link import read_take
from rigmap.store.atomic import write_text_atomic

ROOT = Path(__file__).resolve().parents[1]
FACE = ROOT.parent / "shared" / "face"
OUT = ROOT / "conf" / "latent" / "labels" / "shared_face.yaml"
FPS = 30.0
THRESHOLDS = {"smiling": 0.3, "frowning": 0.2, "blinking": 0.2, "talking": 0.04}  # ours
MIN_S, BRIDGE_S, MAX_S, ROM_S = 1.0, 0.3, 8.0, 20.0  # ours


def mean_filter(x: np.ndarray, seconds: float) -> np.ndarray:
    n = max(1, round(seconds * FPS))
    padded = np.pad(x, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(padded, np.ones(n) / n, mode="valid")


def signals(columns, values) -> dict[str, np.ndarray]:
    v = dict(zip(columns, values.T, strict=True))
    jaw = v["JawOpen"]
    spread = np.sqrt(np.maximum(mean_filter(jaw**2, 1.0) - mean_filter(jaw, 1.0) ** 2, 0))
    raw = {
        "smiling": (v["MouthSmileLeft"] + v["MouthSmileRight"]) / 2,
        "frowning": (v["BrowDownLeft"] + v["BrowDownRight"]) / 2,
        "blinking": mean_filter((v["EyeBlinkLeft"] + v["EyeBlinkRight"]) / 2, 1.0),
        "talking": spread,
    }
    return {label: mean_filter(x, 0.5) > THRESHOLDS[label] for label, x in raw.items()}


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` runs of a mask, short gaps bridged, short runs dropped, long cut."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    spans = [list(pair) for pair in edges.reshape(-1, 2)]
    merged: list[list[int]] = []
    for start, end in spans:
        if merged and start - merged[-1][1] < BRIDGE_S * FPS:
            merged[-1][1] = end
        else:
            merged.append([start, end])
    out = []
    for start, end in merged:
        for s in range(start, end, int(MAX_S * FPS)):
            e = min(end, s + int(MAX_S * FPS))
            if e - s >= MIN_S * FPS:
                out.append((s, e))
    return out


def label_take(path: Path) -> dict[str, list[tuple[float, float]]]:
    take = read_take(path)
    found: dict[str, list[tuple[float, float]]] = {}
    for stretch in take.segments(FPS):
        if len(stretch.values) < MIN_S * FPS:
            continue
        offset = stretch.start_s - take.span_s[0]
        taken = np.zeros(len(stretch.values), dtype=bool)
        for label, mask in signals(take.columns, stretch.values).items():
            for s, e in runs(mask & ~taken):
                taken[s:e] = True
                found.setdefault(label, []).append((offset + s / FPS, offset + e / FPS))
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    labels: dict[str, list[str]] = {"range_of_motion": []}
    for path in sorted(FACE.glob("*.csv")):
        if path.stem.startswith("alex_rom"):
            labels["range_of_motion"].append(f"{{take: {path.stem}, from_s: 0.0, to_s: {ROM_S}}}")
            continue
        for label, spans in label_take(path).items():
            labels.setdefault(label, []).extend(
                f"{{take: {path.stem}, from_s: {a:.2f}, to_s: {b:.2f}}}" for a, b in spans
            )
    lines = [
        "# Segments of the shared Live Link Face takes (../shared/face/, MIT, see its LICENSE)",
        "# labelled by a HEURISTIC of ours from their curves, not by a person:",
        "# scripts/label_face_takes.py (thresholds in its docstring) wrote this file.",
        "# Seconds are counted from each take's first row; format: rigmap.latent.segment_labels.",
        "takes: ../../../../shared/face",
        f"fps: {FPS:g}",
        "labels:",
    ]
    for label, entries in labels.items():
        lines.append(f"  {label}:")
        lines.extend(f"    - {entry}" for entry in entries)
    write_text_atomic(args.out, "\n".join(lines) + "\n")
    print(args.out, {label: len(entries) for label, entries in labels.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
