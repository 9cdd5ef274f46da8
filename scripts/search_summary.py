"""Found, how fast, how long held: the set metrics of a finished search-and-track study.

For a study directory of multi-target trackers (``studies/search.toml``), per method. The
tracks are assigned to the live targets at each step as GOSPA assigns them (c = the
study's cut-off; :func:`sensorplan.study.set_metrics.set_metrics` on the steps and tracks
tables); a target is *reported* at a step where a track is assigned to it.

Per run over steps 1..S, then across runs (mean with its 95 % t-interval, median, 90th
percentile, max): mean GOSPA and its localisation, missed and false parts (the gospa
table); the share of live target-steps without a reported track, split into the steps of
targets never reported, those of reported targets before their first report and those after
it; false tracks per step; label switches; targets lost (unassigned for 20 or more
consecutive steps); targets born and the share of them ever reported. Paired differences
against a reference method per run (mean with its paired 95 % t-interval, median with its
order-statistic interval), and the ratio of each method's mean GOSPA to the reference's.
The reference is named (``--reference``) or chosen by a rule (``--best-of PREFIX``: of the
methods whose names start with PREFIX, the one with the lowest mean GOSPA over the runs,
the first in the study's order on a tie; the choice and the range of their means are
printed first).

Per target, pooled over runs: the steps from birth (its first live step) to its first
report (median, 90th percentile, max) for the targets born during the run and for the ones
known at the start (alive at step 0); the targets never reported, apart (also among the
born ones alive for at least 20 steps, who had time to be found); how long a reported
target is held: the share of its live steps from its first report on with a track. The
ANEES of assigned tracks (target-steps whose estimate is within c). Markdown on stdout.

    python scripts/search_summary.py STUDY_DIR [--with OTHER_DIR ...]
                                     [--reference myopic | --best-of raster/]

``--with`` joins the methods of other study directories run with the same scenario, seed,
run count and steps (a study split into parts): run r of every method starts from the same
random streams whichever file it is in, so the methods stay paired run by run. Only the runs
finished in every directory are kept. With ``--other-scenario`` the directories may differ
in their scenario (a sensor's settings, say, on the same seed): each run's draws are the
same, so the runs are still paired; a method name that repeats is renamed ``NAME@DIR``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import median_interval, t_interval
from sensorplan.study.set_metrics import LOST_STEPS, set_metrics
from sensorplan.study.storage import load_study_dir

#: Per-run metric -> (label, decimals), in table order.
METRICS = {
    "gospa": ("mean GOSPA (m)", 1), "localisation": ("localisation part (m²)", 0),
    "missed": ("missed part (m²)", 0), "false": ("false part (m²)", 0),
    "missed_share": ("live target-steps without a track (%)", 1),
    "missed_never": ("... of targets never reported (%)", 1),
    "missed_before": ("... before a target's first report (%)", 1),
    "missed_after": ("... after a target's first report (%)", 1),
    "false_tracks": ("false tracks per step", 3), "switches": ("label switches per run", 2),
    "lost": ("targets lost per run", 2), "born": ("targets born per run", 2),
    "found_born": ("born targets ever reported (%)", 1)}
#: The per-run metrics whose paired differences against the reference are shown.
PAIRED = ("gospa", "missed_share", "missed_never", "missed_after", "false_tracks", "switches",
          "lost", "found_born")


def per_target(tables: Any) -> Any:
    """One row per (method, run, target): ``known`` (alive at step 0), ``birth`` and
    ``last`` (first and last live step >= 1), ``live`` steps, ``first`` report step (-1:
    never), ``delay`` (NaN: never), ``switches``, ``lost``, ``before`` (unassigned live
    steps before the first report; all of them if never), ``after`` (unassigned live steps
    after it) and ``held_of`` (live steps from the first report on)."""
    import pandas as pd

    c = float(tables.study.methods[0].settings.gospa_c)
    known = tables.steps[tables.steps["step"] == 0].groupby(
        ["method", "run"], observed=True)["target"].agg(set).to_dict()
    steps = tables.steps[tables.steps["step"] >= 1]
    tracks = tables.tracks[tables.tracks["step"] >= 1]
    by_pair = dict(tuple(tracks.groupby(["method", "run"], observed=True)))
    empty = tracks.iloc[:0]
    rows = []
    for (method, run), s in steps.groupby(["method", "run"], observed=True):
        y = by_pair.get((method, run), empty)
        step, target = s["step"].to_numpy(np.int64) - 1, s["target"].to_numpy(np.int64)
        sm = set_metrics(step, target, s[["x", "y"]].to_numpy(float), y["step"].to_numpy() - 1,
                         y["label"].to_numpy(), y[["x", "y"]].to_numpy(float), c,
                         n_steps=tables.study.steps)
        tm = sm.targets
        k = np.searchsorted(tm.ids, target)
        first = tm.first_report_step[k]
        gap = ~sm.assigned
        found = first >= 0
        before = np.bincount(k, weights=gap & (~found | (step < first)), minlength=len(tm.ids))
        after = np.bincount(k, weights=gap & found & (step > first), minlength=len(tm.ids))
        held_of = np.bincount(k, weights=found & (step >= first), minlength=len(tm.ids))
        live = np.bincount(k, minlength=len(tm.ids))
        last = np.zeros(len(tm.ids), dtype=np.int64)
        np.maximum.at(last, k, step)
        rows.append(pd.DataFrame(dict(
            method=method, run=run, target=tm.ids,
            known=[int(t) in known.get((method, run), set()) for t in tm.ids],
            birth=tm.birth_step + 1, last=last + 1, live=live,
            first=np.where(tm.first_report_step >= 0, tm.first_report_step + 1, -1),
            delay=tm.report_delay, switches=tm.label_switches, lost=tm.lost,
            before=before.astype(np.int64), after=after.astype(np.int64),
            held_of=held_of.astype(np.int64))))
    return pd.concat(rows, ignore_index=True)


def per_run(tables: Any, targets: Any) -> Any:
    """One row per (method, run): the per-run metrics of :data:`METRICS`."""
    g = tables.gospa
    runs = g.groupby(["method", "run"], observed=True).agg(
        gospa=("gospa", "mean"), localisation=("localisation", "mean"),
        missed=("missed", "mean"), false=("false", "mean"),
        false_tracks=("false_tracks", "mean"))
    t = targets.assign(never=targets["first"] < 0, born=~targets["known"])
    t = t.assign(found_b=t["born"] & ~t["never"],
                 never_steps=np.where(t["never"], t["live"], 0),
                 before_found=np.where(t["never"], 0, t["before"]))
    per = t.groupby(["method", "run"], observed=True).agg(
        live=("live", "sum"), never_steps=("never_steps", "sum"),
        before_found=("before_found", "sum"), after=("after", "sum"),
        switches=("switches", "sum"), lost=("lost", "sum"), born=("born", "sum"),
        found_b=("found_b", "sum"))
    runs = runs.join(per)
    live = runs.pop("live")
    runs["missed_never"] = 100.0 * runs.pop("never_steps") / live
    runs["missed_before"] = 100.0 * runs.pop("before_found") / live
    runs["missed_after"] = 100.0 * runs.pop("after") / live
    runs["missed_share"] = runs["missed_never"] + runs["missed_before"] + runs["missed_after"]
    found = runs.pop("found_b")
    runs["found_born"] = np.where(runs["born"] > 0, 100.0 * found / runs["born"].clip(1),
                                  np.nan)
    return runs.reset_index()


def mean_gospa(tables: Any) -> dict[str, float]:
    """Per method, in the study's order: the mean GOSPA (m) over steps 1..S per run, then
    over runs."""
    per = tables.gospa.groupby(["method", "run"], observed=True)["gospa"].mean()
    means = per.groupby(level="method", observed=True).mean()
    return {m.name: float(means[m.name]) for m in tables.study.methods
            if m.name in means.index}


def best_of(tables: Any, prefix: str) -> tuple[str, dict[str, float]]:
    """The method whose name starts with ``prefix`` with the lowest mean GOSPA
    (:func:`mean_gospa`; the first in the study's order on a tie), and every such method's
    mean GOSPA.

    Raises
    ------
    ValueError
        No method's name starts with ``prefix``.
    """
    means = {m: v for m, v in mean_gospa(tables).items() if m.startswith(prefix)}
    if not means:
        raise ValueError(f"no method's name starts with {prefix!r}")
    return min(means, key=means.__getitem__), means


def best_of_lines(tables: Any, prefix: str) -> tuple[str, list[str]]:
    """:func:`best_of`'s choice and the markdown lines that state it."""
    best, means = best_of(tables, prefix)
    lo, hi = min(means.values()), max(means.values())
    return best, [f"Reference: {best}, the lowest mean GOSPA ({means[best]:.2f} m) of the "
                  f"{len(means)} methods named {prefix}... (their means {lo:.2f}-{hi:.2f} m), "
                  "chosen on these runs (which favours it: the paired intervals do not allow "
                  "for the choice).", ""]


def anees_assigned(tables: Any) -> dict[str, tuple[float, int]]:
    """Per method: the mean NEES over the target-steps (1..S) whose estimate is within c,
    and how many there are."""
    c = float(tables.study.methods[0].settings.gospa_c)
    s = tables.steps[(tables.steps["step"] >= 1) & (tables.steps["error"] < c)]
    return {str(m): (float(g["nees"].mean()), int(g["nees"].notna().sum()))
            for m, g in s.groupby("method", observed=True)}


def _fmt(v: float, dec: int, sign: str = "") -> str:
    return "–" if not np.isfinite(v) else f"{v:{sign}.{dec}f}"


def summary_lines(tables: Any, reference: str) -> list[str]:
    """The markdown tables of the module docstring."""
    targets = per_target(tables)
    runs = per_run(tables, targets)
    methods = [m.name for m in tables.study.methods]
    anees = anees_assigned(tables)
    out = [f"Per run over steps 1..{tables.study.steps} (n = {runs['run'].nunique()} runs): "
           "mean [95 % t-interval]; median; 90th percentile; max", "",
           "| metric | " + " | ".join(methods) + " |", "|---|" + "--:|" * len(methods)]
    for key, (label, dec) in METRICS.items():
        cells = []
        for m in methods:
            v = runs.loc[runs["method"] == m, key].to_numpy(float)
            v = v[np.isfinite(v)]
            if v.size == 0:                 # e.g. born targets where none are born
                cells.append("–")
                continue
            mean, lo, hi = t_interval(v)
            cells.append(f"{_fmt(mean, dec)} [{_fmt(lo, dec)}, {_fmt(hi, dec)}]; "
                         f"{_fmt(np.median(v), dec)}; {_fmt(np.percentile(v, 90), dec)}; "
                         f"{_fmt(v.max(), dec)}")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out.append("| ANEES of assigned tracks (target-steps) | " + " | ".join(
        f"{anees[m][0]:.2f} ({anees[m][1]})" if m in anees else "–" for m in methods) + " |")

    out += ["", "Per target, pooled over runs: steps from birth to the first report "
            "(median; 90th percentile; max, of the targets reported), never reported "
            f"(count and share), held (share of the live steps from the first report on "
            f"with a track; median target); lost (unassigned {LOST_STEPS}+ steps in a row)",
            "", "| method | targets | delay: median; p90; max | never reported | never "
            f"reported, of those alive {LOST_STEPS}+ steps | held: pooled; median target "
            "| lost |", "|---|---|--:|--:|--:|--:|--:|"]
    for m in methods:
        for who, rows in (("born", ~targets["known"]), ("known at start", targets["known"])):
            t = targets[(targets["method"] == m) & rows]
            if t.empty:
                continue
            d = t["delay"].dropna().to_numpy(float)
            never = t["first"] < 0
            old = t["live"] >= LOST_STEPS
            f = t[~never]
            held = 1.0 - (f["after"] / f["held_of"]).to_numpy(float)
            pooled = 1.0 - f["after"].sum() / max(int(f["held_of"].sum()), 1)
            dtext = (f"{np.median(d):.0f}; {np.percentile(d, 90):.0f}; {d.max():.0f}"
                     if d.size else "–")
            out.append(
                f"| {m} | {who}: {len(t)} | {dtext} | {never.sum()} "
                f"({100 * never.mean():.1f} %) | {(never & old).sum()} of {old.sum()} "
                f"({100 * (never & old).sum() / max(int(old.sum()), 1):.1f} %) | "
                f"{100 * pooled:.1f} %; {100 * np.median(held) if held.size else np.nan:.1f} %"
                f" | {int(t['lost'].sum())} |")

    others = [m for m in methods if m != reference]
    if reference in methods and others:
        wide = runs.set_index(["run", "method"])
        out += ["", f"Paired differences against {reference} per run (method - {reference}):"
                " mean [paired 95 %]; median [95 %]; runs below / above 0", "",
                "| metric | " + " | ".join(others) + " |", "|---|" + "--:|" * len(others)]
        for key in PAIRED:
            label, dec = METRICS[key]
            cells = []
            for m in others:
                d = (wide.xs(m, level="method")[key]
                     - wide.xs(reference, level="method")[key]).to_numpy(float)
                d = d[np.isfinite(d)]
                mean, lo, hi = t_interval(d)
                med, mlo, mhi = median_interval(d)
                cells.append(f"{_fmt(mean, dec, '+')} [{_fmt(lo, dec, '+')}, "
                             f"{_fmt(hi, dec, '+')}]; {_fmt(med, dec, '+')} "
                             f"[{_fmt(mlo, dec, '+')}, {_fmt(mhi, dec, '+')}]; "
                             f"{(d < 0).sum()} / {(d > 0).sum()}")
            out.append(f"| {label} | " + " | ".join(cells) + " |")
        means = mean_gospa(tables)
        out.append(f"| mean GOSPA ratio (method / {reference}) | " + " | ".join(
            f"{means[m] / means[reference]:.3f}" for m in others) + " |")
    return out


def renamed(tables: Any, suffix: str, taken: set[str]) -> Any:
    """``tables`` with each method whose name is in ``taken`` renamed ``NAME@suffix``."""
    names = {m.name: f"{m.name}@{suffix}" for m in tables.study.methods if m.name in taken}
    if not names:
        return tables
    study = dataclasses.replace(tables.study, methods=tuple(
        dataclasses.replace(m, name=names.get(m.name, m.name)) for m in tables.study.methods))

    def frame(name: str) -> Any:
        df = getattr(tables, name)
        return df.assign(method=df["method"].astype(str).replace(names))

    return dataclasses.replace(tables, study=study, **{
        n: frame(n) for n in ("steps", "decisions", "sensors", "tracks", "gospa")})


def join(parts: list[Any], other_scenario: bool = False) -> Any:
    """The tables of several parts of one study as the tables of one study: same scenario,
    seed, run count, steps and study-wide settings, distinct method names; the runs
    finished in every part. ``other_scenario``: the scenarios may differ (the runs are
    still paired by their random streams)."""
    import pandas as pd

    first = parts[0].study
    for p in parts[1:]:
        for key in ("scenario", "seed", "runs", "steps"):
            if key == "scenario" and other_scenario:
                continue
            if getattr(p.study, key) != getattr(first, key):
                raise ConfigError("--with", f"the studies differ in {key}; their runs are "
                                            "not paired")
    methods = tuple(m for p in parts for m in p.study.methods)
    try:
        study = dataclasses.replace(first, methods=methods)
    except ValueError as exc:        # a repeated method name or a different study-wide key
        raise ConfigError("--with", str(exc)) from None
    runs = sorted(set.intersection(*(set(p.runs_done) for p in parts)))
    order = pd.CategoricalDtype(study.method_names, ordered=True)

    def frame(name: str) -> Any:
        df = pd.concat([getattr(p, name)[getattr(p, name)["run"].isin(runs)].astype(
            {"method": str}) for p in parts], ignore_index=True)
        return df.astype({"method": order})

    return dataclasses.replace(
        parts[0], study=study, steps=frame("steps"), decisions=frame("decisions"),
        sensors=frame("sensors"), tracks=frame("tracks"), gospa=frame("gospa"),
        complete=all(p.complete for p in parts), runs_done=runs)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study_dir")
    parser.add_argument("--with", dest="others", action="append", default=[],
                        metavar="OTHER_DIR", help="another part of the same study to join")
    parser.add_argument("--other-scenario", action="store_true",
                        help="the --with directories may have another scenario (the same "
                             "seed, runs and steps: run r has the same random streams, so "
                             "the runs stay paired); a method name that repeats gets the "
                             "directory's name appended, NAME@DIR")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--reference",
                       help="the method the paired differences are taken against "
                            "(default: myopic, where the study has it)")
    which.add_argument("--best-of", metavar="PREFIX",
                       help="take them against the method named PREFIX... with the lowest "
                            "mean GOSPA")
    args = parser.parse_args(argv)
    dirs = [args.study_dir, *args.others]
    try:
        parts = [load_study_dir(d) for d in dirs]
        if args.other_scenario:
            taken = {m.name for m in parts[0].study.methods}
            for i in range(1, len(parts)):
                parts[i] = renamed(parts[i], Path(dirs[i]).name, taken)
                taken |= {m.name for m in parts[i].study.methods}
        tables = join(parts, args.other_scenario) if len(parts) > 1 else parts[0]
    except ConfigError as err:
        parser.error(str(err))
    if not tables.complete:
        sys.stderr.write(f"note: {len(tables.runs_done)} of {tables.study.runs} runs finished "
                         "in every directory; the tables use those\n")
    reference, head = args.reference or "myopic", []
    names = [m.name for m in tables.study.methods]
    if args.reference is not None and args.reference not in names:
        parser.error(f"--reference: no method {args.reference!r} in the study (its methods: "
                     f"{', '.join(names)})")
    if args.best_of is not None:
        try:
            reference, head = best_of_lines(tables, args.best_of)
        except ValueError as err:
            parser.error(str(err))
    print("\n".join(head + summary_lines(tables, reference)))


if __name__ == "__main__":
    main()
