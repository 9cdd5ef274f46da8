"""Figures and tables of the decentralized-planning evidence.

    python scripts/decentral_figures.py DIR_PAPER DIR_HOLES [DIR_OPENLOOP] \\
        [--out docs/figures/decentral]

``DIR_PAPER`` and ``DIR_HOLES`` are finished (or partly finished) study directories of
``studies/decentral.toml`` and ``studies/decentral_holes.toml``; ``DIR_OPENLOOP`` is the
output of ``scripts/decentral_potential.py``. Every number comes from the study metrics
(``sensorplan.study``: ``run_metrics``, ``summary``, ``paired_differences``,
``consistency``) or from the open-loop script's summary; this script only selects and
draws them.

Methods are recognised by their settings, not their names: ``pg``; ``dec-independent``;
``dec-sequential`` at each ``p_loss``; ``dec-jsfp`` without loss at each round budget R (the
budget of the planner's default drawn apart, labelled) and ``dec-jsfp`` with the default
budget at each ``p_loss`` (the no-loss point is the default-budget method). Delay and range
other than perfect, and other modes, are left to the tables.

Writes into ``--out``:

- ``rmse_rounds.png``, ``rmse_loss.png``: closed-loop RMSE over all targets (mean with its
  95 % t-interval) against R and against p_loss, one panel per scenario, with pg,
  dec-independent and (against R) dec-sequential as reference lines (dashed: mean, dotted:
  the ends of its 95 % t-interval); one colour per planner (the method palette);
- ``phi_rounds.png``, ``phi_loss.png`` (with ``DIR_OPENLOOP``): Phi / Phi(pg) on the paper
  and holes decisions and Phi / Phi* on the tiny problems, mean with its 95 % t-interval,
  against R and against p_loss;
- ``summary.csv`` and ``summary.md``: per scenario and method, RMSE mean and median with
  intervals, the paired difference against pg, ANEES with its chi-square band, the share
  of NEES above the 99 % point, and the runs that diverged.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sensorplan.errors import ConfigError
from sensorplan.figures.colors import method_colors, mix_hex
from sensorplan.decentral import DecentralJSFPPlanner
from sensorplan.study import (
                              DIVERGED_THRESHOLD,
                              consistency,
                              kinds_with_all,
                              load_study_dir,
                              paired_differences,
                              run_metrics,
                              summary,
                              )

#: The round budget of ``dec-jsfp`` when a method does not set it.
DEFAULT_ROUNDS = next(f.default for f in dataclasses.fields(DecentralJSFPPlanner)
                      if f.name == "rounds")
SCENARIOS = ("paper", "holes")
TITLES = {"paper": "paper preset", "holes": "sensor holes", "tiny": "tiny problems"}


def role(planner: str, params: dict[str, Any]) -> tuple[str, float] | None:
    """Where a method goes in the figures: ``(family, x)`` or None.

    ``("pg", 0)``, ``("independent", 0)``, ``("sequential", p_loss)``, ``("rounds", R)``
    (dec-jsfp without loss) and ``("loss", p_loss)`` (dec-jsfp with the default budget,
    p_loss > 0); only perfect delay and range, and the JSFP mode, are placed.
    """
    if planner == "pg":
        return "pg", 0.0
    if params.get("delay", 0) != 0 or params.get("comm_range", math.inf) != math.inf:
        return None
    if params.get("mode", "jsfp") != "jsfp":
        return None
    if planner == "dec-independent":
        return "independent", 0.0
    if planner == "dec-sequential":
        return "sequential", float(params.get("p_loss", 0.0))
    if planner == "dec-jsfp":
        p, rounds = float(params.get("p_loss", 0.0)), int(params.get("rounds", DEFAULT_ROUNDS))
        if p == 0.0:
            return "rounds", float(rounds)
        if rounds == DEFAULT_ROUNDS:
            return "loss", p
    return None


def closed_loop_table(study_dir: str | Path, scenario: str) -> pd.DataFrame:
    """Per method of a study: its role and every statistic of the tables (see module)."""
    t = load_study_dir(study_dir)
    study = t.study
    kind = kinds_with_all(study)[-1]                  # "all" when there are several kinds
    metrics = run_metrics(t)
    rmse = summary(metrics, "rmse")
    rmse = rmse[rmse["kind"] == kind].set_index("method")
    pg = next((m.name for m in study.methods if m.settings.planner == "pg"), None)
    refs = {m.name: {"pg": pg} for m in study.methods if m.name != pg}
    diffs = paired_differences(metrics, study, "rmse", refs=refs)
    diffs = (diffs[diffs["kind"] == kind].set_index("method") if len(diffs)
             else pd.DataFrame(columns=["mean", "mean_lo", "mean_hi"]))
    cons = consistency(t)
    cons = cons[cons["kind"] == kind].set_index("method")
    rows = []
    for m in study.methods:
        params = dict(m.settings.planner_params)
        r = role(m.settings.planner, params)
        rows.append(dict(
            scenario=scenario, method=m.name, planner=m.settings.planner,
            rounds=params.get("rounds", math.nan), p_loss=params.get("p_loss", math.nan),
            family=r[0] if r else "", x=r[1] if r else math.nan,
            runs=int(rmse.loc[m.name, "n"]), rmse_mean=rmse.loc[m.name, "mean"],
            rmse_lo=rmse.loc[m.name, "mean_lo"], rmse_hi=rmse.loc[m.name, "mean_hi"],
            rmse_median=rmse.loc[m.name, "median"],
            rmse_median_lo=rmse.loc[m.name, "median_lo"],
            rmse_median_hi=rmse.loc[m.name, "median_hi"],
            diff_pg_mean=diffs["mean"].get(m.name, math.nan),
            diff_pg_lo=diffs["mean_lo"].get(m.name, math.nan),
            diff_pg_hi=diffs["mean_hi"].get(m.name, math.nan),
            anees=cons.loc[m.name, "anees"], anees_band_lo=cons.loc[m.name, "band_lo"],
            anees_band_hi=cons.loc[m.name, "band_hi"],
            nees_high_share=cons.loc[m.name, "high_share"],
            diverged=int(cons.loc[m.name, "diverged"])))
    return pd.DataFrame(rows)


def open_loop_table(openloop_dir: str | Path) -> pd.DataFrame:
    """The open-loop summary with each method's role (from the script's ``meta.json``)."""
    import json

    d = Path(openloop_dir)
    table = pd.read_csv(d / "summary.csv")
    table = table[table["set"].isin(("paper", "holes", "tiny"))]      # not the subgroup
    meta = json.loads((d / "meta.json").read_text())
    specs = {s["name"]: s for s in meta["methods"]["paper"]}
    roles = [role(specs[m]["planner"], specs[m]["params"]) if m in specs else None
             for m in table["method"]]
    table["family"] = [r[0] if r else "" for r in roles]
    table["x"] = [r[1] if r else math.nan for r in roles]
    return table


def _fmt(v: float, lo: float, hi: float, digits: int = 2) -> str:
    if math.isnan(v):
        return "-"
    if math.isnan(lo):
        return f"{v:.{digits}f}"
    return f"{v:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def markdown(table: pd.DataFrame) -> str:
    """The closed-loop table as markdown, one table per scenario."""
    out = []
    for scenario, g in table.groupby("scenario", sort=False):
        caption = (f"**{TITLES.get(scenario, scenario)}** ({int(g['runs'].max())} runs; "
                   "RMSE over all targets, m; method - pg: paired difference, run by run; "
                   "ANEES with its 95 % chi-square band; NEES > 13.28: share above the 99 % "
                   "point of chi-square(4); diverged: runs with an error above "
                   f"{DIVERGED_THRESHOLD:g} m)")
        header = ("| method | RMSE mean [95 % CI] | RMSE median [95 % CI] | "
                  "method - pg [95 % CI] | ANEES [band] | NEES > 13.28 | diverged |")
        out += [caption, "", header, "|---|---|---|---|---|---|---|"]
        for r in g.itertuples():
            out.append(
                f"| {r.method} | {_fmt(r.rmse_mean, r.rmse_lo, r.rmse_hi)} | "
                f"{_fmt(r.rmse_median, r.rmse_median_lo, r.rmse_median_hi)} | "
                f"{_fmt(r.diff_pg_mean, r.diff_pg_lo, r.diff_pg_hi)} | "
                f"{_fmt(r.anees, r.anees_band_lo, r.anees_band_hi)} | "
                f"{r.nees_high_share:.1%} | {r.diverged}/{r.runs} |")
        out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------------------- drawing


def _figure(n_panels: int) -> Any:
    from matplotlib.figure import Figure

    return Figure(figsize=(5.0 * n_panels, 4.2), dpi=110, layout="constrained")


def _save(fig: Any, path: Path) -> Path:
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path


#: Families in the method palette's order: one colour per planner, the same in every figure.
FAMILIES = ("pg", "independent", "sequential", "jsfp")


def _colors() -> dict[str, str]:
    """Colour per family (``rounds`` and ``loss`` are both dec-jsfp)."""
    c = method_colors(FAMILIES)
    return dict(c, rounds=c["jsfp"], loss=c["jsfp"])


def _band(ax: Any, row: Any, cols: tuple[str, str, str], color: str, label: str) -> None:
    """A reference: its mean dashed, its interval's ends dotted (no fill: several
    references overlap)."""
    mean, lo, hi = (float(row[c]) for c in cols)
    ax.axhline(mean, color=color, linestyle="--", linewidth=1.4, label=label, zorder=1)
    if not math.isnan(lo):
        for y in (lo, hi):
            ax.axhline(y, color=mix_hex(color, 0.6), linestyle=":", linewidth=1.0, zorder=1)


def _line(ax: Any, g: pd.DataFrame, xs: np.ndarray, cols: tuple[str, str, str], color: str,
          label: str, marker: str = "o") -> None:
    mean, lo, hi = (g[c].to_numpy(float) for c in cols)
    err = np.vstack([mean - lo, hi - mean])
    err = np.where(np.isnan(err), 0.0, err)
    ax.errorbar(xs, mean, yerr=err, color=color, marker=marker, markersize=5, capsize=3,
                linewidth=1.5, label=label, zorder=3)


def _rounds_axis(ax: Any, rounds: np.ndarray) -> np.ndarray:
    """log2 positions of the budgets; the default budget is drawn apart, two steps right."""
    finite = rounds[rounds != DEFAULT_ROUNDS]
    top = np.log2(finite).max() if finite.size else 0.0
    xs = np.where(rounds == DEFAULT_ROUNDS, top + 2.0, np.log2(np.maximum(rounds, 1)))
    labels = [f"{int(r)}\n(default)" if r == DEFAULT_ROUNDS else f"{int(r)}" for r in rounds]
    ax.set_xticks(xs, labels)
    if (rounds == DEFAULT_ROUNDS).any() and finite.size:
        ax.axvline(top + 1.0, color="0.75", linewidth=0.8, linestyle=":")
    return xs


def _panel_rounds(ax: Any, g: pd.DataFrame, cols: tuple[str, str, str], colors: dict[str, str],
                  refs: tuple[str, ...]) -> None:
    jsfp = g[g["family"] == "rounds"].sort_values("x")
    if len(jsfp):
        xs = _rounds_axis(ax, jsfp["x"].to_numpy(float))
        _line(ax, jsfp, xs, cols, colors["rounds"], "dec-jsfp, no loss")
    for fam in refs:
        ref = g[(g["family"] == fam) & (g["x"] == 0.0)]
        if len(ref):
            _band(ax, ref.iloc[0], cols, colors[fam], _REF_LABELS[fam])
    ax.set_xlabel("round budget R per decision")


def _panel_loss(ax: Any, g: pd.DataFrame, cols: tuple[str, str, str],
                colors: dict[str, str], refs: tuple[str, ...]) -> None:
    default = g[(g["family"] == "rounds") & (g["x"] == float(DEFAULT_ROUNDS))]
    jsfp = pd.concat([default.assign(x=0.0), g[g["family"] == "loss"]]).sort_values("x")
    seq = g[g["family"] == "sequential"].sort_values("x")
    dodge = 0.006
    if len(jsfp):
        _line(ax, jsfp, jsfp["x"].to_numpy(float) - dodge, cols, colors["loss"],
              f"dec-jsfp, R = {DEFAULT_ROUNDS}")
    if len(seq):
        _line(ax, seq, seq["x"].to_numpy(float) + dodge, cols, colors["sequential"],
              "dec-sequential", marker="s")
    for fam in refs:
        ref = g[(g["family"] == fam) & (g["x"] == 0.0)]
        if len(ref):
            _band(ax, ref.iloc[0], cols, colors[fam], _REF_LABELS[fam])
    xs = sorted(set(jsfp["x"]) | set(seq["x"]))
    ax.set_xticks(xs, [f"{x:g}" for x in xs])
    ax.set_xlabel("message-loss probability p_loss")


_REF_LABELS = {"pg": "pg (centralized)", "independent": "dec-independent",
               "sequential": "dec-sequential, no loss"}


def draw_closed_loop(table: pd.DataFrame, out: Path) -> list[Path]:
    """``rmse_rounds.png`` and ``rmse_loss.png``: one panel per scenario."""
    cols = ("rmse_mean", "rmse_lo", "rmse_hi")
    colors = _colors()
    scenarios = list(dict.fromkeys(table["scenario"]))
    paths = []
    for name, panel, refs in (("rmse_rounds", _panel_rounds, ("pg", "independent",
                                                               "sequential")),
                              ("rmse_loss", _panel_loss, ("pg", "independent"))):
        fig = _figure(len(scenarios))
        axes = fig.subplots(1, len(scenarios), squeeze=False)[0]
        for ax, scenario in zip(axes, scenarios):
            g = table[table["scenario"] == scenario]
            panel(ax, g, cols, colors, refs)
            ax.set_title(f"{TITLES.get(scenario, scenario)} ({int(g['runs'].max())} runs)")
            ax.set_ylabel("position RMSE, all targets (m)")
            ax.grid(True, axis="y", color="0.9")
        _legend(fig, axes)
        paths.append(_save(fig, out / f"{name}.png"))
    return paths


def draw_open_loop(table: pd.DataFrame, out: Path) -> list[Path]:
    """``phi_rounds.png`` and ``phi_loss.png``: one panel per set of problems."""
    cols = ("mean", "mean_lo", "mean_hi")
    colors = _colors()
    sets = list(dict.fromkeys(table["set"]))
    paths = []
    for name, panel, refs in (("phi_rounds", _panel_rounds, ("pg", "independent",
                                                             "sequential")),
                              ("phi_loss", _panel_loss, ("pg", "independent"))):
        fig = _figure(len(sets))
        axes = fig.subplots(1, len(sets), squeeze=False)[0]
        for ax, set_name in zip(axes, sets):
            g = table[table["set"] == set_name]
            ref = g["reference"].iloc[0]
            if ref == "pg":
                # pg is the reference: its ratio is 1 on every problem.
                g = pd.concat([g, pd.DataFrame([dict(method="pg", family="pg", x=0.0,
                                                     mean=1.0, mean_lo=math.nan,
                                                     mean_hi=math.nan)])])
            panel(ax, g, cols, colors, refs)
            ax.set_title(f"{TITLES.get(set_name, set_name)} ({int(g['n'].max())} problems)")
            ax.set_ylabel("Phi / Phi(pg)" if ref == "pg" else "Phi / Phi* (exact optimum)")
            ax.grid(True, axis="y", color="0.9")
        _legend(fig, axes)
        paths.append(_save(fig, out / f"{name}.png"))
    return paths


def _legend(fig: Any, axes: Any) -> None:
    handles, labels = {}, []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in handles:
                handles[lab] = h
                labels.append(lab)
    from matplotlib.lines import Line2D

    labels.append("reference: 95 % t-interval")
    handles[labels[-1]] = Line2D([], [], color="0.45", linestyle=":", linewidth=1.0)
    fig.legend([handles[lab] for lab in labels], labels, loc="outside lower center",
               ncols=min(len(labels), 5), frameon=False)


def main(argv: list[str] | None = None) -> list[Path]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paper", type=Path, help="study directory of studies/decentral.toml")
    ap.add_argument("holes", type=Path, help="study directory of studies/decentral_holes.toml")
    ap.add_argument("openloop", type=Path, nargs="?",
                    help="output directory of scripts/decentral_potential.py")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/decentral"),
                    help="where the figures and tables go (default docs/figures/decentral)")
    args = ap.parse_args(argv)
    try:
        tables = [closed_loop_table(d, s) for d, s in zip((args.paper, args.holes),
                                                           SCENARIOS)]
    except ConfigError as err:
        ap.error(str(err))
    args.out.mkdir(parents=True, exist_ok=True)
    table = pd.concat(tables, ignore_index=True)
    table.to_csv(args.out / "summary.csv", index=False)
    (args.out / "summary.md").write_text(markdown(table), encoding="utf-8")
    paths = [args.out / "summary.csv", args.out / "summary.md"]
    paths += draw_closed_loop(table, args.out)
    if args.openloop is not None:
        paths += draw_open_loop(open_loop_table(args.openloop), args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return paths


if __name__ == "__main__":
    main()
