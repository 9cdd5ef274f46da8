"""One platform's agent: a transport-agnostic state machine over its K players.

An agent believes a joint plan (:class:`~sensorplan.planners.engine.GameState`): its own
players exactly, every other platform's players as last heard. A decision is a sequence of
rounds; in round r the driver calls :meth:`Agent.step` (compute, return the message to
send), hands the messages that arrived to :meth:`Agent.end_round`, and after the last round
calls :meth:`Agent.complete`. Nothing here knows how messages travel.

Modes
-----
``jsfp``
    The paper's schedule (sweeps k = K..1, an epoch game of JSFP with inertia in each),
    played in lockstep: one JSFP iteration per round. Each round an agent computes its
    player's utilities against its belief, says whether that player is at a best response,
    and announces the action it will take unless the round turns out to be an equilibrium
    (its switch decided by its own entry of the shared ``rng.random(N)`` vector). At the end
    of the round every agent that heard all its peers' fresh announcements at the same
    schedule position knows whether the epoch game is at an equilibrium, applies the
    announced switches, and draws the shared beta coin, exactly as the centralized planner.
``best-response``
    Each round an agent best-responds with every one of its players (k = K..1) to its
    belief; no inertia, no averaging.
``sequential``
    Round r is agent r - 1's turn: for k = 1..K it takes the action maximising Phi given
    what it has heard (sequential greedy, platform by platform).

A decision whose problem searches is played by :class:`~sensorplan.decentral.search_agent.
SearchAgent`, the same schedule over track and sector looks
(:func:`sensorplan.decentral.decision.make_agent` picks).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..planners.engine import GameState, choose
from ..planners.information import Context
from ..planners.potential_game import current_index
from ..planners.problem import TIE_TOL
from .messages import Message


def is_best(u: np.ndarray, cur: int, scale: float) -> bool:
    """Whether action ``cur`` is a best response to utilities ``u`` within the tie tolerance."""
    return cur >= 0 and bool(u.max() <= u[cur] + TIE_TOL * max(1.0, scale))

MODES = ("jsfp", "best-response", "sequential")


def _same(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> bool:
    """Whether two snapshots of a belief's column are equal (NaN positions included)."""
    return all(np.array_equal(x, y, equal_nan=x.dtype.kind == "f") for x, y in zip(a, b,
                                                                                   strict=True))


@dataclass(frozen=True)
class AgentSpec:
    """How every agent of a decision plays.

    Attributes
    ----------
    mode : {"jsfp", "best-response", "sequential"}
    rounds : int                 round budget R (``sequential`` always uses N rounds)
    alpha, beta : float          JSFP inertia and continue-probability
    max_inner, max_outer : int   JSFP iteration and sweep limits
    communicate : bool           False: every agent plans alone (``independent``)
    """

    mode: str = "jsfp"
    rounds: int = 1000
    alpha: float = 0.3
    beta: float = 0.95
    max_inner: int = 50
    max_outer: int = 10
    communicate: bool = True

    def budget(self, n_agents: int) -> int:
        return n_agents if self.mode == "sequential" else self.rounds


class Agent:
    """Agent ``index``'s belief and schedule for one decision.

    Parameters
    ----------
    ctx : Context                 the decision, identical for every agent
    index : int                   the agent's sensor
    spec : AgentSpec
    gen : numpy.random.Generator  the agent's copy of the decision's shared generator
    decision : int                decision number, stamped on messages
    failed : iterable of int      agents known to be lost before the decision
    """

    def __init__(self, ctx: Context, index: int, spec: AgentSpec, gen: np.random.Generator,
                 decision: int = 0, failed: tuple[int, ...] = ()) -> None:
        self.ctx, self.i, self.spec, self.gen, self.decision = ctx, index, spec, gen, decision
        self.N, self.K = ctx.N, ctx.K
        self.view = self._new_view()
        self.heard: dict[int, Message] = {}
        self.known = np.zeros(self.N, dtype=bool)      # peers heard from in this decision
        self.failed = np.zeros(self.N, dtype=bool)
        self.failed[list(failed)] = True
        self.settled = False
        self.converged: bool | None = None
        self.sweeps = 0
        self.completed = 0
        self.ignored = 0
        self.trace: list[float] = []
        self._pending: tuple[bool, np.ndarray, int] | None = None
        if spec.mode == "jsfp":
            self._start_game()

    def _new_view(self) -> GameState:
        return GameState(self.ctx)

    def _start_game(self) -> None:
        """The JSFP schedule's first sweep (every player unassigned: the initialisation)."""
        self.sweep, self.k, self.t = 1, self.K, 1
        self.changed, self.all_eq = False, True
        self.sweeps = 1
        self._start_epoch()

    # ------------------------------------------------------------------ round protocol
    def step(self, rnd: int) -> Message:
        """Compute round ``rnd`` and return the message announcing the result."""
        mode = self.spec.mode
        if mode == "jsfp" and not self.settled:
            return self._jsfp_step(rnd)
        if mode == "best-response":
            # A list, not a generator: every player responds, any() must not stop early.
            changed = [self._best_response(k) for k in self._response_order()]
            self.settled = not any(changed)
        elif mode == "sequential" and rnd == self.i + 1:
            self._greedy_turn()
            self.settled = True
        return self._message(rnd, best=True)

    def end_round(self, rnd: int, delivered: list[Message]) -> None:
        """Take the messages delivered at the end of round ``rnd`` and finish the round."""
        fresh: dict[int, Message] = {}
        updated: list[Message] = []
        for m in delivered:
            j = m.sender
            prev = self.heard.get(j)
            if j == self.i or self.failed[j] or m.decision != self.decision or (
                    prev is not None and m.round <= prev.round):
                self.ignored += 1              # duplicate, late, or from a lost agent
                continue
            self.heard[j] = m
            self.known[j] = True
            updated.append(m)
            if m.round == rnd:
                fresh[j] = m
        active = self.spec.mode == "jsfp" and not self.settled and self._pending is not None
        eq = active and self._equilibrium(fresh)
        for m in updated:
            self._peer_from(m, eq and m.round == rnd)
        if active:
            self._resolve(eq)

    def peer_failed(self, j: int) -> None:
        """Agent ``j`` is gone: its platform holds still (no move, no look) from now on."""
        if j == self.i or self.failed[j]:
            return
        self.failed[j] = True
        self.known[j] = False
        self.heard.pop(j, None)
        self._clear_peer(j)

    def complete(self) -> None:
        """Fill any own player still unassigned (round budget spent), k = K..1, alone."""
        for k in self._response_order():
            if not self._assigned(k):
                self._best_response(k)
                self.completed += 1

    # ------------------------------------------------------------------ results
    def own_plan(self) -> tuple[np.ndarray, np.ndarray]:
        """This agent's plan: ``(K,)`` lattice indices and ``(K,)`` targets."""
        return self.view.pos[self.i].copy(), self.view.tgt[self.i].copy()

    def beliefs(self) -> tuple[np.ndarray, np.ndarray]:
        """The joint plan this agent believes: ``(N, K)`` lattice indices and targets."""
        return self.view.pos.copy(), self.view.tgt.copy()

    def sectors(self) -> tuple[np.ndarray, np.ndarray] | None:
        """With search on, its own ``(K,)`` and believed ``(N, K)`` sectors; else None."""
        return None

    # ------------------------------------------------------------------ JSFP schedule
    def _start_epoch(self) -> None:
        k = self.k
        self.before = self._column(k)
        self.actions = self._actions(k)
        self.ubar = np.zeros(len(self.actions[0]))
        self.cur = -1
        self.t = 1
        self._pending = None

    def _jsfp_step(self, rnd: int) -> Message:
        """One JSFP iteration for player (i, k) against the belief (the rules of ``pg``)."""
        k, t = self.k, self.t
        u = self._utilities(k, self.actions)
        if t == 1:
            # Every feasible action is scored (pg scores one representative of actions with
            # identical pairs); the first-in-order tie rule makes the choices the same.
            self.cur = self._current(k, self.actions)
        self._round_start = self._column(k)
        best_now = self._is_best(u, self.cur)
        ubar = (t - 1) / t * self.ubar + u / t
        best = self._choose(ubar, self.cur)
        # The switch coin is this agent's entry of the next shared rng.random(N) draw. It is
        # drawn now and taken back in end_round if the round is an equilibrium (pg draws
        # nothing then), so every agent's generator follows the centralized stream.
        self._saved = self.gen.bit_generator.state
        switch = self.gen.random(self.N)[self.i] >= self.spec.alpha
        nxt = best if best != self.cur and (self.cur < 0 or switch) else self.cur
        self._pending = (best_now, ubar, nxt)
        cond = self._cond(self.actions, nxt) if nxt >= 0 else None
        return self._message(rnd, best_now, cond)

    def _equilibrium(self, fresh: dict[int, Message]) -> bool:
        """Every live peer heard so far is at a best response in this very epoch game."""
        assert self._pending is not None
        if not self._pending[0]:
            return False
        here = (self.sweep, self.k, self.t)
        for j in np.flatnonzero(self.known & ~self.failed):
            m = fresh.get(int(j))
            if m is None or not (m.settled or (m.best and (m.sweep, m.epoch, m.iteration) == here)):
                return False
        return True

    def _resolve(self, eq: bool) -> None:
        assert self._pending is not None
        _, ubar, nxt = self._pending
        self._pending = None
        if eq:
            self.gen.bit_generator.state = self._saved
            stop = True
        else:
            self.ubar = ubar
            if nxt != self.cur:
                self._apply(self.k, self.actions, nxt)
                self.cur = nxt
            self._switched()
            stop = bool(self.gen.random() >= self.spec.beta)
        self.t += 1
        if stop or self.t > self.spec.max_inner:
            self._end_epoch(eq)

    def _end_epoch(self, eq: bool) -> None:
        k = self.k
        self.all_eq &= eq
        self.changed |= not _same(self.before, self._column(k))
        if k > 1:
            self.k = k - 1
            self._start_epoch()
            return
        self.trace.append(self.view.potential())
        if not self.changed and self.all_eq:
            self.settled, self.converged = True, True
        elif self.sweep == self.spec.max_outer:
            self.settled, self.converged = True, False
        else:
            self.sweep += 1
            self.sweeps = self.sweep
            self.k, self.changed, self.all_eq = self.K, False, True
            self._start_epoch()

    # ------------------------------------------------------------------ actions
    # The hooks below are what the search agent (search_agent.py) replaces: how a player's
    # actions are listed, scored, compared and applied, and how plans are carried.
    def _response_order(self) -> range:
        """The order in which an agent's own players respond alone: k = K..1."""
        return range(self.K, 0, -1)

    def _assigned(self, k: int) -> bool:
        return bool(self.view.tgt[self.i, k - 1] >= 0)

    def _actions(self, k: int) -> tuple[np.ndarray, ...]:
        return self.view.player_actions(self.i, k)

    def _utilities(self, k: int, actions: tuple[np.ndarray, ...]) -> np.ndarray:
        """Player (i, k)'s utility of every action against the belief (its marginal
        contribution to Phi: Phi up to a term it cannot change)."""
        pos, tgt = actions
        return self.view.chain_gains(self.i, k, pos[:, None], tgt[:, None])[0]

    def _current(self, k: int, actions: tuple[np.ndarray, ...]) -> int:
        pos, tgt = actions
        return current_index(self.view, self.i, k, pos, tgt)

    def _is_best(self, u: np.ndarray, cur: int) -> bool:
        return is_best(u, cur, abs(self.view.potential()))

    def _choose(self, values: np.ndarray, cur: int) -> int:
        return choose(values, cur, abs(self.view.potential()))

    def _cond(self, actions: tuple[np.ndarray, ...], idx: int) -> tuple[Any, ...]:
        pos, tgt = actions
        return int(pos[idx]), int(tgt[idx])

    def _apply(self, k: int, actions: tuple[np.ndarray, ...], idx: int) -> None:
        pos, tgt = actions
        self.view.set_action(self.i, k, int(pos[idx]), int(tgt[idx]))

    def _column(self, k: int) -> tuple[np.ndarray, ...]:
        """Every platform's epoch-k action in the belief (to tell whether it changed)."""
        return self.view.pos[:, k - 1].copy(), self.view.tgt[:, k - 1].copy()

    def _switched(self) -> None:
        """A round that was not an equilibrium has been applied (the search agent counts
        its switches as ``pg`` with search does)."""

    def _peer_from(self, m: Message, equilibrium: bool) -> None:
        self._set_peer(m.sender, *m.plan_after(equilibrium))

    def _clear_peer(self, j: int) -> None:
        self._set_peer(j, np.full(self.K, -1), np.full(self.K, -1))

    # ------------------------------------------------------------------ helpers
    def _message(self, rnd: int, best: bool, cond: tuple[Any, ...] | None = None) -> Message:
        jsfp = self.spec.mode == "jsfp"
        return Message(self.decision, rnd, self.i, self.sweep if jsfp else 0,
                       self.k if jsfp else 0, self.t if jsfp else 0, self.settled, best,
                       self.view.pos[self.i].copy(), self.view.tgt[self.i].copy(), cond)

    def _set_peer(self, j: int, pos: np.ndarray, tgt: np.ndarray) -> None:
        view = self.view
        if np.array_equal(view.pos[j], pos) and np.array_equal(view.tgt[j], tgt):
            return
        view.pos[j], view.tgt[j] = pos, tgt
        view.refresh(j)

    def _best_response(self, k: int) -> bool:
        """Player (i, k) takes its best response to the belief; True if it changed."""
        actions = self._actions(k)
        u = self._utilities(k, actions)
        cur = self._current(k, actions)
        best = self._choose(u, cur)
        if best == cur:
            return False
        self._apply(k, actions, best)
        return True

    def _greedy_turn(self) -> None:
        """This platform's epochs k = 1..K, each the action maximising Phi given the rest."""
        view, i = self.view, self.i
        for k in range(1, self.K + 1):
            pos, tgt = view.player_actions(i, k)
            phi = view.evaluate_chains(i, k, pos[:, None], tgt[:, None])
            best = choose(phi)
            view.set_action(i, k, int(pos[best]), int(tgt[best]))

