"""``rigmap`` command line: rigs, corpus, export to Blender, fit, evaluate, map, pose, reproduce,
simulate (a soft body in Blender mapped onto the squirrel), and the link to a rig's runs in the
MLflow UI (``rigmap tracking url``).

Subcommands take plain flags (argparse); experiment commands pass Hydra
overrides (``key=value``) straight to the pipeline apps.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from pathlib import Path

import numpy as np

from rigmap.app.arguments import override_arguments
from rigmap.app.config import compose_config, find_config_dir
from rigmap.errors import RigmapError
from rigmap.user_outputs import user_paths


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    try:
        return args.run(args) or 0
    except BrokenPipeError:
        # the reader closed the pipe (`rigmap rigs describe biped --controls | head`): stop
        # quietly as Unix tools do, and point stdout at /dev/null so the flush at exit
        # cannot raise again (Python's documented recipe)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except Exception as error:
        from rigmap.tracking.store import tracking_failure

        shown = tracking_failure(error) or error  # a stalled tracking server, in one line
        if not expected_failure(shown) or _debugging():
            raise  # a bug (or RIGMAP_DEBUG=1): the traceback
        what = command_name(parser, sys.argv[1:] if argv is None else argv)
        print(f"rigmap: error: {what}: {failure_message(shown)}", file=sys.stderr)
        return 2


def expected_failure(error: BaseException) -> bool:
    """A failure the user can act on from its message: bad input, a file, the machine.

    rigmap's own errors, bad values (``ValueError``, ``KeyError``), anything the operating
    system refuses (every ``OSError``: a missing file, a folder where a file is expected,
    a full disk), ``MemoryError``, and a config Hydra cannot compose. Anything else is a bug.
    """
    from rigmap.app.config import config_errors

    expected = (RigmapError, ValueError, KeyError, OSError, MemoryError)
    return isinstance(error, (*expected, *config_errors()))


def failure_message(error: BaseException) -> str:
    """The error as one line: its message, or what the OS said about which file."""
    if isinstance(error, KeyError) and error.args:
        text = str(error.args[0])  # KeyError's str() wraps the message in quotes
    elif isinstance(error, OSError) and error.strerror and error.filename is not None:
        names = [str(n) for n in (error.filename, error.filename2) if n is not None]
        text = f"{' -> '.join(names)}: {error.strerror}"
    elif isinstance(error, MemoryError):
        text = f"out of memory{': ' + str(error) if str(error) else ''} (ask for less)"
    else:
        text = str(error).strip() or type(error).__name__
    return " | ".join(line.strip() for line in text.splitlines() if line.strip())


def command_name(parser: argparse.ArgumentParser, argv: list[str]) -> str:
    """The subcommand words of ``argv`` (``learn``, ``synth run``, ``rigs describe``)."""
    words, current = [], parser
    for token in argv:
        choices = next(
            (a.choices for a in current._actions if isinstance(a, argparse._SubParsersAction)),
            None,
        )
        if not choices or token not in choices:
            break
        words.append(token)
        current = choices[token]
    return " ".join(words) or "rigmap"


def _debugging() -> bool:
    from rigmap.app.stage import debugging

    return debugging()


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rigmap",
        description="Learning inverse rig mappings: joint positions -> animation-rig controls.",
    )
    from rigmap.learn import add_learn_command

    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    for add in (
        _add_rigs,
        _add_corpus,
        _add_export,
        _add_fit,
        _add_evaluate,
        _add_map,
        _add_edits,
        _add_reproduce,
        _add_tracking,
    ):
        add(commands)
    add_learn_command(commands, compose_config, find_config_dir)
    from rigmap.app.synth import add_synth_command

    add_synth_command(commands, compose_config, find_config_dir)
    from rigmap.app.studio import add_studio_command

    add_studio_command(commands, compose_config, find_config_dir)
    from rigmap.app.simulate import add_simulate_command

    add_simulate_command(commands, compose_config, find_config_dir)
    return parser


def _folder_option(command, flag: str, help: str) -> None:
    command.add_argument(flag, type=Path, default=None, help=help)


def _add_rigs(commands) -> None:
    rigs = commands.add_parser("rigs", help="list, describe and render rigs")
    rig_commands = rigs.add_subparsers(title="rig commands", metavar="RIG_COMMAND")

    listing = rig_commands.add_parser("list", help="names of the rigs rigmap can load")
    listing.set_defaults(run=_rigs_list)

    describe = rig_commands.add_parser(
        "describe", help="joints and controls (total, used, by kind, by group)"
    )
    describe.add_argument("name", help="rig name, see `rigmap rigs list`")
    describe.add_argument("--json", action="store_true", help="print JSON instead of text")
    describe.add_argument(
        "--controls", action="store_true", help="also list every control (name, kind, range, used)"
    )
    describe.set_defaults(run=_rigs_describe)

    render = rig_commands.add_parser(
        "render", help="draw a pose from front, side and top into a PNG"
    )
    render.add_argument("name", help="rig name, see `rigmap rigs list`")
    source = render.add_mutually_exclusive_group()
    source.add_argument(
        "--random",
        type=_seed,
        metavar="SEED",
        help="a random pose: used controls (but the placement) drawn 40%% into their soft range",
    )
    source.add_argument(
        "--controls",
        type=Path,
        metavar="FILE",
        help="a JSON object {control name: value}; other controls keep their defaults",
    )
    render.add_argument("--out", type=Path, required=True, help="PNG to write")
    render.set_defaults(run=_rigs_render)


def _add_corpus(commands) -> None:
    corpus = commands.add_parser("corpus", help="look at the animator corpus")
    corpus_commands = corpus.add_subparsers(title="corpus commands", metavar="CORPUS_COMMAND")
    show = corpus_commands.add_parser(
        "show",
        help="draw a clip as a contact sheet PNG and an animated GIF",
        description="Example: rigmap corpus show rig=quadruped clip='Turning & Galloping' "
        "--out dog.png (writes dog.png and dog.gif; an --out ending in .gif writes only the GIF)",
    )
    show.add_argument("selection", nargs=2, metavar="KEY=VALUE", help="rig=NAME clip=NAME")
    show.add_argument("--out", type=Path, required=True, help="PNG (plus a GIF beside it) or GIF")
    show.add_argument("--seed", type=int, default=0, help="corpus seed (default 0)")
    show.add_argument(
        "--split",
        choices=["train", "test"],
        default=None,
        help="where to look for the clip (default: both)",
    )
    show.add_argument("--panels", type=int, default=12, help="frames on the contact sheet")
    show.add_argument("--columns", type=int, default=6, help="contact-sheet columns")
    show.set_defaults(run=_corpus_show)


def _add_export(commands) -> None:
    export = commands.add_parser(
        "export-blend",
        help="write predicted controls as keyframes on a Blender rig (.blend for animators)",
    )
    export.add_argument("--rig", required=True, help="a Blender rig: rigify_human, rigify_wolf")
    export.add_argument(
        "--controls",
        type=Path,
        required=True,
        help="parquet with a `frame` column and one column per control (and a `clip` column, "
        "as in rigmap's predicted_controls.parquet: see --clip)",
    )
    export.add_argument(
        "--clip", default=None, help="the clip to key when the table holds several (its `clip`)"
    )
    export.add_argument("--out", type=Path, required=True, help=".blend file to write")
    export.set_defaults(run=_export_blend)


def _add_fit(commands) -> None:
    _add_stage_command(
        commands,
        "fit",
        help="fit an inverse mapping into outputs/models/<rig>/<regressor>-<sampler>-<kernel>/",
        description="Runs the fit stage (pipelines/fit.py) with Hydra overrides, e.g. "
        "rigmap fit rig=biped regressor=gpr kernel=gaussian sampler=none, or "
        "rigmap fit rig=quadruped regressor=nn sampler=pca_gaussian experiment=paper. "
        "The corpus is read from paths.data (data/); the model goes under outputs/models/ "
        "(git-ignored; paths.models=DIR names another folder), never the pipeline's models/. "
        "Paths are relative to the working directory.",
        overrides="rig=, regressor=, kernel=, sampler=, experiment=, budget.*=, paths.*=",
        run=_fit,
    )


def _add_evaluate(commands) -> None:
    _add_stage_command(
        commands,
        "evaluate",
        help="score methods on a rig's test clips into outputs/metrics/<rig>/<set>/ (and MLflow)",
        description="Runs the evaluate stage (as pipelines/evaluate.py, in this process) with "
        "Hydra overrides, e.g. "
        "rigmap evaluate rig=quadruped evaluate.set=methods, rigmap evaluate rig=biped "
        "evaluate.set=samplers, rigmap evaluate rig=face 'evaluate.methods=[gpr,nn]' "
        "evaluate.log_to_mlflow=false. Reads paths.data and paths.models (the pipeline's "
        "data/ and models/; paths.models=outputs/models for your own rigmap fit); writes "
        "under outputs/ (paths.metrics=DIR names another folder), relative to the working "
        "directory.",
        overrides="rig=, evaluate.set=, evaluate.methods=, sampler=, kernel=, experiment=, "
        "tracking.uri=, paths.*=",
        run=_evaluate,
    )


def _add_edits(commands) -> None:
    """``rigmap edits fit|apply|evaluate``: the edits stage's steps (002), one at a time, here;
    ``rigmap edits add``: incremental refinement (§3) played with the edits' ground truth;
    ``rigmap edits learn`` and ``apply --model``: an artist's own pairs (BVH files, or a
    rig's controls parquets) (:mod:`rigmap.app.edits`)."""
    from rigmap.app import edits as edits_app

    edits = commands.add_parser(
        "edits",
        help="learn an artist's edits (example pairs: BVH files, or a rig's controls "
        "parquets with --rig; or the procedural ones) and propagate them to other motion",
    )
    verbs = edits.add_subparsers(title="edit commands", metavar="EDIT_COMMAND")
    for verb, what in (
        ("fit", "fit each edit's GPs into outputs/models/<subject>/edits/"),
        (
            "apply",
            "propagate each edit to the held-out clips into outputs/data/<subject>/edits/; "
            "with --model DIR --input FILE|FOLDER: your learned edit, written as BVH, or "
            "for controls parquets as a parquet and a .blend when the rig has a Blender form",
        ),
        ("evaluate", "score the propagated edits into outputs/metrics/<subject>/edits/"),
        (
            "add",
            "fix frames round by round (suggested vs random) and refit, into "
            "outputs/metrics/<subject>/edits/refinement/",
        ),
    ):
        command = _add_stage_command(
            verbs,
            verb,
            help=what,
            description=(
                f"Runs the edits stage's {verb} step (pipelines/edits.py +edits_step={verb}) on "
                if verb != "add"
                else "Incremental refinement (rigmap.edits.incremental; not a stage): each "
                "round fixes the highest-variance (or random) frames of the held-out clips to "
                "the edit's ground truth and refits (+edits.refine.rounds=, per_round, segment, "
                "seed, random_seeds (how many seeds), choices=[variance,variance_clips]; "
                "+edits.mirror=true). "
                "Runs on "
            )
            + "conf/edits/default.yaml (edits=mls or edits=mirrored: conf/edits/) with Hydra "
            f"overrides, e.g. rigmap edits {verb} 'edits.run=[biped]' 'edits.names=[arm_swing]'. "
            "Writes under outputs/ (paths.data=, paths.models=, paths.metrics= name other "
            "folders); paths are relative to the working directory.",
            overrides="edits=, edits.run=, edits.names=, edits.residual=, edits.weights.*=, "
            "paths.*=",
            run=lambda args, verb=verb: _edits(verb, args),
        )
        if verb == "apply":
            edits_app.add_apply_options(command)
    edits_app.add_learn_command(verbs)
    edits_app.add_fix_command(verbs)


def _edits(verb: str, args) -> int:
    from rigmap.app.edits import run_edits_stage

    if verb == "apply" and args.model is not None:  # an artist's learned edit on their clips
        from rigmap.app.edits import run_apply

        return run_apply(args)
    if verb == "apply" and (args.input, args.out, args.fps) != (None, None, None):
        raise ValueError("--input, --out and --fps go with --model (a rigmap edits learn folder)")
    overrides = [*user_paths(args.overrides), *args.overrides]  # outputs/, not the tracked ones
    for path in run_edits_stage(verb, overrides, args.config_dir):
        print(path)
    return 0


def _add_map(commands) -> None:
    """``rigmap map`` and ``rigmap pose`` (rigmap.app.map_job, config conf/map.yaml)."""
    _add_stage_command(
        commands,
        "map",
        help="map motion (a BVH, a folder of BVHs, joint tracks) onto a rig's controls",
        description="Maps each input clip onto the rig (rigmap.app.map_job): the retarget map "
        "(map.retarget, default conf/retarget/cmu_<rig>.yaml) gives the rig joints it drives; "
        "a GPR on those joints, fitted on data/<rig>/corpus and poses and cached in "
        "models/<rig>/map-<subset>/ (refitted when the rig, subset, settings or data change), "
        "gives the controls; refinement and key reduction follow. Writes <out>/<clip>/ "
        "(default out: outputs/map/<rig>/): controls.parquet, frames.parquet (joint error cm, "
        "confidence), keys.json, result.bvh, summary.json, preview.png and preview.gif, and "
        "result.blend for a Blender rig (a copy of the rig's file, its actions kept, with the "
        "reduced keys as a new action). Examples: rigmap map "
        "input=../shared/mocap/cmu_131_01_walk.bvh rig=biped; rigmap map input=mocap_folder "
        "rig=biped out=mapped; rigmap map input=tracks.parquet map.unit=m map.source_fps=30 "
        "map.retarget=my_skeleton.yaml rig=biped.",
        overrides="input=, rig=, out=, model=, model_cache=, map.fps=, map.frames=, "
        "map.first_frame=, map.unit=, map.source_fps=, map.retarget=, map.settings.*=, "
        "map.preview=, budget.*=, paths.*=",
        run=_map,
        config_name="map",
    )
    _add_stage_command(
        commands,
        "pose",
        help="pose a rig's whole body from a few effector targets and draw it (full-body IK)",
        description='Poses the rig from targets=<file.json> ({"targets": {joint: [x, y, z]}} '
        'or {"frames": [...]}, world cm, Y up, facing +Z) with a GPR on the rig\'s pose '
        "subset (map.rigs.<rig>.pose_subset: biped, quadruped and rigify_human 'effectors' (7 "
        "joints), face 'landmarks'), refined by damped least squares (map.pose_mode=drag, the "
        "default: the frames in order, each from the last; batch: each from its guess), and "
        "writes <out>/ (default "
        "outputs/pose/<rig>/<targets name>/): controls.json and pose_<k>.png. Example: "
        "rigmap pose rig=biped targets=effectors.json.",
        overrides="targets=, rig=, out=, model=, map.pose_subset=, map.pose_mode=, map.drag.*=, "
        "map.settings.*=, budget.*=, paths.*=",
        run=_pose,
        config_name="map",
    )


def _add_stage_command(
    commands, name, *, help, description, overrides, run, config_name="config"
) -> argparse.ArgumentParser:
    """A verb that runs a pipeline stage in this process with Hydra overrides."""
    command = commands.add_parser(name, help=help, description=description)
    override_arguments(command, config_name, overrides)
    command.set_defaults(run=run)
    return command


def _add_reproduce(commands) -> None:
    reproduce = commands.add_parser(
        "reproduce",
        help="run the DVC pipeline (dvc repro) for an experiment and print where the report is",
        description="Composes conf/ with the overrides into params.yaml (as `dvc exp run -S` "
        "would), then runs `dvc repro` with this Python's bin folder first on PATH, streaming "
        "DVC's output. Examples: rigmap reproduce; rigmap reproduce experiment=paper; "
        "rigmap reproduce budget.samples=20000 --target report.",
    )
    reproduce.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help="Hydra overrides of conf/config.yaml: experiment=quick|paper, budget.*=, "
        "regressor.*=, seed= (default: conf/config.yaml as it is, i.e. experiment=quick)",
    )
    reproduce.add_argument(
        "--target",
        action="append",
        default=[],
        metavar="STAGE",
        help="reproduce only this stage and what it depends on (repeatable; default: all)",
    )
    reproduce.add_argument(
        "--dry",
        action="store_true",
        help="show what would run (dvc repro --dry); params.yaml is left as it was. DVC's dry "
        "run stops at the first stage whose inputs an earlier stage has not written yet "
        "(treeverse/dvc#9021), so on a fresh clone it lists only the first stages",
    )
    reproduce.add_argument("--force", action="store_true", help="re-run even unchanged stages")
    reproduce.add_argument(
        "--keep-going", action="store_true", help="run independent stages after a failure"
    )
    reproduce.add_argument(
        "-j",
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="run up to N independent stages at once, each as its own `dvc repro --single-item`"
        " (stages marked meta.runs_alone in dvc.yaml, the ones that time methods, run alone; "
        "default 1: one `dvc repro`)",
    )
    reproduce.add_argument(
        "--params-only",
        action="store_true",
        help="only write params.yaml (then run dvc repro / dvc exp run yourself)",
    )
    _folder_option(
        reproduce,
        "--project",
        "the repository (folder with dvc.yaml and conf/; default: found from here up)",
    )
    reproduce.set_defaults(run=_reproduce)


def _add_tracking(commands) -> None:
    tracking = commands.add_parser("tracking", help="links into the MLflow tracking UI")
    verbs = tracking.add_subparsers(title="tracking commands", metavar="TRACKING_COMMAND")
    url = verbs.add_parser(
        "url",
        help="the link to a rig's runs list with each method's errors and frames/s",
        description="Prints the link to the saved view the evaluate stage keeps of its "
        "latest run of a metrics set (rigmap-methods is Table 1): every method with its "
        "joint error, ground-truth error and frames per second, then its datasets. The "
        "store is the tracking group's (tracking=server, tracking.uri=URI, "
        "MLFLOW_TRACKING_URI, else the project's mlruns.db). Example: rigmap tracking url "
        "--rig quadruped tracking=server",
    )
    url.add_argument("--rig", required=True, help="the rig's name, as `rigmap rigs list` shows it")
    url.add_argument(
        "--view",
        default="methods",
        metavar="SET",
        help="the metrics set: methods (default, Table 1), samplers, kernels, "
        "methods_heldout, methods_train",
    )
    url.add_argument(
        "--ui",
        default=None,
        metavar="URL",
        help="where the MLflow UI is served (default: the tracking server itself, or "
        "http://127.0.0.1:5000 for a local store opened with `mlflow ui`)",
    )
    override_arguments(url, "config", "tracking=, tracking.uri=")
    url.set_defaults(run=_tracking_url)


def _tracking_url(args) -> int:
    from rigmap.app.evaluate import lead_view_link

    print(lead_view_link(list(args.overrides), args.config_dir, args.rig, args.view, args.ui))
    return 0


def _fit(args) -> int:
    from rigmap.app.fit import fit_command

    overrides = [*user_paths(args.overrides, keys=("models",)), *args.overrides]
    print(fit_command(overrides, args.config_dir).folder)
    return 0


def _evaluate(args) -> int:
    """The evaluate stage in this process: the same call as pipelines/evaluate.py."""
    from rigmap.app.evaluate import evaluate_command

    overrides = [*user_paths(args.overrides, keys=("metrics", "reports")), *args.overrides]
    evaluate_command(overrides, args.config_dir)
    return 0


def _map_config(args) -> dict:
    from rigmap.app.map_job import map_config

    # the map's model cache (paths.models) goes under outputs/; the corpus is read from data/
    overrides = [*user_paths(args.overrides, keys=("models",)), *args.overrides]
    return map_config(overrides, args.config_dir)


def _map(args) -> int:
    from rigmap.app.map_job import map_from_config

    map_from_config(_map_config(args), config_dir=find_config_dir(args.config_dir))
    return 0


def _pose(args) -> int:
    from rigmap.app.map_job import pose_from_config

    pose_from_config(_map_config(args))
    return 0


def _export_blend(args) -> int:
    import pandas as pd

    from rigmap.rigs import load
    from rigmap.rigs.blender.export import clip_rows, export_blend

    if args.controls.is_dir():
        raise ValueError(f"--controls {args.controls} is a folder; expected a .parquet file")
    if not args.controls.exists():
        raise FileNotFoundError(f"controls file {args.controls} does not exist")
    _output_file(args.out, "--out", "mapped.blend")
    controls = clip_rows(pd.read_parquet(args.controls), args.clip)
    with load(args.rig) as rig:
        out = export_blend(rig, controls, args.out)
    print(out)
    return 0


def _key_values(pairs: list[str], required: tuple[str, ...]) -> dict[str, str]:
    """``["rig=biped", "clip=Tai Chi"]`` -> dict, with a clear error for anything else."""
    values = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or key not in required:
            raise ValueError(f"expected {' '.join(k + '=…' for k in required)}, got {pair!r}")
        values[key] = value
    missing = [k for k in required if k not in values]
    if missing:
        raise ValueError(f"missing {', '.join(k + '=…' for k in missing)}")
    return values


def _corpus_show(args) -> int:
    from rigmap.viz.contact_sheet import show_clip

    chosen = _key_values(args.selection, ("rig", "clip"))
    _output_file(args.out, "--out", "clip.png")
    written = show_clip(
        chosen["rig"],
        chosen["clip"],
        args.out,
        split=args.split,
        seed=args.seed,
        panels=args.panels,
        columns=args.columns,
    )
    for path in written:
        print(path)
    return 0


def _rigs_list(args) -> int:
    from rigmap.rigs import available

    for name in available():
        print(name)
    return 0


def describe_rig(rig) -> dict:
    """The facts `rigs describe` prints: counts, groups, kinds, joints."""
    summary = rig.controls.summary()
    return {
        "name": rig.name,
        "description": rig.description,
        "length_unit": rig.length_unit,
        "differentiable": rig.differentiable,
        "joints": rig.n_joints,
        "joint_dofs": 3 * rig.n_joints,
        "controls": summary["total"],
        "used_controls": summary["used"],
        "controls_by_kind": summary["by_kind"],
        "controls_by_group": summary["by_group"],
        "joint_names": list(rig.joint_names),
        # Blender rigs also say how many bones and transform channels they expose
        **({"bones": rig.stats} if hasattr(rig, "stats") else {}),
    }


def _rigs_describe(args) -> int:
    from rigmap.rigs import load

    rig = load(args.name)
    facts = describe_rig(rig)
    if args.controls:
        facts["control_table"] = rig.controls.records()
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    print(f"{rig.name}: {rig.description}")
    print(f"  joints:   {facts['joints']} ({facts['joint_dofs']} numbers, {rig.length_unit})")
    print(f"  controls: {facts['controls']} total, {facts['used_controls']} used by animators")
    print("  by kind:")
    for kind, count in facts["controls_by_kind"].items():
        print(f"    {kind:10s} {count['total']:5d} total {count['used']:5d} used")
    print("  by group:")
    for group, count in facts["controls_by_group"].items():
        print(f"    {group:14s} {count['total']:5d} total {count['used']:5d} used")
    if args.controls:
        print("  controls (name, kind, default, soft range, used):")
        for c in rig.controls:
            mark = "used" if c.used else ""
            print(
                f"    {c.name:32s} {c.kind:9s} {c.default:8.3f} "
                f"[{c.lower:8.3f}, {c.upper:8.3f}] {mark}"
            )
    return 0


def pose_controls(rig, *, seed: int | None = None, controls_file: Path | None = None):
    """Full control vector for `rigs render`: defaults, a seeded random pose, or a file."""
    Y = rig.controls.defaults.copy()
    if seed is not None:
        rng = np.random.default_rng(seed)
        # the placement control would only slide the character out of frame
        used = [i for i in rig.controls.used_indices if rig.controls.groups[i] != "root"]
        lo, hi = rig.controls.lower[used], rig.controls.upper[used]
        Y[used] += 0.4 * (rng.uniform(lo, hi) - Y[used])
    if controls_file is not None:
        for name, value in _controls_json(controls_file).items():
            try:
                column = rig.controls.index(name)
            except KeyError as error:
                raise KeyError(f"{controls_file}: rig {rig.name!r}: {error.args[0]}") from None
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(
                    f"{controls_file}: control {name!r} is {value!r}; expected a number"
                )
            Y[column] = float(value)
    return Y


def _controls_json(path: Path) -> dict:
    """``--controls``: a JSON object ``{control name: value}``; errors name the file."""
    from rigmap.store import read_data_file

    values = read_data_file(path, "--controls file", ValueError)
    if not isinstance(values, dict):
        raise ValueError(f"{path}: expected a JSON object {{control: value}}")
    return values


def _output_file(path: Path, flag: str, example: str) -> Path:
    """An output file option that names an existing folder is refused before any work."""
    if path.is_dir():
        raise ValueError(
            f"{flag} {path} is a folder; expected a file to write, e.g. {path / example}"
        )
    return path


def _seed(text: str) -> int:
    """``--random``: a seed for numpy, an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0 (a random seed), got {text!r}")
    return value


def _rigs_render(args) -> int:
    from rigmap.rigs import load

    _output_file(args.out, "--out", "pose.png")
    rig = load(args.name)
    Y = pose_controls(rig, seed=args.random, controls_file=args.controls)
    if rig.faces is not None:
        from rigmap.viz.mesh import render_mesh_views

        out = render_mesh_views(rig, Y, args.out)
    else:
        from rigmap.viz.skeleton import render_skeleton_views

        label = (
            "rest pose"
            if args.random is None and args.controls is None
            else (
                f"random pose (seed {args.random})"
                if args.random is not None
                else str(args.controls)
            )
        )
        out = render_skeleton_views(rig, Y, args.out, title=f"{rig.name} — {label}")
    print(out)
    return 0


def _reproduce(args) -> int:
    from rigmap.reproduce import plan_reproduce, run_reproduce

    plan = plan_reproduce(
        args.overrides,
        targets=args.target,
        project=args.project,
        dry=args.dry,
        force=args.force,
        keep_going=args.keep_going,
        params_only=args.params_only,
        jobs=args.jobs,
    )
    return run_reproduce(plan)


if __name__ == "__main__":
    raise SystemExit(main())
