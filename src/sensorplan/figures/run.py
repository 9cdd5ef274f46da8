"""Figures of saved runs (matplotlib only here, Agg canvas; the CLI imports this lazily).

Plots read what a run recorded (:class:`~sensorplan.simulation.run.Episode`) and the scenario
it ran; they compute nothing the run did not record except the drawing geometry. Colours
come from :mod:`sensorplan.figures.colors` (a target has one colour in every figure; sensors are
greys with distinct markers). :func:`plot_episode` writes the static figure of a run,
:mod:`sensorplan.figures.animation` its animation; both use the drawing helpers here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import (BUILDING_EDGE, BUILDING_FACE, mix, mix_hex, sensor_style, target_color,
                     target_colors)
from .view import CLIP_MAPS as CLIP_MAPS  # the clipping bound lives beside the geometry
from .view import (DENSE_SENSORS, DENSE_TARGETS, LEGEND_ITEMS, N_SIGMA,
                   TIMELINE_IMAGE_HEIGHT, RunView, clip_xy, fade_colors, fov_geometry,
                   map_legend_beside, map_limit, segments)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.patches import Wedge

    from ..simulation.run import Episode
    from ..simulation.scenario import Scenario

#: Number of times at which the static figure draws ellipses, fields of view and looks.
N_ELLIPSES = 5
#: Hatch of a missed look in the assignment timeline.
MISS_HATCH = "////"
#: How a missed look shows in the timeline image.
MISSED_DOT = "light with a black dot"


# ------------------------------------------------------------------------ geometry


def ellipse_geometry(C: Any, limit: float) -> tuple[float, float, float] | None:
    """Width, height (m) and angle (deg) of the ``N_SIGMA`` ellipse of a 2-D covariance.

    Parameters
    ----------
    C : (2, 2) float64
        Position covariance (m^2).
    limit : float
        Largest drawn semi-axis (m): larger ones are clipped to it.

    Returns
    -------
    ``(width, height, angle)`` with ``width >= height`` (the major axis at ``angle``), or
    None when ``C`` is not finite.
    """
    C = np.asarray(C, dtype=float)
    if not np.all(np.isfinite(C)):
        return None
    try:
        vals, vecs = np.linalg.eigh(0.5 * C + 0.5 * C.T)     # halves first: no overflow
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(vals)):
        return None
    semi = np.minimum(N_SIGMA * np.sqrt(np.clip(vals, 0.0, None)), limit)
    angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    return 2.0 * float(semi[1]), 2.0 * float(semi[0]), angle


def field_of_view(ax: Axes, xy: np.ndarray, heading: float, params: object,
                  color: str, alpha: float = 0.15) -> Wedge:
    """Ground sensing region: the range-band annulus sector of the azimuth wedge."""
    from matplotlib.patches import Wedge

    wedge = Wedge(**fov_geometry(xy, heading, params), facecolor=color, alpha=alpha,
                  edgecolor=color, linewidth=1.0, linestyle="--")
    ax.add_patch(wedge)
    return wedge


@dataclass(frozen=True)
class LookRun:
    """Consecutive steps ``first..last`` (inclusive) in which ``sensor`` looked at
    ``target`` with the same outcome (``missed``)."""

    sensor: int
    target: int
    missed: bool
    first: int
    last: int


def look_runs(looked: Any, missed: Any) -> list[LookRun]:
    """The assignment timeline of a run: runs of equal (target, missed) per sensor over
    steps ``1..S`` (steps without a look, ``target = -1``, are left out).

    Parameters
    ----------
    looked : (S+1, N) int
    missed : (S+1, N) bool
    """
    looked = np.asarray(looked)
    missed = np.asarray(missed, dtype=bool)
    out = []
    for i in range(looked.shape[1]):
        start = 1
        for t in range(2, looked.shape[0] + 1):
            if t == looked.shape[0] or (looked[t, i], missed[t, i]) != \
                    (looked[start, i], missed[start, i]):
                if looked[start, i] >= 0:
                    out.append(LookRun(i, int(looked[start, i]), bool(missed[start, i]),
                                       start, t - 1))
                start = t
    return out


# ------------------------------------------------------------------------- drawing


def frame_map(ax: Axes, width: float, height: float, margin: float) -> None:
    """Equal-aspect map axes in metres, with ``margin`` (a fraction of the map) around it."""
    pad = margin * max(width, height)
    ax.set_xlim(-pad, width + pad)
    ax.set_ylim(-pad, height + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, linewidth=0.4, alpha=0.4)


#: Buildings are labelled with their height when there are at most this many (more labels
#: cover the map and take long to draw).
MAX_LABELLED_BUILDINGS = 40


def draw_buildings(ax: Axes, buildings: Any) -> None:
    """Buildings ``(x0, y0, x1, y1, height)`` as grey rectangles, labelled with their
    height when there are at most :data:`MAX_LABELLED_BUILDINGS`."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    rows = [tuple(float(v) for v in b) for b in buildings]
    if not rows:
        return
    if len(rows) > MAX_LABELLED_BUILDINGS:
        # One collection, drawn in one call: thousands of buildings stay quick to draw.
        ax.add_collection(PatchCollection(
            [Rectangle((x0, y0), x1 - x0, y1 - y0) for x0, y0, x1, y1, _ in rows],
            facecolor=BUILDING_FACE, edgecolor=BUILDING_EDGE, linewidth=1.0, zorder=1.5))
        return
    for x0, y0, x1, y1, h in rows:
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=BUILDING_FACE,
                               edgecolor=BUILDING_EDGE, linewidth=1.0, zorder=1.5))
        ax.text(0.5 * (x0 + x1), 0.5 * (y0 + y1), f"{h:g} m", ha="center", va="center",
                fontsize=7.5, color="#333333", zorder=1.6, clip_on=True)


def draw_ellipse(ax: Axes, mean: Any, C: Any, color: str, limit: float, **kw: Any) -> None:
    """Draw the ``N_SIGMA`` ellipse of ``C (2, 2)`` around ``mean`` (nothing if not finite)."""
    from matplotlib.patches import Ellipse

    geo = ellipse_geometry(C, limit)
    if geo is None or not np.all(np.isfinite(mean)):
        return
    ax.add_patch(Ellipse(tuple(mean), geo[0], geo[1], angle=geo[2], fill=False,
                         edgecolor=color, **kw))


def draw_timeline(ax: Axes, episode: Episode, dt: float) -> None:
    """Sensor-to-target assignment: one row per sensor, time on x, a cell per step in the
    colour of the target looked at (hatched when the look missed), decision times as thin
    lines, and false alarms (if any) as dots sized by their count. Above
    :data:`DENSE_SENSORS` sensors the cells are one image, a missed look a light cell with a
    black dot, and every tenth row or so is labelled."""
    looked = np.asarray(episode.looked)
    missed = np.asarray(episode.missed)
    S, N = looked.shape[0] - 1, looked.shape[1]
    many = N > DENSE_SENSORS
    # The limits are set below; autoscaling after every bar would cost O(bars^2).
    ax.set_autoscale_on(False)
    if many:
        from .swarm import draw_look_image

        draw_look_image(ax, looked, missed, dt)
    for run in ([] if many else look_runs(looked, missed)):
        c = target_color(run.target)
        ax.broken_barh([((run.first - 1) * dt, (run.last - run.first + 1) * dt)],
                       (run.sensor - 0.38, 0.76),
                       facecolors=mix(c, 0.45) if run.missed else c,
                       edgecolor="#222222" if run.missed else "none",
                       hatch=MISS_HATCH if run.missed else None, linewidth=0.0,
                       gid=f"look S{run.sensor} T{run.target}" +
                           (" missed" if run.missed else ""))
    steps = np.asarray(episode.decision_steps, dtype=float)
    # Decisions as ticks above the rows (a line per decision would grid over every cell
    # when the run decides at every step).
    ax.plot(steps * dt, np.full(steps.shape, -0.62), "|", color="0.35", markersize=5,
            clip_on=False, markeredgewidth=0.8)
    fa = np.asarray(episode.false_alarms)
    if fa[1:].any():
        when, who = np.nonzero(fa[1:])
        ax.scatter((when + 0.5) * dt, who + 0.25, s=6 + 6 * fa[1:][when, who], color="k",
                   zorder=3, linewidths=0)
    if many:
        from .swarm import label_rows

        label_rows(ax, N)
    else:
        ax.set_yticks(range(N), [f"S{i}" for i in range(N)])
    ax.set_ylim(N - 0.5, -0.5)
    ax.set_xlim(0, S * dt)
    ax.tick_params(axis="y", length=0, pad=4 if many else 16)
    for i in range(0 if many else N):
        color, marker = sensor_style(i)
        ax.plot(-0.011, i, marker, color=color, transform=ax.get_yaxis_transform(),
                clip_on=False, markersize=6)
    ax.set_title(f"Looks: colour = target looked at, {MISSED_DOT if many else 'hatched'} = "
                 "the look missed (no detection of it), ticks on top = decisions"
                 + ("; dots = false alarms (size: count)" if fa[1:].any() else ""),
                 fontsize=9, loc="left", pad=8)


def draw_errors(ax: Axes, episode: Episode, dt: float) -> None:
    """Position error of each target over time (log scale) with the filter's own RMS
    position error ``sqrt(tr P_xy)`` (dotted) and the lost-track threshold (a multi-target
    tracker's: the GOSPA cut-off, beyond which no track is assigned)."""
    from ..study.metrics import LOST_THRESHOLD

    settings = getattr(episode, "settings", None)
    if settings is None or settings.tracker.kind == "known":
        limit, label = LOST_THRESHOLD, f"lost above {LOST_THRESHOLD:g} m"
    else:
        limit = float(settings.gospa_c)
        label = f"no track beyond c = {limit:g} m"

    err = np.asarray(episode.error, dtype=float)
    cov = np.asarray(episode.cov, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        own = np.sqrt(cov[..., 0, 0] + cov[..., 1, 1])
    time_s = np.arange(err.shape[0]) * dt
    floor = 0.1
    many = err.shape[1] > DENSE_TARGETS
    if many:
        from .swarm import draw_error_bundle

        draw_error_bundle(ax, time_s, err, own, floor)
    for j in range(0 if many else err.shape[1]):
        c = target_color(j)
        ax.plot(time_s, np.clip(err[:, j], floor, None), color=c, linewidth=1.4)
        ax.plot(time_s, np.clip(own[:, j], floor, 1e9), color=c, linewidth=0.9, linestyle=":")
    ax.axhline(limit, color="0.3", linestyle="--", linewidth=0.8)
    ax.text(0.995, limit, label, va="bottom",
            ha="right", fontsize=7.5, color="0.3", transform=ax.get_yaxis_transform())
    ax.set_yscale("log")
    top = np.nanmax(np.where(np.isfinite(err), err, np.nan)) if np.isfinite(err).any() else 1
    ax.set_ylim(max(floor, 0.5 * np.nanmin(np.clip(err[1:], floor, None))),
                max(2.0 * top, 2.0 * limit))
    ax.set_xlim(0, (err.shape[0] - 1) * dt)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position error (m)")
    ax.grid(True, which="major", linewidth=0.4, alpha=0.5)
    ax.set_title((f"Position error of each of the {err.shape[1]} targets (thin), their "
                  "median (black) and the median of the filter's own RMS error \u221atr P "
                  "(dotted)") if many else
                 ("Position error per target (solid) and the filter's own RMS error "
                  "\u221atr P (dotted)"), fontsize=9, loc="left")


def episode_layout(episode: Episode, scenario: Scenario, width: float = 10.5,
                   map_height: float = 7.0, dpi: float = 110
                   ) -> tuple[Figure, Axes, Axes, Axes]:
    """A bare Agg figure with the map on top, the assignment timeline and the error panel
    below (sharing the time axis): ``(figure, map, timeline, errors)``."""
    # The Agg canvas of a bare Figure: no pyplot, so no global backend switch and no figure
    # registry (safe inside notebooks and worker processes).
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    N = np.asarray(episode.looked).shape[1]
    timeline_h = timeline_height(N, 0.32) + 0.75
    error_h = 2.3
    fig = Figure(figsize=(width, map_height + timeline_h + error_h + 0.6), dpi=dpi)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 1, height_ratios=[map_height, timeline_h, error_h],
                            hspace=0.28, left=0.08, right=0.97, top=0.96, bottom=0.05)
    ax_map = fig.add_subplot(grid[0])
    ax_time = fig.add_subplot(grid[1])
    ax_err = fig.add_subplot(grid[2], sharex=ax_time)
    ax_time.tick_params(labelbottom=False)
    return fig, ax_map, ax_time, ax_err


def map_legend(ax: Axes, episode: Episode, scenario: Scenario,
               extra: list[Any]) -> None:
    """Legend right of the map: the targets (colour, kind), the sensors (grey, marker,
    altitude), buildings, then ``extra`` handles; more than :data:`LEGEND_ITEMS` targets
    (sensors) are one summary entry."""
    from matplotlib.patches import Patch

    kinds = tuple(episode.target_kinds)
    if len(kinds) > LEGEND_ITEMS or len(scenario.sensors) > LEGEND_ITEMS:
        from .swarm import summary_legend

        summary_legend(ax, kinds, scenario, extra)
        return
    handles: list[Any] = [Patch(facecolor=c, label=f"T{j} ({kind})")
                          for j, (c, kind) in enumerate(zip(target_colors(len(kinds)), kinds))]
    map_legend_beside(ax, handles, scenario, extra, fontsize=8.5)


def episode_title(episode: Episode) -> str:
    """Planner, horizon, steps and the targets' RMSE (each one's up to
    :data:`LEGEND_ITEMS` targets, else their median and worst)."""
    s = episode.settings
    rmse = np.asarray(episode.rmse())
    head = (f"{s.planner}, K = {s.horizon}, e = {s.steps_per_epoch}, {s.execution.upper()}, "
            f"{np.asarray(episode.error).shape[0] - 1} steps \u2014 ")
    if rmse.size > LEGEND_ITEMS:
        from .swarm import rmse_summary

        return head + rmse_summary(rmse)
    return head + "RMSE per target: " + ", ".join(f"{v:.0f}" for v in rmse) + " m"


def timeline_height(N: int, row: float) -> float:
    """Height (inches) of the timeline's rows: ``row`` per sensor, at most
    :data:`TIMELINE_IMAGE_HEIGHT` when the timeline is an image."""
    return min(row * N, TIMELINE_IMAGE_HEIGHT) if N > DENSE_SENSORS else row * N


# ---------------------------------------------------------------------- the figure


def run_view(episode: Episode, scenario: Scenario) -> RunView:
    """The :class:`RunView` of a run on its scenario."""
    truth = clip_xy(np.asarray(episode.truth)[..., :2], scenario)
    S = truth.shape[0] - 1
    return RunView(truth=truth, est=clip_xy(np.asarray(episode.estimate)[..., :2], scenario),
                   cov=np.asarray(episode.cov), spos=clip_xy(episode.sensor_positions, scenario),
                   shead=np.asarray(episode.sensor_headings),
                   looked=np.asarray(episode.looked), missed=np.asarray(episode.missed),
                   times=np.unique(np.linspace(0, S, N_ELLIPSES).round().astype(int)),
                   ages=1.0 - np.arange(S) / max(S - 1, 1), limit=map_limit(scenario))


def draw_sensors(ax: Axes, run: RunView, scenario: Scenario, border: Any) -> None:
    """Each sensor's fields of view and looks at the ellipse times, its path, markers,
    final heading and name (one set of artists per sensor)."""
    from matplotlib.collections import LineCollection

    spos, shead, truth, S = run.spos, run.shead, run.truth, run.S
    W, H = scenario.world.width, scenario.world.height
    looks_at = [t for t in run.times if t >= 1]
    for i in range(run.N):
        color, marker = sensor_style(i)
        params = scenario.sensors[i].params
        for t in looks_at:
            last = t == S
            fov = field_of_view(ax, spos[t, i], float(shead[t, i]), params, color,
                                alpha=0.10 if last else 0.0)
            fov.set_clip_path(border)       # the sensing region that matters is on the map
            if not last:
                fov.set_linewidth(0.6)
                fov.set_linestyle(":")
                fov.set_edgecolor(mix(color, 0.55))
        if S > 0:
            # Lighter than the tracks: the lattice paths are context, the tracks the subject.
            ax.add_collection(LineCollection(list(segments(spos[:, i])), colors=fade_colors(
                mix_hex(color, 0.7), run.ages, None), linewidths=0.8, zorder=2))
        ax.plot(*spos[0, i], marker, color=color, markersize=7, markerfacecolor="white",
                zorder=4)
        ax.plot(*spos[-1, i], marker, color=color, markersize=9, zorder=4)
        arrow = 0.06 * max(W, H)
        ax.annotate("", xy=(spos[-1, i, 0] + arrow * math.cos(shead[-1, i]),
                            spos[-1, i, 1] + arrow * math.sin(shead[-1, i])),
                    xytext=tuple(spos[-1, i]),
                    arrowprops=dict(arrowstyle="->", color=color, linewidth=1.4))
        ax.annotate(f"S{i}", tuple(spos[-1, i]), textcoords="offset points", xytext=(7, -13),
                    color=color, fontsize=9, fontweight="bold")
        for t in looks_at:
            j = run.looked[t, i]
            if j < 0:
                continue
            ax.plot([spos[t, i, 0], truth[t, j, 0]], [spos[t, i, 1], truth[t, j, 1]],
                    color=target_color(j), linewidth=0.9, zorder=2.5,
                    linestyle="--" if run.missed[t, i] else "-", alpha=0.85)


def draw_targets(ax: Axes, run: RunView) -> None:
    """Each target's true and estimated track, start and end, ellipses at the ellipse
    times, name and missed looks (one set of artists per target)."""
    from matplotlib.collections import LineCollection

    truth, est, S = run.truth, run.est, run.S
    for j in range(run.M):
        c = target_color(j)
        if S > 0:
            ax.add_collection(LineCollection(list(segments(truth[:, j])),
                                             colors=fade_colors(c, run.ages, None),
                                             linewidths=2.2, zorder=3))
            ax.add_collection(LineCollection(list(segments(est[:, j])),
                                             colors=fade_colors(c, run.ages, None),
                                             linewidths=1.2, linestyles=":", zorder=3))
        ax.plot(*truth[0, j], "o", color=mix(c, 0.5), markersize=6, zorder=4)
        ax.plot(*truth[-1, j], "s", color=c, markersize=6, zorder=4)
        for t in run.times:
            draw_ellipse(ax, est[t, j], run.cov[t, j, :2, :2], c, run.limit, linewidth=1.0,
                         alpha=0.35 + 0.6 * t / max(S, 1), zorder=3)
        ax.annotate(f"T{j}", tuple(truth[-1, j]), textcoords="offset points", xytext=(6, 4),
                    color=c, fontsize=9, fontweight="bold")
        miss_t = np.nonzero((run.looked[1:] == j) & run.missed[1:])[0] + 1
        if miss_t.size:
            ax.plot(truth[miss_t, j, 0], truth[miss_t, j, 1], "x", color="k", markersize=5,
                    markeredgewidth=1.2, zorder=5, linestyle="none")


def map_handles(run: RunView, dt: float) -> list[Any]:
    """Legend entries of the map's line and shape kinds (after targets and sensors)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    many_s, many_t = run.N > DENSE_SENSORS, run.M > DENSE_TARGETS
    when = ", ".join(f"{t * dt:g}" for t in run.times)
    last = f"{run.S * dt:g}"
    if many_s:
        looks, fov = f"at step {run.S}", f"field of view at step {run.S}"
    else:
        looks = f"at t = {when} s" if many_t else "at the ellipse times"
        fov = f"field of view at step {run.S} (dotted: {looks})"
    return [
        Line2D([], [], color="0.25", linewidth=2.2,
               label="true track, light \u2192 dark = early \u2192 late (\u25cf start, "
                     "\u25a0 end)"),
        Line2D([], [], color="0.25", linestyle=":", linewidth=1.2, label="estimate"),
        Line2D([], [], color="0.25", marker="o", markerfacecolor="none", linestyle="none",
               markersize=10, label=f"{N_SIGMA:g}\u03c3 position ellipse "
                                    f"(t = {last if many_t else when} s)"),
        Line2D([], [], color="k", marker="x", linestyle="none", markersize=6,
               label="a look at the target missed"),
        Line2D([], [], color="0.25", linewidth=1.0,
               label=f"sensor \u2192 looked-at target (dashed: missed), {looks}"),
        Patch(facecolor="0.5", alpha=0.2, edgecolor="0.3", linestyle="--", label=fov),
        Line2D([], [], color="0.25", marker="^", markerfacecolor="white", linestyle="none",
               markersize=8, label="sensor start (open), end (filled)"
                                   + ("" if many_s else ", arrow = heading")),
    ]


def episode_figure(episode: Episode, scenario: Scenario) -> Figure:
    """The static figure of a run (see :func:`plot_episode`), not yet saved."""
    from matplotlib.patches import Rectangle

    from ..study.lifespan import is_set_run
    from . import swarm as dense

    if is_set_run(episode):
        return set_episode_figure(episode, scenario)
    run = run_view(episode, scenario)
    W, H = scenario.world.width, scenario.world.height
    fig, ax, ax_time, ax_err = episode_layout(episode, scenario)
    border = Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.2)
    ax.add_patch(border)
    draw_buildings(ax, scenario.buildings)
    if run.N > DENSE_SENSORS:
        dense.draw_sensors(ax, run, scenario, border)
    else:
        draw_sensors(ax, run, scenario, border)
    if run.M > DENSE_TARGETS:
        dense.draw_targets(ax, run)
    else:
        draw_targets(ax, run)
    map_legend(ax, episode, scenario, map_handles(run, scenario.dt))
    frame_map(ax, W, H, 0.03)
    ax.set_title(episode_title(episode), fontsize=10)
    draw_timeline(ax_time, episode, scenario.dt)
    draw_errors(ax_err, episode, scenario.dt)
    return fig


def set_episode_figure(episode: Episode, scenario: Scenario) -> Figure:
    """The static figure of a run of changing sets (:mod:`sensorplan.figures.sets`), not yet
    saved."""
    import dataclasses

    from matplotlib.patches import Rectangle

    from ..study.set_metrics import episode_set_metrics
    from . import swarm as dense
    from .sets import (draw_gospa_parts, draw_set_looks, draw_set_targets, draw_set_timeline,
                       draw_set_tracks, set_handles, set_legend, set_title, set_view)

    run = run_view(episode, scenario)
    view = set_view(episode, scenario)
    sm = episode_set_metrics(episode)
    W, H = scenario.world.width, scenario.world.height
    fig, ax, ax_time, ax_err = episode_layout(episode, scenario)
    border = Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.2)
    ax.add_patch(border)
    draw_buildings(ax, scenario.buildings)
    # The sensors as for known targets, without their look lines (drawn to tracks below).
    quiet = dataclasses.replace(run, looked=np.full_like(run.looked, -1))
    if run.N > DENSE_SENSORS:
        dense.draw_sensors(ax, quiet, scenario, border)
    else:
        draw_sensors(ax, quiet, scenario, border)
        draw_set_looks(ax, run.spos, view, run.times)
    draw_set_targets(ax, view)
    draw_set_tracks(ax, view, run.times, map_limit(scenario))
    from .search import has_search

    search = None
    if has_search(episode):
        # Search: the undetected intensity of the last step under the scene.
        from .search import colour_bar, draw_heat_map, search_view

        search = search_view(episode, scenario)
        heat = draw_heat_map(ax, search, search.sectors.shape[0] - 1, scenario)
        if heat is not None:
            bar = colour_bar(fig, heat, ax.inset_axes((1.03, 0.0, 0.42, 0.025)))
            bar.set_label("undetected intensity at the last step: expected targets per "
                          "km\u00b2", fontsize=7.5)
    set_legend(ax, episode, scenario, set_handles(view, run.times, scenario.dt))
    frame_map(ax, W, H, 0.03)
    ax.set_title(set_title(episode, sm.gospa), fontsize=10)
    draw_set_timeline(ax_time, view, scenario.dt, episode.decision_steps)
    if search is not None:
        from .search import draw_search_timeline

        draw_search_timeline(ax_time, search.sectors, scenario.dt)
    draw_gospa_parts(ax_err, sm.gospa, sm.n_targets, sm.n_tracks, scenario.dt,
                     episode.settings.gospa_c)
    return fig


def plot_episode(episode: Episode, scenario: Scenario, path: str | Path) -> Path:
    """The figure of one run: map, assignment timeline and errors over time.

    - Map: the map rectangle and buildings (grey, labelled with their height); each
      target's true track (solid) and estimate (dotted) in the target's colour, light to
      dark from the first to the last step, with its start (circle) and end (square) and
      ``2 sigma`` position ellipses at ``N_ELLIPSES`` evenly spaced times; a black cross
      where a look at the target missed; each sensor's ground path (grey, its own marker:
      open at the start, filled at the end, arrow = final heading); at the ellipse times the
      line from each sensor to the target it looked at (dashed if the look missed) and its
      field of view (the range-band annulus sector of its azimuth wedge; shaded at the
      last step).
    - Timeline: one row per sensor, one cell per step in the colour of the target it looked
      at, hatched when the look missed; decisions as thin lines; false alarms as dots.
    - Errors: each target's position error over time and the filter's own RMS error.

    A run of changing sets (a multi-target tracker, or targets born or dying) is drawn from
    its set records instead (:mod:`sensorplan.figures.sets`): each target over its life span
    with birth and death markers, the reported tracks by label with their line width growing
    with their existence r, false tracks dashed, confirmations and deletions marked, and
    GOSPA's parts in place of the per-target errors.

    Runs with more than :data:`DENSE_SENSORS` sensors or :data:`DENSE_TARGETS` targets are
    drawn condensed (:mod:`sensorplan.figures.swarm`), and the legend and title summarise
    more than :data:`LEGEND_ITEMS` of either.

    Parameters
    ----------
    episode : Episode
        ``truth, estimate (S+1, M, 4)``, ``cov (S+1, M, 4, 4)``,
        ``sensor_positions (S+1, N, 2)``, ``sensor_headings (S+1, N)``, ``looked``,
        ``missed (S+1, N)``, ``error (S+1, M)``.
    scenario : Scenario
        The map, the buildings and the sensors' parameters.
    path : path
        Output file; the format follows the suffix (``.png``).

    Returns
    -------
    Path of the written file.
    """
    fig = episode_figure(episode, scenario)
    path = Path(path)
    fig.savefig(path, bbox_inches="tight")      # keeps the legend outside the axes
    return path
