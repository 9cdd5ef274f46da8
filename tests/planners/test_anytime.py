"""Planning on a deadline: a time budget stops a planner with the best complete plan so far.

The wall clock is replaced by a counter (every reading advances it by one "second"), so a
budget of n stops a planner at a known check, independently of the machine's speed.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from factories import paper_problem, tiny_problem
from planner_reference import scale_problem
from sensorplan.errors import ConfigError
from sensorplan.planners.information import potential
from sensorplan.planners import anytime, make_planner
from sensorplan.planners.problem import check_plan

BUDGETED = ("pg", "pg-refine", "sequential-greedy")


class CountingClock:
    """A clock that advances by 1 at every reading."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


def _problems():
    rng = np.random.default_rng(41)
    return [paper_problem(rng, horizon=3), tiny_problem(rng, objective="cumulative"),
            paper_problem(rng, horizon=2, visibility="mean", n_sensors=4, n_targets=6)]


@pytest.mark.parametrize("name", BUDGETED)
def test_a_budget_far_larger_than_needed_gives_the_unbudgeted_result(name):
    for problem in _problems():
        free = make_planner(name).plan(problem, rng=5)
        timed = make_planner(name, time_budget=1e6).plan(problem, rng=5)
        np.testing.assert_array_equal(timed.plan.targets, free.plan.targets)
        np.testing.assert_array_equal(timed.plan.positions, free.plan.positions)
        assert timed.potential == free.potential
        assert timed.converged == free.converged and timed.sweeps == free.sweeps
        assert timed.trace == free.trace
        assert not timed.budget_exhausted and not free.budget_exhausted


@pytest.mark.parametrize("name", BUDGETED)
def test_a_tiny_budget_still_returns_a_feasible_complete_plan(name):
    for problem in _problems() + [scale_problem(n_sensors=6, n_targets=12, horizon=4)]:
        result = make_planner(name, time_budget=1e-6).plan(problem, rng=1)
        check_plan(problem, result.plan)                       # feasible and complete
        phi, info = potential(problem, result.plan)
        np.testing.assert_allclose(result.potential, phi, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(result.information, info, rtol=1e-9, atol=1e-12)
        assert result.budget_exhausted and result.converged is False
        assert result.potential > 0.0                # the first plan looks at something


def _run_with_checks(monkeypatch, name, problem, budget):
    """Run with the counting clock; record (Phi seen, plan) at every check."""
    monkeypatch.setattr(anytime, "clock", CountingClock())
    seen = []
    monkeypatch.setattr(anytime, "CHECK_HOOK", lambda phi, plan: seen.append((phi, plan)))
    result = make_planner(name, time_budget=budget).plan(problem, rng=2)
    return result, seen


@pytest.mark.parametrize("name", BUDGETED)
def test_the_plan_held_at_checks_never_gets_worse(monkeypatch, name):
    problem = paper_problem(np.random.default_rng(7), horizon=3, n_sensors=4, n_targets=6)
    result, seen = _run_with_checks(monkeypatch, name, problem, 1e9)
    assert not result.budget_exhausted and len(seen) > 5
    values = [potential(problem, plan)[0] for _, plan in seen]   # recomputed, independent
    for before, after in zip(values, values[1:]):
        assert after >= before - 1e-9 * max(1.0, abs(before))
    for (phi, _), value in zip(seen, values):                    # the planner's own view
        np.testing.assert_allclose(phi, value, rtol=1e-9)


@pytest.mark.parametrize("name", BUDGETED)
def test_a_stopped_planner_returns_the_plan_held_at_its_last_check(monkeypatch, name):
    problem = paper_problem(np.random.default_rng(8), horizon=3, n_sensors=4, n_targets=6)
    _, seen_all = _run_with_checks(monkeypatch, name, problem, 1e9)
    n_checks = len(seen_all)
    previous = -math.inf
    for stop in sorted({2, 3, n_checks // 3, n_checks // 2, n_checks - 2}):
        # Clock readings: one at the start, one per check; a budget of stop - 0.5 is spent
        # at the stop-th check.
        result, seen = _run_with_checks(monkeypatch, name, problem, stop - 0.5)
        assert result.budget_exhausted and result.converged is False
        assert len(seen) == stop
        np.testing.assert_array_equal(result.plan.targets, seen[-1][1].targets)
        np.testing.assert_array_equal(result.plan.positions, seen[-1][1].positions)
        check_plan(problem, result.plan)
        np.testing.assert_allclose(result.potential, potential(problem, result.plan)[0],
                                   rtol=1e-9)
        # Stopping later never returns less.
        assert result.potential >= previous - 1e-9 * max(1.0, abs(previous))
        previous = result.potential


def _functions_on_stack() -> set[str]:
    frame, names = sys._getframe(1), set()
    while frame is not None:
        names.add(frame.f_code.co_name)
        frame = frame.f_back
    return names


def test_an_epoch_games_long_first_iteration_has_checks_inside(monkeypatch):
    # A game's first iteration recomputes every pair term: at the swarm's size a stretch of
    # 0.1 s or more. With a budget it runs in rounds of player blocks, a check between.
    problem = scale_problem(n_sensors=10, n_targets=20, horizon=4)
    where: list[set[str]] = []
    monkeypatch.setattr(anytime, "CHECK_HOOK",
                        lambda phi, plan: where.append(_functions_on_stack()))
    timed = make_planner("pg", time_budget=1e9).plan(problem, rng=2)
    monkeypatch.setattr(anytime, "CHECK_HOOK", None)
    free = make_planner("pg").plan(problem, rng=2)
    np.testing.assert_array_equal(timed.plan.targets, free.plan.targets)
    np.testing.assert_array_equal(timed.plan.positions, free.plan.positions)
    inside = [n for n, names in enumerate(where) if "_iterate" in names]
    assert inside, "no check inside an iteration's player blocks"
    # Stopped there, the planner returns the plan it held at that check.
    stop = inside[0] + 1
    result, seen = _run_with_checks(monkeypatch, "pg", problem, stop - 0.5)
    assert result.budget_exhausted and len(seen) == stop
    np.testing.assert_array_equal(result.plan.targets, seen[-1][1].targets)
    np.testing.assert_array_equal(result.plan.positions, seen[-1][1].positions)
    check_plan(problem, result.plan)


@pytest.mark.parametrize("name", BUDGETED)
@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, "1s", True])
def test_bad_time_budget_names_the_field(name, bad):
    with pytest.raises(ConfigError) as err:
        make_planner(name, time_budget=bad)
    assert err.value.field == "planner.time_budget"


# ------------------------------------------------------------- the budget in every front end


def test_a_budget_reaches_the_planner_from_every_file_and_the_stone_soup_manager(tmp_path):
    """The plan JSON, a scenario file, a study file and the Stone Soup manager all pass
    ``time_budget`` to the planner; a planner without budgets refuses it, naming the key."""
    from sensorplan.config import load_simulation
    from sensorplan.config.decision import decision_from_dict
    from sensorplan.study import study_from_dict

    decision = {"horizon": 1, "targets": [{"mean": [300.0, 300.0, 1.0, 0.0],
                                           "cov": np.diag([400.0, 400.0, 4.0, 4.0]).tolist()}],
                "sensors": [{"position": [0.0, 300.0], "heading": 0.0}],
                "planner": {"name": "pg", "time_budget": 0.25}}
    assert decision_from_dict(decision).make_planner().time_budget == 0.25
    decision["planner"] = {"name": "random", "time_budget": 0.25}
    with pytest.raises(ConfigError) as info:
        decision_from_dict(decision)
    assert info.value.field == "planner.time_budget"

    sc = tmp_path / "sc.toml"
    sc.write_text('[planning]\nplanner = "sequential-greedy"\n[planning.planner_params]\n'
                  'time_budget = 0.5\n[[targets]]\n[[sensors]]\n')
    assert load_simulation(sc).settings.planner_params["time_budget"] == 0.5

    study = study_from_dict({"runs": 1, "steps": 2, "methods": [
        {"name": "m", "planner": "pg-refine", "planner_params": {"time_budget": 2}}]})
    assert study.methods[0].settings.planner_params["time_budget"] == 2

    stonesoup = pytest.importorskip("stonesoup")
    assert stonesoup
    from sensorplan.integrations.stonesoup import SensorplanManager

    manager = SensorplanManager(sensors=set(), planner="pg", planner_params={"time_budget": 1.5})
    assert manager._planner.time_budget == 1.5
