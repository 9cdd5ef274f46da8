"""Planning speed and quality (issue 4's benchmarks). Run on purpose, not in CI:

    .venv/bin/python benchmarks/bench_planning.py [--decisions 20] [--kmax 8] [--quick]

1. ``pg``, ``pg-refine`` and ``sequential-greedy`` per decision at N = 3, M = 5, e = 2 on
   paper-scenario states (tracker states of closed-loop runs with the ``random`` planner),
   K = 1..kmax: medians of wall and CPU time over the decisions, the fitted growth exponent
   in K (least squares of log time on log K over K >= 2), and ``pg-refine`` / ``pg``.
2. The same K = 3 decisions with ``SENSORPLAN_BACKEND=numpy`` (the numpy reference of the
   potential's recursions and looks; the planning engine's kernels are compiled either way).
3. Exhaustive search against the game as K grows (SPEC 6 claim 3).
4. Quality on 200 random tiny problems against the exact optimum (``brute-force``).

The scale cases (N = 20, M = 50, K = 10 and the swarm) are in ``bench_scale.py``, quality
against a time budget in ``bench_anytime.py``.

CPU time (``time.process_time``) is reported beside wall time because the machines are
shared: the medians of both are printed, ratios are computed in the same run.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from sensorplan.planners import make_planner  # noqa: E402
from sensorplan.problem import PlanningProblem  # noqa: E402
from sensorplan.scenario import paper_scenario  # noqa: E402
from sensorplan.simulation import RunSettings, run_episode  # noqa: E402


def paper_states(n: int, seed: int = 0) -> list[dict]:
    """Tracker states and poses from closed-loop runs of the paper preset (random planner)."""
    scenario = paper_scenario()
    states = []
    run = 0
    while len(states) < n:
        ep = run_episode(scenario, RunSettings(planner="random", steps_per_epoch=2, steps=60),
                         np.random.SeedSequence([seed, run]))
        for t in range(10, 61, 10):
            states.append(dict(means=ep.estimate[t], covs=ep.cov[t],
                               positions=ep.sensor_positions[t], headings=ep.sensor_headings[t]))
        run += 1
    sensors = tuple(s.params for s in scenario.sensors)
    return [dict(s, sensors=sensors) for s in states[:n]]


def time_planner(name: str, problems: list[PlanningProblem]) -> tuple[float, float, float]:
    """Median wall (PlanResult.seconds) and CPU seconds per decision, and mean Phi."""
    make_planner(name).plan(problems[0])            # warm-up (numba cache load)
    wall, cpu, phi = [], [], []
    for p in problems:
        c0 = time.process_time()
        r = make_planner(name).plan(p, rng=0)
        cpu.append(time.process_time() - c0)
        wall.append(r.seconds)
        phi.append(r.potential)
    return float(np.median(wall)), float(np.median(cpu)), float(np.mean(phi))


def exponent(ks: list[int], t: list[float]) -> float:
    sel = [i for i, k in enumerate(ks) if k >= 2]
    return float(np.polyfit(np.log([ks[i] for i in sel]), np.log([t[i] for i in sel]), 1)[0])


def speed(args: argparse.Namespace) -> None:
    states = paper_states(args.decisions)
    rows = {name: [] for name in ("pg", "pg-refine", "sequential-greedy")}
    ks = list(range(1, args.kmax + 1))
    print(f"## Per decision, N = 3, M = 5, e = 2, {args.decisions} paper-scenario states")
    print("| K | pg wall ms | pg CPU ms | pg-refine wall ms | pg-refine CPU ms | refine/pg (CPU)"
          " | greedy CPU ms | Phi pg | Phi pg-refine | Phi greedy |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for K in ks:
        problems = [PlanningProblem(horizon=K, steps_per_epoch=2, **s) for s in states]
        res = {name: time_planner(name, problems) for name in rows}
        for name in rows:
            rows[name].append(res[name])
        pg, rf, gr = res["pg"], res["pg-refine"], res["sequential-greedy"]
        print(f"| {K} | {pg[0]*1e3:.1f} | {pg[1]*1e3:.1f} | {rf[0]*1e3:.1f} | {rf[1]*1e3:.1f} "
              f"| {rf[1]/pg[1]:.2f} | {gr[1]*1e3:.1f} | {pg[2]:.3f} | {rf[2]:.3f} | {gr[2]:.3f} |")
    for name in ("pg", "pg-refine"):
        print(f"growth exponent in K ({name}, CPU, K >= 2): "
              f"{exponent(ks, [r[1] for r in rows[name]]):.2f}")


def backend_comparison(args: argparse.Namespace) -> None:
    code = (
        "import sys, numpy as np; sys.argv=['x']; sys.path.insert(0, {!r});"
        "import bench_planning as b;"
        "from sensorplan.problem import PlanningProblem;"
        "s=b.paper_states({:d});"
        "ps=[PlanningProblem(horizon=3, steps_per_epoch=2, **x) for x in s];"
        "w,c,_=b.time_planner('pg', ps); print(w, c)").format(str(ROOT / "benchmarks"),
                                                                 args.decisions)
    out = {}
    for backend in ("numba", "numpy"):
        env = dict(os.environ, SENSORPLAN_BACKEND=backend)
        res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True)
        out[backend] = [float(x) for x in res.stdout.split()]
    print("\n## Backend, pg K = 3 (median per decision)")
    print("| backend | wall ms | CPU ms |\n|---|---|---|")
    for b, (w, c) in out.items():
        print(f"| {b} | {w*1e3:.1f} | {c*1e3:.1f} |")
    print(f"numpy / numba (CPU): {out['numpy'][1] / out['numba'][1]:.1f}x")


def exhaustive_growth(kmax: int = 4) -> None:
    """SPEC 6 claim 3: exhaustive search grows exponentially in K, the game polynomially."""
    from factories import joint_plan_count
    states = paper_states(3)
    print("\n## Exhaustive search vs the game in K (one sensor, M = 3, e = 2; "
          "median of 3 paper-scenario states)")
    print("| K | joint plans | brute-force CPU s | pg CPU s | pg Phi / optimum "
          "| pg-refine Phi / optimum |")
    print("|---|---|---|---|---|---|")
    for K in range(1, kmax + 1):
        problems = [PlanningProblem(means=s["means"][:3], covs=s["covs"][:3],
                                    positions=s["positions"][:1], headings=s["headings"][:1],
                                    sensors=s["sensors"][:1], horizon=K, steps_per_epoch=2)
                    for s in states]
        bf, pg, ratio, ratio_rf = [], [], [], []
        for p in problems:
            c0 = time.process_time()
            best = make_planner("brute-force", max_plans=10**8).plan(p)
            bf.append(time.process_time() - c0)
            c0 = time.process_time()
            r = make_planner("pg").plan(p)
            pg.append(time.process_time() - c0)
            ratio.append(r.potential / best.potential if best.potential > 0 else 1.0)
            rf = make_planner("pg-refine").plan(p)
            ratio_rf.append(rf.potential / best.potential if best.potential > 0 else 1.0)
        print(f"| {K} | {joint_plan_count(problems[0]):,} | {np.median(bf):.3f} | "
              f"{np.median(pg):.4f} | {np.mean(ratio):.3f} | {np.mean(ratio_rf):.3f} |")
    full = [PlanningProblem(horizon=K, steps_per_epoch=2, **states[0]) for K in range(1, 9)]
    print("Joint plans of the paper problem (N = 3, M = 5): " + ", ".join(
        f"K={p.horizon}: {float(joint_plan_count(p)):.2e}" for p in full))


def quality(n: int) -> None:
    from factories import tiny_problem
    rng = np.random.default_rng(2024)
    names = ("pg", "pg-refine", "sequential-greedy", "random")
    ratios = {nm: [] for nm in names}
    conv, sweeps = [], []
    for s in range(n):
        p = tiny_problem(rng)
        opt = make_planner("brute-force").plan(p).potential
        for nm in names:
            r = make_planner(nm).plan(p, rng=s)
            ratios[nm].append(r.potential / opt if opt > 1e-12 else 1.0)
            if nm == "pg":
                conv.append(r.converged)
                sweeps.append(r.sweeps)
    print(f"\n## Quality on {n} random tiny problems (N <= 3, M <= 4, K <= 4; Phi / optimum)")
    print("| planner | mean | worst | share >= 0.95 |\n|---|---|---|---|")
    for nm in names:
        a = np.array(ratios[nm])
        print(f"| {nm} | {a.mean():.4f} | {a.min():.3f} | {np.mean(a >= 0.95):.3f} |")
    print(f"pg converged on {np.mean(conv):.3f} of them, mean sweeps {np.mean(sweeps):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--decisions", type=int, default=20)
    ap.add_argument("--kmax", type=int, default=8)
    ap.add_argument("--quality", type=int, default=200)
    ap.add_argument("--quick", action="store_true", help="K <= 4, 50 problems")
    args = ap.parse_args()
    if args.quick:
        args.kmax, args.quality = 4, 50
    speed(args)
    backend_comparison(args)
    if not args.quick:
        exhaustive_growth()
    quality(args.quality)


if __name__ == "__main__":
    main()
