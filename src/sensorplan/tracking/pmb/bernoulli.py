r"""The Bernoulli tracks' arrays and the Gaussian steps the PMB update takes on them.

A Bernoulli ``i`` is a target that exists with probability :math:`r_i` and then has the
Gaussian density :math:`N(m_i, P_i)`; it carries a label for its whole life. All of them
live in the arrays of :class:`Bernoullis`, in the order they were created (so labels
ascend). The steps, batched over Bernoullis and detections:

- :func:`pair_terms`: each Gaussian's predicted measurement linearised at its mean
  (:math:`h`, :math:`H'`, :math:`R` from the sensing model), the innovations of every
  detection, their squared Mahalanobis distances (by solves, never an inverse) and log
  likelihoods :math:`\ln N(z_j;\ h_i, S_i)`, :math:`S_i = H'_i C_i H_i'^T + R_i`;
- :func:`updates`: the EKF update of the gated pairs (the tracker's Joseph-form
  :func:`sensorplan.tracking.ekf.position_update`);
- :func:`mixture_moments`: a weighted Gaussian mixture per group, moment matched to one
  Gaussian (:math:`\bar m = \sum_k \beta_k m_k`,
  :math:`\bar P = \sum_k \beta_k [P_k + (m_k - \bar m)(m_k - \bar m)^T]`, symmetrised);
- :func:`missed_existence`: the existence a missed look leaves,
  :math:`r' = r (1 - \bar P) / (1 - r \bar P)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._types import BoolArray, FloatArray, IntArray
from ..ekf import position_update
from .sensing import Look, Sensing

_LOG_2PI = math.log(2.0 * math.pi)


@dataclass
class Bernoullis:
    """Every Bernoulli's existence, density and label (arrays replaced, never resized in
    place).

    Attributes
    ----------
    r : (n,)            existence probabilities in [0, 1]
    means : (n, 4)      ``[x, y, vx, vy]`` (m, m/s)
    covs : (n, 4, 4)
    labels : (n,) int   ascending, never reused
    """

    r: FloatArray
    means: FloatArray
    covs: FloatArray
    labels: IntArray

    def __len__(self) -> int:
        return len(self.r)

    def keep(self, rows: BoolArray | IntArray) -> None:
        """Keep only ``rows`` (a mask or ascending indices)."""
        self.r, self.means = self.r[rows], self.means[rows]
        self.covs, self.labels = self.covs[rows], self.labels[rows]

    def append(self, r: FloatArray, means: FloatArray, covs: FloatArray,
               labels: IntArray) -> None:
        """Add Bernoullis at the end (their labels above every present one)."""
        self.r = np.concatenate([self.r, r])
        self.means = np.concatenate([self.means, means])
        self.covs = np.concatenate([self.covs, covs])
        self.labels = np.concatenate([self.labels, labels])


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
    """

    nu: FloatArray
    Hp: FloatArray
    var: FloatArray
    d2: FloatArray
    log_lik: FloatArray
    gated: BoolArray


def pair_terms(sensing: Sensing, look: Look, means: FloatArray, covs: FloatArray,
               Z: FloatArray, gate: float) -> PairTerms:
    """Innovations, distances and likelihoods of detections ``Z (m, 2)`` under Gaussians
    ``(B, 4)``, ``(B, 4, 4)`` (see the module docstring)."""
    h, Hp, var = sensing.measure(means[:, :2], look)
    S = Hp @ covs[:, :2, :2] @ np.swapaxes(Hp, -1, -2)
    S[:, 0, 0] += var[:, 0]
    S[:, 1, 1] += var[:, 1]
    nu = sensing.residual(Z[None, :, :], h[:, None, :])                     # (B, m, 2)
    sol = np.linalg.solve(S, np.swapaxes(nu, -1, -2))                       # (B, 2, m)
    d2 = np.einsum("bmi,bim->bm", nu, sol)
    logdet = np.linalg.slogdet(S)[1]
    log_lik = -0.5 * d2 - 0.5 * logdet[:, None] - _LOG_2PI
    return PairTerms(nu, Hp, var, d2, log_lik, d2 < gate)


def updates(means: FloatArray, covs: FloatArray, terms: PairTerms, rows: IntArray,
            cols: IntArray) -> tuple[FloatArray, FloatArray]:
    """EKF (Joseph-form) updates of Gaussians ``rows`` with detections ``cols``, ``(K,)``
    pairs of ``terms``: means ``(K, 4)`` and covariances ``(K, 4, 4)``."""
    if len(rows) == 0:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    return position_update(np.ascontiguousarray(means[rows]),
                           np.ascontiguousarray(covs[rows]),
                           np.ascontiguousarray(terms.nu[rows, cols]),
                           np.ascontiguousarray(terms.Hp[rows]),
                           np.ascontiguousarray(terms.var[rows]))


def mixture_moments(weights: FloatArray, means: FloatArray, covs: FloatArray,
                    groups: IntArray, n_groups: int) -> tuple[FloatArray, FloatArray]:
    """Moment-match the mixture of each group to one Gaussian.

    Parameters
    ----------
    weights : (K,) >= 0     component weights (normalised within each group here)
    means : (K, 4), covs : (K, 4, 4)
    groups : (K,) int       each component's group in ``0..n_groups-1``; every group needs
                            a positive total weight

    Returns
    -------
    means : (G, 4), covs : (G, 4, 4) symmetrised
    """
    W = np.zeros((n_groups, len(weights)))
    W[groups, np.arange(len(weights))] = weights
    W /= W.sum(axis=1, keepdims=True)
    mean = W @ means
    d = means - mean[groups]
    spread = covs + d[:, :, None] * d[:, None, :]
    cov = np.einsum("gk,kij->gij", W, spread)
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


def missed_existence(r: FloatArray, pbar: FloatArray) -> FloatArray:
    """:math:`r (1 - \\bar P) / (1 - r \\bar P)`: a Bernoulli's existence after a look that
    did not detect it (0 when it was surely there and surely detectable)."""
    den = 1.0 - r * pbar
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0.0, r * (1.0 - pbar) / den, 0.0)


__all__ = ["Bernoullis", "PairTerms", "missed_existence", "mixture_moments", "pair_terms",
           "updates"]
