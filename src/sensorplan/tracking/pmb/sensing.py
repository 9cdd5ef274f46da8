r"""What the PMB update needs from a measurement model, for the radar and the linear sensor.

The filter is generic over the model through :class:`Sensing`: the predicted measurement,
its Jacobian and noise at ground positions, the probability that a look detects a target
at a point (its detection probability inside the look's sensing region and in sight, 0
elsewhere), the detection probability the detection hypotheses use, the clutter intensity
at the detections, and the probability of detection at each point of the missed-look
quadrature of a Gaussian density (the 512 points of
:func:`sensorplan.tracking.missed.standard_points`). Every number comes from the model's
own module: :mod:`sensorplan.models.radar` or :mod:`sensorplan.models.linear`.

A look is :class:`Look`: the sensor's row, its ground position and heading (the linear
sensor ignores all three: it always scans its whole area).

Likelihoods and intensities are densities in each model's measurement space: per
``(m rad)`` for the radar's ``[r, phi]``, per ``m^2`` for the linear sensor's ``[x, y]``.
Both sides of every ratio the filter forms (a detection's likelihood under a track, under
the undetected intensity, and the clutter intensity) are in the same space.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..._types import FloatArray, IntArray
from ..._compiled.jit import njit
from ...models import linear, radar
from ...models.angles import wrap_angle
from ...models.radar import detection_probability, wrap
from ...models.sensors import ALTITUDE2, FOV, G_MAX, G_MIN
from ..missed import standard_points

#: The largest distance of a missed-look quadrature point's position coordinates from 0.
_RHO = float(np.max(np.hypot(standard_points()[:, 0], standard_points()[:, 1])))
#: Margin (m, rad) of the tests that a look cannot see any, or sees all, of a density's
#: quadrature points: far above their rounding.
_MARGIN = 1e-6
#: Classes of a density for a look (:func:`_classify`).
OUTSIDE, INSIDE, PARTLY = 0, 1, 2


@dataclass(frozen=True)
class Look:
    """One look: ``sensor`` (its row), ``xy`` ``(2,)`` its ground position (m) and
    ``heading`` (rad)."""

    sensor: int
    xy: FloatArray
    heading: float


class Sensing(Protocol):
    """A measurement model as the PMB update uses it (see the module docstring)."""

    #: Whether the measurement's second coordinate is an angle (its innovations wrapped).
    angular: bool

    def quadrature(self, means: FloatArray, covs: FloatArray, look: Look
                   ) -> tuple[IntArray, FloatArray, FloatArray]:
        """The densities ``(B, 4)``, ``(B, 4, 4)`` the look may see, ``rows (k,)``; for
        each, the probability ``p (k, S)`` that the look detects a target at each
        quadrature point ``m + L x_s``, and ``L (k, 4, 4)``. The others' points all lie
        where the look detects nothing."""
        ...

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


class RadarSensing:
    r"""The radar (:mod:`sensorplan.models.radar`), with the scenario's buildings.

    The quadrature's detection probabilities are the radar's
    (:func:`sensorplan.models.radar.detectable_quadrature`, the call the known-target
    tracker's missed-look update makes: field of view, line of sight, detection
    probability). Two classes of density are served without that call, with the same
    numbers: those whose points all lie outside the sensing region (0), and, without
    buildings, those whose points all lie inside it (each point's detection probability
    at its range: no field-of-view test to make). The class comes from a disc around the
    mean that holds every point (radius: the points' largest position norm times the
    spectral norm of the position block of the Cholesky factor, the square root of the
    position covariance's largest eigenvalue). A detection hypothesis takes the radar's
    detection probability at the track's predicted range (the detection lies in the
    sensing region, so the field of view is not applied again).
    """

    angular = True

    def __init__(self, table: FloatArray, buildings: FloatArray | None = None) -> None:
        self.table = np.ascontiguousarray(table, dtype=float)
        self.buildings = None if buildings is None or len(buildings) == 0 else np.asarray(
            buildings, dtype=float).reshape(-1, 5)

    def classify(self, means: FloatArray, covs: FloatArray, look: Look) -> IntArray:
        """``(B,)`` :data:`OUTSIDE`, :data:`INSIDE` or :data:`PARTLY`: where a density's
        quadrature points lie relative to the look's sensing region (range band, azimuth
        wedge) by the disc test of the class docstring; PARTLY when unsure."""
        return _classify(self.table[look.sensor], np.ascontiguousarray(means),
                         np.ascontiguousarray(covs), np.asarray(look.xy, dtype=float),
                         float(look.heading), _RHO, _MARGIN)

    def quadrature(self, means: FloatArray, covs: FloatArray, look: Look
                   ) -> tuple[IntArray, FloatArray, FloatArray]:
        x = standard_points()
        kind = self.classify(means, covs, look)
        if self.buildings is not None:
            kind[kind == INSIDE] = PARTLY           # the line of sight is tested per point
        # The densities the look may see, those wholly inside first.
        inside, partly = np.flatnonzero(kind == INSIDE), np.flatnonzero(kind == PARTLY)
        rows = np.concatenate([inside, partly])
        chol = np.linalg.cholesky(covs[rows])
        base = means[rows, :2] - look.xy
        k = inside.size
        parts = [_detect_inside(self.table[look.sensor], base[:k], chol[:k], x)]
        if partly.size:
            parts.append(radar.detectable_quadrature(
                self.table, np.full(partly.size, look.sensor, dtype=np.int64), base[k:],
                chol[k:], x, np.full(partly.size, float(look.heading)),
                None if self.buildings is None else np.broadcast_to(look.xy, (partly.size, 2)),
                self.buildings))
        return rows, np.concatenate(parts) if len(parts) > 1 else parts[0], chol

    def measure(self, xy: FloatArray, look: Look
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
        B = len(xy)
        h, Hp, var, _ = radar.measure_looks(self.table, np.full(B, look.sensor, dtype=np.int64),
                                            xy, look.xy, np.full(B, float(look.heading)))
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
        return radar.detection_probabilities(self.table,
                                             np.full(len(xy), look.sensor, dtype=np.int64),
                                             xy, look.xy)

    def clutter(self, z: FloatArray, look: Look) -> FloatArray:
        return radar.clutter_densities(self.table[look.sensor], np.asarray(z)[:, 0],
                                       in_region=True)


@njit(cache=True, error_model="numpy")
def _classify(row: np.ndarray, means: np.ndarray, covs: np.ndarray, sxy: np.ndarray,
              heading: float, rho_max: float, margin: float) -> np.ndarray:
    """Each density's disc against the range band and the azimuth wedge: OUTSIDE, INSIDE
    (wedge narrower than a right angle, so that every point in it is in front of the
    boresight plane too) or PARTLY. The disc: centred on the mean, radius ``rho_max``
    times the spectral norm of the position block of the Cholesky factor (the square root
    of the position covariance's largest eigenvalue)."""
    B = means.shape[0]
    out = np.empty(B, dtype=np.int64)
    gmin, gmax, fov = row[G_MIN], row[G_MAX], row[FOV]
    for b in range(B):
        a, c, o = covs[b, 0, 0], covs[b, 1, 1], covs[b, 0, 1]
        rho = rho_max * math.sqrt(0.5 * (a + c) + math.hypot(0.5 * (a - c), o))
        dx, dy = means[b, 0] - sxy[0], means[b, 1] - sxy[1]
        g = math.sqrt(dx * dx + dy * dy)
        if g + rho < gmin - margin or g - rho > gmax + margin:
            out[b] = 0
            continue
        if g <= rho + margin:
            out[b] = 2
            continue
        off = abs(wrap(math.atan2(dy, dx) - heading))
        spread = math.asin(rho / g)
        if off - spread > fov + margin:
            out[b] = 0
        elif (g - rho > gmin + margin and g + rho < gmax - margin
              and off + spread < fov - margin and fov < 0.5 * math.pi - margin):
            out[b] = 1
        else:
            out[b] = 2
    return out


@njit(cache=True, error_model="numpy")
def _detect_inside(row: np.ndarray, base: np.ndarray, chol: np.ndarray, x: np.ndarray
                   ) -> np.ndarray:
    """The radar's detection probability at the quadrature points of densities whose
    points all lie in the sensing region, their ground offsets formed as
    :func:`sensorplan.models.radar.detectable_quadrature` forms them (the same numbers)."""
    B, S = base.shape[0], x.shape[0]
    out = np.empty((B, S))
    alt2 = row[ALTITUDE2]
    for b in range(B):
        b0, b1 = base[b, 0], base[b, 1]
        l00, l10, l11 = chol[b, 0, 0], chol[b, 1, 0], chol[b, 1, 1]
        for s in range(S):
            dx = b0 + l00 * x[s, 0]
            dy = b1 + l10 * x[s, 0] + l11 * x[s, 1]
            out[b, s] = detection_probability(row, dx * dx + dy * dy + alt2)
    return out


class LinearSensing:
    """The linear position sensor (:mod:`sensorplan.models.linear`): its detection
    probability is the same everywhere in its area and 0 outside it."""

    angular = False

    def __init__(self, sensor: linear.LinearSensor) -> None:
        self.sensor = sensor
        self._kappa = linear.clutter_density(sensor)
        self._eye = np.eye(2)

    def quadrature(self, means: FloatArray, covs: FloatArray, look: Look
                   ) -> tuple[IntArray, FloatArray, FloatArray]:
        x = standard_points()
        chol = np.asarray(np.linalg.cholesky(covs), dtype=float)
        xy = means[:, None, :2] + x[None, :, :2] @ np.swapaxes(chol[:, :2, :2], -1, -2)
        rows = np.arange(len(means), dtype=np.int64)
        return rows, linear.detection_probabilities(self.sensor, xy), chol

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


def make_sensing(measurement: FloatArray | linear.LinearSensor,
                 buildings: FloatArray | None = None) -> RadarSensing | LinearSensing:
    """The :class:`Sensing` of a radar table ``(N, C)`` or a linear sensor."""
    if isinstance(measurement, linear.LinearSensor):
        if buildings is not None and len(buildings):
            raise ValueError("the linear sensor sees through buildings: none may be given")
        return LinearSensing(measurement)
    return RadarSensing(measurement, buildings)


__all__ = ["INSIDE", "OUTSIDE", "PARTLY", "LinearSensing", "Look", "RadarSensing", "Sensing",
           "make_sensing"]
