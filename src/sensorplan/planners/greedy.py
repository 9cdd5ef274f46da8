"""The ``sequential-greedy`` baseline (SPEC 4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..information import Context, prepare
from ..problem import PlanningProblem
from .base import PlanResult, RngLike, finish, register, start_clock
from .engine import GameState, choose


def sequential_greedy(ctx: Context) -> GameState:
    """For k = 1..K, for i = 0..N-1: the action maximising Phi given the earlier choices."""
    state = GameState(ctx)
    for k in range(1, ctx.K + 1):
        for i in range(ctx.N):
            pos, tgt = state.player_actions(i, k)
            phi = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
            best = choose(phi)
            state.set_action(i, k, int(pos[best]), int(tgt[best]))
    return state


@register
@dataclass(frozen=True)
class SequentialGreedyPlanner:
    """Sensor by sensor, epoch by epoch, the best action given the earlier ones.

    Deterministic; ``seed`` is accepted for a uniform interface and unused.
    """

    name: ClassVar[str] = "sequential-greedy"
    seed: int | None = 0

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock()
        ctx = prepare(problem)
        return finish(self.name, ctx, sequential_greedy(ctx).to_plan(), start)
