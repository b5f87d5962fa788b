"""DVC stage ``edit_fit``: edit propagation (002), :func:`rigmap.edits.runs.run_fit`.

python pipelines/edit_fit.py +edits=default                      # both subjects
python pipelines/edit_fit.py +edits=default 'edits.run=[cmu_131]'  # skeleton mode only
"""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf

from rigmap.edits.representation import TargetError
from rigmap.edits.runs import run_fit
from rigmap.stage import run_stage
from rigmap.store import Layout


def run(cfg: DictConfig):
    if "edits" not in cfg:
        raise TargetError("no edits config: add +edits=default to the command")
    config = OmegaConf.to_container(cfg.edits, resolve=True)
    return run_fit(config, Layout.from_paths(OmegaConf.to_container(cfg.paths, resolve=True)))


if __name__ == "__main__":
    run_stage(run)
