"""The decentralized planners' own settings, each declared once with its default, help and
rule (:func:`~sensorplan.limits.param`).

Each group is a frozen dataclass mixin; a planner lists the groups it takes
(:mod:`sensorplan.decentral.planners`) and :class:`~sensorplan.planners.registry.
PlannerSettings` checks them all in field order. This module imports neither numpy nor the
agents: the command line builds the ``sensorplan agents`` options (names, placeholders, help
and defaults) from these declarations (:func:`agent_params`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ..limits import Param, Range, declared_params, param
from ..planners.registry import PlannerSettings

TRANSPORTS = ("inproc", "bus")
GAME_MODES = ("jsfp", "best-response")


@dataclass(frozen=True)
class Rounds(PlannerSettings):
    """The round budget of a decision."""

    rounds: int = param(
        1000, bounds=Range(1, None), cli=("--rounds",), metavar="R",
        brief="Round budget of a decision (dec-jsfp, dec-independent)",
        help="The round budget R of a decision; it ends earlier when every agent has "
             "settled.")


@dataclass(frozen=True)
class Links(PlannerSettings):
    """The links between the platforms."""

    p_loss: float = param(
        0.0, bounds=Range(0.0, 1.0), cli=("--p-loss",), metavar="P",
        brief="Probability that a message is lost",
        help="The probability that a message is lost.")
    delay: int = param(
        0, bounds=Range(0, None), cli=("--delay",), metavar="D",
        brief="Rounds a message takes", help="The number of rounds a message takes.")
    comm_range: float = param(
        math.inf, bounds=Range(0.0, None, "m", lo_open=True, inf=True),
        cli=("--comm-range",), metavar="M", brief="Longest working link (ground distance)",
        help="The largest ground distance of a working link (inf: unlimited).")

    def _links(self) -> tuple[float, int, float]:
        return float(self.p_loss), int(self.delay), float(self.comm_range)


@dataclass(frozen=True)
class GameMode(PlannerSettings):
    """How the agents play the game."""

    mode: str = param(
        "jsfp", choices=GAME_MODES, noun="mode", cli=("--agent-mode",), metavar="MODE",
        brief="What the agents play: jsfp (the paper's, with inertia) or best-response",
        help="What the agents play: jsfp (the paper's, with inertia) or best-response.")


@dataclass(frozen=True)
class Transport(PlannerSettings):
    """Where the agents run and how long one waits for a peer."""

    transport: str = param(
        "inproc", choices=TRANSPORTS, noun="transport", cli=("--transport",),
        metavar="inproc|bus",
        brief="Agents in this process (inproc), or one process each on ZeroMQ (bus)",
        help="Where the agents run: all in this process (inproc) or one process each, "
             "talking over ZeroMQ (bus).")
    timeout: float = param(
        10.0, bounds=Range(0.0, None, "s", lo_open=True),
        help="On the bus: how long an agent waits for a peer before declaring it lost.")


#: The groups of settings, in the order ``sensorplan agents`` lists their options.
GROUPS = (Transport, Rounds, Links, GameMode)


def agent_params() -> dict[str, tuple[dataclasses.Field[object], Param]]:
    """Every decentralized planner's own setting that a ``sensorplan agents`` option sets:
    key -> (field, declaration), in the options' order."""
    return {f.name: (f, p) for group in GROUPS for f, p in declared_params(group) if p.cli}
