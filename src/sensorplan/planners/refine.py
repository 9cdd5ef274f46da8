"""``pg-refine``: the paper's game with several starts and a two-epoch local search.

The paper's players are (sensor, epoch), so its equilibria are only stable against one
epoch's change at a time; where a sensor's positions are tightly chained by its moves they
can be far from the optimum. ``pg-refine`` keeps the game and adds

1. three starts: ``pg`` itself (same generator stream as ``pg`` with the same seed),
   ``sequential-greedy``, and ``pg``'s sweeps continued from the greedy plan; the best is kept;
2. a local search until nothing improves Phi by more than the tolerance: joint changes of one
   sensor's positions in two consecutive epochs (its targets kept), then single-player best
   responses.

Every accepted step raises Phi, so the result is never below ``pg`` or ``sequential-greedy``;
the search ends when no single player can improve, i.e. at a pure Nash equilibrium.

With search on the actions are move x (tracks + sectors) and Phi has the search term; the
same starts and local search run on :mod:`~sensorplan.planners.search`'s evaluation
(:func:`search_local_search`). There ``pg``'s own initialisation is the greedy plan, so the
third start is ``pg`` itself and runs once.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from .._types import FloatArray, IntArray
from ..errors import ConfigError
from .anytime import Anytime, BudgetExhausted, complete
from .base import PlanResult, RngLike, finish, make_rng, register, start_clock
from .engine import GameState, choose
from .greedy import sequential_greedy
from .information import prepare
from .potential_game import BudgetedLearningSettings, current_index, run_sweeps
from .problem import POSITION_TOL, TIE_TOL, Plan, PlanningProblem

if TYPE_CHECKING:  # pragma: no cover
    from .search import SearchContext


def _improves(new: float, old: float, scale: float) -> bool:
    """``new`` beats ``old`` by more than the tolerance ``TIE_TOL max(1, |Phi|)``."""
    return bool(new > old + TIE_TOL * max(1.0, scale))


def pair_moves(state: GameState, i: int, k: int) -> IntArray:
    """Feasible position pairs ``(p_k, p_{k+1})`` of sensor i, other epochs fixed.

    Returns
    -------
    (C, 2) int lattice indices in ``R_k`` and ``R_{k+1}``.
    """
    lat = state.ctx.lattices[i]
    q = 0 if k == 1 else state.pos[i, k - 2]
    first = lat.child[k][q]
    first = first[first >= 0]
    second = lat.child[k + 1][first]                                   # (n_first, n_moves)
    a, m = np.nonzero(second >= 0)
    pairs = np.stack([first[a], second[a, m]], axis=1)
    if k + 2 <= state.ctx.K and state.tgt[i, k + 1] >= 0:
        parents = lat.parent_move[k + 2][state.pos[i, k + 1]]
        pairs = pairs[np.isin(pairs[:, 1], parents[parents >= 0])]
    return pairs


def local_search(state: GameState, max_candidates: int = 2500,
                 anytime: Anytime | None = None) -> int:
    """Improve ``state`` in place until no two-epoch move or single player raises Phi.

    A two-epoch move changes one sensor's positions in epochs k and k+1; when the
    ``pairs x M^2`` candidates fit in ``max_candidates`` its targets in both epochs are chosen
    jointly too, otherwise they are kept (the plain move), which bounds the cost per move.
    With ``anytime`` (a time budget) every move considered is a check.

    Returns the number of rounds.
    """
    ctx = state.ctx
    rounds = 0
    while True:
        rounds += 1
        improved = False
        # Gains are Phi up to a constant per (sensor, epochs) move, and every move's
        # candidates include the current chain, so comparing gains compares Phi.
        scale = abs(state.potential())
        for i in range(ctx.N):
            for k in range(1, ctx.K):
                if anytime is not None:
                    anytime.check(state)
                pairs = pair_moves(state, i, k)
                if len(pairs) * ctx.M**2 <= max_candidates:
                    M = ctx.M
                    tj = np.stack(np.divmod(np.arange(M * M), M), axis=1)     # (M^2, 2)
                    pairs, targets = np.repeat(pairs, M * M, axis=0), np.tile(tj, (len(pairs), 1))
                else:
                    targets = np.ascontiguousarray(
                        np.broadcast_to(state.tgt[i, k - 1:k + 1], pairs.shape))
                gains = state.chain_gains(i, k, pairs, targets)[0]
                cur = np.flatnonzero((pairs == state.pos[i, k - 1:k + 1]).all(axis=1)
                                     & (targets == state.tgt[i, k - 1:k + 1]).all(axis=1))[0]
                best = int(np.argmax(gains))
                if _improves(gains[best], gains[cur], scale):
                    state.set_chain(i, k, pairs[best], targets[best].copy())
                    improved = True
        for k in range(ctx.K, 0, -1):
            for i in range(ctx.N):
                if anytime is not None:
                    anytime.check(state)
                pos, tgt = state.player_actions(i, k)
                gains = state.chain_gains(i, k, pos[:, None], tgt[:, None])[0]
                cur = current_index(state, i, k, pos, tgt)
                best = choose(gains, cur, scale)
                if best != cur and _improves(gains[best], gains[cur], scale):
                    state.set_action(i, k, int(pos[best]), int(tgt[best]))
                    improved = True
        if not improved:
            return rounds


# ------------------------------------------------------------------ with search looks


def _same_position(a: FloatArray, b: FloatArray) -> bool:
    """Two ground positions are one lattice point (the search module's tolerance)."""
    return bool(np.abs(np.asarray(a) - np.asarray(b)).max() <= POSITION_TOL * 10)


def _with_position(plan: Plan, i: int, k: int, position: FloatArray) -> Plan:
    """``plan`` with player (i, k) moved to ``position``, its look kept."""
    from .search import with_action

    assert plan.sectors is not None
    return with_action(plan, i, k, position, int(plan.targets[i, k - 1]),
                       int(plan.sectors[i, k - 1]))


def search_pair_moves(sctx: SearchContext, plan: Plan, i: int, k: int
                      ) -> list[tuple[FloatArray, FloatArray]]:
    """Feasible position pairs ``(p_k, p_{k+1})`` of sensor i in a plan with search looks,
    every other epoch fixed, grouped by ``p_k``.

    Returns
    -------
    list of ``(p, Q)``: p (2,) a position of epoch k one move from ``p_{k-1}`` and Q (n, 2)
    the positions of epoch k+1 one move from p and one move before ``p_{k+2}`` (n > 0; both
    in the search game's order).
    """
    from .search import player_positions, with_action

    # Epoch k+1 left unassigned: epoch k's positions without the constraint of p_{k+1}.
    free = with_action(plan, i, k + 1, np.full(2, np.nan), -1, -1)
    out = []
    for p in player_positions(sctx, free, i, k):
        second = player_positions(sctx, _with_position(plan, i, k, p), i, k + 1)
        if len(second):
            out.append((p, second))
    return out


def _with_current(plan: Plan, i: int, k: int, pos: FloatArray, tgt: IntArray,
                  sec: IntArray) -> tuple[FloatArray, IntArray, IntArray, int]:
    """The candidates with player (i, k)'s current action among them, and its index.

    A sector the heading rule maps to an earlier sector's heading is not among a player's
    actions (it is the same action); after another epoch's change the plan may hold one.
    """
    from .search import _index_of

    assert plan.sectors is not None
    cur = _index_of(pos, tgt, sec, plan, i, k)
    if cur >= 0:
        return pos, tgt, sec, cur
    return (np.concatenate([pos, plan.positions[i, k - 1][None]]),
            np.append(tgt, plan.targets[i, k - 1]), np.append(sec, plan.sectors[i, k - 1]),
            len(tgt))


def _search_pair_move(sctx: SearchContext, plan: Plan, i: int, k: int, scale: float,
                      max_candidates: int) -> Plan | None:
    """The best two-epoch move of sensor i in epochs k, k+1 if it raises Phi by more than
    the tolerance, else None.

    Each epoch keeps its look (track or sector); when the ``pairs x L^2`` candidates (L =
    the tracks plus the sensor's sectors) fit in ``max_candidates`` the two looks are chosen
    jointly too. Phi of a candidate is :func:`~sensorplan.planners.search.candidate_potentials`
    of epoch k+1's action in the plan whose epoch k holds the candidate's: one call per
    ``(p_k, look)``, batched over epoch k+1's candidates.
    """
    from .search import candidate_potentials, player_actions, with_action

    assert plan.sectors is not None
    groups = search_pair_moves(sctx, plan, i, k)
    n_looks = sctx.ctx.M + sctx.bearings[i].size
    joint = sum(len(Q) for _, Q in groups) * n_looks**2 <= max_candidates
    now = (int(plan.targets[i, k - 1]), int(plan.sectors[i, k - 1]))
    nxt = (int(plan.targets[i, k]), int(plan.sectors[i, k]))
    looks = [now]
    if joint:
        # Epoch k's distinct looks: those of its first position (a player's actions are its
        # positions times the same looks), and the current one.
        _, tgt, sec = player_actions(sctx, plan, i, k)
        n = sctx.ctx.M + len(np.unique(sec[sec >= 0]))
        looks = [(int(t), int(s)) for t, s in zip(tgt[:n], sec[:n])]
        if now not in looks:
            looks.append(now)
    current = -np.inf
    best_value, best = -np.inf, None
    for p, Q in groups:
        here = _same_position(p, plan.positions[i, k - 1])
        for look in looks:
            trial = with_action(plan, i, k, p, *look)
            if joint:
                pos, tgt, sec = player_actions(sctx, trial, i, k + 1)
            else:
                pos, tgt, sec = Q, np.full(len(Q), nxt[0]), np.full(len(Q), nxt[1])
            cur = -1
            if here and look == now:
                pos, tgt, sec, cur = _with_current(plan, i, k + 1, pos, tgt, sec)
            u = candidate_potentials(sctx, trial, i, k + 1, pos, tgt, sec)
            if cur >= 0:
                current = float(u[cur])
            a = int(np.argmax(u))                    # the first maximum of the group
            if u[a] > best_value:
                best_value, best = float(u[a]), (p, look, pos[a], int(tgt[a]), int(sec[a]))
    # The current pair is always a candidate (the plan is feasible); were it missing,
    # no move is safer than a comparison with nothing.
    if best is None or current == -np.inf or not _improves(best_value, current, scale):
        return None
    p, look, q, t, s = best
    return with_action(with_action(plan, i, k, p, *look), i, k + 1, q, t, s)


def search_local_search(sctx: SearchContext, plan: Plan, max_candidates: int = 2500
                        ) -> tuple[Plan, int]:
    """:func:`local_search` for a plan with search looks: two-epoch moves of one sensor,
    then single-player best responses over move x (tracks + sectors), until nothing raises
    Phi with search by more than the tolerance.

    Returns
    -------
    plan : Plan     a pure Nash equilibrium of the search game
    rounds : int
    """
    from .search import candidate_potentials, evaluate, player_actions, with_action

    ctx = sctx.ctx
    rounds = 0
    while True:
        rounds += 1
        improved = False
        scale = abs(evaluate(sctx, plan).potential)
        for i in range(ctx.N):
            for k in range(1, ctx.K):
                moved = _search_pair_move(sctx, plan, i, k, scale, max_candidates)
                if moved is not None:
                    plan, improved = moved, True
        for k in range(ctx.K, 0, -1):
            for i in range(ctx.N):
                pos, tgt, sec, cur = _with_current(plan, i, k, *player_actions(sctx, plan, i, k))
                u = candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
                best = int(np.argmax(u))
                if _improves(u[best], u[cur], scale):
                    plan = with_action(plan, i, k, pos[best], int(tgt[best]), int(sec[best]))
                    improved = True
        if not improved:
            return plan, rounds


@register
@dataclass(frozen=True)
class RefinedPlanner(BudgetedLearningSettings):
    """``pg-refine`` (beyond the paper); same settings as ``pg``."""

    name: ClassVar[str] = "pg-refine"
    plans_search: ClassVar[bool] = True

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock(engine=True)
        gen = make_rng(rng, self.seed)
        if problem.searching:
            return self._refine_search(problem, gen, start)
        gen_pg = copy.deepcopy(gen)       # pg's own stream: start 1 is exactly `pg`'s plan
        ctx = prepare(problem)
        anytime = None
        if self.time_budget is not None:
            anytime = Anytime(self.time_budget, start)
            anytime.offer(complete(GameState(ctx)))    # the first complete plan, fast
        try:
            return self._refine(ctx, gen, gen_pg, start, anytime)
        except BudgetExhausted:
            assert anytime is not None
            return finish(self.name, ctx, anytime.best_plan(), start, False, anytime.sweeps,
                          tuple(anytime.trace), budget_exhausted=True)

    def _refine(self, ctx, gen: np.random.Generator, gen_pg: np.random.Generator,
                start: float, anytime: Anytime | None) -> PlanResult:
        settings = self.learning
        # The greedy start first: it is deterministic and fast, so a budgeted run holds a
        # good plan early (the order of the starts does not change the result).
        greedy_state = sequential_greedy(ctx, anytime)
        if anytime is not None:
            anytime.offer(greedy_state)
        pg_state = GameState(ctx)
        _, sweeps_pg, trace = run_sweeps(pg_state, gen_pg, *settings, anytime=anytime)
        if anytime is not None:
            anytime.offer(pg_state)
        continued = greedy_state.copy()
        _, sweeps_cont, trace_cont = run_sweeps(continued, gen, *settings, anytime=anytime)
        if anytime is not None:
            anytime.offer(continued)
        starts = [pg_state, greedy_state, continued]
        values = [s.potential() for s in starts]
        best = starts[int(np.argmax(values))]
        rounds = local_search(best, anytime=anytime)
        trace_all = tuple(trace) + tuple(trace_cont) + (best.potential(),)
        return finish(self.name, ctx, best.to_plan(), start, True,
                      sweeps_pg + sweeps_cont + rounds, trace_all)

    def _refine_search(self, problem: PlanningProblem, gen: np.random.Generator,
                       start: float) -> PlanResult:
        """The starts and the local search with track and sector looks (plain numpy, as
        ``pg``'s search game; no time budget yet)."""
        from . import search

        if self.time_budget is not None:
            raise ConfigError("planner.time_budget", "pg-refine with search has no time "
                              "budget yet; leave it unset")
        sctx = search.prepare(problem)
        # pg's initialisation is the greedy plan: pg's sweeps continued from it are pg.
        pg_plan, _, sweeps, trace = search.potential_game(sctx, gen, *self.learning)
        starts = [pg_plan, search.sequential_greedy(sctx)]
        values = [search.evaluate(sctx, p).potential for p in starts]
        plan, rounds = search_local_search(sctx, starts[int(np.argmax(values))])
        trace_all = tuple(trace) + (search.evaluate(sctx, plan).potential,)
        return finish(self.name, sctx, plan, start, True, sweeps + rounds, trace_all)
