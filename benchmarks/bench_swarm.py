"""The swarm's figures in one command: a closed-loop run, cold start and N = 20 planning.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_swarm.py [--steps 100] [--runs 7]
        [--repeats 7]

1. ``sensorplan simulate --preset swarm --steps 100`` as a whole process (N = 100 sensors,
   M = 200 targets, the default ``pg``, K = 1, e = 1; its arrays and figure go to a
   temporary directory): wall and CPU time of the process, per step (process time / steps,
   so start-up and writing the results are included), and the median of the decisions'
   planning times (the planner's own clock, from the run's ``episode.timing.json``). Then
   the same run (same settings and seed) in this process, ``run_episode`` alone after a
   two-step warm-up run: the closed loop's own time per step, without start-up, the
   summary and the figure. Then that run's figure, ``episode.png`` as ``simulate`` draws it
   (the first figure of this process, so matplotlib's import is counted), and the figure
   of a paper-preset run of as many steps (5 targets, 3 sensors), drawn after it.
2. Cold start, from ``bench_startup.py``: ``sensorplan --help`` and the first plan,
   ``sensorplan plan examples/problem.json``, as whole processes (median of ``--runs``
   after one untimed run, kernel cache warm).
3. One ``pg`` decision at N = 20, M = 50, K = 10, from ``bench_scale.py`` (fresh process,
   median of ``--repeats`` after a warm-up decision).

Wall time and CPU time (user + sys of the child processes) are printed side by side: on a
shared machine wall time includes waiting for a core, CPU time does not.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_scale  # noqa: E402
import bench_startup  # noqa: E402


def swarm_run(steps: int) -> None:
    """Time ``sensorplan simulate --preset swarm --steps STEPS`` as one process."""
    with tempfile.TemporaryDirectory() as out:
        args = [sys.executable, "-m", "sensorplan", "simulate", "--preset", "swarm",
                "--steps", str(steps), "--out", out]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True, check=False)     # stderr: the progress lines
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(args[1:])} failed:\n{done.stderr}")
        seconds = json.loads((Path(out) / "episode.timing.json").read_text())[
            "planning_seconds"]
    print(f"## sensorplan simulate --preset swarm --steps {steps} (one process)")
    print("| process wall s | process CPU s | wall ms per step | CPU ms per step "
          "| decisions | planning median ms per decision [min, max] | planning share of wall |")
    print("|---|---|---|---|---|---|---|")
    print(f"| {wall:.1f} | {cpu:.1f} | {1e3 * wall / steps:.0f} | {1e3 * cpu / steps:.0f} "
          f"| {len(seconds)} | {1e3 * statistics.median(seconds):.0f} "
          f"[{1e3 * min(seconds):.0f}, {1e3 * max(seconds):.0f}] "
          f"| {sum(seconds) / wall:.0%} |", flush=True)

    from sensorplan.config.simulate import load_simulation
    from sensorplan.simulation import run_episode

    cfg = load_simulation(preset="swarm", overrides={"steps": steps})
    warm = load_simulation(preset="swarm", overrides={"steps": 2})
    run_episode(warm.scenario, warm.settings, warm.seed)         # imports, kernels, caches
    w0, c0 = time.perf_counter(), time.process_time()
    ep = run_episode(cfg.scenario, cfg.settings, cfg.seed)
    w, c = time.perf_counter() - w0, time.process_time() - c0
    plan = ep.planning_seconds
    print("\nThe same run in this process (run_episode only):")
    print("| wall s | CPU s | wall ms per step | CPU ms per step "
          "| planning median ms per decision | planning share of wall |")
    print("|---|---|---|---|---|---|")
    print(f"| {w:.1f} | {c:.1f} | {1e3 * w / steps:.0f} | {1e3 * c / steps:.0f} "
          f"| {1e3 * statistics.median(plan):.0f} | {plan.sum() / w:.0%} |", flush=True)
    figures(ep, cfg.scenario, steps)


def figures(episode: Any, scenario: Any, steps: int) -> None:
    """Wall and CPU time of ``episode.png`` of the swarm run (matplotlib's import included)
    and of a paper-preset run of ``steps`` steps."""
    from sensorplan.cli.guards import plot_drawable
    from sensorplan.config.simulate import load_simulation
    from sensorplan.simulation import run_episode

    paper = load_simulation(preset="paper", overrides={"steps": steps})
    cases = [("swarm (N = 100, M = 200), matplotlib's import included", episode, scenario),
             ("paper preset (N = 3, M = 5), same steps and seed",
              run_episode(paper.scenario, paper.settings, paper.seed), paper.scenario)]
    print(f"\nThe run's figure (episode.png, {steps} steps, as simulate draws it):")
    print("| figure | wall s | CPU s |\n|---|---|---|")
    with tempfile.TemporaryDirectory() as out:
        for label, ep, sc in cases:
            w0, c0 = time.perf_counter(), time.process_time()
            plot_drawable(ep, sc, Path(out) / "episode.png")
            w, c = time.perf_counter() - w0, time.process_time() - c0
            print(f"| {label} | {w:.2f} | {c:.2f} |", flush=True)


def cold_start(runs: int) -> None:
    """``sensorplan --help`` and the first plan, as whole processes."""
    cases = [c for c in bench_startup.CASES if c[0] in (
        "sensorplan --help", bench_startup.PLAN, bench_startup.PLAN_NUMBA)]
    print(f"\n## Cold start (median of {runs} processes, kernel cache warm)")
    print("| command | wall s | CPU s |\n|---|---|---|")
    for label, args, extra in cases:
        env = {**os.environ, **extra}
        if bench_startup.run_once(args, env) is None:          # untimed; fails loudly below
            raise SystemExit(f"{label} failed")
        times = [t for t in (bench_startup.run_once(args, env) for _ in range(runs)) if t]
        print(f"| {label} | {statistics.median(t[0] for t in times):.3f} "
              f"| {statistics.median(t[1] for t in times):.3f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100, help="steps of the swarm run")
    ap.add_argument("--runs", type=int, default=7, help="processes per cold-start case")
    ap.add_argument("--repeats", type=int, default=7, help="N = 20 decisions timed")
    args = ap.parse_args()
    print(f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}\n")
    swarm_run(args.steps)
    cold_start(args.runs)
    res = bench_scale.measure("scale", args.repeats)
    print(f"\n## One pg decision, N = 20, M = 50, K = 10 (median of {args.repeats})")
    print("| wall s | CPU s | CPU s (min) | max RSS MiB | sweeps |\n|---|---|---|---|---|")
    print(f"| {statistics.median(res['wall']):.3f} | {statistics.median(res['cpu']):.3f} "
          f"| {min(res['cpu']):.3f} | {res['rss']:.0f} | {res['sweeps']} |")


if __name__ == "__main__":
    main()
