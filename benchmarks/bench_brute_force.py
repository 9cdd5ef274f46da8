"""Benchmark: exact brute force over the myopic joint space (issue 4 speed target).

Paper-like decision: 600 m map, N = 3 sensors at altitudes 490/500/510 placed so that all
17 moves stay inside the map, M = 5 targets in [100, 500]^2 with
P0 = diag(400, 400, 4, 4), K = 1, e = 2: 17^3 x 5^3 = 614,125 joint plans. Target: median
<= 3 s with the default (``probabilistic``) visibility; ``mean`` is timed too.

Run::

    .venv/bin/python benchmarks/bench_brute_force.py [--repeats 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from sensorplan.planners.brute_force import BruteForcePlanner, count_joint_plans
from sensorplan.problem import MapRect, PlanningProblem
from sensorplan.sensors import SensorParams


def paper_like_problem(seed: int, visibility: str = "probabilistic", horizon: int = 1,
                       steps_per_epoch: int = 2, objective: str = "terminal") -> PlanningProblem:
    """The benchmark's decision, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    M, N = 5, 3
    xy = rng.uniform(100.0, 500.0, size=(M, 2))
    speed = rng.uniform(3.0, 6.0, size=M)
    course = rng.uniform(-math.pi, math.pi, size=M)
    means = np.column_stack([xy, speed * np.cos(course), speed * np.sin(course)])
    covs = np.broadcast_to(np.diag([400.0, 400.0, 4.0, 4.0]), (M, 4, 4)).copy()
    # 40 m (the longest move) from every edge: all 17 moves stay inside the map.
    positions = rng.uniform(40.0, 560.0, size=(N, 2))
    headings = rng.uniform(-math.pi, math.pi, size=N)
    sensors = tuple(SensorParams(altitude=z) for z in (490.0, 500.0, 510.0))
    return PlanningProblem(means=means, covs=covs, positions=positions, headings=headings,
                           sensors=sensors, horizon=horizon, steps_per_epoch=steps_per_epoch,
                           world=MapRect(600.0, 600.0), visibility=visibility,
                           objective=objective)


def run(visibility: str, repeats: int, seed: int, objective: str = "terminal") -> float:
    """Time ``repeats`` brute-force decisions; print and return the median seconds."""
    problem = paper_like_problem(seed, visibility, objective=objective)
    planner = BruteForcePlanner()
    n_plans = count_joint_plans(problem)
    times, phi = [], float("nan")
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = planner.plan(problem)
        times.append(time.perf_counter() - t0)
        phi = result.potential
    med = statistics.median(times)
    print(f"visibility={visibility:13s} objective={objective:10s} plans={n_plans:,} "
          f"median={med:.3f} s  min={min(times):.3f} s  "
          f"plans/s={n_plans / med:,.0f}  Phi*={phi:.6f} nats")
    return med


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    med = run("probabilistic", args.repeats, args.seed)
    print(f"target <= 3 s (probabilistic): {'met' if med <= 3.0 else 'NOT met'}")
    run("mean", args.repeats, args.seed)
    run("probabilistic", args.repeats, args.seed, objective="cumulative")


if __name__ == "__main__":
    main()
