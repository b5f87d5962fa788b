"""The files a method run attaches: composed config, predicted control curves, error plot.

Each writer is atomic (temp file beside the target, then rename), so a folder
handed to MLflow never holds half a file.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from rigmap.tracking.keys import plain_container

PER_FRAME_COLUMNS = ("clip", "frame", "joint_error", "ground_truth_error")


def write_config_yaml(config: Any, path: str | os.PathLike) -> Path:
    """The composed (resolved) config as YAML."""
    import yaml

    text = yaml.safe_dump(plain_container(config), sort_keys=False, default_flow_style=False)
    return _write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_control_curves(curves: pd.DataFrame, path: str | os.PathLike) -> Path:
    """Predicted controls, one row per frame (e.g. ``clip``, ``frame``, one column per control)."""
    if not isinstance(curves, pd.DataFrame) or curves.empty:
        raise ValueError(
            "predicted control curves: expected a non-empty pandas DataFrame "
            f"(clip, frame, one column per control), got {type(curves).__name__}"
            + (" with no rows" if isinstance(curves, pd.DataFrame) else "")
        )
    non_text = [c for c in curves.columns if not isinstance(c, str)]
    if non_text:
        raise ValueError(
            f"predicted control curves: column names must be strings (control names), "
            f"got {non_text[:5]}"
        )
    return _write_atomically(path, lambda tmp: curves.to_parquet(tmp, index=False))


def plot_per_frame_errors(
    per_frame: pd.DataFrame, path: str | os.PathLike, *, title: str, length_unit: str = "cm"
) -> Path:
    """Joint and ground-truth error against frame, one line per clip, as PNG."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from rigmap.viz.atomic import save_figure

    missing = [c for c in PER_FRAME_COLUMNS if c not in per_frame.columns]
    if missing or per_frame.empty:
        raise ValueError(
            f"per-frame errors: expected rows with columns {list(PER_FRAME_COLUMNS)}, "
            f"missing {missing}, {len(per_frame)} rows"
        )
    figure = Figure(figsize=(9, 5.5), layout="constrained")
    joint_axes, truth_axes = figure.subplots(2, 1, sharex=True)
    for clip, rows in per_frame.groupby("clip", sort=False):
        joint_axes.plot(rows["frame"], rows["joint_error"], label=str(clip), linewidth=1)
        truth_axes.plot(rows["frame"], rows["ground_truth_error"], label=str(clip), linewidth=1)
    joint_axes.set_ylabel(f"joint error ({length_unit}²)")
    truth_axes.set_ylabel("ground-truth error\n(per-control std units²)")
    truth_axes.set_xlabel("frame")
    truth_axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    joint_axes.legend(fontsize="small", loc="upper right")
    joint_axes.set_title(title)
    for axes in (joint_axes, truth_axes):
        axes.grid(alpha=0.3)
    return save_figure(figure, path, dpi=100)


def _write_atomically(path: str | os.PathLike, write: Callable[[str], Any]) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=out.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out
