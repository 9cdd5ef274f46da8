"""The map in Stone Soup's world coordinates, with any origin, and its translation to the core.

The core's :class:`sensorplan.planners.problem.MapRect` is ``[0, W] x [0, H]``. Stone Soup scenarios
are often centred on 0, so the bridge's :class:`MapRect` has an origin ``(x0, y0)``; the
manager plans in the core's frame (world coordinates minus the origin) and executes in world
coordinates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from stonesoup.base import Base, ImmutableMixIn, Property

from ..._types import FloatArray
from ...errors import ConfigError
from ...planners.problem import POSITION_TOL
from ...planners.problem import MapRect as CoreMapRect


def _num(v: float) -> str:
    """A float as the shortest text that reads back to it, without a trailing ``.0``."""
    return repr(float(v)).removesuffix(".0")


class MapRect(ImmutableMixIn, Base):
    """The ground rectangle ``[x0, x0 + width] x [y0, y0 + height]`` (m) in Stone Soup's world
    coordinates; its edge is inside. Immutable, equal by value.

    All four values are required (``MapRect(-500, -500, 1000, 1000)`` is the square centred
    on 0), so the core's two-argument ``MapRect(width, height)`` cannot be mistaken for it.
    """

    x0: float = Property(doc="Smallest ground x of the map (m).")
    y0: float = Property(doc="Smallest ground y of the map (m).")
    width: float = Property(doc="Extent along x (m), > 0.")
    height: float = Property(doc="Extent along y (m), > 0.")

    def __init__(self, x0: float, y0: float, width: float, height: float) -> None:
        values = []
        for name, value in (("x0", x0), ("y0", y0), ("width", width), ("height", height)):
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"world.{name}", f"must be a number, got {value!r}") from None
            if not math.isfinite(v):
                raise ConfigError(f"world.{name}", f"must be finite, got {value!r}")
            if name in ("width", "height") and v <= 0:
                raise ConfigError(f"world.{name}", f"must be > 0, got {_num(v)}")
            values.append(v)
        super().__init__(*values)

    @property
    def origin(self) -> FloatArray:
        """``(x0, y0)`` ``(2,)`` (m): world = core + origin."""
        return np.array([self.x0, self.y0])

    @property
    def core(self) -> CoreMapRect:
        """The same map in the core's frame, ``[0, width] x [0, height]``."""
        return CoreMapRect(self.width, self.height)

    @property
    def key(self) -> tuple[float, float, float, float]:
        """``(x0, y0, width, height)``: two maps are the same map when their keys are equal."""
        return (self.x0, self.y0, self.width, self.height)

    def contains(self, xy: Any, tol: float = POSITION_TOL) -> np.ndarray:
        """Boolean mask of world ground positions ``(..., 2)`` inside the closed map."""
        xy = np.asarray(xy, dtype=float)
        return ((xy[..., 0] >= self.x0 - tol) & (xy[..., 0] <= self.x0 + self.width + tol)
                & (xy[..., 1] >= self.y0 - tol) & (xy[..., 1] <= self.y0 + self.height + tol))

    def __str__(self) -> str:
        return (f"[{_num(self.x0)}, {_num(self.x0 + self.width)}] x "
                f"[{_num(self.y0)}, {_num(self.y0 + self.height)}]")

    @classmethod
    def from_core(cls, world: CoreMapRect) -> MapRect:
        """The core map ``[0, W] x [0, H]`` as a bridge map with origin ``(0, 0)``."""
        return cls(0.0, 0.0, float(world.width), float(world.height))


#: ``LatticeMovable``'s map when none is given: the paper's 600 m square ``[0, 600]^2``.
DEFAULT_WORLD = MapRect(0.0, 0.0, 600.0, 600.0)


def as_world(value: Any) -> MapRect | None:
    """A bridge :class:`MapRect` from a bridge or core map (None stays None)."""
    if value is None or isinstance(value, MapRect):
        return value
    if isinstance(value, CoreMapRect):
        return MapRect.from_core(value)
    raise TypeError(f"world must be a MapRect(x0, y0, width, height), got {value!r}")


def check_inside(field: str, xy: Any, world: MapRect, defaulted: bool = False) -> None:
    """Raise a :class:`ConfigError` naming ``field``, the position and the map's bounds when
    the ground position ``xy`` ``(2,)`` is outside ``world``."""
    xy = np.asarray(xy, dtype=float).ravel()[:2]
    if bool(world.contains(xy)):
        return
    which = " (LatticeMovable's default world)" if defaulted else ""
    raise ConfigError(field, f"({_num(xy[0])}, {_num(xy[1])}) is outside the map {world}"
                             f"{which}; set LatticeMovable(world=MapRect(x0, y0, width, height))")
