"""Decentralized planners behind the project's planner protocol.

``dec-jsfp``        agents play the paper's game over links (JSFP with inertia, or plain
                    best response with ``mode="best-response"``);
``dec-independent`` agents plan alone (no messages), each treating the others as unassigned;
``dec-sequential``  agents decide one after the other over the links (N rounds).

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

from ..errors import ConfigError
from ..planners.base import PlanResult, RngLike, finish, make_rng, register, start_clock
from ..planners.information import prepare
from ..planners.potential_game import LearningSettings
from ..planners.problem import PlanningProblem
from .agent import AgentSpec
from .decision import assemble, run_inproc, to_plan
from .episode import record
from .links import LinkModel, decision_key
from .messages import DecisionLog

TRANSPORTS = ("inproc", "bus")
GAME_MODES = ("jsfp", "best-response")


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


def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_real(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
        v, (bool, np.bool_))


def check_links(p_loss: Any, delay: Any, comm_range: Any) -> None:
    """Raise ConfigError naming the link setting that is out of range."""
    if not _is_real(p_loss) or not 0.0 <= float(p_loss) <= 1.0:
        raise ConfigError("planner.p_loss", f"must be a number in [0, 1], got {p_loss!r}")
    if not _is_int(delay) or delay < 0:
        raise ConfigError("planner.delay", f"must be an integer >= 0 (rounds), got {delay!r}")
    if not _is_real(comm_range) or math.isnan(comm_range) or comm_range <= 0:
        raise ConfigError("planner.comm_range",
                          f"must be a ground distance > 0 in m (inf: unlimited), "
                          f"got {comm_range!r}")


def check_rounds(rounds: Any) -> None:
    if not _is_int(rounds) or rounds < 1:
        raise ConfigError("planner.rounds", f"must be an integer >= 1, got {rounds!r}")


def check_transport(transport: Any, timeout: Any) -> None:
    if transport not in TRANSPORTS:
        raise ConfigError("planner.transport", f"must be one of {TRANSPORTS}, got "
                          f"{transport!r}")
    if not _is_real(timeout) or not math.isfinite(timeout) or timeout <= 0:
        raise ConfigError("planner.timeout", f"must be a finite number of seconds > 0, got "
                          f"{timeout!r}")


def _checks_before(obj: Any, cls: type) -> None:
    """Run the setting checks of the classes after ``cls`` in ``obj``'s MRO (the settings
    declared before ``cls``'s), so that the first setting in field order that breaks its
    rule is the one reported."""
    after = getattr(super(cls, obj), "__post_init__", None)
    if after is not None:
        after()


# Each group of settings is declared once, with its check, in a frozen dataclass mixin; a
# planner lists the groups it takes. Its fields come in the reverse order of its bases.


@dataclass(frozen=True)
class _Rounds:
    """The round budget R per decision (>= 1); the decision ends earlier when every agent
    has settled."""

    rounds: int = 1000

    def __post_init__(self) -> None:
        _checks_before(self, _Rounds)
        check_rounds(self.rounds)


@dataclass(frozen=True)
class _Links:
    """The links: ``p_loss`` (probability that a message is lost, in [0, 1]), ``delay``
    (rounds a message takes, >= 0) and ``comm_range`` (largest ground distance of a working
    link, m, > 0; inf unlimited)."""

    p_loss: float = 0.0
    delay: int = 0
    comm_range: float = math.inf

    def __post_init__(self) -> None:
        _checks_before(self, _Links)
        check_links(self.p_loss, self.delay, self.comm_range)

    def _links(self) -> tuple[float, int, float]:
        return float(self.p_loss), int(self.delay), float(self.comm_range)


@dataclass(frozen=True)
class _GameMode:
    """How the agents play the game: ``jsfp`` or ``best-response``."""

    mode: str = "jsfp"

    def __post_init__(self) -> None:
        _checks_before(self, _GameMode)
        if self.mode not in GAME_MODES:
            raise ConfigError("planner.mode", f"must be one of {GAME_MODES}, got {self.mode!r}")


@dataclass(frozen=True)
class _Agents:
    """Shared machinery: one decision over the chosen transport (``inproc`` or ``bus``; on
    the bus an agent waits ``timeout`` seconds for a peer before declaring it lost), the
    bus's lifetime."""

    name: ClassVar[str]
    if TYPE_CHECKING:              # each planner declares its seed (none here at run time)
        seed: int | None = 0
    transport: str = "inproc"
    timeout: float = 10.0
    _runtime: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _checks_before(self, _Agents)
        check_transport(self.transport, self.timeout)

    def _spec(self) -> AgentSpec:
        raise NotImplementedError

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> DecentralResult:
        """Plan one decision; ``rng`` (or ``seed``) drives the agents' shared random numbers.

        When ``rng`` is a Generator it is advanced as the lowest-numbered live agent's copy
        was (with perfect links: exactly as the centralized ``pg`` advances it).
        """
        start = start_clock()
        gen = make_rng(rng, self.seed)
        ctx = prepare(problem)
        # Planners without link settings have perfect links.
        p_loss, delay, comm_range = (self._links() if isinstance(self, _Links)
                                     else (0.0, 0, math.inf))
        link = LinkModel(decision_key(gen), np.array(problem.positions, dtype=float), p_loss,
                         delay, comm_range)
        spec = self._spec()
        if self.transport == "bus":
            outcomes, failed = self._bus(ctx.N).decide(problem, spec, link, gen)
        else:
            outcomes, failed = run_inproc(ctx, spec, link, gen), ()
        got = assemble(ctx, outcomes, failed)
        if got.gen_state is not None:
            gen.bit_generator.state = got.gen_state
        record(got.log)
        res = finish(self.name, ctx, to_plan(ctx, got.pos, got.tgt), start, None, None,
                     got.trace)
        base = {f.name: getattr(res, f.name) for f in fields(PlanResult)}
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
class DecentralJSFPPlanner(_Agents, _GameMode, _Links, _Rounds, LearningSettings):
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
class DecentralIndependentPlanner(_Agents, _GameMode, _Rounds, LearningSettings):
    """``dec-independent``: every agent plans alone and sends nothing.

    Each agent plays the same schedule as ``dec-jsfp`` (same ``rounds``, ``mode`` and
    learning settings) with every other platform unassigned.
    """

    name: ClassVar[str] = "dec-independent"

    def _spec(self) -> AgentSpec:
        return AgentSpec(self.mode, int(self.rounds), *self.learning, communicate=False)


@register
@dataclass(frozen=True)
class DecentralSequentialPlanner(_Agents, _Links):
    """``dec-sequential``: agent 1 decides its K epochs, tells the others, then agent 2, ...

    N rounds; in its turn an agent takes, epoch by epoch, the action maximising Phi given
    the plans it has heard (a lost message leaves that platform unassigned in its belief).
    """

    name: ClassVar[str] = "dec-sequential"
    seed: int | None = 0

    def _spec(self) -> AgentSpec:
        return AgentSpec("sequential", 1)
