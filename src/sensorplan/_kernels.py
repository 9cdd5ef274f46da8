"""Compiled (numba) kernels for the planners' innermost loop.

The covariance recursion is the planners' hot spot: thousands of tiny 4x4 predict/update
steps per decision. numpy pays ~5 us of call overhead per operation on such small matrices;
one compiled loop does a whole (candidate, target, step) block in well under a microsecond
per step. ``benchmarks/bench_planning.py --backend numpy`` measures the difference. The
pure-numpy reference lives in :mod:`sensorplan.information` and the two are tested equal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import radar
from .radar import P_VIS_MIN, look, range_weight, wrap
from .sensors import COLUMNS


@njit(cache=True, fastmath=False)
def _logdet4(P: np.ndarray) -> float:
    # Cholesky of a 4x4 symmetric positive definite matrix; log det = 2 sum log diag.
    L = np.zeros((4, 4))
    total = 0.0
    for j in range(4):
        s = P[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m]
        if s <= 0.0:
            return np.nan
        d = np.sqrt(s)
        L[j, j] = d
        total += np.log(d)
        for r in range(j + 1, 4):
            t = P[r, j]
            for m in range(j):
                t -= L[r, m] * L[j, m]
            L[r, j] = t / d
    return 2.0 * total


@njit(cache=True)
def _joseph_update(P: np.ndarray, w00: float, w01: float, w11: float, det_w: float,
                   K: np.ndarray, AP: np.ndarray) -> None:
    """In place: update P with position information W in Joseph form.

    With R = W^-1 (the equivalent measurement noise), K = P G^T (G P G^T + R)^-1 and
    P+ = (I - K G) P (I - K G)^T + K R K^T: a sum of PSD terms, accurate also when W C is
    large (the subtractive form loses digits there and the log-det with them).
    """
    r00, r01, r11 = w11 / det_w, -w01 / det_w, w00 / det_w
    s00, s01, s11 = P[0, 0] + r00, P[0, 1] + r01, P[1, 1] + r11
    det_s = s00 * s11 - s01 * s01
    i00, i01, i11 = s11 / det_s, -s01 / det_s, s00 / det_s
    for r in range(4):
        K[r, 0] = P[r, 0] * i00 + P[r, 1] * i01
        K[r, 1] = P[r, 0] * i01 + P[r, 1] * i11
    for r in range(4):
        for c in range(4):
            AP[r, c] = P[r, c] - K[r, 0] * P[0, c] - K[r, 1] * P[1, c]
    for r in range(4):
        for c in range(r, 4):
            v = AP[r, c] - AP[r, 0] * K[c, 0] - AP[r, 1] * K[c, 1]
            v += (K[r, 0] * (r00 * K[c, 0] + r01 * K[c, 1])
                  + K[r, 1] * (r01 * K[c, 0] + r11 * K[c, 1]))
            P[r, c] = v
    for r in range(4):
        for c in range(r):
            P[r, c] = P[c, r]


@njit(cache=True)
def _woodbury_update(P: np.ndarray, w00: float, w01: float, w11: float,
                     Pc: np.ndarray) -> None:
    """In place: P - P G^T (I + W C)^-1 W G P, for a singular W (no R = W^-1 exists)."""
    c00, c01, c11 = P[0, 0], P[0, 1], P[1, 1]
    # A = I + W C ; S = A^{-1} W (2x2 adjugate), det(A) >= 1
    a00 = 1.0 + w00 * c00 + w01 * c01
    a01 = w00 * c01 + w01 * c11
    a10 = w01 * c00 + w11 * c01
    a11 = 1.0 + w01 * c01 + w11 * c11
    det = a00 * a11 - a01 * a10
    s00 = (a11 * w00 - a01 * w01) / det
    s01 = (a11 * w01 - a01 * w11) / det
    s10 = (-a10 * w00 + a00 * w01) / det
    s11 = (-a10 * w01 + a00 * w11) / det
    s01 = 0.5 * (s01 + s10)
    for r in range(4):
        Pc[r, 0] = P[r, 0]
        Pc[r, 1] = P[r, 1]
    for r in range(4):
        x0 = Pc[r, 0] * s00 + Pc[r, 1] * s01
        x1 = Pc[r, 0] * s01 + Pc[r, 1] * s11
        for c in range(r, 4):
            v = P[r, c] - (x0 * Pc[c, 0] + x1 * Pc[c, 1])
            P[r, c] = v
            P[c, r] = v


@njit(cache=True, fastmath=False)
def covariance_recursion_nb(P0: np.ndarray, W: np.ndarray, F: np.ndarray, Q: np.ndarray,
                            need_sum: bool, cv: bool,
                            dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Same contract as :func:`sensorplan.information.covariance_recursion_numpy`.

    ``Q`` is ``(1, 4, 4)`` (shared by every row) or ``(B, 4, 4)`` (one per row). ``cv`` says
    that ``F`` is the CWNA transition with step ``dt``, whose product is then computed in
    closed form (a quarter of the multiplications).
    """
    n = P0.shape[0]
    S = W.shape[1]
    P_end = np.empty((n, 4, 4))
    ld_end = np.empty(n)
    ld_sum = np.zeros(n)
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    Pc = np.empty((4, 2))
    shared_q = Q.shape[0] == 1
    for b in range(n):
        qb = 0 if shared_q else b
        for r in range(4):
            for c in range(4):
                P[r, c] = P0[b, r, c]
        for t in range(S):
            # predict: P = F P F^T + Q
            if cv:
                # F = [[I, dt I], [0, I]] (state [x, y, vx, vy]): the product in closed form,
                # P' = [[A + dt (B + B^T) + dt^2 D, B + dt D], [., D]] + Q, new from old.
                for r in range(2):
                    for c in range(2):
                        FP[r, c] = (P[r, c] + dt * (P[r, c + 2] + P[r + 2, c])
                                    + dt * dt * P[r + 2, c + 2])
                        FP[r, c + 2] = P[r, c + 2] + dt * P[r + 2, c + 2]
                        FP[r + 2, c] = P[r + 2, c] + dt * P[r + 2, c + 2]
                        FP[r + 2, c + 2] = P[r + 2, c + 2]
                for r in range(4):
                    for c in range(r, 4):
                        v = 0.5 * (FP[r, c] + FP[c, r]) + Q[qb, r, c]
                        P[r, c] = v
                        P[c, r] = v
            else:
                for r in range(4):
                    for c in range(4):
                        s = 0.0
                        for m in range(4):
                            s += F[r, m] * P[m, c]
                        FP[r, c] = s
                for r in range(4):
                    for c in range(r, 4):
                        s = Q[qb, r, c]
                        for m in range(4):
                            s += FP[r, m] * F[c, m]
                        P[r, c] = s
                        P[c, r] = s
            w00 = W[b, t, 0, 0]
            w01 = W[b, t, 0, 1]
            w11 = W[b, t, 1, 1]
            if w00 != 0.0 or w01 != 0.0 or w11 != 0.0:
                det_w = w00 * w11 - w01 * w01
                if det_w > 1e-12 * (w00 + w11) ** 2:     # information.JOSEPH_MIN_DET
                    _joseph_update(P, w00, w01, w11, det_w, Pc, FP)
                else:
                    _woodbury_update(P, w00, w01, w11, Pc)
            if need_sum:
                ld_sum[b] += _logdet4(P)
        for r in range(4):
            for c in range(4):
                P_end[b, r, c] = P[r, c]
        ld_end[b] = _logdet4(P)
    return P_end, ld_end, ld_sum


@njit(cache=True)
def _any_in_band(row: np.ndarray, xbar: np.ndarray, Cbar: np.ndarray, j: int, t0: int,
                 e: int, px: float, py: float, probabilistic: bool) -> bool:
    """Whether any look at target j in steps t0 .. t0+e-1 passes the radar's range test."""
    for s in range(e):
        x = xbar[j, t0 + s, 0] - px
        y = xbar[j, t0 + s, 1] - py
        g = math.sqrt(x * x + y * y)
        if g == 0.0:
            continue
        if range_weight(row, x / g, y / g, g, Cbar[j, t0 + s, 0], Cbar[j, t0 + s, 1],
                        Cbar[j, t0 + s, 2], probabilistic) >= P_VIS_MIN:
            return True
    return False


@njit(cache=True)
def sum_by_target_nb(W: np.ndarray, targets: np.ndarray, M: int) -> np.ndarray:
    """Scatter player information ``W (N, K, e, 2, 2)`` into ``(M, K e, 2, 2)`` by target."""
    N, K, e = targets.shape[0], targets.shape[1], W.shape[2]
    out = np.zeros((M, K * e, 2, 2))
    for i in range(N):
        for k in range(K):
            j = targets[i, k]
            if j < 0:
                continue
            for s in range(e):
                for a in range(2):
                    for b in range(2):
                        out[j, k * e + s, a, b] += W[i, k, s, a, b]
    return out


@njit(cache=True)
def _heading_rule(theta: float, bearing: float, max_turn: float) -> float:
    turn = wrap(bearing - theta)
    if turn > max_turn:
        turn = max_turn
    elif turn < -max_turn:
        turn = -max_turn
    return wrap(theta + turn)


@njit(cache=True)
def chain_looks_nb(pos: np.ndarray, tgt: np.ndarray, k0: int, e: int, prev: float,
                   prev_ok: bool, theta0: float, max_turn: float, aim: np.ndarray,
                   xbar: np.ndarray, Cbar: np.ndarray, probabilistic: bool, row: np.ndarray,
                   all_headings: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Headings and look information of candidate chains (see information.chain_looks).

    ``row`` is the sensor's radar table row. Without ``all_headings`` the heading of a
    chain's last epoch is left NaN when none of its looks can pass the range band (it has no
    other use): most candidates of a large initialisation set are out of range.
    """
    C, L = tgt.shape
    th = np.empty((C, L))
    W = np.zeros((C, L, e, 2, 2))
    weight = np.zeros((C, L, e))
    # Epochs whose position and target are the same for every candidate (the fixed tail of
    # a chain) share their bearing: compute it once.
    shared = np.zeros(L, dtype=np.bool_)
    shared_bearing = np.zeros(L)
    for l in range(L):
        same = True
        for c in range(1, C):
            if (tgt[c, l] != tgt[0, l] or pos[c, l, 0] != pos[0, l, 0]
                    or pos[c, l, 1] != pos[0, l, 1]):
                same = False
                break
        if same and C > 0:
            j = tgt[0, l]
            shared[l] = True
            shared_bearing[l] = math.atan2(aim[j, k0 + l - 1, 1] - pos[0, l, 1],
                                           aim[j, k0 + l - 1, 0] - pos[0, l, 0])
    for c in range(C):
        h = prev
        for l in range(L):
            k = k0 + l
            j = tgt[c, l]
            px, py = pos[c, l, 0], pos[c, l, 1]
            if l == L - 1 and not all_headings and not _any_in_band(
                    row, xbar, Cbar, j, (k - 1) * e + 1, e, px, py, probabilistic):
                th[c, l] = np.nan     # no look of the chain's last epoch can count
                continue
            if shared[l]:
                bearing = shared_bearing[l]
            else:
                bearing = math.atan2(aim[j, k - 1, 1] - py, aim[j, k - 1, 0] - px)
            if l == 0 and not prev_ok:
                h = _heading_rule(theta0, bearing, k * max_turn)
            else:
                h = _heading_rule(h, bearing, max_turn)
            th[c, l] = h
            for s in range(e):
                t = (k - 1) * e + 1 + s
                p, w00, w01, w11 = look(row, xbar[j, t, 0] - px, xbar[j, t, 1] - py, h,
                                        Cbar[j, t, 0], Cbar[j, t, 1], Cbar[j, t, 2],
                                        probabilistic)
                weight[c, l, s] = p
                W[c, l, s, 0, 0] = w00
                W[c, l, s, 0, 1] = w01
                W[c, l, s, 1, 0] = w01
                W[c, l, s, 1, 1] = w11
    return th, W, weight


_WARM = False


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel once, on tiny inputs.

    Planners call this before starting their clock, so ``PlanResult.seconds`` is the
    planner's own time, not numba's one-off start-up (~0.1-2 s per process).
    """
    global _WARM
    if _WARM:
        return
    P = np.eye(4)[None].copy()
    W = np.zeros((1, 1, 2, 2))
    for cv in (True, False):
        covariance_recursion_nb(P, W, np.eye(4), np.zeros((1, 4, 4)), True, cv, 1.0)
    row = np.zeros(len(COLUMNS))
    row[0] = row[1] = 1.0
    for probabilistic in (True, False):
        for all_headings in (True, False):
            chain_looks_nb(np.zeros((1, 1, 2)), np.zeros((1, 1), dtype=np.int64), 1, 1, 0.0,
                           True, 0.0, 0.5, np.ones((1, 1, 2)), np.ones((1, 2, 2)),
                           np.ones((1, 2, 3)), probabilistic, row, all_headings)
    sum_by_target_nb(np.zeros((1, 1, 1, 2, 2)), np.zeros((1, 1), dtype=np.int64), 1)
    radar.warm_up()
    _WARM = True
