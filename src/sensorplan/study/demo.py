"""The built-in demo study (``sensorplan demo``)."""

from __future__ import annotations

from .file import parse_study
from .model import Study

#: The study ``sensorplan demo`` runs; ``studies/demo.toml`` holds the same text (tested).
DEMO_STUDY = '''\
# The `sensorplan demo` study (built into the package; this file is the same study):
# the paper scenario with our defaults (probabilistic visibility, negative miss updates),
# a few short paired runs, the paper's planners plus the references. Under two minutes
# on 2 cores, report included:
#   sensorplan demo                              (or: make demo)
#   sensorplan study studies/demo.toml --out out/demo && sensorplan report out/demo
description = "Demo: the paper scenario with our defaults, 12 short paired runs"
runs = 12
steps = 60
seed = 20240601

[scenario]
preset = "paper"

[defaults]
steps_per_epoch = 2        # a decision every 2 steps, as in the paper's study

[[methods]]
name = "random"
planner = "random"

[[methods]]
name = "myopic"
planner = "pg"
horizon = 1

[[methods]]
name = "OL pg K=3"
planner = "pg"
horizon = 3
execution = "ol"

[[methods]]
name = "OLF pg K=3"
planner = "pg"
horizon = 3
execution = "olf"

[[methods]]
name = "OLF sequential-greedy K=3"
planner = "sequential-greedy"
horizon = 3
execution = "olf"
'''


def demo_study() -> Study:
    """The built-in demo study (:data:`DEMO_STUDY`)."""
    return parse_study(DEMO_STUDY, source="demo study")
