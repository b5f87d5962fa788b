"""rigmap.catalog: the report labels of methods, samplers and kernels, read from their parts."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigmap.catalog import CatalogueError, Row, default_catalogue, read_catalogue

ROOT = Path(__file__).resolve().parents[1]


def test_the_package_catalogue_has_the_papers_rows_in_table_order():
    catalogue = default_catalogue()
    assert catalogue.keys("sampler") == (
        "none",
        "uniform",
        "univariate_gaussian",
        "multivariate_gaussian",
        "gmm",
        "pca_gaussian",
    )
    assert catalogue.sampler("pca_gaussian") == Row("pca_gaussian", "PCA & Unit Gaussian")
    assert catalogue.kernel("multiquadric").label == "Multiquadric"
    # a yaml off the evaluate lists is catalogued after them, but not expected by a report
    assert catalogue.kernels[-1].key == "multiquadric_plus_linear"
    assert "multiquadric_plus_linear" not in catalogue.keys("kernel")
    nn_cj = catalogue.method("nn_computed_jacobian")
    assert (nn_cj.label, nn_cj.extra, nn_cj.regressor) == ("NN & Computed Jacobian", False, "nn")
    assert catalogue.method("nn_autodiff_jacobian").display == "NN & Autodiff Jacobian (extra)"
    assert catalogue.method("script").regressor is None


def test_a_later_folder_adds_rows_and_an_unknown_name_is_labelled_by_itself(tmp_path):
    (tmp_path / "method").mkdir()
    (tmp_path / "method" / "gpr_damped.yaml").write_text(
        "defaults:\n  - /refine@refine: computed_jacobian\n  - _self_\n"
        "_target_: rigmap.evaluation.method.Method\nextra: true\n"
        "guess:\n  _target_: rigmap.evaluation.method.RegressorGuess\n  regressor: gpr\n"
        "  title: Damped GPR\nrefine:\n  jacobian: autodiff\n"
    )
    catalogue = read_catalogue([ROOT / "conf", tmp_path])
    row = catalogue.method("gpr_damped")  # its refine group is read from the first folder
    assert (row.label, row.extra) == ("Damped GPR & Autodiff Jacobian", True)
    assert catalogue.methods[-1].key == "gpr_damped"
    assert catalogue.method("nn_magic") == Row("nn_magic", "nn_magic")
    with pytest.raises(CatalogueError, match="kind must be one of"):
        catalogue.rows("regressor")


def test_bad_parts_are_refused_naming_the_file(tmp_path):
    (tmp_path / "sampler").mkdir()
    bad = tmp_path / "sampler" / "ghost.yaml"
    bad.write_text("_target_: rigmap.sampling.NoSuchSampler\n")
    with pytest.raises(CatalogueError, match=r"ghost\.yaml: _target_ 'rigmap.sampling.NoSuch"):
        read_catalogue([tmp_path])
    bad.write_text("- a list\n")
    with pytest.raises(CatalogueError, match=r"ghost\.yaml: expected a mapping"):
        read_catalogue([tmp_path])
    bad.unlink()
    (tmp_path / "method").mkdir()
    (tmp_path / "method" / "odd.yaml").write_text("extra: maybe\n")
    with pytest.raises(CatalogueError, match=r"odd\.yaml: extra must be true or false"):
        read_catalogue([tmp_path])
    with pytest.raises(CatalogueError, match="do not exist"):
        read_catalogue([tmp_path / "nowhere"])
