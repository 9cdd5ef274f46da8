"""The report of a study of changing sets adds the per-run GOSPA figure: one box per method
whose median is the median of the runs' mean GOSPA (computed here from gospa.parquet)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd


def test_a_study_of_sets_reports_gospa_per_run(tmp_path: Path) -> None:
    from sensorplan import study as studies
    from sensorplan.report import write_report
    from sensorplan.report.figures import gospa_per_run
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings
    from sensorplan.study.lifespan import study_has_sets
    from sensorplan.study.storage import load_study_dir

    scenario = dataclasses.replace(search_scenario(), look_detects="all")
    methods = tuple(studies.Method(name, RunSettings(planner=planner, steps=8,
                                                     tracker=TrackerSettings(kind="pmb")))
                    for name, planner in (("pmb/pg", "pg"), ("pmb/random", "random")))
    study = studies.Study(scenario=scenario, runs=3, steps=8, seed=52210, methods=methods)
    assert study_has_sets(study)
    out = tmp_path / "study"
    studies.run_study(study, out, workers=1)
    report = write_report(out)
    assert "gospa_runs" in report.figures and report.figures["gospa_runs"].exists()
    md = report.markdown.read_text(encoding="utf-8")
    assert "](gospa_runs.png)" in md
    g = pd.read_parquet(out / "gospa.parquet")
    per_run = gospa_per_run(load_study_dir(out))
    for name in study.method_names:
        mine = g[g["method"] == name]
        means = [mine.loc[mine["run"] == r, "gospa"].mean() for r in range(3)]
        got = per_run.loc[per_run["method"] == name].sort_values("run")["gospa"].to_numpy()
        np.testing.assert_allclose(got, means, rtol=1e-12)
        parts = mine.groupby("run")[["localisation", "missed", "false"]].mean().to_numpy()
        np.testing.assert_allclose(
            per_run.loc[per_run["method"] == name].sort_values("run")[
                ["localisation", "missed", "false"]].to_numpy(), parts, rtol=1e-12)
    # A study of sets is judged by GOSPA: headline and paired differences, from the table.
    from scipy import stats

    def per_run(name: str) -> np.ndarray:
        mine = g[g["method"] == name]
        return np.array([mine.loc[mine["run"] == r, "gospa"].mean() for r in range(3)])

    d = per_run("pmb/pg") - per_run("pmb/random")
    half = stats.t.ppf(0.975, 2) * d.std(ddof=1) / np.sqrt(3)
    assert (f"| pmb/pg | pmb/random | all | {d.mean():.1f} [{d.mean() - half:.1f}, "
            f"{d.mean() + half:.1f}] |") in md
    assert "\u0394 GOSPA mean (m)" in md and "\u0394 RMSE mean (m)" not in md
    assert "mean GOSPA (each run's mean over its steps)" in md
    assert "| pmb/pg (assigned tracks) |" in md
    # Lost share of a set tracker: its target-steps without an assigned track, i.e. GOSPA's
    # missed part counted in targets (c^2/2 each), not the error rule.
    from sensorplan.study.metrics import run_metrics

    c = float(study.methods[0].settings.gospa_c)
    rm = run_metrics(load_study_dir(out))
    for name in study.method_names:
        mine = g[g["method"] == name].groupby("run")[["missed", "targets"]].sum()
        share = (mine["missed"] / (c ** 2 / 2) / mine["targets"]).to_numpy()
        got = rm[(rm["method"] == name) & (rm["kind"] == "all")].sort_values("run")
        np.testing.assert_allclose(got["lost_share"].to_numpy(), share, atol=1e-12)
