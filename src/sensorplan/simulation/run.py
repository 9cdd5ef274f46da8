"""Closed-loop simulation: truth, sensors, trackers and a planner in the loop.

One run (:func:`run_episode`) alternates decisions and execution:

- At each decision time the trackers' means and covariances and the platforms' poses form a
  :class:`~sensorplan.planners.problem.PlanningProblem`; the planner named in :class:`RunSettings`
  returns a plan of K epochs. ``olf`` (open-loop feedback, rolling horizon) executes its
  first epoch and plans again, so decisions fall every ``e`` steps; ``ol`` (open loop)
  executes all K epochs, so decisions fall every ``K e`` steps.
- At the start of an epoch each platform moves to its planned position and turns (heading
  rule, at most ``max_turn``) toward its planned target's current estimate predicted to the
  epoch's first step; it keeps position, heading and target for the epoch's ``e`` steps.
- Every step: the targets move; the filters predict; every sensor whose target is truly in
  its field of view measures it (the radar model of :mod:`sensorplan.models.radar` at the true
  position: its noise-free measurement plus noise with ``R`` at the true position);
  a look that misses feeds the ``negative`` miss update when enabled, for all
  missed looks in sensor order before the measurement updates, which are also applied in
  sensor order. Looks at distinct tracks are independent, so they are batched into one
  call (``ekf.update_rounds``); a track looked at by several sensors is updated once per
  look, in sensor order.

Randomness: the run's ``SeedSequence`` has four independent children, in this order:
``truth`` (initial target states and sensor poses, then the target motion), ``init`` (the
initial estimation errors), ``noise`` (one child per sensor; every sensor draws its two
standard normals at every step whether it measures or not) and ``planner`` (one generator
passed to every planning call). The truth, initial estimates and noise of a run are
therefore the same for every planner and setting (common random numbers: comparisons
between methods are paired).
"""

from __future__ import annotations

import io
import json
import math
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._types import BoolArray, FloatArray, IntArray, IntegerArray
from ..errors import ConfigError
from ..models import radar
from ..models.angles import heading_rule, wrap_angle
from ..models.sensors import ALTITUDE, CLUTTER_RATE, SWERLING, radar_table
from ..planners import checked_plan, make_planner
from ..planners.problem import PlanningProblem
from ..tracking.ekf import nees
from ..tracking.tracker import Tracker
from .scenario import Scenario, draw_initial, make_truth
from .settings import EXECUTIONS, RunSettings

__all__ = ["EXECUTIONS", "STREAMS", "Episode", "RunSettings", "run_episode", "run_streams"]
#: Names of the run's independent random streams, in spawn order (a new stream is only ever
#: appended, so the earlier ones keep their values).
STREAMS = ("truth", "init", "noise", "planner", "detection", "clutter")


def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


@dataclass(frozen=True)
class Episode:
    """Everything recorded in one closed-loop run.

    Index 0 of the step axis is the initial state, ``1..S`` the state after each step; step
    ``t`` is the move from time ``t - 1`` to ``t`` and its looks measure the truth at ``t``.

    Attributes
    ----------
    target_kinds : (M,) tuple of str
    truth : (S+1, M, 4)               true states
    estimate : (S+1, M, 4)            filter means after the step's updates
    cov : (S+1, M, 4, 4)              filter covariances
    error : (S+1, M)                  position error ``|p_true - p_est|`` (m)
    nees : (S+1, M)                   full-state NEES
    measured : (S+1, M, N) bool       ``measured[t, j, i]``: sensor i measured target j at t
    looked : (S+1, N) int             target sensor i pointed at during step t (-1: none,
                                      always at t = 0)
    missed : (S+1, N) bool            sensor i's look at step t missed (target truly
                                      outside its field of view)
    negative_update : (S+1, M) bool   track j got a negative (missed-look) update at t
    inflated : (S+1, M) bool          track j got the f >= 0.95 inflation at t
    gated_out : (S+1, M, N) bool      sensor i's detection of target j at t fell outside the
                                      validation gate (discarded, or used to restart)
    restarted : (S+1, M) bool         track j was restarted from a detection at t
    map_corrected : (S+1, M) bool     the known map corrected track j at t
    detections : (S+1, N) int         detections sensor i's look returned at t (its target's
                                      and false alarms)
    false_alarms : (S+1, N) int       of which false alarms
    used : (S+1, N) int               detections the tracker used
    discarded : (S+1, N) int          detections outside the validation gate
    sensor_positions : (S+1, N, 2)    pose during step t (initial pose at t = 0)
    sensor_headings : (S+1, N)
    decision_steps : (D,) int         time index at which each decision was taken
    planning_seconds : (D,)           each decision's planning time (s): the planner's own
                                      measure (``PlanResult.seconds``, without one-off
                                      start-up), else the wall time of its call
    potential : (D,)                  Phi of each decision's plan (nats)
    converged : (D,)                  1.0/0.0, NaN for planners without the notion
    sweeps : (D,)                     NaN for planners without the notion
    settings : RunSettings
    seed_entropy : int                entropy of the run's SeedSequence
    seed_spawn_key : tuple of int     its spawn key (the run's seed is
                                      ``SeedSequence(seed_entropy, spawn_key=seed_spawn_key)``)
    """

    target_kinds: tuple[str, ...]
    truth: FloatArray
    estimate: FloatArray
    cov: FloatArray
    error: FloatArray
    nees: FloatArray
    measured: BoolArray
    looked: IntArray
    missed: BoolArray
    negative_update: BoolArray
    inflated: BoolArray
    gated_out: BoolArray
    restarted: BoolArray
    map_corrected: BoolArray
    detections: IntegerArray
    false_alarms: IntegerArray
    used: IntegerArray
    discarded: IntegerArray
    sensor_positions: FloatArray
    sensor_headings: FloatArray
    decision_steps: IntArray
    planning_seconds: FloatArray
    potential: FloatArray
    converged: FloatArray
    sweeps: FloatArray
    settings: RunSettings
    seed_entropy: int
    seed_spawn_key: tuple[int, ...] = ()

    def rmse(self) -> FloatArray:
        """Position RMSE ``(M,)`` of each target over steps ``1..S`` (m)."""
        return np.sqrt(np.mean(self.error[1:] ** 2, axis=0))

    def save(self, path: str | Path) -> Path:
        """Write every array and a JSON metadata entry to an ``.npz`` file.

        The archive is byte-for-byte reproducible: its entries are written in a fixed order
        with a fixed timestamp, and the one wall-clock quantity, ``planning_seconds``, goes
        to a sidecar ``<name>.timing.json``, so the same seed gives identical ``.npz`` files.

        Returns the path of the sidecar.
        """
        path = Path(path)
        meta = {"target_kinds": list(self.target_kinds), "settings": self.settings.to_dict(),
                "seed_entropy": self.seed_entropy,
                "seed_spawn_key": [int(k) for k in self.seed_spawn_key]}
        entries = [(name, np.ascontiguousarray(getattr(self, name))) for name in _ARRAYS]
        entries.append(("meta", np.array(json.dumps(meta, sort_keys=True, default=_json))))
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for name, arr in entries:
                buf = io.BytesIO()
                np.lib.format.write_array(buf, arr, allow_pickle=False)
                info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                zf.writestr(info, buf.getvalue())
        sidecar = _timing_path(path)
        sidecar.write_text(json.dumps({"planning_seconds": self.planning_seconds.tolist()}))
        return sidecar

    @classmethod
    def load(cls, path: str | Path) -> Episode:
        """Read an episode written by :meth:`save` (timings NaN if the sidecar is missing)."""
        path = Path(path)
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in _ARRAYS}
            meta = json.loads(str(data["meta"]))
        sidecar = _timing_path(path)
        if sidecar.exists():
            seconds = np.array(json.loads(sidecar.read_text())["planning_seconds"], dtype=float)
        else:
            seconds = np.full(len(arrays["decision_steps"]), np.nan)
        return cls(target_kinds=tuple(meta["target_kinds"]),
                   settings=RunSettings.from_dict(meta["settings"], trusted=True),
                   seed_entropy=meta["seed_entropy"],
                   seed_spawn_key=tuple(int(k) for k in meta.get("seed_spawn_key", ())),
                   planning_seconds=seconds, **arrays)


def _timing_path(path: Path) -> Path:
    return path.with_name(path.stem + ".timing.json")


_ARRAYS = ("truth", "estimate", "cov", "error", "nees", "measured", "looked", "missed",
           "negative_update", "inflated", "gated_out", "restarted", "map_corrected",
           "detections", "false_alarms", "used", "discarded", "sensor_positions",
           "sensor_headings", "decision_steps", "potential", "converged", "sweeps")


def _json(v: Any) -> Any:
    """JSON fallback for planner parameters (numpy scalars, arrays, tuples)."""
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"cannot store {type(v).__name__} in episode metadata")


def run_streams(seed: int | np.random.SeedSequence) -> dict[str, np.random.SeedSequence]:
    """The run's independent seed sequences, named as in :data:`STREAMS`.

    Equal to ``SeedSequence(seed).spawn(len(STREAMS))`` but without mutating a given
    sequence, so the same ``SeedSequence`` passed to several runs (e.g. one per method)
    gives every run the same streams.
    """
    if isinstance(seed, np.random.SeedSequence):
        ss = seed
    else:
        if not _is_int(seed) or seed < 0:
            raise ConfigError("seed", f"must be an integer >= 0, got {seed!r}")
        ss = np.random.SeedSequence(int(seed))
    return {name: np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (k,),
                                         pool_size=ss.pool_size)
            for k, name in enumerate(STREAMS)}


def _imperfect(table: FloatArray) -> bool:
    """Whether some sensor misses targets in view or reports false alarms."""
    return bool(table[:, SWERLING].any() or table[:, CLUTTER_RATE].any())


class _DetectionDraws:
    """A run's detection outcomes and false alarms, drawn up front from their own streams.

    Per sensor and step: one uniform decides whether a target in view is detected
    (``u < Pd``), drawn whether the sensor looks or not; a Poisson count of false alarms
    (mean ``clutter_rate``) and, per false alarm, two uniforms (its ground range and
    azimuth, uniform in area over the sensing region) and two standard normals (its
    measurement noise). The draws depend only on the run's seed, so every method of a study
    sees the same ones (common random numbers).
    """

    def __init__(self, table: FloatArray, streams: dict[str, np.random.SeedSequence],
                 S: int) -> None:
        N = len(table)
        self.table = table
        self.u = np.stack([np.random.default_rng(c).random(S)
                           for c in streams["detection"].spawn(N)], axis=1)   # (S, N)
        self.counts = np.zeros((S, N), dtype=np.int64)
        self.points: list[list[tuple[FloatArray, FloatArray]]] = []
        for i, c in enumerate(streams["clutter"].spawn(N)):
            rng = np.random.default_rng(c)
            lam = table[i, CLUTTER_RATE]
            counts = rng.poisson(lam, S) if lam > 0 else np.zeros(S, dtype=np.int64)
            draws = rng.random((int(counts.sum()), 2))
            normals = rng.standard_normal((int(counts.sum()), 2))
            self.counts[:, i] = counts
            split = np.cumsum(counts)[:-1]
            self.points.append(list(zip(np.split(draws, split), np.split(normals, split))))

    def detected(self, t: int, target_xy: FloatArray, sensor_xy: FloatArray) -> BoolArray:
        """Whether each sensor's look would detect its target if in view, at step t."""
        pd = radar.detection_probabilities(self.table, np.arange(len(self.table)),
                                           target_xy, sensor_xy)
        return self.u[t - 1] < pd

    def looks(self, t: int, seen: BoolArray, z: FloatArray, pos: FloatArray, head: FloatArray,
              assigned: BoolArray) -> tuple[list[FloatArray], IntegerArray]:
        """Each sensor's detections at step t (its target's if seen, then its false alarms
        in the sensing region), and its number of false alarms."""
        sets, false = [], np.zeros(len(self.table), dtype=np.int16)
        for i in range(len(self.table)):
            clutter = self._clutter_of(i, t, pos[i], head[i]) if assigned[i] \
                else np.zeros((0, 2))
            false[i] = len(clutter)
            sets.append(np.concatenate(([z[i:i + 1]] if seen[i] else []) + [clutter]))
        return sets, false

    def _clutter_of(self, i: int, t: int, sxy: FloatArray, heading: float) -> FloatArray:
        u, n = self.points[i][t - 1]
        if len(u) == 0:
            return np.zeros((0, 2))
        xy = radar.clutter_points(self.table[i], sxy, heading, u)
        h, _, var, inside = radar.measure_looks(self.table, np.full(len(u), i), xy, sxy,
                                                np.full(len(u), heading))
        zc = h + np.sqrt(var) * n
        zc[:, 1] = wrap_angle(zc[:, 1])
        # Points behind the boresight plane (cos psi <= 0) are outside the sensing region.
        return zc[inside]


def _miss_update_kernel() -> Callable[..., tuple[FloatArray, ...]]:
    from ..tracking.missed import miss_update  # lazy: only runs with ``negative`` need it

    return miss_update


def run_episode(scenario: Scenario, settings: RunSettings,
                seed: int | np.random.SeedSequence,
                progress: Callable[[int, int], None] | None = None) -> Episode:
    """Simulate one closed-loop run.

    Parameters
    ----------
    scenario : Scenario
    settings : RunSettings
    seed : int >= 0 or numpy.random.SeedSequence
        The run's seed; see the module docstring for the streams spawned from it.
    progress : callable(done, total), optional
        Called after every step with the number of steps done and S.

    Returns
    -------
    Episode
    """
    streams = run_streams(seed)
    seed_ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(
        int(seed))
    truth_rng = np.random.default_rng(streams["truth"])
    init_rng = np.random.default_rng(streams["init"])
    planner_rng = np.random.default_rng(streams["planner"])
    miss_update = _miss_update_kernel() if settings.tracker.miss_update == "negative" else None
    planner = make_planner(settings.planner, **settings.planner_params)

    S, K, e = settings.steps, settings.horizon, settings.steps_per_epoch
    M, N = len(scenario.targets), len(scenario.sensors)
    sensor_list = tuple(s.params for s in scenario.sensors)
    table = radar_table(sensor_list)
    max_turn = np.array([float(p.max_turn) for p in sensor_list])

    init = draw_initial(scenario, truth_rng, init_rng)
    truth_model = make_truth(scenario, init.truth, truth_rng)
    P0 = np.array(scenario.initial_cov)
    tracker = Tracker(init.estimate, P0, scenario.dt, table,
                      world=(scenario.world.width, scenario.world.height)
                      if settings.tracker.known_map else None,
                      restart_velocity_var=(P0[2, 2], P0[3, 3]),
                      buildings=scenario.building_array,
                      **settings.tracker.tracker_options())
    # All noise up front: each sensor's stream yields 2 normals per step in order, so this
    # equals drawing them step by step, and a sensor draws whether it measures or not.
    noise = np.stack([np.random.default_rng(c).standard_normal((S, 2))
                      for c in streams["noise"].spawn(N)], axis=1)           # (S, N, 2)
    detect = _DetectionDraws(table, streams, S) if _imperfect(table) else None

    truth = np.empty((S + 1, M, 4))
    estimate = np.empty((S + 1, M, 4))
    cov = np.empty((S + 1, M, 4, 4))
    measured = np.zeros((S + 1, M, N), dtype=bool)
    looked = np.full((S + 1, N), -1, dtype=np.int64)
    missed = np.zeros((S + 1, N), dtype=bool)
    negative = np.zeros((S + 1, M), dtype=bool)
    inflated = np.zeros((S + 1, M), dtype=bool)
    gated_out = np.zeros((S + 1, M, N), dtype=bool)
    detections = np.zeros((S + 1, N), dtype=np.int16)
    false_alarms = np.zeros((S + 1, N), dtype=np.int16)
    used = np.zeros((S + 1, N), dtype=np.int16)
    discarded = np.zeros((S + 1, N), dtype=np.int16)
    restarted = np.zeros((S + 1, M), dtype=bool)
    map_corrected = np.zeros((S + 1, M), dtype=bool)
    positions = np.empty((S + 1, N, 2))
    headings = np.empty((S + 1, N))
    decisions: list[tuple[int, float, float, float, float]] = []

    truth[0] = init.truth
    estimate[0] = tracker.means
    cov[0] = tracker.covs
    positions[0] = init.positions
    headings[0] = init.headings
    pos = init.positions.copy()
    head = init.headings.copy()
    sensor_index = np.arange(N)
    epochs_per_plan = K if settings.execution == "ol" else 1
    # Replaced at the first step, which is always a decision.
    plan_targets, plan_positions = np.full((N, 0), -1, dtype=np.int64), np.zeros((N, 0, 2))
    epoch = epochs_per_plan
    target = np.full(N, -1, dtype=np.int64)
    F = tracker.F
    # Load the compiled kernels now, so that no decision's time includes it (the planners
    # warm them too, before starting their clock; a planner of another package may not).
    from ..planners._chains_nb import warm_up

    warm_up()

    planning_buildings = (scenario.building_array if settings.planning_occlusion == "aware"
                          else np.zeros((0, 5)))
    try:
        for t in range(1, S + 1):
            if (t - 1) % e == 0:
                if epoch == epochs_per_plan:
                    problem = PlanningProblem(
                        means=tracker.means, covs=tracker.covs, positions=pos, headings=head,
                        sensors=sensor_list, horizon=K, steps_per_epoch=e, dt=scenario.dt,
                        process_noise=tracker.planning_process_noise(), world=scenario.world,
                        visibility=settings.visibility, objective=settings.objective,
                        planning_detection=settings.planning_detection,
                        buildings=planning_buildings)
                    start = time.perf_counter()
                    result = checked_plan(planner, problem, planner_rng, len(decisions))
                    seconds = _own_seconds(result, time.perf_counter() - start)
                    decisions.append((t - 1, seconds, float(result.potential),
                                      _nan_if_none(result.converged), _nan_if_none(result.sweeps)))
                    plan_targets = np.asarray(result.plan.targets)
                    plan_positions = np.asarray(result.plan.positions)
                    epoch = 0
                target = plan_targets[:, epoch]
                assigned = target >= 0
                pos = np.where(assigned[:, None], plan_positions[:, epoch], pos)
                aim = tracker.means[np.maximum(target, 0)] @ F[:2].T           # (N, 2)
                bearing = np.arctan2(aim[:, 1] - pos[:, 1], aim[:, 0] - pos[:, 0])
                head = np.where(assigned, heading_rule(head, bearing, max_turn), head)
                epoch += 1

            x_true = truth_model.step()
            map_corrected[t] = tracker.predict()

            # Looks at the truth: visibility and the sampled noise use the true position.
            tj = np.maximum(target, 0)
            h_true, _, var_true, seen = radar.measure_looks(table, sensor_index, x_true[tj, :2],
                                                            pos, head)
            assigned = target >= 0
            seen &= assigned
            if scenario.buildings:
                # A building in the line of sight hides the target (false alarms still occur).
                seen &= ~radar.hidden_looks(scenario.building_array, pos, table[:, ALTITUDE],
                                            x_true[tj, :2])
            if detect is not None:
                seen &= detect.detected(t, x_true[tj, :2], pos)
            z = h_true + np.sqrt(var_true) * noise[t - 1]
            z[:, 1] = wrap_angle(z[:, 1])
            sets = n_false = None
            if detect is not None:
                sets, n_false = detect.looks(t, seen, z, pos, head, assigned)
            empty = assigned & ~seen if sets is None else assigned & np.array(
                [len(d) == 0 for d in sets])
            miss = assigned & ~seen

            if miss_update is not None and empty.any():
                i = sensor_index[empty]
                negative[t], inflated[t] = tracker.miss(i, target[i], pos[i], head[i],
                                                        kernel=miss_update)

            if sets is not None and n_false is not None:
                i = sensor_index[assigned & ~empty]
                if i.size:
                    res = tracker.update_sets(i, target[i], [sets[n] for n in i], pos[i],
                                              head[i], kernel=miss_update)
                    negative[t] |= res.negative
                    restarted[t, target[i][res.restarted]] = True
                    map_corrected[t] |= res.map_corrected
                    used[t, i], discarded[t, i] = res.used, res.discarded
                    detections[t, i] = [len(sets[n]) for n in i]
                    false_alarms[t, i] = n_false[i]
                measured[t, target[seen], sensor_index[seen]] = True
            elif seen.any():
                i = sensor_index[seen]
                looks = tracker.update(i, target[i], z[i], pos[i], head[i])
                measured[t, target[i], i] = True
                gated_out[t, target[i], i] = looks.gated_out
                restarted[t, target[i][looks.restarted]] = True
                map_corrected[t] |= looks.map_corrected
                detections[t, i] = 1
                used[t, i] = looks.used
                discarded[t, i] = looks.gated_out

            truth[t] = x_true
            estimate[t] = tracker.means
            cov[t] = tracker.covs
            looked[t] = target
            missed[t] = miss
            positions[t] = pos
            headings[t] = head
            if progress is not None:
                progress(t, S)
    finally:
        # A planner that holds resources (agent processes) releases them with the run.
        close = getattr(planner, "close", None)
        if callable(close):
            close()

    error = np.hypot(truth[..., 0] - estimate[..., 0], truth[..., 1] - estimate[..., 1])
    d = np.array(decisions, dtype=float).reshape(-1, 5)
    return Episode(
        target_kinds=scenario.target_kinds, truth=truth, estimate=estimate, cov=cov,
        error=error, nees=nees(truth, estimate, cov), measured=measured, looked=looked,
        missed=missed, negative_update=negative, inflated=inflated, gated_out=gated_out,
        restarted=restarted, map_corrected=map_corrected, detections=detections,
        false_alarms=false_alarms, used=used, discarded=discarded, sensor_positions=positions,
        sensor_headings=headings,
        decision_steps=d[:, 0].astype(np.int64), planning_seconds=d[:, 1], potential=d[:, 2],
        converged=d[:, 3], sweeps=d[:, 4], settings=settings,
        seed_entropy=_entropy(seed_ss), seed_spawn_key=tuple(seed_ss.spawn_key))


def _entropy(ss: np.random.SeedSequence) -> Any:
    """The sequence's entropy: an int (a list of ints if it was built from one)."""
    e: Any = ss.entropy
    return int(e) if _is_int(e) or isinstance(e, int) else [int(v) for v in e]


def _own_seconds(result: Any, outside: float) -> float:
    """A decision's planning time: the planner's own measure (``PlanResult.seconds``, which
    leaves out one-off start-up), else the wall time of its call measured outside."""
    own = getattr(result, "seconds", None)
    if isinstance(own, (int, float)) and math.isfinite(own) and 0.0 < own <= outside:
        return float(own)
    return outside


def _nan_if_none(v: Any) -> float:
    return math.nan if v is None else float(v)

