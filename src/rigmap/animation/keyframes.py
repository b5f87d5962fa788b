"""Keys and function curves: how an animator's sparse keys become a value on every frame.

An animator sets keys on a control and the DCC fills the frames in between. The
default in Maya and Blender is a cubic Bézier through the keys with *auto-clamped*
tangents: smooth like a spline, but never overshooting the keyed values, and flat
at the curve's highs and lows. The corpus (§6.1) trains on those in-between frames
too, so they must be interpolated the way an animator's tool would.

Conventions (Blender's):

* a key's ``interpolation`` governs the segment that *starts* at that key;
* handles are absolute ``(frame, value)`` points; a segment from key ``a`` to key
  ``b`` is the 2-D cubic Bézier ``a, a.out_handle, b.in_handle, b``;
* before the first key and after the last one the curve holds the end value
  (constant extrapolation), so the end keys get flat auto handles.

Auto-clamped tangent at an interior key ``i`` (neighbours ``i-1``, ``i+1``):
the slope is the Catmull-Rom (centred-difference) slope
``(v[i+1] - v[i-1]) / (t[i+1] - t[i-1])``; it is set to zero where ``v[i]`` is a
local extremum (or a neighbouring segment is flat), and its magnitude is limited to
``3 * min(|d[i-1]|, |d[i]|)`` (``d`` the secant slopes) so a handle, placed a third
of the way to its neighbour in time, never rises past the neighbour's value. With
both handles inside the segment's value range the Bézier stays inside it and is
monotone (Fritsch-Carlson's box ``α, β ≤ 3``). In- and out-handles share one slope,
so the curve is C1 at every auto key.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rigmap.errors import RigmapError

Interpolation = Literal["bezier", "linear", "constant"]
INTERPOLATIONS: tuple[str, ...] = ("bezier", "linear", "constant")
_BEZIER, _LINEAR, _CONSTANT = 0, 1, 2
_INTERPOLATION_CODE = {"bezier": _BEZIER, "linear": _LINEAR, "constant": _CONSTANT}

# A handle this close (in frames) to a third of its segment counts as "auto placed":
# the Bézier's frame coordinate is then linear in its parameter and needs no solve.
_THIRD_TOLERANCE = 1e-9
_SOLVE_ITERATIONS = 60


class KeyframeError(RigmapError, ValueError):
    """Keys that cannot make a curve; the message names the clip and control."""

    def __init__(self, message: str, *, clip: str | None = None, control: str | None = None):
        self.clip = clip
        self.control = control
        self.detail = message
        super().__init__(_locate(clip, control) + message)

    def in_clip(self, clip: str) -> KeyframeError:
        """The same error, now also naming the clip it was found in."""
        return KeyframeError(self.detail, clip=clip, control=self.control)


def _locate(clip: str | None, control: str | None) -> str:
    parts = []
    if clip is not None:
        parts.append(f"clip {clip!r}")
    if control is not None:
        parts.append(f"control {control!r}")
    return (", ".join(parts) + ": ") if parts else ""


@dataclass(frozen=True)
class Key:
    """One key: a value at a frame, and how to travel to the next key.

    ``in_handle`` / ``out_handle`` are optional explicit Bézier handles as absolute
    ``(frame, value)`` points (the in-handle at or before ``frame``, the out-handle
    at or after it); a side left ``None`` gets the auto-clamped handle.
    """

    frame: float
    value: float
    interpolation: Interpolation = "bezier"
    in_handle: tuple[float, float] | None = None
    out_handle: tuple[float, float] | None = None


KeyLike = Key | tuple[float, float]


class FCurve:
    """One control's keys, sorted by frame, evaluated at any frames (vectorised)."""

    def __init__(self, keys: Iterable[KeyLike], control: str | None = None):
        self.control = control
        keys = [k if isinstance(k, Key) else _key_from_pair(k, control) for k in keys]
        if not keys:
            raise KeyframeError("a curve needs at least one key, got none", control=control)
        order = sorted(range(len(keys)), key=lambda i: _sortable_frame(keys[i], control))
        self.keys: tuple[Key, ...] = tuple(keys[i] for i in order)
        self.frames = np.array([float(k.frame) for k in self.keys], dtype=np.float64)
        self.values = np.array([float(k.value) for k in self.keys], dtype=np.float64)
        self._check_keys()
        self._codes = np.array([_INTERPOLATION_CODE[k.interpolation] for k in self.keys])
        self.in_handles, self.out_handles = self._resolve_handles()
        self._build_segments()

    # --- construction ------------------------------------------------------
    @classmethod
    def from_pairs(
        cls,
        pairs: Iterable[tuple[float, float]],
        interpolation: Interpolation = "bezier",
        control: str | None = None,
    ) -> FCurve:
        """A curve from ``(frame, value)`` pairs, all with one interpolation."""
        return cls([Key(f, v, interpolation) for f, v in pairs], control=control)

    def _error(self, message: str) -> KeyframeError:
        """A key check's error, naming this curve's control."""
        return KeyframeError(message, control=self.control)

    def _check_keys(self) -> None:
        for key in self.keys:
            if key.interpolation not in INTERPOLATIONS:
                raise self._error(
                    f"key at frame {key.frame}: interpolation {key.interpolation!r} is not one "
                    f"of {INTERPOLATIONS}",
                )
        bad_frame = ~np.isfinite(self.frames)
        if bad_frame.any():
            raise self._error(
                f"key frame must be a finite number, got {self.frames[bad_frame][0]} "
                f"(value {self.values[bad_frame][0]})",
            )
        bad_value = ~np.isfinite(self.values)
        if bad_value.any():
            i = int(np.flatnonzero(bad_value)[0])
            raise self._error(
                f"key at frame {self.frames[i]:g} has value {self.values[i]}; keys must be "
                "finite numbers",
            )
        same = np.flatnonzero(np.diff(self.frames) == 0.0)
        if same.size:
            i = int(same[0])
            raise self._error(
                f"two keys at frame {self.frames[i]:g} (values {self.values[i]:g} and "
                f"{self.values[i + 1]:g}); one key per frame is allowed",
            )
        for key in self.keys:
            for side, handle in (("in", key.in_handle), ("out", key.out_handle)):
                if handle is None:
                    continue
                h = np.asarray(handle, dtype=np.float64)
                if h.shape != (2,) or not np.isfinite(h).all():
                    raise self._error(
                        f"key at frame {key.frame:g}: {side}_handle must be a finite "
                        f"(frame, value) pair, got {handle!r}",
                    )
                wrong_side = h[0] > key.frame if side == "in" else h[0] < key.frame
                if wrong_side:
                    where = "at or before" if side == "in" else "at or after"
                    raise self._error(
                        f"key at frame {key.frame:g}: {side}_handle frame {h[0]:g} must be "
                        f"{where} the key",
                    )

    def _resolve_handles(self) -> tuple[np.ndarray, np.ndarray]:
        """Absolute (K, 2) in- and out-handles: explicit where given, else auto-clamped."""
        t, v = self.frames, self.values
        slope = auto_clamped_slopes(t, v)
        gap_before = np.concatenate([[0.0], np.diff(t)])
        gap_after = np.concatenate([np.diff(t), [0.0]])
        in_handles = np.stack([t - gap_before / 3, v - slope * gap_before / 3], axis=1)
        out_handles = np.stack([t + gap_after / 3, v + slope * gap_after / 3], axis=1)
        for i, key in enumerate(self.keys):
            if key.in_handle is not None:
                in_handles[i] = key.in_handle
            if key.out_handle is not None:
                out_handles[i] = key.out_handle
        return in_handles, out_handles

    def _build_segments(self) -> None:
        """Per-segment power-basis coefficients of the 2-D Bézier, x and y."""
        t, v = self.frames, self.values
        if len(t) < 2:
            self._x_coeffs = self._y_coeffs = np.zeros((0, 4))
            self._x_is_linear = np.zeros(0, dtype=bool)
            return
        p0 = np.stack([t[:-1], v[:-1]], axis=1)
        p3 = np.stack([t[1:], v[1:]], axis=1)
        p1 = self.out_handles[:-1].copy()
        p2 = self.in_handles[1:].copy()
        # Handles reaching past each other in time would fold the curve back on itself
        # (two values at one frame); shrink both proportionally, as Blender does.
        span = p3[:, 0] - p0[:, 0]
        reach = (p1[:, 0] - p0[:, 0]) + (p3[:, 0] - p2[:, 0])
        too_long = reach > span
        if too_long.any():
            scale = np.where(too_long, span / np.where(too_long, reach, 1.0), 1.0)[:, None]
            p1 = p0 + (p1 - p0) * scale
            p2 = p3 + (p2 - p3) * scale
        # Bernstein -> power basis: B(s) = c0 + c1 s + c2 s^2 + c3 s^3.
        c0 = p0
        c1 = 3 * (p1 - p0)
        c2 = 3 * (p2 - 2 * p1 + p0)
        c3 = p3 - 3 * p2 + 3 * p1 - p0
        coeffs = np.stack([c0, c1, c2, c3], axis=1)  # (S, 4, 2)
        self._x_coeffs = coeffs[:, :, 0]
        self._y_coeffs = coeffs[:, :, 1]
        third = span / 3
        self._x_is_linear = (np.abs(p1[:, 0] - p0[:, 0] - third) <= _THIRD_TOLERANCE) & (
            np.abs(p3[:, 0] - p2[:, 0] - third) <= _THIRD_TOLERANCE
        )

    # --- queries -----------------------------------------------------------
    def __len__(self) -> int:
        return len(self.keys)

    def __repr__(self) -> str:
        name = f"{self.control!r}, " if self.control is not None else ""
        return f"FCurve({name}{len(self)} keys, frames {self.first_frame:g}..{self.last_frame:g})"

    @property
    def first_frame(self) -> float:
        return float(self.frames[0])

    @property
    def last_frame(self) -> float:
        return float(self.frames[-1])

    @property
    def interpolations(self) -> tuple[str, ...]:
        return tuple(k.interpolation for k in self.keys)

    def evaluate(self, frames):
        """Values at ``frames`` (any shape, fractional allowed); a float for a scalar."""
        return self._evaluate(frames, derivative=False)

    def slope(self, frames):
        """d value / d frame at ``frames``, from the segment starting at or before each frame.

        At a key this is the right-hand slope; held regions (extrapolation, stepped
        segments) have slope 0.
        """
        return self._evaluate(frames, derivative=True)

    def retimed(self, factor: float, control: str | None = None) -> FCurve:
        """The same curve with every frame (keys and handles) multiplied by ``factor``."""
        if not (np.isfinite(factor) and factor > 0):
            raise ValueError(f"retime factor must be a positive number, got {factor!r}")
        keys = []
        for i, key in enumerate(self.keys):
            keys.append(
                Key(
                    key.frame * factor,
                    key.value,
                    key.interpolation,
                    None if key.in_handle is None else _scaled(self.in_handles[i], factor),
                    None if key.out_handle is None else _scaled(self.out_handles[i], factor),
                )
            )
        return FCurve(keys, control=self.control if control is None else control)

    def _evaluate(self, frames, derivative: bool):
        t = np.asarray(frames, dtype=np.float64)
        scalar = t.ndim == 0
        t = np.atleast_1d(t)
        if not np.isfinite(t).all():
            raise ValueError(f"{_locate(None, self.control)}frames to evaluate must be finite")
        flat = t.ravel()
        out = np.zeros_like(flat) if derivative else np.empty_like(flat)
        keys_t, keys_v = self.frames, self.values
        if not derivative:
            out[flat <= keys_t[0]] = keys_v[0]
            out[flat >= keys_t[-1]] = keys_v[-1]
        inside = np.flatnonzero((flat > keys_t[0]) & (flat < keys_t[-1]))
        if inside.size:
            x = flat[inside]
            seg = np.searchsorted(keys_t, x, side="right") - 1
            out[inside] = self._inside(x, seg, derivative)
        # a frame exactly on a key starts that key's segment (stepped keys change there)
        if derivative:
            on_key = np.flatnonzero(np.isin(flat, keys_t[:-1]))
            if on_key.size:
                seg = np.searchsorted(keys_t, flat[on_key], side="right") - 1
                out[on_key] = self._inside(flat[on_key], seg, derivative=True)
        result = out.reshape(t.shape)
        return float(result[0]) if scalar else result

    def _inside(self, x: np.ndarray, seg: np.ndarray, derivative: bool) -> np.ndarray:
        t0, t1 = self.frames[seg], self.frames[seg + 1]
        v0, v1 = self.values[seg], self.values[seg + 1]
        code = self._codes[seg]
        u = (x - t0) / (t1 - t0)
        result = np.empty_like(x)

        stepped = code == _CONSTANT
        result[stepped] = 0.0 if derivative else v0[stepped]
        linear = code == _LINEAR
        if derivative:
            result[linear] = ((v1 - v0) / (t1 - t0))[linear]
        else:
            result[linear] = (v0 + u * (v1 - v0))[linear]

        bezier = np.flatnonzero(code == _BEZIER)
        if bezier.size:
            b_seg = seg[bezier]
            s = u[bezier].copy()
            needs_solve = ~self._x_is_linear[b_seg]
            if needs_solve.any():
                s[needs_solve] = _solve_bezier_parameter(
                    self._x_coeffs[b_seg[needs_solve]], x[bezier][needs_solve]
                )
            y = self._y_coeffs[b_seg]
            if derivative:
                xc = self._x_coeffs[b_seg]
                dy = y[:, 1] + s * (2 * y[:, 2] + s * 3 * y[:, 3])
                dx = xc[:, 1] + s * (2 * xc[:, 2] + s * 3 * xc[:, 3])
                with np.errstate(divide="ignore", invalid="ignore"):
                    result[bezier] = np.where(dx > 0, dy / dx, 0.0)
            else:
                result[bezier] = y[:, 0] + s * (y[:, 1] + s * (y[:, 2] + s * y[:, 3]))
        return result


def auto_clamped_slopes(frames: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Auto-clamped tangent slopes (value per frame) at sorted keys; see the module doc."""
    frames = np.asarray(frames, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    slopes = np.zeros_like(values)
    if len(values) < 3:
        return slopes  # end keys are flat: constant extrapolation on both sides
    secant = np.diff(values) / np.diff(frames)
    before, after = secant[:-1], secant[1:]
    centred = (values[2:] - values[:-2]) / (frames[2:] - frames[:-2])
    limit = 3.0 * np.minimum(np.abs(before), np.abs(after))
    clamped = np.sign(centred) * np.minimum(np.abs(centred), limit)
    extremum = before * after <= 0.0
    slopes[1:-1] = np.where(extremum, 0.0, clamped)
    return slopes


def _solve_bezier_parameter(x_coeffs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Bézier parameter s in [0, 1] with X(s) = x, for monotone X (Newton + bisection)."""
    lo = np.zeros_like(x)
    hi = np.ones_like(x)
    span = x_coeffs.sum(axis=1) - x_coeffs[:, 0]
    s = (x - x_coeffs[:, 0]) / span
    tolerance = 1e-12 * np.maximum(1.0, np.abs(x))
    for _ in range(_SOLVE_ITERATIONS):
        c0, c1, c2, c3 = x_coeffs.T
        residual = c0 + s * (c1 + s * (c2 + s * c3)) - x
        if (np.abs(residual) <= tolerance).all():
            break
        lo = np.where(residual < 0, s, lo)
        hi = np.where(residual > 0, s, hi)
        dxds = c1 + s * (2 * c2 + s * 3 * c3)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = s - residual / dxds
        ok = (dxds > 0) & (newton > lo) & (newton < hi)
        s = np.where(ok, newton, 0.5 * (lo + hi))
    return s


def _key_from_pair(pair: Sequence[float], control: str | None) -> Key:
    try:
        frame, value = pair
    except (TypeError, ValueError):
        raise KeyframeError(
            f"a key must be a Key or a (frame, value) pair, got {pair!r}", control=control
        ) from None
    return Key(frame, value)


def _sortable_frame(key: Key, control: str | None) -> float:
    """NaN frames sort last so the finiteness check can report them."""
    try:
        frame = float(key.frame)
        float(key.value)
    except (TypeError, ValueError):
        raise KeyframeError(
            f"a key's frame and value must be numbers, got frame {key.frame!r}, "
            f"value {key.value!r}",
            control=control,
        ) from None
    return frame if np.isfinite(frame) else np.inf


def _scaled(handle: np.ndarray, factor: float) -> tuple[float, float]:
    return (float(handle[0] * factor), float(handle[1]))
