"""The search-and-track and benchmark presets on the command line: short runs, tiny studies
and their reports, and one error line naming the key for each kind of bad input."""

from __future__ import annotations

import json

import pytest

from cli_helpers import assert_bad_input, run

TEMPLATES = '[[targets]]\nkind = "cv"\n[[sensors]]\n'
BIRTHS = 'births = "edges"\nbirth_rate = 0.05\n'


@pytest.mark.parametrize("name, c", [("search", 50), ("williams15", 10), ("vo12", 100)])
def test_a_short_run_of_each_preset(name, c, tmp_path, capsys):
    code, out, err = run(capsys, "simulate", "--preset", name, "--steps", "3", "--out",
                         tmp_path / "o")
    assert code == 0, err
    assert f"GOSPA (c = {c} m)" in " ".join(out.split())
    assert (tmp_path / "o" / "episode.npz").exists()
    # The scan presets have no platforms to draw: no figure, and a note saying so.
    assert (tmp_path / "o" / "episode.png").exists() == (name == "search")
    assert ("note: no episode.png" in err) == (name != "search")


@pytest.mark.parametrize("name, c", [("search", 50.0), ("williams15", 10.0),
                                     ("vo12", 100.0)])
def test_a_tiny_study_of_each_preset_and_its_report(name, c, tmp_path, capsys):
    study = tmp_path / "s.toml"
    planner = 'planner = "random"\n' if name == "search" else ""
    study.write_text(f'runs = 1\nsteps = 3\nseed = 5\n[scenario]\npreset = "{name}"\n'
                     f'[[methods]]\nname = "m"\n{planner}')
    out = tmp_path / "out"
    code, _, err = run(capsys, "study", study, "--out", out)
    assert code == 0, err
    resolved = json.loads((out / "config.resolved.json").read_text())
    # The cut-off is study-wide: recorded once, beside the runs and steps.
    assert resolved["gospa_c"] == c and resolved["methods"][0]["tracker"]["kind"] == "pmb"
    assert (out / "gospa.parquet").exists()
    code, _, err = run(capsys, "report", out)
    assert code == 0, err
    assert f"cut-off c = {c:g} m" in (out / "report" / "summary.md").read_text()
    # A replay re-simulates the run exactly (the set records of a multi-target tracker).
    code, text, err = run(capsys, "replay", out, "--run", "0", "--method", "m",
                          "--no-animate", "--out", tmp_path / "replay")
    assert code == 0, err
    assert "identical to the stored run 0" in text
    assert (tmp_path / "replay" / "episode.png").exists() == (name == "search")


def test_a_study_sets_its_own_gospa_cutoff(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text('runs = 1\nsteps = 2\ngospa_c = 3.5\n[scenario]\npreset = "williams15"\n'
                     '[[methods]]\nname = "m"\n')
    assert run(capsys, "study", study, "--out", tmp_path / "o")[0] == 0
    resolved = json.loads((tmp_path / "o" / "config.resolved.json").read_text())
    assert resolved["gospa_c"] == 3.5


def test_a_tracker_that_cannot_search_says_how_to_turn_search_off(tmp_path, capsys):
    line = assert_bad_input(run(capsys, "simulate", "--preset", "search", "--tracker", "gnn",
                                "--out", tmp_path / "o"), "--tracker")
    assert "search preset plans search looks" in line and "add --search off" in line


@pytest.mark.parametrize("args, field", [
    (["--preset", "williams15", "--planner", "random"], "--planner"),
    (["--preset", "vo12", "--horizon", "2"], "--horizon"),
    (["--preset", "vo12", "--animate"], "--animate"),
    (["--preset", "williams15", "--steps", "82"], "--steps"),
    (["--preset", "williams15", "--tracker", "known"], "--tracker"),
    (["--preset", "search", "--search", "off", "--tracker", "known"], "--tracker"),
    (["--preset", "search", "--tracker", "gnn"], "--tracker"),
    (["--preset", "search", "--tracker", "kalman"], "--tracker"),
    (["--preset", "search", "--gospa-c", "0"], "--gospa-c"),
    (["--preset", "paper", "--gospa-c", "-5"], "--gospa-c"),
])
def test_bad_options_exit_2_naming_them(args, field, tmp_path, capsys):
    line = assert_bad_input(run(capsys, "simulate", *args, "--out", tmp_path / "o"), field)
    assert "Traceback" not in line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("text, field, words", [
    ('births = "sometimes"\n' + TEMPLATES, "births", "choose from"),
    ('births = "edges"\nbirth_rate = -0.1\n' + TEMPLATES, "birth_rate", ">= 0"),
    ('births = "uniform"\nbirth_rate = 0.1\nsurvival_probability = 1.0\n' + TEMPLATES,
     "survival_probability", "without bound"),
    (BIRTHS + "survival_probability = 0.0\n" + TEMPLATES, "survival_probability", "(0, 1]"),
    (BIRTHS + "survival_probability = 1.01\n" + TEMPLATES, "survival_probability", "(0, 1]"),
    (BIRTHS + "initial_targets = -1\n" + TEMPLATES, "initial_targets", ">= 0"),
    ('look_detects = "some"\n' + TEMPLATES, "look_detects", "choose from"),
    (BIRTHS + TEMPLATES + '[tracker]\nkind = "known"\n', "tracker.kind", "known targets"),
    (BIRTHS + 'look_detects = "all"\n' + TEMPLATES + '[tracker]\nkind = "pmb"\n'
     "report_threshold = 1.0\n", "tracker.report_threshold", "(0, 1)"),
    (BIRTHS + 'look_detects = "all"\n' + TEMPLATES + '[tracker]\nkind = "pmb"\n'
     "report_threshold = 0.0\n", "tracker.report_threshold", "(0, 1)"),
    (TEMPLATES + '[tracker]\nkind = "particles"\n', "tracker.kind", "unknown tracker kind"),
    (TEMPLATES + "[run]\ngospa_c = 0.0\n", "run.gospa_c", "(0, "),
    (TEMPLATES + "[run]\ngospa_c = -1.0\n", "run.gospa_c", "(0, "),
    ('scripted = "vo12"\nscan = "radar"\nlook_detects = "all"\n[map]\nwidth = 2000.0\n'
     "height = 2000.0\n", "scan", "unknown scan sensor"),
    ('scripted = "vo12"\nscan = "vo12"\nlook_detects = "all"\n[map]\nwidth = 2000.0\n'
     "height = 2000.0\n[[sensors]]\n", "sensors", "must be empty with scan"),
    ('scripted = "vo12"\nscan = "vo12"\n[map]\nwidth = 2000.0\nheight = 2000.0\n',
     "look_detects", "'all'"),
    ('scan = "vo12"\nlook_detects = "all"\n[map]\nwidth = 2000.0\nheight = 2000.0\n'
     '[[targets]]\nkind = "cv"\n', "scan", "scripted = 'vo12'"),
    ('scripted = "vo12"\nscan = "vo12"\nlook_detects = "all"\n[map]\nwidth = 2000.0\n'
     'height = 2000.0\n[tracker]\nkind = "pmb"\n[planning]\nplanner = "random"\n',
     "planning.planner", "planning does not apply"),
])
def test_bad_file_keys_exit_2_naming_them(text, field, words, tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(text)
    line = assert_bad_input(run(capsys, "simulate", scenario, "--steps", "2", "--out",
                                tmp_path / "o"), field)
    assert words in line, line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("extra, field", [
    ('[[methods]]\nname = "m"\nplanner = "random"\n', "methods[0].planner"),
    ('[defaults]\nhorizon = 2\n[[methods]]\nname = "m"\n', "defaults.horizon"),
    ('gospa_c = 0.0\n[[methods]]\nname = "m"\n', "gospa_c"),
])
def test_bad_study_keys_of_a_scan_preset_exit_2_naming_them(extra, field, tmp_path, capsys):
    study = tmp_path / "s.toml"
    head, _, rest = extra.partition("[")
    study.write_text(f'runs = 1\nsteps = 2\n{head}[scenario]\npreset = "williams15"\n'
                     f"[{rest}")
    assert_bad_input(run(capsys, "study", study, "--out", tmp_path / "o"), field)


@pytest.mark.parametrize("name", ["williams15", "vo12"])
def test_agents_refuse_a_scan_preset(name, tmp_path, capsys):
    line = assert_bad_input(run(capsys, "agents", "--preset", name, "--steps", "2", "--out",
                                tmp_path / "o"), "--preset")
    assert "no platforms" in line
