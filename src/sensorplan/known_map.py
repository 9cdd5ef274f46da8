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
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import log_ndtr

from ._types import BoolArray, FloatArray

#: Extent (in standard deviations per axis) that must stay inside the map for a track to be
#: left untouched.
N_SIGMA = 3.0
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


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
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    flip = alpha > -beta                         # interval mostly above 0: mirror it
    a = np.where(flip, -beta, alpha)
    b = np.where(flip, -alpha, beta)
    # Now a <= -b, so Ncdf(b) is the larger term and not in the far upper tail.
    la, lb = log_ndtr(a), log_ndtr(b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_mass = lb + np.log1p(-np.exp(la - lb))
        fa, fb = np.isfinite(a), np.isfinite(b)
        pa = np.where(fa, np.exp(-0.5 * a * a - _LOG_SQRT_2PI - log_mass), 0.0)
        pb = np.where(fb, np.exp(-0.5 * b * b - _LOG_SQRT_2PI - log_mass), 0.0)
        mean = pa - pb
        a_pa = np.where(fa, a * pa, 0.0)
        b_pb = np.where(fb, b * pb, 0.0)
        var = 1.0 + a_pa - b_pb - mean * mean
    # Cancellation far in a tail can leave a tiny or negative variance: keep it in (0, 1].
    var = np.clip(var, 1e-12, 1.0)
    mean = np.clip(mean, a, b)
    return np.where(flip, -mean, mean), var, log_mass


def truncate_axis(means: FloatArray, covs: FloatArray, axis: int, lo: float, hi: float
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Moments of Gaussians ``(B, 4)``, ``(B, 4, 4)`` truncated to ``lo <= x[axis] <= hi``.

    Returns
    -------
    means : (B, 4), covs : (B, 4, 4) (symmetrised), log_mass : (B,) the log of the
    probability mass inside.
    """
    s2 = covs[:, axis, axis]
    s = np.sqrt(s2)
    m = means[:, axis]
    mu, var, log_mass = truncated_normal_moments((lo - m) / s, (hi - m) / s)
    u = covs[:, :, axis] / s2[:, None]                                   # (B, 4)
    new_means = means + u * (s * mu)[:, None]
    shrink = s2 * (1.0 - var)                                            # P_kk - v_t >= 0
    new_covs = covs - shrink[:, None, None] * u[:, :, None] * u[:, None, :]
    return new_means, 0.5 * (new_covs + np.swapaxes(new_covs, -1, -2)), log_mass


def outside(means: FloatArray, covs: FloatArray, width: float, height: float,
            n_sigma: float = N_SIGMA) -> BoolArray:
    """Tracks whose mean or ``n_sigma`` box (per axis) leaves ``[0, W] x [0, H]``."""
    sx = n_sigma * np.sqrt(covs[..., 0, 0])
    sy = n_sigma * np.sqrt(covs[..., 1, 1])
    x, y = means[..., 0], means[..., 1]
    return (x - sx < 0.0) | (x + sx > width) | (y - sy < 0.0) | (y + sy > height)


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
    means = np.array(means, dtype=float)
    covs = np.array(covs, dtype=float)
    shape = means.shape[:-1]
    m = means.reshape(-1, 4)
    P = covs.reshape(-1, 4, 4)
    hit = outside(m, P, width, height, n_sigma)
    log_mass = np.zeros(len(m))
    if hit.any():
        mh, Ph, lx = truncate_axis(m[hit], P[hit], 0, 0.0, width)
        mh, Ph, ly = truncate_axis(mh, Ph, 1, 0.0, height)
        # Correlation can move x back out a little during the y step: project the mean.
        mh[:, 0] = np.clip(mh[:, 0], 0.0, width)
        mh[:, 1] = np.clip(mh[:, 1], 0.0, height)
        m[hit], P[hit], log_mass[hit] = mh, Ph, lx + ly
    return m.reshape(shape + (4,)), P.reshape(shape + (4, 4)), hit.reshape(shape), \
        log_mass.reshape(shape)
