"""Buildings: the line of sight, targets that reflect off walls, hidden targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models import radar
from sensorplan.errors import ConfigError
from sensorplan.simulation.scenario import Scenario, SensorSpec, TargetSpec, make_truth
from sensorplan.models.sensors import SensorParams
from sensorplan.models.truth import inside_buildings

BOX = np.array([[100.0, 100.0, 200.0, 150.0, 50.0]])      # x0, y0, x1, y1, height


def hidden(sxy, z, q, buildings=BOX):
    return bool(radar.hidden(np.asarray(buildings, dtype=float), sxy[0], sxy[1], z, q[0], q[1]))


# ------------------------------------------------------------------------- line of sight


def test_a_sight_line_through_a_wall_is_blocked():
    # Sensor 500 m up at x = 0; target just behind the building at ground level: the line
    # enters the box through its west wall below the roof.
    assert hidden((0.0, 125.0), 500.0, (210.0, 125.0))
    # and a target behind it to the north-east, through the south wall
    assert hidden((150.0, -300.0), 500.0, (150.0, 160.0))


def test_a_sight_line_passing_over_the_roof_is_clear():
    # Same direction, target far beyond: the line crosses the footprint above the roof
    # (height at x in [100, 200] is 500 (1 - x / 1000) >= 400 > 50).
    assert not hidden((0.0, 125.0), 500.0, (1000.0, 125.0))
    # Close behind the building, but the sensor is almost overhead: still above the roof
    # where the line is over the footprint.
    assert not hidden((205.0, 125.0), 500.0, (215.0, 125.0))


def test_the_roof_height_decides():
    # The line over the footprint descends from 500 (1 - 100/250) = 300 m to 100 m at x = 200:
    # a 150 m building blocks it, a 90 m one does not.
    tall = BOX.copy()
    tall[0, 4] = 150.0
    low = BOX.copy()
    low[0, 4] = 90.0
    assert hidden((0.0, 125.0), 500.0, (250.0, 125.0), tall)
    assert not hidden((0.0, 125.0), 500.0, (250.0, 125.0), low)


def test_grazing_an_edge_or_a_wall_does_not_block():
    """The documented rule: only a line through the inside of a box is blocked."""
    # along the south wall's plane (y = 100), target beyond the building
    assert not hidden((0.0, 100.0), 500.0, (210.0, 100.0))
    # through the corner (200, 150) exactly, from the south-east quadrant
    assert not hidden((250.0, 100.0), 500.0, (150.0, 200.0))
    # a target standing on the wall itself is seen from outside
    assert not hidden((0.0, 125.0), 500.0, (100.0, 125.0))
    # a hair inside the wall plane, it is blocked
    assert hidden((0.0, 100.001), 500.0, (210.0, 100.001))


def test_no_buildings_hide_nothing(rng):
    s = rng.uniform(0, 600, (50, 2))
    q = rng.uniform(0, 600, (50, 2))
    assert not radar.hidden_looks(np.zeros((0, 5)), s, np.full(50, 500.0), q).any()
    assert not radar.hidden_looks(None, s, np.full(50, 500.0), q).any()


# ------------------------------------------------------------------------------ the truth


def test_truth_never_enters_a_building_over_ten_thousand_steps():
    buildings = ((150.0, 150.0, 300.0, 220.0, 40.0), (320.0, 300.0, 420.0, 450.0, 60.0),
                 (80.0, 380.0, 140.0, 520.0, 30.0))
    targets = tuple(TargetSpec(kind=k) for k in ("cv", "cv", "cv", "dubins", "dubins", "dubins"))
    sc = Scenario(targets=targets, sensors=(SensorSpec(),), buildings=buildings,
                  process_noise=0.5)
    rng = np.random.default_rng(17)
    x0 = np.column_stack([[50.0, 550.0, 100.0, 500.0, 60.0, 560.0],
                          [50.0, 550.0, 560.0, 60.0, 300.0, 300.0],
                          rng.uniform(-6, 6, 6), rng.uniform(-6, 6, 6)])
    truth = make_truth(sc, x0, rng)
    blds = sc.building_array
    bounced = 0
    for _ in range(10_000):
        before = truth.states.copy()
        x = truth.step()
        assert not inside_buildings(x[:, :2], blds).any()
        assert np.all((x[:, :2] >= 0) & (x[:, :2] <= 600))
        bounced += int(np.any(np.sign(x[:, 2:]) != np.sign(before[:, 2:])))
    assert bounced > 50                                   # walls were hit, often


# ------------------------------------------------------------------------ hidden targets


def test_a_look_at_a_hidden_target_never_detects_it():
    from sensorplan.simulation.settings import RunSettings
    from sensorplan.simulation import run_episode

    # One building between a fixed sensor and a fixed, slowly moving target.
    sc = Scenario(targets=(TargetSpec(kind="cv", position=(300.0, 300.0), speed=0.0,
                                      heading=0.0),),
                  sensors=(SensorSpec(SensorParams(fov_half_angle=math.pi, moves=(1e-3,)),
                                      position=(0.0, 300.0), heading=0.0),),
                  buildings=((200.0, 250.0, 280.0, 350.0, 400.0),), process_noise=0.0)
    ep = run_episode(sc, RunSettings(planner="pg", steps=30), 1)
    assert not ep.measured.any() and ep.missed[1:].all()
    clear = Scenario(targets=sc.targets, sensors=sc.sensors, process_noise=0.0)
    assert run_episode(clear, RunSettings(planner="pg", steps=30), 1).measured[1:].all()


# ------------------------------------------------------------------------------ validation


@pytest.mark.parametrize("table,field", [
    ("box = [100.0, 100.0, 50.0, 200.0]\nheight = 20.0", "buildings[0].box"),
    ("box = [100.0, 100.0, 700.0, 200.0]\nheight = 20.0", "buildings[0].box"),
    ("box = [100.0, 100.0, 200.0]\nheight = 20.0", "buildings[0].box"),
    ("box = [100.0, 100.0, 200.0, 200.0]\nheight = -1.0", "buildings[0].height"),
    ("box = [100.0, 100.0, 200.0, 200.0]\nheight = 600.0", "sensors[0].altitude"),
    ("box = [100.0, 100.0, 200.0, 200.0]\nheight = 20.0\nroof = 1", "buildings[0].roof"),
])
def test_bad_buildings_exit_2_naming_the_field(table, field, tmp_path, capsys):
    from cli_helpers import assert_bad_input, run

    sc = tmp_path / "s.toml"
    sc.write_text(f"[[targets]]\n[[sensors]]\n[[buildings]]\n{table}\n")
    assert_bad_input(run(capsys, "simulate", sc, "--steps", "2", "--out", tmp_path / "o"),
                     field)


def test_a_study_with_buildings_validates_its_keys(tmp_path, capsys):
    from cli_helpers import assert_bad_input, run

    sc = tmp_path / "s.toml"
    sc.write_text("[[targets]]\n[[sensors]]\n[[buildings]]\nbox = [1.0, 1.0, 2.0, 2.0]\n"
                  "height = 5.0\nhieght = 5.0\n")
    study = tmp_path / "study.toml"
    study.write_text(f'runs = 1\nsteps = 2\n[scenario]\nfile = "{sc}"\n'
                     '[[methods]]\nname = "m"\nplanner = "random"\n')
    line = assert_bad_input(run(capsys, "study", study, "--out", tmp_path / "o"),
                            "scenario.file")
    assert "buildings[0].hieght" in line


def test_a_target_may_not_start_inside_a_building():
    with pytest.raises(ConfigError) as info:
        Scenario(targets=(TargetSpec(position=(150.0, 120.0)),), sensors=(SensorSpec(),),
                 buildings=((100.0, 100.0, 200.0, 150.0, 20.0),))
    assert info.value.field == "targets[0].position"


# ------------------------------------------------------------------------------ planning


def in_sight(buildings, s, z, m, C, probabilistic=True):
    return radar.in_sight_probability(np.asarray(buildings, dtype=float), s[0], s[1], z, m[0],
                                      m[1], C[0], C[1], C[2], probabilistic)


def test_in_sight_probability_is_one_minus_the_weight_of_the_hidden_points():
    """Closed form: a tall block covering exactly the points beyond +1 sd along x hides the
    three nodes at +sqrt(3) sd (weight 1/6) and no other: p = 5/6. Along y (correlated C,
    nodes x = m + l00 u, y = m + l10 u + l11 v) the same block hides the nodes whose x is
    beyond it: those with u = +sqrt(3), again 1/6."""
    m, sd = np.array([1000.0, 1000.0]), 10.0
    block = [[m[0] + sd, m[1] - 400.0, m[0] + 300.0, m[1] + 400.0, 450.0]]
    sensor, z = (m[0] - 300.0, m[1]), 500.0
    assert in_sight(block, sensor, z, m, (sd**2, 0.0, sd**2)) == pytest.approx(5 / 6, abs=1e-15)
    corr = (sd**2, 0.5 * sd**2, sd**2)
    assert in_sight(block, sensor, z, m, corr) == pytest.approx(5 / 6, abs=1e-15)
    # The mean itself hidden: the mean rule gives 0, the nine points give 1/6 (u = -sqrt 3).
    wide = [[m[0] - sd, m[1] - 400.0, m[0] + 300.0, m[1] + 400.0, 450.0]]
    assert in_sight(wide, sensor, z, m, (sd**2, 0.0, sd**2)) == pytest.approx(1 / 6, abs=1e-15)
    assert in_sight(wide, sensor, z, m, (sd**2, 0.0, sd**2), probabilistic=False) == 0.0
    assert in_sight(block, sensor, z, m, (sd**2, 0.0, sd**2), probabilistic=False) == 1.0


def test_in_sight_probability_is_deterministic_in_0_1_and_one_without_buildings(rng):
    blds = np.column_stack([rng.uniform(0, 900, (6, 2)), np.zeros((6, 3))])
    blds[:, 2:4] = blds[:, :2] + rng.uniform(20, 100, (6, 2))
    blds[:, 4] = rng.uniform(10, 200, 6)
    for _ in range(300):
        s, m = rng.uniform(0, 1000, 2), rng.uniform(0, 1000, 2)
        A = rng.normal(size=(2, 2)) * rng.uniform(1, 60)
        C = A @ A.T
        c = (C[0, 0], C[0, 1], C[1, 1])
        p = in_sight(blds, s, 500.0, m, c)
        assert 0.0 <= p <= 1.0 and p == in_sight(blds, s, 500.0, m, c)
        assert in_sight(np.zeros((0, 5)), s, 500.0, m, c) == 1.0


def test_a_planned_look_counts_the_in_sight_probability(rng):
    """Two computations: the look with buildings equals the open-ground look times the
    in-sight probability (weight and information), for random looks."""
    from sensorplan.models.sensors import radar_table

    row = radar_table((SensorParams(fov_half_angle=math.pi / 3),))[0]
    blds = np.array([[300.0, 300.0, 420.0, 380.0, 150.0], [520.0, 250.0, 560.0, 500.0, 90.0]])
    n = 400
    sxy = rng.uniform(0, 800, (n, 2))
    g, a = rng.uniform(250, 450, n), rng.uniform(-math.pi, math.pi, n)
    dx, dy = g * np.cos(a), g * np.sin(a)
    th = a + rng.uniform(-0.5, 0.5, n)
    A = rng.normal(size=(n, 2, 2)) * 8.0
    Cm = A @ np.swapaxes(A, 1, 2) + 4.0 * np.eye(2)
    C = np.stack([Cm[:, 0, 0], Cm[:, 0, 1], Cm[:, 1, 1]], axis=-1)
    for probabilistic in (True, False):
        W0, w0 = radar.look_information(row, dx, dy, th, C, probabilistic)
        W1, w1 = radar.look_information(row, dx, dy, th, C, probabilistic, blds, sxy)
        f = np.array([in_sight(blds, sxy[b], 500.0, sxy[b] + (dx[b], dy[b]), C[b], probabilistic)
                      for b in range(n)])
        keep = w0 * f >= radar.P_VIS_MIN              # below it a look counts for nothing
        assert np.allclose(w1[keep], w0[keep] * f[keep], rtol=1e-12, atol=0)
        assert np.allclose(W1[keep], W0[keep] * f[keep, None, None], rtol=1e-12, atol=1e-300)
        assert np.all(w1[~keep] == 0) and np.all(W1[~keep] == 0)
        assert 0 < (f < 1).sum() and (f < 1).sum() < n       # the case is not trivial


def _two_targets(buildings, visibility):
    from sensorplan.planners.problem import MapRect, PlanningProblem

    # Target 0 due east of the sensor, uncertain (worth looking at); target 1 at 25 degrees,
    # better known. A 200 m block just in front of target 0 hides it from every reachable
    # position; target 1's sight line passes south-west of the block.
    c, s = math.cos(math.radians(25)), math.sin(math.radians(25))
    means = np.array([[1350.0, 1000.0, 0.0, 0.0], [1000 + 350 * c, 1000 + 350 * s, 0.0, 0.0]])
    covs = np.array([np.diag([400.0, 400.0, 4.0, 4.0]), np.diag([100.0, 100.0, 1.0, 1.0])])
    return PlanningProblem(means, covs, np.array([[1000.0, 1000.0]]), np.array([0.0]),
                           (SensorParams(),), horizon=1, world=MapRect(2000.0, 2000.0),
                           buildings=buildings, visibility=visibility)


@pytest.mark.parametrize("visibility", ["probabilistic", "mean"])
def test_the_planner_does_not_look_at_a_hidden_target(visibility):
    from sensorplan.planners import make_planner

    block = [[1280.0, 960.0, 1340.0, 1040.0, 200.0]]
    for planner in ("brute-force", "pg"):
        open_ = make_planner(planner).plan(_two_targets(np.zeros((0, 5)), visibility), rng=0)
        urban = make_planner(planner).plan(_two_targets(block, visibility), rng=0)
        assert open_.plan.targets[0, 0] == 0 and urban.plan.targets[0, 0] == 1
        assert urban.potential < open_.potential


def test_without_buildings_planning_ignores_the_setting(rng):
    """Aware and ignore are the same run on open ground, bit for bit; with a building in
    the way they differ."""
    from sensorplan.simulation.settings import RunSettings
    from sensorplan.simulation import run_episode

    def both(sc):
        return [run_episode(sc, RunSettings(planner="pg", steps=12, planning_occlusion=mode), 3)
                for mode in ("aware", "ignore")]

    targets, sensors = (TargetSpec(), TargetSpec(kind="dubins")), (SensorSpec(),)
    aware, ignore = both(Scenario(targets=targets, sensors=sensors))
    assert np.array_equal(aware.estimate, ignore.estimate)
    assert np.array_equal(aware.looked, ignore.looked)
    assert np.array_equal(aware.potential, ignore.potential)
    town = tuple((x, y, x + 60.0, y + 60.0, 120.0) for x in range(30, 500, 110)
                 for y in range(30, 500, 110))
    aware, ignore = both(Scenario(targets=targets, sensors=sensors, buildings=town))
    assert not np.array_equal(aware.potential, ignore.potential)


def test_a_decision_file_with_buildings(tmp_path, capsys):
    import json

    from cli_helpers import assert_bad_input, run
    from sensorplan.config.decision import decision_from_dict

    data = {"horizon": 1, "map": {"width": 2000.0, "height": 2000.0},
            "targets": [{"mean": [1350.0, 1000.0, 0.0, 0.0],
                         "cov": np.diag([400.0, 400.0, 4.0, 4.0]).tolist()}],
            "sensors": [{"position": [1000.0, 1000.0], "heading": 0.0}],
            "buildings": [{"box": [1280.0, 960.0, 1340.0, 1040.0], "height": 200.0}]}
    assert decision_from_dict(data).problem.buildings.tolist() == [
        [1280.0, 960.0, 1340.0, 1040.0, 200.0]]
    data["buildings"][0]["height"] = 900.0
    path = tmp_path / "d.json"
    path.write_text(json.dumps(data))
    assert_bad_input(run(capsys, "plan", path), "sensors[0].altitude")
    data["buildings"][0] = {"box": [1.0, 2.0, 3.0], "height": 9.0}
    path.write_text(json.dumps(data))
    assert_bad_input(run(capsys, "plan", path), "buildings[0].box")
