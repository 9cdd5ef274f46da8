r"""Association of a look's detections with a track: the validation gate, probabilistic data
association (PDA), and the nearest gated detection.

- **Validation gate.** A detection is used only if the squared Mahalanobis distance of its
  innovation, :math:`\nu^T S^{-1} \nu` with :math:`S = H' C H'^T + R`, is below the
  chi-square(2) quantile of the gate probability, :math:`\gamma = -2\ln(1 - P_G)` (13.82
  for 0.999).
- **PDA** (Bar-Shalom and Tse 1975) with the radar's detection probability and its clutter
  density in the measurement space (:func:`sensorplan.models.radar.clutter_densities`),
  per IMM mode: each mode's likelihood of the look is the PDA's normaliser.
"""

from __future__ import annotations

import math

import numpy as np

from .._types import FloatArray
from ..models.radar import clutter_densities, detection_probabilities
from ._imm_nb import pda_covariances, pda_likelihoods, pda_spread, pda_weights
from .ekf import innovations, mahalanobis2, position_update

#: Ways to associate a look's detections with its track when false alarms are on.
ASSOCIATIONS = ("pda", "nearest")

#: Degrees of freedom of a range/azimuth innovation.
GATE_DOF = 2


def gate_threshold(probability: float) -> float:
    """The chi-square(2) quantile of ``probability``: ``-2 ln(1 - p)`` in closed form."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"gate probability must be in (0, 1), got {probability!r}")
    return -2.0 * math.log1p(-probability)


def pda_update(x: FloatArray, P: FloatArray, Z: FloatArray, sxy: FloatArray, hd: float,
               table: FloatArray, i: int, pg: float
               ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """Probabilistic data association update of one track's R modes with gated detections.

    Parameters
    ----------
    x : (R, 4);  P : (R, 4, 4)   the track's modes
    Z : (m, 2)                   the look's gated detections ``[r, phi]``
    sxy : (2,);  hd : float      the sensor's ground position and heading
    table : (N, C);  i : int     the radar table and the sensor's row
    pg : float                   the gate probability (1 without a gate)

    Returns
    -------
    (x', P', log_den) with the updated modes and each mode's log likelihood of the look
    ``(R,)``, or None when the model gives these detections no probability at all.
    """
    R, m = len(x), len(Z)
    xr = np.repeat(x, m, 0)
    Pr = np.repeat(P, m, 0)
    # (np.repeat / concatenate rather than np.tile: the same arrays, a fifth of the cost)
    sxy_rows = np.repeat(np.asarray(sxy, dtype=float)[None], R * m, axis=0)
    nu, S, Hp, var = innovations(xr, Pr, np.concatenate((Z,) * R), sxy_rows,
                                 np.full(R * m, hd), table, np.full(R * m, i))
    d2 = mahalanobis2(nu, S).reshape(R, m)
    logdet = np.linalg.slogdet(S)[1].reshape(R, m)
    # Pd at each mode's predicted position; clutter density in (r, phi) at each detection.
    pd = detection_probabilities(table, np.full(R, i), x[:, :2], sxy_rows[:R])
    row = table[i]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        # lik = pd exp(-d2/2 - logdet/2) / (2 pi) / rho, rho = rate r / area per
        # detection; none = 1 - pd pg (compiled; exp and the row sums numpy's).
        lik, none, rho_positive = pda_likelihoods(
            pd, np.exp(-0.5 * d2 - 0.5 * logdet), np.ascontiguousarray(Z[:, 0]), row, pg)
        den, beta, beta0, den_ok = pda_weights(lik, none, lik.sum(axis=1))   # (R,), (R, m)
    if rho_positive and den_ok:
        log_den = np.log(den)
    else:
        # The direct form failed at an edge of the valid ranges: a very noisy radar
        # measured a range below the sensing region's (a clutter density <= 0), or every
        # likelihood under- or overflowed (Pd = 1, no gate, detections far off). Redo it
        # in logs with the density taken at the region's slant ranges; ratios survive.
        # Kept as a fallback so that every run the direct form handles stays bit for bit.
        with np.errstate(divide="ignore"):
            log_rho = np.log(clutter_densities(row, Z[:, 0], in_region=True))   # (m,)
            log_lik = (np.log(pd)[:, None] - 0.5 * d2 - 0.5 * logdet
                       - math.log(2.0 * math.pi) - log_rho[None])           # (R, m)
            log_none = np.log(1.0 - pd * pg)
        log_den = np.logaddexp(log_none, np.logaddexp.reduce(log_lik, axis=1))
        if not np.all(np.isfinite(log_den)):
            # The model gives these detections no probability at all (a sensing region
            # of zero area, a singular innovation): they carry no usable information.
            return None
        beta = np.exp(log_lik - log_den[:, None])
        beta0 = np.exp(log_none - log_den)
    nu = nu.reshape(R, m, 2)
    # Combined innovation and spread of innovations (the einsums' sums, compiled).
    nu_c, spread = pda_spread(beta, nu)
    Hp0, var0 = Hp.reshape(R, m, 2, 2)[:, 0], var.reshape(R, m, 2)[:, 0]
    xc, Pc = position_update(x, P, nu_c, Hp0, var0)                  # Joseph, P_c
    # Gain K = P H'^T S^-1 at the mode's linearisation (the same for every detection).
    S0 = S.reshape(R, m, 2, 2)[:, 0]
    PHt = P[:, :, :2] @ np.swapaxes(Hp0, -1, -2)
    K = np.swapaxes(np.linalg.solve(S0, np.swapaxes(PHt, -1, -2)), -1, -2)   # (R, 4, 2)
    Pn = np.empty_like(P)
    pda_covariances(P, Pc, K @ spread @ np.swapaxes(K, -1, -2), beta0, Pn)
    return xc, Pn, log_den
