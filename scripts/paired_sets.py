"""Set metrics and honesty of every method of one or more finished studies on the same
runs, and paired differences between methods of different studies.

A multi-target tracker needs looks that detect every live target in view, a scenario
setting, so it cannot share a study file with the tracker of known targets on a preset
whose looks detect only their own target. Two study files with the same seed, runs and
steps, whose scenarios differ only in what a look detects, have the same truth in run r
(this script checks it, target-step by target-step) and are compared here run by run
(``studies/honest_urban_pmb.toml``).

Per method, per run over steps 1..S, then across runs (mean with its 95 % t-interval,
median, max): the set metrics of ``scripts/search_conditions.py`` (mean GOSPA, c = 50 m,
and its parts; targets lost: a live target without a track within c for 20 or more
consecutive steps), the run RMSE (``sensorplan.study.metrics.run_metrics``: for a
multi-target tracker over the target-steps with an assigned track); then, over all runs,
the ANEES of assigned tracks (target-steps whose estimate is within c), the median run
ANEES of those, their share with NEES above 13.28, the targets lost and the runs with any,
the targets still without a track at the run's end after 20 steps or more, and the
all-target ANEES and diverged runs (largest error above 300 m) of the project's honesty
tables. Then, for each ``A - B``, the paired differences per run of the set metrics and the
RMSE (mean with its paired 95 % t-interval, median with its order-statistic interval, runs
below and above 0). Markdown on stdout.

    python scripts/paired_sets.py STUDY_DIR [STUDY_DIR ...] "A - B" ["C - D" ...]
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from search_conditions import METRICS, per_run  # scripts/ is on the path when run as a script
from sensorplan.errors import ConfigError
from sensorplan.study.metrics import NEES_HIGH, median_interval, run_metrics, t_interval
from sensorplan.study.set_metrics import GOSPA_CUTOFF, LOST_STEPS
from sensorplan.study.storage import load_study_dir

#: A run whose largest position error exceeds this has diverged (as in the report).
DIVERGED_M = 300.0
#: The per-run metrics of the tables: the set metrics and the run RMSE.
ALL_METRICS = {**METRICS, "rmse": ("run RMSE (m; pmb: of assigned tracks)", 2)}


def _truth(tables: Any) -> Any:
    """The first method's live target-steps (run, step, target, x, y), sorted."""
    s = tables.steps
    s = s[s["method"] == tables.study.method_names[0]]
    return s[["run", "step", "target", "x", "y"]].sort_values(
        ["run", "step", "target"]).reset_index(drop=True)


def load(dirs: list[str]) -> tuple[Any, Any, dict[str, dict[str, float]]]:
    """Per-run metrics of every method of ``dirs`` (one frame), the steps of all, and the
    whole-study figures per method. Refuses studies whose runs are not the same."""
    import pandas as pd

    runs, steps, overall, truth = [], [], {}, None
    for d in dirs:
        tables = load_study_dir(d)
        t = _truth(tables)
        if truth is None:
            truth = t
        elif not t.equals(truth):
            raise ConfigError("STUDY_DIR", f"{d}: its truth is not the first study's; the "
                                           "runs cannot be paired")
        r = per_run(tables)
        rm = run_metrics(tables)
        rm = rm[rm["kind"] == "all"][["method", "run", "rmse"]]
        runs.append(r.merge(rm, on=["method", "run"]))
        s = tables.steps[tables.steps["step"] >= 1]
        steps.append(s)
        for m in tables.study.method_names:
            if m in overall:
                raise ConfigError("STUDY_DIR", f"method {m!r} is in two of the studies")
            overall[m] = _overall(s[s["method"] == m])
    return pd.concat(runs, ignore_index=True), pd.concat(steps, ignore_index=True), overall


def _overall(s: Any) -> dict[str, float]:
    """Whole-study figures of one method's target-steps 1..S (see the module docstring)."""
    within = s[s["error"] < GOSPA_CUTOFF]
    nees = within["nees"].to_numpy(float)
    nees = nees[np.isfinite(nees)]
    per_run = within.groupby("run", observed=True)["nees"].mean().to_numpy(float)
    all_nees = s["nees"].to_numpy(float)
    all_nees = all_nees[np.isfinite(all_nees)]
    worst = s.groupby("run", observed=True)["error"].max()
    # A target still without a track within c at the run's end, after LOST_STEPS or more.
    end_lost = 0
    for _, g in s.sort_values("step").groupby(["run", "target"], observed=True):
        gap = ~(g["error"].to_numpy(float) < GOSPA_CUTOFF)
        tail = len(gap) - (np.flatnonzero(~gap)[-1] + 1 if (~gap).any() else 0)
        end_lost += int(tail >= LOST_STEPS)
    return dict(anees=float(nees.mean()), n=float(nees.size),
                run_anees_median=float(np.median(per_run)),
                high=float((nees > NEES_HIGH).mean()), end_lost=float(end_lost),
                anees_all=float(all_nees.mean()), diverged=float((worst > DIVERGED_M).sum()))


def rows(dirs: list[str], pairs: list[tuple[str, str]]) -> list[str]:
    """The markdown tables, headers first."""
    runs, _, overall = load(dirs)
    for a, b in pairs:
        for name in (a, b):
            if name not in overall:
                raise ConfigError("pairs", f"{name!r} is not a method of the studies "
                                           f"(methods: {', '.join(overall)})")
    out = ["| method | metric | mean [95 %] | median | max |", "|---|---|--:|--:|--:|"]
    for m, o in overall.items():
        r = runs[runs["method"] == m]
        for key, (label, dec) in ALL_METRICS.items():
            v = r[key].to_numpy(float)
            mean, lo, hi = t_interval(v)
            out.append(f"| {m} | {label} | {mean:.{dec}f} [{lo:.{dec}f}, {hi:.{dec}f}] | "
                       f"{np.nanmedian(v):.{dec}f} | {np.nanmax(v):.{dec}f} |")
        lost = r["lost"].to_numpy(int)
        out += [f"| {m} | lost targets: total; runs with any; still lost at the end | "
                f"{lost.sum()}; {(lost > 0).sum()} of {len(lost)}; {o['end_lost']:.0f} | | |",
                f"| {m} | ANEES of assigned tracks (target-steps); median run | "
                f"{o['anees']:.2f} ({o['n']:.0f}); {o['run_anees_median']:.2f} | | |",
                f"| {m} | assigned target-steps with NEES > {NEES_HIGH:.2f} | "
                f"{100 * o['high']:.1f} % | | |",
                f"| {m} | all-target ANEES; diverged runs | {o['anees_all']:.2f}; "
                f"{o['diverged']:.0f} | | |"]
    wide = runs.pivot(index="run", columns="method")
    for a, b in pairs:
        n = int((wide[("gospa", a)].notna() & wide[("gospa", b)].notna()).sum())
        out += ["", f"Paired differences {a} - {b} (n = {n} runs):", "",
                "| metric | mean [paired 95 %] | median [95 %] | runs below 0 | runs above 0 |",
                "|---|--:|--:|--:|--:|"]
        for key, (label, dec) in ALL_METRICS.items():
            d = (wide[(key, a)] - wide[(key, b)]).to_numpy(float)
            d = d[np.isfinite(d)]
            mean, lo, hi = t_interval(d)
            med, mlo, mhi = median_interval(d)
            out.append(f"| {label} | {mean:+.{dec}f} [{lo:+.{dec}f}, {hi:+.{dec}f}] | "
                       f"{med:+.{dec}f} [{mlo:+.{dec}f}, {mhi:+.{dec}f}] | {(d < 0).sum()} | "
                       f"{(d > 0).sum()} |")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("args", nargs="+", metavar="STUDY_DIR or 'A - B'")
    args = parser.parse_args(argv)
    dirs = [a for a in args.args if " - " not in a]
    pairs = [tuple(p.strip() for p in a.split(" - ", 1)) for a in args.args if " - " in a]
    if not dirs:
        parser.error("give at least one study directory")
    try:
        print("\n".join(rows(dirs, [(a, b) for a, b in pairs])))
    except ConfigError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
