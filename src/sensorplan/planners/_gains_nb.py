"""Compiled kernels of the planning engine: utilities from sparse pairs.

:func:`gains_nb` (one sensor's candidates, the :meth:`GameState.chain_gains` path) and
:func:`game_totals_nb` with :func:`game_block_nb` (every player of an epoch game, once per
JSFP iteration; the players' part in blocks that may run on threads) turn the pairs of
:func:`sensorplan.planners._pairs_nb.chain_pairs_nb` into utilities: they sum the other
players' looks, recompute each target's baseline recursion where those looks changed, and
then the pairs of those targets only. :func:`game_block_nb` also does an iteration's
bookkeeping, block by block.

Both repeat, operation for operation, what the readable path does (a dense covariance
recursion per pair, ``tests/engine_reference.py``): the same predict and update steps in the
same order, so every utility is bit for bit the one the dense computation gives. What they
skip is only work whose result is known exactly (see each function).
"""

from __future__ import annotations

import numpy as np
from .._compiled.jit import njit

from ._chains_nb import (full16, load_sym10, logdet4, logdet10, predict_cv_sym,
                         predict_step, store_sym10, update_step, update_sym)


@njit(cache=True, nogil=True)
def add_looks(Wp: np.ndarray, tgt: np.ndarray, out: np.ndarray, only: int, skip: int,
              lo: int, hi: int) -> None:
    """Add the players' look information ``Wp (N, K, e, 2, 2)`` into ``out[j, t]`` (w00, w01,
    w11) by target and step, in the order of ``information.sum_by_target`` (sensors, then
    epochs): bit for bit its sums. Only target ``only`` if it is >= 0; sensor ``skip``'s
    epochs ``lo .. hi - 1`` left out."""
    N, K, e = Wp.shape[0], Wp.shape[1], Wp.shape[2]
    for i2 in range(N):
        for k2 in range(K):
            j = tgt[i2, k2]
            if j < 0 or (only >= 0 and j != only) or (i2 == skip and lo <= k2 < hi):
                continue
            for s in range(e):
                t = k2 * e + s
                out[j, t, 0] += Wp[i2, k2, s, 0, 0]
                out[j, t, 1] += Wp[i2, k2, s, 0, 1]
                out[j, t, 2] += Wp[i2, k2, s, 1, 1]


@njit(cache=True, fastmath=False)
def gains_nb(Wp: np.ndarray, tgt: np.ndarray, covs: np.ndarray, F: np.ndarray, Q: np.ndarray,
             cv: bool, dt: float, cum: bool, existence: np.ndarray, s0: int,
             sensor: np.ndarray, lo: np.ndarray,
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
    changed. ``delta`` of a pair is ``term_j(no chain + pair) - term_j(no chain)``, the
    term weighted by the target's probability of existence ``existence[j]``.

    Returns
    -------
    gains : (cand_off[-1],)       each candidate's sum of its pairs' delta
    ld_pre, ld_end, ld_sum : (M,) the "no chain" recursion of each target (all targets when
                                  ``all_targets``, else only those recomputed for the last
                                  player): log-dets summed before ``s0``, at the end, and
                                  summed from ``s0`` on
    """
    K, e = Wp.shape[1], Wp.shape[2]
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
    by_t = np.empty(j_pair.shape[0], dtype=np.int64)
    t_off = np.zeros(M + 1, dtype=np.int64)
    fill = np.zeros(M, dtype=np.int64)
    has_pair = np.zeros(M, dtype=np.bool_)
    for p in range(sensor.shape[0]):
        i = sensor[p]
        Wf[:] = 0.0
        add_looks(Wp, tgt, Wf, -1, i, lo[p], hi[p])       # the other players' looks
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
                update_step(P, Wf[j, t, 0], Wf[j, t, 1], Wf[j, t, 2])
                if cum:
                    acc += logdet4(P)
            ld_pre[j] = acc
            acc = 0.0
            for t in range(S):
                predict_step(P, F, Q, qb, cv, dt, FP)
                for r in range(4):
                    for c in range(4):
                        P_pred[j, t, r, c] = P[r, c]
                update_step(P, Wf[j, s0 + t, 0], Wf[j, s0 + t, 1], Wf[j, s0 + t, 2])
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
                        0 if shared_q else j, cv, dt, cum, existence[j], P, FP)
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
            cum: bool, r: float, P: np.ndarray, FP: np.ndarray) -> None:
    """``delta[q] = r (term(no chain + pair q) - term(no chain))`` for pairs ``idx[a:b]``,
    all of target j (one call per target: the per-pair work is a tight loop), ``r`` its
    probability of existence.

    Up to its first non-zero step ``f`` a pair adds nothing (exact zeros), so its recursion
    equals the baseline's: it starts from the baseline's predicted covariance at ``f`` and
    running log-det sum.

    The weighting by ``r`` is the compiled engine's only one (the numpy evaluation's is
    :func:`sensorplan.planners.information.phi_terms`): every utility is a sum of these
    deltas. With ``r = 1`` the product changes no bit.
    """
    S = part.shape[1]
    q10 = load_sym10(Q[qb])
    for x in range(a, b):
        q = idx[x]
        f = first[q]
        if f >= S:
            d = 0.5 * (ld_sum_b - ld_sum_b) if cum else 0.5 * (ld_end_b - ld_end_b)
            delta[q] = r * d
            continue
        cnt = count[q]
        off = offset[q]
        # The matrix lives in a sym10 tuple (see sensorplan.planners._chains_nb): no array per step.
        s = load_sym10(P_pred[j, f])
        acc = part[j, f - 1] if f > 0 else 0.0
        for t in range(f, S):
            if t > f:
                if cv:
                    s = predict_cv_sym(full16(s), dt, q10)
                else:
                    store_sym10(P, s)
                    predict_step(P, F, Q, qb, cv, dt, FP)
                    s = load_sym10(P)
            d = t - f
            if d < cnt:
                w00 = Wf[j, s0 + t, 0] + data[off + d, 0]
                w01 = Wf[j, s0 + t, 1] + data[off + d, 1]
                w11 = Wf[j, s0 + t, 2] + data[off + d, 2]
            else:
                w00 = Wf[j, s0 + t, 0] + 0.0
                w01 = Wf[j, s0 + t, 1] + 0.0
                w11 = Wf[j, s0 + t, 2] + 0.0
            s = update_sym(s, w00, w01, w11)
            if cum:
                acc += logdet10(s)
        d = 0.5 * (ld_sum_b - acc) if cum else 0.5 * (ld_end_b - logdet10(s))
        delta[q] = r * d



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
          P: np.ndarray, FP: np.ndarray) -> tuple:
    """"No chain" recursion of one target from ``s0`` on, from its covariance ``P0`` at
    ``s0``; keeps the predicted covariance and the running log-det sum of every step.

    Returns ``(log det at the end, log-det sum)``.
    """
    S = part.shape[0]
    q10 = load_sym10(Q[qb])
    s = load_sym10(P0)            # (replaced at t = 0; typed here)
    acc = 0.0
    for t in range(S):
        if cv and t > 0:
            s = predict_cv_sym(full16(s), dt, q10)     # no array per step (as _deltas)
        else:
            # The first step reads P0's both triangles (it may come from outside).
            if t == 0:
                for r in range(4):
                    for c in range(4):
                        P[r, c] = P0[r, c]
            else:
                store_sym10(P, s)
            predict_step(P, F, Q, qb, cv, dt, FP)
            s = load_sym10(P)
        store_sym10(P_pred[t], s)
        s = update_sym(s, Wrow[s0 + t, 0], Wrow[s0 + t, 1], Wrow[s0 + t, 2])
        if cum:
            acc += logdet10(s)
        part[t] = acc
    return logdet10(s), acc



@njit(cache=True, fastmath=False)
def game_totals_nb(Wp: np.ndarray, tgt: np.ndarray, covs: np.ndarray, F: np.ndarray,
                   Q: np.ndarray, cv: bool, dt: float, cum: bool, k: int, has_pair: np.ndarray,
                   shared: np.ndarray, pre: np.ndarray, tot_rows: np.ndarray,
                   tot_ver: np.ndarray, tot_pred: np.ndarray, tot_part: np.ndarray,
                   tot_ld: np.ndarray) -> tuple:
    """The first part of an epoch game's utilities (see :func:`game_players_nb`): the total
    information at every target and step, and the "no chain" recursions it gives.

    The total is summed in the order of ``information.sum_by_target`` (sensors, then
    epochs): bit for bit its sums. The covariance at step ``s0 = (k-1) e`` depends on epochs
    before k only, which the game never changes: it is computed on the first call (``pre``,
    ``shared[0]``). Where the total at a target changed (``tot_rows`` holds the one last
    seen, ``tot_ver`` counts the changes), its shared recursion from ``s0`` is recomputed if
    any player has a pair there (``has_pair``, (M,) bool).

    Returns
    -------
    Wtot : (M, T, 3)    the total information
    first_call : bool
    changed : int       targets whose total changed
    """
    K, e = Wp.shape[1], Wp.shape[2]
    M = covs.shape[0]
    T = K * e
    s0 = (k - 1) * e
    shared_q = Q.shape[0] == 1
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    Wtot = np.zeros((M, T, 3))
    add_looks(Wp, tgt, Wtot, -1, -1, 0, 0)
    first_call = not shared[0]
    if first_call:
        for j in range(M):
            qb = 0 if shared_q else j
            for r in range(4):
                for c in range(4):
                    P[r, c] = covs[j, r, c]
            for t in range(s0):
                predict_step(P, F, Q, qb, cv, dt, FP)
                update_step(P, Wtot[j, t, 0], Wtot[j, t, 1], Wtot[j, t, 2])
            for r in range(4):
                for c in range(4):
                    pre[j, r, c] = P[r, c]
        shared[0] = True
    changed = 0
    for j in range(M):
        if _same_row(tot_rows, j, Wtot, j, T):
            continue
        changed += 1
        tot_ver[j] += 1
        for t in range(T):
            for x in range(3):
                tot_rows[j, t, x] = Wtot[j, t, x]
        if has_pair[j]:
            tot_ld[j, 0], tot_ld[j, 1] = _base(pre[j], Wtot[j], s0, F, Q, 0 if shared_q else j,
                                               cv, dt, cum, tot_pred[j], tot_part[j], P, FP)
    return Wtot, first_call, changed



@njit(cache=True, fastmath=False, nogil=True)
def game_players_nb(p_lo: int, p_hi: int, Wp: np.ndarray, tgt: np.ndarray, F: np.ndarray,
                    Q: np.ndarray, cv: bool, dt: float, cum: bool, existence: np.ndarray,
                    k: int, hi: np.ndarray,
                    c_loc: np.ndarray, j_pair: np.ndarray, first: np.ndarray,
                    count: np.ndarray, offset: np.ndarray, data: np.ndarray,
                    delta: np.ndarray, rows: np.ndarray, by_t: np.ndarray, t_off: np.ndarray,
                    cand_off: np.ndarray, dirty: np.ndarray, dlist: np.ndarray,
                    seen: np.ndarray, Wtot: np.ndarray, pre: np.ndarray, tot_ver: np.ndarray,
                    tot_pred: np.ndarray, tot_part: np.ndarray, tot_ld: np.ndarray) -> int:
    """The pair terms of players ``p_lo .. p_hi - 1`` of an epoch game (players (p, k)).

    An epoch game's utilities are :func:`game_totals_nb`, this for every player (in blocks,
    on threads: a block writes only its own players' entries) and the sums of
    :func:`game_block_nb`. They are the values of :func:`gains_nb` for each player (sensor
    p's epochs ``k-1 .. hi[p]-1`` removed), computed with less work, all of it exact:

    * the other players' information at target j equals the total when player p's own chain
      adds nothing at j (exact zeros leave a sum unchanged), so those targets use the shared
      "no chain" recursion of the total; only the few targets p's own chain looks at get a
      private one;
    * a pair's term is recomputed only when the information it was computed with changed:
      ``rows[p]`` holds it per target (NaN: never), ``seen[p, j]`` the version of the total
      it equals (-1: unknown).

    Returns
    -------
    The number of candidates whose utility must be summed again, listed in
    ``dlist[cand_off[p_lo]:]`` (and flagged in ``dirty``).
    """
    K, e = Wp.shape[1], Wp.shape[2]
    M = Wtot.shape[0]
    T = K * e
    s0 = (k - 1) * e
    S = T - s0
    shared_q = Q.shape[0] == 1
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    own = np.zeros(M, dtype=np.bool_)
    Wown = np.zeros((M, T, 3))
    own_pred = np.empty((M, S, 4, 4))
    own_part = np.empty((M, S))
    own_ld = np.empty((M, 2))
    d0 = cand_off[p_lo]
    n_dirty = 0
    for p in range(p_lo, p_hi):
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
                add_looks(Wp, tgt, Wown, j, p, lo, h)
                if _same_row(rows[p], j, Wown, j, T):
                    continue
                seen[p, j] = -1
                Wf = Wown
                own_ld[j, 0], own_ld[j, 1] = _base(pre[j], Wown[j], s0, F, Q, qb, cv, dt, cum,
                                                   own_pred[j], own_part[j], P, FP)
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
                base_pred, base_part = tot_pred, tot_part
                ld_end_b, ld_sum_b = tot_ld[j, 0], tot_ld[j, 1]
            _deltas(by_t, t_off[p, j], t_off[p, j + 1], base_pred, base_part, ld_end_b,
                    ld_sum_b, Wf, j, s0, first, count, offset, data, delta, F, Q, qb, cv, dt,
                    cum, existence[j], P, FP)
            for x in range(t_off[p, j], t_off[p, j + 1]):
                c = cand_off[p] + c_loc[by_t[x]]
                if not dirty[c]:
                    dirty[c] = True
                    dlist[d0 + n_dirty] = c
                    n_dirty += 1
            for t in range(T):
                for x in range(3):
                    rows[p, j, t, x] = Wf[j, t, x]
        for k2 in range(lo, h):
            j = tgt[p, k2]
            if j >= 0:
                own[j] = False
    return n_dirty



@njit(cache=True)
def _same_row(A: np.ndarray, a: int, B: np.ndarray, b: int, T: int) -> bool:
    """Whether rows ``A[a]`` and ``B[b]`` (T, 3) are equal (bit for bit; NaN never is)."""
    for t in range(T):
        if A[a, t, 0] != B[b, t, 0] or A[a, t, 1] != B[b, t, 1] or A[a, t, 2] != B[b, t, 2]:
            return False
    return True


@njit(cache=True, fastmath=False, nogil=True)
def game_block_nb(p_lo: int, p_hi: int, Wp: np.ndarray, tgt: np.ndarray, F: np.ndarray,
                  Q: np.ndarray, cv: bool, dt: float, cum: bool, existence: np.ndarray,
                  k: int, hi: np.ndarray,
                  c_loc: np.ndarray, j_pair: np.ndarray, first: np.ndarray,
                  count: np.ndarray, offset: np.ndarray, data: np.ndarray,
                  delta: np.ndarray, rows: np.ndarray, by_t: np.ndarray, t_off: np.ndarray,
                  cand_off: np.ndarray, dirty: np.ndarray, dlist: np.ndarray,
                  seen: np.ndarray, Wtot: np.ndarray, pre: np.ndarray, tot_ver: np.ndarray,
                  tot_pred: np.ndarray, tot_part: np.ndarray, tot_ld: np.ndarray,
                  first_call: bool, cp_off: np.ndarray, gcache: np.ndarray,
                  alias_dst: np.ndarray, alias_src: np.ndarray, u: np.ndarray,
                  ubar: np.ndarray, t: int, tol: float, new: np.ndarray,
                  best: np.ndarray) -> bool:
    """One JSFP iteration of players ``p_lo .. p_hi - 1`` of an epoch game (one block: it
    reads and writes only its own players' entries, so blocks may run on threads).

    Their pair terms (:func:`game_players_nb`); each of their candidates' utility, the sum
    of its pairs' terms in pair order, summed again only where one of them changed
    (``gcache`` keeps them; on the first call every candidate), written to ``u``; a current
    action that duplicates an earlier candidate takes its sum (``alias_*``). Then, unless
    ``t`` is 0 (utilities only), the iteration's bookkeeping: whether each of these players
    is at a best response (``vmax <= u[cur] + tol``), the running averages
    ``(t-1)/t ubar + u/t`` into ``new`` and the best responses under the tie rule into
    ``best`` (both computed whatever the answer: the caller discards them when every block
    is at an equilibrium). ``best`` holds the players' current actions on entry (-1:
    unassigned).

    Returns
    -------
    True if every player of the block is at a best response.
    """
    n_dirty = game_players_nb(p_lo, p_hi, Wp, tgt, F, Q, cv, dt, cum, existence, k, hi,
                              c_loc, j_pair, first, count, offset, data, delta, rows, by_t,
                              t_off, cand_off, dirty, dlist, seen, Wtot, pre, tot_ver,
                              tot_pred, tot_part, tot_ld)
    a0, b0 = cand_off[p_lo], cand_off[p_hi]
    if first_call:
        for c in range(a0, b0):
            g = 0.0
            for q in range(cp_off[c], cp_off[c + 1]):
                g += delta[q]
            gcache[c] = g
            dirty[c] = False
    else:
        for y in range(a0, a0 + n_dirty):
            c = dlist[y]
            g = 0.0
            for q in range(cp_off[c], cp_off[c + 1]):
                g += delta[q]
            gcache[c] = g
            dirty[c] = False
    for x in range(alias_dst.shape[0]):              # a duplicate current action
        if a0 <= alias_dst[x] < b0:
            gcache[alias_dst[x]] = gcache[alias_src[x]]
    for c in range(a0, b0):
        u[c] = gcache[c]
    if t == 0:
        return True
    eq = True
    for p in range(p_lo, p_hi):
        if best[p] < 0:
            eq = False
            break
        a, b = cand_off[p], cand_off[p + 1]
        vmax = u[a]
        for x in range(a + 1, b):
            vmax = max(vmax, u[x])
        if not vmax <= u[a + best[p]] + tol:
            eq = False
            break
    w = (t - 1) / t
    for x in range(a0, b0):
        new[x] = w * ubar[x] + u[x] / t
    for p in range(p_lo, p_hi):
        a, b = cand_off[p], cand_off[p + 1]
        cur = best[p]
        vmax = new[a]
        for x in range(a + 1, b):
            vmax = max(vmax, new[x])
        floor = vmax - tol
        if cur >= 0 and new[a + cur] >= floor:
            continue                                 # the current action stays
        best[p] = -1
        for x in range(a, b):
            if new[x] >= floor:
                best[p] = x - a
                break
    return eq
