"""Compiled kernel of the search term for a batch of one player's candidates
(:func:`sensorplan.planners.search.candidate_potentials`).

A look's ``P_d v`` is non-zero on a small part of the grid (its sensing region), and a
candidate changes the miss probabilities of its own chain's epochs only. So mu of a
candidate is the others' mu plus, over the cells its looks cover, the change of those cells'
terms from its first epoch on: the same per-cell recursion as
:func:`~sensorplan.planners.search.expected_found`, in the same order (each cell's ``D``
bit for bit), summed over cells in another order (mu equal to round-off).
"""

from __future__ import annotations

import math

import numpy as np

from .._compiled.jit import njit
from ._chains_nb import logdet4, predict_step, sum_by_target_nb, update_step
from ..models.radar.model import (ANGLE_TOL, cos_psi, detection_probability, hidden, in_band,
                                  in_wedge, look, wrap)
from ..models.sensors import ALTITUDE, ALTITUDE2, FOV

#: Margin on the cosine of the wedge's half-angle outside which a cell is certainly not
#: visible: many orders of magnitude above the rounding of the radar's own tests, so a cell
#: it skips is one :func:`~sensorplan.models.radar.model.visible` rejects too.
_WEDGE_MARGIN = 1e-9


@njit(cache=True)
def _cell_tail(d: float, b: float, survival: float, e: int, miss: np.ndarray, k0: int,
               c: int, chain: np.ndarray) -> float:
    """Found targets of cell c from epoch k0 (0-based) on, from ``d`` (its intensity before
    epoch k0's first step), with epoch kk's miss ``miss[kk, c] * chain[kk - k0]``."""
    acc = 0.0
    for kk in range(k0, miss.shape[0]):
        m = miss[kk, c] * chain[kk - k0]
        for _ in range(e):
            d = survival * d + b
            acc += d * (1.0 - m)
            d = d * m
    return acc


@njit(cache=True)
def found_nb(d0: np.ndarray, births: np.ndarray, survival: float, e: int, K: int, k0: int,
             player: int, plan_sensor: np.ndarray, plan_epoch: np.ndarray,
             plan_row: np.ndarray, look_row: np.ndarray, look_epoch: np.ndarray,
             row_off: np.ndarray, row_idx: np.ndarray, row_val: np.ndarray, has_prev: bool,
             prev_miss: np.ndarray, prev_delta: np.ndarray, prev_base: float,
             prev_rep: np.ndarray, cell_off: np.ndarray, cell_cand: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray,
                        np.ndarray]:
    """mu for each candidate of a player (sensor ``player``) whose chain starts at epoch
    ``k0`` (0-based).

    Parameters
    ----------
    d0, births : (C,)          the undetected intensity now, births per step
    K : int                    epochs
    plan_sensor, plan_epoch, plan_row : (n_p,) int   every planned look's sensor, epoch
                               (0-based) and pool row, in the order their misses multiply
                               (sensor by sensor); the player's from k0 on are not counted
    look_row : (A, n) int      row of each candidate's n chain looks in the pool (-1: none)
    look_epoch : (n,) int      each chain look's epoch (0-based, ascending, from k0)
    row_off, row_idx, row_val  the pool of looks: row r's non-zero ``P_d v`` are
                               ``row_val[row_off[r]:row_off[r+1]]`` at cells ``row_idx[...]``
    has_prev : bool            the other arguments are this call's last returned ``kept``
                               with the same arguments but the planned looks (the same
                               player, candidates and pool rows); else they are not read
    prev_miss, prev_delta, prev_base, prev_rep, cell_off, cell_cand   that ``kept``

    Returns
    -------
    mu : (A,) expected number of undetected targets found
    kept : the others' misses ``(K, C)``, each candidate's change ``(A,)`` and the others'
        mu, each candidate's first candidate with the same looks ``(A,)``, and (from the
        second call on) the candidates whose looks cover each cell (``cell_cand[cell_off[c]:
        cell_off[c + 1]]``; empty before)
    """
    C = d0.shape[0]
    A, n = look_row.shape
    # Every other look's product of 1 - P_d v per epoch (1 - 0 = 1: cells a look misses
    # keep their bits).
    miss = np.ones((K, C))
    for q in range(plan_row.shape[0]):
        if plan_sensor[q] == player and plan_epoch[q] >= k0:
            continue
        r, kk = plan_row[q], plan_epoch[q]
        for p in range(row_off[r], row_off[r + 1]):
            miss[kk, row_idx[p]] *= 1.0 - row_val[p]
    # A candidate's change is a function of its looks and of its cells' misses (their
    # intensities and tails follow from those): where no cell it covers changed a bit
    # since the last call, it is the last call's. (The sign of a zero counts as a bit.)
    dirty = np.zeros(A, dtype=np.bool_)
    n_dirty = 0
    if has_prev:
        rep = prev_rep
        if cell_off.shape[0] == 0:
            cell_off, cell_cand = _cells_covered(look_row, rep, row_off, row_idx, C)
        for c in range(C):
            for kk in range(K):
                m, was = miss[kk, c], prev_miss[kk, c]
                if m != was or math.copysign(1.0, m) != math.copysign(1.0, was):
                    n_dirty += 1
                    for q in range(cell_off[c], cell_off[c + 1]):
                        dirty[cell_cand[q]] = True
                    break
        if n_dirty == 0:
            out = np.empty(A)
            for a in range(A):
                out[a] = prev_base + prev_delta[rep[a]]
            return out, miss, prev_delta, prev_base, rep, cell_off, cell_cand
    else:
        # Candidates whose chains are the same looks (track looks the turn limit clips to
        # one heading, say) have the same mu: each computed once, by its first in key order.
        rep = np.arange(A)
        top = 1
        for a in range(A):
            for l in range(n):
                top = max(top, look_row[a, l] + 2)
        if n > 0 and n * math.log2(top) < 62.0:
            key = np.zeros(A, dtype=np.int64)
            for a in range(A):
                for l in range(n):
                    key[a] = key[a] * top + look_row[a, l] + 1
            order = np.argsort(key, kind="mergesort")
            for q in range(1, A):
                if key[order[q]] == key[order[q - 1]]:
                    rep[order[q]] = rep[order[q - 1]]
    L = K - k0
    # The others alone: mu before k0, each cell's intensity at k0 and its tail from k0.
    d_k0 = d0.copy()
    mu_pre = 0.0
    for kk in range(k0):
        for c in range(C):
            d = d_k0[c]
            m = miss[kk, c]
            for _ in range(e):
                d = survival * d + births[c]
                mu_pre += d * (1.0 - m)
                d = d * m
            d_k0[c] = d
    ones = np.ones(L)
    tail = np.empty(C)
    tail_sum = 0.0
    for c in range(C):
        tail[c] = _cell_tail(d_k0[c], births[c], survival, e, miss, k0, c, ones)
        tail_sum += tail[c]
    base = mu_pre + tail_sum
    out = np.empty(A)
    change = np.empty(A)
    chain = np.ones((C, L))
    stamp = np.full(C, -1, dtype=np.int64)
    done = np.full(C, -1, dtype=np.int64)
    covered = np.zeros(C, dtype=np.int64)
    slot = np.zeros(C, dtype=np.int64)
    kept_miss = np.full((C, L), np.nan)
    kept_delta = np.empty((C, L))
    for a in range(A):
        if rep[a] != a:
            continue
        if has_prev and not dirty[a]:
            change[a] = prev_delta[a]
            out[a] = base + change[a]
            continue
        # One look: every cell it covers is covered once, in the row's order.
        one = -1
        for l in range(n):
            if look_row[a, l] >= 0:
                one = l if one == -1 else -2
        if one >= 0:
            r = look_row[a, one]
            kl = look_epoch[one] - k0
            delta = 0.0
            # The kept-cell update below is written out here and for the first of several
            # looks: as a called njit function it made the N = 20 decision 3.6x slower.
            for q in range(row_off[r], row_off[r + 1]):
                c = row_idx[q]
                m = 1.0 - row_val[q]
                if kept_miss[c, kl] != m:
                    chain[c, kl] = m
                    kept_delta[c, kl] = _cell_tail(d_k0[c], births[c], survival, e, miss, k0,
                                                   c, chain[c]) - tail[c]
                    kept_miss[c, kl] = m
                    chain[c, kl] = 1.0
                delta += kept_delta[c, kl]
            change[a] = delta
            out[a] = base + delta
            continue
        if one == -1:                    # no look
            change[a] = 0.0
            out[a] = base + 0.0
            continue
        # Several looks. The cells in the order they first appear, look by look: the first
        # look's in its row's order, then each later look's not seen before. The later
        # looks' cells are counted first, so that a first look's cell no later look covers
        # takes the direct path.
        f = 0
        while look_row[a, f] < 0:
            f += 1
        for l in range(f + 1, n):
            r = look_row[a, l]
            if r < 0:
                continue
            kl = look_epoch[l] - k0
            for q in range(row_off[r], row_off[r + 1]):
                c = row_idx[q]
                if stamp[c] != a:
                    stamp[c] = a
                    covered[c] = 0
                covered[c] += 1
                slot[c] = kl
                chain[c, kl] = 1.0 - row_val[q]
        delta = 0.0
        r = look_row[a, f]
        kf = look_epoch[f] - k0
        for q in range(row_off[r], row_off[r + 1]):
            c = row_idx[q]
            m = 1.0 - row_val[q]
            if stamp[c] != a:
                if kept_miss[c, kf] != m:
                    chain[c, kf] = m
                    kept_delta[c, kf] = _cell_tail(d_k0[c], births[c], survival, e, miss, k0,
                                                   c, chain[c]) - tail[c]
                    kept_miss[c, kf] = m
                    chain[c, kf] = 1.0
                delta += kept_delta[c, kf]
            else:
                chain[c, kf] = m
                delta += _cell_tail(d_k0[c], births[c], survival, e, miss, k0, c, chain[c]) \
                    - tail[c]
                chain[c, :] = 1.0
                done[c] = a
        for l in range(f + 1, n):
            r = look_row[a, l]
            if r < 0:
                continue
            for q in range(row_off[r], row_off[r + 1]):
                c = row_idx[q]
                if done[c] == a:
                    continue
                done[c] = a
                if covered[c] == 1:
                    kl = slot[c]
                    m = chain[c, kl]
                    if kept_miss[c, kl] != m:
                        kept_delta[c, kl] = _cell_tail(d_k0[c], births[c], survival, e, miss,
                                                       k0, c, chain[c]) - tail[c]
                        kept_miss[c, kl] = m
                    delta += kept_delta[c, kl]
                    chain[c, kl] = 1.0
                else:
                    delta += _cell_tail(d_k0[c], births[c], survival, e, miss, k0, c,
                                        chain[c]) - tail[c]
                    chain[c, :] = 1.0
        change[a] = delta
        out[a] = base + delta
    for a in range(A):
        out[a] = out[rep[a]]
    return out, miss, change, base, rep, cell_off, cell_cand


@njit(cache=True)
def _cells_covered(look_row: np.ndarray, rep: np.ndarray, row_off: np.ndarray,
                   row_idx: np.ndarray, C: int) -> tuple[np.ndarray, np.ndarray]:
    """The candidates (their first of the same looks, ``rep``) whose looks cover each cell:
    ``cand[off[c]:off[c + 1]]`` for cell c (a candidate repeated where several of its looks
    do)."""
    A, n = look_row.shape
    off = np.zeros(C + 1, dtype=np.int64)
    for a in range(A):
        if rep[a] != a:
            continue
        for l in range(n):
            r = look_row[a, l]
            if r >= 0:
                for q in range(row_off[r], row_off[r + 1]):
                    off[row_idx[q] + 1] += 1
    for c in range(C):
        off[c + 1] += off[c]
    fill = off[:C].copy()
    cand = np.empty(off[C], dtype=np.int64)
    for a in range(A):
        if rep[a] != a:
            continue
        for l in range(n):
            r = look_row[a, l]
            if r >= 0:
                for q in range(row_off[r], row_off[r + 1]):
                    c = row_idx[q]
                    cand[fill[c]] = a
                    fill[c] += 1
    return off, cand




@njit(cache=True)
def _pose_slot(keys: np.ndarray, sensor: int, bits: np.ndarray) -> int:
    """The slot of ``(sensor, bits)`` in the open-addressing table ``keys (cap, 4)`` (a free
    slot, ``keys[s, 0] == -1``, if absent); ``cap`` a power of two."""
    mask = keys.shape[0] - 1
    # FNV-style mixing in wrapping int64 arithmetic (constants kept below 2**63: a uint64
    # would make numba's mixed arithmetic float).
    h = (sensor + 1) * -7046029254386353131
    for q in range(3):
        h = (h ^ bits[q]) * 1099511628211
        h ^= h >> 29
    s = h & mask
    while True:
        if keys[s, 0] == -1:
            return s
        if (keys[s, 0] == sensor and keys[s, 1] == bits[0] and keys[s, 2] == bits[1]
                and keys[s, 3] == bits[2]):
            return s
        s = (s + 1) & mask


@njit(cache=True)
def pose_rows_nb(keys: np.ndarray, vals: np.ndarray, sensor: int, bits: np.ndarray,
                 n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows of a look pool by pose: each of B poses' row, new poses numbered from ``n_rows``
    in the order of their first look, and entered in the table.

    Parameters
    ----------
    keys : (cap, 4) int   the table (``-1`` in column 0: free), at most half full after the
                          call (the caller grows it);  vals : (cap,) int   the rows
    bits : (B, 3) int     each pose's x, y and heading as their float64 bits (poses are the
                          same when their bits are: the equality of their bytes)

    Returns
    -------
    rows : (B,);  first : (n_new,) the batch index of each new pose's first look
    """
    B = bits.shape[0]
    rows = np.empty(B, dtype=np.int64)
    first = np.empty(B, dtype=np.int64)
    n_new = 0
    for b in range(B):
        s = _pose_slot(keys, sensor, bits[b])
        if keys[s, 0] == -1:
            keys[s, 0] = sensor
            keys[s, 1] = bits[b, 0]
            keys[s, 2] = bits[b, 1]
            keys[s, 3] = bits[b, 2]
            vals[s] = n_rows + n_new
            first[n_new] = b
            n_new += 1
        rows[b] = vals[s]
    return rows, first[:n_new].copy()


@njit(cache=True, error_model="numpy")
def detect_sparse_into_nb(row: np.ndarray, centres: np.ndarray, xy: np.ndarray,
                          heading: np.ndarray, buildings: np.ndarray, off: np.ndarray,
                          idx: np.ndarray, val: np.ndarray, r0: int) -> int:
    """The non-zero ``P_d v`` of B looks of one sensor at the cell centres, the values of
    :func:`~sensorplan.models.radar.batch.detectable_points` bit for bit, written as rows
    ``r0..r0+B-1`` of the look pool's flat arrays (:class:`~sensorplan.planners.search.
    _LookPool`): written in place, as copying a decision's millions of entries cost more
    than finding them.

    :func:`~sensorplan.models.radar.model.visible`'s tests in its order, split by what they
    depend on: the ground range, the band test, the bearing's ``atan2`` and the slant range
    depend on the look's position only and are computed once for a run of looks from the
    same position (a player's candidates are position-major; the ``atan2`` when a look
    first needs it); the wedge and boresight tests, per heading. Cells certainly outside
    the wedge are skipped before them, and cells certainly inside it pass its test without
    the bearing (by the same margin on the cosine); ``P_d``, a function of the slant range,
    is computed once per cell and position.

    Parameters
    ----------
    row : (n_cols,) the sensor's radar row;  centres : (C, 2);  xy : (B, 2);  heading : (B,)
    buildings : (nb, 5)
    off : rows' starts, room for ``r0 + B + 1``; ``off[r0]`` is where row r0 starts
    idx, val : the rows' cells (ascending within a row) and values, room for ``B * C`` from
               ``off[r0]``;  r0 : the first row written

    Returns
    -------
    the number of entries written (``off[r0 + 1:r0 + B + 1]`` set)
    """
    B, C = xy.shape[0], centres.shape[0]
    half = row[FOV] + ANGLE_TOL
    cut = math.cos(half) - _WEDGE_MARGIN if half < math.pi else -2.0
    # Cells certainly inside the wedge (by the same margin, the other side) pass in_wedge
    # without their atan2: most of a look's cells, and the atan2 was most of their cost.
    inner = math.cos(half) + _WEDGE_MARGIN if half < math.pi else -2.0
    # The band's cells of the current position: cell, offsets, ground range, bearing and
    # slant range (visible()'s g, atan2(dy, dx) and r).
    band = np.empty(C, dtype=np.int64)
    bdx, bdy, bg = np.empty(C), np.empty(C), np.empty(C)
    bearing, slant = np.empty(C), np.empty(C)
    # P_d depends on the slant range only: kept per band cell of the position, computed
    # when a look first needs it (a position's headings overlap: about 7 looks a position).
    pd = np.empty(C)
    pd_at = np.full(C, -1, dtype=np.int64)
    nb = 0
    sx, sy = math.nan, math.nan
    b0 = 0
    n = off[r0]
    for b in range(B):
        # The same position to the bit (a signed zero is another position: its offsets
        # could differ in their zeros' signs).
        if b == 0 or not (xy[b, 0] == sx and xy[b, 1] == sy
                          and math.copysign(1.0, xy[b, 0]) == math.copysign(1.0, sx)
                          and math.copysign(1.0, xy[b, 1]) == math.copysign(1.0, sy)):
            sx, sy = xy[b, 0], xy[b, 1]
            b0 = b
            nb = 0
            for c in range(C):
                dx = centres[c, 0] - sx
                dy = centres[c, 1] - sy
                g = math.sqrt(dx * dx + dy * dy)
                if not in_band(row, g):
                    continue
                band[nb] = c
                bdx[nb], bdy[nb], bg[nb] = dx, dy, g
                bearing[nb] = math.nan           # its atan2 when a look first needs it
                slant[nb] = math.sqrt(g * g + row[ALTITUDE2])
                nb += 1
        h = heading[b]
        ch, sh = math.cos(h), math.sin(h)
        for q in range(nb):
            dx, dy = bdx[q], bdy[q]
            along = dx * ch + dy * sh
            if along < bg[q] * cut:
                continue                                 # certainly outside the wedge
            if not along > bg[q] * inner:                # not certainly inside (g = 0 too)
                if math.isnan(bearing[q]):
                    bearing[q] = math.atan2(dy, dx)
                if not in_wedge(row, wrap(bearing[q] - h)):
                    continue
            if not cos_psi(row, dx, dy, ch, sh, slant[q]) > 0.0:
                continue
            if buildings.shape[0] and hidden(buildings, sx, sy, row[ALTITUDE], sx + dx,
                                             sy + dy):
                continue
            if pd_at[q] != b0:
                pd[q] = detection_probability(row, dx * dx + dy * dy + row[ALTITUDE2])
                pd_at[q] = b0
            p = pd[q]
            if p != 0.0:
                idx[n] = band[q]
                val[n] = p
                n += 1
        off[r0 + 1 + b] = n
    return n - off[r0]


def detect_sparse(row: np.ndarray, centres: np.ndarray, xy: np.ndarray, heading: np.ndarray,
                  buildings: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`detect_sparse_into_nb` into arrays of its own.

    Returns
    -------
    counts : (B,) non-zero cells per look;  idx : (nnz,) their cells, look-major, ascending;
    val : (nnz,)
    """
    B, C = xy.shape[0], centres.shape[0]
    off = np.zeros(B + 1, dtype=np.int64)
    idx = np.empty(B * C, dtype=np.int64)
    val = np.empty(B * C)
    n = detect_sparse_into_nb(row, centres, xy, heading, buildings, off, idx, val, 0)
    return np.diff(off), idx[:n].copy(), val[:n].copy()


@njit(cache=True, fastmath=False, inline="always")
def _term(info: float, measured: bool, existence: float) -> float:
    """:func:`~sensorplan.planners.information.phi_terms`'s rule for one target, bit for bit:
    ``np.maximum(info, 0)`` (the first argument unless below, NaN kept), 0 unmeasured, times
    r."""
    kept = info if (info >= 0.0 or math.isnan(info)) else 0.0
    return existence * (kept if measured else 0.0)


@njit(cache=True, fastmath=False, inline="always")
def _run(P: np.ndarray, W: np.ndarray, t0: int, F: np.ndarray, Q: np.ndarray, qb: int,
         cv: bool, dt: float, need_sum: bool, ld_sum: float, FP: np.ndarray) -> float:
    """In place: steps ``t0..`` of :func:`~sensorplan.planners._chains_nb.
    covariance_recursion_nb`'s loop on ``P``, from its sum of log-dets so far; returns the
    sum."""
    for t in range(t0, W.shape[0]):
        predict_step(P, F, Q, qb, cv, dt, FP)
        update_step(P, W[t, 0, 0], W[t, 0, 1], W[t, 1, 1])
        if need_sum:
            ld_sum += logdet4(P)
    return ld_sum


@njit(cache=True)
def pair_terms_nb(base: np.ndarray, tgt: np.ndarray, w: np.ndarray, k0: int, P0: np.ndarray,
                  F: np.ndarray, Q: np.ndarray, cumulative: bool, cv: bool, dt: float,
                  ld_ref: np.ndarray, existence: np.ndarray) -> np.ndarray:
    """Each target's term of Phi ``(A, M)`` for each candidate of a player whose chain
    starts at epoch ``k0`` (0-based): the others' term where the chain does not look at the
    target, else the recursion over the others' information plus the chain's.

    Parameters
    ----------
    base : (M, T, 2, 2)   the other looks' information by target
    tgt : (A, L) int      the chain's targets (-1: none);  w : (A, L, e, 2, 2) its information
    P0 : (M, 4, 4);  F : (4, 4);  Q : (1, 4, 4) or (M, 4, 4);  cumulative, cv, dt   as in
                          :func:`~sensorplan.planners._chains_nb.covariance_recursion_nb`
    ld_ref : (M,)         the unmeasured log-det the terms are measured from (the last, or
                          for ``cumulative`` the sum over steps 1..T)
    existence : (M,)

    Every row (the others' of a target, or a (candidate, target looked at) pair's) runs
    :func:`~sensorplan.planners._chains_nb.covariance_recursion_nb`'s steps in its order,
    and the terms are :func:`~sensorplan.planners.information.phi_terms`'s, bit for bit. A
    pair's row equals its target's before the chain's first look at the target: the pair
    continues from the target's covariance there.
    """
    out = np.empty((tgt.shape[0], base.shape[0]))
    _pair_terms(base, tgt, w, k0, P0, F, Q, cumulative, cv, dt, ld_ref, existence,
                np.ones(base.shape[0], dtype=np.bool_), out)
    return out


@njit(cache=True)
def player_pair_terms_nb(W: np.ndarray, targets: np.ndarray, player: int, k0: int,
                         tgt: np.ndarray, w: np.ndarray, P0: np.ndarray, F: np.ndarray,
                         Q: np.ndarray, cumulative: bool, cv: bool, dt: float,
                         ld_ref: np.ndarray, existence: np.ndarray, has_prev: bool,
                         prev_base: np.ndarray, prev_terms: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """A player's (sensor ``player``'s chain from epoch ``k0``) terms ``(A, M)`` in one
    call: the others' information by target ``base (M, T, 2, 2)`` (every look's ``W (N, K,
    e, 2, 2)`` but the chain's, summed as
    :func:`~sensorplan.planners._chains_nb.sum_by_target_nb` does), then
    :func:`pair_terms_nb`'s terms; with ``has_prev``, the player's last ``prev_terms`` with
    the same candidates kept but for the targets whose row of ``base`` differs from
    ``prev_base``'s in any bit (a target's terms depend on its own row only).

    Returns
    -------
    terms (A, M), base (M, T, 2, 2)
    """
    others = targets.copy()
    for k in range(k0, targets.shape[1]):
        others[player, k] = -1
    base = sum_by_target_nb(W, others, P0.shape[0])
    M = base.shape[0]
    todo = np.ones(M, dtype=np.bool_)
    if has_prev:
        flat, old = base.reshape(M, -1), prev_base.reshape(M, -1)
        for j in range(M):
            same = True
            for q in range(flat.shape[1]):
                x, y = flat[j, q], old[j, q]
                if not (x == y and math.copysign(1.0, x) == math.copysign(1.0, y)):
                    same = False
                    break
            todo[j] = not same
        out = prev_terms.copy()
    else:
        out = np.empty((tgt.shape[0], M))
    _pair_terms(base, tgt, w, k0, P0, F, Q, cumulative, cv, dt, ld_ref, existence, todo, out)
    return out, base


@njit(cache=True)
def _pair_terms(base: np.ndarray, tgt: np.ndarray, w: np.ndarray, k0: int, P0: np.ndarray,
                F: np.ndarray, Q: np.ndarray, cumulative: bool, cv: bool, dt: float,
                ld_ref: np.ndarray, existence: np.ndarray, todo: np.ndarray,
                out: np.ndarray) -> None:
    """:func:`pair_terms_nb`'s terms of the targets ``todo`` into ``out (A, M)``."""
    A, L = tgt.shape
    M, T = base.shape[0], base.shape[1]
    e = w.shape[2]
    t0 = k0 * e                                  # the chain's first step
    shared_q = Q.shape[0] == 1
    FP = np.empty((4, 4))
    # Each target: its covariance and sum of log-dets before each of the chain's epochs
    # (a pair's row equals its target's before the chain's first look at it), then the
    # others' term.
    P_at = np.empty((M, L, 4, 4))
    sum_at = np.zeros((M, L))
    measured_t0 = np.zeros(M, dtype=np.bool_)
    P = np.empty((4, 4))
    for j in range(M):
        if not todo[j]:
            continue
        qb = 0 if shared_q else j
        P[:, :] = P0[j]
        ld_sum = _run(P, base[j, :t0], 0, F, Q, qb, cv, dt, cumulative, 0.0, FP)
        measured = False
        for t in range(T):
            for r in range(2):
                for c in range(2):
                    if base[j, t, r, c] != 0.0:
                        measured = True
                        if t < t0:
                            measured_t0[j] = True
        for l in range(L):
            P_at[j, l] = P
            sum_at[j, l] = ld_sum
            ld_sum = _run(P, base[j, :(k0 + l + 1) * e], (k0 + l) * e, F, Q, qb, cv, dt,
                          cumulative, ld_sum, FP)
        ld_sum = _run(P, base[j], (k0 + L) * e, F, Q, qb, cv, dt, cumulative, ld_sum, FP)
        info = 0.5 * (ld_ref[j] - (ld_sum if cumulative else logdet4(P)))
        term = _term(info, measured, existence[j])
        for a in range(A):
            out[a, j] = term
    # Each (candidate, target looked at) pair, from the target's state before the chain's
    # first look at it.
    row = np.empty((T, 2, 2))
    for a in range(A):
        for l in range(L):
            j = tgt[a, l]
            if j < 0 or not todo[j]:
                continue
            seen = False
            for l2 in range(l):
                if tgt[a, l2] == j:
                    seen = True
            if seen:
                continue
            row[:, :, :] = base[j]
            for l2 in range(l, L):
                if tgt[a, l2] != j:
                    continue
                for s in range(e):
                    t = (k0 + l2) * e + s
                    for r in range(2):
                        for c in range(2):
                            row[t, r, c] += w[a, l2, s, r, c]
            measured = measured_t0[j]
            for t in range(t0, T):
                for r in range(2):
                    for c in range(2):
                        if row[t, r, c] != 0.0:
                            measured = True
            P[:, :] = P_at[j, l]
            ld_sum = _run(P, row, (k0 + l) * e, F, Q, 0 if shared_q else j, cv, dt,
                          cumulative, sum_at[j, l], FP)
            info = 0.5 * (ld_ref[j] - (ld_sum if cumulative else logdet4(P)))
            out[a, j] = _term(info, measured, existence[j])


@njit(cache=True, error_model="numpy")
def look_information_nb(table: np.ndarray, sensor: np.ndarray, buildings: np.ndarray,
                        xbar: np.ndarray, Cbar: np.ndarray, pos: np.ndarray, th: np.ndarray,
                        tgt: np.ndarray, epoch: np.ndarray, probabilistic: bool,
                        W: np.ndarray, weight: np.ndarray) -> None:
    """Track information of B looks into ``W (B, e, 2, 2)`` and their weights ``p`` into
    ``weight (B, e)`` (both left as they are where ``tgt`` is -1: a sector look or none).

    Parameters
    ----------
    table : (N, n_cols) the radar table;  sensor : (B,) int   each look's sensor (its row)
    buildings : (nb, 5)
    xbar : (M, T + 1, >=2), Cbar : (M, T + 1, 3)   the targets' predicted means and position
                          covariances (``Context.xbar``, ``Context.Cbar``)
    pos : (B, 2);  th : (B,);  tgt : (B,) int;  epoch : (B,) int (1-based)   the looks

    Each look at step t is the radar's :func:`~sensorplan.models.radar.model.look` of the
    target's predicted mean and covariance at t (the values of
    :func:`~sensorplan.planners.information.chain_information`, bit for bit; a look counts
    where its weight is above 0).
    """
    e = W.shape[1]
    for b in range(tgt.shape[0]):
        j = tgt[b]
        if j < 0:
            continue
        row = table[sensor[b]]
        for s in range(e):
            t = (epoch[b] - 1) * e + 1 + s
            p, w00, w01, w11 = look(row, buildings, pos[b, 0], pos[b, 1],
                                    xbar[j, t, 0] - pos[b, 0], xbar[j, t, 1] - pos[b, 1], th[b],
                                    Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2], probabilistic)
            weight[b, s] = p
            W[b, s, 0, 0] = w00
            W[b, s, 0, 1] = w01
            W[b, s, 1, 0] = w01
            W[b, s, 1, 1] = w11

@njit(cache=True, fastmath=False, inline="always")
def _wrap(a: float) -> float:
    """:func:`~sensorplan.models.angles.wrap_angle` of one float, bit for bit (``%`` on
    floats is numpy's ``mod``: the C ``fmod`` moved to the divisor's sign)."""
    two_pi = 2.0 * math.pi
    w = math.pi - (math.pi - a) % two_pi
    return w + two_pi if w <= -math.pi else w


@njit(cache=True, fastmath=False)
def heading_rule_nb(theta: np.ndarray, bearing: np.ndarray, max_turn: float) -> np.ndarray:
    """:func:`~sensorplan.models.angles.heading_rule` of ``theta (A,)``, ``bearing (A,)``,
    bit for bit (``np.clip``'s comparisons, NaN kept)."""
    out = np.empty(theta.shape[0])
    for a in range(theta.shape[0]):
        turn = _wrap(bearing[a] - theta[a])
        if not (math.isnan(turn) or turn > -max_turn):
            turn = -max_turn
        if not (math.isnan(turn) or turn < max_turn):
            turn = max_turn
        out[a] = _wrap(theta[a] + turn)
    return out


@njit(cache=True, fastmath=False)
def _best_nb(u: np.ndarray, current: int, tie_tol: float) -> int:
    """:func:`~sensorplan.planners.search.best_index` (-1 where it finds none: a NaN)."""
    top = u[0]
    for a in range(1, u.shape[0]):
        if not top >= u[a]:               # numpy's max: a NaN wins
            if math.isnan(top):
                break
            top = u[a]
    scale = abs(top)
    floor = top - tie_tol * (scale if scale > 1.0 else 1.0)
    if current >= 0 and u[current] >= floor:
        return current
    for a in range(u.shape[0]):
        if u[a] >= floor:
            return a
    return -1


@njit(cache=True, fastmath=False)
def jsfp_steps_nb(u: np.ndarray, ubar: np.ndarray, off: np.ndarray, t: int,
                  current: np.ndarray, tie_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Every player's step of a JSFP iteration: player p's utilities ``u[off[p]:off[p+1]]``
    (the others' actions now) and running average ``ubar[off[p]:off[p+1]]`` (in place:
    ``(t - 1) / t * ubar + u / t``); its best response to each (as
    :func:`~sensorplan.planners.search.best_index` from ``current[p]``; -1: none).

    Returns
    -------
    now, avg : (P,) int
    """
    P = off.shape[0] - 1
    now = np.empty(P, dtype=np.int64)
    avg = np.empty(P, dtype=np.int64)
    keep = (t - 1) / t
    for p in range(P):
        lo, hi = off[p], off[p + 1]
        for a in range(lo, hi):
            ubar[a] = keep * ubar[a] + u[a] / t
        now[p] = _best_nb(u[lo:hi], current[p], tie_tol)
        avg[p] = _best_nb(ubar[lo:hi], current[p], tie_tol)
    return now, avg


@njit(cache=True)
def _first_of_each_nb(same: np.ndarray) -> np.ndarray:
    """:func:`~sensorplan.planners.search._first_of_each`: the items one pass in order keeps
    unless the same as an item already kept (``same (n, n)``)."""
    n = same.shape[0]
    keep = np.empty(n, dtype=np.int64)
    nk = 0
    for s in range(n):
        dup = False
        for q in range(nk):
            if same[s, keep[q]]:
                dup = True
                break
        if not dup:
            keep[nk] = s
            nk += 1
    return keep[:nk].copy()


@njit(cache=True, fastmath=False)
def player_actions_nb(prev: np.ndarray, moves: np.ndarray, width: float, height: float,
                      tol: float, nxt: np.ndarray, has_next: bool, bearings: np.ndarray,
                      theta: float, max_turn: float, heading_tol: float, M: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~sensorplan.planners.search.player_actions` of a player, bit for bit.

    Parameters
    ----------
    prev : (2,)          the position one move before (the start, or the previous epoch's)
    moves : (m, 2)       the sensor's moves;  width, height, tol   the map and
                         :data:`~sensorplan.planners.problem.POSITION_TOL`
    nxt : (2,)           the next epoch's position, if ``has_next``
    bearings : (S,)      the sector bearings;  theta, max_turn   the heading the sectors'
                         headings turn from and by at most (the heading rule)
    heading_tol : float  :data:`~sensorplan.planners.search.HEADING_TOL`;  M : int  tracks

    Returns
    -------
    positions (A, 2), targets (A,), sectors (A,): position-major, tracks before sectors
    """
    m = moves.shape[0]
    near = tol * 10
    cand = np.empty((m, 2))
    n = 0
    for q in range(m):
        x = prev[0] + moves[q, 0]
        y = prev[1] + moves[q, 1]
        if not (x >= -tol and x <= width + tol and y >= -tol and y <= height + tol):
            continue
        if has_next:
            # numpy's max over the axes and min over the moves: a NaN anywhere fails.
            lo = math.inf
            nan = False
            for r in range(m):
                ex = abs(nxt[0] - x - moves[r, 0])
                ey = abs(nxt[1] - y - moves[r, 1])
                d = ex if (ex >= ey or math.isnan(ex)) else ey
                if math.isnan(d):
                    nan = True
                elif d < lo:
                    lo = d
            if nan or not lo <= near:
                continue
        cand[n, 0] = x
        cand[n, 1] = y
        n += 1
    same = np.empty((n, n), dtype=np.bool_)
    for a in range(n):
        for b in range(n):
            # numpy's max with initial 0: NaN kept.
            d = abs(cand[a, 0] - cand[b, 0])
            d = d if (d >= 0.0 or math.isnan(d)) else 0.0
            db = abs(cand[a, 1] - cand[b, 1])
            d = d if (d >= db or math.isnan(d)) else db
            same[a, b] = d <= near
    keep = _first_of_each_nb(same)
    S = bearings.shape[0]
    if S:
        h = heading_rule_nb(np.full(S, theta), bearings, max_turn)
        hs = np.empty((S, S), dtype=np.bool_)
        for a in range(S):
            for b in range(S):
                hs[a, b] = abs(_wrap(h[a] - h[b])) <= heading_tol
        sectors = _first_of_each_nb(hs)
    else:
        sectors = np.zeros(0, dtype=np.int64)
    n_look = M + sectors.shape[0]
    A = keep.shape[0] * n_look
    pos = np.empty((A, 2))
    tgt = np.empty(A, dtype=np.int64)
    sec = np.empty(A, dtype=np.int64)
    for p in range(keep.shape[0]):
        for l in range(n_look):
            a = p * n_look + l
            pos[a, 0] = cand[keep[p], 0]
            pos[a, 1] = cand[keep[p], 1]
            tgt[a] = l if l < M else -1
            sec[a] = -1 if l < M else sectors[l - M]
    return pos, tgt, sec


__all__ = ["detect_sparse", "detect_sparse_into_nb", "found_nb", "heading_rule_nb",
           "look_information_nb", "jsfp_steps_nb", "pair_terms_nb", "player_actions_nb",
           "player_pair_terms_nb", "pose_rows_nb"]
