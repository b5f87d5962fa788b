"""Stage entry points (rigmap.stage.run_stage): rigmap's errors as one message, bugs as tracebacks.

Each case runs a real pipeline script in a subprocess with ``HYDRA_FULL_ERROR`` unset, as a
user's shell would, and checks stderr, the exit status and that nothing was written.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rigmap.app.stage import USER_ERROR_EXIT, error_message, is_user_error

ROOT = Path(__file__).resolve().parents[1]


def run_script(name: str, *overrides: str, cwd: Path, debug: bool = False):
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "RIGMAP_DEBUG")}
    env["PYTHONPATH"] = str(ROOT / "src")
    if debug:
        env["RIGMAP_DEBUG"] = "1"
    return subprocess.run(
        [sys.executable, str(ROOT / "pipelines" / f"{name}.py"), *overrides],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def files_under(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


def test_a_missing_corpus_file_is_one_message_naming_it(tmp_path):
    result = run_script("pose", "rig=face", "paths.data=data", cwd=tmp_path)
    assert result.returncode == USER_ERROR_EXIT, result.stderr
    assert "Traceback" not in result.stderr
    assert "HYDRA_FULL_ERROR" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines == [
        f"error: pose: corpus file {Path('data/face/corpus/train.parquet')} does not exist"
    ]
    assert files_under(tmp_path) == []


def test_an_unknown_rig_is_one_message_listing_the_choices(tmp_path):
    result = run_script("animate", "rig=nope", "paths.data=data", cwd=tmp_path)
    assert result.returncode == USER_ERROR_EXIT, result.stderr
    assert "Traceback" not in result.stderr
    assert "HYDRA_FULL_ERROR" not in result.stderr
    assert result.stderr.startswith("error: animate: ")
    assert "Could not find 'rig/nope'" in result.stderr
    assert "quadruped" in result.stderr  # the options Hydra lists
    assert files_under(tmp_path) == []


def test_a_corrupted_corpus_file_is_one_message_naming_it(tmp_path):
    corpus = tmp_path / "data" / "face" / "corpus"
    corpus.mkdir(parents=True)
    (corpus / "train.parquet").write_bytes(b"not a parquet file")
    result = run_script("supersample", "rig=face", "sampler=uniform", cwd=tmp_path)
    assert result.returncode == USER_ERROR_EXIT, result.stderr
    assert "Traceback" not in result.stderr
    assert result.stderr.startswith(
        f"error: supersample: {Path('data/face/corpus/train.parquet')}: not a readable parquet file"
    )
    assert files_under(tmp_path) == ["data/face/corpus/train.parquet"]


@pytest.mark.parametrize(
    ("stage", "overrides", "expected"),
    [
        ("fit", ["rig=face", "regressor=gpr", "sampler=none"], "the train corpus of rig 'face'"),
        ("report", ["paths.metrics=m", "paths.data=d", "paths.reports=r"], "m/quadruped/methods/"),
        ("supersample", ["rig=face", "sampler=nope"], "Could not find 'sampler/nope'"),
        (
            "animate",
            ["rig=rigify_human", "rig.name=blend_file"],
            "no motion library for rig 'blend_file'",
        ),  # a user's .blend rig: no clips
    ],
)
def test_other_stages_print_their_errors_as_one_message(tmp_path, stage, overrides, expected):
    result = run_script(stage, *overrides, cwd=tmp_path)
    assert result.returncode == USER_ERROR_EXIT, result.stderr
    assert "Traceback" not in result.stderr and "HYDRA_FULL_ERROR" not in result.stderr
    assert result.stderr.startswith(f"error: {stage}: ")
    assert expected in result.stderr
    assert files_under(tmp_path) == []


def test_rigmap_debug_shows_the_traceback_of_a_user_error(tmp_path):
    result = run_script("pose", "rig=face", "paths.data=data", cwd=tmp_path, debug=True)
    assert result.returncode == 1
    assert "Traceback" in result.stderr
    assert "FileNotFoundError: corpus file" in result.stderr


def test_a_bug_keeps_its_traceback(tmp_path):
    """A value of the wrong type reaching int() is not an error rigmap raised on purpose."""
    result = run_script("animate", "rig=face", "corpus.variation=abc", cwd=tmp_path)
    assert result.returncode == 1
    assert "Traceback" in result.stderr
    assert "ValueError" in result.stderr


@pytest.mark.parametrize(
    ("error", "user", "message"),
    [
        (FileNotFoundError("corpus file x.parquet does not exist"), True, None),
        (FileNotFoundError(2, "No such file or directory", "x.npz"), True, None),
        (PermissionError(13, "Permission denied", "models/q"), True, None),
        (FileNotFoundError(), False, "FileNotFoundError"),
        (ValueError("cannot reshape"), False, None),
        (KeyError("plain KeyError"), False, "plain KeyError"),
    ],
)
def test_which_errors_are_the_users(error, user, message):
    assert is_user_error(error) is user
    assert error_message(error) == (message or str(error))


def test_a_rigmap_key_error_prints_without_quotes():
    from rigmap.rigs.base import UnknownRigError

    error = UnknownRigError("unknown rig 'nope'; available rigs: face")
    assert is_user_error(error)
    assert error_message(error) == "unknown rig 'nope'; available rigs: face"
