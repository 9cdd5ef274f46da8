"""Study throughput (docs/benchmarks.md, 2 workers): the paper's three methods plus ``random``
over 100 runs in <= 3 minutes, the full ``studies/paper.toml`` in <= 10 minutes.

Runs each study from scratch into a temporary directory with the local process pool and
reports wall time and where it goes:

- planning: wall time inside the planners' calls, summed over decisions (from the tables);
- simulation: the rest of the tasks' time (truth, tracking, miss updates, building the
  planning problems, turning the episode into table columns);
- I/O: writing the per-(run, method) Parquet files and the final tables (main process);
- start-up and idle: the remainder of ``workers x wall`` (spawning and importing in the
  workers, the last tasks' tail, waiting on a busy machine).

Other jobs may share the machine, so CPU times are reported next to wall times: the tasks'
process CPU time (summed in the workers), the main process's CPU time and the CPU time of
all child processes (``getrusage(RUSAGE_CHILDREN)``, workers included once they exit).
Planning CPU is estimated as planning wall x (task CPU / task wall).

    .venv/bin/python benchmarks/bench_study.py [--runs 100] [--workers 2]
        [--only three|full|both] [--keep DIR] [--report]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import resource
import shutil
import tempfile
import time
from pathlib import Path

from sensorplan.study import Study, load_study, run_study

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "studies" / "paper.toml"
THREE = ("paper/myopic", "paper/ol", "paper/olf", "paper/random")
TARGETS = {"three": 180.0, "full": 600.0}


def _cpu() -> tuple[float, float]:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime


def bench(study: Study, label: str, workers: int, out: Path, report: bool) -> dict[str, float]:
    if out.exists():
        shutil.rmtree(out)
    load0 = os.getloadavg()[0]
    self0, kids0 = _cpu()
    start = time.perf_counter()
    res = run_study(study, out, workers=workers)
    wall = time.perf_counter() - start
    self1, kids1 = _cpu()
    t = res.timing
    task_wall, task_cpu = t["compute_wall_seconds"], t["compute_cpu_seconds"]
    planning = t["planning_seconds"]
    io = t["write_seconds"] + t["consolidate_seconds"]
    simulation = task_wall - planning
    idle = workers * wall - task_wall - io
    cpu_ratio = task_cpu / task_wall if task_wall > 0 else float("nan")
    pairs = res.total
    target = TARGETS.get(label)
    print(f"\n== {label}: {len(study.methods)} methods x {study.runs} runs x {study.steps} "
          f"steps = {pairs} (run, method) pairs, {workers} workers")
    print(f"   methods: {', '.join(study.method_names)}")
    verdict = "" if target is None else (f"  (target <= {target:.0f} s: "
                                         f"{'met' if wall <= target else 'NOT met'})")
    print(f"   wall time            {wall:8.1f} s{verdict}")
    print(f"   CPU time             {self1 - self0 + kids1 - kids0:8.1f} s  (main "
          f"{self1 - self0:.1f} s, child processes {kids1 - kids0:.1f} s; tasks "
          f"{task_cpu:.1f} s)")
    print(f"   load average (1 min) {load0:8.2f} before, {os.getloadavg()[0]:.2f} after")
    print("   where the workers' time goes (wall, summed over workers; share of "
          f"{workers} x wall):")
    total = workers * wall
    for name, v, cpu in (("planning", planning, planning * cpu_ratio),
                         ("simulation", simulation, simulation * cpu_ratio),
                         ("I/O (main process)", io, None),
                         ("start-up, tail, waiting", idle, None)):
        extra = "" if cpu is None else f"   ~{cpu:7.1f} s CPU"
        print(f"     {name:24s} {v:8.1f} s  {100 * v / total:5.1f} %{extra}")
    print(f"   per pair: {1e3 * task_wall / pairs:.0f} ms wall, {1e3 * task_cpu / pairs:.0f} ms "
          f"CPU (task CPU / wall = {cpu_ratio:.2f}; below 1 means the CPU was shared)")
    out_stats = {"wall": wall, "task_wall": task_wall, "task_cpu": task_cpu,
                 "planning": planning, "io": io}
    if report:
        from sensorplan.report import write_report

        r0 = time.perf_counter()
        write_report(out)
        out_stats["report"] = time.perf_counter() - r0
        print(f"   sensorplan report    {out_stats['report']:8.1f} s wall")
    return out_stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", choices=("three", "full", "both"), default="both")
    ap.add_argument("--keep", type=Path, default=None,
                    help="write the study directories under DIR (default: a temporary "
                         "directory, removed afterwards)")
    ap.add_argument("--report", action="store_true", help="also time sensorplan report")
    args = ap.parse_args()

    print(f"{platform.platform()}, {os.cpu_count()} CPUs, Python {platform.python_version()}")
    paper = load_study(PAPER)
    if args.runs != paper.runs:
        paper = dataclasses.replace(paper, runs=args.runs)
    three = dataclasses.replace(paper, methods=tuple(m for m in paper.methods
                                                     if m.name in THREE))
    base = args.keep or Path(tempfile.mkdtemp(prefix="bench_study_"))
    try:
        if args.only in ("three", "both"):
            bench(three, "three", args.workers, base / "three", args.report)
        if args.only in ("full", "both"):
            bench(paper, "full", args.workers, base / "full", args.report)
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
