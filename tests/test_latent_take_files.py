"""A user's own takes for latent synthesis (issue #41, item 1): a controls table with a label
column, a label YAML over a table, and every bad input named by file and row or label."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.latent.captured_sets import captured_sets
from rigmap.latent.errors import LatentInputError
from rigmap.latent.take_files import (
    TakeFileError,
    labels_by_pattern,
    read_labelled_takes,
    table_takes,
)
from rigmap.rigs import load

ROOT = Path(__file__).resolve().parents[1]
LABELS = ROOT / "conf" / "latent" / "labels" / "shared_face.yaml"


@pytest.fixture(scope="module")
def arkit():
    return load("arkit_face")


@pytest.fixture(scope="module")
def shared_takes(arkit):
    """The shared Live Link takes as the label YAML cuts them (the reference)."""
    return read_labelled_takes(LABELS, arkit, fps=30)


def as_table(takes, controls) -> pd.DataFrame:
    """Takes one after another: ``take``, ``label``, ``frame`` and a column per control."""
    parts = []
    for take in takes:
        part = pd.DataFrame(take.values, columns=list(controls))
        part.insert(0, "frame", np.arange(len(take.values)))
        part.insert(0, "label", take.label)
        part.insert(0, "take", take.name)
        parts.append(part)
    return pd.concat(parts, ignore_index=True)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_labelled_table_gives_the_takes_it_holds(arkit, shared_takes, tmp_path, suffix):
    table = as_table(shared_takes[:6], arkit.used_controls)
    path = tmp_path / f"takes{suffix}"
    table.to_csv(path, index=False) if suffix == ".csv" else table.to_parquet(path)
    read = read_labelled_takes(path, arkit, fps=30)
    assert [t.label for t in read] == [t.label for t in shared_takes[:6]]
    for mine, theirs in zip(read, shared_takes[:6], strict=True):
        assert mine.name == f"{theirs.label} {theirs.name} 0-{len(theirs.values)}"
        np.testing.assert_allclose(mine.values, theirs.values, atol=1e-12)


def test_the_same_takes_as_a_table_give_the_same_sets(arkit, shared_takes, tmp_path):
    """captured_sets on the table equals captured_sets on the label YAML (same frames)."""
    path = tmp_path / "takes.parquet"
    as_table(shared_takes, arkit.used_controls).to_parquet(path)
    for heldout in (False, True):
        from_yaml = captured_sets(arkit, LABELS, fps=30, heldout=heldout)
        from_table = captured_sets(arkit, path, fps=30, heldout=heldout)
        assert list(from_table) == list(from_yaml)
        for label in from_yaml:
            np.testing.assert_allclose(
                from_table[label].values, from_yaml[label].values, atol=1e-12
            )


def test_a_label_yaml_cuts_a_tables_takes_by_frames_seconds_or_whole(arkit, tmp_path):
    rng = np.random.default_rng(0)
    values = rng.uniform(0, 1, size=(90, len(arkit.used_controls)))
    table = pd.DataFrame(values, columns=arkit.used_controls)
    table.insert(0, "take", ["a"] * 60 + ["b"] * 30)
    table.to_csv(tmp_path / "curves.csv", index=False)
    (tmp_path / "labels.yaml").write_text(
        "takes: curves.csv\nfps: 30\nlabels:\n"
        "  wide: [{take: a, frames: [10, 40]}, {take: b}]\n"
        "  calm: [{take: a, from_s: 1.5, to_s: 2.0}]\n"
    )
    takes = read_labelled_takes(tmp_path / "labels.yaml", arkit, fps=30)
    assert [(t.label, len(t.values)) for t in takes] == [("wide", 30), ("wide", 30), ("calm", 15)]
    np.testing.assert_array_equal(takes[0].values, values[10:40])
    np.testing.assert_array_equal(takes[1].values, values[60:90])
    np.testing.assert_array_equal(takes[2].values, values[45:60])


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("  wide: [{take: a, frames: [10, 70]}]\n", r"label 'wide': segment .* outside take 'a'"),
        ("  wide: [{take: zz}]\n", r"label 'wide': no take 'zz' in curves\.csv"),
        ("  wide: [{take: a, frames: [10, 12]}]\n", r"label 'wide': .* holds 2 frames"),
    ],
)
def test_bad_segments_of_a_table_name_the_label(arkit, tmp_path, body, message):
    table = pd.DataFrame(np.zeros((60, len(arkit.used_controls))), columns=arkit.used_controls)
    table.insert(0, "take", "a")
    table.to_csv(tmp_path / "curves.csv", index=False)
    (tmp_path / "labels.yaml").write_text(f"takes: curves.csv\nfps: 30\nlabels:\n{body}")
    with pytest.raises(TakeFileError, match=message):
        read_labelled_takes(tmp_path / "labels.yaml", arkit, fps=30)


def _write(tmp_path, table, name="t.csv") -> Path:
    path = tmp_path / name
    table.to_csv(path, index=False)
    return path


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.assign(mouthGrin=0.0), r"t\.csv: column 'mouthGrin' is not a used control"),
        (
            lambda t: t.drop(columns=["jawOpen"]),
            r"t\.csv: no column for used controls \['jawOpen'\]",
        ),
        (lambda t: t.drop(columns=["label"]), r"t\.csv: no 'label' column"),
        (lambda t: t.assign(jawOpen=[0.1] * 7 + ["x"] + [0.1] * 2), r"row 8, column 'jawOpen'"),
        (
            lambda t: t.assign(cheekPuff=[0.1] * 4 + [np.nan] + [0.1] * 5),
            r"row 5, column 'cheekPuff'",
        ),
        (lambda t: t.assign(frame=[0, 1, 2, 4, 5, 6, 7, 8, 9, 10]), r"row 4: frame 4 follows 2"),
        (lambda t: t.assign(label=["a"] * 8 + ["b"] * 2), r"take 'b t 8-10' \(rows 9-10\) has 2"),
        (lambda t: t.assign(label=["a"] * 9 + [None]), r"row 10 has no label"),
        (lambda t: t.iloc[:0], r"t\.csv: the table has no rows"),
    ],
)
def test_bad_tables_name_the_file_and_the_row_or_column(arkit, tmp_path, edit, message):
    table = pd.DataFrame(np.full((10, len(arkit.used_controls)), 0.1), columns=arkit.used_controls)
    table.insert(0, "label", "a")
    table.insert(0, "frame", np.arange(10))
    with pytest.raises(TakeFileError, match=message):
        table_takes(_write(tmp_path, edit(table)), arkit.used_controls)


def test_a_table_labelled_twice_or_a_take_split_is_refused(arkit, tmp_path):
    table = pd.DataFrame(np.zeros((9, len(arkit.used_controls))), columns=arkit.used_controls)
    table.insert(0, "label", "a")
    with pytest.raises(TakeFileError, match="a label YAML labels it; keep one"):
        table_takes(_write(tmp_path, table), arkit.used_controls, labelled=False)
    split = table.drop(columns=["label"]).assign(take=["x"] * 3 + ["y"] * 3 + ["x"] * 3)
    with pytest.raises(TakeFileError, match=r"take 'x' is split \(again at row 7\)"):
        table_takes(_write(tmp_path, split), arkit.used_controls, labelled=False)


def test_short_takes_and_small_labels_are_named_with_the_file(arkit, tmp_path):
    """A take too short for the model, and a label with too few frames, both named."""
    rng = np.random.default_rng(1)
    table = pd.DataFrame(rng.uniform(0, 1, (53, len(arkit.used_controls))))
    table.columns = arkit.used_controls
    table.insert(0, "label", ["big"] * 50 + ["tiny"] * 3)
    path = _write(tmp_path, table)
    with pytest.raises(LatentInputError, match=r"t\.csv: take 'tiny t 50-53' .* has 3 frames"):
        captured_sets(arkit, path, fps=30)
    table["label"] = ["big"] * 40 + ["small"] * 13  # 13 frames: 10 train, 3 held out
    path = _write(tmp_path, table)
    with pytest.raises(LatentInputError, match=r"t\.csv \(training frames\).*: 'small' has 10$"):
        captured_sets(arkit, path, fps=30)


def test_labels_from_action_names():
    names = ["happy_01", "happy.002", "Grumpy3", "walk"]
    path = Path("rig.blend")
    assert labels_by_pattern(names, r"^[A-Za-z]+", path) == {
        "happy_01": "happy",
        "happy.002": "happy",
        "Grumpy3": "Grumpy",
        "walk": "walk",
    }
    named = labels_by_pattern(["take_sad_1"], r"take_(?P<label>[a-z]+)_\d", path)
    assert named == {"take_sad_1": "sad"}
    with pytest.raises(TakeFileError, match=r"rig\.blend: action '1x' does not match"):
        labels_by_pattern(["1x"], r"^[A-Za-z]+", path)
    with pytest.raises(TakeFileError, match="is not a regex"):
        labels_by_pattern(["a"], r"(", path)


def test_unknown_kinds_of_file_and_patterns_on_tables_are_refused(arkit, tmp_path):
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(TakeFileError, match="takes must be a label YAML"):
        read_labelled_takes(tmp_path / "x.txt", arkit, fps=30)
    with pytest.raises(TakeFileError, match="no such takes file"):
        read_labelled_takes(tmp_path / "none.csv", arkit, fps=30)
    (tmp_path / "t.csv").write_text("label\n")
    with pytest.raises(TakeFileError, match=r"label_pattern labels a \.blend"):
        read_labelled_takes(tmp_path / "t.csv", arkit, fps=30, label_pattern="x")
    with pytest.raises(TakeFileError, match="rig=blend_file"):
        from rigmap.latent.take_files import blend_takes

        blend_takes(tmp_path / "a.blend", arkit, fps=24)
