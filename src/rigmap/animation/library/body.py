"""Keying a whole body: what the dog's and the human's keying helpers share.

:class:`BodyKeys` wraps a :class:`~.clip_builder.ClipBuilder` with the keys
every built-in body rig has under the same names — ``root``, ``cog``, the spline
spine's ``hips``/``chest``/``spine_mid`` — and the two conventions of their
sides: right-side controls mirror the left ones (``tx``, ``ry`` and ``rz``
change sign), so helpers take left-side values; and a polish pass keys
secondary controls on a layer that shares the clip's generator, then keeps
only the controls the motion did not animate. :class:`~.quadruped.Dog` and
:class:`~.biped.Human` add their own limbs on top.
"""

from __future__ import annotations

from collections.abc import Callable

from rigmap.animation.library.clip_builder import ClipBuilder

SIDES = {"l": 1.0, "r": -1.0}
MIRRORED_CHANNELS = ("tx", "ry", "rz")


class BodyKeys:
    """Semantic keys for root, COG and spine, and the left/right mirror of limb channels."""

    def __init__(self, b: ClipBuilder):
        self.b = b

    def _mirrored(self, name: str, side: str, channels: dict, frame, interpolation="bezier"):
        """Key ``name.channel`` for each of ``channels`` given in the left-side convention."""
        sign = SIDES[side]
        for channel, value in channels.items():
            if value is None:
                continue
            if channel in MIRRORED_CHANNELS:
                value = sign * value
            self.b.key(f"{name}.{channel}", frame, value, interpolation)

    def _hold(self, control: str, side: str, start: float, end: float, tx, ty, tz) -> None:
        """An IK control stays put from ``start`` to ``end`` (left-side ``tx``)."""
        sign = SIDES[side]
        for channel, value in (("tx", sign * tx), ("ty", ty), ("tz", tz)):
            self.b.hold(f"{control}.{channel}", start, end, value)

    def _fk_joints(self, frame, joints, side, angles, looseness: float, loose=("ry", "rz")):
        """FK rotations (rx, ry, rz) per joint, top down; below the top one the ``loose``
        channels get a seeded wobble of up to ``looseness`` radians (hand-set FK poses
        are never exactly planar)."""
        for k, (joint, (rx, ry, rz)) in enumerate(zip(joints, angles, strict=True)):
            values = {"rx": rx, "ry": ry, "rz": rz}
            if k:
                for channel in loose:
                    values[channel] = self.b.vary(values[channel], looseness)
            self._mirrored(f"{joint}_{side}_fk", side, values, frame)

    # --- body ---------------------------------------------------------------------------
    def cog(self, frame: float, interpolation: str = "bezier", **channels) -> None:
        self.b.pose(frame, {f"cog.{c}": v for c, v in channels.items()}, interpolation)

    def root(self, frame: float, interpolation: str = "bezier", **channels) -> None:
        self.b.pose(frame, {f"root.{c}": v for c, v in channels.items()}, interpolation)

    def spine(
        self,
        frame: float,
        hips=(0.0, 0.0, 0.0),
        chest=(0.0, 0.0, 0.0),
        chest_t=(0.0, 0.0, 0.0),
        mid=(0.0, 0.0, 0.0),
    ) -> None:
        values = {}
        for prefix, triple, channels in (
            ("hips", hips, ("rx", "ry", "rz")),
            ("chest", chest, ("rx", "ry", "rz")),
            ("chest", chest_t, ("tx", "ty", "tz")),
            ("spine_mid", mid, ("tx", "ty", "tz")),
        ):
            for channel, value in zip(channels, triple, strict=True):
                values[f"{prefix}.{channel}"] = value
        self.b.pose(frame, values)

    # --- the polish pass ------------------------------------------------------------------
    def _polish(self, frames, key_frame: Callable[[BodyKeys, float], None]) -> None:
        """Key secondary controls with ``key_frame(layer, frame)`` on a layer drawing from the
        clip's own generator, then keep them on ``frames`` for the controls the motion left
        alone (so a polish pass never overrides what the motion animates)."""
        animated = set(self.b.controls)
        layer = type(self)(ClipBuilder(self.b.name, self.b.rng, variation=self.b.variation))
        for frame in frames:
            key_frame(layer, frame)
        for control in layer.b.controls:
            if control not in animated:
                for frame in frames:
                    self.b.key(control, frame, layer.b.value_at(control, frame))
