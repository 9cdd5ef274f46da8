"""scripts/paired.py: paired differences of any two methods, against a direct computation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sensorplan.errors import ConfigError
from sensorplan.study import run_study, study_from_dict
from script_helpers import script_module

ROOT = Path(__file__).resolve().parents[2]


def _paired_module():
    return script_module("paired")


def test_paired_rows_match_a_direct_computation(tmp_path: Path) -> None:
    study = study_from_dict({"runs": 4, "steps": 8, "seed": 7, "scenario": {"preset": "paper"},
                             "methods": [{"name": "random", "planner": "random"},
                                         {"name": "myopic", "planner": "pg", "horizon": 1}]})
    run_study(study, tmp_path / "s", workers=1)
    rows = _paired_module().rows(str(tmp_path / "s"), [("myopic", "random")])
    assert len(rows) == 2 + 3                               # header + cv, dubins, all
    steps = pd.read_parquet(tmp_path / "s" / "steps.parquet")
    steps = steps[steps["step"] >= 1]
    rmse = {m: g.groupby("run")["error"].apply(lambda e: np.sqrt(np.mean(e ** 2)))
            for m, g in steps.groupby("method", observed=True)}
    d = (rmse["myopic"] - rmse["random"]).to_numpy(float)
    lo, hi = stats.t.interval(0.95, d.size - 1, loc=d.mean(), scale=stats.sem(d))
    all_row = next(r for r in rows if "| all |" in r)
    assert f"{d.mean():+.1f} [{lo:+.1f}, {hi:+.1f}]" in all_row
    assert f"{100 * np.mean(d < 0):.0f} %" in all_row


def test_paired_names_an_unknown_method(tmp_path: Path) -> None:
    study = study_from_dict({"runs": 1, "steps": 3, "seed": 7, "scenario": {"preset": "paper"},
                             "methods": [{"name": "random", "planner": "random"}]})
    run_study(study, tmp_path / "s", workers=1)
    with pytest.raises(ConfigError, match="'myopic' is not a method"):
        _paired_module().rows(str(tmp_path / "s"), [("myopic", "random")])
