"""The study-table scripts refuse a directory that is not a study and a method the study does
not have: exit 2 and one line naming what is wrong, never a traceback or an empty table."""

from __future__ import annotations

from pathlib import Path

import pytest

from sensorplan.study import parse_study, run_study
from script_helpers import script_module

# One short run of one method: the scripts only need a finished study to refuse.
STUDY = """
runs = 1
steps = 12
seed = 5
scenario = {preset = "search"}
methods = [{name = "pg", planner = "pg", search = "off"}]
"""


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bad_input") / "out"
    run_study(parse_study(STUDY), out, workers=1)
    return out


def _refused(capsys: pytest.CaptureFixture[str], script: str, argv: list[str]) -> str:
    if script == "paired_sets":
        script_module("search_conditions")    # its sibling, found on scripts/ when run
    with pytest.raises(SystemExit) as e:
        script_module(script).main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize("script, argv", [
    ("honest_table", ["table", "{missing}"]),
    ("honest_table", ["paired", "{missing}", "pg - pg"]),
    ("search_summary", ["{missing}"]),
    ("untracked_diagnosis", ["tail", "{missing}", "--method", "pg"]),
    ("untracked_diagnosis", ["held", "{missing}", "--method", "pg"]),
    ("honest_summary", ["{missing}"]),
    ("paired", ["{missing}", "pg - pg"]),
    ("paired_sets", ["{missing}"]),
    ("select_tracker", ["{missing}"]),
    ("decentral_figures", ["{missing}", "{missing}", "--out", "{missing}/figures"]),
])
def test_a_directory_that_is_not_a_study_is_refused(
        script: str, argv: list[str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    missing = str(tmp_path / "nothing here")
    line = _refused(capsys, script, [a.format(missing=missing) for a in argv])
    assert "is not a study directory" in line and missing in line


@pytest.mark.parametrize("script, argv, field", [
    ("honest_table", ["paired", "{dir}", "nope - pg"], "pairs"),
    ("search_summary", ["{dir}", "--reference", "nope"], "--reference"),
    ("untracked_diagnosis", ["tail", "{dir}", "--method", "nope"], "--method"),
    ("untracked_diagnosis", ["study", "{dir}", "--method", "nope"], "--method"),
    ("paired", ["{dir}", "nope - pg"], "pairs"),
    ("paired_sets", ["{dir}", "nope - pg"], "pairs"),
])
def test_a_method_the_study_does_not_have_is_refused(
        script: str, argv: list[str], field: str, study_dir: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    line = _refused(capsys, script, [a.format(dir=study_dir) for a in argv])
    assert field in line and "'nope'" in line and "pg" in line


def test_the_summary_without_a_myopic_method_has_no_paired_part(
        study_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The default reference is a convention, not a request: a study without it is summed
    # up without the paired differences.
    script_module("search_summary").main([str(study_dir)])
    out = capsys.readouterr().out
    assert "| mean GOSPA (m) |" in out and "Paired differences" not in out


def test_before_after_refuses_a_directory_that_is_not_a_study(
        study_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = str(tmp_path / "nothing here")
    for argv in ([str(study_dir), missing], [missing, str(study_dir)]):
        assert script_module("before_after").main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("before_after.py: error:") and "nothing here" in err
        assert "Traceback" not in err


def test_a_grid_directory_without_its_grid_or_method_is_refused(
        study_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = _refused(capsys, "search_conditions", [str(tmp_path)])
    assert "grid_dir" in line and "no grid.json" in line
    grid = tmp_path / "grid"
    grid.mkdir()
    (grid / "grid.json").write_text('{"cells": [{"slug": "cell"}]}')
    (grid / "cell").symlink_to(study_dir)
    line = _refused(capsys, "search_conditions", [str(grid), "--method", "pg",
                                                  "--reference", "nope"])
    assert "--reference" in line and "'nope'" in line


def test_nees_events_refuses_a_method_the_study_file_does_not_have(
        capsys: pytest.CaptureFixture[str]) -> None:
    from script_helpers import ROOT

    study = str(ROOT / "studies" / "honest_table_search_mixture.toml")
    line = _refused(capsys, "nees_events", [study, "nope"])
    assert "method" in line and "'nope'" in line and "sequential-greedy" in line


def test_parts_that_cannot_be_joined_are_refused(
        study_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = _refused(capsys, "search_summary", [str(study_dir), "--with", str(study_dir)])
    assert "error: --with:" in line and "'pg'" in line
    line = _refused(capsys, "paired_sets", [str(study_dir), str(study_dir)])
    assert "STUDY_DIR" in line and "'pg' is in two of the studies" in line
