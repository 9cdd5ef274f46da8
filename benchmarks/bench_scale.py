"""Planning at scale: one ``pg`` decision at N = 20 / M = 50 / K = 10 and at swarm size.

    .venv/bin/python benchmarks/bench_scale.py [--repeats 7] [--growth] [--quick]
        [--settings library|cli|both]

1. **N = 20, M = 50, K = 10** (e = 1, 2,000 m map; the case of ``bench_planning.py``) and
   **swarm** (``swarm_scenario()``: N = 100, M = 200, K = 5, e = 1, 3,000 m map, its first
   decision): each in a fresh process, the median wall and CPU time of ``--repeats``
   decisions after one warm-up decision, the process's max RSS, and the RSS of the same
   process after import and kernel warm-up only (what Python, numpy and numba take).
   ``--settings``: the process as a library user's (numpy's and glibc's defaults), as the
   command line sets it up (no huge pages for numpy, glibc keeping freed memory for reuse:
   ``sensorplan.memory``), or both (the default), each in its own processes.
2. ``--growth``: the cost of one swarm-size decision as N and M vary on the same 3,000 m map
   (K = 5; N in 25..200 at M = 200, M in 50..400 at N = 100), median of 3 decisions (CPU
   time), with the exponents of least-squares fits of log time on log N and log M.

CPU time (``time.process_time``) is printed beside wall time: the machine is shared, and
the ratios and exponents are taken on CPU time.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

_CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {tests!r})
import numpy as np
from sensorplan.planners import make_planner
from sensorplan.planners.base import start_clock
from planner_reference import scale_problem, swarm_problem
start_clock(engine=True)                        # imports and kernel warm-up only
base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
case, reps = {case!r}, {reps}
problem = scale_problem() if case == "scale" else swarm_problem()
make_planner("pg").plan(problem)                # warm-up decision (caches, page faults)
wall, cpu = [], []
for _ in range(reps):
    c0 = time.process_time()
    r = make_planner("pg").plan(problem)
    cpu.append(time.process_time() - c0)
    wall.append(r.seconds)
print(json.dumps(dict(wall=wall, cpu=cpu, phi=r.potential, sweeps=r.sweeps,
                      converged=r.converged, base_rss=base_rss,
                      rss=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def process_env(settings: str) -> dict[str, str]:
    """The environment of a measured process: as a library user's, or as the command line
    sets up its own (read by numpy and glibc when the process starts)."""
    from sensorplan.memory import HUGEPAGE, MALLOC_ENV, MALLOC_VARS, numpy_defaults

    env = {k: v for k, v in os.environ.items() if k not in (HUGEPAGE, *MALLOC_VARS)}
    if settings == "cli":
        numpy_defaults(env)
        env.update(MALLOC_ENV)
    return env


def measure(case: str, reps: int, settings: str = "library") -> dict:
    """Run one case in a fresh process (its own RSS)."""
    code = _CHILD.format(tests=str(ROOT / "tests"), case=case, reps=reps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=process_env(settings))
    return json.loads(out.stdout.strip().splitlines()[-1])


def report(label: str, res: dict) -> None:
    print(f"| {label} | {statistics.median(res['wall']):.3f} | "
          f"{statistics.median(res['cpu']):.3f} | {min(res['cpu']):.3f} | "
          f"{res['rss']:.0f} | {res['base_rss']:.0f} | {res['phi']:.2f} | {res['sweeps']} |")


def swarm_like(n_sensors: int, n_targets: int, seed: int = 0):
    """A decision of the swarm scenario with N sensors and M targets on its 3,000 m map
    (sensors and targets repeat the swarm's specs in turn)."""
    from dataclasses import replace

    from sensorplan.planners.problem import PlanningProblem
    from sensorplan.simulation.scenario import draw_initial, swarm_scenario

    sc = swarm_scenario()
    sc = replace(sc, sensors=tuple(sc.sensors[i % 100] for i in range(n_sensors)),
                 targets=tuple(sc.targets[j % 200] for j in range(n_targets)))
    ss = np.random.SeedSequence(seed).spawn(2)
    ini = draw_initial(sc, np.random.default_rng(ss[0]), np.random.default_rng(ss[1]))
    covs = np.tile(np.array(sc.initial_cov), (n_targets, 1, 1))
    return PlanningProblem(ini.estimate, covs, ini.positions, ini.headings,
                           tuple(s.params for s in sc.sensors), horizon=5, dt=sc.dt,
                           process_noise=sc.process_noise, world=sc.world, objective="terminal")


def growth(quick: bool) -> None:
    import time

    from sensorplan.planners import make_planner

    make_planner("pg").plan(swarm_like(2, 2))
    Ns = [25, 50, 100] if quick else [25, 50, 100, 200]
    Ms = [50, 100, 200] if quick else [50, 100, 200, 400]

    def cost(N: int, M: int) -> float:
        times = []
        for seed in range(3):
            p = swarm_like(N, M, seed)
            c0 = time.process_time()
            make_planner("pg").plan(p)
            times.append(time.process_time() - c0)
        return statistics.median(times)

    print("\n## Growth (swarm map, K = 5, median CPU s of 3 decisions)")
    tN = [cost(N, 200) for N in Ns]
    print("| N (M = 200) | " + " | ".join(map(str, Ns)) + " |")
    print("|---|" + "---|" * len(Ns))
    print("| CPU s | " + " | ".join(f"{t:.2f}" for t in tN) + " |")
    tM = [cost(100, M) for M in Ms]
    print("| M (N = 100) | " + " | ".join(map(str, Ms)) + " |")
    print("| CPU s | " + " | ".join(f"{t:.2f}" for t in tM) + " |")
    eN = np.polyfit(np.log(Ns), np.log(tN), 1)[0]
    eM = np.polyfit(np.log(Ms), np.log(tM), 1)[0]
    print(f"fitted exponents: time ~ N^{eN:.2f} (M = 200), time ~ M^{eM:.2f} (N = 100)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--growth", action="store_true")
    ap.add_argument("--quick", action="store_true", help="3 repeats, smaller growth sweep")
    ap.add_argument("--settings", choices=("library", "cli", "both"), default="both",
                    help="the process's numpy and allocator settings (see the docstring)")
    args = ap.parse_args()
    reps = 3 if args.quick else args.repeats
    print(f"## One pg decision, median of {reps} (fresh process per case)")
    print("| case | settings | wall s (median) | CPU s (median) | CPU s (min) | max RSS MiB "
          "| RSS after import MiB | Phi | sweeps |")
    print("|---|---|---|---|---|---|---|---|---|")
    chosen = ("library", "cli") if args.settings == "both" else (args.settings,)
    for label, case in (("N = 20, M = 50, K = 10", "scale"),
                        ("swarm N = 100, M = 200, K = 5", "swarm")):
        for settings in chosen:
            report(f"{label} | {settings}", measure(case, reps, settings))
    if args.growth:
        growth(args.quick)


if __name__ == "__main__":
    main()
