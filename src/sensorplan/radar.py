r"""The radar: the one model of what a sensor measures and what it can see.

Every consumer calls the compiled functions of this module: the tracker's update
(:mod:`sensorplan.ekf`), the simulator's measurements of the truth
(:mod:`sensorplan.simulation`), the planner's look information (:mod:`sensorplan._kernels`,
:mod:`sensorplan.information`), the missed-look update (:mod:`sensorplan.missed`) and the
Stone Soup bridge. A change to the radar is one edit here. The slow numpy version of the same
model lives in the tests (``tests/radar_reference.py``), as the independent second
computation.

A sensor is one row of a radar table (:func:`sensorplan.sensors.radar_table`). For a target
at ground offset :math:`(dx, dy)` from a platform at altitude :math:`z` with heading
:math:`\theta`:

.. math::
    g = \sqrt{dx^2 + dy^2},\quad r = \sqrt{g^2 + z^2},\quad \phi = \mathrm{atan2}(dy, dx),

    H' = \begin{bmatrix} dx/r & dy/r \\ -dy/g^2 & dx/g^2 \end{bmatrix}
    \quad (\text{Jacobian of } [r, \phi] \text{ w.r.t. the ground position;
    velocity columns are zero}),

    \cos\psi = \frac{\cos\delta\,(dx\cos\theta + dy\sin\theta) + \sin\delta\, z}{r}
    \quad (\text{angle between line of sight and boresight, depression } \delta),

    \sigma_r^2 = c_r r^4,\qquad \sigma_\phi^2 = c_\phi\, r^4 / \cos^2\psi
    \quad (\text{the SNR model, constants in the table row}).

The field of view (the sensing region) is :math:`g \in [g_{min}, g_{max}]`,
:math:`|\mathrm{wrap}(\phi - \theta)| \le f` and :math:`\cos\psi > 0`, bounds inclusive with
a tolerance of :data:`RANGE_TOL` m and :data:`ANGLE_TOL` rad (a point placed exactly on an
edge can compute a rounding error outside it).

In planning, the target's ground position is uncertain, :math:`N(\bar x, C)`; the
probability that it is in view is, linearised at the mean with ground range and azimuth
treated as independent,

.. math::
    p_{vis} = [\Phi(\tfrac{g_{max}-\bar g}{s_g}) - \Phi(\tfrac{g_{min}-\bar g}{s_g})]
              [\Phi(\tfrac{f-d}{s_\phi}) - \Phi(\tfrac{-f-d}{s_\phi})],\quad
    s_g^2 = u^T C u,\ s_\phi^2 = v^T C v / \bar g^2,

with :math:`u` the unit ground vector toward the mean, :math:`v` perpendicular to it and
:math:`d = \mathrm{wrap}(\bar\phi - \theta)`; :math:`p_{vis} = 0` at the nadir or when
:math:`\cos\psi \le 0` at the mean. A planned look counts with the information
:math:`p\, H'^T R^{-1} H'` (its noise is :math:`R / p`); looks with :math:`p` below
:data:`P_VIS_MIN` do not count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._types import BoolArray, FloatArray, IntArray
from .sensors import (ALTITUDE, ALTITUDE2, COS_DEP, FOV, G_MAX, G_MIN, SIN_DEP, VAR_PHI,
                      VAR_R)

#: Tolerance (m) of the inclusive ground-range bounds of the field of view.
RANGE_TOL = 1e-9
#: Tolerance (rad) of the inclusive azimuth bounds of the field of view.
ANGLE_TOL = 1e-12
#: Planned looks less likely than this to see their target do not count.
P_VIS_MIN = 1e-6
#: A planned look whose predicted ground range is more than this many standard deviations
#: outside the range band does not count: its in-band mass is below Ncdf(-6) ~ 1e-9.
BAND_SIGMAS = 6.0


# ------------------------------------------------------------------ scalar kernels


@njit(cache=True, error_model="numpy")
def wrap(a: float) -> float:
    """Wrap an angle to (-pi, pi] (as :func:`sensorplan.angles.wrap_angle`)."""
    two_pi = 2.0 * math.pi
    x = math.pi - a
    # x % two_pi is x itself for 0 <= x < two_pi (the usual case): skip the floating modulo.
    w = math.pi - (x if 0.0 <= x < two_pi else x % two_pi)
    return w + two_pi if w <= -math.pi else w


@njit(cache=True, error_model="numpy")
def cos_psi(row: np.ndarray, dx: float, dy: float, cos_h: float, sin_h: float,
            r: float) -> float:
    """Cosine of the angle between the line of sight and the boresight."""
    return (row[COS_DEP] * (dx * cos_h + dy * sin_h) + row[SIN_DEP] * row[ALTITUDE]) / r


@njit(cache=True, error_model="numpy")
def noise_variances(row: np.ndarray, r2: float, cpsi: float) -> tuple[float, float]:
    """Range (m^2) and azimuth (rad^2) noise variances at slant range^2 ``r2``."""
    r4 = r2 * r2
    return row[VAR_R] * r4, row[VAR_PHI] * r4 / (cpsi * cpsi)


@njit(cache=True, error_model="numpy")
def in_band(row: np.ndarray, g: float) -> bool:
    """Whether ground range ``g`` lies in the field of view's range band."""
    return row[G_MIN] - RANGE_TOL <= g <= row[G_MAX] + RANGE_TOL


@njit(cache=True, error_model="numpy")
def in_wedge(row: np.ndarray, d: float) -> bool:
    """Whether the azimuth offset ``d`` from the heading lies in the field of view's wedge."""
    return abs(d) <= row[FOV] + ANGLE_TOL


@njit(cache=True, error_model="numpy")
def visible(row: np.ndarray, dx: float, dy: float, heading: float) -> bool:
    """Whether a target at ground offset ``(dx, dy)`` is in the field of view."""
    g = math.sqrt(dx * dx + dy * dy)
    if not in_band(row, g):
        return False
    if not in_wedge(row, wrap(math.atan2(dy, dx) - heading)):
        return False
    r = math.sqrt(g * g + row[ALTITUDE2])
    return cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r) > 0.0


@njit(cache=True, error_model="numpy")
def measure(row: np.ndarray, dx: float, dy: float, heading: float
            ) -> tuple[float, float, float, float, float, float, float, float, bool]:
    """Noise-free measurement, Jacobian, noise and visibility of one look.

    Returns
    -------
    r, phi : slant range (m) and azimuth (rad)
    h00, h01, h10, h11 : the ground-position Jacobian ``H'`` (row-major)
    var_r, var_phi : noise variances (m^2, rad^2); ``inf`` azimuth variance if cos psi = 0
    visible : bool

    Degenerate geometry never raises: the Jacobian at the nadir (g = 0) is non-finite, as
    numpy's division would give.
    """
    g2 = dx * dx + dy * dy
    r2 = g2 + row[ALTITUDE2]
    r = math.sqrt(r2)
    phi = math.atan2(dy, dx)
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    var_r, var_phi = noise_variances(row, r2, cpsi)
    seen = in_band(row, math.sqrt(g2)) and in_wedge(row, wrap(phi - heading)) and cpsi > 0.0
    return r, phi, dx / r, dy / r, -dy / g2, dx / g2, var_r, var_phi, seen


@njit(cache=True, error_model="numpy")
def inverse(row: np.ndarray, r: float, phi: float, heading: float
            ) -> tuple[float, float, float, float, float]:
    r"""Ground offset of a measurement ``[r, phi]`` and its linearised covariance.

    The inverse of the measurement model: :math:`g = \sqrt{r^2 - z^2}` (0 if the slant range
    is below the altitude), :math:`(dx, dy) = g (\cos\phi, \sin\phi)`, and with the noise
    ``R`` of the model evaluated at that point and :math:`J = \partial(dx, dy) /
    \partial(r, \phi) = [[r/g \cos\phi, -g \sin\phi], [r/g \sin\phi, g \cos\phi]]`, the
    covariance :math:`J R J^T`.

    Returns
    -------
    dx, dy : ground offset from the sensor (m)
    c00, c01, c11 : its covariance (m^2)
    """
    g = math.sqrt(max(r * r - row[ALTITUDE2], 0.0))
    c, s = math.cos(phi), math.sin(phi)
    dx, dy = g * c, g * s
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    var_r, var_phi = noise_variances(row, r * r, cpsi)
    rg = r / max(g, 1e-9)
    j00, j01, j10, j11 = rg * c, -g * s, rg * s, g * c
    return (dx, dy, j00 * j00 * var_r + j01 * j01 * var_phi,
            j00 * j10 * var_r + j01 * j11 * var_phi, j10 * j10 * var_r + j11 * j11 * var_phi)


@njit(cache=True, error_model="numpy")
def _ncdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


@njit(cache=True, error_model="numpy")
def _interval(lo: float, hi: float, sd: float) -> float:
    """``Ncdf(hi/sd) - Ncdf(lo/sd)``; a zero ``sd`` gives the indicator of ``lo <= 0 <= hi``."""
    if sd > 0.0:
        return _ncdf(hi / sd) - _ncdf(lo / sd)
    return 1.0 if (lo <= 0.0 and hi >= 0.0) else 0.0


@njit(cache=True, error_model="numpy")
def range_weight(row: np.ndarray, ux: float, uy: float, g: float, c00: float, c01: float,
                 c11: float, probabilistic: bool) -> float:
    """The range-band factor of a look's weight, for ground range ``g`` along ``(ux, uy)``.

    ``probabilistic``: the probability that the ground range ``N(g, u^T C u)`` lies in the
    band; otherwise the 0/1 band test of the mean.
    """
    if not probabilistic:
        return 1.0 if in_band(row, g) else 0.0
    sd = math.sqrt(max(ux * ux * c00 + 2.0 * ux * uy * c01 + uy * uy * c11, 0.0))
    gmin, gmax = row[G_MIN], row[G_MAX]
    # More than 6 sd outside the band the mass is below Ncdf(-6) ~ 1e-9, far below
    # P_VIS_MIN: skip the two erfc calls (most looks of a large candidate set are far out).
    if sd > 0.0 and (g > gmax + BAND_SIGMAS * sd or g < gmin - BAND_SIGMAS * sd):
        return 0.0
    return _interval(gmin - g, gmax - g, sd)


@njit(cache=True, error_model="numpy")
def reach(row: np.ndarray, c00: float, c01: float, c11: float, probabilistic: bool) -> float:
    """A ground range (m) beyond which no planned look at the target can count.

    :func:`range_weight` is 0 for every ground range above it, in any direction, when the
    target's position covariance has the entries ``c00, c01, c11``: ``g_max + 6 sd`` with
    ``sd`` the largest standard deviation of that covariance (``probabilistic``), else the
    band's edge; both with a margin for round-off. Planners use it to skip far candidates
    without evaluating them.
    """
    if probabilistic:
        lam = 0.5 * (c00 + c11) + math.sqrt(0.25 * (c00 - c11) ** 2 + c01 * c01)
        edge = row[G_MAX] + BAND_SIGMAS * math.sqrt(max(lam, 0.0) * (1.0 + 1e-9))
    else:
        edge = row[G_MAX] + RANGE_TOL
    return edge * (1.0 + 1e-12) + 1e-9


@njit(cache=True, error_model="numpy")
def look(row: np.ndarray, dx: float, dy: float, heading: float, c00: float, c01: float,
         c11: float, probabilistic: bool) -> tuple[float, float, float, float]:
    """Weight ``p`` and information ``p H'^T R^{-1} H'`` (w00, w01, w11) of a planned look.

    ``probabilistic``: ``p = p_vis`` of a target at ``N((dx, dy), C)``, C given by its
    entries c00, c01, c11; otherwise ``p`` is the 0/1 visibility of the mean. A look with
    ``p < P_VIS_MIN`` gives zeros.
    """
    p, g2, g = look_range(row, dx, dy, c00, c01, c11, probabilistic)
    if p < P_VIS_MIN:
        return 0.0, 0.0, 0.0, 0.0
    return look_in_range(row, dx, dy, g2, g, p, heading, c00, c01, c11, probabilistic)


@njit(cache=True, error_model="numpy")
def look_range(row: np.ndarray, dx: float, dy: float, c00: float, c01: float, c11: float,
               probabilistic: bool) -> tuple[float, float, float]:
    """The heading-free first part of :func:`look`: the range factor ``p`` of the weight
    (:func:`range_weight`; 0 at the nadir), with ``g^2`` and ``g``."""
    g2 = dx * dx + dy * dy
    if g2 == 0.0:
        return 0.0, g2, 0.0
    g = math.sqrt(g2)
    return range_weight(row, dx / g, dy / g, g, c00, c01, c11, probabilistic), g2, g


@njit(cache=True, error_model="numpy")
def look_in_range(row: np.ndarray, dx: float, dy: float, g2: float, g: float, p: float,
                  heading: float, c00: float, c01: float, c11: float,
                  probabilistic: bool) -> tuple[float, float, float, float]:
    """The rest of :func:`look` given :func:`look_range`'s ``p >= P_VIS_MIN``, ``g2``, ``g``
    (a planner computes that part once for looks that differ only in heading)."""
    return look_at_azimuth(row, dx, dy, g2, g, p, math.atan2(dy, dx), heading, c00, c01, c11,
                           probabilistic)


@njit(cache=True, error_model="numpy")
def look_at_azimuth(row: np.ndarray, dx: float, dy: float, g2: float, g: float, p: float,
                    azimuth: float, heading: float, c00: float, c01: float, c11: float,
                    probabilistic: bool) -> tuple[float, float, float, float]:
    """:func:`look_in_range` given the azimuth ``atan2(dy, dx)`` (a planner that has just
    computed the same bearing for the heading rule passes it on)."""
    ux, uy = dx / g, dy / g
    r2 = g2 + row[ALTITUDE2]
    r = math.sqrt(r2)
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    if cpsi <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    d = wrap(azimuth - heading)
    if probabilistic:
        sd_phi = math.sqrt(max(uy * uy * c00 - 2.0 * ux * uy * c01 + ux * ux * c11, 0.0)) / g
        fov = row[FOV]
        p *= _interval(-fov - d, fov - d, sd_phi)
        if p < P_VIS_MIN:
            return 0.0, 0.0, 0.0, 0.0
    elif not in_wedge(row, d):
        return 0.0, 0.0, 0.0, 0.0
    var_r, var_phi = noise_variances(row, r2, cpsi)
    # H'^T R^-1 H' in closed form: a a^T / var_r + b b^T / var_phi with the rows of H',
    # a = (dx, dy) / r and b = (-dy, dx) / g^2.
    wr = p / (var_r * r2)
    wp = p / (var_phi * g2 * g2)
    return p, wr * dx * dx + wp * dy * dy, (wr - wp) * dx * dy, wr * dy * dy + wp * dx * dx


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
def _look_batch(row: np.ndarray, dx: np.ndarray, dy: np.ndarray, th: np.ndarray,
                C: np.ndarray, probabilistic: bool) -> tuple[np.ndarray, np.ndarray]:
    n = dx.shape[0]
    W = np.zeros((n, 2, 2))
    weight = np.zeros(n)
    for b in range(n):
        p, w00, w01, w11 = look(row, dx[b], dy[b], th[b], C[b, 0], C[b, 1], C[b, 2],
                                probabilistic)
        weight[b] = p
        W[b, 0, 0] = w00
        W[b, 0, 1] = w01
        W[b, 1, 0] = w01
        W[b, 1, 1] = w11
    return W, weight


# ------------------------------------------------------------------ numpy-facing wrappers


def _flat(a: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=dtype).ravel()


def measure_looks(table: FloatArray, sensor: IntArray, target_xy: FloatArray,
                  sensor_xy: FloatArray, heading: FloatArray
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
    shape = np.broadcast_shapes(dx.shape, np.shape(heading), np.shape(sensor))
    b = [np.broadcast_to(a, shape) for a in (dx, dy, heading, sensor)]
    h, H, var, seen = _measure_batch(np.ascontiguousarray(table, dtype=float),
                                     _flat(b[3], np.int64), _flat(b[0]), _flat(b[1]),
                                     _flat(b[2]))
    return (h.reshape(shape + (2,)), H.reshape(shape + (2, 2)), var.reshape(shape + (2,)),
            seen.reshape(shape))


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


def look_information(row: FloatArray, dx: FloatArray, dy: FloatArray, th: FloatArray,
                     C: FloatArray, probabilistic: bool) -> tuple[FloatArray, FloatArray]:
    """Weight and information of planned looks by one sensor (see :func:`look`).

    Parameters
    ----------
    row : (C,) the sensor's radar table row
    dx, dy, th : (...)  ground offsets of the target's predicted mean (m), headings (rad)
    C : (..., 3)        predicted position covariance entries (c00, c01, c11) (m^2)
    probabilistic : bool

    Returns
    -------
    W : (..., 2, 2)   ``p H'^T R^{-1} H'`` (1/m^2), zero where the look does not count
    weight : (...)    ``p`` (0 where the look does not count)
    """
    shape = np.broadcast_shapes(np.shape(dx), np.shape(dy), np.shape(th))
    W, weight = _look_batch(np.ascontiguousarray(row, dtype=float),
                            _flat(np.broadcast_to(dx, shape)), _flat(np.broadcast_to(dy, shape)),
                            _flat(np.broadcast_to(th, shape)),
                            np.ascontiguousarray(np.broadcast_to(C, shape + (3,))).reshape(-1, 3),
                            bool(probabilistic))
    return W.reshape(shape + (2, 2)), weight.reshape(shape)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the batched kernels on tiny inputs."""
    table = np.zeros((1, 11))
    table[0, ALTITUDE] = table[0, ALTITUDE2] = 1.0
    z = np.zeros(1)
    i = np.zeros(1, dtype=np.int64)
    _measure_batch(table, i, z + 1.0, z, z)
    _inverse_batch(table, i, np.ones((1, 2)), z)
    _visible_grid(table, i, np.ones((1, 1)), np.zeros((1, 1)), z)
    for probabilistic in (True, False):
        _look_batch(table[0], z + 1.0, z, z, np.ones((1, 3)), probabilistic)
