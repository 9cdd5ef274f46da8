"""Monte Carlo studies: pairing, determinism across executors, resume after SIGKILL,
statistics against scipy, the study files shipped in studies/."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from sensorplan.simulation.settings import TrackerSettings
from scipy import stats

from sensorplan import study as studies
from sensorplan.errors import ConfigError
from sensorplan.config.scenario import scenario_from_dict, scenario_to_dict
from sensorplan.study import load_study, parse_study, study_from_dict

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"

#: Cheap planners, a few short runs, both tracker configurations.
TINY = """
runs = 3
steps = 14
seed = 11
[defaults]
steps_per_epoch = 2
[[methods]]
name = "ours/random"
planner = "random"
[[methods]]
name = "ours/myopic"
planner = "pg"
[[methods]]
name = "paper/olf"
planner = "pg"
horizon = 2
visibility = "mean"
[methods.tracker]
miss_update = "none"
"""


def tiny_study(text: str = TINY) -> studies.Study:
    return parse_study(text)


def frames(out: Path) -> dict[str, pd.DataFrame]:
    t = studies.load_study_dir(out)
    assert t.complete
    return {"steps": t.steps, "decisions": t.decisions.drop(columns="planning_seconds"),
            "sensors": t.sensors, "tracks": t.tracks, "gospa": t.gospa}


def assert_same_tables(a: Path, b: Path) -> None:
    fa, fb = frames(a), frames(b)
    for name in studies.TABLES:
        pd.testing.assert_frame_equal(fa[name], fb[name], check_exact=True, obj=name)


# ------------------------------------------------------------------------------ seeds


def test_run_seed_is_the_spawned_child() -> None:
    study = tiny_study()
    children = np.random.SeedSequence(study.seed).spawn(study.runs)
    for r, child in enumerate(children):
        np.testing.assert_array_equal(study.run_seed(r).generate_state(8),
                                      child.generate_state(8))
    assert not np.array_equal(study.run_seed(0).generate_state(4),
                              study.run_seed(1).generate_state(4))


class _Recorder:
    """A Generator proxy that logs every draw: (stream spawn key, method, copy of output)."""

    def __init__(self, gen: np.random.Generator, key: tuple[Any, ...],
                 log: list[tuple[tuple[int, ...], str, np.ndarray]]) -> None:
        self._gen, self._key, self._log = gen, key, log

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._gen, name)
        if not callable(attr):
            return attr

        def call(*args: Any, **kwargs: Any) -> Any:
            out = attr(*args, **kwargs)
            if name == "spawn":                 # child generators: record their draws too
                self._log.append((self._key, name, np.array(len(out))))
                return [_Recorder(g, self._key + ("child", i), self._log)
                        for i, g in enumerate(out)]
            self._log.append((self._key, name, np.array(out, copy=True)))
            return out
        return call


def _recorded_task(monkeypatch: pytest.MonkeyPatch, study: studies.Study, run: int,
                   method: int) -> tuple[studies.TaskResult, list[Any]]:
    log: list[Any] = []
    real = np.random.default_rng

    def default_rng(seed: Any = None) -> Any:
        if isinstance(seed, _Recorder):
            return seed
        gen = real(seed)
        if isinstance(seed, np.random.SeedSequence):
            return _Recorder(gen, tuple(seed.spawn_key), log)
        return gen

    with monkeypatch.context() as m:
        m.setattr(np.random, "default_rng", default_rng)
        res = studies.run_task(study, run, method)
    return res, log


def test_pairing_same_truth_estimates_and_noise_draws(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two methods in one run see identical truths, initial estimates and noise draws."""
    study = tiny_study()
    a, log_a = _recorded_task(monkeypatch, study, 1, 0)        # random, negative updates
    b, log_b = _recorded_task(monkeypatch, study, 1, 2)        # pg K=2, paper configuration
    c, log_c = _recorded_task(monkeypatch, study, 2, 0)        # another run

    sa, sb, sc = (pd.DataFrame(r.tables["steps"]) for r in (a, b, c))
    truth = ["x", "y"]
    np.testing.assert_array_equal(sa[truth].to_numpy(), sb[truth].to_numpy())
    assert not np.allclose(sa[truth].to_numpy(), sc[truth].to_numpy())
    init_a, init_b = sa[sa["step"] == 0], sb[sb["step"] == 0]
    np.testing.assert_array_equal(init_a[["x_est", "y_est"]].to_numpy(),
                                  init_b[["x_est", "y_est"]].to_numpy())
    # The methods then track differently (otherwise the test would prove nothing).
    assert not np.array_equal(sa["x_est"].to_numpy(), sb["x_est"].to_numpy())
    pa, pb = (pd.DataFrame(r.tables["sensors"]) for r in (a, b))
    np.testing.assert_array_equal(pa.loc[pa["step"] == 0, ["x", "y", "heading"]].to_numpy(),
                                  pb.loc[pb["step"] == 0, ["x", "y", "heading"]].to_numpy())

    def draws(log: list[Any], prefix: tuple[int, ...]) -> list[tuple[Any, str, np.ndarray]]:
        return [e for e in log if e[0][:len(prefix)] == prefix]

    run = (1,)
    for stream in (0, 1, 2):                           # truth, init, noise (simulation.STREAMS)
        da, db = draws(log_a, run + (stream,)), draws(log_b, run + (stream,))
        assert da, f"no draws recorded from stream {stream}"
        assert [(k, n) for k, n, _ in da] == [(k, n) for k, n, _ in db]
        for (_, _, xa), (_, _, xb) in zip(da, db):
            np.testing.assert_array_equal(xa, xb)
    noise = draws(log_a, run + (2,))
    assert len({k for k, _, _ in noise}) == len(study.scenario.sensors)   # one per sensor
    assert all(x.shape == (study.steps, 2) for _, _, x in noise)         # every step drawn
    other = draws(log_c, (2, 2))
    assert not np.array_equal(noise[0][2], other[0][2])


# ---------------------------------------------------------------------- determinism


@pytest.fixture(scope="module")
def serial_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("serial") / "study"
    res = studies.run_study(tiny_study(), out, workers=1)
    assert res.ran == res.total == 9
    return out


def test_same_tables_on_dask(serial_dir: Path, tmp_path: Path) -> None:
    # The local process pool: test_run_study_from_a_script[guarded].
    study = tiny_study()
    studies.run_study(study, tmp_path / "dask", workers=2, scheduler="local", processes=False)
    assert_same_tables(serial_dir, tmp_path / "dask")
    meta = json.loads((tmp_path / "dask" / "meta.json").read_text())
    assert meta["complete"] and meta["sessions"][-1]["executor"].startswith("dask local")


def test_tables_have_every_row_once(serial_dir: Path) -> None:
    t = studies.load_study_dir(serial_dir)
    study = t.study
    M, N = len(study.scenario.targets), len(study.scenario.sensors)
    n_methods = len(study.methods)
    assert len(t.steps) == study.runs * n_methods * (study.steps + 1) * M
    assert not t.steps.duplicated(["run", "method", "step", "target"]).any()
    assert len(t.sensors) == study.runs * n_methods * (study.steps + 1) * N
    # e = 2: OLF decides every 2 steps.
    assert len(t.decisions) == study.runs * n_methods * study.steps // 2
    kinds = t.steps.drop_duplicates("target").sort_values("target")["kind"].astype(str)
    assert list(kinds) == list(study.scenario.target_kinds)
    # Columns are what the episode recorded: error is |p_true - p_est|.
    np.testing.assert_allclose(np.hypot(t.steps["x"] - t.steps["x_est"],
                                        t.steps["y"] - t.steps["y_est"]), t.steps["error"])
    conv = t.decisions.groupby("method", observed=True)["converged"].apply(
        lambda s: s.isna().all())
    assert conv["ours/random"] and not conv["ours/myopic"]
    # Every reported track and every step's GOSPA: known targets, a track each.
    assert len(t.tracks) == len(t.steps)
    np.testing.assert_array_equal(t.tracks[["x", "y"]].to_numpy(),
                                  t.steps[["x_est", "y_est"]].to_numpy())
    assert len(t.gospa) == study.runs * n_methods * study.steps
    g = t.gospa
    np.testing.assert_allclose(g["gospa"] ** 2, g["localisation"] + g["missed"] + g["false"],
                               rtol=1e-9)
    assert (g["targets"] == M).all() and (g["tracks"] == M).all()


def test_finished_study_is_not_recomputed(serial_dir: Path) -> None:
    parts = sorted((serial_dir / "parts").rglob("*.parquet"))
    before = {p: p.stat().st_mtime_ns for p in parts}
    table = (serial_dir / "steps.parquet").stat().st_mtime_ns
    res = studies.run_study(tiny_study(), serial_dir, workers=2)
    assert res.ran == 0
    assert {p: p.stat().st_mtime_ns for p in parts} == before
    assert (serial_dir / "steps.parquet").stat().st_mtime_ns == table


def test_changed_study_in_existing_dir_is_an_error(serial_dir: Path) -> None:
    changed = tiny_study(TINY.replace("runs = 3", "runs = 4").replace("horizon = 2",
                                                                      "horizon = 3"))
    with pytest.raises(ConfigError) as info:
        studies.run_study(changed, serial_dir, workers=1)
    assert info.value.field == "--out"
    assert "different study" in info.value.message
    # More runs alone would be allowed (see test_raising_runs_computes_only_the_new_runs).
    assert "runs" not in info.value.message.split("changed:")[1].split(")")[0]
    assert "methods[2].horizon (2 -> 3)" in info.value.message
    with pytest.raises(ConfigError, match=r"runs \(3 -> 2\)"):
        studies.run_study(tiny_study(TINY.replace("runs = 3", "runs = 2")), serial_dir,
                          workers=1)
    # A new description alone does not change the results: allowed.
    same = tiny_study('description = "renamed"\n' + TINY)
    assert studies.run_study(same, serial_dir, workers=1).ran == 0


def test_methods_run_apart_give_the_tables_of_one_call(serial_dir: Path,
                                                        tmp_path: Path) -> None:
    study, out = tiny_study(), tmp_path / "apart"
    first = studies.run_study(study, out, workers=1, methods=["paper/olf"])
    assert (first.ran, first.done, first.total, first.complete) == (3, 3, 9, False)
    assert not (out / "steps.parquet").exists()
    assert not json.loads((out / "meta.json").read_text())["complete"]
    # Until the others run, the directory reads as a study of the method that has.
    t = studies.load_study_dir(out)
    assert t.study.method_names == ["paper/olf"] and not t.complete
    assert t.methods_missing == ["ours/random", "ours/myopic"]
    whole = studies.load_study_dir(serial_dir)
    pd.testing.assert_frame_equal(
        t.steps.astype({"method": str}).reset_index(drop=True),
        whole.steps[whole.steps["method"] == "paper/olf"].astype({"method": str})
        .reset_index(drop=True), check_exact=True)
    again = studies.run_study(study, out, workers=1, methods=["paper/olf"])
    assert (again.ran, again.done) == (0, 3)
    rest = studies.run_study(study, out, workers=1, methods=["ours/random", "ours/myopic"])
    assert (rest.ran, rest.done, rest.complete) == (6, 9, True)
    assert_same_tables(serial_dir, out)


@pytest.mark.parametrize("methods, said", [(["nope"], "unknown method 'nope'"),
                                           ([], "non-empty"), ("paper/olf", "non-empty")])
def test_unknown_or_empty_methods_are_refused(tmp_path: Path, methods: Any,
                                              said: str) -> None:
    with pytest.raises(ConfigError, match=said) as info:
        studies.run_study(tiny_study(), tmp_path / "s", workers=1, methods=methods)
    assert info.value.field == "--methods"
    assert not (tmp_path / "s").exists()


def test_non_study_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "something.txt").write_text("x")
    with pytest.raises(ConfigError, match="not a study directory"):
        studies.run_study(tiny_study(), tmp_path, workers=1)


# --------------------------------------------------------------------------- resume


def _study_cmd(study_file: Path, out: Path, workers: int) -> list[str]:
    return [sys.executable, "-m", "sensorplan", "study", str(study_file), "--out", str(out),
            "--workers", str(workers)]


def test_resume_after_sigkill_gives_the_uninterrupted_tables(tmp_path: Path) -> None:
    text = TINY.replace("runs = 3", "runs = 4").replace("steps = 14", "steps = 20")
    study_file = tmp_path / "study.toml"
    study_file.write_text(text)
    study = load_study(study_file)
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(_study_cmd(study_file, out, 2), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True, env=env)
    try:
        deadline = time.monotonic() + 120
        while not (out.exists() and studies.done_tasks(out, study)):
            assert proc.poll() is None, "the study ended before it could be killed"
            assert time.monotonic() < deadline, "no (run, method) finished in 120 s"
            time.sleep(0.01)
    finally:
        # The whole process group: the study and its pool workers.
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    done = studies.done_tasks(out, study)
    total = len(study.tasks())
    assert 0 < len(done) < total, "killed too late to test resuming"
    assert not (out / "steps.parquet").exists()
    assert not json.loads((out / "meta.json").read_text())["complete"]

    res = subprocess.run(_study_cmd(study_file, out, 2), capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    meta = json.loads((out / "meta.json").read_text())
    assert meta["complete"]
    last = meta["sessions"][-1]
    assert last["tasks_before"] == len(done)
    assert last["tasks_run"] == total - len(done)         # only what was missing

    ref = tmp_path / "uninterrupted"
    studies.run_study(study, ref, workers=1)
    assert_same_tables(ref, out)
    t = studies.load_study_dir(out)
    assert not t.steps.duplicated(["run", "method", "step", "target"]).any()
    assert sorted(t.steps["run"].unique()) == list(range(study.runs))
    assert not list(out.rglob(".*.tmp*"))


# ----------------------------------------------------------------------- statistics


@pytest.mark.parametrize("n", [2, 3, 7, 30, 101])
def test_t_interval_matches_scipy(n: int) -> None:
    x = np.random.default_rng(n).gamma(2.0, 10.0, size=n)
    mean, lo, hi = studies.t_interval(x)
    ref = stats.t.interval(0.95, n - 1, loc=np.mean(x), scale=stats.sem(x))
    np.testing.assert_allclose([lo, hi], ref, rtol=1e-12)
    np.testing.assert_allclose(mean, np.mean(x), rtol=1e-14)
    lo90, hi90 = studies.t_interval(x, level=0.9)[1:]
    np.testing.assert_allclose([lo90, hi90], stats.t.interval(0.9, n - 1, loc=np.mean(x),
                                                              scale=stats.sem(x)), rtol=1e-12)


def test_t_interval_along_an_axis_with_nans() -> None:
    a = np.random.default_rng(0).normal(size=(12, 5))
    a[3, 1] = np.nan
    mean, lo, hi = studies.t_interval(a, axis=0)
    for j in range(5):
        col = a[:, j][~np.isnan(a[:, j])]
        ref = stats.t.interval(0.95, col.size - 1, loc=col.mean(), scale=stats.sem(col))
        np.testing.assert_allclose([mean[j], lo[j], hi[j]], [col.mean(), *ref], rtol=1e-12)
    m1, lo1, hi1 = studies.t_interval([4.0])
    assert m1 == 4.0 and np.isnan(lo1) and np.isnan(hi1)


@pytest.mark.parametrize("n", [6, 10, 25, 100])
def test_median_interval_is_the_binomial_order_statistic_interval(n: int) -> None:
    x = np.random.default_rng(n).normal(size=n)
    med, lo, hi = studies.median_interval(x)
    xs = np.sort(x)
    assert med == np.median(x)
    # l is the largest rank whose interval [x_(l), x_(n-l+1)] still has coverage >= 95 %.
    cover = [1 - 2 * stats.binom.cdf(k - 1, n, 0.5) for k in range(1, n // 2 + 1)]
    ell = max(k for k, c in enumerate(cover, start=1) if c >= 0.95)
    assert (lo, hi) == (xs[ell - 1], xs[n - ell])
    assert np.isnan(studies.median_interval(x[:5])[1])            # n = 5 cannot reach 95 %


def test_run_metrics_and_paired_differences_match_direct_computations(serial_dir: Path) -> None:
    t = studies.load_study_dir(serial_dir)
    metrics = studies.run_metrics(t)
    st = t.steps
    for (method, run, kind) in [("ours/myopic", 1, "cv"), ("paper/olf", 2, "dubins"),
                                ("ours/random", 0, "all")]:
        sel = (st["method"] == method) & (st["run"] == run) & (st["step"] >= 1)
        if kind != "all":
            sel &= st["kind"] == kind
        err = st.loc[sel, "error"].to_numpy()
        row = metrics[(metrics["method"] == method) & (metrics["run"] == run)
                      & (metrics["kind"] == kind)]
        np.testing.assert_allclose(row["rmse"], np.sqrt(np.mean(err ** 2)), rtol=1e-12)
        np.testing.assert_allclose(row["lost_share"], np.mean(err > studies.LOST_THRESHOLD))

    diffs = studies.paired_differences(metrics, t.study)
    row = diffs[(diffs["method"] == "ours/myopic") & (diffs["against"] == "random")
                & (diffs["kind"] == "cv")].iloc[0]
    assert row["reference"] == "ours/random"
    a = metrics[(metrics["method"] == "ours/myopic") & (metrics["kind"] == "cv")]
    b = metrics[(metrics["method"] == "ours/random") & (metrics["kind"] == "cv")]
    a, b = a.sort_values("run")["rmse"].to_numpy(), b.sort_values("run")["rmse"].to_numpy()
    ci = stats.ttest_rel(a, b).confidence_interval(0.95)
    np.testing.assert_allclose([row["mean"], row["mean_lo"], row["mean_hi"]],
                               [np.mean(a - b), ci.low, ci.high], rtol=1e-10)

    summ = studies.summary(metrics)
    s = summ[(summ["method"] == "ours/myopic") & (summ["kind"] == "cv")].iloc[0]
    ref = stats.t.interval(0.95, a.size - 1, loc=a.mean(), scale=stats.sem(a))
    np.testing.assert_allclose([s["mean_lo"], s["mean_hi"]], ref, rtol=1e-12)


def test_rmse_over_time_matches_a_direct_computation(serial_dir: Path) -> None:
    t = studies.load_study_dir(serial_dir)
    curves = studies.rmse_over_time(t)
    st = t.steps
    step = 9
    sel = (st["method"] == "paper/olf") & (st["kind"] == "dubins") & (st["step"] == step)
    per_run = st[sel].groupby("run")["error"].apply(lambda e: np.mean(e ** 2)).to_numpy()
    row = curves[(curves["method"] == "paper/olf") & (curves["kind"] == "dubins")
                 & (curves["step"] == step)].iloc[0]
    lo, hi = stats.t.interval(0.95, per_run.size - 1, loc=per_run.mean(),
                              scale=stats.sem(per_run))
    np.testing.assert_allclose([row["rmse"], row["lo"], row["hi"]],
                               [np.sqrt(per_run.mean()), np.sqrt(max(lo, 0)), np.sqrt(hi)],
                               rtol=1e-12)


def test_references_pair_random_by_tracker_and_myopic_by_objective() -> None:
    refs = studies.references(load_study(STUDIES / "paper.toml"))
    assert refs["paper/olf"] == {"myopic": "paper/myopic", "random": "paper/random"}
    assert refs["paper/ol"] == {"myopic": "paper/myopic", "random": "paper/random"}
    assert refs["ours/olf-pg-refine"] == {"myopic": "ours/myopic", "random": "ours/random"}
    assert refs["ours/myopic"] == {"myopic": None, "random": "ours/random"}
    assert refs["ours/random"] == {"myopic": None, "random": None}


# ---------------------------------------------------------------------- study files


def _settings(study: studies.Study) -> dict[str, tuple[Any, ...]]:
    return {m.name: (m.settings.planner, m.settings.horizon, m.settings.steps_per_epoch,
                     m.settings.execution, m.settings.visibility,
                     m.settings.tracker.miss_update, m.settings.objective)
            for m in study.methods}


def test_paper_study_lists_the_paper_methods() -> None:
    study = load_study(STUDIES / "paper.toml")
    assert (study.runs, study.steps) == (100, 100)
    assert study.scenario == load_study(STUDIES / "demo_paper.toml").scenario
    t = "terminal"
    assert _settings(study) == {
        "paper/myopic": ("pg", 1, 2, "olf", "mean", "none", t),
        "paper/ol": ("pg", 3, 2, "ol", "mean", "none", t),
        "paper/olf": ("pg", 3, 2, "olf", "mean", "none", t),
        "paper/random": ("random", 1, 2, "olf", "mean", "none", t),
        "ours/myopic": ("pg", 1, 2, "olf", "probabilistic", "negative", t),
        "ours/olf-pg": ("pg", 3, 2, "olf", "probabilistic", "negative", t),
        "ours/olf-pg-refine": ("pg-refine", 3, 2, "olf", "probabilistic", "negative", t),
        "ours/olf-sequential-greedy": ("sequential-greedy", 3, 2, "olf", "probabilistic",
                                       "negative", t),
        "ours/random": ("random", 1, 2, "olf", "probabilistic", "negative", t),
    }


def test_horizon_study_runs_k_1_to_6_on_the_paper_runs() -> None:
    horizon = load_study(STUDIES / "horizon.toml")
    paper = load_study(STUDIES / "paper.toml")
    assert (horizon.seed, horizon.runs, horizon.steps) == (paper.seed, paper.runs, paper.steps)
    ks = [m.settings.horizon for m in horizon.methods if m.settings.planner == "pg"]
    assert ks == [1, 2, 3, 4, 5, 6]
    assert {(m.settings.execution, m.settings.visibility, m.settings.tracker.miss_update)
            for m in horizon.methods} == {("olf", "probabilistic", "negative")}
    assert [[m.settings.horizon for m in g] for g in studies.horizon_groups(horizon)] == \
        [[1, 2, 3, 4, 5, 6]]


@pytest.mark.parametrize("scenario,file", [("slow", "demo.toml"), ("paper", "demo_paper.toml")])
def test_demo_files_are_the_built_in_demos(scenario: str, file: str) -> None:
    assert (STUDIES / file).read_text() == studies.DEMO_STUDIES[scenario]
    demo = studies.demo_study(scenario)
    assert demo.resolved() == load_study(STUDIES / file).resolved()
    assert {m.settings.tracker.miss_update for m in demo.methods} == {"negative"}
    assert {m.settings.visibility for m in demo.methods} == {"probabilistic"}
    assert studies.demo_study() == studies.demo_study("slow")


def test_the_default_demo_runs_the_lookahead_maps_slow_platform_cell() -> None:
    # docs/results.md, "Where looking ahead pays": the speed x0.25 cell, OLF K = 3 against
    # myopic with the cumulative objective and a decision every step (and random).
    from sensorplan.simulation.scenario import PRESETS, paper_scenario
    from sensorplan.study.features import sensor_speed

    demo = studies.demo_study()
    assert demo.scenario == PRESETS["slow"]() == sensor_speed(paper_scenario(), 0.25)
    assert demo.steps == 100
    got = {m.name: (m.settings.planner, m.settings.horizon, m.settings.steps_per_epoch,
                    m.settings.execution, m.settings.objective) for m in demo.methods}
    assert got == {"random": ("random", 1, 1, "olf", "cumulative"),
                   "myopic": ("pg", 1, 1, "olf", "cumulative"),
                   "OLF pg K=3": ("pg", 3, 1, "olf", "cumulative")}
    assert studies.references(demo)["OLF pg K=3"]["myopic"] == "myopic"


def test_resolved_config_round_trips(tmp_path: Path) -> None:
    study = load_study(STUDIES / "paper.toml")
    data = json.loads(json.dumps(study.resolved()))
    again = studies.Study.from_resolved(data)
    assert again.resolved() == study.resolved()
    assert again.scenario == study.scenario
    assert scenario_from_dict(scenario_to_dict(study.scenario)) == study.scenario
    # Every planner setting is filled with the planner's default.
    assert data["methods"][0]["planner_params"] == {"alpha": 0.3, "beta": 0.95,
                                                    "max_inner": 50, "max_outer": 10}


def test_defaults_table_and_scenario_file(tmp_path: Path) -> None:
    (tmp_path / "sc.toml").write_text(
        '[[targets]]\nkind = "dubins"\n[[sensors]]\naltitude = 400.0\n'
        '[tracker]\nmiss_update = "none"\n[planning]\nhorizon = 4\n[run]\nsteps = 9\n')
    study = study_from_dict({
        "runs": 2, "steps": 5, "scenario": {"file": "sc.toml"},
        "defaults": {"planner": "pg", "horizon": 2, "planner_params": {"alpha": 0.5}},
        "methods": [{"name": "a"}, {"name": "b", "horizon": 1,
                                    "planner_params": {"max_outer": 3}}]},
        base_dir=tmp_path)
    a, b = study.methods
    assert (a.settings.planner, a.settings.horizon, b.settings.horizon) == ("pg", 2, 1)
    assert a.settings.planner_params["alpha"] == 0.5
    assert (b.settings.planner_params["alpha"], b.settings.planner_params["max_outer"]) == \
        (0.5, 3)
    # The scenario file's [tracker], [planning] and [run] tables are not the study's.
    assert a.settings.tracker.miss_update == "negative"
    assert a.settings.steps == b.settings.steps == 5
    assert study.scenario.target_kinds == ("dubins",)


def test_method_planner_params_are_exactly_the_planners_settings() -> None:
    inf = float("inf")
    study = study_from_dict({
        "runs": 1, "steps": 3, "defaults": {"planner_params": {"alpha": 0.5}},
        "methods": [{"name": "dec", "planner": "dec-jsfp",
                     "planner_params": {"p_loss": 0.1, "comm_range": inf}},
                    {"name": "random", "planner": "random"}]})
    resolved = study.resolved()["methods"]
    # dec-jsfp's settings as docs/decentral.md lists them, with their defaults.
    assert resolved[0]["planner_params"] == {
        "alpha": 0.5, "beta": 0.95, "max_inner": 50, "max_outer": 10, "rounds": 1000,
        "p_loss": 0.1, "delay": 0, "comm_range": inf, "mode": "jsfp", "transport": "inproc",
        "timeout": 10.0}
    assert resolved[1]["planner_params"] == {}           # alpha is not random's: not applied
    again = studies.Study.from_resolved(json.loads(json.dumps(study.resolved())))
    assert again.resolved() == study.resolved()


@pytest.mark.parametrize("data,field,start", [
    ({"methods": [{"name": "r", "planner": "random", "planner_params": {"alpha": 0.5}}]},
     "methods[0].planner_params.alpha", "unknown key for planner 'random'"),
    ({"defaults": {"planner_params": {"alhpa": 0.5}},
      "methods": [{"name": "p", "planner": "pg"}, {"name": "r", "planner": "random"}]},
     "defaults.planner_params.alhpa", "no method's planner takes it (did you mean 'alpha'?)"),
    ({"defaults": {"planner_params": {"alpha": 1.5}},
      "methods": [{"name": "r", "planner": "random"}, {"name": "p", "planner": "pg"}]},
     "defaults.planner_params.alpha", "must be in (0, 1), got 1.5"),
    ({"methods": [{"name": "p", "planner": "pg", "planner_params": {"seed": 1}}]},
     "methods[0].planner_params.seed", "is not a setting here: the run's seed drives"),
    ({"methods": [{"name": "d", "planner": "dec-jsfp", "planner_params": {"rounds": 2.5}}]},
     "methods[0].planner_params.rounds", "must be an integer, got 2.5"),
])
def test_bad_method_planner_params_name_where_they_were_written(data: dict, field: str,
                                                                start: str) -> None:
    with pytest.raises(ConfigError) as info:
        study_from_dict({"runs": 1, "steps": 3, **data})
    assert info.value.field == field
    assert info.value.message.startswith(start), info.value.message


def test_tracker_settings_inherit_key_by_key() -> None:
    text = TINY + """
[[methods]]
name = "inherits"
planner = "pg"
[defaults.tracker]
miss_update = "none"
"""
    study = parse_study(text)
    got = {m.name: m.settings.tracker.miss_update for m in study.methods}
    assert got == {"ours/random": "none", "ours/myopic": "none", "paper/olf": "none",
                   "inherits": "none"}
    study = parse_study(text.replace('[defaults.tracker]\nmiss_update = "none"', ""))
    assert {m.settings.tracker.miss_update for m in study.methods if m.name != "paper/olf"} \
        == {"negative"}                                   # the setting's default
    resolved = study.resolved()["methods"]
    assert [m["tracker"]["miss_update"] for m in resolved] == ["negative"] * 2 + [
        "none", "negative"]
    # every tracker key is written out, with its default where the file gave none
    assert resolved[0]["tracker"] == TrackerSettings().to_dict()
    assert all("steps" not in m for m in resolved)         # study-wide, at the top level


def test_a_flat_tracker_key_points_to_the_sub_table() -> None:
    with pytest.raises(ConfigError) as info:
        parse_study(TINY.replace('[methods.tracker]\nmiss_update = "none"',
                                 'miss_update = "none"'))
    assert info.value.field == "methods[2].miss_update"
    assert "did you mean 'tracker.miss_update'?" in info.value.message
    with pytest.raises(ConfigError) as info:
        parse_study(TINY + '[defaults.tracker]\nmiss_update = "sometimes"\n')
    assert info.value.field == "defaults.tracker.miss_update"
    assert info.value.message == "unknown miss update 'sometimes'; choose from negative, none"


def test_a_directory_of_the_previous_format_is_refused_with_the_fix(serial_dir: Path,
                                                                     tmp_path: Path) -> None:
    old = tmp_path / "old"
    old.mkdir()
    config = json.loads((serial_dir / "config.resolved.json").read_text())
    config["format"] = "sensorplan-study/1"
    (old / "config.resolved.json").write_text(json.dumps(config))
    with pytest.raises(ConfigError) as info:
        studies.load_study_dir(old)
    assert info.value.field == "DIR"
    assert "sensorplan-study/1" in info.value.message
    assert "run the study again into a new directory" in info.value.message
    with pytest.raises(ConfigError) as info:
        studies.run_study(tiny_study(), old, workers=1)
    assert info.value.field == "--out"
    assert "use another --out or delete it" in info.value.message


def test_a_planner_refusing_in_a_worker_names_the_method_field(tmp_path: Path) -> None:
    study = tiny_study("""
runs = 2
steps = 4
[[methods]]
name = "exhaustive"
planner = "brute-force"
horizon = 2
planner_params = { max_plans = 10 }
""")
    with pytest.raises(ConfigError) as info:
        studies.run_study(study, tmp_path / "bf", workers=2)
    assert info.value.field == "methods[0].planner_params.max_plans"
    assert "exhaustive" in info.value.message


SCRIPT = """\
from sensorplan.study import load_study, run_study

STUDY = load_study({study!r})
{call}
"""


@pytest.mark.parametrize("guarded", [False, True])
def test_run_study_from_a_script(serial_dir: Path, tmp_path: Path, guarded: bool) -> None:
    """Worker processes run the calling script again: without the main guard the call
    fails at once with one sentence naming the fix; with it the study runs in a process
    pool and gives the tables of the serial run."""
    (tmp_path / "tiny.toml").write_text(TINY)
    out = tmp_path / "out"
    call = f"run_study(STUDY, {str(out)!r}, workers=2)\nprint('finished')"
    if guarded:
        call = "if __name__ == '__main__':\n    " + call.replace("\n", "\n    ")
    script = tmp_path / "my_study.py"
    script.write_text(SCRIPT.format(study=str(tmp_path / "tiny.toml"), call=call))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    if guarded:
        assert res.returncode == 0, res.stderr
        assert res.stdout.splitlines() == ["finished"]
        meta = json.loads((out / "meta.json").read_text())
        assert meta["sessions"][-1]["executor"] == "process pool (2 workers)"
        assert_same_tables(serial_dir, out)
        return
    assert res.returncode == 1
    last = res.stderr.strip().splitlines()[-1]
    assert last == (f"RuntimeError: run_study starts worker processes, which run {script} "
                    "again, so call it under `if __name__ == \"__main__\":` in that script "
                    "(or pass workers=1)")
    assert "BrokenProcessPool" not in res.stderr and "in use" not in res.stderr
    assert res.stdout == "" and not out.exists()


def test_config_error_pickles() -> None:
    # In a fresh interpreter: importing distributed (tblib) changes how exceptions pickle.
    code = ("import pickle; from sensorplan.errors import ConfigError; "
            "e = pickle.loads(pickle.dumps(ConfigError('a.b', 'bad'))); "
            "assert (e.field, e.message) == ('a.b', 'bad')")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_gospa_summary_and_curves_match_direct_computations(serial_dir: Path) -> None:
    from sensorplan.study.metrics import gospa_over_time, gospa_summary

    t = studies.load_study_dir(serial_dir)
    summ = gospa_summary(t).set_index("method")
    curves = gospa_over_time(t)
    for method, g in t.gospa.groupby("method", observed=True):
        per_run = [g.loc[g["run"] == r, "gospa"].mean() for r in sorted(g["run"].unique())]
        np.testing.assert_allclose(summ.loc[method, "mean"], np.mean(per_run), rtol=1e-12)
        np.testing.assert_allclose(summ.loc[method, "median"], np.median(per_run), rtol=1e-12)
        step3 = g.loc[g["step"] == 3, "gospa"].mean()
        got = curves[(curves["method"] == method) & (curves["step"] == 3)]["gospa"]
        np.testing.assert_allclose(got.to_numpy(), [step3], rtol=1e-12)


def test_a_study_directory_written_before_gospa_c_is_the_same_study(tmp_path: Path) -> None:
    """config.resolved.json gained the study-wide GOSPA cut-off: a directory without it
    reads back with the default (50 m) and resumes as the same study; another cut-off is
    a different study (its GOSPA tables would differ)."""
    study = parse_study("runs = 1\nsteps = 2\n[[methods]]\nname = \"r\"\nplanner = \"random\"\n")
    assert studies.run_study(study, tmp_path, workers=1).ran == 1
    config = tmp_path / "config.resolved.json"
    old = json.loads(config.read_text())
    assert old["gospa_c"] == 50.0
    del old["gospa_c"]
    config.write_text(json.dumps(old))
    back = studies.Study.from_resolved(old)
    assert back.methods[0].settings.gospa_c == 50.0
    assert studies.run_study(study, tmp_path, workers=1).ran == 0
    other = parse_study("runs = 1\nsteps = 2\ngospa_c = 20.0\n[[methods]]\nname = \"r\"\n"
                        "planner = \"random\"\n")
    with pytest.raises(ConfigError, match=r"gospa_c \(50.0 -> 20.0\)"):
        studies.run_study(other, tmp_path, workers=1)


def test_a_study_directory_written_before_the_reward_is_the_same_study(
        tmp_path: Path) -> None:
    """The methods gained the planning reward: a directory whose methods lack it ran with
    the information reward, reads back with it and resumes as the same study."""
    study = parse_study("runs = 1\nsteps = 2\n[[methods]]\nname = \"r\"\nplanner = \"random\"\n")
    assert studies.run_study(study, tmp_path, workers=1).ran == 1
    config = tmp_path / "config.resolved.json"
    old = json.loads(config.read_text())
    assert old["methods"][0]["reward"] == "information"
    del old["methods"][0]["reward"]
    config.write_text(json.dumps(old))
    assert studies.Study.from_resolved(old).methods[0].settings.reward == "information"
    assert studies.run_study(study, tmp_path, workers=1).ran == 0


@pytest.mark.parametrize(("key", "value", "other"), [("termination_threshold", 1.0, 0.1),
                                                     ("background_birth_rate", 0.0, 0.03),
                                                     ("bernoulli_model", '"cv"', '"imm"')])
def test_a_study_directory_written_before_a_tracker_setting_is_the_same_study(
        tmp_path: Path, key: str, value: float | str, other: float | str) -> None:
    """The tracker gained termination_threshold, background_birth_rate and bernoulli_model
    after studies had run without them: a directory whose methods lack one reads back with
    the value those runs had and resumes as the same study; another value is a different
    study."""
    text = ("runs = 1\nsteps = 2\n[scenario]\npreset = \"search\"\n[[methods]]\nname = \"r\"\n"
            "planner = \"random\"\n[methods.tracker]\nkind = \"pmb\"\n"
            "density_components = 1\n")
    study = parse_study(text + f"{key} = {value}\n")
    assert studies.run_study(study, tmp_path, workers=1).ran == 1
    config = tmp_path / "config.resolved.json"
    old = json.loads(config.read_text())
    written = value.strip('"') if isinstance(value, str) else value
    assert old["methods"][0]["tracker"][key] == written
    del old["methods"][0]["tracker"][key]
    config.write_text(json.dumps(old))
    assert getattr(studies.Study.from_resolved(old).methods[0].settings.tracker,
                   key) == written
    assert studies.run_study(study, tmp_path, workers=1).ran == 0
    with pytest.raises(ConfigError, match=key):
        studies.run_study(parse_study(text + f"{key} = {other}\n"), tmp_path, workers=1)


def test_a_tracker_setting_the_tracker_does_not_read_leaves_the_study_the_same(
        tmp_path: Path) -> None:
    """A preset that gains IMM modes changes the modes' q's of its single-model methods
    too, which they do not read: their directory resumes as the same study; a setting they
    read is a different study."""
    text = ("runs = 1\nsteps = 2\n[scenario]\npreset = \"search\"\n[[methods]]\nname = \"r\"\n"
            "planner = \"random\"\n[methods.tracker]\nkind = \"pmb\"\n"
            "density_components = 1\n")
    assert studies.run_study(parse_study(text), tmp_path, workers=1).ran == 1
    unread = text + "mode_process_noise = [1.0, 2.0]\nswitching = [[0.5, 0.5], [0.5, 0.5]]\n"
    assert studies.run_study(parse_study(unread), tmp_path, workers=1).ran == 0
    with pytest.raises(ConfigError, match="mode_process_noise"):
        studies.run_study(parse_study(unread + "bernoulli_model = \"imm\"\n"), tmp_path,
                          workers=1)


def test_a_scenario_files_unused_planner_settings_are_still_checked(tmp_path) -> None:
    # Its [planning] table is not used (the methods name their planners), but a key its own
    # planner does not take was accepted without a word; a run of the file refuses it.
    from sensorplan.errors import ConfigError
    from sensorplan.study.file import parse_study

    text = (ROOT / "configs" / "paper.toml").read_text()
    good = text
    text = text.replace("[planning.planner_params]", "[planning.planner_params]\nbogus = 3", 1)
    (tmp_path / "scenario.toml").write_text(text)
    study = 'runs = 1\nsteps = 2\n[scenario]\nfile = "scenario.toml"\n' \
            '[[methods]]\nname = "rnd"\nplanner = "random"\n'
    with pytest.raises(ConfigError) as exc:
        parse_study(study, base_dir=tmp_path)
    assert exc.value.field == "scenario.file"
    assert "planning.planner_params.bogus" in exc.value.message
    (tmp_path / "scenario.toml").write_text(good)
    assert parse_study(study, base_dir=tmp_path).methods[0].name == "rnd"


def test_a_study_directory_written_before_the_planning_threshold_planned_on_reported_tracks(
        tmp_path: Path) -> None:
    """The tracker gained planning_threshold (default 0.1) after PMB studies had run with
    planning on the reported tracks only: a directory whose methods lack it reads back with
    the method's report threshold, resumes as the same study when the file names that value,
    and is a different study under today's default."""
    text = ("runs = 1\nsteps = 2\n[scenario]\npreset = \"search\"\n[[methods]]\nname = \"r\"\n"
            "planner = \"random\"\n[methods.tracker]\nkind = \"pmb\"\nreport_threshold = 0.6\n")
    pinned = parse_study(text + "planning_threshold = 0.6\n")
    assert studies.run_study(pinned, tmp_path, workers=1).ran == 1
    config = tmp_path / "config.resolved.json"
    old = json.loads(config.read_text())
    assert old["methods"][0]["tracker"]["planning_threshold"] == 0.6
    del old["methods"][0]["tracker"]["planning_threshold"]
    config.write_text(json.dumps(old))
    assert studies.Study.from_resolved(old).methods[0].settings.tracker.planning_threshold \
        == 0.6
    assert studies.run_study(pinned, tmp_path, workers=1).ran == 0
    today = parse_study(text)
    assert today.methods[0].settings.tracker.planning_threshold == 0.1
    with pytest.raises(ConfigError, match="planning_threshold"):
        studies.run_study(today, tmp_path, workers=1)
