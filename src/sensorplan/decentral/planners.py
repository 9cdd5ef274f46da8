"""Decentralized planners behind the project's planner protocol.

``dec-jsfp``        agents play the paper's game over links (JSFP with inertia, or plain
                    best response with ``mode="best-response"``);
``dec-independent`` agents plan alone (no messages), each treating the others as unassigned;
``dec-sequential``  agents decide one after the other over the links (N rounds).

Each plans search looks too: with a problem whose search is on, every agent plays the same
schedule over track and sector looks against the same undetected intensity
(:mod:`.search_agent`).

Every planner returns a :class:`DecentralResult`: a :class:`PlanResult` whose plan is the
union of the agents' own plans (Phi by the one definition, :func:`finish`) plus ``log``, a
:class:`DecisionLog` of the decision. With ``transport="bus"`` the planner holds one
operating-system process per platform between decisions: call :meth:`close` (or use it as a
context manager) when the run ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

from ..planners.base import PlanResult, RngLike, finish, make_rng, register, start_clock
from ..planners.potential_game import LearningSettings
from ..planners.problem import PlanningProblem
from ..planners.registry import seed_param
from .agent import AgentSpec
from .decision import assemble, decision_context, run_inproc, to_plan, tracks_of
from .episode import record
from .links import LinkModel, decision_key
from .messages import DecisionLog
from .params import GameMode, Links, Rounds, Transport


@dataclass(frozen=True)
class DecentralResult(PlanResult):
    """A :class:`PlanResult` with what happened on the links.

    Attributes
    ----------
    log : DecisionLog             rounds, messages sent/delivered/lost, stale beliefs,
                                  failed agents (deterministic)
    timing : dict                 wall time of every round per agent (diagnostics)
    """

    log: DecisionLog | None = None
    timing: dict[str, Any] | None = field(default=None, compare=False, repr=False)


# Each group of settings is declared once, with its rule, in a frozen dataclass mixin
# (:mod:`.params`); a planner lists the groups it takes. Its fields come in the reverse
# order of its bases, and are checked in that order.


@dataclass(frozen=True)
class _Agents(Transport):
    """Shared machinery: one decision over the chosen transport (``inproc`` or ``bus``; on
    the bus an agent waits ``timeout`` seconds for a peer before declaring it lost), the
    bus's lifetime."""

    name: ClassVar[str]
    #: With search on the agents plan track and sector looks (search_agent.py).
    plans_search: ClassVar[bool] = True
    if TYPE_CHECKING:              # each planner declares its seed (none here at run time)
        seed: int | None = 0
    _runtime: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def _spec(self) -> AgentSpec:
        raise NotImplementedError

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> DecentralResult:
        """Plan one decision; ``rng`` (or ``seed``) drives the agents' shared random numbers.

        When ``rng`` is a Generator it is advanced as the lowest-numbered live agent's copy
        was (with perfect links: exactly as the centralized ``pg`` advances it).
        """
        start = start_clock()
        gen = make_rng(rng, self.seed)
        dctx = decision_context(problem)
        ctx = tracks_of(dctx)
        # Planners without link settings have perfect links.
        p_loss, delay, comm_range = (self._links() if isinstance(self, Links)
                                     else (0.0, 0, math.inf))
        link = LinkModel(decision_key(gen), np.array(problem.positions, dtype=float), p_loss,
                         delay, comm_range)
        spec = self._spec()
        if self.transport == "bus":
            outcomes, failed = self._bus(ctx.N).decide(problem, spec, link, gen)
        else:
            outcomes, failed = run_inproc(dctx, spec, link, gen), ()
        got = assemble(dctx, outcomes, failed)
        if got.gen_state is not None:
            gen.bit_generator.state = got.gen_state
        record(got.log)
        res = finish(self.name, ctx, to_plan(ctx, got.pos, got.tgt, got.sec), start, None,
                     None, got.trace)
        base = {f.name: getattr(res, f.name) for f in fields(PlanResult)}
        # Lost agents' platforms hold station: declared, so the plan check admits them.
        base["holding"] = got.log.failed
        return DecentralResult(**base, log=got.log, timing=got.timing)

    def _bus(self, n_agents: int) -> Any:
        from ..limits import check_bus_agents
        from .bus import Bus  # lazy: only the bus transport needs pyzmq

        check_bus_agents(n_agents, "planner.transport")
        bus = self._runtime.get("bus")
        if bus is None or bus.closed or bus.n_agents != n_agents:
            if bus is not None:
                bus.close()
            bus = Bus(n_agents, timeout=self.timeout)
            self._runtime["bus"] = bus
        return bus

    @property
    def pids(self) -> tuple[int, ...]:
        """Process ids of the running agent processes (empty without a bus)."""
        bus = self._runtime.get("bus")
        return () if bus is None or bus.closed else bus.pids

    def close(self) -> None:
        """Stop the agent processes, if any (idempotent; the planner can be used again)."""
        bus = self._runtime.pop("bus", None)
        if bus is not None:
            bus.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@register
@dataclass(frozen=True)
class DecentralJSFPPlanner(_Agents, GameMode, Links, Rounds, LearningSettings):
    """``dec-jsfp``: one agent per platform playing the game over imperfect links.

    Attributes
    ----------
    rounds : int          round budget R per decision (>= 1); the decision ends earlier when
                          every agent has settled
    p_loss : float        probability that a message is lost, in [0, 1]
    delay : int           rounds a message takes (>= 0)
    comm_range : float    largest ground distance of a working link (m, > 0; inf unlimited)
    mode : {"jsfp", "best-response"}
    transport : {"inproc", "bus"}
    timeout : float       bus: seconds an agent waits for a peer before declaring it lost
    alpha, beta, max_inner, max_outer, seed : as ``pg``
    """

    name: ClassVar[str] = "dec-jsfp"

    def _spec(self) -> AgentSpec:
        return AgentSpec(self.mode, int(self.rounds), *self.learning)


@register
@dataclass(frozen=True)
class DecentralIndependentPlanner(_Agents, GameMode, Rounds, LearningSettings):
    """``dec-independent``: every agent plans alone and sends nothing.

    Each agent plays the same schedule as ``dec-jsfp`` (same ``rounds``, ``mode`` and
    learning settings) with every other platform unassigned.
    """

    name: ClassVar[str] = "dec-independent"

    def _spec(self) -> AgentSpec:
        return AgentSpec(self.mode, int(self.rounds), *self.learning, communicate=False)


@register
@dataclass(frozen=True)
class DecentralSequentialPlanner(_Agents, Links):
    """``dec-sequential``: agent 1 decides its K epochs, tells the others, then agent 2, ...

    N rounds; in its turn an agent takes, epoch by epoch, the action maximising Phi given
    the plans it has heard (a lost message leaves that platform unassigned in its belief).
    """

    name: ClassVar[str] = "dec-sequential"
    seed: int | None = seed_param()

    def _spec(self) -> AgentSpec:
        return AgentSpec("sequential", 1)
