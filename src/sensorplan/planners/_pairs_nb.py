"""Compiled kernels of the planning engine: candidate chains' looks as sparse pairs.

:func:`chain_pairs_nb` computes the looks of a batch of candidate chains of one sensor and
keeps, sparsely, only the (candidate, target) pairs with a look that counts, with that pair's
information from its first non-zero step on; the utilities come from
:mod:`sensorplan.planners._gains_nb`.

The looks are those the readable path computes (``chain_looks`` with the same headings,
the same radar calls, in the same order), bit for bit. What is skipped is only work whose
result is known exactly: looks beyond the radar's reach (:func:`sensorplan.models.radar.reach`),
the heading-free part of looks shared by every candidate, the looks of a shared tail entered
with a heading already seen, and copies of candidates whose pairs equal an earlier one's.
"""

from __future__ import annotations

import math

import numpy as np
from .._compiled.jit import njit

from ..models.radar import (P_VIS_MIN, look_at_azimuth, look_range, look_range_clear, reach,
                            row_values)
from ._chains_nb import aim_bearing, next_heading, shared_epochs


@njit(cache=True, nogil=True)
def chain_pairs_nb(pos: np.ndarray, tgt: np.ndarray, k0: int, e: int, prev: float,
                   prev_ok: bool, theta0: float, max_turn: float, aim: np.ndarray,
                   xbar: np.ndarray, Cbar: np.ndarray, probabilistic: bool, row: np.ndarray,
                   n_steps: int, buildings: np.ndarray) -> tuple:
    """The (candidate, target) pairs of candidate chains with a look that counts.

    A chain of sensor ``row`` covers epochs ``k0 .. k0 + L - 1`` (positions ``pos (C, L, 2)``,
    targets ``tgt (C, L)``); headings and looks are those of
    :func:`sensorplan.planners._chains_nb.chain_looks_nb` with ``all_headings=False``, computed with
    less work: the heading-free part of a look (:func:`sensorplan.models.radar.look_range`) once per
    epoch that every candidate shares; the looks of the shared tail of the chain once per
    distinct heading entering it (candidates whose turn is clipped enter it with the same
    heading, bit for bit); and nothing for last-epoch targets out of the radar's reach.
    ``buildings (B, 5)`` can hide targets (:func:`sensorplan.models.radar.look_range`).

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
    # The radar row by value and the open-sky range test where nothing stands: no reference
    # counting in the loops below (about a tenth of a look's time).
    rv = row_values(row)
    clear = buildings.shape[0] == 0
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
            R = reach(rv, Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2], probabilistic)
            reach2[j, s] = R * R * (1.0 + 1e-12)
            dx = max(x_lo - xbar[j, t, 0], 0.0, xbar[j, t, 0] - x_hi)
            dy = max(y_lo - xbar[j, t, 1], 0.0, xbar[j, t, 1] - y_hi)
            if dx * dx + dy * dy <= reach2[j, s]:
                far[j] = False
    # Epochs whose position and target are the same for every candidate: their bearing and
    # the heading-free part of their looks are computed once.
    shared, sh_bearing = shared_epochs(pos, tgt, aim, k0)
    sh_range = np.zeros((L, e, 3))                   # p, g^2, g
    for l in range(L):
        if shared[l]:
            j = tgt[0, l]
            k = k0 + l
            for s in range(e):
                t = (k - 1) * e + 1 + s
                sh_range[l, s, 0], sh_range[l, s, 1], sh_range[l, s, 2] = look_range(
                    rv, buildings, pos[0, l, 0], pos[0, l, 1], xbar[j, t, 0] - pos[0, l, 0],
                    xbar[j, t, 1] - pos[0, l, 1], Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2],
                    probabilistic)
    # The shared tail: epochs tail .. L-1 are shared; their looks depend only on the
    # heading of epoch ``tail`` (then every later one follows from it). Keep the results of
    # a few distinct ones: where the turn into the tail is not clipped that heading is the
    # tail's bearing up to round-off in the heading rule, a handful of values at most.
    tail = L
    while tail > 1 and shared[tail - 1]:
        tail -= 1
    n_memo = 8 if tail < L else 0
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
    # One-epoch chains (an initialisation's whole reachable region times every target): most
    # candidates are beyond reach of their target; the loop below would give them no pair,
    # so they are passed over at the cost of the reach test alone.
    quick = L == 1 and not shared[0]
    t_last = (k0 - 1) * e + 1
    for c in range(C):
        if quick:
            j = tgt[c, 0]
            if far[j]:
                continue
            out = True
            for s in range(e):
                x0 = xbar[j, t_last + s, 0] - pos[c, 0, 0]
                y0 = xbar[j, t_last + s, 1] - pos[c, 0, 1]
                if x0 * x0 + y0 * y0 <= reach2[j, s]:
                    out = False
                    break
            if out:
                continue
        h = prev
        h_in = prev
        hit = -1
        l = 0
        while l < L:
            if l == tail and n_memo > 0:
                # The tail's heading, as the loop below computes it (tail >= 1).
                h_in = next_heading(h, sh_bearing[tail], k0 + tail, False, theta0, max_turn)
                for x in range(n_kept):
                    if memo_h[x] == h_in and (math.copysign(1.0, memo_h[x])
                                              == math.copysign(1.0, h_in)):
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
                    elif clear:
                        rng_[s, 0], rng_[s, 1], rng_[s, 2] = look_range_clear(
                            rv, x0, y0, Cbar[j, t1 + s, 0], Cbar[j, t1 + s, 1],
                            Cbar[j, t1 + s, 2], probabilistic)
                    else:
                        rng_[s, 0], rng_[s, 1], rng_[s, 2] = look_range(
                            rv, buildings, px, py, x0, y0, Cbar[j, t1 + s, 0],
                            Cbar[j, t1 + s, 1], Cbar[j, t1 + s, 2], probabilistic)
                if rng_[s, 0] >= P_VIS_MIN:
                    any_in = True
            if l == L - 1 and not any_in:
                # The last epoch's heading has no other use and none of its looks counts.
                l += 1
                continue
            bearing = sh_bearing[l] if shared[l] else aim_bearing(aim, j, k, px, py)
            h = next_heading(h, bearing, k, l == 0 and not prev_ok, theta0, max_turn)
            if any_in:
                for s in range(e):
                    if rng_[s, 0] >= P_VIS_MIN:
                        t = t1 + s
                        # At the epoch's first step the target's azimuth is the bearing the
                        # heading rule aimed at (the same numbers): reuse it.
                        azimuth = bearing if s == 0 else math.atan2(xbar[j, t, 1] - py,
                                                                     xbar[j, t, 0] - px)
                        p, w00, w01, w11 = look_at_azimuth(
                            rv, xbar[j, t, 0] - px, xbar[j, t, 1] - py, rng_[s, 1],
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



@njit(cache=True, nogil=True)
def game_chains_nb(xy: np.ndarray, M: int, tail_xy: np.ndarray,
                   tail_tgt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An epoch game player's candidate chains for :func:`chain_pairs_nb`: each position of
    ``xy (P, 2)`` times every target (position-major), followed by the sensor's fixed later
    epochs ``tail_xy (n, 2)``, ``tail_tgt (n,)``.

    Returns
    -------
    pos : (P M, 1 + n, 2);  tgt : (P M, 1 + n) int64
    """
    P, n = xy.shape[0], tail_tgt.shape[0]
    pos = np.empty((P * M, 1 + n, 2))
    tgt = np.empty((P * M, 1 + n), dtype=np.int64)
    c = 0
    for a in range(P):
        for j in range(M):
            pos[c, 0, 0] = xy[a, 0]
            pos[c, 0, 1] = xy[a, 1]
            tgt[c, 0] = j
            for l in range(n):
                pos[c, 1 + l, 0] = tail_xy[l, 0]
                pos[c, 1 + l, 1] = tail_xy[l, 1]
                tgt[c, 1 + l] = tail_tgt[l]
            c += 1
    return pos, tgt


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


@njit(cache=True, nogil=True)
def candidate_sets_nb(c_pair: np.ndarray, rep: np.ndarray) -> tuple:
    """From :func:`chain_pairs_nb`'s pairs (sorted by candidate) and ``rep``:

    Returns
    -------
    owners : candidates holding pairs (sorted)
    dups : candidates whose pairs equal an earlier candidate's (sorted)
    contrib : candidates with a look that counts, the union of both (sorted)
    free : the first candidate without one (-1 if none)
    """
    C = rep.shape[0]
    has = np.zeros(C, dtype=np.bool_)
    for q in range(c_pair.shape[0]):
        has[c_pair[q]] = True
    n_own = 0
    n_dup = 0
    for c in range(C):
        if has[c]:
            n_own += 1
        elif rep[c] != c:
            n_dup += 1
    owners = np.empty(n_own, dtype=np.int64)
    dups = np.empty(n_dup, dtype=np.int64)
    contrib = np.empty(n_own + n_dup, dtype=np.int64)
    a = b = x = 0
    free = -1
    for c in range(C):
        if has[c]:
            owners[a] = c
            a += 1
        elif rep[c] != c:
            dups[b] = c
            b += 1
        elif free < 0:
            free = c
            continue
        else:
            continue
        contrib[x] = c
        x += 1
    return owners, dups, contrib, free


@njit(cache=True)
def player_view_nb(cand: np.ndarray, M: int, cur_pos: int, cur_tgt: int, owners: np.ndarray,
                   free: int, dups: np.ndarray, dup_of: np.ndarray,
                   c_pair: np.ndarray) -> tuple:
    """What an epoch game keeps of a player's candidates (``cand`` positions times ``M``
    targets, position-major) given its current action (lattice index ``cur_pos`` and
    ``cur_tgt``; ``cur_tgt`` -1: unassigned), from :func:`candidate_sets_nb`'s sets.

    Kept: the candidates holding pairs (``owners``), the first without a look that counts
    (``free``) and the current action, in candidate order.

    Returns
    -------
    pos, tgt : (A,) int       the kept actions' positions and targets
    cur_loc : int             the current action's index among them (-1: none)
    c_loc : (n,) int          each pair's candidate's index among them
    alias : int               if the current action duplicates an earlier candidate (it
                              then has no pairs of its own), that one's index, else -1
    """
    cur = -1
    if cur_tgt >= 0:
        for q in range(cand.shape[0]):
            if cand[q] == cur_pos:
                cur = q * M + cur_tgt
                break
    e0, e1 = min(free, cur), max(free, cur)      # the extras, -1 for none
    keep = np.empty(owners.shape[0] + 2, dtype=np.int64)
    n = 0
    a = 0
    for extra in (e0, e1):
        if extra < 0:
            continue
        while a < owners.shape[0] and owners[a] < extra:
            keep[n] = owners[a]
            n += 1
            a += 1
        if (a == owners.shape[0] or owners[a] != extra) and (n == 0 or keep[n - 1] != extra):
            keep[n] = extra
            n += 1
    while a < owners.shape[0]:
        keep[n] = owners[a]
        n += 1
        a += 1
    pos = np.empty(n, dtype=np.int64)
    tgt = np.empty(n, dtype=np.int64)
    cur_loc = -1
    for x in range(n):
        pos[x] = cand[keep[x] // M]
        tgt[x] = keep[x] % M
        if keep[x] == cur:
            cur_loc = x
    c_loc = np.empty(c_pair.shape[0], dtype=np.int64)
    x = 0
    for q in range(c_pair.shape[0]):             # pairs are sorted by candidate
        while keep[x] < c_pair[q]:
            x += 1
        c_loc[q] = x
    alias = -1
    if cur >= 0:
        for d in range(dups.shape[0]):
            if dups[d] == cur:
                x = 0
                while x < n and keep[x] < dup_of[d]:
                    x += 1
                alias = x
                break
    return pos, tgt, cur_loc, c_loc, alias
