"""The report of a grid study (``sensorplan report DIR`` on a directory with ``grid.json``).

Per comparison: a heat map of the paired mean RMSE difference over the cells
(:mod:`.grid_figures`), a table per cell and a verdict (cells where the method is
significantly better, worse, or neither). A grid of changing sets (a method with a
multi-target tracker, or targets born and dying: :func:`~sensorplan.study.grid_run.
judged_by`) is judged by the run's mean GOSPA instead, since a multi-target tracker's RMSE
and ANEES cover only the target-steps that have an assigned track. Every number comes from
:func:`sensorplan.study.grid_run.grid_statistics`, which applies the study metrics to each
cell's directory; this module only formats. Written like a study report: ``report.html``
(figures embedded), ``summary.md``, the PNGs and ``grid_statistics.csv`` (the numbers of
the tables).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..study.grid_run import grid_statistics, method_statistics
from ..study.metrics import DIVERGED_THRESHOLD, LOST_THRESHOLD
from .document import ReportFiles, _ci, _Doc, _f
from .grid_figures import (AXIS_METRICS, SET_AXIS_METRICS, draw_axis_lines, draw_heatmap,
                           heatmap_panels, heatmap_values)
from .headline import SMALL_SAMPLE

VERDICTS = ("better", "worse", "inconclusive", "not run")


def write_grid_report(grid_dir: str | Path, out: str | Path | None = None) -> ReportFiles:
    """Write ``report.html``, ``summary.md``, one heat map per comparison
    (``heatmap_K.png``) and ``grid_statistics.csv`` for a grid directory.

    Parameters
    ----------
    grid_dir : path
        Written by :func:`sensorplan.study.grid_run.run_grid`; cells that have not run
        (or not finished a run) are grey "not run" cells.
    out : path, optional
        Report directory (default ``grid_dir/report``).

    Returns
    -------
    ReportFiles
        ``complete``: every cell finished; ``runs``: finished paired runs over all cells.
    """
    grid_dir = Path(grid_dir)
    info, stats = grid_statistics(grid_dir)
    out = Path(out) if out is not None else grid_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    for stale in out.glob("heatmap_*.png"):
        stale.unlink()
    by_gospa = info["judged_by"] == "gospa"
    panels = heatmap_panels(info)
    figs: dict[str, Path] = {}
    for k, comp in enumerate(info["comparisons"]):
        rows = stats[stats["comparison"] == k]
        values = [heatmap_values(p, rows) for p in panels]
        name = f"heatmap_{k + 1}"
        figs[name] = draw_heatmap(panels, values, comp["label"], info["runs"],
                                  out / f"{name}.png", "GOSPA" if by_gospa else "RMSE")
    stats.assign(label=[info["comparisons"][k]["label"] for k in stats["comparison"]]).to_csv(
        out / "grid_statistics.csv", index=False)
    methods = method_statistics(grid_dir)
    methods.to_csv(out / "method_statistics.csv", index=False)
    (out / "methods.png").unlink(missing_ok=True)
    lines = draw_axis_lines(info, methods, out / "methods.png",
                            SET_AXIS_METRICS if by_gospa else AXIS_METRICS)
    if lines is not None:
        figs["methods"] = lines
    doc = _document(info, stats, figs, grid_dir, methods)
    md, page = out / "summary.md", out / "report.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    page.write_text(doc.html(f"sensorplan grid report: {grid_dir.name}"), encoding="utf-8")
    per_cell = stats.drop_duplicates("cell")
    return ReportFiles(page, md, figs, bool((per_cell["status"] == "complete").all()),
                       int(per_cell["runs_done"].sum()))


def verdicts(stats: Any) -> dict[str, int]:
    """Cells per verdict of one comparison's rows: ``better`` (the 95 % interval of the
    paired mean difference lies below 0), ``worse`` (above 0), ``inconclusive`` and
    ``not run``."""
    counts = stats["verdict"].value_counts()
    return {v: int(counts.get(v, 0)) for v in VERDICTS}


def _verdict_text(label: str, count: dict[str, int]) -> str:
    ran = count["better"] + count["worse"] + count["inconclusive"]
    text = (f"**{label}**: better in {count['better']} of {ran} cells, worse in "
            f"{count['worse']}, inconclusive in {count['inconclusive']}")
    return text + (f" ({count['not run']} not run)." if count["not run"] else ".")


def _cell_row(r: Any, runs: int, sets: tuple[bool, bool] | None = None) -> list[str]:
    """One cell's row; ``sets`` (a grid judged by GOSPA): whether the method and the
    reference have a multi-target tracker, whose diverged count means nothing (its errors
    are those of tracks within the cut-off)."""
    if r.verdict == "not run":
        return [r.cell, "0"] + ["–"] * (9 if sets is None else 11) + ["not run"]
    head = [r.cell, str(r.n) + ("" if r.status == "complete" else f" of {runs}"),
            _ci(r.mean, r.mean_lo, r.mean_hi), _ci(r.median, r.median_lo, r.median_hi),
            f"{100 * r.better_share:.0f} %"]
    if sets is None:
        return head + [_f(r.anees_method, 2), _f(r.anees_reference, 2),
                       f"{r.diverged_method} of {r.n}", f"{r.diverged_reference} of {r.n}",
                       _f(r.ms_method, 1), _f(r.ms_reference, 1), r.verdict]
    return head + [_ci(r.gospa_method, r.gospa_method_lo, r.gospa_method_hi),
                   _ci(r.gospa_reference, r.gospa_reference_lo, r.gospa_reference_hi),
                   _f(r.anees_method, 2), _f(r.anees_reference, 2),
                   "–" if sets[0] else f"{r.diverged_method} of {r.n}",
                   "–" if sets[1] else f"{r.diverged_reference} of {r.n}",
                   _f(r.ms_method, 1), _f(r.ms_reference, 1), r.verdict]


def _document(info: dict[str, Any], stats: Any, figs: dict[str, Path],
              grid_dir: Path, methods: Any) -> _Doc:
    doc = _Doc()
    doc.h(1, "Grid study report" + (f": {info['description']}" if info["description"] else ""))
    comps = info["comparisons"]
    by_gospa = info["judged_by"] == "gospa"
    sets = set(info["set_methods"])
    rule = ("Better or worse: the 95 % paired t-interval of the mean RMSE difference "
            "(method minus reference, all targets) in that cell lies entirely below "
            "or above zero; inconclusive otherwise.")
    if by_gospa:
        rule = ("Better or worse: the 95 % paired t-interval of the mean GOSPA difference "
                "(method minus reference; a run's GOSPA is its mean over steps 1..S) in that "
                "cell lies entirely below or above zero; inconclusive otherwise. "
                + _why_gospa(info))
    doc.headline([_verdict_text(c["label"], verdicts(stats[stats["comparison"] == k]))
                  for k, c in enumerate(comps)] + [rule])
    status = stats.drop_duplicates("cell").set_index("cell")["status"]
    n_run = int((status != "not run").sum())
    doc.p(f"{info['design'].capitalize()} design over {len(info['axes'])} axes: "
          f"{len(info['cells'])} cells ({n_run} with results), each a study of "
          f"{len(info['methods'])} methods on {info['runs']} paired runs of {info['steps']} "
          f"steps, seed {info['seed']}. Every cell uses the same seed, so run r of every "
          "cell starts from the same random streams (common random numbers), and within a "
          "cell every method runs on the same paired runs.")
    doc.toc()

    doc.h(2, "Design")
    doc.table(["axis", "feature", "values", "base"],
              [[a["name"], a["feature"], ", ".join(a["labels"]),
                "–" if a["base_index"] is None else a["labels"][a["base_index"]]]
               for a in info["axes"]])
    doc.table(["cell", *(a["name"] for a in info["axes"]), "status", "runs done"],
              [[c["slug"], *(c["values"][a["name"]] for a in info["axes"]),
                status[c["slug"]], str(int(stats[stats["cell"] == c["slug"]]
                                           ["runs_done"].iloc[0]))]
               for c in info["cells"]],
              caption="cells in run order; DIR/<cell> is an ordinary study directory "
                      "(sensorplan report DIR/<cell> reports it in full)")
    notes = list(dict.fromkeys(n for c in info["cells"] for n in c.get("notes", [])))
    if notes:
        doc.p("Setting axes: " + "; ".join(notes) + ".")

    for k, comp in enumerate(comps):
        rows = stats[stats["comparison"] == k]
        doc.h(2, comp["label"])
        small = rows[(rows["verdict"] != "not run") & (rows["n"] < SMALL_SAMPLE)]
        few = (f" (n < {SMALL_SAMPLE} runs in some cells: intervals unreliable)"
               if len(small) else "")
        if by_gospa:
            doc.p(f"Method `{comp['method']}` minus reference `{comp['reference']}`, run by "
                  f"run within each cell: the run's mean GOSPA over steps 1..S (cut-off c = "
                  f"{info['gospa_c']:g} m).")
            doc.figure(f"heatmap_{k + 1}", figs[f"heatmap_{k + 1}"], _caption(info, comp))
            pair = (comp["method"] in sets, comp["reference"] in sets)
            doc.table(["cell", "n", "\u0394 GOSPA mean (m)", "\u0394 GOSPA median (m)",
                       "runs better", "GOSPA method (m)", "GOSPA reference (m)",
                       "ANEES method" + (" (assigned tracks)" if pair[0] else ""),
                       "ANEES reference" + (" (assigned tracks)" if pair[1] else ""),
                       "diverged method", "diverged reference", "ms/decision method",
                       "ms/decision reference", "verdict"],
                      [_cell_row(r, info["runs"], pair) for r in rows.itertuples()],
                      caption="mean [95 % paired t-interval], median [95 % order-statistic "
                              "interval]; GOSPA of each side: mean [95 % t-interval]; ANEES: "
                              "average NEES over steps 1..S (4 for an honest filter; for a "
                              "multi-target tracker over the target-steps with an assigned "
                              "track); diverged: runs whose largest error exceeds "
                              f"{DIVERGED_THRESHOLD:g} m (–: a multi-target tracker, whose "
                              "assigned tracks lie within the cut-off); ms/decision: mean "
                              "wall time of a planning decision" + few)
        else:
            doc.p(f"Method `{comp['method']}` minus reference `{comp['reference']}`, run by "
                  "run within each cell: position RMSE over steps 1..S and all targets.")
            doc.figure(f"heatmap_{k + 1}", figs[f"heatmap_{k + 1}"], _caption(info, comp))
            doc.table(["cell", "n", "\u0394 RMSE mean (m)", "\u0394 RMSE median (m)",
                       "runs better", "ANEES method", "ANEES reference", "diverged method",
                       "diverged reference", "ms/decision method", "ms/decision reference",
                       "verdict"],
                      [_cell_row(r, info["runs"]) for r in rows.itertuples()],
                      caption="mean [95 % paired t-interval], median [95 % order-statistic "
                              "interval]; ANEES: average NEES over steps 1..S (4 for an "
                              f"honest filter); diverged: runs whose largest error exceeds "
                              f"{DIVERGED_THRESHOLD:g} m; ms/decision: mean wall time of a "
                              "planning decision" + few)
        doc.p(_verdict_text("Verdict", verdicts(rows)))

    doc.h(2, "Methods across the cells")
    if by_gospa:
        _methods_by_gospa(doc, info, methods, figs, sets)
    else:
        doc.p("Each method on its own, per cell, over all targets: mean position RMSE and "
              "share of lost target-steps (error above 50 m), each with its 95 % t-interval "
              "across runs, the ANEES and the runs that diverged.")
        if "methods" in figs:
            doc.figure("methods", figs["methods"], "Each method's mean RMSE, lost share and "
                       "ANEES along each axis, the other axes at their base values; error "
                       "bars: 95 % t-intervals across runs; dotted: the ANEES of an honest "
                       "filter (4).")
        doc.table(["cell", "method", "runs", "RMSE mean (m)", "lost target-steps", "ANEES",
                   "diverged"],
                  [[r.cell, r.method, str(r.n), _ci(r.rmse, r.rmse_lo, r.rmse_hi),
                    _ci(r.lost, max(r.lost_lo, 0.0), min(r.lost_hi, 1.0), pct=True),
                    _f(r.anees, 2),
                    f"{r.diverged} of {r.n}"] for r in methods.itertuples()],
                  caption=f"diverged: runs whose largest error exceeds "
                          f"{DIVERGED_THRESHOLD:g} m")

    doc.h(2, "Files")
    doc.p(f"`{grid_dir.name}/grid.json` (the grid with every cell), one study directory per "
          "cell, `grid_statistics.csv` (one row per comparison and cell) and "
          "`method_statistics.csv` (one row per cell and method): the numbers of the "
          "tables; regenerate this report with `sensorplan report DIR`.")
    return doc


def _why_gospa(info: dict[str, Any]) -> str:
    names = ", ".join(f"`{n}`" for n in info["set_methods"])
    who = (f"{names} track{'s' if len(info['set_methods']) == 1 else ''} with a multi-target "
           "tracker" if names else "the targets are born and die")
    return (f"Judged by GOSPA because {who}: such a tracker's RMSE and ANEES cover only the "
            "target-steps that have an assigned track, so they leave out the targets it "
            "misses; GOSPA charges c^2/2 for each missed target and each false track.")


def _methods_by_gospa(doc: _Doc, info: dict[str, Any], methods: Any, figs: dict[str, Path],
                      sets: set[str]) -> None:
    """The methods table of a grid judged by GOSPA."""
    c = info["gospa_c"]
    doc.p("Each method on its own, per cell: mean GOSPA (the run's mean over steps 1..S, "
          f"cut-off c = {c:g} m) with its 95 % t-interval across runs and its localisation, "
          "missed and false parts (mean contributions to GOSPA^2, m^2); then position RMSE, "
          "lost target-steps, ANEES and diverged runs. For a multi-target tracker ("
          + (", ".join(f"`{n}`" for n in sorted(sets)) or "none here")
          + ") RMSE and ANEES are over the target-steps with an assigned track (a track "
          "within c), and a lost target-step is one without an assigned track (GOSPA's "
          "missed part); for the tracker of known targets they are over all targets and "
          f"lost means an error above {LOST_THRESHOLD:g} m.")
    if "methods" in figs:
        doc.figure("methods", figs["methods"], "Each method's mean GOSPA, lost share and "
                   "ANEES along each axis, the other axes at their base values; error bars: "
                   "95 % t-intervals across runs; dotted: the ANEES of an honest filter (4). "
                   "A multi-target tracker's lost share counts target-steps without an "
                   "assigned track, its ANEES is over assigned tracks.")
    doc.table(["cell", "method", "runs", "GOSPA mean (m)", "localisation", "missed", "false",
               "RMSE mean (m)", "lost target-steps", "ANEES", "RMSE, ANEES over",
               "diverged"],
              [[r.cell, r.method, str(r.n), _ci(r.gospa, r.gospa_lo, r.gospa_hi),
                _f(r.localisation), _f(r.missed), _f(r.false),
                _ci(r.rmse, r.rmse_lo, r.rmse_hi),
                _ci(r.lost, max(r.lost_lo, 0.0), min(r.lost_hi, 1.0), pct=True),
                _f(r.anees, 2),
                "assigned tracks" if r.method in sets else "all targets",
                "–" if r.method in sets else f"{r.diverged} of {r.n}"]
               for r in methods.itertuples()],
              caption=f"GOSPA parts in m^2; diverged: runs whose largest error exceeds "
                      f"{DIVERGED_THRESHOLD:g} m (–: a multi-target tracker)")


def _caption(info: dict[str, Any], comp: dict[str, Any]) -> str:
    layout = ("One row per axis, one column per value, the other axes at their base values; "
              "the base cell (value marked \"(base)\") appears in every row."
              if info["design"] == "star" else
              "Rows: the first axis, columns: the second"
              + (", one panel per value of the others." if len(info["axes"]) > 2 else "."))
    what = ("GOSPA difference" if info["judged_by"] == "gospa" else "RMSE difference")
    over = "run means over steps" if info["judged_by"] == "gospa" else "all targets"
    return (f"Paired mean {what} {comp['method']} minus {comp['reference']} (m, {over}) "
            "per cell, with its 95 % t-interval; blue: the method tracks better, "
            "red: worse, on one scale centred at 0. A thick black border marks a cell whose "
            "interval excludes 0; grey cells have not run. " + layout
            + " A third line gives the runs finished in an unfinished cell.")
