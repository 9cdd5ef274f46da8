"""What a look sees of the undetected intensity's grid: the one call both planning rewards
with search (information, :mod:`.search`; the GOSPA bound, :mod:`.gospa_bound`) score a
look's cells with."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .._types import FloatArray
from ..models import radar
from .information import Context


class Cells(Protocol):
    """The decision's tracks context and the grid's cell centres."""

    @property
    def ctx(self) -> Context: ...
    @property
    def centres(self) -> FloatArray: ...


def detection(cells: Cells, i: int, positions: FloatArray, headings: FloatArray
              ) -> FloatArray:
    """``P_d v`` at every cell centre for looks of sensor i: ``(B, C)`` from poses
    ``positions (B, 2)``, ``headings (B,)`` (the radar's one implementation, the call the
    multi-target tracker thins its undetected cells with)."""
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    d = cells.centres[None, :, :] - positions[:, None, :]
    B = len(positions)
    return radar.detectable_points(cells.ctx.radar, np.full(B, i, dtype=np.int64), d[..., 0],
                                   d[..., 1], np.asarray(headings, dtype=float).reshape(B),
                                   positions, cells.ctx.buildings)
