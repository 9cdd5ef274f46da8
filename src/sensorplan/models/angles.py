"""Angle wrapping and the platform heading rule (docs/model.md, section 2)."""

from __future__ import annotations

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
