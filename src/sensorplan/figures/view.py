"""Constants, geometry and tints shared by the figures of a run (numpy only).

:mod:`sensorplan.figures.run` (one artist per sensor and target) and
:mod:`sensorplan.figures.swarm` (the condensed drawing of many) both draw from here, so
that neither imports the other's module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .colors import mix

if TYPE_CHECKING:  # pragma: no cover
    from ..simulation.scenario import Scenario

#: Chi-square(2) 95 % quantile would be 2.45 sigma; the figures show the usual 2 sigma.
N_SIGMA = 2.0
#: Lightest tint of a faded path (its oldest point), as a weight of the full colour.
FADE_FLOOR = 0.12
#: Above this many sensors the figures draw them condensed (:mod:`sensorplan.figures.swarm`):
#: fields of view and looks at the last step only, no names or heading arrows, and the
#: timeline as one image. 30 is also where sensors' (grey, marker) pairs start to repeat.
DENSE_SENSORS = 30
#: Above this many targets the figures draw them condensed: ellipses at the last step only,
#: no names, and in the error panel thin lines and the median over targets.
DENSE_TARGETS = 30
#: Targets (sensors) named one by one in the legend and the title up to this many; beyond,
#: one summary entry.
LEGEND_ITEMS = 12
#: Height (inches) of the rows of the timeline drawn as an image (more than
#: :data:`DENSE_SENSORS` sensors); one row per sensor otherwise takes 0.32 inch.
TIMELINE_IMAGE_HEIGHT = 4.0


#: Drawn ellipse semi-axes and off-map coordinates are clipped to this many map sizes, so a
#: diverged track (covariance 1e40) draws as fast as any other.
CLIP_MAPS = 3.0


def map_limit(scenario: Scenario) -> float:
    """:data:`CLIP_MAPS` map sizes (m): the clipping bound of drawn geometry."""
    return CLIP_MAPS * max(scenario.world.width, scenario.world.height)


def clip_xy(xy: Any, scenario: Scenario) -> np.ndarray:
    """Positions ``(..., 2)`` clipped to the map grown by :func:`map_limit` on every side
    (only far off-map points move; non-finite ones become NaN, which draws as a gap)."""
    xy = np.array(xy, dtype=float)
    lim = map_limit(scenario)
    xy[~np.isfinite(xy)] = np.nan
    xy[..., 0] = np.clip(xy[..., 0], -lim, scenario.world.width + lim)
    xy[..., 1] = np.clip(xy[..., 1], -lim, scenario.world.height + lim)
    return xy


def fov_geometry(xy: Any, heading: float, params: Any) -> dict[str, Any]:
    """Wedge arguments of a sensor's ground field of view: the range-band annulus sector
    ``[min_ground_range, max_ground_range]`` of its azimuth wedge ``heading -+
    fov_half_angle`` (centre, outer radius, angles in degrees, band width)."""
    g_min = float(params.min_ground_range)
    g_max = float(params.max_ground_range)
    half = math.degrees(float(params.fov_half_angle))
    centre = math.degrees(float(heading))
    return {"center": (float(xy[0]), float(xy[1])), "r": g_max, "theta1": centre - half,
            "theta2": centre + half, "width": g_max - g_min}


def move_fov(wedge: Any, xy: Any, heading: float, params: Any) -> None:
    """Move a field-of-view ``Wedge`` drawn with :func:`fov_geometry` to a new pose (an
    animation's frame)."""
    geo = fov_geometry(xy, heading, params)
    wedge.set_center(geo["center"])
    wedge.set_radius(geo["r"])
    wedge.set_theta1(geo["theta1"])
    wedge.set_theta2(geo["theta2"])
    wedge.set_width(geo["width"])


def fade_colors(color: str, ages: Any, tau: float | None) -> np.ndarray:
    """RGB ``(n, 3)`` tints of ``color`` for path segments of the given ages (steps before
    now): full colour now, lighter with age (``exp(-age / tau)``; linear over the whole path
    when ``tau`` is None and ages are normalised to [0, 1])."""
    ages = np.asarray(ages, dtype=float)
    w = 1.0 - ages if tau is None else np.exp(-ages / tau)
    w = (FADE_FLOOR + (1.0 - FADE_FLOOR) * np.clip(w, 0.0, 1.0)).reshape(-1, 1)
    # colors.mix against white, for every weight at once (the same float operations).
    return w * np.asarray(mix(color, 1.0)) + (1.0 - w) * 1.0


def segments(xy: np.ndarray) -> np.ndarray:
    """Consecutive point pairs ``(n - 1, 2, 2)`` of a path ``(n, 2)``."""
    return np.stack([xy[:-1], xy[1:]], axis=1)


@dataclass(frozen=True)
class RunView:
    """What the static figure draws of a run: positions clipped for drawing (m), the
    ellipse times and the segments' ages."""

    truth: np.ndarray           # (S+1, M, 2)
    est: np.ndarray             # (S+1, M, 2)
    cov: np.ndarray             # (S+1, M, 4, 4)
    spos: np.ndarray            # (S+1, N, 2)
    shead: np.ndarray           # (S+1, N) rad
    looked: np.ndarray          # (S+1, N) int
    missed: np.ndarray          # (S+1, N) bool
    times: np.ndarray           # ellipse times (steps)
    ages: np.ndarray            # (S,) segment s: 1 (oldest) .. 0 (newest)
    limit: float                # clipping bound of drawn geometry (m)

    @property
    def S(self) -> int:
        return self.truth.shape[0] - 1

    @property
    def M(self) -> int:
        return self.truth.shape[1]

    @property
    def N(self) -> int:
        return self.spos.shape[1]


def map_legend_beside(ax: Any, targets: list[Any], scenario: Any, extra: list[Any],
                      fontsize: float, sensors: int | None = None) -> None:
    """The legend right of a run's map: ``targets`` (handles), the first ``sensors`` (all
    for None) sensors (grey, marker, altitude), the buildings, then ``extra``."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from .colors import BUILDING_EDGE, BUILDING_FACE, sensor_style

    handles = list(targets)
    for i, spec in enumerate(scenario.sensors[:sensors]):
        color, marker = sensor_style(i)
        handles.append(Line2D([], [], color=color, marker=marker, linewidth=1.0,
                              label=f"S{i}, z = {float(spec.params.altitude):g} m"))
    if scenario.buildings:
        handles.append(Patch(facecolor=BUILDING_FACE, edgecolor=BUILDING_EDGE,
                             label="building (height)"))
    ax.legend(handles=handles + extra, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              fontsize=fontsize, frameon=False)
