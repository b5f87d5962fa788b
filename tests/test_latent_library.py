"""The face's labelled expression library and the labelled sets built from it."""

from __future__ import annotations

import numpy as np
import pytest

from latent_face import face_rig
from rigmap.animation.library import face_expressions as fx
from rigmap.latent import LatentInputError
from rigmap.latent.library import Take, face_expression_sets, labelled_sets, labels_of_clips


@pytest.fixture(scope="module")
def quick():
    return face_expression_sets(face_rig(), size="quick")


def test_every_label_has_several_takes_of_about_150_frames(quick):
    assert list(quick) == list(fx.LABELS)
    for label, entry in quick.items():
        assert len(entry.names) == 3
        assert 100 <= entry.n_frames <= 220, (label, entry.n_frames)
        assert entry.values.shape == (entry.n_frames, len(face_rig().used_controls))
        assert len(entry.segments) == entry.n_frames


def test_takes_are_24_fps_seeded_and_differ():
    a = fx.build_take("roar", 0, seed=0)
    again = fx.build_take("roar", 0, seed=0)
    other = fx.build_take("roar", 1, seed=0)
    rig = face_rig()
    assert a.clip.fps == 24
    np.testing.assert_array_equal(fx.take_values(a, rig), fx.take_values(again, rig))
    va, vo = fx.take_values(a, rig), fx.take_values(other, rig)
    n = min(len(va), len(vo))
    assert np.abs(va[:n] - vo[:n]).max() > 0.05


def test_held_out_takes_are_new_draws(quick):
    held = face_expression_sets(face_rig(), heldout=True)
    for label in fx.LABELS:
        assert len(held[label].names) == 1
        h = held[label].takes[0]
        for train in quick[label].takes:
            n = min(len(h), len(train))
            assert np.abs(h[:n] - train[:n]).max() > 1e-3


def test_expressions_differ_between_labels(quick):
    """The roar opens the jaw far more than a neutral face; happy smiles more than grumpy."""
    names = face_rig().used_controls
    jaw = names.index("jaw.rx")
    smile = names.index("mouth_smile_l")
    assert quick["roar"].values[:, jaw].max() > 2 * quick["neutral"].values[:, jaw].max()
    assert quick["happy"].values[:, smile].mean() > quick["grumpy"].values[:, smile].mean() + 0.2


def test_an_unlabelled_clip_is_an_error_naming_it():
    values = np.zeros((30, 4))
    with pytest.raises(LatentInputError, match="'take b' has no label"):
        labelled_sets([Take("happy", "take a", values), Take(None, "take b", values)], n_controls=4)
    with pytest.raises(LatentInputError, match="'blink'"):
        labels_of_clips(["smile", "blink"], {"smile": "happy"})


def test_a_label_with_too_few_frames_is_an_error():
    with pytest.raises(LatentInputError, match="'bored' has 10"):
        labelled_sets(
            [Take("happy", "a", np.zeros((30, 2))), Take("bored", "b", np.zeros((10, 2)))],
            n_controls=2,
        )


def test_bad_take_values_are_errors_naming_the_take():
    with pytest.raises(LatentInputError, match=r"'a'.*expected"):
        labelled_sets([Take("happy", "a", np.zeros((30, 3)))], n_controls=2)
    bad = np.zeros((30, 2))
    bad[7, 1] = np.nan
    with pytest.raises(LatentInputError, match=r"'a'.*frame 7"):
        labelled_sets([Take("happy", "a", bad)], n_controls=2)
    with pytest.raises(KeyError, match="sleepy"):
        fx.build_take("sleepy", 0, seed=0)


def _sided(rig):
    names = list(rig.used_controls)
    left = [i for i, n in enumerate(names) if n.endswith("_l") and n[:-2] + "_r" in names]
    return left, [names.index(names[i][:-2] + "_r") for i in left]


def test_coordinated_takes_vary_only_in_their_few_factors():
    rig = face_rig()
    left, right = _sided(rig)

    def roar(k):
        return face_expression_sets(rig, labels=["roar"], coordinated=k)["roar"].takes

    def peaks_differ(takes):
        peaks = np.array([t.max(0) for t in takes])
        return float(np.abs(peaks - peaks[0]).max())

    def lean(takes):
        return max(float(np.abs(t[:, left] - t[:, right]).max()) for t in takes)

    # no factor: every take reaches the same key poses (timing alone differs)
    assert peaks_differ(roar(0)) < 1e-9 and lean(roar(0)) == 0.0
    # intensity: the poses' strengths differ, the face stays symmetric
    assert peaks_differ(roar(1)) > 0.05 and lean(roar(1)) == 0.0
    # intensity and asymmetry: one side leads
    assert lean(roar(2)) > 0.05
    # the library's takes: every pose draws its own values
    assert peaks_differ(roar(None)) > 0.05 and lean(roar(None)) > 0.05
    with pytest.raises(ValueError, match="0-3 factors"):
        fx.build_take("roar", 0, seed=0, coordinated=4)
