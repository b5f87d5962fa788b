"""A corpus from a user's own .blend: its actions read as clips on the rig's controls (§6.1).

The paper learns from the animators' own keyframes on their production rig. Here every
action of the file (or those whose name matches a glob) becomes a :class:`Clip` in rig
space — the keys as stored (frame, value, interpolation, both Bézier handles) in rigmap's
keyframe model — sampled on the whole frames of the action's frame range, exactly as the
``animate`` stage writes a built-in rig's corpus (``data/<rig>/corpus/{train,test}.parquet``).

A Blender worker (:mod:`rigmap.rigs.blender.in_blender.blend_actions`) reads the file;
the file is never written. Around the keys:

* *used controls*: those keyed in the actions, unless ``used`` globs say otherwise;
* *soft ranges*: the span of the keyed values (and the rest value), widened by
  ``soft_range_margin`` of that span and held inside the bones' limits (local-space
  limit constraints, custom properties' hard ranges);
* *test clips*: named (globs) in ``test_clips``, else the ``extreme_test_clips`` clips
  farthest from the rest pose (largest RMS over used controls of the distance from the
  rest value in units of the control's soft range, at the clip's most extreme frame);
  none with ``split=False`` (takes for the latent models, which hold nothing out);
* every curve rigmap evaluates itself is compared with Blender's own evaluation at every
  frame; a curve that differs by more than ``MATCH_TOLERANCE`` (Blender units), or that
  uses what the model does not carry (easing, F-curve modifiers, linear extrapolation,
  quaternion rotations), is *baked*: one linear key per frame from Blender's values.

Checks before a long run (:class:`BlendCheckError`, each message naming file, armature and
action): no armature or several without a choice, no actions, actions keyed on deform bones
only, controls keyed in only one frame, drivers or constraints that make the pose depend on
the frame number, and a rig that poses the same controls differently twice.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from pathlib import Path

import numpy as np

from rigmap.animation.clip import CLIP_FPS, Clip
from rigmap.animation.corpus import Corpus
from rigmap.animation.keyframes import FCurve, Key, KeyframeError
from rigmap.errors import RigmapError
from rigmap.rigs.blender.cache import cache_dir, file_sha256
from rigmap.rigs.blender.environment import find_blender
from rigmap.rigs.blender.rig import RIGIFY_HELPER_BONES, select_names, session_options
from rigmap.rigs.blender.worker_process import WorkerError

#: largest |rigmap − Blender| of a curve kept key for key, in Blender's units (m, rad); ours
MATCH_TOLERANCE = 1e-6
#: two evaluations of the same controls may differ by this much (cm) and still count as the
#: same pose (Blender computes in float32); ours
DETERMINISM_TOLERANCE = 1e-3
#: a control keyed at one value only gets this half-width of soft range (control units); ours
FLAT_RANGE = {"translate": 1.0, "rotate": 0.1, "scale": 0.1, "scalar": 0.1}
IMPORT_FILE = "blend_import.json"
IMPORT_FORMAT = "rigmap.blend_import/1"
READ_TIMEOUT_S = 600.0


class BlendCorpusError(RigmapError, ValueError):
    """The .blend cannot give a corpus; the message names the file, armature and action."""


class BlendCheckError(BlendCorpusError):
    """One or more checks before a long run failed; ``problems`` holds one message each."""

    def __init__(self, problems: Sequence[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


@dataclass
class BlendCorpus:
    """The clips imported from a .blend, their split, used controls and soft ranges."""

    path: Path
    armature: str
    rig_name: str
    fps: int
    clips: list[Clip]
    test_names: list[str]
    used: list[str]
    defaults: dict[str, float]
    soft_ranges: dict[str, tuple[float, float]]
    session_options: dict
    #: per clip and control, Blender's own values on the clip's frames (control units)
    blender_values: dict[str, dict[str, np.ndarray]]
    notes: list[str] = field(default_factory=list)
    baked: dict[str, dict[str, str]] = field(default_factory=dict)
    sha256: str = ""
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def train_names(self) -> list[str]:
        return [c.name for c in self.clips if c.name not in self.test_names]

    def corpus(self, split: str) -> Corpus:
        """The clips of ``split`` played on the used controls (unkeyed ones at rest)."""
        names = self.test_names if split == "test" else self.train_names
        if split not in ("train", "test"):
            raise ValueError(f"split must be 'train' or 'test', got {split!r}")
        clips = [c for c in self.clips if c.name in names]
        lower = [self.soft_ranges[c][0] for c in self.used]
        upper = [self.soft_ranges[c][1] for c in self.used]
        return Corpus.from_clips(
            clips,
            self.used,
            [self.defaults[c] for c in self.used],
            rig=self.rig_name,
            split=split,
            seed=None,
            lower=lower,
            upper=upper,
            extra={
                "source": self.source(),
                "baked": {k: self.baked[k] for k in names if k in self.baked},
            },
        )

    def source(self) -> dict:
        return {
            "blend_file": str(self.path),
            "blend_sha256": self.sha256,
            "armature": self.armature,
            "actions": [c.name for c in self.clips],
        }

    def rig_config(self) -> dict:
        """Options of ``rig=blend_file`` that evaluate this corpus (same controls, ranges)."""
        options = {k: v for k, v in self.session_options.items() if k not in ("path", "prune")}
        return {
            "name": "blend_file",
            "path": str(self.path),
            **options,
            "used": {"include": [_escape(c) for c in self.used], "exclude": []},
            "soft_ranges": {_escape(c): list(r) for c, r in self.soft_ranges.items()},
            "description": f"{self.armature!r} in {self.path.name} (corpus from its actions)",
        }

    def write(self, folder: str | Path) -> Path:
        """``train.parquet``, ``test.parquet`` and ``blend_import.json`` into ``folder``, as
        one atomic step (a ``data/<rig>/corpus`` folder; nothing half-written on failure)."""
        from rigmap.store import write_folder_atomic

        corpora = {split: self.corpus(split) for split in ("train", "test")}  # before writing
        record = {
            "format": IMPORT_FORMAT,
            **self.source(),
            "rig_name": self.rig_name,
            "fps": self.fps,
            "train": self.train_names,
            "test": self.test_names,
            "used": self.used,
            "soft_ranges": {c: list(r) for c, r in self.soft_ranges.items()},
            "baked": self.baked,
            "notes": self.notes,
            "rig_config": self.rig_config(),
        }

        def fill(staging: Path) -> None:
            for split, corpus in corpora.items():
                corpus.write(staging / f"{split}.parquet")
            text = json.dumps(record, indent=1, sort_keys=True, default=float) + "\n"
            (staging / IMPORT_FILE).write_text(text)

        return write_folder_atomic(Path(folder), fill)

    def write_to_layout(self, layout) -> Path:
        """Into the layout's corpus folder of this rig (``data/<rig>/corpus``)."""
        return self.write(layout.corpus_folder(self.rig_name))


def _escape(name: str) -> str:
    """A control name as a glob that matches only itself."""
    return "".join(f"[{ch}]" if ch in "*?[]" else ch for ch in name)


def import_blend_corpus(
    path: str | Path,
    *,
    armature: str | None = None,
    actions: str = "*",
    used=None,
    test_clips: Sequence[str] | None = None,
    extreme_test_clips: int = 1,
    rig_name: str | None = None,
    cog_bone: str | None = None,
    soft_range_margin: float = 0.1,
    check_determinism: bool = True,
    blender: str | None = None,
    timeout: float = READ_TIMEOUT_S,
    split: bool = True,
    **load,
) -> BlendCorpus:
    """Read the actions of ``path`` as clips; run the checks; see the module docstring.
    ``load``: the armature options of :func:`~rigmap.rigs.blender.rig.session_options`
    (``joints``, ``euler_order``…), as a :class:`BlenderRig` takes them."""
    from rigmap.rigs.blender.pool import WorkerPool

    started = time.perf_counter()
    path = _checked_path(path, extreme_test_clips, soft_range_margin)
    sha = file_sha256(path)
    options = session_options(path, where=path.name, armature=armature, cog_bone=cog_bone, **load)
    command = find_blender(blender)
    seconds: dict[str, float] = {}
    with WorkerPool(
        lambda _slot: command.argv(), workers=1, timeout=timeout, log_dir=cache_dir() / "logs"
    ) as pool:
        try:
            info, _ = pool.call("read_actions", {"options": options, "actions": actions})
        except WorkerError as error:
            raise _reworded(error, path) from None
        seconds["read"] = time.perf_counter() - started
        options["armature"], options["cog_bone"] = info["armature"], info["cog_bone"]
        result = _build(
            info,
            path,
            options,
            sha,
            actions,
            used,
            (test_clips, extreme_test_clips) if split else None,
            rig_name or f"blend_file:{path.stem}",
            soft_range_margin,
        )
        seconds["build"] = time.perf_counter() - started - seconds["read"]
        if check_determinism:
            problem = _determinism(pool, result, info)
            if problem:
                raise BlendCheckError([problem])
            seconds["determinism"] = time.perf_counter() - started - sum(seconds.values())
    if file_sha256(path) != sha:  # the worker never saves; this says so
        raise BlendCorpusError(f"{path}: the file changed while it was read")
    seconds["total"] = time.perf_counter() - started
    result.seconds = seconds
    return result


def _checked_path(path, extreme_test_clips, soft_range_margin) -> Path:
    path = Path(path).expanduser().resolve()
    if not path.is_file():
        raise BlendCorpusError(f"blend file {path} does not exist")
    if path.suffix != ".blend":
        raise BlendCorpusError(f"{path}: expected a .blend file")
    if isinstance(extreme_test_clips, bool) or not (
        isinstance(extreme_test_clips, int) and extreme_test_clips >= 1
    ):
        raise BlendCorpusError(
            f"extreme_test_clips must be an integer >= 1, got {extreme_test_clips!r}"
        )
    if not (math.isfinite(soft_range_margin) and soft_range_margin >= 0):
        raise BlendCorpusError(f"soft_range_margin must be >= 0, got {soft_range_margin!r}")
    return path


def _reworded(error: WorkerError, path: Path) -> BlendCorpusError:
    """The worker's message without its wrapping, naming the file once."""
    detail = str(error).split(": ", 1)[-1]  # "Blender worker failed on 'op': Type: message"
    kind, _, message = detail.partition(": ")
    message = message if kind.isidentifier() and message else detail
    if not message.startswith(str(path)):
        message = f"{path}: {message}"
    if kind in ("BlendFileError", "SessionError"):
        return BlendCheckError([message])
    return BlendCorpusError(message)


def _build(info, path, options, sha, pattern, used, test_rule, rig_name, margin):
    """The corpus; ``test_rule``: ``(test_clips, extreme_test_clips)``, None: no test clip."""
    where = f"{path}: armature {info['armature']!r}"
    controls = {c["name"]: c for c in info["controls"]}
    names = [c["name"] for c in info["controls"]]
    whole = _clip_fps(info, path)
    if not info["all_actions"]:
        raise BlendCheckError(
            [
                f"{path}: the file has no actions: there is no animation to "
                f"learn from (key armature {info['armature']!r} first)"
            ]
        )
    if not info["actions"]:
        raise BlendCheckError(
            [
                f"{path}: no action matches {pattern!r} with a slot for armature "
                f"{info['armature']!r}; actions: {info['all_actions']}"
            ]
        )
    clips, blender_values, baked, notes = _clips(info, path, controls, options, whole)
    python_drivers = info.get("python_drivers", 0)
    if python_drivers and not options["use_scripts"]:
        notes.append(
            f"{python_drivers} Python driver(s) on {info['armature']!r} do not run without "
            "use_scripts=true: the rig is evaluated without them"
        )
    used_names = _used(clips, names, used, path, notes, where)
    problems = [*_one_frame_controls(clips, used_names, where), *info["frame_dependence"]]
    if problems:
        raise BlendCheckError(problems)
    defaults = {n: float(controls[n]["default"]) for n in names}
    ranges = _soft_ranges(clips, used_names, controls, info["limits"], margin)
    test = []
    if test_rule is not None:
        test = _test_split(clips, used_names, defaults, ranges, *test_rule, where)
    return BlendCorpus(
        path=path,
        armature=info["armature"],
        rig_name=rig_name,
        fps=whole,
        clips=clips,
        test_names=test,
        used=used_names,
        defaults=defaults,
        soft_ranges=ranges,
        session_options=options,
        blender_values=blender_values,
        notes=notes,
        baked=baked,
        sha256=sha,
    )


def _clip_fps(info, path) -> int:
    fps = float(info["fps"])
    whole = round(fps)
    if abs(fps - whole) > 1e-6 or whole not in CLIP_FPS:
        raise BlendCorpusError(
            f"{path}: the scene plays at {fps:g} fps; rigmap's clips are "
            f"{' or '.join(map(str, CLIP_FPS))} fps"
        )
    return whole


def _clips(info, path, controls, options, fps):
    """The actions as clips (deform-only actions are problems), Blender's values, bakes, notes."""
    where = f"{path}: armature {info['armature']!r}"
    problems, notes = [], []
    scale = float(options["length_scale"])
    clips, blender_values, baked = [], {}, {}
    for action in info["actions"]:
        name = action["name"]
        deform = sorted({c["bone"] for c in action["ignored"] if c.get("why") == "deform bone"})
        if not action["curves"]:
            if deform:
                problems.append(
                    f"{where}, action {name!r}: keys only deform bones ({', '.join(deform[:6])}"
                    f"{' …' if len(deform) > 6 else ''}), no control an animator keys; key the "
                    "control bones, or make these bones controls (rig.exclude_bones)"
                )
            else:
                notes.append(f"action {name!r}: keys no control of {info['armature']!r}; skipped")
            continue
        if deform:
            notes.append(f"action {name!r}: keys on deform bones {deform[:6]} ignored")
        curves, samples = {}, {}
        frames = np.arange(action["start"], action["end"] + 1, dtype=np.float64)
        for curve in action["curves"]:
            control = controls[curve["control"]]
            factor = scale if control["kind"] == "translate" else 1.0
            reference = np.asarray(curve["samples"], dtype=np.float64) * factor
            fcurve, why = _curve(curve, control, factor, frames, reference, name, path)
            if why is not None:
                baked.setdefault(name, {})[curve["control"]] = why
            curves[curve["control"]] = fcurve
            samples[curve["control"]] = reference
        try:
            clip = Clip(
                name,
                fps,
                curves,
                start=action["start"],
                end=action["end"],
                description=f"action {name!r} of {path.name}",
            )
        except KeyframeError as error:
            raise BlendCorpusError(f"{where}: {error}") from None
        clips.append(clip)
        blender_values[name] = samples
    if problems:
        raise BlendCheckError(problems)
    if not clips:
        actions = [a["name"] for a in info["actions"]]
        raise BlendCheckError([f"{where}: none of the actions {actions} keys a control of it"])
    return clips, blender_values, baked, notes


def _used(clips, names, used, path, notes, where) -> list[str]:
    """The keyed controls, or those the ``used`` globs pick (curves on others dropped)."""
    keyed = [n for n in names if any(n in c.curves for c in clips)]
    if used is None:
        return keyed
    flags = select_names(names, used, f"{path.name} used")
    used_names = [n for n, flag in zip(names, flags, strict=True) if flag]
    dropped = [n for n in keyed if n not in used_names]
    if dropped:
        notes.append(f"keyed controls left out by the used globs (held at rest): {dropped[:10]}")
        for clip in clips:
            for control in dropped:
                clip.curves.pop(control, None)
    empty = [c.name for c in clips if not c.curves]
    if empty:
        raise BlendCorpusError(f"{where}: actions {empty} key none of the used controls")
    return used_names


def _one_frame_controls(clips, used_names, where) -> list[str]:
    """Used controls keyed in only one frame wherever keyed: they never move within a clip."""
    problems = []
    for control in used_names:
        keyed_in = [(c.name, c.curves[control]) for c in clips if control in c.curves]
        if keyed_in and all(len(curve) == 1 for _, curve in keyed_in):
            spots = "; ".join(
                f"action {a!r} frame {curve.first_frame:g}" for a, curve in keyed_in[:4]
            )
            problems.append(
                f"{where}: control {control!r} is keyed in only one frame ({spots}): it never "
                "moves within a clip, so the corpus cannot show what it does; key it in more "
                "frames, or leave it out with rig.used exclude"
            )
    return problems


def _curve(curve, control, factor, frames, reference, action, path):
    """rigmap's F-curve of one Blender curve, and why it was baked (``None``: key for key)."""
    why = curve.get("bake")
    if why is None:
        keys = [
            Key(
                float(f),
                float(v) * factor,
                interpolation,
                (float(left[0]), float(left[1]) * factor),
                (float(right[0]), float(right[1]) * factor),
            )
            for f, v, interpolation, left, right in curve["keys"]
        ]
        try:
            fcurve = FCurve(keys, control=control["name"])
        except KeyframeError as error:
            raise BlendCorpusError(f"{path}: action {action!r}: {error}") from None
        gap = np.abs(fcurve.evaluate(frames) - reference) / factor
        worst = int(np.argmax(gap)) if len(gap) else 0
        if len(gap) and gap[worst] > MATCH_TOLERANCE:
            why = (
                f"rigmap's curve differs from Blender's by {gap[worst]:.2g} at frame "
                f"{frames[worst]:g}"
            )
        else:
            return fcurve, None
    if curve.get("baked_keys"):  # already one key a frame (a converted rotation)
        pairs = [(float(k[0]), float(k[1]) * factor) for k in curve["keys"]]
    else:
        pairs = list(zip(frames.tolist(), reference.tolist(), strict=True))
    return FCurve.from_pairs(pairs, "linear", control=control["name"]), why


def _soft_ranges(clips, used, controls, limits, margin) -> dict[str, tuple[float, float]]:
    ranges = {}
    for name in used:
        control = controls[name]
        default = float(control["default"])
        values = [default]
        for clip in clips:
            if name in clip.curves:
                curve = clip.curves[name]
                values.extend(curve.values.tolist())
                values.extend(curve.evaluate(clip.frames).tolist())
        low, high = min(values), max(values)
        pad = margin * (high - low) if high > low else FLAT_RANGE[control["kind"]]
        low, high = low - pad, high + pad
        hard_low, hard_high = limits.get(name) or [None, None]
        if control.get("value_type") in ("bool", "int"):
            hard_low = control.get("hard_min", hard_low)
            hard_high = control.get("hard_max", hard_high)
        keyed_low, keyed_high = min(values), max(values)
        if hard_low is not None and hard_low <= keyed_low:
            low = max(low, float(hard_low))
        if hard_high is not None and hard_high >= keyed_high:
            high = min(high, float(hard_high))
        if not high > low:
            low, high = low - FLAT_RANGE[control["kind"]], high + FLAT_RANGE[control["kind"]]
        ranges[name] = (float(low), float(high))
    return ranges


def extremeness(clip: Clip, used, defaults: Mapping[str, float], ranges) -> tuple[float, int]:
    """Largest RMS distance from rest over the clip's frames, in soft-range units, and its
    frame (ours: control space, so no rig evaluation is needed)."""
    values = clip.evaluate(used, [defaults[c] for c in used])
    rest = np.array([defaults[c] for c in used])
    span = np.array([ranges[c][1] - ranges[c][0] for c in used])
    distance = np.sqrt(np.mean(((values - rest) / span) ** 2, axis=1))
    row = int(np.argmax(distance))
    return float(distance[row]), int(clip.frames[row])


def _test_split(clips, used, defaults, ranges, test_clips, extreme, where) -> list[str]:
    names = [c.name for c in clips]
    if len(clips) < 2:
        raise BlendCorpusError(
            f"{where}: one action ({names}) cannot give both a training and "
            "a test corpus; the import needs at least two"
        )
    if test_clips:
        patterns = [test_clips] if isinstance(test_clips, str) else list(test_clips)
        dead = [p for p in patterns if not any(fnmatchcase(n, p) for n in names)]
        if dead:
            raise BlendCorpusError(f"{where}: test_clips {dead} match no action; actions: {names}")
        test = [n for n in names if any(fnmatchcase(n, p) for p in patterns)]
    else:
        score = {c.name: extremeness(c, used, defaults, ranges)[0] for c in clips}
        chosen = sorted(names, key=lambda n: -score[n])[: min(extreme, len(names) - 1)]
        test = [n for n in names if n in chosen]
    if len(test) == len(names):
        raise BlendCorpusError(
            f"{where}: every action is a test clip ({test}); leave some to train on"
        )
    return test


def _determinism(pool, result: BlendCorpus, info) -> str | None:
    """Pose rest and each of two clips' most extreme frames twice; the same pose twice?"""
    names = [c["name"] for c in info["controls"]]
    rest = np.array([result.defaults[n] for n in names])
    rows, labels = [rest], ["the rest pose"]
    for clip in result.clips[:2]:
        _, frame = extremeness(clip, result.used, result.defaults, result.soft_ranges)
        rows.append(clip.evaluate(names, rest, [float(frame)])[0])
        labels.append(f"frame {frame} of action {clip.name!r}")
    batch = np.array(rows + rows)
    _, out = pool.call("evaluate", {}, {"controls": batch})
    positions = out["positions"]
    n = len(rows)
    gaps = np.linalg.norm(positions[:n] - positions[n:], axis=2)  # (rows, joints)
    row, joint = np.unravel_index(int(np.argmax(gaps)), gaps.shape)
    if gaps[row, joint] <= DETERMINISM_TOLERANCE:
        return None
    return (
        f"{result.path}: armature {result.armature!r} is not deterministic: posing the same "
        f"controls twice ({labels[row]}) moved joint {info['joint_names'][joint]!r} by "
        f"{gaps[row, joint]:.3g} cm; look for Python drivers with random numbers or state, or "
        "dependency cycles"
    )


def action_payload(name: str, start, end, curves: Mapping[str, FCurve]) -> dict:
    """One action for the worker's ``write_actions``: every key of every control's curve
    (frame, value, interpolation, handles or ``None``) in control units."""

    def handle(point) -> list[float] | None:
        return None if point is None else [float(h) for h in point]

    return {
        "name": name,
        "start": start,
        "end": end,
        "curves": {
            control: [
                [
                    float(k.frame),
                    float(k.value),
                    k.interpolation,
                    handle(k.in_handle),
                    handle(k.out_handle),
                ]
                for k in curve.keys
            ]
            for control, curve in curves.items()
        },
    }


def write_actions_blend(
    blend_path: str | Path,
    clips: Sequence[Clip],
    out_path: str | Path,
    *,
    armature: str = "rig",
    cog_bone: str = "torso",
    fps: int | None = None,
    length_scale: float = 100.0,
    exclude_bones: list[str] | None = None,
    blender: str | None = None,
) -> dict:
    """Save a copy of ``blend_path`` with each clip keyed as an action of its own.

    The keys go in as an animator's keys: value, frame and interpolation from the clip,
    Blender's auto-clamped handles where the key has none (its own handles otherwise),
    a fake user so every action stays in the file, the clip's frame range as the action's
    manual range. The original file is not touched; ``out_path`` is written atomically.
    """
    from rigmap.rigs.blender.pool import WorkerPool

    blend_path = Path(blend_path).expanduser().resolve()
    out_path = Path(out_path).expanduser().resolve()
    if out_path == blend_path:
        raise BlendCorpusError(f"{out_path}: write the actions into a copy, not the original")
    if out_path.suffix != ".blend":
        raise BlendCorpusError(f"out_path must end in .blend, got {out_path.name!r}")
    payload = [action_payload(clip.name, clip.start, clip.end, clip.curves) for clip in clips]
    options = {
        "path": str(blend_path),
        "armature": armature,
        "cog_bone": cog_bone,
        "exclude_bones": list(RIGIFY_HELPER_BONES if exclude_bones is None else exclude_bones),
        "length_scale": float(length_scale),
        "prune": False,
        "keep_animation": False,
    }
    command = find_blender(blender)
    with WorkerPool(
        lambda _slot: command.argv(),
        setup=[("load", {"options": options})],
        workers=1,
        timeout=READ_TIMEOUT_S,
        log_dir=cache_dir() / "logs",
    ) as pool:
        info, _ = pool.call(
            "write_actions",
            {
                "clips": payload,
                "fps": None if fps is None else float(fps),
                "out_path": str(out_path),
            },
        )
    return {k: v for k, v in info.items() if k != "ok"}


# --- the pipeline: rig=blend_file with rig.actions -------------------------------
#: options of ``rig.actions`` (the rest of ``rig`` are the BlenderRig's own)
ACTION_OPTIONS = (
    "include",
    "test_clips",
    "extreme_test_clips",
    "soft_range_margin",
    "check_determinism",
)
#: BlenderRig options the import needs to see the same controls
SESSION_KEYS = (
    "armature",
    "cog_bone",
    "joints",
    "control_bones",
    "exclude_bones",
    "euler_order",
    "length_scale",
    "up_axis",
    "translate_range",
    "scale_range",
    "use_scripts",
    "blender",
    "used",
)
SUMMARY_FORMAT = 1


def import_options(rig_options: Mapping, actions: Mapping | None) -> dict:
    """:func:`import_blend_corpus` keywords from a ``blend_file`` rig config and its
    ``actions`` mapping."""
    actions = dict(actions or {})
    unknown = sorted(set(actions) - set(ACTION_OPTIONS))
    if unknown:
        raise BlendCorpusError(
            f"rig.actions: unknown keys {unknown}; expected {list(ACTION_OPTIONS)}"
        )
    if not rig_options.get("path"):
        raise BlendCorpusError("rig 'blend_file' needs rig.path=/path/to/file.blend")
    kwargs = {k: rig_options[k] for k in SESSION_KEYS if rig_options.get(k) is not None}
    kwargs["actions"] = actions.pop("include", None) or "*"
    kwargs.update({k: v for k, v in actions.items() if v is not None})
    return {"path": str(Path(rig_options["path"]).expanduser().resolve()), **kwargs}


def write_blend_corpora(
    rig_options: Mapping, actions: Mapping | None, layout, *, log=print
) -> list[Path]:
    """The ``animate`` stage of a ``blend_file`` rig: its actions into
    ``data/<rig>/corpus/{train,test}.parquet`` (and the rig options the import chose)."""
    kwargs = import_options(rig_options, actions)
    result = import_blend_corpus(**kwargs)
    folder = result.write_to_layout(layout)
    _write_summary(kwargs, result)
    for note in result.notes:
        log(f"{result.rig_name}: {note}")
    for split, names in (("train", result.train_names), ("test", result.test_names)):
        clips = [c for c in result.clips if c.name in names]
        baked = sum(len(result.baked.get(n, {})) for n in names)
        log(
            f"{result.rig_name} {split}: {len(clips)} actions {names[:6]}, "
            f"{sum(c.n_frames for c in clips)} frames at {result.fps} fps, "
            f"{sum(c.key_count for c in clips)} keys ({baked} curves baked), "
            f"{len(result.used)} used controls -> {folder / f'{split}.parquet'}"
        )
    log(f"{result.rig_name}: read {result.path.name} in {result.seconds['total']:.1f} s")
    return [folder / "train.parquet", folder / "test.parquet"]


def build_blend_file(**options):
    """The ``blend_file`` rig (its manifest's factory): with ``actions``, the controls the
    file's actions key become the used ones (:func:`imported_rig_options`); then
    :func:`rigmap.rigs.blender.rigify.build_blend_file`. Here, not in ``rigs``, because the
    import reads the actions as clips (``rigs`` sits below ``animation``)."""
    from rigmap.rigs.blender.rigify import build_blend_file as build_rig

    actions = options.pop("actions", None)
    if actions is not None and options.get("path"):
        rig_options = {k: v for k, v in options.items() if k not in ("path", "name")}
        path = str(Path(options["path"]))
        options.update(imported_rig_options({**rig_options, "path": path}, actions))
    return build_rig(**options)


def imported_rig_options(rig_options: Mapping, actions: Mapping | None) -> dict:
    """``used`` and ``soft_ranges`` (and the armature and COG the import chose) for a
    ``blend_file`` rig whose corpus comes from its actions: from the cache the ``animate``
    stage left (keyed by the file's bytes and the options), importing again if missing."""
    kwargs = import_options(rig_options, actions)
    from rigmap.rigs.blender.cache import read_json

    summary = read_json(_summary_path(kwargs))
    if summary is None:
        summary = _write_summary(kwargs, import_blend_corpus(**kwargs))
    options = {k: summary[k] for k in ("used", "soft_ranges", "armature", "cog_bone")}
    return {k: v for k, v in options.items() if rig_options.get(k) is None}


def _summary_path(kwargs: Mapping) -> Path:
    key = json.dumps(
        [SUMMARY_FORMAT, file_sha256(Path(kwargs["path"])), dict(kwargs)],
        sort_keys=True,
        default=str,
    )
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    return cache_dir() / "blend_import" / f"{Path(kwargs['path']).stem}-{digest}.json"


def _write_summary(kwargs: Mapping, result: BlendCorpus) -> dict:
    from rigmap.rigs.blender.cache import write_json_atomic

    config = result.rig_config()
    summary = {k: config[k] for k in ("used", "soft_ranges", "armature", "cog_bone")}
    write_json_atomic(_summary_path(kwargs), summary)
    return summary
