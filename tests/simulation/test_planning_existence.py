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
