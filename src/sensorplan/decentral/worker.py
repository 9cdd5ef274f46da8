"""An agent process on the message bus: ``python -m sensorplan.decentral.worker``.

The process binds a PULL socket for its peers' round messages, connects one PUSH socket to
each peer and a DEALER socket to the coordinator, says ``ready`` and then serves decisions
until told to stop. It exits when the coordinator says ``stop``, when its parent process
is gone (checked at least every 0.2 s while it waits), or on SIGINT/SIGTERM.

Control frames (coordinator ROUTER <-> agent DEALER): ``[kind, payload]`` with kind
``ready`` / ``beat`` / ``result`` from the agent and ``decide`` / ``dead`` / ``stop`` to it.
"""

from __future__ import annotations

import argparse
import os
import pickle
import shutil
import signal
import sys
import time
from collections import defaultdict
from typing import Any

import zmq

from .agent import Agent
from .decision import decision_context, make_agent, outcome
from .links import Inbox
from .messages import Message, decode, encode

POLL = 0.2           # s: longest wait between checks that the parent is alive


def endpoint(directory: str, name: str) -> str:
    return f"ipc://{os.path.join(directory, name)}"


class Stop(Exception):
    """The coordinator said stop, or is gone."""


class Orphaned(Stop):
    """The coordinator is gone without cleaning up."""


class AgentProcess:
    """One agent's sockets and its decision loop."""

    def __init__(self, directory: str, index: int, n_agents: int, parent: int) -> None:
        self.i, self.n, self.parent = index, n_agents, parent
        self.zctx = zmq.Context()
        self.control = self.zctx.socket(zmq.DEALER)
        self.control.setsockopt(zmq.IDENTITY, b"a%d" % index)
        self.control.setsockopt(zmq.LINGER, 0)
        self.control.connect(endpoint(directory, "coordinator"))
        self.pull = self.zctx.socket(zmq.PULL)
        self.pull.setsockopt(zmq.LINGER, 0)
        self.pull.bind(endpoint(directory, f"agent-{index}"))
        self.push: dict[int, zmq.Socket] = {}
        for j in range(n_agents):
            if j != index:
                s = self.zctx.socket(zmq.PUSH)
                s.setsockopt(zmq.LINGER, 0)
                s.setsockopt(zmq.SNDHWM, 10_000)
                s.connect(endpoint(directory, f"agent-{j}"))
                self.push[j] = s
        self.poller = zmq.Poller()
        self.poller.register(self.pull, zmq.POLLIN)
        self.poller.register(self.control, zmq.POLLIN)
        self.last_beat = time.monotonic()

    # ------------------------------------------------------------------ plumbing
    def check_parent(self) -> None:
        if os.getppid() != self.parent:
            raise Orphaned

    def beat(self, every: float) -> None:
        """Tell the coordinator this agent is alive (at most every ``every`` s)."""
        now = time.monotonic()
        if now - self.last_beat >= every:
            self.control.send_multipart([b"beat", b""])
            self.last_beat = now

    def serve(self) -> None:
        self.control.send_multipart([b"ready", str(os.getpid()).encode()])
        while True:
            self.check_parent()
            if not self.control.poll(int(POLL * 1000)):
                continue
            kind, payload = self.control.recv_multipart()
            if kind == b"stop":
                return
            if kind == b"decide":
                job = pickle.loads(payload)
                result = self.decide(job)
                self.control.send_multipart([b"result", pickle.dumps(result)])
            # a ``dead`` notice between decisions concerns a finished decision: ignore

    def close(self) -> None:
        for s in [self.control, self.pull, *self.push.values()]:
            s.close(0)
        self.zctx.term()

    # ------------------------------------------------------------------ one decision
    def decide(self, job: dict[str, Any]) -> Any:
        spec, link, decision = job["spec"], job["link"], job["decision"]
        timeout = job["timeout"]
        every = min(0.5, timeout / 4)
        ctx = decision_context(job["problem"])     # the same on every agent: tracks, grid
        agent = make_agent(ctx, self.i, spec, job["gen"], decision, job["failed"])
        inbox = Inbox(self.i, link)
        live = set(range(self.n)) - set(job["failed"])
        early: defaultdict[int, dict[int, Message]] = defaultdict(dict)
        sent, rounds = 0, 0
        self.received = 0
        round_s, work_s = [], []
        for r in range(1, spec.budget(self.n) + 1):
            t0 = time.perf_counter()
            msg = agent.step(r)
            work = time.perf_counter() - t0
            settled = msg.settled
            delivered: list[Message] = []
            if spec.communicate:
                data = encode(msg)
                for j in sorted(live - {self.i}):
                    try:
                        self.push[j].send(data, zmq.NOBLOCK)
                        sent += 1
                    except zmq.Again:           # a lost peer stopped reading
                        pass
                got = self.collect(r, live, early, agent, inbox, decision, timeout, every)
                for m in got.values():
                    inbox.accept(m)
                settled = settled and all(m.settled for m in got.values())
                t1 = time.perf_counter()
                delivered = inbox.due(r)
            else:
                t1 = time.perf_counter()
            agent.end_round(r, delivered)
            t2 = time.perf_counter()
            round_s.append(t2 - t0)
            work_s.append(work + t2 - t1)
            rounds = r
            self.beat(every)
            if settled:
                break
        agent.complete()
        return outcome(agent, inbox if spec.communicate else None, rounds, sent,
                       self.received, round_s, work_s)

    def collect(self, r: int, live: set[int], early: defaultdict[int, dict[int, Message]],
                agent: Agent, inbox: Inbox, decision: int, timeout: float,
                every: float) -> dict[int, Message]:
        """Wait for round ``r``'s message of every live peer; a silent peer is lost.

        Messages of later rounds are kept for their round; a message of an earlier round
        (possible only after a timeout) goes to the inbox, which ignores what it has seen.
        """
        got = early.pop(r, {})
        deadline = time.monotonic() + timeout
        while True:
            missing = [j for j in live if j != self.i and j not in got]
            if not missing:
                return got
            left = deadline - time.monotonic()
            if left <= 0:
                for j in missing:
                    self.lose(j, live, got, agent, inbox)
                continue
            for sock, _ in self.poller.poll(int(min(left, POLL) * 1000) + 1):
                if sock is self.pull:
                    while self.pull.poll(0):
                        m = decode(self.pull.recv())
                        self.received += 1
                        if m.decision != decision or m.sender not in live:
                            inbox.ignored += 1
                        elif m.round == r:
                            if m.sender in got:
                                inbox.ignored += 1     # duplicate: the first one counts
                            else:
                                got[m.sender] = m
                        elif m.round > r:
                            early[m.round].setdefault(m.sender, m)
                        else:
                            inbox.accept(m)
                else:
                    kind, payload = self.control.recv_multipart()
                    if kind == b"stop":
                        raise Stop
                    if kind == b"dead":
                        self.lose(int(payload), live, got, agent, inbox)
            self.check_parent()
            self.beat(every)

    def lose(self, j: int, live: set[int], got: dict[int, Message], agent: Agent,
             inbox: Inbox) -> None:
        """Peer ``j`` is gone: forget it for the rest of the run."""
        if j in live and j != self.i:
            live.discard(j)
            got.pop(j, None)
            agent.peer_failed(j)
            inbox.drop_sender(j)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", required=True)
    ap.add_argument("--index", type=int, required=True)
    ap.add_argument("--agents", type=int, required=True)
    ap.add_argument("--parent", type=int, required=True)
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    proc = None
    orphaned = False
    try:
        from ..planners._chains_nb import warm_up
        from ..planners.epoch_game import warm_engine

        from .._compiled.jit import is_active

        warm_up()                # load the compiled kernels before saying ready: a first
        warm_engine()           # compile would otherwise look like a silent, lost agent
        if is_active():
            from .._compiled.prepare import warm_listed

            warm_listed()        # the radar's kernels too, which a searching decision calls
        proc = AgentProcess(args.dir, args.index, args.agents, args.parent)
        proc.serve()
    except Orphaned:
        orphaned = True
    except (Stop, KeyboardInterrupt, SystemExit):
        pass                     # interrupted or told to stop: a quiet, clean exit
    finally:
        if proc is not None:
            proc.close()
    if orphaned:                 # nobody else will remove the socket directory
        shutil.rmtree(args.dir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
