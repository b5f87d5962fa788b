"""DVC stage ``simulate``: the squirrel simulated as a soft body in Blender and mapped back
onto its rig (paper §6.3, Fig. 9).

Simulates the rig's rest mesh (dropped, squashed, pushed; ``conf/simulate.yaml``) in a
Blender worker, fits the vertex subset's mapping on the rig's train corpus and poses, maps
and refines every frame, and writes ``<paths.data>/<rig>/simulate/`` (sim.npz,
controls.parquet, frames.csv, model/), ``<paths.metrics>/<rig>/simulate/summary.json``
and ``<paths.reports>/figures/simulate_<rig>.png``. The work is :mod:`rigmap.app.simulate`.

    python pipelines/simulate.py rig=squirrel
"""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf

from rigmap.app.simulate import simulate_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig) -> dict:
    return simulate_from_config(OmegaConf.to_container(cfg, resolve=True))


if __name__ == "__main__":
    run_stage(run, config_name="simulate")
