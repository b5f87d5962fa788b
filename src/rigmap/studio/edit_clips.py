"""The Edit view's clips and edits, apart from the page: a BVH clip read for dragging, the
drag held by §5's IK over a frame range, the edited file of an example pair, and the
numbers the page prints (:mod:`rigmap.studio.edit_view` draws and drives them).

Joints are shown and dragged in the character's heading frame (its root's ground point at
the origin, its heading turned away: x left, y up, z forward; ours), so a drag means the
same to the body on every frame however the clip turns, and the page's camera faces the
character. The IK is :func:`rigmap.edits.authoring.apply_pose_edit` (bone lengths kept,
the root on its ground point, pins, minimal rotations). The library keys an edit at one
frame and blends it out linearly (§5's offset signal); an example pair must hold the edit
over its frames, so :func:`hold_edit` runs the same IK on every frame of the range, the
drag carried in the heading frame and the pins held on each (ours). A dragged joint
carries the joints below it (fingers, toes: ours; left behind, the IK of the CMU
conversions' hands often did not converge). A frame where the IK still does not converge
takes the channel offset interpolated from its neighbours, and is counted.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rigmap.animation import read_bvh
from rigmap.animation.bvh import BVHMotion
from rigmap.edits.artist import parse_frames
from rigmap.edits.authoring import AuthoringError, apply_pose_edit
from rigmap.edits.pairs import Clip, read_clip
from rigmap.edits.representation import TargetTrack
from rigmap.edits.skeleton_mode import Skeleton, skeleton_positions, track_motion
from rigmap.errors import RigmapError
from rigmap.map.skeleton_match import Skeleton as MatchSkeleton
from rigmap.map.skeleton_match import match_skeleton
from rigmap.regression.placement import turn_matrix
from rigmap.studio.served_folder import ServedFolder
from rigmap.studio.writes import OutputFolder

#: the joints that get a gizmo, by role (found by name and shape, as ``rigmap map`` does)
GIZMO_ROLES = ("hand_l", "hand_r", "foot_l", "foot_r", "head")
#: the character is drawn this tall (m): a BVH's length unit is the file's own (ours)
DISPLAY_HEIGHT_M = 1.75
PROGRESS_EVERY = 10  # frames between progress reports of the held IK; ours
HEADING_AXES = "file units, heading frame: x left, y up, z forward"


class EditViewError(RigmapError, ValueError):
    """A request the view cannot carry out (no clip, no drag, a bad range); one line."""


# --------------------------------------------------------------------------- clips
@dataclass(frozen=True, eq=False)
class OpenedClip:
    """A BVH clip read for the view: the file's motion, the frames read (T-pose cut,
    glitches repaired: :func:`rigmap.edits.pairs.read_clip`), every frame's joints in the
    character's heading frame (file units; x left, y up, z forward)."""

    name: str  # relative to the served folder
    path: Path
    raw: BVHMotion
    clip: Clip
    frames: tuple[int, int] | None  # as typed (file frames), None: the whole clip
    skeleton: Skeleton
    scale: float  # scene metres per file unit
    gizmos: dict[str, str]  # role -> joint name
    joints: np.ndarray  # (F, J, 3)

    @property
    def n_frames(self) -> int:
        return self.clip.track.n_frames

    def joint(self, name: str) -> int:
        return list(self.skeleton.joint_names).index(name)


def bvh_clips(served: ServedFolder, *, limit: int = 500) -> list[str]:
    """The ``.bvh`` files under the served folder (relative, sorted; none leading out)."""
    found = []
    for path in sorted(served.root.rglob("*.bvh")):
        if path.resolve().is_relative_to(served.root) and ".dvc" not in path.parts:
            found.append(served.relative(path))
        if len(found) >= limit:
            break
    return found


def frames_of(text: str) -> tuple[int, int] | None:
    """The typed frames: ``START:STOP`` (file frames from 0, STOP excluded), or empty /
    ``all`` for the whole clip."""
    text = str(text).strip()
    if not text or text == "all":
        return None
    try:
        return parse_frames(text)
    except RigmapError:
        raise EditViewError(
            f"Frames {text!r}: expected START:STOP (file frames from 0, STOP excluded) or all"
        ) from None


def rest_height(skeleton: Skeleton) -> float:
    """The skeleton's height at rest (every rotation zero), in its file's unit."""
    positions = np.zeros((len(skeleton.parents), 3))
    for j, parent in enumerate(skeleton.parents):
        if parent >= 0:
            positions[j] = positions[parent] + skeleton.offsets[j]
    return float(np.ptp(positions[:, 1])) or 1.0


def to_heading_frame(track: TargetTrack, frame: int, positions: np.ndarray) -> np.ndarray:
    """World ``positions`` ``(J, 3)`` of ``frame`` relative to the root's ground point,
    its heading turned away (the character faces +z)."""
    root = track.root()
    ground = np.array([root.x[frame], 0.0, root.z[frame]])
    turn = turn_matrix(np.array([root.heading[frame]]))[0]
    return (np.asarray(positions) - ground) @ turn


def heading_joints(track: TargetTrack, skeleton: Skeleton) -> np.ndarray:
    """Every frame's joints ``(F, J, 3)`` in its heading frame (:func:`to_heading_frame`)."""
    positions = skeleton_positions(track, skeleton)
    root = track.root()
    ground = np.column_stack([root.x, np.zeros_like(root.x), root.z])
    turns = turn_matrix(root.heading)
    return np.einsum("fjb,fba->fja", positions - ground[:, None], turns)


def open_clip(path: Path, name: str, frames, glitch: str = "repair") -> OpenedClip:
    """Read ``path`` (frames ``frames`` of the file) for the view; errors name the file."""
    clip = read_clip(path, frames, glitch)
    raw = read_bvh(path)
    skeleton = Skeleton.of(clip.motion)
    roles = match_skeleton(MatchSkeleton.from_bvh(raw)).roles
    gizmos = {role: roles[role] for role in GIZMO_ROLES if role in roles}
    if not gizmos:
        raise EditViewError(f"{name}: no hand, foot or head joint found to drag")
    return OpenedClip(
        name=name,
        path=path,
        raw=raw,
        clip=clip,
        frames=frames,
        skeleton=skeleton,
        scale=DISPLAY_HEIGHT_M / rest_height(skeleton),
        gizmos=gizmos,
        joints=heading_joints(clip.track, skeleton),
    )


# --------------------------------------------------------------------------- the IK
def below(skeleton: Skeleton, joint: str) -> list[str]:
    """``joint`` and every joint under it (parents come before children in a BVH)."""
    names = list(skeleton.joint_names)
    inside = {names.index(joint)}
    for j, parent in enumerate(skeleton.parents):
        if parent in inside:
            inside.add(j)
    return [names[j] for j in sorted(inside)]


def pose_edit(track, skeleton, frame: int, drags: Mapping[str, np.ndarray], pins: Iterable[str]):
    """One frame edited by the IK: ``drags`` (joint -> offset in the heading frame, file
    units) turned to the frame's heading and given to the joint and those below it; the
    ``pins`` not among them held. Returns the frame's channels and world joint positions."""
    turn = turn_matrix(np.array([track.root().heading[frame]]))[0]
    world = {}
    for joint, drag in drags.items():
        for name in below(skeleton, joint):
            world[name] = turn @ np.asarray(drag, dtype=np.float64)
    held = tuple(p for p in pins if p not in world)
    edited, solved = apply_pose_edit(track, skeleton, frame, world, 0, pins=held)
    return edited.values[frame], solved


def hold_edit(
    track: TargetTrack,
    skeleton: Skeleton,
    frames: Iterable[int],
    drags: Mapping[str, np.ndarray],
    pins: Iterable[str],
    progress: Callable[[int, int], None] | None = None,
) -> tuple[TargetTrack, list[int]]:
    """``track`` with the drags held by the IK on each of ``frames`` (module docstring);
    also the frames where the IK did not converge, whose channel offsets are interpolated
    from the frames where it did."""
    frames, pins = list(frames), tuple(pins)
    values = track.values.copy()
    solved, failed = [], []
    for k, frame in enumerate(frames):
        try:
            values[frame] = pose_edit(track, skeleton, frame, drags, pins)[0]
            solved.append(frame)
        except AuthoringError:
            failed.append(frame)
        if progress is not None and (k + 1) % PROGRESS_EVERY == 0:
            progress(k + 1, len(frames))
    if not solved:
        raise EditViewError(
            f"{track.source}: the IK converged on none of the {len(frames)} frames; drag less far"
        )
    if failed:
        offset = values[solved] - track.values[solved]
        for column in range(values.shape[1]):
            values[failed, column] = track.values[failed, column] + np.interp(
                failed, solved, offset[:, column]
            )
    return track.with_values(values, source=f"{track.source} (edited in the studio)"), failed


def file_motion(raw: BVHMotion, clip: Clip, track: TargetTrack) -> BVHMotion:
    """The whole file with the clip's frames replaced by ``track``'s: the edited file of an
    example pair (§3: the same frames and frame time as its source)."""
    rows = track_motion(track, clip.motion).values
    values = raw.values.copy()
    values[clip.start : clip.start + len(rows)] = rows
    return replace(raw, values=values, source=f"{raw.source} (edited in the studio)")


def joint_shift(result: np.ndarray, source: np.ndarray, joints: list[int]) -> np.ndarray:
    """``(K, 3)`` the mean move of ``joints`` relative to the root, heading frame, between
    two clips' :func:`heading_joints` of the same frames."""
    moved = (result - result[:, :1]) - (source - source[:, :1])
    return moved[:, joints].mean(axis=0)


@dataclass(frozen=True, eq=False)
class LearnedEdit:
    """An edit learned in the page: where its files are and what made it."""

    folder: Path  # under the output folder
    model: Path  # folder/model: edit.npz, edit.json, learned.json
    edited: Path  # folder/edited.bvh
    source: OpenedClip
    drags: dict[str, np.ndarray]  # joint -> heading-frame drag, file units
    summary: dict  # learned.json
    failed: list[int]  # clip frames whose IK did not converge (interpolated)


@dataclass(frozen=True, eq=False)
class AppliedClip:
    """The learned edit propagated to a clip: the clip as read, the result written."""

    input: OpenedClip
    bvh: Path
    track: TargetTrack
    joints: np.ndarray  # (F', J, 3) heading frame
    row: dict  # applied.json's row

    @property
    def same_frames(self) -> bool:
        return not self.row["resampled"]


def vector(v) -> str:
    return "(" + ", ".join(f"{x:+.2f}" for x in v) + ")"


def cos_between(a, b) -> float:
    norm = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.dot(a, b) / norm) if norm > 0 else 0.0


def learned_line(learned: LearnedEdit, out: OutputFolder) -> str:
    """What ``rigmap edits learn`` reported (learned.json), and the drag it learned."""
    pair = learned.summary["pairs"][0]
    start, stop = pair["frames"]
    s = learned.summary
    drags = ", ".join(f"{j} {vector(d)}" for j, d in learned.drags.items())
    line = (
        f"**Learned** {learned.source.name} frames {start}:{stop} → "
        f"`{out.relative(learned.model)}`: {pair['example_frames']} example frames · fit "
        f"{s['fit_s']:.1f} s · length scales {s['kinematic_length_scale']:.3g} (kinematic), "
        f"{s['acceleration_length_scale']:.3g} (acceleration) · drag held on "
        f"{stop - start} frames: {drags} ({HEADING_AXES})"
    )
    if learned.failed:
        line += (
            f" · the IK did not converge on {len(learned.failed)} frames: their offsets "
            "interpolated from the neighbouring frames'"
        )
    notes = " ".join(pair.get("notes") or [])
    return line + (f"\n\n{notes}" if notes else "")


def applied_line(applied: AppliedClip, drags: Mapping[str, np.ndarray], out: OutputFolder) -> str:
    """What ``rigmap edits apply`` reported (applied.json), and how far each dragged joint
    moved on the propagated clip against the clip it edited (the mean over its frames,
    relative to the root), beside the drag."""
    row = applied.row
    line = (
        f"**Applied** to {applied.input.name} → `{out.relative(applied.bvh)}`: "
        f"{row['frames_in']} → {row['frames_out']} frames at {row['fps_out']:g} fps"
    )
    notes = "".join(f"\n\n{note}" for note in row["notes"])  # repaired glitches, a T-pose cut
    if not applied.same_frames:
        return line + " (resampled: a timing edit; the joints' moves are not compared)" + notes
    shifts = joint_shift(
        applied.joints, applied.input.joints, [applied.input.joint(j) for j in drags]
    )
    for (joint, drag), shift in zip(drags.items(), shifts, strict=True):
        line += (
            f" · {joint} moved {vector(shift)} on average (the drag {vector(drag)}, "
            f"cos {cos_between(shift, drag):.2f})"
        )
    return line + f" ({HEADING_AXES})" + notes


@dataclass(frozen=True, eq=False)
class FixReport:
    """What handing in a fix did: the frames (file), the fix's file, the refit's
    learned.json, the distances to the fix before and after, the next suggestions."""

    clip: str
    frames: tuple[int, int]
    file: Path
    summary: dict
    before: float
    after: float | None
    picks: list
    notes: list[str]
    failed: int = 0  # frames of the fix whose IK did not converge (interpolated)


def fixed_line(report: FixReport, out: OutputFolder) -> str:
    """What ``rigmap edits fix`` reported (the refit, what to fix next), and how far the
    propagated clip was from the fix on its frames before the refit and after it."""
    start, stop = report.frames
    s = report.summary
    picks = ", ".join(f"{p.start}:{p.stop} (variance {p.variance:.3g})" for p in report.picks)
    after = "not compared (resampled)" if report.after is None else f"{report.after:.3f}"
    line = (
        f"**Fix handed in**: frames {start}:{stop} of {report.clip} → "
        f"`{out.relative(report.file)}` · refit {s['fit_s']:.2f} s (the pairs and "
        f"{len(s['fixes'])} fixes so far) · distance to the fix on its frames "
        f"{report.before:.3f} → "
        f"{after} (RMS over the joints, file units)"
    )
    if report.failed:
        line += f" · the IK did not converge on {report.failed} of its frames: interpolated"
    if picks:
        line += f" · fix next: frames {picks}"
    return line + "".join(f"\n\n{note}" for note in report.notes)


def rms(a: np.ndarray, b: np.ndarray) -> float:
    """The root mean square of the joints' distances between two ``(..., 3)`` arrays."""
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))))
