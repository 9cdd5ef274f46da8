"""The ``raster`` baseline: a radar engineer's track-while-scan schedule.

No look is chosen by Phi. Each sensor sweeps its search sectors in a fixed order and, every
``revisit_every``-th look, revisits a track instead; the platforms hold station. The
schedule is a function of the problem alone:

- **Looks are numbered over the run.** Sensor i's look in epoch k of a decision is look
  ``n = elapsed_epochs + k`` of the run (:attr:`PlanningProblem.elapsed_epochs`), so the
  schedule goes on from one decision to the next, whether the decisions are one epoch apart
  (open-loop feedback) or K (open loop). Every sensor follows the same numbering.
- **Revisits.** Look n is a revisit when ``revisit_every > 0`` and ``n`` is a multiple of
  it, and always when the sensor has no search sector (search off, or 0 sectors). The
  decision's revisit looks, in epoch order and within an epoch in sensor order, take the
  tracks of :func:`revisit_order` in turn, starting again at the first after the last.
  With no track at all there is nothing to revisit and every look sweeps.
- **Sweep.** Any other look is the sensor's ``m``-th sweep look of the run, ``m = n - 1 -
  floor((n - 1) / revisit_every)`` (``n - 1`` without revisits), and points at sector
  ``order[m mod S]`` of :func:`sweep_order`: one cycle of ``S`` sweep looks visits every
  sector once.
- **Platforms hold station** (the stay move): the schedule steers the beam, not the
  platform.

A sector look aims the heading rule at its sector's bearing, so the turn limit applies:
when the sector is further than the turn limit the beam stops at the limit, and the plan
names the sector that heading stands for (the first of the sectors the rule maps to it,
:func:`~sensorplan.planners.search.sector_actions`), as every planner's sector looks do.
The sweep goes on with the next sector of its order all the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._types import IntArray
from ..errors import ConfigError
from ..limits import Range, param
from ..models.angles import heading_rule, wrap_angle
from .base import PlanResult, RngLike, finish, register, start_clock
from .problem import Plan, PlanningProblem
from .registry import PlannerSettings, seed_param

#: The sweep orders (:func:`sweep_order`).
SWEEPS = ("clockwise", "counterclockwise", "interleaved")

#: A track is confirmed when its probability of existence is at least this (the reporting
#: threshold of the multi-target trackers); confirmed tracks are revisited first.
CONFIRMED = 0.5


def sweep_order(n_sectors: int, sweep: str) -> IntArray:
    """The order in which a sensor's ``S`` sectors are swept: a permutation of ``0..S-1``.

    Sector s lies at the absolute bearing ``2 pi s / S`` (counterclockwise from the x axis,
    the map's east, toward north).

    - ``clockwise``: 0, S-1, S-2, ..., 1 (decreasing bearing, the way most surveillance
      radars turn seen from above);
    - ``counterclockwise``: 0, 1, ..., S-1;
    - ``interleaved``: every other sector, then the gaps: 0, 2, 4, ..., then 1, 3, 5, ...
      (a coarse look all around first, then the sectors in between).
    """
    s = np.arange(n_sectors, dtype=np.int64)
    if sweep == "clockwise":
        return (-s) % max(n_sectors, 1)
    if sweep == "counterclockwise":
        return s
    if sweep == "interleaved":
        return np.concatenate([s[0::2], s[1::2]])
    raise ValueError(f"unknown sweep {sweep!r}; choose from {', '.join(SWEEPS)}")


def is_revisit(look: int, revisit_every: int) -> bool:
    """Whether look ``look`` (1, 2, ... over the run) of a sensor with sectors revisits a
    track: every ``revisit_every``-th look; never with ``revisit_every = 0``."""
    return revisit_every > 0 and look % revisit_every == 0


def sweep_index(look: int, revisit_every: int) -> int:
    """How many sweep looks come before look ``look`` (1, 2, ... over the run): the index
    ``m`` of the sweep position the look takes when it is not a revisit."""
    before = look - 1
    return before - (before // revisit_every if revisit_every > 0 else 0)


def revisit_order(problem: PlanningProblem) -> IntArray:
    """The order in which revisits take the tracks: confirmed tracks (probability of
    existence at least :data:`CONFIRMED`) first, then the larger position uncertainty (the
    trace of the position block of the covariance, m^2) first, then the lower index.

    A track's uncertainty grows while no one looks at it and shrinks when someone does, so
    from one decision to the next this order puts the tracks looked at longest ago first:
    the revisit queue of a track-while-scan radar, read from the tracks themselves.
    """
    covs = np.asarray(problem.covs)
    spread = covs[:, 0, 0] + covs[:, 1, 1]
    existence = np.asarray(problem.existence)
    order = np.lexsort((np.arange(problem.n_targets), -spread, existence < CONFIRMED))
    return order.astype(np.int64)


def schedule(problem: PlanningProblem, sweep: str, revisit_every: int
             ) -> tuple[IntArray, IntArray]:
    """The looks the schedule asks for: ``targets (N, K)`` and ``sectors (N, K)`` (-1 where
    the look is of the other kind), before the turn limit is applied (see the module)."""
    return looks(problem.sector_counts, revisit_order(problem), int(problem.elapsed_epochs),
                 problem.horizon, sweep, revisit_every)


def looks(counts: tuple[int, ...], queue: IntArray, elapsed: int, horizon: int, sweep: str,
          revisit_every: int) -> tuple[IntArray, IntArray]:
    """:func:`schedule` from each sensor's sector count, the revisit order ``queue``, the
    epochs elapsed and the horizon.

    Without any track (an empty ``queue``: a searching decision before the first track)
    there is nothing to revisit, so every look sweeps, as with ``revisit_every = 0``.

    Raises
    ------
    ConfigError
        No track and a sensor without search sectors: it has no look to take.
    """
    N, K = len(counts), horizon
    if len(queue) == 0:
        revisit_every = 0
        idle = [i for i, S in enumerate(counts) if S == 0]
        if idle:
            raise ConfigError(f"sensors[{idle[0]}].search_sectors", "raster has no look for a "
                              "sensor without search sectors while there is no track")
    orders = [sweep_order(S, sweep) for S in counts]
    targets = np.full((N, K), -1, dtype=np.int64)
    sectors = np.full((N, K), -1, dtype=np.int64)
    revisits = 0
    for k in range(1, K + 1):
        look = elapsed + k
        for i in range(N):
            if counts[i] == 0 or is_revisit(look, revisit_every):
                targets[i, k - 1] = queue[revisits % len(queue)]
                revisits += 1
            else:
                sectors[i, k - 1] = orders[i][sweep_index(look, revisit_every) % counts[i]]
    return targets, sectors


def raster_plan(problem: PlanningProblem, sweep: str, revisit_every: int) -> Plan:
    """The plan: every platform holds its position, the looks of :func:`schedule`, each
    sector look named by the sector its heading stands for (the turn limit applied)."""
    N, K = problem.n_sensors, problem.horizon
    targets, sectors = schedule(problem, sweep, revisit_every)
    positions = np.repeat(np.asarray(problem.positions)[:, None, :], K, axis=1)
    if not (sectors >= 0).any():
        return Plan(positions, targets, sectors)
    from . import search

    sctx = search.prepare(problem)
    wanted = Plan(positions, targets, sectors)
    headings = search.plan_headings(sctx, wanted)
    named = sectors.copy()
    for i in range(N):
        turn = float(sctx.ctx.max_turn[i])
        bearings = sctx.bearings[i]
        for k in range(1, K + 1):
            s = int(sectors[i, k - 1])
            if s < 0:
                continue
            prev = float(problem.headings[i]) if k == 1 else float(headings[i, k - 2])
            options = search.sector_actions(sctx, i, k, prev, True)
            reached = heading_rule(prev, bearings[options], turn)
            hit = np.abs(wrap_angle(reached - headings[i, k - 1])) <= search.HEADING_TOL
            named[i, k - 1] = int(options[np.flatnonzero(hit)[0]])
    return Plan(positions, targets, named)


@register
@dataclass(frozen=True)
class RasterPlanner(PlannerSettings):
    """Track-while-scan baseline: fixed sweeps of the search sectors, a track revisited every
    ``revisit_every``-th look, platforms holding station (see the module).

    Deterministic; ``seed`` is accepted for a uniform interface and unused.
    """

    name: ClassVar[str] = "raster"
    #: It plans search looks (when the problem's search is on).
    plans_search: ClassVar[bool] = True
    sweep: str = param("clockwise", choices=SWEEPS, noun="sweep",
                       help="Order in which each sensor sweeps its search sectors: clockwise, "
                            "counterclockwise, or interleaved (every other sector, then the "
                            "gaps).")
    revisit_every: int = param(3, bounds=Range(0, None),
                               help="Every this many looks of a sensor, one revisits a track "
                                    "instead of a sector (0: never; 1: every look).")
    seed: int | None = seed_param()

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock()
        return finish(self.name, problem, raster_plan(problem, self.sweep, self.revisit_every),
                      start)


__all__ = ["CONFIRMED", "SWEEPS", "RasterPlanner", "is_revisit", "looks", "raster_plan",
           "revisit_order", "schedule", "sweep_index", "sweep_order"]
