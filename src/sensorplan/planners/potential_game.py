"""The paper's planner (Algorithm 1): JSFP with inertia over (sensor, epoch) players.

Sweeps run over epochs k = K, K-1, ..., 1. The first sweep is the initialisation (the paper's
dynamic-programming-like pass): every player starts unassigned, so player (i, K) chooses within
the K-step reachable region, then (i, K-1) given the choices at K, and so on. Each epoch's
players then play joint strategy fictitious play with inertia, everyone else fixed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._types import FloatArray, IntArray
from ..errors import ConfigError
from ..limits import Range, param
from .anytime import Anytime, BudgetExhausted, budget_param, complete
from .base import PlanResult, RngLike, finish, make_rng, register, start_clock
from .engine import GameState
from .epoch_game import EpochGame
from .information import prepare
from .problem import PlanningProblem
from .registry import PlannerSettings, seed_param


@dataclass
class EpochState:
    """One JSFP iteration of an epoch game (yielded by :func:`jsfp_epoch` for inspection).

    Attributes
    ----------
    iteration : int                     t, from 1
    utilities : list of (A_i,) arrays   each player's utility of every action now (its
                                        marginal contribution: Phi up to a constant)
    averages : list of (A_i,) arrays    running averages ubar after this iteration
    equilibrium : bool                  current actions are a pure Nash equilibrium
    """

    iteration: int
    utilities: list[FloatArray]
    averages: list[FloatArray]
    equilibrium: bool


def player_utilities(state: GameState, i: int, k: int) -> tuple[IntArray, IntArray, FloatArray]:
    """All feasible actions of player (i, k) and Phi for each (others fixed), one batch."""
    pos, tgt = state.player_actions(i, k)
    return pos, tgt, state.evaluate_chains(i, k, pos[:, None], tgt[:, None])


def current_index(state: GameState, i: int, k: int, pos: IntArray, tgt: IntArray) -> int:
    """Index of player (i, k)'s current action among ``pos, tgt`` (-1 if unassigned)."""
    if state.tgt[i, k - 1] < 0:
        return -1
    hit = np.flatnonzero((pos == state.pos[i, k - 1]) & (tgt == state.tgt[i, k - 1]))
    return int(hit[0]) if hit.size else -1


def jsfp_epoch(state: GameState, k: int, rng: np.random.Generator, alpha: float, beta: float,
               max_inner: int, check: Callable[[], None] | None = None
               ) -> Iterator[EpochState]:
    """JSFP with inertia among players (i, k), i = 0..N-1 (mutates ``state``).

    Each iteration every player computes its utility of every feasible action against the
    others' current actions; if the current actions are a pure Nash equilibrium of the epoch
    game the loop ends. Otherwise ``ubar = (t-1)/t ubar + u/t``, the best response is
    ``argmax ubar`` (tie rule) and each player switches to it with probability
    ``1 - alpha`` (an unassigned player always does); then the loop ends with probability
    ``1 - beta``, or after ``max_inner`` iterations.

    Actions whose looks never count are left out (see :class:`EpochGame`): they have
    utility 0 whatever the others do and only the first of them can ever be chosen.
    ``check`` (a time budget's) is called between the players' preparations.
    """
    N = state.ctx.N
    game = EpochGame(state, k, check)
    cur = game.cur
    ubar = np.zeros(game.cand_off[-1])
    try:
        for t in range(1, max_inner + 1):
            # Utilities are marginal contributions: Phi up to a term the player cannot change.
            u, eq, ubar, best = game.iteration(ubar, t, abs(state.potential()))
            yield EpochState(t, game.split(u), game.split(ubar), eq)
            if eq:
                return
            switch = rng.random(N) >= alpha                 # switch w.p. 1 - alpha (inertia)
            for i in range(N):
                if best[i] != cur[i] and (cur[i] < 0 or switch[i]):
                    pos, tgt = game.actions[i]
                    state.set_action(i, k, int(pos[best[i]]), int(tgt[best[i]]))
                    cur[i] = best[i]           # only this loop changes epoch k's actions
            if rng.random() >= beta:                        # stop w.p. 1 - beta
                return
    finally:
        game.close()


def run_sweeps(state: GameState, rng: np.random.Generator, alpha: float, beta: float,
               max_inner: int, max_outer: int,
               anytime: Anytime | None = None) -> tuple[bool, int, list[float]]:
    """Outer sweeps k = K..1 until a sweep changes nothing and ends at equilibria.

    With ``anytime`` (a time budget), every JSFP iteration is a check (the current plan is
    offered when complete); in the first sweep the partial plan's completion is offered
    after iterations 1, 2, 4, 8, ... and at the end of each epoch game;
    ``anytime.sweeps``/``anytime.trace`` follow the progress. Stopping raises
    :class:`~sensorplan.planners.anytime.BudgetExhausted`.

    Returns
    -------
    converged : bool   the final plan is a pure Nash equilibrium of the full game
    sweeps : int
    trace : Phi after each sweep
    """
    K = state.ctx.K
    trace: list[float] = []
    for sweep in range(1, max_outer + 1):
        changed, all_eq = False, True
        if anytime is not None:
            anytime.sweeps += 1
        for k in range(K, 0, -1):
            before = (state.pos[:, k - 1].copy(), state.tgt[:, k - 1].copy())
            last = None
            check = None
            if anytime is not None:
                anytime.check(state)
                check = anytime.check
            for last in jsfp_epoch(state, k, rng, alpha, beta, max_inner, check):
                if anytime is not None:
                    t = last.iteration
                    if t > 1 and (t - 1) & (t - 2) == 0 and not state.complete():
                        # First sweep: offer the completed partial plan after iterations
                        # 1, 2, 4, 8, ... of each epoch game (a few completions per game).
                        anytime.offer(complete(state))
                    anytime.check(state)
            if anytime is not None and not state.complete():
                anytime.offer(complete(state))
            # A loop that ended by chance or by max_inner may still sit at an equilibrium
            # reached by its last switch; only a verified equilibrium counts.
            all_eq &= last is not None and last.equilibrium
            changed |= bool(np.any(before[0] != state.pos[:, k - 1])
                            or np.any(before[1] != state.tgt[:, k - 1]))
        trace.append(state.potential())
        if anytime is not None:
            anytime.trace.append(trace[-1])
        if not changed and all_eq:
            return True, sweep, trace
    return False, max_outer, trace


#: Probabilities of the learning that must leave both outcomes possible.
_OPEN_PROBABILITY = Range(0.0, 1.0, lo_open=True, hi_open=True)


@dataclass(frozen=True)
class LearningSettings(PlannerSettings):
    """Settings of the paper's learning algorithm, shared by ``pg``, ``pg-refine`` and the
    decentralized game (each declared once, with its rule).

    Attributes
    ----------
    alpha : float      inertia: probability of keeping the current action, in (0, 1)
    beta : float       probability that an inner loop continues after an iteration, in (0, 1)
    max_inner, max_outer : int   iterations of an epoch game, sweeps (>= 1)
    seed : int or None used when ``plan`` gets no ``rng``
    """

    alpha: float = param(0.3, bounds=_OPEN_PROBABILITY,
                         help="Inertia: the probability that a player keeps its action.")
    beta: float = param(0.95, bounds=_OPEN_PROBABILITY,
                        help="The probability that an epoch game goes on after an iteration.")
    max_inner: int = param(50, bounds=Range(1, None),
                           help="Most iterations of an epoch game.")
    max_outer: int = param(10, bounds=Range(1, None), help="Most sweeps over the epochs.")
    seed: int | None = seed_param()

    @property
    def learning(self) -> tuple[float, float, int, int]:
        return self.alpha, self.beta, self.max_inner, self.max_outer


@dataclass(frozen=True)
class BudgetedLearningSettings(LearningSettings):
    """:class:`LearningSettings` plus a time budget (``pg`` and ``pg-refine``).

    Attributes
    ----------
    time_budget : float or None
        Seconds the planner may use (None: no limit). When they run out it returns the best
        complete plan found so far (``converged`` False, ``budget_exhausted`` True); see
        :mod:`sensorplan.planners.anytime`. A budget makes a stopped run's result depend on
        the machine's speed; without one, or if the run ends in time, the result is the
        same as without a budget.
    """

    time_budget: float | None = budget_param()


@register
@dataclass(frozen=True)
class PotentialGamePlanner(BudgetedLearningSettings):
    """``pg``: the paper's Algorithm 1. Myopic planning is ``pg`` with K = 1."""

    name: ClassVar[str] = "pg"
    plans_search: ClassVar[bool] = True

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock(engine=True)
        gen = make_rng(rng, self.seed)
        if problem.searching:
            # Track and sector looks: the plain-numpy game (no time budget yet).
            from . import search

            if self.time_budget is not None:
                raise ConfigError("planner.time_budget", "pg with search has no time "
                                  "budget yet; leave it unset")
            sctx = search.prepare(problem)
            plan, converged, sweeps, trace = search.potential_game(sctx, gen, *self.learning)
            return finish(self.name, sctx, plan, start, converged, sweeps, tuple(trace))
        ctx = prepare(problem)
        state = GameState(ctx)
        if self.time_budget is None:
            converged, sweeps, trace = run_sweeps(state, gen, *self.learning)
            return finish(self.name, ctx, state.to_plan(), start, converged, sweeps,
                          tuple(trace))
        anytime = Anytime(self.time_budget, start)
        anytime.offer(complete(state))                 # the first complete plan, fast
        try:
            converged, sweeps, trace = run_sweeps(state, gen, *self.learning, anytime=anytime)
        except BudgetExhausted:
            return finish(self.name, ctx, anytime.best_plan(), start, False, anytime.sweeps,
                          tuple(anytime.trace), budget_exhausted=True)
        return finish(self.name, ctx, state.to_plan(), start, converged, sweeps, tuple(trace))
