"""The ``sequential-greedy`` baseline."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .anytime import Anytime, BudgetExhausted, budget_param, complete
from ..errors import ConfigError
from .base import PlanResult, RngLike, finish, register, start_clock
from .engine import GameState, choose
from .information import Context, prepare
from .problem import PlanningProblem
from .registry import PlannerSettings, seed_param


def sequential_greedy(ctx: Context, anytime: Anytime | None = None) -> GameState:
    """For k = 1..K, for i = 0..N-1: the action maximising Phi given the earlier choices.

    With ``anytime`` (a time budget) every player update is a check, and after each epoch
    the plan completed by staying is offered; stopping raises
    :class:`~sensorplan.planners.anytime.BudgetExhausted`.
    """
    state = GameState(ctx)
    for k in range(1, ctx.K + 1):
        for i in range(ctx.N):
            if anytime is not None:
                anytime.check()
            pos, tgt = state.player_actions(i, k)
            phi = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
            best = choose(phi)
            state.set_action(i, k, int(pos[best]), int(tgt[best]))
        if anytime is not None and k < ctx.K:
            anytime.offer(complete(state))
    return state


@register
@dataclass(frozen=True)
class SequentialGreedyPlanner(PlannerSettings):
    """Sensor by sensor, epoch by epoch, the best action given the earlier ones.

    Deterministic; ``seed`` is accepted for a uniform interface and unused. ``time_budget``
    (seconds, None for no limit): when it runs out the planner returns the best complete
    plan found so far (``converged`` False, ``budget_exhausted`` True; see
    :mod:`sensorplan.planners.anytime`).
    """

    name: ClassVar[str] = "sequential-greedy"
    plans_search: ClassVar[bool] = True
    seed: int | None = seed_param()
    time_budget: float | None = budget_param()

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock(engine=True)
        if problem.searching:
            from . import search

            if self.time_budget is not None:
                raise ConfigError("planner.time_budget", "sequential-greedy with search has "
                                  "no time budget yet; leave it unset")

            sctx = search.prepare(problem)
            return finish(self.name, sctx, search.sequential_greedy(sctx), start)
        ctx = prepare(problem)
        if self.time_budget is None:
            return finish(self.name, ctx, sequential_greedy(ctx).to_plan(), start)
        anytime = Anytime(self.time_budget, start)
        anytime.offer(complete(GameState(ctx)))        # the first complete plan, fast
        try:
            state = sequential_greedy(ctx, anytime)
        except BudgetExhausted:
            return finish(self.name, ctx, anytime.best_plan(), start, False,
                          budget_exhausted=True)
        return finish(self.name, ctx, state.to_plan(), start)
