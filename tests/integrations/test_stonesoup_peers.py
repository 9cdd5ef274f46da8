"""The peer comparison's JPDA data associators and the comparison script's study mechanics:
the associator a study file names, runs one index at a time, resuming and stopping.

Skipped cleanly where Stone Soup is not installed (the ``stonesoup`` extra).
"""

from __future__ import annotations

import csv
import datetime
import runpy
import signal
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stonesoup")

from sensorplan.integrations.stonesoup._peers import (JPDA_ASSOCIATORS,  # noqa: E402
                                                      benchmark_model, jpda_deleter,
                                                      jpda_tracker, to_detections)

ROOT = Path(__file__).resolve().parents[2]
T0 = datetime.datetime(2026, 1, 1)


def script() -> dict:
    return runpy.run_path(str(ROOT / "benchmarks" / "compare_trackers.py"), run_name="script")


def final_tracks(associator: str, scans: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    model = benchmark_model("williams15")
    tr = jpda_tracker(model, 2, jpda_deleter("steps3", model), T0, associator=associator)
    assert type(tr.data_associator) is JPDA_ASSOCIATORS[associator]
    tracks: set = set()
    for k, z in enumerate(scans, start=1):
        time = T0 + datetime.timedelta(seconds=k)
        _, tracks = tr.update_tracker(time, to_detections(z, time, model.measurement_model))
    states = [(np.asarray(t.state.state_vector, float).ravel(), np.asarray(t.state.covar, float))
              for t in tracks]
    return sorted(states, key=lambda s: tuple(s[0]))


def test_lbp_gives_the_exhaustive_jpda_where_no_two_tracks_share_a_detection():
    # Two targets far apart, one detection each per scan, no clutter: every track's gated
    # detections are its own, the association graph has no loop, and belief propagation is
    # exact there, so JPDAwithLBP's tracks are JPDA's.
    rng = np.random.default_rng(3)
    scans = []
    for k in range(1, 13):
        xy = np.array([[50.0 + k, 50.0 + 0.5 * k], [250.0 - k, 250.0]])
        scans.append(xy + rng.normal(0.0, 1.0, xy.shape))
    exact = final_tracks("JPDA", scans)
    lbp = final_tracks("JPDAwithLBP", scans)
    assert len(exact) == len(lbp) == 2
    for (m1, P1), (m2, P2) in zip(exact, lbp, strict=True):
        np.testing.assert_allclose(m2, m1, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(P2, P1, rtol=1e-6, atol=1e-9)


def test_an_unknown_associator_is_refused():
    model = benchmark_model("vo12")
    with pytest.raises(ValueError, match="associator"):
        jpda_tracker(model, 2, jpda_deleter("steps3", model), T0, associator="MHT")


STUDY = """
description = "test"
runs = {runs}
[seeds]
williams15 = 7
vo12 = 8
[jpda_associator]
vo12 = "{vo12}"
[gospa]
williams15 = 10.0
vo12 = 100.0
[[configs]]
name = "pmb"
kind = "pmb"
[[configs]]
name = "gnn"
kind = "gnn"
[[configs]]
name = "jpda-a"
kind = "jpda"
min_points = 3
deleter = "steps3"
"""


def test_a_study_files_associator_reaches_each_benchmarks_jpda_configurations(tmp_path, capsys):
    s = script()
    path = tmp_path / "study.toml"
    path.write_text(STUDY.format(runs=3, vo12="JPDAwithLBP"))
    vo12 = s["load"](path, "vo12")
    williams15 = s["load"](path, "williams15")
    assert [c.get("associator") for c in vo12["configs"]] == [None, None, "JPDAwithLBP"]
    assert [c.get("associator") for c in williams15["configs"]] == [None, None, "JPDA"]
    path.write_text(STUDY.format(runs=3, vo12="exhaustive"))
    with pytest.raises(SystemExit) as exc:
        s["load"](path, "vo12")
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: jpda_associator.vo12:")


def rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def test_runs_go_one_index_at_a_time_and_a_stopped_study_resumes_to_the_same_rows(tmp_path,
                                                                                  capsys):
    s = script()
    study = tmp_path / "study.toml"
    study.write_text(STUDY.format(runs=3, vo12="JPDA"))
    spec = s["load"](study, "williams15")
    spec["configs"] = spec["configs"][:2]            # pmb and gnn: fast
    out = tmp_path / "out.csv"
    s["run_study"](spec, "williams15", 2, out)
    first = rows(out)
    assert [(r["run"], r["config"]) for r in first] == [
        ("0", "pmb"), ("0", "gnn"), ("1", "pmb"), ("1", "gnn")]
    # A stop inside run 1 that lost gnn's row: the same study redoes that row alone, the same
    # as before (the run's detections come from its own seed), then goes on to run 2.
    out.write_text("".join(out.read_text().splitlines(keepends=True)[:-1]))
    s["run_study"](spec, "williams15", 3, out)
    again = rows(out)
    assert [(r["run"], r["config"]) for r in again] == [
        ("0", "pmb"), ("0", "gnn"), ("1", "pmb"), ("1", "gnn"), ("2", "pmb"), ("2", "gnn")]
    assert again[3]["mean_gospa"] == first[3]["mean_gospa"]
    # A stop time already past starts no run.
    past = datetime.datetime.now(datetime.UTC) - datetime.timedelta(minutes=1)
    other = tmp_path / "other.csv"
    s["run_study"](spec, "williams15", 3, other, past)
    assert rows(other) == []
    # Two of three declared runs: an interim look, no verdict; all three: no "interim".
    capsys.readouterr()
    s["summary"](out, "williams15", 2, spec["configs"], 3)
    text = capsys.readouterr().out
    assert "interim look: runs 0..1 of the declared 3" in text and "no verdict" in text
    s["summary"](out, "williams15", 3, spec["configs"], 3)
    text = capsys.readouterr().out
    assert "3 paired runs," in text and "interim" not in text and "no verdict" not in text


def test_a_tracker_run_past_the_time_limit_is_written_as_timed_out_and_the_study_goes_on(
        tmp_path, capsys):
    s = script()
    study = tmp_path / "study.toml"
    study.write_text(STUDY.format(runs=2, vo12="JPDA"))
    spec = s["load"](study, "williams15")
    spec["configs"] = spec["configs"][:2]
    spec["time_limit"] = {"seconds_per_run": 1e-6}     # every run reaches it
    out = tmp_path / "out.csv"
    s["run_study"](spec, "williams15", 2, out)
    got = rows(out)
    assert [(r["run"], r["config"]) for r in got] == [
        ("0", "pmb"), ("0", "gnn"), ("1", "pmb"), ("1", "gnn")]
    assert all(r["mean_gospa"] == "nan" for r in got)
    assert "timed out after" in capsys.readouterr().out
    # The limit is lifted after each run: nothing fires later in the process.
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_a_configuration_with_timed_out_runs_is_not_eligible_as_its_trackers_best(tmp_path,
                                                                                   capsys):
    s = script()
    configs = [{"name": "pmb", "kind": "pmb"}, {"name": "j-fast", "kind": "jpda"},
               {"name": "j-stall", "kind": "jpda"}]
    rng = np.random.default_rng(3)
    gospa = {"pmb": 5.0 + rng.normal(0, 0.1, 4), "j-fast": 9.0 + rng.normal(0, 0.1, 4),
             "j-stall": np.array([1.0, np.nan, 1.2, 1.1])}
    out = tmp_path / "out.csv"
    with out.open("w", newline="") as f:
        w = csv.DictWriter(f, s["FIELDS"])
        w.writeheader()
        for r in range(4):
            for n, g in gospa.items():
                w.writerow({"benchmark": "williams15", "run": r, "config": n,
                            "mean_gospa": repr(float(g[r])), "localisation": 1, "missed": 1,
                            "false": 1, "step_seconds_median": 0.01,
                            "step_seconds_mean": 0.01, "steps": 81})
    s["summary"](out, "williams15", 4, configs, 4)
    text = capsys.readouterr().out
    verdict = next(line for line in text.splitlines() if line.startswith("decision vs jpda"))
    # The stalled configuration is lower on the runs it finished but cannot be the best.
    assert "(best: j-fast)" in verdict and "pmb better" in verdict
    assert "for transparency: j-stall (not eligible, 1 runs timed out)" in text
    assert "over 3 runs" in text
    stall = next(line for line in text.splitlines() if line.startswith("j-stall"))
    assert stall.split()[-1] == "1"


def test_a_stop_time_of_day_already_past_today_means_tomorrow():
    s = script()
    now = datetime.datetime(2026, 12, 3, 22, 40, 5, tzinfo=datetime.UTC)
    assert s["next_time_of_day"](0, 50, now) == datetime.datetime(2026, 12, 4, 0, 50,
                                                                 tzinfo=datetime.UTC)
    assert s["next_time_of_day"](23, 5, now) == datetime.datetime(2026, 12, 3, 23, 5,
                                                                 tzinfo=datetime.UTC)
    assert s["next_time_of_day"](22, 40, now) == datetime.datetime(2026, 12, 4, 22, 40,
                                                                  tzinfo=datetime.UTC)
