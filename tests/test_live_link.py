"""Live Link Face CSV import and export (rigmap.latent.live_link) on the four shared takes
(../shared/face/) and on small CSVs written here for the bad inputs."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rigmap.latent import LatentInputError
from rigmap.latent.live_link import (
    BLENDSHAPES,
    HEADER,
    ROTATIONS,
    VALUE_COLUMNS,
    LiveLinkError,
    arkit_name,
    live_link_columns,
    read_take,
    take_text,
    timecode_seconds,
    write_take,
)

ROOT = Path(__file__).resolve().parents[1]
FACE = ROOT.parent / "shared" / "face"
#: what the four takes hold (counted by hand from the files: steps of ~4 timecode frames
#: where the usual step is 2, and the rows with BlendShapeCount 0)
TAKES = {
    "alex_rom_3.csv": {"rows": 4030, "seconds": 134.38, "dropped": 3, "lost": 0},
    "S07-001.csv": {"rows": 2028, "seconds": 67.62, "dropped": 2, "lost": 0},
    "S88-001.csv": {"rows": 1939, "seconds": 64.69, "dropped": 3, "lost": 277},
    "facial.csv": {"rows": 1913, "seconds": 63.76, "dropped": 1, "lost": 0},
}


def shared(name: str) -> Path:
    path = FACE / name
    assert path.is_file(), f"{path} is missing: the Live Link Face takes ship in ../shared/face"
    return path


def row(code: str, values, count: int | None = None) -> str:
    count = len(VALUE_COLUMNS) if count is None else count
    return ",".join([code, str(count), *(str(v) for v in values)])


def small_csv(tmp_path, rows: list[str], header=HEADER, name="take.csv") -> Path:
    path = tmp_path / name
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def codes(n: int, start_frame: int = 0, step: int = 2) -> list[str]:
    """Timecodes at 60 fps stepping ``step`` frames from 10:00:00:start_frame."""
    out = []
    for k in range(n):
        frames = start_frame + k * step
        out.append(f"10:00:{frames // 60:02d}:{frames % 60:02d}.000")
    return out


def ramp_rows(n: int, **kw) -> list[str]:
    return [
        row(code, np.full(len(VALUE_COLUMNS), 0.01 * (k + 1)))
        for k, code in enumerate(codes(n, **kw))
    ]


@pytest.mark.parametrize("name", sorted(TAKES))
def test_shared_takes_report_rate_drops_and_lost_tracking(name):
    take = read_take(shared(name))
    want, report = TAKES[name], take.report()
    assert report["rows"] == want["rows"]
    assert report["duration_s"] == pytest.approx(want["seconds"], abs=0.01)
    assert report["sample_rate_hz"] == pytest.approx(30.0)
    assert 29.9 < report["mean_rate_hz"] < 30.0  # the timecode steps 1.999 frames as often
    assert report["dropped_samples"] == want["dropped"]
    assert report["lost_tracking_rows"] == want["lost"]
    assert report["duplicate_rows"] == 0
    assert take.columns == VALUE_COLUMNS
    assert len(take.times) == want["rows"] - want["lost"]
    assert np.all(np.diff(take.times) > 0)
    shapes = take.curves(BLENDSHAPES)
    assert shapes.min() >= 0.0 and 0.9 < shapes.max() < 1.1  # ARKit weights, about 0 to 1.08
    assert np.abs(take.curves(ROTATIONS[:3])).max() == 0.0  # the head was not recorded


def test_lost_tracking_cuts_the_take_and_short_holes_are_interpolated():
    take = read_take(shared("S88-001.csv"))
    assert take.report()["lost_tracking_runs"] == [[384, 512], [1713, 1835], [1841, 1865]]
    segments = take.segments(30.0)
    # lines 2-383 tracked, then 129 lost rows: the first stretch ends where tracking went
    assert len(segments) == 4
    assert segments[0].start_s == pytest.approx(take.times[0])
    first = segments[0]
    end = take.times[np.searchsorted(take.lines, 383)]
    assert first.start_s + (len(first.values) - 1) / 30.0 <= end + 1e-9
    assert all(len(s.values) >= 2 for s in segments)
    # every resampled frame lies between the take's own values (linear interpolation)
    for s in segments:
        assert s.values.min() >= take.values.min() - 1e-12
        assert s.values.max() <= take.values.max() + 1e-12
    # a dropped sample in a stretch: frames fall in its hole and are interpolated
    assert sum(s.interpolated for s in segments) >= 1


def test_resampling_a_uniform_take_returns_its_samples(tmp_path):
    rng = np.random.default_rng(0)
    curves = rng.uniform(0, 1, (50, len(BLENDSHAPES)))
    path = write_take(tmp_path / "a.csv", curves, BLENDSHAPES, fps=30.0, start_s=3600.0)
    [segment] = read_take(path).segments(30.0)
    assert segment.start_s == pytest.approx(3600.0)
    np.testing.assert_allclose(segment.values[:, : len(BLENDSHAPES)], curves, atol=1e-9)
    [half] = read_take(path).segments(15.0)
    np.testing.assert_allclose(half.values[:, : len(BLENDSHAPES)], curves[::2], atol=1e-9)


@pytest.mark.parametrize("fps", [24.0, 30.0, 60.0])
def test_export_then_import_gives_the_curves_back(tmp_path, fps):
    rng = np.random.default_rng(int(fps))
    names = (*BLENDSHAPES, *ROTATIONS[3:])
    curves = rng.uniform(-0.7, 1.08, (97, len(names)))
    curves[5, 3] = 0.123456789012345  # more digits than a short format keeps
    start = 45296.0 + 43.245 / 60  # 12:34:56:43.245 as in a real take
    path = write_take(tmp_path / "out.csv", curves, names, fps=fps, start_s=start)
    take = read_take(path)
    assert take.report()["dropped_samples"] == 0 and not take.lost_lines
    np.testing.assert_allclose(take.curves(names), curves, rtol=0, atol=1e-6)
    np.testing.assert_allclose(take.times, start + np.arange(97) / fps, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(take.curves(ROTATIONS[:3]), 0.0)  # not given: written 0
    [segment] = take.segments(fps)
    np.testing.assert_allclose(segment.values, take.values, rtol=0, atol=1e-6)
    assert path.read_text().splitlines()[0] == ",".join(HEADER)


def test_an_imported_take_exported_again_reads_back_the_same(tmp_path):
    take = read_take(shared("facial.csv"))
    [segment] = take.segments(30.0)
    path = write_take(
        tmp_path / "again.csv", segment.values, take.columns, fps=30.0, start_s=segment.start_s
    )
    again = read_take(path)
    np.testing.assert_allclose(again.values, segment.values, rtol=0, atol=1e-6)
    assert again.report()["sample_rate_hz"] == pytest.approx(30.0)


def test_timecodes():
    assert timecode_seconds("16:48:39:43.245", 60, "x") == pytest.approx(
        16 * 3600 + 48 * 60 + 39 + 43.245 / 60
    )
    with pytest.raises(LiveLinkError, match=r"x: timecode '10:00:00:61\.000' is out of range"):
        timecode_seconds("10:00:00:61.000", 60, "x")
    with pytest.raises(LiveLinkError, match=r"not HH:MM:SS:FF\.fff"):
        timecode_seconds("10:00:00.5", 60, "x")
    assert arkit_name("JawOpen") == "jawOpen"


def test_duplicates_and_drops_in_a_small_csv(tmp_path):
    rows = ramp_rows(10)
    rows.insert(4, rows[3])  # the same sample twice: line 6 repeats line 5
    del rows[8:10]  # two samples dropped after what is now line 9
    take = read_take(small_csv(tmp_path, rows))
    report = take.report()
    assert report["duplicate_rows"] == 1 and take.duplicate_lines == [6]
    assert report["dropped_samples"] == 2
    assert report["gaps"] == [{"after_line": 9, "seconds": pytest.approx(0.1), "samples": 2}]
    [segment] = take.segments(30.0)
    assert len(segment.values) == 10 and segment.interpolated == 2


def test_all_zero_blendshapes_count_as_lost(tmp_path):
    rows = ramp_rows(6)
    rows[2] = row(codes(6)[2], np.zeros(len(VALUE_COLUMNS)))
    take = read_take(small_csv(tmp_path, rows))
    assert take.lost_lines == [4] and len(take.times) == 5


def test_unknown_column_is_named(tmp_path):
    header = (*HEADER[:10], "JawWobble", *HEADER[11:])
    path = small_csv(tmp_path, ramp_rows(3), header=header)
    with pytest.raises(LiveLinkError, match=r"take.csv, line 1: unknown column 'JawWobble' \(col"):
        read_take(path)


def test_missing_blendshape_column_is_named(tmp_path):
    header = tuple(name for name in HEADER if name != "TongueOut")
    rows = [",".join(r.split(",")[:-10] + r.split(",")[-9:]) for r in ramp_rows(3)]
    with pytest.raises(LiveLinkError, match=r"line 1: no column for the blendshapes \['TongueOut"):
        read_take(small_csv(tmp_path, rows, header=header))


def test_non_numeric_value_names_file_line_and_column(tmp_path):
    rows = ramp_rows(5)
    cells = rows[2].split(",")
    cells[2 + BLENDSHAPES.index("JawOpen")] = "abc"
    rows[2] = ",".join(cells)
    with pytest.raises(LiveLinkError, match=r"take.csv, line 4: JawOpen is 'abc', not a number"):
        read_take(small_csv(tmp_path, rows))


def test_lost_tracking_only_is_an_error(tmp_path):
    rows = [f"{code},0" for code in codes(8)]
    with pytest.raises(LiveLinkError, match=r"take.csv: every row \(8, lines 2-9\) lost tracking"):
        read_take(small_csv(tmp_path, rows))


def test_a_take_shorter_than_needed_is_an_error(tmp_path):
    take = read_take(small_csv(tmp_path, ramp_rows(12)))
    assert len(take.segments(30.0, min_frames=12)[0].values) == 12
    with pytest.raises(LiveLinkError, match=r"take.csv: 12 frames at 30 fps .* fewer than the 24"):
        take.segments(30.0, min_frames=24)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda r: [*r[:2], r[1].replace(",61,", ",x,")], r"line 4: BlendShapeCount is 'x'"),
        (lambda r: [*r[:2], ",".join(r[2].split(",")[:30])], r"line 4: 30 fields, the header has"),
        (lambda r: [r[1], r[0], r[2]], r"line 3: the timecode goes back"),
        (lambda r: [*r[:2], r[2].replace("10:00:00:04", "10:00:04")], "line 4: timecode '10:0"),
        (lambda r: [*r[:2], r[2].replace(",0.03,", ",nan,", 1)], "line 4: .* not a finite"),
    ],
)
def test_bad_rows_are_named_by_line(tmp_path, edit, message):
    with pytest.raises(LiveLinkError, match=message):
        read_take(small_csv(tmp_path, edit(ramp_rows(3))))


def test_bad_files_and_headers(tmp_path):
    with pytest.raises(LiveLinkError, match="no such Live Link Face CSV"):
        read_take(tmp_path / "none.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(LiveLinkError, match=r"empty\.csv: empty file"):
        read_take(tmp_path / "empty.csv")
    with pytest.raises(LiveLinkError, match="starts with Timecode,BlendShapeCount"):
        read_take(small_csv(tmp_path, [], header=("Time", *HEADER[1:])))
    with pytest.raises(LiveLinkError, match="a header and no rows"):
        read_take(small_csv(tmp_path, []))
    (tmp_path / "binary.csv").write_bytes(b"Timecode,\xff\xfe\n")
    with pytest.raises(LiveLinkError, match=r"binary\.csv: not a UTF-8 text file \(byte 9\)"):
        read_take(tmp_path / "binary.csv")
    assert issubclass(LiveLinkError, LatentInputError)


def test_export_refuses_bad_curves_and_leaves_nothing(tmp_path):
    good = np.zeros((4, 2))
    out = tmp_path / "x.csv"
    cases = [
        (dict(curves=good, names=("JawOpen", "Jaw")), "unknown Live Link Face column 'Jaw'"),
        (dict(curves=np.zeros((4, 3)), names=("JawOpen", "TongueOut")), r"expected \(frames"),
        (dict(curves=np.array([[0, np.nan]]), names=("JawOpen", "TongueOut")), "frame 0"),
    ]
    for kwargs, message in cases:
        with pytest.raises(LiveLinkError, match=message):
            write_take(out, fps=30.0, **kwargs)
    with pytest.raises(LiveLinkError, match=r"fps 29\.97 is not a whole number of thousandths"):
        write_take(out, good, ("JawOpen", "TongueOut"), fps=29.97)
    assert list(tmp_path.iterdir()) == []
    assert take_text(good, ("JawOpen", "TongueOut"), fps=24.0).count("\n") == 5


def test_live_link_columns_of_a_rigs_controls():
    assert live_link_columns(["jawOpen", "EyeBlinkLeft", "leftEyeYaw"]) == (
        "JawOpen",
        "EyeBlinkLeft",
        "LeftEyeYaw",
    )
    with pytest.raises(LiveLinkError, match="control 'jaw_open' is not an ARKit blendshape"):
        live_link_columns(["jaw_open"])
    with pytest.raises(LiveLinkError, match="name one Live Link Face column twice"):
        live_link_columns(["jawOpen", "JawOpen"])


def test_synth_run_writes_a_live_link_csv_for_an_arkit_rig(tmp_path, monkeypatch):
    from rigmap.app import synth as cli
    from rigmap.latent import steps

    rig = SimpleNamespace(name="arkit", used_controls=("jawOpen", "mouthSmileLeft"))
    P = np.random.default_rng(3).uniform(0, 1, (48, 2))
    config = {"fps": 24, "blend_frames": 12}
    monkeypatch.setattr(
        cli, "_loaded", lambda args, compose, script=None: (rig, config, None, None)
    )
    monkeypatch.setattr(steps, "play_script", lambda *a, **k: (P, SimpleNamespace(log=[])))
    args = SimpleNamespace(out=tmp_path / "shot.csv", script="x.yaml", seed=0)
    assert cli._run(args, None) == 0
    take = read_take(tmp_path / "shot.csv")
    np.testing.assert_allclose(take.curves(["JawOpen", "MouthSmileLeft"]), P, atol=1e-6)
    assert take.report()["sample_rate_hz"] == pytest.approx(24.0)


def test_synth_run_refuses_a_csv_for_a_rig_without_arkit_controls(tmp_path, monkeypatch):
    from rigmap.app import synth as cli
    from rigmap.latent import steps
    from rigmap.rigs import load

    rig = load("face")
    monkeypatch.setattr(
        cli, "_loaded", lambda args, compose, script=None: (rig, {"fps": 24}, None, None)
    )
    monkeypatch.setattr(steps, "play_script", lambda *a, **k: pytest.fail("played"))
    args = SimpleNamespace(out=tmp_path / "shot.csv", script="x.yaml", seed=0)
    with pytest.raises(LiveLinkError, match="is not an ARKit blendshape"):
        cli._run(args, None)
    assert not (tmp_path / "shot.csv").exists()
