"""Held-out motion with walk ↔ stand transitions, for Fig 6's "in between" (ours).

Fig 6 of the paper shows an edit that puts the arms out while walking and down while
standing, and the result in between during transitions. The biped's motion library has
no such frames: its walk keeps one speed from the first frame to the last and no other
clip moves the root (root speed 0 or 70–75 cm/s, nothing between 10 and 40 cm/s), and a
new seed only varies the step, the tempo and the heading. So the edit study gets its
transitions here, outside the library (whose train and test splits feed every other
experiment and stay as they are): "Walk Start Stop" stands, starts walking, walks,
slows down and stands again — the library walk's keys (``rigmap.animation.library.biped``:
the same cycle of strikes, toe-offs and passing poses, arm swing, body bob and sway) with
every amplitude and the root's speed scaled by one speed profile ``s(t)``: 0 for the
first and last second, smoothstep ramps over 1.5 cycles, 1 for 1.5 cycles between.
Seeded like a library clip (:func:`rigmap.animation.library.clip_rng` by its name).
"""

from __future__ import annotations

import math

import numpy as np

from rigmap.animation.library import Motion
from rigmap.animation.library.biped import Human
from rigmap.animation.library.clip_builder import ClipBuilder

STAND, RAMP, CRUISE = 24.0, 45.0, 45.0  # nominal frames at 24 fps: 1 s, 1.5 cycles each
PERIOD, GRID = 30.0, 3.0  # the library walk's cycle and root key spacing


def speed_profile(t, end: float):
    """``s(t)``: 0 standing, 1 walking at full speed, smoothstep ramps between."""
    t = np.asarray(t, dtype=np.float64)
    up = np.clip((t - STAND) / RAMP, 0.0, 1.0)
    down = np.clip((end - STAND - t) / RAMP, 0.0, 1.0)
    u = np.minimum(up, down)
    return u * u * (3.0 - 2.0 * u)


def walk_start_stop(b: ClipBuilder) -> None:
    """Stand, start walking, walk, stop, stand (module docstring)."""
    h = Human(b)
    end = 2 * STAND + 2 * RAMP + CRUISE
    step = b.vary(44.0, 3.0)
    reach = 0.3 * step
    speed = 2 * step / PERIOD  # cm per frame at full speed, as the library walk
    heading = b.vary(0.0, 0.3)
    times = np.arange(0.0, end + 1e-9, GRID)
    # the root's distance: the speed profile integrated (trapezoids on the key grid)
    rates = speed * speed_profile(times, end)
    distance = np.concatenate([[0.0], np.cumsum(0.5 * (rates[1:] + rates[:-1]) * GRID)])
    distance -= 0.5 * distance[-1]
    for t, d in zip(times, distance, strict=True):
        interpolation = "linear" if 0 < t < end else "bezier"
        h.root(
            float(t), interpolation, tx=d * math.sin(heading), tz=d * math.cos(heading), ry=heading
        )

    def s(t: float) -> float:
        return float(speed_profile(t, end))

    height = b.vary(12.0, 2.0)
    swing_arm = b.vary(0.25, 0.06)
    strike_roll, toe_off_roll = b.vary(-0.3, 0.05), b.vary(0.9, 0.1)
    cycles = math.ceil(end / PERIOD)
    for side, phase in {"l": 0.0, "r": PERIOD / 2}.items():
        h.walk_steps(
            side,
            phase,
            PERIOD,
            GRID,
            cycles,
            end,
            reach=reach,
            height=height,
            strike_roll=lambda: strike_roll,
            toe_off_roll=lambda: toe_off_roll,
            scale=s,
        )
        # this side's arm swings forward as the other leg strikes
        h.walk_arm_swing(side, phase, PERIOD, cycles, end, swing_arm, scale=s)
    h.relaxed_hands(end)
    _torso_keys(b, h, end, s)


def _torso_keys(b: ClipBuilder, h: Human, end: float, s) -> None:
    """COG bob and sway, hips and chest counter-turn, head: every quarter cycle, scaled by
    the speed profile ``s(t)``."""
    for k, t in enumerate(np.arange(0.0, end + 1e-9, 7.5)):
        t, w = float(t), s(float(t))
        phase = k % 4  # 0: left strike, 2: right strike
        stance = 1.0 if phase in (0, 1) else -1.0
        turn = 1 if phase == 0 else -1 if phase == 2 else 0
        h.cog(
            t,
            ty=-1.0 - w * (2.0 + (1.5 if phase % 2 == 0 else 0.0)),
            tx=1.5 * stance * w,
            tz=0.0,
            ry=0.0,
        )
        h.spine(
            t,
            hips=(0.02 * w, 0.12 * turn * w, -0.05 * stance * w),
            chest=(0.05 * w, -0.1 * turn * w, 0.02 * stance * w),
        )
        h.head(t, rx=0.05 * w, ry=b.vary(0.0, 0.1))


#: per rig, the transition motions the edit study can hold out (``transitions:`` in
#: conf/edits/default.yaml)
TRANSITION_MOTIONS: dict[str, dict[str, Motion]] = {
    "biped": {
        "Walk Start Stop": Motion(
            "Walk Start Stop",
            walk_start_stop,
            "stands, starts walking, walks, slows to a stop and stands (ours, Fig 6)",
        )
    }
}
