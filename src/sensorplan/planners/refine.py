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
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._types import IntArray
from .anytime import Anytime, BudgetExhausted, complete
from .base import (PlanResult, RngLike, finish, make_rng, refuse_search, register,
                   start_clock)
from .engine import GameState, choose
from .greedy import sequential_greedy
from .information import prepare
from .potential_game import BudgetedLearningSettings, current_index, run_sweeps
from .problem import TIE_TOL, PlanningProblem


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


@register
@dataclass(frozen=True)
class RefinedPlanner(BudgetedLearningSettings):
    """``pg-refine`` (beyond the paper); same settings as ``pg``."""

    name: ClassVar[str] = "pg-refine"
    plans_search: ClassVar[bool] = False          # refuses a searching problem

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        refuse_search(self.name, problem)
        start = start_clock(engine=True)
        gen = make_rng(rng, self.seed)
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
