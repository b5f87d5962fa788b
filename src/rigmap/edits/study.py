"""The edit-propagation study behind the ``edits`` stage (its fit, apply and evaluate steps).

A subject (the biped in rig mode, or CMU takes in skeleton mode) gives example clips (a
subject's own frame range of one take: the paper's were 550 + 74 frames) and held-out clips;
each procedural edit (``conf/edit/``) is applied to both, the model is fitted on the
examples, propagated to the held-out clips and scored against the edit applied to them
(:mod:`rigmap.edits.scoring`). All functions take plain dicts and objects; paths come
from a :class:`rigmap.store.Layout` (``models/<subject>/edits/``,
``data/<subject>/edits/``, ``metrics/<subject>/edits/``).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

import rigmap.rigs
from rigmap.animation.library import motion_library
from rigmap.edits.combine import Weights
from rigmap.edits.mirror import subject_mirror
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel, SourceClip
from rigmap.edits.representation import ChannelScale, TargetError, TargetTrack
from rigmap.edits.subjects import (
    BVH_LEG,
    SkeletonClip,
    Subject,
    leg_length_cm_per_unit,
    read_skeleton_clip,
    rig_clip,
    rig_subject,
    skeleton_clip,
    skeleton_subject,
)


@dataclass(frozen=True, eq=False)
class StudyData:
    """A subject with its channel scale, example clips, held-out clips and out-of-distribution
    clips (motion unlike the examples: the rig library's extreme test clips; Fig 4), and
    the foot joints whose skate the evaluation reports (§7.3)."""

    subject: Subject
    scale: ChannelScale
    train: list[SourceClip]
    heldout: list[SourceClip]
    unlike: list[SourceClip] = field(default_factory=list)
    feet: tuple[str, ...] = ()
    # held-out walk <-> stand transitions, measured for Fig 6's context dependence only
    # (rig mode: rigmap.edits.transitions; the other measures stay on ``heldout``)
    transitions: list[SourceClip] = field(default_factory=list)
    # what reading the clips did (a T-pose cut, capture glitches repaired), for the summary
    notes: tuple[str, ...] = ()


def load_study(name: str, spec: dict) -> StudyData:
    """The subject ``name`` of the ``edits.subjects`` config (see conf/edits/default.yaml)."""
    mode = spec.get("mode")
    if mode not in ("rig", "skeleton"):
        raise TargetError(f"edits subject {name!r}: mode must be 'rig' or 'skeleton', got {mode!r}")
    data = _rig_study(spec) if mode == "rig" else _skeleton_study(name, spec)
    feet = tuple(str(f) for f in spec.get("feet") or ())
    missing = [f for f in feet if f not in data.subject.joint_names]
    if missing:
        raise TargetError(f"edits subject {name!r}: feet {missing} are not among its joints")
    return replace(data, feet=feet)


def _rig_study(spec: dict) -> StudyData:
    rig = rigmap.rigs.load(spec["rig"])
    subject = rig_subject(rig, tuple(spec["root_channels"]), tuple(spec["heading_joints"]))
    names = [m.name for m in motion_library(rig.name).train]
    scale_tracks = [rig_clip(rig, subject.channels, n, int(spec["scale_seed"])) for n in names]
    scale = ChannelScale.fit(scale_tracks)
    train = [
        subject.source(rig_clip(rig, subject.channels, c["clip"], int(c["seed"])))
        for c in spec["train"]
    ]
    heldout_seed = int(spec["heldout_seed"])
    heldout = [
        subject.source(rig_clip(rig, subject.channels, n, heldout_seed))
        for n in _heldout_motions(spec, names)
    ]
    unlike = [
        subject.source(rig_clip(rig, subject.channels, m.name, heldout_seed))
        for m in motion_library(rig.name).test
    ]
    transitions = [
        subject.source(rig_clip(rig, subject.channels, str(n), heldout_seed))
        for n in spec.get("transitions") or ()
    ]
    return StudyData(subject, scale, train, heldout, unlike, transitions=transitions)


def _heldout_motions(spec: dict, library: list[str]) -> list[str]:
    """The motions held out: ``heldout_motions`` (library or transition motions the examples
    do not play, so the scores are not the examples replayed) or, unset, every training
    motion of the library."""
    chosen = spec.get("heldout_motions")
    if chosen is None:
        return library
    known = [*library, *(str(n) for n in spec.get("transitions") or ())]
    unknown = [str(n) for n in chosen if n not in known]
    if unknown or not chosen:
        raise TargetError(
            f"edits subject {spec['rig']!r}: heldout_motions {unknown or '[]'} are not motions "
            f"of its library or transitions (known: {known})"
        )
    return [str(n) for n in chosen]


def _skeleton_study(name: str, spec: dict) -> StudyData:
    reference = Path(spec["reference"])
    aliases = dict(spec.get("joint_aliases") or {})
    leg = tuple(aliases.get(joint, joint) for joint in BVH_LEG)
    rig = rigmap.rigs.load(spec["cm_per_unit_from_rig"])
    cm_per_unit = leg_length_cm_per_unit(rig, reference, bvh_leg=leg)
    subject = skeleton_subject(reference, cm_per_unit, name, tuple(spec["heading_joints"]))
    whole: dict[str, SkeletonClip] = {}
    for item in [*spec["train"], *({"file": f} for f in spec["heldout"])]:
        if item["file"] not in whole:
            whole[item["file"]] = read_skeleton_clip(subject, item["file"])
    scale = ChannelScale.fit([whole[item["file"]].track for item in spec["train"]])
    train = [subject.source(_file_frames(whole[c["file"]], c["frames"])) for c in spec["train"]]
    heldout = [subject.source(whole[f].track) for f in spec["heldout"]]
    unlike = [
        subject.source(skeleton_clip(subject, item["file"], item.get("play", "forward")))
        for item in spec.get("unlike") or ()
    ]
    notes = tuple(note for clip in whole.values() for note in clip.notes)
    return StudyData(subject, scale, train, heldout, unlike, notes=notes)


def _file_frames(clip: SkeletonClip, frames) -> TargetTrack:
    """The file's frames ``[start, stop)`` of a clip whose track may begin after a cut T-pose."""
    start, stop = (int(v) for v in frames)
    if start < clip.start:
        raise TargetError(
            f"{clip.track.source}: example frames {start}:{stop} include frame {clip.start - 1},"
            " an added T-pose, not motion; start them at or after it"
        )
    return clip.track.frames(start - clip.start, stop - clip.start)


def edits_for(
    catalogue: dict, names: list[str], mode: str, spec: Mapping | None = None, subject: str = ""
) -> dict[str, Edit]:
    """The named edits of the catalogue (``conf/edit/*.yaml``) for one mode, as the subject
    ``spec`` (``edits.subjects.<subject>``) has them: their joints renamed by its
    ``joint_aliases`` (skeleton mode: another BVH conversion), their walking gate at its
    ``walking_speeds_cm_s`` where it sets them (its gait's standing and walking speeds)."""
    unknown = sorted(set(names) - set(catalogue))
    if unknown:
        raise TargetError(f"edits {unknown} are not in conf/edit/ (known: {sorted(catalogue)})")
    spec = spec or {}
    aliases = {str(k): str(v) for k, v in (spec.get("joint_aliases") or {}).items()}
    edits = {
        name: Edit.from_config(name, catalogue[name], mode).on_joints(aliases) for name in names
    }
    speeds = spec.get("walking_speeds_cm_s")
    if speeds is not None:
        where = f"edits.subjects.{subject}.walking_speeds_cm_s"
        edits = {name: edit.at_walking_speeds(speeds, where) for name, edit in edits.items()}
    return edits


def model_from(data: StudyData, settings: dict) -> EditModel:
    """An unfitted edit model for the subject, as ``conf/edits`` sets it up."""
    return EditModel(
        data.subject.joints,
        weights_from(settings["weights"]),
        residual=bool(settings["residual"]),
        max_iterations=int(settings["max_iterations"]),
        gp_method=str(settings.get("gp_method", "lbfgs")),
        estimator=str(settings.get("estimator", "gp")),  # "mls": §4.4 (conf/edits/mls.yaml)
        input_scale=str(settings.get("input_scale", "global")),
    )


def fit_edit(data: StudyData, edit: Edit, settings: dict) -> tuple[EditModel, dict]:
    """Fit one edit's model on the examples; returns it and what the fit found."""
    cm, skeleton = data.subject.cm_per_unit, data.subject.skeleton
    pairs = [(source, edit.apply(source.track, cm, skeleton)) for source in data.train]
    model = model_from(data, settings)
    # §7.1 mirrors the training data; off unless the config says so (ours: the stages'
    # results so far are unmirrored)
    mirror = subject_mirror(data.subject) if settings.get("mirror", False) else None
    start = time.perf_counter()
    model.fit(pairs, data.scale, mirror=mirror)
    seconds = time.perf_counter() - start
    frames = int(sum(s.track.n_frames for s in data.train))
    info = {"fit_s": seconds, "training_frames": frames * (2 if mirror else 1)}
    for which in ("kinematic", "acceleration"):
        gp = getattr(model, f"{which}_gp_")
        info[which] = {
            "length_scale": gp.length_scale_,
            "signal": gp.signal_,
            "noise": gp.noise_,
            "iterations": gp.iterations_,
            "log_marginal_likelihood": gp.log_marginal_likelihood_,
        }
    return model, info


def weights_from(values, option: str = "edits.weights") -> Weights:
    """Weights from a mapping (Weights' field names) or a list of four, each a finite
    number >= 0; ``TargetError`` naming ``option`` and the weight otherwise."""
    names = [f.name for f in fields(Weights)]
    if isinstance(values, dict):
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise TargetError(f"{option}: unknown weight(s) {unknown}; the weights are {names}")
        given = dict(values)
    elif isinstance(values, list | tuple) and len(values) == len(names):
        given = dict(zip(names, values, strict=True))
    else:
        raise TargetError(
            f"{option}={values!r}: expected {{{', '.join(names)}}} or a list of "
            f"{len(names)} numbers"
        )
    for name, value in given.items():
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not (number and np.isfinite(value) and value >= 0):
            raise TargetError(f"{option}.{name}={value!r}: expected a finite number >= 0")
    return Weights(**{k: float(v) for k, v in given.items()})


def apply_edit(data: StudyData, model: EditModel) -> list[TargetTrack]:
    """The propagated edit on every held-out clip."""
    return [model.apply(source) for source in data.heldout]
