"""Write figures atomically: a killed run leaves the old file or none, never half a PNG."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def save_figure(fig, out_path: str | Path, **savefig_kwargs) -> Path:
    """Save a matplotlib figure to ``out_path`` via a temp file and rename."""
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=out.suffix)
    os.close(fd)
    os.chmod(tmp, 0o644)  # mkstemp makes 0600; figures are for everyone to read
    try:
        fig.savefig(tmp, **savefig_kwargs)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def save_and_close(fig, out_path: str | Path, **savefig_kwargs) -> Path:
    """:func:`save_figure`, then the figure closed whatever happened (pyplot keeps every open
    figure alive: a long run that draws many would grow without it)."""
    import matplotlib.pyplot as plt

    try:
        return save_figure(fig, out_path, **savefig_kwargs)
    finally:
        plt.close(fig)
