"""What the multi-target trackers share: the map model of a tracker of an unknown number of
targets (the PMB tracker and the GNN baseline), and the base class that holds it."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import KW_ONLY, dataclass

import numpy as np

from ..._types import FloatArray
from ...limits import Range, coerce
from ...models.linear import LinearSensor
from ..base import Looks, motion_matrices
from ..known_map import MAP_EDGES
from ..tracker import gate_threshold
from . import undetected
from .sensing import Look, make_sensing


def _number(name: str, value: object, allowed: Range) -> float:
    """``value`` as a float in ``allowed`` (the settings' own rules), else a ValueError
    naming ``name``."""
    try:
        v = float(coerce(float, value))
    except ValueError as exc:
        raise ValueError(f"{name} {exc}") from None
    message = allowed.violation(v)
    if message:
        raise ValueError(f"{name} {message}")
    return v


#: A length, a duration, a variance: above 0.
POSITIVE = Range(0.0, None, lo_open=True)


def _frozen(a: FloatArray) -> FloatArray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


# eq=False: the fields hold arrays, whose == is elementwise; a model equals only itself.
@dataclass(frozen=True, eq=False)
class MapModel:
    """The model a multi-target tracker of the map holds: its sensors, its motion model,
    the map and its grid of cells (where a first detection may start a target), and the
    gate. Built once and given to either tracker (``PMBTracker(model, ...)``,
    ``GNNTracker(model, ...)``); every field is checked here.

    Parameters
    ----------
    measurement : (N, C) radar table, or LinearSensor
        The sensors: the radar table of :func:`sensorplan.models.sensors.radar_table`
        (``Looks.sensors`` index its rows), or the linear position sensor that scans its
        whole area (:mod:`sensorplan.models.linear`; one scan per look).
    dt : float > 0
        Step (s).
    world : (W, H), each > 0
        The map ``[0, W] x [0, H]`` (m) the grid covers.
    process_noise : float >= 0
        q of the CWNA motion model (m^2/s^3); default 0.05, the paper's filter.
    motion : (F, Q), optional
        Another linear-Gaussian motion model, ``(4, 4)`` each (e.g. a benchmark's discrete
        white-noise acceleration); replaces the CWNA one.
    resolution : float > 0
        Largest side of a grid cell (m); default 25 (a 24 x 24 grid on the 600 m map).
    velocity_var : float > 0
        Prior variance of each velocity component of a target not yet detected
        (m^2/s^2); default 10.5, the paper's targets' (speeds uniform in [3, 6] m/s in a
        uniform direction: E[s^2] / 2 = 10.5).
    speed_range : (lo, hi), optional
        The speeds (m/s) of targets not yet detected, uniform in this range: what a PMB
        tracker's inward birth velocity prior is made of (``birth_velocity = "inward"``);
        None (default): not known.
    gate_probability : float in (0, 1)
        Chi-square gate of every innovation; default 0.999 (the known-target tracker's).
    map_edge : {"exit", "closed"} or None
        What a target that reaches the map's edge does: leaves and is gone (``exit``) or
        turns back (``closed``); None (default): the edge is not modelled. Each tracker's
        docstring says what it does with it.
    buildings : (K, 5), optional
        Buildings ``x0, y0, x1, y1, height`` that hide targets from the radar (none with
        the linear sensor, which sees through them).

    Raises
    ------
    ValueError
        A field out of range or of the wrong shape; the message names it.

    Examples
    --------
    >>> from sensorplan.models.linear import williams15
    >>> model = MapModel(williams15(), 1.0, (300, 300), resolution=30.0)
    >>> model.world, model.grid().nx
    ((300.0, 300.0), 10)
    """

    measurement: FloatArray | LinearSensor
    dt: float
    world: tuple[float, float]
    _: KW_ONLY
    process_noise: float = 0.05
    motion: tuple[FloatArray, FloatArray] | None = None
    resolution: float = 25.0
    velocity_var: float = 10.5
    speed_range: tuple[float, float] | None = None
    gate_probability: float = 0.999
    map_edge: str | None = None
    buildings: FloatArray | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)     # the normalised value (frozen)

        if not isinstance(self.measurement, LinearSensor):
            table = np.asarray(self.measurement)
            if table.ndim != 2 or len(table) == 0 or not np.issubdtype(table.dtype, np.number):
                raise ValueError("measurement must be a radar table (N, C), N >= 1, or a "
                                 f"LinearSensor, got {type(self.measurement).__name__} of "
                                 f"shape {table.shape}")
        put("dt", _number("dt", self.dt, POSITIVE))
        world = np.asarray(self.world, dtype=object).reshape(-1)
        if world.shape != (2,):
            raise ValueError(f"world must be (W, H), got {self.world!r}")
        put("world", (_number("world[0] (W)", world[0], POSITIVE),
                      _number("world[1] (H)", world[1], POSITIVE)))
        put("process_noise", _number("process_noise", self.process_noise, Range(0.0, None)))
        if self.motion is not None:
            try:
                F, Q = (np.asarray(a, dtype=float) for a in self.motion)
            except (TypeError, ValueError):
                raise ValueError(f"motion must be (F, Q), two (4, 4) arrays, got "
                                 f"{self.motion!r}") from None
            if F.shape != (4, 4) or Q.shape != (4, 4) or not (
                    np.all(np.isfinite(F)) and np.all(np.isfinite(Q))):
                raise ValueError(f"motion must be (F, Q), two finite (4, 4) arrays, got shapes "
                                 f"{F.shape} and {Q.shape}")
            put("motion", (_frozen(F), _frozen(Q)))
        put("resolution", _number("resolution", self.resolution, POSITIVE))
        put("velocity_var", _number("velocity_var", self.velocity_var, POSITIVE))
        if self.speed_range is not None:
            sr = np.asarray(self.speed_range, dtype=object).reshape(-1)
            if sr.shape != (2,):
                raise ValueError(f"speed_range must be (lo, hi), got {self.speed_range!r}")
            lo = _number("speed_range[0]", sr[0], Range(0.0, None))
            hi = _number("speed_range[1]", sr[1], Range(0.0, None))
            if hi < lo:
                raise ValueError(f"speed_range must have lo <= hi, got {self.speed_range!r}")
            put("speed_range", (lo, hi))
        put("gate_probability", _number("gate_probability", self.gate_probability,
                                        Range(0.0, 1.0, lo_open=True, hi_open=True)))
        if self.map_edge is not None and self.map_edge not in MAP_EDGES:
            raise ValueError(f"map_edge must be one of {MAP_EDGES} or None, "
                             f"got {self.map_edge!r}")
        if self.buildings is not None:
            b = np.asarray(self.buildings, dtype=float)
            if b.ndim != 2 or b.shape[1] != 5 or not np.all(np.isfinite(b)):
                raise ValueError(f"buildings must be finite (K, 5) rows x0, y0, x1, y1, height, "
                                 f"got shape {b.shape}")
            if len(b) and isinstance(self.measurement, LinearSensor):
                raise ValueError("buildings must be None with a linear sensor (it sees through "
                                 f"buildings), got {len(b)}")
            put("buildings", _frozen(b))

    def grid(self) -> undetected.Grid:
        """The grid of cells over the map (:func:`~.undetected.make_grid`)."""
        return undetected.make_grid(*self.world, self.resolution, self.velocity_var)


class MapTracker:
    """The base of a multi-target tracker of the map: its :class:`MapModel` and what it
    derives once from it.

    Parameters
    ----------
    model : MapModel

    Attributes
    ----------
    model : MapModel
    F, Q : (4, 4)         the motion model's matrices over one step
    sensing : Sensing     the sensors' detection and measurement model, with the buildings
    gate : float          the chi-square(2) gate of ``model.gate_probability``
    grid : Grid           the cells over the map (``model.grid()``)
    dt, world, process_noise, gate_probability, map_edge
        the model's fields
    """

    def __init__(self, model: MapModel) -> None:
        if not isinstance(model, MapModel):
            raise TypeError(f"model must be a MapModel, got {type(model).__name__}")
        self.model = model
        # The model's fields, where the trackers and their callers read them.
        self.dt, self.world, self.process_noise = model.dt, model.world, model.process_noise
        self.gate_probability, self.map_edge = model.gate_probability, model.map_edge
        self.F, self.Q = motion_matrices(model.dt, model.process_noise, model.motion)
        self.sensing = make_sensing(model.measurement, model.buildings)
        self.gate = gate_threshold(model.gate_probability)
        self.grid = model.grid()
        self._cell_means, self._cell_covs = self.grid.cell_states()


def looks_in_order(looks: Looks) -> Iterator[tuple[Look, FloatArray]]:
    """Each look of one step's ``looks``, in the given (sensor) order, with its detections
    ``(m, 2)``; the looks' aims are not used."""
    for n in range(len(looks.sensors)):
        look = Look(int(looks.sensors[n]), np.asarray(looks.positions[n], dtype=float),
                    float(looks.headings[n]))
        yield look, np.asarray(looks.detections[n], dtype=float).reshape(-1, 2)


__all__ = ["MapModel", "MapTracker", "looks_in_order"]
