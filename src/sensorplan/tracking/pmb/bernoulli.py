r"""The Bernoulli tracks' arrays and the Gaussian steps the PMB update takes on them.

A Bernoulli ``i`` is a target that exists with probability :math:`r_i` and then has the
Gaussian density :math:`N(m_i, P_i)`; it carries a label for its whole life. All of them
live in the arrays of :class:`Bernoullis`, in the order they were created (so labels
ascend). The steps, batched over Bernoullis and detections:

- :func:`pair_terms`: each Gaussian's predicted measurement linearised at its mean
  (:math:`h`, :math:`H'`, :math:`R` from the sensing model), the innovations of every
  detection, their squared Mahalanobis distances and log likelihoods
  :math:`\ln N(z_j;\ h_i, S_i)`, :math:`S_i = H'_i C_i H_i'^T + R_i` (one compiled loop
  over the pairs with the 2 x 2 Cholesky factor of :math:`S_i`, never an inverse: a
  numpy version costs a dozen calls per look);
- :func:`updates`: the EKF update of the gated pairs (the tracker's Joseph-form
  :func:`sensorplan.tracking.ekf.position_update`);
- :func:`mixture_moments`: a weighted Gaussian mixture per group, moment matched to one
  Gaussian (:math:`\bar m = \sum_k \beta_k m_k`,
  :math:`\bar P = \sum_k \beta_k [P_k + (m_k - \bar m)(m_k - \bar m)^T]`, symmetrised);
- :func:`missed_look`: the density and :math:`\bar P` a missed look leaves, by the
  missed-look quadrature;
- :func:`missed_existence`: the existence a missed look leaves,
  :math:`r' = r (1 - \bar P) / (1 - r \bar P)`;
- :func:`first_detection`: the density of a target first seen in one detection, from the
  undetected intensity's cell components (the tracker's step 5, for a tracker without the
  intensity: the GNN's initiator).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..._compiled.jit import njit
from ..._types import BoolArray, FloatArray, IntArray
from ...models.radar import wrap
from ..base import Rows
from ..ekf import position_update
from ..missed import MIN_OUTSIDE, standard_points
from .sensing import Look, Sensing

_LOG_2PI = math.log(2.0 * math.pi)
_TINY = float(np.finfo(float).tiny)


@dataclass
class Bernoullis(Rows):
    """Every Bernoulli's existence, density and label (arrays replaced, never resized in
    place): ``r (n,)``, the existence probabilities in [0, 1], and one row per Bernoulli of
    the arrays a :class:`~sensorplan.tracking.base.TrackSet` reports (``means``, ``covs``,
    ``labels``; labels ascending, never reused).

    With an IMM motion model each density is the moment-matched mixture of R modes:
    ``mode_probs (n, R)``, ``mode_means (n, R, 4)``, ``mode_covs (n, R, 4, 4)``; None for a
    single motion model (``means`` and ``covs`` are then the density itself).
    """

    r: FloatArray
    means: FloatArray
    covs: FloatArray
    labels: IntArray
    mode_probs: FloatArray | None = None
    mode_means: FloatArray | None = None
    mode_covs: FloatArray | None = None

    def keep(self, rows: BoolArray | IntArray) -> None:
        """Keep only ``rows`` (a mask or ascending indices)."""
        self.r, self.means = self.r[rows], self.means[rows]
        self.covs, self.labels = self.covs[rows], self.labels[rows]
        if self.mode_probs is not None:
            assert self.mode_means is not None and self.mode_covs is not None
            self.mode_probs, self.mode_means = self.mode_probs[rows], self.mode_means[rows]
            self.mode_covs = self.mode_covs[rows]

    def append(self, r: FloatArray, means: FloatArray, covs: FloatArray,
               labels: IntArray, mode_probs: FloatArray | None = None) -> None:
        """Add Bernoullis at the end (their labels above every present one); with modes,
        each new one's modes all start at its density, with probabilities ``mode_probs
        (R,)``."""
        self.r = np.concatenate([self.r, r])
        self.means = np.concatenate([self.means, means])
        self.covs = np.concatenate([self.covs, covs])
        self.labels = np.concatenate([self.labels, labels])
        if self.mode_probs is not None:
            assert self.mode_means is not None and self.mode_covs is not None
            if mode_probs is None:
                raise ValueError("mode_probs are needed for Bernoullis with modes")
            probs, mm, mP = mode_copies(means, covs, mode_probs)
            self.mode_probs = np.concatenate([self.mode_probs, probs])
            self.mode_means = np.concatenate([self.mode_means, mm])
            self.mode_covs = np.concatenate([self.mode_covs, mP])


def mode_copies(means: FloatArray, covs: FloatArray, mode_probs: FloatArray
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Modes of densities ``(n, 4)``, ``(n, 4, 4)`` that all start at their density, with
    probabilities ``mode_probs (R,)``: ``(n, R)``, ``(n, R, 4)``, ``(n, R, 4, 4)``."""
    R = len(mode_probs)
    return (np.tile(mode_probs, (len(means), 1)), np.repeat(means[:, None], R, axis=1),
            np.repeat(covs[:, None], R, axis=1))


@dataclass(frozen=True)
class PairTerms:
    """Every (Gaussian, detection) pair of one look.

    Attributes
    ----------
    nu : (B, m, 2)       innovations ``z_j - h_i`` (angles wrapped)
    Hp : (B, 2, 2)       ground-position Jacobians at the means
    var : (B, 2)         noise variances (R's diagonal) at the means
    d2 : (B, m)          squared Mahalanobis distances of the innovations under ``S_i``
    log_lik : (B, m)     :math:`\\ln N(z_j; h_i, S_i)`
    gated : (B, m) bool  ``d2`` below the gate threshold
    lik : (B, m)         :math:`N(z_j; h_i, S_i)` inside the gate, 0 outside it
    """

    nu: FloatArray
    Hp: FloatArray
    var: FloatArray
    d2: FloatArray
    log_lik: FloatArray
    gated: BoolArray
    lik: FloatArray


def pair_terms(sensing: Sensing, look: Look, means: FloatArray, covs: FloatArray,
               Z: FloatArray, gate: float) -> PairTerms:
    """Innovations, distances and likelihoods of detections ``Z (m, 2)`` under Gaussians
    ``(B, 4)``, ``(B, 4, 4)`` (see the module docstring)."""
    h, Hp, var = sensing.measure(means[:, :2], look)
    nu, d2, log_lik, gated, lik = _pairs(np.ascontiguousarray(h), np.ascontiguousarray(Hp),
                                    np.ascontiguousarray(var), np.ascontiguousarray(covs),
                                    np.ascontiguousarray(Z, dtype=float),
                                    bool(sensing.angular), float(gate))
    return PairTerms(nu, Hp, var, d2, log_lik, gated, lik)


@njit(cache=True, error_model="numpy")
def _pairs(h: np.ndarray, Hp: np.ndarray, var: np.ndarray, C: np.ndarray, Z: np.ndarray,
           angular: bool, gate: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every (Gaussian b, detection j) pair: ``nu = z_j - h_b`` (the second coordinate
    wrapped when ``angular``), ``S_b = H'_b C_b H_b'^T + diag(var_b)`` (``C_b`` the position
    block of the covariance ``(B, 4, 4)``) by its 2 x 2 Cholesky
    factor ``S = L L^T``, ``d2 = |L^-1 nu|^2`` (forward substitution, no inverse),
    ``ln N = -d2/2 - ln(l00 l11) - ln 2 pi``, ``d2 < gate`` and ``N`` in the gate."""
    B, m = h.shape[0], Z.shape[0]
    nu = np.empty((B, m, 2))
    d2 = np.empty((B, m))
    log_lik = np.empty((B, m))
    gated = np.empty((B, m), dtype=np.bool_)
    lik = np.zeros((B, m))
    for b in range(B):
        a00, a01, a10, a11 = Hp[b, 0, 0], Hp[b, 0, 1], Hp[b, 1, 0], Hp[b, 1, 1]
        c00, c01, c11 = C[b, 0, 0], 0.5 * (C[b, 0, 1] + C[b, 1, 0]), C[b, 1, 1]
        # S = A C A^T + diag(var), A = H'
        t00, t01 = a00 * c00 + a01 * c01, a00 * c01 + a01 * c11
        t10, t11 = a10 * c00 + a11 * c01, a10 * c01 + a11 * c11
        s00 = t00 * a00 + t01 * a01 + var[b, 0]
        s01 = t00 * a10 + t01 * a11
        s11 = t10 * a10 + t11 * a11 + var[b, 1]
        l00 = math.sqrt(s00)
        l10 = s01 / l00
        l11 = math.sqrt(s11 - l10 * l10)
        norm = math.log(l00 * l11) + _LOG_2PI
        for j in range(m):
            n0 = Z[j, 0] - h[b, 0]
            n1 = Z[j, 1] - h[b, 1]
            if angular:
                n1 = wrap(n1)
            nu[b, j, 0] = n0
            nu[b, j, 1] = n1
            y0 = n0 / l00
            y1 = (n1 - l10 * y0) / l11
            q = y0 * y0 + y1 * y1
            d2[b, j] = q
            log_lik[b, j] = -0.5 * q - norm
            gated[b, j] = q < gate
            if q < gate:
                lik[b, j] = math.exp(log_lik[b, j])
    return nu, d2, log_lik, gated, lik


def updates(means: FloatArray, covs: FloatArray, terms: PairTerms, unique: IntArray,
            which: IntArray, cols: IntArray) -> tuple[FloatArray, FloatArray]:
    r"""EKF updates of the Gaussians ``unique[which]`` with detections ``cols``, ``(K,)``
    pairs of ``terms``: means ``(K, 4)`` and covariances ``(K, 4, 4)``.

    A Gaussian is linearised at its own mean, so its gain :math:`K = P H'^T S^{-1}` and
    updated covariance are the same for every detection it gates: the covariance is the
    tracker's Joseph-form update (:func:`sensorplan.tracking.ekf.position_update`), once
    per distinct Gaussian ``unique``; the means :math:`x + K \nu_j` are formed per pair, the
    gain through the Cholesky factor of ``S`` (no inverse).
    """
    if len(cols) == 0:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    _, P_post = position_update(np.ascontiguousarray(means[unique]),
                                np.ascontiguousarray(covs[unique]), np.zeros((len(unique), 2)),
                                np.ascontiguousarray(terms.Hp[unique]),
                                np.ascontiguousarray(terms.var[unique]))
    x_post = _gain_means(means, covs, np.ascontiguousarray(terms.Hp), terms.var, terms.nu,
                         np.ascontiguousarray(unique[which]),
                         np.ascontiguousarray(cols, dtype=np.int64))
    return x_post, P_post[which]


@njit(cache=True, error_model="numpy")
def _gain_means(means: np.ndarray, covs: np.ndarray, Hp: np.ndarray, var: np.ndarray,
                nu: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``x_b + K_b nu_bj`` of each pair: ``K S = G``, ``G = P[:, :2] H'^T`` (the columns the
    position measurement sees), ``S = H' P_pos H'^T + diag(var)``, solved with the 2 x 2
    Cholesky factor of ``S``."""
    out = np.empty((rows.shape[0], 4))
    G = np.empty((4, 2))
    for t in range(rows.shape[0]):
        b, j = rows[t], cols[t]
        a00, a01, a10, a11 = Hp[b, 0, 0], Hp[b, 0, 1], Hp[b, 1, 0], Hp[b, 1, 1]
        for i in range(4):
            G[i, 0] = covs[b, i, 0] * a00 + covs[b, i, 1] * a01
            G[i, 1] = covs[b, i, 0] * a10 + covs[b, i, 1] * a11
        s00 = a00 * G[0, 0] + a01 * G[1, 0] + var[b, 0]
        s01 = a00 * G[0, 1] + a01 * G[1, 1]
        s11 = a10 * G[0, 1] + a11 * G[1, 1] + var[b, 1]
        l00 = math.sqrt(s00)
        l10 = s01 / l00
        l11 = math.sqrt(s11 - l10 * l10)
        y0 = nu[b, j, 0] / l00                          # S^-1 nu: forward, then back
        y1 = (nu[b, j, 1] - l10 * y0) / l11
        v1 = y1 / l11
        v0 = (y0 - l10 * v1) / l00
        for i in range(4):
            out[t, i] = means[b, i] + G[i, 0] * v0 + G[i, 1] * v1
    return out


def mixture_moments(n_groups: int, *parts: tuple[FloatArray, IntArray, FloatArray, FloatArray]
                    ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Moment-match the mixture of each group to one Gaussian.

    Parameters
    ----------
    n_groups : int
    *parts : (weights (K,) >= 0, groups (K,) int in ``0..n_groups-1``, means (K, 4),
             covs (K, 4, 4))
        One or two sets of components (two saves joining the tracker's missed and
        detected hypotheses into new arrays).

    Returns
    -------
    total : (G,)            each group's total weight
    means : (G, 4), covs : (G, 4, 4) symmetrised; zeros for a group of total weight 0
    """
    if not 1 <= len(parts) <= 2:
        raise ValueError("one or two sets of components")
    a = parts[0]
    b = parts[1] if len(parts) == 2 else (np.zeros(0), np.zeros(0, dtype=np.int64),
                                          np.zeros((0, 4)), np.zeros((0, 4, 4)))
    c = [(np.ascontiguousarray(w, dtype=float), np.ascontiguousarray(g, dtype=np.int64),
          np.ascontiguousarray(m, dtype=float), np.ascontiguousarray(P, dtype=float))
         for w, g, m, P in (a, b)]
    return _mixture(int(n_groups), *c[0], *c[1])


@njit(cache=True, error_model="numpy")
def _accumulate(total: np.ndarray, mean: np.ndarray, w: np.ndarray, groups: np.ndarray,
                x: np.ndarray) -> None:
    for k in range(w.shape[0]):
        g = groups[k]
        total[g] += w[k]
        for i in range(4):
            mean[g, i] += w[k] * x[k, i]


@njit(cache=True, error_model="numpy")
def _spread(cov: np.ndarray, mean: np.ndarray, w: np.ndarray, groups: np.ndarray,
            x: np.ndarray, P: np.ndarray) -> None:
    d = np.empty(4)
    for k in range(w.shape[0]):
        g = groups[k]
        for i in range(4):
            d[i] = x[k, i] - mean[g, i]
        for i in range(4):
            for j in range(4):
                cov[g, i, j] += w[k] * (P[k, i, j] + d[i] * d[j])


@njit(cache=True, error_model="numpy")
def _mixture(G: int, wa: np.ndarray, ga: np.ndarray, xa: np.ndarray, Pa: np.ndarray,
             wb: np.ndarray, gb: np.ndarray, xb: np.ndarray, Pb: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`mixture_moments` in two passes over the components (a dozen numpy calls on
    these few components otherwise)."""
    total = np.zeros(G)
    mean = np.zeros((G, 4))
    cov = np.zeros((G, 4, 4))
    _accumulate(total, mean, wa, ga, xa)
    _accumulate(total, mean, wb, gb, xb)
    for g in range(G):
        if total[g] > 0.0:
            for i in range(4):
                mean[g, i] /= total[g]
    _spread(cov, mean, wa, ga, xa, Pa)
    _spread(cov, mean, wb, gb, xb, Pb)
    for g in range(G):
        if total[g] > 0.0:
            for i in range(4):
                for j in range(i, 4):
                    c = 0.5 * (cov[g, i, j] + cov[g, j, i]) / total[g]
                    cov[g, i, j] = c
                    cov[g, j, i] = c
    return total, mean, cov


def missed_look(means: FloatArray, covs: FloatArray, chol: FloatArray, p: FloatArray
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
    r"""What a look that did not detect a target tells of its density, by the missed-look
    quadrature.

    The points :math:`x_b^s = m_b + L_b \xi_s` (:math:`\xi_s` the 512 whitened points of
    :func:`sensorplan.tracking.missed.standard_points`, weights :math:`1/S`) carry the
    look's detection probabilities :math:`p_{bs}`; then

    .. math::
        \bar P_b = \frac1S \sum_s p_{bs},\qquad
        w_{bs} = 1 - p_{bs},\qquad
        \mu = \frac{\sum_s w_{bs} \xi_s}{\sum_s w_{bs}},\quad
        C = \frac{\sum_s w_{bs} \xi_s \xi_s^T}{\sum_s w_{bs}} - \mu\mu^T,\quad
        m' = m + L \mu,\quad P' = L C L^T :

    the known-target tracker's missed-look rule for imperfect detection without a gate
    (:func:`sensorplan.tracking.missed.miss_update` with ``gate_probability=1`` gives the
    same numbers), without its inflation: where that rule inflates (the look covered 95 %
    or more of the density) the filter was too sure of a target it cannot doubt; a
    Bernoulli can, and its existence falls to
    :math:`r (1 - \bar P) / (1 - r \bar P)` instead. A density whose points all have the
    same detection probability (none seen, or a uniform sensor's area covering it) is left
    exactly as it was, with :math:`\bar P` that probability; so is one the look removed
    almost entirely (kept weight below :data:`~sensorplan.tracking.missed.MIN_OUTSIDE`
    points: its existence is then nearly 0).

    Parameters
    ----------
    means : (B, 4), covs : (B, 4, 4), chol : (B, 4, 4) their Cholesky factors
    p : (B, S)      detection probabilities at the points

    Returns
    -------
    means : (B, 4), covs : (B, 4, 4) (new arrays), pbar : (B,)
    """
    return _missed_moments(np.ascontiguousarray(means, dtype=float),
                           np.ascontiguousarray(covs, dtype=float),
                           np.ascontiguousarray(chol, dtype=float),
                           np.ascontiguousarray(p, dtype=float), _moment_terms(),
                           float(MIN_OUTSIDE))


@functools.cache
def _moment_terms() -> FloatArray:
    """``(S, 15)``: for each missed-look point ``x``, ``1``, ``x_0..x_3`` and the products
    ``x_i x_j`` (``j <= i``, row by row): the terms whose weighted sums are the moments."""
    x = standard_points()
    iu = [(i, j) for i in range(4) for j in range(i + 1)]
    out = np.column_stack([np.ones(len(x)), x] + [x[:, i] * x[:, j] for i, j in iu])
    out.flags.writeable = False
    return out


@njit(cache=True, error_model="numpy")
def _missed_moments(means: np.ndarray, covs: np.ndarray, chol: np.ndarray, p: np.ndarray,
                    terms: np.ndarray, min_kept: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`missed_look`, one pass over each density's points (about twenty numpy calls
    on ``(B, S)`` arrays otherwise)."""
    B, S = p.shape
    new_m = means.copy()
    new_P = covs.copy()
    pbar = np.empty(B)
    sums = np.empty(15)
    mu = np.empty(4)
    C = np.empty((4, 4))
    LC = np.empty((4, 4))
    for b in range(B):
        lo, hi, total = p[b, 0], p[b, 0], 0.0
        for s in range(S):
            v = p[b, s]
            lo = min(lo, v)
            hi = max(hi, v)
            total += v
        if lo == hi:
            pbar[b] = lo                     # the same everywhere: the density unchanged
            continue
        pbar[b] = total / S
        # The 15 weighted sums in registers (an array accumulator is stored back on every
        # point: three times slower).
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = a8 = a9 = a10 = a11 = a12 = a13 = a14 = 0.0
        for s in range(S):
            w = 1.0 - p[b, s]
            a0 += w * terms[s, 0]
            a1 += w * terms[s, 1]
            a2 += w * terms[s, 2]
            a3 += w * terms[s, 3]
            a4 += w * terms[s, 4]
            a5 += w * terms[s, 5]
            a6 += w * terms[s, 6]
            a7 += w * terms[s, 7]
            a8 += w * terms[s, 8]
            a9 += w * terms[s, 9]
            a10 += w * terms[s, 10]
            a11 += w * terms[s, 11]
            a12 += w * terms[s, 12]
            a13 += w * terms[s, 13]
            a14 += w * terms[s, 14]
        sums[0], sums[1], sums[2], sums[3], sums[4] = a0, a1, a2, a3, a4
        sums[5], sums[6], sums[7], sums[8], sums[9] = a5, a6, a7, a8, a9
        sums[10], sums[11], sums[12], sums[13], sums[14] = a10, a11, a12, a13, a14
        kept = sums[0]
        if kept < min_kept:
            continue                         # removed almost entirely: r' is nearly 0
        for i in range(4):
            mu[i] = sums[1 + i] / kept
        q = 5
        for i in range(4):
            for j in range(i + 1):
                C[i, j] = sums[q] / kept - mu[i] * mu[j]
                C[j, i] = C[i, j]
                q += 1
        L = chol[b]
        for i in range(4):
            shift = 0.0
            for k in range(i + 1):
                shift += L[i, k] * mu[k]
            new_m[b, i] = means[b, i] + shift
        for i in range(4):                   # L C
            for j in range(4):
                acc = 0.0
                for k in range(i + 1):
                    acc += L[i, k] * C[k, j]
                LC[i, j] = acc
        for i in range(4):                   # (L C) L^T, symmetric
            for j in range(i + 1):
                acc = 0.0
                for k in range(j + 1):
                    acc += LC[i, k] * L[j, k]
                new_P[b, i, j] = acc
                new_P[b, j, i] = acc
    return new_m, new_P, pbar


def missed_existence(r: FloatArray, pbar: FloatArray) -> FloatArray:
    """:math:`r (1 - \\bar P) / (1 - r \\bar P)`: a Bernoulli's existence after a look that
    did not detect it (0 when it was surely there and surely detectable)."""
    # r = 1 and Pbar = 1 give 0 / 0: the numerator is 0 whenever the denominator is.
    return r * (1.0 - pbar) / np.maximum(1.0 - r * pbar, _TINY)

def first_detection(sensing: Sensing, look: Look, cell_means: FloatArray,
                    cell_covs: FloatArray, cell_weight: FloatArray, Z: FloatArray,
                    gate: float) -> tuple[BoolArray, FloatArray, FloatArray]:
    r"""The density of a target first seen in each detection, as the PMB starts a Bernoulli.

    Each cell component :math:`N([p_c, 0], P_u)` (the velocity prior of
    :mod:`~sensorplan.tracking.pmb.undetected`) whose innovation gates :math:`z_j` is
    EKF-updated by it (:func:`updates`); the updates are moment matched
    (:func:`mixture_moments`) with weights ``cell_weight[c]`` :math:`N(z_j; h(p_c), S_c)`,
    the cells' parts of :math:`\lambda_u(z_j)` when ``cell_weight`` is
    :math:`w_c P_d(p_c) v(p_c)`.

    Parameters
    ----------
    sensing : Sensing;  look : Look
    cell_means : (k, 4), cell_covs : (k, 4, 4)   the cells' components
    cell_weight : (k,) >= 0                       each cell's weight (0: not a candidate)
    Z : (m, 2)                                    the look's detections
    gate : float                                  the gate threshold on ``d2``

    Returns
    -------
    found : (m,) bool    detections some cell of positive weight gates
    means : (f, 4), covs : (f, 4, 4)   the densities of the found detections, in order
    """
    m = len(Z)
    if m == 0 or len(cell_means) == 0:
        return np.zeros(m, dtype=bool), np.zeros((0, 4)), np.zeros((0, 4, 4))
    terms = pair_terms(sensing, look, cell_means, cell_covs, Z, gate)
    w = terms.lik * np.asarray(cell_weight, dtype=float)[:, None]          # (k, m)
    found = (w > 0.0).any(axis=0)
    # (cell, detection) pairs cell-major, as the PMB's hypotheses list them.
    cell, det = np.nonzero(w * found[None])
    if cell.size == 0:
        return found, np.zeros((0, 4)), np.zeros((0, 4, 4))
    # cell ascends (np.nonzero is row-major): its distinct values and each pair's index.
    first = np.concatenate([[True], cell[1:] != cell[:-1]])
    unique, which = cell[first], np.cumsum(first) - 1
    xu, Pu = updates(cell_means, cell_covs, terms, unique, which, det)
    group = np.cumsum(found) - 1
    _, means, covs = mixture_moments(int(found.sum()), (w[cell, det], group[det], xu, Pu))
    return found, means, covs


__all__ = ["Bernoullis", "PairTerms", "first_detection", "missed_existence", "missed_look",
           "mixture_moments", "mode_copies", "pair_terms", "updates"]
