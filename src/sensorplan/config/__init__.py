"""Validated input of ``sensorplan plan`` and ``sensorplan simulate``.

- :mod:`.decision`: the single-decision JSON of ``sensorplan plan``;
- :mod:`.simulate`: a scenario file or preset with command-line overrides;
- :mod:`.planners`: checking a planner's settings from a file, and building it.

Scenario files themselves are :mod:`sensorplan.config.scenario`, study files
:mod:`sensorplan.study.file`, the strict models and their errors
:mod:`sensorplan.config.validation`.
The names below are imported on first use, so that ``sensorplan plan`` does not load the
scenario machinery.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .decision import Decision, decision_from_dict, load_decision
    from .planners import build_planner, planner_settings
    from .simulate import PRESETS, SimulationConfig, load_simulation

__all__ = ["PRESETS", "Decision", "SimulationConfig", "build_planner", "decision_from_dict",
           "load_decision", "load_simulation", "planner_settings"]


def __getattr__(name: str) -> Any:
    if name in ("Decision", "decision_from_dict", "load_decision"):
        from . import decision as module
    elif name in ("build_planner", "planner_settings"):
        from . import planners as module  # type: ignore[no-redef]
    elif name in ("PRESETS", "SimulationConfig", "load_simulation"):
        from . import simulate as module  # type: ignore[no-redef]
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value
