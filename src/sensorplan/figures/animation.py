"""Animation of a run, one frame per step (matplotlib, Agg; GIF by Pillow, MP4 by ffmpeg).

Each frame shows the map at time t: the true tracks and estimates so far in each target's
colour, fading with age; the estimates' 2-sigma ellipses; every sensor's field of view, its
recent path and a line to the target it looks at (dashed, with a cross at the target, when
the look missed); false alarms as a count beside the sensor; buildings. Below, the run's
assignment timeline and errors (as in :func:`sensorplan.figures.run.plot_episode`) with the
future greyed out. Colours are those of :mod:`sensorplan.figures.colors`. Many sensors or targets
move as a few collections (:mod:`sensorplan.figures.animation_swarm`). A run of changing sets
(a multi-target tracker, targets born or dying) shows each target over its life span, the
reported tracks (line width from their existence r, false tracks dashed, label and r beside
each), births, deaths, confirmations and deletions as markers for a few steps, a line of
the step's events under the title and the latest events in a log beside the map
(:class:`sensorplan.figures.sets.SetLayer`).
"""

from __future__ import annotations

import itertools
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import mix_hex, sensor_style, target_color
from .search import has_search, search_handles
from .view import move_fov
from .run import (DENSE_SENSORS, DENSE_TARGETS, N_SIGMA, clip_xy, draw_buildings,
                  draw_errors, draw_timeline, ellipse_geometry, episode_title, fade_colors,
                  fov_geometry, map_legend, map_limit, segments, timeline_height)

if TYPE_CHECKING:  # pragma: no cover
    from ..simulation.run import Episode
    from ..simulation.scenario import Scenario

#: Animation formats, by file suffix: GIF (Pillow, always available) and MP4 (needs ffmpeg).
FORMATS = ("gif", "mp4")
#: Default frame rate (frames per second; one frame per step).
FPS = 6
#: Default fading time constant of path history (steps): a point ``tail`` steps old is
#: drawn at about a third of its colour's strength.
TAIL = 12.0


def ffmpeg_available() -> bool:
    """Whether ffmpeg is on the PATH (needed for MP4)."""
    return shutil.which("ffmpeg") is not None


def check_format(fmt: str) -> None:
    """Refuse an unknown animation format, or mp4 without ffmpeg, before any work.

    Raises
    ------
    ConfigError
        Naming ``--animation-format``.
    """
    from ..errors import ConfigError

    if fmt not in FORMATS:
        raise ConfigError("--animation-format", f"must be one of {', '.join(FORMATS)}, "
                          f"got {fmt!r}")
    if fmt == "mp4" and not ffmpeg_available():
        raise ConfigError("--animation-format", "mp4 needs ffmpeg on the PATH, which was "
                          "not found; use gif")


def frame_steps(S: int, every: int = 1) -> list[int]:
    """The steps shown as frames: ``0, every, 2 every, ...`` and always the last, ``S``."""
    steps = list(range(0, S + 1, max(int(every), 1)))
    if steps[-1] != S:
        steps.append(S)
    return steps


def animate_episode(episode: Episode, scenario: Scenario, path: str | Path, *,
                    fps: float = FPS, every: int = 1, tail: float = TAIL,
                    dpi: float = 72) -> Path:
    """Write an animation of a run: one frame per step (see the module docstring).

    Parameters
    ----------
    episode : Episode
    scenario : Scenario
        The map, buildings and sensor parameters the run used.
    path : path
        Output file; ``.gif`` (Pillow) or ``.mp4`` (ffmpeg, which must be installed).
    fps : float
        Frames per second.
    every : int
        Show every ``every``-th step (and the last): fewer frames for long runs.
    tail : float
        Fading time constant of the path history (steps).
    dpi : float
        Pixels per inch of the frames (the figure is 11 inches wide).

    Returns
    -------
    Path of the written file.

    Raises
    ------
    ValueError
        Unknown suffix, or ``.mp4`` without ffmpeg.
    """
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise ValueError(f"animation format must be one of {FORMATS}, got {path.suffix!r}")
    if fmt == "mp4" and not ffmpeg_available():
        raise ValueError("an MP4 animation needs ffmpeg on the PATH; write a .gif instead")
    frames = _Frames(episode, scenario, tail, dpi)
    images = (frames.render(t) for t in frame_steps(frames.S, every))
    if fmt == "gif":
        _write_gif(path, images, fps)
    else:
        _write_mp4(path, images, fps)
    return path


def _write_gif(path: Path, images: Iterator[np.ndarray], fps: float) -> None:
    """Frames ``(h, w, 4) uint8`` to an endlessly looping GIF (Pillow, as matplotlib's
    PillowWriter does)."""
    from PIL import Image

    rgb = [Image.fromarray(np.ascontiguousarray(im[..., :3])) for im in images]
    # One palette for every frame: ten times faster than a palette per frame, half the file
    # size, and no colour flicker. Its colours come from five frames, plus a ramp of 40
    # greys so that the sensors' greys and the light fields of view never snap to a tint.
    picks = [rgb[k] for k in sorted({round(x) for x in np.linspace(0, len(rgb) - 1, 5)})]
    montage = Image.new("RGB", (picks[0].width, picks[0].height * len(picks)))
    for k, im in enumerate(picks):
        montage.paste(im, (0, k * im.height))
    colours = montage.quantize(colors=216, method=Image.Quantize.FASTOCTREE)
    greys = [int(g) for g in np.linspace(0, 255, 40).round() for _ in range(3)]
    palette = Image.new("P", (1, 1))
    palette.putpalette((colours.getpalette() or [])[:3 * 216] + greys)
    frames = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in rgb]
    frames[0].save(path, save_all=True, append_images=frames[1:],
                   duration=int(round(1000 / fps)), loop=0)


def _write_mp4(path: Path, images: Iterator[np.ndarray], fps: float) -> None:
    """Frames ``(h, w, 4) uint8`` piped to ffmpeg as raw RGBA; H.264 in yuv420p (even
    dimensions: padded by one pixel where needed) so that every player opens it."""
    first = next(images)
    h, w = first.shape[:2]
    cmd = ["ffmpeg", "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgba",
           "-s", f"{w}x{h}", "-r", f"{fps:g}", "-i", "-",
           "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2:color=white", "-vcodec", "libx264",
           "-pix_fmt", "yuv420p", str(path)]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdin is not None
    try:
        for im in itertools.chain([first], images):
            proc.stdin.write(np.ascontiguousarray(im).tobytes())
    except BrokenPipeError:
        pass                                    # ffmpeg failed: its message follows
    finally:
        proc.stdin.close()
        err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
        code = proc.wait()
    if code != 0:
        raise OSError(f"ffmpeg failed (exit {code}): {err.strip()[-500:]}")


class _Frames:
    """The figure of an animation and its moving artists, updated in place per frame."""

    def __init__(self, episode: Episode, scenario: Scenario, tail: float,
                 dpi: float) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import LineCollection
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D
        from matplotlib.patches import Ellipse, Patch, Rectangle, Wedge

        self.ep, self.sc, self.tail = episode, scenario, tail
        self.truth = clip_xy(np.asarray(episode.truth)[..., :2], scenario)
        self.est = clip_xy(np.asarray(episode.estimate)[..., :2], scenario)
        self.cov = np.asarray(episode.cov)[..., :2, :2]
        self.spos = clip_xy(episode.sensor_positions, scenario)
        self.shead = np.asarray(episode.sensor_headings)
        self.looked = np.asarray(episode.looked)
        self.missed = np.asarray(episode.missed)
        self.false = np.asarray(episode.false_alarms)
        from ..study.lifespan import is_set_run

        # A run of sets draws its targets, tracks and looks from its set records
        # (:class:`~sensorplan.figures.sets.SetLayer`), not per target.
        self.sets = None
        if is_set_run(episode):
            from .sets import set_view

            self.sets = set_view(episode, scenario)
            self.looked = np.full_like(self.looked, -1)
        self.S, self.M = self.truth.shape[0] - 1, self.truth.shape[1]
        self.N = self.spos.shape[1]
        self.dt = scenario.dt
        self.limit = map_limit(scenario)
        W, H = scenario.world.width, scenario.world.height

        timeline_h = timeline_height(self.N, 0.3) + 0.7
        fig = Figure(figsize=(11.0, 6.4 + timeline_h + 2.0), dpi=dpi)
        self.canvas = FigureCanvasAgg(fig)
        grid = fig.add_gridspec(3, 2, width_ratios=[2.2, 1.0],
                                height_ratios=[6.4, timeline_h, 2.0], hspace=0.32,
                                wspace=0.02, left=0.07, right=0.98, top=0.95, bottom=0.06)
        ax = fig.add_subplot(grid[0, 0])
        legend_ax = fig.add_subplot(grid[0, 1])
        legend_ax.set_axis_off()
        ax_time = fig.add_subplot(grid[1, :])
        ax_err = fig.add_subplot(grid[2, :], sharex=ax_time)
        ax_time.tick_params(labelbottom=False)
        self.fig, self.ax = fig, ax

        border = Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.2)
        ax.add_patch(border)
        draw_buildings(ax, scenario.buildings)
        pad = 0.03 * max(W, H)
        ax.set_xlim(-pad, W + pad)
        ax.set_ylim(-pad, H + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.grid(True, linewidth=0.4, alpha=0.4)

        self.fov: list[Any] = []
        self.spath: list[Any] = []
        self.smark: list[Any] = []
        self.look: list[Any] = []
        self.cross: list[Any] = []
        self.fa_text: list[Any] = []
        # Many sensors or targets: a few collections instead (no names, no counts).
        self.dense: list[Any] = []
        if self.N > DENSE_SENSORS:
            from .animation_swarm import DenseSensors

            self.dense.append(DenseSensors(ax, scenario, self.spos, self.shead, self.looked,
                                           self.missed, self.truth, tail, border))
        for i in range(0 if self.dense else self.N):
            color, marker = sensor_style(i)
            params = scenario.sensors[i].params
            wedge = Wedge(**fov_geometry(self.spos[0, i], self.shead[0, i], params),
                          facecolor=color, alpha=0.10, edgecolor=color, linewidth=1.0,
                          linestyle="--", zorder=1.8)
            ax.add_patch(wedge)
            wedge.set_clip_path(border)
            self.fov.append((wedge, params))
            self.spath.append(ax.add_collection(LineCollection([], linewidths=0.9,
                                                               zorder=2)))
            self.smark.append(ax.plot([], [], marker, color=color, markersize=10,
                                      zorder=6)[0])
            self.look.append(ax.plot([], [], linewidth=1.3, zorder=4)[0])
            self.cross.append(ax.plot([], [], "x", color="k", markersize=9,
                                      markeredgewidth=2.0, zorder=7)[0])
            self.fa_text.append(ax.text(0, 0, "", fontsize=8, color="k", zorder=7,
                                        clip_on=True))
        self.track: list[Any] = []
        self.track_est: list[Any] = []
        self.now: list[Any] = []
        self.now_est: list[Any] = []
        self.ell: list[Any] = []
        many = self.M > DENSE_TARGETS
        if self.sets is not None:
            from .sets import SetLayer

            self.dense.append(SetLayer(ax, legend_ax, self.sets, self.spos, self.limit,
                                       tail))
            many = True                         # no per-target artists
        elif many:
            from .animation_swarm import DenseTargets

            self.dense.append(DenseTargets(ax, self.truth, self.est, self.cov, self.limit,
                                           tail))
        for j in range(0 if many else self.M):
            c = target_color(j)
            self.track.append(ax.add_collection(LineCollection([], linewidths=2.2,
                                                               zorder=3)))
            self.track_est.append(ax.add_collection(LineCollection(
                [], linewidths=1.2, linestyles=":", zorder=3)))
            self.now.append(ax.plot([], [], "o", color=c, markersize=7, zorder=5)[0])
            self.now_est.append(ax.plot([], [], "+", color=c, markersize=9,
                                        markeredgewidth=1.6, zorder=5)[0])
            ell = Ellipse((0, 0), 0, 0, fill=False, edgecolor=c, linewidth=1.2, zorder=4)
            ax.add_patch(ell)
            self.ell.append(ell)
        self.labels = [ax.text(0, 0, f"T{j}", color=target_color(j), fontsize=9,
                               fontweight="bold", zorder=6, clip_on=True)
                       for j in range(0 if many else self.M)]

        # Search: the undetected intensity under the scene, sector looks and finds.
        self.search = None
        if has_search(episode):
            from .search import SearchLayer, search_view

            self.search = SearchLayer(ax, search_view(episode, scenario), scenario, self.spos,
                                      self.shead, self.N > DENSE_SENSORS, border)
            self.dense.append(self.search)
        search_entries = search_handles(self.search.view) if self.search is not None else []
        extra = [
            Line2D([], [], color="0.25", linewidth=2.2, marker="o",
                   label="true track (older: lighter)"),
            Line2D([], [], color="0.25", linestyle=":", marker="+", markersize=9,
                   label="estimate"),
            *_look_entries(f"{N_SIGMA:g}\u03c3 position ellipse",
                           "sensor \u2192 target it looks at", "look missed (no detection)"),
            Patch(facecolor="0.5", alpha=0.2, edgecolor="0.3", linestyle="--",
                  label="field of view"),
        ]
        if self.sets is not None:
            from .sets import set_handles, set_legend

            tail_entries = [
                *_look_entries(f"{N_SIGMA:g}\u03c3 ellipse of a reported track",
                               "sensor \u2192 track it looks at",
                               "the look returned no detection"),
                extra[-1], *search_entries]
            set_legend(ax, episode, scenario,
                       set_handles(self.sets, np.array([], int), self.dt)[1:-3] + tail_entries,
                       summary=True)
        else:
            map_legend(ax, episode, scenario, extra + search_entries)
        # The legend lives in the right-hand column (frames have a fixed size: no "tight").
        leg: Any = ax.get_legend()
        leg.set_bbox_to_anchor((0.0, 1.0), transform=legend_ax.transAxes)
        floor = None
        if self.search is not None and self.search.heat is not None:
            # The heat map's colour bar at the foot of the legend's column.
            from .search import colour_bar

            cax = legend_ax.inset_axes((0.02, 0.05, 0.85, 0.025))
            colour_bar(fig, self.search.heat, cax)
            floor = legend_ax.transAxes.transform((0.0, 0.16))[1]
        for group in self.dense:
            if hasattr(group, "place_log"):
                group.place_log(leg, floor)

        if self.sets is not None:
            from ..study.set_metrics import episode_set_metrics
            from .sets import draw_gospa_parts, draw_set_timeline, set_title

            sm = episode_set_metrics(episode)
            draw_set_timeline(ax_time, self.sets, self.dt, episode.decision_steps)
            draw_gospa_parts(ax_err, sm.gospa, sm.n_targets, sm.n_tracks, self.dt,
                             episode.settings.gospa_c)
        else:
            draw_timeline(ax_time, episode, self.dt)
            draw_errors(ax_err, episode, self.dt)
        if self.search is not None:
            from .search import draw_search_timeline

            draw_search_timeline(ax_time, self.search.view.sectors, self.dt)
        self.future = []
        for a in (ax_time, ax_err):
            veil = Rectangle((0, 0), 0, 1, transform=a.get_xaxis_transform(),
                             facecolor="white", alpha=0.78, edgecolor="none", zorder=10)
            a.add_patch(veil)
            cursor = a.axvline(0, color="k", linewidth=1.0, zorder=11)
            self.future.append((veil, cursor))
        self.title = fig.suptitle("", fontsize=11)
        self.run_title = (set_title(episode, sm.gospa) if self.sets is not None
                          else episode_title(episode))

        # Blitting: everything that does not move is drawn once into a background; a frame
        # restores it and draws only the moving artists (ten times faster than a full draw).
        self.moving: list[Any] = sorted(
            [w for w, _ in self.fov] + self.spath + self.look + self.track + self.track_est
            + self.ell + self.now + self.now_est + self.smark + self.cross + self.labels
            + self.fa_text + [a for pair in self.future for a in pair]
            + [a for group in self.dense for a in group.artists],
            key=lambda a: a.get_zorder())
        if self.search is not None and self.search.heat is not None:
            # The heat map moves, so it is drawn after the background: the map's static
            # artists (border, buildings and their labels) are drawn after it too, in their
            # z-order, to stay on top of it.
            moving = {id(a) for a in self.moving}
            static = [a for a in [*ax.patches, *ax.collections, *ax.texts]
                      if id(a) not in moving]
            self.moving = sorted(self.moving + static, key=lambda a: a.get_zorder())
        for a in self.moving + [self.title]:
            a.set_animated(True)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(fig.bbox)

    def render(self, t: int) -> np.ndarray:
        """The frame of step ``t`` as an ``(h, w, 4) uint8`` RGBA array."""
        self.draw(t)
        canvas = self.canvas
        canvas.restore_region(self.background)
        for a in self.moving:
            a.axes.draw_artist(a)
        self.fig.draw_artist(self.title)
        return np.asarray(canvas.buffer_rgba()).copy()

    def draw(self, t: int) -> None:
        """Update every moving artist to step ``t``."""
        ages = (t - 1 - np.arange(t)).astype(float)     # segment s ends at point s + 1
        for group in self.dense:
            group.update(t)
        for j in range(len(self.track)):
            c = target_color(j)
            self.track[j].set_segments(segments(self.truth[:t + 1, j]) if t else [])
            self.track[j].set_color(fade_colors(c, ages, self.tail) if t else c)
            self.track_est[j].set_segments(segments(self.est[:t + 1, j]) if t else [])
            self.track_est[j].set_color(fade_colors(c, ages, self.tail) if t else c)
            self.now[j].set_data([self.truth[t, j, 0]], [self.truth[t, j, 1]])
            self.now_est[j].set_data([self.est[t, j, 0]], [self.est[t, j, 1]])
            self.labels[j].set_position((self.truth[t, j, 0] + 8, self.truth[t, j, 1] + 8))
            shape = ellipse_geometry(self.cov[t, j], self.limit)
            ok = shape is not None and bool(np.all(np.isfinite(self.est[t, j])))
            self.ell[j].set_visible(ok)
            if shape is not None and ok:
                self.ell[j].set_center(tuple(self.est[t, j]))
                self.ell[j].set_width(shape[0])
                self.ell[j].set_height(shape[1])
                self.ell[j].set_angle(shape[2])
        for i in range(len(self.fov)):
            color, _ = sensor_style(i)
            wedge, params = self.fov[i]
            move_fov(wedge, self.spos[t, i], self.shead[t, i], params)
            self.spath[i].set_segments(segments(self.spos[:t + 1, i]) if t else [])
            self.spath[i].set_color(fade_colors(mix_hex(color, 0.8), ages, self.tail)
                                    if t else color)
            self.smark[i].set_data([self.spos[t, i, 0]], [self.spos[t, i, 1]])
            j = int(self.looked[t, i])
            if j >= 0:
                self.look[i].set_data([self.spos[t, i, 0], self.truth[t, j, 0]],
                                      [self.spos[t, i, 1], self.truth[t, j, 1]])
                self.look[i].set_color(target_color(j))
                self.look[i].set_linestyle("--" if self.missed[t, i] else "-")
            else:
                self.look[i].set_data([], [])
            if j >= 0 and self.missed[t, i]:
                self.cross[i].set_data([self.truth[t, j, 0]], [self.truth[t, j, 1]])
            else:
                self.cross[i].set_data([], [])
            n_false = int(self.false[t, i])
            self.fa_text[i].set_text(f" {n_false} false alarm{'s' if n_false > 1 else ''}"
                                     if n_false else "")
            self.fa_text[i].set_position((self.spos[t, i, 0] + 10, self.spos[t, i, 1] - 22))
        for veil, cursor in self.future:
            veil.set_x(t * self.dt)
            veil.set_width(max(self.S - t, 0) * self.dt + 1e-9)
            cursor.set_xdata([t * self.dt, t * self.dt])
        n_false = int(self.false[t].sum())
        events = self.sets.events.text(t) if self.sets is not None else ""
        self.title.set_text(f"t = {t * self.dt:g} s (step {t} of {self.S})   "
                            f"{self.run_title}" + (f"\n{n_false} false alarms in this step"
                                                   if n_false and not self.fov else "")
                            + (f"\nthis step: {events}" if self.sets is not None else "")
                            + (f"{'   ' if self.sets is not None else chr(10)}search: "
                               f"{self.search.title(t)}" if self.search is not None else ""))


__all__ = ["FORMATS", "animate_episode", "check_format", "ffmpeg_available", "frame_steps"]


def _look_entries(ellipse: str, look: str, missed: str) -> list[Any]:
    """Legend entries of an estimate's ellipse, a look's line and a look without a
    detection, with these labels."""
    from matplotlib.lines import Line2D

    return [Line2D([], [], color="0.25", marker="o", markerfacecolor="none",
                   linestyle="none", markersize=10, label=ellipse),
            Line2D([], [], color="0.25", linewidth=1.3, label=look),
            Line2D([], [], color="0.25", linewidth=1.3, linestyle="--", marker="x",
                   markeredgecolor="k", label=missed)]
