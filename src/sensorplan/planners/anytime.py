"""Planning on a deadline: a time budget, the best complete plan so far, cheap completions.

A planner with a ``time_budget`` (seconds) reads the clock only at safe points (between
JSFP iterations, player updates or local-search moves, and within an epoch game's set-up and
its longer iterations). At each such *check* it first
offers the plan it holds, when that plan is complete, to an :class:`Anytime` record that
keeps the best complete plan seen (by Phi); then, if the budget is spent, it stops and
returns that best plan. So the plan a planner would return if stopped at a check never has
a lower Phi than the one it would have returned at the previous check.

The first complete plan comes before the first check and fast (:func:`complete` of the
empty plan: every sensor stays where it is and looks, epoch after epoch, at the target that
adds most, sensor by sensor; :func:`hold_chains`), so even a budget far too small for
anything else returns a feasible plan; its ``seconds`` then exceed the budget by the time
that took. Partial plans are completed by :func:`complete` too (a sensor with some actions
gets the moves that connect them to the start, or stays after them, looking at the nearest
assigned epoch's target).

The clock decides only *when* a planner stops, never what it chooses otherwise: every
offered plan is computed whether or not the budget is close. A budgeted run that finishes in
time returns exactly what the same planner returns without a budget (its own final plan);
one that is stopped depends on how fast the machine is.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..limits import Range, param
from .engine import GameState, choose
from .problem import Plan

#: The clock budgets are measured with (tests replace it to stop planners deterministically).
clock: Callable[[], float] = time.perf_counter
#: Called at every check with ``(phi, plan)``: the best complete plan so far and its Phi as
#: the planner sees it, i.e. what it would return if stopped there (a test instrument).
CHECK_HOOK: Callable[[float, Plan], None] | None = None


class BudgetExhausted(Exception):
    """Raised at a check when the time budget is spent (caught by the planner)."""


def budget_param() -> Any:
    """The declaration of a planner's ``time_budget`` (a new field for each planner class)."""
    return param(None, bounds=Range(0.0, None, "s", lo_open=True),
                 help="Seconds the planner may use (None: no limit); when they run out it "
                      "returns the best complete plan found so far.")


class Anytime:
    """The clock of a budgeted planner and the best complete plan it has seen.

    Parameters
    ----------
    budget : float       seconds from ``start``
    start : float        the planner's start (:data:`clock` reading)
    """

    def __init__(self, budget: float, start: float) -> None:
        self.budget = float(budget)
        self.start = start
        self.phi = -math.inf
        self.pos: np.ndarray | None = None
        self.tgt: np.ndarray | None = None
        self._state: GameState | None = None
        self.stopped = False
        self.sweeps = 0                          # progress of the planner, for its result
        self.trace: list[float] = []

    def offer(self, state: GameState, phi: float | None = None) -> None:
        """Keep ``state``'s plan if it is complete and beats the best so far."""
        if not state.complete():
            return
        phi = state.potential() if phi is None else phi
        if phi > self.phi:
            self.phi = phi
            self.pos, self.tgt = state.pos.copy(), state.tgt.copy()
            self._state = state

    def check(self, state: GameState | None = None) -> None:
        """A safe point: offer ``state``, then stop (raise) if the budget is spent."""
        if state is not None:
            self.offer(state)
        if CHECK_HOOK is not None:
            CHECK_HOOK(self.phi, self.best_plan())
        if clock() - self.start >= self.budget:
            self.stopped = True
            raise BudgetExhausted

    def best_plan(self) -> Plan:
        """The best complete plan seen (its actions as lattice indices turned into a Plan)."""
        assert self._state is not None and self.pos is not None and self.tgt is not None
        st = self._state.copy()
        st.pos, st.tgt = self.pos.copy(), self.tgt.copy()
        return st.to_plan()


def hold_chains(state: GameState, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Sensor i's *hold* chains: stay at the start for all K epochs, looking at one target.

    Returns
    -------
    pos : (M, K) int lattice indices (the start position in each ``R_k``)
    tgt : (M, K) int target j in every epoch of chain j
    """
    ctx = state.ctx
    lat = ctx.lattices[i]
    stay = np.empty(ctx.K, dtype=np.int64)
    q = 0
    for k in range(1, ctx.K + 1):
        q = int(lat.child[k][q, 0])                  # move 0 is "stay": always in the map
        stay[k - 1] = q
    M = ctx.M
    return np.tile(stay, (M, 1)), np.repeat(np.arange(M), ctx.K).reshape(M, ctx.K)


def complete(state: GameState) -> GameState:
    """A complete plan from a partial one (a new state; ``state`` is unchanged).

    Each sensor's assigned epochs must be consecutive (as the planners leave them). Before
    them the sensor takes, backwards from its first assigned position, the first parent in
    move order (a path from the start through the reachable sets); after them it stays; the
    added epochs look at the nearest assigned epoch's target. Sensors without any action get
    their best hold chain (:func:`hold_chains`), sensor by sensor in index order.
    """
    st = state.copy()
    ctx = st.ctx
    empty = []
    for i in range(ctx.N):
        ks = np.flatnonzero(st.tgt[i] >= 0)
        if ks.size == 0:
            empty.append(i)
            continue
        if ks.size == ctx.K:
            continue
        a, b = int(ks[0]), int(ks[-1])              # 0-based first and last assigned epoch
        if b - a + 1 != ks.size:
            raise ValueError(f"sensor {i}: assigned epochs are not consecutive")
        lat = ctx.lattices[i]
        for k0 in range(a - 1, -1, -1):             # epoch k0 + 1 precedes epoch k0 + 2
            parents = lat.parent_move[k0 + 2][st.pos[i, k0 + 1]]
            st.pos[i, k0] = int(parents[np.flatnonzero(parents >= 0)[0]])
            st.tgt[i, k0] = st.tgt[i, a]
        for k0 in range(b + 1, ctx.K):
            st.pos[i, k0] = int(lat.child[k0 + 1][st.pos[i, k0 - 1], 0])
            st.tgt[i, k0] = st.tgt[i, b]
        st.refresh(i)
    for i in empty:
        pos, tgt = hold_chains(st, i)
        gains = st.chain_gains(i, 1, pos, tgt)[0]
        best = choose(gains)
        st.set_chain(i, 1, pos[best], tgt[best])
    return st
