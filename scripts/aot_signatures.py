"""Write ``src/sensorplan/_compiled/aot_signatures.py``: the kernels the planners call from
Python, with the argument types they are called with, for the ahead-of-time build
(``sensorplan._compiled.aot``).

    PYTHONPATH=src .venv/bin/python scripts/aot_signatures.py

It plans every case of the planner reference tests with every planner that takes it, the
example decision file, and decisions with detection, clutter and buildings, and records each
call that reaches a kernel from Python. Run it after changing a kernel's arguments; the test
``tests/_compiled/test_aot.py`` fails when ``sensorplan plan`` would need numba for the
example file.
"""

from __future__ import annotations

import importlib
import os
import pprint
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
os.environ["SENSORPLAN_AOT"] = "0"

from sensorplan._compiled import jit as _jit  # noqa: E402

CALLS: set[tuple[str, str, tuple]] = set()
OTHER: set[str] = set()          # called with a type no table can hold (read-only array...)
_call = _jit.Kernel.__call__


def _recording_call(self: _jit.Kernel, *args: object) -> object:
    key = _jit.arg_key(args)
    if key is not None:
        CALLS.add((self.__module__, self.__name__, key))
    else:
        OTHER.add(f"{self.__module__}.{self.__name__}")
    return _call(self, *args)


def main() -> None:
    import numpy as np

    from planner_reference import CASES
    from sensorplan.config import load_decision
    from sensorplan.planners import make_planner
    from sensorplan.planners.contract_problems import paper_problem, searching
    from sensorplan.planners.problem import PlanningProblem
    from sensorplan.models.sensors import SensorParams

    for name in ("planners._chains_nb", "planners._lattice_nb", "models.radar.batch",
                 "planners._pairs_nb", "planners._gains_nb", "planners.engine",
                 "planners.epoch_game",
                 "planners.potential_game",
                 "planners.refine", "planners.greedy", "planners.brute_force",
                 "planners.random_plan", "planners._search_nb", "planners.search"):
        importlib.import_module(f"sensorplan.{name}")
    # Every kernel the planners call exists by now: watch their calls.
    _jit.Kernel.__call__ = _recording_call          # type: ignore[method-assign]
    _jit.activate(patch=False)

    decision = load_decision(ROOT / "examples" / "problem.json", None)
    decision.make_planner().plan(decision.problem)
    for build, names, seed in CASES.values():
        problem = build()
        if problem.n_sensors * problem.n_targets > 400:
            continue                                    # same kernels, bigger arrays
        for name in names:
            make_planner(name).plan(problem, rng=seed)
    base = paper_problem(np.random.default_rng(3), horizon=2)
    radar = tuple(SensorParams(detection="swerling1", clutter_rate=2.0) for _ in base.sensors)
    town = np.array([[200.0, 200.0, 300.0, 300.0, 40.0], [400.0, 100.0, 450.0, 350.0, 80.0]])
    for kw in ({"sensors": radar}, {"buildings": town}, {"sensors": radar, "buildings": town},
               {"sensors": radar, "planning_detection": "ignore"},
               {"visibility": "mean"},
               {"objective": "terminal"}):
        fields = dict(means=base.means, covs=base.covs, positions=base.positions,
                      headings=base.headings, sensors=base.sensors, horizon=2)
        fields.update(kw)
        problem = PlanningProblem(**fields)
        for name in ("pg", "pg-refine", "sequential-greedy", "random"):
            make_planner(name).plan(problem, rng=0)
        make_planner("brute-force").plan(PlanningProblem(**{**fields, "horizon": 1}))
        # Search looks (the search term's kernels).
        found = searching(problem, np.random.default_rng(0), 6)
        for name in ("pg", "sequential-greedy"):
            make_planner(name).plan(found, rng=0)
    lines = ['"""The kernels the planners call from Python and their argument types (see',
             ":mod:`sensorplan._compiled.aot`); written by ``scripts/aot_signatures.py``.",
             '"""', "",
             "SIGNATURES: tuple = ("]
    for entry in sorted(CALLS, key=repr):
        lines.append(textwrap.indent(pprint.pformat(entry, width=94, compact=True) + ",",
                                     "    "))
    lines.append(")")
    out = ROOT / "src" / "sensorplan" / "_compiled" / "aot_signatures.py"
    out.write_text("\n".join(lines) + "\n")
    print(f"{len(CALLS)} signatures -> {out}")
    if OTHER:
        print(f"called with other types (numba's kernels will run): {sorted(OTHER)}")


if __name__ == "__main__":
    main()
