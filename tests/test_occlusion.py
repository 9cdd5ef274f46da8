"""Buildings: the line of sight, targets that reflect off walls, hidden targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan import radar
from sensorplan.errors import ConfigError
from sensorplan.scenario import Scenario, SensorSpec, TargetSpec, make_truth
from sensorplan.sensors import SensorParams
from sensorplan.truth import inside_buildings

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
    from sensorplan.settings import RunSettings
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
