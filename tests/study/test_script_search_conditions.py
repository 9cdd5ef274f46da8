"""scripts/search_conditions.py and the ANEES of a multi-target tracker, against direct
computations from a small grid's tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sensorplan.study.grid import load_grid
from sensorplan.study.grid_run import run_grid
from sensorplan.study.metrics import consistency
from sensorplan.study.storage import load_study_dir
from script_helpers import script_module

ROOT = Path(__file__).resolve().parents[2]
GRID = f"""
runs = 6
steps = 30
seed = 5
design = "full"
[scenario]
file = "{(ROOT / 'configs' / 'radar_all.toml').as_posix()}"
[defaults]
planner = "pg"
steps_per_epoch = 2
[[axes]]
feature = "clutter_rate"
values = [3]
[[methods]]
name = "pmb"
[methods.tracker]
kind = "pmb"
[[methods]]
name = "known"
[[comparisons]]
method = "pmb"
reference = "known"
"""


def _script():
    return script_module("search_conditions")


@pytest.fixture(scope="module")
def cell(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("search")
    (base / "g.toml").write_text(GRID)
    run_grid(load_grid(base / "g.toml"), base / "out", workers=1)
    return base / "out" / "clutter_rate=3"


def _longest_nan_run(error: np.ndarray) -> int:
    best = cur = 0
    for e in error:
        cur = cur + 1 if np.isnan(e) else 0
        best = max(best, cur)
    return best


def test_the_scripts_rows_match_a_direct_computation(cell: Path) -> None:
    runs = _script().per_run(load_study_dir(cell)).set_index(["method", "run"])
    g = pd.read_parquet(cell / "gospa.parquet")
    steps = pd.read_parquet(cell / "steps.parquet")
    steps = steps[steps["step"] >= 1]
    for (method, run), r in g.groupby(["method", "run"], observed=True):
        row = runs.loc[(method, run)]
        assert row["gospa"] == pytest.approx(r["gospa"].mean(), rel=1e-12)
        # each missed target costs c^2/2 = 1250 m^2
        missed = r["missed"].to_numpy() / 1250.0
        np.testing.assert_allclose(missed, np.round(missed), atol=1e-9)
        assert row["missed_share"] == pytest.approx(
            100 * missed.sum() / r["targets"].sum(), rel=1e-12)
        if method == "pmb":
            # a pmb target-step has an error only when GOSPA assigned it a track: a target
            # is lost after 20 steps in a row without one
            s = steps[(steps["method"] == method) & (steps["run"] == run)]
            lost = sum(_longest_nan_run(t.sort_values("step")["error"].to_numpy(float)) >= 20
                       for _, t in s.groupby("target"))
            assert row["lost"] == lost
            assert s["error"].isna().sum() == pytest.approx(missed.sum())
    # the paired interval of the GOSPA difference is scipy's
    wide = runs["gospa"].unstack("method")
    d = (wide["pmb"] - wide["known"]).to_numpy(float)
    lo, hi = stats.ttest_rel(wide["pmb"], wide["known"]).confidence_interval()
    text = "\n".join(_script().cell_tables(cell, "pmb", "known"))
    # the wall distances: one per target pmb lost (the same count as the lost column)
    at, wall = _script().lost_at_walls(load_study_dir(cell), "pmb")
    assert at.size == runs.xs("pmb")["lost"].sum()
    assert wall.size == (steps["method"] == "pmb").sum() and (wall >= 0).all()
    assert f"| mean GOSPA (m) | {d.mean():.2f} [{lo:.2f}, {hi:.2f}] |" in text


def test_a_multi_target_trackers_anees_is_over_its_assigned_target_steps(cell: Path) -> None:
    steps = pd.read_parquet(cell / "steps.parquet")
    steps = steps[steps["step"] >= 1]
    pmb = steps[steps["method"] == "pmb"]
    assert pmb["nees"].isna().any() and pmb["nees"].notna().any()
    honest = consistency(load_study_dir(cell))
    row = honest[(honest["method"] == "pmb") & (honest["kind"] == "all")].iloc[0]
    assert row["n"] == pmb["nees"].notna().sum()
    assert row["anees"] == pytest.approx(pmb["nees"].dropna().mean(), rel=1e-12)
    known = honest[(honest["method"] == "known") & (honest["kind"] == "all")].iloc[0]
    assert known["n"] == (steps["method"] == "known").sum()      # every target-step
