"""The closed loop: a scenario's truth, sensing, the tracker and a planner, run step by step.

- :mod:`.run`: one run (:func:`run_episode`), its record (:class:`Episode`) and its random
  streams (:func:`run_streams`);
- :mod:`.settings`: how a run plans, executes and tracks (:class:`RunSettings`);
- :mod:`.scenario`: the world, the targets' truth models and the sensors;
- :mod:`.replay`: one run of a study simulated again.

The names below are imported on first use.
"""

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .run import EXECUTIONS, STREAMS, Episode, run_episode, run_streams
    from .settings import RunSettings

__all__ = ["EXECUTIONS", "STREAMS", "Episode", "RunSettings", "run_episode", "run_streams"]


#: Each public name -> the module that defines it.
_HOME = {"EXECUTIONS": "run", "STREAMS": "run", "Episode": "run", "run_episode": "run",
         "run_streams": "run", "RunSettings": "settings"}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    globals()[name] = value
    return value
