"""Figures of a run of changing sets: targets born and dying, tracks confirmed and deleted.

A run with a multi-target tracker, or with targets that are born or die
(:func:`~sensorplan.study.lifespan.is_set_run`), is drawn from its set records:

- each target's true path only over its life span, a star where it is born, a filled cross
  where it dies (a circle for the targets alive at the start, a square at the end);
- each reported track by its label, its line width growing with its probability of existence
  r (:func:`track_width`), in the colour of the target GOSPA assigns it to at that step, or
  black and dashed when it is assigned to none (a false track); a plus where a track is
  confirmed (its label's first report), a thin diamond where it is deleted (its last);
- sensors as for known targets, each look's line going to the track it looked at;
- the timeline coloured by the looked-at track's target (light with a dot: the look returned
  no detection), and GOSPA's three parts per step instead of the per-target errors.

:func:`sensorplan.figures.run.episode_figure` draws a run of known targets exactly as before
and a run of sets from the pieces here (:func:`~sensorplan.figures.run.set_episode_figure`);
the animation draws from :class:`SetView` too (:class:`SetLayer`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import FALSE_TRACK, mix, target_color
from .swarm import target_rgb
from .view import N_SIGMA

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from ..simulation.run import Episode
    from ..simulation.scenario import Scenario
    from ..study.lifespan import Events

#: Markers of the life events (the legend says which is which).
BIRTH_MARKER, DEATH_MARKER = "*", "X"
CONFIRM_MARKER, DELETE_MARKER = "P", "d"
#: Parts of GOSPA^2 in the error panel (greys: no target, method or kind shares them).
PART_COLORS = {"localisation": "#3d3d3d", "missed": "#8f8f8f", "false": "#cfcfcf"}


def track_width(r: Any) -> np.ndarray:
    """Line width (points) of a track with probability of existence ``r`` in [0, 1]:
    0.4 at r = 0, 3.0 at r = 1 (linear)."""
    return 0.4 + 2.6 * np.clip(np.asarray(r, dtype=float), 0.0, 1.0)


@dataclass(frozen=True)
class SetView:
    """What the figures of a run of sets draw, positions clipped for drawing (m).

    Attributes
    ----------
    alive : (S+1, M) bool
    truth : (S+1, M, 2)
    step, label : (R,) int          the reported track rows, step-major
    xy : (R, 2)                     their means
    cov : (R, 2, 2)                 their position covariances
    r : (R,)                        their probabilities of existence
    target : (R,) int               the target each is assigned to (-1: a false track)
    rgb : (R, 3)                    its colour: its target's, or :data:`FALSE_TRACK`
    looked : (S+1, N) int           label of the track each sensor looked at (-1: none)
    empty_look : (S+1, N) bool      the look returned no detection
    events : Events
    """

    alive: np.ndarray
    truth: np.ndarray
    step: np.ndarray
    label: np.ndarray
    xy: np.ndarray
    cov: np.ndarray
    r: np.ndarray
    target: np.ndarray
    rgb: np.ndarray
    looked: np.ndarray
    empty_look: np.ndarray
    events: Events

    @property
    def S(self) -> int:
        return self.alive.shape[0] - 1

    def rows_at(self, t: int) -> slice:
        """The track rows of step ``t``."""
        lo, hi = np.searchsorted(self.step, [t, t + 1])
        return slice(int(lo), int(hi))

    def look_points(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """Where each sensor's look at step ``t`` points, ``(N, 2)`` (NaN: no look, or its
        track is not reported at ``t``), and the colour of its line ``(N, 3)``."""
        rows = self.rows_at(t)
        labels = self.label[rows]
        want = self.looked[t]
        N = len(want)
        if not len(labels):
            return np.full((N, 2), np.nan), np.full((N, 3), 0.5)
        hit = want[:, None] == labels[None, :]
        k = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
        ok = (want >= 0) & (k >= 0)
        xy = np.where(ok[:, None], self.xy[rows][np.maximum(k, 0)], np.nan)
        rgb = np.where(ok[:, None], self.rgb[rows][np.maximum(k, 0)], 0.5)
        return xy, rgb


def set_view(episode: Episode, scenario: Scenario) -> SetView:
    """The :class:`SetView` of a run on its scenario."""
    from ..study.lifespan import episode_events, looked_labels, track_targets
    from .view import clip_xy

    target = track_targets(episode)
    rgb = np.where((target >= 0)[:, None], target_rgb(np.maximum(target, 0)),
                   np.asarray(mix(FALSE_TRACK, 1.0)))
    step = np.asarray(episode.track_step, dtype=np.int64)
    order = np.argsort(step, kind="stable")          # recorded step-major already
    return SetView(
        alive=np.asarray(episode.alive, dtype=bool),
        truth=clip_xy(np.asarray(episode.truth)[..., :2], scenario),
        step=step[order], label=np.asarray(episode.track_label, dtype=np.int64)[order],
        xy=clip_xy(np.asarray(episode.track_mean)[order, :2], scenario),
        cov=np.asarray(episode.track_cov)[order, :2, :2],
        r=np.asarray(episode.track_existence, dtype=float)[order], target=target[order],
        rgb=rgb[order], looked=looked_labels(episode),
        empty_look=np.asarray(episode.detections) == 0, events=episode_events(episode))


def truth_segments(view: SetView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every live segment of the true paths: ``(K, 2, 2)`` point pairs, the step each ends at
    ``(K,)`` and its target ``(K,)``, ordered by that step (a segment joins two consecutive
    live steps of one target)."""
    both = view.alive[1:] & view.alive[:-1]                     # (S, M)
    t, j = np.nonzero(both)
    seg = np.stack([view.truth[t, j], view.truth[t + 1, j]], axis=1)
    return seg, t + 1, j


def track_segments(view: SetView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every segment of the reported tracks: ``(K, 2, 2)`` point pairs joining a label's
    reports at consecutive steps, the row each ends at ``(K,)`` (its colour and r are that
    row's) and its step ``(K,)``, ordered by step."""
    order = np.lexsort((view.step, view.label))                  # by label, then step
    s, lab = view.step[order], view.label[order]
    join = (lab[1:] == lab[:-1]) & (s[1:] == s[:-1] + 1)
    a, b = order[:-1][join], order[1:][join]
    seg = np.stack([view.xy[a], view.xy[b]], axis=1).reshape(-1, 2, 2)
    by_step = np.argsort(view.step[b], kind="stable")
    return seg[by_step], b[by_step], view.step[b][by_step]


# ------------------------------------------------------------------------- static figure


def draw_set_targets(ax: Axes, view: SetView) -> None:
    """True paths over the life spans (light to dark with time), start, end, birth and
    death markers, names."""
    from matplotlib.collections import LineCollection

    seg, t, j = truth_segments(view)
    S = view.S
    if len(seg):
        rgb = target_rgb(j)
        w = (0.12 + 0.88 * (t - 1) / max(S - 1, 1))[:, None]
        ax.add_collection(LineCollection(list(seg), colors=w * rgb + (1 - w), linewidths=2.2,
                                         zorder=3, gid="true paths"))
    first = np.nonzero(view.alive[0])[0]
    if len(first):
        ax.scatter(view.truth[0, first, 0], view.truth[0, first, 1], s=6 ** 2,
                   c=[mix(target_color(int(k)), 0.5) for k in first], marker="o", linewidths=0,
                   zorder=4, gid="start")
    last = np.nonzero(view.alive[-1])[0]
    if len(last):
        ax.scatter(view.truth[-1, last, 0], view.truth[-1, last, 1], s=6 ** 2,
                   c=target_rgb(last), marker="s", linewidths=0, zorder=4, gid="end")
    draw_events(ax, view.events)
    for k in range(view.alive.shape[1]):
        live = np.nonzero(view.alive[:, k])[0]
        if len(live):
            ax.annotate(f"T{k}", tuple(view.truth[live[-1], k]), textcoords="offset points",
                        xytext=(6, 4), color=target_color(k), fontsize=8.5,
                        fontweight="bold", annotation_clip=True)


def draw_events(ax: Axes, events: Events) -> dict[str, Any]:
    """Births, deaths, confirmations and deletions as four scatters (gids ``births``,
    ``deaths``, ``confirmations``, ``deletions``), each with every event of the run."""
    out = {}
    for name, ev, marker, size in (("births", events.births, BIRTH_MARKER, 13),
                                   ("deaths", events.deaths, DEATH_MARKER, 10),
                                   ("confirmations", events.confirmations, CONFIRM_MARKER, 9),
                                   ("deletions", events.deletions, DELETE_MARKER, 9)):
        face = (target_rgb(ev.ident) if name in ("births", "deaths")
                else np.full((len(ev), 3), 1.0))
        out[name] = ax.scatter(ev.xy[:, 0], ev.xy[:, 1], s=size ** 2, c=face.reshape(-1, 3),
                               marker=marker, edgecolors="k", linewidths=0.9, zorder=6,
                               gid=name)
    return out


def draw_set_tracks(ax: Axes, view: SetView, times: np.ndarray, limit: float) -> None:
    """Reported tracks: their paths (width from r, colour from the assigned target; false
    tracks dashed), ellipses at ``times``, their labels at their last report."""
    from matplotlib.collections import EllipseCollection, LineCollection

    from .swarm import ellipse_arrays

    seg, row, _ = track_segments(view)
    if len(seg):
        false = view.target[row] < 0
        for mask, style in ((~false, "-"), (false, "--")):
            if mask.any():
                ax.add_collection(LineCollection(
                    list(seg[mask]), colors=view.rgb[row[mask]],
                    linewidths=track_width(view.r[row[mask]]), linestyles=style, zorder=3.5,
                    gid="false tracks" if style == "--" else "tracks"))
    at = np.flatnonzero(np.isin(view.step, times))
    if len(at):
        w, h, angle, ok = ellipse_arrays(view.cov[at], limit)
        ok &= np.all(np.isfinite(view.xy[at]), axis=1)
        ax.add_collection(EllipseCollection(
            w[ok], h[ok], angle[ok], units="xy", offsets=view.xy[at][ok],
            offset_transform=ax.transData, facecolors="none", edgecolors=view.rgb[at][ok],
            linewidths=0.9, alpha=0.7, zorder=3.4, gid="track ellipses"))
    # A lone report (no segment) still shows where the track was.
    ax.scatter(view.xy[:, 0], view.xy[:, 1], s=track_width(view.r) ** 2, c=view.rgb,
               marker="o", linewidths=0, zorder=3.6, gid="track reports")
    order = np.lexsort((view.step, view.label))
    lab = view.label[order]
    last = order[np.append(lab[1:] != lab[:-1], True)] if len(lab) else order
    for k in last:
        ax.annotate(f"L{int(view.label[k])}", tuple(view.xy[k]), textcoords="offset points",
                    xytext=(5, -11), color=view.rgb[k], fontsize=7.5, annotation_clip=True)


def draw_set_looks(ax: Axes, spos: np.ndarray, view: SetView, times: np.ndarray) -> None:
    """At ``times``, a line from each sensor to the track it looked at (dashed when the look
    returned no detection)."""
    for t in (int(t) for t in times if t >= 1):
        xy, rgb = view.look_points(t)
        for i in np.flatnonzero(np.isfinite(xy[:, 0])):
            ax.plot([spos[t, i, 0], xy[i, 0]], [spos[t, i, 1], xy[i, 1]], color=rgb[i],
                    linewidth=0.9, zorder=2.5, alpha=0.85,
                    linestyle="--" if view.empty_look[t, i] else "-")


def set_handles(view: SetView, times: np.ndarray, dt: float) -> list[Any]:
    """Legend entries of a set figure's marks, after the targets and sensors."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    when = ", ".join(f"{t * dt:g}" for t in times)

    def mark(marker: str, label: str, face: Any = "0.55", size: float = 9) -> Line2D:
        return Line2D([], [], color="k", marker=marker, markerfacecolor=face,
                      markeredgecolor="k", linestyle="none", markersize=size, label=label)

    ev = view.events
    return [
        Line2D([], [], color="0.25", linewidth=2.2,
               label="true path over its life (\u25cf start, \u25a0 end of run)"),
        mark(BIRTH_MARKER, f"target born ({len(ev.births)})", size=12),
        mark(DEATH_MARKER, f"target died ({len(ev.deaths)})"),
        *[Line2D([], [], color="0.25", linewidth=float(track_width(r)),
                 label=f"reported track, existence r = {r:g}") for r in (0.5, 1.0)],
        Line2D([], [], color=FALSE_TRACK, linewidth=float(track_width(0.75)), linestyle="--",
               label="false track (assigned to no target)"),
        Line2D([], [], color="0.25", linewidth=0,
               label="track colour: the target GOSPA assigns it to"),
        mark(CONFIRM_MARKER, f"track confirmed ({len(ev.confirmations)})", face="white"),
        mark(DELETE_MARKER, f"track deleted ({len(ev.deletions)})", face="white"),
        Line2D([], [], color="0.25", marker="o", markerfacecolor="none", linestyle="none",
               markersize=10, label=f"{N_SIGMA:g}\u03c3 ellipse of a track (t = {when} s)"),
        Line2D([], [], color="0.25", linewidth=1.0,
               label="sensor \u2192 looked-at track (dashed: no detection)"),
        Patch(facecolor="0.5", alpha=0.2, edgecolor="0.3", linestyle="--",
              label=f"field of view at step {view.S}"),
    ]


def set_legend(ax: Axes, episode: Episode, scenario: Scenario, extra: list[Any],
               summary: bool = False) -> None:
    """Legend right of the map: the target slots (colour, kind; one summary entry above
    :data:`~sensorplan.figures.view.LEGEND_ITEMS` or with ``summary``: the animation names
    its targets on the map and needs the room for its event log), the sensors, then
    ``extra``."""
    from matplotlib.patches import Patch

    from ..study.lifespan import slot_kinds
    from .view import LEGEND_ITEMS, map_legend_beside

    M = np.asarray(episode.alive).shape[1]
    kinds = slot_kinds(tuple(episode.target_kinds), M)
    if M > LEGEND_ITEMS or summary:
        handles: list[Any] = [Patch(facecolor="0.6", label=f"{M} targets, one colour each")]
    else:
        handles = [Patch(facecolor=target_color(j), label=f"T{j} ({kinds[j]})")
                   for j in range(M)]
    map_legend_beside(ax, handles, scenario, extra, fontsize=8, sensors=LEGEND_ITEMS)


def set_title(episode: Episode, gospa: Any) -> str:
    """Planner, horizon, steps, mean GOSPA and the counts of events."""
    s = episode.settings
    d = np.asarray(gospa.distance)
    return (f"{s.planner}, K = {s.horizon}, e = {s.steps_per_epoch}, {s.execution.upper()}, "
            f"tracker {s.tracker.kind}, {d.size} steps \u2014 mean GOSPA "
            f"{float(d.mean()) if d.size else float('nan'):.1f} m (c = {s.gospa_c:g} m)")


def draw_set_timeline(ax: Axes, view: SetView, dt: float, decisions: Any) -> None:
    """One row per sensor, a cell per step in the colour of the looked-at track (its
    target's, black for a false track, grey when it is not reported); light with a black dot
    when the look returned no detection; decisions as ticks on top."""
    S, N = view.looked.shape[0] - 1, view.looked.shape[1]
    cells = np.ones((N, max(S, 1), 3))
    for t in range(1, S + 1):
        _, rgb = view.look_points(t)
        on = view.looked[t] >= 0
        cells[on, t - 1] = rgb[on]
    empty = view.empty_look[1:].T & (view.looked[1:].T >= 0)
    cells[empty] = 0.45 * cells[empty] + 0.55
    ax.set_autoscale_on(False)
    if S >= 1:
        ax.imshow(cells, extent=(0, S * dt, N - 0.5, -0.5), origin="upper", aspect="auto",
                  interpolation="nearest", zorder=1)
        row, col = np.nonzero(empty)
        ax.scatter((col + 0.5) * dt, row, s=4, c="k", linewidths=0, zorder=2, gid="empty looks")
    steps = np.asarray(decisions, dtype=float)
    ax.plot(steps * dt, np.full(steps.shape, -0.62), "|", color="0.35", markersize=5,
            clip_on=False, markeredgewidth=0.8)
    _timeline_rows(ax, N, S, dt)
    ax.set_title("Looks: colour = the target of the looked-at track (black: a false track, "
                 "grey: not reported), light with a dot = no detection, ticks on top = "
                 "decisions",
                 fontsize=9, loc="left", pad=8)


def _timeline_rows(ax: Axes, N: int, S: int, dt: float) -> None:
    """Row names and sensor markers of the timeline (as in the figure of known targets)."""
    from .colors import sensor_style
    from .view import DENSE_SENSORS

    many = N > DENSE_SENSORS
    if many:
        from .swarm import label_rows

        label_rows(ax, N)
    else:
        ax.set_yticks(range(N), [f"S{i}" for i in range(N)])
    ax.set_ylim(N - 0.5, -0.5)
    ax.set_xlim(0, max(S, 1) * dt)
    ax.tick_params(axis="y", length=0, pad=4 if many else 16)
    for i in range(0 if many else N):
        color, marker = sensor_style(i)
        ax.plot(-0.011, i, marker, color=color, transform=ax.get_yaxis_transform(),
                clip_on=False, markersize=6)


def draw_gospa_parts(ax: Axes, gospa: Any, n_targets: Any, n_tracks: Any, dt: float,
                     c: float) -> None:
    """GOSPA^2 per step (cut-off ``c``, m) stacked into its localisation, missed and false
    parts (m^2), with the live targets and reported tracks counted on the right axis."""

    S = len(gospa.distance)
    time_s = np.arange(1, S + 1) * dt
    ax.stackplot(time_s, gospa.localisation, gospa.missed, gospa.false,
                 colors=list(PART_COLORS.values()), labels=list(PART_COLORS), step="mid",
                 linewidth=0)
    ax.set_xlim(0, S * dt)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("GOSPA\u00b2 (m\u00b2)")
    ax.grid(True, linewidth=0.4, alpha=0.5)
    counts = ax.twinx()
    counts.step(time_s, n_targets, where="mid", color="0.15", linewidth=1.3,
                label="live targets")
    counts.step(time_s, n_tracks, where="mid", color="k", linewidth=1.0, linestyle="--",
                label="reported tracks")
    # Ticks inside: the frames of an animation have no margin for a right-hand axis.
    counts.tick_params(axis="y", direction="in", pad=-14, labelsize=7)
    counts.set_ylim(0, max(int(np.max(n_targets, initial=0)),
                           int(np.max(n_tracks, initial=0))) + 1)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = counts.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7.5, loc="upper left", ncol=5, frameon=False)
    ax.set_title(f"GOSPA\u00b2 per step and its parts (c = {c:g} m), live targets "
                 "and reported tracks", fontsize=9, loc="left")


# ------------------------------------------------------------------------------ animation

#: Steps an event's marker stays on the animation's map after the event.
EVENT_STEPS = 3
#: Lines of the animation's event log (the latest events).
LOG_LINES = 8      # at most; fewer when the legend leaves less room


class SetLayer:
    """The moving artists of an animation of a run of sets: true paths so far over the life
    spans and the live targets now, the reported tracks so far (width from r) with their
    ellipses and labels now, the events of the last :data:`EVENT_STEPS` steps, each sensor's
    look line to its track (a cross where it returned no detection) and the event log.

    Everything is a handful of collections whose data change per frame: a frame costs about
    what a frame of known targets costs.
    """

    def __init__(self, ax: Axes, log_ax: Axes, view: SetView, spos: np.ndarray,
                 limit: float, tau: float) -> None:
        from matplotlib.collections import EllipseCollection, LineCollection

        self.view, self.spos, self.limit, self.tau = view, spos, limit, tau
        self.log_ax = log_ax
        self.seg, self.seg_t, seg_j = truth_segments(view)
        self.seg_rgb = target_rgb(seg_j)
        self.tseg, trow, self.tseg_t = track_segments(view)
        self.tseg_rgb, self.tseg_w = view.rgb[trow], track_width(view.r[trow])
        self.tseg_false = view.target[trow] < 0
        self.paths: Any = ax.add_collection(LineCollection([], linewidths=2.0, zorder=3),
                                            autolim=False)
        self.tracks: Any = ax.add_collection(LineCollection([], zorder=3.5), autolim=False)
        self.now = ax.scatter([], [], s=7 ** 2, marker="o", linewidths=0, zorder=5)
        self.track_now = ax.scatter([], [], marker="o", linewidths=0.8, edgecolors="k",
                                    zorder=5.5)
        self.ell: Any = ax.add_collection(EllipseCollection(
            [], [], [], units="xy", offsets=np.zeros((0, 2)), offset_transform=ax.transData,
            facecolors="none", linewidths=1.1, zorder=4), autolim=False)
        self.events = draw_events(ax, view.events)
        self.looks: Any = ax.add_collection(LineCollection([], linewidths=1.3, zorder=4),
                                            autolim=False)
        self.cross = ax.scatter([], [], s=9 ** 2, marker="x", c="k", linewidths=2.0, zorder=7)
        most = int(np.bincount(view.step).max(initial=0)) if len(view.step) else 0
        self.names = [ax.text(0, 0, "", fontsize=8, zorder=6, clip_on=True)
                      for _ in range(most)]
        self.target_names = [ax.text(0, 0, f"T{k}", color=target_color(k), fontsize=8.5,
                                     fontweight="bold", zorder=6, clip_on=True)
                             for k in range(view.alive.shape[1])]
        self.log = log_ax.text(0.0, 0.0, "", transform=log_ax.transAxes, fontsize=7.5,
                               va="top", ha="left", family="monospace")
        self.log_room = LOG_LINES
        self.log_lines = [f"{t:>4d}  {view.events.text(t)}" for t in range(1, view.S + 1)
                          if view.events.text(t)]
        self.log_steps = [t for t in range(1, view.S + 1) if view.events.text(t)]
        self.artists: list[Any] = [self.paths, self.tracks, self.ell, self.now,
                                   self.track_now, self.looks, self.cross,
                                   *self.events.values(), *self.names, *self.target_names,
                                   self.log]

    def place_log(self, legend: Any, floor: float | None = None) -> None:
        """Put the event log just below ``legend`` (in the same axes' column), above
        ``floor`` (display units; default the column's bottom)."""
        box = legend.get_window_extent(self.log_ax.figure.canvas.get_renderer())  # type: ignore[attr-defined]
        y = self.log_ax.transAxes.inverted().transform((0.0, box.y0))[1]
        self.log.set_position((0.0, y - 0.03))
        # Lines that fit between the legend and the bottom of the column (the heading too).
        bottom = self.log_ax.get_window_extent().y0 if floor is None else floor
        line = 1.25 * float(self.log.get_fontsize()) * float(self.log_ax.figure.dpi) / 72.0
        self.log_room = int(max(0, min(LOG_LINES, (box.y0 - bottom) / line - 2)))

    def update(self, t: int) -> None:
        """Move every artist to step ``t``."""
        v = self.view
        k = int(np.searchsorted(self.seg_t, t, side="right"))
        self.paths.set_segments(list(self.seg[:k]))
        self.paths.set_color(_faded(self.seg_rgb[:k], t - self.seg_t[:k], self.tau))
        k = int(np.searchsorted(self.tseg_t, t, side="right"))
        self.tracks.set_segments(list(self.tseg[:k]))
        self.tracks.set_color(_faded(self.tseg_rgb[:k], t - self.tseg_t[:k], self.tau))
        self.tracks.set_linewidths(self.tseg_w[:k])
        self.tracks.set_linestyles([(0, (4, 2)) if f else (0, None)
                                    for f in self.tseg_false[:k]] or "-")
        live = np.flatnonzero(v.alive[t])
        self.now.set_offsets(v.truth[t, live].reshape(-1, 2))
        self.now.set_color(target_rgb(live).reshape(-1, 3))  # type: ignore[arg-type]
        for j, name in enumerate(self.target_names):
            name.set_visible(bool(v.alive[t, j]))
            if v.alive[t, j]:
                name.set_position((v.truth[t, j, 0] + 8, v.truth[t, j, 1] + 8))
        rows = v.rows_at(t)
        xy, rgb = v.xy[rows], v.rgb[rows]
        self.track_now.set_offsets(xy.reshape(-1, 2))
        self.track_now.set_facecolor(rgb.reshape(-1, 3))  # type: ignore[arg-type]
        self.track_now.set_sizes(track_width(v.r[rows]) ** 2 * 6)
        from .swarm import ellipse_arrays

        w, h, angle, ok = ellipse_arrays(v.cov[rows], self.limit)
        ok &= np.all(np.isfinite(xy), axis=1)
        self.ell.set_widths(np.where(ok, w, 0.0))
        self.ell.set_heights(np.where(ok, h, 0.0))
        self.ell.set_angles(np.where(ok, angle, 0.0))
        self.ell.set_offsets(np.where(ok[:, None], xy, 0.0).reshape(-1, 2))
        self.ell.set_edgecolor(rgb.reshape(-1, 3))
        for n, name in enumerate(self.names):
            if n < len(xy):
                name.set_text(f"L{int(v.label[rows][n])}  r = {v.r[rows][n]:.2f}")
                name.set_position((xy[n, 0] + 8, xy[n, 1] - 16))
                name.set_color(rgb[n])
                name.set_visible(True)
            else:
                name.set_visible(False)
        for kind, ev in (("births", v.events.births), ("deaths", v.events.deaths),
                         ("confirmations", v.events.confirmations),
                         ("deletions", v.events.deletions)):
            recent = (ev.step <= t) & (ev.step > t - EVENT_STEPS)
            coll = self.events[kind]
            coll.set_offsets(ev.xy[recent].reshape(-1, 2))
            face = (target_rgb(ev.ident[recent]) if kind in ("births", "deaths")
                    else np.ones((int(recent.sum()), 3)))
            coll.set_facecolor(face.reshape(-1, 3))
        look, look_rgb = v.look_points(t)
        on = np.flatnonzero(np.isfinite(look[:, 0]))
        self.looks.set_segments([np.array([self.spos[t, i], look[i]]) for i in on])
        self.looks.set_color(look_rgb[on].reshape(-1, 3))
        self.looks.set_linestyles(["--" if v.empty_look[t, i] else "-" for i in on] or "-")
        empty = on[v.empty_look[t, on]]
        self.cross.set_offsets(look[empty].reshape(-1, 2))
        shown = int(np.searchsorted(self.log_steps, t, side="right"))
        latest = self.log_lines[max(shown - self.log_room, 0):shown][::-1]
        self.log.set_text("step  events (latest first)\n" + "\n".join(latest)
                          if self.log_room else "")


def _faded(rgb: np.ndarray, age: np.ndarray, tau: float) -> np.ndarray:
    """``rgb (K, 3)`` tinted toward white with ``age (K,)`` steps (as
    :func:`~sensorplan.figures.view.fade_colors`, per segment)."""
    from .view import FADE_FLOOR

    w = FADE_FLOOR + (1.0 - FADE_FLOOR) * np.exp(-np.asarray(age, float) / tau)
    return (w[:, None] * rgb + (1.0 - w[:, None])).reshape(-1, 3)
