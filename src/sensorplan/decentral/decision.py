"""One decentralized decision: the in-process driver and the assembly of the agents' plans.

Both transports run the same per-agent sequence (``step``, deliver, ``end_round``, until
the budget is spent or every live agent is settled, then ``complete``) and report one
:class:`AgentOutcome` per live agent; :func:`assemble` turns them into the joint plan and
the :class:`~sensorplan.decentral.messages.DecisionLog`.
"""

from __future__ import annotations

import copy
import time
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._types import IntArray
from ..planners.information import Context
from ..planners.information import prepare as prepare_tracks
from ..planners.problem import Plan, PlanningProblem
from ..planners.search import SearchContext
from .agent import Agent, AgentSpec
from .links import Inbox, LinkModel
from .messages import DecisionLog, decode, encode
from .search_agent import SearchAgent


@dataclass
class AgentOutcome:
    """What an agent reports when a decision ends (picklable; crosses process boundaries).

    ``round_seconds`` and ``work_seconds`` (wall time of each round and the part spent in
    the agent's own computation) are diagnostics only: nothing is decided by them. With
    search on, ``pos`` and ``belief_pos`` are ground positions ``(K, 2)`` and ``(N, K, 2)``
    (m) instead of lattice indices, and ``sec``, ``belief_sec`` the sectors (else None).
    """

    index: int
    pos: np.ndarray
    tgt: IntArray
    belief_pos: np.ndarray
    belief_tgt: IntArray
    gen_state: dict[str, Any]
    settled: bool
    converged: bool | None
    sweeps: int
    completed: int
    trace: tuple[float, ...]
    rounds: int
    sent: int
    counts: dict[str, int]
    failed: tuple[int, ...] = ()
    round_seconds: tuple[float, ...] = ()
    work_seconds: tuple[float, ...] = ()
    sec: IntArray | None = None
    belief_sec: IntArray | None = None


#: What the agents of a decision share: the tracks' precomputation, or with search on the
#: search context (which holds it and the undetected intensity).
DecisionContext = Context | SearchContext


def decision_context(problem: PlanningProblem) -> DecisionContext:
    """The context every agent of ``problem``'s decision plans with: the search context
    when its search is on (:func:`sensorplan.planners.search.prepare`), else the tracks'."""
    if problem.searching:
        from ..planners import search

        return search.prepare(problem)
    return prepare_tracks(problem)


def tracks_of(ctx: DecisionContext) -> Context:
    """The tracks' precomputation of a decision context."""
    return ctx if isinstance(ctx, Context) else ctx.ctx


def make_agent(ctx: DecisionContext, index: int, spec: AgentSpec, gen: np.random.Generator,
               decision: int = 0, failed: tuple[int, ...] = ()) -> Agent:
    """Agent ``index`` of a decision: a :class:`SearchAgent` when ``ctx`` is a search
    context, else an :class:`Agent` (both transports build their agents here)."""
    if isinstance(ctx, Context):
        return Agent(ctx, index, spec, gen, decision, failed)
    return SearchAgent(ctx, index, spec, gen, decision, failed)


def outcome(agent: Agent, inbox: Inbox | None, rounds: int, sent: int, received: int,
            round_seconds: Iterable[float] = (), work_seconds: Iterable[float] = ()
            ) -> AgentOutcome:
    """Collect an agent's result after :meth:`Agent.complete`."""
    pos, tgt = agent.own_plan()
    bpos, btgt = agent.beliefs()
    sectors = agent.sectors()
    sec, bsec = (None, None) if sectors is None else sectors
    counts = {"received": received, "delivered": 0, "lost": 0, "out_of_range": 0, "in_flight": 0,
              "ignored": agent.ignored}
    if inbox is not None:
        counts.update(delivered=inbox.delivered, lost=inbox.lost,
                      out_of_range=inbox.out_of_range, in_flight=len(inbox.pending),
                      ignored=agent.ignored + inbox.ignored)
    return AgentOutcome(agent.i, pos, tgt, bpos, btgt, dict(agent.gen.bit_generator.state),
                        agent.settled, agent.converged, agent.sweeps, agent.completed,
                        tuple(agent.trace), rounds, sent, counts,
                        tuple(int(j) for j in np.flatnonzero(agent.failed)),
                        tuple(round_seconds), tuple(work_seconds), sec, bsec)


def to_plan(ctx: Context, pos: np.ndarray, tgt: IntArray, sec: IntArray | None = None
            ) -> Plan:
    """Lattice indices ``(N, K)`` and targets to a :class:`Plan` (NaN where unassigned);
    with ``sec`` (search on), ``pos`` are the ground positions ``(N, K, 2)`` already."""
    if sec is not None:
        return Plan(pos.copy(), tgt.copy(), sec.copy())
    positions = np.full((ctx.N, ctx.K, 2), np.nan)
    for i in range(ctx.N):
        for k in range(1, ctx.K + 1):
            if tgt[i, k - 1] >= 0:
                positions[i, k - 1] = ctx.lattices[i].positions[k][pos[i, k - 1]]
    return Plan(positions, tgt.copy())


@dataclass
class Assembled:
    """The joint plan of a decision and what happened."""

    pos: np.ndarray
    tgt: IntArray
    log: DecisionLog
    trace: tuple[float, ...]
    gen_state: dict[str, Any] | None
    timing: dict[str, Any] = field(default_factory=dict)
    sec: IntArray | None = None


def assemble(ctx: DecisionContext, outcomes: Mapping[int, AgentOutcome],
             failed: Iterable[int]) -> Assembled:
    """The union of the live agents' own plans; lost agents' platforms hold still.

    The caller's generator continues from the lowest-numbered live agent's copy (all copies
    agree when no message is lost). With search on (a search context) the plan carries
    ground positions and sectors (:attr:`Assembled.sec`).
    """
    searching = not isinstance(ctx, Context)
    N, K = tracks_of(ctx).N, tracks_of(ctx).K
    failed = set(failed) | (set(range(N)) - set(outcomes))
    live = sorted(set(outcomes) - failed)
    pos = np.full((N, K, 2), np.nan) if searching else np.full((N, K), -1, dtype=np.int64)
    tgt = np.full((N, K), -1, dtype=np.int64)
    sec = np.full((N, K), -1, dtype=np.int64) if searching else None
    for i in live:
        pos[i], tgt[i] = outcomes[i].pos, outcomes[i].tgt
        own_sec = outcomes[i].sec
        if sec is not None and own_sec is not None:
            sec[i] = own_sec

    def believed(a: int, b: int) -> bool:
        o = outcomes[a]
        return bool(np.array_equal(o.belief_pos[b], pos[b], equal_nan=searching)
                    and np.array_equal(o.belief_tgt[b], tgt[b])
                    and (sec is None or (o.belief_sec is not None
                                         and np.array_equal(o.belief_sec[b], sec[b]))))

    stale = sum(1 for a in live for b in live if a != b and not believed(a, b))
    total: Counter[str] = Counter()
    for i in live:
        total.update(outcomes[i].counts)
    o = [outcomes.get(i) if i in live else None for i in range(N)]
    log = DecisionLog(
        rounds=max((x.rounds for x in o if x is not None), default=0),
        sent=sum(x.sent for x in o if x is not None), received=total["received"],
        delivered=total["delivered"], lost=total["lost"], out_of_range=total["out_of_range"],
        in_flight=total["in_flight"], ignored=total["ignored"], stale=stale,
        failed=tuple(sorted(failed)),
        settled=tuple(bool(x is not None and x.settled) for x in o),
        converged=tuple(None if x is None else x.converged for x in o),
        sweeps=tuple(0 if x is None else x.sweeps for x in o),
        completed=tuple(0 if x is None else x.completed for x in o))
    first = outcomes[live[0]] if live else None
    timing = {"round_seconds": {i: outcomes[i].round_seconds for i in live},
              "work_seconds": {i: outcomes[i].work_seconds for i in live}}
    return Assembled(pos, tgt, log, first.trace if first else (),
                     first.gen_state if first else None, timing, sec)


class InprocTransport:
    """Deterministic in-process delivery of encoded messages, with counters for tests.

    Everything sent in a round reaches every addressee's queue before anyone reads, so
    delivery does not depend on the order in which agents compute.
    """

    def __init__(self) -> None:
        self.queues: defaultdict[int, list[bytes]] = defaultdict(list)
        self.sends: Counter[int] = Counter()
        self.reads: Counter[int] = Counter()

    def send(self, sender: int, data: bytes, to: Iterable[int]) -> int:
        n = 0
        for j in to:
            self.queues[j].append(data)
            n += 1
        self.sends[sender] += n
        return n

    def receive(self, me: int) -> list[bytes]:
        self.reads[me] += 1
        return self.queues.pop(me, [])


def run_inproc(ctx: DecisionContext, spec: AgentSpec, link: LinkModel,
               gen: np.random.Generator,
               decision: int = 0, failed: Iterable[int] = (),
               fail_at: Mapping[int, int] | None = None,
               transport: InprocTransport | None = None) -> dict[int, AgentOutcome]:
    """Run one decision with every agent in this process, in lockstep.

    Parameters
    ----------
    ctx, spec, link : the decision (:func:`decision_context`), how agents play, the links
    gen : numpy.random.Generator   each agent plays with its own copy (not advanced here)
    decision : int                 stamped on messages
    failed : agents already lost (they take no part; their platforms hold still)
    fail_at : {agent: round}       fault injection: the agent stops before computing that
                                   round; the others learn it at that round, as a bus agent
                                   learns it from a timeout
    transport : InprocTransport    to inspect traffic (a fresh one by default)

    Returns
    -------
    {agent: AgentOutcome} for the agents still live at the end.
    """
    net = transport if transport is not None else InprocTransport()
    failed = tuple(sorted(set(failed)))
    N = tracks_of(ctx).N
    live = [i for i in range(N) if i not in failed]
    agents: dict[int, Agent] = {i: make_agent(ctx, i, spec, copy.deepcopy(gen), decision,
                                              failed) for i in live}
    inboxes = {i: Inbox(i, link) for i in live}
    sent: Counter[int] = Counter()
    received: Counter[int] = Counter()
    times: list[float] = []        # wall time of each round, all agents together
    rounds = 0
    for r in range(1, spec.budget(N) + 1):
        for j in sorted(j for j, fr in (fail_at or {}).items() if fr == r and j in agents):
            del agents[j], inboxes[j]
            for other, agent in agents.items():
                agent.peer_failed(j)
                inboxes[other].drop_sender(j)
        if not agents:
            break
        start = time.perf_counter()
        msgs = {i: a.step(r) for i, a in agents.items()}
        for i, m in msgs.items():
            if spec.communicate:
                sent[i] += net.send(i, encode(m), [j for j in agents if j != i])
        for i, a in agents.items():
            delivered = []
            if spec.communicate:
                for data in net.receive(i):
                    received[i] += 1
                    inboxes[i].accept(decode(data))
                delivered = inboxes[i].due(r)
            a.end_round(r, delivered)
        times.append(time.perf_counter() - start)
        rounds = r
        if all(m.settled for m in msgs.values()):
            break
    out = {}
    for i, a in agents.items():
        a.complete()
        out[i] = outcome(a, inboxes[i] if spec.communicate else None, rounds, sent[i],
                         received[i], times, times)
    return out
