"""Run settings declared once: the declarations, the checks and file tables they generate,
the dictionaries of the resolved files, and adding a setting as one edit."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from typing import Any

import pytest

from sensorplan.errors import ConfigError
from sensorplan.limits import Range
from sensorplan.simulation.scenario import paper_scenario
from sensorplan.config.scenario import PlanningTable, RunTable, TrackerTable
from sensorplan.simulation.settings import (SECTIONS, RunSettings, TrackerSettings, _Settings,
                                            all_settings, field_type, setting)
from sensorplan.config.validation import section_model, validate

DECLARED = all_settings()
TABLES = {"planning": PlanningTable, "tracker": TrackerTable, "run": RunTable}


def test_every_field_is_a_declared_setting_or_a_group() -> None:
    for cls in (RunSettings, TrackerSettings):
        for f in dataclasses.fields(cls):
            tp = field_type(cls, f.name)
            assert "setting" in f.metadata or issubclass(tp, _Settings), f.name
    paths = [path for _, path, _, _ in DECLARED]
    assert paths == ["planner", "planner_params", "horizon", "steps_per_epoch", "execution",
                     "visibility", "objective", "planning_detection", "planning_occlusion",
                     "search", "search_sectors", "reward", "unreported", "find_tail",
                         "track_existence", "steps",
                     "gospa_c",
                     "tracker.kind",
                     "tracker.miss_update", "tracker.model", "tracker.process_noise",
                     "tracker.mode_process_noise", "tracker.switching", "tracker.gate",
                     "tracker.gate_probability", "tracker.reacquire", "tracker.association",
                     "tracker.known_map", "tracker.known_buildings",
                     "tracker.reflect_walls", "tracker.lost_mode", "tracker.lost_probability",
                     "tracker.lost_resolution", "tracker.births", "tracker.birth_velocity",
                     "tracker.map_edge", "tracker.bernoulli_model", "tracker.edge_exit",
                     "tracker.birth_rate", "tracker.background_birth_rate",
                     "tracker.survival_probability", "tracker.established_survival",
                     "tracker.established_existence", "tracker.report_threshold",
                     "tracker.prune_threshold", "tracker.recycle_threshold",
                     "tracker.recycle_motion", "tracker.split_existence",
                     "tracker.density_components",
                     "tracker.planning_threshold", "tracker.termination_threshold",
                     "tracker.grid_resolution",
                     "tracker.confirm_hits", "tracker.confirm_looks", "tracker.delete_misses"]


@pytest.mark.parametrize("cls,path,f,s", DECLARED, ids=[d[1] for d in DECLARED])
def test_declarations_are_complete(cls: type, path: str, f: Any, s: Any) -> None:
    assert s.section in SECTIONS
    # A nested group's settings live in the table named after it.
    assert s.section == path.split(".")[0] if "." in path else s.section != "tracker"
    assert s.help.endswith(".") and s.help.count(". ") == 0, "one sentence"
    assert all(name.startswith("-") for name in s.cli)
    # An option's --help says in a few words what it sets, naming each fixed choice.
    assert bool(s.brief) == bool(s.cli) and len(s.brief) <= 100
    if s.cli and not callable(s.choices):
        assert all(re.search(rf"\b{re.escape(c)}\b", s.brief) for c in s.choices), s.brief
    # The generated file table of its section has exactly this key.
    assert f.name in TABLES[s.section].model_fields


def test_names_are_unique_across_groups_and_options() -> None:
    names = [f.name for _, _, f, _ in DECLARED]
    assert len(names) == len(set(names))          # simulate's overrides are keyed by name
    options = [o for _, _, _, s in DECLARED for o in s.cli]
    assert len(options) == len(set(options))


def test_tables_hold_exactly_their_section() -> None:
    for section, table in TABLES.items():
        keys = {f.name for _, _, f, s in DECLARED if s.section == section}
        extra = {"seed"} if section == "run" else set()
        assert set(table.model_fields) == keys | extra


#: (path, bad value, message); each rule kind once, plus the type checks.
BAD = [
    ("horizon", 0, "must be in [1, 1000], got 0"),
    ("steps", -3, "must be in [1, 100000], got -3"),
    ("horizon", 1.5, "must be an integer, got 1.5"),
    ("horizon", True, "must be an integer, got True"),
    ("execution", "closed", "unknown execution mode 'closed'; choose from ol, olf"),
    ("visibility", "always", "unknown visibility mode 'always'; choose from probabilistic, "
                             "mean"),
    ("objective", 3, "must be a string, got 3"),
    ("tracker.miss_update", "sometimes",
     "unknown miss update 'sometimes'; choose from negative, none"),
]


@pytest.mark.parametrize("path,value,message", BAD, ids=[f"{b[0]}={b[1]!r}" for b in BAD])
def test_one_rule_gives_one_message_in_the_api_and_in_files(path: str, value: Any,
                                                            message: str) -> None:
    *group, key = path.split(".")
    kwargs: dict[str, Any] = {group[0]: {key: value}} if group else {key: value}
    with pytest.raises(ConfigError) as api:
        RunSettings(**kwargs)
    assert (api.value.field, api.value.message) == (path, message)
    section = next(s.section for _, p, _, s in DECLARED if p == path)
    with pytest.raises(ConfigError) as file:
        validate(TABLES[section], {key: value})
    assert (file.value.field, file.value.message) == (key, message)


def test_unknown_planner_lists_the_registry_in_both_paths() -> None:
    from sensorplan.planners import PLANNERS

    expected = (f"unknown planner 'nope'; choose from {', '.join(sorted(PLANNERS))}, or give "
                "a planner class as 'package.module:Class'")
    with pytest.raises(ConfigError) as api:
        RunSettings(planner="nope")
    with pytest.raises(ConfigError) as file:
        validate(PlanningTable, {"planner": "nope"})
    assert api.value.message == file.value.message == expected
    assert {"dec-jsfp", "dec-independent", "dec-sequential"} <= set(PLANNERS)


def test_a_misspelt_planner_gets_the_closest_name() -> None:
    with pytest.raises(ConfigError) as err:
        validate(PlanningTable, {"planner": "pg-refin"})
    assert err.value.field == "planner"
    assert err.value.message.startswith("unknown planner 'pg-refin' (did you mean 'pg-refine'?)")


def test_values_are_normalised_and_round_trip_through_dicts() -> None:
    import numpy as np

    s = RunSettings(planner="random", horizon=np.int64(3), planner_params={"seed": 2},
                    tracker={"miss_update": "none"})
    assert type(s.horizon) is int and s.tracker == TrackerSettings(miss_update="none")
    d = s.to_dict()
    tracker = d.pop("tracker")
    assert d == {"planner": "random", "planner_params": {"seed": 2}, "horizon": 3,
                 "steps_per_epoch": 1, "execution": "olf", "visibility": "probabilistic",
                 "objective": "cumulative", "planning_detection": "aware",
                 "planning_occlusion": "aware", "search": "off", "search_sectors": 0,
                 "reward": "information", "unreported": "localise", "find_tail": 0,
                 "track_existence": "fixed", "steps": 100,
                 "gospa_c": 50.0}
    assert tracker["miss_update"] == "none"
    assert tracker == json.loads(json.dumps(
        {f.name: getattr(TrackerSettings(), f.name)
         for f in dataclasses.fields(TrackerSettings)} | {"miss_update": "none"}))
    d["tracker"] = json.loads(json.dumps(tracker))          # lists, as a JSON file gives
    assert RunSettings.from_dict(d) == s
    with pytest.raises(ConfigError) as info:
        RunSettings.from_dict({**d, "horizn": 2})
    assert info.value.field == "horizn" and "allowed: planner," in info.value.message
    with pytest.raises(ConfigError) as info:
        RunSettings.from_dict({**d, "tracker": {"miss_update": "none", "gate": 0.9}})
    assert info.value.field == "tracker.gate"


def test_file_tables_are_strict() -> None:
    cases = [({"horizon": "2"}, "horizon", "must be an integer, got '2'"),
             ({"horizon": 2.0}, "horizon", "must be an integer, got 2.0"),
             ({"steps_per_epoch": True}, "steps_per_epoch", "must be an integer, got True"),
             ({"horizn": 2}, "horizn", "unknown key (did you mean 'horizon'?); allowed: "
                                       "planner, planner_params, horizon, steps_per_epoch, "
                                       "execution, visibility, objective, planning_detection, "
                                       "planning_occlusion, search, search_sectors, reward, "
                                       "unreported, find_tail, track_existence"),
             ({"planner_params": ["alpha"]}, "planner_params", "must be a table")]
    for data, field, message in cases:
        with pytest.raises(ConfigError) as info:
            validate(PlanningTable, data)
        assert (info.value.field, info.value.message) == (field, message)
    assert validate(PlanningTable, {}).horizon is None      # absent: the default applies


# ----------------------------------------------------------- adding a setting is one edit


@dataclasses.dataclass(frozen=True)
class _Tracker(_Settings):
    """A tracker with two settings of the kinds later work may add."""

    miss_update: str = setting(
        "negative", section="tracker", choices=("negative", "none"), noun="miss update",
        help="Tracker's reaction to a look that misses its target.")
    gate_probability: float = setting(
        0.99, section="tracker", cli=("--gate-probability",), metavar="P",
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        help="Probability that the gate holds a target's own measurement.")
    reacquire: bool = setting(
        True, section="tracker", cli=("--reacquire",), metavar="BOOL",
        help="Whether a lost track is searched for again.")


def test_a_new_setting_is_checked_in_the_api_and_in_files_from_its_declaration() -> None:
    assert _Tracker().gate_probability == 0.99
    table = section_model(_Tracker, "tracker", "ToyTracker")
    assert set(table.model_fields) == {"miss_update", "gate_probability", "reacquire"}
    assert validate(table, {"gate_probability": 0.5, "reacquire": False}).reacquire is False
    for value, message in [(1.0, "must be in (0, 1), got 1.0"),
                           (0, "must be in (0, 1), got 0.0"),
                           ("x", "must be a number, got 'x'"),
                           (math.nan, "must be a finite number")]:
        with pytest.raises(ConfigError) as api:
            _Tracker(gate_probability=value)
        assert (api.value.field, api.value.message) == ("gate_probability", message)
        with pytest.raises(ConfigError) as file:
            validate(table, {"gate_probability": value})
        assert (file.value.field, file.value.message) == ("gate_probability", message)
    for data in ({"reacquire": 1}, {"reacquire": "yes"}):
        with pytest.raises(ConfigError) as info:
            validate(table, data)
        assert info.value.message.startswith("must be true or false")
    with pytest.raises(ConfigError) as api:
        _Tracker(reacquire=1)
    assert api.value.message == "must be true or false, got 1"
    assert _Tracker(gate_probability=0.5).to_dict() == {
        "miss_update": "negative", "gate_probability": 0.5, "reacquire": True}


# ------------------------------------------------------------------------ transitional


def test_the_tracker_option_lives_in_tracker_settings() -> None:
    with pytest.raises(TypeError):
        RunSettings(planner="random", miss_update="none")       # type: ignore[call-arg]
    with pytest.raises(TypeError):
        paper_scenario(miss_update="none")                      # type: ignore[call-arg]
    s = RunSettings(planner="random", tracker={"miss_update": "none"})
    assert s.tracker == TrackerSettings(miss_update="none")


def test_the_size_limits_name_each_setting_as_its_input_spells_it() -> None:
    """The field names of the size limits' errors come from the declarations (the maps
    that were written by hand for the scenario and decision files)."""
    from sensorplan.config.decision import DECISION_FIELDS
    from sensorplan.config.simulate import RUN_FIELDS
    from sensorplan.simulation.settings import limit_fields

    assert RUN_FIELDS == {"horizon": "planning.horizon",
                          "steps_per_epoch": "planning.steps_per_epoch", "targets": "targets",
                          "sensors": "sensors", "moves": "sensors[{i}].moves",
                          "steps": "run.steps", "search_sectors": "planning.search_sectors"}
    assert DECISION_FIELDS == {"horizon": "horizon", "steps_per_epoch": "steps_per_epoch",
                               "targets": "targets", "sensors": "sensors",
                               "moves": "sensors[{i}].moves", "steps": "steps",
                               "search_sectors": "search_sectors"}
    assert limit_fields(lambda key, s: f"<{s.section}>{key}") == {
        "horizon": "<planning>horizon", "steps_per_epoch": "<planning>steps_per_epoch",
        "steps": "<run>steps", "search_sectors": "<planning>search_sectors"}


def test_unused_names_what_the_tracker_ignores() -> None:
    from sensorplan.simulation.settings import LOST_SETTINGS as LS
    from sensorplan.simulation.settings import MULTI_TARGET_SETTINGS as MT

    assert TrackerSettings().unused() == ("process_noise", *LS, *MT)
    assert TrackerSettings(model="cv").unused() == ("mode_process_noise", "switching", *LS,
                                                    *MT)
    assert TrackerSettings(gate=False, reacquire=False).unused() == (
        "process_noise", "gate_probability", *LS, *MT)
    assert TrackerSettings(lost_mode=True).unused() == ("process_noise", *MT)
    assert set(LS) | {"lost_mode"} <= set(TrackerSettings(kind="pmb").unused())
    assert "births" not in TrackerSettings(kind="pmb").unused()
    assert "model" in TrackerSettings(kind="pmb").unused()
    # a PMB with IMM Bernoullis reads the modes' q's and switching, not the single q
    cv, imm = TrackerSettings(kind="pmb").unused(), TrackerSettings(
        kind="pmb", bernoulli_model="imm").unused()
    assert {"mode_process_noise", "switching"} <= set(cv) and "process_noise" not in cv
    assert {"mode_process_noise", "switching"}.isdisjoint(imm) and "process_noise" in imm
    assert "bernoulli_model" in TrackerSettings().unused()
    assert TrackerSettings(kind="pmb").bernoulli_options() == {}
    opts = TrackerSettings(kind="pmb", bernoulli_model="imm").bernoulli_options()
    assert opts["mode_process_noise"] == (0.05, 5.0)
    assert opts["switching"].tolist() == [[0.95, 0.05], [0.1, 0.9]]
    # the PMB and the GNN each ignore the other's own settings
    from sensorplan.simulation.settings import GNN_SETTINGS, PMB_SETTINGS

    pmb, gnn = TrackerSettings(kind="pmb").unused(), TrackerSettings(kind="gnn").unused()
    assert set(GNN_SETTINGS) <= set(pmb) and not set(PMB_SETTINGS) & set(pmb)
    assert set(PMB_SETTINGS) <= set(gnn) and not set(GNN_SETTINGS) & set(gnn)
    assert {"map_edge", "grid_resolution", "process_noise", "gate_probability"}.isdisjoint(gnn)
    assert "births" in gnn and "map_edge" not in pmb       # the map's edge is its own model
    assert set(GNN_SETTINGS) | set(PMB_SETTINGS) <= set(MT)


@pytest.mark.parametrize("kw,path,message", [
    ({"confirm_hits": 4}, "tracker.confirm_hits", "must be at most confirm_looks (3), got 4"),
    ({"confirm_hits": 0}, "tracker.confirm_hits", "must be in [1, 100], got 0"),
    ({"confirm_looks": 1}, "tracker.confirm_hits", "must be at most confirm_looks (1), got 2"),
    ({"delete_misses": 0}, "tracker.delete_misses", "must be in [1, 1000], got 0"),
    ({"delete_misses": 2.5}, "tracker.delete_misses", "must be an integer, got 2.5"),
])
def test_the_gnn_logic_settings_are_checked(kw: dict[str, Any], path: str,
                                            message: str) -> None:
    with pytest.raises(ConfigError) as api:
        RunSettings(tracker={"kind": "gnn", **kw})
    assert (api.value.field, api.value.message) == (path, message)
    ok = TrackerSettings(kind="gnn", confirm_hits=3, confirm_looks=3, delete_misses=1)
    assert (ok.confirm_hits, ok.confirm_looks, ok.delete_misses) == (3, 3, 1)


def test_the_reward_defaults_to_the_gospa_bound_with_search_on_only() -> None:
    from sensorplan.simulation.settings import RunSettings, TrackerSettings

    assert RunSettings().reward == "information"
    on = RunSettings(search="on", search_sectors=6, tracker=TrackerSettings(kind="pmb"))
    assert on.reward == "gospa" and on.to_dict()["reward"] == "gospa"
    named = RunSettings(search="on", search_sectors=6, reward="information",
                        tracker=TrackerSettings(kind="pmb"))
    assert named.reward == "information"
    # A resolved method reads back as it ran.
    assert RunSettings.from_dict(on.to_dict()).reward == "gospa"
