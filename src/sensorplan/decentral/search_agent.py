"""An agent whose decision searches: the same schedules over track and sector looks.

With search on a player's action is a move and a look at a track or at one of its
platform's sectors, and Phi adds the value of search (the expected number of undetected
targets the joint plan finds, :mod:`sensorplan.planners.search`). The other platforms'
looks thin the same undetected intensity, so a player's utility depends on the sector looks
and positions of everyone: an agent takes them from the plans it hears, as it takes their
track looks. Every agent holds the same intensity grid, because it is part of the decision's
problem, as the tracks are.

Every utility is :func:`sensorplan.planners.search.candidate_potentials` against the belief
(Phi of each action, the others fixed) and every choice :func:`~sensorplan.planners.search.
best_index`, the calls the centralized ``pg`` with search makes; so with perfect links the
agents follow it exactly:

``jsfp``
    ``pg`` with search starts from sequential greedy (for k = 1..K, for i = 0..N-1, the
    action maximising Phi given the earlier choices). The agents play it in N K rounds:
    round ``(k - 1) N + i + 1`` is player (i, k)'s turn, against the plans heard so far.
    Then come the sweeps k = K..1 of JSFP with inertia, one iteration per round, exactly as
    :class:`~sensorplan.decentral.agent.Agent` plays them; an epoch game counts as changed
    when any player switched in it (``pg`` with search's rule).
``best-response`` and filling in alone
    An agent's players respond k = 1..K (a search player's moves start from its previous
    epoch's position, so the earlier epochs go first).
``sequential``
    Unchanged: in its turn an agent takes, for k = 1..K, the action maximising Phi.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..planners import search
from ..planners.problem import POSITION_TOL, Plan
from ..planners.search import SearchContext
from .agent import Agent, AgentSpec, _same
from .messages import Message


class SearchView:
    """A searching agent's belief: every platform's positions, targets and sectors.

    Attributes
    ----------
    pos : (N, K, 2) float   ground positions (m); NaN where unassigned
    tgt : (N, K) int        targets; -1 where unassigned or a sector look
    sec : (N, K) int        sectors; -1 where unassigned or a track look
    """

    def __init__(self, sctx: SearchContext) -> None:
        N, K = sctx.ctx.N, sctx.ctx.K
        self.sctx = sctx
        self.pos = np.full((N, K, 2), np.nan)
        self.tgt = np.full((N, K), -1, dtype=np.int64)
        self.sec = np.full((N, K), -1, dtype=np.int64)
        self.version = 0
        self._phi: tuple[int, float] | None = None

    def plan(self) -> Plan:
        return Plan(self.pos.copy(), self.tgt.copy(), self.sec.copy())

    def set(self, j: int, pos: np.ndarray, tgt: np.ndarray, sec: np.ndarray,
            k: int | None = None) -> None:
        """Set platform j's plan (``k``: only its epoch k's action)."""
        at = slice(None) if k is None else k - 1
        self.pos[j, at], self.tgt[j, at], self.sec[j, at] = pos, tgt, sec
        self.version += 1

    def same(self, j: int, pos: np.ndarray, tgt: np.ndarray, sec: np.ndarray) -> bool:
        return bool(np.array_equal(self.pos[j], pos, equal_nan=True)
                    and np.array_equal(self.tgt[j], tgt) and np.array_equal(self.sec[j], sec))

    def potential(self) -> float:
        """Phi with search of the believed (possibly partial) plan."""
        if self._phi is None or self._phi[0] != self.version:
            self._phi = (self.version, search.evaluate(self.sctx, self.plan()).potential)
        return self._phi[1]


class SearchAgent(Agent):
    """Agent ``index`` of a searching decision (same protocol as :class:`Agent`).

    Parameters
    ----------
    sctx : SearchContext          the decision, identical for every agent
                                  (:func:`sensorplan.planners.search.prepare`)
    index, spec, gen, decision, failed : as :class:`Agent`
    """

    view: SearchView            # type: ignore[assignment]

    def __init__(self, sctx: SearchContext, index: int, spec: AgentSpec,
                 gen: np.random.Generator, decision: int = 0,
                 failed: tuple[int, ...] = ()) -> None:
        self.sctx = sctx
        super().__init__(sctx.ctx, index, spec, gen, decision, failed)

    def _new_view(self) -> SearchView:  # type: ignore[override]
        return SearchView(self.sctx)

    # ------------------------------------------------------------------ schedule
    def _start_game(self) -> None:
        """Sweep 0 is the sequential greedy start (N K rounds); the sweeps follow."""
        self.sweep, self.k, self.t = 0, 1, 0
        self.changed, self.all_eq = False, True
        self.sweeps = 0

    def step(self, rnd: int) -> Message:
        if self.spec.mode == "jsfp" and not self.settled and self.sweep == 0:
            k, turn = divmod(rnd - 1, self.N)
            self.k = k + 1
            if turn == self.i:
                self._greedy(k + 1)
            return self._message(rnd, best=False)
        return super().step(rnd)

    def end_round(self, rnd: int, delivered: list[Message]) -> None:
        super().end_round(rnd, delivered)
        if self.spec.mode == "jsfp" and self.sweep == 0 and rnd == self.N * self.K:
            self.sweep, self.k, self.t, self.sweeps = 1, self.K, 1, 1
            self._start_epoch()

    def _switched(self) -> None:
        self.changed |= not _same(self._round_start, self._column(self.k))

    def _greedy(self, k: int) -> None:
        """Player (i, k) takes the action maximising Phi given its belief (ties: first)."""
        actions = self._actions(k)
        self._apply(k, actions, search.best_index(self._utilities(k, actions), -1))

    def _greedy_turn(self) -> None:
        for k in range(1, self.K + 1):
            self._greedy(k)

    # ------------------------------------------------------------------ actions
    def _response_order(self) -> range:
        return range(1, self.K + 1)

    def _assigned(self, k: int) -> bool:
        return bool(self.view.tgt[self.i, k - 1] >= 0 or self.view.sec[self.i, k - 1] >= 0)

    def _actions(self, k: int) -> tuple[np.ndarray, ...]:
        return search.player_actions(self.sctx, self.view.plan(), self.i, k)

    def _utilities(self, k: int, actions: tuple[np.ndarray, ...]) -> np.ndarray:
        """Phi with search of every action of player (i, k), the belief otherwise fixed."""
        pos, tgt, sec = actions
        return search.candidate_potentials(self.sctx, self.view.plan(), self.i, k, pos, tgt,
                                           sec)

    def _current(self, k: int, actions: tuple[np.ndarray, ...]) -> int:
        if not self._assigned(k):
            return -1
        pos, tgt, sec = actions
        v, i = self.view, self.i
        hit = np.flatnonzero((np.abs(pos - v.pos[i, k - 1]).max(axis=1) <= POSITION_TOL * 10)
                             & (tgt == v.tgt[i, k - 1]) & (sec == v.sec[i, k - 1]))
        return int(hit[0]) if hit.size else -1

    def _is_best(self, u: np.ndarray, cur: int) -> bool:
        return cur >= 0 and search.best_index(u, cur) == cur

    def _choose(self, values: np.ndarray, cur: int) -> int:
        return search.best_index(values, cur)

    def _cond(self, actions: tuple[np.ndarray, ...], idx: int) -> tuple[Any, ...]:
        pos, tgt, sec = actions
        return float(pos[idx, 0]), float(pos[idx, 1]), int(tgt[idx]), int(sec[idx])

    def _apply(self, k: int, actions: tuple[np.ndarray, ...], idx: int) -> None:
        pos, tgt, sec = actions
        self.view.set(self.i, pos[idx], tgt[idx], sec[idx], k)

    def _column(self, k: int) -> tuple[np.ndarray, ...]:
        v = self.view
        return v.pos[:, k - 1].copy(), v.tgt[:, k - 1].copy(), v.sec[:, k - 1].copy()

    def _peer_from(self, m: Message, equilibrium: bool) -> None:
        pos, tgt, sec = m.looks_after(equilibrium)
        if not self.view.same(m.sender, pos, tgt, sec):
            self.view.set(m.sender, pos, tgt, sec)

    def _clear_peer(self, j: int) -> None:
        self.view.set(j, np.full((self.K, 2), np.nan), np.full(self.K, -1),
                      np.full(self.K, -1))

    def _message(self, rnd: int, best: bool, cond: tuple[Any, ...] | None = None) -> Message:
        jsfp = self.spec.mode == "jsfp"
        v, i = self.view, self.i
        return Message(self.decision, rnd, i, self.sweep if jsfp else 0,
                       self.k if jsfp else 0, self.t if jsfp else 0, self.settled, best,
                       v.pos[i].copy(), v.tgt[i].copy(), cond, v.sec[i].copy())

    # ------------------------------------------------------------------ results
    def sectors(self) -> tuple[np.ndarray, np.ndarray]:
        return self.view.sec[self.i].copy(), self.view.sec.copy()


__all__ = ["SearchAgent", "SearchView"]
