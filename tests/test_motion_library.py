"""The animator motion library: counts per rig (Table 3), seeded variation, foot plants."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

from rigmap.animation import KeyframeError, SoftRangeWarning
from rigmap.animation.library import (
    ClipBuilder,
    Variation,
    build_clip,
    build_clips,
    build_corpus,
    clip_rng,
    libraries,
    motion_library,
)
from rigmap.rigs import load
from rigmap.viz.contact_sheet import play_clip

# Table 3 of the paper: training frames per character (>=); keyed frames "about 200"
MIN_TRAIN_FRAMES = {
    "quadruped": 750,
    "biped": 750,
    "face": 300,
    "squirrel": 500,
    "rigify_wolf": 750,  # the dog's motions on Rigify's wolf
    "rigify_human": 750,  # the biped's motions on Rigify's human
}
ABOUT_200_KEYFRAMES = {"quadruped", "biped"}
DOG_TEST_CLIPS = {"Jumping & Playing", "Turning & Galloping", "Begging Excitedly"}
PAPER_TEST_CLIPS = {
    "quadruped": DOG_TEST_CLIPS,
    "biped": {"Range of Motion", "Swing Dance", "Tai Chi"},
    "rigify_wolf": DOG_TEST_CLIPS,
    "rigify_human": {"Range of Motion", "Swing Dance", "Tai Chi"},
}
# Blender rigs need the worker environment even to list their controls
BLENDER_MARKS = [
    pytest.mark.blender,
]
RIGS = [
    pytest.param(name, marks=BLENDER_MARKS) if name.startswith("rigify_") else name
    for name in libraries()
]
_CORPORA: dict = {}


def corpus(rig_name: str, split: str, seed: int = 0):
    """Corpora are built once per test session (they are plain keyframe evaluation)."""
    key = (rig_name, split, seed)
    if key not in _CORPORA:
        with warnings.catch_warnings():
            warnings.simplefilter("error", SoftRangeWarning)
            _CORPORA[key] = build_corpus(load(rig_name), split, seed=seed)
    return _CORPORA[key]


@pytest.mark.parametrize("rig_name", RIGS)
def test_counts_match_table_3_and_every_used_control_moves(rig_name, record_property):
    train, test = corpus(rig_name, "train"), corpus(rig_name, "test")
    meta = train.metadata
    values = train.values()
    constant = [c for c, s in zip(train.controls, values.std(axis=0), strict=True) if s < 1e-9]
    summary = {
        "clips": len(meta["clips"]),
        "keyed_frames": meta["keyed_frame_count"],
        "train_frames": meta["frame_count"],
        "test_clips": len(test.metadata["clips"]),
        "test_frames": test.metadata["frame_count"],
        "constant_used_controls": len(constant),
    }
    print(f"\n{rig_name}: {summary}")
    record_property(f"{rig_name}_counts", summary)
    assert meta["frame_count"] >= MIN_TRAIN_FRAMES[rig_name]
    if rig_name in ABOUT_200_KEYFRAMES:
        assert 170 <= meta["keyed_frame_count"] <= 230
    assert train.controls == load(rig_name).used_controls
    assert constant == [], f"used controls that never move in training: {constant}"
    assert test.metadata["frame_count"] >= 60
    if rig_name in PAPER_TEST_CLIPS:
        assert set(test.clip_names) == PAPER_TEST_CLIPS[rig_name]
    assert not set(test.clip_names) & set(train.clip_names)


@pytest.mark.parametrize("rig_name", RIGS)
def test_keys_stay_inside_soft_ranges_for_several_seeds(rig_name):
    rig = load(rig_name)
    for seed in (1, 2):
        with warnings.catch_warnings():
            warnings.simplefilter("error", SoftRangeWarning)
            for split in ("train", "test"):
                build_corpus(rig, split, seed=seed)


def test_same_seed_same_bytes_other_seed_other_clips(tmp_path):
    rig = load("quadruped")
    paths = []
    for name, seed in (("a", 0), ("b", 0), ("c", 5)):
        paths.append(build_corpus(rig, "train", seed=seed).write(tmp_path / f"{name}.parquet"))
    a, b, c = (p.read_bytes() for p in paths)
    assert a == b
    assert a != c
    first, other = corpus("quadruped", "train", 0), build_corpus(rig, "train", seed=5)
    frames_0 = [clip["frames"] for clip in first.metadata["clips"]]
    frames_5 = [clip["frames"] for clip in other.metadata["clips"]]
    assert frames_0 != frames_5, "another seed should change the timing of some clips"
    walk_0 = first.clip_table("Walk")["front_leg_l_ik.ty"].max()
    walk_5 = other.clip_table("Walk")["front_leg_l_ik.ty"].max()
    assert walk_0 != pytest.approx(walk_5), "another seed should change key values (step height)"


def test_each_clip_draws_from_its_own_generator():
    """Adding or reordering clips never changes the others: the seed is (seed, rig, clip)."""
    a = clip_rng(3, "quadruped", "Walk").uniform(size=4)
    b = clip_rng(3, "quadruped", "Walk").uniform(size=4)
    c = clip_rng(3, "quadruped", "Trot").uniform(size=4)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    with pytest.raises(ValueError, match="non-negative integer"):
        clip_rng(-1, "quadruped", "Walk")


def test_no_variation_gives_the_nominal_timing():
    library = motion_library("quadruped")
    _, motion = library.find("Walk")
    nominal = build_clip("quadruped", motion, seed=0, variation=Variation().scaled(0.0))
    again = build_clip("quadruped", motion, seed=9, variation=Variation().scaled(0.0))
    np.testing.assert_array_equal(nominal.keyed_frames, again.keyed_frames)
    varied = build_clip("quadruped", motion, seed=9)
    assert not np.array_equal(nominal.keyed_frames, varied.keyed_frames)


def test_clips_at_30_fps_keep_their_duration():
    at24 = build_clips("face", "train", seed=0)
    at30 = build_clips("face", "train", seed=0, fps=30)
    for a, b in zip(at24, at30, strict=True):
        assert b.fps == 30
        assert b.duration_s == pytest.approx(a.duration_s, abs=1 / 24)


# --- the builder ------------------------------------------------------------------------------
def test_time_warp_keeps_order_and_holds():
    rng = np.random.default_rng(0)
    b = ClipBuilder("probe", rng, variation=Variation(tempo=0.3, timing=0.6))
    for f in range(0, 40, 2):
        b.key("a", f, float(f))
    b.hold("b", 4, 20, 7.0)
    b.key("b", 30, 1.0)
    warp = b.time_warp()
    played = [warp[f] for f in sorted(warp)]
    assert all(later > earlier for earlier, later in itertools.pairwise(played))
    clip = b.build()
    values = clip.evaluate(["a", "b"], [0.0, 0.0])
    held = slice(warp[4.0] - clip.start, warp[20.0] - clip.start + 1)
    np.testing.assert_array_equal(values[held, 1], 7.0)
    assert len(clip.keyed_frames) == len(warp)


def test_builder_refuses_conflicting_and_bad_keys():
    b = ClipBuilder("probe", np.random.default_rng(0))
    b.key("cog.ty", 10, 1.0)
    b.key("cog.ty", 10, 1.0, "linear")  # same value again: only the interpolation changes
    with pytest.raises(KeyframeError, match=r"clip 'probe', control 'cog.ty'.*keyed twice"):
        b.key("cog.ty", 10, 2.0)
    with pytest.raises(KeyframeError, match=r"control 'cog\.tx'.*finite"):
        b.key("cog.tx", 3, float("nan"))
    with pytest.raises(KeyframeError, match="interpolation 'cubic'"):
        b.key("cog.tx", 3, 0.0, "cubic")  # type: ignore[arg-type]
    with pytest.raises(KeyframeError, match="end > start"):
        b.hold("cog.tz", 5, 5, 0.0)
    with pytest.raises(KeyframeError, match="no keys"):
        ClipBuilder("empty", np.random.default_rng(0)).build()


def test_unknown_rig_and_clip_names_are_clear_errors():
    with pytest.raises(KeyError, match="no motion library for rig 'dragon'"):
        motion_library("dragon")
    with pytest.raises(KeyError, match="no clip named 'Moonwalk'"):
        motion_library("biped").find("Moonwalk")
    with pytest.raises(ValueError, match="split must be one of"):
        motion_library("biped").motions("validation")


# --- foot plants --------------------------------------------------------------------------------
def _stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index ranges where ``mask`` holds, end exclusive."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2], strict=True))


def test_walk_plants_each_paw_while_another_swings():
    """IK paw controls hold still over stretches (planted) while others move; in the world
    the planted toe stays within 0.05 cm, and the body travels forward meanwhile."""
    rig = load("quadruped")
    walk = corpus("quadruped", "train").clip_table("Walk")
    legs = ["front_leg_l", "front_leg_r", "hind_leg_l", "hind_leg_r"]
    translate = {leg: walk[[f"{leg}_ik.t{a}" for a in "xyz"]].to_numpy() for leg in legs}
    moving = {
        leg: np.linalg.norm(np.diff(t, axis=0), axis=1) > 1e-9 for leg, t in translate.items()
    }
    played = play_clip(
        rig, build_clip("quadruped", motion_library("quadruped").find("Walk")[1], seed=0)
    )
    for leg in legs:
        planted = _stretches(~moving[leg])
        long_plants = [(s, e) for s, e in planted if e - s >= 5]
        assert len(long_plants) >= 2, f"{leg}: plants {planted}"
        swings = _stretches(moving[leg])
        assert len(swings) >= 2, f"{leg}: the paw never swings"
        # during a swing of this paw, some other paw is planted
        for s, e in swings:
            others = [o for o in legs if o != leg and not moving[o][s:e].any()]
            assert others, f"{leg} swings over frames {s}..{e} with no other paw planted"
        toe = rig.joint_names.index(f"{leg.split('_')[0]}_toe_{leg[-1]}")
        for s, e in long_plants:
            path = played.world[s : e + 1, toe]
            assert np.ptp(path, axis=0).max() < 0.05, f"{leg} toe slides while planted"
    travel = walk["cog.tz"].iloc[-1] - walk["cog.tz"].iloc[0]
    assert travel > 30.0  # cm: the dog walks, not marches in place


def test_trot_paws_stay_put_in_the_world_while_the_root_travels():
    rig = load("quadruped")
    motion = motion_library("quadruped").find("Trot")[1]
    played = play_clip(rig, build_clip("quadruped", motion, seed=0))
    root = played.controls[:, rig.controls.index("root.tz")]
    assert root[-1] - root[0] > 150.0  # cm travelled
    toe = rig.joint_names.index("front_toe_l")
    on_ground = played.world[:, toe, 1] < 1.0
    plants = [(s, e) for s, e in _stretches(on_ground) if e - s >= 6]
    assert len(plants) >= 3
    for s, e in plants:
        horizontal = played.world[s + 1 : e - 1, toe][:, [0, 2]]
        assert np.ptp(horizontal, axis=0).max() < 0.5, "a trotting paw slides on the ground"


def test_some_training_clips_switch_legs_to_fk():
    """Animators switch a lifted leg to FK: the blends and FK channels actually move."""
    train = corpus("quadruped", "train")
    for leg in ("front_leg_l", "front_leg_r", "hind_leg_l", "hind_leg_r"):
        assert train.table[f"{leg}.ik_fk"].min() == pytest.approx(0.0)
    for control in ("upper_arm_l_fk.rx", "thigh_r_fk.rx", "stifle_l_fk.rx"):
        assert train.table[control].std() > 0.05


# --- pictures ---------------------------------------------------------------------------------
def test_contact_sheet_and_gif_are_written(tmp_path):
    from dataclasses import replace

    from PIL import Image

    from rigmap.viz.contact_sheet import write_contact_sheet, write_gif

    rig = load("quadruped")
    motion = motion_library("quadruped").find("Walk")[1]
    played = play_clip(rig, build_clip("quadruped", motion, seed=0))
    short = slice(10, 22)
    played = replace(
        played,
        frames=played.frames[short],
        controls=played.controls[short],
        world=played.world[short],
        cog=played.cog[short],
    )
    sheet = write_contact_sheet(played, tmp_path / "walk.png", panels=4, columns=4)
    gif = write_gif(played, tmp_path / "walk.gif", max_frames=6)
    with Image.open(sheet) as image:
        assert image.format == "PNG" and image.width > image.height
    with Image.open(gif) as image:
        assert image.format == "GIF" and image.n_frames == 6
        # every 2nd frame at 24 fps; GIF stores delays in hundredths of a second
        assert image.info["duration"] == pytest.approx(1000 * 2 / 24, abs=10)
    assert not list(tmp_path.glob(".*"))  # temp files renamed away


def test_show_clip_checks_the_split_before_drawing(tmp_path):
    from rigmap.viz.contact_sheet import show_clip

    with pytest.raises(KeyError, match="'Walk' of rig 'quadruped' is in the 'train' split"):
        show_clip("quadruped", "Walk", tmp_path / "walk.png", split="test")
    with pytest.raises(KeyError, match="no clip named 'Moonwalk'"):
        show_clip("biped", "Moonwalk", tmp_path / "x.gif")
    assert not list(tmp_path.iterdir())
