"""Speed against an earlier version of this repository, on the same machine at the same time.

One ``pg`` decision at N = 20 sensors, M = 50 targets, K = 10 (the scale case of
``bench_scale.py``), timed in this checkout and in ``src/`` of an earlier revision,
interleaved: each round runs one process per version (which goes first alternates), each
making ``--decisions`` timed decisions after an untimed one; a process's figure is its
median. Prints every round, the medians and the ratio earlier / this per round.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_against.py [--rev 92b58f2] [--rounds 6]
        [--decisions 7] [--settings cli|library]

Why a ratio: this machine's speed moves by 30-50 % from hour to hour and from day to day (the
code that took 0.93 s on 2026-11-23 took 1.4-1.6 s on 2026-12-02), so an absolute time set
on one day cannot be checked on another; a ratio measured in interleaved rounds can.

The default revision, ``92b58f2``, is the code the "0.93 s" figure (and the 4x target
set from it) was measured with. Both versions get the same environment: by default with the
command line's process settings (numpy without huge pages, glibc keeping freed memory;
``--settings library`` leaves numpy's and glibc's defaults, as in a library user's process); this
checkout uses its threads (``SENSORPLAN_THREADS``), the earlier code has none. The earlier
code's kernels are compiled by numba in the first, untimed process (10 s here); its
source is unpacked with ``git archive`` into a temporary directory that is removed at the end
(also on Ctrl-C). The two versions must return the same plan (positions and targets to the
bit; Phi may differ in its last digits where its own computation changed); otherwise the
script says so and exits with status 1.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The code the target's baseline (0.93 s, 2026-11-23) was measured with.
BASELINE_REV = "92b58f2"

# Only the API both versions share: the scale case of bench_planning.py as of the baseline,
# with the objective it had then by default (named: the default has since changed).
_CHILD = """
import hashlib, json, math, sys, time
import numpy as np
from sensorplan.planners import make_planner
from sensorplan.planners.problem import MapRect, PlanningProblem
from sensorplan.models.sensors import SensorParams
rng = np.random.default_rng(0)
N, M, K, W = 20, 50, 10, 2000.0
means = np.c_[rng.uniform(100, W - 100, (M, 2)), rng.normal(0, 3, (M, 2))]
covs = np.tile(np.diag([400.0, 400.0, 4.0, 4.0]), (M, 1, 1))
sensors = tuple(SensorParams(altitude=490.0 + 10.0 * (i % 3)) for i in range(N))
problem = PlanningProblem(means, covs, rng.uniform(50, W - 50, (N, 2)),
                          rng.uniform(-math.pi, math.pi, N), sensors, horizon=K,
                          world=MapRect(W, W), objective="terminal")
r = make_planner("pg").plan(problem)
wall, cpu = [], []
for _ in range({decisions}):
    t, c = time.perf_counter(), time.process_time()
    r = make_planner("pg").plan(problem)
    wall.append(time.perf_counter() - t)
    cpu.append(time.process_time() - c)
plan = hashlib.sha256(np.ascontiguousarray(r.plan.positions).tobytes()
                      + np.ascontiguousarray(r.plan.targets, np.int64).tobytes()).hexdigest()[:16]
print(json.dumps(dict(wall=wall, cpu=cpu, phi=float(r.potential), plan=plan)))
"""


def process_env(settings: str) -> dict[str, str]:
    """:func:`bench_scale.process_env` (a library user's process or the command line's), with
    bytecode caches written and used as an installed package's are."""
    sys.path.insert(0, str(ROOT / "src"))
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_scale

    env = bench_scale.process_env(settings)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def unpack(rev: str, into: Path) -> Path:
    """``src/`` of ``rev`` under ``into``; SystemExit(2) naming the revision if git cannot."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "src"],
                             capture_output=True)
    if archive.returncode != 0:
        print(f"error: --rev {rev!r} is not a revision of this repository with a src/ "
              f"directory ({archive.stderr.decode().strip() or 'git archive failed'})",
              file=sys.stderr)
        raise SystemExit(2)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive.stdout, check=True)
    return into / "src"


def run(src: Path, env: dict[str, str], decisions: int) -> dict:
    """One process of ``decisions`` timed decisions with ``src`` first on the path."""
    done = subprocess.run([sys.executable, "-c", _CHILD.format(decisions=decisions)],
                          env={**env, "PYTHONPATH": str(src)}, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"error: the decision failed with {src}:\n{done.stderr[-2000:]}", file=sys.stderr)
        raise SystemExit(1)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", default=BASELINE_REV,
                        help=f"the earlier revision (default {BASELINE_REV}, the target's "
                             "baseline)")
    parser.add_argument("--rounds", type=int, default=6, help="interleaved rounds (>= 1)")
    parser.add_argument("--decisions", type=int, default=7,
                        help="timed decisions per process (>= 1)")
    parser.add_argument("--settings", choices=("cli", "library"), default="cli",
                        help="both processes' numpy and allocator settings: as the command "
                             "line sets them (default) or a library user's defaults")
    opts = parser.parse_args()
    for name in ("rounds", "decisions"):
        if getattr(opts, name) < 1:
            parser.error(f"--{name} must be at least 1, got {getattr(opts, name)}")
    env = process_env(opts.settings)
    with tempfile.TemporaryDirectory(prefix="sensorplan-against-") as tmp:
        srcs = {"earlier": unpack(opts.rev, Path(tmp)), "this": ROOT / "src"}
        print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}, load average "
              f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
        print(f"earlier = {opts.rev}, this = {ROOT}; N = 20, M = 50, K = 10; "
              f"{opts.decisions} decisions per process, median; {opts.settings} settings")
        print("warming up (the earlier code's kernels compile in its first process) ...",
              flush=True)
        first = {v: run(s, env, 1) for v, s in srcs.items()}
        phi = (first["earlier"]["phi"], first["this"]["phi"])
        if first["earlier"]["plan"] != first["this"]["plan"]:
            print(f"error: the versions return different plans (Phi {phi[0]!r} and "
                  f"{phi[1]!r}): not the same computation", file=sys.stderr)
            raise SystemExit(1)
        print(f"same plan from both (positions and targets to the bit; Phi {phi[0]!r} and "
              f"{phi[1]!r}, as each version computes it)")
        print("| round | earlier wall s | this wall s | this CPU s | earlier / this |")
        print("|---|---|---|---|---|")
        rows = []
        for r in range(1, opts.rounds + 1):
            order = ("earlier", "this") if r % 2 else ("this", "earlier")
            res = {v: run(srcs[v], env, opts.decisions) for v in order}
            old = statistics.median(res["earlier"]["wall"])
            new = statistics.median(res["this"]["wall"])
            cpu = statistics.median(res["this"]["cpu"])
            rows.append((old, new, cpu, old / new))
            print(f"| {r} | {old:.3f} | {new:.3f} | {cpu:.3f} | {old / new:.2f} |", flush=True)
        med = [statistics.median(x) for x in zip(*rows)]
        ratios = [x[3] for x in rows]
        print(f"| median | {med[0]:.3f} | {med[1]:.3f} | {med[2]:.3f} | **{med[3]:.2f}** "
              f"(range {min(ratios):.2f}-{max(ratios):.2f}) |")


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:         # the running child is killed, the temporary copy removed
        print("error: interrupted", file=sys.stderr)
        raise SystemExit(130) from None
