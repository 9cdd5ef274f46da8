r"""Stone Soup interop: our radar, platforms and planners inside a Stone Soup tracking loop.

Install with the extra ``sensorplan[stonesoup]``. Only this module imports Stone Soup.

What is here (``docs/stonesoup.md`` has the full mapping and its limits):

- **Converters**, exact both ways: Stone Soup orders a target state ``[x, vx, y, vy]``,
  sensorplan ``[x, y, vx, vy]``; :func:`to_stonesoup_mean`, :func:`to_stonesoup_cov`,
  :func:`to_gaussian_state`, :func:`to_tracks` and their inverses permute entries, nothing
  else.
- :class:`RadarMeasurementModel`: the radar of SPEC 2 as a Stone Soup measurement model
  (slant range with altitude, azimuth, SNR-dependent noise): ``function``, an analytic
  ``jacobian`` and ``covar`` evaluated at a state, so Stone Soup's ``ExtendedKalmanUpdater``
  runs on it.
- Actionables: :class:`LatticeMovable` (a platform movement controller whose actions are
  the SPEC 2 moves inside the map) and :class:`SensorplanRadar` (the radar, mounted on such a
  platform, whose action is *where to look*: an :class:`AimAction` with a ground point; the
  heading then follows the SPEC 2 heading rule from the platform's position).
- :class:`SensorplanManager`: a Stone Soup ``SensorManager`` that turns the tracks and the
  actionables into a :class:`~sensorplan.problem.PlanningProblem`, runs any registered
  planner (rolling horizon: every call plans K epochs and returns the first) and returns
  Stone Soup actions.
- :class:`MutualInformationReward`: a reward for Stone Soup's own sensor managers
  (brute force, greedy, MCTS) that is our one-step objective with ``visibility = "mean"``:
  the sum over tracks of ``0.5 log det P_prior / det P_post`` after Stone Soup's predictor
  and updater apply every look whose target's predicted mean is in the field of view.

Timing convention (Stone Soup's): ``choose_actions(tracks, timestamp)`` receives tracks at
time ``t0`` and returns actions that end at ``timestamp``; the actionables ``act`` at the
start of the epoch, then measure. The planning problem's time 0 is ``t0`` and its step is
the manager's ``dt``.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from stonesoup.base import Property
from stonesoup.models.base import GaussianModel, ReversibleModel
from stonesoup.models.measurement.base import MeasurementModel
from stonesoup.movable import FixedMovable
from stonesoup.movable.action.move_position_action import MovePositionAction
from stonesoup.platform import Platform
from stonesoup.predictor import Predictor
from stonesoup.sensor.sensor import Sensor
from stonesoup.sensormanager.action import Action, ActionableProperty, ActionGenerator
from stonesoup.sensormanager.base import SensorManager
from stonesoup.sensormanager.reward import RewardFunction
from stonesoup.types.angle import Bearing
from stonesoup.types.array import CovarianceMatrix, StateVector, StateVectors
from stonesoup.types.detection import Detection, TrueDetection
from stonesoup.types.groundtruth import GroundTruthState
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState, State
from stonesoup.types.track import Track
from stonesoup.updater import Updater

from .._types import FloatArray
from ..angles import heading_rule, wrap_angle
from ..dynamics import cv_matrices
from ..planners import PlanResult, make_planner
from ..problem import POSITION_TOL, MapRect, PlanningProblem, move_vectors
from ..sensors import SensorParams, jacobian, measure, noise_cov, visible

# --------------------------------------------------------------------------------------------
# Converters
# --------------------------------------------------------------------------------------------

#: ``STONESOUP_ORDER[k]`` is the sensorplan index of Stone Soup state entry k:
#: Stone Soup ``[x, vx, y, vy]`` = sensorplan ``[x, y, vx, vy]`` taken at ``(0, 2, 1, 3)``.
#: The permutation is its own inverse, so the same index converts both ways.
STONESOUP_ORDER = (0, 2, 1, 3)
_ORDER = np.array(STONESOUP_ORDER)


def to_stonesoup_mean(x: Any) -> FloatArray:
    """Reorder states ``(..., 4)`` from ``[x, y, vx, vy]`` to Stone Soup's ``[x, vx, y, vy]``."""
    return np.asarray(x, dtype=float)[..., _ORDER]


def from_stonesoup_mean(v: Any) -> FloatArray:
    """Reorder states ``(..., 4)`` from Stone Soup's ``[x, vx, y, vy]`` to ``[x, y, vx, vy]``."""
    return np.asarray(v, dtype=float)[..., _ORDER]


def to_stonesoup_cov(P: Any) -> FloatArray:
    """Reorder covariances ``(..., 4, 4)`` (rows and columns) to Stone Soup's state order."""
    P = np.asarray(P, dtype=float)
    return P[..., _ORDER, :][..., :, _ORDER]


def from_stonesoup_cov(P: Any) -> FloatArray:
    """Reorder covariances ``(..., 4, 4)`` from Stone Soup's state order to ours."""
    return to_stonesoup_cov(P)


def to_gaussian_state(mean: Any, cov: Any,
                      timestamp: datetime.datetime | None = None) -> GaussianState:
    """A Stone Soup ``GaussianState`` from a mean ``(4,)`` and covariance ``(4, 4)`` (ours)."""
    return GaussianState(StateVector(to_stonesoup_mean(np.reshape(mean, 4))),
                         CovarianceMatrix(to_stonesoup_cov(cov)), timestamp=timestamp)


def from_gaussian_state(state: Any) -> tuple[FloatArray, FloatArray]:
    """Mean ``(4,)`` and covariance ``(4, 4)`` in our order from a Stone Soup Gaussian state."""
    sv = np.asarray(state.state_vector, dtype=float).reshape(4)
    return from_stonesoup_mean(sv), from_stonesoup_cov(np.asarray(state.covar, dtype=float))


def to_tracks(means: Any, covs: Any, timestamp: datetime.datetime | None = None) -> list[Track]:
    """One Stone Soup ``Track`` per target, each holding one ``GaussianState``.

    Parameters
    ----------
    means : (M, 4)   ``[x, y, vx, vy]``
    covs : (M, 4, 4)
    timestamp : datetime, optional

    Returns
    -------
    list of M tracks, in target order.
    """
    means = np.asarray(means, dtype=float)
    covs = np.broadcast_to(np.asarray(covs, dtype=float), means.shape + (4,))
    return [Track([to_gaussian_state(m, P, timestamp)]) for m, P in zip(means, covs)]


def from_tracks(tracks: Iterable[Any]) -> tuple[FloatArray, FloatArray]:
    """Means ``(M, 4)`` and covariances ``(M, 4, 4)`` (ours) of the tracks' latest states.

    The order is the iteration order of ``tracks``; see :func:`ordered_tracks` for sets.
    """
    pairs = [from_gaussian_state(t.state if isinstance(t, Track) else t) for t in tracks]
    if not pairs:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def ordered_tracks(tracks: Iterable[Track]) -> list[Track]:
    """Tracks as a list: a list or tuple keeps its order, any other iterable (a ``set``,
    Stone Soup's usual container) is sorted by ``track.id`` so the order never depends on
    hashing."""
    if isinstance(tracks, (list, tuple)):
        return list(tracks)
    return sorted(tracks, key=lambda t: str(getattr(t, "id", "")))


def to_ground_truth_state(x: Any, timestamp: datetime.datetime | None = None,
                          metadata: Mapping[str, Any] | None = None) -> GroundTruthState:
    """A Stone Soup ``GroundTruthState`` from a true state ``(4,)`` in our order."""
    return GroundTruthState(StateVector(to_stonesoup_mean(np.reshape(x, 4))),
                            timestamp=timestamp, metadata=dict(metadata or {}))


def _ground_xy(state: Any, mapping: Sequence[int]) -> FloatArray:
    """Ground positions ``(n, 2)`` of a Stone Soup state, state vector(s) or array."""
    sv = state.state_vector if hasattr(state, "state_vector") else state
    arr = np.asarray(sv, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    return np.stack([arr[mapping[0], :], arr[mapping[1], :]], axis=-1)


# --------------------------------------------------------------------------------------------
# Measurement model
# --------------------------------------------------------------------------------------------


class RadarMeasurementModel(MeasurementModel, GaussianModel, ReversibleModel):
    r"""The SPEC 2 radar as a Stone Soup measurement model: ``z = [r, phi]``.

    .. math::
        r = \sqrt{dx^2 + dy^2 + z_i^2},\quad \phi = \operatorname{atan2}(dy, dx),\quad
        R = \operatorname{diag}(\sigma_r^2, \sigma_\phi^2)

    with the SNR-dependent standard deviations of :func:`sensorplan.sensors.noise_std`.
    The measurement order is ours, range first (Stone Soup's own ``CartesianToBearingRange``
    puts the bearing first); the azimuth entry is a Stone Soup ``Bearing``, so innovations
    are wrapped by Stone Soup's updaters.

    ``R`` depends on the target's state. :meth:`covar` evaluates it at ``state`` when given,
    otherwise at the state of the latest :meth:`jacobian` call, which is where Stone Soup's
    ``ExtendedKalmanUpdater`` linearises (it calls ``jacobian(prediction)`` before every
    ``covar()``): the filter's ``R`` is therefore taken at its predicted state, as SPEC 2
    says.

    The field of view is not part of a measurement model; :class:`SensorplanRadar` applies it.
    """

    ndim_state: int = Property(default=4, doc="Number of target state dimensions.")
    mapping: Sequence[int] = Property(
        default=(0, 2), doc="Indices of the target's ground x and y in the state vector "
                            "(Stone Soup order ``[x, vx, y, vy]``: ``(0, 2)``).")
    sensor_xy: Sequence[float] = Property(doc="Ground position ``(x, y)`` of the platform (m).")
    heading: float = Property(default=0.0, doc="Platform heading theta (rad); enters R "
                                               "through the boresight angle psi.")
    params: SensorParams = Property(default_factory=SensorParams,
                                    doc="Radar parameters (altitude, SNR model, ...).")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.sensor_xy = tuple(float(v) for v in np.asarray(self.sensor_xy, float).ravel()[:2])
        self._linearised_at: FloatArray | None = None
        self._rng = np.random.default_rng(self.seed)

    @property
    def ndim_meas(self) -> int:
        return 2

    def function(self, state: Any, noise: Any = False, **kwargs: Any) -> StateVector:
        """``[r, phi]`` of a state (``StateVector``) or states (``StateVectors``, one column
        each). ``noise=True`` adds a draw from ``N(0, R)`` with ``R`` at each state."""
        xy = _ground_xy(state, self.mapping)                                    # (n, 2)
        z = measure(xy, np.array(self.sensor_xy), self.params.altitude).T       # (2, n)
        if noise is True:
            noise = self.rvs(num_samples=z.shape[1], state=state, **kwargs)
        elif noise is False or noise is None:
            noise = 0.0
        return np.array([[0.0], [Bearing(0.0)]]) + StateVectors(z) + noise

    def jacobian(self, state: Any, **kwargs: Any) -> FloatArray:
        r"""Analytic Jacobian ``(2, ndim_state)`` at one state (SPEC 2), Stone Soup order.

        .. math:: \partial r/\partial x = dx/r,\ \partial r/\partial y = dy/r,\
                  \partial\phi/\partial x = -dy/g^2,\ \partial\phi/\partial y = dx/g^2

        Also records the state so that :meth:`covar` evaluates ``R`` there.
        """
        xy = _ground_xy(state, self.mapping)
        if xy.shape[0] != 1:
            raise ValueError("jacobian takes one state")
        H_ours = jacobian(xy[0], np.array(self.sensor_xy), self.params.altitude)   # (2, 4)
        H = np.zeros((2, self.ndim_state))
        H[:, self.mapping[0]] = H_ours[:, 0]
        H[:, self.mapping[1]] = H_ours[:, 1]
        self._linearised_at = xy[0].copy()
        return H

    def _noise_point(self, state: Any) -> FloatArray:
        if state is not None:
            xy = _ground_xy(state, self.mapping)
            return xy if xy.shape[0] > 1 else xy[0]
        if self._linearised_at is None:
            raise ValueError("RadarMeasurementModel: R depends on the target state; pass "
                             "state= or call jacobian(state) first")
        return self._linearised_at

    def covar(self, state: Any = None, **kwargs: Any) -> CovarianceMatrix:
        """Noise covariance ``R`` ``(2, 2)`` at ``state`` (default: the latest linearisation
        point, see the class docstring)."""
        xy = self._noise_point(state)
        if xy.ndim > 1:
            raise ValueError("covar takes one state")
        return CovarianceMatrix(noise_cov(xy, np.array(self.sensor_xy), self.heading,
                                          self.params))

    def noise_std(self, state: Any = None) -> FloatArray:
        """Standard deviations ``(n, 2)`` (range m, azimuth rad) at the state(s)."""
        xy = np.atleast_2d(self._noise_point(state))
        R = noise_cov(xy, np.array(self.sensor_xy), self.heading, self.params)
        return np.sqrt(np.stack([R[:, 0, 0], R[:, 1, 1]], axis=-1))

    def scaled_noise(self, state: Any, unit: Any) -> StateVector:
        """Noise ``(2, 1)`` equal to ``sqrt(R(state)) @ unit`` for standard normals ``unit``
        ``(2,)``: lets a simulation reuse its own random streams (common random numbers)."""
        sd = self.noise_std(state)[0]
        return StateVector(sd * np.asarray(unit, dtype=float).reshape(2))

    def rvs(self, num_samples: int = 1, random_state: Any = None, state: Any = None,
            **kwargs: Any) -> StateVector | StateVectors:
        """Draws from ``N(0, R)``; ``R`` at ``state`` (one column per state when several).

        ``random_state`` may be a ``numpy.random.Generator`` (or ``RandomState``); by default
        the model's own generator seeded with ``seed``.
        """
        gen = random_state if random_state is not None else self._rng
        sd = self.noise_std(state)                                              # (n, 2)
        n = max(num_samples, sd.shape[0])
        draws = (np.broadcast_to(sd, (n, 2)) * gen.standard_normal((n, 2))).T
        return StateVector(draws) if n == 1 else StateVectors(draws)

    def logpdf(self, state1: Any, state2: Any, **kwargs: Any) -> float:
        """Log-likelihood of measurement ``state1`` given target state ``state2`` (``R`` at
        ``state2``; azimuth difference wrapped)."""
        diff = np.asarray(state1.state_vector, dtype=float).reshape(2) - np.asarray(
            self.function(state2), dtype=float).reshape(2)
        diff[1] = float(wrap_angle(diff[1]))
        var = self.noise_std(state2)[0] ** 2
        return float(-0.5 * np.sum(diff * diff / var) - 0.5 * np.sum(np.log(2 * np.pi * var)))

    def pdf(self, state1: Any, state2: Any, **kwargs: Any) -> float:
        return float(np.exp(self.logpdf(state1, state2, **kwargs)))

    def inverse_function(self, detection: Any, **kwargs: Any) -> StateVector:
        """Ground position of a measurement (range minus altitude, then azimuth); other
        state entries zero."""
        r, phi = np.asarray(detection.state_vector, dtype=float).reshape(2)
        g = math.sqrt(max(r * r - float(self.params.altitude) ** 2, 0.0))
        out = np.zeros(self.ndim_state)
        out[self.mapping[0]] = self.sensor_xy[0] + g * math.cos(phi)
        out[self.mapping[1]] = self.sensor_xy[1] + g * math.sin(phi)
        return StateVector(out)


# --------------------------------------------------------------------------------------------
# Platform movement: the SPEC 2 moves
# --------------------------------------------------------------------------------------------


class LatticeMoveAction(MovePositionAction):
    """Move the platform to ``target_value``: move ``move_index`` of SPEC 2's move order."""

    move_index: int = Property(default=0, doc="Index of the move (0 = stay).")


class LatticeMoveActionGenerator(ActionGenerator):
    """The SPEC 2 moves (stay, then 8 directions per distance) that end inside the map."""

    move_distances: Sequence[float] = Property(default=(20.0, 40.0),
                                               doc="Move distances s (m).")
    world: MapRect = Property(default_factory=MapRect, doc="The map; its edge is inside.")
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
    """A platform movement controller whose actions are the SPEC 2 moves inside the map.

    Use it as the ``movement_controller`` of a Stone Soup ``FixedPlatform``. The position is
    3-D ``[x, y, z]`` by default (``position_mapping=(0, 1, 2)``); moves change x and y. A
    move takes effect at the platform's next ``act``; with no action the platform stays.
    """

    move_distances: Sequence[float] = Property(default=(20.0, 40.0),
                                               doc="Move distances s (m), SPEC 2.")
    world: MapRect = Property(default_factory=MapRect, doc="The map [0, W] x [0, H].")

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


class AimAction(Action):
    """Look at ground point ``target_value`` ``(x, y)``; ``target`` names what is there
    (a track, or any key)."""

    target: Any = Property(default=None, doc="The target looked at (e.g. its Track).")

    def act(self, current_time: Any, timestamp: Any, init_value: Any, **kwargs: Any) -> Any:
        return self.target_value


class AimActionGenerator(ActionGenerator):
    """One :class:`AimAction` per candidate ``(target, (x, y))`` of the radar."""

    candidates: Sequence[Any] = Property(default=(), doc="``(target, (x, y))`` pairs.")

    def action(self, point: Any, target: Any = None) -> AimAction:
        """An aim action at ``point`` ``(x, y)`` for ``target``."""
        p = np.asarray(point, dtype=float).ravel()
        return AimAction(generator=self, end_time=self.end_time,
                         target_value=(float(p[0]), float(p[1])), target=target)

    @property
    def default_action(self) -> AimAction:
        owner = self.owner
        return AimAction(generator=self, end_time=self.end_time,
                         target_value=self.current_value, target=owner.aim_target)

    def __iter__(self) -> Any:
        for target, point in self.candidates:
            yield self.action(point, target)

    def __contains__(self, item: Any) -> bool:
        if isinstance(item, AimAction):
            item = item.target_value
        p = np.asarray(item, dtype=float).ravel()
        return any(np.allclose(p, np.asarray(q, dtype=float), rtol=0, atol=10 * POSITION_TOL)
                   for _, q in self.candidates)


class SensorplanRadar(Sensor):
    r"""The SPEC 2 radar as an actionable Stone Soup sensor.

    Mount it on a Stone Soup platform (a ``FixedPlatform`` with a :class:`LatticeMovable` to
    let :class:`SensorplanManager` move it); its ground position is the platform's x, y and
    its altitude is ``params.altitude``.

    Pointing. The actionable property is :attr:`aim`, a ground point. When the radar acts on
    a new :class:`AimAction` it turns toward that point by at most ``params.max_turn``
    (SPEC 2 heading rule), from the heading it had, *seen from the platform's position at the
    time of the first use after the act* (a measurement, or reading :attr:`heading`). The turn
    is resolved lazily because Stone Soup acts platforms and sensors in no fixed order: in a
    loop that acts every actionable before measuring, the turn is seen from the new position,
    as SPEC 5 executes it. The heading then stays fixed until the next aim action.

    Field of view: ground range in ``[min_ground_range, max_ground_range]``, azimuth within
    ``fov_half_angle`` of the heading, ``cos psi > 0`` (SPEC 2), via
    :func:`sensorplan.sensors.visible`.
    """

    params: SensorParams = Property(default_factory=SensorParams, doc="Radar parameters.")
    heading: float = Property(default=0.0, doc="Heading theta (rad).")
    aim: Any = ActionableProperty(
        generator_cls=AimActionGenerator,
        generator_kwargs_mapping={"candidates": "aim_candidates"},
        default=None, doc="Ground point ``(x, y)`` the radar looks toward, or None.")
    aim_candidates: Sequence[Any] = Property(
        default=(), doc="``(target, (x, y))`` pairs offered to Stone Soup's sensor managers as "
                        "aim actions (see :func:`set_aim_candidates`).")
    ndim_state: int = Property(default=4, doc="Target state dimension.")
    position_mapping: Sequence[int] = Property(
        default=(0, 2), doc="Indices of a target's ground x and y in its state vector.")
    seed: int | None = Property(default=None, doc="Seed of the radar's noise generator.")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending = False
        self.aim_target: Any = None
        self.rng = np.random.default_rng(self.seed)

    @heading.getter
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
        bearing = math.atan2(aim[1] - xy[1], aim[0] - xy[0])
        self._property_heading = float(heading_rule(self._property_heading, bearing,
                                                    self.params.max_turn))

    @property
    def ground_position(self) -> FloatArray:
        """Ground position ``(2,)`` of the radar (its platform's x, y plus mounting offset)."""
        return np.asarray(self.position, dtype=float).ravel()[:2]

    def act(self, timestamp: datetime.datetime, **kwargs: Any) -> None:
        if not self.validate_timestamp():
            self.timestamp = timestamp
            return
        action = self.scheduled_actions.pop("aim", None)
        if action is not None:
            self._resolve()          # the previous aim's turn, if never used, happens first
            self._property_aim = tuple(float(v) for v in action.target_value)
            self.aim_target = action.target
            self._pending = True
        self.timestamp = timestamp

    @property
    def measurement_model(self) -> RadarMeasurementModel:
        """The measurement model at the radar's current pose."""
        return RadarMeasurementModel(ndim_state=self.ndim_state,
                                     mapping=tuple(self.position_mapping),
                                     sensor_xy=tuple(self.ground_position),
                                     heading=self.heading, params=self.params)

    def is_detectable(self, state: Any, measurement_model: Any = None) -> bool:
        """Whether the state's ground position is in the field of view (SPEC 2)."""
        xy = _ground_xy(state, self.position_mapping)
        return bool(np.all(visible(xy, self.ground_position, self.heading, self.params)))

    def measure(self, ground_truths: Iterable[Any], noise: Any = True,
                rng: np.random.Generator | None = None, **kwargs: Any) -> set[TrueDetection]:
        """Detections of the ground truths in the field of view (noise drawn in the
        iteration order of ``ground_truths``).

        ``noise``: True draws from ``N(0, R)`` with ``R`` at the true state (SPEC 2) using
        ``rng`` or the radar's own generator; False adds none; an array is added as is (see
        :meth:`RadarMeasurementModel.scaled_noise`). For reproducible noise pass a list (or a
        single truth, a dwell on one target) rather than a set.
        """
        model = self.measurement_model
        gen = rng if rng is not None else self.rng
        detections: set[TrueDetection] = set()
        for truth in ground_truths:
            if not self.is_detectable(truth):
                continue
            if noise is True:
                e = model.rvs(state=truth, random_state=gen)
            elif noise is False or noise is None:
                e = 0.0
            else:
                e = noise
            z = model.function(truth, noise=False) + e
            detections.add(TrueDetection(z, measurement_model=model, timestamp=truth.timestamp,
                                         groundtruth_path=truth))
        return detections


def set_aim_candidates(radars: Iterable[SensorplanRadar], tracks: Iterable[Track],
                       dt: float) -> None:
    """Offer every track as an aim to each radar, for Stone Soup's own sensor managers.

    The aim point is the track's mean predicted one step ``dt`` ahead (the point our
    planners aim at in the first step of an epoch, SPEC 4). The candidate's target is the
    Track itself.
    """
    tracks = ordered_tracks(tracks)
    F, _ = cv_matrices(dt, 0.0)
    means, _ = from_tracks(tracks)
    aims = (means @ F.T)[:, :2]
    cands = tuple((t, (float(a[0]), float(a[1]))) for t, a in zip(tracks, aims))
    for radar in radars:
        radar.aim_candidates = cands


# --------------------------------------------------------------------------------------------
# The sensor manager
# --------------------------------------------------------------------------------------------


class SensorplanManager(SensorManager):
    """A Stone Soup sensor manager that plans with any registered sensorplan planner.

    Each call of :meth:`choose_actions` builds a :class:`~sensorplan.problem.PlanningProblem`
    from the tracks (means and covariances at their common time ``t0``) and the managed
    platforms (position, heading, radar parameters, moves, map), runs the planner for
    ``horizon`` epochs of ``steps_per_epoch`` steps of ``dt`` seconds, and returns the first
    epoch as Stone Soup actions (rolling horizon, SPEC 5 ``olf``):

    - each platform: a :class:`LatticeMoveAction` to its planned position of epoch 1;
    - each radar: an :class:`AimAction` at its planned target's mean predicted one step
      ahead, with ``target`` = that Track; the radar's heading rule then gives exactly the
      planner's heading.

    Supported actionables: Stone Soup platforms whose movement controller is a
    :class:`LatticeMovable`, each carrying exactly one :class:`SensorplanRadar` (a platform
    and its radar form one sensor of the plan; the radars are taken from the platforms).
    Anything else raises ``TypeError``. All platforms must share one map. Track covariances
    are symmetrised (``(P + P^T) / 2``) before planning.

    Order: the platforms in the order given when ``platforms`` is a list or tuple, otherwise
    sorted by position; the tracks likewise (a set is sorted by ``track.id``, see
    :func:`ordered_tracks`). The target index of the plan is the track's index in that order.

    After each call ``last_problem``, ``last_result`` (the :class:`PlanResult`) and
    ``last_tracks`` hold what was planned.
    """

    planner: str = Property(default="pg", doc="Registered planner name (``make_planner``).")
    planner_params: Mapping[str, Any] = Property(default_factory=dict,
                                                 doc="Keyword arguments of the planner.")
    horizon: int = Property(default=1, doc="K, epochs per plan.")
    steps_per_epoch: int = Property(default=1, doc="e, filter steps per epoch.")
    dt: float = Property(default=1.0, doc="Filter step (s).")
    process_noise: float = Property(default=0.05,
                                    doc="q (m^2/s^3) of the CWNA model the planner assumes; "
                                        "match the tracker's ConstantVelocity noise.")
    visibility: str = Property(default="probabilistic", doc="SPEC 4 visibility mode.")
    objective: str = Property(default="terminal", doc="SPEC 4 objective.")
    rng: Any = Property(default=0, doc="numpy Generator used for every planning call, or a "
                                       "seed for one.")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._planner = make_planner(self.planner, **dict(self.planner_params))
        self._rng = (self.rng if isinstance(self.rng, np.random.Generator)
                     else np.random.default_rng(self.rng))
        self.last_problem: PlanningProblem | None = None
        self.last_result: PlanResult | None = None
        self.last_tracks: list[Track] = []

    @property
    def actionables(self) -> list[Any]:
        """The managed platforms and radars, in planning order."""
        pairs = self.pairs()
        return [p for p, _ in pairs] + [r for _, r in pairs]

    def pairs(self) -> list[tuple[Platform, SensorplanRadar]]:
        """``(platform, radar)`` per player, in planning order; raises ``TypeError`` for
        unsupported actionables."""
        platforms = self.platforms
        if isinstance(platforms, (list, tuple)):
            ordered = list(platforms)
        else:
            ordered = sorted(platforms, key=lambda p: tuple(
                np.asarray(p.position, dtype=float).ravel().tolist()))
        pairs = []
        for platform in ordered:
            movable = platform.movement_controller
            if not isinstance(movable, LatticeMovable):
                raise TypeError(f"SensorplanManager moves platforms with a LatticeMovable "
                                f"movement controller, got {type(movable).__name__}")
            radars = [s for s in platform.sensors if isinstance(s, SensorplanRadar)]
            others = [s for s in platform.sensors if not isinstance(s, SensorplanRadar)]
            if others or len(radars) != 1:
                names = [type(s).__name__ for s in platform.sensors]
                raise TypeError("each managed platform must carry exactly one SensorplanRadar "
                                f"and no other sensor; got {names}")
            pairs.append((platform, radars[0]))
        mounted = {id(r) for _, r in pairs}
        loose = [s for s in self._property_sensors if id(s) not in mounted]
        if loose:
            raise TypeError("sensors must be SensorplanRadars mounted on the managed platforms; "
                            f"got {[type(s).__name__ for s in loose]} not on one")
        if not pairs:
            raise TypeError("SensorplanManager needs at least one platform")
        return pairs

    def build_problem(self, tracks: Iterable[Track]) -> tuple[PlanningProblem, list[Track]]:
        """The planning problem of the current tracks and platforms, and the track order."""
        ordered = ordered_tracks(tracks)
        if not ordered:
            raise ValueError("choose_actions needs at least one track")
        times = {t.state.timestamp for t in ordered}
        if len(times) != 1:
            raise ValueError("all tracks must be at the same time (predict them first)")
        means, covs = from_tracks(ordered)
        pairs = self.pairs()
        worlds = {(p.movement_controller.world.width, p.movement_controller.world.height)
                  for p, _ in pairs}
        if len(worlds) != 1:
            raise ValueError("all managed platforms must share one map (world)")
        world = pairs[0][0].movement_controller.world
        sensors = tuple(dataclasses.replace(
            r.params, moves=tuple(float(s) for s in p.movement_controller.move_distances))
            for p, r in pairs)
        problem = PlanningProblem(
            means=means, covs=0.5 * (covs + np.swapaxes(covs, -1, -2)),
            positions=np.stack([r.ground_position for _, r in pairs]),
            headings=np.array([r.heading for _, r in pairs]), sensors=sensors,
            horizon=int(self.horizon), steps_per_epoch=int(self.steps_per_epoch),
            dt=float(self.dt), process_noise=float(self.process_noise), world=world,
            visibility=self.visibility, objective=self.objective)
        return problem, ordered

    def choose_actions(self, tracks: Iterable[Track], timestamp: datetime.datetime,
                       nchoose: int = 1, **kwargs: Any) -> list[dict[Any, list[Action]]]:
        """Plan and return ``[config]``, ``config = {actionable: [action]}`` (Stone Soup's
        format with ``nchoose = 1``) for every managed platform and radar.

        Parameters
        ----------
        tracks : iterable of Track
            Every target's track, all at the same time ``t0``.
        timestamp : datetime
            End time of the actions (the next measurement time).
        """
        if nchoose != 1:
            raise ValueError("SensorplanManager returns one configuration (nchoose=1)")
        problem, ordered = self.build_problem(tracks)
        result = self._planner.plan(problem, rng=self._rng)
        F, _ = cv_matrices(problem.dt, 0.0)
        aims = (problem.means @ F.T)[:, :2]
        config: dict[Any, list[Action]] = {}
        for i, (platform, radar) in enumerate(self.pairs()):
            (move_gen,) = platform.actions(timestamp)
            move = move_gen.action_from_value(result.plan.positions[i, 0])
            if move is None:   # pragma: no cover - a feasible plan is always one move away
                raise RuntimeError(f"planned position of platform {i} is not one move away")
            aim_gen = next(g for g in radar.actions(timestamp) if g.attribute == "aim")
            j = int(result.plan.targets[i, 0])
            config[platform] = [move]
            config[radar] = [aim_gen.action(aims[j], target=ordered[j])]
        self.last_problem, self.last_result, self.last_tracks = problem, result, ordered
        return [config]


def execute(config: Mapping[Any, Sequence[Action]], timestamp: datetime.datetime) -> None:
    """Give each actionable its actions and act (platforms first, then sensors), the usual
    Stone Soup loop step; any order gives the same result with :class:`SensorplanRadar`."""
    items = sorted(config.items(), key=lambda kv: isinstance(kv[0], Sensor))
    for actionable, actions in items:
        actionable.add_actions(list(actions))
    for actionable, _ in items:
        actionable.act(timestamp)


# --------------------------------------------------------------------------------------------
# A mutual-information reward for Stone Soup's sensor managers
# --------------------------------------------------------------------------------------------


def _radars_of(actionable: Any) -> list[SensorplanRadar]:
    """The radar itself, or the radars mounted on a platform."""
    if isinstance(actionable, SensorplanRadar):
        return [actionable]
    if isinstance(actionable, Platform):
        return [s for s in actionable.sensors if isinstance(s, SensorplanRadar)]
    return []


class MutualInformationReward(RewardFunction):
    r"""Mutual information of a configuration's looks, for Stone Soup's sensor managers.

    .. math:: \sum_j \tfrac12 \log \frac{\det P_j^-}{\det P_j^+}

    where ``P_j^-`` is track j predicted to ``metric_time`` by ``predictor`` and ``P_j^+``
    the same after ``updater`` applies every look at j (each acted :class:`SensorplanRadar`
    whose aim target is j) whose predicted mean lies in the radar's field of view, with a
    noise-free measurement at that mean. This is SPEC 4's potential with K = e = 1 and
    ``visibility = "mean"`` (tested equal to :func:`sensorplan.information.potential`).

    Works with configurations of platforms (their mounted radars look with their current
    aim) and of radars, as Stone Soup's brute-force, greedy and MCTS managers build them.
    With ``return_tracks`` it also returns the updated tracks (MCTS needs them).
    """

    predictor: Predictor = Property(doc="Predictor, e.g. ExtendedKalmanPredictor.")
    updater: Updater = Property(doc="Updater, e.g. ExtendedKalmanUpdater(None).")
    return_tracks: bool = Property(default=False, doc="Also return the updated tracks.")

    def __call__(self, config: Mapping[Any, Sequence[Action]], tracks: Iterable[Track],
                 metric_time: datetime.datetime, *args: Any, **kwargs: Any) -> Any:
        tracks = ordered_tracks(tracks)
        # Seeding the memo keeps tracks (the ones given, and those the radars aim at or are
        # offered) out of the deep copies of the actionables: copying track histories would
        # cost more than the reward itself.
        memo: dict[int, Any] = {id(t): t for t in tracks}
        for actionable in config:
            for radar in _radars_of(actionable):
                memo[id(radar.aim_target)] = radar.aim_target
                memo.update((id(t), t) for t, _ in radar.aim_candidates)
        radars: dict[int, SensorplanRadar] = {}
        for actionable, actions in config.items():
            acted = copy.deepcopy(actionable, memo)
            acted.add_actions(list(actions))
            acted.act(metric_time)
            radars.update((id(r), r) for r in _radars_of(acted))
        by_id = {str(t.id): k for k, t in enumerate(tracks)}
        prior = [self.predictor.predict(t.state, timestamp=metric_time) for t in tracks]
        post = list(prior)
        for radar in radars.values():
            k = by_id.get(str(getattr(radar.aim_target, "id", None)))
            if k is None or not radar.is_detectable(prior[k]):
                continue
            model = radar.measurement_model
            z = Detection(model.function(post[k], noise=False), measurement_model=model,
                          timestamp=metric_time)
            post[k] = self.updater.update(SingleHypothesis(post[k], z))
        reward = 0.0
        for a, b in zip(prior, post):
            if b is not a:
                reward += 0.5 * (np.linalg.slogdet(np.asarray(a.covar, float))[1]
                                 - np.linalg.slogdet(np.asarray(b.covar, float))[1])
        if not self.return_tracks:
            return reward
        updated = set()
        for t, s in zip(tracks, post):
            u = copy.copy(t)
            u.append(s)
            updated.add(u)
        return reward, updated


__all__ = ["STONESOUP_ORDER", "AimAction", "AimActionGenerator", "LatticeMovable",
           "LatticeMoveAction", "LatticeMoveActionGenerator", "MutualInformationReward",
           "RadarMeasurementModel", "SensorplanManager", "SensorplanRadar", "execute",
           "from_gaussian_state", "from_stonesoup_cov", "from_stonesoup_mean", "from_tracks",
           "ordered_tracks", "set_aim_candidates", "to_gaussian_state", "to_ground_truth_state",
           "to_stonesoup_cov", "to_stonesoup_mean", "to_tracks"]
