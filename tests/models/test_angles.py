"""wrap_angle and the heading rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.models.angles import heading_rule, wrap_angle

TWO_PI = 2 * math.pi
angles = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)
small_angles = st.floats(min_value=-20.0, max_value=20.0, allow_nan=False)
turns = st.floats(min_value=0.0, max_value=math.pi, allow_nan=False)


def ang_dist(a: float, b: float) -> float:
    """Distance between two angles on the circle, in [0, pi], computed without wrap_angle."""
    d = math.fmod(abs(a - b), TWO_PI)
    return min(d, TWO_PI - d)


@settings(max_examples=300, deadline=None)
@given(angles)
def test_wrap_lands_in_half_open_interval_and_keeps_the_angle(a):
    w = float(wrap_angle(a))
    assert -math.pi < w <= math.pi
    # Same direction: differs from a by a whole number of turns (rounding scales with |a|).
    assert ang_dist(w, a) <= 4e-15 * max(1.0, abs(a))


def test_wrap_special_values():
    assert float(wrap_angle(math.pi)) == math.pi
    assert float(wrap_angle(-math.pi)) == math.pi
    assert float(wrap_angle(3 * math.pi)) == pytest.approx(math.pi, abs=1e-15)
    assert float(wrap_angle(0.0)) == 0.0
    np.testing.assert_allclose(wrap_angle([3 * math.pi / 2, -3 * math.pi / 2, TWO_PI, 7.0]),
                               [-math.pi / 2, math.pi / 2, 0.0, 7.0 - TWO_PI], atol=1e-15)


def test_wrap_just_above_pi_is_not_minus_pi():
    # np.mod(pi - a, 2 pi) can round up to exactly 2 pi for a just above pi (or 3 pi, ...),
    # which a naive pi - mod(pi - a, 2 pi) turns into -pi.
    for a in (np.nextafter(math.pi, 4.0), np.nextafter(3 * math.pi, 10.0),
              np.nextafter(-math.pi, 0.0)):
        w = float(wrap_angle(a))
        assert -math.pi < w <= math.pi
        assert ang_dist(w, a) <= 1e-15
    w = wrap_angle(np.array([np.nextafter(math.pi, 4.0), -math.pi, math.pi]))
    assert np.all(w > -math.pi)


def test_wrap_batched_shape():
    a = np.linspace(-20, 20, 24).reshape(2, 3, 4)
    w = wrap_angle(a)
    assert w.shape == a.shape
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-13)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-13)


@settings(max_examples=300, deadline=None)
@given(small_angles, small_angles, turns)
def test_heading_rule_turns_at_most_max_turn_toward_bearing(theta, bearing, max_turn):
    new = float(heading_rule(theta, bearing, max_turn))
    assert -math.pi < new <= math.pi
    before = ang_dist(theta, bearing)
    turned = ang_dist(new, theta)
    assert turned <= max_turn + 1e-12
    if before <= max_turn:
        assert ang_dist(new, bearing) <= 1e-12            # reaches the bearing
    else:
        # Turns the full max_turn, the short way: the gap to the bearing shrinks by max_turn
        # (for a bearing exactly behind, either way is short).
        assert turned == pytest.approx(max_turn, abs=1e-12)
        assert ang_dist(new, bearing) == pytest.approx(before - max_turn, abs=1e-12)


def test_heading_rule_across_the_wrap_turns_the_short_way():
    # theta = 3.0, bearing = -3.0: the short way is +0.283 rad through pi, not -6 rad.
    gap = TWO_PI - 6.0
    assert float(heading_rule(3.0, -3.0, math.pi / 4)) == pytest.approx(-3.0, abs=1e-12)
    assert float(heading_rule(3.0, -3.0, 0.1)) == pytest.approx(3.1, abs=1e-12)
    assert float(heading_rule(-3.0, 3.0, 0.1)) == pytest.approx(-3.1, abs=1e-12)
    # A turn of exactly the gap lands on the bearing (wrapped to -3.0).
    assert float(heading_rule(3.0, -3.0, gap)) == pytest.approx(-3.0, abs=1e-12)
    # Crossing pi from 3.1 by +0.1 wraps to -pi + 0.058...
    assert float(heading_rule(3.1, -3.0, 0.1)) == pytest.approx(3.2 - TWO_PI, abs=1e-12)


def test_heading_rule_closed_forms():
    assert float(heading_rule(0.0, 1.0, math.pi / 4)) == pytest.approx(math.pi / 4)
    assert float(heading_rule(0.0, -1.0, math.pi / 4)) == pytest.approx(-math.pi / 4)
    assert float(heading_rule(0.0, 0.5, math.pi / 4)) == pytest.approx(0.5)
    assert float(heading_rule(1.0, 1.0, 0.0)) == pytest.approx(1.0)
    assert float(heading_rule(0.3, 2.0, 0.0)) == pytest.approx(0.3)       # max_turn = 0


def test_heading_rule_broadcasts():
    theta = np.array([[0.0], [3.0]])
    bearing = np.array([1.0, -3.0, 0.1])
    max_turn = np.array([0.5, 0.5, 0.05])
    out = heading_rule(theta, bearing, max_turn)
    assert out.shape == (2, 3)
    for r in range(2):
        for c in range(3):
            assert out[r, c] == pytest.approx(
                float(heading_rule(theta[r, 0], bearing[c], max_turn[c])), abs=0)
