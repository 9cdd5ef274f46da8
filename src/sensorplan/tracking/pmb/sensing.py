r"""What the PMB update needs from a measurement model, for the radar and the linear sensor.

The filter is generic over the model through :class:`Sensing`: the predicted measurement,
its Jacobian and noise at ground positions, the probability that a look detects a target
at a point (its detection probability inside the look's sensing region and in sight, 0
elsewhere), the detection probability the detection hypotheses use, the clutter intensity
at the detections, and the missed-look update of Gaussian densities (with the probability
:math:`\bar P` of detection each puts on the look). Every number comes from the model's own
module: :mod:`sensorplan.models.radar` (through the tracker's filter and missed-look
steps) or :mod:`sensorplan.models.linear`.

A look is :class:`Look`: the sensor's row, its ground position and heading (the linear
sensor ignores all three: it always scans its whole area).

Likelihoods and intensities are densities in each model's measurement space: per
``(m rad)`` for the radar's ``[r, phi]``, per ``m^2`` for the linear sensor's ``[x, y]``.
Both sides of every ratio the filter forms (a detection's likelihood under a track, under
the undetected intensity, and the clutter intensity) are in the same space.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..._types import BoolArray, FloatArray
from ...models import linear, radar
from ...models.angles import wrap_angle
from ..missed import MIN_OUTSIDE, miss_update, standard_points


@dataclass(frozen=True)
class Look:
    """One look: ``sensor`` (its row), ``xy`` ``(2,)`` its ground position (m) and
    ``heading`` (rad)."""

    sensor: int
    xy: FloatArray
    heading: float


class Sensing(Protocol):
    """A measurement model as the PMB update uses it (see the module docstring)."""

    def measure(self, xy: FloatArray, look: Look
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Predicted measurements ``h (B, 2)``, ground-position Jacobians ``Hp (B, 2, 2)``
        and noise variances (R's diagonal) ``var (B, 2)`` at ground positions ``(B, 2)``."""
        ...

    def residual(self, z: FloatArray, h: FloatArray) -> FloatArray:
        """Innovations ``z - h`` (angles wrapped), broadcasting ``(..., 2)``."""
        ...

    def detectable(self, xy: FloatArray, look: Look) -> FloatArray:
        """``(P,)`` probability that the look detects a target at ground points ``(P, 2)``
        (0 outside its sensing region or out of sight)."""
        ...

    def detection_probability(self, xy: FloatArray, look: Look) -> FloatArray:
        """``(B,)`` the detection probability of a detection hypothesis, at a track's
        predicted ground position ``(B, 2)``."""
        ...

    def clutter(self, z: FloatArray, look: Look) -> FloatArray:
        """``(m,)`` the clutter intensity at detections ``(m, 2)``."""
        ...

    def miss(self, means: FloatArray, covs: FloatArray, look: Look
             ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """The missed-look update of densities ``(B, 4)``, ``(B, 4, 4)``: their means and
        covariances given no detection, :math:`\\bar P` ``(B,)`` and which were inflated."""
        ...


class RadarSensing:
    """The radar (:mod:`sensorplan.models.radar`), with the scenario's buildings.

    The missed-look update is the known-target tracker's
    (:func:`sensorplan.tracking.missed.miss_update`: 512 quadrature points, occlusion,
    its inflation rule when 95 % or more of the density is inside the look) with no gate
    factor, so the probability mass it removes is :math:`\\bar P` exactly. A detection
    hypothesis takes the radar's detection probability at the track's predicted range (the
    detection itself lies in the sensing region, so the field of view is not applied
    again).
    """

    angular = True

    def __init__(self, table: FloatArray, buildings: FloatArray | None = None) -> None:
        self.table = np.ascontiguousarray(table, dtype=float)
        self.buildings = None if buildings is None or len(buildings) == 0 else np.asarray(
            buildings, dtype=float).reshape(-1, 5)

    def measure(self, xy: FloatArray, look: Look
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
        B = len(xy)
        h, Hp, var, _ = radar.measure_looks(self.table, np.full(B, look.sensor, dtype=np.int64),
                                            xy, np.broadcast_to(look.xy, (B, 2)),
                                            np.full(B, float(look.heading)))
        return h, Hp, var

    def residual(self, z: FloatArray, h: FloatArray) -> FloatArray:
        nu = z - h
        nu[..., 1] = wrap_angle(nu[..., 1])
        return nu

    def detectable(self, xy: FloatArray, look: Look) -> FloatArray:
        d = np.asarray(xy, dtype=float) - look.xy
        return radar.detectable_points(self.table, np.array([look.sensor]), d[None, :, 0],
                                       d[None, :, 1], np.array([float(look.heading)]),
                                       np.asarray(look.xy, dtype=float)[None],
                                       self.buildings)[0]

    def detection_probability(self, xy: FloatArray, look: Look) -> FloatArray:
        B = len(xy)
        return radar.detection_probabilities(self.table, np.full(B, look.sensor, dtype=np.int64),
                                             xy, np.broadcast_to(look.xy, (B, 2)))

    def clutter(self, z: FloatArray, look: Look) -> FloatArray:
        return radar.clutter_densities(self.table[look.sensor], np.asarray(z)[:, 0],
                                       in_region=True)

    def miss(self, means: FloatArray, covs: FloatArray, look: Look
             ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        m, P, inflated, pbar = miss_update(means, covs, np.asarray(look.xy, dtype=float),
                                           np.full(len(means), float(look.heading)),
                                           self.table, look.sensor, gate_probability=1.0,
                                           buildings=self.buildings, return_fraction=True)
        return m, P, pbar, np.asarray(inflated, dtype=bool)


class LinearSensing:
    """The linear position sensor (:mod:`sensorplan.models.linear`).

    Its detection probability is the same everywhere in its area, so a miss changes a
    density only where the density reaches beyond the area (the points outside keep their
    weight, those inside keep :math:`1 - P_d`): the moments of the weighted quadrature
    points of the known-target tracker's missed-look update (the same 512 points), with no
    inflation rule (that rule is the radar's). A density whose points all have the same
    detection probability is left exactly as it was.
    """

    angular = False

    def __init__(self, sensor: linear.LinearSensor) -> None:
        self.sensor = sensor
        self._kappa = linear.clutter_density(sensor)
        self._eye = np.eye(2)

    def measure(self, xy: FloatArray, look: Look
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
        B = len(xy)
        Hp = np.broadcast_to(self._eye, (B, 2, 2))
        return linear.measure(self.sensor, xy), Hp, np.full((B, 2), self.sensor.noise_var)

    def residual(self, z: FloatArray, h: FloatArray) -> FloatArray:
        return z - h

    def detectable(self, xy: FloatArray, look: Look) -> FloatArray:
        return linear.detection_probabilities(self.sensor, xy)

    def detection_probability(self, xy: FloatArray, look: Look) -> FloatArray:
        return np.full(len(xy), self.sensor.detection_probability)

    def clutter(self, z: FloatArray, look: Look) -> FloatArray:
        return np.full(len(z), self._kappa)

    def miss(self, means: FloatArray, covs: FloatArray, look: Look
             ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        x = standard_points()
        S = len(x)
        L = np.linalg.cholesky(covs)                                         # (B, 4, 4)
        xy = means[:, None, :2] + x[None, :, :2] @ np.swapaxes(L[:, :2, :2], -1, -2)
        p = linear.detection_probabilities(self.sensor, xy)                  # (B, S)
        uniform = p.min(axis=1) == p.max(axis=1)
        pbar = np.where(uniform, p[:, 0], p.sum(axis=1) / S)
        new_m, new_P = means.copy(), covs.copy()
        w = 1.0 - p
        kept = w.sum(axis=1)
        # Equal weights leave the density as it was, and Pbar is their common value (exactly,
        # rather than to the points' rounding); so does a look that removed nearly every
        # point (its existence is then nearly 0 and the density no longer matters).
        change = ~uniform & (kept >= MIN_OUTSIDE)
        if change.any():
            wc, Lc = w[change] / kept[change, None], L[change]
            mu = wc @ x                                                      # (b, 4)
            C = np.einsum("bs,si,sj->bij", wc, x, x) - mu[:, :, None] * mu[:, None, :]
            new_m[change] = means[change] + (Lc @ mu[:, :, None])[:, :, 0]
            Pn = Lc @ C @ np.swapaxes(Lc, -1, -2)
            new_P[change] = 0.5 * (Pn + np.swapaxes(Pn, -1, -2))
        return new_m, new_P, pbar, np.zeros(len(means), dtype=bool)


def make_sensing(measurement: FloatArray | linear.LinearSensor,
                 buildings: FloatArray | None = None) -> RadarSensing | LinearSensing:
    """The :class:`Sensing` of a radar table ``(N, C)`` or a linear sensor."""
    if isinstance(measurement, linear.LinearSensor):
        if buildings is not None and len(buildings):
            raise ValueError("the linear sensor sees through buildings: none may be given")
        return LinearSensing(measurement)
    return RadarSensing(measurement, buildings)


__all__ = ["LinearSensing", "Look", "RadarSensing", "Sensing", "make_sensing"]
