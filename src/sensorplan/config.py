"""Validated input files: the scenario TOML and the single-decision JSON (SPEC 7).

Both are parsed by strict pydantic v2 models (unknown keys are errors; no int is accepted as a
bool or a float as an int, but ints are accepted where floats are expected; every float must
be finite) and turned into the frozen dataclasses of the core, whose own ``validate`` methods
check the semantic rules. Every bad input becomes one :class:`~sensorplan.errors.ConfigError`
naming the field with a dotted path such as ``sensors[1].altitude``.

Scenario file (TOML; every key optional except ``targets`` and ``sensors``; angles in
radians; defaults are SPEC 1-4's)::

    dt = 1.0                      # s
    process_noise = 0.05          # q, m^2/s^3

    [map]
    width = 600.0                 # m
    height = 600.0

    [initial]                     # what each run draws (SPEC 1)
    target_box = [100.0, 500.0]   # initial target positions uniform in [lo, hi]^2
    speed_range = [3.0, 6.0]      # m/s
    sensor_box = [50.0, 550.0]
    cov = [[400.0, 0.0, 0.0, 0.0], [0.0, 400.0, 0.0, 0.0],
           [0.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 4.0]]     # P0

    [tracker]
    miss_update = "negative"      # or "none" (SPEC 3)

    [planning]
    planner = "random"            # a name in sensorplan.planners.PLANNERS
    horizon = 1                   # K epochs
    steps_per_epoch = 1           # e
    execution = "olf"             # or "ol"
    visibility = "probabilistic"  # or "mean"
    objective = "terminal"        # or "cumulative"

    [planning.planner_params]     # only the ones the planner has are passed on
    alpha = 0.3
    beta = 0.95
    max_inner = 50
    max_outer = 10
    # max_plans = 2000000         (brute-force only)

    [run]
    steps = 100
    seed = 0

    [[targets]]
    kind = "cv"                   # or "dubins"
    # position = [300.0, 200.0]   (drawn if absent), speed = 4.0, heading = 0.5
    turn_hold = 10.0              # s (dubins)
    max_turn_rate = 0.1           # rad/s (dubins)

    [[sensors]]
    altitude = 500.0              # and every other SensorParams field
    moves = [20.0, 40.0]
    # position = [100.0, 100.0]   (drawn if absent), heading = 0.0
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Mapping, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError

from . import io
from .errors import ConfigError
from .problem import OBJECTIVES, VISIBILITY_MODES, MapRect, PlanningProblem
from .scenario import (MISS_UPDATES, TARGET_KINDS, Scenario, SensorSpec, TargetSpec,
                       paper_scenario)
from .sensors import SensorParams

if typing.TYPE_CHECKING:  # pragma: no cover
    from .planners import Planner
    from .simulation import RunSettings

#: Same as ``simulation.EXECUTIONS``; repeated so that ``sensorplan plan`` need not import the
#: simulator.
EXECUTIONS = ("ol", "olf")
#: Built-in scenarios for ``sensorplan simulate --preset``.
PRESETS = ("paper",)


# --------------------------------------------------------------------------- field types


def _length(n: int, what: str) -> AfterValidator:
    def check(value: list[Any]) -> list[Any]:
        if len(value) != n:
            raise ValueError(f"must be {what}, got {len(value)} item(s)")
        return value
    return AfterValidator(check)


def _choice(valid: tuple[str, ...], what: str) -> AfterValidator:
    def check(value: str) -> str:
        if value not in valid:
            raise ValueError(f"unknown {what} {value!r}; choose from {', '.join(valid)}")
        return value
    return AfterValidator(check)


Vec2 = Annotated[list[float], _length(2, "a list of 2 numbers")]
Vec4 = Annotated[list[float], _length(4, "a list of 4 numbers")]
Matrix4 = Annotated[list[Vec4], _length(4, "a 4x4 matrix (4 rows of 4 numbers)")]
Visibility = Annotated[str, _choice(VISIBILITY_MODES, "visibility mode")]
ObjectiveName = Annotated[str, _choice(OBJECTIVES, "objective")]
Execution = Annotated[str, _choice(EXECUTIONS, "execution mode")]
MissUpdate = Annotated[str, _choice(MISS_UPDATES, "miss update")]
TargetKind = Annotated[str, _choice(TARGET_KINDS, "target kind")]
def _open_unit(value: float) -> float:
    if not 0.0 < value < 1.0:
        raise ValueError(f"must be in (0, 1), got {value!r}")
    return value


Fraction = Annotated[float, AfterValidator(_open_unit)]
PositiveInt = Annotated[int, Field(ge=1)]
Seed = Annotated[int, Field(ge=0)]

_SP = SensorParams()
_TS = TargetSpec()
_SC = Scenario(targets=(TargetSpec(),), sensors=(SensorSpec(),))
_MAP = MapRect()


def _problem_default(name: str) -> Any:
    return PlanningProblem.__dataclass_fields__[name].default


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


class MapModel(_Strict):
    width: float = _MAP.width
    height: float = _MAP.height


class SensorParamsModel(_Strict):
    """Every :class:`~sensorplan.sensors.SensorParams` field, with its default."""

    altitude: float = _SP.altitude
    moves: list[float] = list(_SP.moves)
    max_turn: float = _SP.max_turn
    fov_half_angle: float = _SP.fov_half_angle
    min_ground_range: float = _SP.min_ground_range
    max_ground_range: float = _SP.max_ground_range
    depression: float = _SP.depression
    snr_ref_db: float = _SP.snr_ref_db
    range_ref: float = _SP.range_ref
    beamwidth: float = _SP.beamwidth
    monopulse_slope: float = _SP.monopulse_slope
    range_resolution: float = _SP.range_resolution

    def params(self) -> SensorParams:
        kwargs = {f.name: getattr(self, f.name) for f in dataclasses.fields(SensorParams)}
        kwargs["moves"] = tuple(self.moves)
        return SensorParams(**kwargs)


class PlannerParamsModel(_Strict):
    """Planner settings; ``None`` leaves the planner's own default."""

    alpha: Fraction | None = None
    beta: Fraction | None = None
    max_inner: PositiveInt | None = None
    max_outer: PositiveInt | None = None
    max_plans: PositiveInt | None = None

    def given(self) -> dict[str, Any]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


# ---------------------------------------------------------------- single-decision JSON


class DecisionTarget(_Strict):
    mean: Vec4
    cov: Matrix4


class DecisionSensor(SensorParamsModel):
    position: Vec2
    heading: float


class DecisionPlanner(PlannerParamsModel):
    name: str = "pg"
    seed: Seed | None = None


class DecisionFile(_Strict):
    """SPEC 7's single-decision file."""

    dt: float = _problem_default("dt")
    steps_per_epoch: int = _problem_default("steps_per_epoch")
    horizon: int
    map: MapModel = MapModel()
    process_noise: float = _problem_default("process_noise")
    visibility: Visibility = _problem_default("visibility")
    objective: ObjectiveName = _problem_default("objective")
    targets: list[DecisionTarget]
    sensors: list[DecisionSensor]
    planner: DecisionPlanner = DecisionPlanner()


# ----------------------------------------------------------------------- scenario TOML


class InitialModel(_Strict):
    target_box: Vec2 = list(_SC.target_box)
    speed_range: Vec2 = list(_SC.speed_range)
    sensor_box: Vec2 = list(_SC.sensor_box)
    cov: Matrix4 = [list(row) for row in _SC.initial_cov]


class TrackerModel(_Strict):
    miss_update: MissUpdate = _SC.miss_update


class ScenarioTarget(_Strict):
    kind: TargetKind = _TS.kind
    position: Vec2 | None = None
    speed: Annotated[float, Field(ge=0.0)] | None = None
    heading: float | None = None
    turn_hold: float = _TS.turn_hold
    max_turn_rate: float = _TS.max_turn_rate


class ScenarioSensor(SensorParamsModel):
    position: Vec2 | None = None
    heading: float | None = None


class PlanningModel(_Strict):
    """``None`` leaves :class:`~sensorplan.simulation.RunSettings`' default."""

    planner: str | None = None
    horizon: PositiveInt | None = None
    steps_per_epoch: PositiveInt | None = None
    execution: Execution | None = None
    visibility: Visibility | None = None
    objective: ObjectiveName | None = None
    planner_params: PlannerParamsModel = PlannerParamsModel()


class RunModel(_Strict):
    steps: PositiveInt | None = None
    seed: Seed = 0


class RunPart(_Strict):
    """The run-settings part of a scenario file (all a preset can be given)."""

    planning: PlanningModel = PlanningModel()
    run: RunModel = RunModel()


class ScenarioFile(_Strict):
    dt: float = _SC.dt
    process_noise: float = _SC.process_noise
    map: MapModel = MapModel()
    initial: InitialModel = InitialModel()
    tracker: TrackerModel = TrackerModel()
    targets: list[ScenarioTarget]
    sensors: list[ScenarioSensor]
    planning: PlanningModel = PlanningModel()
    run: RunModel = RunModel()

    def scenario(self) -> Scenario:
        targets = tuple(
            TargetSpec(kind=t.kind,
                       position=None if t.position is None else (t.position[0], t.position[1]),
                       speed=t.speed, heading=t.heading, turn_hold=t.turn_hold,
                       max_turn_rate=t.max_turn_rate)
            for t in self.targets)
        sensors = tuple(
            SensorSpec(params=s.params(),
                       position=None if s.position is None else (s.position[0], s.position[1]),
                       heading=s.heading)
            for s in self.sensors)
        ini = self.initial
        return Scenario(
            world=MapRect(self.map.width, self.map.height), dt=self.dt,
            process_noise=self.process_noise, targets=targets, sensors=sensors,
            target_box=(ini.target_box[0], ini.target_box[1]),
            speed_range=(ini.speed_range[0], ini.speed_range[1]),
            sensor_box=(ini.sensor_box[0], ini.sensor_box[1]),
            initial_cov=tuple(tuple(row) for row in ini.cov),
            miss_update=self.tracker.miss_update)


# ------------------------------------------------------------------- error translation


def _dotted(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


def _unwrap(tp: Any) -> Any:
    while True:
        origin = typing.get_origin(tp)
        if origin is Annotated:
            tp = typing.get_args(tp)[0]
        elif origin in (Union, types.UnionType):
            tp = next(a for a in typing.get_args(tp) if a is not type(None))
        else:
            return tp


def _model_at(model: type[BaseModel], loc: tuple[Any, ...]) -> type[BaseModel] | None:
    tp: Any = model
    for part in loc:
        tp = _unwrap(tp)
        if isinstance(part, int):
            args = typing.get_args(tp)
            if not args:
                return None
            tp = args[0]
        elif isinstance(tp, type) and issubclass(tp, BaseModel) and part in tp.model_fields:
            tp = tp.model_fields[part].annotation
        else:
            return None
    tp = _unwrap(tp)
    return tp if isinstance(tp, type) and issubclass(tp, BaseModel) else None


_TYPE_NAMES = {"float_type": "a number", "int_type": "an integer", "string_type": "a string",
               "bool_type": "true or false", "list_type": "a list"}


def _translate(exc: ValidationError, model: type[BaseModel], container: str) -> ConfigError:
    """One :class:`ConfigError` for the first error pydantic found."""
    err = exc.errors()[0]
    loc = tuple(err["loc"])
    kind = err["type"]
    field = _dotted(loc)
    if kind == "extra_forbidden":
        parent = _model_at(model, loc[:-1])
        allowed = list(parent.model_fields) if parent is not None else []
        message = "unknown key"
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        if close:
            message += f" (did you mean {close[0]!r}?)"
        if allowed:
            message += f"; allowed: {', '.join(allowed)}"
    elif kind == "missing":
        message = "is required"
    elif kind == "finite_number":
        message = "must be a finite number"
    elif kind in _TYPE_NAMES:
        got = repr(err.get("input"))
        got = got if len(got) <= 40 else got[:37] + "..."
        message = f"must be {_TYPE_NAMES[kind]}, got {got}"
    elif kind in ("model_type", "model_attributes_type", "dict_type"):
        message = f"must be {container}"
    elif kind == "value_error":
        message = err["msg"].removeprefix("Value error, ")
    else:
        message = err["msg"].replace("Input should be", "must be")
    return ConfigError(field, message)


def _validate(model: type[BaseModel], data: Any, container: str) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise _translate(exc, model, container) from None


# ------------------------------------------------------------------------ planners


def planner_settings(name: str, params: Mapping[str, Any], name_field: str = "planner.name",
                     params_field: str = "planner") -> dict[str, Any]:
    """The subset of ``params`` that planner ``name`` takes (its dataclass fields).

    Parameters
    ----------
    name : str
        A name in :data:`sensorplan.planners.PLANNERS`.
    params : mapping
        Candidate settings (``None`` values are dropped: the planner keeps its default).
    name_field, params_field : str
        Field paths used in errors.

    Raises
    ------
    ConfigError
        Unknown planner (the message lists the registered names), or ``max_plans`` for a
        planner other than ``brute-force``.
    """
    from .planners import PLANNERS

    if not isinstance(name, str) or name not in PLANNERS:
        raise ConfigError(name_field, f"unknown planner {name!r}; choose from "
                          f"{', '.join(sorted(PLANNERS))}")
    if params.get("max_plans") is not None and name != "brute-force":
        raise ConfigError(f"{params_field}.max_plans",
                          f"only the brute-force planner takes max_plans (planner is {name!r})")
    cls = PLANNERS[name]
    if dataclasses.is_dataclass(cls):
        accepted = {f.name for f in dataclasses.fields(cls)}
    else:
        accepted = set(inspect.signature(cls).parameters)
    return {k: v for k, v in params.items() if v is not None and k in accepted}


def build_planner(name: str, settings: Mapping[str, Any], field: str = "planner") -> "Planner":
    """``make_planner(name, **settings)`` with every failure as a :class:`ConfigError`."""
    from .planners import make_planner

    try:
        return make_planner(name, **settings)
    except ConfigError as exc:
        raise ConfigError(field if exc.field == "planner" else exc.field, exc.message) from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(field, str(exc)) from None


# --------------------------------------------------------------------- single decision


@dataclass(frozen=True)
class Decision:
    """A single-decision file: the problem and the planner to solve it with.

    Attributes
    ----------
    problem : PlanningProblem
    planner : str                  registry name
    settings : dict                the settings passed to the planner's constructor
    """

    problem: PlanningProblem
    planner: str
    settings: Mapping[str, Any]

    def make_planner(self) -> "Planner":
        return build_planner(self.planner, self.settings)


def decision_from_dict(data: Any, planner: str | None = None) -> Decision:
    """Validate a SPEC 7 single-decision object and build the problem and planner settings.

    Parameters
    ----------
    data : object
        The parsed JSON.
    planner : str, optional
        Overrides ``planner.name`` (the CLI's ``--planner``); settings of the file that the
        new planner does not take (including ``max_plans``) are dropped.

    Raises
    ------
    ConfigError
        For every bad input of SPEC 7 (the field is a dotted path like ``sensors[1].altitude``).
    """
    model: DecisionFile = _validate(DecisionFile, data, "a JSON object")
    problem = PlanningProblem(
        means=[t.mean for t in model.targets],
        covs=[t.cov for t in model.targets],
        positions=[s.position for s in model.sensors],
        headings=[s.heading for s in model.sensors],
        sensors=tuple(s.params() for s in model.sensors),
        horizon=model.horizon, steps_per_epoch=model.steps_per_epoch, dt=model.dt,
        process_noise=model.process_noise, world=MapRect(model.map.width, model.map.height),
        visibility=model.visibility, objective=model.objective)
    params = model.planner.given()
    if model.planner.seed is not None:
        params["seed"] = model.planner.seed
    if planner is None:
        name = model.planner.name
        settings = planner_settings(name, params)
        field = "planner"
    else:
        if planner != "brute-force":
            params.pop("max_plans", None)
        settings = planner_settings(planner, params, name_field="--planner")
        name, field = planner, "--planner"
    build_planner(name, settings, field)          # surface bad settings now
    return Decision(problem, name, settings)


def load_decision(path: str | Path, planner: str | None = None) -> Decision:
    """:func:`decision_from_dict` on a JSON file."""
    return decision_from_dict(io.read_json(path), planner)


# -------------------------------------------------------------------------- simulation


@dataclass(frozen=True)
class SimulationConfig:
    """Everything ``sensorplan simulate`` runs: scenario, run settings and the run's seed."""

    scenario: Scenario
    settings: "RunSettings"
    seed: int


#: CLI override key -> (section, key) in the scenario file (``miss_update`` goes to
#: RunSettings, not to the scenario's ``[tracker]``).
_OVERRIDES = {
    "planner": ("planning", "planner"), "horizon": ("planning", "horizon"),
    "steps_per_epoch": ("planning", "steps_per_epoch"), "execution": ("planning", "execution"),
    "visibility": ("planning", "visibility"), "objective": ("planning", "objective"),
    "steps": ("run", "steps"), "seed": ("run", "seed"),
}
#: RunSettings field -> field path in the scenario file.
_SETTINGS_FIELDS = {
    "planner": "planning.planner", "planner_params": "planning.planner_params",
    "horizon": "planning.horizon", "steps_per_epoch": "planning.steps_per_epoch",
    "execution": "planning.execution", "visibility": "planning.visibility",
    "objective": "planning.objective", "steps": "run.steps", "miss_update": "--miss-update",
}


def option_name(key: str) -> str:
    """CLI option of an override key: ``steps_per_epoch`` -> ``--steps-per-epoch``."""
    return "--" + key.replace("_", "-")


def _rename(exc: ConfigError, renames: Mapping[str, str]) -> ConfigError:
    for old, new in renames.items():
        if exc.field == old or exc.field.startswith(old + ".") or exc.field.startswith(old + "["):
            return ConfigError(new + exc.field[len(old):], exc.message)
    return exc


def load_simulation(path: str | Path | None = None, preset: str | None = None,
                    overrides: Mapping[str, Any] | None = None) -> SimulationConfig:
    """Scenario file or preset, plus command-line overrides, as a :class:`SimulationConfig`.

    Parameters
    ----------
    path : path, optional
        A scenario TOML file (see the module docstring).
    preset : str, optional
        A name in :data:`PRESETS` (``paper``: :func:`~sensorplan.scenario.paper_scenario` with
        default run settings). Give ``path`` or ``preset``, not both; neither means ``paper``.
    overrides : mapping, optional
        Keys ``planner, horizon, steps_per_epoch, execution, visibility, objective, steps,
        seed, miss_update``; ``None`` values are ignored. Errors in them name the CLI option
        (``--horizon``).

    Raises
    ------
    ConfigError
    """
    given = {k: v for k, v in (overrides or {}).items() if v is not None}
    unknown = sorted(set(given) - set(_OVERRIDES) - {"miss_update"})
    if unknown:
        raise ConfigError(option_name(unknown[0]), "is not a simulation setting")
    if path is not None and preset is not None:
        raise ConfigError("--preset", "give a scenario file or --preset, not both")
    if path is None:
        preset = preset or "paper"
        if preset not in PRESETS:
            raise ConfigError("--preset", f"unknown preset {preset!r}; choose from "
                              f"{', '.join(PRESETS)}")
        data: dict[str, Any] = {}
    else:
        data = io.read_toml(path)
    renames: dict[str, str] = {}
    miss_update = given.pop("miss_update", None)
    for key, value in given.items():
        section, name = _OVERRIDES[key]
        if not isinstance(data.setdefault(section, {}), dict):
            continue                                # the model reports the bad section
        data[section][name] = value
        renames[f"{section}.{name}"] = option_name(key)
    try:
        if path is None:
            part: Any = _validate(RunPart, data, "a table")
            scenario = paper_scenario()
        else:
            part = _validate(ScenarioFile, data, "a table")
            scenario = part.scenario()
        if miss_update is not None and miss_update not in MISS_UPDATES:
            raise ConfigError("--miss-update", f"unknown miss update {miss_update!r}; "
                              f"choose from {', '.join(MISS_UPDATES)}")
        settings = _run_settings(part.planning, part.run, miss_update,
                                 planner_overridden="planner" in given)
    except ConfigError as exc:
        raise _rename(exc, renames) from None
    return SimulationConfig(scenario, settings, part.run.seed)


def _run_settings(planning: PlanningModel, run: RunModel, miss_update: str | None,
                  planner_overridden: bool = False) -> "RunSettings":
    from .simulation import RunSettings

    kwargs: dict[str, Any] = {
        k: getattr(planning, k)
        for k in ("planner", "horizon", "steps_per_epoch", "execution", "visibility", "objective")
        if getattr(planning, k) is not None}
    if run.steps is not None:
        kwargs["steps"] = run.steps
    if miss_update is not None:
        kwargs["miss_update"] = miss_update
    name = kwargs.get("planner", RunSettings.__dataclass_fields__["planner"].default)
    params = planning.planner_params.given()
    if planner_overridden and name != "brute-force":
        # The file's settings were meant for its own planner; --planner replaces it.
        params.pop("max_plans", None)
    kwargs["planner_params"] = planner_settings(
        name, params, name_field="planning.planner",
        params_field="planning.planner_params")
    build_planner(name, kwargs["planner_params"], "planning.planner_params")
    try:
        return RunSettings(**kwargs)
    except ConfigError as exc:
        raise _rename(exc, _SETTINGS_FIELDS) from None


# ----------------------------------------------------------------------------- studies
#
# A study file (TOML) names a scenario, the number of paired runs, their length, the root
# seed and a list of methods; ``sensorplan study`` runs every method on every run
# (see :mod:`sensorplan.experiments` and docs/studies.md)::
#
#     description = "what this study is for"      # optional, free text
#     runs = 100                                  # paired Monte Carlo runs
#     steps = 100                                 # simulation steps per run
#     seed = 2024                                 # root SeedSequence of the study
#
#     [scenario]                                  # optional; default: preset = "paper"
#     preset = "paper"                            # or: file = "../configs/paper.toml"
#                                                 # (relative to this file; its [planning]
#                                                 # and [run] tables are not used)
#
#     [defaults]                                  # optional: settings every method inherits
#     steps_per_epoch = 2
#
#     [[methods]]
#     name = "paper/olf"                          # unique; used in tables and figures
#     planner = "pg"                              # a registered planner
#     horizon = 3                                 # K
#     steps_per_epoch = 2                         # e
#     execution = "olf"                           # or "ol"
#     visibility = "mean"                         # or "probabilistic" (default)
#     objective = "terminal"                      # or "cumulative"
#     miss_update = "none"                        # or "negative"; default: the scenario's
#     [methods.planner_params]                    # alpha, beta, max_inner, max_outer,
#     alpha = 0.3                                 # max_plans (brute-force)


def _method_name(value: str) -> str:
    if not value.strip():
        raise ValueError("must be a non-empty name")
    if len(value) > 80:
        raise ValueError(f"must be at most 80 characters, got {len(value)}")
    if any(not ch.isprintable() for ch in value):
        raise ValueError("must not contain control characters")
    return value


def _non_empty(value: list[Any]) -> list[Any]:
    if not value:
        raise ValueError("at least one method is required")
    return value


MethodName = Annotated[str, AfterValidator(_method_name)]


class StudyScenarioModel(_Strict):
    preset: str | None = None
    file: str | None = None


class MethodSettingsModel(_Strict):
    """A method's settings; ``None`` inherits ``[defaults]``, then RunSettings' default."""

    planner: str | None = None
    planner_params: PlannerParamsModel | None = None
    horizon: PositiveInt | None = None
    steps_per_epoch: PositiveInt | None = None
    execution: Execution | None = None
    visibility: Visibility | None = None
    objective: ObjectiveName | None = None
    miss_update: MissUpdate | None = None


class MethodModel(MethodSettingsModel):
    name: MethodName


class StudyFile(_Strict):
    description: str = ""
    runs: PositiveInt
    steps: PositiveInt
    seed: Seed = 0
    scenario: StudyScenarioModel = StudyScenarioModel()
    defaults: MethodSettingsModel = MethodSettingsModel()
    methods: Annotated[list[MethodModel], AfterValidator(_non_empty)]


#: Method settings in the order they are resolved and written.
_METHOD_KEYS = ("planner", "horizon", "steps_per_epoch", "execution", "visibility",
                "objective", "miss_update")


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """A scenario as the content of a scenario file, every default filled in.

    Fields left to each run's seed (``None`` positions, speeds, headings) are omitted, as
    they would be in the file. :func:`scenario_from_dict` inverts it exactly (floats
    round-trip through JSON unchanged).
    """
    def sensor(spec: SensorSpec) -> dict[str, Any]:
        d: dict[str, Any] = {}
        for f in dataclasses.fields(SensorParams):
            v = getattr(spec.params, f.name)
            d[f.name] = [float(m) for m in v] if f.name == "moves" else float(v)
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

    return {
        "dt": float(scenario.dt), "process_noise": float(scenario.process_noise),
        "map": {"width": float(scenario.world.width), "height": float(scenario.world.height)},
        "initial": {"target_box": [float(v) for v in scenario.target_box],
                    "speed_range": [float(v) for v in scenario.speed_range],
                    "sensor_box": [float(v) for v in scenario.sensor_box],
                    "cov": [[float(v) for v in row] for row in scenario.initial_cov]},
        "tracker": {"miss_update": scenario.miss_update},
        "targets": [target(t) for t in scenario.targets],
        "sensors": [sensor(s) for s in scenario.sensors],
    }


def scenario_from_dict(data: Any, source: str = "scenario") -> Scenario:
    """Validate scenario-file content (a parsed TOML table) and build the scenario.

    ``[planning]`` and ``[run]`` are validated but not part of the scenario.

    Raises
    ------
    ConfigError
        Naming the field as in a scenario file (``targets[0].kind``).
    """
    model: ScenarioFile = _validate(ScenarioFile, data, "a table")
    return model.scenario()


def _study_scenario(model: StudyScenarioModel, base_dir: Path | None) -> tuple[Scenario, str]:
    if model.preset is not None and model.file is not None:
        raise ConfigError("scenario", "give preset or file, not both")
    if model.file is None:
        preset = model.preset or "paper"
        if preset not in PRESETS:
            raise ConfigError("scenario.preset", f"unknown preset {preset!r}; choose from "
                              f"{', '.join(PRESETS)}")
        return paper_scenario(), f"preset {preset}"
    path = Path(model.file)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    try:
        data = io.read_toml(path)
        return scenario_from_dict(data), f"file {path}"
    except ConfigError as exc:
        where = exc.field if exc.field == str(path) else f"{path}: {exc.field}"
        raise ConfigError("scenario.file", f"{where}: {exc.message}") from None


def study_from_dict(data: Any, base_dir: str | Path | None = None) -> Any:
    """Validate a study table and build the :class:`~sensorplan.experiments.Study`.

    Parameters
    ----------
    data : object
        The parsed TOML (see the block comment above for the keys).
    base_dir : path, optional
        Directory that a relative ``scenario.file`` is relative to (the study file's).

    Raises
    ------
    ConfigError
        Naming the field with a dotted path such as ``methods[2].horizon`` (or
        ``defaults.horizon`` when the value came from ``[defaults]``).
    """
    from .experiments import Method, Study
    from .planners import PLANNERS
    from .simulation import RunSettings

    model: StudyFile = _validate(StudyFile, data, "a table")
    scenario, source = _study_scenario(model.scenario, None if base_dir is None
                                       else Path(base_dir))
    defaults = model.defaults
    seen: dict[str, int] = {}
    methods = []
    for i, m in enumerate(model.methods):
        if m.name in seen:
            raise ConfigError(f"methods[{i}].name", f"duplicate method name {m.name!r} "
                              f"(also methods[{seen[m.name]}])")
        seen[m.name] = i
        kwargs: dict[str, Any] = {}
        origin: dict[str, str] = {}
        for key in _METHOD_KEYS:
            own, inherited = getattr(m, key), getattr(defaults, key)
            if own is not None:
                kwargs[key], origin[key] = own, f"methods[{i}].{key}"
            elif inherited is not None:
                kwargs[key], origin[key] = inherited, f"defaults.{key}"
        if "planner" not in kwargs:
            raise ConfigError(f"methods[{i}].planner", "is required (in the method or in "
                              "[defaults])")
        kwargs.setdefault("miss_update", scenario.miss_update)
        params = {} if defaults.planner_params is None else defaults.planner_params.given()
        params_field = ("defaults.planner_params" if m.planner_params is None
                        else f"methods[{i}].planner_params")
        if m.planner_params is not None:
            params.update(m.planner_params.given())
        name = kwargs["planner"]
        settings = planner_settings(name, params, name_field=origin["planner"],
                                    params_field=params_field)
        planner = build_planner(name, settings, params_field)
        # Every setting the study file can give, filled with the planner's own default so
        # that config.resolved.json shows what ran.
        cls = PLANNERS[name]
        settable = set(PlannerParamsModel.model_fields)
        if dataclasses.is_dataclass(cls):
            filled = {f.name: getattr(planner, f.name) for f in dataclasses.fields(cls)
                      if f.name in settable}
        else:
            filled = dict(settings)
        try:
            run_settings = RunSettings(planner_params=filled, steps=model.steps, **kwargs)
        except ConfigError as exc:
            field = origin.get(exc.field, f"methods[{i}].{exc.field}")
            raise ConfigError(field, exc.message) from None
        methods.append(Method(m.name, run_settings))
    return Study(scenario=scenario, runs=model.runs, steps=model.steps, seed=model.seed,
                 methods=tuple(methods), description=model.description,
                 scenario_source=source)


def load_study(path: str | Path) -> Any:
    """:func:`study_from_dict` on a TOML file (a relative scenario file is relative to it)."""
    path = Path(path)
    return study_from_dict(io.read_toml(path), base_dir=path.parent)


def parse_study(text: str, source: str = "<study>", base_dir: str | Path | None = None) -> Any:
    """:func:`study_from_dict` on TOML text (the built-in demo study)."""
    import tomllib

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, f"invalid TOML: {exc}") from None
    return study_from_dict(data, base_dir=base_dir)
