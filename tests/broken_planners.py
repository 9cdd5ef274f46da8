"""Plug-in planners that break the planner contract on purpose, one way each.

Each starts from ``sequential-greedy``'s plan (those that spoil a search look, from
``raster``'s) and spoils it, keeping the result otherwise well formed, so the only defect is
the one its name says. Named as ``broken_planners:Class``
(``tests/`` is on the path of the suite and of the commands it starts).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from sensorplan.planners import Plan, PlanResult, make_planner


def _greedy(problem, rng) -> PlanResult:
    return make_planner("sequential-greedy").plan(problem, rng=rng)


@dataclass(frozen=True)
class Teleport:
    """Sensor 0 jumps in epoch 1 to the corner of the map farthest from it (300 m or more
    on the paper's 600 m map) and stays there."""

    name: ClassVar[str] = "teleport"
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        res = _greedy(problem, self.seed if rng is None else rng)
        positions = np.array(res.plan.positions)
        x, y = problem.positions[0]
        w, h = problem.world.width, problem.world.height
        positions[0, :] = (0.0 if x > w / 2 else w, 0.0 if y > h / 2 else h)
        return dataclasses.replace(res, planner=self.name,
                                   plan=Plan(positions, res.plan.targets))


@dataclass(frozen=True)
class TargetOutOfRange:
    """Every sensor looks at target 99 in every epoch (its moves are greedy's)."""

    name: ClassVar[str] = "target-99"
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        res = _greedy(problem, self.seed if rng is None else rng)
        targets = np.full_like(res.plan.targets, 99)
        return dataclasses.replace(res, planner=self.name,
                                   plan=Plan(res.plan.positions, targets))


@dataclass(frozen=True)
class Incomplete:
    """The last sensor has no action in the last epoch."""

    name: ClassVar[str] = "incomplete"
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        res = _greedy(problem, self.seed if rng is None else rng)
        positions, targets = np.array(res.plan.positions), np.array(res.plan.targets)
        positions[-1, -1], targets[-1, -1] = np.nan, -1
        return dataclasses.replace(res, planner=self.name, plan=Plan(positions, targets))


def _sweeping(problem, rng) -> PlanResult:
    """``raster``'s plan with sector looks only (when the problem searches)."""
    return make_planner("raster", revisit_every=0).plan(problem, rng=rng)


@dataclass(frozen=True)
class SectorOutOfRange:
    """Sensor 0's look in epoch 1 points at the sector one past its last (sector 0 when it
    has none: a search look while the problem's search is off); raster's plan otherwise."""

    name: ClassVar[str] = "sector-past-the-last"
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        res = _sweeping(problem, self.seed if rng is None else rng)
        targets, sectors = np.array(res.plan.targets), np.array(res.plan.sectors)
        targets[0, 0], sectors[0, 0] = -1, problem.sector_counts[0]
        return dataclasses.replace(res, planner=self.name,
                                   plan=Plan(res.plan.positions, targets, sectors))


@dataclass(frozen=True)
class TargetAndSector:
    """Sensor 0's look in epoch 1 has both target 0 and sector 0; raster's plan otherwise."""

    name: ClassVar[str] = "target-and-sector"
    seed: int | None = 0

    def plan(self, problem, rng=None) -> PlanResult:
        res = _sweeping(problem, self.seed if rng is None else rng)
        targets, sectors = np.array(res.plan.targets), np.array(res.plan.sectors)
        targets[0, 0], sectors[0, 0] = 0, 0
        return dataclasses.replace(res, planner=self.name,
                                   plan=Plan(res.plan.positions, targets, sectors))
