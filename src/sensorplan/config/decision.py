"""The single-decision file (JSON) of ``sensorplan plan`` (docs/cli.md)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import ConfigDict

from ..errors import ConfigError
from ..limits import (MAX_SEARCH_SECTORS, MAX_SENSORS, MAX_TARGETS, MAX_UNDETECTED_CELLS,
                      RANGES, Range, check_count, check_covariance_scale, check_decision_size,
                      check_sensor_precision)
from ..planners.problem import (SEARCH_MODES, MapRect, PlanningProblem, UndetectedIntensity,
                                check_covariance)
from ..simulation.scenario import HEADING_HINT
from ..simulation.settings import RunSettings, limit_fields
from . import files as io
from .planners import build_planner, planner_settings, replaced_planner_settings
from .validation import (BuildingModel, MapModel, Matrix4, Seed, SensorParamsModel, Strict,
                         Vec2, Vec4, radians_of, setting_type, validate)

if TYPE_CHECKING:  # pragma: no cover
    from ..planners import Planner


#: A complete single-decision file (``sensorplan plan --example`` prints it; the same text
#: is examples/problem.json and the example of docs/cli.md): one target, one sensor with
#: every radar parameter at its default, the pg planner with its default settings.
EXAMPLE_PROBLEM = """\
{
  "dt": 1.0, "steps_per_epoch": 1, "horizon": 3,
  "map": {"width": 600, "height": 600},
  "process_noise": 0.05, "visibility": "probabilistic", "objective": "cumulative",
  "targets": [{"mean": [300, 200, 4, 1], "cov": [[400,0,0,0],[0,400,0,0],[0,0,4,0],[0,0,0,4]]}],
  "sensors": [{"position": [100, 100], "altitude": 500, "heading": 0.0,
               "moves": [20, 40], "max_turn": 0.785398,
               "fov_half_angle": 0.523599, "min_ground_range": 250, "max_ground_range": 450,
               "depression": 0.698132, "snr_ref_db": 15, "range_ref": 600,
               "beamwidth": 0.0523599, "monopulse_slope": 1.6, "range_resolution": 30}],
  "planner": {"name": "pg", "alpha": 0.3, "beta": 0.95, "max_inner": 50,
              "max_outer": 10, "seed": 0}
}
"""


def _problem_default(name: str) -> Any:
    return PlanningProblem.__dataclass_fields__[name].default


class DecisionTarget(Strict):
    mean: Vec4
    cov: Matrix4
    #: Probability that the target exists, r in [0, 1]: its information counts r times in
    #: Phi (checked by the problem, which names ``targets[j].existence``).
    existence: float = 1.0
    #: Whether the tracker reports the target; the gospa reward finds one it does not
    #: instead of localising it (checked by the problem: needs reward gospa).
    reported: bool = True


class DecisionSensor(SensorParamsModel):
    position: Vec2
    heading: float | None = None            # one of the two is required (checked after)
    heading_deg: float | None = None
    #: Search sectors of the sensor (with ``search`` on): that many absolute bearings
    #: equally spaced around the platform; 0: none.
    search_sectors: int = 0


class DecisionUndetected(Strict):
    """``undetected``: the undetected targets' intensity on a grid of cells (with
    ``search`` on; see :class:`~sensorplan.planners.problem.UndetectedIntensity`)."""

    centres: list[Vec2]
    weights: list[float]                    # expected undetected targets per cell now
    births: list[float] | None = None       # expected births per cell per step (0)
    survival: float = 1.0                   # per step
    cell_size: Vec2                         # a x b of a cell (m)
    weight: float | None = None             # nats per found target (None: derived)


class DecisionPlanner(Strict):
    """``planner``: its name, seed and settings; the planner decides which settings exist
    (checked by :func:`~sensorplan.config.planners.planner_settings`)."""

    model_config = ConfigDict(extra="allow")

    name: str = "pg"
    seed: Seed | None = None


class DecisionFile(Strict):
    """The single-decision file."""

    dt: float = _problem_default("dt")
    steps_per_epoch: int = _problem_default("steps_per_epoch")
    horizon: int
    map: MapModel = MapModel()
    process_noise: float = _problem_default("process_noise")
    visibility: setting_type(RunSettings, "visibility") = (  # type: ignore[valid-type]
        _problem_default("visibility"))
    objective: setting_type(RunSettings, "objective") = (  # type: ignore[valid-type]
        _problem_default("objective"))
    planning_detection: setting_type(  # type: ignore[valid-type]
        RunSettings, "planning_detection") = _problem_default("planning_detection")
    targets: list[DecisionTarget]
    sensors: list[DecisionSensor]
    buildings: list[BuildingModel] = []
    search: Literal[SEARCH_MODES] = "off"  # type: ignore[valid-type]
    undetected: DecisionUndetected | None = None
    #: What Phi with search measures: ``information`` or ``gospa`` (the GOSPA bound removed,
    #: cut-off ``gospa_c`` in m).
    reward: setting_type(RunSettings, "reward") = (  # type: ignore[valid-type]
        _problem_default("reward"))
    gospa_c: setting_type(RunSettings, "gospa_c") = (  # type: ignore[valid-type]
        _problem_default("gospa_c"))
    #: Steps after the horizon over which the ``gospa`` reward still counts a find.
    find_tail: setting_type(RunSettings, "find_tail") = (  # type: ignore[valid-type]
        _problem_default("find_tail"))
    #: Whether the ``gospa`` reward values what a look tells about a track's existence.
    track_existence: setting_type(RunSettings, "track_existence") = (  # type: ignore[valid-type]
        _problem_default("track_existence"))
    #: Epochs of the run before this decision: where a fixed schedule (raster) stands.
    elapsed_epochs: int = _problem_default("elapsed_epochs")
    planner: DecisionPlanner = DecisionPlanner()


@dataclass(frozen=True)
class Decision:
    """A single-decision file: the problem and the planner to solve it with.

    Attributes
    ----------
    problem : PlanningProblem
    planner : str                  a planner name or ``package.module:Class``
    settings : dict                the settings passed to the planner's constructor
    existence_given : bool         whether the file gave any target's ``existence`` (the
                                   output then reports every target's)
    """

    problem: PlanningProblem
    planner: str
    settings: Mapping[str, Any]
    existence_given: bool = False

    def make_planner(self) -> Planner:
        return build_planner(self.planner, self.settings)


#: Field names of a decision file in the size limits' errors.
DECISION_FIELDS = limit_fields(lambda key, s: key, targets="targets", sensors="sensors",
                               moves="sensors[{i}].moves")


def _check_magnitudes(model: DecisionFile) -> None:
    """The ranges of :data:`sensorplan.limits.RANGES` for what a decision file gives beyond
    a scenario's keys: the targets' estimates and the sensors' headings."""
    check_count(len(model.targets), MAX_TARGETS, "targets", "targets")
    check_count(len(model.sensors), MAX_SENSORS, "sensors", "sensors")
    for j, t in enumerate(model.targets):
        for v in t.mean[:2]:
            RANGES["coordinate"].check(v, f"targets[{j}].mean")
        for v in t.mean[2:]:
            RANGES["velocity"].check(v, f"targets[{j}].mean")
        check_covariance_scale(_pd_or_none(t.cov, f"targets[{j}].cov"), f"targets[{j}].cov")
    for i, s in enumerate(model.sensors):
        Range(0, MAX_SEARCH_SECTORS).check(s.search_sectors, f"sensors[{i}].search_sectors")
        if s.heading is None and s.heading_deg is None:
            raise ConfigError(f"sensors[{i}].heading", "is required (in radians; or "
                              "heading_deg in degrees)")
        if s.heading is not None:
            RANGES["heading"].check(s.heading, f"sensors[{i}].heading", HEADING_HINT)
    for name in ("dt", "process_noise"):
        RANGES[name].check(getattr(model, name), name)
    for name in ("width", "height"):
        RANGES["length"].check(getattr(model.map, name), f"map.{name}")


def _pd_or_none(P: Any, field: str) -> Any:
    """``P`` after the covariance rules (finite, symmetric, positive definite)."""
    for row in P:
        for v in row:
            RANGES["covariance"].check(v, field)
    check_covariance(P, field)
    return P


def _undetected(model: DecisionFile) -> UndetectedIntensity | None:
    """The file's ``undetected`` as the problem takes it (the problem checks it further)."""
    u = model.undetected
    if u is None:
        return None
    C = len(u.centres)
    check_count(C, MAX_UNDETECTED_CELLS, "undetected.centres", "cells")
    for name, rule in (("weights", "cell_intensity"), ("births", "birth_rate")):
        v = getattr(u, name)
        if v is not None and len(v) != C:
            raise ConfigError(f"undetected.{name}", f"must have one number per cell ({C}), "
                              f"got {len(v)}")
        for c, x in enumerate(v or ()):
            RANGES[rule].check(x, f"undetected.{name}[{c}]")
    a, b = u.cell_size
    for x in (a, b):
        RANGES["cell_size"].check(x, "undetected.cell_size")
    if u.weight is not None:
        RANGES["found_weight"].check(u.weight, "undetected.weight")
    for c, xy in enumerate(u.centres):
        if not model.map.width >= xy[0] >= 0 <= xy[1] <= model.map.height:
            raise ConfigError(f"undetected.centres[{c}]", MapRect(
                model.map.width, model.map.height).outside(xy))
    births = np.zeros(C) if u.births is None else np.array(u.births, dtype=float)
    return UndetectedIntensity(np.array(u.centres, dtype=float).reshape(-1, 2),
                               np.array(u.weights, dtype=float), births, u.survival,
                               np.diag([a * a / 12.0, b * b / 12.0]), u.weight)


def decision_from_dict(data: Any, planner: str | None = None) -> Decision:
    """Validate a single-decision object and build the problem and planner settings.

    Parameters
    ----------
    data : object
        The parsed JSON.
    planner : str, optional
        Overrides ``planner.name`` (the CLI's ``--planner``); settings of the file that the
        new planner does not take are dropped.

    Raises
    ------
    ConfigError
        For every bad input (the field is a dotted path like ``sensors[1].altitude``).
    """
    model: DecisionFile = validate(DecisionFile, data, "a JSON object")
    _check_magnitudes(model)
    problem = PlanningProblem(
        means=np.array([t.mean for t in model.targets], dtype=float),
        covs=np.array([t.cov for t in model.targets], dtype=float),
        positions=np.array([s.position for s in model.sensors], dtype=float),
        headings=np.array([radians_of(s, "heading", None) for s in model.sensors],
                          dtype=float),
        sensors=tuple(s.params() for s in model.sensors),
        horizon=model.horizon, steps_per_epoch=model.steps_per_epoch, dt=model.dt,
        process_noise=model.process_noise, world=MapRect(model.map.width, model.map.height),
        visibility=model.visibility, objective=model.objective,
        planning_detection=model.planning_detection,
        buildings=np.array([b.row() for b in model.buildings], dtype=float),
        existence=np.array([t.existence for t in model.targets], dtype=float),
        reported=np.array([t.reported for t in model.targets], dtype=bool).reshape(-1),
        search=model.search, search_sectors=tuple(s.search_sectors for s in model.sensors),
        undetected=_undetected(model), elapsed_epochs=model.elapsed_epochs,
        reward=model.reward, gospa_c=model.gospa_c, find_tail=model.find_tail,
        track_existence=model.track_existence)
    for i, s in enumerate(problem.sensors):
        check_sensor_precision(s, f"sensors[{i}]")
    check_decision_size(problem.horizon, problem.steps_per_epoch, problem.n_targets,
                        [s.moves for s in problem.sensors], problem.world.width,
                        problem.world.height, DECISION_FIELDS, len(problem.buildings))
    params = dict(model.planner.model_extra or {})
    if model.planner.seed is not None:
        params["seed"] = model.planner.seed
    if planner is None:
        name = model.planner.name
        settings = planner_settings(name, params)
    else:
        # The file's settings were written for its own planner: keep those the new one takes.
        name = planner
        settings = replaced_planner_settings(model.planner.name, name, params,
                                             name_field="--planner", params_field="planner")
    given = any("existence" in t.model_fields_set for t in model.targets)
    return Decision(problem, name, settings, given)


def load_decision(path: str | Path, planner: str | None = None) -> Decision:
    """:func:`decision_from_dict` on a JSON file."""
    data = io.read_input(path, "decision")
    if not isinstance(data, dict):
        raise ConfigError(str(path), f"must hold a JSON object ({{...}}) with the decision's "
                          f"keys, got a {type(data).__name__}")
    return decision_from_dict(data, planner)
