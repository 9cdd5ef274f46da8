"""Closed-loop runs with agents: record every decision's log and never leak processes.

:func:`recording` collects the :class:`DecisionLog` of every decentralized decision taken
while it is active (in this thread or task), so a study can wrap
:func:`sensorplan.simulation.run.run_episode` without changing it. :func:`run_agents` runs one
episode that way and stops every agent process the episode started, however it ends.
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np

from .messages import DecisionLog

if TYPE_CHECKING:
    from ..simulation.run import Episode, RunSettings
    from ..simulation.scenario import Scenario

_RECORDERS: contextvars.ContextVar[tuple[list[DecisionLog], ...]] = contextvars.ContextVar(
    "sensorplan_decentral_recorders", default=())


@contextmanager
def recording() -> Iterator[list[DecisionLog]]:
    """Context manager yielding a list that receives each decision's log, in order."""
    logs: list[DecisionLog] = []
    token = _RECORDERS.set(_RECORDERS.get() + (logs,))
    try:
        yield logs
    finally:
        _RECORDERS.reset(token)


def record(log: DecisionLog) -> None:
    """Append ``log`` to every active :func:`recording`."""
    for logs in _RECORDERS.get():
        logs.append(log)


def run_agents(scenario: Scenario, settings: RunSettings,
               seed: int | np.random.SeedSequence,
               progress: Callable[[int, int], None] | None = None,
               ) -> tuple[Episode, list[DecisionLog]]:
    """One closed-loop episode with a decentralized planner; every agent process it
    started is stopped when it returns or raises (also on KeyboardInterrupt).

    Returns the episode and the log of each of its decisions.
    """
    from ..simulation.run import run_episode
    from .bus import open_buses

    before = {id(b) for b in open_buses()}
    try:
        with recording() as logs:
            episode = run_episode(scenario, settings, seed, progress)
    finally:
        for bus in open_buses():
            if id(bus) not in before:
                bus.close()
    return episode, logs


__all__ = ["record", "recording", "run_agents"]
