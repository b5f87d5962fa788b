"""Curl and wave attributes spread along a chain (tails, ears, fingers, toes).

Production rigs let animators bend a whole chain with one number: ``curl``
adds the same bend at every joint (so the chain coils), ``wave`` adds a
travelling sine along it (``amplitude``, ``phase``), ``spread`` fans chains
apart at their base. This layer gives the extra rotation for joint ``i``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from rigmap.rigs.engine.builder import Attribute, EvalContext, RigBuilder
from rigmap.rigs.engine.transforms import axis_rotation, rotation_product


@dataclass
class ChainAttributes:
    """Curl / side-curl / wave attributes and the bend axes they act on."""

    curl: Attribute
    side_curl: Attribute | None
    wave_amplitude: Attribute | None
    wave_phase: Attribute | None
    bend_axis: str = "x"
    side_axis: str = "y"
    wavelength: float = 1.0  # in chains: one full wave along the chain
    # +1 or -1: mirrored chains (left/right) bend the mirrored way for the same value
    bend_sign: float = 1.0
    side_sign: float = 1.0

    def rotation(self, ctx: EvalContext, index: int, count: int) -> torch.Tensor:
        """Extra local rotation of joint ``index`` of ``count`` (``(N, 3, 3)``)."""
        bend = self.curl(ctx) / count
        side = self.side_curl(ctx) / count if self.side_curl is not None else None
        if self.wave_amplitude is not None:
            position = 2 * math.pi * index / (count * self.wavelength)
            phase = self.wave_phase(ctx) if self.wave_phase is not None else 0.0
            wave = self.wave_amplitude(ctx) * torch.sin(position + phase)
            if side is None:
                bend = bend + wave
            else:
                side = side + wave
        if side is None:
            return axis_rotation(self.bend_sign * bend, self.bend_axis)
        return rotation_product(
            [(self.bend_sign * bend, self.bend_axis), (self.side_sign * side, self.side_axis)]
        )

    def rotations(self, ctx: EvalContext, count: int) -> torch.Tensor:
        """Every joint's :meth:`rotation` of a ``count``-joint chain at once, ``(N, count, 3,
        3)``: the same arithmetic on a ``(N, count)`` batch of angles, so equal to the
        joint-by-joint rotations to the last bit, in a few operations per chain instead of
        a few dozen per joint (without a wave, one rotation serves every joint)."""
        bend = self.curl(ctx) / count
        side = self.side_curl(ctx) / count if self.side_curl is not None else None
        if self.wave_amplitude is None:
            return self._rotation_of(bend, side)[:, None].expand(-1, count, 3, 3)
        position = ctx.const(
            [2 * math.pi * index / (count * self.wavelength) for index in range(count)]
        )
        if self.wave_phase is not None:
            position = position + self.wave_phase(ctx)[:, None]
        wave = self.wave_amplitude(ctx)[:, None] * torch.sin(position)
        if side is None:
            bend = bend[:, None] + wave
        else:
            bend, side = bend[:, None].expand_as(wave), side[:, None] + wave
        return self._rotation_of(bend, side)

    def _rotation_of(self, bend: torch.Tensor, side: torch.Tensor | None) -> torch.Tensor:
        if side is None:
            return axis_rotation(_signed(self.bend_sign, bend), self.bend_axis)
        return rotation_product(
            [
                (_signed(self.bend_sign, bend), self.bend_axis),
                (_signed(self.side_sign, side), self.side_axis),
            ]
        )


def _signed(sign: float | torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """``sign * angle``; a sign per row (the structured pass folds the left and right chains
    into one batch, :mod:`rigmap.rigs.engine.structured`) broadcasts over the chain's joints."""
    if isinstance(sign, torch.Tensor) and sign.ndim < angle.ndim:
        sign = sign.reshape(sign.shape + (1,) * (angle.ndim - sign.ndim))
    return sign * angle


def chain_attributes(
    b: RigBuilder,
    prefix: str,
    *,
    group: str,
    curl_range: tuple[float, float] = (-math.pi, math.pi),
    side_curl: bool = True,
    wave: bool = True,
    used: tuple[str, ...] = ("curl", "side_curl", "wave_amplitude", "wave_phase"),
    bend_axis: str = "x",
    side_axis: str = "y",
    bend_sign: float = 1.0,
    side_sign: float = 1.0,
) -> ChainAttributes:
    """Add ``{prefix}.curl`` (total bend in radians along the chain) and friends.

    Rest frames are world-aligned, so a rotation about y or z is mirrored between
    the left and right side: pass ``bend_sign``/``side_sign`` = -1 on one side to
    make the same attribute value bend both sides the mirrored (symmetric) way.
    """

    def attr(name, lower, upper):
        return b.attribute(
            f"{prefix}.{name}",
            default=0.0,
            lower=lower,
            upper=upper,
            used=name in used,
            group=group,
        )

    return ChainAttributes(
        curl=attr("curl", *curl_range),
        side_curl=attr("side_curl", *curl_range) if side_curl else None,
        wave_amplitude=attr("wave_amplitude", -0.6, 0.6) if wave else None,
        wave_phase=attr("wave_phase", -math.pi, math.pi) if wave else None,
        bend_axis=bend_axis,
        side_axis=side_axis,
        bend_sign=bend_sign,
        side_sign=side_sign,
    )
