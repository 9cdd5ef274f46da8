"""The report of a study: PNG figures, one self-contained HTML page, a markdown summary.

Everything is computed from the study directory's files alone (``config.resolved.json``,
``meta.json`` and the tidy tables) with the statistics of :mod:`sensorplan.experiments`;
this module only draws (matplotlib, Agg, no pyplot state) and formats. The HTML page embeds
its figures as base64 ``data:`` URIs, so it opens from disk with no network and can be
mailed as one file.

Definitions used throughout (docs/studies.md):

- RMSE of a run, per target kind: ``sqrt(mean over steps 1..S and the kind's targets of
  error^2)``; across runs its mean with a t-interval and its median with an
  order-statistic interval (both 95 %).
- RMSE at step t: ``sqrt(mean over runs of the run's mean squared error at t)``; the band
  is the square root of the t-interval of that mean.
- Lost target-step: position error > 50 m.
- Paired difference: per run, method minus reference (same truths, estimates and noise);
  mean with the paired t-interval.
"""

from __future__ import annotations

import base64
import html
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import experiments as ex
from .plotting import field_of_view, frame_map

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Figure files, in page order, with their captions.
FIGURES = {
    "scenario": "Scenario snapshot: the first run's true target tracks (the same for every "
                "method), the initial estimates, and the sensor paths of one method with "
                "the fields of view in the first step.",
    "rmse_time": "Position RMSE over time for each target kind; one line per method (one "
                 "line style per planning/tracker configuration), the band is the 95 % "
                 "interval across runs.",
    "rmse_overall": "Overall position RMSE per run, summarized across runs: mean with its "
                    "95 % t-interval and median with its 95 % order-statistic interval.",
    "lost_share": "Share of lost target-steps (position error > 50 m), mean across runs "
                  "with its 95 % t-interval.",
    "paired_differences": "Paired RMSE differences (method minus reference, run by run) "
                          "against the myopic planner and against random with the same "
                          "tracker; mean with its 95 % paired t-interval. Left of zero: "
                          "the method tracks better.",
    "planning_time": "Wall time of each planning decision per method (log scale).",
    "convergence": "Convergence of the game planners: share of decisions that ended at a "
                   "pure Nash equilibrium, and sweeps per decision.",
    "horizon": "Methods that differ only in the horizon K: overall RMSE (mean with its 95 % "
               "t-interval) and planning time per decision against K.",
}
#: Figures drawn only when the study has what they show.
OPTIONAL_FIGURES = ("horizon",)

_KIND_COLORS = {"cv": "#1f77b4", "dubins": "#d62728", "all": "#555555"}


@dataclass
class ReportFiles:
    """What :func:`write_report` wrote."""

    html: Path
    markdown: Path
    figures: dict[str, Path] = field(default_factory=dict)
    complete: bool = True
    runs: int = 0


# ------------------------------------------------------------------------ formatting


def _f(v: float, digits: int = 1) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _ci(mean: float, lo: float, hi: float, digits: int = 1, pct: bool = False) -> str:
    k = 100.0 if pct else 1.0
    unit = " %" if pct else ""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"{_f(k * mean, digits)}{unit}"
    return f"{_f(k * mean, digits)} [{_f(k * lo, digits)}, {_f(k * hi, digits)}]{unit}"


def _method_colors(names: list[str]) -> dict[str, Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10" if len(names) <= 10 else "tab20"]
    return {n: cmap(i % cmap.N) for i, n in enumerate(names)}


def _new_figure(width: float, height: float) -> "Figure":
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110, layout="constrained")


def _save(fig: "Figure", path: Path) -> Path:
    # "tight" keeps legends placed outside the axes inside the image.
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path


# ---------------------------------------------------------------------------- figures


def _fig_scenario(t: ex.StudyTables, path: Path) -> Path:
    from matplotlib.patches import Rectangle, Wedge

    study = t.study
    run = t.runs_done[0]
    names = study.method_names
    shown = next((m.name for m in study.methods if m.settings.planner != "random"), names[0])
    steps = t.steps[(t.steps["run"] == run) & (t.steps["method"] == shown)]
    sens = t.sensors[(t.sensors["run"] == run) & (t.sensors["method"] == shown)]
    fig = _new_figure(10.0, 7.0)
    ax = fig.add_subplot()
    W, H = study.scenario.world.width, study.scenario.world.height
    ax.add_patch(Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.0))
    from matplotlib.lines import Line2D

    handles = []
    for j, kind in enumerate(study.scenario.target_kinds):
        g = steps[steps["target"] == j].sort_values("step")
        color = _KIND_COLORS.get(kind, "k")
        style = "-" if kind == "cv" else "--"
        ax.plot(g["x"], g["y"], style, color=color, linewidth=1.6)
        ax.plot(g["x"].iloc[0], g["y"].iloc[0], "o", color=color, markersize=6)
        ax.plot(g["x_est"].iloc[0], g["y_est"].iloc[0], "x", color=color, markersize=7)
        ax.annotate(f"T{j}", (g["x"].iloc[0], g["y"].iloc[0]), textcoords="offset points",
                    xytext=(5, 5), fontsize=9, color=color)
    for kind in dict.fromkeys(study.scenario.target_kinds):
        handles.append(Line2D([], [], color=_KIND_COLORS.get(kind, "k"),
                              linestyle="-" if kind == "cv" else "--",
                              label=f"true track, {kind} target (\u25cf start)"))
    handles.append(Line2D([], [], color="0.3", marker="x", linestyle="none",
                          label="initial estimate"))
    for i, spec in enumerate(study.scenario.sensors):
        g = sens[sens["sensor"] == i].sort_values("step")
        color = f"C{(i + 2) % 10}"
        ax.plot(g["x"], g["y"], "-", color=color, linewidth=0.9, alpha=0.7)
        x0, y0 = g["x"].iloc[0], g["y"].iloc[0]
        ax.plot(x0, y0, "^", color=color, markersize=9)
        # The field of view of the first step (after the first decision's move and turn).
        first = g.iloc[min(1, len(g) - 1)]
        x1, y1, h0 = first["x"], first["y"], first["heading"]
        p = spec.params
        field_of_view(ax, np.array([x1, y1]), float(h0), p, color, alpha=0.12)
        handles.append(Line2D([], [], color=color, marker="^",
                              label=f"sensor {i} ({float(p.altitude):g} m): \u25b2 start, path"))
    handles.append(Wedge((0, 0), 1, 0, 1, facecolor="0.5", alpha=0.2, edgecolor="0.4",
                         linestyle="--", label="field of view in step 1"))
    frame_map(ax, W, H, 0.05)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8.5,
              frameon=False)
    ax.set_title(f"Run {run}: {study.steps} steps; sensor paths of method \u201c{shown}\u201d",
                 fontsize=11)
    return _save(fig, path)


def _method_styles(study: Any) -> dict[str, str]:
    """Line style per method: one per planning/tracker configuration (visibility, objective,
    miss update), so that the paper's configuration and ours read apart in line plots."""
    configs: dict[tuple[str, ...], str] = {}
    styles = ["-", "--", ":", "-."]
    out = {}
    for m in study.methods:
        s = m.settings
        key = (s.visibility, s.objective, str(s.miss_update))
        configs.setdefault(key, styles[len(configs) % len(styles)])
        out[m.name] = configs[key]
    return out


def _fig_rmse_time(curves: Any, t: ex.StudyTables, colors: dict[str, Any],
                   path: Path) -> Path:
    kinds = list(dict.fromkeys(t.study.scenario.target_kinds))
    dt = t.study.scenario.dt
    styles = _method_styles(t.study)
    fig = _new_figure(6.0 * len(kinds) + 0.5, 5.4)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        for name in t.study.method_names:
            c = curves[(curves["method"] == name) & (curves["kind"] == kind)]
            time_s = c["step"].to_numpy() * dt
            ax.plot(time_s, c["rmse"], color=colors[name], linestyle=styles[name],
                    linewidth=1.5, label=name)
            ax.fill_between(time_s, c["lo"], c["hi"], color=colors[name], alpha=0.12,
                            linewidth=0)
        n = int(t.steps.loc[t.steps["kind"] == kind, "target"].nunique())
        ax.set_title(f"{kind} targets ({n} per run, {len(t.runs_done)} runs)")
        ax.set_xlabel("time (s)")
        ax.grid(True, linewidth=0.4, alpha=0.5)
        ax.set_ylim(bottom=0)
    axes[0].set_ylabel("position RMSE (m)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)),
               fontsize=9, frameon=False)
    fig.suptitle("Position RMSE over time (band: 95 % interval across runs)")
    return _save(fig, path)


def _method_axis(ax: "Axes", names: list[str]) -> np.ndarray:
    y = np.arange(len(names))[::-1].astype(float)
    ax.set_yticks(y, names)
    ax.set_ylim(-0.7, len(names) - 0.3)
    return y


def _fig_rmse_overall(summ: Any, t: ex.StudyTables, path: Path) -> Path:
    kinds = ex.kinds_with_all(t.study)
    names = t.study.method_names
    fig = _new_figure(3.6 * len(kinds) + 2.2, 0.42 * len(names) + 1.9)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        y = _method_axis(ax, names)
        s = summ[summ["kind"] == kind].set_index("method").reindex(names)
        mean, med = s["mean"].to_numpy(float), s["median"].to_numpy(float)
        ax.errorbar(mean, y + 0.13, xerr=_xerr(mean, s["mean_lo"], s["mean_hi"]), fmt="o",
                    color="#1f77b4", capsize=3, markersize=5, label="mean, 95 % t-interval")
        ax.errorbar(med, y - 0.13, xerr=_xerr(med, s["median_lo"], s["median_hi"]),
                    fmt="D", color="#ff7f0e", capsize=3, markersize=4.5,
                    label="median, 95 % order-statistic interval")
        ax.set_title(f"{kind} targets" if kind != "all" else "all targets")
        ax.set_xlabel("RMSE per run (m)")
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
        ax.set_xlim(left=0)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=2, fontsize=9, frameon=False)
    fig.suptitle(f"Overall position RMSE ({len(t.runs_done)} paired runs, "
                 f"steps 1..{t.study.steps})")
    return _save(fig, path)


def _xerr(center: np.ndarray, lo: Any, hi: Any) -> np.ndarray:
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    err = np.vstack([center - lo, hi - center])
    return np.nan_to_num(np.clip(err, 0.0, None))


def _fig_lost(lost: Any, t: ex.StudyTables, path: Path) -> Path:
    kinds = ex.kinds_with_all(t.study)
    names = t.study.method_names
    fig = _new_figure(3.4 * len(kinds) + 2.2, 0.42 * len(names) + 1.6)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        y = _method_axis(ax, names)
        s = lost[lost["kind"] == kind].set_index("method").reindex(names)
        mean = 100 * s["mean"].to_numpy(float)
        ax.barh(y, mean, color=_KIND_COLORS.get(kind, "0.5"), alpha=0.75, height=0.6)
        ax.errorbar(mean, y, xerr=_xerr(mean, 100 * s["mean_lo"], 100 * s["mean_hi"]),
                    fmt="none", ecolor="k", capsize=3, linewidth=1.0)
        ax.set_title(f"{kind} targets" if kind != "all" else "all targets")
        ax.set_xlabel("lost target-steps (%)")
        ax.set_xlim(left=0)
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
    fig.suptitle(f"Share of target-steps with position error > {ex.LOST_THRESHOLD:g} m "
                 "(mean across runs, 95 % t-interval)")
    return _save(fig, path)


def _fig_paired(diffs: Any, t: ex.StudyTables, path: Path) -> Path:
    kinds = ex.kinds_with_all(t.study)
    names = t.study.method_names
    fig = _new_figure(13.0, 0.5 * len(names) + 2.2)
    axes = fig.subplots(1, 2, squeeze=False)[0]
    handles: list[Any] = []
    labels: list[str] = []
    offsets = np.linspace(0.22, -0.22, len(kinds)) if len(kinds) > 1 else np.zeros(1)
    for ax, against in zip(axes, ("myopic", "random")):
        d = diffs[diffs["against"] == against] if len(diffs) else diffs
        rows = [n for n in names if len(d) and (d["method"] == n).any()]
        if not rows:
            ax.text(0.5, 0.5, f"no method has a {against} reference in this study",
                    ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        refs = {n: d.loc[d["method"] == n, "reference"].iloc[0] for n in rows}
        y = _method_axis(ax, [f"{n}  (vs {refs[n]})" for n in rows])
        for off, kind in zip(offsets, kinds):
            s = d[d["kind"] == kind].set_index("method").reindex(rows)
            mean = s["mean"].to_numpy(float)
            ax.errorbar(mean, y + off, xerr=_xerr(mean, s["mean_lo"], s["mean_hi"]),
                        fmt="o", color=_KIND_COLORS.get(kind, "k"), capsize=3, markersize=5,
                        label=f"{kind} targets" if kind != "all" else "all targets")
        ax.axvline(0.0, color="k", linewidth=0.9)
        ax.set_xlabel("\u0394 RMSE = method \u2212 reference (m)   \u2190 method better")
        ax.set_title(f"against {against}")
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
        handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9,
                   frameon=False)
    fig.suptitle("Paired RMSE differences per run: mean with 95 % paired t-interval")
    return _save(fig, path)


def _fig_planning(t: ex.StudyTables, colors: dict[str, Any], path: Path) -> Path:
    names = t.study.method_names
    fig = _new_figure(9.0, 0.45 * len(names) + 1.8)
    ax = fig.add_subplot()
    y = _method_axis(ax, names)
    data = []
    for name in names:
        ms = 1e3 * t.decisions.loc[t.decisions["method"] == name,
                                   "planning_seconds"].to_numpy(float)
        data.append(np.clip(ms, 1e-3, None))
    import matplotlib

    # Matplotlib 3.10 replaced vert=False by orientation="horizontal".
    horizontal = ({"orientation": "horizontal"}
                  if tuple(int(v) for v in matplotlib.__version__.split(".")[:2]) >= (3, 10)
                  else {"vert": False})
    bp = ax.boxplot(data, positions=y, widths=0.55, whis=(5, 95), showfliers=True,
                    flierprops=dict(markersize=2, alpha=0.4), patch_artist=True,
                    medianprops=dict(color="k"), **horizontal)
    for patch, name in zip(bp["boxes"], names):
        patch.set_facecolor(colors[name])
        patch.set_alpha(0.6)
    ax.set_yticks(y, names)
    ax.set_xscale("log")
    _plain_log_labels(ax.xaxis)
    ax.set_xlabel("planning time per decision (ms, wall clock; log scale)")
    ax.grid(True, axis="x", which="both", linewidth=0.4, alpha=0.4)
    ax.set_title("Planning time per decision (box: quartiles and median; whiskers: 5th-95th "
                 "percentile)", fontsize=10.5)
    return _save(fig, path)


def _fig_convergence(plan: Any, t: ex.StudyTables, path: Path) -> Path:
    p = plan[np.isfinite(plan["converged_share"].to_numpy(float))]
    names = [n for n in t.study.method_names if (p["method"] == n).any()]
    fig = _new_figure(11.0, 0.45 * max(len(names), 1) + 1.9)
    axes = fig.subplots(1, 2, squeeze=False)[0]
    if not names:
        for ax in axes:
            ax.set_axis_off()
        axes[0].text(0.5, 0.5, "no planner in this study reports convergence",
                     ha="center", va="center", transform=axes[0].transAxes)
        return _save(fig, path)
    dec = t.decisions
    for ax in axes:
        _method_axis(ax, names)
    y = np.arange(len(names))[::-1].astype(float)
    s = p.set_index("method").reindex(names)
    share = 100 * s["converged_share"].to_numpy(float)
    axes[0].barh(y, share, color="#2ca02c", alpha=0.75, height=0.6)
    for yi, v in zip(y, share):
        axes[0].text(min(v, 100) + 1, yi, f"{v:.1f} %", va="center", fontsize=8.5)
    axes[0].set_xlim(0, 115)
    axes[0].set_xlabel("decisions that converged (%)")
    axes[0].set_title("Converged to a pure Nash equilibrium")
    max_sweeps = int(np.nanmax(s["sweeps_max"].to_numpy(float)))
    for yi, name in zip(y, names):
        sw = dec.loc[dec["method"] == name, "sweeps"].dropna().to_numpy(float)
        counts = np.bincount(sw.astype(int), minlength=max_sweeps + 1)
        left = 0.0
        for k in range(1, max_sweeps + 1):
            frac = 100 * counts[k] / max(sw.size, 1)
            if frac > 0:
                axes[1].barh(yi, frac, left=left, height=0.6,
                             color=_sweep_color(k, max_sweeps), edgecolor="white",
                             linewidth=0.5)
                if frac >= 7:
                    dark = (k - 1) / max(max_sweeps - 1, 1) < 0.6
                    axes[1].text(left + frac / 2, yi, str(k), ha="center", va="center",
                                 fontsize=8, color="white" if dark else "black")
            left += frac
        axes[1].text(101, yi, f"mean {sw.mean():.2f}", va="center", fontsize=8.5)
    axes[1].set_xlim(0, 122)
    axes[1].set_xlabel("share of decisions (%) by number of sweeps (number in the bar)")
    axes[1].set_title("Sweeps per decision")
    fig.suptitle("Convergence of the potential-game planners (one sweep: epochs K..1)")
    return _save(fig, path)


def _fig_horizon(groups: list[list[ex.Method]], summ: Any, t: ex.StudyTables,
                 path: Path) -> Path:
    kinds = ex.kinds_with_all(t.study)
    fig = _new_figure(12.5, 4.8)
    ax_rmse, ax_time = fig.subplots(1, 2)
    styles = ["-", "--", ":", "-."]
    dec = t.decisions
    for gi, group in enumerate(groups):
        ks = np.array([m.settings.horizon for m in group], dtype=float)
        label = group[-1].settings
        tag = "" if len(groups) == 1 else f" [{label.planner}, {label.execution.upper()}]"
        for kind in kinds:
            s = summ[summ["kind"] == kind].set_index("method").reindex([m.name for m in group])
            mean, med = s["mean"].to_numpy(float), s["median"].to_numpy(float)
            color = _KIND_COLORS.get(kind, "k")
            shift = 0.05 * (kinds.index(kind) - 1)
            ax_rmse.errorbar(ks + shift, mean, yerr=_xerr(mean, s["mean_lo"], s["mean_hi"]),
                             marker="o", linestyle=styles[gi % 4], color=color, capsize=3,
                             label=f"{kind} targets, mean{tag}")
            ax_rmse.plot(ks + shift, med, marker="D", markerfacecolor="white",
                         linestyle=":", color=color, label=f"{kind} targets, median{tag}")
        mean_ms = np.array([1e3 * dec.loc[dec["method"] == m.name, "planning_seconds"].mean()
                            for m in group])
        med_ms = [1e3 * dec.loc[dec["method"] == m.name, "planning_seconds"].median()
                  for m in group]
        # Polynomial growth c K^p is a straight line of slope p on log-log axes.
        p = np.polyfit(np.log(ks), np.log(mean_ms), 1)[0] if len(ks) >= 3 else math.nan
        ax_time.plot(ks, mean_ms, marker="o", linestyle=styles[gi % 4], color="#9467bd",
                     label=f"mean{tag} (fit: \u221d K^{p:.1f})")
        ax_time.plot(ks, med_ms, marker="s", linestyle=styles[gi % 4], color="#8c564b",
                     label=f"median{tag}")
    all_k = sorted({m.settings.horizon for g in groups for m in g})
    for ax in (ax_rmse, ax_time):
        ax.set_xlabel("horizon K (epochs)")
        ax.grid(True, which="both", linewidth=0.4, alpha=0.4)
        ax.legend(fontsize=8)
    ax_rmse.set_xticks(all_k)
    ax_rmse.set_ylabel("RMSE per run (m)")
    ax_rmse.set_ylim(bottom=0)
    ax_rmse.set_title("Tracking error against the horizon (mean: 95 % t-interval)")
    ax_time.set_xscale("log")
    ax_time.set_yscale("log")
    ax_time.set_xticks(all_k, [str(k) for k in all_k])
    ax_time.xaxis.set_minor_formatter(_no_label())
    _plain_log_labels(ax_time.yaxis)
    ax_time.set_ylabel("planning time per decision (ms)")
    ax_time.set_title("Planning cost against the horizon (log-log)")
    return _save(fig, path)


def _no_label() -> Any:
    from matplotlib.ticker import NullFormatter

    return NullFormatter()


def _plain_log_labels(axis: Any) -> None:
    """Label a log axis 0.1, 1, 10 (and 2, 5 between) instead of 10^0 or 6x10^0."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(FuncFormatter(lambda v, _: ""))


def _sweep_color(k: int, kmax: int) -> Any:
    from matplotlib import colormaps

    return colormaps["viridis"](0.15 + 0.8 * (k - 1) / max(kmax - 1, 1))


# ------------------------------------------------------------------- document model


class _Doc:
    """Blocks rendered both as markdown and as HTML."""

    def __init__(self) -> None:
        self.blocks: list[tuple[str, Any]] = []

    def h(self, level: int, text: str) -> None:
        self.blocks.append(("h", (level, text)))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, header: list[str], rows: list[list[str]], caption: str = "") -> None:
        self.blocks.append(("table", (header, rows, caption)))

    def figure(self, name: str, path: Path) -> None:
        self.blocks.append(("figure", (name, path)))

    def markdown(self) -> str:
        out: list[str] = []
        for kind, b in self.blocks:
            if kind == "h":
                out.append("#" * b[0] + " " + b[1])
            elif kind == "p":
                out.append(b)
            elif kind == "table":
                header, rows, caption = b
                if caption:
                    out.append(f"*{caption}*\n")
                esc = [[c.replace("|", "\\|") for c in r] for r in [header] + rows]
                out.append("| " + " | ".join(esc[0]) + " |")
                out.append("|" + "|".join("---" if i == 0 else "--:"
                                          for i in range(len(header))) + "|")
                out += ["| " + " | ".join(r) + " |" for r in esc[1:]]
            elif kind == "figure":
                name, path = b
                out.append(f"![{FIGURES[name]}]({path.name})\n\n*{FIGURES[name]}*")
            out.append("")
        return "\n".join(out)

    def html(self, title: str) -> str:
        body: list[str] = []
        for kind, b in self.blocks:
            if kind == "h":
                body.append(f"<h{b[0]}>{html.escape(b[1])}</h{b[0]}>")
            elif kind == "p":
                body.append(f"<p>{_inline(b)}</p>")
            elif kind == "table":
                header, rows, caption = b
                cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
                head = "".join(f"<th>{html.escape(c)}</th>" for c in header)
                trs = "".join("<tr>" + "".join(
                    f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
                body.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{trs}"
                            "</tbody></table>")
            elif kind == "figure":
                name, path = b
                data = base64.b64encode(path.read_bytes()).decode("ascii")
                body.append(f'<figure id="fig-{name}"><img src="data:image/png;base64,{data}" '
                            f'alt="{html.escape(FIGURES[name])}"><figcaption>'
                            f"{html.escape(FIGURES[name])}</figcaption></figure>")
        return _HTML.format(title=html.escape(title), body="\n".join(body))


def _inline(text: str) -> str:
    """Escape, then render markdown `code` and **bold** spans."""
    import re

    t = html.escape(text)
    t = re.sub(r"`([^`]+)`", r"<code>\1</code>", t)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)


_HTML = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
body {{ font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1150px;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }}
h1 {{ font-size: 1.6em; }} h2 {{ margin-top: 1.8em; border-bottom: 1px solid #ddd; }}
table {{ border-collapse: collapse; margin: 0.8em 0 1.2em; font-size: 0.9em; }}
caption {{ caption-side: top; text-align: left; font-style: italic; padding-bottom: 0.3em; }}
th, td {{ border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }}
th:first-child, td:first-child {{ text-align: left; }}
thead th {{ background: #f3f3f3; }}
tbody tr:nth-child(even) {{ background: #fafafa; }}
figure {{ margin: 1.2em 0; }} figure img {{ max-width: 100%; height: auto; }}
figcaption {{ font-size: 0.9em; color: #444; }}
code {{ background: #f3f3f3; padding: 0 0.2em; }}
</style>
</head>
<body>
{body}
</body>
</html>
"""


# ------------------------------------------------------------------------------ report


def write_report(study_dir: str | Path, out: str | Path | None = None) -> ReportFiles:
    """Write ``report.html``, ``summary.md`` and the PNG figures of a study directory.

    Parameters
    ----------
    study_dir : path
        Written by :func:`sensorplan.experiments.run_study` (finished or not: an unfinished
        study is reported on the runs every method has finished).
    out : path, optional
        Report directory (default ``study_dir/report``).

    Returns
    -------
    ReportFiles

    Raises
    ------
    ConfigError
        ``study_dir`` is not a study directory or holds no finished run.
    """
    study_dir = Path(study_dir)
    t = ex.load_study_dir(study_dir)
    out = Path(out) if out is not None else study_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    study = t.study
    names = study.method_names
    colors = _method_colors(names)

    metrics = ex.run_metrics(t)
    rmse = ex.summary(metrics, "rmse")
    lost = ex.summary(metrics, "lost_share")
    # A t-interval of a share can leave [0, 1]; show it clipped (the share cannot).
    lost[["mean_lo", "mean_hi"]] = lost[["mean_lo", "mean_hi"]].clip(0.0, 1.0)
    diffs = ex.paired_differences(metrics, study)
    curves = ex.rmse_over_time(t)
    plan = ex.planning_summary(t)
    sensing = ex.sensing_summary(t)

    figs = {
        "scenario": _fig_scenario(t, out / "scenario.png"),
        "rmse_time": _fig_rmse_time(curves, t, colors, out / "rmse_time.png"),
        "rmse_overall": _fig_rmse_overall(rmse, t, out / "rmse_overall.png"),
        "lost_share": _fig_lost(lost, t, out / "lost_share.png"),
        "paired_differences": _fig_paired(diffs, t, out / "paired_differences.png"),
        "planning_time": _fig_planning(t, colors, out / "planning_time.png"),
        "convergence": _fig_convergence(plan, t, out / "convergence.png"),
    }
    groups = ex.horizon_groups(study)
    if groups:
        figs["horizon"] = _fig_horizon(groups, rmse, t, out / "horizon.png")
    else:
        (out / "horizon.png").unlink(missing_ok=True)     # stale from an earlier report

    doc = _document(t, rmse, lost, diffs, plan, sensing, figs)
    title = f"sensorplan study report: {study_dir.name}"
    md = out / "summary.md"
    page = out / "report.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    page.write_text(doc.html(title), encoding="utf-8")
    return ReportFiles(page, md, figs, t.complete, len(t.runs_done))


def _document(t: ex.StudyTables, rmse: Any, lost: Any, diffs: Any, plan: Any, sensing: Any,
              figs: dict[str, Path]) -> _Doc:
    study, meta = t.study, t.meta
    doc = _Doc()
    doc.h(1, "Study report" + (f": {study.description}" if study.description else ""))
    sessions = meta.get("sessions", [])
    wall = meta.get("wall_seconds")
    versions = meta.get("versions", {})
    kinds = study.scenario.target_kinds
    counts = ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds))
    facts = [f"{len(t.runs_done)} paired runs" + ("" if t.complete else
                                                  f" of {study.runs} (**study unfinished**)"),
             f"{study.steps} steps of {study.scenario.dt:g} s", f"seed {study.seed}",
             f"scenario: {study.scenario_source}",
             f"{len(study.scenario.targets)} targets ({counts}), "
             f"{len(study.scenario.sensors)} sensors"]
    doc.p("; ".join(facts) + ".")
    if wall is not None:
        ex_names = ", ".join(dict.fromkeys(s.get("executor", "?") for s in sessions))
        doc.p(f"Computed in {wall:.0f} s wall time over {len(sessions)} session(s) "
              f"({ex_names}) on {meta.get('platform', '?')} with {meta.get('cpu_count', '?')} "
              f"CPUs; sensorplan {versions.get('sensorplan', '?')}, numpy "
              f"{versions.get('numpy', '?')}, Python {versions.get('python', '?')}"
              + (f", git {meta['git']}" if meta.get("git") else "") + ".")

    doc.h(2, "Methods")
    refs = ex.references(study)
    doc.table(["method", "planner", "K", "e", "execution", "visibility", "objective",
               "miss update", "vs myopic", "vs random"],
              [[m.name, m.settings.planner, str(m.settings.horizon),
                str(m.settings.steps_per_epoch), m.settings.execution.upper(),
                m.settings.visibility, m.settings.objective, str(m.settings.miss_update),
                refs[m.name]["myopic"] or "–", refs[m.name]["random"] or "–"]
               for m in study.methods])
    doc.p("Every method runs on the same paired runs: identical true trajectories, initial "
          "estimates, sensor starts and measurement noise streams (common random numbers).")

    doc.h(2, "Position RMSE and lost tracks")
    doc.p("RMSE of a run (per target kind) = sqrt(mean over steps 1..S and the kind's targets "
          "of the squared position error). Across runs: mean [95 % t-interval] and median "
          "[95 % distribution-free order-statistic interval]. Lost: share of target-steps with "
          f"error > {ex.LOST_THRESHOLD:g} m, mean across runs [95 % t-interval, clipped to "
          "[0, 100] %].")
    for kind in ex.kinds_with_all(study):
        r = rmse[rmse["kind"] == kind].set_index("method")
        lo = lost[lost["kind"] == kind].set_index("method")
        rows = []
        for name in study.method_names:
            if name not in r.index:
                continue
            a, b = r.loc[name], lo.loc[name]
            rows.append([name, _ci(a["mean"], a["mean_lo"], a["mean_hi"]),
                         _ci(a["median"], a["median_lo"], a["median_hi"]),
                         _ci(b["mean"], b["mean_lo"], b["mean_hi"], pct=True)])
        label = f"{kind} targets" if kind != "all" else "all targets"
        doc.table(["method", "RMSE mean (m)", "RMSE median (m)", "lost target-steps"], rows,
                  caption=label)
    doc.figure("rmse_time", figs["rmse_time"])
    doc.figure("rmse_overall", figs["rmse_overall"])
    doc.figure("lost_share", figs["lost_share"])

    doc.h(2, "Paired differences")
    doc.p("Per run: RMSE of the method minus RMSE of the reference on the same run. Mean "
          "[95 % paired t-interval], median [95 % order-statistic interval], and the share "
          "of runs in which the method had the lower RMSE. An interval entirely below zero "
          "means the method is better with 95 % confidence.")
    for against in ("myopic", "random"):
        d = diffs[diffs["against"] == against] if len(diffs) else diffs
        rows = [[r.method, r.reference, str(r.kind), _ci(r.mean, r.mean_lo, r.mean_hi),
                 _ci(r.median, r.median_lo, r.median_hi), f"{100 * r.better_share:.0f} %"]
                for r in d.itertuples()] if len(d) else []
        if rows:
            doc.table(["method", "reference", "kind", "\u0394 RMSE mean (m)",
                       "\u0394 RMSE median (m)", "runs better"], rows,
                      caption=f"against {against}")
        else:
            doc.p(f"No method has a {against} reference in this study.")
    doc.figure("paired_differences", figs["paired_differences"])

    doc.h(2, "Planning time and convergence")
    rows = []
    for r in plan.itertuples():
        conv = ("–" if not math.isfinite(r.converged_share)
                else f"{100 * r.converged_share:.1f} %")
        sweeps = "–" if not math.isfinite(r.sweeps_mean) else \
            f"{r.sweeps_mean:.2f} (max {r.sweeps_max:.0f})"
        rows.append([str(r.method), str(r.decisions), _f(r.mean_ms, 2), _f(r.median_ms, 2),
                     _f(r.p90_ms, 2), _f(r.max_ms, 1), _f(r.seconds_per_run, 2), conv,
                     sweeps, _f(r.phi_mean, 2)])
    doc.table(["method", "decisions", "mean ms", "median ms", "p90 ms", "max ms",
               "s per run", "converged", "sweeps", "mean Phi (nats)"], rows,
              caption="planning time is wall-clock time of the planner call (depends on "
                      "the machine and its load)")
    doc.figure("planning_time", figs["planning_time"])
    doc.figure("convergence", figs["convergence"])
    if "horizon" in figs:
        doc.figure("horizon", figs["horizon"])

    doc.h(2, "Sensing")
    doc.table(["method", "looks per sensor-step", "measurements per sensor-step",
               "looks that missed"],
              [[str(r.method), f"{r.look_share:.2f}", f"{r.measurements_per_sensor_step:.2f}",
                "–" if not math.isfinite(r.miss_share) else f"{100 * r.miss_share:.1f} %"]
               for r in sensing.itertuples()],
              caption="over sensor-steps 1..S; a missed look points at a target that is "
                      "truly outside the field of view")
    doc.figure("scenario", figs["scenario"])
    doc.p("Files: `config.resolved.json` (the study with every default), `meta.json` "
          "(versions, seed, wall time), `steps.parquet`, `decisions.parquet`, "
          "`sensors.parquet` (tidy tables); regenerate this report with "
          "`sensorplan report DIR`.")
    return doc
