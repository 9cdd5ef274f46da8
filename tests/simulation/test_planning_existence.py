"""The closed loop hands each decision the tracks' probabilities of existence."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np

from sensorplan.planners import PLANNERS, make_planner
from sensorplan.planners.problem import PlanningProblem
from sensorplan.simulation import RunSettings, run_episode
from sensorplan.simulation.scenario import paper_scenario
from sensorplan.tracking.tracker import KnownTargetTracker


class Recording:
    """The random planner, keeping every problem it is given."""

    name: ClassVar[str] = "recording"
    problems: ClassVar[list[PlanningProblem]] = []

    def plan(self, problem: PlanningProblem, rng: Any = None) -> Any:
        self.problems.append(problem)
        return dataclasses.replace(make_planner("random").plan(problem, rng), planner=self.name)


def test_each_decision_gets_the_tracks_existence(monkeypatch) -> None:
    reported: list[np.ndarray] = []
    plain_tracks = KnownTargetTracker.tracks

    def tracks(self: KnownTargetTracker) -> Any:
        ts = plain_tracks(self)
        # A different weight per track and per call: what a multi-target tracker reports.
        r = (np.arange(len(ts)) + 1.0 + len(reported)) / (len(ts) + 40.0)
        reported.append(r)
        return dataclasses.replace(ts, existence=r)

    monkeypatch.setattr(KnownTargetTracker, "tracks", tracks)
    monkeypatch.setitem(PLANNERS, "recording", Recording)
    Recording.problems.clear()
    run_episode(paper_scenario(), RunSettings(planner="recording", steps=6, horizon=2,
                                              steps_per_epoch=1), 3)
    assert len(Recording.problems) >= 3
    for problem in Recording.problems:
        # The weights of the tracks of the call that led to this decision.
        assert any(np.array_equal(problem.existence, r) for r in reported)
    assert len({p.existence.tobytes() for p in Recording.problems}) == len(Recording.problems)


def radar_all(planning_threshold: float | None, steps: int = 30, seed: int = 11) -> Any:
    """configs/radar_all.toml with the PMB tracker (closed map edge), its planning threshold
    replaced when given."""
    from pathlib import Path

    from sensorplan.config import load_simulation

    cfg = load_simulation(Path(__file__).parents[2] / "configs" / "radar_all.toml",
                          overrides={"steps": steps, "seed": seed})
    tr = dataclasses.replace(cfg.settings.tracker, kind="pmb", map_edge="closed")
    if planning_threshold is not None:
        tr = dataclasses.replace(tr, planning_threshold=planning_threshold)
    # Decisions every two steps, as in the studies of this preset.
    return (cfg.scenario, dataclasses.replace(cfg.settings, tracker=tr, steps_per_epoch=2),
            cfg.seed)


def test_a_planning_threshold_at_or_above_the_report_threshold_changes_nothing() -> None:
    # Seed 14: a track fades below the report threshold within the 60 steps.
    scenario, base, seed = radar_all(0.5, steps=60, seed=14)
    assert base.tracker.report_threshold == 0.5
    a = run_episode(scenario, base, seed)
    b = run_episode(*radar_all(0.9, steps=60, seed=14)[:2], seed)
    for f in dataclasses.fields(a):
        if f.name not in ("planning_seconds", "settings"):
            x, y = getattr(a, f.name), getattr(b, f.name)
            if isinstance(x, np.ndarray):
                np.testing.assert_array_equal(x, y, err_msg=f.name)
            else:
                assert x == y, f.name
    today = radar_all(None, steps=60, seed=14)[1]
    assert today.tracker.planning_threshold == 0.1                      # the default
    c = run_episode(scenario, today, seed)
    assert not np.array_equal(a.potential, c.potential)


def test_planning_sees_the_bernoullis_above_the_planning_threshold(monkeypatch) -> None:
    from sensorplan.tracking.pmb.tracker import PMBTracker

    seen: list[Any] = []
    plain = PMBTracker.planning_tracks

    def planning_tracks(self: PMBTracker) -> Any:
        ts = plain(self)
        # What the tracker holds: the Bernoullis at or above 0.1, none below.
        np.testing.assert_array_equal(ts.labels, self.bern.labels[self.bern.r >= 0.1])
        seen.append(ts)
        return ts

    monkeypatch.setattr(PMBTracker, "planning_tracks", planning_tracks)
    monkeypatch.setitem(PLANNERS, "recording", Recording)
    Recording.problems.clear()
    scenario, settings, seed = radar_all(0.1, steps=40)
    ep = run_episode(scenario, dataclasses.replace(settings, planner="recording"), seed)
    assert len(Recording.problems) == 20                           # e = 2: every other step
    faint = 0
    for problem in Recording.problems:
        match = [ts for ts in seen if ts.existence.tobytes() == problem.existence.tobytes()]
        assert match and np.array_equal(match[0].means, problem.means)
        faint += int(np.any(problem.existence < 0.5))
    assert faint > 0                 # some decision planned on a track that was not reported
    # The record names reported tracks only: every recorded look's index is in the set
    # reported at the epoch's start.
    reported = np.bincount(ep.track_step, minlength=ep.looked.shape[0])
    t = np.arange(1, ep.looked.shape[0])
    start = t - 1 - (t - 1) % 2
    assert np.all(ep.looked[1:] < reported[start][:, None])


class SearchRecording(Recording):
    """:class:`Recording` for searching runs."""

    name: ClassVar[str] = "search-recording"
    plans_search: ClassVar[bool] = True


def test_confirm_hands_planning_which_tracks_are_reported(monkeypatch) -> None:
    from sensorplan.config import load_simulation
    from sensorplan.tracking.pmb.tracker import PMBTracker

    seen: list[tuple[Any, np.ndarray]] = []
    plain = PMBTracker.planning_tracks

    def planning_tracks(self: PMBTracker) -> Any:
        ts = plain(self)
        seen.append((ts, np.isin(ts.labels, self.tracks().labels)))
        return ts

    monkeypatch.setattr(PMBTracker, "planning_tracks", planning_tracks)
    monkeypatch.setitem(PLANNERS, "search-recording", SearchRecording)
    cfg = load_simulation(preset="radar")
    scenario, settings = cfg.scenario, cfg.settings
    runs = {}
    for mode in ("localise", "confirm"):
        Recording.problems.clear()
        seen.clear()
        run_episode(scenario, dataclasses.replace(settings, planner="search-recording",
                                                  unreported=mode, steps=60), 5)
        runs[mode] = (list(Recording.problems), list(seen))
    assert all(p.reported is None for p in runs["localise"][0])
    problems, tracks = runs["confirm"]
    hidden = 0
    for problem in problems:
        match = [flags for ts, flags in tracks if ts.existence.tobytes()
                 == problem.existence.tobytes() and np.array_equal(ts.means, problem.means)]
        assert match
        flags = match[0]
        if flags.all():
            assert problem.reported is None
        else:
            np.testing.assert_array_equal(problem.reported, flags)
            # Not reported: below the report threshold (a reported one may be lower).
            assert np.all(problem.existence[~flags] < 0.5)
            hidden += 1
    assert hidden > 0                 # some decision planned on a track not reported


def test_confirm_changes_nothing_under_the_information_reward() -> None:
    from sensorplan.config import load_simulation

    cfg = load_simulation(preset="radar")
    eps = [run_episode(cfg.scenario, dataclasses.replace(cfg.settings, reward="information",
                                                         unreported=mode, steps=25), 5)
           for mode in ("localise", "confirm")]
    for f in dataclasses.fields(eps[0]):
        if f.name not in ("planning_seconds", "settings"):
            x, y = getattr(eps[0], f.name), getattr(eps[1], f.name)
            if isinstance(x, np.ndarray):
                np.testing.assert_array_equal(x, y, err_msg=f.name)
            else:
                assert x == y, f.name
