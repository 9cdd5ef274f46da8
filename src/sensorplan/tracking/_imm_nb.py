"""Compiled pieces of the IMM tracker's step (:mod:`sensorplan.tracking.tracker`).

A track has a handful of modes of 4 states each, so the tracker's numpy expressions cost
their call overhead, not their arithmetic. These kernels do the elementwise arithmetic and
the small sums over modes of those expressions in one call, each written in the order
numpy evaluates the expression it replaces: the sums over modes accumulate from 0 in mode
order, as ``np.einsum`` does for them, so the results are the same bit for bit. Matrix
products stay numpy's (``@`` goes to BLAS, which rounds differently from a plain loop), as
do ``exp`` and ``log`` (numpy's are vectorised and round differently from numba's).
"""

from __future__ import annotations

import numpy as np

from .._compiled.jit import njit
from ..models.radar.model import clutter_density


@njit(cache=True, error_model="numpy")
def combine_rows(mu: np.ndarray, x: np.ndarray, P: np.ndarray, rows: np.ndarray,
                 means: np.ndarray, covs: np.ndarray) -> None:
    """Moment-match the modes of tracks ``rows`` into ``means``, ``covs`` (in place).

    Parameters
    ----------
    mu : (M, R) mode probabilities;  x : (M, R, 4) mode means;  P : (M, R, 4, 4)
    rows : (B,) int    the tracks to combine
    means : (M, 4), covs : (M, 4, 4)   written at ``rows``:
        ``m = sum_r mu_r x_r``, ``C = sum_r mu_r (P_r + d_r d_r^T)``, ``d_r = x_r - m``,
        ``covs = (C + C^T) / 2``
    """
    R = mu.shape[1]
    m = np.empty(4)
    d = np.empty((R, 4))
    C = np.empty((4, 4))
    for h in range(rows.shape[0]):
        b = rows[h]
        for k in range(4):
            acc = 0.0
            for r in range(R):
                acc += mu[b, r] * x[b, r, k]
            m[k] = acc
        for r in range(R):
            for k in range(4):
                d[r, k] = x[b, r, k] - m[k]
        for i in range(4):
            for j in range(4):
                acc = 0.0
                for r in range(R):
                    acc += mu[b, r] * (P[b, r, i, j] + d[r, i] * d[r, j])
                C[i, j] = acc
        for i in range(4):
            means[b, i] = m[i]
            for j in range(4):
                covs[b, i, j] = 0.5 * (C[i, j] + C[j, i])


@njit(cache=True, error_model="numpy")
def mix(mu: np.ndarray, switching: np.ndarray, c: np.ndarray, x: np.ndarray, P: np.ndarray
        ) -> tuple[np.ndarray, np.ndarray]:
    """The IMM's mixed initial conditions of every mode.

    Parameters
    ----------
    mu : (M, R) mode probabilities;  switching : (R, R) ``Pi``
    c : (M, R)     predicted mode probabilities ``mu Pi`` (floored)
    x : (M, R, 4), P : (M, R, 4, 4)   mode means and covariances

    Returns
    -------
    x0 : (M, R, 4), P0 : (M, R, 4, 4)
        ``x0_j = sum_i w_ij x_i``, ``P0_j = sum_i w_ij (P_i + d_ij d_ij^T)`` with
        ``w_ij = mu_i Pi_ij / c_j`` and ``d_ij = x_i - x0_j``.
    """
    M, R = mu.shape
    x0 = np.empty((M, R, 4))
    P0 = np.empty((M, R, 4, 4))
    w = np.empty((R, R))
    d = np.empty((R, 4))
    for m in range(M):
        for i in range(R):
            for j in range(R):
                w[i, j] = mu[m, i] * switching[i, j] / c[m, j]
        for j in range(R):
            for k in range(4):
                acc = 0.0
                for i in range(R):
                    acc += w[i, j] * x[m, i, k]
                x0[m, j, k] = acc
            for i in range(R):
                for k in range(4):
                    d[i, k] = x[m, i, k] - x0[m, j, k]
            for a in range(4):
                for b in range(4):
                    acc = 0.0
                    for i in range(R):
                        acc += w[i, j] * (P[m, i, a, b] + d[i, a] * d[i, b])
                    P0[m, j, a, b] = acc
    return x0, P0


@njit(cache=True, error_model="numpy")
def pda_spread(beta: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Combined innovation and spread of innovations of PDA, per mode.

    Parameters
    ----------
    beta : (R, m) association probabilities;  nu : (R, m, 2) innovations

    Returns
    -------
    nu_c : (R, 2)      ``sum_i beta_i nu_i``
    spread : (R, 2, 2) ``sum_i beta_i nu_i nu_i^T - nu_c nu_c^T``
    """
    R, m = beta.shape
    nu_c = np.empty((R, 2))
    spread = np.empty((R, 2, 2))
    for r in range(R):
        for k in range(2):
            acc = 0.0
            for i in range(m):
                acc += beta[r, i] * nu[r, i, k]
            nu_c[r, k] = acc
        for k in range(2):
            for l in range(2):
                acc = 0.0
                for i in range(m):
                    acc += beta[r, i] * nu[r, i, k] * nu[r, i, l]
                spread[r, k, l] = acc - nu_c[r, k] * nu_c[r, l]
    return nu_c, spread


@njit(cache=True, error_model="numpy")
def pda_covariances(P: np.ndarray, Pc: np.ndarray, KSK: np.ndarray, beta0: np.ndarray,
                    out: np.ndarray) -> None:
    """PDA's covariance per mode, ``b0 P + (1 - b0) P_c + K spread K^T``, symmetrised into
    ``out`` ``(R, 4, 4)`` (which may be ``P`` itself)."""
    X = np.empty((4, 4))
    for r in range(P.shape[0]):
        b = beta0[r]
        c = 1.0 - b
        for i in range(4):
            for j in range(4):
                X[i, j] = b * P[r, i, j] + c * Pc[r, i, j] + KSK[r, i, j]
        for i in range(4):
            for j in range(4):
                out[r, i, j] = 0.5 * (X[i, j] + X[j, i])


@njit(cache=True, error_model="numpy")
def pda_likelihoods(pd: np.ndarray, density: np.ndarray, ranges: np.ndarray, row: np.ndarray,
                    pg: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """PDA's detection likelihoods against clutter, per mode and detection.

    Parameters
    ----------
    pd : (R,) detection probabilities;  density : (R, m) ``exp(-d2/2 - logdet/2)``
    ranges : (m,) measured ranges (m);  row : the sensor's radar table row (its clutter
    density, :func:`~sensorplan.models.radar.clutter_density`);  pg : gate probability

    Returns
    -------
    lik : (R, m)  ``pd density / (2 pi) / rho``, ``rho`` the clutter density at each range
    none : (R,)   ``1 - pd pg``
    rho_positive : bool   every clutter density > 0
    """
    R, m = density.shape
    rho = np.empty(m)
    positive = True
    for i in range(m):
        rho[i] = clutter_density(row, ranges[i])
        positive = positive and rho[i] > 0.0
    lik = np.empty((R, m))
    none = np.empty(R)
    for r in range(R):
        for i in range(m):
            lik[r, i] = pd[r] * density[r, i] / (2.0 * np.pi) / rho[i]
        none[r] = 1.0 - pd[r] * pg
    return lik, none, positive


@njit(cache=True, error_model="numpy")
def pda_weights(lik: np.ndarray, none: np.ndarray, total: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Association probabilities ``beta = lik / den``, ``beta0 = none / den`` with
    ``den = none + total`` (``total`` the row sums of ``lik``), and whether every ``den``
    is finite and positive."""
    R, m = lik.shape
    den = np.empty(R)
    beta = np.empty((R, m))
    beta0 = np.empty(R)
    ok = True
    for r in range(R):
        den[r] = none[r] + total[r]
        ok = ok and np.isfinite(den[r]) and den[r] > 0.0
        for i in range(m):
            beta[r, i] = lik[r, i] / den[r]
        beta0[r] = none[r] / den[r]
    return den, beta, beta0, ok


#: numpy sums fewer than 8 terms one after the other (more: pairwise, in blocks of 8);
#: :func:`normalise_rows` sums in order, so it is used for fewer modes than this.
SEQUENTIAL_SUM = 8


@njit(cache=True, error_model="numpy")
def floored_rows(p: np.ndarray, rows: np.ndarray, floor: float) -> np.ndarray:
    """``np.maximum(p[rows], floor)`` (NaN kept)."""
    out = np.empty((rows.shape[0], p.shape[1]))
    for h in range(rows.shape[0]):
        for r in range(p.shape[1]):
            v = p[rows[h], r]
            out[h, r] = v if v >= floor or np.isnan(v) else floor
    return out


@njit(cache=True, error_model="numpy")
def shifted_by_max(logp: np.ndarray, log_likelihood: np.ndarray) -> np.ndarray:
    """``logw - max(logw)`` per row, ``logw = logp + log_likelihood`` (NaN propagates)."""
    B, R = logp.shape
    out = np.empty((B, R))
    for b in range(B):
        top = -np.inf
        for r in range(R):
            v = logp[b, r] + log_likelihood[b, r]
            out[b, r] = v
            if np.isnan(v) or np.isnan(top):
                top = np.nan
            elif v > top:
                top = v
        for r in range(R):
            out[b, r] = out[b, r] - top
    return out


@njit(cache=True, error_model="numpy")
def normalise_rows(w: np.ndarray, probs: np.ndarray, rows: np.ndarray) -> None:
    """``probs[rows] = w / w.sum(axis=1)`` with the sum taken in order (fewer than
    :data:`SEQUENTIAL_SUM` modes, where numpy's sum is the same)."""
    for h in range(rows.shape[0]):
        acc = 0.0
        for r in range(w.shape[1]):
            acc += w[h, r]
        for r in range(w.shape[1]):
            probs[rows[h], r] = w[h, r] / acc


__all__ = ["SEQUENTIAL_SUM", "combine_rows", "floored_rows", "mix", "normalise_rows",
           "pda_covariances", "pda_likelihoods", "pda_spread", "pda_weights",
           "shifted_by_max"]
