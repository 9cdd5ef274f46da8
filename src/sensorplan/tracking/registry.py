"""The trackers by kind (``tracker.kind`` of the run settings), imported when used.

Importing this module loads nothing else: the settings and the command line's help read the
kinds without loading numpy.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Tracker kind -> ``module:Class``.
TRACKERS: dict[str, str] = {
    "known": "sensorplan.tracking.tracker:KnownTargetTracker",
    "pmb": "sensorplan.tracking.pmb.tracker:PMBTracker",
    "gnn": "sensorplan.tracking.gnn:GNNTracker",
}


def tracker_kinds() -> tuple[str, ...]:
    """The tracker kinds, in registration order."""
    return tuple(TRACKERS)


def tracker_class(kind: str) -> Any:
    """The class of tracker ``kind`` (KeyError for an unknown kind)."""
    module, name = TRACKERS[kind].split(":")
    return getattr(importlib.import_module(module), name)
