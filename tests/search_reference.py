"""The batched search utilities as they were before the compiled search term (commit
bb0564c): plain numpy, every candidate's whole plan recomputed. The tests run the planners
with these in place of :func:`sensorplan.planners.search.candidate_potentials` and require
the same plans (``tests/planners/test_search_fast.py``).
"""

from __future__ import annotations

import numpy as np

from sensorplan._types import FloatArray, IntArray
from sensorplan.models.angles import heading_rule
from sensorplan.planners.information import (chain_information, covariance_recursion,
                                             measured, phi_terms, sum_by_target)
from sensorplan.planners.problem import Plan
from sensorplan.planners.search import SearchContext, detection, expected_found, plan_headings


def candidate_potentials(sctx: SearchContext, plan: Plan, i: int, k: int,
                         positions: FloatArray, targets: IntArray, sectors: IntArray
                         ) -> FloatArray:
    """Phi with search for each candidate action of player (i, k), the others fixed: one
    batch over candidates (the track terms in one covariance recursion, mu vectorised over
    cells and candidates). Player (i, k)'s action also moves the headings of sensor i's
    later epochs (the heading rule chains them); those are recomputed per candidate.

    Returns
    -------
    (A,) nats
    """
    ctx = sctx.ctx
    A, K, L = len(targets), ctx.K, ctx.K - k + 1
    assert plan.sectors is not None
    headings = plan_headings(sctx, plan)
    # Sensor i's epochs k..K per candidate.
    pos = np.repeat(plan.positions[i, k - 1:][None], A, axis=0)
    tgt = np.repeat(plan.targets[i, k - 1:][None], A, axis=0)
    sec = np.repeat(plan.sectors[i, k - 1:][None], A, axis=0)
    pos[:, 0], tgt[:, 0], sec[:, 0] = positions, targets, sectors
    assigned = (tgt >= 0) | (sec >= 0)
    th = np.full((A, L), np.nan)
    theta0, turn = float(ctx.problem.headings[i]), float(ctx.max_turn[i])
    prev_ok = k == 1 or bool(plan.assigned[i, k - 2])
    h = np.full(A, theta0 if k == 1 or not prev_ok else float(headings[i, k - 2]))
    for l in range(L):
        kk = k + l
        if not assigned[0, l] and l > 0:       # later epochs: the same for every candidate
            prev_ok = False
            continue
        if ctx.M:
            aim = ctx.aim[np.maximum(tgt[:, l], 0), kk - 1]
            toward = np.arctan2(aim[:, 1] - pos[:, l, 1], aim[:, 0] - pos[:, l, 0])
        else:                                   # no track: every look is a sector look
            toward = np.zeros(A)
        b = np.where(sec[:, l] >= 0, sctx.bearings[i][np.maximum(sec[:, l], 0)]
                     if sctx.bearings[i].size else 0.0, toward)
        h = heading_rule(h, b, turn) if prev_ok else heading_rule(theta0, b, kk * turn)
        th[:, l] = h
        prev_ok = True
    info = _candidate_track_information(sctx, plan, i, k, headings, pos, tgt, th)
    # Search: every other look's miss probability, times each candidate's chain.
    miss = np.ones((K, len(sctx.centres)))
    for n in range(ctx.N):
        ks = np.flatnonzero(plan.assigned[n])
        if n == i:
            ks = ks[ks < k - 1]
        if ks.size:
            miss[ks] *= 1.0 - detection(sctx, n, plan.positions[n, ks], headings[n, ks])
    miss_c = np.broadcast_to(miss, (A,) + miss.shape).copy()
    for l in range(L):
        if assigned[0, l] or l == 0:
            p = detection(sctx, i, pos[:, l], th[:, l])
            miss_c[:, k - 1 + l] *= 1.0 - p
    mu = expected_found(sctx, miss_c)
    return info + sctx.weight * mu


def _candidate_track_information(sctx: SearchContext, plan: Plan, i: int, k: int,
                                 headings: FloatArray, pos: FloatArray, tgt: IntArray,
                                 th: FloatArray) -> FloatArray:
    """The tracks' part of Phi ``(A,)`` for each candidate of player (i, k): every other
    look's information plus the candidate's chain ``pos (A, L, 2)``, ``tgt (A, L)``, ``th
    (A, L)`` over epochs k..K (0 without tracks)."""
    ctx = sctx.ctx
    A, L = tgt.shape
    if ctx.M == 0:
        return np.zeros(A)
    track = tgt >= 0
    others = plan.targets.copy()
    others[i, k - 1:] = -1
    W_all, _ = _plan_track_W(sctx, plan, headings)
    base = sum_by_target(ctx, W_all, others)                        # (M, T, 2, 2)
    w, _ = chain_information(ctx, i, k, np.where(track[..., None], pos, 0.0),
                             np.where(track, th, 0.0), np.maximum(tgt, 0))
    w = np.where(track[..., None, None, None], w, 0.0)               # (A, L, e, 2, 2)
    Wt = np.broadcast_to(base, (A,) + base.shape).copy()
    e = ctx.e
    for l in range(L):
        for s in range(e):
            t = (k - 1 + l) * e + s
            rows = np.flatnonzero(track[:, l])      # one row per candidate: no repeats
            Wt[rows, tgt[rows, l], t] += w[rows, l, s]
    M, T = ctx.M, ctx.T
    P0 = np.broadcast_to(np.asarray(ctx.problem.covs), (A, M, 4, 4)).reshape(A * M, 4, 4)
    Q = ctx.Q if ctx.Q.shape[0] == 1 else np.broadcast_to(ctx.Q, (A, M, 4, 4)).reshape(
        A * M, 4, 4)
    cumulative = ctx.problem.objective == "cumulative"
    flat = Wt.reshape(A * M, T, 2, 2)
    _, ld_end, ld_sum = covariance_recursion(np.ascontiguousarray(P0), flat, ctx.F,
                                             np.ascontiguousarray(Q), cumulative)
    ld_bar = np.broadcast_to(ctx.ld_bar, (A, M, T + 1)).reshape(A * M, T + 1)
    info = phi_terms(ld_bar, ld_end, ld_sum, cumulative, measured(flat),
                     np.tile(ctx.existence, A)).reshape(A, M).sum(axis=1)
    return info


def _plan_track_W(sctx: SearchContext, plan: Plan, headings: FloatArray
                  ) -> tuple[FloatArray, IntArray]:
    ctx = sctx.ctx
    track = plan.targets >= 0
    W = np.zeros((ctx.N, ctx.K, ctx.e, 2, 2))
    for n in range(ctx.N):
        if track[n].any():
            w, _ = chain_information(ctx, n, 1,
                                     np.where(track[n][:, None], plan.positions[n], 0.0)[None],
                                     np.where(track[n], headings[n], 0.0)[None],
                                     np.maximum(plan.targets[n], 0)[None])
            W[n] = np.where(track[n][:, None, None, None], w[0], 0.0)
    return W, plan.targets


