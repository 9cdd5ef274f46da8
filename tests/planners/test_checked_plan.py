"""Every decision that is executed is checked first (checked_plan), and check_planner says
what it checked when a planner passes."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from broken_planners import Incomplete, TargetOutOfRange, Teleport
from sensorplan.planners import (CHECKS, CheckReport, PlanRejected, check_planner, checked_plan,
                                 make_planner)
from sensorplan.planners.contract_problems import (contract_problems, paper_problem,
                                                 search_contract_problems)
from sensorplan.planners.problem import Plan, PlanError, check_plan


@pytest.fixture
def problem():
    return paper_problem(np.random.default_rng(5), horizon=3)


#: broken planner -> (sensor, epoch) of the first wrong action, and words of the rule.
BROKEN = {
    Teleport: (0, 1, "is not one move from"),
    TargetOutOfRange: (0, 1, "target 99 does not exist (the targets are 0..4)"),
    Incomplete: (2, 3, "no action"),
}


@pytest.mark.parametrize("cls", list(BROKEN), ids=[c.name for c in BROKEN])
def test_a_broken_plan_is_refused_naming_planner_sensor_and_epoch(cls, problem) -> None:
    sensor, epoch, words = BROKEN[cls]
    with pytest.raises(PlanRejected) as err:
        checked_plan(cls(), problem, rng=1, decision=4)
    exc = err.value
    assert (exc.field, exc.sensor, exc.epoch, exc.decision) == ("planner", sensor, epoch, 4)
    assert words in exc.detail
    assert exc.message.startswith(f"{cls.name!r} (broken_planners:{cls.__name__}) broke the "
                                  f"planner contract (decision 4, sensor {sensor} epoch "
                                  f"{epoch}): ")
    assert exc.message.endswith("nothing of its plan was executed")


def test_the_teleport_is_hundreds_of_metres(problem) -> None:
    # The premise of the test above: the jump is far beyond the 40 m moves.
    plan = Teleport().plan(problem, rng=1).plan
    assert np.linalg.norm(plan.positions[0, 0] - problem.positions[0]) > 250.0


@pytest.mark.parametrize("name", ["pg", "sequential-greedy", "random"])
def test_a_good_plan_passes_unchanged(name: str, problem) -> None:
    planner = make_planner(name)
    got = checked_plan(planner, problem, rng=2)
    want = planner.plan(problem, rng=2)
    np.testing.assert_array_equal(got.plan.targets, want.plan.targets)
    np.testing.assert_array_equal(got.plan.positions, want.plan.positions)


def test_a_result_of_the_wrong_kind_is_refused(problem) -> None:
    class NotAResult:
        name = "lazy"

        def plan(self, problem, rng=None):
            return {"plan": None}

    with pytest.raises(PlanRejected, match=r"'lazy' \(.*NotAResult\) broke the planner "
                                           r"contract: plan returned dict, not a PlanResult"):
        checked_plan(NotAResult(), problem)


def test_the_refusal_crosses_process_boundaries(problem) -> None:
    with pytest.raises(PlanRejected) as err:
        checked_plan(Teleport(), problem, decision=2)
    again = pickle.loads(pickle.dumps(err.value))
    assert (type(again), again.field, again.message) == (PlanRejected, "planner",
                                                          err.value.message)


def test_check_plan_names_the_first_sensor_and_epoch(problem) -> None:
    good = make_planner("sequential-greedy").plan(problem).plan
    targets = np.array(good.targets)
    targets[1, 2] = -1
    with pytest.raises(PlanError) as err:
        check_plan(problem, Plan(good.positions, targets))
    assert (err.value.sensor, err.value.epoch) == (1, 3)
    assert str(err.value).startswith("sensor 1 epoch 3: no action")
    check_plan(problem, Plan(good.positions, targets), complete=False)   # allowed then
    positions = np.array(good.positions)
    positions[2, 1] = (-40.0, 10.0)
    with pytest.raises(PlanError, match=r"^sensor 2 epoch 2: position \[-40, 10\] is "
                                        r"outside the map \[0, 600\] x \[0, 600\] m$"):
        check_plan(problem, Plan(positions, good.targets))


def test_a_declared_holding_sensor_may_have_no_action_and_only_it(problem) -> None:
    import dataclasses

    res = make_planner("sequential-greedy").plan(problem, rng=3)
    targets = np.array(res.plan.targets)
    positions = np.array(res.plan.positions)
    targets[1], positions[1] = -1, np.nan           # sensor 1 holds in every epoch
    held = dataclasses.replace(res, plan=Plan(positions, targets))
    with pytest.raises(PlanRejected, match="sensor 1 epoch 1\\): no action"):
        checked_plan(_Fixed(held), problem)
    checked_plan(_Fixed(dataclasses.replace(held, holding=(1,))), problem)
    # Declaring a sensor holding does not excuse another one, nor a partial hold.
    two = np.array(targets)
    two[2] = -1
    with pytest.raises(PlanRejected, match="sensor 2 epoch 1\\): no action"):
        checked_plan(_Fixed(dataclasses.replace(held, plan=Plan(positions, two),
                                                holding=(1,))), problem)
    partial = np.array(res.plan.targets)
    partial[1, 2] = -1
    with pytest.raises(PlanRejected, match="sensor 1 epoch 1\\): a holding sensor has an "
                                           "action"):
        checked_plan(_Fixed(dataclasses.replace(res, plan=Plan(res.plan.positions, partial),
                                                holding=(1,))), problem)
    with pytest.raises(PlanRejected, match="holding sensor 7 does not exist"):
        checked_plan(_Fixed(dataclasses.replace(held, holding=(7,))), problem)


class _Fixed:
    """A planner that returns a given result (under sequential-greedy's name)."""

    name = "sequential-greedy"

    def __init__(self, result) -> None:
        self.result = result

    def plan(self, problem, rng=None):
        return self.result


def test_check_planner_reports_what_it_ran() -> None:
    report = check_planner("sequential-greedy")
    assert isinstance(report, CheckReport)
    assert report.planner == "sequential-greedy"
    assert report.checks == tuple(CHECKS)
    # It plans search looks: the searching problems too.
    assert report.problems == tuple(c.label for c in contract_problems()
                                    + search_contract_problems())
    assert report.declined == ()
    assert str(report).startswith(f"planner 'sequential-greedy' passed {len(CHECKS)} check(s) "
                                  f"({', '.join(CHECKS)}) on "
                                  f"{len(contract_problems() + search_contract_problems())} "
                                  "problem(s)")


def test_check_planner_reports_the_problems_it_declined() -> None:
    # brute force declines the paper-size problems above its max_plans (allowed: not tiny).
    report = check_planner(make_planner("brute-force", max_plans=20_000),
                           checks=["feasible_complete_plan"])
    paper = tuple(c.label for c in contract_problems() + search_contract_problems()
                  if not c.tiny)
    assert report.checks == ("feasible_complete_plan",)
    assert report.declined == paper
    assert f"declining {len(paper)} as too large" in str(report)


def test_a_wrapper_without_a_name_passes_the_inner_plan_on(problem) -> None:
    class Recorder:                       # as tests and scripts wrap a planner to watch it
        def __init__(self, inner):
            self.inner = inner

        def plan(self, problem, rng=None):
            return self.inner.plan(problem, rng=rng)

    got = checked_plan(Recorder(make_planner("sequential-greedy")), problem)
    assert got.planner == "sequential-greedy"
    with pytest.raises(PlanRejected, match=r"Recorder broke the planner contract \(sensor 0 "
                                           r"epoch 1\)"):
        checked_plan(Recorder(Teleport()), problem)
