"""``rigmap synth fit|match|run|demo``: latent synthesis (Bailey et al. 2016) from the shell.

``fit`` and ``match`` run the latent stage's ``fit`` / ``match`` steps in this process
with Hydra overrides; ``run`` plays a timed YAML command script with the fitted models
into a controls parquet; ``demo`` is the headless interactive demo, a small game loop
(noughts and crosses, as the paper's Tic-Tac-Toe) whose events each submit an emotion's
commands to the real-time controller, one ``step()`` per frame.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rigmap.app.arguments import override_arguments

OVERRIDES = (
    "rig=face|squirrel|arkit_face, latent.max_iter=, latent.n_pca=, latent.labels=, paths.*="
)


def add_synth_command(commands, compose_config, find_config_dir) -> None:
    synth = commands.add_parser(
        "synth",
        help="latent synthesis: fit GPLVMs per label, match them, play command scripts",
        description="Latent synthesis (Bailey, Watt & O'Brien 2016; rigmap.latent): one "
        "scaling → PCA → GPLVM model per labelled set of a rig's keyframed motion, matching "
        "points between every pair, and a particle driven by MOVE / IDLE / TRANSITION / PLAY "
        "commands. Settings: conf/latent/default.yaml (latent.*).",
    )
    verbs = synth.add_subparsers(title="synth commands", metavar="SYNTH_COMMAND")
    for verb, what in (
        ("fit", "fit one latent model per label into outputs/models/<rig>/latent/fit/"),
        (
            "match",
            "find matching points of every model pair into outputs/models/<rig>/latent/match/",
        ),
    ):
        command = verbs.add_parser(
            verb,
            help=what,
            description=f"Runs the latent_{verb} stage (pipelines/latent.py "
            f"+latent_step={verb}) in this process: {what}. Example: rigmap synth {verb} "
            "rig=face latent.max_iter=100 latent.log_to_mlflow=false. Writes under outputs/ "
            "(paths.models=DIR names another folder), relative to the working directory.",
        )
        if verb == "fit":
            _takes_options(command)
        override_arguments(command, "config", OVERRIDES)
        command.set_defaults(run=lambda args, verb=verb: _stage(verb, args, compose_config))
    run = verbs.add_parser(
        "run",
        help="play a timed YAML command script into a controls parquet",
        description="Plays a command script (conf/latent/scripts/<name>.yaml, or a path to a "
        ".yaml: `start: <model>` and a list of commands such as `- move: {take: happy 1, "
        "frame: 20}`, `- idle: {frames: 48}`, `- transition: {model: roar}`, `- play: {take: "
        "roar 0}`) with the models of `rigmap synth fit` and `match`, 24 frames a second, "
        "and writes one row per frame (frame, one column per used control); an --out ending in "
        ".csv is a Live Link Face CSV instead (a rig whose controls are ARKit blendshapes), "
        "one ending in .blend a file Blender opens and plays (a Blender rig: its file with the "
        "keys on its controls; a mesh rig such as the ARKit face: its mesh with a shape key a "
        "control). Unknown models "
        "or takes are errors naming them. Example: rigmap synth run roar_after_idle rig=face "
        "--out shot.parquet (overrides right after the script, options after them).",
    )
    run.add_argument("script", help="a script name (conf/latent/scripts/) or a .yaml path")
    run.add_argument(
        "--out",
        type=Path,
        required=True,
        help="controls parquet to write, a Live Link Face .csv (ARKit-named controls) or a .blend",
    )
    run.add_argument("--seed", type=int, default=0, help="seed of the particle's random force")
    override_arguments(run, "config", OVERRIDES)
    run.set_defaults(run=lambda args: _run(args, compose_config))
    demo = verbs.add_parser(
        "demo",
        help="headless interactive demo: a game loop driving the controller",
        description="A headless game of noughts and crosses (the paper's Tic-Tac-Toe demo) "
        "between two seeded random players; each event (a move, a threat, a win, a loss, a "
        "draw) submits an emotion's commands (TRANSITION to it, PLAY one of its takes) to the "
        "real-time controller, which is stepped once per frame at 24 fps. Prints the events, "
        "the frames and the controller's frames per second and p99 frame time. Example: "
        "rigmap synth demo rig=face --games 2 --out demo.parquet.",
    )
    demo.add_argument("--games", type=int, default=1, help="games to play (default 1)")
    demo.add_argument("--seed", type=int, default=0, help="seed of the players and the particle")
    demo.add_argument("--frames-per-turn", type=int, default=24, help="frames between turns")
    demo.add_argument("--out", type=Path, default=None, help="controls parquet to write (opt.)")
    override_arguments(demo, "config", OVERRIDES)
    demo.set_defaults(run=lambda args: _demo(args, compose_config))


def _takes_options(command) -> None:
    command.add_argument(
        "--takes",
        type=Path,
        default=None,
        help="your own labelled takes (latent.takes): a label YAML of segments (of Live Link "
        "Face CSVs, a controls table or a .blend), a controls table (.csv/.parquet: a column "
        "per used control, named as the rig names them, and a `label` column; optional "
        "`frame` and `take`), or a .blend whose actions are the takes (then rig=blend_file "
        "rig.path=FILE unless you name the rig)",
    )
    command.add_argument(
        "--label-pattern",
        default=None,
        help="a .blend action's label: this regular expression's `label` group, else its "
        "first group, else its match (default: the name's leading letters, happy_02 -> happy)",
    )


def takes_overrides(args) -> list[str]:
    """Hydra overrides of ``--takes``: a .blend's actions are takes of the rig in that file,
    so ``rig=blend_file rig.path=FILE`` unless the overrides name a rig."""
    takes = getattr(args, "takes", None)
    if takes is None:
        return []
    takes = takes.expanduser().resolve()
    if not takes.exists():
        raise FileNotFoundError(f"--takes: {takes} does not exist")
    named_rig = any(o.split("=", 1)[0].lstrip("+~") == "rig" for o in args.overrides)
    if takes.suffix.lower() == ".blend" and not named_rig:
        return ["rig=blend_file", f"rig.path={takes}"]
    return []


def _stage(verb: str, args, compose_config) -> int:
    from omegaconf import open_dict

    from rigmap.app.latent import run_step
    from rigmap.user_outputs import user_paths

    overrides = [*user_paths(args.overrides), *takes_overrides(args), *args.overrides]
    cfg = compose_config([f"+latent_step={verb}", *overrides], args.config_dir)
    if getattr(args, "takes", None) is not None:  # set, not a Hydra override: any path text
        with open_dict(cfg):
            cfg.latent.takes = str(args.takes.expanduser().resolve())
            cfg.latent.label_pattern = args.label_pattern
    print(run_step(cfg))
    return 0


def _loaded(args, compose_config, script: str | None = None):
    """The rig, the latent config and the fitted models; ``script`` is read (and checked)
    before the models load."""
    from rigmap.app.inputs import layout_of, rig_from_config
    from rigmap.app.latent import fitted_models_config, latent_config
    from rigmap.latent import steps

    cfg = fitted_models_config(args.overrides, args.config_dir, compose_config)
    config = latent_config(cfg)
    if script is not None:
        steps.read_script(steps.script_path(script), max_frames=steps.max_script_frames(config))
    rig, layout = rig_from_config(cfg.rig), layout_of(cfg)
    return rig, config, steps.load_fitted(layout, rig.name), steps.load_table(layout, rig.name)


def _run(args, compose_config) -> int:
    from rigmap.latent import steps
    from rigmap.latent.live_link import live_link_columns, write_take

    rig, config, fitted, table = _loaded(args, compose_config, script=args.script)
    suffix = args.out.suffix.lower()
    as_csv = suffix == ".csv"
    columns = live_link_columns(rig.used_controls) if as_csv else None  # before playing
    if suffix == ".blend":
        blend_writer(rig)  # before playing: a rig with no .blend form is refused first
    P, controller = steps.play_script(
        fitted,
        table,
        steps.script_path(args.script),
        seed=args.seed,
        blend_frames=int(config["blend_frames"]),
        max_frames=steps.max_script_frames(config),
        progress=True,
    )
    fps = steps.fps_of(config, rig)
    meta = {"rig": rig.name, "script": str(args.script), "seed": args.seed, "fps": fps}
    if as_csv:  # a Live Link Face CSV: plays on any ARKit-driven face
        write_take(args.out, P, columns, fps=fps)
    elif suffix == ".blend":
        import pandas as pd

        table = pd.DataFrame(np.asarray(P), columns=list(rig.used_controls))
        table.insert(0, "frame", np.arange(len(P)))
        blend_writer(rig)(rig, table, args.out, fps=fps, action_name=Path(args.script).stem)
    else:
        steps.write_controls(args.out, rig, P, meta)
    for row in steps.log_rows(controller):
        state = "ok" if row["success"] else "not met"
        print(f"  {row['command']:<10} {row['model']:<10} {row['frames']:>4} frames  {state}")
    print(f"{args.out}: {len(P)} frames ({len(P) / fps:.1f} s)")
    return 0


def blend_writer(rig):
    """:func:`rigmap.rigs.blender.lookup.blend_writer`, its refusal naming ``--out``."""
    from rigmap.rigs.blender.writers import blend_writer as writer_of

    try:
        return writer_of(rig)
    except ValueError as error:
        raise ValueError(f"--out: {error}; write a .parquet") from None


def _demo(args, compose_config) -> int:
    from rigmap.latent import steps
    from rigmap.latent.game import EVENT_EMOTIONS, emotion_commands, game_events
    from rigmap.latent.synthesis import Controller

    rig, _, fitted, table = _loaded(args, compose_config)
    rng = np.random.default_rng(args.seed)
    start = "neutral" if "neutral" in fitted.models else next(iter(fitted.models))
    ctrl = Controller(
        fitted.models, start=start, takes=fitted.sets, transitions=table, seed=args.seed
    )
    frames, times = [], []
    for game in range(args.games):
        for player, event in game_events(rng):
            emotion = EVENT_EMOTIONS[event]
            model_now = ctrl.model_after_queue()
            for command in emotion_commands(fitted, model_now, emotion, rng):
                ctrl.submit(command)
            print(f"game {game + 1}: {player} {event:<14} → {emotion}", flush=True)
            for _ in range(args.frames_per_turn):  # the game waits for the next turn
                t0 = time.perf_counter()
                frames.append(ctrl.step())
                times.append(time.perf_counter() - t0)
        while ctrl.busy:
            t0 = time.perf_counter()
            frames.append(ctrl.step())
            times.append(time.perf_counter() - t0)
    times_ms = 1e3 * np.array(times)
    print(
        f"{len(frames)} frames; controller {1e3 / times_ms.mean():.0f} frames/s, "
        f"p99 {np.percentile(times_ms, 99):.1f} ms a frame (24 fps needs 41.7 ms)"
    )
    if args.out is not None:
        meta = {"rig": rig.name, "demo": "noughts and crosses", "seed": args.seed}
        steps.write_controls(args.out, rig, np.array(frames), meta)
        print(args.out)
    return 0
