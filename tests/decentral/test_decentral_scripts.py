"""The decentralized-planning evidence: its study files, the open-loop script and the
figure script (scripts/decentral_potential.py, scripts/decentral_figures.py)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sensorplan.decentral import DecentralJSFPPlanner
from sensorplan.study import load_study, run_study, study_from_dict
from script_helpers import script_module

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_ROUNDS = next(f.default for f in dataclasses.fields(DecentralJSFPPlanner)
                      if f.name == "rounds")


def _script(name: str) -> Any:
    """A module of scripts/, imported under its own name (once)."""
    return script_module(name)


# ------------------------------------------------------------------------ study files

#: The lead's list: method -> (planner, the planner settings it must run with).
EXPECTED = {
    "pg": ("pg", {}),
    "independent": ("dec-independent", {"rounds": DEFAULT_ROUNDS}),
    "sequential": ("dec-sequential", {"p_loss": 0.0}),
    **{f"jsfp R={r}": ("dec-jsfp", {"rounds": r, "p_loss": 0.0}) for r in (1, 2, 4, 8)},
    "jsfp": ("dec-jsfp", {"rounds": DEFAULT_ROUNDS, "p_loss": 0.0}),
    **{f"jsfp p={p}": ("dec-jsfp", {"rounds": DEFAULT_ROUNDS, "p_loss": p})
       for p in (0.1, 0.3, 0.5)},
    **{f"sequential p={p}": ("dec-sequential", {"p_loss": p}) for p in (0.1, 0.3, 0.5)},
}


@pytest.mark.parametrize("name, seed", [("decentral", 5077), ("decentral_holes", 5081)])
def test_study_files_resolve_to_the_intended_planners(name: str, seed: int) -> None:
    study = load_study(ROOT / "studies" / f"{name}.toml")
    assert (study.runs, study.steps, study.seed) == (100, 100, seed)
    assert study.method_names == list(EXPECTED)
    for m in study.methods:
        planner, params = EXPECTED[m.name]
        s = m.settings
        assert s.planner == planner, m.name
        assert {k: s.planner_params[k] for k in params} == params, m.name
        assert (s.horizon, s.steps_per_epoch, s.execution) == (3, 2, "olf"), m.name
        # Everything else is the project's default: perfect delay and range, in-process
        # agents, the game's learning settings, our visibility/objective/tracker.
        if planner != "pg":
            assert s.planner_params["transport"] == "inproc"
        if planner in ("dec-jsfp", "dec-sequential"):
            assert s.planner_params["delay"] == 0
            assert s.planner_params["comm_range"] == math.inf
        if planner in ("dec-jsfp", "dec-independent"):
            assert s.planner_params["mode"] == "jsfp"
        if planner != "dec-sequential":
            assert (s.planner_params["alpha"], s.planner_params["beta"],
                    s.planner_params["max_inner"], s.planner_params["max_outer"]) == \
                (0.3, 0.95, 50, 10)
        assert (s.visibility, s.objective) == ("probabilistic", "terminal")
        assert s.tracker == study.methods[0].settings.tracker
    sensors = [sp.params for sp in study.scenario.sensors]
    if name == "decentral_holes":
        assert all((p.min_ground_range, p.max_ground_range, p.moves) == (350.0, 450.0,
                                                                         (10.0, 20.0))
                   for p in sensors)
    else:
        assert [p.altitude for p in sensors] == [490.0, 500.0, 510.0]
        assert all(p.min_ground_range != 350.0 for p in sensors)


# -------------------------------------------------------------------- open-loop script


def test_first_decision_is_the_closed_loop_first_problem(monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    """The open-loop problems are the simulator's first decision, field by field."""
    from sensorplan.simulation import run as simulation
    pot = _script("decentral_potential")
    scenario, settings, _ = pot.study_methods(pot.STUDIES["holes"])
    seen = []
    real = simulation.make_planner

    class Recorder:
        def __init__(self, inner: Any) -> None:
            self.inner = inner

        def plan(self, problem: Any, rng: Any = None) -> Any:
            seen.append(problem)
            return self.inner.plan(problem, rng=rng)

    monkeypatch.setattr(simulation, "make_planner",
                        lambda name, **kw: Recorder(real(name, **kw)))
    ss = np.random.SeedSequence(42, spawn_key=(3,))
    simulation.run_episode(scenario, dataclasses.replace(settings, steps=1), ss)
    ours = pot.first_decision(scenario, settings, ss)
    theirs = seen[0]
    for f in dataclasses.fields(theirs):
        a, b = getattr(ours, f.name), getattr(theirs, f.name)
        if isinstance(a, np.ndarray) or np.ndim(a) > 0 and not isinstance(a, tuple):
            np.testing.assert_array_equal(a, b, err_msg=f.name)
        else:
            assert a == b, f.name
    # The default tracker (an IMM) plans with its effective q, not the scenario's 0.05.
    assert np.all(np.asarray(ours.process_noise) > scenario.process_noise)


@pytest.fixture(scope="module")
def openloop_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The open-loop script on 3 tiny problems."""
    out = tmp_path_factory.mktemp("openloop")
    _script("decentral_potential").run(out, seed=5099, problems=3, sets=("tiny",),
                                       quiet=True)
    return out


def test_no_plan_beats_the_exact_optimum(openloop_dir: Path) -> None:
    pot = _script("decentral_potential")
    raw = pot.read_raw(openloop_dir / "openloop.csv")
    assert sorted(raw["problem"].unique()) == [0, 1, 2]
    assert set(raw["method"]) == set(EXPECTED)          # pg and every decentralized method
    assert (raw["reference"] == "brute-force").all()
    # The optimum bounds every plan (Phi*, not pg, is the reference here).
    assert (raw["phi"] <= raw["phi_reference"] * (1 + 1e-9) + 1e-12).all()
    ok = raw["ratio"].dropna()
    assert len(ok) == len(raw) and (ok <= 1 + 1e-9).all()
    # Paired: with perfect links and the default budget dec-jsfp is pg, bit for bit.
    wide = raw.pivot(index="problem", columns="method", values="phi")
    np.testing.assert_array_equal(wide["jsfp"], wide["pg"])


def test_open_loop_summary_and_resume(openloop_dir: Path, monkeypatch: pytest.MonkeyPatch
                                      ) -> None:
    pot = _script("decentral_potential")
    raw = pot.read_raw(openloop_dir / "openloop.csv")
    summary = pd.read_csv(openloop_dir / "summary.csv")
    table = summary[summary["set"] == "tiny"].set_index("method")
    multi = summary[summary["set"] == pot.MULTI].set_index("method")
    n_multi = raw.loc[raw["n_sensors"] >= 2, "problem"].nunique()
    assert (multi["n"] == n_multi).all() if n_multi else multi.empty
    for method, g in raw.groupby("method"):
        x = g["ratio"].to_numpy(float)
        assert table.loc[method, "n"] == x.size
        np.testing.assert_allclose(table.loc[method, "mean"], x.mean(), rtol=1e-12)
        lo, hi = stats.t.interval(0.95, x.size - 1, loc=x.mean(),
                                  scale=x.std(ddof=1) / np.sqrt(x.size))
        if x.std() > 0:
            np.testing.assert_allclose([table.loc[method, "mean_lo"],
                                        table.loc[method, "mean_hi"]], [lo, hi], rtol=1e-9)
        np.testing.assert_allclose(table.loc[method, "median"], np.median(x), rtol=1e-12)
        np.testing.assert_allclose(table.loc[method, "below"], np.mean(x < 1 - 1e-9))
    # Running again computes nothing and rewrites the same files.
    before = {p.name: p.read_bytes() for p in openloop_dir.iterdir()}

    def fail(*args: Any) -> None:
        raise AssertionError("recomputed a finished problem")

    monkeypatch.setattr(pot, "problem_rows", fail)
    pot.run(openloop_dir, seed=5099, problems=3, sets=("tiny",), quiet=True)
    assert {p.name: p.read_bytes() for p in openloop_dir.iterdir()} == before
    with pytest.raises(SystemExit) as exc:
        pot.run(openloop_dir, seed=1, problems=3, sets=("tiny",), quiet=True)
    assert exc.value.code == 2


# ----------------------------------------------------------------------- figure script

CHEAP = {"runs": 2, "steps": 10, "defaults": {
    "planner": "pg", "horizon": 1, "steps_per_epoch": 2,
    "planner_params": {"max_outer": 2, "max_inner": 10}}, "methods": [
    {"name": "pg"},
    {"name": "independent", "planner": "dec-independent"},
    {"name": "sequential", "planner": "dec-sequential"},
    {"name": "jsfp R=1", "planner": "dec-jsfp", "planner_params": {"rounds": 1}},
    {"name": "jsfp", "planner": "dec-jsfp"},
    {"name": "jsfp p=0.5", "planner": "dec-jsfp", "planner_params": {"p_loss": 0.5}},
    {"name": "sequential p=0.5", "planner": "dec-sequential",
     "planner_params": {"p_loss": 0.5}}]}


@pytest.fixture(scope="module")
def study_dirs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("studies")
    paper = study_from_dict(dict(CHEAP, seed=1, scenario={"preset": "paper"}))
    holes = study_from_dict(dict(CHEAP, seed=2, scenario={"file": "configs/holes.toml"}),
                            base_dir=ROOT)
    run_study(paper, base / "paper", workers=1)
    run_study(holes, base / "holes", workers=1)
    return base / "paper", base / "holes"


def _direct(steps: pd.DataFrame) -> pd.DataFrame:
    """Per method, straight from steps.parquet: RMSE over steps 1..S and every target per
    run, its mean with the t-interval, its median, the paired difference against pg (none
    for pg itself), ANEES and the runs whose largest error exceeds 300 m."""
    d = steps[steps["step"] >= 1]
    out = []
    per_run = {m: g.groupby("run")["error"].apply(lambda e: np.sqrt(np.mean(e ** 2)))
               for m, g in d.groupby("method", observed=True)}
    for method, g in d.groupby("method", observed=True):
        x = per_run[method].to_numpy(float)
        lo, hi = stats.t.interval(0.95, x.size - 1, loc=x.mean(),
                                  scale=x.std(ddof=1) / np.sqrt(x.size))
        diff = x - per_run["pg"].reindex(per_run[method].index).to_numpy(float)
        # An RMSE interval stays at or above zero, where every RMSE lies.
        out.append(dict(method=method, rmse_mean=x.mean(), rmse_lo=max(lo, 0.0), rmse_hi=hi,
                        rmse_median=np.median(x),
                        diff_pg_mean=math.nan if method == "pg" else diff.mean(),
                        anees=g["nees"].mean(),
                        diverged=int((g.groupby("run")["error"].max() > 300.0).sum())))
    return pd.DataFrame(out).set_index("method")


def test_figure_script_writes_its_figures_and_the_study_numbers(
        study_dirs: tuple[Path, Path], openloop_dir: Path, tmp_path: Path) -> None:
    from PIL import Image

    fig = _script("decentral_figures")
    out = tmp_path / "figs"
    fig.main([str(study_dirs[0]), str(study_dirs[1]), str(openloop_dir), "--out", str(out)])
    for name in ("rmse_rounds", "rmse_loss", "phi_rounds", "phi_loss"):
        with Image.open(out / f"{name}.png") as im:
            assert im.format == "PNG" and im.width > 500 and im.height > 300
    table = pd.read_csv(out / "summary.csv")
    md = (out / "summary.md").read_text()
    for scenario, d in zip(("paper", "holes"), study_dirs):
        ours = table[table["scenario"] == scenario].set_index("method")
        direct = _direct(pd.read_parquet(d / "steps.parquet"))
        assert list(ours.index) == [m["name"] for m in CHEAP["methods"]]
        for col in direct.columns:
            np.testing.assert_allclose(ours.loc[direct.index, col].to_numpy(float),
                                       direct[col].to_numpy(float), rtol=1e-10,
                                       err_msg=f"{scenario} {col}")
        # Every method is placed where the figures expect it, from its settings.
        assert ours.loc["pg", "family"] == "pg"
        assert (ours.loc["jsfp R=1", "family"], ours.loc["jsfp R=1", "x"]) == ("rounds", 1.0)
        assert ours.loc["jsfp", "x"] == DEFAULT_ROUNDS
        assert (ours.loc["jsfp p=0.5", "family"], ours.loc["jsfp p=0.5", "x"]) == ("loss", 0.5)
        assert (ours.loc["sequential p=0.5", "family"],
                ours.loc["sequential p=0.5", "x"]) == ("sequential", 0.5)
        for method, r in ours.iterrows():
            assert f"| {method} | {r.rmse_mean:.2f} [" in md
    # Perfect links, default budget: dec-jsfp is pg, so its paired difference is exactly 0.
    assert (table.loc[table["method"] == "jsfp", "diff_pg_mean"] == 0.0).all()
