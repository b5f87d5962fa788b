"""The head: FK neck, head control following the neck or the world, jaw, aimed eyes.

One unit for any character with a neck and two eyes (the biped and the dog).
Its controls:

- ``neck_{i}_fk``… one FK control per neck joint (``neck_1``… ``neck_n``);
- ``head`` with its follow blend (:func:`~.space_blend.space_blend_control`);
- ``jaw_ctrl`` (opens about X);
- ``eye_aim`` (where both eyes look, parented to the root) and one ``eye_{side}_aim``
  per eye, offset sideways from it, which the eyes aim at (:func:`~.aim.aim_joint`).

Joints: the neck, ``head``, ``head_end``, ``jaw``, ``jaw_end``, and per side
``eye_{side}`` with its pupil ``eye_end_{side}``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rigmap.rigs.engine.builder import RigBuilder
from rigmap.rigs.features.aim import aim_joint
from rigmap.rigs.features.fixed_joint import fixed_joint
from rigmap.rigs.features.fk_chain import fk_chain, fk_joint
from rigmap.rigs.features.sides import SIDES, mirror
from rigmap.rigs.features.space_blend import space_blend_control

GROUP = "head"


@dataclass(frozen=True)
class HeadSpec:
    """Rest world positions (cm) of the head's parts; eyes are given on the left side.

    ``jaw_open`` is the jaw's widest soft opening about X (radians); ``pupil`` how
    far in front of the eye its end joint sits (cm).
    """

    neck: Sequence[Sequence[float]]
    head: Sequence[float]
    head_end: Sequence[float]
    jaw: Sequence[float]
    jaw_end: Sequence[float]
    jaw_open: float
    eye_aim: Sequence[float]
    eye: Sequence[float]
    pupil: float


def head(
    b: RigBuilder,
    spec: HeadSpec,
    *,
    parent: str,
    per_side: Callable[[str, float], None] | None = None,
) -> None:
    """Add neck, head, jaw and eyes on joint ``parent`` (the top of the spine).

    ``per_side(side, sign)`` runs after each eye is built, for parts that hang on the
    head one per side (a dog's ears), so their channels sit next to that eye's.
    """
    neck = [f"neck_{i}" for i in range(1, len(spec.neck) + 1)]
    fk_chain(
        b,
        neck,
        parent=parent,
        positions=list(spec.neck),
        group=GROUP,
        used="rx ry rz",
        rotate_range=0.8,
    )
    space_blend_control(
        b,
        "head",
        parent=neck[-1],
        world_space="root",
        position=spec.head,
        group=GROUP,
        used="rx ry rz",
    )
    b.joint("head", neck[-1])
    fixed_joint(b, "head_end", parent="head", position=spec.head_end)
    opens = {"rx": (-0.1, spec.jaw_open), "ry": (-0.3, 0.3), "rz": (-0.2, 0.2)}
    fk_joint(b, "jaw", parent="head", position=spec.jaw, group=GROUP, used="rx", rotate_range=opens)
    fixed_joint(b, "jaw_end", parent="jaw", position=spec.jaw_end)
    b.transform_control(
        "eye_aim",
        parent="root",
        offset=spec.eye_aim,
        group=GROUP,
        used="tx ty tz",
        translate_range=60.0,
    )
    for side, sign in SIDES:
        _eye(b, spec, side, sign)
        if per_side is not None:
            per_side(side, sign)


def _eye(b: RigBuilder, spec: HeadSpec, side: str, sign: float) -> None:
    eye = mirror(spec.eye, sign)
    b.transform_control(
        f"eye_{side}_aim",
        parent="eye_aim",
        offset=mirror((spec.eye[0], 0, 0), sign),
        group=GROUP,
        used="",
        translate_range=10.0,
    )
    aim_joint(
        b,
        f"eye_{side}",
        f"eye_end_{side}",
        parent="head",
        target=f"eye_{side}_aim",
        position=eye,
        end_position=eye + np.array([0.0, 0.0, spec.pupil]),
    )
