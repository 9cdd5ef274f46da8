r"""The map is known: a track is truncated to the map it cannot leave.

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

The elementwise arithmetic runs in small compiled kernels; the transcendental functions
(``log_ndtr``, ``exp``, ``log1p``) stay numpy's and scipy's, so the results are the ones
the plain numpy formulas give, bit for bit (numba's ``exp`` would round differently from
numpy's vectorised one). A track's truncation is a few hundred flops spread over a
hundred numpy calls otherwise, and the tracker applies the map twice a step.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import log_ndtr

from .._compiled.jit import njit
from .._types import BoolArray, FloatArray

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
