"""rigmap.app.inputs: the plain objects a stage builds from its composed config."""

from __future__ import annotations

from pathlib import Path

from hydra import compose, initialize_config_dir

from rigmap.app.inputs import corpus_fps, layout_of, rig_from_config, sampler_seed
from rigmap.store import Layout

ROOT = Path(__file__).resolve().parents[1]


def config(*overrides: str):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def test_layout_of_the_paths_config(tmp_path):
    cfg = config(f"paths.data={tmp_path / 'd'}", "paths.models=m")
    layout = layout_of(cfg)
    assert layout == Layout(data=tmp_path / "d", models=Path("m"))
    assert layout.corpus("face", "train") == tmp_path / "d/face/corpus/train.parquet"
    assert layout.samples("face", "gmm") == tmp_path / "d/face/samples/gmm.npz"


def test_the_rig_and_its_corpus_frame_rate_from_the_rig_group():
    face = config("rig=face")
    assert corpus_fps(face.rig) == 30  # conf/rig/face.yaml
    assert rig_from_config(face.rig).name == "face"  # `corpus` is not the factory's option
    assert corpus_fps(config("rig=rigify_wolf").rig) == 24  # no corpus block: the default


def test_the_sampler_seed_is_the_runs_seed_mixed_with_the_strategy():
    assert sampler_seed(0, "gmm") == sampler_seed(0, "gmm")
    assert len({sampler_seed(0, "gmm"), sampler_seed(1, "gmm"), sampler_seed(0, "uniform")}) == 3
