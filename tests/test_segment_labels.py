"""Label YAMLs over Live Link Face takes (rigmap.latent.segment_labels): the committed
heuristic labelling of ../shared/face/ and small files with each mistake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.latent import LatentInputError
from rigmap.latent.library import labelled_sets
from rigmap.latent.live_link import BLENDSHAPES, VALUE_COLUMNS, write_take
from rigmap.latent.segment_labels import LabelFileError, labelled_takes, read_labels

ROOT = Path(__file__).resolve().parents[1]
SHARED_LABELS = ROOT / "conf" / "latent" / "labels" / "shared_face.yaml"
FACE = ROOT.parent / "shared" / "face"


def test_the_shared_takes_labelling_gives_every_label_enough_frames():
    assert (FACE / "S88-001.csv").is_file(), f"{FACE} is missing: the takes ship in ../shared"
    labels = read_labels(SHARED_LABELS)
    assert labels.labels == ["range_of_motion", "smiling", "talking", "frowning", "blinking"]
    takes = labelled_takes(labels, names=BLENDSHAPES)
    sets = labelled_sets(takes, n_controls=len(BLENDSHAPES))
    assert set(sets) == set(labels.labels)
    assert sets["range_of_motion"].n_frames == 600  # 20 s at 30 fps
    for entry in sets.values():
        assert entry.n_frames >= 24
    # the heuristic's own signals hold in the segments it labelled
    smile = [BLENDSHAPES.index("MouthSmileLeft"), BLENDSHAPES.index("MouthSmileRight")]
    frown = [BLENDSHAPES.index("BrowDownLeft"), BLENDSHAPES.index("BrowDownRight")]
    assert sets["smiling"].values[:, smile].mean() > 3 * sets["talking"].values[:, smile].mean()
    assert sets["frowning"].values[:, frown].mean() > 3 * sets["smiling"].values[:, frown].mean()


@pytest.fixture
def folder(tmp_path) -> Path:
    """A 4 s take at 30 fps (``a``) whose tracking is lost from 1 s to 2 s."""
    curves = np.tile(np.linspace(0, 1, 120)[:, None], (1, len(VALUE_COLUMNS)))
    write_take(tmp_path / "a.csv", curves, VALUE_COLUMNS, fps=30.0)
    lines = (tmp_path / "a.csv").read_text().splitlines()
    for k in range(31, 61):  # data rows 30-59 (file lines 32-61): tracking lost
        lines[k] = lines[k].split(",")[0] + ",0"
    (tmp_path / "a.csv").write_text("\n".join(lines) + "\n")
    return tmp_path


def labels_file(folder: Path, body: str) -> Path:
    path = folder / "labels.yaml"
    path.write_text(f"takes: .\nfps: 30\nlabels:\n{body}")
    return path


def test_segments_in_frames_and_seconds_and_lost_tracking_splits(folder):
    body = (
        "  x:\n    - {take: a, from_s: 0.5, to_s: 3.0}\n  y:\n    - {take: a, frames: [60, 90]}\n"
    )
    takes = labelled_takes(read_labels(labels_file(folder, body)))
    assert [t.name for t in takes] == ["x a 0.50-3.00/0", "x a 0.50-3.00/1", "y a 2.00-3.00"]
    assert [len(t.values) for t in takes] == [15, 30, 30]  # 0.5-1 s, 2-3 s; 2-3 s
    np.testing.assert_allclose(takes[2].values[:, 0], np.linspace(0, 1, 120)[60:90], atol=1e-9)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "  x:\n    - {take: a, from_s: 3.0, to_s: 4.5}\n",
            r"label 'x': segment 3-4\.5 s is outside take 'a' \(3\.97 s",
        ),
        (
            "  x:\n    - {take: a, from_s: 1.1, to_s: 1.9}\n",
            "label 'x': segment .* holds no tracked",
        ),
        ("  x:\n    - {take: b, from_s: 0, to_s: 1}\n", r"label 'x': no take 'b'"),
        ("  x:\n    - {take: ../a, from_s: 0, to_s: 1}\n", "is not a file stem"),
        (
            "  x:\n    - {take: a, from_s: 2, to_s: 1}\n",
            "label 'x', segment 1: the segment 2-1 s is empty",
        ),
        ("  x:\n    - {take: a, from_s: 0}\n", "from_s and to_s must both be seconds"),
        ("  x:\n    - {take: a, frames: [0, 1.5]}\n", r"frames must be \[first, end\]"),
        ("  x:\n    - {take: a, start: 0, to_s: 1}\n", r"unknown keys \['start'\]"),
        ("  x: []\n", "label 'x' needs a list of segments"),
    ],
)
def test_bad_segments_name_the_label(folder, body, message):
    with pytest.raises(LabelFileError, match=message):
        labelled_takes(read_labels(labels_file(folder, body)))


def test_bad_files(folder):
    with pytest.raises(LabelFileError, match="no such label file"):
        read_labels(folder / "none.yaml")
    (folder / "bad.yaml").write_text("labels: [\n")
    with pytest.raises(LabelFileError, match=r"bad\.yaml: not YAML"):
        read_labels(folder / "bad.yaml")
    (folder / "bad.yaml").write_text("fps: 0\nlabels: {x: [{take: a, from_s: 0, to_s: 1}]}\n")
    with pytest.raises(LabelFileError, match="fps must be a number"):
        read_labels(folder / "bad.yaml")
    (folder / "bad.yaml").write_text("label: {}\n")
    with pytest.raises(LabelFileError, match="expected a mapping with `labels"):
        read_labels(folder / "bad.yaml")


def test_a_label_with_too_few_frames_is_named(folder):
    body = (
        "  x:\n    - {take: a, from_s: 0.0, to_s: 1.0}\n  y:\n    - {take: a, frames: [62, 70]}\n"
    )
    takes = labelled_takes(read_labels(labels_file(folder, body)))
    with pytest.raises(LatentInputError, match="fewer than 24 frames: 'y' has 8"):
        labelled_sets(takes, n_controls=len(VALUE_COLUMNS))
