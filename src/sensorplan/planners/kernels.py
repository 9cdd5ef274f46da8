"""Compiled kernels of the planning engine (:mod:`sensorplan.planners.engine`).

Two loops do the planners' work:

* :func:`chain_pairs_nb` computes the looks of a batch of candidate chains of one sensor and
  keeps, sparsely, only the (candidate, target) pairs with a look that counts, with that
  pair's information from its first non-zero step on;
* :func:`gains_nb` turns such pairs into utilities: for every player of a batch it sums the
  other players' looks, recomputes each target's baseline recursion where those looks
  changed, and then the pairs of those targets only.

Both repeat, operation for operation, what the readable path does (``chain_looks`` then a
dense covariance recursion per pair): the same headings, the same radar calls, the same
predict and update steps in the same order, so every utility is bit for bit the one the
dense computation gives. What they skip is only work whose result is known exactly: looks
beyond the radar's reach (:func:`sensorplan.radar.reach`), and the steps of a pair before
its first look, which equal the baseline's steps.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._kernels import _heading_rule, logdet4, predict_step, update_step
from ..radar import P_VIS_MIN, look_at_azimuth, look_range, reach


@njit(cache=True)
def chain_pairs_nb(pos: np.ndarray, tgt: np.ndarray, k0: int, e: int, prev: float,
                   prev_ok: bool, theta0: float, max_turn: float, aim: np.ndarray,
                   xbar: np.ndarray, Cbar: np.ndarray, probabilistic: bool, row: np.ndarray,
                   n_steps: int) -> tuple:
    """The (candidate, target) pairs of candidate chains with a look that counts.

    A chain of sensor ``row`` covers epochs ``k0 .. k0 + L - 1`` (positions ``pos (C, L, 2)``,
    targets ``tgt (C, L)``); headings and looks are those of
    :func:`sensorplan._kernels.chain_looks_nb` with ``all_headings=False``, computed with
    less work: the heading-free part of a look (:func:`sensorplan.radar.look_range`) once per
    epoch that every candidate shares; the looks of the shared tail of the chain once per
    distinct heading entering it (candidates whose turn is clipped enter it with the same
    heading, bit for bit); and nothing for last-epoch targets out of the radar's reach.

    Returns
    -------
    c_pair, j_pair : (n,) int64   pairs in order of candidate, then target
    first : (n,) int64            first step (from ``s0 = (k0 - 1) e``, 0-based) whose
                                  information is non-zero (``n_steps`` if none)
    count : (n,) int64            steps stored from ``first`` on
    offset : (n,) int64           row of step ``first`` in ``data``
    data : (m, 3)                 w00, w01, w11 of the pair's looks, steps ``first ..
                                  first + count - 1`` (zero where it does not look)
    rep : (C,) int64              the first candidate with exactly the same pairs (itself
                                  unless a duplicate; a duplicate's pairs are left out)
    """
    C, L = tgt.shape
    M = aim.shape[0]
    last_t0 = (k0 + L - 2) * e + 1          # first step of the last epoch
    # Targets beyond reach of every candidate position in the last epoch: no look counts.
    x_lo, x_hi, y_lo, y_hi = np.inf, -np.inf, np.inf, -np.inf
    for c in range(C):
        x_lo = min(x_lo, pos[c, L - 1, 0])
        x_hi = max(x_hi, pos[c, L - 1, 0])
        y_lo = min(y_lo, pos[c, L - 1, 1])
        y_hi = max(y_hi, pos[c, L - 1, 1])
    reach2 = np.empty((M, e))
    far = np.ones(M, dtype=np.bool_)
    for j in range(M):
        for s in range(e):
            t = last_t0 + s
            R = reach(row, Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2], probabilistic)
            reach2[j, s] = R * R * (1.0 + 1e-12)
            dx = max(x_lo - xbar[j, t, 0], 0.0, xbar[j, t, 0] - x_hi)
            dy = max(y_lo - xbar[j, t, 1], 0.0, xbar[j, t, 1] - y_hi)
            if dx * dx + dy * dy <= reach2[j, s]:
                far[j] = False
    # Epochs whose position and target are the same for every candidate: their bearing and
    # the heading-free part of their looks are computed once.
    shared = np.zeros(L, dtype=np.bool_)
    sh_bearing = np.zeros(L)
    sh_range = np.zeros((L, e, 3))                   # p, g^2, g
    for l in range(L):
        same = C > 0
        for c in range(1, C):
            if (tgt[c, l] != tgt[0, l] or pos[c, l, 0] != pos[0, l, 0]
                    or pos[c, l, 1] != pos[0, l, 1]):
                same = False
                break
        if same:
            j = tgt[0, l]
            k = k0 + l
            shared[l] = True
            sh_bearing[l] = math.atan2(aim[j, k - 1, 1] - pos[0, l, 1],
                                       aim[j, k - 1, 0] - pos[0, l, 0])
            for s in range(e):
                t = (k - 1) * e + 1 + s
                sh_range[l, s, 0], sh_range[l, s, 1], sh_range[l, s, 2] = look_range(
                    row, xbar[j, t, 0] - pos[0, l, 0], xbar[j, t, 1] - pos[0, l, 1],
                    Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2], probabilistic)
    # The shared tail: epochs tail .. L-1 are shared; their looks depend only on the
    # heading entering them. Keep the results of a few distinct entering headings.
    tail = L
    while tail > 1 and shared[tail - 1]:
        tail -= 1
    n_memo = 4 if tail < L else 0
    memo_h = np.zeros(max(n_memo, 1))
    memo_w = np.zeros((max(n_memo, 1), L, e, 3))
    memo_looked = np.zeros((max(n_memo, 1), L), dtype=np.bool_)
    n_kept = 0
    # Room for every pair: at most one per candidate and distinct target of its chain,
    # each with at most n_steps steps (no reallocation inside the loop).
    cap = C * min(L, M)
    c_pair = np.empty(cap, dtype=np.int64)
    j_pair = np.empty(cap, dtype=np.int64)
    first = np.empty(cap, dtype=np.int64)
    count = np.empty(cap, dtype=np.int64)
    offset = np.empty(cap, dtype=np.int64)
    data = np.empty((cap * min(n_steps, L * e), 3))
    n = 0
    m = 0
    # Duplicate candidates (chains of several epochs only): rep[c] is the first candidate
    # with exactly c's pairs.
    dedupe = L > 1
    rep = np.arange(C)
    # Open-addressing hash table of candidates by the hash of their pairs.
    h_size = 1
    while dedupe and h_size < 2 * C:
        h_size *= 2
    h_cand = np.full(h_size, -1, dtype=np.int64)
    h_key = np.zeros(h_size, dtype=np.int64)
    pair_start = np.zeros(C if dedupe else 0, dtype=np.int64)
    pair_end = np.zeros(C if dedupe else 0, dtype=np.int64)
    bits = data.reshape(-1).view(np.int64)
    w = np.zeros((L, e, 3))
    rng_ = np.zeros((e, 3))
    looked = np.zeros(L, dtype=np.bool_)
    for c in range(C):
        h = prev
        h_in = prev
        hit = -1
        l = 0
        while l < L:
            if l == tail and n_memo > 0:
                h_in = h
                for x in range(n_kept):
                    if memo_h[x] == h and math.copysign(1.0, memo_h[x]) == math.copysign(1.0, h):
                        hit = x
                        break
                if hit >= 0:
                    for l2 in range(tail, L):
                        looked[l2] = memo_looked[hit, l2]
                        for s in range(e):
                            for x in range(3):
                                w[l2, s, x] = memo_w[hit, l2, s, x]
                    break
            looked[l] = False
            for s in range(e):
                w[l, s, 0] = 0.0
                w[l, s, 1] = 0.0
                w[l, s, 2] = 0.0
            k = k0 + l
            j = tgt[c, l]
            px, py = pos[c, l, 0], pos[c, l, 1]
            t1 = (k - 1) * e + 1
            if l == L - 1 and far[j]:
                l += 1
                continue
            any_in = False
            for s in range(e):
                if shared[l]:
                    for x in range(3):
                        rng_[s, x] = sh_range[l, s, x]
                else:
                    x0 = xbar[j, t1 + s, 0] - px
                    y0 = xbar[j, t1 + s, 1] - py
                    if l == L - 1 and x0 * x0 + y0 * y0 > reach2[j, s]:
                        rng_[s, 0] = 0.0
                    else:
                        rng_[s, 0], rng_[s, 1], rng_[s, 2] = look_range(
                            row, x0, y0, Cbar[j, t1 + s, 0], Cbar[j, t1 + s, 1],
                            Cbar[j, t1 + s, 2], probabilistic)
                if rng_[s, 0] >= P_VIS_MIN:
                    any_in = True
            if l == L - 1 and not any_in:
                # The last epoch's heading has no other use and none of its looks counts.
                l += 1
                continue
            if shared[l]:
                bearing = sh_bearing[l]
            else:
                bearing = math.atan2(aim[j, k - 1, 1] - py, aim[j, k - 1, 0] - px)
            if l == 0 and not prev_ok:
                h = _heading_rule(theta0, bearing, k * max_turn)
            else:
                h = _heading_rule(h, bearing, max_turn)
            if any_in:
                for s in range(e):
                    if rng_[s, 0] >= P_VIS_MIN:
                        t = t1 + s
                        # At the epoch's first step the target's azimuth is the bearing the
                        # heading rule aimed at (the same numbers): reuse it.
                        azimuth = bearing if s == 0 else math.atan2(xbar[j, t, 1] - py,
                                                                     xbar[j, t, 0] - px)
                        p, w00, w01, w11 = look_at_azimuth(
                            row, xbar[j, t, 0] - px, xbar[j, t, 1] - py, rng_[s, 1],
                            rng_[s, 2], rng_[s, 0], azimuth, h, Cbar[j, t, 0], Cbar[j, t, 1],
                            Cbar[j, t, 2], probabilistic)
                        w[l, s, 0] = w00
                        w[l, s, 1] = w01
                        w[l, s, 2] = w11
                        if p > 0:
                            looked[l] = True
            l += 1
        if n_memo > 0 and hit < 0:
            # Remember the shared tail's looks for the heading that entered it.
            x = n_kept if n_kept < n_memo else c % n_memo
            memo_h[x] = h_in
            for l2 in range(tail, L):
                memo_looked[x, l2] = looked[l2]
                for s in range(e):
                    for y in range(3):
                        memo_w[x, l2, s, y] = w[l2, s, y]
            if n_kept < n_memo:
                n_kept += 1
        # One pair per distinct target among the epochs with a look that counts, in
        # increasing target order; it holds every look of the chain at that target.
        n0, m0 = n, m
        j_prev = -1
        while True:
            j_next = M
            for l in range(L):
                if looked[l] and j_prev < tgt[c, l] < j_next:
                    j_next = tgt[c, l]
            if j_next == M:
                break
            j_prev = j_next
            f, g = n_steps, -1
            for l in range(L):
                if tgt[c, l] == j_next:
                    for s in range(e):
                        if w[l, s, 0] != 0.0 or w[l, s, 1] != 0.0 or w[l, s, 2] != 0.0:
                            f = min(f, l * e + s)
                            g = max(g, l * e + s)
            cnt = g - f + 1 if g >= 0 else 0
            c_pair[n] = c
            j_pair[n] = j_next
            first[n] = f
            count[n] = cnt
            offset[n] = m
            for q in range(cnt):
                l, s = divmod(f + q, e)
                hit = tgt[c, l] == j_next
                data[m + q, 0] = w[l, s, 0] if hit else 0.0
                data[m + q, 1] = w[l, s, 1] if hit else 0.0
                data[m + q, 2] = w[l, s, 2] if hit else 0.0
            n += 1
            m += cnt
        if dedupe and n > n0:
            # A candidate whose pairs equal an earlier candidate's (same targets, steps and
            # information, bit for bit) has the same utility whatever the others do: keep
            # the earlier one's pairs only (typically chains whose turn is clipped, so that
            # their shared tail is entered with the same heading, and whose own look does
            # not count).
            hsh = np.int64(1469598103934665603)
            for q in range(n0, n):
                hsh = (hsh ^ j_pair[q]) * np.int64(1099511628211)
                hsh = (hsh ^ first[q]) * np.int64(1099511628211)
                for x in range(offset[q] * 3, (offset[q] + count[q]) * 3):
                    hsh = (hsh ^ bits[x]) * np.int64(1099511628211)
            slot = hsh & (h_size - 1)
            c0 = -1
            while h_cand[slot] >= 0:
                if h_key[slot] == hsh:
                    c0 = h_cand[slot]
                    break
                slot = (slot + 1) & (h_size - 1)
            if c0 >= 0 and _same_pairs_range(pair_start[c0], pair_end[c0], n0, n, j_pair,
                                             first, count, offset, bits):
                rep[c] = c0
                n, m = n0, m0                            # drop the copy
            elif c0 < 0:
                h_cand[slot] = c
                h_key[slot] = hsh
                pair_start[c] = n0
                pair_end[c] = n
    return (c_pair[:n].copy(), j_pair[:n].copy(), first[:n].copy(), count[:n].copy(),
            offset[:n].copy(), data[:m].copy(), rep)


@njit(cache=True)
def _same_pairs_range(a0: int, a1: int, b0: int, b1: int, j_pair: np.ndarray,
                      first: np.ndarray, count: np.ndarray, offset: np.ndarray,
                      bits: np.ndarray) -> bool:
    """Whether pairs ``a0..a1-1`` and ``b0..b1-1`` are equal (targets, steps, information
    bits)."""
    if a1 - a0 != b1 - b0:
        return False
    for d in range(a1 - a0):
        qa, qb = a0 + d, b0 + d
        if j_pair[qa] != j_pair[qb] or first[qa] != first[qb] or count[qa] != count[qb]:
            return False
        for x in range(count[qa] * 3):
            if bits[offset[qa] * 3 + x] != bits[offset[qb] * 3 + x]:
                return False
    return True


@njit(cache=True, fastmath=False)
def gains_nb(Wp: np.ndarray, tgt: np.ndarray, covs: np.ndarray, F: np.ndarray, Q: np.ndarray,
             cv: bool, dt: float, cum: bool, s0: int, sensor: np.ndarray, lo: np.ndarray,
             hi: np.ndarray, pair_off: np.ndarray, c_loc: np.ndarray, j_pair: np.ndarray,
             first: np.ndarray, count: np.ndarray, offset: np.ndarray, data: np.ndarray,
             delta: np.ndarray, rows: np.ndarray, cand_off: np.ndarray,
             all_targets: bool) -> tuple:
    """Utilities of a batch of players, updating their cached pair terms in place.

    Player ``p`` is sensor ``sensor[p]`` with its epochs ``lo[p] .. hi[p] - 1`` (0-based)
    removed ("no chain"); its pairs are ``pair_off[p] .. pair_off[p + 1] - 1`` (candidate
    ``c_loc`` among its ``cand_off[p + 1] - cand_off[p]`` candidates). ``rows[p]`` holds, per
    target and step, the other players' summed information (w00, w01, w11) the cached
    ``delta`` were computed with (NaN: never); a pair is recomputed only if its target's row
    changed. ``delta`` of a pair is ``term_j(no chain + pair) - term_j(no chain)``.

    Returns
    -------
    gains : (cand_off[-1],)       each candidate's sum of its pairs' delta
    ld_pre, ld_end, ld_sum : (M,) the "no chain" recursion of each target (all targets when
                                  ``all_targets``, else only those recomputed for the last
                                  player): log-dets summed before ``s0``, at the end, and
                                  summed from ``s0`` on
    """
    N, K, e = Wp.shape[0], Wp.shape[1], Wp.shape[2]
    M = covs.shape[0]
    T = K * e
    S = T - s0
    shared_q = Q.shape[0] == 1
    gains = np.zeros(cand_off[-1])
    Wf = np.zeros((M, T, 3))
    stale = np.zeros(M, dtype=np.bool_)
    P_pred = np.empty((M, S, 4, 4))
    part = np.empty((M, S))
    ld_pre = np.zeros(M)
    ld_end = np.zeros(M)
    ld_sum = np.zeros(M)
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    Pc = np.empty((4, 2))
    by_t = np.empty(j_pair.shape[0], dtype=np.int64)
    t_off = np.zeros(M + 1, dtype=np.int64)
    fill = np.zeros(M, dtype=np.int64)
    has_pair = np.zeros(M, dtype=np.bool_)
    for p in range(sensor.shape[0]):
        i = sensor[p]
        # The other players' looks, summed by target and step in the order of
        # information.sum_by_target (sensors, then epochs): bit for bit the same sums.
        Wf[:] = 0.0
        for i2 in range(N):
            for k2 in range(K):
                j = tgt[i2, k2]
                if j < 0 or (i2 == i and lo[p] <= k2 < hi[p]):
                    continue
                for s in range(e):
                    t = k2 * e + s
                    Wf[j, t, 0] += Wp[i2, k2, s, 0, 0]
                    Wf[j, t, 1] += Wp[i2, k2, s, 0, 1]
                    Wf[j, t, 2] += Wp[i2, k2, s, 1, 1]
        has_pair[:] = False
        for q in range(pair_off[p], pair_off[p + 1]):
            has_pair[j_pair[q]] = True
        for j in range(M):
            stale[j] = False
            for t in range(T):
                if (rows[p, j, t, 0] != Wf[j, t, 0] or rows[p, j, t, 1] != Wf[j, t, 1]
                        or rows[p, j, t, 2] != Wf[j, t, 2]):
                    stale[j] = True
                    break
            # The baseline is needed for targets with a pair, or for every target when the
            # caller wants Phi(no chain).
            if not (all_targets or (stale[j] and has_pair[j])):
                continue
            # "No chain" recursion of target j: up to s0, then from s0 on, keeping the
            # predicted covariance and the running log-det sum of every step.
            qb = 0 if shared_q else j
            for r in range(4):
                for c in range(4):
                    P[r, c] = covs[j, r, c]
            acc = 0.0
            for t in range(s0):
                predict_step(P, F, Q, qb, cv, dt, FP)
                update_step(P, Wf[j, t, 0], Wf[j, t, 1], Wf[j, t, 2], Pc, FP)
                if cum:
                    acc += logdet4(P)
            ld_pre[j] = acc
            acc = 0.0
            for t in range(S):
                predict_step(P, F, Q, qb, cv, dt, FP)
                for r in range(4):
                    for c in range(4):
                        P_pred[j, t, r, c] = P[r, c]
                update_step(P, Wf[j, s0 + t, 0], Wf[j, s0 + t, 1], Wf[j, s0 + t, 2], Pc, FP)
                if cum:
                    acc += logdet4(P)
                part[j, t] = acc
            ld_end[j] = logdet4(P)
            ld_sum[j] = acc
        # The pairs of stale targets, grouped by target.
        a, b = pair_off[p], pair_off[p + 1]
        for j in range(M + 1):
            t_off[j] = 0
        for q in range(a, b):
            if stale[j_pair[q]]:
                t_off[j_pair[q] + 1] += 1
        for j in range(M):
            t_off[j + 1] += t_off[j]
            fill[j] = t_off[j]
        for q in range(a, b):
            j = j_pair[q]
            if stale[j]:
                by_t[fill[j]] = q
                fill[j] += 1
        for j in range(M):
            if t_off[j + 1] > t_off[j]:
                _deltas(by_t, t_off[j], t_off[j + 1], P_pred, part, ld_end[j], ld_sum[j], Wf,
                        j, s0, first, count, offset, data, delta, F, Q,
                        0 if shared_q else j, cv, dt, cum, P, FP, Pc)
        for q in range(a, b):
            gains[cand_off[p] + c_loc[q]] += delta[q]
        for j in range(M):
            if stale[j]:
                for t in range(T):
                    for x in range(3):
                        rows[p, j, t, x] = Wf[j, t, x]
    return gains, ld_pre, ld_end, ld_sum


@njit(cache=True, fastmath=False)
def _deltas(idx: np.ndarray, a: int, b: int, P_pred: np.ndarray, part: np.ndarray,
            ld_end_b: float, ld_sum_b: float, Wf: np.ndarray, j: int, s0: int,
            first: np.ndarray, count: np.ndarray, offset: np.ndarray, data: np.ndarray,
            delta: np.ndarray, F: np.ndarray, Q: np.ndarray, qb: int, cv: bool, dt: float,
            cum: bool, P: np.ndarray, FP: np.ndarray, Pc: np.ndarray) -> None:
    """``delta[q] = term(no chain + pair q) - term(no chain)`` for pairs ``idx[a:b]``, all
    of target j (one call per target: the per-pair work is a tight loop).

    Up to its first non-zero step ``f`` a pair adds nothing (exact zeros), so its recursion
    equals the baseline's: it starts from the baseline's predicted covariance at ``f`` and
    running log-det sum.
    """
    S = part.shape[1]
    for x in range(a, b):
        q = idx[x]
        f = first[q]
        if f >= S:
            delta[q] = 0.5 * (ld_sum_b - ld_sum_b) if cum else 0.5 * (ld_end_b - ld_end_b)
            continue
        cnt = count[q]
        off = offset[q]
        for r in range(4):
            for c in range(4):
                P[r, c] = P_pred[j, f, r, c]
        acc = part[j, f - 1] if f > 0 else 0.0
        for t in range(f, S):
            if t > f:
                predict_step(P, F, Q, qb, cv, dt, FP)
            d = t - f
            if d < cnt:
                w00 = Wf[j, s0 + t, 0] + data[off + d, 0]
                w01 = Wf[j, s0 + t, 1] + data[off + d, 1]
                w11 = Wf[j, s0 + t, 2] + data[off + d, 2]
            else:
                w00 = Wf[j, s0 + t, 0] + 0.0
                w01 = Wf[j, s0 + t, 1] + 0.0
                w11 = Wf[j, s0 + t, 2] + 0.0
            update_step(P, w00, w01, w11, Pc, FP)
            if cum:
                acc += logdet4(P)
        if cum:
            delta[q] = 0.5 * (ld_sum_b - acc)
        else:
            delta[q] = 0.5 * (ld_end_b - logdet4(P))


@njit(cache=True)
def index_pairs_nb(pair_off: np.ndarray, c_loc: np.ndarray, j_pair: np.ndarray,
                   cand_off: np.ndarray, M: int) -> tuple:
    """Indexes of a game's pairs: by target per player, and by candidate.

    Returns
    -------
    by_t : (n,) int       pair indices of player p with target j are
                          ``by_t[t_off[p, j]:t_off[p, j + 1]]`` (increasing)
    t_off : (P, M + 1) int
    cp_off : (n_cand + 1,) int   pairs of global candidate x are ``cp_off[x]:cp_off[x + 1]``
                          (pairs of a player are sorted by candidate, then target)
    """
    P = pair_off.shape[0] - 1
    n = j_pair.shape[0]
    by_t = np.empty(n, dtype=np.int64)
    t_off = np.zeros((P, M + 1), dtype=np.int64)
    cp_off = np.zeros(cand_off[-1] + 1, dtype=np.int64)
    fill = np.empty(M, dtype=np.int64)
    for p in range(P):
        a, b = pair_off[p], pair_off[p + 1]
        for q in range(a, b):
            t_off[p, j_pair[q] + 1] += 1
            cp_off[cand_off[p] + c_loc[q] + 1] += 1
        t_off[p, 0] = a
        for j in range(M):
            t_off[p, j + 1] += t_off[p, j]
            fill[j] = t_off[p, j]
        for q in range(a, b):
            by_t[fill[j_pair[q]]] = q
            fill[j_pair[q]] += 1
    for x in range(cand_off[-1]):
        cp_off[x + 1] += cp_off[x]
    return by_t, t_off, cp_off


@njit(cache=True, fastmath=False)
def _base(P0: np.ndarray, Wrow: np.ndarray, s0: int, F: np.ndarray, Q: np.ndarray, qb: int,
          cv: bool, dt: float, cum: bool, P_pred: np.ndarray, part: np.ndarray,
          P: np.ndarray, FP: np.ndarray, Pc: np.ndarray) -> tuple:
    """"No chain" recursion of one target from ``s0`` on, from its covariance ``P0`` at
    ``s0``; keeps the predicted covariance and the running log-det sum of every step.

    Returns ``(log det at the end, log-det sum)``.
    """
    S = part.shape[0]
    for r in range(4):
        for c in range(4):
            P[r, c] = P0[r, c]
    acc = 0.0
    for t in range(S):
        predict_step(P, F, Q, qb, cv, dt, FP)
        for r in range(4):
            for c in range(4):
                P_pred[t, r, c] = P[r, c]
        update_step(P, Wrow[s0 + t, 0], Wrow[s0 + t, 1], Wrow[s0 + t, 2], Pc, FP)
        if cum:
            acc += logdet4(P)
        part[t] = acc
    return logdet4(P), acc


@njit(cache=True, fastmath=False)
def game_gains_nb(Wp: np.ndarray, tgt: np.ndarray, covs: np.ndarray, F: np.ndarray,
                  Q: np.ndarray, cv: bool, dt: float, cum: bool, k: int, hi: np.ndarray,
                  c_loc: np.ndarray, j_pair: np.ndarray, first: np.ndarray,
                  count: np.ndarray, offset: np.ndarray, data: np.ndarray, delta: np.ndarray,
                  rows: np.ndarray, by_t: np.ndarray, t_off: np.ndarray, cp_off: np.ndarray,
                  cand_off: np.ndarray, gcache: np.ndarray, dirty: np.ndarray,
                  dlist: np.ndarray, seen: np.ndarray, shared: np.ndarray, pre: np.ndarray,
                  tot_rows: np.ndarray, tot_ver: np.ndarray, tot_pred: np.ndarray,
                  tot_part: np.ndarray, tot_ld: np.ndarray, alias_dst: np.ndarray,
                  alias_src: np.ndarray) -> np.ndarray:
    """Utilities of the players (p, k), p = 0..N-1, of an epoch game (one call per iteration).

    The same values as :func:`gains_nb` for each player (sensor p's epochs ``k-1 .. hi[p]-1``
    removed), computed with less work, all of it exact:

    * the other players' information at target j equals the total over every player when
      player p's own chain adds nothing at j (exact zeros leave a sum unchanged), so those
      targets share one "no chain" recursion per change of the total (``tot_*``, whose
      changes ``tot_ver`` counts); only the few targets p's own chain looks at get a
      private one;
    * the covariance at step ``s0 = (k-1) e`` depends on epochs before k only, which the game
      never changes: it is computed once (``pre``, ``shared[0]``);
    * a candidate's utility is the sum of its pairs' terms in pair order; it is summed again
      only when one of them changed (``gcache``; ``dirty``/``dlist`` list those); a current
      action that duplicates an earlier candidate takes its sum (``alias_*``).

    ``rows[p]`` holds the information each of p's cached terms was computed with (NaN:
    never), ``seen[p, j]`` the version of the total it equals (-1: unknown), ``tot_rows``
    the total the shared recursions were computed with.

    Returns
    -------
    (cand_off[-1],) utilities of every player's candidates, concatenated (a new array).
    """
    N, K, e = Wp.shape[0], Wp.shape[1], Wp.shape[2]
    M = covs.shape[0]
    T = K * e
    s0 = (k - 1) * e
    S = T - s0
    shared_q = Q.shape[0] == 1
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    Pc = np.empty((4, 2))
    # The total information at every target and step, in the order of sum_by_target.
    Wtot = np.zeros((M, T, 3))
    for i2 in range(N):
        for k2 in range(K):
            j = tgt[i2, k2]
            if j < 0:
                continue
            for s in range(e):
                t = k2 * e + s
                Wtot[j, t, 0] += Wp[i2, k2, s, 0, 0]
                Wtot[j, t, 1] += Wp[i2, k2, s, 0, 1]
                Wtot[j, t, 2] += Wp[i2, k2, s, 1, 1]
    first_call = not shared[0]
    if first_call:
        for j in range(M):
            qb = 0 if shared_q else j
            for r in range(4):
                for c in range(4):
                    P[r, c] = covs[j, r, c]
            for t in range(s0):
                predict_step(P, F, Q, qb, cv, dt, FP)
                update_step(P, Wtot[j, t, 0], Wtot[j, t, 1], Wtot[j, t, 2], Pc, FP)
            for r in range(4):
                for c in range(4):
                    pre[j, r, c] = P[r, c]
        shared[0] = True
    tot_ok = np.ones(M, dtype=np.bool_)              # shared recursion valid for the total
    for j in range(M):
        if not _same_row(tot_rows, j, Wtot, j, T):
            tot_ver[j] += 1
            tot_ok[j] = False
            for t in range(T):
                for x in range(3):
                    tot_rows[j, t, x] = Wtot[j, t, x]
    own = np.zeros(M, dtype=np.bool_)
    Wown = np.zeros((M, T, 3))
    own_pred = np.empty((M, S, 4, 4))
    own_part = np.empty((M, S))
    own_ld = np.empty((M, 2))
    n_dirty = 0
    for p in range(N):
        lo, h = k - 1, hi[p]
        for k2 in range(lo, h):
            j = tgt[p, k2]
            if j < 0:
                continue
            for s in range(e):
                if Wp[p, k2, s, 0, 0] != 0.0 or Wp[p, k2, s, 0, 1] != 0.0 \
                        or Wp[p, k2, s, 1, 1] != 0.0:
                    own[j] = True
        for j in range(M):
            if t_off[p, j + 1] == t_off[p, j]:
                continue                                 # p has no pair at target j
            qb = 0 if shared_q else j
            if own[j]:
                # The other players' information only: the sum without p's chain.
                for t in range(T):
                    Wown[j, t, 0] = 0.0
                    Wown[j, t, 1] = 0.0
                    Wown[j, t, 2] = 0.0
                for i2 in range(N):
                    for k2 in range(K):
                        if tgt[i2, k2] != j or (i2 == p and lo <= k2 < h):
                            continue
                        for s in range(e):
                            t = k2 * e + s
                            Wown[j, t, 0] += Wp[i2, k2, s, 0, 0]
                            Wown[j, t, 1] += Wp[i2, k2, s, 0, 1]
                            Wown[j, t, 2] += Wp[i2, k2, s, 1, 1]
                if _same_row(rows[p], j, Wown, j, T):
                    continue
                seen[p, j] = -1
                Wf = Wown
                own_ld[j, 0], own_ld[j, 1] = _base(pre[j], Wown[j], s0, F, Q, qb, cv, dt, cum,
                                                   own_pred[j], own_part[j], P, FP, Pc)
                base_pred, base_part = own_pred, own_part
                ld_end_b, ld_sum_b = own_ld[j, 0], own_ld[j, 1]
            else:
                if seen[p, j] == tot_ver[j]:
                    continue
                if _same_row(rows[p], j, Wtot, j, T):
                    seen[p, j] = tot_ver[j]
                    continue
                seen[p, j] = tot_ver[j]
                Wf = Wtot
                if not tot_ok[j]:
                    tot_ld[j, 0], tot_ld[j, 1] = _base(pre[j], Wtot[j], s0, F, Q, qb, cv, dt,
                                                       cum, tot_pred[j], tot_part[j], P, FP, Pc)
                    tot_ok[j] = True
                base_pred, base_part = tot_pred, tot_part
                ld_end_b, ld_sum_b = tot_ld[j, 0], tot_ld[j, 1]
            _deltas(by_t, t_off[p, j], t_off[p, j + 1], base_pred, base_part, ld_end_b,
                    ld_sum_b, Wf, j, s0, first, count, offset, data, delta, F, Q, qb, cv, dt,
                    cum, P, FP, Pc)
            for x in range(t_off[p, j], t_off[p, j + 1]):
                c = cand_off[p] + c_loc[by_t[x]]
                if not dirty[c]:
                    dirty[c] = True
                    dlist[n_dirty] = c
                    n_dirty += 1
            for t in range(T):
                for x in range(3):
                    rows[p, j, t, x] = Wf[j, t, x]
        for k2 in range(lo, h):
            j = tgt[p, k2]
            if j >= 0:
                own[j] = False
    if first_call:                                   # every utility is summed once
        n_dirty = gcache.shape[0]
        for c in range(n_dirty):
            dlist[c] = c
    for y in range(n_dirty):
        c = dlist[y]
        g = 0.0
        for q in range(cp_off[c], cp_off[c + 1]):
            g += delta[q]
        gcache[c] = g
        dirty[c] = False
    for x in range(alias_dst.shape[0]):              # a duplicate current action
        gcache[alias_dst[x]] = gcache[alias_src[x]]
    return gcache.copy()


@njit(cache=True)
def _same_row(A: np.ndarray, a: int, B: np.ndarray, b: int, T: int) -> bool:
    """Whether rows ``A[a]`` and ``B[b]`` (T, 3) are equal (bit for bit; NaN never is)."""
    for t in range(T):
        if A[a, t, 0] != B[b, t, 0] or A[a, t, 1] != B[b, t, 1] or A[a, t, 2] != B[b, t, 2]:
            return False
    return True


@njit(cache=True)
def jsfp_step_nb(u: np.ndarray, ubar: np.ndarray, t: int, cand_off: np.ndarray,
                 cur: np.ndarray, tol: float) -> tuple:
    """One JSFP iteration's bookkeeping for every player, in one pass.

    Whether the current actions are an equilibrium (``vmax <= u[cur] + tol`` for every
    player); if not, the running averages ``(t-1)/t ubar + u/t`` (a new array, as the numpy
    expression) and every player's best response under the tie rule.

    Returns
    -------
    equilibrium : bool
    ubar : (n,)   new running averages (``ubar`` itself at an equilibrium)
    best : (P,)   best responses (-1 at an equilibrium)
    """
    P = cur.shape[0]
    eq = True
    for p in range(P):
        if cur[p] < 0:
            eq = False
            break
        a, b = cand_off[p], cand_off[p + 1]
        vmax = u[a]
        for x in range(a + 1, b):
            if u[x] > vmax:
                vmax = u[x]
        if not vmax <= u[a + cur[p]] + tol:
            eq = False
            break
    best = np.full(P, -1, dtype=np.int64)
    if eq:
        return True, ubar, best
    w = (t - 1) / t
    new = np.empty_like(ubar)
    for x in range(u.shape[0]):
        new[x] = w * ubar[x] + u[x] / t
    for p in range(P):
        a, b = cand_off[p], cand_off[p + 1]
        vmax = new[a]
        for x in range(a + 1, b):
            if new[x] > vmax:
                vmax = new[x]
        floor = vmax - tol
        if cur[p] >= 0 and new[a + cur[p]] >= floor:
            best[p] = cur[p]
            continue
        for x in range(a, b):
            if new[x] >= floor:
                best[p] = x - a
                break
    return False, new, best


@njit(cache=True)
def player_positions_nb(positions: np.ndarray, cand: np.ndarray, parents: np.ndarray,
                        use_parents: bool, ref: np.ndarray) -> np.ndarray:
    """Candidate positions (indices into ``positions``), only those among ``parents`` if
    ``use_parents``, sorted stably by their distance from ``ref`` rounded to 1e-6 m (the
    engine's tie order)."""
    keep = np.empty(cand.shape[0], dtype=np.int64)
    n = 0
    for x in range(cand.shape[0]):
        c = cand[x]
        ok = not use_parents
        for y in range(parents.shape[0]):
            if parents[y] == c:
                ok = True
                break
        if ok:
            keep[n] = c
            n += 1
    dist = np.empty(n)
    for x in range(n):
        dx = positions[keep[x], 0] - ref[0]
        dy = positions[keep[x], 1] - ref[1]
        dist[x] = np.rint(np.sqrt(dx * dx + dy * dy) * 1e6)
    order = np.argsort(dist, kind="mergesort")
    return keep[:n][order]
