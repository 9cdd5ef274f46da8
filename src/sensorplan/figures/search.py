"""What search does, drawn on a run's map: the undetected intensity, sector looks, finds.

- **The undetected intensity** (a tracker that keeps one, ``pmb``: the episode's
  ``undetected``) as a heat map under the scene, in expected targets per km^2 on one colour
  scale for the whole run (:data:`~sensorplan.figures.colors.INTENSITY_CMAP`, zero at its
  lightest), with a colour bar; the title gives its sum, the expected number of undetected
  targets.
- **A search look** (the episode's ``searched``: the look points at a search sector, not a
  track) as the beam's sector, hatched in the sensor's grey, with a dotted ray along the
  sector's bearing and the bearing in degrees beside the sensor; a look at a track stays a
  line to the track.
- **A target found by search**: a track confirmed (its label's first report) at a step
  where it lies in the field of view of a search look of that step (range band and azimuth
  wedge; occlusion is not checked), ringed and named for a few steps.

:class:`SearchLayer` holds the animation's moving artists (as
:class:`~sensorplan.figures.sets.SetLayer` does); :func:`search_view` the arrays it draws.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import INTENSITY_CMAP, sensor_style
from .view import fov_geometry, move_fov

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from ..simulation.run import Episode
    from ..simulation.scenario import Scenario

#: Opacity of the heat map: the grid lines and fields of view stay visible through it.
HEAT_ALPHA = 0.8
#: Steps a find stays ringed on the animation's map.
FOUND_STEPS = 4


@dataclass(frozen=True)
class Finds:
    """Targets found by search looks (see the module docstring).

    Attributes
    ----------
    step, label : (F,) int      the step of the find and the found track's label
    sensor : (F,) int           the search look it lies in (the first, by sensor index)
    xy : (F, 2)                 the track's reported position then (m)
    """

    step: np.ndarray
    label: np.ndarray
    sensor: np.ndarray
    xy: np.ndarray

    def __len__(self) -> int:
        return len(self.step)


@dataclass(frozen=True)
class SearchView:
    """What the figures draw of a run's search.

    Attributes
    ----------
    density : (S+1, ny, nx) or None   undetected intensity, expected targets per km^2
    expected : (S+1,) or None         its sum over the map, expected undetected targets
    vmax : float                      top of the colour scale (per km^2)
    sectors : (S+1, N) int            search sector of each sensor's look (-1: none)
    bearings : (S+1, N)               that sector's bearing (rad; NaN: none)
    finds : Finds
    mu : (S+1,)                       mu of the plan being executed at each step: the
                                      expected number of undetected targets it finds (the
                                      episode's ``search_found`` of the latest decision
                                      taken before the step; NaN: none, or search off)
    """

    density: np.ndarray | None
    expected: np.ndarray | None
    vmax: float
    sectors: np.ndarray
    bearings: np.ndarray
    finds: Finds
    mu: np.ndarray


def has_search(episode: Episode) -> bool:
    """Whether the run has anything of search to draw (an intensity or sector looks)."""
    return episode.undetected is not None or episode.searched is not None


def per_km2(episode: Episode, scenario: Scenario) -> np.ndarray | None:
    """The episode's undetected intensity in expected targets per km^2, ``(S+1, ny, nx)``
    (None without one)."""
    if episode.undetected is None:
        return None
    grid = np.asarray(episode.undetected, dtype=float)
    area = scenario.world.width * scenario.world.height / (grid.shape[1] * grid.shape[2])
    return grid * (1e6 / area)


def in_field_of_view(xy: np.ndarray, position: np.ndarray, heading: float,
                     params: Any) -> np.ndarray:
    """Which ground points ``(K, 2)`` lie in a sensor's field of view: its ground-range band
    ``[min_ground_range, max_ground_range]`` and azimuth wedge ``heading -+
    fov_half_angle`` (no line-of-sight check)."""
    d = np.asarray(xy, dtype=float) - np.asarray(position, dtype=float)
    r = np.hypot(d[:, 0], d[:, 1])
    off = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - heading)))
    return ((r >= float(params.min_ground_range)) & (r <= float(params.max_ground_range))
            & (np.abs(off) <= float(params.fov_half_angle)))


def search_finds(episode: Episode, scenario: Scenario) -> Finds:
    """The tracks found by search looks: confirmed (first reported) at a step ``t >= 1``
    inside the field of view of a search look of step ``t``."""
    empty = Finds(np.zeros(0, int), np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)))
    if episode.searched is None or not len(episode.track_step):
        return empty
    searched = np.asarray(episode.searched)
    steps = np.asarray(episode.track_step, dtype=np.int64)
    labels = np.asarray(episode.track_label, dtype=np.int64)
    order = np.lexsort((steps, labels))                     # by label, then step
    first = order[np.r_[True, labels[order][1:] != labels[order][:-1]]]
    rows: list[tuple[int, int, int, float, float]] = []
    for k in first[steps[first] >= 1]:
        t = int(steps[k])
        xy = np.asarray(episode.track_mean)[k, :2]
        for i in np.flatnonzero(searched[t] >= 0):
            inside = in_field_of_view(xy[None], episode.sensor_positions[t, i],
                                      float(episode.sensor_headings[t, i]),
                                      scenario.sensors[i].params)
            if inside[0]:
                rows.append((t, int(labels[k]), int(i), float(xy[0]), float(xy[1])))
                break
    if not rows:
        return empty
    rows.sort()
    a = np.array(rows)
    return Finds(a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int), a[:, 3:5])


def search_view(episode: Episode, scenario: Scenario) -> SearchView:
    """The :class:`SearchView` of a run on its scenario."""
    from ..planners.search import sector_bearings
    from ..simulation.settings import sector_counts

    density = per_km2(episode, scenario)
    S1, N = np.asarray(episode.looked).shape
    sectors = (np.asarray(episode.searched, dtype=np.int64) if episode.searched is not None
               else np.full((S1, N), -1, dtype=np.int64))
    bearings = np.full((S1, N), np.nan)
    if (sectors >= 0).any():
        counts = sector_counts(episode.settings.search_sectors, N)
        for i, n in enumerate(counts):
            on = sectors[:, i] >= 0
            bearings[on, i] = sector_bearings(n)[sectors[on, i]]
    top = float(np.max(density, initial=0.0)) if density is not None else 0.0
    expected = (np.asarray(episode.undetected, dtype=float).sum(axis=(1, 2))
                if episode.undetected is not None else None)
    mu = np.full(S1, np.nan)
    if episode.search_found is not None and len(episode.search_found):
        # A decision at time index d plans the looks of steps d + 1, ...
        k = np.searchsorted(np.asarray(episode.decision_steps), np.arange(S1), side="left") - 1
        mu = np.where(k >= 0, np.asarray(episode.search_found)[np.maximum(k, 0)], np.nan)
    return SearchView(density, expected, top if top > 0 else 1.0, sectors, bearings,
                      search_finds(episode, scenario), mu)


def shown(density: np.ndarray, vmax: float) -> np.ndarray:
    """The heat map's cells: those below a thousandth of the colour scale are left out
    (transparent), so that the map where no undetected target can be stays as it is."""
    return np.ma.masked_less(density, 1e-3 * vmax)


def draw_heat_map(ax: Axes, view: SearchView, t: int, scenario: Scenario) -> Any:
    """The intensity of step ``t`` as an image over the map (None without one)."""
    if view.density is None:
        return None
    from matplotlib.colors import Normalize

    W, H = scenario.world.width, scenario.world.height
    return ax.imshow(shown(view.density[t], view.vmax), extent=(0, W, 0, H), origin="lower",
                     cmap=INTENSITY_CMAP, norm=Normalize(0.0, view.vmax), alpha=HEAT_ALPHA,
                     interpolation="nearest", zorder=0.5, gid="undetected intensity")


def colour_bar(fig: Any, image: Any, cax: Axes) -> Any:
    """A horizontal colour bar of the heat map in ``cax``, its unit stated."""
    bar = fig.colorbar(image, cax=cax, orientation="horizontal")
    bar.set_label("undetected intensity: expected targets per km\u00b2", fontsize=7.5)
    bar.ax.tick_params(labelsize=7)
    return bar


def search_handles(view: SearchView) -> list[Any]:
    """Legend entries of the search marks that the run has."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    out: list[Any] = []
    if (view.sectors >= 0).any():
        out.append(Patch(facecolor="none", edgecolor="0.25", hatch="//", linewidth=1.4,
                         label="search look: the beam's sector (dotted: its bearing)"))
    if len(view.finds):
        out.append(Line2D([], [], color="k", marker="o", markerfacecolor="none",
                          markersize=13, markeredgewidth=1.8, linestyle="none",
                          label=f"track found by a search look ({len(view.finds)})"))
    return out


def draw_search_timeline(ax: Axes, sectors: np.ndarray, dt: float) -> None:
    """Hatch the cells of a run of sets' look timeline (one row per sensor, a cell per step)
    whose look was a search look, and say so in its title."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    t, i = np.nonzero(sectors[1:] >= 0)
    if not len(t):
        return
    cells = [Rectangle((k * dt, row - 0.5), dt, 1.0) for k, row in zip(t, i)]
    ax.add_collection(PatchCollection(cells, facecolor="none", edgecolor="0.3", hatch="//",
                                      linewidth=0.0, zorder=1.5, gid="search looks"),
                      autolim=False)
    ax.set_title("Looks: colour = the looked-at track's target (black: false track, grey: "
                 "not reported); light + dot: no detection; hatched: search look; ticks: "
                 "decisions", fontsize=9, loc="left", pad=8)


class SearchLayer:
    """The moving artists of search in an animation: the heat map, each sensor's search
    sector, ray and bearing, and the recent finds (see the module docstring)."""

    def __init__(self, ax: Axes, view: SearchView, scenario: Scenario, spos: np.ndarray,
                 shead: np.ndarray, dense: bool, clip: Any = None) -> None:
        from matplotlib.patches import Wedge

        self.view, self.spos, self.shead, self.scenario = view, spos, shead, scenario
        self.heat = draw_heat_map(ax, view, 0, scenario)
        self.wedges: list[Any] = []
        self.rays: list[Any] = []
        self.texts: list[Any] = []
        # Many sensors are drawn condensed: their search looks only in the title's count.
        for i in range(0 if dense else spos.shape[1]):
            color, _ = sensor_style(i)
            params = scenario.sensors[i].params
            wedge = Wedge(**fov_geometry(spos[0, i], shead[0, i], params), facecolor="none",
                          edgecolor=color, hatch="//", linewidth=1.4, zorder=2.2)
            wedge.set_visible(False)
            ax.add_patch(wedge)
            if clip is not None:
                wedge.set_clip_path(clip)
            self.wedges.append((wedge, params))
            self.rays.append(ax.plot([], [], ":", color=color, linewidth=1.4, zorder=2.3)[0])
            if clip is not None:
                self.rays[-1].set_clip_path(clip)
            self.texts.append(ax.text(0, 0, "", fontsize=7.5, color=color, zorder=7,
                                      clip_on=True))
        self.found = ax.scatter([], [], s=13 ** 2, marker="o", facecolors="none",
                                edgecolors="k", linewidths=1.8, zorder=6.5)
        self.found_names = [ax.text(0, 0, "", fontsize=8, fontweight="bold", zorder=7,
                                    clip_on=True) for _ in range(self._most_found())]
        self.artists: list[Any] = ([self.heat] if self.heat is not None else []) + [
            w for w, _ in self.wedges] + self.rays + self.texts + [self.found,
                                                                   *self.found_names]

    def _most_found(self) -> int:
        """Most finds ringed at once."""
        steps = self.view.finds.step
        return max((int(np.sum((steps > t - FOUND_STEPS) & (steps <= t))) for t in
                    np.unique(steps)), default=0)

    def update(self, t: int) -> None:
        """Move every artist to step ``t``."""
        v = self.view
        if self.heat is not None and v.density is not None:
            self.heat.set_data(shown(v.density[t], v.vmax))
        for i, (wedge, params) in enumerate(self.wedges):
            s = int(v.sectors[t, i])
            on = s >= 0 and t >= 1
            wedge.set_visible(on)
            if not on:
                self.rays[i].set_data([], [])
                self.texts[i].set_text("")
                continue
            move_fov(wedge, self.spos[t, i], self.shead[t, i], params)
            b = float(v.bearings[t, i])
            x, y = self.spos[t, i]
            reach = float(params.max_ground_range)
            self.rays[i].set_data([x, x + reach * math.cos(b)], [y, y + reach * math.sin(b)])
            self.texts[i].set_text(f"S{i} search sector {s}: {math.degrees(b) % 360:.0f}\u00b0")
            self.texts[i].set_position((x + 10, y + 14))
        f = v.finds
        recent = np.flatnonzero((f.step > t - FOUND_STEPS) & (f.step <= t))
        self.found.set_offsets(f.xy[recent].reshape(-1, 2))
        for n, name in enumerate(self.found_names):
            if n < len(recent):
                k = recent[n]
                name.set_text(f"found L{int(f.label[k])} (S{int(f.sensor[k])})")
                name.set_position((f.xy[k, 0] + 12, f.xy[k, 1] + 12))
                name.set_visible(True)
            else:
                name.set_visible(False)

    def title(self, t: int) -> str:
        """The title's search line of step ``t``."""
        v = self.view
        parts = []
        if v.expected is not None:
            parts.append(f"expected undetected targets {v.expected[t]:.2f}")
        n = int((v.sectors[t] >= 0).sum()) if t >= 1 else 0
        parts.append(f"{n} search look{'s' if n != 1 else ''}")
        if np.isfinite(v.mu[t]):
            parts.append(f"the plan expects to find {v.mu[t]:.2f}")
        found = int(np.sum(v.finds.step == t))
        if found:
            parts.append(f"{found} found")
        return ", ".join(parts)
