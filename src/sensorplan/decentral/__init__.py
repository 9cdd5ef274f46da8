"""Decentralized planning: one agent per platform, negotiating plans over links.

The planners ``dec-jsfp``, ``dec-independent`` and ``dec-sequential`` are known by name
everywhere (the registry imports :mod:`.planners` on first use). See ``docs/decentral.md``
for the protocol.

Importing this package loads nothing else (no numpy): the command line's help reads the
planners' settings from :mod:`.params`; every name below is imported on first use.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .agent import MODES, Agent, AgentSpec
    from .decision import AgentOutcome, InprocTransport, assemble, run_inproc
    from .episode import recording, run_agents
    from .links import Inbox, LinkModel, decision_key
    from .messages import DecisionLog, Message, decode, encode
    from .planners import (
                           DecentralIndependentPlanner,
                           DecentralJSFPPlanner,
                           DecentralResult,
                           DecentralSequentialPlanner,
    )

#: Each public name -> the module that defines it.
_HOME = {
    **dict.fromkeys(("MODES", "Agent", "AgentSpec"), "agent"),
    **dict.fromkeys(("AgentOutcome", "InprocTransport", "assemble", "run_inproc"), "decision"),
    **dict.fromkeys(("recording", "run_agents"), "episode"),
    **dict.fromkeys(("Inbox", "LinkModel", "decision_key"), "links"),
    **dict.fromkeys(("DecisionLog", "Message", "decode", "encode"), "messages"),
    **dict.fromkeys(("DecentralIndependentPlanner", "DecentralJSFPPlanner", "DecentralResult",
                     "DecentralSequentialPlanner"), "planners"),
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{_HOME[name]}", __name__), name)
    globals()[name] = value
    return value


__all__ = ["MODES", "Agent", "AgentOutcome", "AgentSpec", "DecentralIndependentPlanner",
           "DecentralJSFPPlanner", "DecentralResult", "DecentralSequentialPlanner",
           "DecisionLog", "Inbox", "InprocTransport", "LinkModel", "Message", "assemble",
           "decision_key", "decode", "encode", "recording", "run_agents", "run_inproc"]
