"""``rigmap learn path/to/rig.blend``: the pipeline's stages on a user's own .blend, in order.

The file's armature is ``rig=blend_file`` (conf/rig/blend_file.yaml) and its actions the
corpus (:mod:`rigmap.animation.blend_corpus`); then the stages the built-in Blender rigs
run in dvc.yaml, with the same commands (``pipelines/<stage>.py``): pose, supersample (the
``pipeline.blender_samplers``), the network, the GPR (``pipeline.blender_kernels``) and the
mean predictor, and Table 1's methods on the test clips (``evaluate.set=methods``) into
``outputs/metrics/blend_file:<stem>/methods/``. The budgets are the rig config's
``_overrides_``. Each stage runs in a process of its own, as DVC would run it; the wall
time of each is printed as JSON at the end. The .blend is only read. Not a DVC stage: a
user's file is not one of the reproduced experiments, so nothing here touches dvc.yaml,
dvc.lock or the tracked data/, models/, metrics/: everything goes under ``outputs/``
(git-ignored) or the folder given with ``--out`` (:mod:`rigmap.user_outputs`).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

from rigmap.errors import RigmapError
from rigmap.store.layout import Layout
from rigmap.user_outputs import USER_OUTPUTS, user_paths

STAGES = ("animate", "pose", "supersample", "fit_nn", "fit_gpr", "fit_mean", "evaluate")


class LearnError(RigmapError, RuntimeError):
    """A stage of ``rigmap learn`` failed; the message is the stage's own."""


def rig_overrides(blend: Path, armature: str | None) -> list[str]:
    rig = ["rig=blend_file", f"rig.path={blend}"]
    return [*rig, f"rig.armature={armature}"] if armature else rig


def learn_commands(
    blend: str | os.PathLike,
    *,
    armature: str | None = None,
    overrides: list[str] | tuple[str, ...] = (),
    project: Path,
    compose,
    python: str = sys.executable,
    out: str | os.PathLike | None = None,
) -> list[tuple[str, list[str]]]:
    """``(stage, argv)`` of every stage, in the order they must run.

    ``compose(overrides, config_dir)`` is the Hydra composition (:func:`rigmap.cli.compose_config`)
    that names the pipeline's Blender samplers and kernels. ``out``: the folder of the
    stages' data/, models/, metrics/ and reports/ (default ``<project>/outputs``).
    """
    blend = Path(blend).expanduser().resolve()
    if not blend.is_file():
        raise FileNotFoundError(f"no .blend file at {blend}")
    if blend.suffix != ".blend":
        raise ValueError(f"{blend}: expected a .blend file")
    rig = rig_overrides(blend, armature)
    extra = list(overrides)
    out = Path(out).expanduser().resolve() if out is not None else project / USER_OUTPUTS
    extra = [*user_paths(extra, root=out), *extra]
    cfg = compose([*rig, *extra], Layout.project_conf(project))
    samplers = list(cfg.pipeline.blender_samplers)
    kernels = list(cfg.pipeline.blender_kernels)

    def stage(script: str, *args: str) -> list[str]:
        return [python, str(project / "pipelines" / f"{script}.py"), *rig, *args, *extra]

    commands = [("animate", stage("animate")), ("pose", stage("pose"))]
    commands += [("supersample", stage("supersample", f"sampler={s}")) for s in samplers]
    commands += [("fit_nn", stage("fit", "regressor=nn", f"sampler={s}")) for s in samplers]
    commands += [
        ("fit_gpr", stage("fit", "regressor=gpr", "sampler=none", f"kernel={k}")) for k in kernels
    ]
    commands += [("fit_mean", stage("fit", "regressor=mean", "sampler=none"))]
    commands += [("evaluate", stage("evaluate", "evaluate.set=methods"))]
    return commands


def run_learn(
    blend,
    *,
    armature: str | None = None,
    overrides=(),
    project: Path,
    compose,
    until: str | None = None,
    dry: bool = False,
    out=sys.stdout,
    outputs: str | os.PathLike | None = None,
) -> dict:
    """Run the stages (up to and including ``until``); ``{"stages": [{stage, seconds}]}``."""
    if until is not None and until not in STAGES:
        raise ValueError(f"--until must be one of {list(STAGES)}, got {until!r}")
    commands = learn_commands(
        blend,
        armature=armature,
        overrides=overrides,
        project=project,
        compose=compose,
        out=outputs,
    )
    if until is not None:
        last = max(i for i, (name, _) in enumerate(commands) if name == until)
        commands = commands[: last + 1]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(project / "src"), str(project / "pipelines"), env.get("PYTHONPATH", "")]
    ).rstrip(os.pathsep)
    timings = []
    for name, argv in commands:
        # runnable as printed (--dry): the stages run in the project, as DVC runs them
        print(
            f"rigmap learn: {name}: cd {shlex.quote(str(project))} && {shlex.join(argv)}",
            file=out,
            flush=True,
        )
        if dry:
            continue
        started = time.perf_counter()
        code, message = _run_stage(argv, project, env)
        seconds = time.perf_counter() - started
        timings.append({"stage": name, "command": argv[1:], "seconds": round(seconds, 2)})
        if code != 0:
            raise LearnError(
                f"stage {name}: {message}"
                if message
                else f"stage {name} failed (exit {code}); its output is above"
            )
    report = {"blend_file": str(Path(blend).resolve()), "stages": timings}
    if not dry:
        print(json.dumps(report, indent=1), file=out)
    return report


STAGE_ERROR = "error: "  # how a stage prints an error the user can fix (rigmap.app.stage)


def _run_stage(argv: list[str], project: Path, env: dict) -> tuple[int, str]:
    """Run one stage, its stderr passed through; (exit code, its ``error: <stage>:`` message).

    The stage's own one-line error is held back and returned, so that ``rigmap learn``
    prints it once, as its own error; everything else (progress, a bug's traceback)
    reaches the terminal as the stage writes it.
    """
    process = subprocess.Popen(argv, cwd=project, env=env, stderr=subprocess.PIPE)
    message, pending = "", b""
    while chunk := os.read(process.stderr.fileno(), 65536):
        *lines, pending = (pending + chunk).split(b"\n")
        for line in lines:
            text = line.decode("utf-8", "replace")
            if text.startswith(STAGE_ERROR):
                message = text.split(": ", 2)[-1]  # "error: <stage>: <message>"
            else:
                sys.stderr.buffer.write(line + b"\n")
        if pending and not pending.startswith(STAGE_ERROR.encode()[: len(pending)]):
            sys.stderr.buffer.write(pending)  # a progress bar's line, shown as it draws
            pending = b""
        sys.stderr.buffer.flush()
    if pending:
        sys.stderr.buffer.write(pending)
    process.stderr.close()
    return process.wait(), message


def add_learn_command(commands, compose, find_config_dir) -> None:
    """``rigmap learn [--armature NAME] [--until STAGE] [--dry] PATH.blend [KEY=VALUE ...]``

    (options before the file: argparse takes the positionals in one run)
    """
    learn = commands.add_parser(
        "learn",
        help="the whole pipeline on your own .blend: its actions as the corpus, then fit and "
        "evaluate (outputs/metrics/blend_file:<name>/)",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
    )
    learn.add_argument("blend", type=Path, help="the .blend with an armature and its actions")
    learn.add_argument(
        "--armature", default=None, help="the armature object (default: the file's only one)"
    )
    learn.add_argument("--until", default=None, choices=STAGES, help="stop after this stage")
    learn.add_argument("--dry", action="store_true", help="print the stage commands only")
    learn.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder of the run's data/, models/, metrics/ (default: outputs/ in the project)",
    )
    learn.add_argument(
        "overrides", nargs="*", metavar="KEY=VALUE", help="Hydra overrides given to every stage"
    )
    learn.add_argument(
        "--project",
        type=Path,
        default=None,
        help="the repository (folder with conf/ and pipelines/; default: found from here up)",
    )
    learn.set_defaults(run=lambda args: _learn(args, compose, find_config_dir))


def _learn(args, compose, find_config_dir) -> int:
    project = (args.project or find_config_dir(None).parent).resolve()
    run_learn(
        args.blend,
        armature=args.armature,
        overrides=args.overrides,
        project=project,
        compose=compose,
        until=args.until,
        dry=args.dry,
        outputs=args.out,
    )
    return 0
