"""Decentralized planning: one agent per platform, negotiating plans over links.

The planners ``dec-jsfp``, ``dec-independent`` and ``dec-sequential`` are known by name
everywhere (the registry imports :mod:`.planners` on first use). See ``docs/decentral.md``
for the protocol.
"""

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

__all__ = ["MODES", "Agent", "AgentOutcome", "AgentSpec", "DecentralIndependentPlanner",
           "DecentralJSFPPlanner", "DecentralResult", "DecentralSequentialPlanner",
           "DecisionLog", "Inbox", "InprocTransport", "LinkModel", "Message", "assemble",
           "decision_key", "decode", "encode", "recording", "run_agents", "run_inproc"]
