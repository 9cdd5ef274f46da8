"""Peer comparison: sensorplan's trackers against Stone Soup's on the same detections.

For each run of a filter benchmark (``williams15`` or ``vo12``: scripted truth,
:mod:`sensorplan.models.scripted`; linear position sensor, :mod:`sensorplan.models.linear`)
the detections are drawn once, from the run's generator (``SeedSequence(seed).spawn(runs)``),
and every configuration of the study file tracks the same detections: sensorplan's ``pmb``
(and ``gnn`` when that tracker kind is registered), Stone Soup's GM-PHD filter and Stone
Soup's JPDA tracker (``sensorplan.integrations.stonesoup._peers``). The study file
(``studies/trackers/peers.toml``, ``studies/trackers/peers2.toml``) fixes the
configurations, run count, seeds, the JPDA data associator of each benchmark (its
``[jpda_associator]`` table: ``JPDA``, the default, or ``JPDAwithLBP``) and the decision
rule before any run.

Runs are done one run index at a time: run ``r`` of every configuration before run
``r + 1`` of any, so the runs complete at any moment are a prefix ``0..n-1``, a paired
sample. Until all of the study's runs are complete the summary is an interim look: it prints
no verdict.

Per run and configuration the CSV gets the mean over steps of GOSPA (p = 2, alpha = 2, the
benchmark's cut-off) and of its localisation, missed and false parts (m^2), and the median
and mean seconds per step (predict and update; the same process runs every configuration,
one after another). The CSV is resumable: configurations already written for a run are
skipped, so a stopped study continues with the same command. ``--stop-at HH:MM`` (UTC)
starts no run index at or after the next time the clock reads it; SIGINT or SIGTERM stops at
once, keeping every row already written (the interrupted tracker's row of that run is redone
on resuming). The summary prints, per configuration: mean GOSPA with a 95 % t-interval,
median, the paired difference to ``pmb`` with its 95 % t-interval, median seconds per step
and the ratio to ``pmb``'s, and the decision rule's verdicts.

Run::

    nice .venv/bin/python benchmarks/compare_trackers.py --benchmark williams15 \\
        --study studies/trackers/peers.toml --out out/peers/williams15.csv [--runs N]
        [--stop-at HH:MM] [--summary-only]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import math
import signal
import sys
import time
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from sensorplan.integrations.stonesoup._peers import (JPDA_ASSOCIATORS, BenchmarkModel,
                                                       benchmark_model, gmphd_tracker,
                                                       jpda_deleter, jpda_tracker, positions,
                                                       to_detections)
from sensorplan.integrations.stonesoup._pmb import gaussian_cell_masses
from sensorplan.models import linear
from sensorplan.models.scripted import scripted_truth
from sensorplan.study.set_metrics import gospa_over_time
from sensorplan.tracking.base import Looks
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from sensorplan.tracking.registry import TRACKERS, tracker_class

FIELDS = ["benchmark", "run", "config", "mean_gospa", "localisation", "missed", "false",
          "step_seconds_median", "step_seconds_mean", "steps"]
T0 = datetime.datetime(2026, 1, 1)


def fail(field: str, message: str) -> None:
    print(f"error: {field}: {message}", file=sys.stderr)
    raise SystemExit(2)


# ------------------------------------------------------------------------------ one run's data
def draw_run(name: str, rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The truth's live positions and one scan's detections at each step ``1..S``."""
    truth = scripted_truth(name)
    sensor = benchmark_model(name).sensor
    xs, zs = [], []
    for _ in range(truth.steps):
        states, alive = truth.step()
        xy = states[alive, :2]
        z, _ = linear.scan(sensor, xy, rng)
        xs.append(xy)
        zs.append(z)
    return xs, zs


def gospa_parts(truth: list[np.ndarray], tracks: list[np.ndarray], c: float) -> np.ndarray:
    """Mean over steps of GOSPA and its localisation, missed and false parts, ``(4,)``."""
    S = len(truth)
    n = max(1, max(len(x) for x in truth))
    m = max(1, max(len(y) for y in tracks))
    T = np.zeros((S, n, 2))
    A = np.zeros((S, n), bool)
    Y = np.zeros((S, m, 2))
    P = np.zeros((S, m), bool)
    for s in range(S):
        T[s, :len(truth[s])], A[s, :len(truth[s])] = truth[s], True
        Y[s, :len(tracks[s])], P[s, :len(tracks[s])] = tracks[s], True
    g = gospa_over_time(T, A, Y, P, c)
    return np.array([g.distance.mean(), g.localisation.mean(), g.missed.mean(),
                     g.false.mean()])


# ------------------------------------------------------------------------------ the trackers
StepFn = Callable[[int, np.ndarray], dict[str, np.ndarray]]


def pmb_runner(model: BenchmarkModel, cfg: dict[str, Any]) -> StepFn:
    """One step of sensorplan's PMB tracker: predict, update with the scan, report."""
    res = float(cfg.get("resolution", 25.0))
    birth = gaussian_cell_masses(model.world, res, model.birth_means[:, :2],
                                 np.sqrt(model.birth_covs[:, [0, 1], [0, 1]]),
                                 model.birth_weights)
    tr = PMBTracker(MapModel(model.sensor, model.dt, (model.world.width, model.world.height),
                             motion=(model.F, model.Q), resolution=res,
                             velocity_var=model.velocity_var),
                    survival_probability=model.survival, births=birth)
    tr.undetected = gaussian_cell_masses(model.world, res, model.birth_means[:, :2],
                                         np.sqrt(model.birth_covs[:, [0, 1], [0, 1]]),
                                         model.initial_weights)
    return sensorplan_steps(tr, cfg["name"])


def gnn_runner(model: BenchmarkModel, cfg: dict[str, Any]) -> StepFn:
    """sensorplan's GNN tracker with its defaults and the benchmark's sensor and motion."""
    cls = tracker_class("gnn")
    tr = cls(MapModel(model.sensor, model.dt, (model.world.width, model.world.height),
                      motion=(model.F, model.Q)))
    return sensorplan_steps(tr, cfg["name"])


def sensorplan_steps(tr: Any, name: str) -> StepFn:
    one = (np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64), np.zeros((1, 2)),
           np.zeros(1))

    def step(k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        tr.predict()
        tr.update(Looks(*one, (z,)))
        return {name: np.array(tr.tracks().means[:, :2])}
    return step


def gmphd_runner(model: BenchmarkModel, cfgs: list[dict[str, Any]]) -> StepFn:
    """Stone Soup's GM-PHD filter; every state threshold of ``cfgs`` reads the same run."""
    tr = gmphd_tracker(model, T0)
    mm = model.measurement_model

    def step(k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        now = T0 + datetime.timedelta(seconds=k * model.dt)
        tr.update_tracker(now, to_detections(z, now, mm))
        return {c["name"]: positions(tr.reported(float(c["state_threshold"]))) for c in cfgs}
    return step


def jpda_runner(model: BenchmarkModel, cfg: dict[str, Any]) -> StepFn:
    """Stone Soup's JPDA tracker with the configuration's confirmation, deleter and data
    associator."""
    tr = jpda_tracker(model, int(cfg["min_points"]), jpda_deleter(cfg["deleter"], model), T0,
                      associator=cfg.get("associator", "JPDA"))
    mm = model.measurement_model

    def step(k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        now = T0 + datetime.timedelta(seconds=k * model.dt)
        _, tracks = tr.update_tracker(now, to_detections(z, now, mm))
        return {cfg["name"]: positions(t.state for t in tracks)}
    return step


def groups(configs: list[dict[str, Any]]) -> list[tuple[str, list[dict[str, Any]]]]:
    """The tracker runs of a run: one per configuration, except that GM-PHD configurations
    (which differ only in the state threshold) share one filter run."""
    out: list[tuple[str, list[dict[str, Any]]]] = []
    phd = [c for c in configs if c["kind"] == "gmphd"]
    for c in configs:
        if c["kind"] == "gmphd":
            if c is phd[0]:
                out.append(("gmphd", phd))
        else:
            out.append((c["kind"], [c]))
    return out


class TimedOut(Exception):
    """A tracker run reached the study's wall-time limit."""


def _time_out(signum: int, frame: object) -> None:
    raise TimedOut


def run_group(kind: str, cfgs: list[dict[str, Any]], model: BenchmarkModel,
              zs: list[np.ndarray], limit: float | None = None
              ) -> tuple[dict[str, list[np.ndarray]], np.ndarray]:
    """Run one tracker over a run's detections; raises :class:`TimedOut` once ``limit``
    seconds of wall time have passed (``None``: no limit)."""
    if limit is None:
        return _run_group(kind, cfgs, model, zs)
    # An interval timer, because the trackers that stall (Stone Soup's exhaustive JPDA)
    # spend their time in Python, where the alarm's exception is raised.
    previous = signal.signal(signal.SIGALRM, _time_out)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        return _run_group(kind, cfgs, model, zs)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _run_group(kind: str, cfgs: list[dict[str, Any]], model: BenchmarkModel,
               zs: list[np.ndarray]) -> tuple[dict[str, list[np.ndarray]], np.ndarray]:
    if kind == "pmb":
        step = pmb_runner(model, cfgs[0])
    elif kind == "gnn":
        step = gnn_runner(model, cfgs[0])
    elif kind == "gmphd":
        step = gmphd_runner(model, cfgs)
    else:
        step = jpda_runner(model, cfgs[0])
    out: dict[str, list[np.ndarray]] = {c["name"]: [] for c in cfgs}
    seconds = np.empty(len(zs))
    for k, z in enumerate(zs):
        t = time.perf_counter()
        reported = step(k + 1, z)
        seconds[k] = time.perf_counter() - t
        for name, xy in reported.items():
            out[name].append(xy)
    return out, seconds


# ------------------------------------------------------------------------------ the study
def load(study: Path, benchmark: str) -> dict[str, Any]:
    try:
        spec = tomllib.loads(study.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        fail("--study", str(exc))
    spec["configs"] = [c for c in spec["configs"]
                       if c["kind"] != "gnn" or "gnn" in TRACKERS]
    spec["seed"] = int(spec["seeds"][benchmark])
    associator = spec.get("jpda_associator", {}).get(benchmark, "JPDA")
    if associator not in JPDA_ASSOCIATORS:
        fail(f"jpda_associator.{benchmark}",
             f"must be one of {', '.join(sorted(JPDA_ASSOCIATORS))}, got {associator!r}")
    for c in spec["configs"]:
        if c["kind"] == "jpda":
            c["associator"] = associator
    return spec


def done_runs(path: Path, benchmark: str) -> dict[int, set[str]]:
    """The configurations already written for each run of ``benchmark``."""
    have: dict[int, set[str]] = {}
    if path.exists():
        with path.open() as f:
            for row in csv.DictReader(f):
                if row["benchmark"] == benchmark:
                    have.setdefault(int(row["run"]), set()).add(row["config"])
    return have


def run_study(spec: dict[str, Any], benchmark: str, runs: int, out: Path,
              stop_at: datetime.datetime | None = None) -> None:
    model = benchmark_model(benchmark)
    c = float(spec["gospa"][benchmark])
    configs = spec["configs"]
    limit = spec.get("time_limit", {}).get("seconds_per_run")
    limit = None if limit is None else float(limit)
    seeds = np.random.SeedSequence(spec["seed"]).spawn(int(spec["runs"]))
    if runs > len(seeds):
        fail("--runs", f"at most the study's {len(seeds)} runs")
    have = done_runs(out, benchmark)
    out.parent.mkdir(parents=True, exist_ok=True)
    new = not out.exists()
    with out.open("a", newline="") as f:
        writer = csv.DictWriter(f, FIELDS)
        if new:
            writer.writeheader()
        for r in range(runs):
            missing = [cf for cf in configs if cf["name"] not in have.get(r, set())]
            if not missing:
                continue
            if stop_at is not None and datetime.datetime.now(datetime.UTC) >= stop_at:
                print(f"{benchmark}: stop time reached before run {r}; the same command "
                      "resumes", flush=True)
                return
            t_run = time.perf_counter()
            truth, zs = draw_run(benchmark, np.random.default_rng(seeds[r]))
            for kind, cfgs in groups(missing):
                t_group = time.perf_counter()
                try:
                    tracks, seconds = run_group(kind, cfgs, model, zs, limit)
                except TimedOut:
                    elapsed = time.perf_counter() - t_group
                    for cf in cfgs:
                        writer.writerow({"benchmark": benchmark, "run": r, "config": cf["name"],
                                         "mean_gospa": "nan", "localisation": "nan",
                                         "missed": "nan", "false": "nan",
                                         "step_seconds_median": "nan",
                                         "step_seconds_mean": repr(elapsed / len(zs)),
                                         "steps": len(zs)})
                    f.flush()
                    print(f"  {'/'.join(cf['name'] for cf in cfgs)}: timed out after "
                          f"{elapsed:.0f} s (limit {limit:.0f} s)", flush=True)
                    continue
                for cf in cfgs:
                    g = gospa_parts(truth, tracks[cf["name"]], c)
                    writer.writerow({"benchmark": benchmark, "run": r, "config": cf["name"],
                                     "mean_gospa": repr(float(g[0])),
                                     "localisation": repr(float(g[1])),
                                     "missed": repr(float(g[2])),
                                     "false": repr(float(g[3])),
                                     "step_seconds_median": repr(float(np.median(seconds))),
                                     "step_seconds_mean": repr(float(seconds.mean())),
                                     "steps": len(zs)})
                # Each tracker's rows reach the file as soon as it finishes: a stop loses at
                # most the tracker that was running.
                f.flush()
                print(f"  {'/'.join(cf['name'] for cf in cfgs)}: "
                      f"{time.perf_counter() - t_group:.1f} s, "
                      f"{float(np.mean(seconds)):.4f} s/step mean", flush=True)
            print(f"{benchmark} run {r}: {time.perf_counter() - t_run:.1f} s", flush=True)


def t_interval(x: np.ndarray) -> tuple[float, float, float]:
    m = float(np.mean(x))
    if len(x) < 2:
        return m, math.nan, math.nan
    h = float(stats.t.ppf(0.975, len(x) - 1) * np.std(x, ddof=1) / math.sqrt(len(x)))
    return m, m - h, m + h


def summary(out: Path, benchmark: str, runs: int, configs: list[dict[str, Any]],
            declared: int | None = None) -> None:
    """Print the table of the complete runs among the first ``runs``, and the decision
    rule's verdicts only when all ``declared`` runs (default ``runs``) are complete."""
    rows: dict[str, dict[int, dict[str, float]]] = {}
    with out.open() as f:
        for row in csv.DictReader(f):
            if row["benchmark"] == benchmark and int(row["run"]) < runs:
                rows.setdefault(row["config"], {})[int(row["run"])] = {
                    k: float(row[k]) for k in FIELDS[3:]}
    names = [c["name"] for c in configs if c["name"] in rows]
    common = sorted(set.intersection(*(set(rows[n]) for n in names)))
    if not common:
        print("no complete runs yet")
        return

    def col(name: str, key: str) -> np.ndarray:
        return np.array([rows[name][r][key] for r in common])

    def finished(name: str) -> np.ndarray:
        """Which common runs the configuration finished (a timed-out run has NaN GOSPA)."""
        return np.isfinite(col(name, "mean_gospa"))

    def paired(name: str) -> tuple[np.ndarray, np.ndarray]:
        """pmb's and the configuration's mean GOSPA on the runs both finished."""
        ok = finished(name) & finished("pmb")
        return col("pmb", "mean_gospa")[ok], col(name, "mean_gospa")[ok]

    base_t = float(np.nanmedian(col("pmb", "step_seconds_median")))
    declared = runs if declared is None else declared
    interim = len(common) < declared
    print(f"\n{benchmark}: {len(common)} paired runs"
          + (f" (interim look: runs 0..{len(common) - 1} of the declared {declared})"
             if interim else "") + ", GOSPA p = 2, alpha = 2 (m)")
    head = (f"{'config':<18} {'mean GOSPA [95% CI]':>24} {'median':>7} "
            f"{'loc':>7} {'missed':>7} {'false':>7} {'diff vs pmb [95% CI]':>26} "
            f"{'s/step':>8} {'x pmb':>6} {'timed out':>9}")
    print(head)
    for n in names:
        ok = finished(n)
        g = col(n, "mean_gospa")[ok]
        m, lo, hi = t_interval(g)
        pb, pc = paired(n)
        d, dlo, dhi = t_interval(pb - pc)
        t = float(np.median(col(n, "step_seconds_median")[ok]))
        parts = [float(np.mean(col(n, k)[ok])) for k in ("localisation", "missed", "false")]
        diff = "" if n == "pmb" else f"{d:+8.3f} [{dlo:+.3f}, {dhi:+.3f}]"
        print(f"{n:<18} {m:8.3f} [{lo:7.3f}, {hi:7.3f}] {float(np.median(g)):7.3f} "
              f"{parts[0]:7.2f} {parts[1]:7.2f} {parts[2]:7.2f} {diff:>26} "
              f"{t:8.4f} {t / base_t:6.1f} {int((~ok).sum()):9d}")
    print("diff = pmb - config (negative: pmb lower) on the runs both finished; "
          "loc/missed/false: mean parts (m^2); s/step: median over runs of each run's median "
          "seconds per step; timed out: runs stopped at the study's time limit (figures are "
          "over the runs finished)")
    if interim:
        print(f"no verdict: the decision rule applies once all {declared} runs are complete")
        return
    for family in ("gmphd", "jpda"):
        fam = [c["name"] for c in configs if c["kind"] == family and c["name"] in names]
        eligible = [n for n in fam if finished(n).all()]
        if not eligible:
            continue

        def mean_finished(n: str) -> float:
            return float(np.mean(col(n, "mean_gospa")[finished(n)]))

        best = min(eligible, key=mean_finished)
        d, dlo, dhi = t_interval(col("pmb", "mean_gospa") - col(best, "mean_gospa"))
        verdict = ("pmb better" if dhi < 0 else "pmb worse" if dlo > 0
                   else "not distinguished")
        print(f"decision vs {family} (best: {best}): pmb - best = {d:+.3f} "
              f"[{dlo:+.3f}, {dhi:+.3f}] -> {verdict}")
        for n in fam:
            if n not in eligible and mean_finished(n) < mean_finished(best):
                pb, pc = paired(n)
                d, dlo, dhi = t_interval(pb - pc)
                print(f"  for transparency: {n} (not eligible, {int((~finished(n)).sum())} "
                      f"runs timed out) would be best on its finished runs: pmb - {n} = "
                      f"{d:+.3f} [{dlo:+.3f}, {dhi:+.3f}] over {len(pb)} runs")


def next_time_of_day(hour: int, minute: int, now: datetime.datetime) -> datetime.datetime:
    """The first moment after ``now`` at which the clock reads ``hour:minute``: a session
    that runs past midnight gives tomorrow's."""
    at = now.replace(hour=hour, minute=minute, second=0, microsecond=0)
    return at if at > now else at + datetime.timedelta(days=1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--benchmark", choices=("williams15", "vo12"), required=True)
    ap.add_argument("--study", type=Path, default=Path("studies/trackers/peers.toml"))
    ap.add_argument("--out", type=Path, required=True, help="the CSV (appended, resumable)")
    ap.add_argument("--runs", type=int, default=None,
                    help="runs to do (the first ones of the study's; default all)")
    ap.add_argument("--stop-at", default=None, metavar="HH:MM",
                    help="UTC time of day from which no new run index starts (the next time "
                         "the clock reads it)")
    ap.add_argument("--summary-only", action="store_true", help="print the summary only")
    args = ap.parse_args(argv)
    spec = load(args.study, args.benchmark)
    runs = int(spec["runs"]) if args.runs is None else args.runs
    if runs < 1:
        fail("--runs", f"must be >= 1, got {runs}")
    stop_at = None
    if args.stop_at is not None:
        try:
            hm = datetime.datetime.strptime(args.stop_at, "%H:%M")
        except ValueError:
            fail("--stop-at", f"must be HH:MM (UTC), got {args.stop_at!r}")
        stop_at = next_time_of_day(hm.hour, hm.minute, datetime.datetime.now(datetime.UTC))
    if not args.summary_only:
        # SIGTERM stops as Ctrl-C does: the CSV is closed with every finished row in it.
        signal.signal(signal.SIGTERM, signal.default_int_handler)
        try:
            run_study(spec, args.benchmark, runs, args.out, stop_at)
        except KeyboardInterrupt:
            print(f"{args.benchmark}: stopped; the same command resumes", flush=True)
    if args.out.exists():
        summary(args.out, args.benchmark, runs, spec["configs"], int(spec["runs"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
