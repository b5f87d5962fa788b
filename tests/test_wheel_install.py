"""rigmap built as a wheel and installed into a fresh virtual environment outside the
checkout: ``rigmap rigs list`` and a tiny fit run from a folder that has no ``conf/``.

Nothing is downloaded: the wheel is built without build isolation from the running
interpreter's setuptools, installed with ``--no-deps``, and the environment gets the
dependencies through a ``.pth`` file naming this interpreter's site-packages, which comes
after the new environment's own (so the ``rigmap`` imported is the wheel's).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 300  # ours: each step takes seconds; this only stops a hung one

#: the corpus and poses of one rig, made by the installed library (the DVC stages'
#: scripts are not part of the wheel); the config is the one shipped inside the package
MAKE_DATA = """
from rigmap.animation.corpus_files import pose_corpora, write_corpora
from rigmap.cli import compose_config
from rigmap.app.inputs import corpus_settings, layout_of, rig_from_config

cfg = compose_config(["rig=quadruped"])
rig, layout = rig_from_config(cfg.rig), layout_of(cfg)
write_corpora(rig, layout, **corpus_settings(cfg))
pose_corpora(rig, layout, batch_size=int(cfg.pose.batch_size), progress=False)
"""


#: the data files the modules read at import (package-data in pyproject.toml), summarised
SHIPPED_DATA = """
from rigmap.animation.library import face
from rigmap.reports import edits_tables, latent_tables, published
from rigmap.rigs.blender import rigify
from rigmap.rigs.characters import face as face_rig, squirrel

print(published.TABLE1[-1], sorted(latent_tables.TABLES), sorted(edits_tables.TABLES))
print(rigify.PRESETS, sorted(face.BEATS), face_rig.COLOURS, squirrel.COLOURS)

from rigmap.studio.page_server import PAGES, served_files

print({route: len(body) for route, (body, _) in served_files(PAGES).items()})  # own pages
"""


def _run(command: list, cwd: Path) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["MLFLOW_TRACKING_URI"] = f"sqlite:///{cwd / 'mlruns.db'}"
    done = subprocess.run(
        [str(c) for c in command],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )
    assert done.returncode == 0, f"{command} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def _wheel(tmp: Path) -> Path:
    """A wheel built from a copy of the sources (building in the checkout would leave
    ``build/`` and ``*.egg-info`` there)."""
    source = tmp / "source"
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info")
    for name in ("src", "conf"):
        shutil.copytree(ROOT / name, source / name, symlinks=True, ignore=skip)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, source / name)
    pip = [sys.executable, "-m", "pip"]
    _run([*pip, "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-w", tmp, source], tmp)
    (wheel,) = tmp.glob("rigmap-*.whl")
    return wheel


def _environment(tmp: Path, wheel: Path) -> Path:
    """A new venv holding only the wheel; this interpreter's packages come after it."""
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], tmp)
    python = venv / "bin" / "python"
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            python,
            "install",
            "--no-deps",
            "--no-index",
            wheel,
        ],
        tmp,
    )
    own = _run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp)
    ours = {sysconfig.get_paths()[key] for key in ("purelib", "platlib")}
    # "zz": .pth files are read in name order, and each path goes after the venv's own
    (Path(own.strip()) / "zz_rigmap_dependencies.pth").write_text("\n".join(sorted(ours)) + "\n")
    return venv


@pytest.mark.slow
def test_wheel_in_a_fresh_venv_lists_rigs_and_fits(tmp_path):
    venv = _environment(tmp_path, _wheel(tmp_path))
    work = tmp_path / "work"  # outside the checkout, with no conf/ of its own
    work.mkdir()
    python, rigmap = venv / "bin" / "python", venv / "bin" / "rigmap"

    imported = _run([python, "-c", "import rigmap; print(rigmap.__file__)"], work).strip()
    assert Path(imported).is_relative_to(venv), imported
    # the package's own conf/ is found beside the package, and no checkout is reached
    where = "from rigmap.store.layout import packaged_conf as p, source_checkout as s"
    shipped, checkout = _run([python, "-c", f"{where}; print(p()); print(s())"], work).split()
    assert Path(shipped).is_relative_to(venv) and (Path(shipped) / "config.yaml").is_file()
    assert checkout == "None", checkout

    # the data files came with the wheel: the installed modules read what the tree's do
    data = subprocess.run(
        [sys.executable, "-c", SHIPPED_DATA], capture_output=True, text=True, check=True
    ).stdout
    assert _run([python, "-c", SHIPPED_DATA], work) == data

    listed = _run([rigmap, "rigs", "list"], work).split()
    assert {"quadruped", "biped", "face", "squirrel"} <= set(listed), listed

    _run([python, "-c", MAKE_DATA], work)
    assert (work / "data/quadruped/poses/train.parquet").is_file()
    _run(
        [
            rigmap,
            "fit",
            "rig=quadruped",
            "regressor=gpr",
            "sampler=none",
            "budget.gpr_points=60",
            "budget.length_scales=3",
            "budget.cv_splits=2",
        ],
        work,
    )
    fit = json.loads((work / "outputs/models/quadruped/gpr-none-multiquadric/fit.json").read_text())
    assert fit["gpr"]["support_points"] == 60
    # a real fit: closer to the training controls than the mean predictor (which scores 1)
    assert fit["training_error"]["ground_truth_error"] < 0.9
