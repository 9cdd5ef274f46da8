"""Benchmark: one PMB data association by loopy belief propagation (docs/benchmarks.md,
"PMB association by loopy belief propagation").

n Bernoulli tracks and m = n measurements, each track gating ``--per-track`` (3) random
measurements with PMB-like weights (existence, P_d, a whitened Gaussian likelihood, new
target plus clutter intensity), at n = 10 and n = 50. Times, as medians over every call
(``--problems`` problems, ``--repeats`` calls each, after an untimed call that compiles):

* ``association_lbp``: the library's call (checks, ratio form, compiled kernel);
* the dense numpy iteration of ``tests/pmb_reference.py`` (the same messages on ``(n, m)``
  arrays, the readable version);
* ``association_components`` (splitting the gating graph into clusters), for reference.

Target: the association of 10 x 10 well below 0.5 ms (a whole PMB update with 10
Bernoullis and 10 detections per look for 3 sensors within 2 ms). Prints a markdown table.

Run::

    PYTHONPATH=src .venv/bin/python benchmarks/bench_pmb_association.py [--problems 20]
        [--repeats 50] [--per-track 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sensorplan.tracking.pmb.association import association_components, association_lbp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from pmb_reference import lbp_dense  # noqa: E402  (the readable numpy iteration)

SIZES = (10, 50)
TARGET_10 = 0.5e-3


def problem(rng: np.random.Generator, n: int, per_track: int) -> tuple[np.ndarray, ...]:
    """``(w_miss (n,), w_det (n, n), w_new (n,))``: each track gates ``per_track``
    measurements."""
    gated = np.zeros((n, n), dtype=bool)
    for i in range(n):
        gated[i, rng.choice(n, size=per_track, replace=False)] = True
    r, pd = rng.uniform(0.05, 1.0, n), rng.uniform(0.5, 0.99, n)
    lik = np.exp(-0.5 * rng.uniform(0.0, 9.21, (n, n))) / (2.0 * np.pi)
    w_det = np.where(gated, (r * pd)[:, None] * lik, 0.0)
    return 1.0 - r * pd, w_det, rng.uniform(0.001, 0.05, n)


def median_seconds(fn: Callable[[], object], repeats: int) -> list[float]:
    """Seconds of ``repeats`` calls of ``fn`` after an untimed one."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--per-track", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print("| n x m | gated pairs | iterations (median) | association_lbp (numba) "
          "| dense numpy | numpy / numba | components |")
    print("|---|---|---|---|---|---|---|")
    medians = {}
    for n in SIZES:
        compiled, dense, parts, iterations = [], [], [], []
        for _ in range(args.problems):
            w = problem(rng, n, args.per_track)
            compiled += median_seconds(lambda w=w: association_lbp(*w), args.repeats)
            dense += median_seconds(lambda w=w: lbp_dense(*w), args.repeats)
            parts += median_seconds(lambda w=w: association_components(w[1]), args.repeats)
            iterations.append(association_lbp(*w).iterations)
        c, d, p = (statistics.median(t) for t in (compiled, dense, parts))
        medians[n] = c
        print(f"| {n} x {n} | {n * args.per_track} | {statistics.median(iterations):g} "
              f"| {c * 1e6:.1f} µs | {d * 1e6:.0f} µs | {d / c:.0f}x | {p * 1e6:.1f} µs |")
    ok = medians[10] <= TARGET_10
    print(f"\n10 x 10 target <= {TARGET_10 * 1e3:g} ms: {'met' if ok else 'NOT met'}")


if __name__ == "__main__":
    main()
