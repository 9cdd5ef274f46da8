"""Headings in degrees, unknown planner keys whatever their value, positions outside the map
with their value and bounds, and the kind of an input file."""

from __future__ import annotations

import copy
import math

import pytest

from cli_helpers import SPEC7
from sensorplan.config import decision_from_dict
from sensorplan.config.files import file_kind, read_input
from sensorplan.config.scenario import scenario_from_dict
from sensorplan.errors import ConfigError
from sensorplan.planners.registry import check_settings

HINT = "(angles are in radians; degrees are written heading_deg)"


def scenario(target: dict | None = None, sensor: dict | None = None) -> dict:
    return {"targets": [{"kind": "cv", "position": [300.0, 250.0], **(target or {})}],
            "sensors": [{"position": [100.0, 100.0], **(sensor or {})}]}


def decision(**sensor: float) -> dict:
    d = copy.deepcopy(SPEC7)
    d["sensors"][0].pop("heading")
    d["sensors"][0].update(sensor)
    return d


@pytest.mark.parametrize("where", ["target", "sensor"])
def test_heading_deg_is_the_heading_in_degrees(where: str) -> None:
    a = scenario_from_dict(scenario(**{where: {"heading_deg": 45.0}}))
    b = scenario_from_dict(scenario(**{where: {"heading": math.radians(45.0)}}))
    assert a == b
    spec = a.targets[0] if where == "target" else a.sensors[0]
    assert spec.heading == math.radians(45.0)


@pytest.mark.parametrize("where,field", [("target", "targets[0]"), ("sensor", "sensors[0]")])
def test_a_heading_in_degrees_written_as_radians_is_refused_with_the_hint(
        where: str, field: str) -> None:
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(scenario(**{where: {"heading": 45.0}}))
    assert (err.value.field, err.value.message) == (
        f"{field}.heading", f"must be at most 2pi rad in magnitude, got 45.0 {HINT}")
    # A full turn either way is a heading; degrees beyond one are refused too.
    for ok in (2 * math.pi, -2 * math.pi, -3.0):
        scenario_from_dict(scenario(**{where: {"heading": ok}}))
    with pytest.raises(ConfigError, match=r"must be at most 360 deg in magnitude, got -400"):
        scenario_from_dict(scenario(**{where: {"heading_deg": -400.0}}))
    with pytest.raises(ConfigError, match=r"heading_deg: give heading \(radians\) or "
                                          r"heading_deg \(degrees\), not both"):
        scenario_from_dict(scenario(**{where: {"heading": 0.1, "heading_deg": 6.0}}))


def test_a_decision_takes_heading_or_heading_deg() -> None:
    a = decision_from_dict(decision(heading_deg=30.0)).problem
    b = decision_from_dict(decision(heading=math.radians(30.0))).problem
    assert a.headings.tolist() == b.headings.tolist() == [math.radians(30.0)]
    with pytest.raises(ConfigError) as err:
        decision_from_dict(decision())
    assert (err.value.field, err.value.message) == (
        "sensors[0].heading", "is required (in radians; or heading_deg in degrees)")
    with pytest.raises(ConfigError) as err:
        decision_from_dict(decision(heading=90.0))
    assert err.value.field == "sensors[0].heading" and err.value.message.endswith(HINT)


def test_an_unknown_planner_key_is_refused_even_when_null() -> None:
    doc = {**SPEC7, "planner": {"name": "sequential-greedy", "name2": None}}
    with pytest.raises(ConfigError) as err:
        decision_from_dict(doc)
    assert err.value.field == "planner.name2"
    assert err.value.message.startswith("unknown key for planner 'sequential-greedy'")
    # A null value of a setting the planner has still means "its default".
    assert check_settings("sequential-greedy", {"seed": None}) == {}
    with pytest.raises(ConfigError, match="unknown key"):
        check_settings("pg", {"alpah": None}, keep_none=True)


def test_a_position_outside_the_map_says_the_value_and_the_bounds() -> None:
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(scenario(sensor={"position": [700.0, 100.0]}))
    assert (err.value.field, err.value.message) == (
        "sensors[0].position", "[700, 100] is outside the map [0, 600] x [0, 600] m")
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(scenario(target={"position": [300.0, -2.5]}))
    assert (err.value.field, err.value.message) == (
        "targets[0].position", "[300, -2.5] is outside the map [0, 600] x [0, 600] m")
    doc = copy.deepcopy(SPEC7)
    doc["map"] = {"width": 500, "height": 400}
    doc["sensors"][0]["position"] = [100, 450]
    with pytest.raises(ConfigError) as err:
        decision_from_dict(doc)
    assert (err.value.field, err.value.message) == (
        "sensors[0].position", "[100, 450] is outside the map [0, 500] x [0, 400] m")


@pytest.mark.parametrize("data,kind", [
    ({"runs": 2, "methods": []}, "study"),
    ({"runs": 2, "methods": [], "axes": []}, "grid"),
    ({"targets": [], "sensors": []}, "scenario"),
    ({"horizon": 2, "targets": [], "sensors": []}, "decision"),
    ({"runs": 2, "targets": []}, None),                 # a broken file of either kind
    ({"dt": 1.0}, None),
])
def test_the_kind_of_a_file_is_told_by_keys_only_it_has(data: dict, kind: str | None) -> None:
    assert file_kind(data) == kind


def test_a_json_decision_missing_keys_is_still_a_decision(tmp_path) -> None:
    # Its keys may look like a scenario's, but a JSON file is only ever a decision.
    path = tmp_path / "p.json"
    path.write_text('{"targets": [], "sensors": []}')
    assert read_input(path, "decision") == {"targets": [], "sensors": []}
