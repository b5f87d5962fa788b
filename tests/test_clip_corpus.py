"""Clips played on whole frames, the corpus table, its parquet file, and validation."""

import hashlib
import json
import os
import warnings

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from rigmap.animation import (
    Clip,
    Corpus,
    CorpusError,
    FCurve,
    Key,
    KeyframeError,
    SoftRangeWarning,
    read_corpus,
)

CONTROLS = ["root.tx", "root.ty", "spine.rz", "neck.rz", "tail.curl"]
DEFAULTS = np.array([0.0, 50.0, 0.0, 0.1, 0.0])  # cm, cm, rad, rad, factor
LOWER = np.array([-200.0, 0.0, -1.0, -1.0, 0.0])
UPPER = np.array([200.0, 100.0, 1.0, 1.0, 1.0])


def walk_clip(fps=24):
    """Two seconds at 24 fps: the root moves forward and bobs, the spine sways."""
    return Clip(
        "walk",
        fps,
        {
            "root.tx": [(0, 0.0), (48, 120.0)],
            "root.ty": [(0, 50.0), (12, 47.0), (24, 50.0), (36, 47.0), (48, 50.0)],
            "spine.rz": [Key(0, -0.2), Key(24, 0.2), Key(48, -0.2)],
        },
    )


def sit_clip():
    return Clip(
        "sit",
        24,
        {
            "root.ty": [(0, 50.0), (20, 30.0)],
            "tail.curl": [Key(0, 0.0, "constant"), Key(10, 0.6, "linear"), Key(20, 0.2)],
        },
        end=30,
    )


def build(clips=None, seed=7, **kwargs):
    return Corpus.from_clips(
        [walk_clip(), sit_clip()] if clips is None else clips,
        CONTROLS,
        DEFAULTS,
        rig="toy",
        split="train",
        seed=seed,
        lower=LOWER,
        upper=UPPER,
        **kwargs,
    )


# --- clips --------------------------------------------------------------------------
def test_clip_frame_counts_at_24_and_30_fps():
    at24 = walk_clip()
    assert (at24.start, at24.end, at24.n_frames) == (0, 48, 49)
    assert at24.duration_s == pytest.approx(2.0)
    at30 = at24.retimed(30)
    assert (at30.start, at30.end, at30.n_frames) == (0, 60, 61)
    assert at30.duration_s == pytest.approx(2.0)
    a = at24.evaluate(CONTROLS, DEFAULTS)
    b = at30.evaluate(CONTROLS, DEFAULTS)
    assert a.shape == (49, 5) and b.shape == (61, 5)
    # same instant, different frame numbers: 0.5 s is frame 12 at 24 fps and 15 at 30 fps
    for seconds in (0.5, 1.0, 1.5):
        np.testing.assert_allclose(a[round(seconds * 24)], b[round(seconds * 30)], atol=1e-12)
    assert a[12, 1] == pytest.approx(47.0)  # the bob's low key


def test_clip_evaluate_orders_columns_and_fills_defaults():
    clip = sit_clip()
    table = clip.evaluate(CONTROLS, DEFAULTS)
    assert table.shape == (31, 5)
    np.testing.assert_array_equal(table[:, 0], 0.0)  # root.tx default
    np.testing.assert_array_equal(table[:, 3], 0.1)  # neck.rz default
    # stepped then linear tail: 0 until frame 10, then 0.6 -> 0.2 over 10 frames, then held
    assert table[9, 4] == 0.0
    assert table[15, 4] == pytest.approx(0.4)
    assert table[25, 4] == pytest.approx(0.2)
    # the keys hold after the last key up to the clip's end (frame 30)
    assert table[30, 1] == pytest.approx(30.0)
    reordered = clip.evaluate(CONTROLS[::-1], DEFAULTS[::-1])
    np.testing.assert_array_equal(reordered, table[:, ::-1])


def test_clip_evaluate_at_chosen_frames():
    clip = walk_clip()
    table = clip.evaluate(CONTROLS, DEFAULTS, frames=[6.0, 24.0])
    assert table[1, 2] == pytest.approx(0.2)
    assert table[0, 0] == pytest.approx(clip.curves["root.tx"].evaluate(6.0))


def test_key_counts():
    clip = walk_clip()
    assert clip.key_count == 2 + 5 + 3
    np.testing.assert_array_equal(clip.keyed_frames, [0, 12, 24, 36, 48])


def test_clip_range_covers_fractional_keys():
    clip = Clip("pose", 30, {"a": [(2.5, 0.0), (10.2, 1.0)]})
    assert (clip.start, clip.end) == (2, 11)


@pytest.mark.parametrize(
    ("curves", "control", "message"),
    [
        ({"spine.rz": [(0, 0.0), (10, float("nan"))]}, "spine.rz", "value nan"),
        ({"spine.rz": [(0, 0.0), (10, 1.0), (10, 2.0)]}, "spine.rz", "two keys at frame 10"),
        ({"neck.rz": []}, "neck.rz", "at least one key"),
        ({"neck.rz": [(0, 1.0, 2.0)]}, "neck.rz", "(frame, value) pair"),
        ({"neck.rz": FCurve([Key(0, 1.0)], control="spine.rz")}, "neck.rz", "labelled"),
    ],
)
def test_bad_keys_in_a_clip_name_clip_and_control(curves, control, message):
    with pytest.raises(KeyframeError) as caught:
        Clip("jump", 24, curves)
    text = str(caught.value)
    assert f"clip 'jump', control '{control}'" in text
    assert message in text
    assert (caught.value.clip, caught.value.control) == ("jump", control)


def test_empty_clip_is_an_error_naming_it():
    with pytest.raises(KeyframeError, match="clip 'idle': the clip has no curves"):
        Clip("idle", 24, {})


def test_frame_rate_must_be_24_or_30():
    with pytest.raises(KeyframeError, match=r"clip 'walk': fps must be one of \(24, 30\), got 25"):
        Clip("walk", 25, {"a": [(0, 0.0)]})


def test_unknown_control_names_the_clip_control_and_close_matches():
    clip = Clip("walk", 24, {"spine.rzz": [(0, 0.0), (10, 1.0)]})
    with pytest.raises(KeyframeError) as caught:
        clip.evaluate(CONTROLS, DEFAULTS)
    text = str(caught.value)
    assert "clip 'walk', control 'spine.rzz'" in text
    assert "did you mean ['spine.rz'" in text


# --- the corpus table -----------------------------------------------------------------
def test_corpus_table_has_every_frame_of_every_clip():
    corpus = build()
    table = corpus.table
    assert list(table.columns) == ["clip", "frame", *CONTROLS]
    assert len(table) == 49 + 31
    assert table["clip"].tolist() == ["walk"] * 49 + ["sit"] * 31
    assert table["frame"].tolist() == list(range(49)) + list(range(31))
    np.testing.assert_array_equal(
        corpus.clip_table("walk")[CONTROLS].to_numpy(), walk_clip().evaluate(CONTROLS, DEFAULTS)
    )
    assert corpus.values().shape == (80, 5)
    assert corpus.metadata["key_count"] == 10 + 5
    assert corpus.metadata["keyed_frame_count"] == 5 + 3
    assert corpus.metadata["clips"][1] == {
        "name": "sit",
        "start": 0,
        "end": 30,
        "frames": 31,
        "key_count": 5,
        "keyed_frames": 3,
        "curves": 2,
        "description": "",
    }


def test_corpus_validation_errors():
    with pytest.raises(CorpusError, match="the corpus is empty"):
        build(clips=[])
    with pytest.raises(CorpusError, match=r"repeated: \['walk'\]"):
        build(clips=[walk_clip(), walk_clip()])
    with pytest.raises(KeyframeError, match="clip 'walk': 30 fps, but clip 'sit' is 24 fps"):
        build(clips=[sit_clip(), walk_clip(30)])
    odd = Clip("wag", 24, {"tail.curll": [(0, 0.0), (6, 1.0)]})
    with pytest.raises(KeyframeError, match=r"clip 'wag', control 'tail.curll'.*\['tail.curl'\]"):
        build(clips=[walk_clip(), odd])


def test_keys_outside_soft_range_warn_with_clip_control_value_and_range():
    wild = Clip("begging", 24, {"spine.rz": [(0, 0.0), (5, 1.4), (9, -1.2), (12, 0.5)]})
    with pytest.warns(SoftRangeWarning) as caught:
        corpus = build(clips=[walk_clip(), wild])
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "clip 'begging', control 'spine.rz'" in message
    assert "2 key(s) outside the soft range [-1, 1]" in message
    assert "worst value 1.4 at frame 5" in message
    assert len(corpus.table) == 49 + 13  # a warning, not an error


def test_keys_inside_soft_range_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build()


# --- files ----------------------------------------------------------------------------
def test_parquet_round_trip_preserves_values_and_metadata(tmp_path):
    corpus = build(extra={"library": "toy motions", "clips_per_split": 2})
    path = corpus.write(tmp_path / "toy" / "corpus" / "train.parquet")
    back = Corpus.read(path, rig="toy", control_names=CONTROLS, split="train")
    pd.testing.assert_frame_equal(back.table, corpus.table, check_exact=True)
    assert back.metadata == corpus.metadata
    assert (back.rig, back.fps, back.split, back.metadata["seed"]) == ("toy", 24, "train", 7)
    assert back.clip_names == ["walk", "sit"]
    assert back.metadata["extra"]["library"] == "toy motions"
    assert sorted(os.listdir(path.parent)) == ["train.parquet"]  # no temp file left behind


def test_parquet_is_byte_identical_for_identical_input(tmp_path):
    first = build().write(tmp_path / "a" / "train.parquet")
    second = build().write(tmp_path / "b" / "train.parquet")
    other_seed = build(seed=8).write(tmp_path / "c" / "train.parquet")
    digest = [hashlib.sha256(p.read_bytes()).hexdigest() for p in (first, second, other_seed)]
    assert digest[0] == digest[1]
    assert digest[0] != digest[2]  # the seed is in the metadata, so it changes the bytes


def test_failed_write_leaves_the_old_file_and_no_temp(tmp_path):
    path = build().write(tmp_path / "train.parquet")
    before = path.read_bytes()
    broken = build(extra={"not json": object()})
    with pytest.raises(CorpusError, match="not plain JSON"):
        broken.write(path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["train.parquet"]


def test_reading_checks_rig_controls_and_format(tmp_path):
    path = build().write(tmp_path / "train.parquet")
    with pytest.raises(CorpusError, match="corpus is for rig 'toy', expected 'biped'"):
        Corpus.read(path, rig="biped")
    with pytest.raises(CorpusError, match=r"missing \['ear.rz'\], unexpected \['tail.curl'\]"):
        Corpus.read(path, control_names=[*CONTROLS[:-1], "ear.rz"])
    plain = tmp_path / "plain.parquet"
    pq.write_table(pa.table({"clip": ["a"], "frame": [0]}), plain)
    with pytest.raises(CorpusError, match="not a rigmap corpus"):
        read_corpus(plain)
    with pytest.raises(FileNotFoundError, match=r"missing\.parquet"):
        read_corpus(tmp_path / "missing.parquet")
    garbage = tmp_path / "garbage.parquet"
    garbage.write_bytes(b"not parquet at all")
    with pytest.raises(CorpusError, match="not a readable parquet file"):
        read_corpus(garbage)


def _write_raw(path, table, metadata):
    """Bypass write_corpus's checks, as a buggy or foreign writer would."""
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    arrow = arrow.replace_schema_metadata({b"rigmap": json.dumps(metadata).encode()})
    pq.write_table(arrow, path)


def test_reading_rejects_non_finite_values_naming_clip_and_control(tmp_path):
    corpus = build()
    table = corpus.table.copy()
    table.loc[60, "neck.rz"] = np.nan  # row 60 is frame 11 of 'sit'
    path = tmp_path / "bad.parquet"
    _write_raw(path, table, corpus.metadata)
    with pytest.raises(CorpusError, match=r"clip 'sit', control 'neck\.rz': value nan at frame 11"):
        read_corpus(path)


def test_reading_rejects_rows_that_disagree_with_the_metadata(tmp_path):
    corpus = build()
    path = tmp_path / "short.parquet"
    _write_raw(path, corpus.table.iloc[:-3], corpus.metadata)  # 'sit' lost its last frames
    with pytest.raises(CorpusError, match=r"clip 'sit': expected frames 0\.\.30 \(31 rows\)"):
        read_corpus(path)
    empty = tmp_path / "empty.parquet"
    _write_raw(empty, corpus.table.iloc[:0], corpus.metadata)
    with pytest.raises(CorpusError, match="the corpus is empty"):
        read_corpus(empty)
