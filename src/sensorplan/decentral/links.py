"""Simulated links: range, seeded loss and delay, decided at the receiver.

Whether a message counts depends only on the decision's key, the round, the sender and the
receiver (never on arrival order or process timing), so the in-process transport and the
message bus deliver exactly the same messages. :class:`Inbox` is the receiver's side and is
shared by both transports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._types import FloatArray
from .messages import Message


def decision_key(gen: np.random.Generator) -> tuple[int, ...]:
    """Non-negative integers identifying ``gen``'s current state (nothing is drawn).

    The decision's links are keyed by the generator the planner is given, so a seeded run
    draws the same losses every time and different decisions draw different ones.
    """
    words: list[int] = []

    def walk(v: Any) -> None:
        if isinstance(v, dict):
            for key in sorted(v):
                walk(v[key])
        elif isinstance(v, (bool, np.bool_)):
            words.append(int(v))
        elif isinstance(v, (int, np.integer)):
            words.append(int(v) % (1 << 128))
        elif isinstance(v, np.ndarray):
            words.extend(int(x) % (1 << 64) for x in v.ravel().tolist())
        elif isinstance(v, str):
            words.extend(v.encode())

    walk(gen.bit_generator.state)
    return tuple(words)


@dataclass(frozen=True)
class LinkModel:
    """Which messages of a decision arrive, and when.

    Attributes
    ----------
    key : tuple of int     :func:`decision_key` of the decision
    positions : (N, 2)     platform ground positions at the decision (m)
    p_loss : float         probability that a message is lost, independently per
                           (round, sender, receiver)
    delay : int            a message sent in round r is delivered at the end of round
                           r + delay (0: the same round)
    comm_range : float     largest ground distance of a working link (m); inf = unlimited
    """

    key: tuple[int, ...]
    positions: FloatArray
    p_loss: float = 0.0
    delay: int = 0
    comm_range: float = math.inf

    def in_range(self, sender: int, receiver: int) -> bool:
        if math.isinf(self.comm_range):
            return True
        d = self.positions[sender] - self.positions[receiver]
        return bool(math.hypot(d[0], d[1]) <= self.comm_range)

    def lost(self, rnd: int, sender: int, receiver: int) -> bool:
        """The loss draw of one message: its own generator keyed by (decision, r, s, d)."""
        if self.p_loss <= 0.0:
            return False
        if self.p_loss >= 1.0:
            return True
        ss = np.random.SeedSequence(self.key, spawn_key=(rnd, sender, receiver))
        return bool(np.random.default_rng(ss).random() < self.p_loss)


@dataclass
class Inbox:
    """A receiver's side of its links: filters, buffers and releases messages by round.

    :meth:`accept` takes every message that physically reaches the receiver, in any order
    and any number of times; :meth:`due` releases, at the end of round r, the messages that
    count and whose delay has passed, each (sender, round) once.
    """

    me: int
    link: LinkModel
    pending: dict[tuple[int, int], Message] = field(default_factory=dict)
    seen: set[tuple[int, int]] = field(default_factory=set)
    delivered: int = 0
    lost: int = 0
    out_of_range: int = 0
    ignored: int = 0

    def accept(self, m: Message) -> None:
        key = (m.sender, m.round)
        if m.sender == self.me or key in self.seen:
            self.ignored += 1                       # a duplicate: idempotent
            return
        self.seen.add(key)
        if not self.link.in_range(m.sender, self.me):
            self.out_of_range += 1
        elif self.link.lost(m.round, m.sender, self.me):
            self.lost += 1
        else:
            self.pending[key] = m

    def due(self, rnd: int) -> list[Message]:
        """Messages delivered at the end of round ``rnd``, ordered by (sender, round)."""
        keys = sorted(k for k in self.pending if k[1] + self.link.delay <= rnd)
        out = [self.pending.pop(k) for k in keys]
        self.delivered += len(out)
        return out

    def drop_sender(self, sender: int) -> None:
        """Forget what a failed agent sent and has not arrived yet."""
        for key in [k for k in self.pending if k[0] == sender]:
            del self.pending[key]
