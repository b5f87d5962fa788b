"""Latent synthesis from a user's .blend and out to a .blend (issue #41): a Rigify human saved
with keyed actions is fitted, matched and played with ``rigmap synth``, and the shot written
as keys on that rig plays back in Blender as the synthesised controls; the ARKit face's shot
written as shape keys plays back the same way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.latent.take_files import blend_takes, read_labelled_takes

pytestmark = [pytest.mark.blender]

ROOT = Path(__file__).resolve().parents[1]
MOTIONS = ("Idle", "Walk", "Range of Motion")
TINY = ["latent.latent_dim=2", "latent.max_iter=20", "latent.log_to_mlflow=false"]


@pytest.fixture(scope="module")
def hero_blend(tmp_path_factory):
    """Rigify's human with three of the biped's motions keyed on it as actions."""
    from rigmap.animation.blend_corpus import write_actions_blend
    from rigmap.animation.library import build_clip, motion_library
    from rigmap.rigs.blender.rigify import rigify_blend

    library = motion_library("rigify_human")
    motions = [
        m for split in ("train", "test") for m in library.motions(split) if m.name in MOTIONS
    ]
    clips = [build_clip("rigify_human", m, seed=0) for m in motions]
    path = tmp_path_factory.mktemp("hero") / "hero.blend"
    write_actions_blend(rigify_blend("human"), clips, path, fps=24)
    return path


def _paths(tmp_path) -> list[str]:
    return [f"paths.{k}={tmp_path / k}" for k in ("data", "models", "metrics", "reports")]


def test_a_blends_actions_fit_play_and_go_back_into_a_blend(hero_blend, tmp_path):
    from rigmap.app.inputs import rig_from_config
    from rigmap.cli import compose_config, main
    from rigmap.latent import steps
    from rigmap.rigs.blender import read_blend_animation
    from rigmap.store import Layout

    rig_overrides = [
        "rig=blend_file",
        f"rig.path={hero_blend}",
        "rig.armature=rig",
        "+rig.workers=1",
    ]
    fit = ["synth", "fit", "--takes", str(hero_blend), "rig.armature=rig", "+rig.workers=1"]
    assert main([*fit, *TINY, *_paths(tmp_path)]) == 0
    assert main(["synth", "match", *rig_overrides, *TINY, *_paths(tmp_path)]) == 0
    layout = Layout.from_paths({k: str(tmp_path / k) for k in ("data", "models", "metrics")})
    fitted = steps.load_fitted(layout, "blend_file:hero")
    assert sorted(fitted.models) == ["Idle", "Range", "Walk"]  # labels from the action names
    assert fitted.sets["Walk"].names == ["Walk train"]
    with rig_from_config(compose_config(rig_overrides, ROOT / "conf").rig) as rig:
        named = blend_takes(hero_blend, rig, fps=24)
        walk = named["Walk"]
        cut = len(walk) - round(0.25 * len(walk))
        np.testing.assert_allclose(fitted.sets["Walk"].takes[0], walk[:cut][:150])
        script = tmp_path / "shot.yaml"
        script.write_text(
            "start: Walk\ncommands:\n  - play: {take: Walk train}\n  - idle: {frames: 6}\n"
        )
        shot = tmp_path / "shot.blend"
        run = ["synth", "run", str(script), *rig_overrides, *TINY, *_paths(tmp_path)]
        assert main([*run, "--out", str(shot)]) == 0
        played, _ = steps.play_script(fitted, steps.load_table(layout, rig.name), script, seed=0)
        table, _ = read_blend_animation(rig, shot, frames=np.arange(len(played)))
    np.testing.assert_allclose(table[list(rig.used_controls)].to_numpy(), played, atol=1e-5)


def test_a_blends_takes_need_a_blender_rig_and_their_labels_a_matching_name(hero_blend):
    from rigmap.rigs import load

    with pytest.raises(ValueError, match="rig=blend_file"):
        read_labelled_takes(hero_blend, load("arkit_face"), fps=24)


def test_a_blend_of_one_action_is_one_take_not_a_corpus_without_a_test_clip(tmp_path):
    """The corpus import holds its most extreme action out and so needs two; takes for the
    latent models hold nothing out, so one action is one take."""
    from rigmap.animation.blend_corpus import (
        BlendCorpusError,
        import_blend_corpus,
        write_actions_blend,
    )
    from rigmap.animation.library import build_clip, motion_library
    from rigmap.rigs.blender.rigify import rigify_blend

    library = motion_library("rigify_human")
    idle = next(m for s in ("train", "test") for m in library.motions(s) if m.name == "Idle")
    path = tmp_path / "idle.blend"
    write_actions_blend(rigify_blend("human"), [build_clip("rigify_human", idle, seed=0)], path)
    options = {"armature": "rig", "check_determinism": False}
    with pytest.raises(BlendCorpusError, match="needs at least two"):
        import_blend_corpus(path, **options)
    takes = import_blend_corpus(path, **options, split=False)
    assert [c.name for c in takes.clips] == ["Idle"] and takes.test_names == []
    assert takes.train_names == ["Idle"]


def test_the_arkit_faces_shot_as_shape_keys_plays_back_its_controls(tmp_path):
    from rigmap.cli import main
    from rigmap.latent import steps
    from rigmap.rigs.blender.shape_keys import read_shape_key_blend
    from rigmap.store import Layout

    tiny = ["rig=arkit_face", "latent.labels=[smiling,talking]", *TINY, *_paths(tmp_path)]
    for verb in ("fit", "match"):
        assert main(["synth", verb, *tiny]) == 0
    script = ROOT / "conf" / "latent" / "scripts" / "smile_after_talking.yaml"
    shot = tmp_path / "shot.blend"
    assert main(["synth", "run", str(script), *tiny, "--out", str(shot)]) == 0
    layout = Layout.from_paths({k: str(tmp_path / k) for k in ("data", "models", "metrics")})
    fitted = steps.load_fitted(layout, "arkit_face")
    played, _ = steps.play_script(fitted, steps.load_table(layout, "arkit_face"), script, seed=0)
    keys = read_shape_key_blend(shot)
    assert len(keys) == len(played) and keys.attrs["fps"] == pytest.approx(30.0)
    from rigmap.rigs import load

    used = load("arkit_face").used_controls
    np.testing.assert_allclose(keys[list(used)].to_numpy(), played, atol=1e-5)
