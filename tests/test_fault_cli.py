"""Issue 36's faults of the pipeline's commands and of the CLI, each trial named in its test.

- no value reaches a shell: a hostile ``seed`` in params.yaml under ``dvc repro --single-item``
  / ``-s`` (which skip the ``check_params`` stage) creates no file and fails with one line;
- the committed params.yaml is what conf/ composes (CI runs the same check);
- expected failures of ``rigmap`` and ``rigmap learn`` are one-line errors, exit status 2;
- two writers of one output: one wins whole, never a mixed file or folder;
- a user's own runs write under ``outputs/`` (ignored), never into tracked folders.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from rigmap.store.pipeline_files import stage_families
from stage_scripts import copy_stage_files

ROOT = Path(__file__).resolve().parents[1]


def _project(tmp_path: Path, **changes) -> Path:
    """A copy of the pipeline (stage files, conf/, params.yaml; code linked) with ``changes``."""
    project = tmp_path / "project"
    project.mkdir(parents=True)
    copy_stage_files(project)
    shutil.copy(ROOT / "params.yaml", project / "params.yaml")
    shutil.copytree(ROOT / "conf", project / "conf")
    for name in ("src", "pipelines"):
        (project / name).symlink_to(ROOT / name)
    params = yaml.safe_load((project / "params.yaml").read_text())
    for dotted, value in changes.items():
        node = params
        *parents, leaf = dotted.split(".")
        for key in parents:
            node = node[key]
        node[leaf] = value
    (project / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    return project


def _dvc(project: Path, *args: str) -> subprocess.CompletedProcess:
    bin_dir = Path(sys.executable).parent
    env = dict(
        os.environ,
        PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
        PYTHONPATH=f"{ROOT / 'src'}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
    )
    env.pop("DVC_STAGE", None)
    return subprocess.run(
        [sys.executable, "-m", "dvc", *args],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


HOSTILE_SEEDS = {
    "seed_semicolon": "0; touch X",
    "seed_dollar": "$(touch X)",
    "seed_backticks": "`touch X`",
}


@pytest.mark.parametrize("seed", list(HOSTILE_SEEDS.values()), ids=list(HOSTILE_SEEDS))
@pytest.mark.parametrize("flag", ["--single-item", "-s"])
def test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item(
    tmp_path, flag, seed
):
    """Trial: seed "0; touch X" (and $(...), backticks) once data/params_checked.txt exists."""
    project = _project(tmp_path, seed=seed)
    assert _dvc(project, "init", "--no-scm", "-q").returncode == 0
    (project / "data").mkdir()
    (project / "data" / "params_checked.txt").write_text("params.yaml checked\n")
    done = _dvc(project, "repro", flag, "stages/data/dvc.yaml:animate@biped")
    output = done.stdout + done.stderr
    assert done.returncode != 0, output[-2000:]
    assert not (project / "X").exists(), f"{seed!r} ran a shell command"
    assert not (project / "data" / "biped").exists()  # the stage itself never started
    message = f"error: animate: params.yaml: 1 bad value(s), the stage did not run: seed = {seed!r}"
    assert message in output, output[-2000:]
    assert "expected an integer (as in conf/), got a string" in output
    assert "Traceback" not in output


def test_every_stage_command_is_a_fixed_string_whose_values_are_declared_params():
    """Trial: no ``${...}`` in any cmd; each KEY=@NAME is a params: entry (so DVC re-runs it)."""
    import re

    stages = {name: found.body for name, found in stage_families(ROOT).items()}
    checked = 0
    for name, stage in stages.items():
        assert "${" not in stage["cmd"], f"{name}: {stage['cmd']}"
        listed = set()
        for entry in stage.get("params", []):
            if isinstance(entry, str):
                listed.add(entry)
            else:
                for keys in entry.values():
                    listed.update(keys or [""])  # null: the whole file
        for key in re.findall(r"=@([A-Za-z_][\w.]*)", stage["cmd"]):
            if key.startswith("item."):
                assert key[len("item.") :] in stage["matrix"], f"{name}: @{key}"
                continue
            covered = any(key == p or key.startswith(f"{p}.") or p == "" for p in listed)
            assert covered, f"{name}: @{key} is not in its params: {sorted(listed)}"
            checked += 1
    assert checked > 50


def test_placeholders_take_the_matrix_entry_and_params_yaml_values(tmp_path):
    """Trial: ``fit_gpr@biped-linear`` fills rig and kernel from its own matrix entry."""
    from rigmap.app.placeholders import resolve_argv

    project = _project(tmp_path, seed=7)
    argv = ["fit.py", "rig=@item.rig", "regressor=gpr", "kernel=@item.kernel", "seed=@seed"]
    resolved = resolve_argv(argv, project, "fit_gpr@biped-linear")
    assert resolved.argv == ["fit.py", "rig=biped", "regressor=gpr", "kernel=linear"]
    assert resolved.params == {"seed": ("seed", 7)}
    assert resolve_argv(["fit.py", "seed=3"], project, None).argv == ["fit.py", "seed=3"]


@pytest.mark.parametrize("rig", ["biped;touch X", "$(touch X)", "a b"])
def test_hostile_matrix_value_is_refused_before_any_command(tmp_path, rig):
    """Trial: a rig name with shell syntax in pipeline.rigs never reaches an argument."""
    from rigmap.app.placeholders import PlaceholderError, resolve_argv

    project = _project(tmp_path, **{"pipeline.rigs": [rig]})
    with pytest.raises(PlaceholderError, match="is not a plain name"):
        resolve_argv(["animate.py", "rig=@item.rig"], project, f"animate@{rig}")
    assert not (project / "X").exists()


def test_placeholder_outside_dvc_says_how_to_run_it(tmp_path):
    """Trial: ``rig=@item.rig`` typed by hand, with no DVC_STAGE."""
    from rigmap.app.placeholders import PlaceholderError, resolve_argv

    project = _project(tmp_path)
    with pytest.raises(PlaceholderError, match="run it with dvc repro"):
        resolve_argv(["animate.py", "rig=@item.rig"], project, "")


def test_committed_params_yaml_is_what_conf_composes():
    """Trial: the committed params.yaml against conf/ (``.ci/run`` runs the same check)."""
    from rigmap.app.params import stale_params

    assert stale_params(ROOT) == []
    assert "python -m rigmap.pipeline_params fresh" in (ROOT / ".ci" / "run").read_text()


def test_stale_params_yaml_fails_the_check(tmp_path, monkeypatch, capsys):
    """Trial: tune.steps 80 / control_weight 0.01 in params.yaml while conf/ says otherwise."""
    from rigmap.app.params import main

    tuned = "method.nn_joint_space_tuned.tune"
    project = _project(tmp_path, **{f"{tuned}.steps": 80, f"{tuned}.control_weight": 0.01})
    monkeypatch.chdir(project)
    assert main(["fresh"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"differs from what conf/ composes at {tuned}.control_weight, {tuned}.steps" in err
    shutil.copy(ROOT / "params.yaml", project / "params.yaml")
    assert main(["fresh"]) == 0


def _write_one(job: tuple[str, str, int]) -> tuple[int, str]:
    """One stress writer: ``kind`` "folder" or "file", its ``ident``; (ident, error or "")."""
    import time

    from rigmap.errors import RigmapError
    from rigmap.store import write_folder_atomic, write_text_atomic

    target, kind, ident = job

    def fill(folder: Path) -> None:
        for part in range(5):
            (folder / f"part{part}.txt").write_text(f"writer {ident} part {part}\n" * 200)
            time.sleep(0.002)

    try:
        for _ in range(10):
            if kind == "folder":
                write_folder_atomic(target, fill)
            else:
                write_text_atomic(target, f"writer {ident}\n" * 1000)
    except RigmapError as error:
        return ident, str(error)
    return ident, ""


def _stress(target: Path, kinds: list[str]) -> list[tuple[int, str]]:
    import multiprocessing

    jobs = [(str(target), kind, ident) for ident, kind in enumerate(kinds)]
    with multiprocessing.get_context("fork").Pool(len(jobs)) as pool:
        return pool.map(_write_one, jobs)


def _one_writers_content(target: Path) -> str:
    """Which writer's output ``target`` is, whole; fails on a mix."""
    if target.is_dir():
        names = sorted(p.name for p in target.iterdir())
        assert names == [f"part{i}.txt" for i in range(5)], names
        texts = {p.read_text().split(" part ")[0] for p in target.iterdir()}
        assert len(texts) == 1, texts  # every part from the same writer
        return texts.pop()
    text = target.read_text()
    lines = set(text.splitlines())
    assert len(lines) == 1 and text.count("\n") == 1000, lines
    return lines.pop()


def test_six_writers_of_one_output_folder_each_win_whole(tmp_path):
    """Trial: 6 processes x 10 writes of one folder (60 writes): no IsADirectoryError,
    NotADirectoryError or ENOTEMPTY; the folder is one writer's, whole."""
    target = tmp_path / "out" / "corpus"
    results = _stress(target, ["folder"] * 6)
    assert [error for _, error in results] == [""] * 6
    assert _one_writers_content(target).startswith("writer ")
    assert sorted(p.name for p in target.parent.iterdir()) == ["corpus"]  # no leftovers


def test_six_writers_of_one_output_file_and_folder_mixed_get_a_clear_error(tmp_path):
    """Trial: 3 file writers and 3 folder writers of one path: each wins whole or gets
    one line naming the path; never a mixed file/folder."""
    target = tmp_path / "out" / "model"
    results = _stress(target, ["file", "folder"] * 3)
    errors = [error for _, error in results if error]
    for error in errors:
        assert error.startswith(f"{target}: a ") and "\n" not in error, error
        assert "not replacing it with a" in error
    winner = _one_writers_content(target)
    assert winner.startswith("writer ")
    assert sorted(p.name for p in target.parent.iterdir()) == ["model"]


def _raising(error: BaseException):
    def run(args) -> int:
        raise error

    return run


EXPECTED_FAILURES = [
    ("is_a_directory", IsADirectoryError(21, "Is a directory", "out/model"),
     "out/model: Is a directory"),
    ("not_a_directory", NotADirectoryError(20, "Not a directory", "out/file/x"),
     "out/file/x: Not a directory"),
    ("enotempty", OSError(39, "Directory not empty", "out/.corpus.tmp", None, "out/corpus"),
     "out/.corpus.tmp -> out/corpus: Directory not empty"),
    ("disk_full", OSError(28, "No space left on device", "models/q/fit.npz"),
     "models/q/fit.npz: No space left on device"),
    ("memory", MemoryError(), "out of memory (ask for less)"),
    ("value", ValueError("map.frames: expected an integer >= 1"),
     "map.frames: expected an integer >= 1"),
    ("key", KeyError("unknown control 'tail.curly'"), "unknown control 'tail.curly'"),
    ("multi_line", ValueError("2 bad value(s):\n  seed = -1\n  budget.samples = 0"),
     "2 bad value(s): | seed = -1 | budget.samples = 0"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("trial", "error", "message"), EXPECTED_FAILURES, ids=[t[0] for t in EXPECTED_FAILURES]
)
def test_cli_expected_failure_is_one_line_with_exit_2(monkeypatch, capsys, trial, error, message):
    """Trials: OSErrors (IsADirectory, NotADirectory, ENOTEMPTY, ENOSPC), MemoryError,
    ValueError, KeyError, a multi-line message: ``rigmap: error: <command>: <message>``."""
    import rigmap.cli as cli

    monkeypatch.delenv("RIGMAP_DEBUG", raising=False)
    monkeypatch.setattr(cli, "_rigs_list", _raising(error))
    assert cli.main(["rigs", "list"]) == 2
    err = capsys.readouterr().err
    assert err == f"rigmap: error: rigs list: {message}\n"


def test_cli_bug_keeps_its_traceback_and_rigmap_debug_shows_expected_ones(monkeypatch):
    """Trials: a TypeError (a bug) propagates; RIGMAP_DEBUG=1 re-raises an expected one."""
    import rigmap.cli as cli

    monkeypatch.delenv("RIGMAP_DEBUG", raising=False)
    monkeypatch.setattr(cli, "_rigs_list", _raising(TypeError("unsupported operand")))
    with pytest.raises(TypeError, match="unsupported operand"):
        cli.main(["rigs", "list"])
    monkeypatch.setenv("RIGMAP_DEBUG", "1")
    monkeypatch.setattr(cli, "_rigs_list", _raising(IsADirectoryError(21, "Is a dir", "x")))
    with pytest.raises(IsADirectoryError):
        cli.main(["rigs", "list"])


def test_cli_params_yaml_that_is_a_folder_is_one_line(tmp_path, capsys, monkeypatch):
    """Trial: ``rigmap reproduce --params-only`` where params.yaml is a folder."""
    from rigmap.cli import main

    monkeypatch.delenv("RIGMAP_DEBUG", raising=False)
    project = tmp_path / "project"
    shutil.copytree(ROOT / "conf", project / "conf")
    shutil.copy(ROOT / "dvc.yaml", project / "dvc.yaml")
    (project / "params.yaml").mkdir()
    assert main(["reproduce", "--params-only", "--project", str(project)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rigmap: error: reproduce: ") and err.count("\n") == 1, err
    assert "params.yaml" in err and "Traceback" not in err
    assert (project / "params.yaml").is_dir()  # left as it was


FAKE_STAGE = """\
import sys
from pathlib import Path

args = dict(a.lstrip("+").split("=", 1) for a in sys.argv[1:] if "=" in a)
script = Path(sys.argv[0]).stem
name = f"fit_{args['regressor']}" if script == "fit" else script  # learn's stage name
sys.stderr.write(f"{name}: progress 50%\\r{name}: progress 100%\\n")
Path(args["paths.data"], "from_" + script).mkdir(parents=True, exist_ok=True)
if args.get("fail") == name:
    sys.stderr.write(f"error: {name}: corpus file x.parquet does not exist\\n")
    raise SystemExit(2)
"""


def _learn_project(tmp_path: Path) -> Path:
    """conf/ of the repository and stand-in stage scripts that record where they write."""
    project = tmp_path / "project"
    shutil.copytree(ROOT / "conf", project / "conf")
    (project / "pipelines").mkdir()
    for script in ("animate", "pose", "supersample", "fit", "evaluate"):
        (project / "pipelines" / f"{script}.py").write_text(FAKE_STAGE)
    (project / "hero.blend").write_bytes(b"BLENDER-v500")
    return project


def _learn(project: Path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    env.pop("RIGMAP_DEBUG", None)
    return subprocess.run(
        [sys.executable, "-m", "rigmap.cli", "learn", "--project", str(project), *args],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


LEARN_STAGES = ("animate", "pose", "supersample", "fit_nn", "fit_gpr", "fit_mean", "evaluate")


def test_learn_stages_are_the_ones_failed_below():
    from rigmap.learn import STAGES

    assert STAGES == LEARN_STAGES


@pytest.mark.parametrize("stage", LEARN_STAGES, ids=[f"learn_fails_in_{s}" for s in LEARN_STAGES])
def test_learn_stage_failure_is_one_line_error_not_runtime_error(tmp_path, stage):
    """Trial: a stage of ``rigmap learn`` fails with its clear message (was a RuntimeError
    traceback): the message once, as learn's own, exit 2; the stage's progress still shown;
    the stages after it never start."""
    project = _learn_project(tmp_path)
    done = _learn(project, str(project / "hero.blend"), f"+fail={stage}")
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and "RuntimeError" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if "error" in line]
    message = f"rigmap: error: learn: stage {stage}: corpus file x.parquet does not exist"
    assert lines == [message], done.stderr
    assert f"{stage}: progress 100%" in done.stderr
    later = LEARN_STAGES[LEARN_STAGES.index(stage) + 1 :]
    assert not [s for s in later if f"{s}: progress" in done.stderr], done.stderr


def test_learn_writes_under_outputs_never_into_tracked_folders(tmp_path):
    """Trial: ``rigmap learn my.blend`` wrote data/, models/, metrics/ into the checkout;
    now outputs/ (git-ignored) by default, or the folder given with --out."""
    project = _learn_project(tmp_path)
    done = _learn(project, str(project / "hero.blend"))
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in project.iterdir()) == [
        "conf", "hero.blend", "outputs", "pipelines"
    ]  # fmt: skip
    written = sorted(p.name for p in (project / "outputs" / "data").iterdir())
    assert written == ["from_animate", "from_evaluate", "from_fit", "from_pose", "from_supersample"]
    assert "/outputs/" in (ROOT / ".gitignore").read_text().splitlines()
    mine = tmp_path / "mine"
    done = _learn(project, "--out", str(mine), str(project / "hero.blend"))
    assert done.returncode == 0, done.stderr
    assert (mine / "data" / "from_evaluate").is_dir()


ALL_PATHS = ("data", "models", "metrics", "reports")


@pytest.mark.parametrize(
    ("command", "tail", "keys"),
    [
        (["edits", "fit"], [], ALL_PATHS),
        (["edits", "add"], [], ALL_PATHS),
        (["synth", "fit"], [], ALL_PATHS),
        (["synth", "run", "s.yaml"], ["--out", "x.parquet"], ()),  # writes --out only
        (["synth", "demo"], [], ()),
        (["map", "input=a.bvh", "rig=biped"], [], ("models",)),
        (["fit", "rig=biped"], [], ("models",)),
        (["evaluate", "rig=biped"], [], ("metrics", "reports")),
    ],
    ids=["edits_fit", "edits_add", "synth_fit", "synth_run", "synth_demo", "map", "fit", "eval"],
)
def test_user_commands_compose_paths_under_outputs(monkeypatch, command, tail, keys):
    """Trials: ``rigmap edits``, ``synth``, ``map`` (its model cache), ``fit`` and ``evaluate``
    write under outputs/ unless a paths.* override names another folder; the data they only
    read stays the pipeline's; DVC stages keep conf/'s paths."""
    import rigmap.app.config
    import rigmap.cli as cli

    seen = []

    def compose(overrides, config_dir=None, **kwargs):
        seen.append(list(overrides))
        raise ValueError("composed")  # stop before any work

    monkeypatch.delenv("RIGMAP_DEBUG", raising=False)
    monkeypatch.setattr(cli, "compose_config", compose)  # the verbs handed it (synth)
    monkeypatch.setattr(rigmap.app.config, "compose_config", compose)  # the application layer
    assert cli.main([*command, *tail]) == 2
    paths = [o for o in seen[0] if o.startswith("paths.")]
    assert paths == [f"paths.{k}=outputs/{k}" for k in keys]
    seen.clear()
    assert cli.main([*command, "paths.models=/tmp/mine", *tail]) == 2
    assert "paths.models=outputs/models" not in seen[0]
    assert seen[0][-1] == "paths.models=/tmp/mine"


CONFIG_OF_SCRIPT = {"map_mocap": "map", "map": "map", "tune": "tune"}  # run_stage(config_name=)


def _hydra_value(value) -> str:
    """A value as DVC pasted it into a command (``${seed}`` -> ``0``; dvc.parsing's to_str),
    a null as Hydra spells it (a pasted ``None`` would be the string "None")."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


CHANGED = {"seed": 5, "budget.samples": 123, "budget.gpr_points": 77, "budget.cv_splits": 3,
           "budget.refine_iterations": 2, "regressor.hidden": 64, "regressor.alpha": 0.25,
           "corpus.variation": 0.5, "corpus.heldout_sides": "drawn", "latent.max_iter": 9,
           "latent.blend_frames": 6}  # fmt: skip


def test_every_stage_gets_the_config_its_interpolated_command_gave(tmp_path):
    """Trial: one entry of every stage, its placeholders filled and params merged, composes
    the very config the former ``KEY=${KEY}`` command composed, for changed values too."""
    import shlex

    from dvc.repo import Repo
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from rigmap.app.placeholders import apply_params, resolve_argv
    from rigmap.app.stage import stage_config

    project = _project(tmp_path, **CHANGED)
    firsts = {}
    with Repo(str(ROOT)) as repo:
        for stage in repo.index.stages:
            firsts.setdefault(stage.name.partition("@")[0], stage)
    compared, merged = 0, set()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        for name, stage in firsts.items():
            argv = shlex.split(stage.cmd)[1:]  # python <script> overrides...
            if not argv[0].startswith("pipelines/"):
                continue  # check_params: python -m rigmap.pipeline_params check params.yaml
            resolved = resolve_argv(argv, project, stage.name)
            config = CONFIG_OF_SCRIPT.get(Path(argv[0]).stem, "config")
            pasted = [f"{k}={_hydra_value(v)}" for k, (_, v) in resolved.params.items()]
            before = compose(config_name=config, overrides=resolved.argv[1:] + pasted)
            now = compose(config_name=config, overrides=resolved.argv[1:])
            now = apply_params(now, resolved.params)
            assert OmegaConf.to_container(stage_config(now), resolve=True) == (
                OmegaConf.to_container(stage_config(before), resolve=True)
            ), name
            merged |= set(resolved.params)
            compared += 1
    assert compared >= 30, compared
    assert set(CHANGED) <= merged  # each changed value reached some stage
