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

from ...dynamics import cv_matrices
from ...planners import PlanResult, make_planner
from ...problem import PlanningProblem

from ._actionables import LatticeMovable, SensorplanRadar
from ._convert import from_tracks, ordered_tracks

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
