"""The built-in demo studies (``sensorplan demo [--scenario NAME]``)."""

from __future__ import annotations

from ..errors import ConfigError
from .file import parse_study
from .model import Study

#: The references every demo compares planning ahead with: random and myopic planning.
_REFERENCES = '''\
[[methods]]
name = "random"
planner = "random"

[[methods]]
name = "myopic"
planner = "pg"
horizon = 1
'''

#: The study ``sensorplan demo`` runs by default; ``studies/demo.toml`` holds the same text
#: (tested).
DEMO_STUDY = '''\
# The `sensorplan demo` study (built into the package; this file is the same study):
# where looking ahead pays. The paper's scenario with slow platforms (the `slow` preset:
# moves of 5 and 10 m per step, a quarter of the paper's), our defaults, a decision every
# step: random, myopic planning and planning three epochs ahead (OLF, K = 3) on the same
# paired runs. About a minute on 2 cores, report included:
#   sensorplan demo                              (or: make demo)
#   sensorplan study studies/demo.toml --out out/demo && sensorplan report out/demo
# The paper's scenario instead: sensorplan demo --scenario paper (studies/demo_paper.toml).
# Runs, steps and the seed were fixed before the runs that checked the headline's verdict
# on three seeds (docs/results.md, "The demo").
description = "Demo: slow platforms (5 or 10 m per step), where looking ahead pays; 40 paired runs"
runs = 40
steps = 100
seed = 4637

[scenario]
preset = "slow"

[defaults]
steps_per_epoch = 1        # a decision every step
objective = "cumulative"

''' + _REFERENCES + '''
[[methods]]
name = "OLF pg K=3"
planner = "pg"
horizon = 3
execution = "olf"
'''

#: The study ``sensorplan demo --scenario paper`` runs; ``studies/demo_paper.toml`` holds the
#: same text (tested).
PAPER_DEMO_STUDY = '''\
# The `sensorplan demo --scenario paper` study (built into the package; this file is the
# same study): the paper scenario with our defaults (probabilistic visibility, negative
# miss updates), a few short paired runs, the paper's planners plus the references. Under
# two minutes on 2 cores, report included:
#   sensorplan demo --scenario paper             (writes out/demo-paper)
#   sensorplan study studies/demo_paper.toml --out out/demo-paper
#   sensorplan report out/demo-paper
description = "Demo: the paper scenario with our defaults, 12 short paired runs"
runs = 12
steps = 60
seed = 20240601

[scenario]
preset = "paper"

[defaults]
steps_per_epoch = 2        # a decision every 2 steps, as in the paper's study

''' + _REFERENCES + '''
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

#: The demo studies by scenario name; the first is the default.
DEMO_STUDIES: dict[str, str] = {"slow": DEMO_STUDY, "paper": PAPER_DEMO_STUDY}


def demo_study(scenario: str = "slow") -> Study:
    """The built-in demo study of ``scenario`` (a key of :data:`DEMO_STUDIES`): ``slow``
    (the default, :data:`DEMO_STUDY`) or ``paper`` (:data:`PAPER_DEMO_STUDY`); another name
    is a :class:`~sensorplan.errors.ConfigError` naming ``--scenario``."""
    if scenario not in DEMO_STUDIES:
        raise ConfigError("--scenario", f"unknown demo scenario {scenario!r}; choose from "
                                        f"{', '.join(DEMO_STUDIES)}")
    return parse_study(DEMO_STUDIES[scenario], source=f"demo study ({scenario})")
