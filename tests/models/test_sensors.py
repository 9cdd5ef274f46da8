"""Sensor parameters declared once: the dataclass's rules, and the file model made from it."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest

from sensorplan.config.validation import SensorParamsModel, validate
from sensorplan.errors import ConfigError
from sensorplan.models.sensors import ANGLE_FIELDS, SensorParams

#: (field, bad value, message): each kind of rule once, written out by hand.
BAD = [
    ("detection", "radar", "unknown detection model 'radar'; choose from ideal, swerling1"),
    ("altitude", math.nan, "must be a finite number"),
    ("altitude", "high", "must be a number, got 'high'"),
    ("max_ground_range", 0.0, "must be > 0"),
    ("moves", (), "must list at least one move distance"),
    ("moves", (20.0, -1.0), "move distances must be > 0"),
    ("altitude", 2e5, "must be in [1, 100000] m, got 200000.0"),
    ("fov_half_angle", 30.0, "must be in (0, pi] rad, got 30.0 (angles are in radians; "
                             "degrees are written fov_half_angle_deg)"),
    ("false_alarm_probability", 1.0, "must be in (0, 1), got 1.0"),
    ("clutter_rate", -1.0, "must be in [0, 1000] per look, got -1.0"),
    ("range_error_floor", -1.0, "must be in [0, 10000] m, got -1.0"),
    ("azimuth_error_floor", 1.0, "must be in [0, 0.1] rad, got 1.0 (angles are in radians; "
                                 "degrees are written azimuth_error_floor_deg)"),
    ("min_ground_range", 500.0, "must be <= max_ground_range"),
]


@pytest.mark.parametrize("name,value,message", BAD, ids=[f"{b[0]}={b[1]!r}" for b in BAD])
def test_a_broken_rule_names_the_field(name: str, value: Any, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        SensorParams(**{name: value}).validate("sensors[2]")
    assert (info.value.field, info.value.message) == (f"sensors[2].{name}", message)


def test_the_defaults_are_valid_and_the_angles_are_the_radian_fields() -> None:
    SensorParams().validate()
    assert ANGLE_FIELDS == ("max_turn", "fov_half_angle", "depression", "beamwidth",
                            "azimuth_error_floor")


def test_the_file_model_is_the_dataclass() -> None:
    """Every field in declaration order with its default (an angle optional, with a
    ``_deg`` twin); an empty table gives the defaults, and every value reaches the
    dataclass."""
    names = [f.name for f in dataclasses.fields(SensorParams)]
    assert list(SensorParamsModel.model_fields) == names + [f"{n}_deg" for n in ANGLE_FIELDS]
    assert validate(SensorParamsModel, {}).params() == SensorParams()
    given = {"altitude": 320.0, "moves": [15.0], "max_turn_deg": 30.0, "fov_half_angle": 0.7,
             "min_ground_range": 100.0, "max_ground_range": 300.0, "depression_deg": 35.0,
             "snr_ref_db": 12.0, "range_ref": 500.0, "beamwidth": 0.05,
             "monopulse_slope": 1.4, "range_resolution": 25.0, "detection": "swerling1",
             "false_alarm_probability": 1e-5, "clutter_rate": 2.0,
             "range_error_floor": 40.0, "azimuth_error_floor_deg": 0.1}
    assert validate(SensorParamsModel, given).params() == SensorParams(
        altitude=320.0, moves=(15.0,), max_turn=math.radians(30.0), fov_half_angle=0.7,
        min_ground_range=100.0, max_ground_range=300.0, depression=math.radians(35.0),
        snr_ref_db=12.0, range_ref=500.0, beamwidth=0.05, monopulse_slope=1.4,
        range_resolution=25.0, detection="swerling1", false_alarm_probability=1e-5,
        clutter_rate=2.0, range_error_floor=40.0, azimuth_error_floor=math.radians(0.1))
    for data, field, message in (
            ({"detection": "radar"}, "detection",
             "unknown detection model 'radar'; choose from ideal, swerling1"),
            ({"altitude": "high"}, "altitude", "must be a number, got 'high'"),
            ({"moves": 20.0}, "moves", "must be a list, got 20.0"),
            ({"max_turn": 0.5, "max_turn_deg": 30.0}, "max_turn_deg",
             "give max_turn (radians) or max_turn_deg (degrees), not both")):
        with pytest.raises(ConfigError) as info:
            validate(SensorParamsModel, data)
        assert (info.value.field, info.value.message) == (field, message)
