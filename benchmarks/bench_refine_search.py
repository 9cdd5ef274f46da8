"""What ``pg-refine`` costs and gains over ``pg`` with search looks. Run on purpose, not in CI:

    .venv/bin/python benchmarks/bench_refine_search.py [--decisions 12] [--horizon 3]

Problems: the decisions of closed-loop runs of the ``search`` preset with search on (what
``sensorplan simulate --preset search --search on --planner random --horizon K`` builds,
every PlanningProblem recorded; runs seeded 0, 1, ... until enough decisions, every third
decision from the fourth on kept). Each is planned by ``pg`` and ``pg-refine`` (rng 0) in
alternation, the order swapped every problem so that the machine's load hits both alike.
Printed: median wall and CPU seconds per decision of each, the ratio of the medians and the
median of the per-problem ratios; mean Phi of each and how often ``pg-refine`` is above
``pg`` (by more than the tie tolerance) or below it (never, by construction).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sensorplan.config.simulate import load_simulation
from sensorplan.planners import make_planner
from sensorplan.planners.problem import TIE_TOL, PlanningProblem
from sensorplan.simulation import run as simulation
from sensorplan.simulation import run_episode


def search_problems(n: int, horizon: int) -> list[PlanningProblem]:
    """The recorded problems of searching runs of the search preset (random planner)."""
    cfg = load_simulation(preset="search", overrides={"search": "on", "planner": "random",
                                                      "horizon": horizon, "steps": 30})
    built: list[PlanningProblem] = []
    real = simulation.PlanningProblem

    def record(*args, **kwargs):  # type: ignore[no-untyped-def]
        built.append(real(*args, **kwargs))
        return built[-1]

    problems: list[PlanningProblem] = []
    simulation.PlanningProblem = record  # type: ignore[misc]
    try:
        run = 0
        while len(problems) < n:
            built.clear()
            run_episode(cfg.scenario, cfg.settings, np.random.SeedSequence([0, run]))
            problems += [p for p in built[3::3] if p.searching]
            run += 1
    finally:
        simulation.PlanningProblem = real  # type: ignore[misc]
    return problems[:n]


def timed(name: str, problem: PlanningProblem) -> tuple[float, float, float]:
    """Wall seconds (the planner's own), CPU seconds and Phi of one plan."""
    c0 = time.process_time()
    r = make_planner(name).plan(problem, rng=0)
    return r.seconds, time.process_time() - c0, r.potential


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--decisions", type=int, default=12)
    ap.add_argument("--horizon", type=int, default=3)
    args = ap.parse_args()
    problems = search_problems(args.decisions, args.horizon)
    names = ("pg", "pg-refine")
    make_planner("pg").plan(problems[0], rng=0)               # warm the kernels
    out = {name: [] for name in names}
    for j, problem in enumerate(problems):
        for name in (names if j % 2 == 0 else names[::-1]):
            out[name].append(timed(name, problem))
    a = {name: np.array(v) for name, v in out.items()}
    pg, refine = a["pg"], a["pg-refine"]
    print(f"## pg-refine vs pg with search: {len(problems)} decisions of the search preset, "
          f"K = {args.horizon}")
    print("| planner | median wall s | median CPU s | mean Phi |")
    print("|---|---|---|---|")
    for name in names:
        w, c, phi = np.median(a[name][:, 0]), np.median(a[name][:, 1]), a[name][:, 2].mean()
        print(f"| {name} | {w:.3f} | {c:.3f} | {phi:.4f} |")
    tol = TIE_TOL * np.maximum(1.0, np.abs(pg[:, 2]))
    print(f"ratio of medians (wall, CPU): {np.median(refine[:, 0]) / np.median(pg[:, 0]):.2f}, "
          f"{np.median(refine[:, 1]) / np.median(pg[:, 1]):.2f}; median per-problem ratio "
          f"(CPU) {np.median(refine[:, 1] / pg[:, 1]):.2f}")
    print(f"pg-refine above pg on {int(np.sum(refine[:, 2] > pg[:, 2] + tol))}, below on "
          f"{int(np.sum(refine[:, 2] < pg[:, 2] - tol))} of {len(problems)}; mean Phi "
          f"gain {np.mean(refine[:, 2] - pg[:, 2]):.4f} nats")


if __name__ == "__main__":
    main()
