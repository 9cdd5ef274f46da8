"""The sensor manager that runs sensorplan's planners, and a mutual-information reward for
Stone Soup's own sensor managers."""

from __future__ import annotations

import copy
import dataclasses
import datetime
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from stonesoup.base import Property
from stonesoup.platform import Platform
from stonesoup.predictor import Predictor
from stonesoup.sensor.sensor import Sensor
from stonesoup.sensormanager.action import Action
from stonesoup.sensormanager.base import SensorManager
from stonesoup.sensormanager.reward import RewardFunction
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.track import Track
from stonesoup.updater import Updater

from ..._types import FloatArray
from ...errors import ConfigError
from ...models.motion import cv_matrices
from ...planners import PlanResult, checked_plan, make_planner
from ...planners.objective import PLANNING_DETECTIONS
from ...planners import search
from ...planners.problem import (POSITION_TOL, SEARCH_MODES, Plan, PlanningProblem,
                                 move_vectors)

from ._actionables import (AimAction, LatticeMoveAction, LatticeMovable, SearchSector,
                           SensorplanRadar)
from ._convert import from_tracks, ordered_tracks
from ._world import MapRect, check_inside

# --------------------------------------------------------------------------------------------
# The sensor manager
# --------------------------------------------------------------------------------------------

#: Largest difference (s) between ``choose_actions``' timestamp and the end of the first epoch.
TIME_TOL = 1e-6


def existence_of(tracks: Sequence[Track]) -> FloatArray:
    """``(M,)`` each track's existence probability: its state's ``existence_probability``
    (a :class:`BernoulliGaussianState`'s), else 1."""
    return np.array([float(getattr(t.state, "existence_probability", 1.0)) for t in tracks],
                    dtype=float).reshape(-1)



class SensorplanManager(SensorManager):
    """A Stone Soup sensor manager that plans with any registered sensorplan planner.

    Each call of :meth:`choose_actions` builds a
    :class:`~sensorplan.planners.problem.PlanningProblem`
    from the tracks (means and covariances at their common time ``t0``) and the managed
    platforms (position, heading, radar parameters, moves, map), runs the planner for
    ``horizon`` epochs of ``steps_per_epoch`` steps of ``dt`` seconds, and returns the first
    epoch as Stone Soup actions (rolling horizon, ``olf``):

    - each platform: a :class:`LatticeMoveAction` to its planned position of epoch 1;
    - each radar: an :class:`AimAction` at its planned target's mean predicted one step
      ahead, with ``target`` = that Track; the radar's heading rule then gives exactly the
      planner's heading.

    With no track at all (a tracker before its first initiation) it returns the
    stay-and-hold configuration: every platform stays, every radar keeps its aim and heading
    (with search off; with search on it plans where to search).

    Search (``search="on"``): a look may also point at one of each radar's
    ``search_sectors``, and the planner maximises Phi with search: each track's information
    weighted by its existence probability (a :class:`BernoulliGaussianState`'s, else 1) plus
    ``w mu``, the expected number of undetected targets the looks find
    (:mod:`sensorplan.planners.search`), from ``tracker``'s undetected intensity now
    (:meth:`PMBStoneSoupTracker.undetected_intensity`; its map must be the platforms'). A
    search look comes back as an :class:`AimAction` at a :class:`SearchSector` with its
    ``bearing``. The planner must plan search looks (``brute-force``, ``pg``,
    ``pg-refine``, ``sequential-greedy``, ``random``, ``raster``).

    Tracks: Stone Soup's constant-velocity states ``[x, vx, y, vy]`` or
    ``[x, vx, y, vy, z, vz]`` as they are; any other layout names its ground position and
    velocity entries with ``position_mapping`` and ``velocity_mapping``. The planner sees the
    ground marginal (those four entries of the mean, that block of the covariance,
    symmetrised).

    Map: the platforms' :class:`MapRect` in world coordinates, any origin. The planner works
    in its own frame ``[0, width] x [0, height]`` (world minus the origin): ``last_problem``
    and ``last_result`` are in that frame, :meth:`planned_positions` and the returned
    actions in world coordinates.

    Supported actionables: Stone Soup platforms whose movement controller is a
    :class:`LatticeMovable`, each carrying exactly one :class:`SensorplanRadar` (a platform
    and its radar form one sensor of the plan; the radars are taken from the platforms).
    Anything else raises ``TypeError``. All platforms must share one map.

    Order: the platforms in the order given when ``platforms`` is a list or tuple, otherwise
    sorted by position; the tracks likewise (a set is sorted by content, see
    :func:`ordered_tracks`). Sensor i of the plan (``sensors[i]`` in error messages) is the
    i-th platform, target j the j-th track in that order.

    Detection: the radars' ``params`` (``detection``, ``false_alarm_probability``,
    ``clutter_rate``) go into the problem as they are; with ``planning_detection="aware"``
    (the default) the plan expects missed detections and false alarms (a look counts its
    detection probability and the information clutter takes away), with ``"ignore"`` only
    whether the target is in view. Ideal radars without clutter plan the same either way.

    Randomness: the planner draws from ``rng`` only (a ``numpy.random.Generator``, or a seed
    for one, used for every call), never from NumPy's global state.

    After each call ``last_problem``, ``last_result`` (the :class:`PlanResult`) and
    ``last_tracks`` hold what was planned (None, None and ``[]`` after a hold).
    """

    planner: str = Property(default="pg", doc="A planner name or ``package.module:Class`` "
                                              "(``make_planner``).")
    planner_params: Mapping[str, Any] = Property(
        default_factory=dict, doc="The planner's settings (its dataclass fields, e.g. "
                                  "``time_budget``); an unknown key is a ConfigError.")
    horizon: int = Property(default=1, doc="K, epochs per plan.")
    steps_per_epoch: int = Property(default=1, doc="e, filter steps per epoch.")
    dt: float = Property(default=1.0, doc="Filter step (s).")
    process_noise: float = Property(default=0.05,
                                    doc="q (m^2/s^3) of the CWNA model the planner assumes; "
                                        "match the tracker's ConstantVelocity noise.")
    visibility: str = Property(default="probabilistic", doc="Visibility mode.")
    objective: str = Property(
        default="cumulative", doc="``cumulative`` (information summed over the horizon's "
                                  "steps) or ``terminal`` (at its end, the paper's).")
    planning_detection: str = Property(
        default="aware", doc="``aware``: planned looks count the radars' detection "
                             "probability and clutter (``params.detection``, "
                             "``params.clutter_rate``); ``ignore``: only whether the target "
                             "is in view.")
    rng: Any = Property(default=0, doc="numpy Generator used for every planning call, or a "
                                       "seed for one (a seed, to save the setup as YAML).")
    position_mapping: Sequence[int] | None = Property(
        default=None, doc="Indices of ground x and y in the tracks' states; None: (0, 2) for "
                          "Stone Soup's 4-D and 6-D constant-velocity states.")
    velocity_mapping: Sequence[int] | None = Property(
        default=None, doc="Indices of ground vx and vy in the tracks' states; None: (1, 3) "
                          "for Stone Soup's 4-D and 6-D constant-velocity states.")
    search: str = Property(default="off", doc="``on``: looks may also search the radars' "
                                              "``search_sectors`` and Phi values search.")
    tracker: Any = Property(default=None, doc="The PMBStoneSoupTracker whose undetected "
                                              "intensity search plans from (search on).")
    search_weight: float | None = Property(
        default=None, doc="w, nats a newly found target is worth; None: the information of "
                          "its first detection (first_detection_weight).")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # Stone Soup's YAML writes the derived set of sensors and reads it back as ruamel's
        # CommentedSet, which lacks the set methods SensorManager uses.
        self._property_sensors: set[Any] = set(self._property_sensors or ())
        if self.planning_detection not in PLANNING_DETECTIONS:
            raise ConfigError("planning_detection", f"must be one of {PLANNING_DETECTIONS}, "
                                                    f"got {self.planning_detection!r}")
        if self.search not in SEARCH_MODES:
            raise ConfigError("search", f"must be one of {SEARCH_MODES}, got {self.search!r}")
        if self.search == "on" and not callable(getattr(self.tracker, "undetected_intensity",
                                                        None)):
            raise ConfigError("tracker", "search on needs the tracker whose undetected "
                                         "intensity it plans from (a PMBStoneSoupTracker)")
        self._planner = make_planner(self.planner, **dict(self.planner_params))
        self._rng = (self.rng if isinstance(self.rng, np.random.Generator)
                     else np.random.default_rng(self.rng))
        self.last_problem: PlanningProblem | None = None
        self.last_result: PlanResult | None = None
        self.last_tracks: list[Track] = []
        self._last_start: FloatArray | None = None

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
        pairs: list[tuple[Platform, SensorplanRadar]] = []
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
            # The plan moves the radar; the lattice moves the platform: they must coincide.
            if np.abs(radars[0].ground_position - movable.ground_position).max() > POSITION_TOL:
                raise ValueError("a managed SensorplanRadar must sit at its platform's ground "
                                 "position (mounting_offset zero in x and y)")
            radars[0].check_altitude(f"sensors[{len(pairs)}].params.altitude")
            pairs.append((platform, radars[0]))
        mounted = {id(r) for _, r in pairs}
        loose = [s for s in self._property_sensors if id(s) not in mounted]
        if loose:
            raise TypeError("sensors must be SensorplanRadars mounted on the managed platforms; "
                            f"got {[type(s).__name__ for s in loose]} not on one")
        if not pairs:
            raise TypeError("SensorplanManager needs at least one platform")
        return pairs

    def world_of(self, pairs: Sequence[tuple[Platform, SensorplanRadar]]) -> MapRect:
        """The platforms' common map; raises ``ValueError`` if they differ and a
        :class:`~sensorplan.errors.ConfigError` naming ``sensors[i].position`` and the map's
        bounds if a platform is outside it."""
        world = pairs[0][0].movement_controller.world
        for platform, _ in pairs[1:]:
            if platform.movement_controller.world != world:
                raise ValueError("all managed platforms must share one map (world); got "
                                 f"{world} and {platform.movement_controller.world}")
        for i, (platform, radar) in enumerate(pairs):
            check_inside(f"sensors[{i}].position", radar.ground_position, world,
                         platform.movement_controller.world_is_default)
        return world

    def build_problem(self, tracks: Iterable[Track]) -> tuple[PlanningProblem, list[Track]]:
        """The planning problem of the current tracks and platforms (in the planner's frame:
        world coordinates minus the map's origin), and the track order."""
        ordered = ordered_tracks(tracks)
        searching = self.search == "on"
        if not ordered and not searching:
            raise ValueError("a planning problem needs at least one track (choose_actions "
                             "returns the stay-and-hold configuration instead)")
        times = {t.state.timestamp for t in ordered}
        if len(times) > 1:
            raise ValueError("all tracks must be at the same time (predict them first)")
        means, covs = from_tracks(ordered, self.position_mapping, self.velocity_mapping)
        pairs = self.pairs()
        world = self.world_of(pairs)
        search: dict[str, Any] = {}
        if searching:
            if self.tracker.world != world:
                raise ValueError(f"the tracker's map {self.tracker.world} is not the "
                                 f"platforms' {world}")
            search = {"search": "on",
                      "search_sectors": tuple(int(r.search_sectors) for _, r in pairs),
                      "undetected": self.tracker.undetected_intensity(self.search_weight),
                      "existence": existence_of(ordered)}
        start = np.stack([r.ground_position for _, r in pairs])
        means[:, :2] -= world.origin          # exact for the default origin (0, 0)
        sensors = tuple(dataclasses.replace(
            r.params, moves=tuple(float(s) for s in p.movement_controller.move_distances))
            for p, r in pairs)
        problem = PlanningProblem(
            means=means, covs=0.5 * (covs + np.swapaxes(covs, -1, -2)),
            positions=start - world.origin,
            headings=np.array([r.heading for _, r in pairs]), sensors=sensors,
            horizon=int(self.horizon), steps_per_epoch=int(self.steps_per_epoch),
            dt=float(self.dt), process_noise=float(self.process_noise), world=world.core,
            visibility=self.visibility, objective=self.objective,
            planning_detection=self.planning_detection, **search)
        return problem, ordered

    def choose_actions(self, tracks: Iterable[Track], timestamp: datetime.datetime,
                       nchoose: int = 1, **kwargs: Any) -> list[dict[Any, list[Action]]]:
        """Plan and return ``[config]``, ``config = {actionable: [action]}`` (Stone Soup's
        format with ``nchoose = 1``) for every managed platform and radar.

        Parameters
        ----------
        tracks : iterable of Track
            Every target's track, all at the same time ``t0``. None at all gives the
            stay-and-hold configuration (every platform stays, every radar keeps its aim).
        timestamp : datetime
            End time of the actions: the end of the first epoch, the tracks' time plus
            ``steps_per_epoch * dt`` (the next measurement time when ``steps_per_epoch`` is
            1). Another time is a :class:`~sensorplan.errors.ConfigError` naming
            ``timestamp`` (:meth:`check_timestamp`).
        """
        if nchoose != 1:
            raise ValueError("SensorplanManager returns one configuration (nchoose=1)")
        ordered = ordered_tracks(tracks)
        pairs = self.pairs()
        config: dict[Any, list[Action]] = {}
        if not ordered and self.search != "on":
            self.world_of(pairs)
            for platform, radar in pairs:
                (move_gen,) = platform.actions(timestamp)
                aim_gen = next(g for g in radar.actions(timestamp) if g.attribute == "aim")
                config[platform] = [move_gen.default_action]
                config[radar] = [aim_gen.default_action]
            self.last_problem, self.last_result, self.last_tracks = None, None, []
            self._last_start = None
            return [config]
        problem, ordered = self.build_problem(ordered)
        if ordered:
            self.check_timestamp(ordered[0].state.timestamp, timestamp)
        start = np.stack([r.ground_position for _, r in pairs])     # world, as planned from
        result = checked_plan(self._planner, problem, self._rng)
        # Aim points from the world-frame means, as the planner aims in its frame.
        F, _ = cv_matrices(problem.dt, 0.0)
        means, _ = from_tracks(ordered, self.position_mapping, self.velocity_mapping)
        aims = (means @ F.T)[:, :2]
        origin = pairs[0][0].movement_controller.world.origin
        for i, (platform, radar) in enumerate(pairs):
            (move_gen,) = platform.actions(timestamp)
            move = move_gen.action_from_value(result.plan.positions[i, 0] + origin)
            if move is None:   # pragma: no cover - a feasible plan is always one move away
                raise RuntimeError(f"planned position of platform {i} is not one move away")
            aim_gen = next(g for g in radar.actions(timestamp) if g.attribute == "aim")
            j = int(result.plan.targets[i, 0])
            config[platform] = [move]
            if j >= 0:
                config[radar] = [aim_gen.action(aims[j], target=ordered[j])]
            else:
                assert result.plan.sectors is not None
                config[radar] = [aim_gen.sector_action(int(result.plan.sectors[i, 0]))]
        self.last_problem, self.last_result, self.last_tracks = problem, result, ordered
        self._last_start = start
        return [config]

    def check_timestamp(self, t0: Any, timestamp: Any) -> None:
        """Raise a :class:`~sensorplan.errors.ConfigError` naming ``timestamp`` unless it is
        the end of the first epoch, ``t0 + steps_per_epoch * dt`` (to 1e-6 s), where ``t0``
        is the tracks' time: the plan's epochs last ``steps_per_epoch * dt``, so any other
        gap would be planned as if it were that long. Tracks without a time are not
        checked."""
        if t0 is None or timestamp is None:
            return
        gap = (timestamp - t0).total_seconds()
        e, dt = int(self.steps_per_epoch), float(self.dt)
        epoch = e * dt
        if abs(gap - epoch) <= TIME_TOL + 1e-9 * abs(epoch):
            return
        steps = f"{e} x {dt:g} s = " if e != 1 else ""
        fix = f" (or set dt={gap / e:g} for epochs of {gap:g} s)" if gap > 0 else ""
        raise ConfigError("timestamp", f"is {gap:g} s after the tracks' time, but this "
                                       f"manager plans epochs of steps_per_epoch x dt = "
                                       f"{steps}{epoch:g} s: give the end of the first epoch, "
                                       f"the tracks' time + {epoch:g} s{fix}")

    def planned_positions(self) -> FloatArray:
        """World ground positions ``(N, K, 2)`` (m) of the last plan, epoch by epoch.

        Replayed from the platforms' world positions at planning time with the plan's moves,
        each added as :class:`LatticeMovable` adds it: the positions the platforms reach when
        they execute the plan, bit for bit, whatever the map's origin. NaN where a player is
        unassigned.
        """
        if self.last_result is None or self._last_start is None:
            raise ValueError("no plan yet (choose_actions has not planned)")
        problem, plan = self.last_problem, self.last_result.plan
        assert problem is not None
        out = np.full(plan.positions.shape, np.nan)
        for i, params in enumerate(problem.sensors):
            moves = move_vectors(tuple(params.moves))
            core, world = problem.positions[i], self._last_start[i]
            for k in range(plan.positions.shape[1]):
                step = plan.positions[i, k] - core
                if not np.all(np.isfinite(step)):
                    continue
                m = int(np.argmin(np.abs(moves - step).max(axis=1)))
                core, world = plan.positions[i, k], world + moves[m]
                out[i, k] = world
        return out
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
    noise-free measurement at that mean. This is sensorplan's potential with K = e = 1 and
    ``visibility = "mean"`` (tested equal to :func:`sensorplan.planners.information.potential`).

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
            model = radar.measurement_model_for(np.shape(prior[k].state_vector)[0])
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


# --------------------------------------------------------------------------------------------
# A reward that values search, for Stone Soup's sensor managers
# --------------------------------------------------------------------------------------------


class SearchAndTrackReward(RewardFunction):
    r"""Phi with search of a configuration's looks, for Stone Soup's sensor managers.

    .. math:: \sum_j r_j I_j + w \mu

    Stone Soup's rewards see only the tracks; this one also sees ``tracker``'s undetected
    intensity (:meth:`PMBStoneSoupTracker.undetected_intensity`), so a look at a search
    sector is worth the undetected targets it is expected to find. It is sensorplan's
    potential with search on (:func:`sensorplan.planners.search.potential`) over one step
    of ``dt``: ``I_j`` the information of track j (existence ``r_j`` from a
    :class:`BernoulliGaussianState`, else 1), ``mu`` the expected number of undetected
    targets the looks find, ``w`` ``search_weight`` (None: the information of a first
    detection).

    The configuration's radars (:class:`SensorplanRadar`, given themselves or by their
    platform) look as their :class:`AimAction` says: at a track (by its id), or at a
    :class:`SearchSector`; a radar with a hold action, or aiming at nothing in ``tracks``,
    does not look. Each radar looks from its platform's position after the configuration's
    :class:`LatticeMoveAction` for that platform (else from where it is), with the heading
    the rule gives from its heading now. Every radar's platform must be a
    :class:`LatticeMovable` on the tracker's map.
    """

    tracker: Any = Property(doc="The PMBStoneSoupTracker whose undetected intensity counts.")
    dt: float = Property(default=1.0, doc="Step (s) to the looks.")
    process_noise: float = Property(default=0.05, doc="q (m^2/s^3) of the planning model.")
    visibility: str = Property(default="probabilistic", doc="Visibility mode.")
    planning_detection: str = Property(default="aware", doc="``aware`` or ``ignore``.")
    search_weight: float | None = Property(default=None, doc="w (nats per found target).")
    position_mapping: Sequence[int] | None = Property(default=None,
                                                      doc="Ground x, y in the states.")
    velocity_mapping: Sequence[int] | None = Property(default=None,
                                                      doc="Ground vx, vy in the states.")

    def problem_and_plan(self, config: Mapping[Any, Sequence[Action]], tracks: Iterable[Track]
                         ) -> tuple[PlanningProblem, Plan]:
        """The one-step planning problem and plan (core frame) a configuration means."""
        ordered = ordered_tracks(tracks)
        index = {str(t.id): j for j, t in enumerate(ordered)}
        moves: dict[int, LatticeMoveAction] = {}
        aims: dict[int, AimAction] = {}
        radars: list[SensorplanRadar] = []
        for actionable, actions in config.items():
            for action in actions:
                if isinstance(action, LatticeMoveAction):
                    moves[id(getattr(actionable, "movement_controller", actionable))] = action
                elif isinstance(action, AimAction):
                    aims[id(actionable)] = action
            for radar in _radars_of(actionable):
                if all(radar is not r for r in radars):
                    radars.append(radar)
        if not radars:
            raise ValueError("the configuration holds no SensorplanRadar")
        world = self.tracker.world
        N = len(radars)
        start, moved = np.zeros((N, 2)), np.full((N, 1, 2), np.nan)
        targets, sectors = np.full((N, 1), -1), np.full((N, 1), -1)
        params = []
        for i, radar in enumerate(radars):
            movable = radar.movement_controller
            if not isinstance(movable, LatticeMovable) or movable.world != world:
                raise TypeError("every radar must sit on a platform with a LatticeMovable "
                                "on the tracker's map")
            start[i] = radar.ground_position
            params.append(dataclasses.replace(radar.params, moves=tuple(
                float(s) for s in movable.move_distances)))
            aim = aims.get(id(radar))
            if aim is None or aim.hold:
                continue
            if isinstance(aim.target, SearchSector):
                sectors[i, 0] = aim.target.index
            elif str(getattr(aim.target, "id", None)) in index:
                targets[i, 0] = index[str(aim.target.id)]
            else:
                continue
            move = moves.get(id(movable))
            end = (movable.ground_position if move is None
                   else np.asarray(move.target_value, dtype=float).ravel()[:2])
            step = end - movable.ground_position
            moved[i, 0] = start[i] + step - world.origin
        means, covs = from_tracks(ordered, self.position_mapping, self.velocity_mapping)
        means[:, :2] -= world.origin
        problem = PlanningProblem(
            means=means, covs=0.5 * (covs + np.swapaxes(covs, -1, -2)),
            positions=start - world.origin, headings=np.array([r.heading for r in radars]),
            sensors=tuple(params), horizon=1, dt=float(self.dt),
            process_noise=float(self.process_noise), world=world.core,
            visibility=self.visibility, planning_detection=self.planning_detection,
            existence=existence_of(ordered), search="on",
            search_sectors=tuple(int(r.search_sectors) for r in radars),
            undetected=self.tracker.undetected_intensity(self.search_weight))
        return problem, Plan(moved, targets, sectors)

    def __call__(self, config: Mapping[Any, Sequence[Action]], tracks: Iterable[Track],
                 metric_time: datetime.datetime, *args: Any, **kwargs: Any) -> float:
        problem, plan = self.problem_and_plan(config, tracks)
        return float(search.potential(problem, plan)[0])
