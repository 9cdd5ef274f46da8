"""The report's search section: what search looks did to the intensity of undetected targets.

Shown only for a study in which some method searches (``search = "on"``). From the
``gospa`` table's ``undetected`` and ``intensity`` columns (written for every method whose
tracker keeps an undetected intensity, :data:`sensorplan.study.tables.TABLE_DOC`):

- the expected number of undetected targets over time, per method, mean across runs with
  its 95 % t-interval (``undetected_count``);
- the intensity itself at the stored steps of one representative run, per method, as small
  multiples on one colour scale (``undetected_maps``): the run whose curve of expected
  undetected targets, averaged over those methods, lies nearest (root mean square over the
  steps) to the same curve's mean over runs; every method on that same run, so the maps
  compare methods on the same truth;
- GOSPA's three parts over time, per method, mean across runs with its 95 % t-interval
  (``gospa_parts_time``; GOSPA itself is the GOSPA section's ``gospa_time``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..figures.colors import INTENSITY_CMAP
from ..simulation.run import intensity_grid_shape
from ..study.metrics import LEVEL, t_interval
from ..study.storage import StudyTables
from .figures import _method_colors, _method_styles, _new_figure, _save

#: Captions of the search section's figures.
SEARCH_FIGURES = {
    "undetected_count": "Expected number of undetected targets (the sum of the tracker's "
                        "undetected intensity) after each step, one line per method whose "
                        "tracker keeps one; mean across runs, the band its 95 % t-interval.",
    "undetected_maps": "The undetected intensity (expected targets per km\u00b2) at the "
                       "stored steps of run {run}, the representative run: the one whose "
                       "expected number of undetected targets over time, averaged over the "
                       "methods, lies nearest (root mean square over the steps) to its mean "
                       "over runs. One row per method on that same run (the same truth), "
                       "one colour scale for all panels.",
    "gospa_parts_time": "GOSPA's three parts over time (localisation of the assigned tracks, "
                        "missed targets, false tracks; m\u00b2, summing to GOSPA\u00b2), one "
                        "line per method; mean across runs, the band its 95 % t-interval.",
}


def searching(study: Any) -> bool:
    """Whether some method of the study searches (the search section applies)."""
    return any(m.settings.search == "on" for m in study.methods)


def intensity_methods(t: StudyTables) -> list[str]:
    """The methods whose runs recorded an undetected intensity, in study order."""
    g = t.gospa
    if "undetected" not in g:
        return []
    has = g.groupby("method", observed=True)["undetected"].apply(lambda v: v.notna().any())
    return [n for n in t.study.method_names if bool(has.get(n, False))]


def over_time(t: StudyTables, column: str, methods: list[str] | None = None,
              level: float = LEVEL) -> Any:
    """Mean of a ``gospa`` table column at each step per method, with its t-interval
    across runs (clipped at 0: every column drawn is a count or a square).

    Columns: method, step, mean, lo, hi, n.
    """
    import pandas as pd

    rows = []
    names = t.study.method_names if methods is None else methods
    g = t.gospa
    for name in names:
        wide = g[g["method"] == name].pivot(index="run", columns="step", values=column)
        mean, lo, hi = t_interval(wide.to_numpy(float), level, axis=0)
        rows.append(pd.DataFrame(dict(method=name, step=wide.columns.to_numpy(), mean=mean,
                                      lo=np.clip(lo, 0.0, None), hi=hi,
                                      n=wide.notna().sum(axis=0).to_numpy())))
    return pd.concat(rows, ignore_index=True)


def representative_run(t: StudyTables, methods: list[str]) -> int:
    """The run whose expected number of undetected targets over time, averaged over
    ``methods``, lies nearest (root mean square over the steps) to that curve's mean over
    runs; the lowest such run on a tie."""
    g = t.gospa[t.gospa["method"].isin(methods)]
    curve = g.groupby(["run", "step"], observed=True)["undetected"].mean().unstack("step")
    curve = curve.loc[[r for r in t.runs_done if r in curve.index]]
    values = curve.to_numpy(float)
    distance = np.sqrt(np.nanmean((values - np.nanmean(values, axis=0)) ** 2, axis=1))
    return int(curve.index[int(np.argmin(distance))])


def intensity_maps(t: StudyTables, run: int, method: str) -> tuple[list[int], np.ndarray]:
    """The stored steps of (run, method)'s intensity and the grids ``(k, ny, nx)``, expected
    undetected targets per cell, row 0 at the map's bottom edge."""
    g = t.gospa
    rows = g[(g["run"] == run) & (g["method"] == method) & g["intensity"].notna()]
    rows = rows.sort_values("step")
    m = t.study.methods[t.study.method_names.index(method)]
    shape = intensity_grid_shape(t.study.scenario, m.settings.tracker)
    grids = [np.asarray(v, dtype=float).reshape(shape) for v in rows["intensity"]]
    return [int(s) for s in rows["step"]], np.array(grids).reshape(-1, *shape)


def per_km2(study: Any, shape: tuple[int, ...]) -> float:
    """Factor from expected targets per cell to per km^2 on a grid of ``shape`` (ny, nx)
    over the study's map."""
    w, h = study.scenario.world.width, study.scenario.world.height
    return 1e6 / (w * h / (shape[-1] * shape[-2]))


def draw_search_figures(t: StudyTables, out: Path) -> dict[str, Path]:
    """Write the search section's figures into ``out`` when the study searches (none
    otherwise; stale files of an earlier report are removed)."""
    colors = _method_colors(t.study.method_names)
    names = intensity_methods(t) if searching(t.study) else []
    figs: dict[str, Path] = {}
    if searching(t.study):
        figs["gospa_parts_time"] = _fig_gospa_parts_time(t, colors,
                                                         out / "gospa_parts_time.png")
    if names:
        figs["undetected_count"] = _fig_undetected_count(t, names, colors,
                                                         out / "undetected_count.png")
        figs["undetected_maps"] = _fig_undetected_maps(t, names, out / "undetected_maps.png")
    for name in SEARCH_FIGURES:
        if name not in figs:
            (out / f"{name}.png").unlink(missing_ok=True)
    return figs


def _band_plot(ax: Any, curves: Any, name: str, color: Any, dt: float, style: str) -> None:
    c = curves[curves["method"] == name]
    time_s = c["step"].to_numpy() * dt
    ax.plot(time_s, c["mean"], color=color, linestyle=style, linewidth=1.5, label=name)
    ax.fill_between(time_s, c["lo"], c["hi"], color=color, alpha=0.12, linewidth=0)


def _fig_undetected_count(t: StudyTables, names: list[str], colors: dict[str, Any],
                          path: Path) -> Path:
    curves = over_time(t, "undetected", names)
    styles = _method_styles(t.study)
    dt = t.study.scenario.dt
    fig = _new_figure(7.0, 4.6)
    ax = fig.subplots()
    for name in names:
        _band_plot(ax, curves, name, colors[name], dt, styles[name])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("expected undetected targets")
    ax.set_ylim(bottom=0)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(4, len(labels)),
               fontsize=9, frameon=False)
    fig.suptitle(f"Expected number of undetected targets ({len(t.runs_done)} runs; band: "
                 "95 % interval)")
    return _save(fig, path)


def _fig_undetected_maps(t: StudyTables, names: list[str], path: Path) -> Path:
    from matplotlib.colors import Normalize

    run = representative_run(t, names)
    maps = {n: intensity_maps(t, run, n) for n in names}
    k = max(len(steps) for steps, _ in maps.values())
    scale = {n: per_km2(t.study, g.shape) for n, (_, g) in maps.items()}
    top = max(float(np.max(g, initial=0.0)) * scale[n] for n, (_, g) in maps.items())
    norm = Normalize(0.0, top if top > 0 else 1.0)
    W, H = t.study.scenario.world.width, t.study.scenario.world.height
    fig = _new_figure(1.9 * k + 1.6, 1.9 * len(names) + 0.9)
    axes = fig.subplots(len(names), k, squeeze=False, sharex=True, sharey=True)
    dt = t.study.scenario.dt
    image = None
    for row, name in zip(axes, names):
        steps, grids = maps[name]
        for col, ax in enumerate(row):
            if col >= len(steps):
                ax.set_axis_off()
                continue
            image = ax.imshow(grids[col] * scale[name], extent=(0, W, 0, H), origin="lower",
                              cmap=INTENSITY_CMAP, norm=norm, interpolation="nearest")
            ax.set_title(f"t = {steps[col] * dt:g} s: {grids[col].sum():.2f}", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
        row[0].set_ylabel(name, fontsize=8.5)
    if image is not None:
        bar = fig.colorbar(image, ax=axes, shrink=0.8, pad=0.02)
        bar.set_label("expected undetected targets per km\u00b2", fontsize=8.5)
    fig.suptitle(f"Undetected intensity of run {run} (panel title: time, expected "
                 "undetected targets on the map)", fontsize=10)
    return _save(fig, path)


#: GOSPA's parts (columns of the ``gospa`` table) and their panel titles.
_PARTS = {"localisation": "localisation of the assigned tracks",
          "missed": "missed targets", "false": "false tracks"}


def _fig_gospa_parts_time(t: StudyTables, colors: dict[str, Any], path: Path) -> Path:
    styles = _method_styles(t.study)
    dt = t.study.scenario.dt
    fig = _new_figure(13.0, 4.4)
    axes = fig.subplots(1, len(_PARTS), sharey=True)
    for ax, (column, title) in zip(axes, _PARTS.items()):
        curves = over_time(t, column)
        for name in t.study.method_names:
            _band_plot(ax, curves, name, colors[name], dt, styles[name])
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("time (s)")
        ax.set_ylim(bottom=0)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    axes[0].set_ylabel("part of GOSPA\u00b2 (m\u00b2)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)),
               fontsize=9, frameon=False)
    fig.suptitle(f"GOSPA\u00b2 over time by part ({len(t.runs_done)} runs; band: 95 % "
                 "interval)")
    return _save(fig, path)


def _number(v: float) -> str:
    return f"{v:.2f}" if math.isfinite(v) else "\u2013"


def _interval(values: np.ndarray) -> str:
    """Mean [95 % t-interval, lower end clipped at 0] of per-run values, two decimals (the
    mean alone when the interval is undefined)."""
    mean, lo, hi = (float(v) for v in t_interval(values))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return _number(mean)
    return f"{_number(mean)} [{_number(max(lo, 0.0))}, {_number(hi)}]"


def search_section(doc: Any, t: StudyTables, figs: dict[str, Path]) -> None:
    """The search section of the report's document (nothing when no method searches)."""
    if not searching(t.study):
        return

    names = intensity_methods(t)
    doc.h(2, "Search: targets not yet detected")
    doc.p("A multi-target tracker with an undetected intensity (`pmb`) keeps, on a grid of "
          "map cells, the expected number of targets that exist but were never detected; "
          "search looks thin it where they cover the map, births feed it. Its sum is the "
          "expected number of undetected targets. Per run its mean over steps 1..S and its "
          "value at the last step; across runs the mean with its 95 % t-interval.")
    if not names:
        doc.p("No method of this study has a tracker that keeps an undetected intensity.")
        return
    g = t.gospa
    last = int(g["step"].max())
    rows = []
    for name in names:
        mine = g[g["method"] == name]
        per_run = mine.groupby("run", observed=True)["undetected"].mean().to_numpy(float)
        final = mine[mine["step"] == last]["undetected"].to_numpy(float)
        rows.append([name, _interval(per_run), _interval(final),
                     _number(float(np.nanmax(mine["undetected"].to_numpy(float))))])
    doc.table(["method", "expected undetected, mean over steps",
               f"at the last step ({last})", "largest (any run, step)"], rows,
              caption="expected number of undetected targets")
    doc.figure("undetected_count", figs["undetected_count"],
               SEARCH_FIGURES["undetected_count"])
    run = representative_run(t, names)
    doc.figure("undetected_maps", figs["undetected_maps"],
               SEARCH_FIGURES["undetected_maps"].format(run=run))
    doc.p(f"To watch it step by step (the intensity under the scene, search looks as "
          f"sectors): `sensorplan replay DIR --run {run} --method NAME`.")
