"""DVC stage ``edits``: edit propagation (002), one subject a run.

One script for the three steps of :mod:`rigmap.edits.steps` (``run_fit``, ``run_apply``,
``run_evaluate``): all three in that order, or the one ``+edits_step`` names:

    python pipelines/edits.py +edits=default                        # the subjects of edits.run
    python pipelines/edits.py +edits=default +edits_step=apply 'edits.run=[cmu_131]'  # CMU only
    python pipelines/edits.py +edits=default +edits_subject=cmu_07  # one subject

The DVC stage runs one subject each (``+edits_subject=@item.subject``: a matrix entry is a
name, never a list pasted into a command); its three steps share their inputs, so one stage
runs them (each step a stage of its own cost three start-ups and nothing else).
"""

from __future__ import annotations

from omegaconf import DictConfig

from rigmap.app.edits import run_edits_steps
from rigmap.app.stage import run_stage


def run(cfg: DictConfig):
    return run_edits_steps(cfg)


if __name__ == "__main__":
    run_stage(run)
