r"""Missed detections and false alarms of the radar, in Stone Soup's terms.

The radar model decides everything here (:mod:`sensorplan.models.radar`): the detection
probability of a target in view (``radar.detection_probabilities``), where false alarms
fall (``radar.clutter_points``: uniform in ground area over the look's sensing region) and
how they are measured (``radar.measure_looks``: ``[r, phi]`` with the noise ``R`` at their
position). This module draws from the caller's noise source and wraps the results as Stone
Soup ``Clutter`` detections, and gives the quantities Stone Soup's
``PDAHypothesiser`` asks for.

Clutter density in the measurement space. ``clutter_rate`` :math:`\lambda` false alarms
are uniform in ground area over the sensing region of area :math:`A = f\,(g_{max}^2 -
g_{min}^2)` (the ``area`` column of the radar table). With :math:`r^2 = g^2 + z^2` the
ground area element is :math:`g\,dg\,d\phi = r\,dr\,d\phi`, so in the measurement space
``(r, phi)`` the density is

.. math:: \rho(r) = \lambda\, r / A \quad [1 / (\mathrm{m\ rad})],

which integrates to :math:`\lambda` over the region. Its average over the region,
:math:`\lambda / (2 f (r_{max} - r_{min}))`, equals :math:`\rho` at the middle slant range
:math:`(r_{min} + r_{max}) / 2`.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from stonesoup.types.angle import Bearing
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Clutter, Detection

from ..._types import FloatArray
from ...models import radar
from ...models.sensors import ALTITUDE2, CLUTTER_RATE, G_MAX, G_MIN, SWERLING


def is_swerling(table: FloatArray) -> bool:
    """Whether the radar (one-row table) detects with probability below 1."""
    return bool(table[0, SWERLING] != 0.0)


def detection_probability(table: FloatArray, target_xy: FloatArray,
                          sensor_xy: FloatArray) -> float:
    """Pd of a target in view at ground position ``(2,)``, from a radar at ``(2,)`` (1 with
    ideal detection)."""
    return float(radar.detection_probabilities(
        table, np.zeros(1, dtype=np.int64), np.reshape(target_xy, (1, 2)),
        np.reshape(sensor_xy, (1, 2)))[0])


def clutter_density(table: FloatArray, slant_range: float | None) -> float:
    r"""Clutter density ``rho = clutter_rate * r / A`` (1/(m rad)) in the measurement space
    ``(r, phi)`` at slant range ``r`` (m); ``None``: at the middle slant range, which is the
    region's average density ``clutter_rate / (2 f (r_max - r_min))``.

    0 without clutter; ``inf`` for a sensing region of zero area with clutter.
    """
    row = table[0]
    if slant_range is None:
        slant_range = 0.5 * (math.sqrt(row[G_MIN] ** 2 + row[ALTITUDE2])
                             + math.sqrt(row[G_MAX] ** 2 + row[ALTITUDE2]))
    return float(radar.clutter_densities(row, float(slant_range)))


def draw_clutter(table: FloatArray, sensor_xy: FloatArray, heading: float, gen: Any,
                 noise: bool, model: Any, timestamp: datetime.datetime | None) -> set[Clutter]:
    """One look's false alarms as Stone Soup ``Clutter`` (draws nothing without clutter).

    Draws, in this order, from ``gen`` (a ``Generator``, ``RandomState`` or ``np.random``):
    the count ``~ Poisson(clutter_rate)``, then ``(n, 2)`` uniforms (ground range, uniform in
    area over the band, and azimuth over the wedge: ``radar.clutter_points``), then, when
    ``noise``, ``(n, 2)`` standard normals scaled by the noise standard deviations at each
    point. Points with ``cos psi <= 0`` are not in the sensing region and are dropped. Each
    detection carries ``model`` and ``timestamp``.
    """
    lam = float(table[0, CLUTTER_RATE])
    if lam == 0.0:
        return set()
    n = int(gen.poisson(lam))
    if n == 0:
        return set()
    u = np.asarray(gen.random((n, 2)), dtype=float)
    e = np.asarray(gen.standard_normal((n, 2)), dtype=float) if noise else None
    z = radar.false_alarms(table, 0, sensor_xy, heading, u, e)
    return {Clutter(StateVector([[float(r)], [Bearing(float(phi))]]), timestamp=timestamp,
                    measurement_model=model)
            for r, phi in z}


def ordered_detections(detections: Iterable[Detection]) -> list[Detection]:
    """Detections in a fixed order: by measurement vector (then time).

    ``measure`` returns a ``set`` (Stone Soup's convention), whose iteration order follows
    object ids. Stone Soup's ``PDA`` sums over the detections in the order it is given them,
    so a set can change the last bits of an update from run to run; pass
    ``ordered_detections(detections)`` for bit-identical runs.
    """
    def key(d: Detection) -> tuple[Any, ...]:
        sv = tuple(float(v) for v in np.asarray(d.state_vector, dtype=float).ravel())
        ts = d.timestamp
        return (sv, ts is not None, ts or datetime.datetime.min)

    return sorted(detections, key=key)
