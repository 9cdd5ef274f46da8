"""Benchmark: GOSPA over many steps, ours (sensorplan.study.set_metrics) against Stone Soup's.

The data: ``--targets`` targets per step, uniform on a 2 km square; a track per target
(position noise 10 m, 5 % of targets without a track) plus Poisson(2) false tracks per step,
in shuffled slots; cut-off c = 50 m, p = 2, alpha = 2.

(a) The first ``--ss-steps`` steps through Stone Soup's ``GOSPAMetric`` and through ours, in
one process, interleaved, the median of ``--repeats`` runs each. Stone Soup's path is its
per-step ``compute_gospa_metric(tracks, truths)`` (public; ``compute_over_time`` and
``compute_metric`` call it once per time stamp after sorting and grouping, so they are not
faster), with ``measure=Euclidean(mapping=(0, 2))`` on (x, vx, y, vy) states so that it
compares positions only. Its ``State`` objects are built before the timed region. Ours is
timed twice: :func:`gospa_over_time` on the padded arrays, and :func:`gospa` called step by
step. Both answers are checked to agree (relative 1e-9).

(b) The absolute time of :func:`gospa_over_time` on ``--steps`` steps of the same kind
(arrays built before the timed region), and of :func:`set_metrics` on the same steps as
long tables (one row per (step, target) and per (step, track)).

Run::

    PYTHONPATH=src .venv/bin/python benchmarks/bench_gospa.py [--steps 50000]
        [--targets 40] [--repeats 5] [--ss-steps 200] [--seed 2026]

Wall time (``time.perf_counter``) and CPU time (``time.process_time``) are both printed:
other processes share the machine's cores.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np

from sensorplan.study.set_metrics import gospa, gospa_over_time, set_metrics

C = 50.0
MAP = 2000.0
SIGMA = 10.0
P_NO_TRACK = 0.05
FALSE_RATE = 2.0


def make_steps(rng: np.random.Generator, steps: int, targets: int):
    """Padded truth and tracks: (S, n, 2), (S, n) bool, (S, m_max, 2), (S, m_max) bool."""
    truth = rng.uniform(0.0, MAP, (steps, targets, 2))
    alive = np.ones((steps, targets), dtype=bool)
    n_false = rng.poisson(FALSE_RATE, steps)
    tracks = np.concatenate([truth + rng.normal(0.0, SIGMA, truth.shape),
                             rng.uniform(0.0, MAP, (steps, int(n_false.max()), 2))], axis=1)
    present = np.concatenate([rng.random((steps, targets)) >= P_NO_TRACK,
                              np.arange(n_false.max()) < n_false[:, None]], axis=1)
    shuffle = np.argsort(rng.random(present.shape), axis=1)
    tracks = np.take_along_axis(tracks, shuffle[..., None], axis=1)
    present = np.take_along_axis(present, shuffle, axis=1)
    return truth, alive, tracks, present


def long_tables(truth, alive, tracks, present):
    """The padded steps as long tables (step, id, xy) and (step, label, xy)."""
    ts, ti = np.nonzero(alive)
    ys, yi = np.nonzero(present)
    return ts, ti, truth[ts, ti], ys, yi, tracks[ys, yi]


def stonesoup_steps(rng, truth, alive, tracks, present):
    """Per step: (track States, truth States), (x, vx, y, vy) with random velocities."""
    from stonesoup.types.state import State

    start = datetime.datetime(2026, 1, 1)
    out = []

    def states(xy, when):
        v = rng.normal(0.0, 10.0, (len(xy), 2))
        return [State(np.array([[x], [vx], [y], [vy]]), timestamp=when)
                for (x, y), (vx, vy) in zip(xy, v)]

    for s in range(len(truth)):
        when = start + datetime.timedelta(seconds=s)
        out.append((states(tracks[s][present[s]], when), states(truth[s][alive[s]], when)))
    return out


def timed(fn: Callable[[], object]) -> tuple[float, float, object]:
    """(wall s, cpu s, result) of one call."""
    wall, cpu = time.perf_counter(), time.process_time()
    result = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000, help="steps of part (b)")
    parser.add_argument("--targets", type=int, default=40, help="targets per step")
    parser.add_argument("--repeats", type=int, default=5, help="runs per timing (median)")
    parser.add_argument("--ss-steps", type=int, default=200,
                        help="steps of part (a), the comparison with Stone Soup")
    parser.add_argument("--seed", type=int, default=2026)
    opts = parser.parse_args()
    from stonesoup import __version__ as ss_version
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric

    rng = np.random.default_rng(opts.seed)
    data = make_steps(rng, opts.steps, opts.targets)
    few = tuple(a[:opts.ss_steps] for a in data)
    ss_data = stonesoup_steps(rng, *few)
    metric = GOSPAMetric(c=C, p=2, measure=Euclidean(mapping=(0, 2)))
    tables = long_tables(*data)
    n_tracks = data[3].sum(axis=1)
    print(f"date: {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC; "
          f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"numpy {np.__version__}, Stone Soup {ss_version}; load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"data: {opts.targets} targets per step, tracks per step mean "
          f"{n_tracks.mean():.1f} (min {n_tracks.min()}, max {n_tracks.max()}), c = {C} m, "
          f"p = 2, seed {opts.seed}")

    def run_stonesoup():
        return [metric.compute_gospa_metric(y, t)[0].value for y, t in ss_data]

    def run_batched():
        return gospa_over_time(*few, C)

    def run_per_step():
        return [gospa(t[a], y[p], C) for t, a, y, p in zip(*few)]

    cases = {"Stone Soup GOSPAMetric.compute_gospa_metric": run_stonesoup,
             "ours, gospa_over_time": run_batched, "ours, gospa() step by step": run_per_step}
    # One untimed run of each (warm-up), which also checks that the answers agree.
    theirs = np.array([v["distance"] for v in run_stonesoup()])
    mine = run_batched().distance
    one_by_one = np.array([g.distance for g in run_per_step()])
    worst = float(np.max(np.abs(mine - theirs) / np.maximum(theirs, 1e-300)))
    assert worst <= 1e-9 and np.array_equal(mine, one_by_one), worst
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in cases}
    for _ in range(opts.repeats):                           # interleaved
        for name, fn in cases.items():
            wall, cpu, _ = timed(fn)
            times[name].append((wall, cpu))
    wall_of = {k: statistics.median(t[0] for t in ts) for k, ts in times.items()}
    cpu_of = {k: statistics.median(t[1] for t in ts) for k, ts in times.items()}
    ss_wall = wall_of[next(iter(cases))]
    print(f"\n(a) {opts.ss_steps} steps, median of {opts.repeats} interleaved runs (after one "
          f"untimed run each); largest relative difference of the distances: {worst:.1e}\n")
    print("| path | wall s | CPU s | per step | Stone Soup / this |")
    print("|---|---:|---:|---:|---:|")
    for name in cases:
        print(f"| {name} | {wall_of[name]:.4f} | {cpu_of[name]:.4f} | "
              f"{wall_of[name] / opts.ss_steps * 1e6:,.1f} us | {ss_wall / wall_of[name]:,.0f}x |")

    big = {"gospa_over_time": lambda: gospa_over_time(*data, C),
           "set_metrics (long tables)": lambda: set_metrics(*tables, c=C)}
    big_times: dict[str, list[tuple[float, float]]] = {k: [] for k in big}
    for _ in range(opts.repeats):
        for name, fn in big.items():
            wall, cpu, _ = timed(fn)
            big_times[name].append((wall, cpu))
    print(f"\n(b) {opts.steps:,} steps x {opts.targets} targets x {n_tracks.mean():.1f} tracks, "
          f"median of {opts.repeats} runs\n")
    print("| ours | wall s | CPU s | per step |")
    print("|---|---:|---:|---:|")
    for name, ts in big_times.items():
        wall, cpu = statistics.median(t[0] for t in ts), statistics.median(t[1] for t in ts)
        print(f"| {name} | {wall:.3f} | {cpu:.3f} | {wall / opts.steps * 1e6:,.1f} us |")


if __name__ == "__main__":
    main()
