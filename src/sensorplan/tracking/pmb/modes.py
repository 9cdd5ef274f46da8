r"""The interacting multiple model (IMM) motion of the PMB's Bernoullis.

Each Bernoulli's density is a mixture of R modes, CWNA motion models that differ in their
process noise, with a Markov switching matrix :math:`\Pi` (:math:`\Pi_{ij} = P(j \mid i)`),
as in the known-target tracker's IMM (:mod:`sensorplan.tracking.imm`, Blom and
Bar-Shalom 1988). Its existence is the Bernoulli's, shared by the modes; its density, what
the association, the report and the planner see, is the modes' moment-matched mixture.

- **Predict**: mixing :math:`\bar c_j = \sum_i \Pi_{ij}\mu_i`,
  :math:`\mu_{i|j} = \Pi_{ij}\mu_i/\bar c_j`, mixed initial conditions per mode, each
  mode's Kalman prediction with its own Q, :math:`\mu \leftarrow \bar c`. At an exit edge
  each mode keeps its mass on the map: :math:`r` is multiplied by
  :math:`\sum_j \mu_j M_j` and :math:`\mu_j \propto \mu_j M_j`.
- **A look**: the missed-look hypothesis of mode j has :math:`\bar P_j` (the quadrature
  of its own density), the Bernoulli's is :math:`\bar P = \sum_j \mu_j \bar P_j`; a
  detection's likelihood is :math:`l = \sum_j \mu_j l_j` (each mode linearised at its own
  mean, 0 outside its gate). The association runs on these Bernoulli-level weights, as
  with one model. The track-oriented merge then keeps one Gaussian per mode: mode j of
  Bernoulli i is the moment-matched mixture of its missed hypothesis, weight
  :math:`p^{miss}_i\, r_i \mu_j (1 - \bar P_j) / (1 - r_i \bar P)`, and its detections
  :math:`z_k`, weights :math:`p^{det}_{ik}\, \mu_j l_{jk} / l_k`; the existence is the
  sum of every weight (as with one model) and each mode's probability its share.
- A Bernoulli started by a detection has every mode at its one density, with the
  switching matrix's stationary probabilities.

With R = 1 this is the single-model Bernoulli (the tests check it to 1e-12).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._types import BoolArray, FloatArray, IntArray
from ...models.motion import cv_matrices
from .._imm_nb import combine_rows, mix
from ..ekf import predict as kalman_predict
from ..imm import stationary
from .bernoulli import Bernoullis, mode_copies
from .hypotheses import Hypotheses

_TINY = float(np.finfo(float).tiny)


@dataclass(frozen=True, eq=False)
class Modes:
    """The modes' motion: ``q (R,)`` (m^2/s^3), their CWNA covariances ``Q (R, 4, 4)``
    over a step, the switching matrix ``(R, R)`` and its stationary distribution ``(R,)``
    (a new Bernoulli's mode probabilities)."""

    q: FloatArray
    Q: FloatArray
    switching: FloatArray
    initial: FloatArray


def make_modes(dt: float, mode_process_noise: object, switching: object) -> Modes:
    """The :class:`Modes` of q's ``mode_process_noise`` (each >= 0) and a switching matrix
    ``(R, R)`` (entries in [0, 1], rows summing to 1).

    Raises
    ------
    ValueError
        Either out of range or of the wrong shape; the message names it.
    """
    q = np.asarray(mode_process_noise, dtype=float).reshape(-1)
    if q.size == 0 or not (np.all(np.isfinite(q)) and np.all(q >= 0.0)):
        raise ValueError(f"mode_process_noise must be one q >= 0 per mode, got "
                         f"{mode_process_noise!r}")
    Pi = np.asarray(switching, dtype=float)
    if Pi.shape != (q.size, q.size) or not (
            np.all(np.isfinite(Pi)) and np.all((Pi >= 0.0) & (Pi <= 1.0))
            and np.allclose(Pi.sum(axis=1), 1.0, rtol=0.0, atol=1e-9)):
        raise ValueError(f"switching must be a ({q.size}, {q.size}) matrix of probabilities "
                         f"whose rows sum to 1, got {switching!r}")
    Q = np.stack([cv_matrices(float(dt), float(v))[1] for v in q])
    for a in (q, Q, Pi):
        a.flags.writeable = False
    initial = stationary(Pi)
    initial.flags.writeable = False
    return Modes(q, Q, Pi, initial)


def start_modes(bern: Bernoullis, modes: Modes) -> None:
    """Give every Bernoulli ``R`` modes at its density, with the initial probabilities."""
    bern.mode_probs, bern.mode_means, bern.mode_covs = mode_copies(bern.means, bern.covs,
                                                                   modes.initial)


def combine(bern: Bernoullis, rows: IntArray | None = None) -> None:
    """Moment-match the modes of ``rows`` (None: every Bernoulli) into ``means`` and
    ``covs`` (new arrays)."""
    assert bern.mode_probs is not None and bern.mode_means is not None
    assert bern.mode_covs is not None
    rows = np.arange(len(bern)) if rows is None else np.asarray(rows, dtype=np.int64)
    means, covs = np.array(bern.means), np.array(bern.covs)
    combine_rows(bern.mode_probs, bern.mode_means, bern.mode_covs, rows, means, covs)
    bern.means, bern.covs = means, covs


def predict(bern: Bernoullis, F: FloatArray, modes: Modes
            ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Mixing and each mode's prediction (the Bernoullis' modes replaced; not combined).

    Returns
    -------
    x0 : (n, R, 4), P0 : (n, R, 4, 4)   the mixed initial conditions (each mode's start)
    xp : (n, R, 4), Pp : (n, R, 4, 4)   the predicted modes
    """
    mu, Pi = bern.mode_probs, modes.switching
    assert mu is not None
    c = np.maximum(mu @ Pi, 1e-300)
    x0, P0 = mix(mu, Pi, c, bern.mode_means, bern.mode_covs)
    xp, Pp = kalman_predict(x0, P0, F, modes.Q)      # Q (R, 4, 4): each mode its own
    bern.mode_probs = c / c.sum(axis=1, keepdims=True)
    bern.mode_means, bern.mode_covs = xp, Pp
    return x0, P0, xp, Pp


def keep_on_map(bern: Bernoullis, log_mass: FloatArray) -> None:
    """Each mode's mass on the map ``exp(log_mass) (n, R)``: the existence is multiplied by
    the modes' total, the probabilities by their own (renormalised; kept where the total
    is 0)."""
    assert bern.mode_probs is not None
    w = bern.mode_probs * np.exp(log_mass)
    mass = w.sum(axis=1)
    bern.r = bern.r * mass
    ok = mass > 0.0
    probs = np.array(bern.mode_probs)
    probs[ok] = w[ok] / mass[ok, None]
    bern.mode_probs = probs


def bernoulli_pbar(mode_probs: FloatArray, pbar_modes: FloatArray) -> FloatArray:
    r""":math:`\bar P = \sum_j \mu_j \bar P_j` of each Bernoulli ``(n,)`` from its modes'
    ``(n, R)``."""
    return np.einsum("nr,nr->n", mode_probs, pbar_modes)


def missed_weights(p_miss: FloatArray, r: FloatArray, pbar: FloatArray,
                   mode_probs: FloatArray, pbar_modes: FloatArray) -> FloatArray:
    r"""Each mode's missed-hypothesis weight ``(q, R)``:
    :math:`p^{miss}\, r\, \mu_j (1 - \bar P_j) / (1 - r \bar P)`; a row sums to the
    single-model weight :math:`p^{miss}\, r (1 - \bar P) / (1 - r \bar P)`."""
    scale = p_miss * r / np.maximum(1.0 - r * pbar, _TINY)
    return scale[:, None] * mode_probs * (1.0 - pbar_modes)


def missed_probs(mode_probs: FloatArray, pbar_modes: FloatArray) -> FloatArray:
    r"""The mode probabilities after a look that did not detect the target:
    :math:`\mu_j (1 - \bar P_j)`, renormalised (kept where every mode was surely
    detectable)."""
    w = mode_probs * (1.0 - pbar_modes)
    total = w.sum(axis=1, keepdims=True)
    return np.where(total > 0.0, w / np.maximum(total, _TINY), mode_probs)


@dataclass(frozen=True)
class ModeHypotheses:
    """A look's update hypotheses over the Bernoullis' modes and the cells.

    Attributes
    ----------
    unique : (U,) int   the distinct Gaussians updated: mode ``j`` of Bernoulli ``i`` is
                        ``i R + j``, cell ``c`` is ``n R + c``
    which : (K,) int    each hypothesis' index in ``unique``
    det : (K,) int      its detection
    weight : (K,)       its weight
    group : (K,) int    its mixture: ``g R + j`` for mode j of the g-th updated Bernoulli
                        (``Hypotheses.rows``), ``q R + s`` for the s-th started one
    """

    unique: IntArray
    which: IntArray
    det: IntArray
    weight: FloatArray
    group: IntArray


def mode_hypotheses(h: Hypotheses, lik_modes: FloatArray, mode_probs: FloatArray,
                    lik: FloatArray, n: int) -> ModeHypotheses:
    r"""Split each Bernoulli's detection hypothesis :math:`(i, k)` of ``h`` over its modes,
    weights :math:`p^{det}_{ik}\, \mu_j l_{jk} / l_k`, and renumber the cells' after the
    modes.

    Parameters
    ----------
    h : Hypotheses            of the look, over the Bernoulli-level weights
    lik_modes : (n, R, m)     each mode's likelihood of each detection (0 outside its gate)
    mode_probs : (n, R)
    lik : (n, m)              :math:`l_k = \sum_j \mu_j l_{jk}`
    n : int                   Bernoullis
    """
    R = mode_probs.shape[1]
    q = h.rows.size
    k1 = int(np.searchsorted(h.gauss, n))             # Bernoulli pairs first, then cells
    gi, dk = h.gauss[:k1], h.det[:k1]
    share = mode_probs[gi] * lik_modes[gi, :, dk] / lik[gi, dk][:, None]       # (k1, R)
    t, j = np.nonzero(share > 0.0)
    gauss = np.concatenate([gi[t] * R + j, n * R + (h.gauss[k1:] - n)])
    det = np.concatenate([dk[t], h.det[k1:]])
    weight = np.concatenate([h.weight[:k1][t] * share[t, j], h.weight[k1:]])
    group = np.concatenate([h.group[:k1][t] * R + j, q * R + (h.group[k1:] - q)])
    unique, which = np.unique(gauss, return_inverse=True)
    return ModeHypotheses(unique, which.reshape(-1), det, weight, group)


def merged_modes(bern: Bernoullis, rows: IntArray, total: FloatArray, means: FloatArray,
                 covs: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Write the merged modes of the updated Bernoullis ``rows (q,)``: ``total (q, R)``
    each mode's weight, ``means (q, R, 4)``, ``covs (q, R, 4, 4)`` its moments. A mode of
    weight 0 keeps its density (its probability is 0). Returns the existences ``(q,)`` and
    which rows have any weight."""
    assert bern.mode_probs is not None and bern.mode_means is not None
    assert bern.mode_covs is not None
    r_post = total.sum(axis=1)
    live = r_post > 0.0
    on = total > 0.0
    probs, mm, mP = np.array(bern.mode_probs), np.array(bern.mode_means), np.array(
        bern.mode_covs)
    probs[rows[live]] = total[live] / r_post[live, None]
    sub_m, sub_P = mm[rows], mP[rows]
    sub_m[on], sub_P[on] = means[on], covs[on]
    mm[rows], mP[rows] = sub_m, sub_P
    bern.mode_probs, bern.mode_means, bern.mode_covs = probs, mm, mP
    return r_post, live


def planning_noise(mode_probs: FloatArray, modes: Modes) -> FloatArray:
    """Each Bernoulli's effective q one step ahead, ``(mu Pi) . q`` ``(n,)``: what the
    planner predicts it with."""
    return (mode_probs @ modes.switching) @ modes.q


__all__ = ["ModeHypotheses", "Modes", "bernoulli_pbar", "combine", "keep_on_map",
           "make_modes", "merged_modes", "missed_probs", "missed_weights", "mode_hypotheses",
           "planning_noise", "predict", "start_modes"]
