"""The message bus: one operating-system process per agent, on ZeroMQ.

The coordinator (the simulator's side) starts the agent processes, sends each decision's
problem, and collects every agent's outcome. Agents exchange round messages directly with
each other (PUSH to each peer's PULL socket over ``ipc://`` endpoints in a private temporary
directory); the coordinator is not on that path.

Lifecycle: :meth:`Bus.close` (also run at garbage collection and interpreter exit) tells
the agents to stop, waits briefly, then terminates and finally kills any still running, and
reaps them all. An agent exits by itself when its parent dies. A decision never hangs:
every wait is bounded by ``timeout`` seconds without word from an agent, after which that
agent is declared lost, killed, and its platform holds still for the rest of the run.
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
import weakref
from pathlib import Path
from typing import Self

import numpy as np
import zmq

from ..planners.problem import PlanningProblem
from .agent import AgentSpec
from .decision import AgentOutcome
from .links import LinkModel
from .worker import POLL, endpoint

START_TIMEOUT = 120.0       # s: importing numpy/numba and loading compiled kernels
_OPEN: weakref.WeakSet[Bus] = weakref.WeakSet()


def open_buses() -> list[Bus]:
    """Every bus of this process that is not closed yet."""
    return [b for b in list(_OPEN) if not b.closed]


def _package_root() -> str:
    return str(Path(__file__).resolve().parents[2])


class _Processes:
    """The resources of a bus; closing them must not need the Bus object (finalizer)."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[bytes]] = []
        self.zctx: zmq.Context | None = None
        self.router: zmq.Socket | None = None
        self.directory: str | None = None

    def close(self) -> None:
        if self.router is not None:
            for i, p in enumerate(self.procs):
                if p.poll() is None:
                    try:
                        self.router.send_multipart([b"a%d" % i, b"stop", b""], zmq.NOBLOCK)
                    except zmq.ZMQError:
                        pass
        deadline = time.monotonic() + 2.0
        for p in self.procs:
            try:
                p.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(1.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if self.router is not None:
            self.router.close(0)
            self.router = None
        if self.zctx is not None:
            self.zctx.term()
            self.zctx = None
        if self.directory is not None:
            shutil.rmtree(self.directory, ignore_errors=True)
            self.directory = None


class Bus:
    """N agent processes and the coordinator's socket.

    Parameters
    ----------
    n_agents : int
    timeout : float    seconds without word from an agent before it is declared lost
    """

    def __init__(self, n_agents: int, timeout: float = 10.0) -> None:
        self.n_agents, self.timeout = n_agents, float(timeout)
        self.failed: set[int] = set()
        self.decision = 0
        self.closed = False
        self._res = _Processes()
        self._finalizer = weakref.finalize(self, self._res.close)
        _OPEN.add(self)
        try:
            self._start()
        except BaseException:
            self.close()
            raise

    def _start(self) -> None:
        res = self._res
        res.directory = tempfile.mkdtemp(prefix="sensorplan-bus-")     # private: mode 0700
        res.zctx = zmq.Context()
        res.router = res.zctx.socket(zmq.ROUTER)
        res.router.setsockopt(zmq.LINGER, 0)
        res.router.bind(endpoint(res.directory, "coordinator"))
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [_package_root()] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
        for i in range(self.n_agents):
            res.procs.append(subprocess.Popen(
                [sys.executable, "-m", "sensorplan.decentral.worker", "--dir", res.directory,
                 "--index", str(i), "--agents", str(self.n_agents), "--parent",
                 str(os.getpid())], env=env, stdin=subprocess.DEVNULL))
        ready: set[int] = set()
        deadline = time.monotonic() + START_TIMEOUT
        while len(ready) < self.n_agents:
            if time.monotonic() > deadline:
                raise RuntimeError("agent processes did not start in time")
            for i, p in enumerate(res.procs):
                if p.poll() is not None:
                    raise RuntimeError(f"agent process {i} exited at start (status "
                                       f"{p.returncode})")
            if res.router.poll(int(POLL * 1000)):
                ident, kind, _ = res.router.recv_multipart()
                if kind == b"ready":
                    ready.add(int(ident[1:]))

    @property
    def pids(self) -> tuple[int, ...]:
        """Process ids of every agent process started (lost ones included)."""
        return tuple(p.pid for p in self._res.procs)

    def _send(self, i: int, kind: bytes, payload: bytes = b"") -> None:
        assert self._res.router is not None
        try:
            self._res.router.send_multipart([b"a%d" % i, kind, payload], zmq.NOBLOCK)
        except zmq.ZMQError:
            pass

    def _lose(self, i: int, live: set[int]) -> None:
        """Agent ``i`` is silent or dead: kill it, tell the others, hold its platform."""
        self.failed.add(i)
        live.discard(i)
        p = self._res.procs[i]
        if p.poll() is None:
            p.kill()
        p.wait()
        for j in sorted(live):
            self._send(j, b"dead", str(i).encode())

    def decide(self, problem: PlanningProblem, spec: AgentSpec, link: LinkModel,
               gen: np.random.Generator) -> tuple[dict[int, AgentOutcome], set[int]]:
        """Run one decision on the agent processes.

        Returns the outcomes of the agents that finished it and the set of lost agents.
        """
        if self.closed:
            raise RuntimeError("the bus is closed")
        router = self._res.router
        assert router is not None
        self.decision += 1
        live = set(range(self.n_agents)) - self.failed
        job = pickle.dumps({"decision": self.decision, "problem": problem, "spec": spec,
                            "link": link, "gen": gen, "failed": tuple(sorted(self.failed)),
                            "timeout": self.timeout})
        for i in sorted(live):
            self._send(i, b"decide", job)
        results: dict[int, AgentOutcome] = {}
        heard = {i: time.monotonic() for i in live}
        while set(results) < live:
            if router.poll(int(POLL * 1000)):
                while router.poll(0):
                    ident, kind, payload = router.recv_multipart()
                    i = int(ident[1:])
                    if i not in live:
                        continue
                    heard[i] = time.monotonic()
                    if kind == b"result":
                        results[i] = pickle.loads(payload)
            now = time.monotonic()
            for i in sorted(live - set(results)):
                if self._res.procs[i].poll() is not None or now - heard[i] > self.timeout:
                    self._lose(i, live)
        return {i: r for i, r in results.items() if i in live}, set(self.failed)

    def close(self) -> None:
        """Stop every agent process and release the sockets (idempotent)."""
        self.closed = True
        _OPEN.discard(self)
        self._finalizer()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
