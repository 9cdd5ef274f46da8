"""Scenario values: the world, the targets' truth models and the sensors.

A scenario may fix initial target states and sensor poses or leave them to be drawn from a
run's seed (the paper draws them anew in every run): a field left ``None`` is drawn.
How a run plans and tracks is not part of the scenario: see :mod:`sensorplan.simulation.settings`.
Scenario files are read and written by :mod:`sensorplan.config.scenario`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from .._types import FloatArray
from ..errors import ConfigError
from ..models.sensors import SensorParams
from ..models.truth import TruthModel, inside_buildings
from ..planners.problem import MapRect, check_buildings, check_covariance

TargetKind = Literal["cv", "dubins"]
TARGET_KINDS = ("cv", "dubins")
#: Default start regions as fractions ``(a / n, b / n)`` of each map side: targets in the
#: middle two thirds, sensors all but the outer twelfths ([100, 500] and [50, 550] m on the
#: paper's 600 m map).
TARGET_BOX = (1, 5, 6)
SENSOR_BOX = (1, 11, 12)


@dataclass(frozen=True)
class TargetSpec:
    """One target's truth model and (optionally) its initial state.

    Attributes
    ----------
    kind : {"cv", "dubins"}
        ``cv``: the filter's CWNA model with wall mirroring; ``dubins``: constant speed,
        piecewise-constant turn rate redrawn every ``turn_hold`` s from
        ``[-max_turn_rate, max_turn_rate]``, exact arcs, reflection at walls.
    position : (x, y) or None      drawn uniformly in the scenario's ``target_box`` if None
    speed : float or None          drawn uniformly in ``speed_range`` if None (m/s)
    heading : float or None        drawn uniformly in (-pi, pi] if None (rad)
    turn_hold : float              s, dubins only
    max_turn_rate : float          rad/s, dubins only
    """

    kind: str = "cv"
    position: tuple[float, float] | None = None
    speed: float | None = None
    heading: float | None = None
    turn_hold: float = 10.0
    max_turn_rate: float = 0.1


@dataclass(frozen=True)
class SensorSpec:
    """One platform: its radar parameters and (optionally) its initial pose."""

    params: SensorParams = field(default_factory=SensorParams)
    position: tuple[float, float] | None = None   # drawn uniformly in sensor_box if None
    heading: float | None = None                  # drawn uniformly in (-pi, pi] if None


@dataclass(frozen=True)
class Scenario:
    """World, targets and sensors.

    Attributes
    ----------
    world : MapRect
    dt : float                       simulation step (s)
    process_noise : float            q (m^2/s^3), filter model and ``cv`` truth
    targets, sensors : tuples of TargetSpec / SensorSpec
    target_box : (lo, hi) or None    initial target positions uniform in [lo, hi]^2, inside
                                     the map; None: the middle two thirds of each map side
                                     (:data:`TARGET_BOX`, [100, 500] on the 600 m map)
    speed_range : (lo, hi)           initial target speeds (m/s)
    sensor_box : (lo, hi) or None    initial sensor positions uniform in [lo, hi]^2, inside
                                     the map; None: all but 1/12 of each side at both ends
                                     (:data:`SENSOR_BOX`, [50, 550] on the 600 m map)
    initial_cov : (4, 4)             P0: initial estimate = truth + N(0, P0)
    buildings : tuple of (x0, y0, x1, y1, height)
        Buildings: axis-aligned boxes on the ground (m) that hide targets from sensors
        and that targets reflect off; every sensor flies above all of them.
    """

    world: MapRect = field(default_factory=MapRect)
    dt: float = 1.0
    process_noise: float = 0.05
    targets: tuple[TargetSpec, ...] = ()
    sensors: tuple[SensorSpec, ...] = ()
    target_box: tuple[float, float] | None = None
    speed_range: tuple[float, float] = (3.0, 6.0)
    sensor_box: tuple[float, float] | None = None
    initial_cov: tuple[tuple[float, ...], ...] = (
        (400.0, 0.0, 0.0, 0.0), (0.0, 400.0, 0.0, 0.0), (0.0, 0.0, 4.0, 0.0), (0.0, 0.0, 0.0, 4.0))
    buildings: tuple[tuple[float, float, float, float, float], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "targets", tuple(self.targets))
        object.__setattr__(self, "sensors", tuple(self.sensors))
        object.__setattr__(self, "buildings",
                           tuple(tuple(float(v) for v in b) for b in self.buildings))
        # On a square map the default boxes are squares like any given box: fill them in,
        # so that a scenario equals its written-out form.
        w, h = self.world.width, self.world.height
        if w == h and math.isfinite(w) and w > 0:
            for name, (a, b, n) in (("target_box", TARGET_BOX), ("sensor_box", SENSOR_BOX)):
                if getattr(self, name) is None:
                    object.__setattr__(self, name, (w * a / n, w * b / n))
        self.validate()

    def start_region(self, which: str) -> tuple[FloatArray, FloatArray]:
        """Lower and upper corners ``(x, y)`` of the region where ``which`` (``"targets"``
        or ``"sensors"``) start: the given box squared, else the default fractions of each
        map side."""
        box = self.target_box if which == "targets" else self.sensor_box
        if box is not None:
            return np.array([box[0], box[0]], float), np.array([box[1], box[1]], float)
        a, b, n = TARGET_BOX if which == "targets" else SENSOR_BOX
        side = np.array([self.world.width, self.world.height], float)
        return side * a / n, side * b / n

    @property
    def building_array(self) -> FloatArray:
        """The buildings as a ``(K, 5)`` array ``x0, y0, x1, y1, height``."""
        return np.array(self.buildings, dtype=float).reshape(-1, 5)

    @property
    def target_kinds(self) -> tuple[str, ...]:
        return tuple(t.kind for t in self.targets)

    def validate(self) -> None:
        """The decision file's rules that apply to scenarios, and the ranges of
        :data:`sensorplan.limits.RANGES`; raise ConfigError naming the field."""
        from ..limits import (MAX_SENSORS, MAX_TARGETS, MAX_TURNS_PER_STEP, RANGES, check_count,
                              check_covariance_scale)

        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ConfigError("dt", "must be a finite number > 0")
        RANGES["dt"].check(self.dt, "dt")
        if not (math.isfinite(self.process_noise) and self.process_noise >= 0):
            raise ConfigError("process_noise", "must be a finite number >= 0")
        RANGES["process_noise"].check(self.process_noise, "process_noise")
        for name in ("width", "height"):
            v = getattr(self.world, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"map.{name}", "must be a finite number > 0")
            RANGES["length"].check(v, f"map.{name}")
        if not self.targets:
            raise ConfigError("targets", "at least one target is required")
        if not self.sensors:
            raise ConfigError("sensors", "at least one sensor is required")
        check_count(len(self.targets), MAX_TARGETS, "targets", "targets")
        check_count(len(self.sensors), MAX_SENSORS, "sensors", "sensors")
        for name in ("target_box", "speed_range", "sensor_box"):
            if getattr(self, name) is None:
                continue
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ConfigError(f"initial.{name}", "must be finite with lo <= hi")
        W, H = self.world.width, self.world.height
        for name in ("target_box", "sensor_box"):
            box = getattr(self, name)
            if box is not None and not (0.0 <= box[0] and box[1] <= min(W, H)):
                raise ConfigError(f"initial.{name}", f"[{box[0]:g}, {box[1]:g}] squared must "
                                  f"lie inside the map [0, {W:g}] x [0, {H:g}] (leave it out "
                                  "to scale the default to the map)")
        if self.speed_range[0] < 0:
            raise ConfigError("initial.speed_range", "speeds must be >= 0")
        for v in self.speed_range:
            RANGES["speed"].check(v, "initial.speed_range")
        P0 = np.array(self.initial_cov, dtype=float)
        if P0.shape == (4, 4) and np.all(np.isfinite(P0)):
            for v in P0.ravel():
                RANGES["covariance"].check(v, "initial.cov")
        check_covariance(P0, "initial.cov")
        check_covariance_scale(P0, "initial.cov")
        for j, t in enumerate(self.targets):
            if t.kind not in TARGET_KINDS:
                raise ConfigError(f"targets[{j}].kind", f"must be one of {TARGET_KINDS}")
            if t.position is not None and not (np.all(np.isfinite(t.position))
                                               and self.world.contains(np.array(t.position))):
                raise ConfigError(f"targets[{j}].position", f"is outside the map [0, {W:g}] "
                                  f"x [0, {H:g}]")
            if t.turn_hold <= 0 or not math.isfinite(t.turn_hold):
                raise ConfigError(f"targets[{j}].turn_hold", "must be a finite number > 0")
            if t.max_turn_rate < 0 or not math.isfinite(t.max_turn_rate):
                raise ConfigError(f"targets[{j}].max_turn_rate", "must be a finite number >= 0")
            RANGES["turn_hold"].check(t.turn_hold, f"targets[{j}].turn_hold")
            if t.kind == "dubins" and t.turn_hold * MAX_TURNS_PER_STEP < self.dt:
                raise ConfigError(f"targets[{j}].turn_hold", f"must be at least dt / "
                                  f"{MAX_TURNS_PER_STEP} = {self.dt / MAX_TURNS_PER_STEP:g} s "
                                  f"(at most {MAX_TURNS_PER_STEP} turn-rate draws per step), "
                                  f"got {t.turn_hold!r}")
            RANGES["max_turn_rate"].check(t.max_turn_rate, f"targets[{j}].max_turn_rate",
                                          " (angles are in radians; degrees per second are "
                                          "written max_turn_rate_deg)")
            if t.speed is not None:
                RANGES["speed"].check(t.speed, f"targets[{j}].speed")
            if t.heading is not None:
                RANGES["heading"].check(t.heading, f"targets[{j}].heading")
        for i, s in enumerate(self.sensors):
            s.params.validate(f"sensors[{i}]")
            if s.position is not None and not (np.all(np.isfinite(s.position))
                                               and self.world.contains(np.array(s.position))):
                raise ConfigError(f"sensors[{i}].position", f"is outside the map [0, {W:g}] "
                                  f"x [0, {H:g}]")
            if s.heading is not None:
                RANGES["heading"].check(s.heading, f"sensors[{i}].heading")
        self._validate_buildings()

    def _validate_buildings(self) -> None:
        check_buildings(self.buildings, self.world, [s.params.altitude for s in self.sensors])
        blds = self.building_array
        for j, t in enumerate(self.targets):
            if t.position is not None and inside_buildings(np.array(t.position), blds):
                raise ConfigError(f"targets[{j}].position", "is inside a building")


def paper_scenario(**radar: Any) -> Scenario:
    """The paper's scenario: M = 5 (3 ``cv``, 2 ``dubins``), N = 3 sensors at 490/500/510 m.

    Initial target states and sensor poses are left to each run's seed. ``radar`` gives
    every sensor further :class:`SensorParams` fields (the ``radar`` preset's detection).
    """
    targets = tuple(TargetSpec(kind=k) for k in ("cv", "cv", "cv", "dubins", "dubins"))
    sensors = tuple(SensorSpec(SensorParams(altitude=a, **radar)) for a in (490.0, 500.0, 510.0))
    return Scenario(targets=targets, sensors=sensors)


#: Detection of the ``radar`` preset (docs/model.md, "Detection and false alarms"): a
#: Swerling 1 target behind a CFAR detector with a false-alarm probability of 1e-6 per
#: resolution cell, and one false detection per look from clutter residue.
RADAR_DETECTION = {"detection": "swerling1", "false_alarm_probability": 1e-6,
                   "clutter_rate": 1.0}


def radar_scenario() -> Scenario:
    """The paper's scenario with real radar conditions: Swerling 1 detection (Pd about
    0.5-0.7 over the sensing region) and one false alarm per look (see
    :data:`RADAR_DETECTION`)."""
    return paper_scenario(**RADAR_DETECTION)


def town_buildings(half_size: float = 30.0
                   ) -> tuple[tuple[float, float, float, float, float], ...]:
    """A town centre on the paper's 600 x 600 m map: a 3 x 3 grid of square buildings
    centred at 160, 300 and 440 m on each axis (the target area's middle), ``2 half_size``
    m wide, 150 m tall in the centre, 90 m at the middle of each side and 45 m at the
    corners. With the default 30 m half size: 60 m blocks on 80 m streets, 20 % of the
    area where targets start. Chosen once, from typical downtown proportions, before any
    run."""
    heights = ((45.0, 90.0, 45.0), (90.0, 150.0, 90.0), (45.0, 90.0, 45.0))
    centres = (160.0, 300.0, 440.0)
    return tuple((cx - half_size, cy - half_size, cx + half_size, cy + half_size, heights[a][b])
                 for a, cx in enumerate(centres) for b, cy in enumerate(centres))


def urban_scenario() -> Scenario:
    """The paper's scenario in a town centre (:func:`town_buildings`): targets drive the
    streets and reflect off the walls, and a building between a sensor and a target hides
    it."""
    return dataclasses.replace(paper_scenario(), buildings=town_buildings())


#: The ``slow`` preset's move distances (m per step): a quarter of the paper's 20 and 40 m.
SLOW_MOVES = (5.0, 10.0)


def slow_scenario() -> Scenario:
    """The paper's scenario with slow platforms: every sensor moves 5 or 10 m per step (a
    quarter of the paper's 20 and 40 m), so it must reposition for several steps before it
    can see a target it is not placed for. The "speed x0.25" condition of docs/results.md,
    "Where looking ahead pays", where planning three epochs ahead beats myopic planning."""
    scenario = paper_scenario()
    sensors = tuple(dataclasses.replace(s, params=dataclasses.replace(s.params, moves=SLOW_MOVES))
                    for s in scenario.sensors)
    return dataclasses.replace(scenario, sensors=sensors)


def swarm_scenario() -> Scenario:
    """A swarm: N = 100 sensors and M = 200 targets on a 3,000 x 3,000 m map.

    The paper's scenario scaled up at the paper's densities: the same sensor and target
    parameters (altitudes 490/500/510 m in turn, 3 ``cv`` to 2 ``dubins`` targets, speeds
    3-6 m/s, P0), targets uniform in [100, 2900]^2 (2.6e-5 per m^2; the paper's 3.1e-5) and
    sensors in [50, 2950]^2 (1.2e-5 per m^2, as in the paper). Initial target states and
    sensor poses are left to each run's seed.
    """
    targets = tuple(TargetSpec(kind=("cv", "cv", "cv", "dubins", "dubins")[j % 5])
                    for j in range(200))
    sensors = tuple(SensorSpec(SensorParams(altitude=(490.0, 500.0, 510.0)[i % 3]))
                    for i in range(100))
    return Scenario(world=MapRect(3000.0, 3000.0), targets=targets, sensors=sensors,
                    target_box=(100.0, 2900.0), sensor_box=(50.0, 2950.0))


#: Built-in scenarios by name (``--preset``, a study's ``scenario.preset``).
PRESETS: dict[str, Callable[[], Scenario]] = {"paper": paper_scenario, "radar": radar_scenario,
                                              "urban": urban_scenario, "swarm": swarm_scenario,
                                              "slow": slow_scenario}


@dataclass(frozen=True)
class InitialConditions:
    """One run's drawn initial conditions.

    Attributes
    ----------
    truth : (M, 4)         true target states [x, y, vx, vy]
    estimate : (M, 4)      initial filter means (truth + N(0, P0))
    positions : (N, 2)     sensor ground positions
    headings : (N,)        sensor headings
    """

    truth: FloatArray
    estimate: FloatArray
    positions: FloatArray
    headings: FloatArray


def draw_initial(scenario: Scenario, truth_rng: np.random.Generator,
                 init_rng: np.random.Generator) -> InitialConditions:
    """Draw what the scenario leaves open.

    ``truth_rng`` draws target states and sensor poses (what every method of a paired run
    shares); ``init_rng`` draws the initial estimation error.
    """
    M = len(scenario.targets)
    truth = np.empty((M, 4))
    blds = scenario.building_array
    t_lo, t_hi = scenario.start_region("targets")
    for j, t in enumerate(scenario.targets):
        pos = truth_rng.uniform(t_lo, t_hi)
        # Targets start outside the buildings: redraw (only a scenario with buildings ever
        # draws more than once, so the others keep their streams).
        for _ in range(1000):
            if not (t.position is None and inside_buildings(pos, blds)):
                break
            pos = truth_rng.uniform(t_lo, t_hi)
        else:
            raise ConfigError("initial.target_box", "is (almost) all inside buildings")
        speed = truth_rng.uniform(*scenario.speed_range)
        heading = np.pi - truth_rng.uniform(0.0, 2 * np.pi)
        pos = np.array(t.position, dtype=float) if t.position is not None else pos
        speed = t.speed if t.speed is not None else speed
        heading = t.heading if t.heading is not None else heading
        truth[j] = [pos[0], pos[1], speed * np.cos(heading), speed * np.sin(heading)]
    N = len(scenario.sensors)
    positions = np.empty((N, 2))
    headings = np.empty(N)
    s_lo, s_hi = scenario.start_region("sensors")
    for i, s in enumerate(scenario.sensors):
        pos = truth_rng.uniform(s_lo, s_hi)
        heading = np.pi - truth_rng.uniform(0.0, 2 * np.pi)
        positions[i] = s.position if s.position is not None else pos
        headings[i] = s.heading if s.heading is not None else heading
    L = np.linalg.cholesky(np.array(scenario.initial_cov))
    estimate = truth + init_rng.standard_normal((M, 4)) @ L.T
    return InitialConditions(truth, estimate, positions, headings)


def make_truth(scenario: Scenario, initial_states: FloatArray,
               rng: np.random.Generator) -> TruthModel:
    """The scenario's :class:`~sensorplan.models.truth.TruthModel` starting at ``initial_states``
    ``(M, 4)``, drawing from the truth generator ``rng``."""
    return TruthModel(scenario.target_kinds, initial_states, rng,
                      turn_hold=[t.turn_hold for t in scenario.targets],
                      max_turn_rate=[t.max_turn_rate for t in scenario.targets],
                      world_size=(scenario.world.width, scenario.world.height),
                      dt=scenario.dt, process_noise=scenario.process_noise,
                      buildings=scenario.building_array)
