r"""One look's association weights, and the hypotheses its marginals leave, as arrays.

Two compiled loops over the (Bernoulli, detection) and (cell, detection) pairs of a look,
before and after loopy belief propagation; each replaces a dozen numpy calls on these small
arrays (measured: about a third of a look's time went to such calls). The quantities are
those of :mod:`sensorplan.tracking.pmb.tracker`'s module docstring, steps 3-5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._compiled.jit import njit
from ..._types import FloatArray, IntArray


@dataclass(frozen=True)
class Weights:
    r"""A look's association weights.

    Attributes
    ----------
    w_miss : (n,)    :math:`1 - r_i \bar P_i` (floored at a tiny positive weight)
    w_det : (n, m)   :math:`r_i P_{d,i}\, l_{ij}`, 0 outside the gate
    w_new : (m,)     :math:`\lambda_u(z_j) + \kappa(z_j)` (floored)
    cell : (k, m)    each cell's part of :math:`\lambda_u(z_j)`, 0 outside the gate
    lam_u : (m,)     :math:`\lambda_u(z_j)`
    """

    w_miss: FloatArray
    w_det: FloatArray
    w_new: FloatArray
    cell: FloatArray
    lam_u: FloatArray


def weights(lik: FloatArray, r: FloatArray, pd: FloatArray, pbar: FloatArray,
            cell_weight: FloatArray, kappa: FloatArray, floor: float) -> Weights:
    r"""The association weights of a look.

    Parameters
    ----------
    lik : (n + k, m)     Gaussian likelihoods of the detections in the gate (0 outside) of
                         the n Bernoullis, then the k cells
    r, pd, pbar : (n,)   existence, detection probability at the predicted position and
                         :math:`\bar P` of each Bernoulli
    cell_weight : (k,)   :math:`w_c P_d(p_c) v(p_c)` of each cell
    kappa : (m,)         clutter intensity at each detection
    floor : float        the smallest miss and new weight
    """
    w_miss, w_det, w_new, cell, lam_u = _weights(
        np.ascontiguousarray(lik), np.ascontiguousarray(r), np.ascontiguousarray(pd),
        np.ascontiguousarray(pbar), np.ascontiguousarray(cell_weight),
        np.ascontiguousarray(kappa, dtype=float), float(floor))
    return Weights(w_miss, w_det, w_new, cell, lam_u)


@njit(cache=True, error_model="numpy")
def _weights(lik: np.ndarray, r: np.ndarray, pd: np.ndarray, pbar: np.ndarray,
             cw: np.ndarray, kappa: np.ndarray, floor: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n, k, m = r.shape[0], cw.shape[0], lik.shape[1]
    w_miss = np.empty(n)
    w_det = np.empty((n, m))
    for i in range(n):
        w_miss[i] = max(1.0 - r[i] * pbar[i], floor)
        f = r[i] * pd[i]
        for j in range(m):
            w_det[i, j] = lik[i, j] * f
    cell = np.empty((k, m))
    lam_u = np.zeros(m)
    for c in range(k):
        for j in range(m):
            v = lik[n + c, j] * cw[c]
            cell[c, j] = v
            lam_u[j] += v
    w_new = np.empty(m)
    for j in range(m):
        w_new[j] = max(lam_u[j] + kappa[j], floor)
    return w_miss, w_det, w_new, cell, lam_u


@dataclass(frozen=True)
class Hypotheses:
    r"""What a look's marginals leave: Bernoullis to merge, detections that start one, and
    every hypothesis that is an EKF update.

    Attributes
    ----------
    rows : (q,) int       the Bernoullis the look updates (it could detect them, or they
                          gate a detection), ascending
    started : (s,) int    the detections that start a Bernoulli, ascending
    r_new : (s,)          their existence :math:`p^{new}_j \lambda_u / (\lambda_u + \kappa)`
    gauss : (K,) int      the Gaussian of each update hypothesis (a Bernoulli ``< n``, a
                          cell ``n + c``), ascending
    unique : (U,) int     the distinct Gaussians of ``gauss``, ascending
    which : (K,) int      the index in ``unique`` of each hypothesis' Gaussian
    det : (K,) int        its detection
    weight : (K,)         its weight: :math:`p^{det}_{ij}` (a Bernoulli's), the cell's
                          part of :math:`\lambda_u(z_j)` (a new Bernoulli's)
    group : (K,) int      its mixture: ``0..q-1`` the rows, ``q..q+s-1`` the started
    started_alone : int   started detections in no Bernoulli's gate
    """

    rows: IntArray
    started: IntArray
    r_new: FloatArray
    gauss: IntArray
    unique: IntArray
    which: IntArray
    det: IntArray
    weight: FloatArray
    group: IntArray
    started_alone: int


def hypotheses(p_det: FloatArray, p_new: FloatArray, w: Weights, pbar: FloatArray,
               prune_threshold: float) -> Hypotheses:
    """The hypotheses of a look (see :class:`Hypotheses`); a detection starts a Bernoulli
    when its existence is at least ``prune_threshold`` and the undetected intensity gave it
    weight."""
    rows, started, r_new, gauss, unique, which, det, weight, group, alone = _hypotheses(
        np.ascontiguousarray(p_det), np.ascontiguousarray(p_new), w.w_det, w.cell, w.lam_u,
        w.w_new, np.ascontiguousarray(pbar), float(prune_threshold))
    return Hypotheses(rows, started, r_new, gauss, unique, which, det, weight, group,
                      int(alone))


@njit(cache=True, error_model="numpy")
def _hypotheses(p_det: np.ndarray, p_new: np.ndarray, w_det: np.ndarray, cell: np.ndarray,
                lam_u: np.ndarray, w_new: np.ndarray, pbar: np.ndarray, prune: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                           np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    n, m = w_det.shape
    k = cell.shape[0]
    # The Bernoullis the look updates and each one's mixture index.
    where = np.full(n, -1, dtype=np.int64)
    q = 0
    n_det = 0
    for i in range(n):
        hit = pbar[i] > 0.0
        for j in range(m):
            if w_det[i, j] > 0.0:
                hit = True
                n_det += 1
        if hit:
            where[i] = q
            q += 1
    rows = np.empty(q, dtype=np.int64)
    for i in range(n):
        if where[i] >= 0:
            rows[where[i]] = i
    # The detections that start a Bernoulli.
    mark = np.full(m, -1, dtype=np.int64)
    s = 0
    r_all = np.empty(m)
    for j in range(m):
        r_all[j] = p_new[j] * lam_u[j] / w_new[j]
        if lam_u[j] > 0.0 and r_all[j] >= prune:
            mark[j] = s
            s += 1
    started = np.empty(s, dtype=np.int64)
    r_new = np.empty(s)
    alone = 0
    for j in range(m):
        if mark[j] >= 0:
            started[mark[j]] = j
            r_new[mark[j]] = r_all[j]
            gated = False
            for i in range(n):
                gated = gated or w_det[i, j] > 0.0
            alone += 0 if gated else 1
    n_cell = 0
    for c in range(k):
        for j in range(m):
            if mark[j] >= 0 and cell[c, j] > 0.0:
                n_cell += 1
    K = n_det + n_cell
    gauss = np.empty(K, dtype=np.int64)
    det = np.empty(K, dtype=np.int64)
    weight = np.empty(K)
    group = np.empty(K, dtype=np.int64)
    t = 0
    for i in range(n):
        for j in range(m):
            if w_det[i, j] > 0.0:
                gauss[t], det[t], weight[t], group[t] = i, j, p_det[i, j], where[i]
                t += 1
    for c in range(k):
        for j in range(m):
            if mark[j] >= 0 and cell[c, j] > 0.0:
                gauss[t], det[t], weight[t], group[t] = n + c, j, cell[c, j], q + mark[j]
                t += 1
    # The distinct Gaussians (gauss ascends: Bernoulli pairs row by row, then cells).
    which = np.empty(K, dtype=np.int64)
    U = 0
    for t in range(K):
        if t == 0 or gauss[t] != gauss[t - 1]:
            U += 1
        which[t] = U - 1
    unique = np.empty(U, dtype=np.int64)
    for t in range(K):
        unique[which[t]] = gauss[t]
    return rows, started, r_new, gauss, unique, which, det, weight, group, alone


__all__ = ["Hypotheses", "Weights", "hypotheses", "weights"]
