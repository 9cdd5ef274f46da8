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

After the table, the plan and its floor ``python -c "import numpy"`` are timed again,
interleaved (numpy, plan, numpy, plan, ...), and the ratio of their medians is printed
against the target of 5x: a change in the machine's load shifts both alike
(``--ratio-only``: this part alone).

``--fresh-clone DIR`` measures a newcomer's start instead: it clones this repository's
committed ``HEAD`` into ``DIR`` (which must not exist; put it under /tmp), runs the
Makefile's set-up there (``make .venv/.installed-stamp``: a venv in ``DIR/.venv``, the
install, ``sensorplan compile``), and times the clone's first ``sensorplan plan
examples/problem.json`` and the next ones, each a whole process, against the target of
2 s for the first.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_startup.py --fresh-clone /tmp/sp-clone
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
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


#: The targets: a warm plan within this many times ``import numpy``; a fresh clone's first
#: plan after ``make`` within this many seconds.
RATIO_TARGET = 5.0
FRESH_TARGET = 2.0


def interleaved(env: dict[str, str], runs: int) -> None:
    """Time ``import numpy`` and the plan alternately; print medians and their ratio."""
    numpy_args = ["-c", "import numpy"]
    plan_args = ["-m", "sensorplan", "plan", str(PROBLEM)]
    for args in (numpy_args, plan_args):                      # untimed: caches written
        run_once(args, env)
    times: dict[str, list[tuple[float, float]]] = {"numpy": [], "plan": []}
    for _ in range(runs):
        for key, args in (("numpy", numpy_args), ("plan", plan_args)):
            res = run_once(args, env)
            if res is None:
                print(f"interleaved: {key} failed")
                return
            times[key].append(res)
    for i, what in ((0, "wall"), (1, "cpu")):
        numpy_s, plan_s = (statistics.median(t[i] for t in times[k]) for k in ("numpy", "plan"))
        ratio = plan_s / numpy_s
        print(f"interleaved, {runs} pairs, {what} medians: import numpy {numpy_s:.3f} s, "
              f"{PLAN} {plan_s:.3f} s; ratio {ratio:.2f}x, target <= {RATIO_TARGET:g}x: "
              f"{'met' if ratio <= RATIO_TARGET else 'NOT met'}")


def fresh_clone(dest: Path, runs: int) -> None:
    """Clone HEAD into ``dest``, set it up with the Makefile, time its first plans."""
    if dest.exists():
        sys.exit(f"error: --fresh-clone: {dest} exists; give a new directory")
    py = shutil.which("python3.11") or sys.executable
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}; python for the venv: {py}")
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(dest)],
                   check=True)
    head = subprocess.run(["git", "-C", str(dest), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "SENSORPLAN_AOT", "VIRTUAL_ENV",
                        "PYTHONDONTWRITEBYTECODE")}
    start = time.perf_counter()
    subprocess.run(["make", "-C", str(dest), f"PY={py}", ".venv/.installed-stamp"], env=env,
                   check=True)
    print(f"clone of {head}: make's set-up (venv, install, sensorplan compile) "
          f"{time.perf_counter() - start:.1f} s")
    sensorplan = [str(dest / ".venv" / "bin" / "sensorplan"), "plan", "examples/problem.json"]
    walls = []
    for i in range(1 + runs):
        t0 = time.perf_counter()
        done = subprocess.run(sensorplan, cwd=dest, env=env, capture_output=True, text=True)
        walls.append(time.perf_counter() - t0)
        if done.returncode != 0:
            sys.exit(f"plan {i + 1} failed: {done.stderr.strip()}")
        if i == 0:
            said = done.stderr.strip()
            print(f"first plan: {walls[0]:.3f} s wall, target < {FRESH_TARGET:g} s: "
                  f"{'met' if walls[0] < FRESH_TARGET else 'NOT met'}"
                  + (f"; it said: {said}" if said else "; nothing on stderr"))
    if runs:
        print(f"the next {runs} plans: median {statistics.median(walls[1:]):.3f} s, "
              f"{min(walls[1:]):.3f}-{max(walls[1:]):.3f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15, help="processes per case")
    parser.add_argument("--src", type=Path, action="append",
                        help="a src directory to time (repeatable; default: this checkout's)")
    parser.add_argument("--as-is", action="store_true",
                        help="keep PYTHONDONTWRITEBYTECODE if set (default: children write "
                             "and use bytecode caches, as an installed package does)")
    parser.add_argument("--fresh-clone", type=Path, metavar="DIR",
                        help="clone HEAD into DIR, run make's set-up there and time its "
                             "first plans (nothing else)")
    parser.add_argument("--ratio-only", action="store_true",
                        help="only the interleaved plan / import numpy ratio")
    opts = parser.parse_args()
    if opts.fresh_clone is not None:
        fresh_clone(opts.fresh_clone.resolve(), min(opts.runs, 5))
        return
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
    if opts.ratio_only:
        interleaved(envs[-1], opts.runs)
        return
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
    interleaved(envs[-1], opts.runs)


if __name__ == "__main__":
    main()
