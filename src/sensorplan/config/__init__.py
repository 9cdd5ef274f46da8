"""Validated input of ``sensorplan plan`` and ``sensorplan simulate``.

- :mod:`.decision`: the single-decision JSON (SPEC 7);
- :mod:`.simulate`: a scenario file or preset with command-line overrides;
- :mod:`.planners`: which settings a planner takes, and building it.

Scenario files themselves are :mod:`sensorplan.scenario_file`, study files
:mod:`sensorplan.study.file`, the strict models and their errors :mod:`sensorplan.validation`.
"""

from .decision import Decision, decision_from_dict, load_decision
from .planners import build_planner, planner_settings
from .simulate import PRESETS, SimulationConfig, load_simulation

__all__ = ["PRESETS", "Decision", "SimulationConfig", "build_planner", "decision_from_dict",
           "load_decision", "load_simulation", "planner_settings"]
