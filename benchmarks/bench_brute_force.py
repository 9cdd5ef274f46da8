"""Benchmark: exact brute force over the myopic joint space (docs/benchmarks.md, its target).

Paper-like decision (``tests/factories.py:paper_problem``): 600 m map, N = 3 sensors at
altitudes 490/500/510 placed so that all 17 moves stay inside the map, M = 5 targets in
[100, 500]^2 with
P0 = diag(400, 400, 4, 4), K = 1, e = 2: 17^3 x 5^3 = 614,125 joint plans. Target: median
<= 3 s with the default (``probabilistic``) visibility; ``mean`` is timed too.

Run::

    .venv/bin/python benchmarks/bench_brute_force.py [--repeats 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from sensorplan.planners.brute_force import BruteForcePlanner, count_joint_plans

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from factories import paper_problem  # noqa: E402  (the test problems, shared)


def run(visibility: str, repeats: int, seed: int, objective: str = "terminal") -> float:
    """Time ``repeats`` brute-force decisions; print and return the median seconds."""
    # Sensors at least 50 m from every edge: all 17 moves stay inside the map.
    problem = paper_problem(np.random.default_rng(seed), horizon=1, steps_per_epoch=2,
                            visibility=visibility, objective=objective)
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
