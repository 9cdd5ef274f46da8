"""Page faults of repeated decisions: glibc's defaults against the command line's settings.

    .venv/bin/python benchmarks/bench_memory.py [--rounds 3] [--decisions 3]

Each round runs three fresh processes, interleaved: glibc's defaults, the command line's
settings as environment variables (``sensorplan.memory.malloc_defaults``) and the library's
switch (``sensorplan.keep_freed_memory()``). Each plans one N = 10, M = 20, K = 4 decision
twice untimed, then counts the minor page faults of ``--decisions`` more. Prints every round
and the medians. How many faults glibc's defaults cause depends on the host and its load
(14,000 per N = 20 decision on one day, about 100 on a busy host on another), which is why
this is a benchmark and the test suite checks only that the settings take effect.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_scale import process_env  # noqa: E402

_CHILD = """
import resource, sys
sys.path.insert(0, {tests!r})
import sensorplan
if sys.argv[1] == "switch":
    sensorplan.keep_freed_memory()
from planner_reference import scale_problem
from sensorplan.planners import make_planner
problem = scale_problem(n_sensors=10, n_targets=20, horizon=4)
for _ in range(2):
    make_planner("pg").plan(problem)
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range({decisions}):
    make_planner("pg").plan(problem)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""

SETTINGS = {"defaults": "library", "environment": "cli", "switch": "library"}


def faults(how: str, decisions: int) -> int:
    """Minor page faults of ``decisions`` decisions in a fresh process set up as ``how``."""
    code = _CHILD.format(tests=str(ROOT / "tests"), decisions=decisions)
    out = subprocess.run([sys.executable, "-c", code, how], capture_output=True, text=True,
                         check=True, env=process_env(SETTINGS[how]))
    return int(out.stdout.split()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--decisions", type=int, default=3)
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.decisions < 1:
        parser.error("--rounds and --decisions must be at least 1")
    counts: dict[str, list[int]] = {how: [] for how in SETTINGS}
    print(f"| round | {' | '.join(SETTINGS)} |")
    for r in range(args.rounds):
        for how in SETTINGS:
            counts[how].append(faults(how, args.decisions))
        print(f"| {r + 1} | {' | '.join(str(counts[h][-1]) for h in SETTINGS)} |", flush=True)
    med = {h: statistics.median(c) for h, c in counts.items()}
    print(f"| median | {' | '.join(f'{med[h]:.0f}' for h in SETTINGS)} |")
    print("faults per decision, median: " + ", ".join(
        f"{h} {med[h] / args.decisions:.0f}" for h in SETTINGS))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
