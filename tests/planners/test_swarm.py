"""The swarm scenario (N = 100, M = 200, 3 km map) and a decision of it at a reduced size."""

from __future__ import annotations

import numpy as np

from planner_reference import swarm_problem
from sensorplan.planners.information import potential
from sensorplan.planners import make_planner
from sensorplan.planners.problem import check_plan
from sensorplan.simulation.scenario import draw_initial, paper_scenario, swarm_scenario


def test_swarm_scenario_is_the_paper_scaled_up():
    sc, paper = swarm_scenario(), paper_scenario()
    assert (len(sc.sensors), len(sc.targets)) == (100, 200)
    assert (sc.world.width, sc.world.height) == (3000.0, 3000.0)
    # the paper's sensors (altitudes in turn) and targets (3 cv : 2 dubins)
    assert {s.params for s in sc.sensors} == {s.params for s in paper.sensors}
    assert [s.params.altitude for s in sc.sensors[:6]] == [490.0, 500.0, 510.0] * 2
    assert sc.target_kinds.count("cv") == 120 and sc.target_kinds.count("dubins") == 80
    assert sc.speed_range == paper.speed_range and sc.initial_cov == paper.initial_cov
    assert (sc.dt, sc.process_noise) == (paper.dt, paper.process_noise)
    # at the paper's densities: targets and sensors per square metre of their boxes
    def density(n, box):
        return n / (box[1] - box[0]) ** 2
    assert abs(density(200, sc.target_box) / density(5, paper.target_box) - 1) < 0.25
    assert abs(density(100, sc.sensor_box) / density(3, paper.sensor_box) - 1) < 0.05


def test_swarm_initial_conditions_fill_the_map():
    sc = swarm_scenario()
    ini = draw_initial(sc, np.random.default_rng(0), np.random.default_rng(1))
    assert ini.truth.shape == (200, 4) and ini.positions.shape == (100, 2)
    assert np.all((ini.truth[:, :2] >= 100.0) & (ini.truth[:, :2] <= 2900.0))
    assert np.all((ini.positions >= 50.0) & (ini.positions <= 2950.0))
    # spread over the whole map, not bunched: every 1 km square holds a sensor
    cells = {(int(x // 1000), int(y // 1000)) for x, y in ini.positions}
    assert len(cells) == 9


def test_one_swarm_decision_at_reduced_size():
    problem = swarm_problem(horizon=3, n_sensors=12, n_targets=24, seed=3)
    result = make_planner("pg").plan(problem, rng=0)
    check_plan(problem, result.plan)
    np.testing.assert_allclose(result.potential, potential(problem, result.plan)[0], rtol=1e-9)
    assert result.potential > 0.0 and isinstance(result.converged, bool)
