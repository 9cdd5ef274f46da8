r"""The map is known: a track is truncated to the map it cannot leave, and moved out of the
buildings it cannot enter.

Targets never leave the map ``[0, W] x [0, H]``, so a filter whose position estimate (or its
3-sigma extent) lies outside it is knowably wrong. The map is applied as negative
information: the Gaussian track :math:`N(m, P)` is replaced by the Gaussian with the first
two moments of its restriction to the map.

The map is an axis-aligned box, so the restriction is done exactly one axis at a time
(density truncation, as in constrained Kalman filtering: Simon & Simon, "Constrained
Kalman filtering via density function truncation for turbofan engine health estimation",
Int. J. Systems Science 41(2), 2010). Truncating the Gaussian to :math:`a \le x_k \le b`
leaves every other component Gaussian given :math:`x_k`, so with the standardised bounds
:math:`\alpha = (a - m_k)/s`, :math:`\beta = (b - m_k)/s`, :math:`s^2 = P_{kk}`, the
truncated normal's mean :math:`\mu_t` and variance :math:`v_t`, and
:math:`u = P_{\cdot k} / P_{kk}`:

.. math::
    m' = m + u\,(\mu_t - m_k),\qquad P' = P - (P_{kk} - v_t)\, u u^T .

Each axis step is exact for that axis, moves the mean to the map's side and never increases
any variance (:math:`P' \preceq P`, since :math:`v_t \le P_{kk}`). The x step is followed by
the y step on the moment-matched result; a strong x-y correlation can then leave the mean a
little outside in x, in which case the mean (only) is projected onto the map. The constraint
is applied only when the mean or its 3-sigma box leaves the map, so tracks well inside are
never touched.

Buildings (:func:`building_constraint`) are the same knowledge: no target is ever inside a
footprint. Their complement is not a box, so the restriction is computed with the
missed-look update's quadrature (:mod:`sensorplan.tracking.missed`): the 512 whitened
points mapped through the track, those inside a footprint dropped, the rest moment matched.

The elementwise arithmetic runs in small compiled kernels; the transcendental functions
(``log_ndtr``, ``exp``, ``log1p``) stay numpy's and scipy's, so the results are the ones
the plain numpy formulas give, bit for bit (numba's ``exp`` would round differently from
numpy's vectorised one). A track's truncation is a few hundred flops spread over a
hundred numpy calls otherwise, and the tracker applies the map twice a step.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import log_ndtr, ndtr, owens_t

from .._compiled.jit import njit
from .._types import BoolArray, FloatArray, IntArray

#: What a multi-target tracker assumes of a target that reaches the map's edge
#: (:func:`map_edge_predict`): it leaves the map and is gone, or it stays in the map.
MAP_EDGES = ("exit", "closed")

#: Extent (in standard deviations per axis) that must stay inside the map for a track to be
#: left untouched.
N_SIGMA = 3.0
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


# ------------------------------------------------------------------ compiled kernels
# Every formula is written in the order of the numpy expression it replaces (the comments
# give it), so that the rounding is the same.


@njit(cache=True, error_model="numpy", inline="always")
def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of one float: NaN passes through, ties keep the bound."""
    if not np.isnan(x):
        x = x if x > lo else lo
    if not np.isnan(x):
        x = x if x < hi else hi
    return x


@njit(cache=True, error_model="numpy")
def _mirror(alpha: np.ndarray, beta: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bounds mirrored to the lower half-line: ``a, b, flip``."""
    n = alpha.shape[0]
    a, b = np.empty(n), np.empty(n)
    flip = np.empty(n, dtype=np.bool_)
    for r in range(n):
        f = alpha[r] > -beta[r]                      # interval mostly above 0: mirror it
        flip[r] = f
        a[r] = -beta[r] if f else alpha[r]
        b[r] = -alpha[r] if f else beta[r]
    return a, b, flip


@njit(cache=True, error_model="numpy")
def _standardise(means: np.ndarray, covs: np.ndarray, k: int, lo: float, hi: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mirrored standardised bounds ``(lo - m_k)/s, (hi - m_k)/s`` of rows ``(B, 4)``."""
    n = means.shape[0]
    alpha, beta = np.empty(n), np.empty(n)
    for r in range(n):
        s = np.sqrt(covs[r, k, k])
        alpha[r] = (lo - means[r, k]) / s
        beta[r] = (hi - means[r, k]) / s
    return _mirror(alpha, beta)


@njit(cache=True, error_model="numpy")
def _density_args(a: np.ndarray, b: np.ndarray, log_mass: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Logs of the density-to-mass ratios at the bounds (``-0.5 a a - c - log_mass``)."""
    n = a.shape[0]
    ea, eb = np.empty(n), np.empty(n)
    for r in range(n):
        ea[r] = -0.5 * a[r] * a[r] - _LOG_SQRT_2PI - log_mass[r]
        eb[r] = -0.5 * b[r] * b[r] - _LOG_SQRT_2PI - log_mass[r]
    return ea, eb


@njit(cache=True, error_model="numpy", inline="always")
def _moments_at(a: float, b: float, flip: bool, pa: float, pb: float) -> tuple[float, float]:
    """Mean and variance of one truncated standard normal from its boundary ratios."""
    fa, fb = np.isfinite(a), np.isfinite(b)
    pa = pa if fa else 0.0
    pb = pb if fb else 0.0
    mean = pa - pb
    a_pa = a * pa if fa else 0.0
    b_pb = b * pb if fb else 0.0
    var = 1.0 + a_pa - b_pb - mean * mean
    # Cancellation far in a tail can leave a tiny or negative variance: keep it in (0, 1].
    var = _clip(var, 1e-12, 1.0)
    mean = _clip(mean, a, b)
    return (-mean if flip else mean), var


@njit(cache=True, error_model="numpy")
def _moments(a: np.ndarray, b: np.ndarray, flip: np.ndarray, pa: np.ndarray, pb: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    n = a.shape[0]
    mean, var = np.empty(n), np.empty(n)
    for r in range(n):
        mean[r], var[r] = _moments_at(a[r], b[r], flip[r], pa[r], pb[r])
    return mean, var


@njit(cache=True, error_model="numpy")
def _shift(means: np.ndarray, covs: np.ndarray, k: int, a: np.ndarray, b: np.ndarray,
           flip: np.ndarray, pa: np.ndarray, pb: np.ndarray) -> None:
    """Condition rows ``(B, 4)``, ``(B, 4, 4)`` on their truncation along axis k, in place:
    ``m + u s mu``, ``sym(P - s2 (1 - var) u u^T)``, ``u = P[:, k] / s2``."""
    u = np.empty(4)
    N = np.empty((4, 4))
    for r in range(means.shape[0]):
        mu, var = _moments_at(a[r], b[r], flip[r], pa[r], pb[r])
        s2 = covs[r, k, k]
        s = np.sqrt(s2)
        for i in range(4):
            u[i] = covs[r, i, k] / s2
        d = s * mu
        shrink = s2 * (1.0 - var)                                    # P_kk - v_t >= 0
        for i in range(4):
            means[r, i] = means[r, i] + u[i] * d
            for j in range(4):
                N[i, j] = covs[r, i, j] - shrink * u[i] * u[j]
        for i in range(4):
            for j in range(4):
                covs[r, i, j] = 0.5 * (N[i, j] + N[j, i])


@njit(cache=True, error_model="numpy")
def _outside_rows(means: np.ndarray, covs: np.ndarray, width: float, height: float,
                  n_sigma: float) -> np.ndarray:
    n = means.shape[0]
    hit = np.empty(n, dtype=np.bool_)
    for r in range(n):
        sx = n_sigma * np.sqrt(covs[r, 0, 0])
        sy = n_sigma * np.sqrt(covs[r, 1, 1])
        x, y = means[r, 0], means[r, 1]
        hit[r] = (x - sx < 0.0) | (x + sx > width) | (y - sy < 0.0) | (y + sy > height)
    return hit


@njit(cache=True, error_model="numpy")
def _scatter(means: np.ndarray, covs: np.ndarray, rows: np.ndarray, mh: np.ndarray,
             Ph: np.ndarray, lx: np.ndarray, ly: np.ndarray, width: float, height: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Copies of the tracks with the truncated rows put back (means projected on the map)
    and the log-mass of each track (0 where not truncated)."""
    m, P = means.copy(), covs.copy()
    log_mass = np.zeros(means.shape[0])
    for h in range(rows.shape[0]):
        r = rows[h]
        m[r, :] = mh[h]
        # Correlation can move x back out a little during the y step: project the mean.
        m[r, 0] = _clip(mh[h, 0], 0.0, width)
        m[r, 1] = _clip(mh[h, 1], 0.0, height)
        P[r] = Ph[h]
        log_mass[r] = lx[h] + ly[h]
    return m, P, log_mass


@njit(cache=True, error_model="numpy")
def _select(means: np.ndarray, covs: np.ndarray, width: float, height: float,
            n_sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                     np.ndarray, np.ndarray, np.ndarray]:
    """The tracks that leave the map (mask and rows), copies of their rows and the
    mirrored bounds of their x truncation (one call instead of five)."""
    hit = _outside_rows(means, covs, width, height, n_sigma)
    rows = np.flatnonzero(hit)
    mh = np.empty((rows.shape[0], 4))
    Ph = np.empty((rows.shape[0], 4, 4))
    for h in range(rows.shape[0]):
        mh[h] = means[rows[h]]
        Ph[h] = covs[rows[h]]
    a, b, flip = _standardise(mh, Ph, 0, 0.0, width)
    return hit, rows, mh, Ph, a, b, flip


@njit(cache=True, error_model="numpy")
def _shift_x_then_standardise_y(mh: np.ndarray, Ph: np.ndarray, a: np.ndarray,
                                b: np.ndarray, flip: np.ndarray, pa: np.ndarray,
                                pb: np.ndarray, height: float
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _shift(mh, Ph, 0, a, b, flip, pa, pb)
    return _standardise(mh, Ph, 1, 0.0, height)


@njit(cache=True, error_model="numpy")
def _shift_y_then_scatter(means: np.ndarray, covs: np.ndarray, rows: np.ndarray,
                          mh: np.ndarray, Ph: np.ndarray, a: np.ndarray, b: np.ndarray,
                          flip: np.ndarray, pa: np.ndarray, pb: np.ndarray, lx: np.ndarray,
                          ly: np.ndarray, width: float, height: float
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _shift(mh, Ph, 1, a, b, flip, pa, pb)
    return _scatter(means, covs, rows, mh, Ph, lx, ly, width, height)


def _tails(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Log-mass of ``[a, b]`` (``a <= -b``) and the density-to-mass ratios at its bounds
    (call with floating-point errors ignored)."""
    # Ncdf(b) is the larger term and not in the far upper tail.
    la, lb = log_ndtr(a), log_ndtr(b)
    log_mass = lb + np.log1p(-np.exp(la - lb))
    ea, eb = _density_args(a, b, log_mass)
    return log_mass, np.exp(ea), np.exp(eb)


# ------------------------------------------------------------------ public functions


def truncated_normal_moments(alpha: FloatArray, beta: FloatArray
                             ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean, variance and log-mass of a standard normal truncated to ``[alpha, beta]``.

    Stable far in the tails: the interval is mirrored to the lower half-line and the ratios
    of density to mass are formed in log space. ``alpha`` may be ``-inf`` and ``beta``
    ``+inf``.

    Returns
    -------
    mean : (...)      in [alpha, beta]
    var : (...)       in (0, 1]
    log_mass : (...)  log(Ncdf(beta) - Ncdf(alpha))
    """
    alpha, beta = np.broadcast_arrays(np.asarray(alpha, dtype=float),
                                      np.asarray(beta, dtype=float))
    shape = alpha.shape
    a, b, flip = _mirror(np.ascontiguousarray(alpha).reshape(-1),
                         np.ascontiguousarray(beta).reshape(-1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_mass, pa, pb = _tails(a, b)
    mean, var = _moments(a, b, flip, pa, pb)
    return mean.reshape(shape), var.reshape(shape), log_mass.reshape(shape)


def truncate_axis(means: FloatArray, covs: FloatArray, axis: int, lo: float, hi: float
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Moments of Gaussians ``(B, 4)``, ``(B, 4, 4)`` truncated to ``lo <= x[axis] <= hi``.

    Returns
    -------
    means : (B, 4), covs : (B, 4, 4) (symmetrised), log_mass : (B,) the log of the
    probability mass inside.
    """
    means = np.array(means, dtype=float, order="C")
    covs = np.array(covs, dtype=float, order="C")
    a, b, flip = _standardise(means, covs, axis, float(lo), float(hi))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_mass, pa, pb = _tails(a, b)
    _shift(means, covs, axis, a, b, flip, pa, pb)
    return means, covs, log_mass


def outside(means: FloatArray, covs: FloatArray, width: float, height: float,
            n_sigma: float = N_SIGMA) -> BoolArray:
    """Tracks whose mean or ``n_sigma`` box (per axis) leaves ``[0, W] x [0, H]``."""
    means = np.asarray(means, dtype=float)
    m = np.ascontiguousarray(means).reshape(-1, 4)
    P = np.ascontiguousarray(covs, dtype=float).reshape(-1, 4, 4)
    return _outside_rows(m, P, float(width), float(height), float(n_sigma)).reshape(
        means.shape[:-1])


def map_constraint(means: FloatArray, covs: FloatArray, width: float, height: float,
                   n_sigma: float = N_SIGMA
                   ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]:
    """Truncate the tracks that leave the map to it (see the module docstring).

    Parameters
    ----------
    means : (..., 4), covs : (..., 4, 4)
    width, height : float   the map ``[0, W] x [0, H]`` (m)
    n_sigma : float         per-axis extent that must stay inside to be left untouched

    Returns
    -------
    means : (..., 4), covs : (..., 4, 4)
    applied : (...) bool       which tracks were truncated
    log_mass : (...)           log-probability (under the input track) that the target is
                               on the map: 0 where not applied
    """
    means = np.asarray(means, dtype=float)
    shape = means.shape[:-1]
    m = np.ascontiguousarray(means).reshape(-1, 4)
    P = np.ascontiguousarray(covs, dtype=float).reshape(-1, 4, 4)
    width, height = float(width), float(height)
    hit, rows, mh, Ph, a, b, flip = _select(m, P, width, height, float(n_sigma))
    if rows.size:
        # The x step, then the y step on its result (truncate_axis twice, fewer calls).
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lx, pa, pb = _tails(a, b)
            a, b, flip = _shift_x_then_standardise_y(mh, Ph, a, b, flip, pa, pb, height)
            ly, pa, pb = _tails(a, b)
        m, P, log_mass = _shift_y_then_scatter(m, P, rows, mh, Ph, a, b, flip, pa, pb, lx, ly,
                                               width, height)
    else:
        m, P, log_mass = m.copy(), P.copy(), np.zeros(len(m))
    return m.reshape(shape + (4,)), P.reshape(shape + (4, 4)), hit.reshape(shape), \
        log_mass.reshape(shape)


# ------------------------------------------------------------------ buildings

#: Share of a track's quadrature points inside buildings at or above which the track is
#: inconsistent (it was almost sure the target was where no target can be): its position
#: variances first grow by the square of half the largest side of the buildings it is in.
BUILDING_INFLATE_FRACTION = 0.95


def near_buildings(means: FloatArray, covs: FloatArray, buildings: FloatArray,
                   n_sigma: float = N_SIGMA) -> BoolArray:
    """Tracks ``(..., 4)``, ``(..., 4, 4)`` whose ``n_sigma`` position box (per axis)
    overlaps a building footprint of ``buildings`` ``(K, 5)``: the only ones
    :func:`building_constraint` can change."""
    means = np.asarray(means, dtype=float)
    covs = np.asarray(covs, dtype=float)
    b = np.asarray(buildings, dtype=float).reshape(-1, 5)
    if len(b) == 0:
        return np.zeros(means.shape[:-1], dtype=bool)
    x, y = means[..., 0, None], means[..., 1, None]
    sx = n_sigma * np.sqrt(covs[..., 0, 0])[..., None]
    sy = n_sigma * np.sqrt(covs[..., 1, 1])[..., None]
    return np.any((x - sx < b[:, 2]) & (x + sx > b[:, 0]) & (y - sy < b[:, 3])
                  & (y + sy > b[:, 1]), axis=-1)


def building_constraint(means: FloatArray, covs: FloatArray, buildings: FloatArray, *,
                        reflect_dt: float | None = None, points: FloatArray | None = None,
                        n_sigma: float = N_SIGMA
                        ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]:
    r"""Move tracks out of the buildings: no target is ever inside a footprint.

    Each track near a building (:func:`near_buildings`) is replaced by the moments of its
    restriction to the outside of every footprint,

    .. math::
        m' = E[x \mid x \notin B],\qquad P' = \mathrm{Cov}[x \mid x \notin B],

    by the missed-look quadrature: the whitened points :math:`\xi_s` mapped to
    :math:`m + L \xi_s`, the points whose ground position is inside a footprint dropped,
    the ``n`` others moment matched with weights ``1/n``. When at least
    :data:`BUILDING_INFLATE_FRACTION` of the points (or all but fewer than 5) are inside, the
    track was confidently wrong: both position variances first grow by
    :math:`(s/2)^2`, ``s`` the largest side of the footprints holding its points, and the
    restriction is taken of the grown track (if it still leaves fewer than 5 points outside,
    the grown track is kept).

    With ``reflect_dt`` (after a predict over ``dt`` s) the walls also act as they act on
    the targets: a point that entered a footprint during the step (its position
    ``dt`` s earlier along its velocity, ``p - v dt``, is outside every footprint) is
    mirrored across the wall it came through and that velocity component changes sign
    (:func:`sensorplan.models.truth.reflect_off_buildings`, the targets' own rule); only the
    points still inside are dropped, and the moments are those of the reflected points. A
    track that turns at a wall then predicts the turn instead of a target inside the wall.

    Parameters
    ----------
    means : (..., 4) float64;  covs : (..., 4, 4) float64
    buildings : (K, 5) float64      ``x0, y0, x1, y1, height`` (m)
    reflect_dt : float, optional    the step just predicted (s): reflect at the walls
    points : (S, 4) float64, optional
        Whitened standard-normal points (default the missed-look update's 512).
    n_sigma : float
        Tracks whose ``n_sigma`` box clears every footprint are returned unchanged.

    Returns
    -------
    means : (..., 4);  covs : (..., 4, 4)  symmetric positive definite
    applied : (...) bool   tracks the buildings changed
    log_mass : (...)       log of the share of the (input) track's points outside every
                           footprint, floored at ``log(1/S)``: 0 where not applied
    """
    from .missed import MIN_OUTSIDE, _point_set, in_footprints

    x, xx = _point_set(points)
    S = x.shape[0]
    means = np.asarray(means, dtype=float)
    shape = means.shape[:-1]
    m = np.array(means, dtype=float).reshape(-1, 4)
    P = np.array(np.broadcast_to(covs, shape + (4, 4)), dtype=float).reshape(-1, 4, 4)
    b = np.asarray(buildings, dtype=float).reshape(-1, 5)
    applied = np.zeros(len(m), dtype=bool)
    log_mass = np.zeros(len(m))
    rows = np.flatnonzero(near_buildings(m, P, b, n_sigma))
    if rows.size:
        L = np.linalg.cholesky(P[rows])
        inside: BoolArray = in_footprints(m[rows], L, x, b)                 # (B, S, K)
        hit: BoolArray = np.any(inside, axis=2)                             # (B, S)
        some = np.any(hit, axis=1)
        rows, L, inside, hit = rows[some], L[some], inside[some], hit[some]
        applied[rows] = True
        few = max(MIN_OUTSIDE, (1.0 - BUILDING_INFLATE_FRACTION) * S)
        if reflect_dt is not None and rows.size:
            # The walls as the targets meet them; a track with too few points left after
            # the reflection falls through to the plain restriction (and its growth).
            mean, cov, n = _reflected_moments(m[rows], L, hit, x, b, float(reflect_dt))
            ok = n > few
            m[rows[ok]], P[rows[ok]] = mean[ok], cov[ok]
            log_mass[rows[ok]] = np.log(n[ok] / S)
            rows, L, inside, hit = rows[~ok], L[~ok], inside[~ok], hit[~ok]
        mr, Pr = m[rows], P[rows]
        n_out = S - hit.sum(axis=1)
        log_mass[rows] = np.log(np.maximum(n_out, 1) / S)
        grow = n_out <= few
        if grow.any():
            g = np.flatnonzero(grow)
            side = np.maximum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1])         # (K,)
            half = 0.5 * np.max(np.where(inside[g].any(axis=1), side, 0.0), axis=1)
            Pr[g, 0, 0] += half ** 2
            Pr[g, 1, 1] += half ** 2
            L[g] = np.linalg.cholesky(Pr[g])
            hit[g] = in_footprints(mr[g], L[g], x, b).any(axis=2)
            n_out[g] = S - hit[g].sum(axis=1)
        cut = (n_out < S) & (n_out >= MIN_OUTSIDE)
        w = (~hit[cut]).astype(float)                                       # (C, S)
        n = n_out[cut].astype(float)[:, None]
        mu = (w @ x) / n                                                    # (C, 4)
        C = ((w @ xx) / n).reshape(-1, 4, 4) - mu[:, :, None] * mu[:, None, :]
        Lc = L[cut]
        newP = Lc @ C @ np.swapaxes(Lc, -1, -2)
        mr[cut] = mr[cut] + (Lc @ mu[:, :, None])[..., 0]
        Pr[cut] = 0.5 * (newP + np.swapaxes(newP, -1, -2))
        m[rows], P[rows] = mr, Pr
    return (m.reshape(shape + (4,)), P.reshape(shape + (4, 4)), applied.reshape(shape),
            log_mass.reshape(shape))


def _reflected_moments(means: FloatArray, chol: FloatArray, inside: BoolArray, x: FloatArray,
                       buildings: FloatArray, dt: float
                       ) -> tuple[FloatArray, FloatArray, IntArray]:
    """Moments of B tracks' points ``m + L x_s`` after the walls: points inside a footprint
    (``inside`` ``(B, S)``) that were outside ``dt`` s earlier are reflected (the targets'
    rule), the others still inside are dropped. Returns the means ``(B, 4)``, covariances
    ``(B, 4, 4)`` and the number of points kept ``(B,)``."""
    from ..models.truth import inside_buildings, reflect_off_buildings

    pts = means[:, None, :] + np.einsum("bij,sj->bsi", chol, x)               # (B, S, 4)
    bi, si = np.nonzero(inside)
    new = pts[bi, si]
    old = new[:, :2] - dt * new[:, 2:]
    came_in = ~inside_buildings(old, buildings)
    xy, flipped = reflect_off_buildings(old[came_in], new[came_in, :2], buildings)
    moved = new[came_in]
    moved[:, :2] = xy
    moved[:, 2:] = np.where(flipped, -moved[:, 2:], moved[:, 2:])
    pts[bi[came_in], si[came_in]] = moved
    dropped = np.zeros(inside.shape, dtype=bool)
    dropped[bi, si] = inside_buildings(pts[bi, si, :2], buildings)
    keep = (~dropped).astype(float)                                          # (B, S)
    n = keep.sum(axis=1)
    safe = np.maximum(n, 1.0)
    mean = np.einsum("bs,bsi->bi", keep, pts) / safe[:, None]
    d = pts - mean[:, None, :]
    cov = np.einsum("bs,bsi,bsj->bij", keep, d, d) / safe[:, None, None]
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2)), n.astype(np.int64)


def map_reflection(means: FloatArray, covs: FloatArray, width: float, height: float, *,
                   points: FloatArray | None = None, n_sigma: float = N_SIGMA
                   ) -> tuple[FloatArray, FloatArray, BoolArray]:
    r"""Predicted tracks after the map's walls, as the targets meet them.

    Targets reflect off the walls of ``[0, W] x [0, H]``: a position that left the map is
    mirrored back in and that velocity component reverses
    (:func:`sensorplan.models.truth.mirror`, the targets' own rule). Each track whose mean
    or ``n_sigma`` box leaves the map is replaced by the moments of its quadrature points
    (the missed-look update's 512) after that rule; the mass is kept, so the result is on
    the map with the reflected part's velocities reversed. Tracks inside are untouched.

    Returns
    -------
    means : (..., 4);  covs : (..., 4, 4);  applied : (...) bool
    """
    from ..models.truth import mirror
    from .missed import _point_set

    x, _ = _point_set(points)
    means = np.asarray(means, dtype=float)
    shape = means.shape[:-1]
    m = np.array(means, dtype=float).reshape(-1, 4)
    P = np.array(np.broadcast_to(covs, shape + (4, 4)), dtype=float).reshape(-1, 4, 4)
    applied = outside(m, P, width, height, n_sigma)
    rows = np.flatnonzero(applied)
    if rows.size:
        L = np.linalg.cholesky(P[rows])
        pts = m[rows, None, :] + np.einsum("bij,sj->bsi", L, x)                # (B, S, 4)
        folded, flipped = mirror(pts[..., :2], np.array([width, height]))
        moved = (folded != pts[..., :2]).any(axis=(1, 2))
        pts[..., :2] = folded
        pts[..., 2:] = np.where(flipped, -pts[..., 2:], pts[..., 2:])
        mean = pts.mean(axis=1)
        d = pts - mean[:, None, :]
        cov = np.einsum("bsi,bsj->bij", d, d) / pts.shape[1]
        r = rows[moved]
        m[r], P[r] = mean[moved], 0.5 * (cov[moved] + np.swapaxes(cov[moved], -1, -2))
        applied[rows[~moved]] = False
    return m.reshape(shape + (4,)), P.reshape(shape + (4, 4)), applied.reshape(shape)


def map_edge_predict(means: FloatArray, covs: FloatArray, width: float, height: float,
                     edge: str) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]:
    r"""Predicted densities at the map's edge, as a tracker of targets that may not exist
    models it (one of :data:`MAP_EDGES`).

    ``exit``: a target that reaches the edge leaves the map and is gone (targets born at
    the edges die there); a density whose mean or 3-sigma box leaves the map is truncated
    to it (:func:`map_constraint`) and ``log_mass`` is the log of its mass on the map, the
    probability that the target is still there, so a track's existence is multiplied by
    ``exp(log_mass)``. ``closed``: targets turn back at the walls (the closed-map presets'
    truth, :func:`sensorplan.models.truth.mirror`); the part of the density beyond a wall
    is reflected back in with that velocity component reversed (:func:`map_reflection`, the
    moments of the reflected quadrature points: a density wholly on the map, whose mean is
    on the map), and ``log_mass`` is 0: no target leaves, so no existence is lost at the
    edge. The reflected moments are not truncated again: they already describe a density
    on the map, and cutting their Gaussian's tail at the wall would count the wall twice
    (a track 1 m inside a wall moving out at 4 m/s: its mean 0.4 m further in and its x
    variance 27 % smaller than the reflected density's).

    Returns
    -------
    means : (..., 4), covs : (..., 4, 4), applied : (...) bool (densities changed),
    log_mass : (...) (0 where not applied, and everywhere with ``closed``)
    """
    if edge == "exit":
        return map_constraint(means, covs, width, height)
    if edge != "closed":
        raise ValueError(f"map edge must be one of {MAP_EDGES}, got {edge!r}")
    m, P, reflected = map_reflection(means, covs, width, height)
    return m, P, reflected, np.zeros(reflected.shape)


# ------------------------------------------------------------------ leaving the map

#: How a tracker whose targets leave the map (``exit``) charges a track's existence at the
#: edge in a step (:func:`crossing_log_mass`): by its predicted density's mass off the map
#: (``outside``), or by the probability that a target on the map at the step's start
#: crosses the edge during the step (``crossing``).
EDGE_EXITS = ("outside", "crossing")

#: ``1 - rho^2`` below this is taken as this: a step whose end position is (almost) fixed
#: by its start (no velocity uncertainty, no process noise) stays finite.
_MIN_ONE_MINUS_RHO2 = 1e-30


def bivariate_normal_cdf(h: FloatArray, k: FloatArray, rho: FloatArray) -> FloatArray:
    r"""``P(X <= h, Y <= k)`` of standard normals ``X, Y`` with correlation ``rho``, by
    Owen's T function (Owen, "Tables for computing bivariate normal probabilities", Ann.
    Math. Statist. 27, 1956):

    .. math::
        \Phi_2(h, k; \rho) = \tfrac12 \Phi(h) + \tfrac12 \Phi(k)
            - T\!\Big(h, \frac{k - \rho h}{h \sqrt{1 - \rho^2}}\Big)
            - T\!\Big(k, \frac{h - \rho k}{k \sqrt{1 - \rho^2}}\Big) - \beta,

    :math:`\beta = 1/2` when :math:`h k < 0`, else 0. Elementwise over broadcast arrays;
    ``h`` or ``k`` exactly 0 is taken as the smallest positive float (the function is
    continuous there).
    """
    h, k, rho = np.broadcast_arrays(np.asarray(h, dtype=float), np.asarray(k, dtype=float),
                                    np.asarray(rho, dtype=float))
    tiny = float(np.finfo(float).tiny)
    h = np.where(h == 0.0, tiny, h)
    k = np.where(k == 0.0, tiny, k)
    s = np.sqrt(np.maximum(1.0 - rho * rho, _MIN_ONE_MINUS_RHO2))
    with np.errstate(over="ignore", invalid="ignore"):
        ah = (k - rho * h) / (h * s)
        ak = (h - rho * k) / (k * s)
    out = (0.5 * (ndtr(h) + ndtr(k)) - owens_t(h, ah) - owens_t(k, ak)
           - 0.5 * (h * k < 0.0))
    return np.asarray(np.clip(out, 0.0, np.minimum(ndtr(h), ndtr(k))), dtype=float)


def crossing_log_mass(means: FloatArray, covs: FloatArray, F: FloatArray, Q: FloatArray,
                      width: float, height: float) -> FloatArray:
    r"""Log-probability that a target on the map at a step's start is still on it at the
    step's end, for the densities ``N(means, covs)`` at the start and the motion
    :math:`x' = F x + w`, :math:`w \sim N(0, Q)`.

    A track's existence says the target is alive, and a live target is on the map (it dies
    when it leaves): so its density at the start is on the map, and the existence it loses
    at the edge is the chance of crossing during the step,

    .. math::
        h_k = P(p'_k \notin [0, L_k] \mid p_k \in [0, L_k]),

    per axis ``k`` (x, then y, as the truncation takes them: the result is
    :math:`\log (1 - h_x) + \log (1 - h_y)`), with the start and end positions
    :math:`(p_k, p'_k)` jointly normal: means :math:`m_k` and :math:`(F m)_k`, variances
    :math:`P_{kk}` and :math:`(F P F^T + Q)_{kk}`, covariance :math:`(P F^T)_{kk}`. The
    numerator is two rectangles of that bivariate normal (:func:`bivariate_normal_cdf`).
    The predicted density's mass off the map (:func:`map_constraint`'s ``log_mass``) is
    instead :math:`P(p'_k \notin [0, L_k])`: it also counts, every step, the part of the
    Gaussian that lies off the map already at the start, where no live target is.

    Parameters
    ----------
    means : (..., 4), covs : (..., 4, 4)
        The densities at the step's start (before the prediction).
    F, Q : (4, 4) or (..., 4, 4)
        The motion model's transition and process noise.
    width, height : float
        The map ``[0, W] x [0, H]`` (m).

    Returns
    -------
    (...) log-probabilities (<= 0; ``-inf`` for a density with no mass on the map)
    """
    m = np.asarray(means, dtype=float)
    P = np.asarray(covs, dtype=float)
    F = np.asarray(F, dtype=float)
    Ft = np.swapaxes(F, -1, -2)
    m1 = np.einsum("...ij,...j->...i", F, m)
    C = P @ Ft                                                 # Cov(x, x')
    P1 = F @ P @ Ft + np.asarray(Q, dtype=float)
    total = np.zeros(m.shape[:-1])
    for k, L in ((0, float(width)), (1, float(height))):
        s0 = np.sqrt(P[..., k, k])
        s1 = np.sqrt(P1[..., k, k])
        rho = np.clip(C[..., k, k] / (s0 * s1), -1.0, 1.0)
        a0, b0 = -m[..., k] / s0, (L - m[..., k]) / s0
        a1, b1 = -m1[..., k] / s1, (L - m1[..., k]) / s1
        inside = ndtr(b0) - ndtr(a0)
        below = (bivariate_normal_cdf(b0, a1, rho)
                 - bivariate_normal_cdf(a0, a1, rho))         # on the map, then below 0
        above = (bivariate_normal_cdf(b0, -b1, -rho)
                 - bivariate_normal_cdf(a0, -b1, -rho))       # on the map, then beyond L
        crossed = np.clip(below, 0.0, None) + np.clip(above, 0.0, None)
        hazard = np.divide(crossed, inside, out=np.ones_like(inside), where=inside > 0.0)
        with np.errstate(divide="ignore"):
            total = total + np.log1p(-np.minimum(hazard, 1.0))
    return total
