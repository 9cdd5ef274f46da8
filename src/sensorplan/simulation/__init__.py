"""The closed loop: a scenario's truth, sensing, the tracker and a planner, run step by step.

- :mod:`.run`: one run (:func:`run_episode`), its record (:class:`Episode`) and its random
  streams (:func:`run_streams`);
- :mod:`.settings`: how a run plans, executes and tracks (:class:`RunSettings`);
- :mod:`.scenario`: the world, the targets' truth models and the sensors;
- :mod:`.replay`: one run of a study simulated again.

The names below are imported on first use.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .run import EXECUTIONS, STREAMS, Episode, run_episode, run_streams
    from .settings import RunSettings

__all__ = ["EXECUTIONS", "STREAMS", "Episode", "RunSettings", "run_episode", "run_streams"]


def __getattr__(name: str) -> Any:
    if name in ("EXECUTIONS", "STREAMS", "Episode", "run_episode", "run_streams"):
        from . import run as module
    elif name == "RunSettings":
        from . import settings as module  # type: ignore[no-redef]
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value
