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
- With ``search = "on"`` the problem also holds the tracker's undetected intensity (the
  tracker seam's :func:`~sensorplan.tracking.base.undetected_report`) and each sensor's
  search sectors, a decision is taken even without a track, and a planned sector look turns
  toward its sector's bearing instead (the looks detect every target in the beam); the
  episode records each step's sector looks and each decision's mu and ``w mu``.
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

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..errors import ConfigError
from ..models.angles import heading_rule
from ..models.motion import cv_matrices
from ..models.sensors import radar_table
from ..planners import checked_plan, make_planner
from ..planners.problem import PlanningProblem, UndetectedIntensity
from ..tracking.base import Tracker, TrackSet, planning_tracks, undetected_report
from ..tracking.registry import tracker_class
from .episode import Episode, Recorder, _is_int
from .scenario import Scenario, draw_initial, make_population
from .sensing import Sensing
from .settings import EXECUTIONS, RunSettings, TrackerSettings, sector_counts

if TYPE_CHECKING:  # pragma: no cover
    from ..tracking.pmb.map_tracker import MapModel

__all__ = ["EXECUTIONS", "STREAMS", "Episode", "RunSettings", "run_episode", "run_streams"]
#: Names of the run's independent random streams, in spawn order (a new stream is only ever
#: appended, so the earlier ones keep their values).
STREAMS = ("truth", "init", "noise", "planner", "detection", "clutter", "target_detection",
           "births")


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
    if scenario.scan is not None:
        # A benchmark's sensor scans the whole map: nothing to plan.
        from .scan import run_scan_episode

        return run_scan_episode(scenario, settings, streams, seed_ss, progress)
    truth_rng = np.random.default_rng(streams["truth"])
    planner_rng = np.random.default_rng(streams["planner"])
    planner = make_planner(settings.planner, **settings.planner_params)
    S, e = settings.steps, settings.steps_per_epoch
    N = len(scenario.sensors)
    table = radar_table(tuple(s.params for s in scenario.sensors))

    init = draw_initial(scenario, truth_rng, np.random.default_rng(streams["init"]))
    truth_model = make_population(scenario, init.truth, truth_rng,
                                  np.random.default_rng(streams["births"]))
    tracker = make_tracker(scenario, settings, init.estimate, table)
    known = settings.tracker.kind == "known"
    sensing = Sensing(table, scenario.building_array, streams, S, scenario.look_detects,
                      aims_at_targets=known)
    record = Recorder(S, len(init.truth), N, known_targets=known)
    record.start(init.truth, tracker.tracks(), init.positions, init.headings)
    _record_intensity(record, 0, tracker)
    schedule = _Schedule(scenario, settings, planner, planner_rng, table, init)
    # Load the compiled kernels now, so that no decision's time includes it (the planners
    # warm them too, before starting their clock; a planner of another package may not).
    from .._compiled.prepare import warm_for_runs
    from ..planners._chains_nb import warm_up

    warm_for_runs()
    warm_up()
    try:
        for t in range(1, S + 1):
            if (t - 1) % e == 0:
                schedule.epoch(t, tracker, record)
            if schedule.searching:
                record.search(t, schedule.sectors)
            x_true, alive = truth_model.step()
            predicted = tracker.predict()
            looks, sensed = sensing.look(t, x_true, schedule.positions, schedule.headings,
                                         schedule.aimed, alive,
                                         getattr(truth_model, "heights", None))
            update = tracker.update(looks)
            record.pose(t, schedule.positions, schedule.headings)
            record.step(t, x_true, alive, tracker.tracks(), schedule.recorded, looks, sensed,
                        predicted, update)
            _record_intensity(record, t, tracker)
            if progress is not None:
                progress(t, S)
    finally:
        # A planner that holds resources (agent processes) releases them with the run.
        close = getattr(planner, "close", None)
        if callable(close):
            close()
    # Every target slot's kind: born targets take the templates in turn (slot s moves as
    # template s mod T).
    kinds = scenario.target_kinds
    slots = record.arrays["alive"].shape[1]
    return record.episode(tuple(kinds[s % len(kinds)] for s in range(slots)), settings,
                          seed_ss)


def _record_intensity(record: Recorder, t: int, tracker: Tracker) -> None:
    """Record the tracker's undetected intensity after step ``t`` (nothing for a tracker
    that keeps none)."""
    report = undetected_report(tracker)
    if report is not None:
        record.intensity(t, report.centres, report.weights)


def intensity_grid_shape(scenario: Scenario, tracker: TrackerSettings) -> tuple[int, int]:
    """``(ny, nx)``: the rows and columns of a multi-target tracker's undetected intensity
    grid on the scenario's map (cells at most ``tracker.grid_resolution`` m wide), the shape
    of :attr:`Episode.undetected`'s steps and of a study's stored intensity."""
    from ..tracking.pmb.undetected import make_grid

    grid = make_grid(scenario.world.width, scenario.world.height, tracker.grid_resolution,
                     1.0)
    return grid.ny, grid.nx


def map_edge(scenario: Scenario, tracker: TrackerSettings) -> str:
    """A multi-target tracker's model of the map's edge: ``tracker.map_edge``, or with
    ``"scenario"`` the scenario truth's: ``exit`` where targets leave the map (born at the
    edges, dying when they leave; a scripted benchmark truth, whose targets the walls do not
    turn back and the tracker no longer sees once they are off the map), ``closed`` where
    the walls turn every target back (no births, or births anywhere)."""
    if tracker.map_edge != "scenario":
        return tracker.map_edge
    return "exit" if scenario.births == "edges" or scenario.scripted is not None else "closed"


def map_model(scenario: Scenario, tracker: TrackerSettings, table: FloatArray) -> MapModel:
    """The map model of a multi-target tracker (``pmb``, ``gnn``) of the scenario: its
    radars (``table``), step, map, buildings and edge rule with the tracker settings'
    process noise, grid resolution and gate."""
    # Imported here: the known-target tracker's runs do without the PMB modules (and scipy).
    from ..tracking.pmb.map_tracker import MapModel

    lo, hi = scenario.speed_range
    # A target not yet detected moves at a speed uniform in speed_range, in a uniform
    # direction: each velocity component has variance E[s^2] / 2.
    return MapModel(table, scenario.dt, (scenario.world.width, scenario.world.height),
                    process_noise=tracker.process_noise, resolution=tracker.grid_resolution,
                    velocity_var=max((lo * lo + lo * hi + hi * hi) / 6.0, 1e-6),
                    speed_range=(lo, hi),
                    gate_probability=tracker.gate_probability,
                    map_edge=map_edge(scenario, tracker), buildings=scenario.building_array)


def lost_grid(scenario: Scenario, tracker: TrackerSettings, table: FloatArray) -> Any:
    """The grid of the known-target tracker's lost-target mode (None when it is off): the
    map in cells of ``lost_resolution``, the buildings closed, the velocity prior of the
    scenario's speeds (:func:`sensorplan.tracking.lost.velocity_variance`).

    Raises
    ------
    ConfigError
        The mode without the negative miss update, or with detection that is not ideal
        (missed detections, false alarms, looks that detect every target).
    """
    if not tracker.lost_mode:
        return None
    if tracker.miss_update != "negative":
        raise ConfigError("tracker.lost_mode", "needs miss_update = 'negative'")
    from ..models.sensors import CLUTTER_RATE, SWERLING

    if (table[:, SWERLING].any() or table[:, CLUTTER_RATE].any()
            or scenario.look_detects == "all"):
        raise ConfigError("tracker.lost_mode", "needs ideal detection: no missed detections, "
                          "no false alarms, a look detecting only its target")
    from ..tracking.lost import make_lost_grid, velocity_variance

    return make_lost_grid(scenario.world.width, scenario.world.height,
                          tracker.lost_resolution, velocity_variance(scenario.speed_range),
                          scenario.dt, scenario.building_array)


def make_tracker(scenario: Scenario, settings: RunSettings, estimate: FloatArray,
                 table: FloatArray) -> Tracker:
    """The run's tracker (``settings.tracker.kind``), started at the initial estimates
    ``(M, 4)`` with the scenario's initial covariance."""
    P0 = np.array(scenario.initial_cov)
    cls = tracker_class(settings.tracker.kind)
    tr = settings.tracker
    if tr.kind == "known":
        return cls(
            estimate, P0, scenario.dt, table,
            world=(scenario.world.width, scenario.world.height) if tr.known_map else None,
            restart_velocity_var=(P0[2, 2], P0[3, 3]), buildings=scenario.building_array,
            miss_update=_miss_update_kernel() if tr.miss_update == "negative" else None,
            detects_all=scenario.look_detects == "all",
            lost_grid=lost_grid(scenario, tr, table), **tr.tracker_options())
    model = map_model(scenario, tr, table)
    if tr.kind == "gnn":
        return cls(model, means=estimate, covs=P0, confirm_hits=tr.confirm_hits,
                   confirm_looks=tr.confirm_looks, delete_misses=tr.delete_misses)
    return cls(model, means=estimate, covs=P0, survival_probability=tr.survival_probability,
               established_survival=tr.established_survival or None,
               established_existence=tr.established_existence,
               births=tr.births, birth_rate=tr.birth_rate if tr.births != "none" else 0.0,
               background_birth_rate=tr.background_birth_rate,
               prune_threshold=tr.prune_threshold, report_threshold=tr.report_threshold,
               recycle_threshold=tr.recycle_threshold, recycle_motion=tr.recycle_motion,
               split_existence=tr.split_existence,
               density_components=tr.density_components,
               planning_threshold=tr.planning_threshold,
               termination_threshold=tr.termination_threshold, edge_exit=tr.edge_exit,
               birth_velocity=tr.birth_velocity, **tr.bernoulli_options())


class _Schedule:
    """The plan being executed: decisions when one is due, and each epoch's poses and aims.

    At a decision the tracks planning sees (:func:`~sensorplan.tracking.base.planning_tracks`:
    the reported ones, or with a PMB tracker's ``planning_threshold`` below its report
    threshold also fainter ones) and the platforms' poses form the planning problem; ``olf``
    executes the plan's first epoch, ``ol`` all K. At an epoch's start each platform moves to
    its planned position and turns (heading rule) toward its planned track's mean predicted
    to the epoch's first step. ``aimed`` indexes the tracks planning saw at the epoch's
    start, ``recorded`` the reported ones (-1 for a look at a track not reported), as the
    run's record wants.
    """

    def __init__(self, scenario: Scenario, settings: RunSettings, planner: Any,
                 rng: np.random.Generator, table: FloatArray, init: Any) -> None:
        self.scenario, self.settings, self.planner, self.rng = scenario, settings, planner, rng
        self.sensors = tuple(s.params for s in scenario.sensors)
        self.max_turn = np.array([float(p.max_turn) for p in self.sensors])
        self.positions = init.positions.copy()
        self.headings = init.headings.copy()
        N = len(self.sensors)
        self.aimed = np.full(N, -1, dtype=np.int64)
        self.recorded = self.aimed
        self.per_plan = settings.horizon if settings.execution == "ol" else 1
        self.epoch_index = self.per_plan                 # the first step is a decision
        self.plan_labels = np.full((N, 0), -1, dtype=np.int64)
        self.plan_positions = np.zeros((N, 0, 2))
        self.buildings = (scenario.building_array if settings.planning_occlusion == "aware"
                          else np.zeros((0, 5)))
        # Search looks: the sector each sensor's look of the current epoch points at (-1:
        # a track or none), and each plan epoch's.
        self.searching = settings.search == "on"
        self.sectors = np.full(N, -1, dtype=np.int64)
        self.plan_sectors = np.full((N, 0), -1, dtype=np.int64)
        if self.searching:
            from ..planners.search import sector_bearings

            self.sector_bearings = [sector_bearings(S) for S in
                                    sector_counts(settings.search_sectors, N)]

    def epoch(self, t: int, tracker: Tracker, record: Recorder) -> None:
        """Start the epoch that begins with step ``t`` (deciding first if a plan is due)."""
        tracks = planning_tracks(tracker)
        if self.epoch_index == self.per_plan:
            self._decide(t, tracks, tracker.planning_process_noise(), record, tracker)
        k = self.epoch_index
        label = self.plan_labels[:, k]
        self.aimed = tracks_index(tracks, label)
        self.recorded = tracks_index(tracker.tracks(), np.where(self.aimed >= 0, label, -1))
        assigned = self.aimed >= 0
        self.sectors = self.plan_sectors[:, k] if self.searching else self.sectors
        search = self.sectors >= 0
        if not len(tracks) and not search.any():  # nothing to look at: the sensors hold still
            self.epoch_index += 1
            return
        if search.any():
            # A search look moves as planned and aims the heading rule at its sector.
            assigned = assigned | search
        self.positions = np.where(assigned[:, None], self.plan_positions[:, k], self.positions)
        if len(tracks):
            F = cv_matrices(self.scenario.dt, 0.0)[0]
            aim = tracks.means[np.maximum(self.aimed, 0)] @ F[:2].T                # (N, 2)
            bearing = np.arctan2(aim[:, 1] - self.positions[:, 1],
                                 aim[:, 0] - self.positions[:, 0])
        else:
            bearing = np.zeros(len(self.positions))
        if search.any():
            bearing = np.where(search, [b[s] if s >= 0 else 0.0 for b, s in
                                        zip(self.sector_bearings, self.sectors)], bearing)
        self.headings = np.where(assigned, heading_rule(self.headings, bearing, self.max_turn),
                                 self.headings)
        self.epoch_index += 1

    def _reported(self, tracks: TrackSet, tracker: Tracker) -> BoolArray | None:
        """Which planned tracks the tracker reports, for the gospa reward's ``confirm``
        (None otherwise: planning values every track as reported)."""
        if self.settings.unreported != "confirm" or self.settings.reward != "gospa":
            return None
        return np.isin(tracks.labels, tracker.tracks().labels)

    def _decide(self, t: int, tracks: TrackSet, q: float | FloatArray, record: Recorder,
                tracker: Tracker) -> None:
        s = self.settings
        if not len(tracks) and not self.searching:
            # No track to plan on (a multi-target tracker that holds none): no decision;
            # every sensor keeps its pose for the plan's epochs.
            N = len(self.sensors)
            self.plan_labels = np.full((N, self.per_plan), -1, dtype=np.int64)
            self.plan_positions = np.repeat(self.positions[:, None], self.per_plan, axis=1)
            self.epoch_index = 0
            return
        search = self._search_problem(tracker) if self.searching else {}
        problem = PlanningProblem(
            means=tracks.means, covs=tracks.covs, positions=self.positions,
            headings=self.headings, sensors=self.sensors, horizon=s.horizon,
            steps_per_epoch=s.steps_per_epoch, dt=self.scenario.dt, process_noise=q,
            world=self.scenario.world, visibility=s.visibility, objective=s.objective,
            planning_detection=s.planning_detection, buildings=self.buildings,
            existence=tracks.existence, reported=self._reported(tracks, tracker),
            elapsed_epochs=(t - 1) // s.steps_per_epoch,     # where a fixed schedule stands
            **search)
        start = time.perf_counter()
        result = checked_plan(self.planner, problem, self.rng, len(record.decisions))
        seconds = _own_seconds(result, time.perf_counter() - start)
        record.decision(t - 1, seconds, float(result.potential),
                        _nan_if_none(result.converged), _nan_if_none(result.sweeps))
        targets = np.asarray(result.plan.targets)
        self.plan_labels = np.where(targets >= 0, tracks.labels[np.maximum(targets, 0)]
                                    if len(tracks) else -1, -1)
        self.plan_positions = np.asarray(result.plan.positions)
        if self.searching:
            self.plan_sectors = np.asarray(result.plan.sectors)
            record.search_term(*_search_term(problem, result))
        self.epoch_index = 0

    def _search_problem(self, tracker: Tracker) -> dict[str, Any]:
        """The search part of a decision's problem: the sectors and the tracker's
        undetected intensity now (before the step's predict: the planner predicts it)."""
        report = undetected_report(tracker)
        if report is None:
            raise ConfigError("search", "needs a tracker that keeps the intensity of "
                              "undetected targets (tracker.kind = 'pmb')")
        undetected = UndetectedIntensity(report.centres, report.weights, report.births,
                                         report.survival, report.cell_cov)
        return {"search": "on", "search_sectors": self.settings.search_sectors,
                "undetected": undetected, "reward": self.settings.reward,
                "gospa_c": self.settings.gospa_c, "find_tail": self.settings.find_tail,
                "track_existence": self.settings.track_existence}


def tracks_index(tracks: TrackSet, labels: IntArray) -> IntArray:
    """The index in ``tracks`` of each label (-1 for -1 or a label no longer reported)."""
    order = np.argsort(tracks.labels, kind="stable")
    ranked = tracks.labels[order]
    pos = np.clip(np.searchsorted(ranked, labels), 0, max(len(ranked) - 1, 0))
    found = (labels >= 0) & (len(ranked) > 0)
    found &= ranked[pos] == labels if len(ranked) else found
    return np.where(found, order[pos] if len(ranked) else -1, -1)


def _own_seconds(result: Any, outside: float) -> float:
    """A decision's planning time: the planner's own measure (``PlanResult.seconds``, which
    leaves out one-off start-up), else the wall time of its call measured outside."""
    own = getattr(result, "seconds", None)
    if isinstance(own, (int, float)) and math.isfinite(own) and 0.0 < own <= outside:
        return float(own)
    return outside


def _search_term(problem: PlanningProblem, result: Any) -> tuple[float, float]:
    """A searching decision's mu and w mu: the planner's own report (:class:`PlanResult`
    ``found`` and ``search_weight``), else Phi with search of its plan."""
    found, weight = getattr(result, "found", None), getattr(result, "search_weight", None)
    if found is None or weight is None:
        from ..planners import search

        ev = search.evaluate(search.prepare(problem), result.plan)
        found, weight = ev.found, ev.weight
    return float(found), float(weight) * float(found)


def _nan_if_none(v: Any) -> float:
    return math.nan if v is None else float(v)

