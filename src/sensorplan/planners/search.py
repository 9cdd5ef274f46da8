r"""Search looks and the value of search: Phi with ``search = "on"``.

A look points the beam at a track or at a search sector: one of ``S_i`` absolute bearings
``2 pi s / S_i`` around sensor i's platform. A sector look aims the heading rule at the
sector's bearing, so the turn limit applies; sectors the rule maps to the same heading are
one action (:func:`sector_actions`).

With search on, Phi is

.. math::
    \Phi(a) = \sum_j r_j\, I_j(a) + w\, \mu(a),\qquad
    \mu(a) = \sum_{t=1}^{T} \sum_c D_t(c)\, \Big(1 - \prod_{l \in L_t} (1 - P_{d,l}(c)\,
             v_l(c))\Big),

``I_j`` the track information of :mod:`~sensorplan.planners.information` (the same
definition), ``L_t`` the looks of step t (every step of an epoch is a look of each of the
epoch's assigned players, as for tracks: with one step per epoch the sum is over epochs),
``P_d v`` the radar's probability of detecting a target at the cell's centre (0 outside
the sensing region or out of sight; :func:`sensorplan.models.radar.detectable_points`, the
call the multi-target tracker thins its undetected cells with) and ``D_t`` the undetected
intensity predicted to step t, ``D_t = p_S D'_{t-1} + b``, from the intensity thinned by
the plan's earlier looks, ``D'_t = D_t \prod_{l \in L_t} (1 - P_{d,l} v_l)``. A target found
within the horizon is not tracked within it. mu is a closed form on the grid, so Phi stays
an exact potential: a player's utility is its marginal contribution to both parts.

``w`` (nats per newly found target) is :func:`first_detection_weight` unless the problem
sets it: docs/planning.md gives the derivation.

This module is plain numpy: :func:`potential` is the reference definition,
:func:`candidate_potentials` the batched one the planners use (tested equal).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from .._types import FloatArray, IntArray
from ..errors import ConfigError
from ..models import radar
from ..models.angles import heading_rule, heading_rule_scalar, wrap_angle
from ._search_nb import (detect_sparse_into_nb, found_nb, jsfp_steps_nb, look_information_nb,
                         player_actions_nb, player_pair_terms_nb, pose_rows_nb)
from .cells import candidate_chains, detection
from .information import (BACKEND, Context, chain_information, covariance_recursion,
                          cv_form, measured, phi_terms, sum_by_target, target_information)
from .information import prepare as prepare_tracks
from .problem import POSITION_TOL, TIE_TOL, Plan, PlanningProblem, move_vectors

if TYPE_CHECKING:  # pragma: no cover
    from .gospa_bound import GospaContext

#: Headings closer than this (rad) are the same heading (sector deduplication).
HEADING_TOL = 1e-12
#: No earlier terms (player_pair_terms_nb's arguments without them).
_NO_BASE = np.zeros((0, 0, 2, 2))
_NO_TERMS = np.zeros((0, 0))
#: No earlier call (found_nb's kept arguments without one).
NO_FOUND = (np.ones((0, 0)), np.zeros(0), 0.0, np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))


def sector_bearings(n_sectors: int) -> FloatArray:
    """The ``(S,)`` absolute bearings ``wrap(2 pi s / S)`` of S search sectors (rad)."""
    return wrap_angle(2.0 * np.pi * np.arange(n_sectors) / max(n_sectors, 1))


@dataclass(frozen=True)
class SearchContext:
    """Per-decision precomputation of Phi with search.

    Attributes
    ----------
    ctx : Context            the tracks' precomputation (:func:`information.prepare`)
    bearings : list of (S_i,) arrays   each sensor's sector bearings
    centres : (C, 2);  d0 : (C,);  births : (C,);  survival : float   the intensity
    weight : float           w, nats per newly found target
    memo : dict              what :func:`candidate_potentials` keeps between its calls for
                             this decision (by a look's pose, a plan, a candidate set)
    gospa : GospaContext or None   with ``reward = "gospa"``: Phi is the GOSPA-bound reward
                             (:mod:`sensorplan.planners.gospa_bound`)
    """

    ctx: Context
    bearings: list[FloatArray]
    centres: FloatArray
    d0: FloatArray
    births: FloatArray
    survival: float
    weight: float
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    gospa: GospaContext | None = None


def first_detection_weight(ctx: Context, cell_cov: FloatArray) -> float:
    r"""w: the information (nats) a newly found target's first detection gives about its
    position, relative to knowing only its cell.

    .. math:: w = \tfrac12 \log\det(I_2 + W C_u)

    with ``C_u`` the cell's position covariance and ``W`` the position information of one
    detection by sensor 0 on its boresight at the middle of its ground-range band (the
    radar's noise model, without the detection probability: the detection happened).
    """
    row = ctx.radar[0]
    s = ctx.problem.sensors[0]
    mid = 0.5 * (float(s.min_ground_range) + float(s.max_ground_range))
    C = np.array([cell_cov[0, 0], cell_cov[0, 1], cell_cov[1, 1]])
    W, p = radar.look_information(row, np.array([mid]), np.array([0.0]), np.array([0.0]),
                                  C[None], True, ctx.buildings, np.zeros((1, 2)))
    if not p[0] > 0:
        return 0.0
    Wd = W[0] / p[0]
    return float(0.5 * np.linalg.slogdet(np.eye(2) + Wd @ np.asarray(cell_cov))[1])


def prepare(problem: PlanningProblem) -> SearchContext:
    """Precompute Phi with search for one decision (the problem's search must be on)."""
    if not problem.searching or problem.undetected is None:
        raise ConfigError("search", "the problem's search is off")
    ctx = prepare_tracks(problem, search=True)
    u = problem.undetected
    weight = first_detection_weight(ctx, u.cell_cov) if u.weight is None else float(u.weight)
    sctx = SearchContext(ctx, [sector_bearings(S) for S in problem.sector_counts],
                         np.array(u.centres, dtype=float), np.array(u.weights, dtype=float),
                         np.array(u.births, dtype=float), float(u.survival), weight)
    if problem.reward == "gospa":
        from . import gospa_bound

        sctx = dataclasses.replace(sctx, gospa=gospa_bound.prepare(sctx))
    return sctx


def look_bearing(sctx: SearchContext, i: int, k: int, position: FloatArray | list[float],
                 target: int, sector: int) -> float:
    """The bearing the heading rule aims at for sensor i's look in epoch k (1-based)."""
    if sector >= 0:
        return float(sctx.bearings[i][sector])
    aim = sctx.ctx.aim[target, k - 1]
    return math.atan2(aim[1] - position[1], aim[0] - position[0])


def plan_headings(sctx: SearchContext, plan: Plan) -> FloatArray:
    """Headings ``(N, K)`` of a plan's looks by the heading rule (NaN where unassigned).

    Each look turns from the previous epoch's heading toward its bearing by at most the
    turn limit; after an unassigned epoch, from the initial heading by at most ``k`` turn
    limits (what is reachable in k epochs).
    """
    ctx = sctx.ctx
    out = np.full((ctx.N, ctx.K), np.nan)
    for i in range(ctx.N):
        out[i] = _sensor_headings(sctx, plan, i)
    return out


def _sensor_headings(sctx: SearchContext, plan: Plan, i: int) -> list[float]:
    """Row i of :func:`plan_headings` (a sensor's headings depend on its own looks only)."""
    ctx = sctx.ctx
    assert plan.sectors is not None
    out = [math.nan] * ctx.K
    # Python floats and lists: a sensor's part of a plan is K single looks.
    assigned, positions = plan.assigned[i].tolist(), plan.positions[i].tolist()
    targets, sectors = plan.targets[i].tolist(), plan.sectors[i].tolist()
    h, prev_ok = float(ctx.problem.headings[i]), True
    theta0, turn = float(ctx.problem.headings[i]), float(ctx.max_turn[i])
    for k in range(1, ctx.K + 1):
        if not assigned[k - 1]:
            prev_ok = False
            continue
        b = look_bearing(sctx, i, k, positions[k - 1], targets[k - 1], sectors[k - 1])
        h = (heading_rule_scalar(h, b, turn) if prev_ok
             else heading_rule_scalar(theta0, b, k * turn))
        out[k - 1] = h
        prev_ok = True
    return out


def expected_found(sctx: SearchContext, miss: FloatArray) -> FloatArray:
    """mu from the probability that each epoch's looks all miss a target in each cell.

    Parameters
    ----------
    miss : (..., K, C)   ``prod over the epoch's looks of (1 - P_d v)``

    Returns
    -------
    (...,) expected number of undetected targets the looks find
    """
    D = np.broadcast_to(sctx.d0, miss.shape[:-2] + sctx.d0.shape).copy()
    mu = np.zeros(miss.shape[:-2])
    for k in range(miss.shape[-2]):
        m = miss[..., k, :]
        for _ in range(sctx.ctx.e):
            D = sctx.survival * D + sctx.births
            mu += (D * (1.0 - m)).sum(axis=-1)
            D = D * m
    return mu


def track_information(sctx: SearchContext, plan: Plan, headings: FloatArray
                      ) -> tuple[FloatArray, IntArray]:
    """The tracks' terms of Phi ``(M,)`` for a plan whose headings are given, and each
    track look's number of looks that count ``(N, K)`` (0 elsewhere)."""
    ctx = sctx.ctx
    track = plan.targets >= 0
    W = np.zeros((ctx.N, ctx.K, ctx.e, 2, 2))
    counts = np.zeros((ctx.N, ctx.K), dtype=np.int64)
    for i in range(ctx.N):
        if track[i].any():
            pos = np.where(track[i][:, None], plan.positions[i], 0.0)[None]
            th = np.where(track[i], headings[i], 0.0)[None]
            tgt = np.maximum(plan.targets[i], 0)[None]
            w, counted = chain_information(ctx, i, 1, pos, th, tgt)
            W[i] = np.where(track[i][:, None, None, None], w[0], 0.0)
            counts[i] = np.where(track[i], counted[0].sum(axis=-1), 0)
    return target_information(ctx, sum_by_target(ctx, W, plan.targets)), counts


@dataclass(frozen=True)
class SearchEvaluation:
    """Phi with search and its parts: ``potential = information.sum() + weight * found``;
    ``measurements (N, K)``: a track look's looks that count (as without search), a search
    look's steps when it covers a cell."""

    potential: float
    information: FloatArray
    found: float
    weight: float
    headings: FloatArray
    measurements: IntArray


def evaluate(sctx: SearchContext, plan: Plan) -> SearchEvaluation:
    """Phi of ``plan`` with search: the definition, one plan (plain numpy with the ``numpy``
    backend; else from the decision's compiled track information and look pool, the same
    numbers bit for bit), kept in ``sctx.memo`` by the plan (a game's last sweep and the
    planner's result ask about the same plan)."""
    memo = _plan_memo(sctx, plan)
    got = memo.get("evaluation")
    if got is None:
        got = memo["evaluation"] = _evaluate(sctx, plan)
    return cast(SearchEvaluation, got)


def _evaluate(sctx: SearchContext, plan: Plan) -> SearchEvaluation:
    if sctx.gospa is not None:
        from . import gospa_bound

        headings = plan_headings(sctx, plan)
        phi, info, mu, weight, counts = gospa_bound.evaluate(sctx, plan, headings)
        return SearchEvaluation(phi, info, mu, weight, headings, counts)
    ctx = sctx.ctx
    assert plan.sectors is not None
    miss = np.ones((ctx.K, len(sctx.centres)))
    if BACKEND == "numpy":
        headings = plan_headings(sctx, plan)
        info, counts = track_information(sctx, plan, headings)
        for i in range(ctx.N):
            ks = np.flatnonzero(plan.assigned[i])
            if ks.size:
                p = detection(sctx, i, plan.positions[i, ks], headings[i, ks])
                miss[ks] *= 1.0 - p
                # A search look counts at each step when it covers a cell.
                sector = plan.sectors[i, ks] >= 0
                counts[i, ks[sector]] = (p[sector] > 0).any(axis=1) * ctx.e
    else:
        # The same numbers from what the game kept: the compiled track information and the
        # look pool's rows (a cell a look misses would multiply its miss by 1 - 0 = 1).
        headings = _plan_headings(sctx, plan).copy()
        W, counts = _plan_track_looks(sctx, plan, headings)
        info = target_information(ctx, sum_by_target(ctx, W, plan.targets))
        counts = counts.copy()
        pool, parts = _pool(sctx), _sensor_parts(sctx, plan)
        for i in range(ctx.N):
            assigned = np.flatnonzero(plan.assigned[i]).tolist()
            if assigned:
                rows = _part_rows(sctx, parts[i], plan, i, headings)
                for q, k in enumerate(assigned):
                    idx, val = pool.row(int(rows[q]))
                    miss[k, idx] *= 1.0 - val
                    if plan.sectors[i, k] >= 0:
                        counts[i, k] = bool((val > 0).any()) * ctx.e
    mu = float(expected_found(sctx, miss))
    return SearchEvaluation(float(info.sum()) + sctx.weight * mu, info, mu, sctx.weight,
                            headings, counts)


def potential(problem: PlanningProblem, plan: Plan) -> tuple[float, FloatArray, float]:
    """Phi with search of ``plan``: ``(phi, information (M,), mu)``."""
    ev = evaluate(prepare(problem), plan)
    return ev.potential, ev.information, ev.found


def sector_actions(sctx: SearchContext, i: int, k: int, prev_heading: float, prev_ok: bool
                   ) -> IntArray:
    """The sectors of player (i, k) that are distinct actions: the first sector of each
    heading the heading rule maps the sectors to, from ``prev_heading`` (or, after an
    unassigned epoch, ``prev_ok`` False, from the initial heading by ``k`` turn limits)."""
    b = sctx.bearings[i]
    if b.size == 0:
        return np.zeros(0, dtype=np.int64)
    turn = float(sctx.ctx.max_turn[i])
    h = (heading_rule(prev_heading, b, turn) if prev_ok
         else heading_rule(float(sctx.ctx.problem.headings[i]), b, k * turn))
    return distinct_headings(h)


def distinct_headings(headings: FloatArray) -> IntArray:
    """Indices of the first of each distinct heading (to :data:`HEADING_TOL`), ascending:
    the sectors that are distinct actions, given the headings the rule maps them to."""
    h = np.asarray(headings, dtype=float).reshape(-1)
    return _first_of_each(np.abs(wrap_angle(h[:, None] - h[None, :])) <= HEADING_TOL)


def _first_of_each(same: np.ndarray) -> IntArray:
    """Indices kept by one pass in order that keeps an item unless it is the same
    (``same (n, n)``, symmetric) as an item already kept; ascending."""
    n = same.shape[0]
    alone = same.sum(axis=1) == 1          # the same as itself only: always kept
    if alone.all():
        return np.arange(n, dtype=np.int64)
    rows = same.tolist()
    keep: list[int] = []
    for s in range(n):
        if alone[s] or not any(rows[s][t] for t in keep):
            keep.append(s)
    return np.array(keep, dtype=np.int64)


def player_positions(sctx: SearchContext, plan: Plan, i: int, k: int) -> FloatArray:
    """Positions ``(P, 2)`` player (i, k) may take: one move from its epoch k-1 position
    (the start for k = 1), inside the map, and one move from its epoch k+1 position when
    that epoch is assigned (the order of the moves)."""
    problem = sctx.ctx.problem
    moves = move_vectors(problem.sensors[i].moves)
    prev = problem.positions[i] if k == 1 else plan.positions[i, k - 2]
    cand = prev + moves
    ok = problem.world.contains(cand)
    if k < sctx.ctx.K and plan.assigned[i, k]:
        nxt = plan.positions[i, k]
        d = np.abs(nxt[None, None, :] - cand[:, None, :] - moves[None]).max(axis=-1)
        ok &= d.min(axis=1) <= POSITION_TOL * 10
    # Distinct positions only (a zero-length move may repeat the stay).
    cand = cand[ok]
    same = (np.abs(cand[:, None] - cand[None]).max(axis=-1, initial=0.0)
            <= POSITION_TOL * 10)
    return cand[_first_of_each(same)].reshape(-1, 2)


def player_actions(sctx: SearchContext, plan: Plan, i: int, k: int
                   ) -> tuple[FloatArray, IntArray, IntArray]:
    """Every action of player (i, k): positions ``(A, 2)``, targets ``(A,)`` and sectors
    ``(A,)`` (-1 where the other kind), position-major, tracks before sectors."""
    assert plan.sectors is not None
    if k == 1:
        prev_h, prev_ok = float(sctx.ctx.problem.headings[i]), True
    else:
        prev_ok = bool(plan.assigned[i, k - 2])
        prev_h = float(_plan_headings(sctx, plan)[i, k - 2]) if prev_ok else 0.0
    # The actions depend on the player's previous heading and its neighbouring epochs'
    # positions only: kept in sctx.memo by those (read-only), as sweeps ask again.
    nxt = k < sctx.ctx.K and bool(plan.assigned[i, k])
    key = (i, k, prev_ok, prev_h, plan.positions[i, k - 2].tobytes() if k > 1 else b"",
           plan.positions[i, k].tobytes() if nxt else b"")
    memo = sctx.memo.setdefault("actions", {})
    got = memo.get(key)
    if got is None:
        # sector_actions and player_positions in one compiled call.
        problem, turn = sctx.ctx.problem, float(sctx.ctx.max_turn[i])
        theta, limit = ((prev_h, turn) if prev_ok else (float(problem.headings[i]), k * turn))
        prev = problem.positions[i] if k == 1 else plan.positions[i, k - 2]
        got = memo[key] = player_actions_nb(
            np.ascontiguousarray(prev, dtype=float),
            np.ascontiguousarray(move_vectors(problem.sensors[i].moves)),
            float(problem.world.width), float(problem.world.height), POSITION_TOL,
            np.ascontiguousarray(plan.positions[i, k] if nxt else np.zeros(2)), nxt,
            sctx.bearings[i], theta, limit, HEADING_TOL, sctx.ctx.M)
        for a in got:
            a.flags.writeable = False
    return got


def candidate_potentials(sctx: SearchContext, plan: Plan, i: int, k: int,
                         positions: FloatArray, targets: IntArray, sectors: IntArray
                         ) -> FloatArray:
    """Phi with search for each candidate action of player (i, k), the others fixed: one
    batch over candidates. Player (i, k)'s action also moves the headings of sensor i's
    later epochs (the heading rule chains them); those are recomputed per candidate.

    Only what a candidate changes is computed per candidate: the terms of the targets its
    chain looks at (every other target keeps its term) and the cells its looks cover
    (:func:`~sensorplan.planners._search_nb.found_nb`); each look's ``P_d v`` and each other
    sensor's track information are kept in ``sctx.memo`` by the look's pose. The track
    terms are :func:`evaluate`'s bit for bit, mu equals its value to round-off. A call
    that asks again for the same utilities (the others' actions and the candidates as
    before) gets them from ``sctx.memo``.

    Returns
    -------
    (A,) nats
    """
    if sctx.gospa is not None:
        from . import gospa_bound

        return gospa_bound.candidate_potentials(sctx, plan, i, k, positions, targets, sectors,
                                                _plan_headings(sctx, plan))
    assert plan.sectors is not None
    # The same plan and read-only candidates as this player's last call (a JSFP iteration
    # in which nobody moved): its utilities.
    last = sctx.memo.setdefault("last_call", {})
    prev = last.get((i, k))
    if (prev is not None and prev[0] is plan and prev[1] is positions and prev[2] is targets
            and prev[3] is sectors):
        return cast(FloatArray, prev[4].copy())
    # The utilities depend on the others' actions and the candidates, not on the player's
    # own action: a JSFP iteration in which no other player moved asks again for the same.
    # (The plan's bytes without the player's entries.)
    q = i * plan.targets.shape[1] + k - 1
    pos_b, tgt_b, sec_b = _plan_key(sctx, plan)
    ps, ts, ss = plan.positions.itemsize * 2, plan.targets.itemsize, plan.sectors.itemsize
    # Read-only candidates (player_actions') are kept alive in sctx.memo: known by identity.
    kept = all(isinstance(a, np.ndarray) and not a.flags.writeable
               for a in (positions, targets, sectors))
    which = ((id(positions), id(targets), id(sectors)) if kept else
             (np.asarray(positions, dtype=float).tobytes(), np.asarray(targets).tobytes(),
              np.asarray(sectors).tobytes()))
    key = (i, k, pos_b[:q * ps] + pos_b[(q + 1) * ps:], tgt_b[:q * ts] + tgt_b[(q + 1) * ts:],
           sec_b[:q * ss] + sec_b[(q + 1) * ss:], kept, *which)
    memo = sctx.memo.setdefault("utilities", {})
    got = memo.get(key)
    if got is None or (kept and not (got[0] is positions and got[1] is targets
                                     and got[2] is sectors)):
        got = memo[key] = (positions, targets, sectors,
                           _candidate_potentials(sctx, plan, i, k, positions, targets, sectors,
                                                 kept))
    if kept:
        last[(i, k)] = (plan, positions, targets, sectors, got[3])
    return cast(FloatArray, got[3].copy())


def _candidate_potentials(sctx: SearchContext, plan: Plan, i: int, k: int,
                          positions: FloatArray, targets: IntArray, sectors: IntArray,
                          kept: bool) -> FloatArray:
    pm = _plan_memo(sctx, plan)
    headings = pm.get("headings")
    if headings is None:
        headings = _plan_headings(sctx, plan)
    tgt, w, rows, epochs = _candidate_looks(sctx, plan, i, k, positions, targets, sectors,
                                            headings, kept)
    info = _candidate_track_information(sctx, plan, i, k, headings, tgt, w, pm)
    mu = _candidate_found(sctx, plan, i, k, headings, rows, epochs, pm)
    return info + sctx.weight * mu


def _candidate_looks(sctx: SearchContext, plan: Plan, i: int, k: int, positions: FloatArray,
                     targets: IntArray, sectors: IntArray, headings: FloatArray, cached: bool
                     ) -> tuple[IntArray, FloatArray, IntArray, IntArray]:
    """Player (i, k)'s candidate chains (:func:`~sensorplan.planners.cells.candidate_chains`)
    as looks: targets ``(A, L)``, track information ``(A, L, e, 2, 2)``, pool rows
    ``(A, n)`` of the chain's n looks and their epochs ``(n,)`` (0-based: epoch k and
    sensor i's later assigned epochs).

    The chains depend on the candidates and on sensor i's other epochs only, not on the
    other sensors, whose moves make the next iterations of an epoch game: kept in
    ``sctx.memo`` by those when ``cached`` (the candidates by identity: read-only arrays
    kept alive there).
    """
    assert plan.sectors is not None
    if cached:
        memo = sctx.memo.setdefault("candidate_looks", {})
        key = (i, k, id(positions), id(targets), id(sectors),
               *(a[i, :k - 1].tobytes() + a[i, k:].tobytes()
                 for a in (plan.positions, plan.targets, plan.sectors)))
        got = memo.get(key)
        if got is not None and got[0] is positions and got[1] is targets and got[2] is sectors:
            return cast("tuple[IntArray, FloatArray, IntArray, IntArray]", got[3])
    ctx = sctx.ctx
    A, L = len(targets), ctx.K - k + 1
    pos, tgt, assigned, th = candidate_chains(sctx, plan, i, k, positions, targets,
                                                sectors, headings)
    ls = [l for l in range(L) if l == 0 or assigned[0, l]]
    rows = np.empty((A, len(ls)), dtype=np.int64)
    w = np.zeros((A, L, ctx.e, 2, 2))
    for q, l in enumerate(ls):
        rows[:, q], w[:, l] = _chain_column(sctx, i, k + l, pos[:, l], tgt[:, l], th[:, l])
    out = (tgt, w, rows, np.array(ls, dtype=np.int64) + (k - 1))
    if cached:
        memo[key] = (positions, targets, sectors, out)
    return out


def _plan_memo(sctx: SearchContext, plan: Plan) -> dict[str, Any]:
    """What :func:`candidate_potentials` derives from a whole plan, kept in ``sctx.memo`` by
    the plan (the players of a JSFP iteration all ask about the same plan)."""
    memo = sctx.memo.setdefault("plans", {})
    key = _plan_key(sctx, plan)
    got = memo.get(key)
    if got is None:
        got = memo[key] = {}
    return got


def _plan_key(sctx: SearchContext, plan: Plan) -> tuple[bytes, bytes, bytes]:
    """The bytes of a plan's positions, targets and sectors, kept by the plan's identity
    (the plan kept alive with them: a game asks about the same plan object many times)."""
    keys = sctx.memo.setdefault("plan_keys", {})
    got = keys.get(id(plan))
    if got is None or got[0] is not plan:
        assert plan.sectors is not None
        got = keys[id(plan)] = (plan, (plan.positions.tobytes(), plan.targets.tobytes(),
                                       plan.sectors.tobytes()))
    return cast("tuple[bytes, bytes, bytes]", got[1])


def _plan_headings(sctx: SearchContext, plan: Plan) -> FloatArray:
    """:func:`plan_headings`, kept with the plan (read-only)."""
    memo = _plan_memo(sctx, plan)
    got = memo.get("headings")
    if got is None:
        parts = _sensor_parts(sctx, plan)
        switch = _from_switch(memo, "headings")
        if switch is None:
            got = np.array([part["headings"] for part in parts], dtype=float)
        else:
            got = switch[0].copy()
            got[switch[1]] = parts[switch[1]]["headings"]
        got.flags.writeable = False
        memo["headings"] = got
    return got


def _sensor_parts(sctx: SearchContext, plan: Plan) -> list[dict[str, Any]]:
    """Every sensor's :func:`_sensor_part`, kept with the plan (or set by :func:`_switched`
    from the plan it came from)."""
    memo = _plan_memo(sctx, plan)
    got = memo.get("parts")
    if got is None:
        got = memo["parts"] = [_sensor_part(sctx, plan, n) for n in range(sctx.ctx.N)]
    return cast("list[dict[str, Any]]", got)


def _switched(sctx: SearchContext, plan: Plan, i: int, k: int, position: FloatArray,
              target: int, sector: int) -> Plan:
    """:func:`with_action`, the new plan's sensor parts those of ``plan`` but sensor i's
    (a switch changes one sensor's part)."""
    new = with_action(plan, i, k, position, target, sector)
    old = _plan_memo(sctx, plan)
    parts = old.get("parts")
    memo = _plan_memo(sctx, new)
    if parts is not None and "parts" not in memo:
        parts = list(parts)
        parts[i] = _sensor_part(sctx, new, i)
        memo["parts"] = parts
        memo["came_from"] = (old, i)
    return new


def _from_switch(memo: dict[str, Any], name: str) -> tuple[Any, int] | None:
    """What the plan a plan was switched from (:func:`_switched`) kept as ``name``, and the
    sensor the switch changed (None if it kept none): the new plan's is the same but that
    sensor's part."""
    came = memo.get("came_from")
    if came is None or came[0].get(name) is None:
        return None
    return came[0][name], came[1]


def _sensor_part(sctx: SearchContext, plan: Plan, n: int) -> dict[str, Any]:
    """What a sensor's own looks determine (its headings, its looks' pool rows), kept in
    ``sctx.memo`` by its part of the plan: plans met in a game differ in a few sensors."""
    assert plan.sectors is not None
    memo = sctx.memo.setdefault("sensor_parts", {})
    key = (n, plan.positions[n].tobytes(), plan.targets[n].tobytes(),
           plan.sectors[n].tobytes())
    got = memo.get(key)
    if got is None:
        got = memo[key] = {"headings": _sensor_headings(sctx, plan, n)}
    return cast("dict[str, Any]", got)


def _chain_column(sctx: SearchContext, i: int, kk: int, pos: FloatArray, tgt: IntArray,
                  th: FloatArray) -> tuple[IntArray, FloatArray]:
    """Sensor i's looks in epoch kk from ``pos (A, 2)``, targets ``tgt (A,)`` (-1: a sector)
    and headings ``th (A,)``: their rows in the look pool and their track information
    ``(A, e, 2, 2)`` (0 for a sector look), kept in ``sctx.memo`` (a player's candidates
    are the same from one iteration of its game to the next)."""
    memo = sctx.memo.setdefault("columns", {})
    key = (i, kk, pos.tobytes(), th.tobytes(), tgt.tobytes())
    got = memo.get(key)
    if got is None:
        ctx = sctx.ctx
        rows = _pool(sctx).rows(sctx, i, pos, th)
        track = tgt >= 0
        w = np.zeros((len(tgt), ctx.e, 2, 2))
        if ctx.M and track.any():
            if BACKEND == "numpy":
                wt, _ = chain_information(ctx, i, kk, pos[track][:, None],
                                          th[track][:, None], tgt[track][:, None])
                w[track] = wt[:, 0]
            else:
                B = len(tgt)
                look_information_nb(ctx.radar, np.full(B, i), ctx.buildings, ctx.xbar, ctx.Cbar,
                                    np.ascontiguousarray(pos), np.ascontiguousarray(th),
                                    np.ascontiguousarray(tgt), np.full(B, kk),
                                    ctx.probabilistic, w, np.empty((B, ctx.e)))
        got = memo[key] = (rows, w)
    return got


def _part_rows(sctx: SearchContext, part: dict[str, Any], plan: Plan, n: int,
               headings: FloatArray) -> IntArray:
    """The look pool's rows of sensor n's planned looks in epoch order, kept in its part
    ``part`` of ``plan`` (:func:`_sensor_parts`)."""
    got = part.get("rows")
    if got is None:
        ks = np.flatnonzero(plan.assigned[n])
        got = part["rows"] = _pool(sctx).rows(sctx, n, plan.positions[n, ks], headings[n, ks])
    return cast(IntArray, got)


def _candidate_found(sctx: SearchContext, plan: Plan, i: int, k: int, headings: FloatArray,
                     rows: IntArray, epochs: IntArray, memo: dict[str, Any]) -> FloatArray:
    """mu ``(A,)`` for each candidate of player (i, k) whose chain's looks in ``epochs``
    (0-based) are the look pool's ``rows (A, len(epochs))``: every other look's misses,
    times the chain's (``memo``: the plan's :func:`_plan_memo`)."""
    ctx = sctx.ctx
    pool = _pool(sctx)
    n_look, k_look, row = _planned_looks(sctx, plan, headings, memo)
    # What the player's last call kept, if its candidates' looks are the same (kept alive
    # here: known by identity): the same others' looks (the misses multiply in their order)
    # give the same mu; else its candidates whose cells' misses kept their bits keep theirs.
    kept = sctx.memo.setdefault("found", {})
    prev = kept.get((i, k))
    has = prev is not None and prev[0] is rows and prev[1] is epochs
    others = None
    if has:
        other = (n_look != i) | (k_look < k - 1)
        others = (n_look[other].tobytes(), k_look[other].tobytes(), row[other].tobytes())
        if prev[3] == others:
            return cast(FloatArray, prev[4])
    mu, *state = found_nb(sctx.d0, sctx.births, sctx.survival, ctx.e, ctx.K, k - 1, int(i),
                          n_look, k_look, row, rows, epochs, *pool.arrays(), has,
                          *(prev[2] if has else NO_FOUND))
    mu.flags.writeable = False
    kept[(i, k)] = (rows, epochs, state, others, mu)
    return cast(FloatArray, mu)


def _planned_looks(sctx: SearchContext, plan: Plan, headings: FloatArray,
                   memo: dict[str, Any]) -> tuple[IntArray, IntArray, IntArray]:
    """Every planned look's sensor, epoch (0-based) and pool row, sensor by sensor (the
    order the misses multiply in), kept in the plan's ``memo``."""
    looks = memo.get("looks")
    if looks is None:
        sensor_parts = _sensor_parts(sctx, plan)
        switch = _from_switch(memo, "looks")
        if switch is None:
            n_look, k_look = (np.ascontiguousarray(a) for a in np.nonzero(plan.assigned))
            parts = [_part_rows(sctx, sensor_parts[n], plan, n, headings)
                     for n in np.unique(n_look).tolist()]
            row = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        else:
            # The switched sensor's looks in place of its old ones.
            (n_old, k_old, row_old), n = switch
            lo, hi = np.searchsorted(n_old, [n, n + 1]).tolist()
            ks = np.flatnonzero(plan.assigned[n])
            n_look = np.concatenate([n_old[:lo], np.full(len(ks), n), n_old[hi:]])
            k_look = np.concatenate([k_old[:lo], ks, k_old[hi:]])
            row = np.concatenate([row_old[:lo], _part_rows(sctx, sensor_parts[n], plan, n,
                                                           headings), row_old[hi:]])
        looks = memo["looks"] = (n_look, k_look, row)
    return cast("tuple[IntArray, IntArray, IntArray]", looks)


class _LookPool:
    """Every look's non-zero ``P_d v`` (:func:`detection`'s values, from
    :func:`~sensorplan.planners._search_nb.detect_sparse_into_nb`), by the look's pose: sensor,
    ground position and heading, bit for bit. Rows live in growing flat arrays, the layout
    :func:`~sensorplan.planners._search_nb.found_nb` reads."""

    def __init__(self) -> None:
        # Open-addressing table of poses -> rows (:func:`pose_rows_nb`): at most half full.
        self.keys = np.full((1 << 12, 4), -1, dtype=np.int64)
        self.vals = np.zeros(1 << 12, dtype=np.int64)
        # Rows' starts and the rows; room to grow. Large to start with: a decision's rows
        # reach millions of entries at N = 20, and pages never written cost nothing.
        self.off = np.zeros(1 << 14, dtype=np.int64)
        self.idx = np.empty(1 << 20, dtype=np.int64)
        self.val = np.empty(1 << 20)
        self.n_rows = 0

    def rows(self, sctx: SearchContext, n: int, positions: FloatArray, headings: FloatArray
             ) -> IntArray:
        """The pool's rows of sensor n's looks from ``positions (B, 2)``, ``headings (B,)``
        (computed, in one batch, for the poses not seen before)."""
        B = len(headings)
        pose = np.empty((B, 3))
        pose[:, :2] = positions
        pose[:, 2] = headings
        if 2 * (self.n_rows + B) > len(self.vals):
            self._grow(self.n_rows + B)
        out, first = pose_rows_nb(self.keys, self.vals, int(n), pose.view(np.int64),
                                  self.n_rows)
        if len(first):
            ctx = sctx.ctx
            R, start = self.n_rows, int(self.off[self.n_rows])
            self.off = _grown(self.off, R + 1 + len(first))
            most = start + len(first) * len(sctx.centres)       # every look sees every cell
            self.idx = _grown(self.idx, most)
            self.val = _grown(self.val, most)
            detect_sparse_into_nb(ctx.radar[n], sctx.centres,
                                  np.ascontiguousarray(pose[first, :2]),
                                  np.ascontiguousarray(pose[first, 2]), ctx.buildings,
                                  self.off, self.idx, self.val, R)
            self.n_rows += len(first)
        return out

    def _grow(self, n: int) -> None:
        """A table with room for ``n`` poses at most half full, every pose entered again."""
        cap = len(self.vals)
        while cap < 2 * n:
            cap *= 2
        used = np.flatnonzero(self.keys[:, 0] >= 0)
        old = self.keys[used[np.argsort(self.vals[used])]]   # by row: rows 0..n_rows-1
        self.keys = np.full((cap, 4), -1, dtype=np.int64)
        self.vals = np.zeros(cap, dtype=np.int64)
        # Runs of one sensor's consecutive rows, entered again under the same rows.
        cuts = np.flatnonzero(np.diff(old[:, 0])) + 1
        for lo, hi in ([] if len(old) == 0 else
                       zip([0, *cuts.tolist()], [*cuts.tolist(), len(old)])):
            pose_rows_nb(self.keys, self.vals, int(old[lo, 0]),
                         np.ascontiguousarray(old[lo:hi, 1:]), lo)

    def row(self, r: int) -> tuple[IntArray, FloatArray]:
        """Cells and values of row r."""
        a, b = self.off[r], self.off[r + 1]
        return self.idx[a:b], self.val[a:b]

    def arrays(self) -> tuple[IntArray, IntArray, FloatArray]:
        """The pool's flat arrays (with unused room at their ends)."""
        return self.off, self.idx, self.val


def _grown(a: np.ndarray, n: int) -> np.ndarray:
    """``a``, or a copy with room for at least ``n`` items (doubling: appends cost O(1))."""
    if len(a) >= n:
        return a
    out = np.empty(max(n, 2 * len(a)), dtype=a.dtype)
    out[:len(a)] = a
    return out


def _pool(sctx: SearchContext) -> _LookPool:
    pool = sctx.memo.get("looks")
    if pool is None:
        pool = sctx.memo["looks"] = _LookPool()
    return pool


def _candidate_track_information(sctx: SearchContext, plan: Plan, i: int, k: int,
                                 headings: FloatArray, tgt: IntArray, w: FloatArray,
                                 memo: dict[str, Any]) -> FloatArray:
    """The tracks' part of Phi ``(A,)`` for each candidate of player (i, k): every other
    look's information plus the candidate's chain over epochs k..K, targets ``tgt (A, L)``
    (-1: none) and information ``w (A, L, e, 2, 2)`` (0 without tracks); ``memo``: the
    plan's :func:`_plan_memo`.

    A candidate changes the terms of the targets its chain looks at only: the other
    players' summed information is shared, each target's term without the chain is computed
    once, and only (candidate, target looked at) pairs run the recursion, from their
    target's covariance before the chain's first look at it (each pair's row is the dense
    computation's row and runs its steps in order, so its term is the same to the bit).
    """
    ctx = sctx.ctx
    A, L = tgt.shape
    if ctx.M == 0:
        return np.zeros(A)
    got = memo.get("track_looks")
    W = (got if got is not None else _plan_track_looks(sctx, plan, headings))[0]
    if BACKEND == "numpy":
        others = plan.targets.copy()
        others[i, k - 1:] = -1
        base = sum_by_target(ctx, W, others)                        # (M, T, 2, 2)
        base_terms = _target_terms(ctx, base, np.arange(ctx.M))
        return pair_terms_numpy(ctx, base, base_terms, tgt, w, k).sum(axis=1)
    arrays = sctx.memo.get("pair_arrays")
    if arrays is None:
        cumulative = ctx.problem.objective == "cumulative"
        ld_ref = ctx.ld_bar[:, 1:].sum(axis=-1) if cumulative else ctx.ld_bar[:, -1]
        arrays = sctx.memo["pair_arrays"] = (
            np.ascontiguousarray(ctx.problem.covs, dtype=float), ctx.F,
            np.ascontiguousarray(ctx.Q, dtype=float), cumulative, *cv_form(ctx.F),
            np.ascontiguousarray(ld_ref), np.ascontiguousarray(ctx.existence, dtype=float))
    # The player's last terms with the same candidate chains: a target's terms depend on its
    # others' information only, and a JSFP iteration's moves change a few targets' of it.
    kept = sctx.memo.setdefault("pair_terms", {})
    prev = kept.get((i, k))
    has = prev is not None and prev[0] is tgt and prev[1] is w
    terms, base = player_pair_terms_nb(
        W, np.ascontiguousarray(plan.targets, dtype=np.int64), int(i), k - 1,
        np.ascontiguousarray(tgt), w, *arrays, has, prev[2] if has else _NO_BASE,
        prev[3] if has else _NO_TERMS)
    kept[(i, k)] = (tgt, w, base, terms)
    return terms.sum(axis=1)


def pair_terms_numpy(ctx: Context, base: FloatArray, base_terms: FloatArray, tgt: IntArray,
                     w: FloatArray, k: int) -> FloatArray:
    """Plain-numpy reference of :func:`~sensorplan.planners._search_nb.pair_terms_nb` (the
    ``numpy`` backend, tests): each target's term ``(A, M)`` for each candidate of player
    (i, k), the chain's targets ``tgt (A, L)`` and information ``w (A, L, e, 2, 2)``."""
    A, L = tgt.shape
    M, e = ctx.M, ctx.e
    a_look, l_look = np.nonzero(tgt >= 0)
    pair, inv = np.unique(a_look * M + tgt[a_look, l_look], return_inverse=True)
    pj = pair % M
    rows = base[pj]                                                  # (P, T, 2, 2) copy
    for l in range(L):
        sel = l_look == l
        for s in range(e):
            rows[inv[sel], (k - 1 + l) * e + s] += w[a_look[sel], l, s]
    terms = np.broadcast_to(base_terms, (A, M)).copy()
    terms[pair // M, pj] = _target_terms(ctx, rows, pj)
    return terms


def _target_terms(ctx: Context, W: FloatArray, j: IntArray) -> FloatArray:
    """Phi's terms ``(P,)`` of targets ``j (P,)`` with summed information ``W (P, T, 2, 2)``."""
    P0 = np.asarray(ctx.problem.covs)[j]
    Q = ctx.Q if ctx.Q.shape[0] == 1 else ctx.Q[j]
    cumulative = ctx.problem.objective == "cumulative"
    _, ld_end, ld_sum = covariance_recursion(np.ascontiguousarray(P0), W, ctx.F,
                                             np.ascontiguousarray(Q), cumulative)
    return phi_terms(ctx.ld_bar[j], ld_end, ld_sum, cumulative, measured(W), ctx.existence[j])


def _plan_track_W(sctx: SearchContext, plan: Plan, headings: FloatArray) -> FloatArray:
    """Every player's track information ``(N, K, e, 2, 2)`` (0 where not a track look)."""
    return _plan_track_looks(sctx, plan, headings)[0]


def _plan_track_looks(sctx: SearchContext, plan: Plan, headings: FloatArray
                      ) -> tuple[FloatArray, IntArray]:
    """:func:`_plan_track_W` and each track look's number of steps that count ``(N, K)``
    (0 elsewhere), kept with the plan."""
    memo = _plan_memo(sctx, plan)
    got = memo.get("track_looks")
    if got is None:
        switch = _from_switch(memo, "track_looks") if BACKEND != "numpy" else None
        if switch is None:
            got = _track_looks(sctx, plan, headings)
        else:
            (W, counts), n = switch
            Wn, cn = _sensor_track(sctx, plan, headings, n)
            W, counts = W.copy(), counts.copy()
            W[n], counts[n] = Wn, cn
            got = (W, counts)
        memo["track_looks"] = got
    return cast("tuple[FloatArray, IntArray]", got)


def _track_looks(sctx: SearchContext, plan: Plan, headings: FloatArray
                 ) -> tuple[FloatArray, IntArray]:
    ctx = sctx.ctx
    N, K = ctx.N, ctx.K
    if BACKEND == "numpy":
        W = np.zeros((N * K, ctx.e, 2, 2))
        counted = np.zeros((N * K, ctx.e), dtype=bool)
        track = plan.targets >= 0
        for n in range(N):
            if track[n].any():
                w, c = chain_information(ctx, n, 1, np.where(track[n][:, None],
                                                             plan.positions[n], 0.0)[None],
                                         np.where(track[n], headings[n], 0.0)[None],
                                         np.maximum(plan.targets[n], 0)[None])
                W[n * K:(n + 1) * K] = np.where(track[n][:, None, None, None], w[0], 0.0)
                counted[n * K:(n + 1) * K] = c[0] & track[n][:, None]
        return W.reshape(N, K, ctx.e, 2, 2), counted.sum(axis=-1).reshape(N, K)
    # By sensor, kept in its part of the plan: a sensor's looks depend on its part only.
    pieces = [_sensor_track(sctx, plan, headings, n) for n in range(N)]
    return (np.concatenate([p[0] for p in pieces]).reshape(N, K, ctx.e, 2, 2),
            np.concatenate([p[1] for p in pieces]).reshape(N, K))


def _sensor_track(sctx: SearchContext, plan: Plan, headings: FloatArray, n: int
                  ) -> tuple[FloatArray, IntArray]:
    """Sensor n's rows of :func:`_track_looks` (compiled), kept in its part of the plan."""
    part = _sensor_parts(sctx, plan)[n]
    got = part.get("track")
    if got is None:
        ctx = sctx.ctx
        K = ctx.K
        Wn = np.zeros((K, ctx.e, 2, 2))
        weight = np.zeros((K, ctx.e))
        look_information_nb(ctx.radar, np.full(K, n), ctx.buildings, ctx.xbar,
                            ctx.Cbar, np.ascontiguousarray(plan.positions[n]),
                            np.ascontiguousarray(headings[n]),
                            np.ascontiguousarray(plan.targets[n]),
                            np.arange(1, K + 1), ctx.probabilistic, Wn, weight)
        got = part["track"] = (Wn, (weight > 0).sum(axis=-1))
    return cast("tuple[FloatArray, IntArray]", got)


def with_action(plan: Plan, i: int, k: int, position: FloatArray, target: int,
                sector: int) -> Plan:
    """``plan`` with player (i, k)'s action replaced."""
    assert plan.sectors is not None
    pos, tgt, sec = plan.positions.copy(), plan.targets.copy(), plan.sectors.copy()
    pos[i, k - 1], tgt[i, k - 1], sec[i, k - 1] = position, target, sector
    return Plan(pos, tgt, sec)


def enumerate_plans(sctx: SearchContext, chains: list[IntArray]
                    ) -> itertools.product:  # type: ignore[type-arg]
    """Every feasible joint plan's per-sensor parts (brute force): for each sensor, its
    chains of positions (``chains[i] (n_i, K)``, indices into ``R_k``, the brute-force
    planner's enumeration) times its look sequences (every target and every sector)."""
    ctx = sctx.ctx
    per_sensor = []
    for i in range(ctx.N):
        lat = ctx.lattices[i]
        looks = [(j, -1) for j in range(ctx.M)] + [(-1, s) for s in
                                                   range(sctx.bearings[i].size)]
        opts = []
        for ch in chains[i]:
            xy = np.stack([lat.positions[kk + 1][ch[kk]] for kk in range(ctx.K)])
            for seq in itertools.product(looks, repeat=ctx.K):
                opts.append((xy, np.array([a for a, _ in seq]), np.array([b for _, b in seq])))
        per_sensor.append(opts)
    return itertools.product(*per_sensor)


def count_plans(sctx: SearchContext, n_chains: list[int]) -> int:
    """The number of joint plans :func:`enumerate_plans` yields (``n_chains[i]``: sensor
    i's number of chains)."""
    n = 1
    for i in range(sctx.ctx.N):
        looks = sctx.ctx.M + sctx.bearings[i].size
        n *= n_chains[i] * looks ** sctx.ctx.K
    return n


def brute_force(sctx: SearchContext, chains: list[IntArray]) -> tuple[Plan, float]:
    """The first joint plan in enumeration order (:func:`enumerate_plans`) within the tie
    tolerance of the best, and its Phi."""
    best: Plan | None = None
    best_phi = -np.inf
    for parts in enumerate_plans(sctx, chains):
        plan = Plan(np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts]),
                    np.stack([p[2] for p in parts]))
        phi = evaluate(sctx, plan).potential
        if best is None or phi > best_phi + TIE_TOL * max(1.0, abs(best_phi)):
            best, best_phi = plan, phi
    assert best is not None
    return best, best_phi


def best_index(u: FloatArray, current: int) -> int:
    """The best action: the current one if within the tie tolerance of the maximum, else
    the first maximum."""
    top = float(u.max())
    floor = top - TIE_TOL * max(1.0, abs(top))
    if current >= 0 and u[current] >= floor:
        return current
    top_ones = u >= floor
    first = int(top_ones.argmax())
    if not top_ones[first]:             # NaN: none (as an empty flatnonzero would say)
        raise IndexError("no action within the tie tolerance of the best")
    return first


def _index_of(pos: FloatArray, tgt: IntArray, sec: IntArray, plan: Plan, i: int,
              k: int) -> int:
    assert plan.sectors is not None
    if not plan.assigned[i, k - 1]:
        return -1
    hit = np.flatnonzero((np.abs(pos - plan.positions[i, k - 1]).max(axis=1)
                          <= POSITION_TOL * 10) & (tgt == plan.targets[i, k - 1])
                         & (sec == plan.sectors[i, k - 1]))
    return int(hit[0]) if hit.size else -1


def sequential_greedy(sctx: SearchContext) -> Plan:
    """For k = 1..K, for i = 0..N-1: the action (track or sector look) maximising Phi with
    search given the earlier choices, the later players unassigned; ties to the first."""
    plan = Plan.empty(sctx.ctx.N, sctx.ctx.K)
    for k in range(1, sctx.ctx.K + 1):
        for i in range(sctx.ctx.N):
            pos, tgt, sec = player_actions(sctx, plan, i, k)
            u = candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
            b = best_index(u, -1)
            plan = _switched(sctx, plan, i, k, pos[b], int(tgt[b]), int(sec[b]))
    return plan


def random_plan(sctx: SearchContext, rng: np.random.Generator) -> Plan:
    """A uniform random feasible plan: each epoch a random move (among those that stay in
    the map) and a random look among the targets and the sensor's sectors."""
    ctx = sctx.ctx
    N, K, M = ctx.N, ctx.K, ctx.M
    positions = np.empty((N, K, 2))
    targets = np.full((N, K), -1, dtype=np.int64)
    sectors = np.full((N, K), -1, dtype=np.int64)
    for i in range(N):
        for k, xy in ctx.lattices[i].random_walk(rng):
            positions[i, k - 1] = xy
            look = int(rng.integers(M + sctx.bearings[i].size))
            if look < M:
                targets[i, k - 1] = look
            else:
                sectors[i, k - 1] = look - M
    return Plan(positions, targets, sectors)


def potential_game(sctx: SearchContext, rng: np.random.Generator, alpha: float, beta: float,
                   max_inner: int, max_outer: int) -> tuple[Plan, bool, int, list[float]]:
    """JSFP with inertia over (sensor, epoch) players with track and sector looks.

    Initialisation: :func:`sequential_greedy` (each player's best response to the earlier
    epochs, the later ones unassigned). Then sweeps over k = K..1 of the epoch games as in
    ``pg`` (running averages, switch with probability ``1 - alpha``, stop with probability
    ``1 - beta`` or after ``max_inner`` iterations) until a sweep changes nothing and every
    epoch game ends at an equilibrium.

    Returns
    -------
    plan, converged, sweeps, trace (Phi after each sweep)
    """
    ctx = sctx.ctx
    N, K = ctx.N, ctx.K
    plan = sequential_greedy(sctx)
    trace: list[float] = []
    for sweep in range(1, max_outer + 1):
        changed, all_eq = False, True
        for k in range(K, 0, -1):
            actions = [player_actions(sctx, plan, i, k) for i in range(N)]
            # The players' running averages end to end (one compiled step for them all).
            off = np.cumsum([0] + [len(a[1]) for a in actions])
            ubar = np.zeros(int(off[-1]))
            # Each player's current action: its index moves with its switches only (a
            # player's actions are distinct).
            cur = [_index_of(*actions[i], plan, i, k) for i in range(N)]
            eq = False
            for t in range(1, max_inner + 1):
                u = np.concatenate([candidate_potentials(sctx, plan, i, k, *actions[i])
                                    for i in range(N)])
                # best_index of u, ubar (t - 1) / t * ubar + u / t, best_index of it.
                now, avg = jsfp_steps_nb(u, ubar, off, t, np.array(cur, dtype=np.int64),
                                         TIE_TOL)
                if (now < 0).any() or (avg < 0).any():
                    raise IndexError("no action within the tie tolerance of the best")
                eq = now.tolist() == cur
                best = avg.tolist()
                if eq:
                    break
                switch = rng.random(N) >= alpha
                for i in range(N):
                    if best[i] != cur[i] and (cur[i] < 0 or switch[i]):
                        pos, tgt, sec = actions[i]
                        b = cur[i] = best[i]
                        plan = _switched(sctx, plan, i, k, pos[b], int(tgt[b]), int(sec[b]))
                        changed = True
                if rng.random() >= beta:
                    break
            all_eq &= eq
        trace.append(evaluate(sctx, plan).potential)
        if not changed and all_eq:
            return plan, True, sweep, trace
    return plan, False, max_outer, trace


__all__ = ["HEADING_TOL", "SearchContext", "SearchEvaluation",
           "brute_force", "candidate_potentials", "count_plans", "distinct_headings", "evaluate",
           "expected_found",
           "first_detection_weight", "plan_headings", "player_actions", "potential",
           "potential_game", "prepare", "random_plan", "sector_actions", "sector_bearings",
           "sequential_greedy"]
