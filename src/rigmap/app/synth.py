"""``rigmap synth fit|match|run|demo``: latent synthesis (Bailey et al. 2016) from the shell.

``fit`` and ``match`` run the ``latent_fit`` / ``latent_match`` stages in this process
with Hydra overrides; ``run`` plays a timed YAML command script with the fitted models
into a controls parquet; ``demo`` is the headless interactive demo, a small game loop
(noughts and crosses, as the paper's Tic-Tac-Toe) whose events each submit an emotion's
commands to the real-time controller, one ``step()`` per frame.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

OVERRIDES = (
    "rig=face|squirrel|arkit_face, latent.max_iter=, latent.n_pca=, latent.labels=, paths.*="
)

#: the demo's events and the emotion each plays (ours; the paper's game picks per event)
EVENT_EMOTIONS = {
    "own_move": "curious",
    "opponent_move": "neutral",
    "threat": "grumpy",
    "win": "happy",
    "loss": "roar",
    "draw": "bored",
}
LINES = [(0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6), (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6)]


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
        _overrides(command)
        command.set_defaults(run=lambda args, verb=verb: _stage(verb, args, compose_config))
    run = verbs.add_parser(
        "run",
        help="play a timed YAML command script into a controls parquet",
        description="Plays a command script (conf/latent/scripts/<name>.yaml, or a path to a "
        ".yaml: `start: <model>` and a list of commands such as `- move: {take: happy 1, "
        "frame: 20}`, `- idle: {frames: 48}`, `- transition: {model: roar}`, `- play: {take: "
        "roar 0}`) with the models of `rigmap synth fit` and `match`, 24 frames a second, "
        "and writes one row per frame (frame, one column per used control); an --out ending in "
        ".csv is a Live Link Face CSV instead (a rig whose controls are ARKit blendshapes). "
        "Unknown models "
        "or takes are errors naming them. Example: rigmap synth run roar_after_idle rig=face "
        "--out shot.parquet (overrides right after the script, options after them).",
    )
    run.add_argument("script", help="a script name (conf/latent/scripts/) or a .yaml path")
    run.add_argument(
        "--out",
        type=Path,
        required=True,
        help="controls parquet to write, or a Live Link Face .csv (ARKit-named controls)",
    )
    run.add_argument("--seed", type=int, default=0, help="seed of the particle's random force")
    _overrides(run)
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
    _overrides(demo)
    demo.set_defaults(run=lambda args: _demo(args, compose_config))


def _overrides(command) -> None:
    command.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help=f"Hydra overrides of conf/config.yaml ({OVERRIDES})",
    )
    command.add_argument(
        "--config-dir",
        type=Path,
        default=None,
        help="the Hydra conf/ folder (default: ./conf, else the conf/ of rigmap's source checkout)",
    )


def _stage(verb: str, args, compose_config) -> int:
    from rigmap.app.latent import run_step
    from rigmap.user_outputs import user_paths

    overrides = [*user_paths(args.overrides), *args.overrides]  # outputs/, not the tracked ones
    cfg = compose_config([f"+latent_step={verb}", *overrides], args.config_dir)
    print(run_step(cfg))
    return 0


def _loaded(args, compose_config, script: str | None = None):
    """The rig, the latent config and the fitted models; ``script`` is read (and checked)
    before the models load."""
    from rigmap.app.inputs import layout_of, rig_from_config
    from rigmap.app.latent import latent_config
    from rigmap.latent import steps
    from rigmap.store import Layout
    from rigmap.user_outputs import user_paths

    # only --out is written; the models are your own `synth fit` and `match`'s under
    # outputs/ when there, else the pipeline's (models/), unless paths.models=DIR names them
    cfg = compose_config(list(args.overrides), args.config_dir)
    own = user_paths(args.overrides, keys=("models",))
    if own and Layout(models=Layout.user_root("models")).latent_fit(str(cfg.rig.name)).is_dir():
        cfg = compose_config([*own, *args.overrides], args.config_dir)
    config = latent_config(cfg)
    if script is not None:
        steps.read_script(steps.script_path(script), max_frames=steps.max_script_frames(config))
    rig, layout = rig_from_config(cfg.rig), layout_of(cfg)
    return rig, config, steps.load_fitted(layout, rig.name), steps.load_table(layout, rig.name)


def _run(args, compose_config) -> int:
    from rigmap.latent import steps
    from rigmap.latent.live_link import live_link_columns, write_take

    rig, config, fitted, table = _loaded(args, compose_config, script=args.script)
    as_csv = args.out.suffix.lower() == ".csv"
    columns = live_link_columns(rig.used_controls) if as_csv else None  # before playing
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
    else:
        steps.write_controls(args.out, rig, P, meta)
    for row in steps.log_rows(controller):
        state = "ok" if row["success"] else "not met"
        print(f"  {row['command']:<10} {row['model']:<10} {row['frames']:>4} frames  {state}")
    print(f"{args.out}: {len(P)} frames ({len(P) / fps:.1f} s)")
    return 0


def game_events(rng) -> list[tuple[str, str]]:
    """One random game: ``(player, event)`` per turn, ``player`` "x" (us) or "o"."""
    board, events = [None] * 9, []
    for turn in range(9):
        player = "x" if turn % 2 == 0 else "o"
        free = [k for k in range(9) if board[k] is None]
        board[int(rng.choice(free))] = player
        if any(all(board[k] == player for k in line) for line in LINES):
            events.append((player, "win" if player == "x" else "loss"))
            return events
        two = any(
            sum(board[k] == "o" for k in line) == 2 and any(board[k] is None for k in line)
            for line in LINES
        )
        mover = "own" if player == "x" else "opponent"
        kind = "threat" if two and player == "o" else f"{mover}_move"
        events.append((player, kind))
    events.append(("-", "draw"))
    return events


def emotion_commands(fitted, model_now: str, emotion: str, rng) -> list:
    """TRANSITION to ``emotion`` (if it is a model) and PLAY one of its takes."""
    from rigmap.latent.synthesis import Idle, Play, Transition

    target = emotion if emotion in fitted.models else model_now
    commands = [] if target == model_now else [Transition(target)]
    names = fitted.sets[target].names
    return [*commands, Play(names[int(rng.integers(len(names)))]), Idle(6)]


def _demo(args, compose_config) -> int:
    from rigmap.latent import steps
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
