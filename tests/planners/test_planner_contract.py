"""The planner contract: sensorplan.planners.check_planner's checks for every registered
planner, and deliberately broken planners that fail the check they break."""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from factories import paper_problem
from sensorplan.errors import ConfigError
from sensorplan.planners import (CHECKS, PLANNERS, Plan, PlannerCheckError, PlanResult,
                                 check_planner, finish, make_planner, start_clock)
from sensorplan.planners.contract_problems import contract_problems
from sensorplan.planners.registry import BUILTIN


@pytest.mark.parametrize("check", list(CHECKS))
@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_contract(name: str, check: str) -> None:
    check_planner(make_planner(name), checks=[check])


def test_every_built_in_planner_is_in_the_contract() -> None:
    assert set(BUILTIN) <= set(PLANNERS)
    assert {"dec-jsfp", "dec-independent", "dec-sequential"} <= set(PLANNERS)


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_convergence_is_reported_by_the_game_planners_only(name: str) -> None:
    problem = next(c.problem for c in contract_problems() if c.problem.n_sensors > 1)
    result = make_planner(name).plan(problem, rng=1)
    if name in ("pg", "pg-refine"):
        assert isinstance(result.converged, bool) and result.sweeps >= 1
    else:
        assert result.converged is None
    assert result.seconds > 0.0


def test_different_seeds_give_different_random_plans() -> None:
    problem = paper_problem(np.random.default_rng(2), horizon=3)
    plans = {make_planner("random").plan(problem, rng=s).plan.targets.tobytes()
             for s in range(5)}
    assert len(plans) > 1


def test_unknown_planner_names_the_field() -> None:
    with pytest.raises(ConfigError) as err:
        make_planner("simulated-annealing")
    assert err.value.field == "planner.name"


# ------------------------------------------------------------------ broken planners


@dataclass(frozen=True)
class Greedy:
    """Sequential greedy, the base that each broken planner below spoils in one way."""

    name: ClassVar[str] = "greedy-base"
    plans_search: ClassVar[bool] = True
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        result = make_planner("sequential-greedy").plan(problem, rng)
        return dataclasses.replace(result, planner=self.name)


@dataclass(frozen=True)
class Anonymous(Greedy):
    """Signs its results with another planner's name."""

    name: ClassVar[str] = "broken-name"

    def plan(self, problem, rng=None) -> PlanResult:
        return dataclasses.replace(super().plan(problem, rng), planner="sequential-greedy")


@dataclass(frozen=True)
class Teleports(Greedy):
    """Moves sensor 0 two moves in its first epoch."""

    name: ClassVar[str] = "broken-teleport"

    def plan(self, problem, rng=None) -> PlanResult:
        start = start_clock()
        res = super().plan(problem, rng)
        positions = res.plan.positions.copy()
        positions[0, :] += 2.0 * problem.sensors[0].moves[0]
        return finish(self.name, problem, Plan(positions, res.plan.targets.copy()), start)


@dataclass(frozen=True)
class Boasts(Greedy):
    """Reports more information than its plan gives (and so beats exhaustive search)."""

    name: ClassVar[str] = "broken-boast"

    def plan(self, problem, rng=None) -> PlanResult:
        res = super().plan(problem, rng)
        extra = 1.0 + 0.5 * res.potential
        return dataclasses.replace(res, potential=res.potential + extra,
                                   information=res.information + extra / problem.n_targets)


_CALLS = itertools.count()


@dataclass(frozen=True)
class IgnoresSeed(Greedy):
    """A random plan from a new seed at every call, whatever ``rng`` says."""

    name: ClassVar[str] = "broken-seed"

    def plan(self, problem, rng=None) -> PlanResult:
        res = make_planner("random").plan(problem, rng=next(_CALLS))
        return dataclasses.replace(res, planner=self.name)


@dataclass(frozen=True)
class Mutates(Greedy):
    """Moves the first target's mean while planning."""

    name: ClassVar[str] = "broken-mutate"

    def plan(self, problem, rng=None) -> PlanResult:
        problem.means.setflags(write=True)
        problem.means[0, 0] += 1.0
        problem.means.setflags(write=False)
        return super().plan(problem, rng)


@dataclass(frozen=True)
class HidesSearch(Greedy):
    """Plans searching problems (with sector looks) but does not declare it."""

    name: ClassVar[str] = "broken-search"
    plans_search: ClassVar[bool] = False


@dataclass(frozen=True)
class RefusesOtherwise(Greedy):
    """Does not declare search and refuses a searching problem, but on another field."""

    name: ClassVar[str] = "broken-refusal"
    plans_search: ClassVar[bool] = False

    def plan(self, problem, rng=None) -> PlanResult:
        if problem.searching:
            raise ConfigError("planner.sectors", "no sectors here")
        return super().plan(problem, rng)


#: broken planner -> (the check it breaks, other checks it fails by the same defect)
BROKEN = {
    Anonymous: ("result_well_formed", set()),
    Teleports: ("feasible_complete_plan", set()),
    Boasts: ("never_above_brute_force", {"potential_matches_recomputation"}),
    IgnoresSeed: ("same_seed_same_plan", set()),
    Mutates: ("input_not_mutated", set()),
    HidesSearch: ("search_declared", set()),
    RefusesOtherwise: ("search_declared", set()),
}


def test_every_check_has_a_broken_planner() -> None:
    assert {check for check, _ in BROKEN.values()} | {"potential_matches_recomputation"} \
        == set(CHECKS)


def test_a_boasting_planner_fails_the_potential_check() -> None:
    with pytest.raises(PlannerCheckError) as err:
        check_planner(Boasts(), checks=["potential_matches_recomputation"])
    assert err.value.check == "potential_matches_recomputation"


@pytest.mark.parametrize("cls", list(BROKEN), ids=[c.name for c in BROKEN])
def test_a_broken_planner_fails_the_check_it_breaks(cls: type) -> None:
    check, also = BROKEN[cls]
    with pytest.raises(PlannerCheckError) as err:
        check_planner(cls(), checks=[check])
    assert (err.value.check, err.value.planner) == (check, cls.name)
    assert f"planner {cls.name!r} fails check {check!r} on " in str(err.value)
    if cls is Mutates:
        return                      # it damages every problem it sees; one check is enough
    for other in set(CHECKS) - {check} - also:
        check_planner(cls(), checks=[other])          # the defect is that check's alone


def test_the_base_of_the_broken_planners_passes() -> None:
    check_planner(Greedy())


def test_check_names_are_checked() -> None:
    with pytest.raises(ValueError, match="unknown check 'fast'"):
        check_planner(Greedy(), checks=["fast"])
