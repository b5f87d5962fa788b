"""What the latent stage's four steps do, from a plain config dict, a rig and a :class:`Layout`.

- :func:`run_fit` (step ``fit``): the rig's labelled sets, one scaling → PCA → GPLVM
  model per label → ``models/<rig>/latent/fit/models.{json,npz}`` and ``fit.json``;
- :func:`run_match` (step ``match``): matching points of every model pair (§5.2) →
  ``models/<rig>/latent/match/transitions.{json,npz}`` and ``match.json``;
- :func:`run_synthesize` (step ``synthesize``): every command script of the rig played
  by the controller once per seed → ``data/<rig>/latent/<script>-seed<k>.parquet``
  (frame, one column per used control) and ``log.json`` (each command's frames, success);
- :func:`run_evaluate` (step ``evaluate``): the measurements of
  :mod:`rigmap.latent.measures` → ``metrics/<rig>/latent/summary.json`` and one CSV per
  table, and Fig 2 → ``reports/figures/latent_<rig>.png``.

The models are arrays + JSON (:mod:`rigmap.latent.files`): nothing is unpickled, so a
tampered model file in the DVC cache or remote is refused, never run.
"""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.latent import files
from rigmap.latent.captured_sets import captured_sets
from rigmap.latent.errors import LatentInputError
from rigmap.latent.gplvm import GPLVMSettings
from rigmap.latent.library import FittedModels, fit_models, rig_sets
from rigmap.latent.scripts import MAX_SCRIPT_FRAMES, MAX_SCRIPT_FRAMES_LIMIT, read_script
from rigmap.latent.synthesis import Controller, SynthesisSettings
from rigmap.latent.transitions import TransitionTable, match_models
from rigmap.store import Layout, json_ready, write_json_atomic, write_text_atomic
from rigmap.store.layout import LATENT
from rigmap.store.table_file import write_table_file

SCRIPTS_DIR = Layout.latent_scripts()
CONTROLS_KEY = b"rigmap.latent_controls"


def settings_of(config: dict, **changes) -> GPLVMSettings:
    values = {
        "latent_dim": int(config["latent_dim"]),
        "max_iter": int(config["max_iter"]),
        "connectivity": bool(config["connectivity"]),
        "seed": int(config.get("seed", 0)),
    }
    return GPLVMSettings(**{**values, **changes})


def n_pca_of(config: dict, rig=None) -> int | None:
    """``latent.n_pca`` if set, else ``latent.<rig>_n_pca`` if the rig has one; ``None``:
    PCA keeps ``latent.variance`` of the variance (the paper's 85 %)."""
    n = config.get("n_pca")
    if n is None and rig is not None:
        n = config.get(f"{rig.name}_n_pca")
    return None if n is None else int(n)


def _written(path: Path, step: str) -> Path:
    """``path``'s folder, or the error that says which step writes it."""
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist; run the latent {step} step first")
    return path.parent


def fps_of(config: dict, rig) -> float:
    """``latent.<rig>_fps`` if set (captured takes at their own rate), else ``latent.fps``."""
    return float(config.get(f"{rig.name}_fps") or config["fps"])


def takes_file(config: dict, rig) -> Path | None:
    """``latent.takes`` (a user's file: a label YAML, a controls table or a .blend, relative
    to the working directory), else ``latent.<rig>_takes`` (relative to ``conf/latent/``),
    else ``None`` for a rig whose sets are its motion library's."""
    if config.get("takes"):
        return Path(str(config["takes"])).expanduser().resolve()
    named = config.get(f"{rig.name}_takes")
    if not named:
        return None
    path = Path(str(named)).expanduser()
    return path if path.is_absolute() else SCRIPTS_DIR.parent / path


def sets_of(config: dict, rig, *, heldout: bool = False):
    captured = takes_file(config, rig)
    if captured is not None:
        return captured_sets(
            rig,
            captured,
            fps=fps_of(config, rig),
            size=str(config["size"]),
            labels=config.get("labels"),
            heldout=heldout,
            label_pattern=config.get("label_pattern"),
        )
    return rig_sets(
        rig,
        seed=int(config.get("seed", 0)),
        size=str(config["size"]),
        labels=config.get("labels"),
        heldout=heldout,
    )


def run_fit(config: dict, rig, layout: Layout) -> Path:
    sets = sets_of(config, rig)
    fitted = fit_models(
        rig,
        sets,
        fps=fps_of(config, rig),
        settings=settings_of(config),
        variance=float(config["variance"]),
        n_pca=n_pca_of(config, rig),
    )
    folder = layout.latent_fit(rig.name)
    files.save_fitted(folder, fitted)
    info = {
        label: {
            "frames": sets[label].n_frames,
            "takes": sets[label].names,
            "pca_dims": int(m.pca.n_components_),
            "latent_dim": int(m.gplvm.settings.latent_dim),
            "fit_s": fitted.fit_seconds[label],
            "lbfgs_iterations": m.gplvm.iterations,
            "objective_start": m.gplvm.history[0],
            "objective_end": m.gplvm.history[-1],
        }
        for label, m in fitted.models.items()
    }
    return write_json_atomic(folder / "fit.json", json_ready(info))


def load_fitted(layout: Layout, rig: str) -> FittedModels:
    """The ``fit`` step's models (arrays + JSON, checked; never unpickled)."""
    return files.load_fitted(_written(layout.latent_fit(rig) / "models.json", "fit"))


def load_table(layout: Layout, rig: str) -> TransitionTable:
    """The ``match`` step's matching points (arrays + JSON, checked)."""
    folder = _written(layout.latent_match(rig) / "transitions.json", "match")
    return files.load_table(folder)


def match_threshold(config: dict, rig) -> float:
    """``latent.<rig>_match_threshold_cm`` if set (a rig measured on joints, not a mesh,
    needs its own), else ``latent.match_threshold_cm``."""
    return float(config.get(f"{rig.name}_match_threshold_cm") or config["match_threshold_cm"])


def run_match(config: dict, rig, layout: Layout) -> Path:
    fitted = load_fitted(layout, rig.name)
    start = time.perf_counter()
    table = match_models(
        rig,
        fitted.models,
        threshold_cm=match_threshold(config, rig),
        max_iter=int(config["match_max_iter"]),
    )
    seconds = time.perf_counter() - start
    folder = layout.latent_match(rig.name)
    files.save_table(folder, table)
    from rigmap.latent.measures import matching_rows

    info = {
        "threshold_cm": table.threshold_cm,
        "seconds": seconds,
        "pairs": matching_rows(table, list(fitted.models)),
    }
    return write_json_atomic(folder / "match.json", json_ready(info))


def script_names(config: dict, rig) -> list[str]:
    key = "scripts" if rig.name == "face" else f"{rig.name}_scripts"
    if key not in config:
        raise LatentInputError(f"latent.{key}: no command scripts configured for {rig.name!r}")
    return list(config[key])


def script_path(name: str) -> Path:
    path = Path(name)
    if path.suffix in (".yaml", ".yml"):
        return path
    path = SCRIPTS_DIR / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in SCRIPTS_DIR.glob("*.yaml"))
        raise LatentInputError(f"no command script {name!r}; scripts: {known} or a .yaml path")
    return path


def play_script(
    fitted,
    table,
    path,
    *,
    seed: int,
    blend_frames: int = 12,
    max_frames: int = MAX_SCRIPT_FRAMES,
    progress: bool = False,
):
    """``(controls (F, C), controller)`` of one command script played to its end (at
    most ``max_frames`` frames, ``latent.max_script_frames``)."""
    start, commands = read_script(path, max_frames=max_frames)
    start = start or next(iter(fitted.models))
    controller = Controller(
        fitted.models,
        start=start,
        takes=fitted.sets,
        transitions=table,
        seed=seed,
        settings=SynthesisSettings(blend_frames=blend_frames),
    )
    return controller.run(commands, max_frames=max_frames, progress=progress), controller


def max_script_frames(config: dict) -> int:
    """``latent.max_script_frames``: a whole number from 1 to :data:`MAX_SCRIPT_FRAMES_LIMIT`
    (default :data:`MAX_SCRIPT_FRAMES`; both ours)."""
    value = config.get("max_script_frames", MAX_SCRIPT_FRAMES)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise LatentInputError(f"latent.max_script_frames={value!r}: expected a whole number >= 1")
    if value > MAX_SCRIPT_FRAMES_LIMIT:
        raise LatentInputError(
            f"latent.max_script_frames={value}: expected at most {MAX_SCRIPT_FRAMES_LIMIT} "
            "(every frame's controls are held in memory)"
        )
    return value


def write_controls(path: Path, rig, P: np.ndarray, metadata: dict) -> Path:
    table = pd.DataFrame(np.asarray(P), columns=list(rig.used_controls))
    table.insert(0, "frame", np.arange(len(P)))
    return write_table_file(path, table, CONTROLS_KEY, json_ready(metadata), what="controls")


def read_controls(layout: Layout, rig, script: str, seed: int) -> np.ndarray:
    """Used-control values ``(F, C)`` of one script's run by the ``synthesize`` step."""
    from rigmap.store.table_file import read_table_file

    path = layout.app_data(rig.name, LATENT) / f"{Path(script).stem}-seed{seed}.parquet"
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist; run the latent synthesize step first")
    table, _ = read_table_file(path, CONTROLS_KEY, what="controls")
    return table[list(rig.used_controls)].to_numpy(np.float64)


def log_rows(controller) -> list[dict]:
    return [
        {
            "command": type(e.command).__name__.upper(),
            "model": e.model,
            "start": e.start,
            "frames": e.frames,
            "success": bool(e.success),
        }
        for e in controller.log
    ]


def run_synthesize(config: dict, rig, layout: Layout) -> Path:
    cap = max_script_frames(config)
    for name in script_names(config, rig):  # every script checked before the models load
        read_script(script_path(name), max_frames=cap)
    fitted, table = load_fitted(layout, rig.name), load_table(layout, rig.name)
    folder = layout.app_data(rig.name, LATENT)
    log = {}
    for name in script_names(config, rig):
        for seed in config["seeds"]:
            P, controller = play_script(
                fitted,
                table,
                script_path(name),
                seed=int(seed),
                blend_frames=int(config["blend_frames"]),
                max_frames=cap,
            )
            meta = {"rig": rig.name, "script": name, "seed": int(seed), "fps": fps_of(config, rig)}
            write_controls(folder / f"{Path(name).stem}-seed{seed}.parquet", rig, P, meta)
            log[f"{Path(name).stem}-seed{seed}"] = log_rows(controller)
    return write_json_atomic(folder / "log.json", json_ready(log))


def csv_text(rows: list[dict]) -> str:
    out = io.StringIO()
    if rows:
        writer = csv.DictWriter(out, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(json_ready(rows))
    return out.getvalue()


def write_tables(folder: Path, tables: dict[str, list[dict]]) -> None:
    for name, rows in tables.items():
        write_text_atomic(folder / f"{name}.csv", csv_text(rows))


def _measure(config: dict, rig, fitted, table, heldout) -> tuple[dict, dict]:
    """Every measurement: ``(summary, tables)``."""
    from rigmap.latent import measures as m

    ev, fps, fraction = config["evaluate"], fps_of(config, rig), float(config["variance"])
    variance = (fraction, n_pca_of(config, rig))
    labels, seed = list(fitted.models), int(config.get("seed", 0))
    sets, settings = fitted.sets, settings_of(config)
    P = np.vstack([s.values for s in sets.values()])
    P_test = np.vstack([heldout[label].values for label in labels])
    compare = settings_of(config, max_iter=int(ev.get("compare_max_iter") or config["max_iter"]))
    fit = {"fps": fps, "variance": variance}  # how every refit below is made
    data = (rig, sets, heldout)  # what the two sweeps fit on and test on
    jobs = {
        "pca": lambda: [
            {
                "model": label,
                "model_pca_dims": int(model.pca.n_components_),
                **{
                    f"{k}_at_{fraction:g}": v
                    for k, v in m.pca_dims(rig, sets[label].values, fraction).items()
                },
            }
            for label, model in fitted.models.items()
        ],
        "scaling": lambda: m.scaled_against_unscaled(rig, P, P_test, ev["pca_sizes"]),
        "latent_dims": lambda: m.latent_dim_sweep(
            *data,
            labels[: int(ev["sweep_labels"])],
            ev["latent_dims"],
            settings=settings,
            fitted=fitted,
            **fit,
        ),
        "one_vs_per_label": lambda: m.one_against_per_label(
            *data,
            labels[: int(ev["compare_labels"])],
            ev["compare_dims"],
            settings=compare,
            **fit,
        ),
        "matching": lambda: m.matching_rows(table, labels),
        "smoothness": lambda: m.transition_smoothness(
            rig,
            fitted,
            table,
            m.ordered_pairs(labels, int(ev["smoothness_pairs"])),
            starts=int(ev["transition_starts"]),
            seed=seed,
            fps=fps,
        ),
        "suites": lambda: m.command_suites(fitted, table, n=int(ev["suite_commands"]), seed=seed),
        "fit_time": lambda: [
            {"model": label, "frames": sets[label].n_frames, "fit_s": fitted.fit_seconds[label]}
            for label in labels
        ],
    }
    tables, seconds = {}, {}
    for name, job in jobs.items():
        started = time.perf_counter()
        tables[name] = job()
        seconds[name] = time.perf_counter() - started
    extra = {"pca_dims_all_labels": m.pca_dims(rig, P, fraction), "seconds": seconds}
    return _summary(tables, **extra), tables


def _summary(tables: dict, **extra) -> dict:
    def column(name, key):
        return [row[key] for row in tables[name] if row.get(key) is not None]

    def median(name, key):
        values = column(name, key)
        return float(np.median(values)) if values else None

    sweep: dict[int, list[float]] = {}
    for row in tables["latent_dims"]:
        sweep.setdefault(row["latent_dim"], []).append(row["surface_rms_cm"])
    points = column("matching", "points")
    return {
        "metrics_are_rigmaps_own": True,
        "pca_dims_at_85": {
            r["model"]: r["scaled_at_0.85"] for r in tables["pca"] if "scaled_at_0.85" in r
        },
        "model_pca_dims": {r["model"]: r["model_pca_dims"] for r in tables["pca"]},
        **extra,
        "heldout_surface_rms_cm_by_latent_dim": {q: float(np.mean(v)) for q, v in sweep.items()},
        "matching_points": {
            "min": min(points),
            "median": float(np.median(points)),
            "max": max(points),
            "pairs_without": points.count(0),
        },
        "matching_spread_latent_median": median("matching", "spread_latent"),
        "matching_distance_cm_median": median("matching", "distance_cm_median"),
        "smoothness": {
            key: median("smoothness", key) for key in tables["smoothness"][0] if key != "pair"
        },
        "suites": {
            r["command"]: {"success_rate": r["success_rate"], "frames_median": r["frames_median"]}
            for r in tables["suites"]
        },
    }


def run_evaluate(config: dict, rig, layout: Layout) -> Path:
    fitted, table = load_fitted(layout, rig.name), load_table(layout, rig.name)
    heldout = sets_of(config, rig, heldout=True)
    summary, tables = _measure(config, rig, fitted, table, heldout)
    from rigmap.latent.measures import seed_spread

    for name in script_names(config, rig):  # the synthesize stage's runs of each script
        played = [read_controls(layout, rig, name, int(seed)) for seed in config["seeds"]]
        summary.setdefault("seed_repeats", {})[Path(name).stem] = seed_spread(rig, played)
    folder = layout.app_metrics(rig.name, LATENT)
    write_tables(folder, tables)
    from rigmap.latent.figures import draw_latent_spaces

    draw_latent_spaces(
        rig,
        fitted,
        settings_of(config, connectivity=False),
        fps_of(config, rig),
        (float(config["variance"]), n_pca_of(config, rig)),
        layout.figures() / f"latent_{rig.name}.png",
        labels=list(fitted.models)[: int(config["evaluate"].get("figure_labels", 2))],
    )
    return write_json_atomic(folder / "summary.json", json_ready(summary))
