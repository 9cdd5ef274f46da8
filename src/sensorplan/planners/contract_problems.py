"""Seeded planning problems for the planner contract, the tests and the benchmarks.

- :func:`tiny_problem`: random tiny problems, small enough for exhaustive search;
- :func:`paper_problem`: a decision of the paper scenario (3 sensors, 5 targets);
- :func:`joint_plan_count`: the exact number of feasible joint plans of a problem;
- :func:`weighted`: a problem with random probabilities of existence (some 0, some 1);
- :func:`searching`: a problem with search on, over an undetected intensity on a grid;
- :func:`contract_problems`: the fixed set :func:`~sensorplan.planners.check_planner` uses;
  :func:`search_contract_problems` the searching ones it adds for planners that plan
  search looks.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from ..models.sensors import SensorParams
from .problem import (OBJECTIVES, VISIBILITY_MODES, MapRect, PlanningProblem,
                      UndetectedIntensity, build_lattice, move_vectors)


def joint_plan_count(problem: PlanningProblem) -> int:
    """Exact number of feasible joint plans (product over sensors of chains x L_i^K, L_i the
    looks of sensor i: the M targets, plus its search sectors when the problem searches)."""
    total = 1
    for i, s in enumerate(problem.sensors):
        lat = build_lattice(problem.positions[i], move_vectors(s.moves), problem.horizon,
                            problem.world)
        ways = np.ones(1)
        for k in range(1, problem.horizon + 1):
            nxt = np.zeros(len(lat.positions[k]))
            q, m = np.nonzero(lat.child[k] >= 0)
            np.add.at(nxt, lat.child[k][q, m], ways[q])
            ways = nxt
        looks = problem.n_targets + problem.sector_counts[i]
        total *= int(ways.sum()) * looks ** problem.horizon
    return total


def tiny_problem(rng: np.random.Generator, max_plans: int = 60_000,
                 visibility: str | None = None, objective: str = "terminal") -> PlanningProblem:
    """A random tiny problem (N <= 3, M <= 4, K <= 4) with at most ``max_plans`` joint plans.

    Geometry and sensor parameters vary: a map two to three moves wide, one move distance,
    random field of view, range band, turn limit and altitude, targets anywhere around the
    map (so some sensors must move before they see anything). ``visibility=None`` draws it.
    """
    while True:
        N = int(rng.integers(1, 4))
        M = int(rng.integers(1, 5))
        K = int(rng.integers(1, 5))
        e = int(rng.integers(1, 3))
        s = float(rng.uniform(60.0, 120.0))
        width, height = s * rng.uniform(1.2, 3.0, size=2)
        gmin = float(rng.uniform(0.0, 1.5 * s))
        sensors = tuple(
            SensorParams(altitude=float(rng.uniform(60.0, 300.0)), moves=(s,),
                         max_turn=float(rng.uniform(math.pi / 8, math.pi)),
                         fov_half_angle=float(rng.uniform(math.pi / 10, math.pi / 2)),
                         min_ground_range=gmin,
                         max_ground_range=gmin + float(rng.uniform(0.8 * s, 3.0 * s)),
                         snr_ref_db=float(rng.uniform(5.0, 20.0)))
            for _ in range(N))
        pos = rng.uniform(0, 1, (N, 2)) * [width, height]
        tpos = rng.uniform(-0.5, 1.5, (M, 2)) * [width, height]
        means = np.c_[tpos, rng.normal(0.0, 3.0, (M, 2))]
        sd = rng.uniform(5.0, 40.0, M)
        covs = np.array([np.diag([d * d, d * d, 4.0, 4.0]) for d in sd])
        vis = visibility or ("probabilistic" if rng.random() < 0.5 else "mean")
        problem = PlanningProblem(means, covs, pos, rng.uniform(-math.pi, math.pi, N), sensors,
                                  horizon=K, steps_per_epoch=e, world=MapRect(width, height),
                                  visibility=vis, objective=objective)
        if joint_plan_count(problem) <= max_plans:
            return problem


def paper_problem(rng: np.random.Generator, horizon: int = 3, steps_per_epoch: int = 2,
                  visibility: str = "probabilistic", objective: str = "terminal",
                  n_sensors: int = 3, n_targets: int = 5) -> PlanningProblem:
    """A decision of the paper scenario: targets in [100, 500]^2, P0, sensors in [50, 550]^2."""
    means = np.c_[rng.uniform(100, 500, (n_targets, 2)), rng.normal(0, 3, (n_targets, 2))]
    covs = np.tile(np.diag([400.0, 400.0, 4.0, 4.0]), (n_targets, 1, 1))
    alts = (490.0, 500.0, 510.0)
    sensors = tuple(SensorParams(altitude=alts[i % 3]) for i in range(n_sensors))
    return PlanningProblem(means, covs, rng.uniform(50, 550, (n_sensors, 2)),
                           rng.uniform(-math.pi, math.pi, n_sensors), sensors, horizon=horizon,
                           steps_per_epoch=steps_per_epoch, visibility=visibility,
                           objective=objective)


def weighted(problem: PlanningProblem, rng: np.random.Generator) -> PlanningProblem:
    """``problem`` with random probabilities of existence: uniform in [0, 1], then the
    smallest set to exactly 0 and, with two targets or more, the largest to exactly 1 (the
    ends, where a weight changes the most)."""
    r = rng.uniform(0.0, 1.0, problem.n_targets)
    lo, hi = int(np.argmin(r)), int(np.argmax(r))
    r[hi] = 1.0
    r[lo] = 0.0
    return dataclasses.replace(problem, existence=r)


def searching(problem: PlanningProblem, rng: np.random.Generator, sectors: int | tuple[int, ...],
              cells: int = 6) -> PlanningProblem:
    """``problem`` with search on: ``sectors`` search sectors (one number, or one per
    sensor) and an undetected intensity on a ``cells x cells`` grid over the map, with
    random expected numbers of undetected targets (uniform in [0, 1] per cell), births
    (uniform in [0, 0.01] per cell and step) and survival (uniform in [0.9, 1]); a found
    target's weight is derived (None)."""
    W, H = problem.world.width, problem.world.height
    a, b = W / cells, H / cells
    cx, cy = (np.arange(cells) + 0.5) * a, (np.arange(cells) + 0.5) * b
    centres = np.column_stack([np.tile(cx, cells), np.repeat(cy, cells)])
    C = len(centres)
    u = UndetectedIntensity(centres, rng.uniform(0.0, 1.0, C), rng.uniform(0.0, 0.01, C),
                            float(rng.uniform(0.9, 1.0)),
                            np.diag([a * a / 12.0, b * b / 12.0]))
    return dataclasses.replace(problem, search="on", search_sectors=sectors, undetected=u)


@dataclass(frozen=True)
class ContractProblem:
    """One problem of the contract set.

    Attributes
    ----------
    label : str                 e.g. ``"tiny[2] (mean, cumulative)"``, for messages
    problem : PlanningProblem
    tiny : bool                 at most 20,000 joint plans: exhaustive search is cheap
    """

    label: str
    problem: PlanningProblem
    tiny: bool


#: Joint plans of the contract's tiny problems, at most.
TINY_PLANS = 20_000


@functools.cache
def contract_problems() -> tuple[ContractProblem, ...]:
    """The fixed problems of the planner contract: for each visibility mode and objective,
    four tiny problems and one paper-size decision (K = 2); then, with the targets weighted
    by random probabilities of existence (:func:`weighted`), two tiny problems and one
    paper-size decision. Built once per process."""
    out = []
    for visibility in VISIBILITY_MODES:
        for objective in OBJECTIVES:
            rng = np.random.default_rng(7)
            mode = f"({visibility}, {objective})"
            out += [ContractProblem(f"tiny[{j}] {mode}",
                                    tiny_problem(rng, TINY_PLANS, visibility, objective), True)
                    for j in range(4)]
            out.append(ContractProblem(f"paper {mode}", paper_problem(
                rng, horizon=2, visibility=visibility, objective=objective), False))
    rng = np.random.default_rng(11)
    for j, (visibility, objective) in enumerate((("probabilistic", "cumulative"),
                                                 ("mean", "terminal"))):
        problem = tiny_problem(rng, TINY_PLANS, visibility, objective)
        # Weights 0, 1 and one in between, among players that interact.
        while problem.n_targets < 3 or problem.n_sensors < 2:
            problem = tiny_problem(rng, TINY_PLANS, visibility, objective)
        out.append(ContractProblem(f"tiny[{j}] ({visibility}, {objective}, weighted)",
                                   weighted(problem, rng), True))
    problem = paper_problem(rng, horizon=2, visibility="probabilistic", objective="cumulative")
    out.append(ContractProblem("paper (probabilistic, cumulative, weighted)",
                               weighted(problem, rng), False))
    return tuple(out)


#: Joint plans of the contract's tiny searching problems, at most (their brute force
#: evaluates each plan with the plain reference definition of Phi with search).
TINY_SEARCH_PLANS = 400


@functools.cache
def search_contract_problems() -> tuple[ContractProblem, ...]:
    """The searching problems of the planner contract (for the planners that declare they
    plan search looks; every other planner must refuse them): four tiny ones, with one to
    four sectors per sensor, the third with no track worth looking at (every existence 0:
    only search pays) and the fourth with its targets weighted by random probabilities of
    existence, and one paper-size decision (K = 2, 6 sectors, a 12 x 12 grid); then two tiny
    ones with the GOSPA-bound reward, one per objective, one with it and a track not
    reported, and that one again with the looks resolving the tracks' existence. Built once
    per process."""
    out = []
    rng = np.random.default_rng(13)
    j = 0
    while j < 4:
        base = tiny_problem(rng, 200, objective=str(rng.choice(OBJECTIVES)))
        if j == 2:
            base = dataclasses.replace(base, existence=np.zeros(base.n_targets))
        if j == 3:
            base = weighted(base, rng)
        sectors = tuple(int(s) for s in rng.integers(1, 5, base.n_sensors))
        problem = searching(base, rng, sectors)
        if joint_plan_count(problem) > TINY_SEARCH_PLANS:
            continue
        mode = f"{problem.visibility}, {problem.objective}, search"
        extra = {2: ", no track", 3: ", weighted"}.get(j, "")
        out.append(ContractProblem(f"tiny[{j}] ({mode}{extra})", problem, True))
        j += 1
    paper = searching(paper_problem(rng, horizon=2, objective="cumulative"), rng, 6, cells=12)
    out.append(ContractProblem("paper (probabilistic, cumulative, search)", paper, False))
    # The GOSPA-bound reward: one tiny problem per objective, two epochs or more, weighted
    # tracks and a cut-off that clips some tracks' bound (their own generator: the cases
    # above stay as they are).
    rng = np.random.default_rng(17)
    for objective in OBJECTIVES:
        while True:
            base = weighted(tiny_problem(rng, 200, objective=objective), rng)
            sectors = tuple(int(s) for s in rng.integers(1, 3, base.n_sensors))
            problem = dataclasses.replace(searching(base, rng, sectors), reward="gospa",
                                          gospa_c=float(rng.uniform(5.0, 60.0)))
            if (problem.horizon >= 2 and problem.n_targets >= 2
                    and joint_plan_count(problem) <= TINY_SEARCH_PLANS):
                break
        out.append(ContractProblem(f"tiny ({problem.visibility}, {objective}, search, "
                                   f"gospa)", problem, True))
    # The GOSPA-bound reward with a track not reported: it is found, not localised.
    rng = np.random.default_rng(19)
    while True:
        base = weighted(tiny_problem(rng, 200, objective="cumulative"), rng)
        sectors = tuple(int(s) for s in rng.integers(1, 3, base.n_sensors))
        reported = np.arange(base.n_targets) > 0
        existence = np.array(base.existence)
        existence[0] = rng.uniform(0.1, 0.5)        # below a report threshold of 0.5
        problem = dataclasses.replace(searching(base, rng, sectors), reward="gospa",
                                      reported=reported, existence=existence)
        if (problem.horizon >= 2 and problem.n_targets >= 2
                and joint_plan_count(problem) <= TINY_SEARCH_PLANS):
            break
    out.append(ContractProblem(f"tiny ({problem.visibility}, cumulative, search, gospa, "
                               "a track not reported)", problem, True))
    # The same with looks that resolve the reported tracks' existence (their beams count).
    out.append(ContractProblem(f"tiny ({problem.visibility}, cumulative, search, gospa, "
                               "a track not reported, existence resolved)",
                               dataclasses.replace(problem, track_existence="resolved"), True))
    return tuple(out)


__all__ = ["TINY_PLANS", "TINY_SEARCH_PLANS", "ContractProblem", "contract_problems",
           "joint_plan_count", "paper_problem", "search_contract_problems", "searching",
           "tiny_problem", "weighted"]
