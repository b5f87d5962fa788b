"""DVC stage ``report``: the paper's tables, the figures and ``reports/index.html``.

Reads every rig's metrics (``<paths.metrics>/<rig>/{methods,samplers,kernels}/``), test
clip names and train corpus (``<paths.data>/<rig>/corpus/``); writes
``<paths.reports>/index.html``, ``<paths.reports>/tables/`` and
``<paths.reports>/figures/results/``. A missing metrics file is an error that lists it.

Which rows are expected: methods, samplers and kernels come from the ``evaluate`` config
(what the evaluate stages ran), the rigs of Table 2 and the kernel table from
``pipeline.sweep_rigs``, Table 1's rigs from the lists its families run
(``pipeline.table1_rigs``, ``mesh_table1_rigs``, ``blender_rigs``), users' own .blend files
(Tables 1 and 3) from the ``blend_file:<stem>`` names in ``pipeline.blender_rigs``, the
network rows' sampler from ``sampler``; a ``report`` block, if the config has one, may set
``rigs``, ``excluded_methods``, ``clips`` (see rigmap.reports.settings.ReportSettings):

    python pipelines/report.py
    python pipelines/report.py '+report.rigs=[quadruped,biped]'
"""

from __future__ import annotations

from pathlib import Path

import yaml
from omegaconf import DictConfig, OmegaConf, open_dict

from rigmap.app.inputs import layout_of
from rigmap.app.objects import sampler_name
from rigmap.app.stage import run_stage
from rigmap.catalog import Catalogue, packaged_conf, read_catalogue
from rigmap.reports import ReportFiles, ReportSettings, build_report
from rigmap.reports.tables import BLEND_FILE_PREFIX

PARAMS_FILE = Path("params.yaml")  # DVC runs the stage at the repository root


def report_catalogue() -> Catalogue:
    """The labels of the rows: the package's config and every folder on Hydra's search path
    (a part added in another config folder, e.g. a plugin's, is labelled as its class says)."""
    from hydra.core.hydra_config import HydraConfig

    folders = [packaged_conf()]
    sources = HydraConfig.get().runtime.config_sources if HydraConfig.initialized() else []
    for source in sources:
        folder = Path(source.path)
        if source.schema == "file" and folder.is_dir():
            if folder.resolve() not in [f.resolve() for f in folders]:
                folders.append(folder)
    return read_catalogue(folders)


def report_settings(cfg: DictConfig) -> ReportSettings:
    """Expected rows: the ``evaluate`` lists, the network's sampler, then ``report``."""
    values: dict = {"catalogue": report_catalogue()}
    evaluate = cfg.get("evaluate")
    if evaluate is not None:
        for key in ("methods", "samplers", "kernels", "clips"):
            if evaluate.get(key) is not None:
                values[key] = list(evaluate[key])
    pipeline = cfg.get("pipeline")
    if pipeline is not None and pipeline.get("sweep_rigs") is not None:
        values["sampler_rigs"] = list(pipeline.sweep_rigs)  # what the sweep stages ran
    if pipeline is not None and pipeline.get("blender_rigs") is not None:
        blender = [str(rig) for rig in pipeline.blender_rigs]
        own = [rig for rig in blender if rig.startswith(BLEND_FILE_PREFIX)]  # users' .blend files
        values["blend_file_rigs"] = own
        values["method_rigs"] = [  # what the Table 1 families evaluated
            *pipeline.get("table1_rigs", []),
            *pipeline.get("mesh_table1_rigs", []),
            *[rig for rig in blender if rig not in own],
        ]
    if cfg.get("sampler") is not None and cfg.sampler.get("_target_") is not None:
        values["nn_sampler"] = sampler_name(cfg.sampler)
    report = cfg.get("report")
    if report is not None:
        values.update(OmegaConf.to_container(report, resolve=True))
    return ReportSettings.from_mapping(values)


def with_pipeline_lists(cfg: DictConfig, params_file: Path = PARAMS_FILE) -> DictConfig:
    """``cfg`` with params.yaml's ``pipeline`` lists when the stage config dropped them.

    Stages run without ``pipeline`` (rigmap.stage.stage_config); the report needs its lists
    of the rigs each table's stages ran (``sweep_rigs``, ``table1_rigs``, ``mesh_table1_rigs``,
    ``blender_rigs`` with the users' files), and params.yaml is where DVC recorded them (param
    dependencies of this stage: ``dvc exp run -S`` changes them there, not in conf/).
    """
    if cfg.get("pipeline") is not None or not params_file.is_file():
        return cfg
    lists = (yaml.safe_load(params_file.read_text()) or {}).get("pipeline")
    if lists is None:
        return cfg
    with open_dict(cfg):
        cfg.pipeline = lists
    return cfg


def run(cfg: DictConfig) -> ReportFiles:
    cfg = with_pipeline_lists(cfg)
    layout = layout_of(cfg)
    files = build_report(
        metrics_root=layout.metrics,
        data_root=layout.data,
        reports_root=layout.reports,
        settings=report_settings(cfg),
    )
    for name, paths in files.tables.items():
        print(f"{name}: " + ", ".join(str(p) for p in paths.values()))
    for figure in files.figures:
        print(f"figure: {figure.path}")
    for note in files.notes:
        print(f"note: {note}")
    print(f"report: {files.index}")
    return files


if __name__ == "__main__":
    run_stage(run)
