"""The recorded-traffic preset on the command line: one error line saying how to fetch the
records when they are missing, and (only when they have been fetched) a short closed-loop
run with search looks and a tiny study. Nothing here downloads."""

from __future__ import annotations

import json

import pytest

from cli_helpers import assert_bad_input, run
from sensorplan.models import traffic as tf

HAVE_DATA = tf.data_path().is_file()
needs_data = pytest.mark.skipif(not HAVE_DATA, reason="the recorded flights are not fetched "
                                f"({tf.FETCH_COMMAND})")


def test_missing_records_are_one_error_line_with_the_fetch_command(tmp_path, capsys,
                                                                    monkeypatch):
    monkeypatch.setenv(tf.DATA_ENV, str(tmp_path / "absent.json.gz"))
    line = assert_bad_input(run(capsys, "simulate", "--preset", "traffic", "--steps", "2",
                                "--out", tmp_path / "o"), "--preset")
    assert tf.FETCH_COMMAND in line
    study = tmp_path / "s.toml"
    study.write_text('runs = 1\nsteps = 2\n[scenario]\npreset = "traffic"\n'
                     '[[methods]]\nname = "m"\n')
    line = assert_bad_input(run(capsys, "study", study, "--out", tmp_path / "s"),
                            "scenario.preset")
    assert tf.FETCH_COMMAND in line


@needs_data
def test_a_short_run_with_search_looks(tmp_path, capsys):
    code, out, err = run(capsys, "simulate", "--preset", "traffic", "--search", "on",
                         "--steps", "4", "--out", tmp_path / "o")
    assert code == 0, err
    text = " ".join(out.split())
    assert "GOSPA (c = 500 m)" in text and "search:" in text
    assert (tmp_path / "o" / "episode.npz").exists()


@needs_data
def test_a_tiny_study_runs_a_method_on_the_recorded_truth(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text('runs = 2\nsteps = 3\nseed = 5\n[scenario]\npreset = "traffic"\n'
                     '[[methods]]\nname = "m"\nplanner = "random"\n')
    out = tmp_path / "out"
    code, _, err = run(capsys, "study", study, "--out", out)
    assert code == 0, err
    resolved = json.loads((out / "config.resolved.json").read_text())
    assert resolved["gospa_c"] == 500.0 and resolved["methods"][0]["tracker"]["kind"] == "pmb"
