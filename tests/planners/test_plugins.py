"""Planners written outside the package: examples/nearest_planner.py through @register,
the ``module:Class`` form and an entry point, in the CLI, files, studies and reports."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cli_helpers import SPEC7, run
from sensorplan.config import decision_from_dict, load_simulation
from sensorplan.errors import ConfigError
from sensorplan.planners import (ENTRY_POINT_GROUP, PLANNERS, check_planner, make_planner,
                                 planner_class, potential)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SRC = ROOT / "src"
REFERENCE = "nearest_planner:NearestTargetPlanner"


def test_the_example_passes_the_contract(nearest_on_path: None) -> None:
    cls = planner_class(REFERENCE)
    check_planner(cls())
    assert "nearest" in PLANNERS                    # importing it ran @register


def test_the_docs_show_the_example_verbatim() -> None:
    doc = (ROOT / "docs" / "planning.md").read_text()
    code = re.search(r"```python\n(@register\n.*?)```", doc, re.S).group(1)
    assert code in (EXAMPLES / "nearest_planner.py").read_text()


def test_module_class_form_in_plan_files_and_options(
        nearest_on_path: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = {**SPEC7, "planner": {"name": REFERENCE, "standoff": 300}}
    decision = decision_from_dict(data)
    assert dict(decision.settings) == {"standoff": 300.0}
    path = tmp_path / "p.json"
    path.write_text(json.dumps(SPEC7))
    code, out, err = run(capsys, "plan", path, "--planner", REFERENCE)
    assert code == 0, err
    result = json.loads(out)
    assert result["planner"] == "nearest"
    # The printed plan is the planner's own, and Phi is its plan's.
    problem = decision.problem
    own = make_planner(REFERENCE).plan(problem)
    assert [[a["target"] for a in row] for row in result["plan"]] == own.plan.targets.tolist()
    assert result["potential"] == pytest.approx(potential(problem, own.plan)[0], rel=1e-12)


@pytest.mark.parametrize("params,field,message", [
    ({"standof": 300.0}, "planner.standof",
     "unknown key for planner 'nearest' (did you mean 'standoff'?); allowed: standoff, seed"),
    ({"standoff": "far"}, "planner.standoff", "must be a number, got 'far'"),
    ({"standoff": -1.0}, "planner.standoff", "standoff must be >= 0 m, got -1.0"),
])
def test_its_settings_are_its_fields(nearest_on_path: None, params: dict, field: str,
                                     message: str) -> None:
    with pytest.raises(ConfigError) as err:
        decision_from_dict({**SPEC7, "planner": {"name": REFERENCE, **params}})
    assert (err.value.field, err.value.message) == (field, message)


def test_module_class_form_in_a_scenario(nearest_on_path: None, tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(f'[planning]\nplanner = "{REFERENCE}"\n[planning.planner_params]\n'
                    'standoff = 250\n[[targets]]\n[[sensors]]\n')
    settings = load_simulation(path).settings
    assert (settings.planner, dict(settings.planner_params)) == (REFERENCE, {"standoff": 250.0})
    # simulate --planner: the file's settings the new planner lacks are dropped.
    path.write_text('[planning]\nplanner = "pg"\n[planning.planner_params]\nalpha = 0.5\n'
                    '[[targets]]\n[[sensors]]\n')
    settings = load_simulation(path, overrides={"planner": REFERENCE}).settings
    assert (settings.planner, dict(settings.planner_params)) == (REFERENCE, {})
    with pytest.raises(ConfigError) as err:
        load_simulation(path, overrides={"planner": "nearest_planner:Nearest"})
    assert err.value.field == "--planner"


@pytest.mark.parametrize("name,message", [
    ("no_such_module:Planner", "cannot import 'no_such_module' for planner "
                               "'no_such_module:Planner'"),
    ("nearest_planner:Nope", "module 'nearest_planner' has no 'Nope'"),
    ("nearest_planner:np", "'nearest_planner:np' is not a planner class: not a class"),
    ("nearest_planner:", "'nearest_planner:' is not a planner reference"),
])
def test_bad_references_say_why(nearest_on_path: None, name: str, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        make_planner(name)
    assert err.value.field == "planner.name"
    assert err.value.message.startswith(message)


def _plugin_site(tmp_path: Path) -> Path:
    """A directory holding the example module and the metadata of an installed
    distribution that declares it as an entry point (what ``pip install`` leaves)."""
    site = tmp_path / "site"
    dist = site / "sensorplan_nearest-0.1.dist-info"
    dist.mkdir(parents=True)
    shutil.copy(EXAMPLES / "nearest_planner.py", site)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: sensorplan-nearest\n"
                                   "Version: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\nnearest = {REFERENCE}\n")
    return site


def test_an_entry_point_adds_a_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert "nearest" not in PLANNERS
    monkeypatch.syspath_prepend(str(_plugin_site(tmp_path)))
    try:
        assert "nearest" in PLANNERS and "nearest" in sorted(PLANNERS)
        assert make_planner("nearest", standoff=200.0).standoff == 200.0
        with pytest.raises(ConfigError) as err:
            make_planner("nearst")
        assert "(did you mean 'nearest'?)" in err.value.message
    finally:
        sys.modules.pop("nearest_planner", None)
        del PLANNERS["nearest"]                      # loading it ran @register


# -------------------------------------------------- study and report, as processes

STUDY = """
runs = 1
steps = 4
seed = 5
[scenario]
preset = "paper"
[defaults]
horizon = 2
[[methods]]
name = "nearest"
planner = "{planner}"
[methods.planner_params]
standoff = 300.0
[[methods]]
name = "pg"
planner = "pg"
"""


def _cli(args: list[str], pythonpath: list[Path], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(str(p) for p in pythonpath)}
    return subprocess.run([sys.executable, "-m", "sensorplan", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def _study_and_report(tmp_path: Path, planner: str, path: list[Path], workers: int) -> None:
    (tmp_path / "study.toml").write_text(STUDY.format(planner=planner))
    done = _cli(["study", "study.toml", "--out", "run", "--workers", str(workers)],
                [SRC, *path], tmp_path)
    assert done.returncode == 0, done.stderr
    resolved = json.loads((tmp_path / "run" / "config.resolved.json").read_text())
    assert resolved["methods"][0]["planner"] == planner
    assert resolved["methods"][0]["planner_params"] == {"standoff": 300.0}
    # The report is written where the plugin cannot be imported.
    probe = subprocess.run([sys.executable, "-c", "import nearest_planner"], cwd=tmp_path,
                           env={**os.environ, "PYTHONPATH": str(SRC)}, capture_output=True)
    assert probe.returncode != 0
    report = _cli(["report", "run"], [SRC], tmp_path)
    assert report.returncode == 0, report.stderr
    summary = (tmp_path / "run" / "report" / "summary.md").read_text()
    assert "nearest" in summary and "pg" in summary


def test_a_study_through_the_entry_point_reports_without_the_plugin(tmp_path: Path) -> None:
    """An installed plugin; the report runs where it is not installed."""
    _study_and_report(tmp_path, "nearest", [_plugin_site(tmp_path)], workers=1)


def test_a_study_through_module_class_reports_without_the_module(tmp_path: Path) -> None:
    _study_and_report(tmp_path, REFERENCE, [EXAMPLES], workers=1)


SCRIPT = """
import sys
sys.path.insert(0, {examples!r})
from nearest_planner import NearestTargetPlanner          # registers 'nearest'
from sensorplan.study import parse_study, run_study

study = parse_study({study!r})
if __name__ == "__main__":
    res = run_study(study, "out", workers=2)
    print("ran", res.ran)
"""


@pytest.mark.slow
def test_worker_processes_find_an_installed_plugin(tmp_path: Path) -> None:
    _study_and_report(tmp_path, "nearest", [_plugin_site(tmp_path)], workers=2)


@pytest.mark.slow
def test_run_study_from_a_script_with_a_planner_it_registers(tmp_path: Path) -> None:
    """Spawned workers import the script again, so its planner is registered there too."""
    script = tmp_path / "my_study.py"
    script.write_text(SCRIPT.format(examples=str(EXAMPLES),
                                    study=STUDY.format(planner="nearest")))
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["ran", "2"]
