"""One contract for every registered planner (like scikit-learn's estimator checks)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorplan.information import potential
from sensorplan.planners import PLANNERS, make_planner
from sensorplan.problem import check_plan

from factories import paper_problem, tiny_problem

MODES = [(v, o) for v in ("probabilistic", "mean") for o in ("terminal", "cumulative")]


def _snapshot(problem):
    return [np.array(a, copy=True) for a in (problem.means, problem.covs, problem.positions,
                                               problem.headings)]


@pytest.mark.parametrize("name", sorted(PLANNERS))
@pytest.mark.parametrize("visibility,objective", MODES)
def test_planner_contract(name, visibility, objective):
    rng = np.random.default_rng(7)
    problems = [tiny_problem(rng, max_plans=20_000, visibility=visibility, objective=objective)
                for _ in range(4)]
    if name != "brute-force":   # the paper problem has ~4e11 joint plans: brute force refuses
        problems.append(paper_problem(rng, horizon=2, visibility=visibility, objective=objective))
    for problem in problems:
        before = _snapshot(problem)
        planner = make_planner(name)
        result = planner.plan(problem, rng=3)
        check_plan(problem, result.plan)                       # feasible and complete
        phi, info = potential(problem, result.plan)
        np.testing.assert_allclose(result.potential, phi, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(result.information, info, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(result.information.sum(), result.potential, rtol=1e-9,
                                   atol=1e-12)
        assert result.potential >= 0.0
        again = make_planner(name).plan(problem, rng=3)
        np.testing.assert_array_equal(again.plan.targets, result.plan.targets)
        np.testing.assert_array_equal(again.plan.positions, result.plan.positions)
        for a, b in zip(before, _snapshot(problem)):
            np.testing.assert_array_equal(a, b)                # input not mutated
        assert result.seconds > 0.0
        if name in ("pg", "pg-refine"):
            assert isinstance(result.converged, bool) and result.sweeps >= 1
        else:
            assert result.converged is None


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_never_above_brute_force(name):
    if "brute-force" not in PLANNERS:
        pytest.skip("brute-force planner not registered")
    rng = np.random.default_rng(11)
    for _ in range(6):
        problem = tiny_problem(rng, max_plans=20_000)
        best = make_planner("brute-force").plan(problem).potential
        got = make_planner(name).plan(problem, rng=1).potential
        assert got <= best + 1e-9 * max(1.0, abs(best))


def test_different_seeds_give_different_random_plans():
    problem = paper_problem(np.random.default_rng(2), horizon=3)
    plans = {make_planner("random").plan(problem, rng=s).plan.targets.tobytes() for s in range(5)}
    assert len(plans) > 1


def test_unknown_planner_names_the_field():
    from sensorplan.errors import ConfigError
    with pytest.raises(ConfigError) as err:
        make_planner("simulated-annealing")
    assert err.value.field == "planner.name"
