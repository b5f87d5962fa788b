"""`rigmap rigs …`: the commands a newcomer runs first."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from rigmap.cli import main


@pytest.mark.parametrize("name", ["quadruped", "biped"])
def test_describe_json_has_the_counts(name, capsys):
    assert main(["rigs", "describe", name, "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert {"joints", "controls", "used_controls"} <= set(facts)
    by_kind_total = sum(v["total"] for v in facts["controls_by_kind"].values())
    by_group_used = sum(v["used"] for v in facts["controls_by_group"].values())
    assert by_kind_total == facts["controls"]
    assert by_group_used == facts["used_controls"]
    assert len(facts["joint_names"]) == facts["joints"]


def test_list_names_the_builtin_rigs(capsys):
    assert main(["rigs", "list"]) == 0
    names = capsys.readouterr().out.split()
    assert {"quadruped", "biped"} <= set(names)


def test_render_writes_a_three_view_png(tmp_path, capsys):
    out = tmp_path / "dog.png"
    assert main(["rigs", "render", "quadruped", "--random", "4", "--out", str(out)]) == 0
    image = np.asarray(Image.open(out).convert("L"), dtype=float)
    assert image.shape[1] > 2 * image.shape[0]  # three views side by side
    assert (image < 128).mean() > 0.005  # something dark was drawn: bones, axes, text
    assert not list(tmp_path.glob(".*"))  # no temp file left behind


def test_render_from_a_controls_file_and_its_errors(tmp_path, capsys):
    good = tmp_path / "pose.json"
    good.write_text(json.dumps({"tail.curl": 1.0, "head.ry": 0.4}))
    assert (
        main(
            [
                "rigs",
                "render",
                "quadruped",
                "--controls",
                str(good),
                "--out",
                str(tmp_path / "p.png"),
            ]
        )
        == 0
    )
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"tail.curly": 1.0}))
    assert (
        main(
            [
                "rigs",
                "render",
                "quadruped",
                "--controls",
                str(bad),
                "--out",
                str(tmp_path / "q.png"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "bad.json" in err and "no control named 'tail.curly'" in err
    assert "tail.curl" in err  # the close match is suggested
    assert not (tmp_path / "q.png").exists()


def test_unknown_rig_is_a_clear_error(capsys):
    assert main(["rigs", "describe", "dragon"]) == 2
    err = capsys.readouterr().err
    assert "unknown rig 'dragon'" in err and "quadruped" in err


def test_corpus_show_writes_a_sheet_and_a_gif(tmp_path, capsys):
    out = tmp_path / "tai_chi.png"
    assert (
        main(
            [
                "corpus",
                "show",
                "rig=face",
                "clip=Shouting",
                "--out",
                str(out),
                "--panels",
                "4",
                "--columns",
                "2",
            ]
        )
        == 0
    )
    assert out.exists() and out.with_suffix(".gif").exists()
    with Image.open(out.with_suffix(".gif")) as gif:
        assert gif.n_frames > 10
    assert main(["corpus", "show", "rig=face", "clap=Shouting", "--out", str(out)]) == 2
    assert "expected rig=… clip=…" in capsys.readouterr().err


def test_a_reader_that_closes_the_pipe_early_stops_it_quietly():
    """`rigmap rigs describe biped --controls | head -3`: no traceback, SIGPIPE's status.

    The pipe's reading end is closed before the command starts, so its first write fails
    for certain (a reader closing after some lines races the writer's buffering)."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    command = [sys.executable, "-m", "rigmap.cli", "rigs", "describe", "biped", "--controls"]
    try:
        done = subprocess.run(command, stdout=write_end, stderr=subprocess.PIPE, timeout=120)
    finally:
        os.close(write_end)
    errors = done.stderr.decode()
    assert "Traceback" not in errors and "BrokenPipeError" not in errors, errors
    assert done.returncode == 141
