"""What agents tell each other in a round, and what a decision records.

A :class:`Message` is the only thing an agent learns about another agent during a decision.
It travels as a few dozen bytes (:func:`encode` / :func:`decode`), so the in-process transport
and the message bus carry exactly the same content.

With search on (the decision's problem searches), a plan's look has a target or a sector,
and its positions travel as float64 ground positions rather than lattice indices: a
searching plan's positions are the float sums of its moves, as the centralized planner
builds them (:func:`sensorplan.planners.search.player_actions`), and only the exact values
keep every agent's Phi bit-identical to it.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._types import FloatArray, IntArray

# decision, round, sender, sweep, epoch, iteration, flags, K, cond position, cond target
_HEADER = struct.Struct("<IIHHHHBHii")
_SETTLED, _BEST, _COND, _SEARCH = 1, 2, 4, 8
# A search message's cond: ground position (2 float64), target, sector.
_SEARCH_COND = struct.Struct("<ddii")


@dataclass(frozen=True)
class Message:
    """One agent's announcement at the end of its computation in a round.

    Attributes
    ----------
    decision : int        which decision of the run (messages of another one are dropped)
    round : int           r, from 1
    sender : int          agent (= sensor) index
    sweep, epoch, iteration : int
                          the sender's place in the schedule (s, k, t) when it computed;
                          0 where the mode has no schedule
    settled : bool        the sender will not change its plan again in this decision
    best : bool           its player (sender, epoch) was at a best response this round
    pos, tgt : (K,) int   the sender's plan at the start of the round: lattice indices in
                          ``R_1..R_K`` and targets, -1 where unassigned; with search on
                          ``pos`` is ``(K, 2)`` float ground positions (m, NaN unassigned)
    cond : tuple or None  the action its player (sender, epoch) takes at the end of the
                          round unless the round turns out to be an equilibrium of the epoch
                          game (JSFP only): ``(lattice index, target)``, with search on
                          ``(x, y, target, sector)``
    sec : (K,) int or None
                          with search on, the sender's sectors (-1 where the look is at a
                          target or unassigned); None with search off
    """

    decision: int
    round: int
    sender: int
    sweep: int
    epoch: int
    iteration: int
    settled: bool
    best: bool
    pos: np.ndarray
    tgt: IntArray
    cond: tuple[Any, ...] | None = None
    sec: IntArray | None = None

    @property
    def searching(self) -> bool:
        """Whether the message carries a searching plan (sectors, float positions)."""
        return self.sec is not None

    def plan_after(self, equilibrium: bool) -> tuple[np.ndarray, IntArray]:
        """The sender's plan after the round: ``cond`` applied unless ``equilibrium``."""
        pos, tgt = self.pos.copy(), self.tgt.copy()
        if self.cond is not None and not equilibrium:
            pos[self.epoch - 1], tgt[self.epoch - 1] = self.cond
        return pos, tgt

    def looks_after(self, equilibrium: bool) -> tuple[FloatArray, IntArray, IntArray]:
        """A searching sender's plan after the round: positions ``(K, 2)``, targets and
        sectors ``(K,)``, ``cond`` applied unless ``equilibrium``."""
        assert self.sec is not None
        pos, tgt, sec = self.pos.copy(), self.tgt.copy(), self.sec.copy()
        if self.cond is not None and not equilibrium:
            x, y, t, s = self.cond
            pos[self.epoch - 1] = (x, y)
            tgt[self.epoch - 1], sec[self.epoch - 1] = t, s
        return pos, tgt, sec


def encode(m: Message) -> bytes:
    """Message to bytes (little-endian header, then the plan: int32 lattice indices and
    targets; with search on float64 positions, then int32 targets and sectors, then the
    cond action if any)."""
    flags = ((_SETTLED * m.settled) | (_BEST * m.best) | (_COND * (m.cond is not None))
             | (_SEARCH * m.searching))
    cp, ct = m.cond if m.cond is not None and not m.searching else (-1, -1)
    head = _HEADER.pack(m.decision, m.round, m.sender, m.sweep, m.epoch, m.iteration, flags,
                        len(m.tgt), cp, ct)
    if m.sec is None:
        return head + np.concatenate([m.pos, m.tgt]).astype("<i4").tobytes()
    body = (np.asarray(m.pos, dtype="<f8").tobytes()
            + np.concatenate([m.tgt, m.sec]).astype("<i4").tobytes())
    tail = b"" if m.cond is None else _SEARCH_COND.pack(*m.cond)
    return head + body + tail


def decode(data: bytes) -> Message:
    """Inverse of :func:`encode`; raises ``ValueError`` on a malformed buffer."""
    if len(data) < _HEADER.size:
        raise ValueError("message too short")
    d, r, s, sw, k, t, flags, K, cp, ct = _HEADER.unpack_from(data)
    head = (d, r, s, sw, k, t, bool(flags & _SETTLED), bool(flags & _BEST))
    if flags & _SEARCH:
        size = _HEADER.size + 24 * K + (_SEARCH_COND.size if flags & _COND else 0)
        if len(data) != size:
            raise ValueError("message length does not match its horizon")
        o = _HEADER.size
        pos = np.frombuffer(data, dtype="<f8", count=2 * K, offset=o).reshape(K, 2)
        looks = np.frombuffer(data, dtype="<i4", count=2 * K, offset=o + 16 * K)
        looks = looks.astype(np.int64)
        x, y, ct, cs = (_SEARCH_COND.unpack_from(data, o + 24 * K) if flags & _COND
                        else (0.0, 0.0, -1, -1))
        cond_s = (x, y, ct, cs) if flags & _COND else None
        return Message(*head, pos.astype(float), looks[:K], cond_s, looks[K:])
    if len(data) != _HEADER.size + 8 * K:
        raise ValueError("message length does not match its horizon")
    body = np.frombuffer(data, dtype="<i4", offset=_HEADER.size).astype(np.int64)
    cond = (cp, ct) if flags & _COND else None
    return Message(*head, body[:K], body[K:], cond)


@dataclass(frozen=True)
class DecisionLog:
    """What happened in one decentralized decision (deterministic: no wall-clock times).

    Attributes
    ----------
    rounds : int                    rounds run (the decision ends early once every live
                                    agent is settled)
    sent : int                      messages sent (one per live ordered pair and round)
    received : int                  messages agents took from the transport (before the
                                    links decide whether they count)
    delivered : int                 messages that reached their receiver in time
    lost : int                      dropped by the loss draw
    out_of_range : int              dropped because the platforms were too far apart
    in_flight : int                 delayed messages still undelivered at the end
    ignored : int                   duplicates and messages older than one already heard
    stale : int                     ordered pairs (a, b) of live agents where a's final
                                    belief of b's plan is not b's final plan
    failed : tuple of int           agents lost during or before the decision; their
                                    platforms hold still (no move, no look)
    settled : (N,) bool             each agent had finished its schedule (or stopped
                                    changing) when the decision ended
    converged : (N,) bool or None   JSFP: the agent's sweeps ended at a verified
                                    equilibrium; None in other modes or if failed
    sweeps : (N,) int               sweeps each agent started (0 outside JSFP)
    completed : (N,) int            own players an agent still had to fill in alone when
                                    the round budget ran out
    """

    rounds: int
    sent: int
    received: int
    delivered: int
    lost: int
    out_of_range: int
    in_flight: int
    ignored: int
    stale: int
    failed: tuple[int, ...]
    settled: tuple[bool, ...]
    converged: tuple[bool | None, ...]
    sweeps: tuple[int, ...]
    completed: tuple[int, ...] = field(default=())
