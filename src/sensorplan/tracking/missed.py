r"""Negative information from missed looks (``miss_update = "negative"``).

A sensor that looked for a target and did not detect it learns that the target is
probably not in its sensing region :math:`A` (range band, azimuth wedge around the heading,
:math:`\cos\psi > 0`). The predicted track :math:`N(m, P)` is replaced by the
Gaussian with the first two moments of its restriction to the outside of :math:`A`,

.. math::
    m' = E[x \mid x \notin A],\qquad P' = \mathrm{Cov}[x \mid x \notin A],

computed by a fixed deterministic quadrature: ``S = 512`` whitened standard-normal points
:math:`\xi_s` (mean exactly 0, covariance exactly ``I`` with weights ``1/S``) are mapped to
:math:`x_s = m + L \xi_s` with :math:`P = L L^T`, the points inside :math:`A` are dropped,
and the remaining ``n`` points are moment matched with weights ``1/n``:

.. math::
    \mu = \frac1n \sum_{s \notin A} \xi_s,\quad
    C = \frac1n \sum_{s \notin A} \xi_s \xi_s^T - \mu \mu^T,\quad
    m' = m + L \mu,\quad P' = L C L^T .

When the fraction ``f = (S - n) / S`` of points inside is ``>= 0.95`` the filter was
inconsistent (it was almost sure the target was there): the track is not truncated, each
position variance grows by :math:`(g_{max} - g_{min})^2 / 4` instead.

With imperfect detection the rule generalises: a point inside the sensing region keeps the
weight :math:`1 - P_d P_G` (the probability that a target there gave no gated detection;
:math:`P_d` from the radar model at the point's range, :math:`P_G` the gate probability)
instead of being dropped, a point outside keeps weight 1, and the moments are the weighted
ones. With :math:`P_d = P_G = 1` the weights are exactly 0 and 1: the rule above. The
maths, the choices and the accuracy are documented in docs/model.md.

Buildings enter twice. A building hides what is behind it, so a point it hides from the
sensor keeps its weight (a look cannot learn that a target is absent from a place it cannot
see). And no target is ever inside a building: with ``footprints`` the points inside one get
weight 0, so the update conditions on both facts at once, the miss and the known map (a
building hides its own footprint from every sensor, so without this a run of misses would
pile the track's mass onto the one place no target can be).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import solve_triangular
from scipy.special import ndtri
from scipy.stats import qmc

from .._compiled.jit import njit
from .._types import BoolArray, FloatArray, IntArray
from ..models import radar
from ..models.sensors import G_MAX, G_MIN, SensorParams, radar_table

#: Number of quadrature points.
N_POINTS = 512
#: Seed of the scrambled Sobol sequence behind the default point set.
SOBOL_SEED = 20250305
#: Inside fraction at or above which the track is inflated instead of truncated.
INFLATE_FRACTION = 0.95
#: Fewest points kept for a truncation: d + 1 points are needed for a full-rank 4-D
#: covariance. Fewer fall back to inflation; with S = 512 and f < 0.95 at least 26 remain,
#: so this only guards smaller user-supplied point sets.
MIN_OUTSIDE = 5


@functools.lru_cache(maxsize=8)
def standard_points(n: int = N_POINTS, seed: int = SOBOL_SEED) -> FloatArray:
    """Deterministic whitened standard-normal points in 4-D.

    Scrambled Sobol points (``scipy.stats.qmc.Sobol``, seeded) are mapped through the inverse
    normal CDF, centred, and multiplied by the inverse Cholesky factor of their sample
    covariance (normalised by ``1/n``), so that their mean is 0 and their covariance ``I`` to
    rounding (about 1e-16).

    Parameters
    ----------
    n : int
        Number of points, a power of two (Sobol balance properties).
    seed : int
        Scrambling seed.

    Returns
    -------
    (n, 4) float64, read-only (the result is cached).

    Examples
    --------
    >>> X = standard_points()
    >>> X.shape, bool(np.allclose(X.T @ X / len(X), np.eye(4), atol=1e-12))
    ((512, 4), True)
    """
    if n < 8 or n & (n - 1):
        raise ValueError(f"n must be a power of two >= 8, got {n}")
    u = _sobol(n, seed)
    z = ndtri(u)
    z = z - z.mean(axis=0)
    chol = np.linalg.cholesky(z.T @ z / n)
    x = solve_triangular(chol, z.T, lower=True).T
    # A second centring removes the O(1e-17) mean the solve leaves behind; it changes the
    # covariance by O(1e-34).
    x = x - x.mean(axis=0)
    x.flags.writeable = False
    return x


def _sobol(n: int, seed: int) -> FloatArray:
    try:
        engine = qmc.Sobol(d=4, scramble=True, rng=np.random.default_rng(seed))
    except TypeError:  # scipy < 1.15 names the argument ``seed``
        engine = qmc.Sobol(d=4, scramble=True, seed=np.random.default_rng(seed))
    return engine.random_base2(int(np.log2(n)))


def _outer(x: FloatArray) -> FloatArray:
    """Outer products ``x_s x_s^T`` of points ``(S, 4)``, flattened to ``(S, 16)``."""
    return (x[:, :, None] * x[:, None, :]).reshape(len(x), 16)


@functools.cache
def _default_point_set() -> tuple[FloatArray, FloatArray]:
    x = standard_points()
    xx = _outer(x)
    xx.flags.writeable = False
    return x, xx


def _point_set(points: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """Points ``(S, 4)`` and their outer products ``(S, 16)``."""
    if points is None:
        return _default_point_set()
    x = np.asarray(points, dtype=float)
    if x.ndim != 2 or x.shape[1] != 4:
        raise ValueError(f"points must be (S, 4), got {x.shape}")
    return x, _outer(x)


def _inside(means: FloatArray, chol: FloatArray, x: FloatArray, sensor_xy: FloatArray,
            heading: FloatArray, table: FloatArray, sensor: IntArray,
            buildings: FloatArray | None = None) -> FloatArray:
    """Probability that the look detects a target at each mapped point ``m + L x_s``,
    ``(..., S)``: its detection probability inside the sensing region, 0 outside (exactly
    0 or 1 with ideal detection)."""
    # L is lower triangular, so the ground position of a point depends on its first two
    # whitened coordinates and the 2x2 position block of L only; the compiled call forms
    # the points' offsets itself (a dozen numpy calls over (..., S) arrays otherwise).
    base = means[..., :2] - sensor_xy                                        # (..., 2)
    batch = base.shape[:-1]
    if chol.shape[:-2] != batch:
        batch = np.broadcast_shapes(batch, chol.shape[:-2])
        base = np.broadcast_to(base, batch + (2,))
        chol = np.broadcast_to(chol, batch + (4, 4))
    S = x.shape[0]
    sxy = None if buildings is None else np.broadcast_to(sensor_xy, batch + (2,)).reshape(-1, 2)
    inside = radar.detectable_quadrature(table, _flat_batch(sensor, batch), base.reshape(-1, 2),
                                         chol.reshape(-1, 4, 4), x, _flat_batch(heading, batch),
                                         sxy, buildings)
    return inside.reshape(batch + (S,))


def in_footprints(means: FloatArray, chol: FloatArray, x: FloatArray,
                  buildings: FloatArray) -> BoolArray:
    """Whether the ground position of each point ``m + L x_s`` is strictly inside a
    building's footprint (a point on a wall is outside, as for the targets).

    Parameters
    ----------
    means : (B, 4);  chol : (B, 4, 4) lower Cholesky factors;  x : (S, 4) whitened points
    buildings : (K, 5)   ``x0, y0, x1, y1, height``

    Returns
    -------
    (B, S, K) bool
    """
    pts = means[:, None, :2] + np.einsum("bij,sj->bsi", chol[:, :2, :2], x[:, :2])
    px, py = pts[..., 0, None], pts[..., 1, None]
    b = np.asarray(buildings, dtype=float).reshape(-1, 5)
    return (px > b[:, 0]) & (px < b[:, 2]) & (py > b[:, 1]) & (py < b[:, 3])


def _flat_batch(a: np.ndarray, batch: tuple[int, ...]) -> np.ndarray:
    """``a`` broadcast to ``batch`` and flattened (no broadcast_to call when it has the
    shape already: its overhead dominates these tiny batches)."""
    return (a if a.shape == batch else np.broadcast_to(a, batch)).reshape(-1)


def _rows(table: FloatArray | SensorParams, sensor: IntArray | int | None,
          ) -> tuple[FloatArray, IntArray]:
    """A radar table and each look's row in it; a SensorParams is a one-row table."""
    if isinstance(table, SensorParams):
        return radar_table(table), np.zeros((), dtype=np.int64)
    return (np.ascontiguousarray(table, dtype=float),
            np.asarray(0 if sensor is None else sensor, dtype=np.int64))


def inside_fraction(means: FloatArray, covs: FloatArray, sensor_xy: FloatArray,
                    heading: FloatArray, table: FloatArray | SensorParams,
                    sensor: IntArray | int | None = None, *,
                    points: FloatArray | None = None) -> FloatArray:
    """Fraction ``f`` of the quadrature points of each track inside the sensing region.

    The quadrature estimate of the probability mass of :math:`N(m, P)` that a look from
    ``(sensor_xy, heading)`` covers; :func:`miss_update` inflates when it is ``>= 0.95``.
    Arguments as in :func:`miss_update`.

    Returns
    -------
    (...,) float64 in [0, 1], a multiple of ``1/S``.
    """
    x, _ = _point_set(points)
    table, sensor = _rows(table, sensor)
    means = np.asarray(means, dtype=float)
    chol = np.linalg.cholesky(np.asarray(covs, dtype=float))
    inside = _inside(means, chol, x, np.asarray(sensor_xy, dtype=float),
                     np.asarray(heading, dtype=float), table, sensor)
    return np.count_nonzero(inside > 0, axis=-1) / x.shape[0]


def miss_update(means: FloatArray, covs: FloatArray, sensor_xy: FloatArray,
                heading: FloatArray, table: FloatArray | SensorParams,
                sensor: IntArray | int | None = None, *,
                points: FloatArray | None = None, gate_probability: float = 1.0,
                buildings: FloatArray | None = None,
                footprints: FloatArray | None = None,
                return_fraction: bool = False) -> tuple[FloatArray, ...]:
    r"""Update tracks with a missed look (``negative``), batched over tracks.

    Each track :math:`N(m, P)` is replaced by the moments of its restriction to the outside
    of the sensing region of a sensor at ``sensor_xy`` heading ``heading`` (see the module
    docstring), or, when the fraction of quadrature points inside is ``>= 0.95`` (or fewer
    than :data:`MIN_OUTSIDE` points would remain), keeps its mean and gets
    :math:`(g_{max} - g_{min})^2 / 4` added to both position variances.

    Parameters
    ----------
    means : (..., 4) float64
        Predicted means ``[x, y, vx, vy]`` (m, m/s).
    covs : (..., 4, 4) float64
        Predicted covariances, symmetric positive definite.
    sensor_xy : (..., 2) float64
        Ground position of the sensor that missed (m).
    heading : (...) float64
        Its heading (rad).
    table : (N, C) float64 or SensorParams
        Radar table of the sensors (:func:`sensorplan.models.sensors.radar_table`); one
        SensorParams stands for a one-row table.
    sensor : (...) int, optional
        Row of ``table`` of the sensor that missed, broadcastable to the batch shape
        (default row 0).
    points : (S, 4) float64, optional
        Whitened standard-normal points (mean 0 and covariance ``I`` with weights ``1/S``);
        default the cached 512 Sobol points of :func:`standard_points`.
    gate_probability : float
        Pg of the tracker's gate: a target detected outside the gate would not have been
        associated, so the look's miss means "not detected in the gate".
    buildings : (K, 5) float64, optional
        Buildings ``x0, y0, x1, y1, height``: a point they hide from the sensor counts as
        outside the sensing region (the look could not have seen a target there).
    footprints : (K, 5) float64, optional
        Buildings no target is ever inside: points in their footprints get weight 0 (the
        update conditions on the miss and on the target being outside every building).
    return_fraction : bool
        Also return the probability mass the look removes (the probability, under the
        track, that the look should have detected the target in its gate).

    Returns
    -------
    means : (..., 4) float64
    covs : (..., 4, 4) float64
        Symmetric positive definite.
    inflated : (...,) bool
        Whether the inflation rule was applied instead of the truncation.
    fraction : (...,) float64
        Only with ``return_fraction``: the fraction ``f`` of points inside.

    Raises
    ------
    numpy.linalg.LinAlgError
        If a covariance is not positive definite.

    Examples
    --------
    >>> m = np.array([250.0, 0.0, 1.0, 0.0]); P = np.diag([900.0, 900.0, 4.0, 4.0])
    >>> m2, P2, infl = miss_update(m, P, np.zeros(2), 0.0, SensorParams())
    >>> bool(infl), bool(m2[0] < 250.0), bool(P2[0, 0] < 900.0)
    (False, True, True)
    """
    x, xx = _point_set(points)
    table, sensor = _rows(table, sensor)
    S = x.shape[0]
    means = np.asarray(means, dtype=float)
    covs = np.asarray(covs, dtype=float)
    heading = np.asarray(heading, dtype=float)
    chol = np.asarray(np.linalg.cholesky(covs), dtype=float)      # (typed float64, no copy)
    inside = _inside(means, chol, x, np.asarray(sensor_xy, dtype=float), heading, table,
                     sensor, buildings)

    # Each point keeps the probability that the look would NOT have produced a gated
    # detection of a target there: 1 - Pd Pg inside the sensing region, 1 outside. With
    # ideal detection and no gate the weights are exactly 0 and 1: the points inside are
    # dropped.
    w = 1.0 - gate_probability * inside
    if footprints is not None and len(footprints):
        flat = _flat_rows(means, w.shape[:-1], (4,))
        solid = in_footprints(flat, _flat_rows(chol, w.shape[:-1], (4, 4)), x,
                              footprints).any(axis=-1)
        w = np.where(solid.reshape(w.shape), 0.0, w)
    n_out = w.sum(axis=-1)
    batch = n_out.shape
    # The elementwise steps run compiled, in numpy's order; the matrix products stay numpy's.
    mu, C, inflated, fraction = _weighted_moments((w @ x).reshape(-1, 4),
                                                  (w @ xx).reshape(-1, 16),
                                                  n_out.reshape(-1), S)
    mu, C = mu.reshape(batch + (4,)), C.reshape(batch + (4, 4))
    shift = (chol @ mu[..., :, None])[..., 0]
    spread = chol @ C @ np.swapaxes(chol, -1, -2)
    new_means, new_covs = _miss_result(
        _flat_rows(means, batch, (4,)), _flat_rows(covs, batch, (4, 4)),
        shift.reshape(-1, 4), spread.reshape(-1, 4, 4), inflated, table,
        _flat_batch(sensor, batch))
    new_means, new_covs = new_means.reshape(batch + (4,)), new_covs.reshape(batch + (4, 4))
    inflated = inflated.reshape(batch)
    if return_fraction:
        return new_means, new_covs, inflated, fraction.reshape(batch)
    return new_means, new_covs, inflated


def _flat_rows(a: np.ndarray, batch: tuple[int, ...], row: tuple[int, ...]) -> np.ndarray:
    """``a`` broadcast to ``batch + row``, as contiguous ``(-1,) + row``."""
    shape = batch + row
    return np.ascontiguousarray(a if a.shape == shape else np.broadcast_to(a, shape)
                                ).reshape((-1,) + row)


@njit(cache=True, error_model="numpy")
def _weighted_moments(wx: np.ndarray, wxx: np.ndarray, n_out: np.ndarray, S: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Moments of the weighted points: ``mu = w x / n``, ``C = w x x^T / n - mu mu^T``
    (``n`` the kept weight, or S for an inflated track), the inflation rule and the
    fraction ``(S - n) / S`` of the weight the look removed."""
    B = n_out.shape[0]
    mu = np.empty((B, 4))
    C = np.empty((B, 4, 4))
    inflated = np.empty(B, dtype=np.bool_)
    fraction = np.empty(B)
    for b in range(B):
        f = (S - n_out[b]) / S
        fraction[b] = f
        infl = (f >= INFLATE_FRACTION) | (n_out[b] < MIN_OUTSIDE)
        inflated[b] = infl
        # Inflated rows are discarded below; any n > 0 keeps their arithmetic finite.
        n = float(S) if infl else n_out[b]
        for i in range(4):
            mu[b, i] = wx[b, i] / n
        for i in range(4):
            for j in range(4):
                C[b, i, j] = wxx[b, 4 * i + j] / n - mu[b, i] * mu[b, j]
    return mu, C, inflated, fraction


@njit(cache=True, error_model="numpy")
def _miss_result(means: np.ndarray, covs: np.ndarray, shift: np.ndarray, spread: np.ndarray,
                 inflated: np.ndarray, table: np.ndarray, sensor: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``m + L mu`` and ``L C L^T``, or for an inflated track ``m`` and ``P`` with
    ``(g_max - g_min)^2 / 4`` added to both position variances; symmetrised."""
    B = means.shape[0]
    new_means = np.empty((B, 4))
    new_covs = np.empty((B, 4, 4))
    X = np.empty((4, 4))
    for b in range(B):
        if inflated[b]:
            span = table[sensor[b], G_MAX] - table[sensor[b], G_MIN]
            grow = 0.25 * span * span
            for i in range(4):
                new_means[b, i] = means[b, i]
                for j in range(4):
                    X[i, j] = covs[b, i, j] + (grow if i == j and i < 2 else 0.0)
        else:
            for i in range(4):
                new_means[b, i] = means[b, i] + shift[b, i]
                for j in range(4):
                    X[i, j] = spread[b, i, j]
        for i in range(4):
            for j in range(4):
                new_covs[b, i, j] = 0.5 * (X[i, j] + X[j, i])
    return new_means, new_covs
