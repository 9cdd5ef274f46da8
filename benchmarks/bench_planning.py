"""Planning speed and quality (docs/benchmarks.md). Run on purpose, not in CI:

    .venv/bin/python benchmarks/bench_planning.py [--decisions 20] [--kmax 8] [--quick]
    .venv/bin/python benchmarks/bench_planning.py --detection [--occlusion] [--existence]
        [--decisions 20] [--repeats 3]

1. ``pg``, ``pg-refine`` and ``sequential-greedy`` per decision at N = 3, M = 5, e = 2 on
   paper-scenario states (tracker states of closed-loop runs with the ``random`` planner),
   K = 1..kmax: medians of wall and CPU time over the decisions, the fitted growth exponent
   in K (least squares of log time on log K over K >= 2), and ``pg-refine`` / ``pg``.
2. The same K = 3 decisions with ``SENSORPLAN_BACKEND=numpy`` (the numpy reference of the
   potential's recursions and looks; the planning engine's kernels are compiled either way).
3. Exhaustive search against the game as K grows (the paper's third claim).
4. Quality on 200 random tiny problems against the exact optimum (``brute-force``).

``--detection`` and ``--occlusion`` run only what the planning modes cost (target: aware
<= 1.2x ignore): planning problems built exactly as closed-loop runs build them (random
planner, e = 2; ``configs/radar.toml``, the radar of results.md section 7, for detection,
``urban`` for occlusion), each planned by ``pg`` (K = 1 and 3) under ``aware`` and under
``ignore`` in alternation on the same problem, so that the machine's load hits both
alike; medians per decision, the ratio of the medians and the median of the per-problem
ratios. ``--existence`` does the same for targets weighted by probabilities of existence
against no weights (the paper preset).

The scale cases (N = 20, M = 50, K = 10 and the swarm) are in ``bench_scale.py``, quality
against a time budget in ``bench_anytime.py``.

CPU time (``time.process_time``) is reported beside wall time because the machines are
shared: the medians of both are printed, ratios are computed in the same run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from sensorplan.planners import make_planner  # noqa: E402
from sensorplan.planners.problem import PlanningProblem  # noqa: E402
from sensorplan.simulation.scenario import paper_scenario  # noqa: E402
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
    # terminal: the objective every recorded figure of docs/benchmarks.md was measured with
    return [dict(s, sensors=sensors, objective="terminal") for s in states[:n]]


def preset_problems(preset: str, n: int, seed: int = 0) -> list[PlanningProblem]:
    """Planning problems of closed-loop runs of a preset (or a scenario file: a path ending
    in .toml, from the repository root), as the simulation builds them.

    What ``sensorplan simulate --preset NAME --planner random -e 2 --steps 60`` runs, with
    every ``PlanningProblem`` it builds recorded (the tracker's means, covariances and
    planning q, the poses, the run's planning modes and the buildings); the decisions at
    t = 10, 20, ..., 50 of each run are kept.
    """
    from sensorplan.simulation import run as simulation
    from sensorplan.config.simulate import load_simulation

    overrides = {"planner": "random", "steps_per_epoch": 2, "steps": 60}
    cfg = (load_simulation(ROOT / preset, overrides=overrides) if preset.endswith(".toml")
           else load_simulation(preset=preset, overrides=overrides))
    built: list[PlanningProblem] = []
    real = simulation.PlanningProblem

    def record(*args, **kwargs):
        built.append(real(*args, **kwargs))
        return built[-1]

    problems: list[PlanningProblem] = []
    simulation.PlanningProblem = record
    try:
        run = 0
        while len(problems) < n:
            built.clear()
            run_episode(cfg.scenario, cfg.settings, np.random.SeedSequence([seed, run]))
            problems += built[5::5]                  # decisions fall at t - 1 = 0, 2, 4, ...
            run += 1
    finally:
        simulation.PlanningProblem = real
    return problems[:n]


def _plan_times(problem: PlanningProblem) -> tuple[float, float, int]:
    c0 = time.process_time()
    r = make_planner("pg").plan(problem, rng=0)
    return r.seconds, time.process_time() - c0, r.sweeps


def mode_cost(label: str, preset: str,
              variants: Callable[[PlanningProblem], dict[str, PlanningProblem]],
              args: argparse.Namespace, modes: tuple[str, str] = ("aware", "ignore")) -> None:
    """Time ``pg`` under two variants of the same problems (``aware`` and ``ignore`` unless
    ``modes`` names others; the ratios are the first over the second).

    ``variants(problem)`` returns ``{"aware": problem, "ignore": problem}``. Each problem is
    planned ``args.repeats`` times in each mode, alternating and swapping the order every
    time (aware, ignore, ignore, aware, ...); a problem's time in a mode is the median of
    its repeats.
    """
    m1, m2 = modes
    base = preset_problems(preset, args.decisions)
    print(f"\n## {label}: pg, {preset} preset, N = {base[0].n_sensors}, "
          f"M = {base[0].n_targets}, e = 2, {len(base)} decisions x {args.repeats} "
          f"repeats per mode, interleaved (load {os.getloadavg()[0]:.1f})")
    print(f"| K | {m1} wall ms | {m2} wall ms | {m1} CPU ms | {m2} CPU ms "
          "| ratio of medians (CPU) | ratio of medians (wall) | median per-problem ratio "
          f"(CPU) [min, max] | sweeps {m1} / {m2} | per sweep: ratio of medians (CPU) "
          "| same plan |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for K in (1, 3):
        pairs = [variants(dataclasses.replace(p, horizon=K)) for p in base]
        for mode in modes:
            _plan_times(pairs[0][mode])              # warm-up: caches, this mode's kernels
        med = {m: {"wall": [], "cpu": [], "sweeps": []} for m in modes}
        same = 0
        for i, pair in enumerate(pairs):
            got = {m: {"wall": [], "cpu": [], "sweeps": []} for m in pair}
            for r in range(args.repeats):
                order = modes if (i + r) % 2 == 0 else modes[::-1]
                for m in order:
                    w, c, sw = _plan_times(pair[m])
                    got[m]["wall"].append(w)
                    got[m]["cpu"].append(c)
                    got[m]["sweeps"].append(sw)
            for m, times in got.items():
                for key, values in times.items():
                    med[m][key].append(float(np.median(values)))
            plans = [make_planner("pg").plan(pair[m], rng=0).plan for m in modes]
            same += all(np.array_equal(getattr(plans[0], f), getattr(plans[1], f))
                        for f in ("positions", "targets"))
        a, g = med[m1], med[m2]
        per = np.array(a["cpu"]) / np.array(g["cpu"])
        # The modes can converge in different numbers of sweeps: the cost of one sweep
        # separates the price of the looks from the game's path.
        sweep_ratio = (np.median(np.array(a["cpu"]) / np.array(a["sweeps"]))
                       / np.median(np.array(g["cpu"]) / np.array(g["sweeps"])))
        print(f"| {K} | {np.median(a['wall'])*1e3:.2f} | {np.median(g['wall'])*1e3:.2f} "
              f"| {np.median(a['cpu'])*1e3:.2f} | {np.median(g['cpu'])*1e3:.2f} "
              f"| {np.median(a['cpu']) / np.median(g['cpu']):.3f} "
              f"| {np.median(a['wall']) / np.median(g['wall']):.3f} "
              f"| {np.median(per):.3f} [{per.min():.2f}, {per.max():.2f}] "
              f"| {np.mean(a['sweeps']):.2f} / {np.mean(g['sweeps']):.2f} "
              f"| {sweep_ratio:.3f} "
              f"| {same}/{len(pairs)} |")


def detection_cost(args: argparse.Namespace) -> None:
    """``planning_detection`` aware against ignore on the decisions of configs/radar.toml
    (known targets)."""
    mode_cost("Detection in planning", "configs/radar.toml", lambda p: {
        m: dataclasses.replace(p, planning_detection=m) for m in ("aware", "ignore")}, args)


def occlusion_cost(args: argparse.Namespace) -> None:
    """``planning_occlusion`` aware (the buildings) against ignore (none) on the urban
    preset's decisions (what the simulation passes for each setting)."""
    def variants(p: PlanningProblem) -> dict[str, PlanningProblem]:
        assert len(p.buildings) > 0, "the urban preset's problems carry its buildings"
        return {"aware": p, "ignore": dataclasses.replace(p, buildings=np.zeros((0, 5)))}
    mode_cost("Occlusion in planning", "urban", variants, args)


def existence_cost(args: argparse.Namespace) -> None:
    """Targets weighted by probabilities of existence against the same problems without
    weights, on the paper preset's decisions. The weights are drawn uniform in [0.05, 1]
    once per problem (seeded), what a multi-target tracker's tracks might report."""
    gen = np.random.default_rng(0)

    def variants(p: PlanningProblem) -> dict[str, PlanningProblem]:
        r = gen.uniform(0.05, 1.0, p.n_targets)
        return {"weighted": dataclasses.replace(p, existence=r), "plain": p}
    mode_cost("Targets weighted by existence", "paper", variants, args,
              modes=("weighted", "plain"))


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
        "from sensorplan.planners.problem import PlanningProblem;"
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
    """The paper's third claim: exhaustive search grows exponentially in K, the game
    polynomially."""
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
                                    sensors=s["sensors"][:1], horizon=K, steps_per_epoch=2,
                                    objective="terminal")
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
    ap.add_argument("--detection", action="store_true",
                    help="only: planning_detection aware vs ignore (configs/radar.toml)")
    ap.add_argument("--occlusion", action="store_true",
                    help="only: planning_occlusion aware vs ignore (urban preset)")
    ap.add_argument("--existence", action="store_true",
                    help="only: targets weighted by existence vs no weights (paper preset)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="plans per problem and mode for --detection / --occlusion / "
                         "--existence")
    args = ap.parse_args()
    if args.detection or args.occlusion or args.existence:
        if args.detection:
            detection_cost(args)
        if args.occlusion:
            occlusion_cost(args)
        if args.existence:
            existence_cost(args)
        return
    if args.quick:
        args.kmax, args.quality = 4, 50
    speed(args)
    backend_comparison(args)
    if not args.quick:
        exhaustive_growth()
    quality(args.quality)


if __name__ == "__main__":
    main()
