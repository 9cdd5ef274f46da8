"""The figures of a study report (matplotlib, Agg, no pyplot state), one function each.

Every figure is drawn from a study's tables and the statistics of
:mod:`sensorplan.study.metrics`; :func:`draw_figures` writes them all.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..figures.colors import (MEAN_COLOR, MEDIAN_COLOR, kind_color, kind_marker, method_colors,
                              mix_hex, sensor_style, target_color)
from ..figures.run import draw_buildings, draw_ellipse, field_of_view, frame_map
from ..study.lifespan import study_has_sets
from ..study.metrics import LOST_THRESHOLD, horizon_groups, kinds_with_all
from ..study.model import Method
from ..study.storage import StudyTables

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Figure files, in page order, with their captions.
FIGURES = {
    "scenario": "Scenario snapshot: the first run's true target tracks (the same for every "
                "method; each target in its colour of the run figures), the initial "
                "estimates with their 2-sigma ellipses, and the sensor paths of one method "
                "with the fields of view in the first step.",
    "rmse_time": "Position RMSE over time for each target kind; one line per method (one "
                 "line style per planning/tracker configuration), the band is the 95 % "
                 "interval across runs.",
    "rmse_overall": "Overall position RMSE per run, summarized across runs: mean with its "
                    "95 % t-interval and median with its 95 % order-statistic interval.",
    "nees_time": "Average NEES over time for each target kind (runs x targets at each step), "
                 "one line per method, on a log scale; the grey band is the 95 % chi-square "
                 "band of a consistent filter for that many samples, the dashed line its "
                 "expected value 4.",
    "lost_share": f"Share of lost target-steps (position error > {LOST_THRESHOLD:g} m), mean "
                  "across runs with its 95 % t-interval.",
    "paired_differences": "Paired RMSE differences (method minus reference, run by run) "
                          "against the myopic planner and against random with the same "
                          "tracker; mean with its 95 % paired t-interval. Left of zero: "
                          "the method tracks better.",
    "planning_time": "Wall time of each planning decision per method (log scale).",
    "convergence": "Convergence of the game planners: share of decisions that ended at a "
                   "pure Nash equilibrium, and sweeps per decision.",
    "gospa_time": "Mean GOSPA over time (the reported tracks against the live targets, "
                  "c = 50 m), one line per method; the band is the 95 % interval across runs.",
    "gospa_runs": "GOSPA per run (each run's mean over its steps), one box per method (line: "
                  "median, box: quartiles, whiskers: 1.5 interquartile ranges, dots: the "
                  "runs), and the three parts of GOSPA^2 per run (localisation of the "
                  "assigned tracks, missed targets, false tracks; m^2).",
    "horizon": "Methods that differ only in the horizon K: overall RMSE (mean with its 95 % "
               "t-interval) and planning time per decision against K.",
}
#: Figures drawn only when the study has what they show.
OPTIONAL_FIGURES = ("gospa_runs", "horizon")



def draw_figures(t: StudyTables, out: Path, stats: dict[str, Any]) -> dict[str, Path]:
    """Write every figure of :data:`FIGURES` that applies into ``out``; return their paths.

    ``stats`` holds the report's statistics: ``rmse`` and ``lost`` (summaries), ``diffs``
    (paired differences), ``curves`` (RMSE over time) and ``plan`` (planning summary);
    ``quantity`` (optional, default ``RMSE``) names what the paired differences are of.
    """
    colors = _method_colors(t.study.method_names)
    figs = {
        "scenario": _fig_scenario(t, out / "scenario.png"),
        "rmse_time": _fig_rmse_time(stats["curves"], t, colors, out / "rmse_time.png"),
        "rmse_overall": _fig_rmse_overall(stats["rmse"], t, out / "rmse_overall.png"),
        "lost_share": _fig_lost(stats["lost"], t, out / "lost_share.png"),
        "nees_time": _fig_nees_time(stats["nees"], t, colors, out / "nees_time.png"),
        "paired_differences": _fig_paired(stats["diffs"], t, out / "paired_differences.png",
                                          stats.get("quantity", "RMSE")),
        "gospa_time": _fig_gospa_time(stats["gospa"], t, colors, out / "gospa_time.png"),
    }
    if len(t.decisions):             # a scan study plans nothing
        figs["planning_time"] = _fig_planning(t, colors, out / "planning_time.png")
        figs["convergence"] = _fig_convergence(stats["plan"], t, out / "convergence.png")
    if study_has_sets(t.study):
        figs["gospa_runs"] = _fig_gospa_runs(t, colors, out / "gospa_runs.png")
    else:
        (out / "gospa_runs.png").unlink(missing_ok=True)  # stale from an earlier report
    groups = horizon_groups(t.study)
    if groups:
        figs["horizon"] = _fig_horizon(groups, stats["rmse"], t, out / "horizon.png")
    else:
        (out / "horizon.png").unlink(missing_ok=True)     # stale from an earlier report
    return figs


def _method_colors(names: list[str]) -> dict[str, Any]:
    # Methods have their own palette (not the targets' nor the target kinds').
    return dict(method_colors(names))


def _new_figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110, layout="constrained")


def _save(fig: Figure, path: Path) -> Path:
    # "tight" keeps legends placed outside the axes inside the image.
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path


# ---------------------------------------------------------------------------- figures


def _fig_scenario(t: StudyTables, path: Path) -> Path:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    study = t.study
    run = t.runs_done[0]
    names = study.method_names
    shown = next((m.name for m in study.methods if m.settings.planner != "random"), names[0])
    steps = t.steps[(t.steps["run"] == run) & (t.steps["method"] == shown)]
    sens = t.sensors[(t.sensors["run"] == run) & (t.sensors["method"] == shown)]
    fig = _new_figure(10.0, 7.0)
    ax = fig.add_subplot()
    W, H = study.scenario.world.width, study.scenario.world.height
    border = Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.0)
    ax.add_patch(border)
    draw_buildings(ax, study.scenario.buildings)
    P0 = np.asarray(study.scenario.initial_cov)[:2, :2]
    limit = 3.0 * max(W, H)
    handles: list[Any] = []
    # Targets in their own colours (the same as in a run's figures); the kind is the
    # line style.
    # Every target of the run (with births, more than the scenario's templates), over the
    # steps it is alive; one born during the run starts with a star and has no initial
    # estimate.
    targets = sorted(int(j) for j in steps["target"].unique())
    born = False
    for j in targets:
        g = steps[steps["target"] == j].sort_values("step")
        kind = str(g["kind"].iloc[0])
        color = target_color(j)
        style: Any = "-" if kind == "cv" else "--"
        ax.plot(g["x"], g["y"], style, color=color, linewidth=1.6)
        start = "o" if g["step"].iloc[0] == 0 else "*"
        born |= start == "*"
        ax.plot(g["x"].iloc[0], g["y"].iloc[0], start, color=color,
                markersize=6 if start == "o" else 10)
        ax.plot(g["x"].iloc[-1], g["y"].iloc[-1], "s", color=color, markersize=6)
        x0 = np.array([g["x_est"].iloc[0], g["y_est"].iloc[0]])
        if start == "o" and np.all(np.isfinite(x0)):
            ax.plot(*x0, "x", color=color, markersize=7)
            draw_ellipse(ax, x0, P0, mix_hex(color, 0.7), limit, linewidth=0.9)
        ax.annotate(f"T{j}", (g["x"].iloc[0], g["y"].iloc[0]), textcoords="offset points",
                    xytext=(5, 5), fontsize=9, color=color, fontweight="bold")
        if len(targets) <= 12:
            handles.append(Line2D([], [], color=color, linestyle=style,
                                  label=f"T{j} ({kind})"))
    if len(targets) > 12:
        handles.append(Line2D([], [], color="0.5", label=f"{len(targets)} targets, one "
                                                         "colour each"))
    if born:
        handles.append(Line2D([], [], color="0.3", marker="*", linestyle="none",
                              markersize=9, label="target born during the run"))
    handles.append(Line2D([], [], color="0.3", marker="o", markersize=5, linewidth=1.2,
                          label="true track (\u25cf start, \u25a0 end; dashed: dubins)"))
    handles.append(Line2D([], [], color="0.3", marker="x", linestyle="none",
                          label="initial estimate with its 2\u03c3 ellipse"))
    for i, spec in enumerate(study.scenario.sensors):
        g = sens[sens["sensor"] == i].sort_values("step")
        color, marker = sensor_style(i)
        ax.plot(g["x"], g["y"], "-", color=mix_hex(color, 0.6), linewidth=0.9)
        x0, y0 = g["x"].iloc[0], g["y"].iloc[0]
        ax.plot(x0, y0, marker, color=color, markersize=9)
        # The field of view of the first step (after the first decision's move and turn).
        first = g.iloc[min(1, len(g) - 1)]
        x1, y1, h0 = first["x"], first["y"], first["heading"]
        p = spec.params
        fov = field_of_view(ax, np.array([x1, y1]), float(h0), p, color, alpha=0.08)
        fov.set_clip_path(border)
        handles.append(Line2D([], [], color=color, marker=marker,
                              label=f"sensor {i} ({float(p.altitude):g} m): start, path"))
    handles.append(Patch(facecolor="0.5", alpha=0.2, edgecolor="0.4", linestyle="--",
                         label="field of view in step 1"))
    frame_map(ax, W, H, 0.05)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8.5,
              frameon=False)
    ax.set_title(f"Run {run}: {study.steps} steps; sensor paths of method \u201c{shown}\u201d",
                 fontsize=11)
    return _save(fig, path)


def _method_styles(study: Any) -> dict[str, str]:
    """Line style per method: one per planning/tracker configuration (visibility, objective,
    tracker settings), so that the paper's configuration and ours read apart in line plots."""
    configs: dict[tuple[Any, ...], str] = {}
    styles = ["-", "--", ":", "-."]
    out = {}
    for m in study.methods:
        s = m.settings
        key = (s.visibility, s.objective, s.tracker)
        configs.setdefault(key, styles[len(configs) % len(styles)])
        out[m.name] = configs[key]
    return out


def _fig_rmse_time(curves: Any, t: StudyTables, colors: dict[str, Any],
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


def _fig_gospa_time(curves: Any, t: StudyTables, colors: dict[str, Any], path: Path) -> Path:
    dt = t.study.scenario.dt
    styles = _method_styles(t.study)
    fig = _new_figure(7.0, 5.0)
    ax = fig.subplots()
    for name in t.study.method_names:
        c = curves[curves["method"] == name]
        time_s = c["step"].to_numpy() * dt
        ax.plot(time_s, c["gospa"], color=colors[name], linestyle=styles[name], linewidth=1.5,
                label=name)
        ax.fill_between(time_s, c["lo"], c["hi"], color=colors[name], alpha=0.12, linewidth=0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("GOSPA (m)")
    ax.set_ylim(bottom=0)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(4, len(labels)),
               fontsize=9, frameon=False)
    fig.suptitle(f"GOSPA over time ({len(t.runs_done)} runs; band: 95 % interval)")
    return _save(fig, path)


def gospa_per_run(t: StudyTables) -> Any:
    """Each (method, run)'s mean over its steps of GOSPA (m) and of its three parts (m^2).

    Columns: method, run, gospa, localisation, missed, false.
    """
    return t.gospa.groupby(["method", "run"], observed=True).agg(
        gospa=("gospa", "mean"), localisation=("localisation", "mean"),
        missed=("missed", "mean"), false=("false", "mean")).reset_index()


def _fig_gospa_runs(t: StudyTables, colors: dict[str, Any], path: Path) -> Path:
    per_run = gospa_per_run(t)
    names = t.study.method_names
    fig = _new_figure(max(9.0, 1.1 * len(names) + 6.0), 4.8)
    axes = fig.subplots(1, 4, gridspec_kw={"width_ratios": [1.4, 1, 1, 1]})
    rng = np.random.default_rng(0)          # jitter of the dots only (drawing, not results)
    for ax, column, unit in zip(axes, ("gospa", "localisation", "missed", "false"),
                                ("m", "m\u00b2", "m\u00b2", "m\u00b2")):
        data = [per_run.loc[per_run["method"] == n, column].to_numpy(float) for n in names]
        box = ax.boxplot(data, orientation="horizontal", widths=0.55, patch_artist=True,
                         showfliers=False, medianprops=dict(color="k", linewidth=1.4))
        for patch, name in zip(box["boxes"], names):
            patch.set_facecolor(mix_hex(colors[name], 0.35))
            patch.set_edgecolor(colors[name])
        for k, (values, name) in enumerate(zip(data, names)):
            ax.scatter(values, k + 1 + rng.uniform(-0.18, 0.18, len(values)), s=9,
                       color=colors[name], linewidths=0, zorder=3)
        ax.set_yticks(range(1, len(names) + 1),
                      names if column == "gospa" else [""] * len(names))
        ax.invert_yaxis()
        ax.set_xlabel(f"{'GOSPA' if column == 'gospa' else column} ({unit})")
        ax.set_xlim(left=0)
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
        ax.set_title("GOSPA per run" if column == "gospa" else f"{column} part", fontsize=10)
    fig.suptitle(f"GOSPA per run and its parts ({len(t.runs_done)} runs)")
    return _save(fig, path)


def _fig_nees_time(curves: Any, t: StudyTables, colors: dict[str, Any], path: Path) -> Path:
    kinds = list(dict.fromkeys(t.study.scenario.target_kinds))
    dt = t.study.scenario.dt
    styles = _method_styles(t.study)
    fig = _new_figure(6.0 * len(kinds) + 0.5, 5.0)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        ck = curves[(curves["kind"] == kind) & (curves["step"] >= 1)]
        band = ck.groupby("step")[["band_lo", "band_hi"]].first()
        time_s = band.index.to_numpy() * dt
        ax.fill_between(time_s, band["band_lo"], band["band_hi"], color="0.8", linewidth=0,
                        label="95 % band (consistent)")
        ax.axhline(4.0, color="0.35", linestyle="--", linewidth=0.8)
        for name in t.study.method_names:
            c = ck[ck["method"] == name]
            ax.plot(c["step"].to_numpy() * dt, c["anees"], color=colors[name],
                    linestyle=styles[name], linewidth=1.2, label=name)
        ax.set_yscale("log")
        _plain_log_labels(ax.yaxis)
        ax.set_title(f"{kind} targets")
        ax.set_xlabel("time (s)")
        ax.grid(True, which="both", linewidth=0.3, alpha=0.5)
    axes[0].set_ylabel("average NEES")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)),
               fontsize=9, frameon=False)
    fig.suptitle("Track consistency over time: average NEES (4 for an honest filter)")
    return _save(fig, path)


def _method_axis(ax: Axes, names: list[str]) -> np.ndarray:
    y = np.arange(len(names))[::-1].astype(float)
    ax.set_yticks(y, names)
    ax.set_ylim(-0.7, len(names) - 0.3)
    return y


def _fig_rmse_overall(summ: Any, t: StudyTables, path: Path) -> Path:
    kinds = kinds_with_all(t.study)
    names = t.study.method_names
    fig = _new_figure(3.6 * len(kinds) + 2.2, 0.42 * len(names) + 1.9)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        y = _method_axis(ax, names)
        s = summ[summ["kind"] == kind].set_index("method").reindex(names)
        mean, med = s["mean"].to_numpy(float), s["median"].to_numpy(float)
        ax.errorbar(mean, y + 0.13, xerr=_xerr(mean, s["mean_lo"], s["mean_hi"]), fmt="o",
                    color=MEAN_COLOR, capsize=3, markersize=5, label="mean, 95 % t-interval")
        ax.errorbar(med, y - 0.13, xerr=_xerr(med, s["median_lo"], s["median_hi"]),
                    fmt="D", color=MEDIAN_COLOR, markerfacecolor="white", capsize=3,
                    markersize=4.5, label="median, 95 % order-statistic interval")
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


def _fig_lost(lost: Any, t: StudyTables, path: Path) -> Path:
    kinds = kinds_with_all(t.study)
    names = t.study.method_names
    fig = _new_figure(3.4 * len(kinds) + 2.2, 0.42 * len(names) + 1.6)
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds):
        y = _method_axis(ax, names)
        s = lost[lost["kind"] == kind].set_index("method").reindex(names)
        mean = 100 * s["mean"].to_numpy(float)
        ax.barh(y, mean, color=kind_color(kind), alpha=0.75, height=0.6)
        ax.errorbar(mean, y, xerr=_xerr(mean, 100 * s["mean_lo"], 100 * s["mean_hi"]),
                    fmt="none", ecolor="k", capsize=3, linewidth=1.0)
        ax.set_title(f"{kind} targets" if kind != "all" else "all targets")
        ax.set_xlabel("lost target-steps (%)")
        ax.set_xlim(left=0)
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
    fig.suptitle(f"Share of target-steps with position error > {LOST_THRESHOLD:g} m "
                 "(mean across runs, 95 % t-interval)")
    return _save(fig, path)


def _fig_paired(diffs: Any, t: StudyTables, path: Path, quantity: str = "RMSE") -> Path:
    kinds = kinds_with_all(t.study)
    if quantity != "RMSE":
        # GOSPA is of the whole set: one kind, the one that covers every target.
        kinds = kinds[-1:]
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
                        fmt=kind_marker(kind), color=kind_color(kind), capsize=3, markersize=5,
                        label=f"{kind} targets" if kind != "all" else "all targets")
        ax.axvline(0.0, color="k", linewidth=0.9)
        ax.set_xlabel(f"\u0394 {quantity} = method \u2212 reference (m)   \u2190 method better")
        ax.set_title(f"against {against}")
        ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
        handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9,
                   frameon=False)
    fig.suptitle(f"Paired {quantity} differences per run: mean with 95 % paired t-interval")
    return _save(fig, path)


def _fig_planning(t: StudyTables, colors: dict[str, Any], path: Path) -> Path:
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


def _fig_convergence(plan: Any, t: StudyTables, path: Path) -> Path:
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
    axes[0].barh(y, share, color="0.55", height=0.6)
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


def _fig_horizon(groups: list[list[Method]], summ: Any, t: StudyTables,
                 path: Path) -> Path:
    kinds = kinds_with_all(t.study)
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
            color = kind_color(kind)
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
        ax_time.plot(ks, mean_ms, marker="o", linestyle=styles[gi % 4], color=MEAN_COLOR,
                     label=f"mean{tag} (fit: \u221d K^{p:.1f})")
        ax_time.plot(ks, med_ms, marker="D", markerfacecolor="white",
                     linestyle=styles[gi % 4], color=MEDIAN_COLOR, label=f"median{tag}")
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
