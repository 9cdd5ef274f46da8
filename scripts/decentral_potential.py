"""Open loop: the potential Phi of decentralized plans against the centralized plan and the
exact optimum, on the same decision problems (paired).

    python scripts/decentral_potential.py [--seed 5099] [--problems 100] \\
        [--out /work/runs/decentral_openloop]

Three sets of ``--problems`` decisions each:

- ``paper`` and ``holes``: the first decision of a closed-loop run of the scenario of
  ``studies/decentral.toml`` (paper preset) and ``studies/decentral_holes.toml``
  (configs/holes.toml): initial conditions drawn by ``sensorplan.simulation.scenario.draw_initial``,
  the default tracker's estimates and planning process noise, K = 3, e = 2 and every other
  planning setting of those studies, built exactly as the simulator builds its first
  problem (a test compares the two). Every method of the study file plans each problem and
  its Phi is divided by the centralized ``pg``'s.
- ``tiny``: ``sensorplan.planners.contract_problems.tiny_problem`` (N <= 3, M <= 4, K <= 4, with
  the studies' visibility and objective), where ``brute-force`` gives the optimum Phi*;
  ``pg`` and every decentralized method are divided by it.

Every method meets problem i with the same planner seed (paired). Problem i of each set
depends only on ``--seed`` and i (``SeedSequence(seed, spawn_key=(set, i, ...))``), so the
first problems of a larger run are those of a smaller one.

Writes into ``--out``: ``openloop.csv`` (one row per set, problem and method: Phi, the
reference's Phi, their ratio, and what happened on the links), ``summary.csv`` and
``summary.md`` (per set and method: mean ratio with its 95 % t-interval, median with its
order-statistic interval, shares below and above 1; also for the tiny problems with at
least two platforms) and ``meta.json``. The raw table is
rewritten after every problem (atomically), so Ctrl-C loses at most the problem under way;
running the same command again continues where it stopped. The output depends only on
``--seed`` and ``--problems``: no wall time is stored.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sensorplan.planners import make_planner
from sensorplan.planners.contract_problems import tiny_problem
from sensorplan.planners.problem import PlanningProblem
from sensorplan.simulation.scenario import Scenario, draw_initial
from sensorplan.models.sensors import radar_table
from sensorplan.simulation.settings import RunSettings
from sensorplan.simulation import run_streams
from sensorplan.study import load_study, median_interval, t_interval
from sensorplan.tracking.tracker import KnownTargetTracker

ROOT = Path(__file__).resolve().parents[1]
#: The sets of problems, in order, with the study file whose scenario and methods they use.
STUDIES = {"paper": ROOT / "studies" / "decentral.toml",
           "holes": ROOT / "studies" / "decentral_holes.toml"}
SETS = ("paper", "holes", "tiny")
FORMAT = "sensorplan-decentral-openloop/1"
#: Ratios within this relative distance of 1 count as equal (rounding of Phi).
TIE = 1e-9
COLUMNS = ["set", "problem", "method", "planner", "phi", "reference", "phi_reference",
           "ratio", "rounds", "delivered", "lost", "stale", "n_sensors", "n_targets",
           "horizon"]


@dataclass(frozen=True)
class MethodSpec:
    """One method of a study file: its name, planner and every planner setting."""

    name: str
    planner: str
    params: dict[str, Any]

    def make(self) -> Any:
        return make_planner(self.planner, **self.params)


@functools.cache
def study_methods(path: Path) -> tuple[Scenario, RunSettings, list[MethodSpec]]:
    """A study file's scenario, the settings of its ``pg`` method (the decisions' K, e,
    visibility, objective, tracker) and every method with its resolved planner settings."""
    study = load_study(path)
    methods = [MethodSpec(m.name, m.settings.planner, dict(m.settings.planner_params))
               for m in study.methods]
    reference = next(m for m in study.methods if m.settings.planner == "pg")
    return study.scenario, reference.settings, methods


def first_decision(scenario: Scenario, settings: RunSettings,
                   seed: np.random.SeedSequence) -> PlanningProblem:
    """The first planning problem of a closed-loop run of ``scenario`` with ``settings`` and
    run seed ``seed``, as :func:`sensorplan.simulation.run_episode` builds it: the initial
    estimates and P0, the tracker's planning process noise (with the default IMM tracker its
    effective q, not the scenario's), the sensors' drawn poses."""
    streams = run_streams(seed)
    init = draw_initial(scenario, np.random.default_rng(streams["truth"]),
                        np.random.default_rng(streams["init"]))
    sensors = tuple(s.params for s in scenario.sensors)
    P0 = np.array(scenario.initial_cov)
    tracker = KnownTargetTracker(init.estimate, P0, scenario.dt, radar_table(sensors),
                      world=(scenario.world.width, scenario.world.height)
                      if settings.tracker.known_map else None,
                      restart_velocity_var=(P0[2, 2], P0[3, 3]),
                      buildings=scenario.building_array,
                      **settings.tracker.tracker_options())
    buildings = (scenario.building_array if settings.planning_occlusion == "aware"
                 else np.zeros((0, 5)))
    return PlanningProblem(
        means=tracker.means, covs=tracker.covs, positions=init.positions,
        headings=init.headings, sensors=sensors, horizon=settings.horizon,
        steps_per_epoch=settings.steps_per_epoch, dt=scenario.dt,
        process_noise=tracker.planning_process_noise(), world=scenario.world,
        visibility=settings.visibility, objective=settings.objective,
        planning_detection=settings.planning_detection, buildings=buildings)


def problem_seeds(seed: int, set_index: int, i: int
                  ) -> tuple[np.random.SeedSequence, np.random.SeedSequence]:
    """Problem i of set ``set_index``: its own seed and the planners' (shared by methods)."""
    return (np.random.SeedSequence(seed, spawn_key=(set_index, i, 0)),
            np.random.SeedSequence(seed, spawn_key=(set_index, i, 1)))


def solve(problem: PlanningProblem, planner_seed: np.random.SeedSequence,
          methods: list[MethodSpec], reference: MethodSpec) -> list[dict[str, Any]]:
    """Phi of every method on ``problem`` and its ratio to ``reference``'s Phi.

    Each planner gets a fresh generator from ``planner_seed`` (paired). The ratio is NaN
    when the reference's Phi is 0 (no look can see anything: every plan is as good).
    """
    def run(m: MethodSpec) -> tuple[float, Any]:
        res = m.make().plan(problem, rng=np.random.default_rng(planner_seed))
        return float(res.potential), getattr(res, "log", None)

    phi_ref, _ = run(reference)
    rows = []
    for m in methods:
        phi, log = run(m)
        rows.append(dict(
            method=m.name, planner=m.planner, phi=phi, reference=reference.name,
            phi_reference=phi_ref, ratio=phi / phi_ref if phi_ref > 0 else math.nan,
            rounds=log.rounds if log is not None else None,
            delivered=log.delivered if log is not None else None,
            lost=log.lost if log is not None else None,
            stale=log.stale if log is not None else None,
            n_sensors=len(problem.sensors), n_targets=len(problem.means),
            horizon=problem.horizon))
    return rows


def problem_rows(set_name: str, i: int, seed: int) -> list[dict[str, Any]]:
    """Every method's row of problem ``i`` of set ``set_name``."""
    k = SETS.index(set_name)
    problem_ss, planner_ss = problem_seeds(seed, k, i)
    if set_name == "tiny":
        _, settings, methods = study_methods(STUDIES["paper"])
        problem = tiny_problem(np.random.default_rng(problem_ss),
                               visibility=settings.visibility, objective=settings.objective)
        rows = solve(problem, planner_ss, methods,
                     MethodSpec("brute-force", "brute-force", {}))
    else:
        scenario, settings, methods = study_methods(STUDIES[set_name])
        problem = first_decision(scenario, settings, problem_ss)
        pg = next(m for m in methods if m.planner == "pg")
        rows = solve(problem, planner_ss, [m for m in methods if m != pg], pg)
    return [dict(set=set_name, problem=i, **r) for r in rows]


#: A subgroup summarized besides the sets: the tiny problems with several platforms (about
#: half of ``tiny_problem``'s draws have one platform, where there is nothing to negotiate).
MULTI = "tiny, N >= 2"


def summarize(raw: pd.DataFrame) -> pd.DataFrame:
    """Per set and method: the ratio's mean [t-interval], median [order-statistic interval],
    and the shares of problems below and above 1 (beyond :data:`TIE`); then the same for
    the tiny problems with at least two platforms (:data:`MULTI`)."""
    multi = raw[(raw["set"] == "tiny") & (raw["n_sensors"] >= 2)].assign(set=MULTI)
    out = []
    for (set_name, method), g in pd.concat([raw, multi]).groupby(["set", "method"],
                                                                  sort=False):
        x = g["ratio"].to_numpy(float)
        ok = x[~np.isnan(x)]
        mean, lo, hi = t_interval(ok)
        med, mlo, mhi = median_interval(ok)
        out.append(dict(set=set_name, method=method, reference=g["reference"].iloc[0],
                        n=ok.size, degenerate=int(np.isnan(x).sum()), mean=float(mean),
                        mean_lo=float(lo), mean_hi=float(hi), median=med, median_lo=mlo,
                        median_hi=mhi, below=float(np.mean(ok < 1 - TIE)),
                        above=float(np.mean(ok > 1 + TIE))))
    return pd.DataFrame(out)


def markdown(summary: pd.DataFrame) -> str:
    """The summary as markdown tables, one per set."""
    lines = []
    for set_name, g in summary.groupby("set", sort=False):
        ref = g["reference"].iloc[0]
        lines += [f"**{set_name}**: Phi / Phi({ref}) over {int(g['n'].max())} problems"
                  + (" (a subgroup of tiny)" if set_name == MULTI else ""),
                  "", "| method | mean [95 % CI] | median [95 % CI] | below 1 | above 1 |",
                  "|---|---|---|---|---|"]
        for r in g.itertuples():
            lines.append(f"| {r.method} | {r.mean:.4f} [{r.mean_lo:.4f}, {r.mean_hi:.4f}] | "
                         f"{r.median:.4f} [{r.median_lo:.4f}, {r.median_hi:.4f}] | "
                         f"{r.below:.0%} | {r.above:.0%} |")
        if g["degenerate"].any():
            lines.append(f"\n({int(g['degenerate'].max())} problem(s) with Phi({ref}) = 0 "
                         "left out.)")
        lines.append("")
    return "\n".join(lines)


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def identity(seed: int) -> dict[str, Any]:
    """What every problem's rows depend on (with the set and the problem's index)."""
    return dict(format=FORMAT, seed=seed,
                methods={k: [vars(m) for m in study_methods(p)[2]]
                         for k, p in STUDIES.items()})


def read_raw(path: Path) -> pd.DataFrame:
    """An ``openloop.csv`` (floats read back exactly)."""
    return pd.read_csv(path)


def load_done(out: Path, seed: int, problems: int, sets: tuple[str, ...]) -> pd.DataFrame:
    """Rows already in ``out`` for ``sets`` and problems < ``problems`` (empty if none).

    Raises SystemExit(2) when ``out`` holds another run (other seed or methods)."""
    meta, raw = out / "meta.json", out / "openloop.csv"
    if not raw.exists():
        return pd.DataFrame(columns=COLUMNS)
    old = json.loads(meta.read_text()) if meta.exists() else {}
    old = {k: v for k, v in old.items() if k not in ("problems", "sets")}
    if old != json.loads(json.dumps(identity(seed))):
        print(f"error: --out: {out} holds another run (other seed or methods); use another "
              "--out or delete it", file=sys.stderr)
        raise SystemExit(2)
    df = read_raw(raw)
    return df[df["set"].isin(sets) & (df["problem"] < problems)]


def save(out: Path, raw: pd.DataFrame, seed: int, problems: int,
         sets: tuple[str, ...]) -> None:
    raw = raw.sort_values(["set", "problem"], key=lambda s: s.map(SETS.index)
                          if s.name == "set" else s, kind="stable")
    _write(out / "openloop.csv", raw[COLUMNS].to_csv(index=False))
    _write(out / "meta.json", json.dumps(dict(identity(seed), problems=problems,
                                              sets=list(sets)), indent=1) + "\n")


@contextmanager
def progress(total: int, done: int) -> Iterator[Callable[[str], None]]:
    """A rich bar on a terminal, a plain line about every 10 % otherwise."""
    from rich.console import Console
    from rich.progress import (
                               BarColumn,
                               MofNCompleteColumn,
                               Progress,
                               TextColumn,
                               TimeElapsedColumn,
                               TimeRemainingColumn,
                               )

    console = Console(stderr=True)
    if console.is_terminal:
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                      TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                      console=console) as bar:
            task = bar.add_task("problems", total=total, completed=done)
            yield lambda label: bar.update(task, advance=1, description=label)
        return
    state = {"done": done, "next": 0.0, "start": time.perf_counter()}

    def line(label: str) -> None:
        state["done"] += 1
        if state["done"] / total >= state["next"] or state["done"] == total:
            state["next"] = state["done"] / total + 0.1
            console.print(f"{label}: {state['done']}/{total} problems, "
                          f"{time.perf_counter() - state['start']:.0f} s", highlight=False)
    yield line


def run(out: Path, seed: int = 5099, problems: int = 100, sets: tuple[str, ...] = SETS,
        quiet: bool = False) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Compute (or finish) the open-loop comparison into ``out``; return (raw, summary).

    ``sets`` is a subset of :data:`SETS`; rows of other sets or of problems >= ``problems``
    already in ``out`` are dropped, so the files depend only on the arguments."""
    unknown = set(sets) - set(SETS)
    if unknown or not sets:
        raise ValueError(f"sets must be a non-empty subset of {SETS}, got {sets}")
    sets = tuple(s for s in SETS if s in sets)
    out.mkdir(parents=True, exist_ok=True)
    raw = load_done(out, seed, problems, sets)
    done = set(zip(raw["set"], raw["problem"]))
    todo = [(s, i) for s in sets for i in range(problems) if (s, i) not in done]
    frames = [raw] if len(raw) else []
    with (progress(len(sets) * problems, len(done)) if not quiet else _silent()) as tick:
        try:
            for set_name, i in todo:
                frames.append(pd.DataFrame(problem_rows(set_name, i, seed)))
                save(out, pd.concat(frames, ignore_index=True), seed, problems, sets)
                tick(set_name)
        except KeyboardInterrupt:
            n = sum(len(f) for f in frames)
            print(f"\ninterrupted: {n} rows saved in {out / 'openloop.csv'}; run the same "
                  "command again to continue", file=sys.stderr)
            raise SystemExit(130) from None
    raw = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=COLUMNS)
    save(out, raw, seed, problems, sets)
    raw = read_raw(out / "openloop.csv")               # what the file holds, typed the same
    table = summarize(raw)
    _write(out / "summary.csv", table.to_csv(index=False))
    _write(out / "summary.md", markdown(table))
    return raw, table


@contextmanager
def _silent() -> Iterator[Callable[[str], None]]:
    yield lambda label: None


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=5099, help="root seed (default 5099)")
    ap.add_argument("--problems", type=int, default=100,
                    help="problems per set: paper, holes and tiny (default 100)")
    ap.add_argument("--sets", default=",".join(SETS),
                    help="comma-separated subset of paper,holes,tiny (default: all)")
    ap.add_argument("--out", type=Path, default=Path("/work/runs/decentral_openloop"),
                    help="output directory (default /work/runs/decentral_openloop)")
    args = ap.parse_args(argv)
    if args.seed < 0:
        ap.error("--seed: must be an integer >= 0")
    if args.problems < 1:
        ap.error("--problems: must be an integer >= 1")
    sets = tuple(x.strip() for x in args.sets.split(",") if x.strip())
    if not sets or set(sets) - set(SETS):
        ap.error(f"--sets: must be a comma-separated subset of {','.join(SETS)}")
    start = time.perf_counter()
    _, table = run(args.out, args.seed, args.problems, sets)
    print(markdown(table))
    print(f"wrote {args.out}/openloop.csv, summary.csv, summary.md "
          f"({time.perf_counter() - start:.0f} s)", file=sys.stderr)


if __name__ == "__main__":
    main()
