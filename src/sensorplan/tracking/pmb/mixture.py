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

from ..._compiled.jit import njit
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


@njit(cache=True, error_model="numpy")
def _logdet(A: np.ndarray) -> float:
    """``ln|A|`` of a symmetric positive definite ``A (n, n)`` by its Cholesky factor."""
    n = A.shape[0]
    L = np.zeros((n, n))
    out = 0.0
    for i in range(n):
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = np.sqrt(acc)
                out += np.log(acc)
            else:
                L[i, j] = acc / L[j, j]
    return out


@njit(cache=True, error_model="numpy")
def _merge(wi: float, wj: float, mi: np.ndarray, mj: np.ndarray, Pi: np.ndarray,
           Pj: np.ndarray, m: np.ndarray, P: np.ndarray) -> None:
    """The moment-matched Gaussian of two components into ``m``, ``P``: ``j``'s moments
    when both weights are 0."""
    tot = wi + wj
    a = wi / tot if tot > 0.0 else 0.0
    c = wj / tot if tot > 0.0 else 1.0
    n = m.shape[0]
    for k in range(n):
        m[k] = a * mi[k] + c * mj[k]
    for k in range(n):
        for el in range(n):
            P[k, el] = (a * Pi[k, el] + c * Pj[k, el]
                        + a * c * (mi[k] - mj[k]) * (mi[el] - mj[el]))
    for k in range(n):
        for el in range(k):
            P[k, el] = P[el, k] = 0.5 * (P[k, el] + P[el, k])


@njit(cache=True, error_model="numpy")
def _reduce_rows(w: np.ndarray, m: np.ndarray, P: np.ndarray, keep: int,
                 out_w: np.ndarray, out_m: np.ndarray, out_P: np.ndarray) -> None:
    """:func:`reduce` of every row into ``out_*``."""
    q, K = w.shape
    n = m.shape[2]
    ld = np.zeros(K)
    alive = np.ones(K, dtype=np.bool_)
    mt = np.empty(n)
    Pt = np.empty((n, n))
    for r in range(q):
        ww, mm, PP = w[r].copy(), m[r].copy(), P[r].copy()
        for k in range(K):
            alive[k] = True
            ld[k] = _logdet(PP[k]) if ww[k] > 0.0 else 0.0
        for _ in range(K - keep):
            best, bi, bj = np.inf, -1, -1
            for i in range(K):
                if not alive[i]:
                    continue
                for j in range(i + 1, K):
                    if not alive[j]:
                        continue
                    cost = 0.0
                    if ww[i] > 0.0 and ww[j] > 0.0:
                        _merge(ww[i], ww[j], mm[i], mm[j], PP[i], PP[j], mt, Pt)
                        cost = 0.5 * ((ww[i] + ww[j]) * _logdet(Pt) - ww[i] * ld[i]
                                      - ww[j] * ld[j])
                    if cost < best:
                        best, bi, bj = cost, i, j
            _merge(ww[bi], ww[bj], mm[bi], mm[bj], PP[bi], PP[bj], mt, Pt)
            ww[bi] += ww[bj]
            mm[bi], PP[bi] = mt, Pt
            ld[bi] = _logdet(Pt) if ww[bi] > 0.0 else 0.0
            ww[bj] = 0.0
            alive[bj] = False
        s = 0
        for k in range(K):
            if alive[k]:
                out_w[r, s], out_m[r, s], out_P[r, s] = ww[k], mm[k], PP[k]
                s += 1


def reduce(weights: FloatArray, means: FloatArray, covs: FloatArray, keep: int
           ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Reduce each row's mixture to ``keep`` components by Runnalls' greedy merging.

    Parameters
    ----------
    weights : (q, K) >= 0;  means : (q, K, n);  covs : (q, K, n, n)
        The candidates; one of weight 0 may have any moments (it merges first, at no cost).
    keep : int in [1, K]

    Returns
    -------
    weights (q, keep), means (q, keep, n), covs (q, keep, n, n)
        Each row's survivors in their candidates' order; its weights sum to its
        candidates'. A component of weight 0 is one no candidate of positive weight reached
        (its moments are a placeholder).
    """
    w = np.ascontiguousarray(weights, dtype=float)
    m = np.ascontiguousarray(means, dtype=float)
    P = np.ascontiguousarray(covs, dtype=float)
    q, K = w.shape
    if not 1 <= keep <= K:
        raise ValueError(f"keep must be in [1, {K}], got {keep}")
    n = m.shape[-1]
    out = np.empty((q, keep)), np.empty((q, keep, n)), np.empty((q, keep, n, n))
    _reduce_rows(w, m, P, int(keep), *out)
    return out


__all__ = ["MAX_COMPONENTS", "components_as_modes", "detected_groups", "missed_groups",
           "predict", "reduce"]
