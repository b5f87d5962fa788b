"""``rigmap learn PATH.blend``: the stage commands it runs on a user's .blend (no Blender)."""

from __future__ import annotations

import io
import shlex
from pathlib import Path

import pytest

from rigmap.cli import _parser, compose_config
from rigmap.learn import STAGES, learn_commands, run_learn

PROJECT = Path(__file__).resolve().parents[1]


@pytest.fixture
def blend(tmp_path):
    path = tmp_path / "hero.blend"
    path.write_bytes(b"BLENDER-v500")  # the commands are made without opening it
    return path


def test_every_stage_runs_on_rig_blend_file_with_the_overrides(blend):
    commands = learn_commands(
        blend, armature="rig", overrides=["seed=3"], project=PROJECT, compose=compose_config
    )
    assert [name for name, _ in commands] == list(STAGES)  # one sampler, one kernel (Table 1)
    for _, argv in commands:
        assert argv[2:5] == ["rig=blend_file", f"rig.path={blend.resolve()}", "rig.armature=rig"]
        assert argv[-1] == "seed=3"
    scripts = [Path(argv[1]).name for _, argv in commands]
    assert scripts[:3] == ["animate.py", "pose.py", "supersample.py"]
    assert scripts[-1] == "evaluate.py" and "evaluate.set=methods" in commands[-1][1]
    assert "kernel=multiquadric" in dict(commands)["fit_gpr"]
    assert "sampler=pca_gaussian" in dict(commands)["fit_nn"]


def test_until_stops_after_a_stage_and_bad_input_is_named(blend, tmp_path):
    out = io.StringIO()
    report = run_learn(
        blend, project=PROJECT, compose=compose_config, until="pose", dry=True, out=out
    )
    lines = out.getvalue().splitlines()
    assert [line.split(":")[1].strip() for line in lines] == ["animate", "pose"]
    assert report["stages"] == [] and "rig.armature" not in out.getvalue()  # the only armature
    # each line is the command as it runs (interpreter, script, overrides, in the project)
    commands = learn_commands(blend, project=PROJECT, compose=compose_config)[:2]
    for line, (_, argv) in zip(lines, commands, strict=True):
        assert line.split(": ", 2)[2] == f"cd {PROJECT} && {shlex.join(argv)}"
    with pytest.raises(ValueError, match="--until must be one of"):
        run_learn(blend, project=PROJECT, compose=compose_config, until="nope", dry=True, out=out)
    with pytest.raises(FileNotFoundError, match=r"no \.blend file at"):
        learn_commands(tmp_path / "missing.blend", project=PROJECT, compose=compose_config)
    (tmp_path / "rig.fbx").write_bytes(b"")
    with pytest.raises(ValueError, match=r"expected a \.blend file"):
        learn_commands(tmp_path / "rig.fbx", project=PROJECT, compose=compose_config)


def test_the_cli_parses_options_then_the_file_and_overrides(blend):
    args = _parser().parse_args(["learn", "--armature", "rig", str(blend), "seed=1"])
    assert (args.blend, args.armature, args.overrides) == (blend, "rig", ["seed=1"])
