"""What search costs a planning decision (docs/benchmarks.md). Run on purpose, not in CI:

    .venv/bin/python benchmarks/search_decision.py [--repeats 7] [--seed 0] [--cells 24]
        [--planners pg sequential-greedy] [--sizes 3 20]

Target: a decision with 3 sensors, K = 3, 8 tracks and 12 search sectors per
sensor takes at most 3x the same decision with search off; at N = 20 sensors the same.

Both decisions of a pair come from one seeded problem, built by the project's builders
(:func:`~sensorplan.planners.contract_problems.paper_problem`: the paper's 600 m map,
e = 2, M = 8 targets, N sensors; then :func:`~sensorplan.planners.contract_problems.searching`
adds 12 sectors per sensor and an undetected intensity on a ``cells x cells`` grid, 24 x 24
by default: the ``pmb`` tracker's 25 m cells on this map). The search-off decision is the
same problem before ``searching``. Two warm-up decisions of each (kernels compiled or
loaded, caches filled) are excluded; then ``--repeats`` repetitions alternate search on and off,
swapping the order every time, so that the machine's load hits both alike. Printed: the
median wall time (``PlanResult.seconds``) and CPU time of each, and the ratio of the medians
search / no search (CPU and wall) against the 3x target.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from sensorplan.planners import make_planner
from sensorplan.planners.contract_problems import paper_problem, searching
from sensorplan.planners.problem import PlanningProblem

TARGET_RATIO = 3.0


def problems(n_sensors: int, seed: int, cells: int) -> dict[str, PlanningProblem]:
    """The pair of decisions: ``{"search": ..., "no search": ...}`` from one seeded problem."""
    rng = np.random.default_rng(seed)
    off = paper_problem(rng, horizon=3, steps_per_epoch=2, n_sensors=n_sensors, n_targets=8)
    return {"search": searching(off, rng, 12, cells=cells), "no search": off}


def time_once(planner: str, problem: PlanningProblem) -> tuple[float, float]:
    """Wall (the planner's own ``seconds``) and CPU seconds of one decision."""
    c0 = time.process_time()
    r = make_planner(planner).plan(problem, rng=0)
    return r.seconds, time.process_time() - c0


def bench(planner: str, n_sensors: int, args: argparse.Namespace) -> float:
    """Print one row of the table; return the CPU ratio search / no search."""
    pair = problems(n_sensors, args.seed, args.cells)
    for _ in range(2):
        # Warm-up, twice: a kernel numba runs (not the ahead-of-time module's) makes the next
        # decision load every listed kernel first, inside the CPU time measured here.
        for p in pair.values():
            time_once(planner, p)
    got: dict[str, dict[str, list[float]]] = {m: {"wall": [], "cpu": []} for m in pair}
    modes = list(pair)
    for r in range(args.repeats):
        for m in (modes if r % 2 == 0 else modes[::-1]):
            w, c = time_once(planner, pair[m])
            got[m]["wall"].append(w)
            got[m]["cpu"].append(c)
    med = {m: {k: float(np.median(v)) for k, v in t.items()} for m, t in got.items()}
    s, o = med["search"], med["no search"]
    cpu, wall = s["cpu"] / o["cpu"], s["wall"] / o["wall"]
    print(f"| {planner} | {n_sensors} | {s['wall']*1e3:.1f} | {o['wall']*1e3:.1f} "
          f"| {s['cpu']*1e3:.1f} | {o['cpu']*1e3:.1f} | {cpu:.2f} | {wall:.2f} "
          f"| {'met' if cpu <= TARGET_RATIO else 'NOT met'} |", flush=True)
    return cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cells", type=int, default=24)
    parser.add_argument("--planners", nargs="+", default=["pg", "sequential-greedy"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[3, 20])
    args = parser.parse_args()
    print(f"## Search on vs off: K = 3, e = 2, M = 8, 12 sectors, {args.cells}x{args.cells} "
          f"cells, seed {args.seed}, {args.repeats} interleaved repeats after two warm-ups "
          f"(load {os.getloadavg()[0]:.1f})")
    print("| planner | N | search wall ms | no-search wall ms | search CPU ms "
          "| no-search CPU ms | ratio (CPU) | ratio (wall) | <= 3x |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for planner in args.planners:
            bench(planner, n, args)


if __name__ == "__main__":
    main()
