"""An artist's own edits (skeleton mode): example pairs of BVH files in, BVH clips out.

§3: "The artist first selects a pre-existing animation clip, then edits it … The source
and target clips are assumed to have the same number of frames". :func:`read_pairs` reads
each pair (a source BVH and the artist's edited version, optionally a frame range of
both) and checks that assumption with one-line errors naming the file: the same
skeleton, the same frame count and frame time (a BVH has one frame time, so it cannot
carry the paper's timing signal; a pair whose timing differs is refused); a value that is
not a number is refused by the reader (:func:`rigmap.animation.bvh.read_bvh`, naming the
line). Frames that are not captured motion are found with
:func:`rigmap.map.skeleton_match.check_frames` (``rigmap map`` uses it too): a glitch
frame (every channel zero, e.g. ``cmu_07_12.bvh``'s frame 1, counted from 0) is repaired
from its neighbours and left out of the examples, said so in the notes, or refused
(``glitch="refuse"``); an added T-pose at frame 0 (the MotionBuilder-friendly CMU
conversion) is cut. :func:`learn_pairs` fits the :class:`EditModel` on the pairs;
:func:`apply_clip` propagates it to a clip and, when the edit changes the timing
(predicted Δt), resamples the result to a fixed frame rate (:func:`fixed_rate`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rigmap.animation import read_bvh
from rigmap.animation.bvh import ROTATION_CHANNELS, BVHMotion
from rigmap.edits.propagation import EditModel, FeatureJoints, SourceClip
from rigmap.edits.representation import (
    ChannelScale,
    TargetError,
    TargetTrack,
    resample,
    root_differentials,
)
from rigmap.edits.skeleton_mode import (
    Skeleton,
    skeleton_positions,
    skeleton_targets,
    track_motion,
)
from rigmap.map.skeleton_match import Skeleton as MatchSkeleton
from rigmap.map.skeleton_match import check_frames, match_skeleton

GLITCH_POLICIES = ("repair", "refuse")
#: a predicted Δt this far (relative) from the clip's frame time counts as a timing edit (ours)
TIMING_TOLERANCE = 1e-6


class PairError(TargetError):
    """An example pair or clip that breaks the method's assumptions; names the file."""


@dataclass(frozen=True, eq=False)
class Clip:
    """A BVH clip read for the edits: its (repaired, cut) motion and target track, the
    frames that are not captured motion (``bad``, repaired), and what was done."""

    motion: BVHMotion
    track: TargetTrack
    bad: np.ndarray
    notes: tuple[str, ...]
    start: int = 0  # the file's frame that is the clip's frame 0

    def source(self) -> SourceClip:
        """The clip as the model reads it (joint positions in the file's length unit)."""
        return SourceClip(skeleton_positions(self.track, Skeleton.of(self.motion)), self.track)


def read_clip(
    path, frames: tuple[int, int] | None = None, glitch: str = "repair", tpose: bool | None = None
) -> Clip:
    """One BVH clip, checked, glitches repaired or refused, frames ``start:stop`` kept;
    ``tpose`` says whether frame 0 is a T-pose (default: found by ``check_frames``)."""
    if glitch not in GLITCH_POLICIES:
        raise PairError(f"--glitch must be one of {GLITCH_POLICIES}, got {glitch!r}")
    motion = read_bvh(path)
    where = str(path)
    Skeleton.of(motion)
    check = _frame_check(motion)
    tpose_at_0 = check.tpose_at_0 if tpose is None else tpose
    values, bad, notes = without_glitches(motion, where, glitch, check.glitches, tpose_at_0)
    start, stop = _frame_range(where, motion.n_frames, frames)
    if tpose_at_0 and start == 0:
        start = 1
        notes.append(f"{where}: frame 0 is an added T-pose, not motion: cut")
    if stop - start < 3:
        raise PairError(f"{where}: frames {start}:{stop} hold fewer than 3 frames of motion")
    cut = replace(motion, values=values[start:stop].copy(), source=where)
    return Clip(cut, skeleton_targets(cut), bad[start:stop].copy(), tuple(notes), start)


def _frame_check(motion: BVHMotion):
    return check_frames(
        motion.values,
        motion.global_positions(),
        motion.joint_names,
        match_skeleton(MatchSkeleton.from_bvh(motion)),
    )


def without_glitches(
    motion: BVHMotion, where: str, glitch: str, glitches=None, tpose_at_0: bool = False
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The motion's values with its capture glitches (frames whose every channel is zero;
    found here unless ``glitches`` lists them) rebuilt from their neighbours, the glitch
    mask and a note saying so; with ``glitch="refuse"`` a glitch is a ``PairError``."""
    glitches = list(_frame_check(motion).glitches if glitches is None else glitches)
    bad = np.zeros(motion.n_frames, dtype=bool)
    if not glitches:
        return motion.values.copy(), bad, []
    if glitch == "refuse":
        raise PairError(
            f"{where}: frames {glitches} (from 0) are capture glitches (every channel zero); "
            "--glitch repair rebuilds them"
        )
    bad[glitches] = True
    # a T-pose is not motion either: a glitch beside it is rebuilt from captured frames
    not_motion = bad.copy()
    not_motion[0] |= bool(tpose_at_0)
    values = rebuilt_frames(motion, motion.values.copy(), not_motion)
    return (
        values,
        bad,
        [
            f"{where}: glitch frames {glitches} (from 0, every channel zero) repaired from their "
            "neighbours"
        ],
    )


def _frame_range(where: str, n: int, frames) -> tuple[int, int]:
    if frames is None:
        return 0, n
    start, stop = (int(v) for v in frames)
    if not 0 <= start < stop <= n:
        raise PairError(f"{where}: --frames {start}:{stop} is not a range within its {n} frames")
    return start, stop


def rebuilt_frames(motion: BVHMotion, values: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``bad`` rows interpolated from the good ones; angles unwrapped first (ours: a turn
    through ±180° between two good frames is not interpolated the long way round)."""
    good = np.flatnonzero(~bad)
    if len(good) < 2:
        raise PairError(f"{motion.source}: fewer than 2 frames are not glitches")
    rotation = np.array([c in ROTATION_CHANNELS for joint in motion.channels for c in joint])
    frames = np.arange(len(values))
    out = values.copy()
    for column in range(values.shape[1]):
        known = values[good, column]
        if rotation[column]:
            known = np.unwrap(known, period=360.0)
        out[bad, column] = np.interp(frames[bad], good, known)
    return out


@dataclass(frozen=True, eq=False)
class Pair:
    """An example pair read and checked: the source clip, the edited track, the frames
    that are examples (not repaired glitches of either file)."""

    source: Clip
    edited: Clip

    @property
    def examples(self) -> np.ndarray:
        """Not a repaired frame, nor the frame after one (its root step and turn are
        differences from the repaired frame)."""
        bad = self.source.bad | self.edited.bad
        return ~(bad | np.concatenate([[False], bad[:-1]]))


def read_pair(source_path, edited_path, frames=None, glitch: str = "repair") -> Pair:
    """One example pair, checked against §3's assumption (module docstring)."""
    whole = [read_bvh(p) for p in (source_path, edited_path)]
    source_motion, edited_motion = whole
    Skeleton.of(source_motion).check_same(Skeleton.of(edited_motion), str(edited_path))
    if edited_motion.n_frames != source_motion.n_frames:
        raise PairError(
            f"{edited_path}: {edited_motion.n_frames} frames, but its source "
            f"{source_path} has {source_motion.n_frames} (§3: a source and its "
            "edit have the same number of frames)"
        )
    if abs(edited_motion.frame_time - source_motion.frame_time) > 1e-9:
        raise PairError(
            f"{edited_path}: frame time {edited_motion.frame_time:g} s, its "
            f"source {source_path} {source_motion.frame_time:g} s (a BVH pair "
            "cannot carry a timing edit)"
        )
    source = read_clip(source_path, frames, glitch)
    # the source decides whether frame 0 is a T-pose: an edit may have moved its arms
    edited = read_clip(edited_path, frames, glitch, tpose=source.start > (frames or (0,))[0])
    if source.track.n_frames != edited.track.n_frames:  # a T-pose cut from one file only
        raise PairError(
            f"{edited_path}: {edited.track.n_frames} frames of motion after "
            f"the checks, its source {source_path} {source.track.n_frames}"
        )
    return Pair(source, edited)


def feature_joints(motion: BVHMotion) -> FeatureJoints:
    """The joints the features read (the root and every joint of non-zero offset, as the
    study's :func:`rigmap.edits.subjects.skeleton_subject`) and the hips and thighs that
    place the heading frame, found by :func:`rigmap.map.skeleton_match.match_skeleton`
    (so either CMU naming works)."""
    roles = match_skeleton(MatchSkeleton.from_bvh(motion)).roles
    names = list(motion.joint_names)
    missing = [r for r in ("hips", "thigh_l", "thigh_r") if r not in roles]
    if missing:
        raise PairError(f"{motion.source}: no joint found for {missing} (the heading frame)")
    root, left, right = (names.index(roles[r]) for r in ("hips", "thigh_l", "thigh_r"))
    moving = [j for j in range(len(names)) if j == 0 or np.linalg.norm(motion.offsets[j]) > 0]
    return FeatureJoints(tuple(moving), root, left, right)


def learn_pairs(pairs: list[Pair], model: EditModel, extra: list[tuple] = ()) -> EditModel:
    """Fit ``model`` (made with :func:`feature_joints`) on the pairs, the channel scale
    from their source clips; repaired frames are not examples. ``extra``: more
    ``(source, edited track, frame mask)`` examples (the artist's fixes,
    :mod:`rigmap.edits.fixes`)."""
    if not pairs:
        raise PairError("give at least one example pair (--source and --edited)")
    first = Skeleton.of(pairs[0].source.motion)
    for pair in pairs[1:]:
        first.check_same(Skeleton.of(pair.source.motion), pair.source.motion.source)
    scale = pair_scale([p.source.track for p in pairs])
    examples = [(p.source.source(), p.edited.track, p.examples) for p in pairs]
    return model.fit([*examples, *extra], scale)


def pair_scale(tracks: list[TargetTrack]) -> ChannelScale:
    """:meth:`ChannelScale.fit`, with Δt in frames of the source: a BVH's frame time is
    constant, so ``fit`` keeps Δt in seconds, where a 1.5× timing edit at 120 fps is a
    0.004 offset; the GPs' prior variance then falls below the combined solve's
    ``MIN_VARIANCE`` floor and the solve stops halfway between the edit and the source
    (measured: Δt × 1.25 for a learned × 1.5, on the training clip itself). Ours; the
    stages keep ``fit``'s scale (their metrics stay as they are)."""
    scale = ChannelScale.fit(tracks)
    if scale.std[0] == 1.0:  # constant Δt: measured in the examples' frame time instead
        std = scale.std.copy()
        std[0] = 1.0 / tracks[0].fps
        scale = ChannelScale(scale.channels, std)
    return scale


def apply_clip(model: EditModel, clip: Clip, fps: float | None = None) -> TargetTrack:
    """The learned edit on one BVH clip (:func:`propagate`)."""
    return propagate(model, clip.source(), fps)


def propagate(model: EditModel, source: SourceClip, fps: float | None = None) -> TargetTrack:
    """The learned edit on one clip (either mode), at ``fps`` (default the clip's):
    resampled when the predicted Δt differs from the frame time or another rate is asked
    for."""
    track = source.track
    model.scale.check(track)
    result = model.apply(source)
    rate = float(fps or track.fps)
    timed = np.abs(result.values[:, 0] * track.fps - 1.0).max() > TIMING_TOLERANCE
    if timed or abs(rate - track.fps) > 1e-9:
        result = fixed_rate(result, rate)
    return result


def fixed_rate(track: TargetTrack, fps: float) -> TargetTrack:
    """The track on the schedule ``0, 1/fps, …`` of its integrated frame times (§4.5: "the
    target sequence must then be resampled"): the root's ground position and heading and
    the pose channels interpolated (:func:`resample`), the per-frame steps and turns
    recomputed at the new rate."""
    if not np.isfinite(fps) or fps <= 0:
        raise PairError(f"--fps must be a positive number, got {fps}")
    root = track.root()
    rows = np.column_stack([root.x, root.z, root.heading, track.values[:, 4:]])
    out = resample(rows, root.time, fps)
    if len(out) < 3:
        raise PairError(f"{track.source}: fewer than 3 frames at {fps:g} fps")
    differentials = root_differentials(out[:, 0], out[:, 1], out[:, 2], fps)
    values = np.column_stack([differentials, out[:, 3:]])
    start = (float(out[0, 0]), float(out[0, 1]), float(out[0, 2]))
    return replace(track, values=values, fps=float(fps), start=start)


def clip_motion(track: TargetTrack, clip: Clip) -> BVHMotion:
    """The edited track as a BVH motion of the clip's own hierarchy."""
    return track_motion(track, clip.motion)


def bvh_files(path) -> list[Path]:
    """A BVH file, or the ``*.bvh`` files of a folder (sorted); none is an error."""
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".bvh" and p.is_file())
        if not files:
            raise PairError(f"{path}: the folder holds no .bvh file")
        return files
    if not path.is_file():
        raise PairError(f"{path}: no such BVH file or folder")
    return [path]
