"""The planners' speed-ups change no decision: plans equal those recorded before them.

``tests/data/planner_reference.npz`` was written by ``tests/planner_reference.py`` with the
code of commit 5a3b30c, before the engine's speed-ups; the same problem and seed must give the
same plan (the same targets, positions to the lattice's 1e-6 m), the same convergence and
sweep count, and the same Phi to 1e-12 relative.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner_reference import CASES
from sensorplan.planners import make_planner

REFERENCE = np.load(Path(__file__).parents[1] / "data" / "planner_reference.npz")
PARAMS = [pytest.param(case, name, id=f"{case}-{name}")
          for case, (_, names, _) in CASES.items() for name in names]


@pytest.mark.parametrize("case,name", PARAMS)
def test_plan_equals_the_recorded_reference(case, name):
    build, _, seed = CASES[case]
    result = make_planner(name).plan(build(), rng=seed)
    key = f"{case}/{name}"
    np.testing.assert_array_equal(result.plan.targets, REFERENCE[f"{key}/targets"])
    # Positions to the lattice tolerance, Phi to rtol 1e-12: a refactor may reorder a sum.
    np.testing.assert_allclose(result.plan.positions, REFERENCE[f"{key}/positions"],
                               rtol=0.0, atol=1e-6)
    np.testing.assert_allclose(result.potential, float(REFERENCE[f"{key}/potential"]),
                               rtol=1e-12, atol=0.0)
    converged = int(REFERENCE[f"{key}/converged"])
    assert result.converged == (None if converged < 0 else bool(converged))
    sweeps = int(REFERENCE[f"{key}/sweeps"])
    assert result.sweeps == (None if sweeps < 0 else sweeps)
