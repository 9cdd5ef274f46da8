"""What agents tell each other in a round, and what a decision records.

A :class:`Message` is the only thing an agent learns about another agent during a decision.
It travels as a few dozen bytes (:func:`encode` / :func:`decode`), so the in-process transport
and the message bus carry exactly the same content.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from .._types import IntArray

# decision, round, sender, sweep, epoch, iteration, flags, K, cond position, cond target
_HEADER = struct.Struct("<IIHHHHBHii")
_SETTLED, _BEST, _COND = 1, 2, 4


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
                          ``R_1..R_K`` and targets, -1 where unassigned
    cond : (int, int) or None
                          the action (lattice index, target) its player (sender, epoch) takes
                          at the end of the round unless the round turns out to be an
                          equilibrium of the epoch game (JSFP only)
    """

    decision: int
    round: int
    sender: int
    sweep: int
    epoch: int
    iteration: int
    settled: bool
    best: bool
    pos: IntArray
    tgt: IntArray
    cond: tuple[int, int] | None = None

    def plan_after(self, equilibrium: bool) -> tuple[IntArray, IntArray]:
        """The sender's plan after the round: ``cond`` applied unless ``equilibrium``."""
        pos, tgt = self.pos.copy(), self.tgt.copy()
        if self.cond is not None and not equilibrium:
            pos[self.epoch - 1], tgt[self.epoch - 1] = self.cond
        return pos, tgt


def encode(m: Message) -> bytes:
    """Message to bytes (little-endian header, then the int32 plan)."""
    flags = (_SETTLED * m.settled) | (_BEST * m.best) | (_COND * (m.cond is not None))
    cp, ct = m.cond if m.cond is not None else (-1, -1)
    head = _HEADER.pack(m.decision, m.round, m.sender, m.sweep, m.epoch, m.iteration, flags,
                        len(m.pos), cp, ct)
    return head + np.concatenate([m.pos, m.tgt]).astype("<i4").tobytes()


def decode(data: bytes) -> Message:
    """Inverse of :func:`encode`; raises ``ValueError`` on a malformed buffer."""
    if len(data) < _HEADER.size:
        raise ValueError("message too short")
    d, r, s, sw, k, t, flags, K, cp, ct = _HEADER.unpack_from(data)
    if len(data) != _HEADER.size + 8 * K:
        raise ValueError("message length does not match its horizon")
    body = np.frombuffer(data, dtype="<i4", offset=_HEADER.size).astype(np.int64)
    cond = (cp, ct) if flags & _COND else None
    return Message(d, r, s, sw, k, t, bool(flags & _SETTLED), bool(flags & _BEST),
                   body[:K], body[K:], cond)


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
