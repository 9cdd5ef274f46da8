"""Condensed drawing of runs with many sensors or targets (a swarm), for
:mod:`sensorplan.figures.run` and :mod:`sensorplan.figures.animation`.

Above :data:`~sensorplan.figures.view.DENSE_SENSORS` sensors or
:data:`~sensorplan.figures.view.DENSE_TARGETS` targets, one artist per sensor, target, ellipse or
look costs matplotlib tens of seconds (a 100-sensor, 200-target run had over ten thousand)
and draws a picture nobody can read. Here each kind of thing is one collection (all
sensors' paths one ``LineCollection``, all fields of view one ``PatchCollection``, all
ellipses one ``EllipseCollection``, the look timeline one image), and what only clutters at
that size is left out: ellipses, fields of view and looks are drawn at the last step only,
and sensors and targets carry no names. Colours are those of the full drawing.
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import (
                     BUILDING_EDGE,
                     BUILDING_FACE,
                     SENSOR_MARKERS,
                     TARGET_PALETTE,
                     mix,
                     mix_hex,
                     sensor_style,
                     target_color,
                     )
from .view import LEGEND_ITEMS, N_SIGMA, RunView, fade_colors, fov_geometry, segments

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from ..simulation.scenario import Scenario

#: Tint of a missed look's cell in the timeline image (as in the hatched cells).
MISSED_TINT = 0.45


def palette_rgb(weight: float = 1.0) -> np.ndarray:
    """``(P, 3)`` RGB of the target palette, tinted towards white by ``weight``."""
    return np.array([mix(c, weight) for c in TARGET_PALETTE])


def target_rgb(indices: Any, weight: float = 1.0) -> np.ndarray:
    """``(..., 3)`` RGB of targets ``indices`` (their
    :func:`~sensorplan.figures.colors.target_color`,
    tinted by ``weight``)."""
    return palette_rgb(weight)[np.asarray(indices, dtype=int) % len(TARGET_PALETTE)]


def faded_paths(xy: np.ndarray, colors: list[str], ages: np.ndarray,
                tau: float | None) -> tuple[list[np.ndarray], np.ndarray]:
    """Segments ``(K * (n - 1), 2, 2)`` of ``K`` paths ``xy (n, K, 2)`` and their faded
    colours (each path's own colour, :func:`~sensorplan.figures.view.fade_colors`)."""
    if xy.shape[0] < 2 or xy.shape[1] == 0:
        return [], np.zeros((0, 3))
    segs = np.concatenate([segments(xy[:, k]) for k in range(xy.shape[1])])
    cols = np.concatenate([fade_colors(c, ages, tau) for c in colors])
    return list(segs), cols


def ellipse_arrays(cov: np.ndarray, limit: float) -> tuple[np.ndarray, ...]:
    """Widths, heights (m), angles (deg) of the ``N_SIGMA`` ellipses of ``cov (K, 2, 2)``
    and which are finite (``ok (K,)``); semi-axes clipped to ``limit`` as in
    :func:`~sensorplan.figures.run.ellipse_geometry`."""
    cov = np.asarray(cov, dtype=float)
    ok = np.all(np.isfinite(cov), axis=(-2, -1))
    sym = np.where(ok[:, None, None], 0.5 * cov + 0.5 * np.swapaxes(cov, -1, -2), 0.0)
    vals, vecs = np.linalg.eigh(sym)
    ok &= np.all(np.isfinite(vals), axis=-1)
    semi = np.minimum(N_SIGMA * np.sqrt(np.clip(np.nan_to_num(vals), 0.0, None)), limit)
    angle = np.degrees(np.arctan2(vecs[:, 1, 1], vecs[:, 0, 1]))
    return 2.0 * semi[:, 1], 2.0 * semi[:, 0], angle, ok


def fov_patches(xy: np.ndarray, heading: np.ndarray, scenario: Scenario) -> list[Any]:
    """One ``Wedge`` (ground field of view) per sensor at positions ``xy (N, 2)``."""
    from matplotlib.patches import Wedge

    return [Wedge(**fov_geometry(xy[i], float(heading[i]), scenario.sensors[i].params))
            for i in range(xy.shape[0])]


def draw_sensors(ax: Axes, run: RunView, scenario: Scenario, border: Any) -> None:
    """All sensors in a few artists: fields of view and looks at the last step, paths,
    start (open) and end (filled) markers."""
    from matplotlib.collections import LineCollection, PatchCollection

    spos, S, N = run.spos, run.S, run.N
    styles = [sensor_style(i) for i in range(N)]
    greys = [c for c, _ in styles]
    if S >= 1:
        fov = PatchCollection(fov_patches(spos[S], run.shead[S], scenario),
                              facecolors=greys, edgecolors=greys, alpha=0.10,
                              linewidths=1.0, linestyles="--", zorder=1, gid="fields of view")
        fov.set_clip_path(border)           # the sensing region that matters is on the map
        ax.add_collection(fov, autolim=False)
    # Lighter and smaller than a few sensors' (a hundred markers would hide the tracks).
    segs, cols = faded_paths(spos, [mix_hex(c, 0.5) for c in greys], run.ages, None)
    ax.add_collection(LineCollection(segs, colors=cols, linewidths=0.6, zorder=2,
                                     gid="sensor paths"), autolim=False)
    for marker in sorted({m for _, m in styles}, key=SENSOR_MARKERS.index):
        who = [i for i in range(N) if styles[i][1] == marker]
        c = [greys[i] for i in who]
        ax.scatter(spos[0, who, 0], spos[0, who, 1], s=4 ** 2, marker=marker,
                   facecolors="white", edgecolors=c, linewidths=0.8, zorder=4)
        ax.scatter(spos[-1, who, 0], spos[-1, who, 1], s=6 ** 2, marker=marker, c=c,
                   linewidths=0, zorder=4)
    if S >= 1:
        i = np.nonzero(run.looked[S] >= 0)[0]
        j = run.looked[S, i]
        looks = LineCollection(list(np.stack([spos[S, i], run.truth[S, j]], axis=1)),
                               colors=target_rgb(j), linewidths=0.9, alpha=0.85, zorder=2.5,
                               linestyles=["--" if m else "-" for m in run.missed[S, i]],
                               gid="looks")
        ax.add_collection(looks, autolim=False)


def draw_targets(ax: Axes, run: RunView) -> None:
    """All targets in a few artists: true tracks and estimates, start and end markers,
    ellipses at the last step and the missed looks."""
    from matplotlib.collections import EllipseCollection, LineCollection

    truth, est, S, M = run.truth, run.est, run.S, run.M
    colors = [target_color(j) for j in range(M)]
    for xy, width, style, gid in ((truth, 1.6, "-", "tracks"), (est, 0.9, ":", "estimates")):
        segs, cols = faded_paths(xy, colors, run.ages, None)
        ax.add_collection(LineCollection(segs, colors=cols, linewidths=width,
                                         linestyles=style, zorder=3, gid=gid), autolim=False)
    ax.scatter(truth[0, :, 0], truth[0, :, 1], s=4 ** 2, marker="o",
               c=target_rgb(np.arange(M), 0.5), linewidths=0, zorder=4)
    ax.scatter(truth[-1, :, 0], truth[-1, :, 1], s=4 ** 2, marker="s",
               c=target_rgb(np.arange(M)), linewidths=0, zorder=4)
    w, h, angle, ok = ellipse_arrays(run.cov[S, :, :2, :2], run.limit)
    ok &= np.all(np.isfinite(est[S]), axis=-1)
    ax.add_collection(EllipseCollection(w[ok], h[ok], angle[ok], units="xy",
                                        offsets=est[S][ok], offset_transform=ax.transData,
                                        facecolors="none", edgecolors=target_rgb(
                                            np.nonzero(ok)[0]), linewidths=1.0, zorder=3,
                                        gid="ellipses"),
                      autolim=False)
    t, i = np.nonzero((run.looked[1:] >= 0) & run.missed[1:])
    j = run.looked[1:][t, i]
    ax.scatter(truth[t + 1, j, 0], truth[t + 1, j, 1], s=4 ** 2, marker="x", c="k",
               linewidths=1.0, zorder=5, gid="missed looks")


def draw_look_image(ax: Axes, looked: np.ndarray, missed: np.ndarray, dt: float) -> None:
    """The assignment timeline as one image: row ``i``, column ``t - 1`` in the colour of
    the target sensor ``i`` looked at in step ``t`` (a light tint with a black dot when the
    look missed; white: no look)."""
    S, N = looked.shape[0] - 1, looked.shape[1]
    if S < 1:
        return
    cells = np.ones((N, S, 3))
    who = looked[1:].T                                   # (N, S)
    seen = who >= 0
    miss = missed[1:].T & seen
    cells[seen & ~miss] = target_rgb(who[seen & ~miss])
    cells[miss] = target_rgb(who[miss], MISSED_TINT)
    ax.imshow(cells, extent=(0, S * dt, N - 0.5, -0.5), origin="upper", aspect="auto",
              interpolation="nearest", zorder=1)
    # Thin white rules between rows, so that neighbours looking at same-coloured targets
    # stay apart; not on rows of a few pixels, where they would alias into stripes.
    if ax.get_window_extent().height >= 6 * N:
        ax.hlines(np.arange(N - 1) + 0.5, 0, S * dt, colors="white", linewidth=0.6,
                  zorder=1.5)
    i, t = np.nonzero(miss)
    ax.scatter((t + 0.5) * dt, i, s=2.5, c="k", linewidths=0, zorder=2, gid="missed looks")


def label_rows(ax: Axes, N: int) -> None:
    """Row labels ``S0, S10, ...`` of the timeline image (about ten, at round numbers)."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(nbins=10, integer=True))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"S{v:.0f}"
                                               if 0 <= v < N else ""))


def draw_error_bundle(ax: Axes, time_s: np.ndarray, err: np.ndarray, own: np.ndarray,
                      floor: float) -> None:
    """Every target's position error as one collection of thin lines in its colour, the
    median over targets (black) and the median of the filter's own RMS error (dotted)."""
    from matplotlib.collections import LineCollection

    M = err.shape[1]
    lines = np.stack([np.broadcast_to(time_s[:, None], err.shape),
                      np.clip(err, floor, None)], axis=-1).swapaxes(0, 1)   # (M, S+1, 2)
    ax.add_collection(LineCollection(list(lines), colors=target_rgb(np.arange(M)), linewidths=0.6,
                                     alpha=0.45, zorder=2, gid="errors"), autolim=False)
    with np.errstate(all="ignore"):
        ax.plot(time_s, np.clip(np.nanmedian(err, axis=1), floor, None), color="k",
                linewidth=1.6, zorder=3)
        ax.plot(time_s, np.clip(np.nanmedian(own, axis=1), floor, 1e9), color="k",
                linewidth=1.1, linestyle=":", zorder=3)


def summary_legend(ax: Axes, kinds: tuple[str, ...], scenario: Scenario,
                   extra: list[Any]) -> None:
    """:func:`~sensorplan.figures.run.map_legend` with more than ``LEGEND_ITEMS`` targets or
    sensors: each group that large is one entry (its colours or markers side by side, its
    range of names, kinds or altitudes)."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    entries: list[tuple[Any, str]] = []
    if len(kinds) > LEGEND_ITEMS:
        count = ", ".join(f"{n} {k}" for k, n in Counter(kinds).items())
        label = (f"T0\u2013T{len(kinds) - 1} ({count}),\ncolours repeat every "
                 f"{len(TARGET_PALETTE)} targets")
        entries.append((tuple(Patch(facecolor=c) for c in TARGET_PALETTE), label))
    else:
        entries += [(Patch(facecolor=target_color(j)), f"T{j} ({kind})")
                    for j, kind in enumerate(kinds)]
    z = [float(spec.params.altitude) for spec in scenario.sensors]
    if len(z) > LEGEND_ITEMS:
        span = f"{min(z):g} m" if min(z) == max(z) else f"{min(z):g}\u2013{max(z):g} m"
        entries.append((tuple(Line2D([], [], color=sensor_style(i)[0], linestyle="none",
                                     marker=sensor_style(i)[1], markersize=6)
                              for i in range(3)),
                        f"S0\u2013S{len(z) - 1}, z = {span},\ngreys and markers repeat"))
    else:
        entries += [(Line2D([], [], color=sensor_style(i)[0], marker=sensor_style(i)[1],
                            linewidth=1.0), f"S{i}, z = {zi:g} m") for i, zi in enumerate(z)]
    if scenario.buildings:
        entries.append((Patch(facecolor=BUILDING_FACE, edgecolor=BUILDING_EDGE),
                        "building (height)"))
    entries += [(h, h.get_label()) for h in extra]
    ax.legend([h for h, _ in entries], [label for _, label in entries], loc="upper left",
              bbox_to_anchor=(1.01, 1.0), fontsize=8.5, frameon=False,
              handler_map={tuple: HandlerTuple(ndivide=None, pad=0.0)})


def rmse_summary(rmse: np.ndarray) -> str:
    """Title part of many targets' RMSE: median and worst (with which)."""
    if not np.isfinite(rmse).any():
        return f"RMSE of the {rmse.size} targets: not finite"
    worst = int(np.nanargmax(np.where(np.isnan(rmse), -np.inf, rmse)))
    return (f"RMSE over the {rmse.size} targets: median {np.nanmedian(rmse):.0f} m, "
            f"worst {rmse[worst]:.0f} m (T{worst})")
