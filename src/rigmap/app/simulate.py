"""``rigmap simulate`` and the ``simulate`` stage: Fig. 9 with a real simulator (§6.3).

From the config (``conf/simulate.yaml`` composed by Hydra, resolved to plain containers):

1. the squirrel's rest mesh is simulated in a Blender worker as a soft body, dropped,
   squashed and pushed (:func:`rigmap.simulation.soft_body.simulate_soft_body`), and its
   vertices are written as ``sim.npz`` (rigmap's joint-tracks format: cm, Y up) — or
   ``input=`` names such a file made before, and it is read instead;
2. the vertex subset ``simulate.subset`` names gets its mapping, fitted on the rig's train
   corpus and poses (the map's :func:`~rigmap.map.subset_model.obtain_subset_model`,
   cached beside the outputs in ``model/``); each frame is guessed and refined
   (:func:`rigmap.simulation.vertex_mapping.map_vertices`);
3. the controls are written as ``controls.parquet`` (``frame`` and every control, as
   ``rigmap map`` writes them), the scores as ``summary.json`` and the per-frame ones as
   ``frames.csv`` (:mod:`rigmap.simulation.metrics`), and the figure
   (:mod:`rigmap.simulation.figure`).

The stage (``pipelines/simulate.py``) writes ``<paths.data>/<rig>/simulate/`` (sim.npz,
controls.parquet, frames.csv, model/), ``<paths.metrics>/<rig>/simulate/summary.json`` (a
folder of JSON only: DVC reads it as metrics) and ``<paths.reports>/figures/simulate_<rig>.png``;
``rigmap simulate`` writes all of them into one folder, ``out=`` (default
``outputs/simulate/<rig>/``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rigmap.map.clip import MapSettings
from rigmap.store import Layout, write_json_atomic, write_text_atomic
from rigmap.store.layout import MAP_STAGE_MODEL

SIMULATE = "simulate"  # the stage's folder under data/<rig>/ and metrics/<rig>/, its verb
SIM_FILE = "sim.npz"
CONTROLS_FILE = "controls.parquet"
SUMMARY_FILE = "summary.json"
FRAMES_FILE = "frames.csv"
Log = Callable[[str], None]


@dataclass(frozen=True)
class SimulateFolders:
    """Where one run writes: the data (simulation, controls, model), metrics, figure."""

    data: Path
    metrics: Path
    figure: Path

    @classmethod
    def of(cls, config: Mapping[str, Any], rig_name: str) -> SimulateFolders:
        if config.get("out"):
            out = Path(config["out"])
            return cls(out, out, out / f"{SIMULATE}_{rig_name}.png")
        layout = Layout.from_paths(config.get("paths"))
        return cls(
            layout.app_data(rig_name, SIMULATE),
            layout.app_metrics(rig_name, SIMULATE),
            layout.figures() / f"{SIMULATE}_{rig_name}.png",
        )


def simulate_config(overrides: list[str], config_dir=None) -> dict[str, Any]:
    """``conf/simulate.yaml`` with ``overrides``, the rig's ``_overrides_`` applied, plain."""
    from rigmap.app.config import compose_config
    from rigmap.app.objects import plain
    from rigmap.app.stage import stage_config

    return plain(stage_config(compose_config(overrides, config_dir, config_name=SIMULATE)))


def simulate_from_config(config: Mapping[str, Any], *, log: Log = print) -> dict:
    """Simulate (or read ``input``), map, score and draw; returns the summary written."""
    from rigmap.rigs import load
    from rigmap.simulation.vertex_mapping import vertex_subset

    options = config[SIMULATE]
    settings = _map_settings(options.get("settings") or {})
    with load({k: v for k, v in dict(config["rig"]).items() if k != "corpus"}) as rig:
        subset = vertex_subset(rig, options["subset"])  # a bad subset before the simulation
        folders = SimulateFolders.of(config, rig.name)
        vertices, fps, facts = _simulation(config, rig, folders, log)
        model = _model(config, rig, subset, folders, log)
        return _map_and_score(rig, vertices, fps, model, settings, folders, facts, options, log)


def _map_settings(values: Mapping) -> MapSettings:
    """``simulate.settings`` as :class:`MapSettings` (a one-line error for an unknown key)."""
    values = dict(values)
    values["hold"] = tuple(values.get("hold") or ())
    try:
        return MapSettings(**values)
    except TypeError as error:
        raise ValueError(f"simulate.settings: {error}") from None


def _simulation(config, rig, folders: SimulateFolders, log: Log):
    """The simulated vertices: read from ``input``, or simulated and written."""
    from rigmap.simulation.sim_file import read_vertices, write_simulation
    from rigmap.simulation.soft_body import Scenario, simulate_soft_body

    if config.get("input"):
        vertices, fps = read_vertices(config["input"], rig)
        log(f"{config['input']}: {len(vertices)} frames of {vertices.shape[1]} vertices read")
        return vertices, fps, {"input": str(config["input"])}
    options = config[SIMULATE]
    scenario = Scenario(**options["scenario"])
    sim = simulate_soft_body(rig, scenario, blender=options.get("blender"))
    path = write_simulation(
        folders.data / SIM_FILE,
        sim.vertices,
        rig.joint_names,
        sim.fps,
        rig.faces,
        scenario.to_dict(),
    )
    log(
        f"{path}: {scenario.frames} frames simulated by Blender {sim.info['blender_version']} "
        f"in {sim.info['seconds']:.1f} s"
    )
    return sim.vertices, sim.fps, {"scenario": scenario.to_dict(), "simulation": sim.info}


def _model(config, rig, subset, folders: SimulateFolders, log: Log):
    from rigmap.map.subset_model import obtain_subset_model

    started = time.perf_counter()
    model = obtain_subset_model(
        rig,
        subset,
        Layout.from_paths(config.get("paths")),
        config["regressor"],
        cache=folders.data / MAP_STAGE_MODEL,
        log=log,
    )
    log(
        f"{model.folder}: {len(subset.joints)} vertices' mapping "
        f"({'fitted' if model.refitted else 'cached'}, {time.perf_counter() - started:.1f} s)"
    )
    return model


def _map_and_score(rig, vertices, fps, model, settings, folders, facts, options, log) -> dict:
    from rigmap.simulation.figure import simulation_figure
    from rigmap.simulation.metrics import per_frame, summary
    from rigmap.simulation.vertex_mapping import map_vertices

    mapping = map_vertices(rig, vertices, model, settings)
    controls = pd.DataFrame(mapping.controls, columns=rig.control_names)
    controls.insert(0, "frame", np.arange(len(controls)))
    _write_table(controls, folders.data / CONTROLS_FILE)
    frames = per_frame(rig, vertices, mapping)
    subset = model.mapping.subset
    facts = {
        "fps": fps,
        "subset": {"name": subset.name, "vertices": len(subset.joints)},
        "refine_iterations": settings.refine_iterations,
        **facts,
    }
    headline = summary(rig, frames, mapping, facts)
    write_text_atomic(folders.data / FRAMES_FILE, frames.to_csv(index=False))
    write_json_atomic(folders.metrics / SUMMARY_FILE, headline)
    mapped = np.asarray(rig.world_vertices(mapping.controls))
    simulation_figure(
        rig,
        vertices,
        mapped,
        frames,
        list(options.get("figure_frames", [0])),
        folders.figure,
        fps=fps,
    )
    teeth = headline["teeth_inside_body"]
    log(
        f"{folders.metrics / SUMMARY_FILE}: vertex error {headline['vertex_error_rms_cm']:.2f} cm "
        f"RMS ({headline['vertex_error_rms_percent_of_height']:.2f} % of height), "
        f"{headline['seconds_per_frame'] * 1000:.0f} ms a frame; teeth vertices inside the "
        f"body: simulation {teeth['simulation']['teeth_vertex_frames_inside']}, rig "
        f"{teeth['rig']['teeth_vertex_frames_inside']} (vertex-frames); figure {folders.figure}"
    )
    return headline


def _write_table(table: pd.DataFrame, path: Path) -> None:
    from rigmap.store import atomic_file

    with atomic_file(path, suffix=".parquet") as staging:
        table.to_parquet(staging, index=False)


# --------------------------------------------------------------------------- the verb
def add_simulate_command(commands, compose_config, find_config_dir) -> None:
    """``rigmap simulate KEY=VALUE ...`` (the same work as the stage, into ``outputs/``)."""
    from rigmap.app.arguments import override_arguments

    command = commands.add_parser(
        SIMULATE,
        help="simulate the squirrel as a soft body in Blender and map it onto the rig (Fig. 9)",
        description="Drops, squashes and pushes the squirrel's rest mesh as a soft body in a "
        "Blender worker (Blender's cloth solver with pressure; .venv-blender), writes its "
        "vertices per frame as sim.npz (cm, Y up; rigmap map's joint-tracks format), maps "
        "them onto the rig with a GPR on a vertex subset (simulate.subset, fitted on "
        "data/squirrel/corpus and poses), refines each frame, and writes controls.parquet, "
        "summary.json and frames.csv (vertex error, teeth inside the body, time per frame) "
        "and simulate_<rig>.png into out= (default outputs/simulate/<rig>/). Examples: "
        "rigmap simulate; rigmap simulate seed=3; rigmap simulate "
        "input=outputs/simulate/squirrel/sim.npz.",
    )
    override_arguments(
        command,
        SIMULATE,
        "input=, out=, seed=, simulate.scenario.*=, simulate.subset.*=, "
        "simulate.settings.*=, simulate.figure_frames=, budget.*=, paths.*=",
    )
    command.set_defaults(run=lambda args: _run_verb(args, find_config_dir))


def _run_verb(args, find_config_dir) -> int:
    config = simulate_config(list(args.overrides), find_config_dir(args.config_dir))
    if not config.get("out"):
        config["out"] = str(Layout.user_output(SIMULATE, config["rig"]["name"]))
    simulate_from_config(config)
    return 0
