"""Angles in degrees, small-sample intervals, the example decision file and the command
line's hints for the usual mix-ups."""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from cli_helpers import SPEC7, assert_bad_input, run
from sensorplan.config import decision_from_dict
from sensorplan.config.decision import EXAMPLE_PROBLEM
from sensorplan.errors import ConfigError
from sensorplan.config.scenario import scenario_from_dict
from sensorplan.study import METRIC_RANGES, SMALL_SAMPLE, paired_differences, parse_study, summary

ROOT = Path(__file__).resolve().parents[2]
ANGLES = {"max_turn": (0.0, math.pi, False), "fov_half_angle": (0.0, math.pi, True),
          "depression": (0.0, math.pi / 2, True), "beamwidth": (1e-4, math.pi / 2, False)}


def doc_with(**sensor: float) -> dict:
    d = copy.deepcopy(SPEC7)
    for name in ANGLES:
        d["sensors"][0].pop(name)
    d["sensors"][0].update(sensor)
    return d


# ---------------------------------------------------------------------------- angles


@pytest.mark.parametrize("name", sorted(ANGLES))
def test_degrees_mean_the_same_as_radians(name: str) -> None:
    value = {"max_turn": 45.0, "fov_half_angle": 30.0, "depression": 40.0,
             "beamwidth": 3.0}[name]
    a = decision_from_dict(doc_with(**{name + "_deg": value})).problem.sensors[0]
    b = decision_from_dict(doc_with(**{name: math.radians(value)})).problem.sensors[0]
    assert a == b
    assert getattr(a, name) == math.radians(value)


@pytest.mark.parametrize("name", sorted(ANGLES))
def test_degrees_written_as_radians_are_refused_with_the_hint(name: str) -> None:
    lo, hi, lo_open = ANGLES[name]
    with pytest.raises(ConfigError) as info:
        decision_from_dict(doc_with(**{name: 200.0}))
    assert info.value.field == f"sensors[0].{name}"
    assert f"{name}_deg" in info.value.message and "rad" in info.value.message
    assert ("pi/2" if hi == math.pi / 2 else "pi") in info.value.message
    # The bounds themselves: the upper one is in, the lower one unless the range is open.
    decision_from_dict(doc_with(**{name: hi}))
    if lo_open:
        with pytest.raises(ConfigError):
            decision_from_dict(doc_with(**{name: lo}))
    else:
        decision_from_dict(doc_with(**{name: lo}))


@pytest.mark.parametrize("name", sorted(ANGLES))
def test_both_spellings_or_degrees_out_of_range_are_one_error(name: str) -> None:
    with pytest.raises(ConfigError) as info:
        decision_from_dict(doc_with(**{name: 0.5, name + "_deg": 30.0}))
    assert info.value.field == f"sensors[0].{name}_deg"
    assert f"{name} (radians) or {name}_deg (degrees), not both" in info.value.message
    with pytest.raises(ConfigError) as info:
        decision_from_dict(doc_with(**{name + "_deg": 500.0}))
    assert info.value.field == f"sensors[0].{name}_deg" and "deg" in info.value.message


def test_degrees_in_scenario_and_study_files(capsys, tmp_path) -> None:
    sc = scenario_from_dict({"targets": [{"kind": "dubins", "max_turn_rate_deg": 6.0}],
                             "sensors": [{"fov_half_angle_deg": 45.0, "max_turn_deg": 30.0}]})
    assert sc.targets[0].max_turn_rate == math.radians(6.0)
    assert sc.sensors[0].params.fov_half_angle == math.radians(45.0)
    f = tmp_path / "sc.toml"
    f.write_text("[[targets]]\n[[sensors]]\nfov_half_angle = 30\n")
    line = assert_bad_input(run(capsys, "simulate", f, "--out", tmp_path / "o"),
                            "sensors[0].fov_half_angle")
    assert "fov_half_angle_deg" in line
    f.write_text('[[targets]]\nkind = "dubins"\nmax_turn_rate = 5.0\nmax_turn_rate_deg = 5.0\n'
                 "[[sensors]]\n")
    assert_bad_input(run(capsys, "simulate", f, "--out", tmp_path / "o"),
                     "targets[0].max_turn_rate_deg")
    study = tmp_path / "st.toml"
    study.write_text('runs = 1\nsteps = 2\n[scenario]\nfile = "sc.toml"\n[[methods]]\n'
                     'name = "r"\nplanner = "random"\n')
    f.write_text("[[targets]]\n[[sensors]]\nmax_turn = 45\n")
    line = assert_bad_input(run(capsys, "study", study, "--out", tmp_path / "so"),
                            "scenario.file")
    assert "sensors[0].max_turn" in line and "max_turn_deg" in line


# --------------------------------------------------------------------- small samples


def _metrics(values: dict[str, list[float]]) -> pd.DataFrame:
    rows = [dict(method=m, run=r, kind="cv", rmse=v) for m, vs in values.items()
            for r, v in enumerate(vs)]
    return pd.DataFrame(rows)


def test_rmse_intervals_are_clipped_at_zero_and_small_samples_flagged() -> None:
    x = [1.0, 2.0, 60.0]                     # a t-interval reaching below 0
    s = summary(_metrics({"a": x}))
    row = s.iloc[0]
    half = stats.t.ppf(0.975, 2) * np.std(x, ddof=1) / math.sqrt(3)
    assert np.mean(x) - half < 0             # unclipped it would be negative
    assert row.mean_lo == 0.0
    assert row.mean_hi == pytest.approx(np.mean(x) + half, rel=1e-12)
    assert bool(row.small_sample)
    big = summary(_metrics({"a": list(np.linspace(1, 3, SMALL_SAMPLE))})).iloc[0]
    assert not bool(big.small_sample)
    # Shares are clipped to [0, 1].
    m = _metrics({"a": [0.0, 0.0, 0.9]}).rename(columns={"rmse": "lost_share"})
    s = summary(m, "lost_share").iloc[0]
    assert s.mean_lo == 0.0 and s.mean_hi <= 1.0
    assert METRIC_RANGES["lost_share"] == (0.0, 1.0)


def test_paired_differences_flag_small_samples() -> None:
    study = parse_study('runs = 3\nsteps = 2\n[[methods]]\nname = "myopic"\nplanner = "pg"\n'
                        '[[methods]]\nname = "k2"\nplanner = "pg"\nhorizon = 2\n')
    d = paired_differences(_metrics({"myopic": [1.0, 2.0, 3.0], "k2": [2.0, 2.5, 9.0]}),
                           study)
    row = d.iloc[0]
    assert (row.method, row.reference, row.n) == ("k2", "myopic", 3)
    assert bool(row.small_sample)
    diffs = np.array([1.0, 0.5, 6.0])
    half = stats.t.ppf(0.975, 2) * np.std(diffs, ddof=1) / math.sqrt(3)
    assert row.mean_lo == pytest.approx(diffs.mean() - half, rel=1e-12)   # may be < 0


# ---------------------------------------------------------------------- example file


def test_plan_example_prints_the_shipped_example_and_it_plans(capsys, tmp_path) -> None:
    code, out, err = run(capsys, "plan", "--example")
    assert (code, err) == (0, "")
    shipped = (ROOT / "examples" / "problem.json").read_text()
    assert out == EXAMPLE_PROBLEM == shipped
    json.loads(out)                                     # plain JSON, no comments
    assert out.strip() in (ROOT / "docs" / "cli.md").read_text()
    f = tmp_path / "p.json"
    f.write_text(out)
    code, result, err = run(capsys, "plan", f)
    assert code == 0, err
    assert json.loads(result)["planner"] == "pg"
    assert_bad_input(run(capsys, "plan", "--example", f), "--example")
    assert "--example" in assert_bad_input(run(capsys, "plan"), "PROBLEM.json")


def test_the_readme_points_at_the_shipped_example() -> None:
    readme = (ROOT / "README.md").read_text()
    assert "sensorplan plan examples/problem.json" in readme
    assert "sensorplan plan --example" in readme
    assert not re.search(r"sensorplan plan problem\.json", readme)


# ----------------------------------------------------------------------------- hints


@pytest.mark.parametrize("name,suggested", [("greedy", "sequential-greedy"),
                                            ("pg_refine", "pg-refine"),
                                            ("brute", "brute-force"), ("PG", "pg")])
def test_unknown_planner_names_get_a_suggestion(capsys, name, suggested) -> None:
    line = assert_bad_input(run(capsys, "simulate", "--planner", name), "--planner")
    assert f"did you mean {suggested!r}?" in line


def test_unknown_preset_names_get_a_suggestion(capsys, tmp_path) -> None:
    line = assert_bad_input(run(capsys, "simulate", "--preset", "papr"), "--preset")
    assert "did you mean 'paper'?" in line
    f = tmp_path / "s.toml"
    f.write_text('runs = 1\nsteps = 2\n[scenario]\npreset = "Radar"\n[[methods]]\nname = "r"\n'
                 'planner = "random"\n')
    line = assert_bad_input(run(capsys, "study", f, "--out", tmp_path / "o"),
                            "scenario.preset")
    assert "did you mean 'radar'?" in line


def test_simulate_hints_at_presets_and_decision_files(capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    line = assert_bad_input(run(capsys, "simulate", "paper"), "paper")
    assert "--preset paper" in line
    (tmp_path / "problem.json").write_text(EXAMPLE_PROBLEM)
    line = assert_bad_input(run(capsys, "simulate", "problem.json"), "problem.json")
    assert "sensorplan plan" in line
    (tmp_path / "decision.toml").write_text(EXAMPLE_PROBLEM)      # JSON under another name
    assert "sensorplan plan" in assert_bad_input(run(capsys, "simulate", "decision.toml"),
                                                 "decision.toml")


def test_demo_help_does_not_mention_the_scheduler(capsys) -> None:
    code, out, _ = run(capsys, "demo", "--help")
    assert code == 0 and "--workers" in out and "scheduler" not in out.lower()
