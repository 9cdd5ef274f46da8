"""The moving artists of an animation of many sensors or targets, as a few collections.

:mod:`sensorplan.figures.animation` updates one set of artists per target and per sensor for every
frame; above :data:`~sensorplan.figures.view.DENSE_TARGETS` targets or
:data:`~sensorplan.figures.view.DENSE_SENSORS` sensors that is over a thousand artists and
half a second a frame. Here all targets (sensors) share one collection per kind of thing,
updated in place, as the static figure's condensed drawing does
(:mod:`sensorplan.figures.swarm`): no names, and a path fades in steps of a few segments
(each step one polyline in one tint) instead of segment by segment.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import SENSOR_MARKERS, mix, mix_hex, sensor_style
from .swarm import ellipse_arrays, target_rgb
from .view import FADE_FLOOR, fov_geometry

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from ..simulation.scenario import Scenario

#: Paths fade in steps of this many segments (at least; more when the tail is long).
FADE_STEP = 4
#: Segments older than this many fading time constants share the faintest tint.
FADE_CUTOFF = 4.0
#: Most tints of one path.
MAX_TINTS = 12


def faded_chunks(xy: np.ndarray, rgb: np.ndarray, t: int,
                 tau: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Polylines of paths ``xy[:t + 1] (t + 1, K, 2)`` cut into chunks of a few segments
    and each chunk's tint of ``rgb (K, 3)`` at its mean age (steps before ``t``;
    ``exp(-age / tau)`` above the floor tint, as :func:`~sensorplan.figures.view.fade_colors`);
    segments older than :data:`FADE_CUTOFF` ``tau`` form one chunk at the oldest tint."""
    if t < 1:
        return [], np.zeros((0, 3))
    cutoff = max(math.ceil(FADE_CUTOFF * tau), 1)
    step = max(FADE_STEP, math.ceil(cutoff / MAX_TINTS))
    old = max(t - cutoff, 0)                 # points 0..old: the oldest chunk
    chunks = []                              # (first point, last point, mean age)
    end = t
    while end > old:
        start = max(end - step, old)
        # Segment s joins points s and s + 1 and is t - 1 - s steps old.
        chunks.append((start, end, t - 1 - 0.5 * (start + end - 1)))
        end = start
    if old > 0:
        chunks.append((0, old, float(cutoff)))
    lines: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    for start, end, age in chunks:
        w = FADE_FLOOR + (1.0 - FADE_FLOOR) * min(math.exp(-age / tau), 1.0)
        lines.extend(np.swapaxes(xy[start:end + 1], 0, 1))
        cols.append(w * rgb + (1.0 - w))
    return lines, np.concatenate(cols)


class DenseTargets:
    """All targets' moving artists: true tracks and estimates so far (fading), current
    positions and estimates, ellipses."""

    def __init__(self, ax: Axes, truth: np.ndarray, est: np.ndarray, cov: np.ndarray,
                 limit: float, tau: float) -> None:
        from matplotlib.collections import EllipseCollection, LineCollection

        self.truth, self.est, self.cov, self.limit, self.tau = truth, est, cov, limit, tau
        M = truth.shape[1]
        self.rgb = target_rgb(np.arange(M))
        # Any: matplotlib's stubs type add_collection's result as a bare Collection.
        self.track: Any = ax.add_collection(LineCollection([], linewidths=1.6, zorder=3),
                                            autolim=False)
        self.track_est: Any = ax.add_collection(LineCollection(
            [], linewidths=0.9, linestyles=":", zorder=3), autolim=False)
        self.now = ax.scatter(truth[0, :, 0], truth[0, :, 1], s=5 ** 2, c=self.rgb,
                              marker="o", linewidths=0, zorder=5)
        self.now_est = ax.scatter(est[0, :, 0], est[0, :, 1], s=6 ** 2, c=self.rgb,
                                  marker="+", linewidths=1.2, zorder=5)
        self.ell: Any = ax.add_collection(EllipseCollection(
            np.zeros(M), np.zeros(M), np.zeros(M), units="xy", offsets=np.zeros((M, 2)),
            offset_transform=ax.transData, facecolors="none", edgecolors=self.rgb,
            linewidths=1.0, zorder=4), autolim=False)
        self.artists: list[Any] = [self.track, self.track_est, self.ell, self.now,
                                   self.now_est]

    def update(self, t: int) -> None:
        """Move every artist to step ``t``."""
        for coll, xy in ((self.track, self.truth), (self.track_est, self.est)):
            lines, cols = faded_chunks(xy, self.rgb, t, self.tau)
            coll.set_segments(lines)
            coll.set_color(cols)
        self.now.set_offsets(self.truth[t])
        self.now_est.set_offsets(self.est[t])
        w, h, angle, ok = ellipse_arrays(self.cov[t], self.limit)
        ok &= np.all(np.isfinite(self.est[t]), axis=-1)
        self.ell.set_widths(np.where(ok, w, 0.0))
        self.ell.set_heights(np.where(ok, h, 0.0))
        self.ell.set_angles(np.where(ok, angle, 0.0))
        self.ell.set_offsets(np.where(ok[:, None], self.est[t], 0.0))


class DenseSensors:
    """All sensors' moving artists: fields of view, paths so far (fading), positions, the
    line to the target each looks at (dashed, with a cross at the target, when missed)."""

    def __init__(self, ax: Axes, scenario: Scenario, spos: np.ndarray, shead: np.ndarray,
                 looked: np.ndarray, missed: np.ndarray, truth: np.ndarray, tau: float,
                 border: Any) -> None:
        from matplotlib.collections import LineCollection, PatchCollection

        self.sc, self.spos, self.shead, self.tau = scenario, spos, shead, tau
        self.looked, self.missed, self.truth = looked, missed, truth
        N = spos.shape[1]
        styles = [sensor_style(i) for i in range(N)]
        greys = [c for c, _ in styles]
        self.path_rgb = np.array([mix(mix_hex(c, 0.5), 1.0) for c in greys])
        self.fov: Any = ax.add_collection(PatchCollection(
            self._wedges(0), facecolors=greys, edgecolors=greys, alpha=0.10, linewidths=1.0,
            linestyles="--", zorder=1.8), autolim=False)
        self.fov.set_clip_path(border)
        self.path: Any = ax.add_collection(LineCollection([], linewidths=0.7, zorder=2),
                                           autolim=False)
        self.marks: list[tuple[list[int], Any]] = []
        for marker in sorted({m for _, m in styles}, key=SENSOR_MARKERS.index):
            who = [i for i in range(N) if styles[i][1] == marker]
            self.marks.append((who, ax.scatter(spos[0, who, 0], spos[0, who, 1], s=6 ** 2,
                                               marker=marker, c=[greys[i] for i in who],
                                               linewidths=0, zorder=6)))
        self.look: Any = ax.add_collection(LineCollection([], linewidths=1.0, zorder=4),
                                           autolim=False)
        self.cross = ax.scatter(np.zeros(0), np.zeros(0), s=6 ** 2, marker="x", c="k",
                                linewidths=1.5, zorder=7)
        self.artists: list[Any] = [self.fov, self.path, self.look, self.cross] + [
            m for _, m in self.marks]

    def _wedges(self, t: int) -> list[Any]:
        from matplotlib.patches import Wedge

        return [Wedge(**fov_geometry(self.spos[t, i], float(self.shead[t, i]),
                                     self.sc.sensors[i].params))
                for i in range(self.spos.shape[1])]

    def update(self, t: int) -> None:
        """Move every artist to step ``t``."""
        self.fov.set_paths(self._wedges(t))
        lines, cols = faded_chunks(self.spos, self.path_rgb, t, self.tau)
        self.path.set_segments(lines)
        self.path.set_color(cols)
        for who, marks in self.marks:
            marks.set_offsets(self.spos[t, who])
        i = np.nonzero(self.looked[t] >= 0)[0]
        j = self.looked[t, i]
        miss = self.missed[t, i].astype(bool)
        self.look.set_segments(np.stack([self.spos[t, i], self.truth[t, j]], axis=1))
        self.look.set_color(target_rgb(j))
        self.look.set_linestyles(["--" if m else "-" for m in miss] or "-")
        self.cross.set_offsets(self.truth[t, j[miss]].reshape(-1, 2))
