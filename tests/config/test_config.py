"""Input files: the single-decision JSON and the scenario TOML, with their errors."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sensorplan.config import (PRESETS, decision_from_dict, load_decision, load_simulation,
                               planner_settings)
from sensorplan.errors import ConfigError
from sensorplan.models import traffic as tf
from sensorplan.planners import PLANNERS
from sensorplan.simulation.scenario import Scenario, SensorSpec, TargetSpec, paper_scenario
from sensorplan.models.sensors import SensorParams

from cli_helpers import SPEC7

#: The traffic preset is built from recorded flights, fetched once
#: (``python -m sensorplan.models.traffic``); its checks skip without them.
RECORDINGS = tf.data_path().is_file()
needs_recordings = pytest.mark.skipif(
    not RECORDINGS, reason=f"the recorded flights are not fetched ({tf.FETCH_COMMAND})")

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


MINIMAL = {"horizon": 2,
           "targets": [{"mean": [300, 200, 4, 1],
                        "cov": [[400, 0, 0, 0], [0, 400, 0, 0], [0, 0, 4, 0], [0, 0, 0, 4]]}],
           "sensors": [{"position": [100, 100], "heading": 0.5}]}


def spec7(**changes: Any) -> dict[str, Any]:
    d = copy.deepcopy(SPEC7)
    d.update(changes)
    return d


def error_of(fn: Any, *args: Any, **kwargs: Any) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        fn(*args, **kwargs)
    return info.value


# ------------------------------------------------------------------ single decision


def test_spec7_example_builds_the_problem() -> None:
    d = decision_from_dict(SPEC7, planner="random")
    p = d.problem
    np.testing.assert_array_equal(p.means, [[300, 200, 4, 1]])
    np.testing.assert_array_equal(p.covs[0], np.diag([400.0, 400.0, 4.0, 4.0]))
    np.testing.assert_array_equal(p.positions, [[100, 100]])
    np.testing.assert_array_equal(p.headings, [0.0])
    assert (p.horizon, p.steps_per_epoch, p.dt, p.process_noise) == (3, 1, 1.0, 0.05)
    assert (p.world.width, p.world.height) == (600.0, 600.0)
    s = p.sensors[0]
    assert s.moves == (20.0, 40.0)
    assert (s.max_turn, s.fov_half_angle, s.depression, s.beamwidth) == (
        0.785398, 0.523599, 0.698132, 0.0523599)
    assert (s.altitude, s.range_ref, s.range_resolution, s.monopulse_slope) == (
        500.0, 600.0, 30.0, 1.6)


def test_defaults_are_spec_values() -> None:
    """Omitted keys take the documented defaults (checked against literal values)."""
    d = decision_from_dict(MINIMAL, planner="random")
    p = d.problem
    assert (p.dt, p.steps_per_epoch, p.process_noise) == (1.0, 1, 0.05)
    assert (p.world.width, p.world.height) == (600.0, 600.0)
    assert (p.visibility, p.objective) == ("probabilistic", "cumulative")
    s = p.sensors[0]
    assert s.altitude == 500.0
    assert s.moves == (20.0, 40.0)
    assert s.max_turn == math.pi / 4
    assert s.fov_half_angle == math.pi / 6
    assert (s.min_ground_range, s.max_ground_range) == (250.0, 450.0)
    assert s.depression == pytest.approx(40 * math.pi / 180, rel=1e-15)
    assert (s.snr_ref_db, s.range_ref) == (15.0, 600.0)
    assert s.beamwidth == pytest.approx(3 * math.pi / 180, rel=1e-15)
    assert (s.monopulse_slope, s.range_resolution) == (1.6, 30.0)


def test_default_planner_is_pg() -> None:
    assert decision_from_dict(MINIMAL).planner == "pg"


def test_ints_accepted_for_floats_but_not_bools_or_strings() -> None:
    assert decision_from_dict(spec7(dt=2), planner="random").problem.dt == 2.0
    for bad in (True, "1.0", None, [1.0]):
        err = error_of(decision_from_dict, spec7(dt=bad), planner="random")
        assert err.field == "dt"
    err = error_of(decision_from_dict, spec7(horizon=3.0), planner="random")
    assert (err.field, err.message) == ("horizon", "must be an integer, got 3.0")
    err = error_of(decision_from_dict, spec7(horizon=True), planner="random")
    assert err.field == "horizon"


def test_error_paths_are_dotted_with_indices() -> None:
    d = spec7()
    d["sensors"] = [copy.deepcopy(d["sensors"][0]) for _ in range(2)]
    d["sensors"][1]["altitude"] = "high"
    err = error_of(decision_from_dict, d, planner="random")
    assert err.field == "sensors[1].altitude"
    d = spec7()
    d["targets"][0]["cov"][2] = [0, 0, 4]
    assert error_of(decision_from_dict, d, planner="random").field == "targets[0].cov[2]"
    d = spec7()
    d["targets"][0]["mean"][3] = float("inf")
    err = error_of(decision_from_dict, d, planner="random")
    assert (err.field, err.message) == ("targets[0].mean[3]", "must be a finite number")


def test_unknown_key_names_it_and_suggests() -> None:
    d = spec7()
    d["sensors"][0]["altitud"] = 500
    err = error_of(decision_from_dict, d, planner="random")
    assert err.field == "sensors[0].altitud"
    assert "unknown key" in err.message and "'altitude'" in err.message


def test_only_the_first_error_is_reported() -> None:
    d = spec7(dt="x", horizon="y")
    assert error_of(decision_from_dict, d, planner="random").field == "dt"


def test_semantic_errors_come_from_the_dataclasses() -> None:
    d = spec7()
    d["targets"][0]["cov"][0][1] = 1e-3              # asymmetric beyond 1e-9 relative
    err = error_of(decision_from_dict, d, planner="random")
    assert (err.field, err.message) == ("targets[0].cov", "must be symmetric")
    d = spec7()
    d["targets"][0]["cov"][0][1] = 2e-7              # within 1e-9 * max|P| = 4e-7
    decision_from_dict(d, planner="random")
    d = spec7()
    d["sensors"][0]["position"] = [600.0000001, 0]   # closed map edge (1e-6 tolerance)
    decision_from_dict(d, planner="random")
    d["sensors"][0]["position"] = [600.01, 0]
    assert error_of(decision_from_dict, d, planner="random").field == "sensors[0].position"


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_planner_gets_exactly_its_own_settings(name: str) -> None:
    cls = PLANNERS[name]
    fields = [f.name for f in dataclasses.fields(cls) if f.init and not f.name.startswith("_")]
    params = {"seed": 3, "alpha": 0.2, "beta": 0.9, "max_inner": 7, "max_outer": 4,
              "max_plans": 1000, "rounds": 5, "p_loss": 0.25, "mode": "best-response"}
    own = {k: v for k, v in params.items() if k in fields}
    assert planner_settings(name, own) == own
    decision = decision_from_dict(spec7(planner={"name": name, **own}))
    assert decision.planner == name
    assert dict(decision.settings) == own
    planner = decision.make_planner()
    for k, v in own.items():
        assert getattr(planner, k) == v
    # A setting of another planner is refused, naming the closest of its own.
    other = sorted(set(params) - set(fields))[0]
    err = error_of(decision_from_dict, spec7(planner={"name": name, other: params[other]}))
    assert err.field == f"planner.{other}"
    assert err.message.startswith(f"unknown key for planner {name!r}")
    assert err.message.endswith(f"allowed: {', '.join(fields)}")


DEC_TOML = """
[planning]
planner = "dec-jsfp"
[planning.planner_params]
{params}
[[targets]]
[[sensors]]
"""


@pytest.mark.parametrize("params,field,message", [
    ("rounds = 8\np_loss = 0.25\ndelay = 1\ncomm_range = inf\nmode = 'best-response'\n"
     "transport = 'inproc'\ntimeout = 5", None, None),
    ("rouds = 8", "planning.planner_params.rouds", "unknown key for planner 'dec-jsfp' "
     "(did you mean 'rounds'?); allowed: alpha, beta, max_inner, max_outer, rounds, p_loss, "
     "delay, comm_range, mode, transport, timeout"),
    ("rounds = 1.5", "planning.planner_params.rounds", "must be an integer, got 1.5"),
    ("p_loss = 'high'", "planning.planner_params.p_loss", "must be a number, got 'high'"),
    ("p_loss = 2", "planning.planner_params.p_loss", "must be in [0, 1], got 2.0"),
    ("comm_range = nan", "planning.planner_params.comm_range", "must be > 0 m or inf, got nan"),
    ("seed = 4", "planning.planner_params.seed", "is not a setting here: the run's seed "
     "drives the planner ([run] seed of a scenario, seed of a study)"),
])
def test_a_scenario_takes_exactly_the_planners_settings(tmp_path: Path, params: str,
                                                        field: str | None,
                                                        message: str | None) -> None:
    path = tmp_path / "dec.toml"
    path.write_text(DEC_TOML.format(params=params))
    if field is None:
        s = load_simulation(path).settings
        assert dict(s.planner_params) == {"rounds": 8, "p_loss": 0.25, "delay": 1,
                                          "comm_range": math.inf, "mode": "best-response",
                                          "transport": "inproc", "timeout": 5.0}
        return
    err = error_of(load_simulation, path)
    assert (err.field, err.message) == (field, message)


@pytest.mark.parametrize("name", sorted(set(PLANNERS) - {"brute-force"}))
def test_max_plans_only_for_brute_force(name: str) -> None:
    err = error_of(decision_from_dict, spec7(planner={"name": name, "max_plans": 10}))
    assert err.field == "planner.max_plans"


def test_override_drops_settings_the_new_planner_lacks() -> None:
    d = spec7(planner={"name": "brute-force", "max_plans": 10, "seed": 4})
    decision = decision_from_dict(d, planner="random")
    assert decision.planner == "random"
    assert dict(decision.settings) == {"seed": 4}


def test_unknown_planner_lists_the_registry() -> None:
    err = error_of(decision_from_dict, spec7(planner={"name": "nope"}))
    assert err.field == "planner.name"
    for name in PLANNERS:
        assert name in err.message
    err = error_of(decision_from_dict, spec7(), planner="nope")
    assert err.field == "--planner"


@pytest.mark.parametrize("key,value", [("alpha", 0.0), ("alpha", 1.0), ("beta", 0),
                                       ("beta", 1.5), ("max_inner", 0), ("max_outer", 0),
                                       ("seed", -1)])
def test_planner_setting_ranges(key: str, value: float) -> None:
    err = error_of(decision_from_dict, spec7(planner={"name": "random", key: value}))
    assert err.field == f"planner.{key}"


def test_load_decision_reads_files(tmp_path: Path) -> None:
    path = tmp_path / "p.json"
    path.write_text(json.dumps(SPEC7))
    assert load_decision(path, "random").problem.horizon == 3
    missing = tmp_path / "missing.json"
    assert error_of(load_decision, missing).field == str(missing)
    path.write_text('{"horizon": 1, "horizon": 2}')
    assert error_of(load_decision, path).field == "horizon"     # duplicate key
    path.write_text('{"horizon": ')
    err = error_of(load_decision, path)
    assert err.field == str(path) and "invalid JSON" in err.message


# ------------------------------------------------------------------------ scenarios


def test_paper_toml_is_the_preset() -> None:
    from sensorplan.simulation import RunSettings

    cfg = load_simulation(CONFIGS / "paper.toml")
    assert cfg.scenario == paper_scenario()
    assert cfg.settings == RunSettings()
    preset = load_simulation(preset="paper")
    assert preset.scenario == cfg.scenario
    assert preset.settings == cfg.settings
    assert preset.seed == cfg.seed == 0
    assert PRESETS[0] == "paper" and "radar" in PRESETS


def test_quick_toml_is_tiny() -> None:
    cfg = load_simulation(CONFIGS / "quick.toml")
    assert len(cfg.scenario.sensors) == 2
    assert len(cfg.scenario.targets) == 2
    assert cfg.settings.steps == 20


def test_minimal_toml_takes_the_defaults(tmp_path: Path) -> None:
    from sensorplan.simulation import RunSettings

    path = tmp_path / "s.toml"
    path.write_text("[[targets]]\n[[sensors]]\n")
    cfg = load_simulation(path)
    assert cfg.scenario == Scenario(targets=(TargetSpec(),), sensors=(SensorSpec(),))
    assert cfg.settings == RunSettings()
    assert cfg.seed == 0


def test_toml_fields_reach_the_dataclasses(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text("""
dt = 0.5
process_noise = 0.1
[map]
width = 800
height = 700
[initial]
target_box = [10, 20]
speed_range = [1, 2]
sensor_box = [30, 40]
cov = [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 3, 0], [0, 0, 0, 4]]
[tracker]
miss_update = "none"
[planning]
planner = "pg"
horizon = 2
steps_per_epoch = 3
execution = "ol"
visibility = "mean"
objective = "cumulative"
[planning.planner_params]
alpha = 0.5
[run]
steps = 7
seed = 11
[[targets]]
kind = "dubins"
position = [100, 200]
speed = 5
heading = -1.0
turn_hold = 4
max_turn_rate = 0.2
[[sensors]]
altitude = 450
moves = [10]
position = [50, 60]
heading = 1.5
""")
    cfg = load_simulation(path)
    sc = cfg.scenario
    assert (sc.dt, sc.process_noise, sc.world.width, sc.world.height) == (0.5, 0.1, 800, 700)
    assert (sc.target_box, sc.speed_range, sc.sensor_box) == ((10, 20), (1, 2), (30, 40))
    np.testing.assert_array_equal(sc.initial_cov, np.diag([1.0, 2.0, 3.0, 4.0]))
    assert cfg.settings.tracker.miss_update == "none"
    assert sc.targets == (TargetSpec("dubins", (100.0, 200.0), 5.0, -1.0, 4.0, 0.2),)
    assert sc.sensors == (SensorSpec(SensorParams(altitude=450.0, moves=(10.0,)),
                                     (50.0, 60.0), 1.5),)
    s = cfg.settings
    assert (s.planner, s.horizon, s.steps_per_epoch, s.execution, s.visibility, s.objective,
            s.steps) == ("pg", 2, 3, "ol", "mean", "cumulative", 7)
    assert dict(s.planner_params) == {"alpha": 0.5}
    assert cfg.seed == 11


def test_overrides_win_and_errors_name_the_option() -> None:
    cfg = load_simulation(CONFIGS / "quick.toml", overrides={
        "horizon": 3, "steps": 5, "seed": 9, "execution": "ol", "miss_update": "none",
        "visibility": "mean", "objective": "cumulative", "planner": "random",
        "steps_per_epoch": 1})
    s = cfg.settings
    assert (s.horizon, s.steps, s.execution, s.tracker.miss_update, s.visibility, s.objective,
            s.steps_per_epoch) == (3, 5, "ol", "none", "mean", "cumulative", 1)
    assert cfg.seed == 9
    for key, value, field in [("horizon", 0, "--horizon"), ("steps", 0, "--steps"),
                              ("seed", -2, "--seed"), ("execution", "x", "--execution"),
                              ("planner", "x", "--planner"), ("miss_update", "x", "--miss-update"),
                              ("steps_per_epoch", 0, "--steps-per-epoch"),
                              ("visibility", "x", "--visibility"),
                              ("objective", "x", "--objective")]:
        for source in ({"path": CONFIGS / "quick.toml"}, {"preset": "paper"}):
            err = error_of(load_simulation, overrides={key: value}, **source)
            assert err.field == field, (key, source)
    assert error_of(load_simulation, preset="nope").field == "--preset"
    assert error_of(load_simulation, CONFIGS / "quick.toml", "paper").field == "--preset"


def test_planner_override_drops_max_plans(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text('[planning]\nplanner = "brute-force"\n[planning.planner_params]\n'
                    'max_plans = 100\n[[targets]]\n[[sensors]]\n')
    assert dict(load_simulation(path).settings.planner_params) == {"max_plans": 100}
    cfg = load_simulation(path, overrides={"planner": "random"})
    assert cfg.settings.planner == "random"
    assert dict(cfg.settings.planner_params) == {}
    path.write_text('[planning]\nplanner = "random"\n[planning.planner_params]\n'
                    'max_plans = 100\n[[targets]]\n[[sensors]]\n')
    assert error_of(load_simulation, path).field == "planning.planner_params.max_plans"


def test_the_radar_preset_is_the_paper_scenario_with_radar_detection() -> None:
    from sensorplan.simulation.scenario import RADAR_DETECTION, radar_scenario

    sc = load_simulation(preset="radar").scenario
    assert sc == radar_scenario()
    assert sc.targets == paper_scenario().targets
    for spec, paper in zip(sc.sensors, paper_scenario().sensors):
        assert spec.params.altitude == paper.params.altitude
        assert {k: getattr(spec.params, k) for k in RADAR_DETECTION} == RADAR_DETECTION
    # A radar's look detects every target in view, and the multi-target tracker keeps them.
    cfg = load_simulation(preset="radar")
    assert sc.look_detects == "all" and cfg.settings.tracker.kind == "pmb"
    assert cfg.settings.search_sectors == 6 and cfg.settings.search == "on"
    assert cfg.settings.reward == "gospa"
    assert cfg.settings.tracker.termination_threshold == 0.1
    assert (cfg.settings.tracker.births, cfg.settings.tracker.birth_rate) == ("uniform", 0.05)
    assert cfg.settings.tracker.planning_threshold == 0.02
    assert cfg.settings.unreported == "confirm"


@pytest.mark.parametrize("preset,files", [
    ("radar", ["honest_table_radar_anywhere", "radar_lost_targets", "report_termination"]),
    ("search", ["honest_table_search_background", "search_recycle", "search_background"]),
])
def test_earlier_study_files_keep_what_they_ran(preset: str, files: list[str]) -> None:
    """The radar and search presets confirm tracks they do not report (and radar plans down
    to existence 0.02); the study files that ran before name what they ran."""
    from sensorplan.study.file import load_study

    assert load_simulation(preset=preset).settings.unreported == "confirm"
    for name in files:
        study = load_study(ROOT / "studies" / f"{name}.toml")
        assert {m.settings.unreported for m in study.methods} == {"localise"}, name
        if preset == "radar":
            assert {m.settings.tracker.planning_threshold for m in study.methods} == {0.1}


def _search_study_files() -> list[Path]:
    """The study and grid files that run the search preset."""
    return [p for p in sorted((ROOT / "studies").rglob("*.toml"))
            if 'preset = "search"' in p.read_text()]


def test_the_search_preset_recycles_and_earlier_files_keep_what_they_ran() -> None:
    """The search preset hands a faded track back to the undetected intensity at 0.1; the
    study files that ran before name 0, each method but those that set it themselves."""
    from sensorplan.study.file import load_study

    assert load_simulation(preset="search").settings.tracker.recycle_threshold == 0.1
    assert load_simulation(preset="radar").settings.tracker.recycle_threshold == 0.0
    recycling = {"pmb/recycle", "pmb/recycle0.1", "recycle0.1"}
    # Written for the preset as it is now (they name its settings themselves).
    current = {"honest_table_search_recycle.toml", "search_inward_dev.toml",
               "search_established_dev.toml", "search_established_odds_dev.toml",
               "search_moving_recycle_dev.toml",
               "search_faded_bernoulli_dev.toml", "search_split_dev.toml",
               "search_mixture_dev.toml", "search_mixture.toml",
               "search_mixture_crossing.toml", "search_mixture_crossing_400.toml",
               "honest_table_search_mixture.toml", "search_resolved_dev.toml",
               "search_resolved.toml", "search_established.toml",
               "search_lookahead_dev.toml", "search_snr.toml", "search_radar18.toml"}
    for path in _search_study_files():
        if path.name.startswith("lookahead") or path.name in current:
            continue
        study = load_study(path)
        for m in study.methods:
            want = 0.1 if m.name in recycling else 0.0
            assert m.settings.tracker.recycle_threshold == want, (path.name, m.name)


def test_the_search_preset_keeps_two_components_and_earlier_files_keep_what_they_ran(
) -> None:
    """The search preset's Bernoulli densities keep two Gaussian components and the edge
    charges the probability of crossing it; every other preset keeps one and the mass off
    the map. The search study files that ran before name those, each method but those that
    set them itself."""
    from sensorplan.study.file import load_study

    tracker = load_simulation(preset="search").settings.tracker
    assert (tracker.density_components, tracker.edge_exit) == (2, "crossing")
    for preset in ("radar", "traffic", "williams15", "vo12"):
        if preset == "traffic" and not RECORDINGS:
            continue                  # built from the recorded flights, not fetched here
        other = load_simulation(preset=preset).settings.tracker
        assert (other.density_components, other.edge_exit) == (1, "outside"), preset
    # Written for the preset as it is now.
    current = {"search_mixture_crossing.toml", "search_mixture_crossing_400.toml",
               "honest_table_search_mixture.toml", "search_resolved_dev.toml",
               "search_resolved.toml", "search_established.toml",
               "search_lookahead_dev.toml", "search_snr.toml", "search_radar18.toml"}
    searched = 0
    for path in _search_study_files():
        if path.name in current:
            continue
        searched += 1
        written = tomllib.loads(path.read_text())
        if "axes" in written:                 # a grid file: its defaults name them
            named = written["defaults"]["tracker"]
            assert (named["density_components"], named["edge_exit"]) == (1, "outside")
            continue
        for m in load_study(path).methods:
            spec = next((x for x in written["methods"] if x["name"] == m.name), {})
            own = spec.get("tracker", {})
            want = (own.get("density_components", 1), own.get("edge_exit", "outside"))
            got = (m.settings.tracker.density_components, m.settings.tracker.edge_exit)
            assert got == want, (path.name, m.name)
    assert searched >= 30


def _traffic_study_files() -> list[Path]:
    """The study files that run the traffic preset or its scenario written out."""
    return [p for p in sorted((ROOT / "studies").rglob("*.toml"))
            if 'preset = "traffic"' in p.read_text() or "traffic_thermal_radars" in p.read_text()]


@needs_recordings
def test_the_traffic_preset_runs_imm_bernoullis_and_earlier_files_keep_what_they_ran() -> None:
    """The traffic preset's tracks are IMMs of the recorded motion's two fitted modes; the
    study files that ran before name one motion model, each method but those that set the
    IMM themselves."""
    from sensorplan.simulation.scenario import TRAFFIC_MODE_Q, TRAFFIC_SWITCHING
    from sensorplan.study.file import load_study

    tracker = load_simulation(preset="traffic").settings.tracker
    assert (tracker.bernoulli_model, tracker.mode_process_noise, tracker.switching) == (
        "imm", TRAFFIC_MODE_Q, TRAFFIC_SWITCHING)
    assert load_simulation(preset="search").settings.tracker.bernoulli_model == "cv"
    files = _traffic_study_files()
    assert len(files) >= 10
    for path in files:
        for m in load_study(path).methods:
            want = "imm" if m.name.endswith("/imm") else "cv"
            assert m.settings.tracker.bernoulli_model == want, (path.name, m.name)


@needs_recordings
def test_the_traffic_preset_has_the_recordings_survival_and_earlier_files_keep_theirs(
) -> None:
    """The traffic preset's tracker survives a step with the recording's probability and its
    planning values faded tracks as ones to confirm; the study files keep the generic 0.99
    and localise, but the methods that set either."""
    from sensorplan.simulation.scenario import TRAFFIC_SURVIVAL
    from sensorplan.study.file import load_study

    preset = load_simulation(preset="traffic").settings
    assert (preset.tracker.survival_probability, preset.unreported) == (0.997, "confirm")
    assert TRAFFIC_SURVIVAL == 0.997
    both = {"traffic_survival_confirm.toml": {"pg/imm", "sequential-greedy/imm",
                                              "dec-independent/imm"},
            "traffic_survival_confirm_dev.toml": {"pg/survival/confirm/imm"},
            "traffic_plan_threshold.toml": {"pg/imm", "pg/plan0.02/imm",
                                            "sequential-greedy/plan0.02/imm",
                                            "dec-independent/plan0.02/imm"}}
    survival = {"traffic_survival_dev.toml": {"pg/survival/imm"}}
    confirm = {"traffic_confirm.toml": {"pmb/confirm"}}
    files = _traffic_study_files()
    assert len(files) >= 13
    for path in files:
        for m in load_study(path).methods:
            named = both.get(path.name, set())
            want = (0.997 if m.name in named | survival.get(path.name, set()) else 0.99,
                    "confirm" if m.name in named | confirm.get(path.name, set()) else "localise")
            got = (m.settings.tracker.survival_probability, m.settings.unreported)
            assert got == want, (path.name, m.name)


@needs_recordings
def test_the_traffic_preset_plans_down_to_0_02_and_earlier_files_keep_0_1() -> None:
    """The traffic preset's planning sees tracks down to existence 0.02, as the radar
    preset's does; every traffic study file keeps 0.1 but the methods that set 0.02."""
    from sensorplan.study.file import load_study

    assert load_simulation(preset="traffic").settings.tracker.planning_threshold == 0.02
    files = _traffic_study_files()
    assert len(files) >= 14
    for path in files:
        for m in load_study(path).methods:
            want = 0.02 if "/plan0.02/" in m.name else 0.1
            assert m.settings.tracker.planning_threshold == want, (path.name, m.name)


@needs_recordings
def test_traffic_study_files_name_the_radars_they_ran() -> None:
    """The traffic study files that name configs/traffic_thermal_radars.toml run the
    preset's scenario (the file is the preset's, written out, so that they keep what they
    ran if the preset's radars change); the study of error floors runs it with radars that
    have floors and 2 km blind discs, and nothing else changed."""
    from sensorplan.config.scenario import scenario_from_dict
    from sensorplan.simulation.scenario import traffic_scenario
    from sensorplan.study.file import load_study

    thermal = scenario_from_dict(tomllib.loads(
        (ROOT / "configs" / "traffic_thermal_radars.toml").read_text()))
    assert thermal == traffic_scenario()
    files = [p for p in sorted((ROOT / "studies").rglob("*.toml"))
             if "traffic_thermal_radars" in p.read_text()]
    assert len(files) >= 10
    for path in files:
        assert load_study(path).scenario == thermal, path.name
    floors = load_study(ROOT / "studies" / "traffic_floors.toml").scenario
    assert dataclasses.replace(floors, sensors=thermal.sensors) == thermal
    for new, old in zip(floors.sensors, thermal.sensors):
        assert (new.params.range_error_floor, math.degrees(new.params.azimuth_error_floor),
                new.params.min_ground_range) == (60.0, pytest.approx(0.14), 2000.0)
        p = dataclasses.replace(new.params, min_ground_range=10000.0, range_error_floor=0.0,
                                azimuth_error_floor=0.0)
        assert dataclasses.replace(new, params=p) == old


def test_the_swarm_preset_has_a_quieter_imm_manoeuvre_mode() -> None:
    swarm = load_simulation(preset="swarm").settings.tracker
    paper = load_simulation(preset="paper").settings.tracker
    assert swarm.mode_process_noise == (0.05, 1.0) and paper.mode_process_noise == (0.05, 5.0)
    assert dataclasses.replace(swarm, mode_process_noise=paper.mode_process_noise) == paper
    # A given value wins: the earlier swarm study files name what they ran.
    from sensorplan.study.file import load_study

    table = load_study(ROOT / "studies" / "honest_table_swarm.toml")
    assert {m.settings.tracker.mode_process_noise for m in table.methods} == {(0.05, 5.0)}


def test_configs_radar_is_the_radar_preset_with_looks_at_one_target() -> None:
    # What docs/results.md section 7 ran: the preset's radar, the paper's looks, known targets.
    cfg = load_simulation(CONFIGS / "radar.toml")
    preset = load_simulation(preset="radar")
    assert cfg.scenario == dataclasses.replace(preset.scenario, look_detects="target")
    assert cfg.settings.tracker.kind == "known"
