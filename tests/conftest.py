"""Shared fixtures: the suite's seeded generator and the problem factories of
``factories.py`` (the one module that builds test problems)::

    def test_something(rng, problem_factory, plan_factory):
        problem = problem_factory(rng, n_sensors=2, n_targets=3, horizon=2)
        plan = plan_factory(problem, rng, p_unassigned=0.2)
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

# The suite runs numba's kernels (in this process and in the commands it starts), as every
# command but ``plan`` does; tests/_compiled/test_aot.py runs the ahead-of-time ones and checks that
# they give the same plans. Without this the first ``plan`` a test starts would build them.
os.environ.setdefault("SENSORPLAN_AOT", "0")

# The commands the tests start see Ctrl-C as a terminal's foreground job does. A CI that runs
# the suite as a background job of a shell script starts it with Ctrl-C ignored; every command
# started from it would inherit that (and, as it should, keep ignoring Ctrl-C).
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from factories import make_problem, random_plan  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="session", autouse=True)
def warm_kernels() -> None:
    """Compile (or load from numba's disk cache) every compiled kernel once per session.

    Without it the first test that plans pays the one-off cost (seconds on a fresh clone),
    which makes that test look slow and its timing-sensitive checks flaky. Both warm-ups
    remember that they ran, so the planners' own calls to them are free afterwards.
    """
    from sensorplan.planners._chains_nb import warm_up
    from sensorplan.planners.epoch_game import warm_engine

    warm_up()           # covariance recursion, looks, the radar's batched kernels
    warm_engine()       # the planning engine's chain, gain and JSFP kernels


@pytest.fixture
def rng() -> np.random.Generator:
    """The suite's seeded generator (a fresh one per test)."""
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def problem_factory():
    """:func:`factories.make_problem`, as a fixture."""
    return make_problem


@pytest.fixture(scope="session")
def plan_factory():
    """:func:`factories.random_plan`, as a fixture."""
    return random_plan


@pytest.fixture
def nearest_on_path(monkeypatch):
    """examples/ importable (``nearest_planner``); afterwards the module is forgotten and the
    name ``nearest`` its import registered is removed again."""
    monkeypatch.syspath_prepend(str(EXAMPLES))
    yield
    sys.modules.pop("nearest_planner", None)
    from sensorplan.planners import PLANNERS
    from sensorplan.planners.registry import planner_names

    if "nearest" in planner_names():
        try:
            del PLANNERS["nearest"]
        except KeyError:                       # an entry point: not a registration
            pass
