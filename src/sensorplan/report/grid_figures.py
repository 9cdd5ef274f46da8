"""The heat maps of a grid report (matplotlib, Agg, no pyplot state).

:func:`heatmap_panels` lays the cells out (no plotting), :func:`heatmap_values` takes the
numbers of one comparison from :func:`sensorplan.study.grid_run.grid_statistics`, and
:func:`draw_heatmap` draws them.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..study.features import axis_title

#: Colour map of the differences: diverging, colour-blind safe (ColorBrewer RdBu),
#: blue below zero (the method better), red above.
CMAP = "RdBu_r"
#: Fill of a cell that has not run.
NOT_RUN = "#bdbdbd"


@dataclass(frozen=True)
class Panel:
    """One heat map: ``slugs[r][c]`` is the cell at row r, column c (None: no cell);
    ``base_rows``/``base_cols`` the positions of base values (marked)."""

    title: str
    rows: tuple[str, ...]
    cols: tuple[str, ...]
    slugs: tuple[tuple[str | None, ...], ...]
    base_rows: tuple[int, ...] = ()
    base_cols: tuple[int, ...] = ()
    row_title: str = ""
    col_title: str = ""


def heatmap_panels(info: dict[str, Any]) -> list[Panel]:
    """The panels of a grid (``grid.json`` content).

    Star: one panel per axis, one column per value, the other axes at their bases (the
    base cell appears in every panel). Full: the first axis down, the second across (one
    row if there is one axis); with more axes, one panel per combination of the others.
    """
    axes, cells = info["axes"], info["cells"]
    by_index = {tuple(c["index"]): c["slug"] for c in cells}
    if info["design"] == "star":
        base = tuple(a["base_index"] for a in axes)
        panels = []
        for i, a in enumerate(axes):
            row = tuple(by_index.get(base[:i] + (k,) + base[i + 1:])
                        for k in range(len(a["labels"])))
            panels.append(Panel(a["name"], (axis_title(a["name"]),), tuple(a["labels"]),
                                (row,), (), (a["base_index"],)))
        return panels

    def bases(a: dict[str, Any]) -> tuple[int, ...]:
        return () if a["base_index"] is None else (a["base_index"],)

    if len(axes) == 1:
        a = axes[0]
        row = tuple(by_index.get((k,)) for k in range(len(a["labels"])))
        return [Panel(a["name"], (axis_title(a["name"]),), tuple(a["labels"]), (row,), (),
                      bases(a))]
    a, b, rest = axes[0], axes[1], axes[2:]
    panels = []
    for combo in itertools.product(*(range(len(x["labels"])) for x in rest)):
        slugs = tuple(tuple(by_index.get((r, c) + combo) for c in range(len(b["labels"])))
                      for r in range(len(a["labels"])))
        title = ", ".join(f"{x['name']} = {x['labels'][k]}" for x, k in zip(rest, combo))
        panels.append(Panel(title, tuple(a["labels"]), tuple(b["labels"]), slugs, bases(a),
                            bases(b), axis_title(a["name"]), axis_title(b["name"])))
    return panels


def heatmap_values(panel: Panel, stats: Any) -> dict[str, np.ndarray]:
    """The numbers drawn in ``panel`` for one comparison's rows of the grid statistics
    (one row per cell): ``mean``, ``lo``, ``hi`` (m, NaN where not run), ``n`` and
    ``run`` (the cell has a finished run), each ``(rows, cols)``."""
    by_cell = stats.set_index("cell")
    shape = (len(panel.rows), len(panel.cols))
    out = {k: np.full(shape, np.nan) for k in ("mean", "lo", "hi")}
    out["n"] = np.zeros(shape, dtype=int)
    out["run"] = np.zeros(shape, dtype=bool)
    for r, c in itertools.product(range(shape[0]), range(shape[1])):
        slug = panel.slugs[r][c]
        if slug is None or slug not in by_cell.index:
            continue
        s = by_cell.loc[slug]
        if s["status"] == "not run":
            continue
        out["mean"][r, c], out["lo"][r, c], out["hi"][r, c] = s["mean"], s["mean_lo"], \
            s["mean_hi"]
        out["n"][r, c], out["run"][r, c] = int(s["n"]), True
    return out


def _text(v: float, digits: int = 1) -> str:
    return "–" if not math.isfinite(v) else f"{v:+.{digits}f}".replace("-", "\u2212")


def draw_heatmap(panels: list[Panel], values: list[dict[str, np.ndarray]], title: str,
                 runs: int, path: Path, quantity: str = "RMSE") -> Path:
    """One comparison's heat map: a panel per :class:`Panel`, one colour scale centred on
    0 (symmetric), each cell annotated with the mean and its 95 % interval, a thick black
    border where the interval excludes 0, grey "not run" cells, base values in bold;
    ``quantity`` names the difference (``RMSE`` or ``GOSPA``, m) on the colour bar."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    finite = np.concatenate([np.abs(v["mean"][np.isfinite(v["mean"])]) for v in values])
    limit = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    norm = Normalize(-limit, limit)
    ncols = max(len(p.cols) for p in panels)
    heights = [len(p.rows) + 0.6 for p in panels]
    fig = Figure(figsize=(1.5 * ncols + 3.4, 0.8 * sum(heights) + 0.9), dpi=110,
                 layout="constrained")
    axs = fig.subplots(len(panels), 1, squeeze=False, gridspec_kw={"height_ratios": heights})
    cmap = ScalarMappable(norm=norm, cmap=CMAP)
    for ax, p, v in zip(axs[:, 0], panels, values):
        for r, c in itertools.product(range(len(p.rows)), range(len(p.cols))):
            if p.slugs[r][c] is None:
                continue
            done = bool(v["run"][r, c])
            mean, lo, hi = v["mean"][r, c], v["lo"][r, c], v["hi"][r, c]
            face = cmap.to_rgba(mean) if done and math.isfinite(mean) else NOT_RUN
            ax.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, facecolor=face,
                                   edgecolor="white", linewidth=1.0))
            if done and (hi < 0 or lo > 0):
                # Inset, so that neighbouring significant cells keep separate borders.
                ax.add_patch(Rectangle((c - 0.45, r - 0.45), 0.9, 0.9, fill=False,
                                       edgecolor="black", linewidth=2.5, zorder=2))
            if not done:
                text, colour = "not run", "#333333"
            else:
                text = f"{_text(mean)}\n[{_text(lo)}, {_text(hi)}]"
                if v["n"][r, c] < runs:
                    text += f"\nn = {v['n'][r, c]}"
                colour = "white" if abs(norm(mean) - 0.5) > 0.3 else "black"
            ax.text(c, r, text, ha="center", va="center", fontsize=8.5, color=colour,
                    zorder=3)
        ax.set_xlim(-0.5, ncols - 0.5)
        ax.set_ylim(len(p.rows) - 0.5, -0.5)
        ax.set_xticks(range(len(p.cols)),
                      [t + (" (base)" if k in p.base_cols else "") for k, t in enumerate(p.cols)])
        ax.set_yticks(range(len(p.rows)),
                      [t + (" (base)" if k in p.base_rows else "") for k, t in enumerate(p.rows)])
        for k, label in enumerate(ax.get_xticklabels()):
            label.set_fontweight("bold" if k in p.base_cols else "normal")
        for k, label in enumerate(ax.get_yticklabels()):
            label.set_fontweight("bold" if k in p.base_rows else "normal")
        ax.tick_params(length=0)
        for spine in ax.spines.values():
            spine.set_visible(False)
        if p.col_title:
            ax.set_xlabel(p.col_title)
        if p.row_title:
            ax.set_ylabel(p.row_title)
        if len(panels) > 1 and p.row_title:
            ax.set_title(p.title, fontsize=10)
    fig.colorbar(cmap, ax=axs[:, 0].tolist(), shrink=0.8,
                 label=f"paired mean \u0394 {quantity} (m), method \u2212 reference\n"
                       "< 0: method better")
    fig.suptitle(title)
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path


#: The per-method metrics drawn along each axis: column, label, scale.
AXIS_METRICS = (("rmse", "mean RMSE (m)", 1.0), ("lost", "lost target-steps (%)", 100.0),
                ("anees", "ANEES (4: honest)", 1.0))
#: The same for a grid judged by GOSPA: mean GOSPA instead of RMSE; the lost share of a
#: multi-target tracker is its target-steps without an assigned track, its ANEES that of
#: the assigned tracks.
SET_AXIS_METRICS = (("gospa", "mean GOSPA (m)", 1.0),
                    ("lost", "lost target-steps (%)", 100.0),
                    ("anees", "ANEES (4: honest)", 1.0))


def draw_axis_lines(info: dict[str, Any], methods: Any, path: Path,
                    metrics: tuple[tuple[str, str, float], ...] = AXIS_METRICS
                    ) -> Path | None:
    """Each method's mean RMSE (or another of ``metrics``: column, label, scale), lost
    share (both with 95 % t-intervals) and ANEES along every axis of a star design (the
    other axes at base): one row per axis, one column per metric, one line per method.
    None for a full design (its heat maps show the cells)."""
    from matplotlib.figure import Figure

    from ..figures.colors import method_colors

    if info["design"] != "star" or methods.empty:
        return None
    by_index = {tuple(c["index"]): c["slug"] for c in info["cells"]}
    base = tuple(a["base_index"] for a in info["axes"])
    names = list(dict.fromkeys(methods["method"]))
    colors = method_colors(names)
    axes = info["axes"]
    fig = Figure(figsize=(4.2 * len(metrics), 2.9 * len(axes) + 0.6), dpi=110,
                 layout="constrained")
    grid = fig.subplots(len(axes), len(metrics), squeeze=False)
    for i, a in enumerate(axes):
        slugs = [by_index.get(base[:i] + (k,) + base[i + 1:]) for k in range(len(a["labels"]))]
        for c, (col, label, scale) in enumerate(metrics):
            ax = grid[i, c]
            for m in names:
                rows = methods[methods["method"] == m].set_index("cell")
                x = [k for k, sl in enumerate(slugs) if sl in rows.index]
                if not x:
                    continue
                sel = rows.loc[[slugs[k] for k in x]]
                y = scale * sel[col].to_numpy(float)
                err = None
                if f"{col}_lo" in sel:
                    lo, hi = sel[f"{col}_lo"].to_numpy(float), sel[f"{col}_hi"].to_numpy(float)
                    if col == "lost":                  # a share: its interval within [0, 1]
                        lo, hi = np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)
                    err = np.vstack([y - scale * lo, scale * hi - y])
                ax.errorbar(x, y, yerr=err, color=colors[m], marker="o", ms=4, capsize=3,
                            label=m)
            if col == "anees":
                from matplotlib.ticker import ScalarFormatter

                ax.axhline(4.0, color="#555555", ls=":", lw=1)
                ax.set_yscale("log")
                ax.yaxis.set_major_formatter(ScalarFormatter())
                ax.yaxis.set_minor_formatter(ScalarFormatter())
            ax.set_xticks(range(len(a["labels"])),
                          [t + (" (base)" if k == a["base_index"] else "")
                           for k, t in enumerate(a["labels"])], fontsize=8)
            ax.set_xlabel(axis_title(a["name"]))
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    grid[0, 0].legend(fontsize=8)
    fig.suptitle("Each method along each axis (the other axes at base; 95 % t-intervals)")
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path
