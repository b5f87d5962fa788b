"""The command-line side of :mod:`rigmap.edits.artist`: ``rigmap edits learn`` (BVH pairs, or
a built-in rig's controls parquets with ``--rig``), ``rigmap edits fix``, the ``--model``
options of ``rigmap edits apply``, and the edits' settings read from ``conf/``.
Imports stay light here (the parser is built on every ``rigmap`` call); the work is
imported when a command runs."""

from __future__ import annotations

from pathlib import Path

from rigmap.app.arguments import config_dir_option
from rigmap.store import Layout
from rigmap.user_outputs import USER_OUTPUTS


def load_settings(config_dir=None) -> dict:
    """``conf/edits/default.yaml``'s model settings (residual, weights, iterations)."""
    from omegaconf import OmegaConf

    from rigmap.app.config import compose_config

    cfg = compose_config(["+edits=default"], config_dir)
    return OmegaConf.to_container(cfg.edits, resolve=True)


#: the edits stage's steps, in the order the stage runs them (rigmap.edits.steps.run_<step>)
EDIT_STEPS = ("fit", "apply", "evaluate")


def run_edits_steps(cfg) -> list[Path]:
    """The edits stage from a composed config (``pipelines/edits.py``): every step in order,
    or the one ``+edits_step`` names; ``+edits_subject`` runs one subject of ``edits.run``."""
    from rigmap.edits import steps
    from rigmap.edits.representation import TargetError

    if "edits" not in cfg:
        raise TargetError("no edits config: add +edits=default to the command")
    step = cfg.get("edits_step")
    if step is not None and step not in EDIT_STEPS:
        raise TargetError(f"+edits_step: expected one of {EDIT_STEPS}, got {step!r}")
    config, layout = _edits_inputs(cfg)
    subject = cfg.get("edits_subject")
    if subject is not None:
        config["run"] = [str(subject)]
    chosen = EDIT_STEPS if step is None else (step,)
    return [path for name in chosen for path in getattr(steps, f"run_{name}")(config, layout)]


def run_edits_stage(verb: str, overrides: list[str], config_dir=None) -> list[Path]:
    """``rigmap edits <verb>``: ``rigmap.edits.steps.run_<verb>`` (a step of the edits stage,
    or ``add``) on ``conf/edits/default.yaml`` with ``overrides``."""
    from rigmap.app.config import compose_config
    from rigmap.edits import steps

    config, layout = _edits_inputs(compose_config(["+edits=default", *overrides], config_dir))
    return list(getattr(steps, f"run_{verb}")(config, layout))


def _edits_inputs(cfg) -> tuple[dict, Layout]:
    """The composed ``edits`` settings as a plain dict, and the layout of ``paths``."""
    from omegaconf import OmegaConf

    config = OmegaConf.to_container(cfg.edits, resolve=True)
    return config, Layout.from_paths(OmegaConf.to_container(cfg.paths, resolve=True))


GLITCH_HELP = (
    "a capture glitch (a frame whose every channel is zero): repair (default: rebuilt from "
    "its neighbours, left out of the examples, said so in the summary) or refuse (an error)"
)


def add_learn_command(verbs) -> None:
    learn = verbs.add_parser(
        "learn",
        help="learn an edit from your example pairs (a source and your edited version: BVH "
        "files, or controls parquets of a built-in rig with --rig)",
        description="Fits the edit-propagation model (Ikemoto et al. 2009: two GPs and the "
        "combined solve; settings of conf/edits/default.yaml) on example pairs: --source "
        "a.bvh --edited a_edited.bvh, repeated for more pairs, each with an optional "
        "--frames START:STOP (from 0, STOP excluded; the same frames of both files). A pair "
        "must have the same skeleton, frame count and frame time (§3), every channel a "
        "number. Rig mode: --rig NAME (biped, quadruped: root.tx, root.tz, root.ry and the "
        "pelvis/thigh joints; rigify_human, Z-up: root.tx, root.ty, root.rz and DEF-spine, "
        "DEF-thigh.L/R) with controls parquets as "
        "rigmap map writes them (a frame column of consecutive numbers and one column per "
        "control; every used control present, no other column, finite numbers; a control "
        "the rig does not use only at its default); --frames are then the frame column's "
        "numbers, and the parquets are read at --fps. Writes edit.npz + edit.json (the "
        "model: arrays and JSON) and learned.json (with the mode, and the rig and fps in "
        f"rig mode) into --out (default {USER_OUTPUTS}/edits/<first edited file's name>/); "
        "nothing is written when a check fails. Examples: rigmap edits learn --source "
        "walk.bvh --edited walk_arms_up.bvh --frames 40:475; rigmap edits learn --rig biped "
        "--source walk.parquet --edited walk_bowed.parquet",
    )
    for flag, what in (
        ("--source", "a source clip (repeat once per pair)"),
        ("--edited", "the edited version of the --source at the same place"),
    ):
        learn.add_argument(
            flag, action="append", type=Path, metavar="FILE", required=True, help=what
        )
    learn.add_argument(
        "--frames",
        action="append",
        metavar="START:STOP",
        help="the pair's frames (once per pair, or never: whole clips)",
    )
    learn.add_argument(
        "--rig",
        default=None,
        metavar="NAME",
        help="rig mode: the rig the controls parquets belong to (biped, quadruped, rigify_human)",
    )
    learn.add_argument(
        "--fps",
        type=float,
        default=None,
        help="with --rig: the parquets' frame rate (a parquet has no frame time; default 24, "
        "the rig corpus's rate); recorded in the model, apply reads its input at it",
    )
    learn.add_argument("--out", type=Path, default=None, help="the folder to write the model to")
    learn.add_argument(
        "--glitch",
        choices=("repair", "refuse"),
        default="repair",
        help=GLITCH_HELP + " (BVH pairs only)",
    )
    config_dir_option(learn)
    learn.set_defaults(run=run_learn)


def add_fix_command(verbs) -> None:
    fix = verbs.add_parser(
        "fix",
        help="hand in corrected frames of a clip: refit the learned edit, suggest what to fix next",
        description="The incremental loop of §3 (Fig 2): --fixed is a BVH of your corrected "
        "frames (the clip's skeleton, one frame per frame of --frames START:STOP of the "
        "--source file, from 0, STOP excluded). For a rig-mode model (learned with --rig) "
        "--source and --fixed are controls parquets and the fixed file's frame column holds "
        "the numbers START..STOP-1 of the frames it replaces. The fix joins the examples of "
        "the --model folder (a copy kept in its fixes/), the edit is refitted on the pairs "
        "and every fix so far, and the frames of highest variance on --source not fixed yet "
        "are printed as the ones to fix next. Then rigmap edits apply --model again.",
    )
    fix.add_argument("--model", type=Path, required=True, help="a folder of rigmap edits learn")
    fix.add_argument("--source", type=Path, required=True, help="the clip you corrected")
    fix.add_argument(
        "--fixed",
        type=Path,
        required=True,
        help="the corrected frames: a BVH, or a controls parquet for a rig-mode model",
    )
    fix.add_argument(
        "--frames",
        required=True,
        metavar="START:STOP",
        help="the frames of --source the corrected frames replace",
    )
    fix.add_argument("--suggest", type=int, default=3, help="how many segments to suggest")
    fix.add_argument("--segment", type=int, default=12, help="frames per suggested segment")
    config_dir_option(fix)
    fix.set_defaults(run=run_fix)


def run_fix(args) -> int:
    from rigmap.edits.artist import parse_frames
    from rigmap.edits.fixes import fix_folder
    from rigmap.edits.pairs import PairError

    frames = parse_frames(args.frames)
    if frames is None:
        raise PairError("--frames must be START:STOP (the corrected frames), not all")
    if args.suggest < 1 or args.segment < 1:
        raise PairError(f"--suggest and --segment must be >= 1, got {args.suggest}, {args.segment}")
    settings = load_settings(args.config_dir)
    picks, notes = fix_folder(
        args.model, args.source, args.fixed, frames, settings, args.suggest, args.segment
    )
    for note in notes:  # a glitch in the fix, rebuilt and left out of the examples
        print(f"note: {note}; left out of the examples")
    print(
        f"refitted {args.model / 'edit.npz'} with frames {frames[0]}:{frames[1]} of {args.source}"
    )
    for pick in picks:
        print(
            f"fix next: frames {pick.start}:{pick.stop} of {args.source} "
            f"(variance {pick.variance:.3g})"
        )
    return 0


def add_apply_options(command) -> None:
    """``rigmap edits apply --model DIR --input FILE|FOLDER``: a learned edit on clips."""
    command.description += (
        " With --model DIR (a folder `rigmap edits learn` wrote) it instead applies that "
        "edit to --input (a file or a folder of them: BVH files, or controls parquets for "
        "a model learned with --rig, where a `rigmap map` output folder, or a folder of "
        "them, gives its controls.parquet under the folder's name; a file of the other "
        "mode is refused) and writes, per "
        "clip, <name>.npz (the edited track) and: for BVH, <name>.bvh (the clip's own "
        "hierarchy, at --fps or the clip's rate); for a parquet, <name>.parquet (frame and "
        "every used control of the rig, at --fps or the model's rate; the input is read at "
        "the model's rate) and <name>.blend, an action keyed on those controls at the "
        "output rate, when the rig has a Blender form (rigify_human; the built-in biped and "
        "quadruped have none: applied.json says so). A timing edit (a predicted "
        "frame time) is resampled to that fixed rate. Then applied.json, into --out "
        f"(default {USER_OUTPUTS}/edits/<model folder's name>/applied/); every clip is "
        "checked before any file is written."
    )
    command.add_argument(
        "--model", type=Path, default=None, help="a folder written by rigmap edits learn"
    )
    command.add_argument(
        "--input",
        type=Path,
        default=None,
        metavar="FILE_OR_FOLDER",
        help="with --model: the clip(s) to edit (BVH, or controls parquets in rig mode)",
    )
    command.add_argument("--out", type=Path, default=None, help="with --model: output folder")
    command.add_argument(
        "--fps",
        type=float,
        default=None,
        help="with --model: the output frame rate (default: the clip's; a parquet's is the "
        "model's)",
    )
    command.add_argument(
        "--glitch",
        choices=("repair", "refuse"),
        default="repair",
        help=GLITCH_HELP + " (BVH clips only)",
    )


def run_learn(args) -> int:
    from rigmap.edits.artist import learn_folder, learn_rig_folder, pair_specs
    from rigmap.edits.pairs import PairError
    from rigmap.edits.rig_pairs import CORPUS_FPS, RigMode

    specs = pair_specs(args.source, args.edited, args.frames)
    out = args.out or Layout.user_output("edits", Path(specs[0][1]).stem)
    settings = load_settings(args.config_dir)
    if args.rig is not None:
        mode = RigMode.of(args.rig, CORPUS_FPS if args.fps is None else args.fps)
        folder = learn_rig_folder(specs, out, settings, mode)
    elif args.fps is not None:
        raise PairError("--fps goes with --rig (controls parquets); a BVH has its frame time")
    else:
        folder = learn_folder(specs, out, settings, args.glitch)
    import json

    summary = json.loads((folder / "learned.json").read_text())
    for pair in summary["pairs"]:
        start, stop = pair["frames"]
        print(
            f"pair {pair['source']} -> {pair['edited']}: frames {start}:{stop}, "
            f"{pair['example_frames']} example frames"
        )
        for note in pair["notes"]:
            print(f"  {note}")
    mode = f"rig {summary['rig']} at {summary['fps']:g} fps" if "rig" in summary else "skeleton"
    print(f"model ({mode}): {folder / 'edit.npz'} (fit {summary['fit_s']:.1f} s)")
    return 0


def run_apply(args) -> int:
    from rigmap.edits.artist import apply_folder
    from rigmap.edits.pairs import PairError

    if args.overrides:
        raise PairError(f"--model takes no KEY=VALUE overrides, got {args.overrides}")
    if args.input is None:
        raise PairError("--model needs --input (a file or a folder of them)")
    out = args.out or Layout.user_output("edits", args.model.resolve().name, "applied")
    _, summary = apply_folder(args.model, args.input, out, args.fps, args.glitch)
    for row in summary["clips"]:
        timing = " (resampled)" if row["resampled"] else ""
        print(
            f"{row['input']} -> {row.get('bvh') or row['parquet']}: {row['frames_in']} -> "
            f"{row['frames_out']} frames at {row['fps_out']:g} fps{timing}"
        )
        if row.get("blend"):
            print(f"  {row['blend']}")
        elif row.get("no_blend"):
            print(f"  {row['no_blend']}")
        for note in row["notes"]:
            print(f"  {note}")
    return 0
