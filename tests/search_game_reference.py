"""The search game's loop as it was before its utilities were kept per player (commit
184dc47): every player's utilities asked for in every iteration, each player's current
action searched for among its actions each iteration. The tests run ``pg`` with this loop
and the plain-numpy utilities of ``tests/search_reference.py`` in place of
:func:`sensorplan.planners.search.potential_game` and
:func:`sensorplan.planners.search.candidate_potentials`, and require the same plans
(``tests/planners/test_search_compiled.py``).
"""

from __future__ import annotations

import numpy as np

from sensorplan.planners import search
from sensorplan.planners.problem import Plan
from sensorplan.planners.search import SearchContext


def potential_game(sctx: SearchContext, rng: np.random.Generator, alpha: float, beta: float,
                   max_inner: int, max_outer: int) -> tuple[Plan, bool, int, list[float]]:
    """:func:`sensorplan.planners.search.potential_game`'s contract, the loop before."""
    ctx = sctx.ctx
    N, K = ctx.N, ctx.K
    plan = search.sequential_greedy(sctx)
    trace: list[float] = []
    for sweep in range(1, max_outer + 1):
        changed, all_eq = False, True
        for k in range(K, 0, -1):
            actions = [search.player_actions(sctx, plan, i, k) for i in range(N)]
            ubar = [np.zeros(len(a[1])) for a in actions]
            eq = False
            for t in range(1, max_inner + 1):
                cur = [search._index_of(*actions[i], plan, i, k) for i in range(N)]
                best = []
                eq = True
                for i in range(N):
                    u = search.candidate_potentials(sctx, plan, i, k, *actions[i])
                    eq &= search.best_index(u, cur[i]) == cur[i]
                    ubar[i] = (t - 1) / t * ubar[i] + u / t
                    best.append(search.best_index(ubar[i], cur[i]))
                if eq:
                    break
                switch = rng.random(N) >= alpha
                for i in range(N):
                    if best[i] != cur[i] and (cur[i] < 0 or switch[i]):
                        pos, tgt, sec = actions[i]
                        b = best[i]
                        plan = search.with_action(plan, i, k, pos[b], int(tgt[b]), int(sec[b]))
                        changed = True
                if rng.random() >= beta:
                    break
            all_eq &= eq
        trace.append(search.evaluate(sctx, plan).potential)
        if not changed and all_eq:
            return plan, True, sweep, trace
    return plan, False, max_outer, trace
