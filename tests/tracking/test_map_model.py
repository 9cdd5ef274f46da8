"""The map model of the multi-target trackers (MapModel): its checks, its normalised fields
and what both trackers derive from one model."""

from __future__ import annotations

import dataclasses
import doctest
import math

import numpy as np
import pytest

from sensorplan.models import linear
from sensorplan.models.motion import cv_matrices
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.gnn import GNNTracker
from sensorplan.tracking.pmb import map_tracker
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from sensorplan.tracking.pmb.undetected import make_grid

TABLE = radar_table((SensorParams(), SensorParams()))
BOX = np.array([[100.0, 100.0, 150.0, 140.0, 20.0]])
TRACKERS = (PMBTracker, GNNTracker)


@pytest.mark.parametrize(("key", "value"), [
    ("measurement", "radar"), ("measurement", np.zeros(7)), ("measurement", np.zeros((0, 7))),
    ("dt", 0.0), ("dt", -1.0), ("dt", math.nan), ("dt", math.inf), ("dt", "1"), ("dt", True),
    ("world", (0.0, 300.0)), ("world", (300.0, -1.0)), ("world", (300.0,)),
    ("world", (300.0, 300.0, 1.0)), ("world", (300.0, math.inf)), ("world", "ab"),
    ("process_noise", -0.1), ("process_noise", math.nan),
    ("motion", (np.eye(3), np.eye(3))), ("motion", (np.eye(4),)),
    ("motion", (np.eye(4), np.full((4, 4), math.nan))), ("motion", 1.0),
    ("resolution", 0.0), ("resolution", -25.0),
    ("velocity_var", 0.0), ("velocity_var", -1.0),
    ("gate_probability", 0.0), ("gate_probability", 1.0), ("gate_probability", 1.5),
    ("map_edge", "wall"), ("map_edge", 1),
    ("buildings", np.zeros((2, 4))), ("buildings", np.zeros(5)),
    ("buildings", np.array([[0.0, 0.0, 1.0, 1.0, math.nan]])),
])
def test_each_bad_field_is_refused_naming_it(key: str, value: object) -> None:
    kwargs: dict = {"measurement": TABLE, "dt": 1.0, "world": (300.0, 300.0), key: value}
    with pytest.raises(ValueError, match=f"^{key}"):
        MapModel(**kwargs)


def test_buildings_are_refused_with_the_linear_sensor() -> None:
    with pytest.raises(ValueError, match="^buildings .*linear sensor"):
        MapModel(linear.williams15(), 1.0, (300.0, 300.0), buildings=BOX)
    # None or no buildings at all is the linear sensor's model.
    assert MapModel(linear.williams15(), 1.0, (300.0, 300.0), buildings=np.zeros((0, 5)))


def test_the_fields_are_normalised_and_frozen() -> None:
    F, Q = cv_matrices(2.0, 0.3)
    model = MapModel(TABLE, 2, [600, 400], process_noise=0, motion=(F.tolist(), Q),
                     resolution=30, velocity_var=4, buildings=BOX.tolist())
    assert model.dt == 2.0 and type(model.dt) is float
    assert model.world == (600.0, 400.0) and all(type(v) is float for v in model.world)
    assert (model.process_noise, model.resolution, model.velocity_var) == (0.0, 30.0, 4.0)
    assert model.motion is not None
    np.testing.assert_array_equal(model.motion[0], F)
    np.testing.assert_array_equal(model.motion[1], Q)
    assert model.buildings is not None
    np.testing.assert_array_equal(model.buildings, BOX)
    # The arrays are the model's own: read-only copies.
    for a in (*model.motion, model.buildings):
        assert not a.flags.writeable
    Q[0, 0] = 99.0
    assert model.motion[1][0, 0] != 99.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.dt = 3.0  # type: ignore[misc]


def test_the_defaults_are_the_documented_ones() -> None:
    model = MapModel(TABLE, 1.0, (600.0, 600.0))
    assert (model.process_noise, model.motion, model.resolution, model.velocity_var,
            model.gate_probability, model.map_edge, model.buildings) == (
        0.05, None, 25.0, 10.5, 0.999, None, None)
    failed, tried = doctest.testmod(map_tracker)
    assert tried > 0 and failed == 0


@pytest.mark.parametrize("cls", TRACKERS)
def test_a_tracker_derives_its_motion_grid_and_gate_from_the_model(cls: type) -> None:
    model = MapModel(TABLE, 2.0, (600.0, 400.0), process_noise=0.3, resolution=30.0,
                     velocity_var=4.0, gate_probability=0.99, map_edge="closed", buildings=BOX)
    tr = cls(model)
    assert tr.model is model
    F, Q = cv_matrices(2.0, 0.3)
    np.testing.assert_array_equal(tr.F, F)
    np.testing.assert_array_equal(tr.Q, Q)
    grid = make_grid(600.0, 400.0, 30.0, 4.0)
    assert (tr.grid.nx, tr.grid.ny) == (grid.nx, grid.ny) == (20, 14)
    np.testing.assert_array_equal(tr.grid.centres, grid.centres)
    np.testing.assert_array_equal(tr.grid.cov, grid.cov)
    np.testing.assert_allclose(tr.gate, -2.0 * math.log(0.01), rtol=1e-12)   # chi-square(2)
    assert (tr.dt, tr.world, tr.process_noise, tr.gate_probability, tr.map_edge) == (
        2.0, (600.0, 400.0), 0.3, 0.99, "closed")
    np.testing.assert_array_equal(tr.sensing.buildings, BOX)


@pytest.mark.parametrize("cls", TRACKERS)
def test_a_given_motion_replaces_the_cwna_model(cls: type) -> None:
    F = np.eye(4) + np.diag([1.0, 1.0], 2)
    Q = 0.5 * np.eye(4)
    tr = cls(MapModel(linear.williams15(), 1.0, (300.0, 300.0), process_noise=7.0,
                      motion=(F, Q)))
    np.testing.assert_array_equal(tr.F, F)
    np.testing.assert_array_equal(tr.Q, Q)


@pytest.mark.parametrize("cls", TRACKERS)
def test_a_tracker_refuses_anything_but_a_map_model(cls: type) -> None:
    with pytest.raises(TypeError, match="model must be a MapModel"):
        cls(TABLE)
