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

from omegaconf import DictConfig, OmegaConf

from rigmap.app.stage import run_stage
from rigmap.edits import steps
from rigmap.edits.representation import TargetError
from rigmap.store import Layout

STEPS = ("fit", "apply", "evaluate")


def run(cfg: DictConfig):
    if "edits" not in cfg:
        raise TargetError("no edits config: add +edits=default to the command")
    step = cfg.get("edits_step")
    if step is not None and step not in STEPS:
        raise TargetError(f"+edits_step: expected one of {STEPS}, got {step!r}")
    config = OmegaConf.to_container(cfg.edits, resolve=True)
    subject = cfg.get("edits_subject")
    if subject is not None:
        config["run"] = [str(subject)]
    layout = Layout.from_paths(OmegaConf.to_container(cfg.paths, resolve=True))
    chosen = STEPS if step is None else (step,)
    return [path for name in chosen for path in getattr(steps, f"run_{name}")(config, layout)]


if __name__ == "__main__":
    run_stage(run)
