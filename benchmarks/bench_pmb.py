"""Benchmark: one PMB update with 10 Bernoullis and 10 detections per look, 3 radar looks,
beside one GNN update of the same step (docs/benchmarks.md, "One PMB update").

The paper's map (600 x 600 m, the default 25 m grid: 576 cells of undetected intensity with
``--undetected`` (2) expected undetected targets), three Swerling 1 radars at the paper's
altitudes looking at the middle of the map, 10 Bernoullis (existence uniform in [0.3, 1],
position standard deviations 5-20 m) scattered where the looks overlap, and each look's 10
detections: those of the Bernoullis in its sensing region (drawn from their densities, with
noise) and false alarms for the rest. The detections no Bernoulli explains start new
Bernoullis, which the next looks update too (about 23 by the end of the step). Each timed
call is :meth:`PMBTracker.update` on a fresh copy of the same tracker (the copies are made
before the clock starts). Prints the median and quartiles of the wall time per problem and
overall, the median CPU time (``time.thread_time``: other jobs share the machine), and with
``--profile`` ``cProfile``'s table over the same calls.

The GNN tracker (:class:`GNNTracker`, defaults) gets the same step: the 10 Bernoullis'
densities as 10 confirmed tracks and the same three looks; its unassigned detections start
tentative tracks. Its updates are timed the same way, interleaved problem by problem with
the PMB's, and the summary gives both medians and their ratio. With ``--imm`` the PMB
with two IMM modes in every Bernoulli (the known tracker's default modes, q 0.05 and 5)
gets the same step too, timed the same way, and the summary gives its ratio to the
single-model PMB; with ``--components R`` so does the PMB whose Bernoulli densities keep R
Gaussian components (``density_components``).

Target: the median update <= 2 ms.

Run::

    PYTHONPATH=src .venv/bin/python benchmarks/bench_pmb.py [--problems 10] [--repeats 50]
        [--seed 0] [--undetected 2.0] [--imm] [--components 2] [--profile]
"""

from __future__ import annotations

import argparse
import copy
import cProfile
import pstats
import statistics
import time

import numpy as np

from sensorplan.models import radar
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.base import Looks
from sensorplan.tracking.gnn import GNNTracker
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker

TARGET = 2e-3
N_BERNOULLI = 10
PER_LOOK = 10


def problem(rng: np.random.Generator, undetected: float = 2.0) -> tuple[PMBTracker, Looks]:
    """A tracker holding 10 Bernoullis (and ``undetected`` expected undetected targets) and
    one step's three looks of 10 detections each."""
    params = [SensorParams(altitude=a, clutter_rate=1.0, detection="swerling1")
              for a in (490.0, 500.0, 510.0)]
    table = radar_table(params)
    centre = np.array([300.0, 300.0])
    bearings = np.array([0.3, 2.4, 4.4]) + rng.uniform(-0.2, 0.2, 3)
    sensors = centre - 340.0 * np.column_stack([np.cos(bearings), np.sin(bearings)])
    heads = np.arctan2(centre[1] - sensors[:, 1], centre[0] - sensors[:, 0])
    means = np.zeros((N_BERNOULLI, 4))
    means[:, :2] = centre + rng.uniform(-60.0, 60.0, (N_BERNOULLI, 2))
    means[:, 2:] = rng.normal(0.0, 3.0, (N_BERNOULLI, 2))
    sd = rng.uniform(5.0, 20.0, (N_BERNOULLI, 2))
    covs = np.zeros((N_BERNOULLI, 4, 4))
    covs[:, 0, 0], covs[:, 1, 1] = sd[:, 0] ** 2, sd[:, 1] ** 2
    covs[:, 2, 2] = covs[:, 3, 3] = 4.0
    tracker = PMBTracker(MapModel(table, 1.0, (600.0, 600.0)), means=means, covs=covs,
                         existence=rng.uniform(0.3, 1.0, N_BERNOULLI), births="edges",
                         birth_rate=0.05, initial_undetected=undetected)
    dets = []
    for i in range(3):
        truth = means[:, :2] + sd * rng.standard_normal((N_BERNOULLI, 2))
        h, _, var, seen = radar.measure_looks(table, np.full(N_BERNOULLI, i), truth,
                                              np.broadcast_to(sensors[i], (N_BERNOULLI, 2)),
                                              np.full(N_BERNOULLI, heads[i]))
        z = (h + np.sqrt(var) * rng.standard_normal(h.shape))[seen][:PER_LOOK]
        fa = np.zeros((0, 2))
        while len(fa) < PER_LOOK - len(z):
            fa = np.concatenate([fa, radar.false_alarms(table, i, sensors[i], heads[i],
                                                         rng.random((PER_LOOK, 2)), None)])
        dets.append(np.concatenate([z, fa[:PER_LOOK - len(z)]]))
    looks = Looks(np.arange(3), np.full(3, -1), sensors, heads, tuple(dets))
    return tracker, looks


def variant_of(tracker: PMBTracker, **options: object) -> PMBTracker:
    """The same tracker (model, Bernoullis, undetected intensity) with ``options`` (IMM
    modes or mixture components, each at the Bernoulli's density)."""
    out = PMBTracker(tracker.model, means=tracker.bern.means, covs=tracker.bern.covs,
                     existence=tracker.bern.r, births=tracker.births,
                     **options)  # type: ignore[arg-type]
    out.undetected = tracker.undetected.copy()
    return out


def gnn_of(tracker: PMBTracker) -> GNNTracker:
    """The GNN tracker of the same sensors, map and motion holding the PMB's Bernoullis as
    confirmed tracks."""
    return GNNTracker(tracker.model, means=tracker.bern.means, covs=tracker.bern.covs)


def timed(trackers: list, looks: Looks) -> tuple[list[float], list[float]]:
    """Wall and CPU seconds of ``update(looks)`` on each of ``trackers`` (fresh copies)."""
    times, cpu = [], []
    for t in trackers:
        t0, c0 = time.perf_counter(), time.thread_time()
        t.update(looks)
        cpu.append(time.thread_time() - c0)
        times.append(time.perf_counter() - t0)
    return times, cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--problems", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--undetected", type=float, default=2.0,
                    help="expected undetected targets on the map (0: no Bernoulli is started)")
    ap.add_argument("--imm", action="store_true",
                    help="also time the PMB with two IMM modes in every Bernoulli")
    ap.add_argument("--components", type=int, default=0, metavar="R",
                    help="also time the PMB whose Bernoulli densities keep R Gaussian "
                         "components (2 to 8)")
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args(argv)
    if args.components and not 2 <= args.components <= 8:
        ap.error(f"--components must be 0 (off) or 2 to 8, got {args.components}")
    # The variants of the single-model PMB timed beside it: a name and their options.
    variants: list[tuple[str, dict[str, object]]] = []
    if args.imm:
        variants.append(("PMB with 2 IMM modes",
                         dict(mode_process_noise=(0.05, 5.0),
                              switching=np.array([[0.95, 0.05], [0.1, 0.9]]))))
    if args.components:
        variants.append((f"PMB with {args.components} mixture components",
                         dict(density_components=args.components)))
    rng = np.random.default_rng(args.seed)
    problems = [problem(rng, args.undetected) for _ in range(args.problems)]
    copy.deepcopy(problems[0][0]).update(problems[0][1])          # compile / load kernels
    gnns = [gnn_of(tracker) for tracker, _ in problems]
    copy.deepcopy(gnns[0]).update(problems[0][1])
    all_times: list[float] = []
    all_cpu: list[float] = []
    gnn_times: list[float] = []
    gnn_cpu: list[float] = []
    var_times: list[list[float]] = [[] for _ in variants]
    var_cpu: list[list[float]] = [[] for _ in variants]
    print("| problem | Bernoullis after | median | lower quartile | upper quartile | "
          "median CPU | GNN tracks after | GNN median | GNN median CPU |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k, (tracker, looks) in enumerate(problems):
        fresh = [copy.deepcopy(tracker) for _ in range(args.repeats + 1)]
        fresh[0].update(looks)
        times, cpu = timed(fresh[1:], looks)
        all_times += times
        all_cpu += cpu
        g_fresh = [copy.deepcopy(gnns[k]) for _ in range(args.repeats + 1)]
        g_fresh[0].update(looks)
        g_times, g_cpu = timed(g_fresh[1:], looks)
        gnn_times += g_times
        gnn_cpu += g_cpu
        for v, (_, options) in enumerate(variants):
            v_fresh = [variant_of(tracker, **options) for _ in range(args.repeats + 1)]
            v_fresh[0].update(looks)
            v_times, v_cpu = timed(v_fresh[1:], looks)
            var_times[v] += v_times
            var_cpu[v] += v_cpu
        q = statistics.quantiles(times, n=4)
        print(f"| {k} | {len(fresh[0].bern)} | {1e3 * statistics.median(times):.3f} ms | "
              f"{1e3 * q[0]:.3f} ms | {1e3 * q[2]:.3f} ms | "
              f"{1e3 * statistics.median(cpu):.3f} ms | {len(g_fresh[0].labels)} | "
              f"{1e3 * statistics.median(g_times):.3f} ms | "
              f"{1e3 * statistics.median(g_cpu):.3f} ms |")
    med = statistics.median(all_times)
    print(f"\nall: median {1e3 * med:.3f} ms wall, {1e3 * statistics.median(all_cpu):.3f} ms "
          f"CPU over {len(all_times)} updates (target {1e3 * TARGET:.1f} ms: "
          f"{'met' if med <= TARGET else 'NOT met'})")
    g_med, g_med_cpu = statistics.median(gnn_times), statistics.median(gnn_cpu)
    print(f"GNN: median {1e3 * g_med:.3f} ms wall, {1e3 * g_med_cpu:.3f} ms CPU over "
          f"{len(gnn_times)} updates; PMB / GNN: {med / g_med:.2f} wall, "
          f"{statistics.median(all_cpu) / g_med_cpu:.2f} CPU")
    for v, (name, _) in enumerate(variants):
        v_med, v_med_cpu = statistics.median(var_times[v]), statistics.median(var_cpu[v])
        print(f"{name}: median {1e3 * v_med:.3f} ms wall, {1e3 * v_med_cpu:.3f} ms CPU "
              f"over {len(var_times[v])} updates; / single: {v_med / med:.2f} wall, "
              f"{v_med_cpu / statistics.median(all_cpu):.2f} CPU")
    if args.profile:
        fresh = [(copy.deepcopy(t), lk) for t, lk in problems for _ in range(args.repeats)]
        prof = cProfile.Profile()
        prof.enable()
        for t, lk in fresh:
            t.update(lk)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
