"""Honest in every preset: one row per (preset, method) cell of the honest-table studies,
with the verdict of the rule written into their headers (studies/honest_table_*.toml).

For each study directory and each of its methods:

- a method whose tracker is the known-target one (``tracker.kind = "known"``): the ANEES
  over all target-steps 1..S of all runs (4 is exact) and the runs that *diverge* (largest
  position error of any target above 300 m, as in the report);
- a method with a multi-target tracker (``pmb``): the ANEES of assigned tracks (the
  target-steps whose estimate lies within the study's GOSPA cut-off c, as the report's
  consistency table and ``scripts/search_summary.py`` count it) and the runs that *lose a
  held target*: a target is held from its first report on (the first step a track within c
  is assigned to it, as GOSPA assigns), and lost when it then stays alive without one for
  20 or more consecutive steps. Targets never reported were never held, so they do not
  count here; they are reported apart (targets never reported, and the runs that lose a
  target by the set metrics' wider count, which includes them).

Verdict of a cell: ``pass`` when the ANEES lies in [2, 6] and the diverged (or lost) runs
are at most 1 in 100 (bad runs x 100 <= runs); ``fail`` otherwise; ``incomplete`` while
fewer runs are finished than the study file asks for. Beside the rule: the number of
target-steps behind the ANEES, the run ANEES (median; mean [95 % t-interval]; max), the
ANEES without the run of largest ANEES, and the share of target-steps with NEES above 13.28
(1 % for an honest filter).

    python scripts/honest_table.py table DIR [DIR ...]
    python scripts/honest_table.py paired DIR "A - B" [...] [--pooled]
    python scripts/honest_table.py time STUDY.toml [...] --seed 120429 --runs 2

``time`` runs ``--runs`` runs of every method of each study file on ``--seed`` (a
development seed, used for nothing else) in this process and prints only the wall and CPU
seconds of each (run, method) and the estimated cost of the full study; it writes nothing
and prints no outcome.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import DIVERGED_THRESHOLD, NEES_HIGH, set_methods, t_interval
from sensorplan.study.set_metrics import LOST_STEPS, set_metrics
from sensorplan.study.storage import load_study_dir

#: The rule's band for the ANEES and its bound on bad runs per 100.
ANEES_BAND = (2.0, 6.0)
BAD_PER_100 = 1


def longest_gap_held(step: np.ndarray, assigned: np.ndarray) -> int:
    """The longest run of consecutive live steps without a track after the target's first
    report (its first assigned step); 0 if it is never reported.

    Parameters
    ----------
    step : (n,) int    the target's live steps, increasing
    assigned : (n,) bool    whether a track was assigned to it at each of them
    """
    hits = np.flatnonzero(assigned)
    if hits.size == 0:
        return 0
    longest = current = 0
    previous = None
    for s, a in zip(step[hits[0]:].tolist(), assigned[hits[0]:].tolist()):
        if a or (previous is not None and s != previous + 1):
            current = 0
        if not a:
            current += 1
            longest = max(longest, current)
        previous = s
    return longest


def set_run_counts(tables: Any, method: str) -> Any:
    """Per run of a multi-target method: ``held_lost`` (targets held, then lost),
    ``any_lost`` (targets unassigned 20+ consecutive steps, never-reported ones included),
    ``targets`` and ``never`` (targets never reported)."""
    import pandas as pd

    c = float(tables.study.methods[0].settings.gospa_c)
    steps = tables.steps[tables.steps["method"] == method]
    steps = steps[steps["step"] >= 1]
    tracks = tables.tracks[(tables.tracks["method"] == method) & (tables.tracks["step"] >= 1)]
    by_run = dict(tuple(tracks.groupby("run", observed=True)))
    rows = []
    for run, s in steps.groupby("run", observed=True):
        y = by_run.get(run, tracks.iloc[:0])
        step, target = s["step"].to_numpy(np.int64) - 1, s["target"].to_numpy(np.int64)
        sm = set_metrics(step, target, s[["x", "y"]].to_numpy(float), y["step"].to_numpy() - 1,
                         y["label"].to_numpy(), y[["x", "y"]].to_numpy(float), c,
                         n_steps=tables.study.steps)
        held_lost = never = 0
        ids = np.unique(target)
        for t in ids:
            k = target == t
            order = np.argsort(step[k], kind="stable")
            st, a = step[k][order], sm.assigned[k][order]
            held_lost += longest_gap_held(st, a) >= LOST_STEPS
            never += not a.any()
        rows.append(dict(run=run, held_lost=held_lost, any_lost=sm.targets.targets_lost,
                         targets=len(ids), never=never))
    return pd.DataFrame(rows)


@dataclasses.dataclass(frozen=True)
class Cell:
    """One row of the table."""

    study: str
    method: str
    tracker: str
    runs: int
    planned: int
    anees: float
    n: int
    run_anees: tuple[float, float, float, float, float]   # median, mean, lo, hi, max
    without_worst: float
    high_share: float
    bad: int
    bad_what: str
    extra: str

    @property
    def verdict(self) -> str:
        if self.runs < self.planned:
            return "incomplete"
        ok = (ANEES_BAND[0] <= self.anees <= ANEES_BAND[1]
              and self.bad * 100 <= BAD_PER_100 * self.runs)
        return "pass" if ok else "fail"


def cells(study_dir: str) -> list[Cell]:
    """The cells of one study directory (finished or not)."""
    tables = load_study_dir(study_dir)
    study = tables.study
    sets = set(set_methods(study))
    c = float(study.methods[0].settings.gospa_c)
    steps = tables.steps[tables.steps["step"] >= 1]
    out = []
    for m in study.methods:
        g = steps[steps["method"] == m.name]
        runs = int(g["run"].nunique())
        # A target-step without an estimate has no NEES (as in the report's consistency
        # table); for a set tracker only the estimates within c count.
        g = g[g["nees"].notna() & (g["error"] < c)] if m.name in sets else g[g["nees"].notna()]
        per_run = g.groupby("run", observed=True)["nees"].mean()
        nees = g["nees"].to_numpy(float)
        if per_run.size:
            mean, lo, hi = t_interval(per_run.to_numpy(float)) if per_run.size > 1 else (
                float(per_run.iloc[0]), math.nan, math.nan)
            worst = per_run.idxmax()
            rest = g[g["run"] != worst]["nees"]
            run_anees = (float(per_run.median()), mean, lo, hi, float(per_run.max()))
            without = float(rest.mean()) if len(rest) else math.nan
        else:
            run_anees, without = (math.nan,) * 5, math.nan
        if m.name in sets:
            counts = set_run_counts(tables, m.name)
            bad = int((counts["held_lost"] > 0).sum())
            extra = (f"targets never reported {int(counts['never'].sum())} of "
                     f"{int(counts['targets'].sum())}; runs losing any target "
                     f"{int((counts['any_lost'] > 0).sum())}")
            what = "lose a held target"
        else:
            err = steps[steps["method"] == m.name].groupby("run", observed=True)["error"].max()
            bad = int((err > DIVERGED_THRESHOLD).sum())
            extra, what = "", "diverge"
        out.append(Cell(study=study.scenario_source.removeprefix("preset "), method=m.name,
                        tracker=m.settings.tracker.kind, runs=runs, planned=study.runs,
                        anees=float(nees.mean()) if nees.size else math.nan, n=int(nees.size),
                        run_anees=run_anees, without_worst=without,
                        high_share=float((nees > NEES_HIGH).mean()) if nees.size else math.nan,
                        bad=bad, bad_what=what, extra=extra))
    return out


def table_lines(study_dirs: list[str]) -> list[str]:
    """The markdown table of every cell of ``study_dirs``, then the verdict count."""
    out = ["| preset | method | tracker | runs | ANEES (target-steps) | run ANEES: median; "
           "mean [95 %]; max | without the worst run | NEES > 13.28 | bad runs | verdict | "
           "beside the rule |",
           "|---|---|---|--:|--:|--:|--:|--:|--:|---|---|"]
    verdicts: dict[str, int] = {}
    for d in study_dirs:
        for x in cells(d):
            med, mean, lo, hi, mx = x.run_anees
            out.append(
                f"| {x.study} | {x.method} | {x.tracker} | {x.runs} of {x.planned} | "
                f"{x.anees:.2f} ({x.n}) | {med:.2f}; {mean:.2f} [{lo:.2f}, {hi:.2f}]; "
                f"{mx:.1f} | {x.without_worst:.2f} | {100 * x.high_share:.1f} % | "
                f"{x.bad} {x.bad_what} | {x.verdict} | {x.extra} |")
            verdicts[x.verdict] = verdicts.get(x.verdict, 0) + 1
    out += ["", "Cells: " + ", ".join(f"{v} {k}" for k, v in sorted(verdicts.items()))]
    return out


def paired_lines(study_dir: str, pairs: list[tuple[str, str]],
                 pooled: bool = False) -> list[str]:
    """For each ``A - B`` of multi-target methods: the held targets lost per run, paired
    (mean difference with its 95 % t-interval), and the runs that lose a held target with
    A, with B, and with one of them only. ``pooled``: one more row, the pairs' differences
    summed per run (:func:`pooled_difference`), for a rule about several planners at once
    that keeps each run one sample."""
    tables = load_study_dir(study_dir)
    names = [m.name for m in tables.study.methods]
    missing = sorted({x for pair in pairs for x in pair} - set(names))
    if missing:
        raise ConfigError("pairs", f"no method {missing[0]!r} in {study_dir} (its methods: "
                                   f"{', '.join(names)})")
    out = ["| A - B | runs | held lost per run: A; B | A - B [paired 95 %] | runs losing "
           "one: A; B | only A; only B |", "|---|--:|--:|--:|--:|--:|"]
    diffs = []
    for a, b in pairs:
        ca = set_run_counts(tables, a).set_index("run")["held_lost"]
        cb = set_run_counts(tables, b).set_index("run")["held_lost"]
        ca, cb = ca.align(cb, join="inner")
        diffs.append(ca - cb)
        d = (ca - cb).to_numpy(float)
        mean, lo, hi = t_interval(d)
        la, lb = ca.to_numpy() > 0, cb.to_numpy() > 0
        out.append(f"| {a} - {b} | {d.size} | {ca.mean():.3f}; {cb.mean():.3f} | "
                   f"{mean:+.3f} [{lo:+.3f}, {hi:+.3f}] | {int(la.sum())}; {int(lb.sum())} "
                   f"| {int((la & ~lb).sum())}; {int((lb & ~la).sum())} |")
    if pooled:
        d = pooled_difference(diffs)
        mean, lo, hi = t_interval(d)
        out.append(f"| the {len(pairs)} pairs summed per run | {d.size} | | "
                   f"{mean:+.3f} [{lo:+.3f}, {hi:+.3f}] | | |")
    return out


def pooled_difference(diffs: list[Any]) -> np.ndarray:
    """Per run, the sum of several pairs' differences (pandas Series indexed by run), over
    the runs every pair has: one sample per run, so that a t-interval over them is not
    narrowed by counting a run's correlated pairs as independent."""
    total = diffs[0]
    for d in diffs[1:]:
        total, d = total.align(d, join="inner")
        total = total + d
    return np.asarray(total.sort_index().to_numpy(float))


def _pair(text: str) -> tuple[str, str]:
    a, sep, b = text.partition(" - ")
    if not sep or not a.strip() or not b.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write a pair as 'A - B'")
    return a.strip(), b.strip()


def time_lines(study_files: list[str], seed: int, runs: int) -> Iterator[str]:
    """Wall and CPU seconds of ``runs`` runs of every method of each study file on
    ``seed``, a line as each method finishes (a slow method shows before the end); the
    outcomes are discarded unread."""
    from sensorplan.study import load_study
    from sensorplan.study.execution import run_task

    yield "| study | method | wall per run (s) | CPU per run (s) |"
    yield "|---|---|--:|--:|"
    total_wall = total_cpu = 0.0
    for path in study_files:
        study = dataclasses.replace(load_study(path), seed=seed, runs=runs)
        full = load_study(path).runs
        file_wall = file_cpu = 0.0
        for i, m in enumerate(study.methods):
            wall = cpu = 0.0
            for r in range(runs):
                start = time.perf_counter()
                result = run_task(study, r, i)
                wall += time.perf_counter() - start
                cpu += result.cpu
            yield f"| {path} | {m.name} | {wall / runs:.2f} | {cpu / runs:.2f} |"
            file_wall += wall / runs * full
            file_cpu += cpu / runs * full
        yield f"| {path} | all methods, {full} runs | {file_wall:.0f} | {file_cpu:.0f} |"
        total_wall += file_wall
        total_cpu += file_cpu
    yield f"| all | one worker | {total_wall:.0f} | {total_cpu:.0f} |"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("table", help="the table of finished (or running) study directories")
    t.add_argument("study_dirs", nargs="+")
    p = sub.add_parser("paired", help="held targets lost, paired, for 'A - B' pairs")
    p.add_argument("study_dir")
    p.add_argument("pairs", nargs="+", type=_pair)
    p.add_argument("--pooled", action="store_true",
                   help="add the pairs' differences summed per run")
    c = sub.add_parser("time", help="time every method of study files on a development seed")
    c.add_argument("study_files", nargs="+")
    c.add_argument("--seed", type=int, required=True)
    c.add_argument("--runs", type=int, default=2)
    args = parser.parse_args(argv)
    try:
        if args.command == "table":
            print("\n".join(table_lines(args.study_dirs)))
        elif args.command == "paired":
            print("\n".join(paired_lines(args.study_dir, args.pairs, args.pooled)))
        else:
            for line in time_lines(args.study_files, args.seed, args.runs):
                print(line, flush=True)
    except ConfigError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
