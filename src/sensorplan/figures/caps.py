"""What a figure of a run can draw: shapes capped to the map's scale (numpy only).

A covariance ellipse or a field of view many orders of magnitude larger than the map (a
track never measured, with a huge initial covariance or process noise; a radar reaching
1e8 m over a 600 m map) draws little or nothing visible, yet matplotlib's renderer spends
seconds to minutes on its outline. :func:`drawable` returns the episode with every position
covariance capped so that its ellipse is at most a few map sizes across, and
:func:`drawable_scenario` the scenario with the sensors' ground ranges capped likewise; what
lies inside the map frame is drawn the same. Only drawing uses them: the recorded run and
its scenario are not changed.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from .._types import FloatArray

if TYPE_CHECKING:  # pragma: no cover
    from ..planners.problem import MapRect
    from ..simulation.run import Episode
    from ..simulation.scenario import Scenario

#: Largest standard deviation drawn, in map sizes (the larger side).
MAX_SIGMA_MAPS = 5.0
#: Largest ground range of a field of view drawn, in map diagonals (a sensor is on the map,
#: so the part of its field of view beyond one diagonal is off the map anyway).
MAX_RANGE_MAPS = 2.0


def cap_position_covariances(cov: FloatArray, max_sigma: float) -> FloatArray:
    """``cov (..., 4, 4)`` with each ground-position block's eigenvalues capped at
    ``max_sigma ** 2`` (directions kept) and non-finite entries replaced by that cap.

    Returns a new array; blocks already below the cap are returned unchanged.
    """
    out = np.array(cov, dtype=float, copy=True)
    cap = float(max_sigma) ** 2
    block = out[..., :2, :2]
    bad = ~np.all(np.isfinite(block), axis=(-2, -1))
    block[bad] = cap * np.eye(2)
    big = np.abs(block).max(axis=(-2, -1)) > cap
    if np.any(big):
        sub = 0.5 * (block[big] + np.swapaxes(block[big], -1, -2))
        vals, vecs = np.linalg.eigh(sub)
        vals = np.clip(vals, 0.0, cap)
        block[big] = (vecs * vals[..., None, :]) @ np.swapaxes(vecs, -1, -2)
    out[..., :2, :2] = block
    return out


def drawable(episode: Episode, world: MapRect) -> Episode:
    """``episode`` with its covariances capped for drawing on ``world``
    (:data:`MAX_SIGMA_MAPS` map sizes); the episode itself when nothing needs capping."""
    scale = max(float(world.width), float(world.height))
    cov = np.asarray(episode.cov)
    capped = cap_position_covariances(cov, MAX_SIGMA_MAPS * scale)
    if np.array_equal(capped, cov):
        return episode
    return dataclasses.replace(episode, cov=capped)


def drawable_scenario(scenario: Scenario) -> Scenario:
    """``scenario`` with each sensor's ground-range band capped at :data:`MAX_RANGE_MAPS`
    map diagonals (the scenario itself when nothing needs capping)."""
    limit = MAX_RANGE_MAPS * float(np.hypot(scenario.world.width, scenario.world.height))
    sensors = []
    for spec in scenario.sensors:
        p = spec.params
        g_min, g_max = float(p.min_ground_range), float(p.max_ground_range)
        if g_max <= limit:
            sensors.append(spec)
            continue
        params = dataclasses.replace(p, min_ground_range=min(g_min, limit),
                                     max_ground_range=limit)
        sensors.append(dataclasses.replace(spec, params=params))
    if all(a is b for a, b in zip(sensors, scenario.sensors)):
        return scenario
    return dataclasses.replace(scenario, sensors=tuple(sensors))
