"""The closed loop with search on: sector looks are planned and executed as planned, where no
track exists every look searches, the recorded search term is Phi's, runs repeat, and search
off leaves every run as it was."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cli_helpers import assert_bad_input, run
from sensorplan.config import load_simulation
from sensorplan.planners import search
from sensorplan.simulation import run as run_module
from sensorplan.simulation.episode import Episode
from sensorplan.simulation.run import make_tracker, run_episode
from sensorplan.simulation.scenario import SEARCH_SECTORS
from sensorplan.study.file import parse_study
from sensorplan.tracking.base import undetected_report

STEPS = 10


def searching(**overrides: Any) -> Any:
    """The search preset with search on (myopic pg, OLF: a decision every step)."""
    return load_simulation(preset="search", overrides={"search": "on", "steps": STEPS,
                                                       "seed": 3, **overrides})


@pytest.fixture(scope="module")
def loop() -> tuple[Episode, list[tuple[Any, Any]]]:
    """A searching run of the search preset whose known targets are left out (no track at
    the start), with every decision's problem and result recorded."""
    cfg = searching()
    scenario = dataclasses.replace(cfg.scenario, initial_targets=0)
    return recorded_run(scenario, cfg.settings, cfg.seed)


def recorded_run(scenario: Any, settings: Any, seed: int
                 ) -> tuple[Episode, list[tuple[Any, Any]]]:
    """A run, and every decision's (problem, result) as the loop checked it."""
    decisions: list[tuple[Any, Any]] = []
    real = run_module.checked_plan

    def spy(planner: Any, problem: Any, rng: Any = None, decision: Any = None) -> Any:
        result = real(planner, problem, rng, decision)
        decisions.append((problem, result))
        return result

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_module, "checked_plan", spy)
        episode = run_episode(scenario, settings, seed)
    return episode, decisions


def test_sector_looks_happen_and_every_look_searches_where_no_track_exists(loop) -> None:
    ep, decisions = loop
    assert ep.searched is not None and ep.search_found is not None
    assert len(decisions) == len(ep.decision_steps) == STEPS      # OLF, e = 1
    assert (ep.searched[1:] >= 0).any()
    untracked = [d for d, (problem, _) in enumerate(decisions) if problem.n_targets == 0]
    assert untracked                              # the first decisions know no target
    for d in untracked:
        plan = decisions[d][1].plan
        assert (plan.sectors >= 0).all() and (plan.targets < 0).all()
        t = int(ep.decision_steps[d]) + 1         # the step the decision's epoch covers
        assert (ep.searched[t] >= 0).all()
        assert (ep.looked[t] == -1).all()


def test_the_looks_are_executed_as_planned(loop) -> None:
    ep, decisions = loop
    for d, (problem, result) in enumerate(decisions):
        t = int(ep.decision_steps[d]) + 1
        plan = result.plan
        # Every decision is searching; the step's sector looks are the plan's first epoch.
        np.testing.assert_array_equal(ep.searched[t], plan.sectors[:, 0])
        np.testing.assert_array_equal(ep.sensor_positions[t], plan.positions[:, 0])
        # The heading rule toward the sector's bearing (or the track), as planned.
        planned = search.plan_headings(search.prepare(problem), plan)[:, 0]
        np.testing.assert_allclose(ep.sensor_headings[t], planned, rtol=0, atol=1e-9)


def test_the_recorded_search_term_is_phis(loop) -> None:
    ep, decisions = loop
    for d, (problem, result) in enumerate(decisions):
        assert problem.searching and problem.sector_counts == (SEARCH_SECTORS,) * 3
        phi, info, mu = search.potential(problem, result.plan)
        assert ep.potential[d] == pytest.approx(phi, rel=1e-12)
        assert ep.search_found[d] == pytest.approx(mu, rel=1e-12)
        assert ep.search_term[d] == pytest.approx(phi - info.sum(), rel=1e-9, abs=1e-12)
    assert (ep.search_found > 0).all()
    # Where there is no track, Phi is the search term alone.
    for d, (problem, _) in enumerate(decisions):
        if problem.n_targets == 0:
            assert ep.search_term[d] == pytest.approx(ep.potential[d], rel=1e-12)


def test_the_recorded_intensity_is_the_trackers() -> None:
    cfg = searching()
    tracker = make_tracker(cfg.scenario, cfg.settings, np.zeros((0, 4)), _table(cfg))
    report = undetected_report(tracker)
    assert report is not None
    np.testing.assert_array_equal(report.weights, tracker.undetected)
    np.testing.assert_array_equal(report.births, tracker.births)
    tr = cfg.settings.tracker
    assert tr.background_birth_rate > 0.0             # the search preset's
    assert report.births.sum() == pytest.approx(tr.birth_rate + tr.background_birth_rate,
                                                rel=1e-12)
    assert report.survival == cfg.settings.tracker.survival_probability
    # A cell's position covariance: uniform over a 25 m square.
    np.testing.assert_allclose(report.cell_cov, np.diag([625.0 / 12] * 2), rtol=1e-12)
    report.weights[:] = 1.0                       # a copy: the tracker is untouched
    assert not np.array_equal(tracker.undetected, report.weights)
    known = load_simulation(preset="paper", overrides={"steps": 2})
    assert undetected_report(make_tracker(known.scenario, known.settings,
                                          np.zeros((5, 4)), _table(known))) is None


def _table(cfg: Any) -> np.ndarray:
    from sensorplan.models.sensors import radar_table

    return radar_table(tuple(s.params for s in cfg.scenario.sensors))


def _arrays(ep: Episode) -> dict[str, Any]:
    return {f.name: getattr(ep, f.name) for f in dataclasses.fields(ep)
            if f.name not in ("planning_seconds", "settings")}


def _same(a: Episode, b: Episode) -> None:
    for name, value in _arrays(a).items():
        other = getattr(b, name)
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, other, err_msg=name)
        else:
            assert value == other, name


def test_the_same_seed_gives_the_same_run(loop) -> None:
    ep, _ = loop
    cfg = searching()
    again = run_episode(dataclasses.replace(cfg.scenario, initial_targets=0), cfg.settings,
                        cfg.seed)
    _same(ep, again)


def test_a_searching_episode_file_keeps_its_search_records(loop, tmp_path: Path) -> None:
    ep, _ = loop
    ep.save(tmp_path / "e.npz")
    back = Episode.load(tmp_path / "e.npz")
    for name in ("searched", "search_found", "search_term"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ep, name))


def test_search_off_leaves_the_run_as_it_was(tmp_path: Path) -> None:
    base = load_simulation(preset="search", overrides={"steps": 6, "seed": 2,
                                                       "search": "off"})
    assert base.settings.search_sectors == SEARCH_SECTORS
    off = run_episode(base.scenario, base.settings, base.seed)
    other = dataclasses.replace(base.settings, search_sectors=11)
    _same(off, run_episode(base.scenario, other, base.seed))
    assert off.searched is None and off.search_found is None and off.search_term is None
    off.save(tmp_path / "off.npz")
    with np.load(tmp_path / "off.npz") as data:
        assert not {"searched", "search_found", "search_term"} & set(data.files)


def test_the_search_preset_searches_for_the_gospa_bound_by_default() -> None:
    cfg = load_simulation(preset="search")
    assert (cfg.settings.search, cfg.settings.reward) == ("on", "gospa")
    off = load_simulation(preset="search", overrides={"search": "off"})
    assert (off.settings.search, off.settings.reward) == ("off", "information")
    # The radar preset searches too (for targets whose tracks were lost).
    assert load_simulation(preset="radar").settings.search == "on"


def test_the_summary_reports_the_search(capsys, tmp_path: Path) -> None:
    code, out, err = run(capsys, "simulate", "--preset", "search", "--search", "on",
                         "--steps", "2", "--out", tmp_path)
    assert code == 0, err
    text = " ".join(out.split())                  # as printed, wrapped at any width
    assert f"search on ({SEARCH_SECTORS} sectors)" in text
    assert "looked at a search sector; Phi's search term w mu per decision" in text


@pytest.mark.parametrize(("args", "field"), [
    (("--preset", "paper", "--search", "on"), "--search"),
    (("--preset", "search", "--search", "on", "--search-sectors", "0"), "--search-sectors"),
    (("--preset", "search", "--search", "sometimes"), "--search"),
    (("--preset", "search", "--search-sectors", "-1"), "--search-sectors"),
])
def test_bad_search_settings_are_one_line(capsys, tmp_path: Path, args: tuple[str, ...],
                                          field: str) -> None:
    assert_bad_input(run(capsys, "simulate", *args, "--out", tmp_path), field)


def test_a_planner_that_does_not_plan_search_is_refused_before_the_run(
        nearest_on_path: None, capsys, tmp_path: Path) -> None:
    # Every built-in planner plans search looks; a plug-in that does not declare it is
    # refused when the settings are checked, naming the option.
    line = assert_bad_input(run(capsys, "simulate", "--preset", "search", "--search", "on",
                                "--planner", "nearest_planner:NearestTargetPlanner",
                                "--out", tmp_path), "--search")
    assert "does not plan search looks" in line


def test_bad_search_settings_in_files_name_the_key(capsys, tmp_path: Path) -> None:
    quick = (Path(__file__).resolve().parents[2] / "configs" / "quick.toml").read_text()
    path = tmp_path / "s.toml"
    path.write_text(quick.replace("[planning]\n", '[planning]\nsearch = "on"\n'
                                  'search_sectors = 6\n'))
    line = assert_bad_input(run(capsys, "simulate", path, "--out", tmp_path),
                            "planning.search")
    assert "tracker.kind = 'pmb'" in line


def test_pg_refine_plans_the_loops_search_looks(capsys, tmp_path: Path) -> None:
    # A study method and simulate with pg-refine and search on: settings accepted, every
    # decision a converged plan of the searching problem whose Phi is Phi with search.
    study = parse_study("""
runs = 1
steps = 3
seed = 2
[scenario]
preset = "search"
[[methods]]
name = "refined"
planner = "pg-refine"
search = "on"
horizon = 2
""")
    settings = study.methods[0].settings
    assert (settings.planner, settings.search) == ("pg-refine", "on")
    # What a study task runs (study.execution.run_task), each decision recorded.
    _, decisions = recorded_run(study.scenario, settings, study.run_seed(0))
    assert decisions
    for problem, result in decisions:
        assert problem.searching and result.converged
        assert result.potential == pytest.approx(search.potential(problem, result.plan)[0],
                                                 rel=1e-9, abs=1e-12)
    code, out, err = run(capsys, "simulate", "--preset", "search", "--search", "on",
                         "--planner", "pg-refine", "--horizon", "2", "--steps", "2",
                         "--out", tmp_path)
    assert code == 0, err
    assert "looked at a search sector" in " ".join(out.split())


def test_a_study_of_the_search_preset_takes_its_sectors() -> None:
    study = parse_study("""
runs = 1
steps = 5
seed = 1
[scenario]
preset = "search"
[[methods]]
name = "searching"
planner = "pg"
search = "on"
[[methods]]
name = "twelve"
planner = "random"
search = "on"
search_sectors = 12
[[methods]]
name = "tracks"
planner = "pg"
search = "off"
""")
    got = {m.name: (m.settings.search, m.settings.search_sectors) for m in study.methods}
    assert got == {"searching": ("on", SEARCH_SECTORS), "twelve": ("on", 12),
                   "tracks": ("off", SEARCH_SECTORS)}


PER_SENSOR = """
look_detects = "all"
births = "edges"
birth_rate = 0.05
initial_targets = 1

[planning]
planner = "pg"
search = "on"
search_sectors = SECTORS

[tracker]
kind = "pmb"

[run]
steps = 4
seed = 1

[[targets]]
kind = "cv"

[[sensors]]
altitude = 490.0
position = [100.0, 100.0]
heading = 0.78

[[sensors]]
altitude = 510.0
position = [500.0, 500.0]
heading = -2.35
"""


def test_each_sensor_searches_its_own_sectors(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(PER_SENSOR.replace("SECTORS", "[3, 8]"))
    cfg = load_simulation(path)
    assert cfg.settings.search_sectors == (3, 8)
    ep, problems = recorded_run(cfg.scenario, cfg.settings, cfg.seed)
    assert all(p.sector_counts == (3, 8) for p, _ in problems)
    assert (ep.searched[1:] < np.array([3, 8])).all()
    for d, (problem, result) in enumerate(problems):
        t = int(ep.decision_steps[d]) + 1
        planned = search.plan_headings(search.prepare(problem), result.plan)[:, 0]
        np.testing.assert_allclose(ep.sensor_headings[t], planned, rtol=0, atol=1e-9)


@pytest.mark.parametrize("sectors", ["[3]", "[3, 8, 2]"])
def test_one_count_per_sensor_or_one_for_all(capsys, tmp_path: Path, sectors: str) -> None:
    path = tmp_path / "s.toml"
    path.write_text(PER_SENSOR.replace("SECTORS", sectors))
    line = assert_bad_input(run(capsys, "simulate", path, "--out", tmp_path),
                            "planning.search_sectors")
    assert "one per sensor (2)" in line


def test_a_study_method_with_one_count_too_few_is_named() -> None:
    from sensorplan.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        parse_study("""
runs = 1
steps = 5
[scenario]
preset = "search"
[[methods]]
name = "two"
planner = "pg"
search = "on"
search_sectors = [6, 6]
""")
    assert err.value.field == "methods[0].search_sectors"
    assert "one per sensor (3)" in err.value.message


def test_a_gospa_run_plans_the_bound_with_the_runs_cut_off() -> None:
    """Every decision of a run with the gospa reward is a gospa problem with the run's c,
    and the recorded search term is that reward's (m^2), recomputed from its plan."""
    cfg = searching(reward="gospa", gospa_c=35.0, steps=4)
    ep, decisions = recorded_run(cfg.scenario, cfg.settings, cfg.seed)
    assert decisions and ep.search_term is not None
    for d, (problem, result) in enumerate(decisions):
        assert (problem.reward, problem.gospa_c) == ("gospa", 35.0)
        ev = search.evaluate(search.prepare(problem), result.plan)
        assert ev.potential == result.potential
        assert ep.search_term[d] == pytest.approx(ev.potential - ev.information.sum(),
                                                  rel=1e-12)
    # The same run with the information reward plans in nats: another Phi.
    info = searching(steps=4, reward="information")
    _, other = recorded_run(info.scenario, info.settings, info.seed)
    assert other[0][0].reward == "information"
    assert other[0][1].potential != decisions[0][1].potential


@pytest.mark.parametrize(("given", "want"), [(0.0, None), (1.0, 1.0)])
def test_the_established_survival_reaches_the_tracker(given: float, want: Any) -> None:
    cfg = searching()
    tr = dataclasses.replace(cfg.settings.tracker, established_survival=given,
                             established_existence=0.95)
    settings = dataclasses.replace(cfg.settings, tracker=tr)
    tracker = make_tracker(cfg.scenario, settings, np.zeros((0, 4)), _table(cfg))
    assert tracker.established_survival == want          # 0: the tracker survival
    assert tracker.established_existence == 0.95
