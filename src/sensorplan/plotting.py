"""Figures of saved runs (matplotlib only here, Agg canvas; the CLI imports this lazily).

Plots read what a run recorded (:class:`~sensorplan.simulation.Episode`) and the scenario
it ran; they compute nothing the run did not record except the drawing geometry.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.patches import Wedge

    from .scenario import Scenario
    from .simulation import Episode

#: Number of times at which the estimates' 2-sigma ellipses are drawn.
N_ELLIPSES = 5
#: Chi-square(2) 95 % quantile would be 2.45 sigma; the figure shows the usual 2 sigma.
N_SIGMA = 2.0


def _ellipse(ax: "Axes", mean: np.ndarray, C: np.ndarray, color: str, **kw: object) -> None:
    """Draw the ``N_SIGMA`` ellipse of a 2-D Gaussian with covariance ``C (2, 2)``."""
    from matplotlib.patches import Ellipse

    vals, vecs = np.linalg.eigh(0.5 * (C + C.T))
    vals = np.clip(vals, 0.0, None)
    angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    ax.add_patch(Ellipse(tuple(mean), 2 * N_SIGMA * math.sqrt(vals[1]),
                         2 * N_SIGMA * math.sqrt(vals[0]), angle=angle, fill=False,
                         edgecolor=color, **kw))


def field_of_view(ax: "Axes", xy: np.ndarray, heading: float, params: object,
                  color: str, alpha: float = 0.15) -> "Wedge":
    """Ground sensing region: the range-band annulus sector of the azimuth wedge."""
    from matplotlib.patches import Wedge

    g_min = float(params.min_ground_range)      # type: ignore[attr-defined]
    g_max = float(params.max_ground_range)      # type: ignore[attr-defined]
    half = math.degrees(float(params.fov_half_angle))  # type: ignore[attr-defined]
    centre = math.degrees(heading)
    wedge = Wedge(tuple(xy), g_max, centre - half, centre + half, width=g_max - g_min,
                  facecolor=color, alpha=alpha, edgecolor=color, linewidth=1.0, linestyle="--")
    ax.add_patch(wedge)
    return wedge


def frame_map(ax: "Axes", width: float, height: float, margin: float) -> None:
    """Equal-aspect map axes in metres, with ``margin`` (a fraction of the map) around it."""
    pad = margin * max(width, height)
    ax.set_xlim(-pad, width + pad)
    ax.set_ylim(-pad, height + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, linewidth=0.4, alpha=0.4)


def plot_episode(episode: "Episode", scenario: "Scenario", path: str | Path) -> Path:
    """Map of one run: true tracks, estimates, sensor paths and fields of view.

    Draws the map rectangle; each target's true track (solid) with its start (circle) and
    end (square); the estimated track (dotted) with ``2 sigma`` position ellipses at
    ``N_ELLIPSES`` evenly spaced times; each sensor's ground path with its final heading
    (arrow) and its field of view at the last step (the range-band annulus sector of its
    azimuth wedge, shaded).

    Parameters
    ----------
    episode : Episode
        ``truth, estimate (S+1, M, 4)``, ``cov (S+1, M, 4, 4)``,
        ``sensor_positions (S+1, N, 2)``, ``sensor_headings (S+1, N)``.
    scenario : Scenario
        The map and the sensors' parameters.
    path : path
        Output file; the format follows the suffix (``.png``).

    Returns
    -------
    Path of the written file.
    """
    # The Agg canvas of a bare Figure: no pyplot, so no global backend switch and no figure
    # registry (safe inside notebooks and worker processes).
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    truth = np.asarray(episode.truth)
    est = np.asarray(episode.estimate)
    cov = np.asarray(episode.cov)
    spos = np.asarray(episode.sensor_positions)
    shead = np.asarray(episode.sensor_headings)
    S = truth.shape[0] - 1
    M, N = truth.shape[1], spos.shape[1]
    W, H = scenario.world.width, scenario.world.height
    # Targets and sensors take different tab10 colours (when M + N <= 10) so that a path is
    # never mistaken for a track.
    palette = colormaps["tab10"]
    target_colors = [palette(j % 10) for j in range(M)]
    sensor_colors = [palette((M + i) % 10) for i in range(N)]
    times = np.unique(np.linspace(0, S, N_ELLIPSES).round().astype(int))

    fig = Figure(figsize=(9.5, 8.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    border = Rectangle((0, 0), W, H, fill=False, edgecolor="0.3", linewidth=1.2)
    ax.add_patch(border)

    sensor_handles: list[Line2D] = []
    for i in range(N):
        c = sensor_colors[i]
        params = scenario.sensors[i].params
        fov = field_of_view(ax, spos[-1, i], float(shead[-1, i]), params, c)
        fov.set_clip_path(border)           # the sensing region that matters is on the map
        ax.plot(spos[:, i, 0], spos[:, i, 1], "-", color=c, linewidth=1.2, alpha=0.75)
        ax.plot(*spos[0, i], "o", color=c, markersize=6, markerfacecolor="white")
        ax.plot(*spos[-1, i], "^", color=c, markersize=9)
        arrow = 0.06 * max(W, H)
        ax.annotate("", xy=(spos[-1, i, 0] + arrow * math.cos(shead[-1, i]),
                            spos[-1, i, 1] + arrow * math.sin(shead[-1, i])),
                    xytext=tuple(spos[-1, i]),
                    arrowprops=dict(arrowstyle="->", color=c, linewidth=1.5))
        ax.annotate(f"S{i}", tuple(spos[-1, i]), textcoords="offset points", xytext=(6, -12),
                    color=c, fontsize=9, fontweight="bold")
        sensor_handles.append(Line2D([], [], color=c, linewidth=1.2, marker="^",
                                     label=f"S{i} path, z = {float(params.altitude):g} m"))

    for j in range(M):
        c = target_colors[j]
        ax.plot(truth[:, j, 0], truth[:, j, 1], "-", color=c, linewidth=2.0)
        ax.plot(*truth[0, j, :2], "o", color=c, markersize=6)
        ax.plot(*truth[-1, j, :2], "s", color=c, markersize=6)
        ax.plot(est[:, j, 0], est[:, j, 1], ":", color=c, linewidth=1.4)
        for t in times:
            _ellipse(ax, est[t, j, :2], cov[t, j, :2, :2], c, linewidth=1.0, alpha=0.8)
        ax.annotate(f"T{j} ({episode.target_kinds[j]})", tuple(truth[-1, j, :2]),
                    textcoords="offset points", xytext=(6, 4), color=c, fontsize=9)

    handles = [
        Line2D([], [], color="0.2", linewidth=2.0, label="true track (\u25cf start, \u25a0 end)"),
        Line2D([], [], color="0.2", linestyle=":", linewidth=1.4, label="estimate"),
        Line2D([], [], color="0.2", marker="o", markerfacecolor="none", linestyle="none",
               markersize=10, label=f"{N_SIGMA:g}\u03c3 position ellipse (t = "
                                     f"{', '.join(str(int(t)) for t in times)})"),
        Line2D([], [], color="0.4", marker="^", linestyle="none", markersize=8,
               label=f"sensor: \u25cb start, \u25b2 at t = {S}, arrow = heading"),
        Patch(facecolor="0.5", alpha=0.2, edgecolor="0.4", linestyle="--",
              label=f"field of view at t = {S}"),
        *sensor_handles,
    ]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9,
              frameon=False)
    frame_map(ax, W, H, 0.03)
    s = episode.settings
    rmse = np.asarray(episode.rmse())
    ax.set_title(f"{s.planner}, K = {s.horizon}, e = {s.steps_per_epoch}, "
                 f"{s.execution.upper()}, {S} steps \u2014 RMSE per target: "
                 + ", ".join(f"{v:.0f}" for v in rmse) + " m", fontsize=10)
    path = Path(path)
    fig.savefig(path, bbox_inches="tight")      # keeps the legend outside the axes
    return path
