"""Angle wrapping and the platform heading rule (docs/model.md, section 2)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .._types import FloatArray

TWO_PI = 2.0 * np.pi


def wrap_angle(a: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi].

    Examples
    --------
    >>> float(wrap_angle(-np.pi)), float(wrap_angle(3 * np.pi / 2))
    (3.141592653589793, -1.5707963267948966)
    """
    # pi - mod(pi - a, 2 pi) lands in (-pi, pi] in exact arithmetic; in floating point the
    # mod can round up to exactly 2 pi (a just above pi), giving -pi: fold that back.
    w = np.pi - np.mod(np.pi - np.asarray(a, dtype=float), TWO_PI)
    return np.where(w <= -np.pi, w + TWO_PI, w)


def heading_rule(theta: ArrayLike, bearing: ArrayLike, max_turn: ArrayLike) -> FloatArray:
    """Turn from ``theta`` toward ``bearing`` by at most ``max_turn`` (radians).

    .. math:: \\theta' = \\mathrm{wrap}(\\theta + \\mathrm{clip}(\\mathrm{wrap}(b - \\theta),
              -m, m))
    """
    theta = np.asarray(theta, dtype=float)
    max_turn = np.asarray(max_turn, dtype=float)
    turn = np.clip(wrap_angle(np.asarray(bearing, dtype=float) - theta), -max_turn, max_turn)
    return wrap_angle(theta + turn)


def wrap_scalar(a: float) -> float:
    """:func:`wrap_angle` of one float in plain Python, bit for bit (Python's float ``%`` is
    numpy's ``mod``: the C ``fmod`` moved to the divisor's sign)."""
    w = math.pi - (math.pi - a) % TWO_PI
    return w + TWO_PI if w <= -math.pi else w


def heading_rule_scalar(theta: float, bearing: float, max_turn: float) -> float:
    """:func:`heading_rule` of floats in plain Python, bit for bit (``np.clip``'s order of
    comparisons), for loops over single looks."""
    turn = wrap_scalar(bearing - theta)
    turn = turn if turn > -max_turn else -max_turn
    turn = turn if turn < max_turn else max_turn
    return wrap_scalar(theta + turn)
