r"""The interacting multiple model mixture of a set of tracks (Blom and Bar-Shalom 1988).

Each track has R modes, CWNA motion models that differ in their process noise, with a
Markov switching matrix :math:`\Pi`, :math:`\Pi_{ij} = P(j \mid i)`. Every step: mixing
:math:`\bar c_j = \sum_i \Pi_{ij}\mu_i`, :math:`\mu_{i|j} = \Pi_{ij}\mu_i/\bar c_j`, mixed
initial conditions per mode, the mode-matched predictions, :math:`\mu \leftarrow \bar c`;
every piece of evidence then updates each mode and multiplies its probability by the mode's
likelihood of that evidence (:meth:`ModeMixture.reweight`). The combined (moment-matched)
Gaussian is the track. With one mode it is a single extended Kalman filter.
"""

from __future__ import annotations

import numpy as np

from .._types import FloatArray, IntArray
from ..models.motion import cv_matrices
from ._imm_nb import (SEQUENTIAL_SUM, combine_rows, floored_rows, mix, normalise_rows,
                      shifted_by_max)
from .ekf import predict


def stationary(switching: FloatArray) -> FloatArray:
    """The stationary distribution ``pi = pi Pi`` of a Markov switching matrix ``(R, R)``."""
    R = switching.shape[0]
    # Solve (Pi^T - I) pi = 0 with sum(pi) = 1 (least squares on the stacked system).
    A = np.vstack([switching.T - np.eye(R), np.ones((1, R))])
    b = np.zeros(R + 1)
    b[-1] = 1.0
    pi = np.linalg.lstsq(A, b, rcond=None)[0]
    pi = np.clip(pi, 0.0, None)
    return pi / pi.sum()


class ModeMixture:
    """The modes of M tracks and their moment-matched combination.

    Parameters
    ----------
    means : (M, 4);  covs : (M, 4, 4) or (4, 4) (broadcast to every track)
    dt : float                   step (s)
    process_noise : float        q of the single-model filter (m^2/s^3)
    mode_process_noise : sequence of float, optional
        The IMM modes' q (m^2/s^3); None: the single-model filter.
    switching : (R, R), optional
        Markov switching matrix of the modes (rows sum to 1).

    Attributes
    ----------
    means, covs : (M, 4), (M, 4, 4)   the tracks (the modes' moment-matched Gaussians)
    mode_means, mode_covs, mode_probs : (M, R, 4), (M, R, 4, 4), (M, R)
    """

    def __init__(self, means: FloatArray, covs: FloatArray, dt: float, *,
                 process_noise: float, mode_process_noise: tuple[float, ...] | None = None,
                 switching: FloatArray | None = None) -> None:
        means = np.array(means, dtype=float)
        covs = np.array(np.broadcast_to(covs, means.shape + (4,)), dtype=float)
        self.dt = float(dt)
        self.F, self.Q = cv_matrices(dt, process_noise)
        if mode_process_noise is None:
            self.q_modes = np.array([float(process_noise)])
            self.switching = np.ones((1, 1))
        else:
            self.q_modes = np.asarray(mode_process_noise, dtype=float)
            self.switching = np.asarray(switching, dtype=float)
        self.Q_modes = np.stack([cv_matrices(dt, q)[1] for q in self.q_modes])
        self.initial_probs = stationary(self.switching)
        R = len(self.q_modes)
        M = len(means)
        self.mode_means = np.repeat(means[:, None], R, axis=1)
        self.mode_covs = np.repeat(covs[:, None], R, axis=1)
        self.mode_probs = np.tile(self.initial_probs, (M, 1))
        self.means, self.covs = means, covs
        self._all_rows = np.arange(M)

    @property
    def n_modes(self) -> int:
        return len(self.q_modes)

    def combine(self, targets: IntArray | slice = slice(None)) -> None:
        """Moment-match the modes of ``targets`` into their tracks (a slice: all of them)."""
        if self.n_modes == 1:
            self.means[targets] = self.mode_means[targets, 0]
            self.covs[targets] = self.mode_covs[targets, 0]
            return
        rows = self._all_rows if isinstance(targets, slice) else np.asarray(targets,
                                                                            dtype=np.int64)
        combine_rows(self.mode_probs, self.mode_means, self.mode_covs, rows, self.means,
                     self.covs)

    def reweight(self, targets: IntArray, log_likelihood: FloatArray) -> None:
        """Multiply mode probabilities by likelihoods ``(B, R)`` (log), renormalised."""
        if self.n_modes == 1:
            return
        # log(max(mu, 1e-300)) + L, minus its row maximum; then exp and normalise. The
        # elementwise steps are compiled, in numpy's order; log and exp stay numpy's.
        rows = np.asarray(targets, dtype=np.int64)
        w = np.exp(shifted_by_max(np.log(floored_rows(self.mode_probs, rows, 1e-300)),
                                  log_likelihood))
        if self.n_modes < SEQUENTIAL_SUM:
            normalise_rows(w, self.mode_probs, rows)
        else:
            self.mode_probs[rows] = w / w.sum(axis=1, keepdims=True)

    def planning_process_noise(self) -> float | FloatArray:
        """q the planner should predict with: the filter's q, or per target ``(M,)`` the
        IMM's effective q under the mode probabilities predicted one step ahead."""
        if self.n_modes == 1:
            return float(self.q_modes[0])
        return (self.mode_probs @ self.switching) @ self.q_modes

    def predict_modes(self) -> None:
        """Predict every track one step: mixing first for an IMM, then each mode's CWNA
        prediction, then the tracks moment-matched."""
        if self.n_modes == 1:
            self.mode_means[:, 0], self.mode_covs[:, 0] = predict(
                self.mode_means[:, 0], self.mode_covs[:, 0], self.F, self.Q)
        else:
            mu, Pi = self.mode_probs, self.switching
            c = np.maximum(mu @ Pi, 1e-300)                                  # (M, R)
            x0, P0 = mix(mu, Pi, c, self.mode_means, self.mode_covs)         # (M, R, ...)
            Fm = self.F
            xp = x0 @ Fm.T
            Pp = Fm @ P0 @ Fm.T + self.Q_modes[None]
            self.mode_means, self.mode_covs = xp, 0.5 * (Pp + np.swapaxes(Pp, -1, -2))
            self.mode_probs = c / c.sum(axis=1, keepdims=True)
        self.combine()

    def restart(self, rows: IntArray, means: FloatArray, covs: FloatArray) -> None:
        """Start tracks ``rows`` afresh at ``means (B, 4)``, ``covs (B, 4, 4)``, every mode
        the same, mode probabilities at their initial values."""
        self.mode_means[rows] = means[:, None]
        self.mode_covs[rows] = covs[:, None]
        self.mode_probs[rows] = self.initial_probs
        self.combine(rows)
