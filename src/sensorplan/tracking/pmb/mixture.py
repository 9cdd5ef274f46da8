r"""A Bernoulli whose density is a Gaussian mixture of its hypotheses.

With ``density_components = R > 1`` each Bernoulli keeps up to R Gaussian components
instead of one: after a look, each component's missed-look hypothesis and its detected
hypotheses (merged over the detections) are 2R candidates, which are reduced back to R by
merging, one pair at a time, the pair whose moment-matched merge loses the least
(Runnalls 2007, "Kullback-Leibler approach to Gaussian mixture reduction": the cost
:math:`\tfrac12[(w_i + w_j)\ln|P_{ij}| - w_i \ln|P_i| - w_j \ln|P_j|]`, an upper bound on
the Kullback-Leibler divergence the merge adds). A component of weight 0 merges at no cost,
so a Bernoulli's components stay apart only where the hypotheses do.

The components share the Bernoulli's existence and its one motion model; they are carried
in the arrays the IMM uses for its modes (:mod:`.modes`: ``mode_probs`` the components'
weights within the Bernoulli, ``mode_means``, ``mode_covs``), with no switching between
them, so the association, the missed-look update, the map's edge and the moment-matched
density the report and the planner see are the IMM's, word for word. What differs is the
predict (each component on its own, no mixing) and the merge after a look (this module).

Why: a track that has not been detected for a few steps is spread; a detection that is not
its target's, inside its gate, takes a share of its existence. Merged into one Gaussian the
track moves toward that detection as a whole, and the looks follow it away from the
target. Kept as components, the missed hypothesis stays where the target would be, and the
next detection of the target takes the weight back.
"""

from __future__ import annotations

import numpy as np

from ..._types import FloatArray, IntArray
from ..ekf import predict as kalman_predict
from .bernoulli import Bernoullis
from .modes import Modes

#: The most components a Bernoulli's density may keep.
MAX_COMPONENTS = 8


def components_as_modes(process_noise: float, Q: FloatArray, components: int) -> Modes:
    """The :class:`~.modes.Modes` of a mixture density of ``components`` Gaussians that
    share the motion model ``Q (4, 4)`` (q ``process_noise``): no switching between them,
    a new Bernoulli's weight all on its first."""
    if not (isinstance(components, (int, np.integer)) and 2 <= components <= MAX_COMPONENTS):
        raise ValueError(f"density_components must be an integer in [2, {MAX_COMPONENTS}] "
                         f"for a mixture, got {components!r}")
    R = int(components)
    initial = np.zeros(R)
    initial[0] = 1.0
    arrays = (np.full(R, float(process_noise)), np.repeat(np.asarray(Q)[None], R, axis=0),
              np.eye(R), initial)
    for a in arrays:
        a.flags.writeable = False
    return Modes(*arrays)


def predict(bern: Bernoullis, F: FloatArray, Q: FloatArray
            ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Each component's Kalman prediction (the Bernoullis' components replaced; not
    combined), returned as :func:`.modes.predict` returns: each component's start
    ``(n, R, 4)``, ``(n, R, 4, 4)`` and its prediction."""
    x0, P0 = bern.mode_means, bern.mode_covs
    assert x0 is not None and P0 is not None
    xp, Pp = kalman_predict(x0, P0, F, Q)
    bern.mode_means, bern.mode_covs = xp, Pp
    return x0, P0, xp, Pp


def missed_groups(q: int, R: int) -> IntArray:
    """The candidate each component's missed hypothesis goes to: of the updated Bernoulli
    ``g``'s component ``j`` (flat index ``g R + j``), candidate ``g 2R + j``."""
    k = np.arange(q * R)
    return (k // R) * (2 * R) + k % R


def detected_groups(group: IntArray, q: int, R: int) -> IntArray:
    """The candidates of a look's detected and started hypotheses, from their groups in
    :func:`.modes.mode_hypotheses` (``g R + j``, then ``q R + s``): component ``j``'s
    detections of Bernoulli ``g`` to candidate ``g 2R + R + j``, the s-th started
    Bernoulli to ``q 2R + s``."""
    group = np.asarray(group, dtype=np.int64)
    bern = group < q * R
    return np.where(bern, (group // R) * (2 * R) + R + group % R, group + q * R)


def _logdet(covs: FloatArray, on: np.ndarray) -> FloatArray:
    """``ln|P|`` where ``on``, 0 elsewhere (where ``P`` may be a placeholder)."""
    eye = np.broadcast_to(np.eye(covs.shape[-1]), covs.shape)
    return np.where(on, np.linalg.slogdet(np.where(on[..., None, None], covs, eye))[1], 0.0)


def reduce(weights: FloatArray, means: FloatArray, covs: FloatArray, keep: int
           ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Reduce each row's mixture to ``keep`` components by Runnalls' greedy merging.

    Parameters
    ----------
    weights : (q, K) >= 0;  means : (q, K, 4);  covs : (q, K, 4, 4)
        The candidates; one of weight 0 may have any moments (it merges first, at no cost).
    keep : int in [1, K]

    Returns
    -------
    weights (q, keep), means (q, keep, 4), covs (q, keep, 4, 4)
        Each row's weights sum to its candidates'; a component of weight 0 is one no
        candidate of positive weight reached (its moments are a placeholder).
    """
    q, K = weights.shape
    w, m, P = np.array(weights, dtype=float), np.array(means), np.array(covs)
    alive = np.ones((q, K), dtype=bool)
    ld = _logdet(P, w > 0.0)
    I, J = np.triu_indices(K, 1)
    rows = np.arange(q)
    for _ in range(K - keep):
        wi, wj = w[:, I], w[:, J]
        tot = wi + wj
        a = np.divide(wi, tot, out=np.zeros_like(tot), where=tot > 0.0)
        c = np.divide(wj, tot, out=np.ones_like(tot), where=tot > 0.0)
        d = m[:, I] - m[:, J]
        mij = a[..., None] * m[:, I] + c[..., None] * m[:, J]
        Pij = (a[..., None, None] * P[:, I] + c[..., None, None] * P[:, J]
               + (a * c)[..., None, None] * np.einsum("...i,...j->...ij", d, d))
        both = (wi > 0.0) & (wj > 0.0)
        ldij = _logdet(Pij, both)
        cost = np.where(both, 0.5 * (tot * ldij - wi * ld[:, I] - wj * ld[:, J]), 0.0)
        cost[~(alive[:, I] & alive[:, J])] = np.inf
        k = np.argmin(cost, axis=1)
        i, j = I[k], J[k]
        w[rows, i], m[rows, i] = tot[rows, k], mij[rows, k]
        P[rows, i] = 0.5 * (Pij[rows, k] + np.swapaxes(Pij[rows, k], -1, -2))
        ld[rows, i] = np.where(tot[rows, k] > 0.0, _logdet(P[rows, i], tot[rows, k] > 0.0),
                               0.0)
        w[rows, j] = 0.0
        alive[rows, j] = False
    r, s = np.nonzero(alive)                    # row-major: each row's survivors in order
    return (w[r, s].reshape(q, keep), m[r, s].reshape(q, keep, m.shape[-1]),
            P[r, s].reshape(q, keep, *P.shape[-2:]))


__all__ = ["MAX_COMPONENTS", "components_as_modes", "detected_groups", "missed_groups",
           "predict", "reduce"]
