"""Batched radar kernels and the numpy-facing wrappers every consumer calls.

Each loops a scalar function of :mod:`sensorplan.models.radar.model` (the one radar model) over a
batch in one compiled call; the wrappers broadcast and reshape numpy arrays around them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..._compiled.jit import njit
from ..._types import BoolArray, FloatArray, IntArray
from ..angles import wrap_angle
from ..sensors import ALTITUDE, ALTITUDE2, AREA, CLUTTER_RATE, COLUMNS, FOV, G_MAX, G_MIN
from .model import ANGLE_TOL, detection_probability, hidden, inverse, look, measure, visible


# ------------------------------------------------------------------ batched kernels


@njit(cache=True, error_model="numpy")
def _measure_batch(table: np.ndarray, idx: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                   heading: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                 np.ndarray]:
    n = dx.shape[0]
    h = np.empty((n, 2))
    H = np.empty((n, 2, 2))
    var = np.empty((n, 2))
    seen = np.empty(n, dtype=np.bool_)
    for b in range(n):
        r, phi, h00, h01, h10, h11, vr, vp, ok = measure(table[idx[b]], dx[b], dy[b],
                                                         heading[b])
        h[b, 0] = r
        h[b, 1] = phi
        H[b, 0, 0] = h00
        H[b, 0, 1] = h01
        H[b, 1, 0] = h10
        H[b, 1, 1] = h11
        var[b, 0] = vr
        var[b, 1] = vp
        seen[b] = ok
    return h, H, var, seen


@njit(cache=True, error_model="numpy")
def _pd_batch(table: np.ndarray, idx: np.ndarray, dx: np.ndarray, dy: np.ndarray
              ) -> np.ndarray:
    n = dx.shape[0]
    out = np.empty(n)
    for b in range(n):
        row = table[idx[b]]
        out[b] = detection_probability(row, dx[b] * dx[b] + dy[b] * dy[b] + row[ALTITUDE2])
    return out


@njit(cache=True, error_model="numpy")
def _inverse_batch(table: np.ndarray, idx: np.ndarray, z: np.ndarray,
                   heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = z.shape[0]
    d = np.empty((n, 2))
    C = np.empty((n, 2, 2))
    for b in range(n):
        dx, dy, c00, c01, c11 = inverse(table[idx[b]], z[b, 0], z[b, 1], heading[b])
        d[b, 0] = dx
        d[b, 1] = dy
        C[b, 0, 0] = c00
        C[b, 0, 1] = C[b, 1, 0] = c01
        C[b, 1, 1] = c11
    return d, C


@njit(cache=True, error_model="numpy")
def _visible_grid(table: np.ndarray, idx: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                  heading: np.ndarray) -> np.ndarray:
    B, S = dx.shape
    out = np.empty((B, S), dtype=np.bool_)
    for b in range(B):
        row = table[idx[b]]
        for s in range(S):
            out[b, s] = visible(row, dx[b, s], dy[b, s], heading[b])
    return out


@njit(cache=True, error_model="numpy")
def _detect_grid(table: np.ndarray, idx: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                 heading: np.ndarray, sxy: np.ndarray, buildings: np.ndarray) -> np.ndarray:
    B, S = dx.shape
    out = np.zeros((B, S))
    for b in range(B):
        row = table[idx[b]]
        for s in range(S):
            if visible(row, dx[b, s], dy[b, s], heading[b]) and (
                    buildings.shape[0] == 0
                    or not hidden(buildings, sxy[b, 0], sxy[b, 1], row[ALTITUDE],
                                  sxy[b, 0] + dx[b, s], sxy[b, 1] + dy[b, s])):
                out[b, s] = detection_probability(
                    row, dx[b, s] * dx[b, s] + dy[b, s] * dy[b, s] + row[ALTITUDE2])
    return out


#: Margin on the cosine of the wedge's half-angle below which a point is certainly outside
#: the wedge: many orders of magnitude above the rounding of either test.
_WEDGE_MARGIN = 1e-9


@njit(cache=True, error_model="numpy")
def _detect_quadrature(table: np.ndarray, idx: np.ndarray, base: np.ndarray,
                       chol: np.ndarray, x: np.ndarray, heading: np.ndarray, sxy: np.ndarray,
                       buildings: np.ndarray) -> np.ndarray:
    """:func:`_detect_grid` at the ground offsets ``base_b + L_b x_s`` of quadrature points
    (``L_b`` lower triangular, so only its position block and ``x_s[:2]`` matter), formed
    here in the order numpy formed them: ``dx = b0 + l00 x0``, ``dy = b1 + l10 x0 + l11 x1``.

    Most points of a missed look lie in the range band but off the azimuth wedge, where
    :func:`visible` pays an ``atan2``. A point whose direction is off the boresight by
    clearly more than the wedge's half-angle ``w`` (``cos`` of the angle below
    ``cos w - 1e-9``, i.e. at least about 1e-9 rad beyond the edge, far above the rounding
    of either test) is skipped without it; every other point gets the full test. So the
    result is the one :func:`visible` gives, point for point.
    """
    B, S = base.shape[0], x.shape[0]
    out = np.zeros((B, S))
    for b in range(B):
        row = table[idx[b]]
        b0, b1 = base[b, 0], base[b, 1]
        l00, l10, l11 = chol[b, 0, 0], chol[b, 1, 0], chol[b, 1, 1]
        half = row[FOV] + ANGLE_TOL
        cut = math.cos(half) - _WEDGE_MARGIN if half < math.pi else -2.0
        ch, sh = math.cos(heading[b]), math.sin(heading[b])
        for s in range(S):
            dx = b0 + l00 * x[s, 0]
            dy = b1 + l10 * x[s, 0] + l11 * x[s, 1]
            if dx * ch + dy * sh < math.sqrt(dx * dx + dy * dy) * cut:
                continue                                 # certainly outside the wedge
            if visible(row, dx, dy, heading[b]) and (
                    buildings.shape[0] == 0
                    or not hidden(buildings, sxy[b, 0], sxy[b, 1], row[ALTITUDE],
                                  sxy[b, 0] + dx, sxy[b, 1] + dy)):
                out[b, s] = detection_probability(row, dx * dx + dy * dy + row[ALTITUDE2])
    return out


@njit(cache=True, error_model="numpy")
def _hidden_batch(buildings: np.ndarray, sxy: np.ndarray, z: np.ndarray,
                  qxy: np.ndarray) -> np.ndarray:
    n = sxy.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for b in range(n):
        out[b] = hidden(buildings, sxy[b, 0], sxy[b, 1], z[b], qxy[b, 0], qxy[b, 1])
    return out


@njit(cache=True, error_model="numpy")
def _look_batch(row: np.ndarray, buildings: np.ndarray, sxy: np.ndarray, dx: np.ndarray,
                dy: np.ndarray, th: np.ndarray, C: np.ndarray,
                probabilistic: bool) -> tuple[np.ndarray, np.ndarray]:
    n = dx.shape[0]
    W = np.zeros((n, 2, 2))
    weight = np.zeros(n)
    for b in range(n):
        p, w00, w01, w11 = look(row, buildings, sxy[b, 0], sxy[b, 1], dx[b], dy[b], th[b],
                                C[b, 0], C[b, 1], C[b, 2], probabilistic)
        weight[b] = p
        W[b, 0, 0] = w00
        W[b, 0, 1] = w01
        W[b, 1, 0] = w01
        W[b, 1, 1] = w11
    return W, weight


# ------------------------------------------------------------------ numpy-facing wrappers


def _flat(a: Any, dtype: type = np.float64) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=dtype).ravel()


def measure_looks(table: FloatArray, sensor: IntArray | int, target_xy: FloatArray,
                  sensor_xy: FloatArray, heading: FloatArray | float
                  ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
    """Measurement model of a batch of looks, one compiled call.

    Parameters
    ----------
    table : (N, C) radar table
    sensor : (...) int       row of ``table`` of each look's sensor
    target_xy : (..., 2)     target ground positions (m)
    sensor_xy : (..., 2)     sensor ground positions (m)
    heading : (...)          sensor headings (rad)

    Returns
    -------
    h : (..., 2)        noise-free ``[r, phi]`` (m, rad)
    H : (..., 2, 2)     ground-position Jacobian ``H'``
    var : (..., 2)      diagonal of the noise covariance ``R``
    visible : (...) bool
    """
    target_xy = np.asarray(target_xy, dtype=float)
    sensor_xy = np.asarray(sensor_xy, dtype=float)
    dx = target_xy[..., 0] - sensor_xy[..., 0]
    dy = target_xy[..., 1] - sensor_xy[..., 1]
    if (dx.ndim == 1 and type(heading) is np.ndarray and type(sensor) is np.ndarray
            and heading.shape == sensor.shape == dx.shape and heading.dtype == np.float64
            and sensor.dtype == np.int64 and type(table) is np.ndarray
            and table.dtype == np.float64):
        # The tracker's and the simulator's calls: one flat batch, nothing to broadcast
        # (the wrapper's checks cost several times the compiled call on a few looks).
        return _measure_batch(np.ascontiguousarray(table), np.ascontiguousarray(sensor),
                              dx, dy, np.ascontiguousarray(heading))
    shape = np.broadcast_shapes(dx.shape, np.shape(heading), np.shape(sensor))
    # Broadcast only what needs it: most calls pass equal shapes, and broadcast_to's
    # overhead dominates these tiny batches.
    b = [a if np.shape(a) == shape else np.broadcast_to(a, shape)
         for a in (dx, dy, heading, sensor)]
    h, H, var, seen = _measure_batch(np.ascontiguousarray(table, dtype=float),
                                     _flat(b[3], np.int64), _flat(b[0]), _flat(b[1]),
                                     _flat(b[2]))
    return (h.reshape(shape + (2,)), H.reshape(shape + (2, 2)), var.reshape(shape + (2,)),
            seen.reshape(shape))


def detection_probabilities(table: FloatArray, sensor: IntArray, target_xy: FloatArray,
                            sensor_xy: FloatArray) -> FloatArray:
    """Detection probability of each look at a target in view (:func:`detection_probability`).

    Parameters
    ----------
    table : (N, C); sensor : (B,) int; target_xy, sensor_xy : (B, 2)

    Returns
    -------
    (B,) float64 in (0, 1]
    """
    d = np.asarray(target_xy, dtype=float) - np.asarray(sensor_xy, dtype=float)
    return _pd_batch(np.ascontiguousarray(table, dtype=float),
                     np.ascontiguousarray(sensor, dtype=np.int64),
                     np.ascontiguousarray(d[:, 0]), np.ascontiguousarray(d[:, 1]))


def inverse_looks(table: FloatArray, sensor: IntArray, z: FloatArray, sensor_xy: FloatArray,
                  heading: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Ground positions of measurements and their linearised covariances (:func:`inverse`).

    Parameters
    ----------
    table : (N, C); sensor : (B,) int; z : (B, 2) ``[r, phi]``; sensor_xy : (B, 2);
    heading : (B,)

    Returns
    -------
    xy : (B, 2) ground positions (m), C : (B, 2, 2) their covariances (m^2)
    """
    d, C = _inverse_batch(np.ascontiguousarray(table, dtype=float),
                          np.ascontiguousarray(sensor, dtype=np.int64),
                          np.ascontiguousarray(z, dtype=float),
                          np.ascontiguousarray(heading, dtype=float))
    return np.asarray(sensor_xy, dtype=float) + d, C


def visible_points(table: FloatArray, sensor: IntArray, dx: FloatArray, dy: FloatArray,
                   heading: FloatArray) -> BoolArray:
    """Field-of-view test of S ground offsets per look.

    Parameters
    ----------
    table : (N, C)
    sensor : (B,) int
    dx, dy : (B, S)    ground offsets of points from look b's sensor (m)
    heading : (B,)

    Returns
    -------
    (B, S) bool
    """
    return _visible_grid(np.ascontiguousarray(table, dtype=float),
                         np.ascontiguousarray(sensor, dtype=np.int64),
                         np.ascontiguousarray(dx, dtype=float),
                         np.ascontiguousarray(dy, dtype=float),
                         np.ascontiguousarray(heading, dtype=float))


def detectable_points(table: FloatArray, sensor: IntArray, dx: FloatArray, dy: FloatArray,
                      heading: FloatArray, sensor_xy: FloatArray | None = None,
                      buildings: FloatArray | None = None) -> FloatArray:
    """Probability that a look detects a target at each of S ground offsets per look:
    the detection probability inside the field of view and in sight (no building in
    between; needs ``sensor_xy``), 0 otherwise (ideal detection gives exactly 0 or 1).

    Parameters
    ----------
    table : (N, C); sensor : (B,) int; dx, dy : (B, S); heading : (B,)
    sensor_xy : (B, 2), optional     sensor ground positions, for the line of sight
    buildings : (K, 5), optional     ``x0, y0, x1, y1, height`` of each building

    Returns
    -------
    (B, S) float64 in [0, 1]
    """
    blds = _buildings(buildings)
    sxy = np.zeros((len(sensor), 2)) if sensor_xy is None else np.ascontiguousarray(
        sensor_xy, dtype=float).reshape(-1, 2)
    return _detect_grid(np.ascontiguousarray(table, dtype=float),
                        np.ascontiguousarray(sensor, dtype=np.int64),
                        np.ascontiguousarray(dx, dtype=float),
                        np.ascontiguousarray(dy, dtype=float),
                        np.ascontiguousarray(heading, dtype=float), sxy, blds)


def detectable_quadrature(table: FloatArray, sensor: IntArray, base: FloatArray,
                          chol: FloatArray, points: FloatArray, heading: FloatArray,
                          sensor_xy: FloatArray | None = None,
                          buildings: FloatArray | None = None) -> FloatArray:
    """:func:`detectable_points` at quadrature points ``m + L x_s`` of B Gaussians, the
    ground offsets formed in the compiled call (the same values as numpy forms them).

    Parameters
    ----------
    table : (N, C); sensor : (B,) int
    base : (B, 2)        ground offset of each Gaussian's mean from its look's sensor (m)
    chol : (B, 4, 4)     lower Cholesky factors of the covariances
    points : (S, 4)      whitened points x_s
    heading : (B,);  sensor_xy : (B, 2), optional;  buildings : (K, 5), optional

    Returns
    -------
    (B, S) float64 in [0, 1]
    """
    blds = _buildings(buildings)
    B = len(base)
    sxy = np.zeros((B, 2)) if sensor_xy is None else np.ascontiguousarray(
        sensor_xy, dtype=float).reshape(-1, 2)
    return _detect_quadrature(np.ascontiguousarray(table, dtype=float),
                              np.ascontiguousarray(sensor, dtype=np.int64),
                              np.ascontiguousarray(base, dtype=float),
                              np.ascontiguousarray(chol, dtype=float),
                              np.ascontiguousarray(points, dtype=float),
                              np.ascontiguousarray(heading, dtype=float), sxy, blds)


def _buildings(buildings: FloatArray | None) -> np.ndarray:
    if buildings is None:
        return np.zeros((0, 5))
    # A copy: a read-only array (a frozen problem's) would compile a second kernel.
    return np.array(buildings, dtype=float, order="C").reshape(-1, 5)


def hidden_looks(buildings: FloatArray | None, sensor_xy: FloatArray, altitude: FloatArray,
                 target_xy: FloatArray) -> BoolArray:
    """Whether buildings hide each target ``(B, 2)`` from its sensor ``(B, 2)`` at
    ``altitude`` ``(B,)`` (see :func:`hidden`)."""
    blds = _buildings(buildings)
    n = len(np.asarray(sensor_xy).reshape(-1, 2))
    if len(blds) == 0:
        return np.zeros(n, dtype=bool)
    return _hidden_batch(blds, np.ascontiguousarray(sensor_xy, dtype=float).reshape(-1, 2),
                         np.ascontiguousarray(np.broadcast_to(altitude, (n,)), dtype=float),
                         np.ascontiguousarray(target_xy, dtype=float).reshape(-1, 2))


def clutter_points(row: FloatArray, sensor_xy: FloatArray, heading: float,
                   u: FloatArray) -> FloatArray:
    """Ground positions of false alarms, uniform in area over a look's sensing region.

    Parameters
    ----------
    row : (C,) the sensor's radar table row
    sensor_xy : (2,); heading : float
    u : (n, 2) uniforms in [0, 1): ground range (uniform in area over the range band) and
        azimuth (uniform over the wedge)

    Returns
    -------
    (n, 2) ground positions, all in the range band and the wedge; those with
    ``cos psi <= 0`` (behind the boresight plane) are not in the sensing region and are
    left to the caller's visibility test (:func:`measure_looks`).
    """
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    g2min, g2max = row[G_MIN] ** 2, row[G_MAX] ** 2
    g = np.sqrt(g2min + u[:, 0] * (g2max - g2min))
    a = heading + row[FOV] * (2.0 * u[:, 1] - 1.0)
    return np.asarray(sensor_xy, dtype=float) + g[:, None] * np.column_stack(
        [np.cos(a), np.sin(a)])


def clutter_densities(row: FloatArray, r: FloatArray | float, *, in_region: bool = False
                      ) -> FloatArray:
    """Density of false alarms in ``(r, phi)`` (1/(m rad)) at slant ranges ``r`` (m): the
    clutter rate times ``r`` over the sensing region's ground area (see
    :func:`~sensorplan.models.radar.model.clutter_density`).

    ``in_region``: take the density at ``r`` clipped to the sensing region's slant ranges
    (a noisy range may fall outside the band the false alarms come from). 0 without clutter;
    ``inf`` for a region of zero area with clutter.
    """
    r = np.asarray(r, dtype=float)
    if in_region:
        r = np.clip(r, math.sqrt(row[ALTITUDE2] + row[G_MIN] ** 2),
                    math.sqrt(row[ALTITUDE2] + row[G_MAX] ** 2))
    if row[CLUTTER_RATE] == 0.0:
        return np.zeros(r.shape)
    with np.errstate(divide="ignore"):
        return row[CLUTTER_RATE] * r / row[AREA]


def false_alarms(table: FloatArray, sensor: int, sensor_xy: FloatArray, heading: float,
                 u: FloatArray, normals: FloatArray | None) -> FloatArray:
    """One look's false alarms as measurements ``[r, phi]``.

    Parameters
    ----------
    table : (N, C) radar table; sensor : the looking sensor's row
    sensor_xy : (2,); heading : float
    u : (n, 2) uniforms placing them uniformly in area over the sensing region
        (:func:`clutter_points`)
    normals : (n, 2) standard normals for their measurement noise, or None for none

    Returns
    -------
    (k, 2) measurements of the ``k <= n`` points inside the sensing region (those behind the
    boresight plane, ``cos psi <= 0``, are not), azimuth wrapped, in the order drawn.
    """
    n = len(u)
    if n == 0:
        return np.zeros((0, 2))
    xy = clutter_points(table[sensor], sensor_xy, heading, u)
    h, _, var, inside = measure_looks(table, np.full(n, sensor), xy, sensor_xy,
                                      np.full(n, float(heading)))
    z = h[inside]
    if normals is not None:
        # outside the region the azimuth noise may be infinite: only the points kept
        z = z + np.sqrt(var[inside]) * np.asarray(normals, dtype=float)[inside]
    z[:, 1] = wrap_angle(z[:, 1])
    return z


def look_information(row: FloatArray, dx: FloatArray, dy: FloatArray, th: FloatArray,
                     C: FloatArray, probabilistic: bool, buildings: FloatArray | None = None,
                     sensor_xy: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Weight and information of planned looks by one sensor (see :func:`look`).

    Parameters
    ----------
    row : (C,) the sensor's radar table row
    dx, dy, th : (...)  ground offsets of the target's predicted mean (m), headings (rad)
    C : (..., 3)        predicted position covariance entries (c00, c01, c11) (m^2)
    probabilistic : bool
    buildings : (B, 5), optional   boxes ``x0, y0, x1, y1, height`` that can hide the target
    sensor_xy : (..., 2), optional the sensor's ground position (needed with buildings)

    Returns
    -------
    W : (..., 2, 2)   ``p H'^T R^{-1} H'`` (1/m^2), zero where the look does not count
    weight : (...)    ``p`` (0 where the look does not count)
    """
    shape = np.broadcast_shapes(np.shape(dx), np.shape(dy), np.shape(th))
    blds = _buildings(buildings)
    if blds.shape[0] and sensor_xy is None:
        raise ValueError("sensor_xy is needed to test buildings")
    sxy = np.zeros(shape + (2,)) if sensor_xy is None else np.broadcast_to(sensor_xy,
                                                                          shape + (2,))
    W, weight = _look_batch(np.ascontiguousarray(row, dtype=float), blds,
                            np.ascontiguousarray(sxy, dtype=float).reshape(-1, 2),
                            _flat(np.broadcast_to(dx, shape)), _flat(np.broadcast_to(dy, shape)),
                            _flat(np.broadcast_to(th, shape)),
                            np.ascontiguousarray(np.broadcast_to(C, shape + (3,))).reshape(-1, 3),
                            bool(probabilistic))
    return W.reshape(shape + (2, 2)), weight.reshape(shape)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the batched kernels on tiny inputs."""
    table = np.zeros((1, len(COLUMNS)))
    table[0, ALTITUDE] = table[0, ALTITUDE2] = 1.0
    z = np.zeros(1)
    i = np.zeros(1, dtype=np.int64)
    _measure_batch(table, i, z + 1.0, z, z)
    _inverse_batch(table, i, np.ones((1, 2)), z)
    _pd_batch(table, i, z + 1.0, z)
    _visible_grid(table, i, np.ones((1, 1)), np.zeros((1, 1)), z)
    _detect_grid(table, i, np.ones((1, 1)), np.zeros((1, 1)), z, np.zeros((1, 2)),
                 np.zeros((1, 5)))
    _detect_quadrature(table, i, np.ones((1, 2)), np.eye(4)[None], np.zeros((1, 4)), z,
                       np.zeros((1, 2)), np.zeros((1, 5)))
    _hidden_batch(np.zeros((1, 5)), np.zeros((1, 2)), z + 1.0, np.ones((1, 2)))
    for probabilistic in (True, False):
        _look_batch(table[0], np.zeros((0, 5)), np.zeros((1, 2)), z + 1.0, z, z,
                    np.ones((1, 3)), probabilistic)
