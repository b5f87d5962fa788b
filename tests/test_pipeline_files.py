"""The stage files: the root dvc.yaml and stages/<family>/dvc.yaml, read as one pipeline."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigmap.reproduce import dvc_target
from rigmap.store.pipeline_files import (
    PipelineFileError,
    family_of,
    pipeline_files,
    short_name,
    stage_families,
)

ROOT = Path(__file__).resolve().parents[1]


def _write(project: Path, path: str, text: str) -> None:
    (project / path).parent.mkdir(parents=True, exist_ok=True)
    (project / path).write_text(text)


def test_families_come_from_every_file_with_their_file(tmp_path):
    _write(tmp_path, "dvc.yaml", "stages:\n  report:\n    cmd: python r.py\n")
    _write(
        tmp_path,
        "stages/fit/dvc.yaml",
        "stages:\n  fit: &fit\n    wdir: ../..\n    meta: {runs_alone: true}\n"
        "    cmd: python f.py\n  fit_more: {<<: *fit, cmd: python g.py}\n",
    )
    assert pipeline_files(tmp_path) == [Path("dvc.yaml"), Path("stages/fit/dvc.yaml")]
    families = stage_families(tmp_path)
    assert sorted(families) == ["fit", "fit_more", "report"]
    assert families["fit_more"].body["meta"] == {"runs_alone": True}  # anchors within a file
    assert families["fit"].address("fit@biped-gmm") == "stages/fit/dvc.yaml:fit@biped-gmm"
    assert families["report"].address("report") == "report"
    assert dvc_target(families, "fit@biped") == "stages/fit/dvc.yaml:fit@biped"
    assert dvc_target(families, "fit") == "stages/fit/dvc.yaml:fit"
    assert dvc_target(families, "report") == "report"
    assert dvc_target(families, "unknown@x") == "unknown@x"  # DVC names what it cannot find
    # a matrix key with a colon (a .blend's rig, blend_file:hero) is a name, not an address
    assert dvc_target(families, "fit@blend_file:hero") == "stages/fit/dvc.yaml:fit@blend_file:hero"
    address = "stages/fit/dvc.yaml:fit@blend_file:hero"
    assert dvc_target(families, address) == address


def test_a_family_defined_twice_is_refused_naming_both_files(tmp_path):
    _write(tmp_path, "dvc.yaml", "stages:\n  fit:\n    cmd: python f.py\n")
    _write(tmp_path, "stages/fit/dvc.yaml", "stages:\n  fit:\n    cmd: python g.py\n")
    with pytest.raises(PipelineFileError, match=r"stages/fit/dvc.yaml: stage 'fit' .* dvc.yaml"):
        stage_families(tmp_path)


def test_a_broken_stage_file_is_named(tmp_path):
    _write(tmp_path, "stages/map/dvc.yaml", "stages: [unclosed\n")
    with pytest.raises(PipelineFileError, match=r"stages/map/dvc\.yaml: not a readable stage file"):
        stage_families(tmp_path)


def test_short_names_and_families():
    assert short_name("stages/fit/dvc.yaml:fit_nn@biped-gmm") == "fit_nn@biped-gmm"
    assert short_name("fit_nn@biped-gmm") == "fit_nn@biped-gmm"
    assert short_name("stages/fit/dvc.yaml:fit_mean_blend_file") == "fit_mean_blend_file"
    assert family_of("stages/evaluate/dvc.yaml:evaluate@quadruped") == "evaluate"
    assert family_of("report") == "report"


def test_the_repository_keeps_only_the_two_pipeline_wide_stages_at_the_root():
    families = stage_families(ROOT)
    at_root = sorted(n for n, f in families.items() if f.file == Path("dvc.yaml"))
    assert at_root == ["check_params", "report"]
    for name, found in families.items():
        if found.file != Path("dvc.yaml"):  # every other stage runs from the project root
            assert found.body.get("wdir") == "../..", name
