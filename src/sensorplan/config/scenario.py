"""Scenario files (TOML): their strict model, reading and writing.

Every key is optional except ``targets`` (optional with ``scripted``) and ``sensors``
(optional with ``scan``);
angles in radians, or in degrees under the same key with ``_deg`` appended
(``fov_half_angle_deg = 30``; one of the two); defaults as below (``configs/paper.toml``
spells out every key)::

    dt = 1.0                      # s
    process_noise = 0.05          # q, m^2/s^3

    # Targets that are born and die (leave all five out for the paper's known targets):
    births = "none"               # or "edges" (on the boundary, heading inward; a target
                                  # that leaves the map dies) or "uniform" (anywhere)
    birth_rate = 0.0              # expected births per step (Poisson); > 0 needs births
    survival_probability = 1.0    # per step, in (0, 1]; < 1 with births = "uniform"
    # initial_targets = 3         # the first 3 [[targets]] start; the [[targets]] are the
                                  # templates of born ones, cycled (default: all start)
    # scripted = "williams15"     # a published benchmark's scripted truth ("vo12"): its
                                  # own births, deaths and trajectories, map and dt
    look_detects = "target"       # a look detects only its target (the paper's), or "all":
                                  # every live target in its sensing region
    # scan = "williams15"         # the benchmark's linear sensor scans the whole map every
                                  # step instead of the [[sensors]] (none then; "vo12")

    [map]
    width = 600.0                 # m
    height = 600.0

    [initial]                     # what each run draws
    target_box = [100.0, 500.0]   # initial target positions uniform in [lo, hi]^2 (inside
                                  # the map; default: the middle 2/3 of each map side)
    speed_range = [3.0, 6.0]      # m/s
    sensor_box = [50.0, 550.0]    # (default: each side without its outer twelfths)
    cov = [[400.0, 0.0, 0.0, 0.0], [0.0, 400.0, 0.0, 0.0],
           [0.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 4.0]]     # P0

    [[targets]]
    kind = "cv"                   # or "dubins"
    # position = [300.0, 200.0]   (drawn if absent), speed = 4.0, heading = 0.5
    turn_hold = 10.0              # s (dubins)
    max_turn_rate = 0.1           # rad/s (dubins)

    [[sensors]]
    altitude = 500.0              # and every other SensorParams field
    moves = [20.0, 40.0]
    # position = [100.0, 100.0]   (drawn if absent), heading = 0.0

    # How ``sensorplan simulate`` runs it (sensorplan.simulation.settings declares every key; a
    # study
    # using the file ignores these three tables):
    [planning]                    # planner, planner_params, horizon, steps_per_epoch,
    horizon = 1                   # execution, visibility, objective
    [tracker]                     # miss_update
    [run]                         # steps, and the run's seed
    seed = 0

:func:`scenario_from_dict` validates a parsed file and builds the
:class:`~sensorplan.simulation.scenario.Scenario`; :func:`scenario_to_dict` writes one back (the
scenario of a study's ``config.resolved.json``).
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any

from pydantic import ValidationInfo, field_validator

from ..errors import ConfigError
from ..limits import RANGES, check_sensor_precision
from ..models.sensors import SensorParams
from ..planners.problem import MapRect
from ..models.population import BIRTHS
from ..simulation.scenario import LOOK_DETECTS, TARGET_KINDS, Scenario, SensorSpec, TargetSpec
from ..simulation.settings import RunSettings, TrackerSettings
from .validation import (BuildingModel, MapModel, Matrix4, Seed, SensorParamsModel, Strict,
                         Vec2, choice, in_range, one_spelling, radians_of, section_model,
                         validate)

_TS = TargetSpec()
_SC = Scenario(targets=(TargetSpec(),), sensors=(SensorSpec(),))

TargetKind = Annotated[str, choice(TARGET_KINDS, "target kind")]

#: The run-settings tables, generated from sensorplan.simulation.settings.
PlanningTable = section_model(RunSettings, "planning", "PlanningTable",
                              "The ``[planning]`` table; ``None`` takes the setting's default.")
TrackerTable = section_model(TrackerSettings, "tracker", "TrackerTable",
                             "The ``[tracker]`` table; ``None`` takes the setting's default.")
RunTable = section_model(RunSettings, "run", "RunTable",
                         "The ``[run]`` table: run settings and the run's seed.",
                         seed=(Seed, 0))


class InitialModel(Strict):
    target_box: Vec2 | None = None
    speed_range: Vec2 = list(_SC.speed_range)
    sensor_box: Vec2 | None = None
    cov: Matrix4 = [list(row) for row in _SC.initial_cov]


class ScenarioTarget(Strict):
    kind: TargetKind = _TS.kind
    position: Vec2 | None = None
    speed: Annotated[float, in_range(RANGES["speed"])] | None = None
    heading: float | None = None
    heading_deg: float | None = None
    turn_hold: float = _TS.turn_hold
    max_turn_rate: float | None = None
    max_turn_rate_deg: float | None = None

    @field_validator("max_turn_rate_deg", "heading_deg")
    @classmethod
    def _one_spelling(cls, value: float | None, info: ValidationInfo) -> float | None:
        name = str(info.field_name).removesuffix("_deg")
        return one_spelling(name, value, info.data.get(name))


class ScenarioSensor(SensorParamsModel):
    position: Vec2 | None = None
    heading: float | None = None
    heading_deg: float | None = None


class SettingsTables(Strict):
    """The run-settings part of a scenario file (all a preset can be given)."""

    planning: PlanningTable = PlanningTable()  # type: ignore[valid-type]
    tracker: TrackerTable = TrackerTable()  # type: ignore[valid-type]
    run: RunTable = RunTable()  # type: ignore[valid-type]


class ScenarioFile(Strict):
    dt: float = _SC.dt
    process_noise: float = _SC.process_noise
    births: Annotated[str, choice(BIRTHS, "births")] = _SC.births
    birth_rate: float = _SC.birth_rate
    survival_probability: float = _SC.survival_probability
    initial_targets: int | None = None
    scripted: str | None = None
    look_detects: Annotated[str, choice(LOOK_DETECTS, "look_detects")] = _SC.look_detects
    scan: str | None = None
    map: MapModel = MapModel()
    initial: InitialModel = InitialModel()
    tracker: TrackerTable = TrackerTable()  # type: ignore[valid-type]
    targets: list[ScenarioTarget] | None = None
    sensors: list[ScenarioSensor] | None = None
    buildings: list[BuildingModel] = []
    planning: PlanningTable = PlanningTable()  # type: ignore[valid-type]
    run: RunTable = RunTable()  # type: ignore[valid-type]

    def scenario(self) -> Scenario:
        if self.targets is None and self.scripted is None:
            # Required unless a scripted truth brings its own targets.
            raise ConfigError("targets", "is required")
        if self.sensors is None and self.scan is None:
            raise ConfigError("sensors", "is required")
        targets = tuple(
            TargetSpec(kind=t.kind,
                       position=None if t.position is None else (t.position[0], t.position[1]),
                       speed=t.speed, heading=radians_of(t, "heading", None),
                       turn_hold=t.turn_hold,
                       max_turn_rate=radians_of(t, "max_turn_rate", _TS.max_turn_rate))
            for t in self.targets or ())
        sensors = tuple(
            SensorSpec(params=s.params(),
                       position=None if s.position is None else (s.position[0], s.position[1]),
                       heading=radians_of(s, "heading", None))
            for s in self.sensors or ())
        ini = self.initial
        scenario = Scenario(
            world=MapRect(self.map.width, self.map.height), dt=self.dt,
            process_noise=self.process_noise, targets=targets, sensors=sensors,
            target_box=None if ini.target_box is None else (ini.target_box[0],
                                                            ini.target_box[1]),
            speed_range=(ini.speed_range[0], ini.speed_range[1]),
            sensor_box=None if ini.sensor_box is None else (ini.sensor_box[0],
                                                            ini.sensor_box[1]),
            initial_cov=tuple(tuple(row) for row in ini.cov),
            buildings=tuple(b.row() for b in self.buildings), births=self.births,
            birth_rate=self.birth_rate, survival_probability=self.survival_probability,
            initial_targets=self.initial_targets, scripted=self.scripted,
            look_detects=self.look_detects, scan=self.scan)
        for i, spec in enumerate(scenario.sensors):
            check_sensor_precision(spec.params, f"sensors[{i}]")
        return scenario


#: Sensor keys that :func:`scenario_to_dict` leaves out at their default 0 (added after
#: study directories stored scenarios without them).
UNWRITTEN_ZERO = ("range_error_floor", "azimuth_error_floor")


def scenario_from_dict(data: Any) -> Scenario:
    """Validate scenario-file content (a parsed TOML table) and build the scenario.

    ``[planning]``, ``[tracker]`` and ``[run]`` are validated but not part of the scenario.

    Raises
    ------
    ConfigError
        Naming the field as in a scenario file (``targets[0].kind``).
    """
    model: ScenarioFile = validate(ScenarioFile, data)
    return model.scenario()


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """A scenario as the content of a scenario file, every default filled in.

    Fields left to each run's seed (``None`` positions, speeds, headings) are omitted, as
    they would be in the file. The births, deaths and scripted-truth keys are written only
    when they differ from the known-target defaults, and the radar's error floors only when
    they are not 0, so that a scenario without them is written as it always was (a study
    directory written before they existed still holds the same study).
    :func:`scenario_from_dict` inverts it exactly (floats round-trip through JSON
    unchanged).
    """
    def sensor(spec: SensorSpec) -> dict[str, Any]:
        d: dict[str, Any] = {}
        for f in dataclasses.fields(SensorParams):
            v = getattr(spec.params, f.name)
            if f.name == "moves":
                d[f.name] = [float(m) for m in v]
            elif f.name in UNWRITTEN_ZERO and v == 0.0:
                continue
            else:
                d[f.name] = v if isinstance(v, str) else float(v)
        if spec.position is not None:
            d["position"] = [float(spec.position[0]), float(spec.position[1])]
        if spec.heading is not None:
            d["heading"] = float(spec.heading)
        return d

    def target(spec: TargetSpec) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": spec.kind}
        if spec.position is not None:
            d["position"] = [float(spec.position[0]), float(spec.position[1])]
        for name in ("speed", "heading"):
            if getattr(spec, name) is not None:
                d[name] = float(getattr(spec, name))
        d["turn_hold"] = float(spec.turn_hold)
        d["max_turn_rate"] = float(spec.max_turn_rate)
        return d

    population: dict[str, Any] = {}
    if scenario.births != _SC.births:
        population["births"] = scenario.births
    if scenario.birth_rate != _SC.birth_rate:
        population["birth_rate"] = float(scenario.birth_rate)
    if scenario.survival_probability != _SC.survival_probability:
        population["survival_probability"] = float(scenario.survival_probability)
    if scenario.initial_targets is not None:
        population["initial_targets"] = int(scenario.initial_targets)
    if scenario.scripted is not None:
        population["scripted"] = scenario.scripted
    if scenario.look_detects != _SC.look_detects:
        population["look_detects"] = scenario.look_detects
    if scenario.scan is not None:
        population["scan"] = scenario.scan
    return {
        "dt": float(scenario.dt), "process_noise": float(scenario.process_noise),
        **population,
        "map": {"width": float(scenario.world.width), "height": float(scenario.world.height)},
        # A box left to the map (None: a non-square map) is left out, as in the file.
        "initial": {**({} if scenario.target_box is None else
                       {"target_box": [float(v) for v in scenario.target_box]}),
                    "speed_range": [float(v) for v in scenario.speed_range],
                    **({} if scenario.sensor_box is None else
                       {"sensor_box": [float(v) for v in scenario.sensor_box]}),
                    "cov": [[float(v) for v in row] for row in scenario.initial_cov]},
        "targets": [target(t) for t in scenario.targets],
        "sensors": [sensor(s) for s in scenario.sensors],
        "buildings": [{"box": [float(v) for v in b[:4]], "height": float(b[4])}
                      for b in scenario.buildings],
    }
