"""Start-up time of the command line, as whole processes (median of N runs).

Measures ``import sensorplan``, ``sensorplan --help``, ``sensorplan --version`` and
``sensorplan plan examples/problem.json`` end to end with a warm kernel cache (one untimed
run first; it builds the ahead-of-time kernels if they are missing), the same plan with
numba's kernels (``SENSORPLAN_AOT=0``), plus the floors they stand on: the interpreter,
numpy, numba, and loading numba's compiler target with the cached kernels. Prints wall
time and CPU time (user + sys of the child): on a loaded machine wall time includes waiting
for a core, CPU time does not.

The children run as an installed package does: Python's bytecode caches (``__pycache__``)
are written by the untimed run and used after it. ``PYTHONDONTWRITEBYTECODE`` in the
caller's environment is left out of theirs (a note says so): with it every process
compiles this package's modules from source again, about 0.07 s more per process.
``--as-is`` keeps the environment unchanged.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_startup.py [--runs 15] [--src DIR ...]

``--src`` times other checkouts' ``src`` directories (before/after comparisons); their runs
alternate, so that a change in the machine's load affects them alike. A case a checkout
cannot run (an option it lacks) prints ``-``.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = ROOT / "examples" / "problem.json"

NUMBA_ONLY = {"SENSORPLAN_AOT": "0"}
PLAN = "sensorplan plan examples/problem.json"
PLAN_NUMBA = f"{PLAN} (numba's kernels)"
#: (label, arguments of python, extra environment)
CASES: list[tuple[str, list[str], dict[str, str]]] = [
    ("python -c pass", ["-c", "pass"], {}),
    ("import numpy", ["-c", "import numpy"], {}),
    ("import numba", ["-c", "import numba"], {}),
    ("numba target + cached kernels",
     ["-c", "from sensorplan.planners._chains_nb import warm_up; warm_up()"], NUMBA_ONLY),
    ("import sensorplan", ["-c", "import sensorplan"], {}),
    ("sensorplan --version", ["-m", "sensorplan", "--version"], {}),
    ("sensorplan --help", ["-m", "sensorplan", "--help"], {}),
    (PLAN, ["-m", "sensorplan", "plan", str(PROBLEM)], {}),
    (PLAN_NUMBA, ["-m", "sensorplan", "plan", str(PROBLEM)], NUMBA_ONLY),
]


def run_once(args: list[str], env: dict[str, str]) -> tuple[float, float] | None:
    """(wall, cpu) seconds of one child process; None if it failed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        return None
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15, help="processes per case")
    parser.add_argument("--src", type=Path, action="append",
                        help="a src directory to time (repeatable; default: this checkout's)")
    parser.add_argument("--as-is", action="store_true",
                        help="keep PYTHONDONTWRITEBYTECODE if set (default: children write "
                             "and use bytecode caches, as an installed package does)")
    opts = parser.parse_args()
    srcs = [s.resolve() for s in (opts.src or [ROOT / "src"])]
    base = dict(os.environ)
    if not opts.as_is and base.pop("PYTHONDONTWRITEBYTECODE", None) is not None:
        print("note: PYTHONDONTWRITEBYTECODE left out of the children's environment "
              "(bytecode caches written by the untimed run, then used); --as-is keeps it")
    envs = [{**base, "PYTHONPATH": str(s)} for s in srcs]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    for i, s in enumerate(srcs):
        print(f"[{i}] {s}")
    print(f"median of {opts.runs} processes per case; wall s / cpu s")
    print(f"{'case':40s}" + "".join(f"{f'[{i}] wall':>10s}{'cpu':>7s}" for i in range(len(srcs))))
    for label, args, extra in CASES:
        results: list[list[tuple[float, float]]] = [[] for _ in srcs]
        ok = [run_once(args, {**env, **extra}) is not None for env in envs]     # warm-up run
        for _ in range(opts.runs):
            for i, env in enumerate(envs):
                if ok[i]:
                    res = run_once(args, {**env, **extra})
                    if res is not None:
                        results[i].append(res)
        cells = []
        for times in results:
            if not times:
                cells.append(f"{'-':>10s}{'-':>7s}")
                continue
            wall = statistics.median(t[0] for t in times)
            cpu = statistics.median(t[1] for t in times)
            cells.append(f"{wall:10.3f}{cpu:7.3f}")
        print(f"{label:40s}" + "".join(cells), flush=True)


if __name__ == "__main__":
    main()
