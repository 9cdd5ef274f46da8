"""What the multi-target trackers share: the models and the map of a tracker of an unknown
number of targets (the PMB tracker and the GNN baseline)."""

from __future__ import annotations

from typing import Any

from ..._types import FloatArray
from ...models.linear import LinearSensor
from ..tracker import gate_threshold
from ..base import motion_matrices
from ..known_map import MAP_EDGES
from . import undetected
from .sensing import make_sensing


class MapTracker:
    """The motion model, the measurement model, the gate and the grid of map cells (where
    a first detection may start a target) of a multi-target tracker.

    Parameters
    ----------
    measurement : radar table or LinearSensor   the sensors' measurement model
    dt : float > 0                    step (s)
    world : (W, H)                    the map ``[0, W] x [0, H]`` (m)
    process_noise : float >= 0        q of the constant-velocity model (m^2/s^3)
    motion : (F, Q) or None           a motion model of its own instead (a benchmark's)
    resolution : float > 0            largest cell side (m)
    velocity_var : float > 0          each velocity component's prior variance (m^2/s^2)
    gate_probability : float          probability mass of a track's gate
    map_edge : {"exit", "closed"} or None   what a target does at the map's edge: leaves
                                      it, or turns back (None: the map is not modelled)
    buildings : (B, 5) or None        footprints that hide targets (the radar)
    """

    def __init__(self, measurement: FloatArray | LinearSensor, dt: float,
                 world: tuple[float, float], *, process_noise: float, motion: Any,
                 resolution: float, velocity_var: float, gate_probability: float,
                 map_edge: str | None, buildings: FloatArray | None) -> None:
        if map_edge is not None and map_edge not in MAP_EDGES:
            raise ValueError(f"map_edge must be one of {MAP_EDGES} or None, got {map_edge!r}")
        self.F, self.Q = motion_matrices(dt, process_noise, motion)
        self.sensing = make_sensing(measurement, buildings)
        self.dt = float(dt)
        self.process_noise = float(process_noise)
        self.gate = gate_threshold(gate_probability)
        self.gate_probability = float(gate_probability)
        self.map_edge = map_edge
        self.world = (float(world[0]), float(world[1]))
        self.grid = undetected.make_grid(*self.world, resolution, velocity_var)
        self._cell_means, self._cell_covs = self.grid.cell_states()
