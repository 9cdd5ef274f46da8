"""The ``random`` baseline: a uniformly random feasible move and target, epoch by epoch."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import PlanResult, RngLike, finish, make_rng, register, start_clock
from .information import prepare
from .problem import Plan, PlanningProblem
from .registry import PlannerSettings, seed_param


@register
@dataclass(frozen=True)
class RandomPlanner(PlannerSettings):
    """Uniform random feasible plan (a baseline), seeded."""

    name: ClassVar[str] = "random"
    plans_search: ClassVar[bool] = True
    seed: int | None = seed_param()

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock()
        gen = make_rng(rng, self.seed)
        if problem.searching:
            from . import search

            sctx = search.prepare(problem)
            return finish(self.name, sctx, search.random_plan(sctx, gen), start)
        ctx = prepare(problem)
        N, K = problem.n_sensors, problem.horizon
        positions = np.empty((N, K, 2))
        targets = np.empty((N, K), dtype=np.int64)
        for i in range(N):
            for k, xy in ctx.lattices[i].random_walk(gen):
                positions[i, k - 1] = xy
                targets[i, k - 1] = gen.integers(problem.n_targets)
        return finish(self.name, ctx, Plan(positions, targets), start)
