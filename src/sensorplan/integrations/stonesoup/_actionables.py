"""Actionable Stone Soup types: lattice-moving platforms and the aimable radar."""

from __future__ import annotations

import datetime
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from stonesoup.base import Property
from stonesoup.movable import FixedMovable
from stonesoup.movable.action.move_position_action import MovePositionAction
from stonesoup.sensor.sensor import Sensor
from stonesoup.sensormanager.action import Action, ActionableProperty, ActionGenerator
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Clutter, TrueDetection
from stonesoup.types.state import State
from stonesoup.types.track import Track

from ..._types import FloatArray
from ...errors import ConfigError
from ...models import radar
from ...models.angles import heading_rule, wrap_angle
from ...models.motion import cv_matrices
from ...models.sensors import CLUTTER_RATE, SensorParams, radar_table
from ...planners.problem import POSITION_TOL, move_vectors
from ...planners.search import HEADING_TOL, distinct_headings, sector_bearings

from ._convert import _ground_xy, from_tracks, ordered_tracks
from ._detection import clutter_density, detection_probability, draw_clutter, is_swerling
from ._measurement import RadarMeasurementModel, noise_source
from ._world import DEFAULT_WORLD, MapRect, as_world

#: Largest difference (m) between a radar's height on its platform and ``params.altitude``.
ALTITUDE_TOL = 1e-6

# --------------------------------------------------------------------------------------------
# Platform movement: the lattice moves
# --------------------------------------------------------------------------------------------


class LatticeMoveAction(MovePositionAction):
    """Move the platform to ``target_value``: move ``move_index`` of the move order."""

    move_index: int = Property(default=0, doc="Index of the move (0 = stay).")


class LatticeMoveActionGenerator(ActionGenerator):
    """The lattice moves (stay, then 8 directions per distance) that end inside the map."""

    move_distances: Sequence[float] = Property(default=(20.0, 40.0),
                                               doc="Move distances s (m).")
    world: MapRect = Property(default=DEFAULT_WORLD,
                              doc="The map (world coordinates); its edge is inside.")
    ground_mapping: Sequence[int] = Property(
        default=(0, 1), doc="Indices of ground x and y in the platform position.")

    def _targets(self) -> tuple[FloatArray, FloatArray]:
        """Every move's end position (in position order) and whether it is inside the map."""
        cur = np.asarray(self.current_value, dtype=float).ravel()
        moves = move_vectors(tuple(self.move_distances))
        ends = np.tile(cur, (len(moves), 1))
        ends[:, self.ground_mapping[0]] += moves[:, 0]
        ends[:, self.ground_mapping[1]] += moves[:, 1]
        ground = ends[:, list(self.ground_mapping)]
        return ends, self.world.contains(ground)

    def action_for_move(self, move_index: int) -> LatticeMoveAction:
        """The action of one move (raises ``ValueError`` if it leaves the map)."""
        ends, inside = self._targets()
        if not inside[move_index]:
            raise ValueError(f"move {move_index} leaves the map")
        return LatticeMoveAction(generator=self, end_time=self.end_time,
                                 target_value=StateVector(ends[move_index]),
                                 move_index=int(move_index))

    def action_from_value(self, value: Any) -> LatticeMoveAction | None:
        """The action reaching ground position ``value`` (``(2,)``, or a full position), or
        None when no move inside the map reaches it within 1e-6 m."""
        v = np.asarray(value, dtype=float).ravel()
        ground = v[list(self.ground_mapping)] if v.size > 2 else v[:2]
        ends, inside = self._targets()
        d = np.abs(ends[:, list(self.ground_mapping)] - ground).max(axis=1)
        hits = np.flatnonzero(inside & (d <= 10 * POSITION_TOL))
        return self.action_for_move(int(hits[0])) if hits.size else None

    @property
    def default_action(self) -> LatticeMoveAction:
        return self.action_for_move(0)

    def __iter__(self) -> Any:
        ends, inside = self._targets()
        for m in np.flatnonzero(inside):
            yield LatticeMoveAction(generator=self, end_time=self.end_time,
                                    target_value=StateVector(ends[m]), move_index=int(m))

    def __contains__(self, item: Any) -> bool:
        if isinstance(item, MovePositionAction):
            item = item.target_value
        return self.action_from_value(item) is not None


def _float_vector(v: Any) -> StateVector:
    """A float64 copy of a state vector."""
    return StateVector(np.array(v, dtype=float))


class LatticeMovable(FixedMovable):
    """A platform movement controller whose actions are the lattice moves inside the map.

    Use it as the ``movement_controller`` of a Stone Soup ``FixedPlatform``. The position is
    3-D ``[x, y, z]`` by default (``position_mapping=(0, 1, 2)``); moves change x and y. A
    move takes effect at the platform's next ``act``; with no action the platform stays.

    ``world`` is the map in world coordinates, a :class:`MapRect` ``(x0, y0, width, height)``
    with any origin (``MapRect(-500, -500, 1000, 1000)`` is centred on 0). Without one it is
    ``DEFAULT_WORLD``, the paper's ``[0, 600] x [0, 600]``. A core
    ``sensorplan.planners.problem.MapRect(W, H)`` is taken as ``[0, W] x [0, H]``.
    """

    move_distances: Sequence[float] = Property(default=(20.0, 40.0),
                                               doc="Move distances s (m).")
    world: MapRect = Property(default=DEFAULT_WORLD,
                              doc="The map in world coordinates; default [0, 600] x [0, 600].")

    @world.setter  # type: ignore[no-redef]  # Stone Soup's Property idiom
    def world(self, value: Any) -> None:
        self._property_world = as_world(value)

    @property
    def world_is_default(self) -> bool:
        """Whether the map is the default one (no ``world`` given)."""
        return self.world is DEFAULT_WORLD

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # Integer positions (State([[300], [300], [490]])) would truncate planned moves.
        self.state.state_vector = _float_vector(self.state.state_vector)
        self._next_action: Action | None = None

    @property
    def ground_position(self) -> FloatArray:
        """Ground position ``(2,)`` (m)."""
        return np.asarray(self.position, dtype=float).ravel()[:2]

    def actions(self, timestamp: datetime.datetime,
                start_timestamp: datetime.datetime | None = None) -> set[ActionGenerator]:
        start = start_timestamp if start_timestamp is not None else self.state.timestamp
        return {LatticeMoveActionGenerator(owner=self, attribute="position", start_time=start,
                                           end_time=timestamp,
                                           move_distances=tuple(self.move_distances),
                                           world=self.world)}

    def add_actions(self, actions: Sequence[Action]) -> bool:
        self._next_action = actions[0] if len(actions) else None
        return True

    def act(self, timestamp: datetime.datetime, *args: Any, **kwargs: Any) -> None:
        self.move(timestamp)

    def move(self, timestamp: datetime.datetime, **kwargs: Any) -> None:
        new_state = State.from_state(self.state, timestamp=timestamp)
        new_state.state_vector = _float_vector(new_state.state_vector)
        self.states.append(new_state)
        if self._next_action is not None:
            self.position = self._next_action.target_value
        self._next_action = None


# --------------------------------------------------------------------------------------------
# The radar as an actionable Stone Soup sensor
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SearchSector:
    """Search sector ``index`` of ``count``: the absolute bearing ``wrap(2 pi index /
    count)`` (rad) around the radar's platform; the ``target`` of a sector look."""

    index: int
    count: int

    @property
    def bearing(self) -> float:
        """The sector's absolute bearing (rad)."""
        return float(sector_bearings(self.count)[self.index])


class AimAction(Action):
    """Look at ground point ``target_value`` ``(x, y)``; ``target`` names what is there
    (a track, or any key).

    A search look (``target`` a :class:`SearchSector`) also sets ``bearing``: the radar
    turns toward that absolute bearing, wherever its platform moves; ``target_value`` is then
    a point on the sector's boresight, for display.

    With ``hold=True`` the radar keeps its aim, its aimed target and its heading (no turn):
    the generator's ``default_action``, and what :class:`SensorplanManager` returns when there
    is no track and search is off.
    """

    target: Any = Property(default=None, doc="The target looked at (e.g. its Track, or a "
                                             "SearchSector).")
    hold: bool = Property(default=False, doc="Keep the current aim and heading.")
    bearing: float | None = Property(default=None, doc="Absolute bearing (rad) to turn "
                                                       "toward instead of the point's.")

    def act(self, current_time: Any, timestamp: Any, init_value: Any, **kwargs: Any) -> Any:
        return self.target_value


class AimActionGenerator(ActionGenerator):
    """One :class:`AimAction` per candidate ``(target, (x, y))`` of the radar, then one per
    distinct search look: of the radar's ``sectors`` bearings, those the heading rule (from
    the radar's heading now, at most ``max_turn``) maps to the same heading are one action,
    the first sector of each."""

    candidates: Sequence[Any] = Property(default=(), doc="``(target, (x, y))`` pairs.")
    sectors: int = Property(default=0, doc="Number of search sectors (0: no search looks).")

    def sector_action(self, index: int) -> AimAction:
        """The search look at sector ``index``: turn toward its bearing."""
        sector = SearchSector(int(index), int(self.sectors))
        b = sector.bearing
        xy = self.owner.ground_position
        reach = float(self.owner.params.max_ground_range)
        point = (float(xy[0] + reach * math.cos(b)), float(xy[1] + reach * math.sin(b)))
        return AimAction(generator=self, end_time=self.end_time, target_value=point,
                         target=sector, bearing=b)

    def distinct_sectors(self) -> list[int]:
        """The sectors that are distinct actions, ascending."""
        if int(self.sectors) <= 0:
            return []
        h = heading_rule(float(self.owner.heading), sector_bearings(int(self.sectors)),
                         float(self.owner.params.max_turn))
        return [int(s) for s in distinct_headings(h)]

    def action(self, point: Any, target: Any = None) -> AimAction:
        """An aim action at ``point`` ``(x, y)`` for ``target``."""
        p = np.asarray(point, dtype=float).ravel()
        return AimAction(generator=self, end_time=self.end_time,
                         target_value=(float(p[0]), float(p[1])), target=target)

    @property
    def default_action(self) -> AimAction:
        """Hold: keep the aim and the heading (no turn)."""
        return AimAction(generator=self, end_time=self.end_time,
                         target_value=self.current_value, target=self.owner.aim_target,
                         hold=True)

    def __iter__(self) -> Any:
        for target, point in self.candidates:
            yield self.action(point, target)
        for s in self.distinct_sectors():
            yield self.sector_action(s)

    def __contains__(self, item: Any) -> bool:
        if isinstance(item, AimAction):
            if item.hold:
                return True
            if item.bearing is not None:
                b = sector_bearings(int(self.sectors))
                return bool(np.any(np.abs(wrap_angle(b - item.bearing)) <= HEADING_TOL))
            item = item.target_value
        p = np.asarray(item, dtype=float).ravel()
        return any(np.allclose(p, np.asarray(q, dtype=float), rtol=0, atol=10 * POSITION_TOL)
                   for _, q in self.candidates)


class SensorplanRadar(Sensor):
    r"""sensorplan's radar as an actionable Stone Soup sensor.

    Mount it on a Stone Soup platform (a ``FixedPlatform`` with a :class:`LatticeMovable` to
    let :class:`SensorplanManager` move it); its ground position is the platform's x, y and
    its altitude is ``params.altitude``. A platform with a height (a 3-D position, as
    ``position_mapping=(0, 1, 2)`` gives) must carry the radar at that altitude: the
    platform's z plus the mounting offset's must equal ``params.altitude`` (to 1e-6 m), or
    every use of the radar (:meth:`measure`, its measurement model, field of view, detection
    and clutter) raises a :class:`~sensorplan.errors.ConfigError` naming
    ``params.altitude``. A 2-D platform has no height: ``params.altitude`` alone counts.

    Pointing. The actionable property is :attr:`aim`, a ground point. When the radar acts on
    a new :class:`AimAction` it turns toward that point by at most ``params.max_turn``
    (the heading rule), from the heading it had, *seen from the platform's position at the
    time of the first use after the act* (a measurement, or reading :attr:`heading`). The turn
    is resolved lazily because Stone Soup acts platforms and sensors in no fixed order: in a
    loop that acts every actionable before measuring, the turn is seen from the new position,
    as sensorplan's closed loop executes it. The heading then stays fixed until the next aim action.
    A search look (an aim whose ``bearing`` is set, at a :class:`SearchSector`) turns toward
    that absolute bearing instead, from wherever the platform is; ``search_sectors`` offers
    them to Stone Soup's sensor managers beside the track aims.

    Field of view: ground range in ``[min_ground_range, max_ground_range]``, azimuth within
    ``fov_half_angle`` of the heading, ``cos psi > 0``, from the one radar model
    (:func:`sensorplan.models.radar.measure_looks`).

    Detection (``params.detection``, ``params.clutter_rate``): with ``"swerling1"`` a target
    in view is detected with probability :meth:`detection_probability` (else nothing is
    reported for it: a missed detection); with ``clutter_rate > 0`` each :meth:`measure`
    call (one look) also reports Poisson(``clutter_rate``) false alarms as Stone Soup
    ``Clutter``, uniform in ground area over the sensing region. :meth:`clutter_spatial_density`
    gives their density in the measurement space, for Stone Soup's ``PDAHypothesiser``. The
    defaults (``"ideal"``, no clutter) report every target in view and nothing else, and draw
    nothing but the measurement noise. Clutter comes from ``params`` (the radar has no Stone
    Soup ``clutter_model``).

    Randomness, as in Stone Soup: :meth:`measure` draws (noise, detection outcomes, false
    alarms) from ``rng`` when given, else from the radar's own generator when ``seed`` is set
    (``numpy.random.default_rng(seed)``, one stream for the radar's life), else from NumPy's
    global state. So ``np.random.seed(1990)`` at the top of a script makes the detections
    repeatable, like Stone Soup's own sensors and models.

    Truths may have any state layout whose ground x and y sit at ``position_mapping``
    (``(0, 2)`` fits ``[x, vx, y, vy]`` and ``[x, vx, y, vy, z, vz]``); each detection's
    measurement model has the truth's dimension.
    """

    params: SensorParams = Property(default_factory=SensorParams, doc="Radar parameters.")
    heading: float = Property(default=0.0, doc="Heading theta (rad).")
    aim: Any = ActionableProperty(
        generator_cls=AimActionGenerator,
        generator_kwargs_mapping={"candidates": "aim_candidates", "sectors": "search_sectors"},
        default=None, doc="Ground point ``(x, y)`` the radar looks toward, or None.")
    aim_candidates: Sequence[Any] = Property(
        default=(), doc="``(target, (x, y))`` pairs offered to Stone Soup's sensor managers as "
                        "aim actions (see :func:`set_aim_candidates`).")
    search_sectors: int = Property(
        default=0, doc="Search sectors S: absolute bearings 2 pi s / S around the platform "
                       "offered as search looks (0: none).")
    ndim_state: int = Property(default=4, doc="Target state dimension.")
    position_mapping: Sequence[int] = Property(
        default=(0, 2), doc="Indices of a target's ground x and y in its state vector.")
    seed: int | None = Property(
        default=None, doc="Seed of the radar's own noise generator (setting it restarts "
                          "the generator); None: NumPy's global state (seed it with "
                          "np.random.seed), as in Stone Soup.")

    @seed.setter  # type: ignore[no-redef, union-attr]  # Stone Soup's Property idiom
    def seed(self, value: int | None) -> None:
        self._property_seed = value
        #: The radar's own generator (from ``seed``), or None: NumPy's global state.
        self.rng = None if value is None else np.random.default_rng(value)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending = False
        self.aim_target: Any = None
        self.aim_bearing: float | None = None

    @heading.getter  # type: ignore[no-redef, attr-defined]  # Stone Soup's Property idiom
    def heading(self) -> float:
        self._resolve()
        return self._property_heading

    def _resolve(self) -> None:
        """Apply the pending turn toward :attr:`aim` from the current position."""
        if not self._pending:
            return
        self._pending = False
        aim = self._property_aim
        if aim is None:
            return
        xy = self.ground_position
        bearing = (self.aim_bearing if self.aim_bearing is not None
                   else math.atan2(aim[1] - xy[1], aim[0] - xy[0]))
        self._property_heading: float = float(heading_rule(self._property_heading, bearing,
                                                           self.params.max_turn))

    @property
    def ground_position(self) -> FloatArray:
        """Ground position ``(2,)`` of the radar (its platform's x, y plus mounting offset)."""
        return np.asarray(self.position, dtype=float).ravel()[:2]

    def check_altitude(self, field: str = "params.altitude") -> None:
        """Raise a :class:`~sensorplan.errors.ConfigError` naming ``field`` when the radar
        sits at a height (its platform's z plus the mounting offset's) other than
        ``params.altitude``: the radar model measures from ``params.altitude``, so a
        platform flying elsewhere would be measured from the wrong height, silently.
        Nothing to check on a 2-D platform or without one."""
        position = self.position
        if position is None:
            return
        p = np.asarray(position, dtype=float).ravel()
        if p.size < 3:
            return
        z, altitude = float(p[2]), float(self.params.altitude)
        if not abs(z - altitude) <= ALTITUDE_TOL:
            raise ConfigError(field, f"is {altitude:g} m, but the radar is at z = {z:g} m "
                                     f"(its platform's z plus the mounting offset); the radar "
                                     f"measures from params.altitude, so make them equal: "
                                     f"SensorParams(altitude={z:g}), or the platform at "
                                     f"z = {altitude:g}")

    def act(self, timestamp: datetime.datetime, **kwargs: Any) -> None:
        if not self.validate_timestamp():
            self.timestamp = timestamp
            return
        action = self.scheduled_actions.pop("aim", None)
        if action is not None and action.hold:
            self._resolve()          # the previous aim's turn, if never used, still happens
        elif action is not None:
            self._resolve()          # the previous aim's turn, if never used, happens first
            self._property_aim = tuple(float(v) for v in action.target_value)
            self.aim_target = action.target
            self.aim_bearing = None if action.bearing is None else float(action.bearing)
            self._pending = True
        self.timestamp = timestamp

    @property
    def measurement_model(self) -> RadarMeasurementModel:
        """The measurement model at the radar's current pose."""
        return self.measurement_model_for(self.ndim_state)

    def measurement_model_for(self, ndim_state: int) -> RadarMeasurementModel:
        """The measurement model at the radar's current pose for states of ``ndim_state``
        entries (the ground position at ``position_mapping``)."""
        self.check_altitude()
        return RadarMeasurementModel(ndim_state=int(ndim_state),
                                     mapping=tuple(self.position_mapping),
                                     sensor_xy=tuple(self.ground_position),
                                     heading=self.heading, params=self.params)

    def is_detectable(self, state: Any, measurement_model: Any = None) -> bool:
        """Whether the state's ground position is in the field of view."""
        self.check_altitude()
        xy = _ground_xy(state, self.position_mapping)
        seen = radar.measure_looks(radar_table(self.params), 0, xy, self.ground_position,
                                   self.heading)[3]
        return bool(np.all(seen))

    def detection_probability(self, state: Any) -> float:
        """Probability ``Pd`` that a look detects a target at the state's ground position when
        it is in view, from the radar's current position (1 with ``"ideal"`` detection).

        The value :meth:`measure` uses for a truth; at a track's predicted state it is the
        ``prob_detect`` of Stone Soup's ``PDAHypothesiser``. The field of view is not part of
        it (see :meth:`is_detectable`).
        """
        self.check_altitude()
        xy = _ground_xy(state, self.position_mapping)
        if xy.shape[0] != 1:
            raise ValueError("detection_probability takes one state")
        return detection_probability(radar_table(self.params), xy[0], self.ground_position)

    def clutter_spatial_density(self, state: Any = None) -> float:
        r"""Density of the false alarms in the measurement space ``(r, phi)``, 1/(m rad).

        ``clutter_rate`` false alarms uniform in ground area over the sensing region of area
        ``A = fov_half_angle * (max_ground_range^2 - min_ground_range^2)`` have the density
        ``rho = clutter_rate * r / A`` at slant range ``r``: at the state's slant range from
        the radar when ``state`` is given (the ``clutter_spatial_density`` of Stone Soup's
        ``PDAHypothesiser`` for a track's predicted state), else at the middle slant range
        ``(r_min + r_max) / 2``, which is the region's average ``clutter_rate /
        (2 fov_half_angle (r_max - r_min))`` (a constant approximation). 0 without clutter.
        """
        self.check_altitude()
        r = None
        if state is not None:
            xy = _ground_xy(state, self.position_mapping)
            if xy.shape[0] != 1:
                raise ValueError("clutter_spatial_density takes one state")
            r = float(np.hypot(np.hypot(*(xy[0] - self.ground_position)),
                               float(self.params.altitude)))
        return clutter_density(radar_table(self.params), r)

    def measure(self, ground_truths: Iterable[Any], noise: Any = True,
                rng: np.random.Generator | None = None,
                timestamp: datetime.datetime | None = None,
                **kwargs: Any) -> set[TrueDetection | Clutter]:
        """One look: detections of the ground truths in the field of view, and false alarms.

        Draws, in this order (from ``rng``, else the radar's own generator from ``seed``,
        else NumPy's global state; see the class docstring):

        1. per truth in view, in the iteration order of ``ground_truths``: with
           ``"swerling1"`` detection one uniform ``u`` (detected iff ``u < Pd``, see
           :meth:`detection_probability`); then, if detected, its noise ``N(0, R)`` with
           ``R`` at the true state;
        2. with ``clutter_rate > 0``: the number of false alarms ``~ Poisson(clutter_rate)``,
           their positions (uniform in ground area over the sensing region) and their noise
           (``R`` at each position). Those in the field of view are returned as Stone Soup
           ``Clutter`` carrying the radar's measurement model, at the first truth's
           ``timestamp`` (else ``timestamp``, else the radar's last ``act`` time).

        ``noise``: True draws the noise; False adds none (and draws none); an array is added
        as is to the truths' measurements (see :meth:`RadarMeasurementModel.scaled_noise`)
        while false alarms draw theirs. With the defaults (``"ideal"``, no clutter) the only
        draws are the truths' noise. For reproducible draws pass a list (or a single truth,
        a dwell on one target) rather than a set.
        """
        self.check_altitude()
        truths = list(ground_truths)
        table = radar_table(self.params)
        swerling = is_swerling(table)
        models: dict[int, RadarMeasurementModel] = {}
        gen = noise_source(rng, self.rng)
        detections: set[TrueDetection | Clutter] = set()
        for truth in truths:
            if not self.is_detectable(truth):
                continue
            if swerling:
                xy = _ground_xy(truth, self.position_mapping)[0]
                if not gen.random() < detection_probability(table, xy, self.ground_position):
                    continue                                  # a missed detection
            model = self._model_of(models, int(np.shape(truth.state_vector)[0]))
            if noise is True:
                e = model.rvs(state=truth, random_state=gen)
            elif noise is False or noise is None:
                e = 0.0
            else:
                e = noise
            z = model.function(truth, noise=False) + e
            detections.add(TrueDetection(z, measurement_model=model, timestamp=truth.timestamp,
                                         groundtruth_path=truth))
        if table[0, CLUTTER_RATE] > 0.0:
            ndim = int(np.shape(truths[0].state_vector)[0]) if truths else int(self.ndim_state)
            when = truths[0].timestamp if truths else (timestamp or self.timestamp)
            detections |= draw_clutter(table, self.ground_position, self.heading, gen,
                                       noise is not False and noise is not None,
                                       self._model_of(models, ndim), when)
        return detections

    def _model_of(self, models: dict[int, RadarMeasurementModel],
                  ndim: int) -> RadarMeasurementModel:
        """One measurement model per state dimension within a look."""
        if ndim not in models:
            models[ndim] = self.measurement_model_for(ndim)
        return models[ndim]


def set_aim_candidates(radars: Iterable[SensorplanRadar], tracks: Iterable[Track],
                       dt: float, position_mapping: Sequence[int] | None = None,
                       velocity_mapping: Sequence[int] | None = None) -> None:
    """Offer every track as an aim to each radar, for Stone Soup's own sensor managers.

    The aim point is the track's mean predicted one step ``dt`` ahead (the point our
    planners aim at in the first step of an epoch). The candidate's target is the
    Track itself. The mappings locate the ground position and velocity in the tracks' states
    (see :func:`ground_index`; 4-D and 6-D constant-velocity states need none).
    """
    tracks = ordered_tracks(tracks)
    F, _ = cv_matrices(dt, 0.0)
    means, _ = from_tracks(tracks, position_mapping, velocity_mapping)
    aims = (means @ F.T)[:, :2]
    cands = tuple((t, (float(a[0]), float(a[1]))) for t, a in zip(tracks, aims))
    for rad in radars:
        rad.aim_candidates = cands
