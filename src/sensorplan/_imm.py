"""Compiled pieces of the IMM tracker's step (:mod:`sensorplan.tracker`).

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

from ._jit import njit


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


__all__ = ["combine_rows"]
