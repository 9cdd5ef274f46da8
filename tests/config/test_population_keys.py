"""The births, deaths and scripted-truth keys of scenario files: what they build, how they
are written back, and the one-line error naming the key for each kind of bad value."""

from __future__ import annotations

import tomllib

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sensorplan.config.scenario import scenario_from_dict, scenario_to_dict
from sensorplan.simulation.scenario import benchmark_scenario, paper_scenario

from cli_helpers import assert_bad_input, run

ROOT = Path(__file__).resolve().parents[2]
TEMPLATES = '[[targets]]\nkind = "cv"\n[[targets]]\nkind = "dubins"\n[[sensors]]\n'


def test_a_births_file_builds_the_scenario(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('births = "edges"\nbirth_rate = 0.05\nsurvival_probability = 0.99\n'
                    "initial_targets = 1\n" + TEMPLATES)
    # (simulate refuses the default tracker of known targets for it: read the scenario)
    sc = scenario_from_dict(tomllib.loads(path.read_text()))
    assert (sc.births, sc.birth_rate, sc.survival_probability, sc.initial_targets) == (
        "edges", 0.05, 0.99, 1)
    assert sc.n_initial == 1 and not sc.known_targets
    assert scenario_from_dict(json.loads(json.dumps(scenario_to_dict(sc)))) == sc


def test_zero_initial_targets_with_births_and_a_scripted_truth(tmp_path):
    sc = scenario_from_dict({"births": "uniform", "birth_rate": 1, "survival_probability":
                             0.9, "initial_targets": 0, "targets": [{}], "sensors": [{}]})
    assert sc.n_initial == 0 and sc.birth_rate == 1.0
    sc = scenario_from_dict({"scripted": "vo12", "map": {"width": 2000, "height": 2000},
                             "targets": [{}], "sensors": [{}]})
    assert sc.n_initial == 0 and sc.scripted == "vo12"
    assert scenario_from_dict(scenario_to_dict(sc)) == sc


def test_known_target_scenarios_are_written_as_before():
    """The new keys are written only when set, so a known-target scenario's written form
    (a study's config.resolved.json) has exactly the keys it had before they existed."""
    d = scenario_to_dict(paper_scenario())
    assert set(d) == {"dt", "process_noise", "map", "initial", "targets", "sensors",
                      "buildings"}
    assert not {"range_error_floor", "azimuth_error_floor"} & set(d["sensors"][0])
    assert paper_scenario().known_targets


def test_error_floors_are_written_when_set_and_read_back():
    sc = scenario_from_dict({"targets": [{}], "sensors": [
        {"range_error_floor": 60.0, "azimuth_error_floor_deg": 0.14}, {}]})
    d = scenario_to_dict(sc)
    assert d["sensors"][0]["range_error_floor"] == 60.0
    assert "range_error_floor" not in d["sensors"][1]
    assert scenario_from_dict(json.loads(json.dumps(d))) == sc


@pytest.mark.parametrize("lines, field, words", [
    ('births = "everywhere"', "births", "choose from none, edges, uniform"),
    ("births = 3", "births", "a string"),
    ('births = "edges"\nbirth_rate = -0.5', "birth_rate", ">= 0"),
    ('births = "edges"\nbirth_rate = 1000.0', "birth_rate", "[0, 100]"),
    ("birth_rate = 0.5", "birth_rate", 'births = "none"'),
    ('births = "edges"\nbirth_rate = nan', "birth_rate", "finite"),
    ('births = "uniform"\nbirth_rate = 0.5', "survival_probability", "without bound"),
    ('births = "uniform"\nbirth_rate = 0.5\nsurvival_probability = 1.0',
     "survival_probability", "without bound"),
    ("survival_probability = 0.0", "survival_probability", "(0, 1]"),
    ("survival_probability = -0.2", "survival_probability", "(0, 1]"),
    ("survival_probability = 1.5", "survival_probability", "(0, 1]"),
    ("initial_targets = -1", "initial_targets", ">= 0"),
    ("initial_targets = 1.5", "initial_targets", "an integer"),
    ("initial_targets = 3", "initial_targets", "at most the number of targets (2)"),
    ("initial_targets = 0", "initial_targets", "no targets"),
    ('scripted = "vo13"', "scripted", "williams15, vo12"),
    ('scripted = "williams15"', "map.width", "300"),
    ('scripted = "vo12"\nbirths = "edges"\n[map]\nwidth = 2000.0\nheight = 2000.0', "scripted",
     "its own births"),
])
def test_bad_population_keys_exit_2_naming_the_key(lines, field, words, tmp_path, capsys):
    # The scalar keys go before the tables (TOML puts everything after [map] in it).
    scenario = tmp_path / "s.toml"
    head, _, tables = lines.partition("\n[")
    scenario.write_text(head + "\n" + TEMPLATES + ("[" + tables + "\n" if tables else ""))
    line = assert_bad_input(run(capsys, "simulate", scenario, "--steps", "2", "--out",
                                tmp_path / "out"), field)
    assert words in line
    assert not (tmp_path / "out").exists()


def test_python_m_sensorplan_refuses_uniform_births_that_never_die(tmp_path):
    """The real command line, in a process of its own: exit 2, one line, no traceback."""
    scenario = tmp_path / "s.toml"
    scenario.write_text('births = "uniform"\nbirth_rate = 0.5\n' + TEMPLATES)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "SENSORPLAN_AOT": "0"}
    done = subprocess.run([sys.executable, "-m", "sensorplan", "simulate", str(scenario),
                           "--steps", "2", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: survival_probability: "), lines


def test_a_scripted_file_needs_no_targets(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('scripted = "williams15"\n[map]\nwidth = 300.0\nheight = 300.0\n'
                    "[[sensors]]\n")
    sc = scenario_from_dict(tomllib.loads(path.read_text()))
    assert sc.scripted == "williams15" and sc.targets == () and sc.n_initial == 0
    assert sc == benchmark_scenario("williams15", sc.sensors)


def test_without_targets_and_without_a_scripted_truth(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text("[[sensors]]\n")
    line = assert_bad_input(run(capsys, "simulate", path, "--steps", "2"), "targets")
    assert line.endswith("is required")


def test_a_tracker_of_known_targets_refuses_a_truth_with_births(tmp_path, capsys) -> None:
    from cli_helpers import run

    f = tmp_path / "births.toml"
    f.write_text('births = "edges"\nbirth_rate = 0.05\n[[targets]]\nkind = "cv"\n'
                 '[[sensors]]\n')
    code, out, err = run(capsys, "simulate", f, "--steps", "3", "--out", tmp_path / "o")
    assert code == 2 and out == ""
    assert err.splitlines() == [
        "error: tracker.kind: a tracker of known targets needs every target known from the "
        "start (births = 'none', survival_probability = 1, no scripted truth); choose a "
        "multi-target tracker"]
