"""Faults at the start of ``rigmap reproduce``: bad parameters, signals, what a run needs.

Issue 20, defects 3 (values reach the shell unchecked), 4 (a broken tracking server is
found late, hangs, or gives a traceback), 5 (unwritable outputs found after the work),
7 (``budget.samples=0``), 8 (a killed ``--dry`` leaves params.yaml modified) and 9
(silent coercions of ``budget.samples=2.5`` and ``regressor.hidden=1.5``).

The project is a copy of the real ``conf/`` and stage files; ``dvc`` is a small fake
script (it records that it ran), so no stage ever runs.
"""

from __future__ import annotations

import http.server
import io
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from rigmap.app.params import ParamsError, write_params
from rigmap.preflight import PreflightError, check_pipeline_needs
from rigmap.reproduce import plan_reproduce, run_reproduce
from stage_scripts import copy_stage_files

REPO = Path(__file__).resolve().parents[1]
NO_TRACKING_ENV = {"PATH": os.environ.get("PATH", "")}


@pytest.fixture
def project(tmp_path) -> Path:
    folder = tmp_path / "project"
    folder.mkdir()
    shutil.copytree(REPO / "conf", folder / "conf")
    copy_stage_files(folder)
    write_params(folder)
    return folder


@pytest.fixture
def fake_dvc(tmp_path) -> Path:
    """A ``bin/`` with a ``dvc`` that notes its arguments in ``ran.txt`` and then sleeps."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    script = bin_dir / "dvc"
    script.write_text(
        f'#!/bin/sh\necho "$@" >> {tmp_path / "ran.txt"}\necho "Running stage \'x\'"\n'
        'case "$1" in repro) exec sleep 30;; dag) echo "";; status) echo "{}";; esac\n'
    )
    script.chmod(0o755)
    return bin_dir


# --------------------------------------------------------------------------- parameter values
BAD_OVERRIDES = {
    # override: the words the error must hold (besides the key)
    "budget.samples=2.5": "expected an integer",  # defect 9: silently drew 2
    "budget.samples=abc": "expected an integer",  # defect 3
    "budget.samples=-5": "integer >= 1",  # defect 3
    "budget.samples=0": "integer >= 1",  # defect 7: wrote an empty file, the fit failed later
    "regressor.hidden=1.5": "expected an integer",  # defect 9: trained 1 unit
    "regressor.hidden=0": "integer >= 1",
    "regressor.epochs=-1": "integer >= 1",
    "regressor.learning_rate=0": "finite number > 0",
    "regressor.learning_rate=nan": "finite number",
    "regressor.learning_rate=inf": "finite number",
    "regressor.alpha=-0.1": "finite number >= 0",
    "regressor.threads=0": "integer >= 1",
    "budget.cv_splits=1": "integer >= 2",
    "pose.batch_size=0": "integer >= 1",
    "supersample.chunk_size=true": "expected an integer",
    "seed=-1": "integer >= 0",
    "seed=1.5": "expected an integer",
    "corpus.variation=0": "finite number > 0",
    "tracking.probe_timeout_s=-3": "finite number > 0",
    "rig.name='quadruped; touch pwned'": "shell metacharacter",  # defect 3: ran a command
    "tracking.experiment_prefix='a$(id)'": "shell metacharacter",
    "paths.data='d`id`'": "shell metacharacter",
    "evaluate.methods=[nn,'gpr|x']": "shell metacharacter",
}


@pytest.mark.parametrize("override", list(BAD_OVERRIDES))
def test_bad_values_are_refused_before_params_yaml_is_written(project, override):
    """Defects 3, 7, 9: each value names its key and what was expected; the file is untouched."""
    before = (project / "params.yaml").read_bytes()
    with pytest.raises(ParamsError) as error:
        write_params(project, [override])
    key = override.split("=", 1)[0]
    assert f"{key} = " in str(error.value) and BAD_OVERRIDES[override] in str(error.value)
    assert (project / "params.yaml").read_bytes() == before
    assert [p.name for p in project.glob(".params.yaml*")] == []  # no temporary left


def test_an_unquoted_semicolon_is_refused_by_the_override_grammar(project):
    with pytest.raises(ParamsError, match=r"cannot compose .* rig\.name=quadruped;ls"):
        write_params(project, ["rig.name=quadruped;ls"])


def test_good_values_are_written(project):
    update = write_params(project, ["budget.samples=20000", "regressor.learning_rate=1e-4"])
    written = yaml.safe_load((project / "params.yaml").read_text())
    assert written["budget"]["samples"] == 20000 and update.changed
    assert written["regressor"]["learning_rate"] == 1e-4
    write_params(project, ["experiment=paper"])  # every value of the paper's experiment passes


CLI_BAD_VALUES = {
    "budget.samples=2.5": "budget.samples = 2.5: expected an integer",
    "budget.samples=0": "budget.samples = 0: expected an integer >= 1",
    "regressor.hidden=abc": "regressor.hidden = 'abc': expected an integer",
    "rig.name='x; rm -rf ~'": "rig.name = 'x; rm -rf ~': contains ';', a shell metacharacter",
    "experiment=papr": "unknown experiment 'papr'",
}


@pytest.mark.parametrize("override", list(CLI_BAD_VALUES))
def test_the_cli_prints_the_bad_value_without_a_traceback(project, override):
    done = subprocess.run(
        [sys.executable, "-m", "rigmap.cli", "reproduce", "--params-only", "--project",
         str(project), override],
        capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": _path()},
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert CLI_BAD_VALUES[override] in done.stderr
    assert "Traceback" not in done.stderr


def _path() -> str:
    return os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])


# --------------------------------------------------------------------------- signals
SIGNALLED_DRY_RUN = """
import sys
from rigmap.reproduce import plan_reproduce, run_reproduce
plan = plan_reproduce(["budget.samples=1234"], project=sys.argv[1], dry=True,
                      python=sys.argv[2] + "/python")
sys.exit(run_reproduce(plan))
"""


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_signalled_dry_run_puts_params_yaml_back(project, fake_dvc, tmp_path, signum):
    """Defect 8: SIGTERM of ``rigmap reproduce --dry`` left the dry run's params.yaml."""
    before = (project / "params.yaml").read_bytes()
    # a shell that started the suite in the background leaves SIGINT ignored, and Python then
    # installs no Ctrl-C handler; the child gets the default disposition a terminal gives
    process = subprocess.Popen(
        [sys.executable, "-c", SIGNALLED_DRY_RUN, str(project), str(fake_dvc)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": _path()},
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while "repro" not in _read(tmp_path / "ran.txt"):  # dvc repro --dry is running
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert b"samples: 1234" in (project / "params.yaml").read_bytes()
        process.send_signal(signum)
        process.wait(timeout=120)
    finally:
        process.kill()
        process.wait()
    assert process.returncode in (128 + signum, -signum)  # SIGINT: Python dies by the signal
    assert (project / "params.yaml").read_bytes() == before
    assert [p.name for p in project.glob(".params.yaml*")] == []


def _read(path: Path) -> str:
    return path.read_text() if path.is_file() else ""


# --------------------------------------------------------------------------- preflight
def _params(project: Path, **tracking) -> dict:
    params = yaml.safe_load((project / "params.yaml").read_text())
    params["tracking"].update(tracking)
    return params


def test_preflight_passes_on_a_healthy_project(project):
    checks = check_pipeline_needs(project, _params(project), NO_TRACKING_ENV)
    assert checks == [
        "Blender worker environment: ok", "tracking store: ok", "output folders: ok",
    ]  # fmt: skip


def test_closed_port_is_named_at_once(project):
    """Defect 4: a closed port was named only when an evaluate stage was reached."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]  # nothing listens there once closed
    uri = f"http://127.0.0.1:{port}"
    started = time.perf_counter()
    with pytest.raises(PreflightError, match="connection refused") as error:
        check_pipeline_needs(project, _params(project, uri=uri), NO_TRACKING_ENV)
    assert uri in str(error.value) and time.perf_counter() - started < 5


def test_hanging_server_fails_within_the_stated_timeout(project):
    """Defect 4: a server that accepts connections and never answers hung for 252 s."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(8)
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}"
        started = time.perf_counter()
        params = _params(project, uri=uri, probe_timeout_s=60.0)  # capped at 10 s
        with pytest.raises(PreflightError, match=r"timeout 10 s; no answer within 10 s"):
            check_pipeline_needs(project, params, NO_TRACKING_ENV)
        assert 9 < time.perf_counter() - started < 15


class _Failing(http.server.BaseHTTPRequestHandler):
    def do_GET(self):  # http.server calls it by this name
        self.send_error(503, "Service Unavailable")

    def log_message(self, *args):
        pass


def test_failing_server_is_one_clear_error(project):
    """Defect 4: a server answering 503 gave a raw traceback."""
    server = http.server.HTTPServer(("127.0.0.1", 0), _Failing)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        uri = f"http://127.0.0.1:{server.server_address[1]}"
        with pytest.raises(PreflightError, match=r"answers HTTP 503: the server is failing"):
            check_pipeline_needs(project, _params(project, uri=uri), NO_TRACKING_ENV)
    finally:
        server.shutdown()
        server.server_close()


def test_an_output_folder_that_cannot_be_written_is_named(project):
    """Defect 5: an unwritable models/ gave a raw PermissionError after the fits."""
    (project / "models").write_text("a file where the models folder should be")
    with pytest.raises(PreflightError, match=r"paths\.models = .*models: is a file"):
        check_pipeline_needs(project, _params(project), NO_TRACKING_ENV)


def test_missing_blender_is_named_before_any_stage(project, monkeypatch):
    """Issue 20: a missing Blender environment failed only after 87 stages and 32 minutes."""
    monkeypatch.setenv("RIGMAP_BLENDER", str(project / "no-such-blender"))
    # the wolf, the .blend fixture (a Blender rig of its own config) and the human only mapped
    needs = r"Blender rig\(s\) \['rigify_wolf', 'blend_file:hero', 'rigify_human'\] need Blender"
    with pytest.raises(PreflightError, match=needs):
        check_pipeline_needs(project, _params(project), NO_TRACKING_ENV)


def test_reproduce_stops_before_dvc_and_keeps_params_yaml(project, fake_dvc, tmp_path):
    """Every problem is listed at once, in seconds, and dvc repro never starts."""
    (project / "reports").write_text("not a folder")
    before = (project / "params.yaml").read_bytes()
    environ = {"PATH": os.environ["PATH"], "MLFLOW_TRACKING_URI": "http://127.0.0.1:9"}
    plan = plan_reproduce(
        ["budget.samples=999"], project=project, python=fake_dvc / "python", environ=environ
    )
    started = time.perf_counter()
    with pytest.raises(PreflightError) as error:
        run_reproduce(plan, out=io.StringIO())
    assert time.perf_counter() - started < 15
    message = str(error.value)
    assert "2 problem(s)" in message and "http://127.0.0.1:9" in message
    assert "paths.reports" in message
    assert "repro" not in _read(tmp_path / "ran.txt")
    assert (project / "params.yaml").read_bytes() == before


def test_reproduce_preflight_lines_then_dvc(project, fake_dvc, tmp_path):
    plan = plan_reproduce(
        ["budget.samples=999"], project=project, python=fake_dvc / "python",
        environ=NO_TRACKING_ENV, params_only=False,
    )  # fmt: skip
    plan = plan.__class__(**{**plan.__dict__, "command": (plan.command[0], "status")})
    log = tmp_path / "out.txt"
    with log.open("w") as out:
        assert run_reproduce(plan, out=out) == 0
    text = log.read_text()
    assert "preflight output folders: ok" in text and "status" in _read(tmp_path / "ran.txt")
    assert b"samples: 999" in (project / "params.yaml").read_bytes()  # a real run keeps it


def test_stages_run_with_pinned_cpu_code_paths(project, fake_dvc):
    """Issue 20 (reproducible numbers): MKL and ATen take the same code path on every machine;
    a value the user set wins."""
    plan = plan_reproduce([], project=project, python=fake_dvc / "python", environ={"PATH": ""})
    assert plan.env["MKL_CBWR"] == "AVX2" and plan.env["ATEN_CPU_CAPABILITY"] == "avx2"
    mine = {"PATH": "", "MKL_CBWR": "COMPATIBLE"}
    plan = plan_reproduce([], project=project, python=fake_dvc / "python", environ=mine)
    assert plan.env["MKL_CBWR"] == "COMPATIBLE"


def test_stages_run_on_one_thread_unless_the_user_says_otherwise(project, fake_dvc):
    """A stage process started with the plan's environment runs torch and numpy's BLAS on
    one thread (side-by-side stages' threads would wait on each other); OMP_NUM_THREADS
    set by the user wins."""
    probe = (
        "import torch, numpy, threadpoolctl; "
        "blas = [p['num_threads'] for p in threadpoolctl.threadpool_info() "
        "if p['user_api'] == 'blas']; print(torch.get_num_threads(), max(blas))"
    )
    for mine, wanted in (({}, "1 1"), ({"OMP_NUM_THREADS": "2"}, "2")):
        environ = {"PATH": "", **mine}
        plan = plan_reproduce([], project=project, python=fake_dvc / "python", environ=environ)
        env = {**plan.env, "PATH": os.environ["PATH"]}
        shown = subprocess.run(
            [sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True
        ).stdout.split()
        assert " ".join(shown[: len(wanted.split())]) == wanted, shown
