"""Latent synthesis's sets from captured takes: the shared Live Link Face takes, as the label
file labels them, on the ARKit face (issue #41)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.latent.captured_sets import CAPTURED_FRAMES, captured_sets
from rigmap.latent.errors import LatentInputError
from rigmap.latent.live_link import live_link_columns, read_take
from rigmap.latent.segment_labels import labelled_takes, read_labels
from rigmap.rigs import load

ROOT = Path(__file__).resolve().parents[1]
LABELS = ROOT / "conf" / "latent" / "labels" / "shared_face.yaml"


@pytest.fixture(scope="module")
def arkit():
    return load("arkit_face")


@pytest.fixture(scope="module")
def sets(arkit):
    return {
        side: captured_sets(arkit, LABELS, fps=30, heldout=side == "held out")
        for side in ("train", "held out")
    }


def test_every_label_has_training_and_held_out_frames_within_the_budget(sets, arkit):
    labels = ["range_of_motion", "smiling", "talking", "frowning", "blinking"]
    train, held = CAPTURED_FRAMES["quick"]
    assert list(sets["train"]) == list(sets["held out"]) == labels
    for label in labels:
        assert 24 <= sets["train"][label].n_frames <= train
        assert 12 <= sets["held out"][label].n_frames <= held
        values = sets["train"][label].values
        assert values.shape[1] == len(arkit.controls.used_indices)  # the used controls
        assert values.min() >= 0.0 and values.max() <= 1.0 + 1e-9


def test_held_out_frames_are_the_takes_last_quarter_never_trained_on(sets, arkit):
    """The range-of-motion take (one 600-frame segment): training is its first frames,
    held out the first frames of its last quarter."""
    used = [arkit.control_names[i] for i in arkit.controls.used_indices]
    (take,) = [
        t
        for t in labelled_takes(read_labels(LABELS), names=live_link_columns(used))
        if t.label == "range_of_motion"
    ]
    train, held = CAPTURED_FRAMES["quick"]
    cut = len(take.values) - round(0.25 * len(take.values))
    np.testing.assert_array_equal(sets["train"]["range_of_motion"].values, take.values[:train])
    np.testing.assert_array_equal(
        sets["held out"]["range_of_motion"].values, take.values[cut : cut + held]
    )
    assert sets["held out"]["range_of_motion"].names == [f"{take.name} held out"]


def test_a_label_file_at_another_rate_or_an_unknown_label_is_refused(arkit):
    with pytest.raises(LatentInputError, match=r"at 30 fps.*latent\.<rig>_fps"):
        captured_sets(arkit, LABELS, fps=24)
    with pytest.raises(LatentInputError, match=r"no label \['yawning'\]"):
        captured_sets(arkit, LABELS, fps=30, labels=["yawning"])
    with pytest.raises(LatentInputError, match="size must be one of"):
        captured_sets(arkit, LABELS, fps=30, size="huge")


def test_a_rig_whose_controls_are_not_arkits_is_refused():
    with pytest.raises(LatentInputError, match="is not an ARKit blendshape"):
        captured_sets(load("face"), LABELS, fps=30)


def test_captured_takes_fit_match_and_play_out_as_a_live_link_csv(tmp_path):
    """The stage code on two captured labels (test-sized fits, ours), then ``rigmap synth
    run`` writes the shot as a Live Link Face CSV that reads back as the played curves."""
    from rigmap.app.latent import run_step
    from rigmap.cli import compose_config, main
    from rigmap.latent import steps
    from rigmap.latent.live_link import BLENDSHAPES
    from rigmap.store import Layout

    paths = [f"paths.{k}={tmp_path / k}" for k in ("data", "models", "metrics", "reports")]
    tiny = [
        "rig=arkit_face",
        "latent.labels=[smiling,talking]",
        "latent.n_pca=4",
        "latent.latent_dim=2",
        "latent.max_iter=25",
        "latent.log_to_mlflow=false",
        *paths,
    ]
    for step in ("fit", "match"):
        run_step(compose_config([*tiny, f"+latent_step={step}"], ROOT / "conf"))
    layout = Layout.from_paths({k: str(tmp_path / k) for k in ("data", "models", "metrics")})
    fitted = steps.load_fitted(layout, "arkit_face")
    assert fitted.models["smiling"].pca.n_components_ == 4
    assert steps.load_table(layout, "arkit_face").threshold_cm == 0.2  # the rig's own
    shot = tmp_path / "shot.csv"
    script = ROOT / "conf" / "latent" / "scripts" / "smile_after_talking.yaml"
    assert main(["synth", "run", str(script), *tiny, "--out", str(shot)]) == 0
    played, _ = steps.play_script(fitted, steps.load_table(layout, "arkit_face"), script, seed=0)
    take = read_take(shot)
    arkit = load("arkit_face")
    used = [arkit.control_names[i] for i in arkit.controls.used_indices]
    np.testing.assert_allclose(take.curves(live_link_columns(used)), played, atol=1e-6)
    unused = [c for c in BLENDSHAPES if c not in live_link_columns(used)]
    assert unused and np.all(take.curves(unused) == 0.0)
