"""Compiled (numba) kernels for the planners' innermost loop.

The covariance recursion is the planners' hot spot: thousands of tiny 4x4 predict/update
steps per decision. numpy pays ~5 us of call overhead per operation on such small matrices;
one compiled loop does a whole (candidate, target, step) block in well under a microsecond
per step. ``benchmarks/bench_planning.py --backend numpy`` measures the difference. The
pure-numpy reference lives in :mod:`sensorplan.planners.information` and the two are tested equal.
"""

from __future__ import annotations

import math

import numpy as np
from .._compiled.jit import njit

from ..models import radar
from ..models.radar import P_VIS_MIN, look, range_weight, wrap
from ..models.sensors import COLUMNS


# The 4x4 covariance steps, once each, on scalars: a symmetric matrix is the tuple of its
# upper triangle ``(p00, p01, p02, p03, p11, p12, p13, p22, p23, p33)`` ("sym10"). A loop
# that keeps its matrix in such a tuple (the planners' per-pair recursions) touches no array
# between steps: numba counts references to every array a helper is handed, an atomic
# operation per array and call that cost the planners about a seventh of their time. The
# array forms below load, call the same scalar step and store, so both give the same numbers.


@njit(cache=True, inline="always")
def load_sym10(P: np.ndarray) -> tuple:
    """The upper triangle of a 4x4 array as a sym10 tuple."""
    return (P[0, 0], P[0, 1], P[0, 2], P[0, 3], P[1, 1], P[1, 2], P[1, 3], P[2, 2], P[2, 3],
            P[3, 3])


@njit(cache=True, inline="always")
def store_sym10(P: np.ndarray, s: tuple) -> None:
    """Write a sym10 tuple into a 4x4 array (both triangles)."""
    P[0, 0] = s[0]
    P[0, 1] = P[1, 0] = s[1]
    P[0, 2] = P[2, 0] = s[2]
    P[0, 3] = P[3, 0] = s[3]
    P[1, 1] = s[4]
    P[1, 2] = P[2, 1] = s[5]
    P[1, 3] = P[3, 1] = s[6]
    P[2, 2] = s[7]
    P[2, 3] = P[3, 2] = s[8]
    P[3, 3] = s[9]


@njit(cache=True, fastmath=False, inline="always")
def logdet_sym(m00: float, m10: float, m20: float, m30: float, m11: float, m21: float,
               m31: float, m22: float, m32: float, m33: float) -> float:
    """log det of a 4x4 symmetric positive definite matrix given its lower triangle by
    columns (NaN if not PD).

    Cholesky, ``log det = 2 sum log diag(L)``, unrolled in the order of the textbook column
    loop.
    """
    s = m00
    if s <= 0.0:
        return np.nan
    d0 = np.sqrt(s)
    total = 0.0
    total += np.log(d0)
    l10 = m10 / d0
    l20 = m20 / d0
    l30 = m30 / d0
    s = m11
    s -= l10 * l10
    if s <= 0.0:
        return np.nan
    d1 = np.sqrt(s)
    total += np.log(d1)
    t = m21
    t -= l20 * l10
    l21 = t / d1
    t = m31
    t -= l30 * l10
    l31 = t / d1
    s = m22
    s -= l20 * l20
    s -= l21 * l21
    if s <= 0.0:
        return np.nan
    d2 = np.sqrt(s)
    total += np.log(d2)
    t = m32
    t -= l30 * l20
    t -= l31 * l21
    l32 = t / d2
    s = m33
    s -= l30 * l30
    s -= l31 * l31
    s -= l32 * l32
    if s <= 0.0:
        return np.nan
    d3 = np.sqrt(s)
    total += np.log(d3)
    return 2.0 * total


@njit(cache=True, fastmath=False, inline="always")
def logdet4(P: np.ndarray) -> float:
    """log det of a 4x4 symmetric positive definite array (its lower triangle; NaN if not
    PD): :func:`logdet_sym`."""
    return logdet_sym(P[0, 0], P[1, 0], P[2, 0], P[3, 0], P[1, 1], P[2, 1], P[3, 1], P[2, 2],
                      P[3, 2], P[3, 3])


@njit(cache=True, fastmath=False, inline="always")
def logdet10(s: tuple) -> float:
    """:func:`logdet_sym` of a sym10 tuple."""
    return logdet_sym(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8], s[9])


@njit(cache=True, inline="always")
def joseph_sym(s: tuple, w00: float, w01: float, w11: float, det_w: float) -> tuple:
    """The sym10 ``s`` updated with position information W in Joseph form.

    With R = W^-1 (the equivalent measurement noise), K = P G^T (G P G^T + R)^-1 and
    P+ = (I - K G) P (I - K G)^T + K R K^T: a sum of PSD terms, accurate also when W C is
    large (the subtractive form loses digits there and the log-det with them).

    Each entry is computed as the loops ``K = P[:, :2] S^-1``, ``A = P - K P[:2]``,
    ``P+ = A - A[:, :2] K^T + K R K^T`` would, in the same order.
    """
    r00, r01, r11 = w11 / det_w, -w01 / det_w, w00 / det_w
    p00, p01, p02, p03, p11, p12, p13, p22, p23, p33 = s
    s00, s01, s11 = p00 + r00, p01 + r01, p11 + r11
    det_s = s00 * s11 - s01 * s01
    i00, i01, i11 = s11 / det_s, -s01 / det_s, s00 / det_s
    k00 = p00 * i00 + p01 * i01
    k01 = p00 * i01 + p01 * i11
    k10 = p01 * i00 + p11 * i01
    k11 = p01 * i01 + p11 * i11
    k20 = p02 * i00 + p12 * i01
    k21 = p02 * i01 + p12 * i11
    k30 = p03 * i00 + p13 * i01
    k31 = p03 * i01 + p13 * i11
    a00 = p00 - k00 * p00 - k01 * p01
    a01 = p01 - k00 * p01 - k01 * p11
    a02 = p02 - k00 * p02 - k01 * p12
    a03 = p03 - k00 * p03 - k01 * p13
    a10 = p01 - k10 * p00 - k11 * p01
    a11 = p11 - k10 * p01 - k11 * p11
    a12 = p12 - k10 * p02 - k11 * p12
    a13 = p13 - k10 * p03 - k11 * p13
    a20 = p02 - k20 * p00 - k21 * p01
    a21 = p12 - k20 * p01 - k21 * p11
    a22 = p22 - k20 * p02 - k21 * p12
    a23 = p23 - k20 * p03 - k21 * p13
    a30 = p03 - k30 * p00 - k31 * p01
    a31 = p13 - k30 * p01 - k31 * p11
    a33 = p33 - k30 * p03 - k31 * p13
    v = a00 - a00 * k00 - a01 * k01
    v += (k00 * (r00 * k00 + r01 * k01) + k01 * (r01 * k00 + r11 * k01))
    o00 = v
    v = a01 - a00 * k10 - a01 * k11
    v += (k00 * (r00 * k10 + r01 * k11) + k01 * (r01 * k10 + r11 * k11))
    o01 = v
    v = a02 - a00 * k20 - a01 * k21
    v += (k00 * (r00 * k20 + r01 * k21) + k01 * (r01 * k20 + r11 * k21))
    o02 = v
    v = a03 - a00 * k30 - a01 * k31
    v += (k00 * (r00 * k30 + r01 * k31) + k01 * (r01 * k30 + r11 * k31))
    o03 = v
    v = a11 - a10 * k10 - a11 * k11
    v += (k10 * (r00 * k10 + r01 * k11) + k11 * (r01 * k10 + r11 * k11))
    o11 = v
    v = a12 - a10 * k20 - a11 * k21
    v += (k10 * (r00 * k20 + r01 * k21) + k11 * (r01 * k20 + r11 * k21))
    o12 = v
    v = a13 - a10 * k30 - a11 * k31
    v += (k10 * (r00 * k30 + r01 * k31) + k11 * (r01 * k30 + r11 * k31))
    o13 = v
    v = a22 - a20 * k20 - a21 * k21
    v += (k20 * (r00 * k20 + r01 * k21) + k21 * (r01 * k20 + r11 * k21))
    o22 = v
    v = a23 - a20 * k30 - a21 * k31
    v += (k20 * (r00 * k30 + r01 * k31) + k21 * (r01 * k30 + r11 * k31))
    o23 = v
    v = a33 - a30 * k30 - a31 * k31
    v += (k30 * (r00 * k30 + r01 * k31) + k31 * (r01 * k30 + r11 * k31))
    o33 = v
    return (o00, o01, o02, o03, o11, o12, o13, o22, o23, o33)


@njit(cache=True, inline="always")
def woodbury_sym(p: tuple, w00: float, w01: float, w11: float) -> tuple:
    """P - P G^T (I + W C)^-1 W G P for a singular W (no R = W^-1 exists), as a sym10;
    ``p`` is the full matrix, row-major (16 entries: the array form reads both triangles).
    """
    c00, c01, c11 = p[0], p[1], p[5]
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
    # Columns 0 and 1 of P (the array form's copy Pc), then x_r = Pc[r] S.
    u0, u1, u2, u3 = p[0], p[4], p[8], p[12]
    v0, v1, v2, v3 = p[1], p[5], p[9], p[13]
    x00, x01 = u0 * s00 + v0 * s01, u0 * s01 + v0 * s11
    x10, x11 = u1 * s00 + v1 * s01, u1 * s01 + v1 * s11
    x20, x21 = u2 * s00 + v2 * s01, u2 * s01 + v2 * s11
    x30, x31 = u3 * s00 + v3 * s01, u3 * s01 + v3 * s11
    return (p[0] - (x00 * u0 + x01 * v0), p[1] - (x00 * u1 + x01 * v1),
            p[2] - (x00 * u2 + x01 * v2), p[3] - (x00 * u3 + x01 * v3),
            p[5] - (x10 * u1 + x11 * v1), p[6] - (x10 * u2 + x11 * v2),
            p[7] - (x10 * u3 + x11 * v3), p[10] - (x20 * u2 + x21 * v2),
            p[11] - (x20 * u3 + x21 * v3), p[15] - (x30 * u3 + x31 * v3))


@njit(cache=True, inline="always")
def full16(s: tuple) -> tuple:
    """The 16 entries, row-major, of the symmetric matrix of a sym10 tuple."""
    return (s[0], s[1], s[2], s[3], s[1], s[4], s[5], s[6], s[2], s[5], s[7], s[8], s[3],
            s[6], s[8], s[9])


@njit(cache=True, inline="always")
def load16(P: np.ndarray) -> tuple:
    """The 16 entries of a 4x4 array, row-major."""
    return (P[0, 0], P[0, 1], P[0, 2], P[0, 3], P[1, 0], P[1, 1], P[1, 2], P[1, 3], P[2, 0],
            P[2, 1], P[2, 2], P[2, 3], P[3, 0], P[3, 1], P[3, 2], P[3, 3])


@njit(cache=True, fastmath=False, inline="always")
def predict_cv_sym(p: tuple, dt: float, q: tuple) -> tuple:
    """``F P F^T + Q`` for the CWNA transition with step ``dt`` (state [x, y, vx, vy]), in
    closed form: P' = [[A + dt (B + B^T) + dt^2 D, B + dt D], [., D]] + Q, new from old, made
    symmetric. ``p``: the 16 entries of P, row-major; ``q``: Q as a sym10; returns a sym10.
    (``dt2`` is the product dt * dt the loop form evaluates first.)
    """
    dt2 = dt * dt
    p00, p01, p02, p03, p10, p11, p12, p13, p20, p21, p22, p23, p30, p31, p32, p33 = p
    f00 = p00 + dt * (p02 + p20) + dt2 * p22
    f01 = p01 + dt * (p03 + p21) + dt2 * p23
    f02 = p02 + dt * p22
    f03 = p03 + dt * p23
    f10 = p10 + dt * (p12 + p30) + dt2 * p32
    f11 = p11 + dt * (p13 + p31) + dt2 * p33
    f12 = p12 + dt * p32
    f13 = p13 + dt * p33
    f20 = p20 + dt * p22
    f21 = p21 + dt * p23
    f22 = p22
    f23 = p23
    f30 = p30 + dt * p32
    f31 = p31 + dt * p33
    f32 = p32
    f33 = p33
    return (0.5 * (f00 + f00) + q[0], 0.5 * (f01 + f10) + q[1], 0.5 * (f02 + f20) + q[2],
            0.5 * (f03 + f30) + q[3], 0.5 * (f11 + f11) + q[4], 0.5 * (f12 + f21) + q[5],
            0.5 * (f13 + f31) + q[6], 0.5 * (f22 + f22) + q[7], 0.5 * (f23 + f32) + q[8],
            0.5 * (f33 + f33) + q[9])


@njit(cache=True, fastmath=False, inline="always")
def update_sym(p: tuple, w00: float, w01: float, w11: float) -> tuple:
    """Add position information ``W = [[w00, w01], [w01, w11]]`` to the sym10 ``p``.

    Joseph form when ``W`` is well conditioned, the subtractive form when it is nearly
    singular (see :func:`sensorplan.planners.information.information_update`); ``W = 0`` leaves it
    unchanged.
    """
    if w00 != 0.0 or w01 != 0.0 or w11 != 0.0:
        det_w = w00 * w11 - w01 * w01
        if det_w > 1e-12 * (w00 + w11) ** 2:     # information.JOSEPH_MIN_DET
            return joseph_sym(p, w00, w01, w11, det_w)
        return woodbury_sym(full16(p), w00, w01, w11)
    return p


@njit(cache=True, fastmath=False, inline="always")
def predict_step(P: np.ndarray, F: np.ndarray, Q: np.ndarray, qb: int, cv: bool, dt: float,
                 FP: np.ndarray) -> None:
    """In place: ``P <- F P F^T + Q[qb]``, symmetric (``FP`` is scratch, 4x4).

    ``cv`` says that ``F`` is the CWNA transition with step ``dt``, whose product is then
    computed in closed form (:func:`predict_cv_sym`, a quarter of the multiplications).
    """
    if cv:
        store_sym10(P, predict_cv_sym(load16(P), dt, load_sym10(Q[qb])))
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


@njit(cache=True, fastmath=False, inline="always")
def update_step(P: np.ndarray, w00: float, w01: float, w11: float) -> None:
    """In place: :func:`update_sym` of a 4x4 array (the Joseph form reads its upper
    triangle: every update follows a predict, which leaves it symmetric)."""
    if w00 != 0.0 or w01 != 0.0 or w11 != 0.0:
        det_w = w00 * w11 - w01 * w01
        if det_w > 1e-12 * (w00 + w11) ** 2:     # information.JOSEPH_MIN_DET
            store_sym10(P, joseph_sym(load_sym10(P), w00, w01, w11, det_w))
        else:
            store_sym10(P, woodbury_sym(load16(P), w00, w01, w11))


@njit(cache=True, fastmath=False)
def covariance_recursion_nb(P0: np.ndarray, W: np.ndarray, F: np.ndarray, Q: np.ndarray,
                            need_sum: bool, cv: bool,
                            dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Same contract as :func:`sensorplan.planners.information.covariance_recursion_numpy`.

    ``Q`` is ``(1, 4, 4)`` (shared by every row) or ``(B, 4, 4)`` (one per row); ``cv``: see
    :func:`predict_step`.
    """
    n = P0.shape[0]
    S = W.shape[1]
    P_end = np.empty((n, 4, 4))
    ld_end = np.empty(n)
    ld_sum = np.zeros(n)
    P = np.empty((4, 4))
    FP = np.empty((4, 4))
    shared_q = Q.shape[0] == 1
    for b in range(n):
        qb = 0 if shared_q else b
        for r in range(4):
            for c in range(4):
                P[r, c] = P0[b, r, c]
        for t in range(S):
            predict_step(P, F, Q, qb, cv, dt, FP)
            update_step(P, W[b, t, 0, 0], W[b, t, 0, 1], W[b, t, 1, 1])
            if need_sum:
                ld_sum[b] += logdet4(P)
        for r in range(4):
            for c in range(4):
                P_end[b, r, c] = P[r, c]
        ld_end[b] = logdet4(P)
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


# The heading chain (docs/planning.md, section 1), once for every kernel that flies it.


@njit(cache=True, inline="always")
def aim_bearing(aim: np.ndarray, j: int, k: int, px: float, py: float) -> float:
    """Bearing (rad) from the ground position ``(px, py)`` to the point the heading rule aims
    at in epoch ``k`` (1-based) when looking at target ``j``: ``aim[j, k - 1]``, the target's
    mean predicted to the epoch's first step (``Context.aim``)."""
    return math.atan2(aim[j, k - 1, 1] - py, aim[j, k - 1, 0] - px)


@njit(cache=True, inline="always")
def next_heading(h: float, bearing: float, k: int, after_gap: bool, theta0: float,
                 max_turn: float) -> float:
    """Heading of a chain's epoch ``k`` (1-based) toward ``bearing``.

    The heading rule from the previous epoch's heading ``h``; after an unassigned epoch
    ``k - 1`` (``after_gap``, only during the initialisation) the turn from ``theta0`` by at
    most ``k max_turn``: what is reachable in k epochs.
    """
    if after_gap:
        return _heading_rule(theta0, bearing, k * max_turn)
    return _heading_rule(h, bearing, max_turn)


@njit(cache=True)
def shared_epochs(pos: np.ndarray, tgt: np.ndarray, aim: np.ndarray,
                  k0: int) -> tuple[np.ndarray, np.ndarray]:
    """The epochs of candidate chains (``pos (C, L, 2)``, ``tgt (C, L)`` from epoch ``k0``)
    whose position and target are the same for every candidate (the fixed tail of a chain),
    and their :func:`aim_bearing` (0 elsewhere): computed once for all candidates.

    Returns
    -------
    shared : (L,) bool;  bearing : (L,)
    """
    C, L = tgt.shape
    shared = np.zeros(L, dtype=np.bool_)
    bearing = np.zeros(L)
    for l in range(L):
        same = C > 0
        for c in range(1, C):
            if (tgt[c, l] != tgt[0, l] or pos[c, l, 0] != pos[0, l, 0]
                    or pos[c, l, 1] != pos[0, l, 1]):
                same = False
                break
        if same:
            shared[l] = True
            bearing[l] = aim_bearing(aim, tgt[0, l], k0 + l, pos[0, l, 0], pos[0, l, 1])
    return shared, bearing


@njit(cache=True)
def chain_headings_nb(pos: np.ndarray, tgt: np.ndarray, k0: int, prev: np.ndarray,
                      prev_ok: bool, theta0: float, max_turn: float,
                      aim: np.ndarray) -> np.ndarray:
    """Headings ``(C, L)`` of candidate chains from epoch ``k0`` (those of
    :func:`chain_looks_nb`), each entered from its heading ``prev[c]``."""
    C, L = tgt.shape
    th = np.empty((C, L))
    for c in range(C):
        h = prev[c]
        for l in range(L):
            k = k0 + l
            h = next_heading(h, aim_bearing(aim, tgt[c, l], k, pos[c, l, 0], pos[c, l, 1]),
                             k, l == 0 and not prev_ok, theta0, max_turn)
            th[c, l] = h
    return th


@njit(cache=True)
def chain_looks_nb(pos: np.ndarray, tgt: np.ndarray, k0: int, e: int, prev: float,
                   prev_ok: bool, theta0: float, max_turn: float, aim: np.ndarray,
                   xbar: np.ndarray, Cbar: np.ndarray, probabilistic: bool, row: np.ndarray,
                   all_headings: bool, buildings: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Headings and look information of candidate chains (see information.chain_looks).

    ``row`` is the sensor's radar table row, ``buildings`` the ``(B, 5)`` boxes that can hide a
    target (:func:`sensorplan.models.radar.look`). Without ``all_headings`` the heading of a
    chain's last epoch is left NaN when none of its looks can pass the range band (it has no
    other use): most candidates of a large initialisation set are out of range.
    """
    C, L = tgt.shape
    th = np.empty((C, L))
    W = np.zeros((C, L, e, 2, 2))
    weight = np.zeros((C, L, e))
    shared, shared_bearing = shared_epochs(pos, tgt, aim, k0)
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
            bearing = shared_bearing[l] if shared[l] else aim_bearing(aim, j, k, px, py)
            h = next_heading(h, bearing, k, l == 0 and not prev_ok, theta0, max_turn)
            th[c, l] = h
            for s in range(e):
                t = (k - 1) * e + 1 + s
                p, w00, w01, w11 = look(row, buildings, px, py, xbar[j, t, 0] - px,
                                        xbar[j, t, 1] - py, h, Cbar[j, t, 0], Cbar[j, t, 1],
                                        Cbar[j, t, 2], probabilistic)
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
                           np.ones((1, 2, 3)), probabilistic, row, all_headings,
                           np.zeros((0, 5)))
    chain_headings_nb(np.zeros((1, 1, 2)), np.zeros((1, 1), dtype=np.int64), 1, np.zeros(1),
                      True, 0.0, 0.5, np.ones((1, 1, 2)))
    sum_by_target_nb(np.zeros((1, 1, 1, 2, 2)), np.zeros((1, 1), dtype=np.int64), 1)
    radar.warm_up()
    _WARM = True
