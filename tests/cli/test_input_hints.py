"""Hints for the usual first-hour mix-ups on the command line: the wrong kind of file, an
option that needs another option, and output into a pipe that closes early."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cli_helpers import SPEC7, assert_bad_input, run, said

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
QUICK = ROOT / "configs" / "quick.toml"
STUDY = ROOT / "studies" / "paper.toml"
GRID = ROOT / "studies" / "lookahead_map.toml"
DECISION = ROOT / "examples" / "problem.json"


@pytest.mark.parametrize("command,path,says", [
    ("simulate", STUDY, "is a study file (it has runs and [[methods]]): a study is run with "
                        "sensorplan study; simulate reads a scenario TOML file"),
    ("simulate", GRID, "is a grid file (it has [[axes]]): a grid is run with sensorplan grid; "
                       "simulate reads a scenario TOML file"),
    ("study", QUICK, "is a scenario file (it has [[targets]] and [[sensors]]): a scenario is "
                     "simulated with sensorplan simulate; study reads a study TOML file"),
    ("study", DECISION, "is a single-decision file: a decision is planned with sensorplan "
                        "plan; study reads a study TOML file"),
    ("plan", QUICK, "is a scenario file (it has [[targets]] and [[sensors]]): a scenario is "
                    "simulated with sensorplan simulate; plan reads a single-decision JSON "
                    "file (sensorplan plan --example prints one)"),
    ("plan", STUDY, "is a study file (it has runs and [[methods]]): a study is run with "
                    "sensorplan study; plan reads a single-decision JSON file"),
    ("grid", QUICK, "is a scenario file (it has [[targets]] and [[sensors]]): a scenario is "
                    "simulated with sensorplan simulate; grid reads a grid TOML file"),
])
def test_the_wrong_kind_of_file_is_named_with_its_command(
        command: str, path: Path, says: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    line = assert_bad_input(run(capsys, command, path, *(["--out", out] if command != "plan"
                                                          else [])), str(path))
    assert line.startswith(f"error: {path}: {says}"), line
    assert not out.exists()


def test_a_toml_file_of_no_known_kind_given_to_plan(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "x.toml"
    path.write_text("dt = 1.0\n")
    line = assert_bad_input(run(capsys, "plan", path), str(path))
    assert line == (f"error: {path}: is a TOML file; plan reads a single-decision JSON file "
                    "(sensorplan plan --example prints one)")
    path.write_text("this is [ neither\n")             # then the JSON error, as before
    line = assert_bad_input(run(capsys, "plan", path), str(path))
    assert "invalid JSON" in line


def test_no_gate_alone_names_the_option_to_add(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("simulate", "agents"):
        line = assert_bad_input(run(capsys, command, QUICK, "--no-gate", "--out",
                                    tmp_path / command), "--no-gate")
        assert line.endswith(": add --no-reacquire"), line
    # A file that turns re-acquisition on itself still names its own key.
    path = tmp_path / "s.toml"
    path.write_text(QUICK.read_text() + "\n[tracker]\ngate = false\n")
    assert_bad_input(run(capsys, "simulate", path, "--out", tmp_path / "f"),
                     "tracker.reacquire")


def _into_closed_pipe(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run the CLI with its stdout a pipe whose reading end is already closed (what
    ``| head -1`` becomes once head has read its line): every write fails."""
    read, write = os.pipe()
    os.close(read)
    try:
        env = {**os.environ, "PYTHONPATH": str(SRC)}
        return subprocess.run([sys.executable, "-m", "sensorplan", *args], stdout=write,
                               stderr=subprocess.PIPE, text=True, cwd=cwd, env=env,
                               timeout=600)
    finally:
        os.close(write)


@pytest.mark.parametrize("args", [
    ["plan", str(DECISION)],
    ["simulate", str(QUICK), "--steps", "4", "--out", "OUT"],
    ["--help"],
])
def test_a_closed_stdout_ends_quietly_with_141(args: list[str], tmp_path: Path) -> None:
    args = [str(tmp_path / "o") if a == "OUT" else a for a in args]
    res = _into_closed_pipe(*args, cwd=tmp_path)
    # A run slowed by a loaded host may print its progress lines (stderr is a pipe, not
    # the closed stdout); anything else on stderr would be a message about the pipe.
    assert (res.returncode, said(res.stderr)) == (141, [])


def test_the_plan_is_still_printed_into_an_open_pipe(tmp_path: Path) -> None:
    # The premise of the test above: the same command succeeds when the pipe stays open.
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    res = subprocess.run([sys.executable, "-m", "sensorplan", "plan", str(DECISION)],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["planner"] == SPEC7["planner"]["name"]


def test_a_value_given_to_a_flag_is_named_as_such(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # "--gate false": the flag takes no value, so "false" becomes the scenario file.
    line = assert_bad_input(run(capsys, "simulate", "--preset", "paper", "--gate", "false",
                                "--out", tmp_path / "o"), "false")
    assert line == ("error: false: no such file (a flag such as --gate takes no value: write "
                    "--gate or --no-gate, not --gate false)")


@pytest.mark.parametrize("command", ["study", "grid"])
@pytest.mark.parametrize("text", ["", "# a study, some day\n"])
def test_an_empty_study_or_grid_file_is_named_as_empty(command: str, text: str,
                                                      tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    # It was told "runs: is required" (fuzz pass 4, its fifth run: three cases).
    path = tmp_path / "s.toml"
    path.write_text(text)
    line = assert_bad_input(run(capsys, command, path, "--out", tmp_path / "o"), str(path))
    assert line.startswith(f"error: {path}: is empty; {command} reads a {command} TOML file")
