"""The planners' utilities computed the plain way, as the second computation of the engine.

For a batch of candidate chains of one sensor: every chain's looks by
:func:`sensorplan.planners.information.chain_looks` (dense), the other players' information by
:func:`sensorplan.planners.information.sum_by_target`, and for every (candidate, target) pair with a
look that counts the full covariance recursion of that target (no shared prefix, no cache).
This is how the engine computed utilities before its speed-ups; the engine's kernels must give
the same numbers bit for bit.
"""

from __future__ import annotations

import numpy as np

from sensorplan.planners.information import chain_looks, covariance_recursion, sum_by_target
from sensorplan.planners.engine import GameState


def dense_gains(state: GameState, i: int, k0: int, cand_pos: np.ndarray,
                cand_tgt: np.ndarray) -> np.ndarray:
    """Phi(chain) - Phi(no chain) of each candidate chain ``(C, L)`` of sensor i from k0."""
    ctx = state.ctx
    C, L = cand_tgt.shape
    k_last = k0 + L - 1
    k_end = k_last
    if k_last < ctx.K and state.tgt[i, k_last] >= 0:
        k_end = k_last + 1
        while k_end < ctx.K and state.tgt[i, k_end] >= 0:
            k_end += 1
    prev_ok = k0 == 1 or state.tgt[i, k0 - 2] >= 0
    prev = state.heading[i, k0 - 2] if k0 > 1 and prev_ok else ctx.problem.headings[i]
    mask = state.tgt.copy()
    mask[i, k0 - 1:k_end] = -1
    W_fixed = sum_by_target(ctx, state.W, mask)
    s0 = (k0 - 1) * ctx.e
    cum = ctx.problem.objective == "cumulative"
    covs = np.array(ctx.problem.covs)
    P_pre, _, _ = covariance_recursion(covs, W_fixed[:, :s0], ctx.F, ctx.Q_rows(slice(None)),
                                       cum)
    _, ld_end_b, ld_sum_b = covariance_recursion(P_pre, W_fixed[:, s0:], ctx.F,
                                                 ctx.Q_rows(slice(None)), cum)
    # Chains: the candidate's epochs, then the sensor's following assigned epochs.
    Lf = k_end - k0 + 1
    pos = np.empty((C, Lf, 2))
    tgt = np.empty((C, Lf), dtype=np.int64)
    for l in range(Lf):
        kk = k0 + l
        idx = cand_pos[:, l] if l < L else np.full(C, state.pos[i, kk - 1])
        pos[:, l] = ctx.lattices[i].positions[kk][idx]
        tgt[:, l] = cand_tgt[:, l] if l < L else state.tgt[i, kk - 1]
    _, W_chain, counted = chain_looks(ctx, i, k0, pos, tgt, prev, prev_ok, all_headings=False)
    gains = np.zeros(C)
    for c in range(C):
        looked = sorted({int(tgt[c, l]) for l in range(Lf) if counted[c, l].any()})
        for j in looked:
            W_pair = W_fixed[j, s0:].copy()
            W_add = np.zeros_like(W_pair)
            for l in range(Lf):
                if tgt[c, l] == j:
                    W_add[l * ctx.e:(l + 1) * ctx.e] = W_chain[c, l]
            W_pair = W_fixed[j, s0:] + W_add
            _, ld_end, ld_sum = covariance_recursion(P_pre[j:j + 1], W_pair[None], ctx.F,
                                                     ctx.Q_rows(j), cum)
            # The target's weight, its probability of existence (1: no bit changes).
            r = ctx.problem.existence[j]
            if cum:
                gains[c] += r * (0.5 * (ld_sum_b[j] - ld_sum[0]))
            else:
                gains[c] += r * (0.5 * (ld_end_b[j] - ld_end[0]))
    return gains
