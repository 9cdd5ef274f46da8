"""Set metrics of a finished grid of multi-target trackers, cell by cell, with the tails.

For each cell of a grid directory (``studies/search_conditions.toml``) and each method, per
run over steps 1..S: mean GOSPA (c = 50 m) and its localisation, missed and false parts
(the gospa table); the share of live target-steps without a reported track within c (the
missed part's count: ``missed / (c^2 / 2)`` over the live targets); false tracks per step;
targets lost (a live target without a track within c for 20 or more consecutive steps,
:func:`sensorplan.study.set_metrics.set_metrics` on the steps and tracks tables); and the
ANEES of assigned tracks (target-steps whose estimate is within c: the track GOSPA assigns
for a multi-target tracker, the target's own track for the tracker of known targets).
Across runs: mean with its 95 % t-interval, median and max; then the paired differences
METHOD - REFERENCE per run (mean with its paired 95 % t-interval, median with its
order-statistic interval, share of runs below 0); then where METHOD lost its targets: the
distance to the map's nearest wall at the start of each lost target's longest stretch
without a track, against all of its live target-steps. Markdown on stdout.

    python scripts/search_conditions.py GRID_DIR [--method pmb --reference known]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import median_interval, t_interval
from sensorplan._types import FloatArray
from sensorplan.study.set_metrics import GOSPA_CUTOFF, LOST_STEPS, set_metrics
from sensorplan.study.storage import load_study_dir

#: What each per-run metric is called in the tables, and how many decimals it gets.
METRICS = {"gospa": ("mean GOSPA (m)", 2), "localisation": ("localisation (m^2)", 0),
           "missed": ("missed part (m^2)", 0), "false": ("false part (m^2)", 0),
           "missed_share": ("target-steps without a track within c (%)", 2),
           "false_tracks": ("false tracks per step", 3), "lost": ("targets lost per run", 3)}


def per_run(tables: Any) -> Any:
    """One row per (method, run): the metrics of the module docstring (ANEES apart)."""
    import pandas as pd

    half_c2 = GOSPA_CUTOFF ** 2 / 2.0
    g = tables.gospa
    runs = g.groupby(["method", "run"], observed=True).agg(
        gospa=("gospa", "mean"), localisation=("localisation", "mean"),
        missed=("missed", "mean"), false=("false", "mean"),
        false_tracks=("false_tracks", "mean"), missed_sum=("missed", "sum"),
        targets=("targets", "sum")).reset_index()
    runs["missed_share"] = 100.0 * runs.pop("missed_sum") / half_c2 / runs.pop("targets")
    steps = tables.steps[tables.steps["step"] >= 1]
    tracks = tables.tracks[tables.tracks["step"] >= 1]
    lost = []
    for (method, run), s in steps.groupby(["method", "run"], observed=True):
        y = tracks[(tracks["method"] == method) & (tracks["run"] == run)]
        sm = set_metrics(s["step"].to_numpy() - 1, s["target"].to_numpy(),
                         s[["x", "y"]].to_numpy(float), y["step"].to_numpy() - 1,
                         y["label"].to_numpy(), y[["x", "y"]].to_numpy(float), GOSPA_CUTOFF,
                         n_steps=tables.study.steps)
        lost.append(dict(method=method, run=run, lost=sm.targets.targets_lost))
    return runs.merge(pd.DataFrame(lost), on=["method", "run"])


def anees_assigned(tables: Any) -> dict[str, tuple[float, int]]:
    """Per method: the mean NEES over the target-steps (1..S) whose estimate is within c,
    and how many there are."""
    s = tables.steps[(tables.steps["step"] >= 1) & (tables.steps["error"] < GOSPA_CUTOFF)]
    return {str(m): (float(g["nees"].mean()), int(g["nees"].notna().sum()))
            for m, g in s.groupby("method", observed=True)}


def lost_at_walls(tables: Any, method: str) -> tuple[FloatArray, FloatArray]:
    """Distance (m) to the map's nearest wall of each target ``method`` lost, at the first
    step of its longest stretch without a track within c; and of every live target-step.

    A target-step has no track within c where its error is missing (a multi-target
    tracker) or at least c (the tracker of known targets' own track)."""
    w, h = tables.study.scenario.world.width, tables.study.scenario.world.height
    s = tables.steps[(tables.steps["step"] >= 1) & (tables.steps["method"] == method)]
    s = s.sort_values(["run", "target", "step"])
    xy = s[["x", "y"]].to_numpy(float)
    wall = np.minimum(np.minimum(xy[:, 0], w - xy[:, 0]), np.minimum(xy[:, 1], h - xy[:, 1]))
    gap = ~(s["error"].to_numpy(float) < GOSPA_CUTOFF)
    key = s["run"].to_numpy(np.int64) * 1_000_000 + s["target"].to_numpy(np.int64)
    out = []
    for rows in np.split(np.arange(len(s)), np.flatnonzero(np.diff(key)) + 1):
        best = cur = start = first = 0
        for k in rows:
            if gap[k]:
                start = k if cur == 0 else start
                cur += 1
                if cur > best:
                    best, first = cur, start
            else:
                cur = 0
        if best >= LOST_STEPS:
            out.append(wall[first])
    return np.asarray(out, dtype=float), wall


def cell_tables(cell_dir: Path, method: str, reference: str) -> list[str]:
    tables = load_study_dir(cell_dir)
    names = [m.name for m in tables.study.methods]
    for flag, name in (("--method", method), ("--reference", reference)):
        if name not in names:
            raise ConfigError(flag, f"no method {name!r} in {cell_dir} (its methods: "
                                    f"{', '.join(names)})")
    runs = per_run(tables)
    anees = anees_assigned(tables)
    out = ["| method | metric | mean [95 %] | median | max |", "|---|---|--:|--:|--:|"]
    for m in (method, reference):
        r = runs[runs["method"] == m]
        for key, (label, dec) in METRICS.items():
            v = r[key].to_numpy(float)
            mean, lo, hi = t_interval(v)
            out.append(f"| {m} | {label} | {mean:.{dec}f} [{lo:.{dec}f}, {hi:.{dec}f}] | "
                       f"{np.median(v):.{dec}f} | {v.max():.{dec}f} |")
        lost = r["lost"].to_numpy(int)
        a, n = anees[m]
        out.append(f"| {m} | lost targets: total; runs with any | {lost.sum()}; "
                   f"{(lost > 0).sum()} of {len(lost)} | | |")
        out.append(f"| {m} | ANEES of assigned tracks (target-steps) | {a:.2f} ({n}) | | |")
    wide = runs.pivot(index="run", columns="method")
    out += ["", f"Paired differences {method} - {reference} (n = {len(wide)} runs):", "",
            "| metric | mean [paired 95 %] | median [95 %] | runs below 0 | runs above 0 |",
            "|---|--:|--:|--:|--:|"]
    for key, (label, dec) in METRICS.items():
        d = (wide[(key, method)] - wide[(key, reference)]).to_numpy(float)
        mean, lo, hi = t_interval(d)
        med, mlo, mhi = median_interval(d)
        out.append(f"| {label} | {mean:.{dec}f} [{lo:.{dec}f}, {hi:.{dec}f}] | "
                   f"{med:.{dec}f} [{mlo:.{dec}f}, {mhi:.{dec}f}] | {(d < 0).sum()} | "
                   f"{(d > 0).sum()} |")
    lost, wall = lost_at_walls(tables, method)
    if lost.size:
        out += ["", f"Where {method} lost its {lost.size} targets: within 50 m of a wall "
                f"{100 * (lost < 50).mean():.0f} % (of all its live target-steps: "
                f"{100 * (wall < 50).mean():.0f} %), within 25 m {100 * (lost < 25).mean():.0f} "
                f"%, median distance {np.median(lost):.0f} m."]
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grid_dir")
    parser.add_argument("--method", default="pmb")
    parser.add_argument("--reference", default="known")
    args = parser.parse_args(argv)
    root = Path(args.grid_dir)
    if not (root / "grid.json").is_file():
        parser.error(f"grid_dir: {root} is not a grid directory (no grid.json)")
    info = json.loads((root / "grid.json").read_text())
    try:
        for cell in info["cells"]:
            print(f"### {cell['slug']}\n")
            print("\n".join(cell_tables(root / cell["slug"], args.method, args.reference)))
            print()
    except ConfigError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
