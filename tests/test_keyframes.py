"""Keys and curves: auto-clamped Bézier, linear and stepped, explicit handles, bad keys."""

import numpy as np
import pytest

from rigmap.animation import FCurve, Key, KeyframeError, auto_clamped_slopes

# A curve an animator might key on a spine rotation (radians): rise, a plateau-ish
# shoulder (small step), a peak, a dip, settle.
FRAMES = [0.0, 10.0, 14.0, 30.0, 41.0, 60.0]
VALUES = [0.0, 0.8, 0.85, 1.3, -0.4, 0.1]


def keyed(frames=FRAMES, values=VALUES, interpolation="bezier"):
    return FCurve.from_pairs(zip(frames, values, strict=True), interpolation, control="spine.rz")


def test_auto_clamped_bezier_passes_through_every_key():
    curve = keyed()
    np.testing.assert_allclose(curve.evaluate(FRAMES), VALUES, atol=1e-12)


def test_constant_extrapolation_outside_the_keys():
    curve = keyed()
    assert curve.evaluate(-25.0) == pytest.approx(0.0)
    assert curve.evaluate(1000.0) == pytest.approx(0.1)
    assert curve.slope(-3.0) == 0.0
    assert curve.slope(70.0) == 0.0


def test_no_overshoot_monotone_between_monotone_keys():
    # Steep then nearly flat: a Catmull-Rom tangent would overshoot 0.85 after frame 10.
    curve = keyed()
    t = np.linspace(0, 60, 6001)
    y = curve.evaluate(t)
    for (t0, v0), (t1, v1) in zip(
        zip(FRAMES, VALUES, strict=True), zip(FRAMES[1:], VALUES[1:], strict=True), strict=False
    ):
        inside = (t >= t0) & (t <= t1)
        segment = y[inside]
        lo, hi = min(v0, v1), max(v0, v1)
        assert segment.min() >= lo - 1e-12 and segment.max() <= hi + 1e-12, (t0, t1)
        steps = np.diff(segment) * np.sign(v1 - v0)
        assert steps.min() >= -1e-12, f"not monotone between frames {t0} and {t1}"


def test_unclamped_catmull_rom_would_overshoot_here():
    # The clamp matters on this data: the centred slope at frame 10 is 0.85/14 per frame,
    # but 3 * the secant slope after it (0.05/4 per frame) is smaller.
    centred = (0.85 - 0.0) / 14.0
    limit = 3 * (0.85 - 0.8) / 4.0
    assert centred > limit
    slopes = auto_clamped_slopes(np.array(FRAMES), np.array(VALUES))
    assert slopes[1] == pytest.approx(limit)


def test_zero_slope_at_extrema_and_end_keys():
    curve = keyed()
    slopes = auto_clamped_slopes(np.array(FRAMES), np.array(VALUES))
    # frame 30 is a peak (1.3), frame 41 a dip (-0.4); the ends are flat
    assert slopes[[0, 3, 4, 5]].tolist() == [0.0, 0.0, 0.0, 0.0]
    h = 1e-6
    for frame in (30.0, 41.0):
        left = (curve.evaluate(frame) - curve.evaluate(frame - h)) / h
        right = (curve.evaluate(frame + h) - curve.evaluate(frame)) / h
        assert abs(left) < 1e-5 and abs(right) < 1e-5
    # and the peak really is the curve's maximum
    t = np.linspace(0, 60, 6001)
    assert curve.evaluate(t).max() == pytest.approx(1.3, abs=1e-12)


def test_c1_at_unclamped_interior_key():
    # keys 0 -> 1 -> 3 -> 3.5: the tangent at frame 10 is the centred slope, unclamped
    curve = FCurve.from_pairs([(0, 0.0), (10, 1.0), (20, 3.0), (30, 3.5)])
    centred = (3.0 - 0.0) / 20.0
    assert centred < 3 * min(1.0 / 10, 2.0 / 10)
    h = 1e-5
    left = (curve.evaluate(10.0) - curve.evaluate(10.0 - h)) / h
    right = (curve.evaluate(10.0 + h) - curve.evaluate(10.0)) / h
    assert left == pytest.approx(centred, rel=1e-4)
    assert right == pytest.approx(centred, rel=1e-4)
    assert curve.slope(10.0) == pytest.approx(centred, rel=1e-12)


def test_bezier_midpoint_matches_hand_computed_value():
    # Two keys, flat ends: the segment is smoothstep 3u^2 - 2u^3 scaled to the values.
    curve = FCurve.from_pairs([(0, 2.0), (12, 5.0)])
    u = np.array([0.25, 0.5, 0.75])
    np.testing.assert_allclose(curve.evaluate(12 * u), 2.0 + 3.0 * (3 * u**2 - 2 * u**3))


def test_linear_exact_values():
    curve = keyed(interpolation="linear")
    assert curve.evaluate(5.0) == pytest.approx(0.4)
    assert curve.evaluate(12.0) == pytest.approx(0.825)
    assert curve.evaluate(35.5) == pytest.approx(1.3 + (-1.7) * 5.5 / 11)
    assert curve.slope(20.0) == pytest.approx(0.45 / 16)


def test_stepped_holds_until_the_next_key():
    curve = keyed(interpolation="constant")
    values = curve.evaluate([0, 9.999, 10, 13.5, 14, 29, 30, 59.9, 60, 61])
    np.testing.assert_array_equal(values, [0, 0, 0.8, 0.8, 0.85, 0.85, 1.3, -0.4, 0.1, 0.1])


def test_interpolation_belongs_to_the_segment_after_the_key():
    curve = FCurve(
        [Key(0, 0.0, "constant"), Key(10, 1.0, "linear"), Key(20, 3.0, "bezier"), Key(30, 2.0)]
    )
    assert curve.evaluate(5.0) == 0.0
    assert curve.evaluate(15.0) == pytest.approx(2.0)
    between = curve.evaluate(np.linspace(20, 30, 101))
    assert between.max() <= 3.0 + 1e-12 and between.min() >= 2.0 - 1e-12


def test_keys_given_out_of_order_are_sorted():
    shuffled = FCurve.from_pairs(
        [(30, 1.3), (0, 0.0), (14, 0.85), (60, 0.1), (10, 0.8), (41, -0.4)]
    )
    t = np.linspace(-5, 65, 141)
    np.testing.assert_array_equal(shuffled.evaluate(t), keyed().evaluate(t))
    assert shuffled.frames.tolist() == FRAMES


def test_evaluate_keeps_shape_and_scalars():
    curve = keyed()
    grid = np.arange(12, dtype=float).reshape(3, 4)
    assert curve.evaluate(grid).shape == (3, 4)
    assert isinstance(curve.evaluate(3), float)


def test_explicit_third_handles_reproduce_the_auto_curve():
    auto = keyed()
    explicit = FCurve(
        [
            Key(f, v, "bezier", tuple(auto.in_handles[i]), tuple(auto.out_handles[i]))
            for i, (f, v) in enumerate(zip(FRAMES, VALUES, strict=True))
        ]
    )
    t = np.linspace(0, 60, 301)
    np.testing.assert_allclose(explicit.evaluate(t), auto.evaluate(t), atol=1e-12)


def test_explicit_handles_not_at_thirds_are_solved_in_frame():
    # Long out-handle, short in-handle: x(s) is non-linear in s; check against a dense
    # sampling of the 2-D Bézier itself.
    p0, p1, p2, p3 = map(np.array, ([0.0, 0.0], [8.0, 3.0], [9.0, 2.0], [10.0, 1.0]))
    curve = FCurve([Key(0, 0.0, out_handle=tuple(p1)), Key(10, 1.0, in_handle=tuple(p2))])
    s = np.linspace(0, 1, 20001)[:, None]
    points = (1 - s) ** 3 * p0 + 3 * (1 - s) ** 2 * s * p1 + 3 * (1 - s) * s**2 * p2 + s**3 * p3
    frames = np.array([0.5, 2.0, 5.0, 7.5, 9.0, 9.9])
    expected = np.interp(frames, points[:, 0], points[:, 1])
    np.testing.assert_allclose(curve.evaluate(frames), expected, atol=1e-6)
    assert curve.evaluate(9.0) > 1.3  # the long handle lifts the curve well above the end key


def test_overlapping_handles_are_shortened_not_folded():
    # Handles reaching 9 frames into a 10-frame segment from both ends would fold the
    # curve (two values per frame); both are scaled by 10/18 towards their keys.
    curve = FCurve([Key(0, 0.0, out_handle=(9.0, 2.0)), Key(10, 1.0, in_handle=(1.0, -1.0))])
    scale = 10 / 18
    p0, p3 = np.array([0.0, 0.0]), np.array([10.0, 1.0])
    p1 = p0 + scale * (np.array([9.0, 2.0]) - p0)
    p2 = p3 + scale * (np.array([1.0, -1.0]) - p3)
    s = np.linspace(0, 1, 20001)[:, None]
    points = (1 - s) ** 3 * p0 + 3 * (1 - s) ** 2 * s * p1 + 3 * (1 - s) * s**2 * p2 + s**3 * p3
    assert (np.diff(points[:, 0]) >= 0).all()  # the shortened curve is a function of frame
    frames = np.linspace(0.25, 9.75, 20)
    expected = np.interp(frames, points[:, 0], points[:, 1])
    np.testing.assert_allclose(curve.evaluate(frames), expected, atol=1e-6)


def test_single_key_is_constant():
    curve = FCurve([Key(7, 0.25)])
    np.testing.assert_array_equal(curve.evaluate([-1, 7, 100]), [0.25, 0.25, 0.25])


def test_retimed_keeps_time_in_seconds():
    at24 = keyed()
    at30 = at24.retimed(30 / 24)
    seconds = np.linspace(0, 2.5, 51)
    np.testing.assert_allclose(at30.evaluate(seconds * 30), at24.evaluate(seconds * 24), atol=1e-12)


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ([Key(0, 0.0), Key(5, float("nan"))], "frame 5 has value nan"),
        ([Key(0, 0.0), Key(float("nan"), 1.0)], "finite number, got nan"),
        ([Key(0, 0.0), Key(5, 1.0), Key(5, 2.0)], "two keys at frame 5"),
        ([Key(0, 0.0, "cubic")], "interpolation 'cubic'"),
        ([Key(0, 0.0, in_handle=(3.0, 1.0))], "in_handle frame 3 must be at or before"),
        ([], "at least one key"),
    ],
)
def test_bad_keys_name_the_control(keys, message):
    with pytest.raises(KeyframeError, match=r"control 'spine\.rz'") as caught:
        FCurve(keys, control="spine.rz")
    assert message in str(caught.value)
    assert caught.value.control == "spine.rz"


def test_random_curves_never_overshoot_and_stay_c1():
    rng = np.random.default_rng(2017)
    for _ in range(40):
        n = int(rng.integers(3, 12))
        frames = np.cumsum(rng.uniform(0.5, 20.0, n))
        values = rng.normal(0.0, 1.0, n) * rng.choice([1.0, 0.01], n)  # big and tiny steps
        curve = FCurve.from_pairs(zip(frames, values, strict=True))
        for i in range(n - 1):
            t = np.linspace(frames[i], frames[i + 1], 200)
            y = curve.evaluate(t)
            lo, hi = sorted((values[i], values[i + 1]))
            assert y.min() >= lo - 1e-12 and y.max() <= hi + 1e-12
            assert (np.diff(y) * np.sign(values[i + 1] - values[i])).min() >= -1e-12
        # one tangent per key: the slope arriving equals the slope leaving
        h = 1e-6 * np.diff(frames).min()
        inner = frames[1:-1]
        left = (curve.evaluate(inner) - curve.evaluate(inner - h)) / h
        np.testing.assert_allclose(left, curve.slope(inner), atol=1e-4 * np.abs(values).max())
