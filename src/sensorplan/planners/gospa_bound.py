r"""The GOSPA-bound reward: Phi with search as the expected GOSPA bound a plan removes.

With ``reward = "gospa"`` (search on), Phi is how much a plan lowers the expected GOSPA
bound (alpha = 2, p = 2, cut-off c) of the tracks and of the undetected targets, in m^2:

.. math::
    \Phi_G(a) = \sum_j r_j\, \big[B_j - G_j(a)\big] + g \sum_{s=1}^{T} \omega_s\, f_s(a),

- ``G_j(a) = min(tr P_j(T | Z_j(a)), c^2)`` (``terminal``) or the same summed over the steps
  t = 1..T (``cumulative``), ``P_j(t | Z_j(a))`` the position block of track j's covariance
  after the plan's looks up to t (the covariance-only recursion of the information
  objective) and ``B_j`` the same without any look; ``r_j`` the track's probability of
  existence;
- ``f_s(a)`` the expected number of undetected targets the plan's looks find at step s (the
  terms of the information reward's mu, :func:`sensorplan.planners.search.expected_found`,
  so ``sum_s f_s = mu``);
- ``omega_s = p_S^(T-s)`` (``terminal``) or ``sum_{t=s..T} p_S^(t-s)`` (``cumulative``):
  a target found at step s is still alive at step t with probability ``p_S^(t-s)``; with a
  find tail of L steps (``problem.find_tail``, default 0) each adds
  ``p_S^(T-s) sum_{m=1..L} p_S^m``: the steps after the horizon a target not found would
  stay missed, while a track's covariance is restored by the next look at it, so the
  first sum counts the horizon only;
- ``g = max(0, c^2/2 - min(tr C_f, c^2))``: a found target's bound drops from the missed
  cost c^2/2 to its localisation cost, ``C_f`` the position covariance of a target known
  only to lie in its cell after one detection (the detection of
  :func:`~sensorplan.planners.search.first_detection_weight`).

A track the tracker does not report (``problem.reported`` False: a Bernoulli below the
report threshold) costs ``r c^2/2`` whatever its covariance: if it exists it is missed. Its
term in the first sum is 0; it is found instead, as a point of undetected intensity with
mass ``r_j`` at its predicted mean (surviving as the cells do), so ``f_s`` counts it too.

With ``track_existence = "resolved"`` a reported track's term adds what the plan's looks
tell about whether it exists. A track of existence r and capped localisation cost
``L = min(tr P, c^2/2)`` costs ``r L + (1 - r) c^2/2`` reported and ``r c^2/2`` not; the
tracker can report it or not, so its bound is the smaller. If every look covering its
predicted mean through step t misses it (probability ``Q_t = prod (1 - P_d v)`` given that
it exists), its existence falls and the smaller cost may become not reporting it; the
expected bound then drops by

.. math::
    E_t(Q_t) - E_t(1),\qquad
    E_t(Q) = \max\big(0,\ (1 - r_t)\, c^2/2 - r_t\, Q\, (c^2/2 - L_t)\big),

``r_t = p_S^t r`` (exact for one step: over a longer horizon the track is taken to exist
throughout if it exists at t), ``L_t`` from the track's covariance without any look (a
detection's covariance reduction is the first sum's term), summed over t = 1..T
(``cumulative``) or at T. E is convex, non-increasing in Q and 0 at Q = 1 for a track
whose existence is above the bound's report point, so the term is at least 0 and largest
for tracks near it. Every look whose beam covers the track counts (a look detects every
target in its beam), not only the looks aimed at it. The cost is capped at c^2/2: a track
whose localisation costs more than a missed target would not be reported anyway.

Why this form: a reported track j costs ``r_j min(tr P_j, c^2) + (1 - r_j) c^2/2`` (a false
track when it does not exist) and an undetected target c^2/2 while alive; with ``fixed``
existence looks change neither ``r_j`` nor how many targets live, so the ``(1 - r_j)`` part
and every target never found cancel in the difference (the expected existence after a look
is r_j again, and the cost is linear in it; only the choice of not reporting, which makes
the bound concave in r_j, lets a look's existence information lower it: ``resolved``).
Unmeasured tracks contribute exactly 0 and measured ones at least 0 (a look never widens
the covariance), so ``Phi_G >= 0``. Phi_G is a closed form of
the joint plan, so each player's utility is its marginal contribution and the game stays an
exact potential game. docs/planning.md derives it.

:func:`evaluate` is the reference definition (plain loops over targets, steps and looks);
:func:`candidate_potentials` the batched one the planners use (tested equal). The planners
reach both through :func:`sensorplan.planners.search.evaluate` and
:func:`~sensorplan.planners.search.candidate_potentials`, which hand over the plan's
headings; this module does not import the search module (it is imported by it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..models import radar
from ..models.motion import predict_covariance
from .cells import candidate_chains, detection
from .information import (Context, chain_information, epoch_information,
                          information_update, sum_by_target)
from .problem import Plan


class SearchParts(Protocol):
    """What this module reads of a :class:`~sensorplan.planners.search.SearchContext`."""

    @property
    def ctx(self) -> Context: ...
    @property
    def bearings(self) -> list[FloatArray]: ...
    @property
    def centres(self) -> FloatArray: ...
    @property
    def d0(self) -> FloatArray: ...
    @property
    def births(self) -> FloatArray: ...
    @property
    def survival(self) -> float: ...
    @property
    def gospa(self) -> GospaContext | None: ...


@dataclass(frozen=True)
class GospaContext:
    """Per-decision precomputation of the GOSPA-bound reward.

    Attributes
    ----------
    c2 : float               c^2 (m^2)
    found_value : float      g, m^2 of bound a found target removes (>= 0)
    step_weights : (T,)      omega_s: how much of a step-s find counts in the bound
    baseline : (M, T)        ``min(tr Pbar_j(t), c^2)`` for t = 1..T, without any look
    cumulative : bool        the objective
    track_weights : (M,)     r_j for a reported track, 0 for one not reported
    unreported : (U,) int    the tracks not reported, found as points
    points : (U, T, 2)       their predicted ground positions at t = 1..T
    resolved : (R,) int      with ``track_existence = "resolved"``, the reported tracks
                             (else empty)
    resolved_points : (R, T, 2)   their predicted ground positions at t = 1..T
    resolved_existence : (R, T)   their existence predicted to t, ``p_S^t r``
    resolved_cost : (R, T)   their localisation cost without a look, ``min(tr Pbar, c^2/2)``
    """

    c2: float
    found_value: float
    step_weights: FloatArray
    baseline: FloatArray
    cumulative: bool
    track_weights: FloatArray
    unreported: IntArray
    points: FloatArray
    resolved: IntArray
    resolved_points: FloatArray
    resolved_existence: FloatArray
    resolved_cost: FloatArray


def found_covariance(sctx: SearchParts) -> FloatArray:
    """``C_f (2, 2)``: a target known only to lie in a cell, after one detection by sensor
    0 on its boresight at the middle of its ground-range band (the detection that fixes
    the information reward's w, without the detection probability: it happened)."""
    ctx = sctx.ctx
    cell = np.asarray(ctx.problem.undetected.cell_cov if ctx.problem.undetected is not None
                      else np.eye(2), dtype=float)
    s = ctx.problem.sensors[0]
    mid = 0.5 * (float(s.min_ground_range) + float(s.max_ground_range))
    C = np.array([cell[0, 0], cell[0, 1], cell[1, 1]])
    W, p = radar.look_information(ctx.radar[0], np.array([mid]), np.array([0.0]),
                                  np.array([0.0]), C[None], True, ctx.buildings,
                                  np.zeros((1, 2)))
    if not p[0] > 0:
        return cell
    # (C^-1 + W)^-1 = (I + C W)^-1 C, without inverting C.
    return np.asarray(np.linalg.solve(np.eye(2) + cell @ (W[0] / p[0]), cell))


def step_weights(survival: float, T: int, cumulative: bool, tail: int = 0) -> FloatArray:
    """``omega (T,)``: the weight of a target found at step s = 1..T in the bound, counted
    over the horizon and ``tail`` steps after it."""
    powers = float(survival) ** np.arange(T, dtype=float)          # p_S^m, m = 0..T-1
    # Step s's weight reads m = T - s: the last power, or the sum of the first T - s + 1
    # (a running sum, not the geometric closed form, which cancels near p_S = 1).
    table = np.cumsum(powers) if cumulative else powers
    after = float(np.sum(float(survival) ** np.arange(1, tail + 1, dtype=float)))
    return np.asarray(table[::-1] + after * powers[::-1], dtype=float)


def prepare(sctx: SearchParts) -> GospaContext:
    """The reward's precomputation for a searching decision whose ``reward`` is gospa."""
    ctx = sctx.ctx
    c2 = float(ctx.problem.gospa_c) ** 2
    Cf = found_covariance(sctx)
    g = max(0.0, 0.5 * c2 - min(float(np.trace(Cf)), c2))
    cumulative = ctx.problem.objective == "cumulative"
    Pbar = ctx.Pbar[:, 1:]
    baseline = np.minimum(Pbar[..., 0, 0] + Pbar[..., 1, 1], c2)
    reported = (np.ones(ctx.M, dtype=bool) if ctx.problem.reported is None
                else np.asarray(ctx.problem.reported, dtype=bool))
    unreported = np.flatnonzero(~reported)
    resolved = (np.flatnonzero(reported) if ctx.problem.track_existence == "resolved"
                else np.zeros(0, dtype=np.int64))
    survived = float(sctx.survival) ** np.arange(1, ctx.T + 1, dtype=float)
    return GospaContext(c2, g, step_weights(sctx.survival, ctx.T, cumulative,
                                            int(ctx.problem.find_tail)), baseline,
                        cumulative, np.where(reported, ctx.existence, 0.0), unreported,
                        np.ascontiguousarray(ctx.xbar[unreported, 1:, :2]), resolved,
                        np.ascontiguousarray(ctx.xbar[resolved, 1:, :2]),
                        np.asarray(ctx.existence, dtype=float)[resolved, None] * survived,
                        np.minimum(baseline[resolved], 0.5 * c2))


def point_detection(sctx: SearchParts, i: int, k: int, positions: FloatArray,
                    headings: FloatArray, points: FloatArray | None = None) -> FloatArray:
    """``P_d v`` at the unreported tracks' predicted means at each step of epoch k, for
    looks of sensor i: ``(B, e, U)`` from poses ``positions (B, 2)``, ``headings (B,)``
    (the call :func:`~sensorplan.planners.cells.detection` makes at the cells' centres);
    at ``points (U, T, 2)`` instead when given."""
    ctx, gctx = sctx.ctx, sctx.gospa
    assert gctx is not None
    if points is None:
        points = gctx.points
    e, U = ctx.e, len(points)
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    B = len(positions)
    pts = points[:, (k - 1) * e:k * e]                                   # (U, e, 2)
    d = pts.transpose(1, 0, 2)[None] - positions[:, None, None, :]       # (B, e, U, 2)
    p = radar.detectable_points(ctx.radar, np.full(B, i, dtype=np.int64),
                                np.ascontiguousarray(d[..., 0].reshape(B, e * U)),
                                np.ascontiguousarray(d[..., 1].reshape(B, e * U)),
                                np.asarray(headings, dtype=float).reshape(B), positions,
                                ctx.buildings)
    return np.asarray(p, dtype=float).reshape(B, e, U)


def _bound_terms(gctx: GospaContext, traces: FloatArray, measured: BoolArray) -> FloatArray:
    """Per-track terms ``r_j (B_j - G_j)`` from the position traces ``(..., M, T)`` after
    the looks: exactly 0 unmeasured or not reported, at least 0 measured (below 0 is
    round-off)."""
    drop = gctx.baseline - np.minimum(traces, gctx.c2)
    term = drop.sum(axis=-1) if gctx.cumulative else drop[..., -1]
    return gctx.track_weights * np.where(measured, np.maximum(term, 0.0), 0.0)


def _existence_terms(gctx: GospaContext, miss: FloatArray) -> FloatArray:
    """The ``resolved`` tracks' existence terms ``(..., R)`` from each step's probability
    that the plan's looks miss each track, ``miss (..., T, R)`` (module docstring)."""
    half = 0.5 * gctx.c2
    r = gctx.resolved_existence.T                                        # (T, R)
    stake = (1.0 - r) * half
    gain = r * (half - gctx.resolved_cost.T)
    Q = np.cumprod(miss, axis=-2)
    drop = np.maximum(0.0, stake - gain * Q) - np.maximum(0.0, stake - gain)
    return np.asarray(drop.sum(axis=-2) if gctx.cumulative else drop[..., -1, :])


def evaluate(sctx: SearchParts, plan: Plan, headings: FloatArray
             ) -> tuple[float, FloatArray, float, float, IntArray]:
    """Phi_G of ``plan`` whose look headings are ``headings (N, K)``: the reference
    definition (plain loops, one plan).

    Returns
    -------
    potential : float           m^2
    information : (M,)          the tracks' terms ``r_j (B_j - G_j)`` (m^2; 0 not reported),
                                with ``resolved`` existence their existence terms added
    found : float               mu (undetected targets and unreported tracks found)
    weight : float              the bound removed per target found: ``potential =
                                information.sum() + weight * found`` (g when mu = 0)
    measurements : (N, K) int   a track look's looks that count, a search look's steps when
                                it covers a cell
    """
    ctx = sctx.ctx
    gctx = sctx.gospa
    assert gctx is not None and plan.sectors is not None
    N, K, M, T, e = ctx.N, ctx.K, ctx.M, ctx.T, ctx.e
    counts = np.zeros((N, K), dtype=np.int64)
    W = np.zeros((M, T, 2, 2))
    miss = np.ones((K, len(sctx.centres)))
    U = len(gctx.unreported)
    miss_points = np.ones((T, U))
    R_res = len(gctx.resolved)
    miss_resolved = np.ones((T, R_res))
    # The points looks find (tracks not reported) and those whose misses tell existence.
    points = np.concatenate([gctx.points, gctx.resolved_points])
    for i in range(N):
        for k in range(1, K + 1):
            if not plan.assigned[i, k - 1]:
                continue
            pos, th = plan.positions[i, k - 1], headings[i, k - 1]
            j = int(plan.targets[i, k - 1])
            if j >= 0:
                w, counted = epoch_information(ctx, i, k, pos[None], np.array([th]),
                                               np.array([j]))
                for s in range(e):
                    W[j, (k - 1) * e + s] += w[0, s]
                counts[i, k - 1] = int(counted[0].sum())
            p = detection(sctx, i, pos[None], np.array([th]))[0]
            miss[k - 1] *= 1.0 - p
            if U or R_res:
                pp = point_detection(sctx, i, k, pos[None], np.array([th]), points)[0]
                for s in range(e):
                    miss_points[(k - 1) * e + s] *= 1.0 - pp[s, :U]
                    miss_resolved[(k - 1) * e + s] *= 1.0 - pp[s, U:]
            if j < 0 and (p > 0).any():
                counts[i, k - 1] = e          # a search look counts at each step it covers
    traces = np.zeros((M, T))
    for j in range(M):
        P = np.asarray(ctx.problem.covs[j], dtype=float)
        Q = ctx.Q_rows(j)[0]
        for t in range(T):
            P = ctx.F @ P @ ctx.F.T + Q
            if np.any(W[j, t] != 0.0):
                # Information form of the update: P - P G^T (I + W C)^-1 W G P.
                C = P[:2, :2]
                S = np.linalg.solve(np.eye(2) + W[j, t] @ C, W[j, t])
                P = P - P[:, :2] @ S @ P[:2, :]
                P = 0.5 * (P + P.T)
            traces[j, t] = P[0, 0] + P[1, 1]
    measured = np.array([bool(np.any(W[j] != 0.0)) for j in range(M)], dtype=bool)
    info = _bound_terms(gctx, traces, measured)
    if R_res:
        info[gctx.resolved] += _existence_terms(gctx, miss_resolved)
    # Undetected targets and unreported tracks found at each step, and how long each find
    # counts.
    D = np.array(sctx.d0, dtype=float)
    R = np.array(ctx.existence[gctx.unreported], dtype=float)
    f = np.zeros(T)
    for t in range(T):
        m = miss[t // e]
        D = sctx.survival * D + sctx.births
        f[t] = float(np.sum(D * (1.0 - m)))
        D = D * m
        if U:
            R = sctx.survival * R
            f[t] += float(np.sum(R * (1.0 - miss_points[t])))
            R = R * miss_points[t]
    kept = 0.0
    # Bound removed at step t by the targets found so far; the tail's steps see no looks.
    for t in range(T + int(ctx.problem.find_tail)):
        alive = sum(f[s] * sctx.survival ** (t - s) for s in range(min(t + 1, T)))
        if gctx.cumulative or t >= T - 1:
            kept += alive
    mu = float(f.sum())
    term = gctx.found_value * kept
    weight = term / mu if mu > 0 else gctx.found_value
    return float(info.sum()) + term, info, mu, weight, counts


def candidate_potentials(sctx: SearchParts, plan: Plan, i: int, k: int,
                         positions: FloatArray, targets: IntArray, sectors: IntArray,
                         headings: FloatArray) -> FloatArray:
    """Phi_G for each candidate action of player (i, k), the others fixed: one batch over
    candidates (the tracks' covariance recursion over candidates x tracks, the finds over
    candidates x cells). ``headings (N, K)`` are the plan's; the candidate's heading chains
    through sensor i's later epochs.

    Returns
    -------
    (A,) m^2
    """
    ctx = sctx.ctx
    gctx = sctx.gospa
    assert gctx is not None and plan.sectors is not None
    A, K, L, M, e = len(targets), ctx.K, ctx.K - k + 1, ctx.M, ctx.e
    pos, tgt, assigned, th = candidate_chains(sctx, plan, i, k, positions, targets,
                                                sectors, headings)
    value = np.zeros(A)
    if M:
        value += _candidate_tracks(sctx, gctx, plan, i, k, headings, pos, tgt, th)
    # Finds: every other look's miss probability, times each candidate's chain.
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
            miss_c[:, k - 1 + l] *= 1.0 - detection(sctx, i, pos[:, l], th[:, l])
    f = _batched_finds(sctx.d0, sctx.births, sctx.survival, miss_c, ctx.T, e)
    U, R = len(gctx.unreported), len(gctx.resolved)
    if U or R:
        # The tracks not reported (found as points) and the resolved ones (their misses
        # tell their existence): one pass over the looks for both.
        miss_p = _candidate_point_misses(sctx, plan, i, k, headings, pos, assigned, th,
                                         np.concatenate([gctx.points, gctx.resolved_points]))
        if U:
            f += _batched_finds(ctx.existence[gctx.unreported], 0.0, sctx.survival,
                                miss_p[..., :U], ctx.T, 1)
        if R:
            value += _existence_terms(gctx, miss_p[..., U:]).sum(axis=-1)
    return value + gctx.found_value * (f @ gctx.step_weights)


def _candidate_point_misses(sctx: SearchParts, plan: Plan, i: int, k: int,
                            headings: FloatArray, pos: FloatArray, assigned: BoolArray,
                            th: FloatArray, points: FloatArray) -> FloatArray:
    """``(A, T, U)``: the probability that each candidate's plan misses each of ``points
    (U, T, 2)`` at each step, every other look's misses times the candidate's chain."""
    ctx = sctx.ctx
    A, L = pos.shape[:2]
    T, e = ctx.T, ctx.e
    miss = np.ones((T, len(points)))
    for n in range(ctx.N):
        for a in np.flatnonzero(plan.assigned[n]):
            if n == i and a >= k - 1:
                continue
            p = point_detection(sctx, n, int(a) + 1, plan.positions[n, a][None],
                                headings[n, a:a + 1], points)[0]
            miss[a * e:(a + 1) * e] *= 1.0 - p
    miss_c = np.broadcast_to(miss, (A,) + miss.shape).copy()
    for l in range(L):
        if assigned[0, l] or l == 0:
            kk = k + l
            miss_c[:, (kk - 1) * e:kk * e] *= 1.0 - point_detection(sctx, i, kk, pos[:, l],
                                                                     th[:, l], points)
    return miss_c


def _batched_finds(d0: FloatArray, births: FloatArray | float, survival: float,
                   miss: FloatArray, T: int, e: int) -> FloatArray:
    """``(A, T)``: the expected finds at each of ``T`` steps of a pool ``d0 (P,)`` of cells
    or points (``births`` per step, each surviving with ``survival``) under each candidate's
    miss probabilities ``miss (A, T / e, P)``, one row per period of ``e`` steps."""
    A = miss.shape[0]
    D = np.broadcast_to(d0, (A,) + np.shape(d0)).copy()
    f = np.zeros((A, T))
    for t in range(T):
        m = miss[:, t // e]
        D = survival * D + births
        f[:, t] = (D * (1.0 - m)).sum(axis=-1)
        D = D * m
    return f


def _candidate_tracks(sctx: SearchParts, gctx: GospaContext, plan: Plan, i: int, k: int,
                      headings: FloatArray, pos: FloatArray, tgt: IntArray, th: FloatArray
                      ) -> FloatArray:
    """The tracks' part of Phi_G ``(A,)``: every other track look plus each candidate's
    chain over epochs k..K, one covariance recursion over candidates x tracks."""
    ctx = sctx.ctx
    A, L = tgt.shape
    M, T, e = ctx.M, ctx.T, ctx.e
    track = tgt >= 0
    others = plan.targets.copy()
    others[i, k - 1:] = -1
    W_plan = np.zeros((ctx.N, ctx.K, e, 2, 2))
    for n in range(ctx.N):
        ks = np.flatnonzero(others[n] >= 0)
        if ks.size:
            w, _ = chain_information(ctx, n, 1, np.nan_to_num(plan.positions[n])[None],
                                     np.nan_to_num(headings[n])[None],
                                     np.maximum(plan.targets[n], 0)[None])
            W_plan[n, ks] = w[0, ks]
    base = sum_by_target(ctx, W_plan, others)                        # (M, T, 2, 2)
    w, _ = chain_information(ctx, i, k, np.where(track[..., None], pos, 0.0),
                             np.where(track, th, 0.0), np.maximum(tgt, 0))
    Wt = np.broadcast_to(base, (A,) + base.shape).copy()             # (A, M, T, 2, 2)
    for l in range(L):
        rows = np.flatnonzero(track[:, l])          # one row per candidate: no repeats
        for s in range(e):
            Wt[rows, tgt[rows, l], (k - 1 + l) * e + s] += w[rows, l, s]
    flat = Wt.reshape(A * M, T, 2, 2)
    P = np.broadcast_to(np.asarray(ctx.problem.covs), (A, M, 4, 4)).reshape(A * M, 4, 4)
    Q = ctx.Q if ctx.Q.shape[0] == 1 else np.broadcast_to(ctx.Q, (A, M, 4, 4)).reshape(
        A * M, 4, 4)
    traces = np.empty((A * M, T))
    for t in range(T):
        P = predict_covariance(P, ctx.F, Q)
        P, _ = information_update(P, flat[:, t])
        traces[:, t] = P[:, 0, 0] + P[:, 1, 1]
    measured = np.any(flat != 0.0, axis=(-3, -2, -1)).reshape(A, M)
    return _bound_terms(gctx, traces.reshape(A, M, T), measured).sum(axis=-1)


__all__ = ["GospaContext", "SearchParts", "candidate_potentials", "detection", "evaluate",
           "found_covariance", "point_detection", "prepare", "step_weights"]
