"""The single-decision file (JSON, SPEC 7) of ``sensorplan plan``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ConfigDict

from .. import io
from ..problem import MapRect, PlanningProblem
from ..settings import RunSettings
from ..validation import (BuildingModel, MapModel, Matrix4, Seed, SensorParamsModel, Strict, Vec2, Vec4,
                          setting_type, validate)
from .planners import build_planner, planner_settings

if TYPE_CHECKING:  # pragma: no cover
    from ..planners import Planner


def _problem_default(name: str) -> Any:
    return PlanningProblem.__dataclass_fields__[name].default


class DecisionTarget(Strict):
    mean: Vec4
    cov: Matrix4


class DecisionSensor(SensorParamsModel):
    position: Vec2
    heading: float


class DecisionPlanner(Strict):
    """``planner``: its name, seed and settings; the planner decides which settings exist
    (checked by :func:`~sensorplan.config.planners.planner_settings`)."""

    model_config = ConfigDict(extra="allow")

    name: str = "pg"
    seed: Seed | None = None


class DecisionFile(Strict):
    """SPEC 7's single-decision file."""

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
    planner: DecisionPlanner = DecisionPlanner()


@dataclass(frozen=True)
class Decision:
    """A single-decision file: the problem and the planner to solve it with.

    Attributes
    ----------
    problem : PlanningProblem
    planner : str                  a planner name or ``package.module:Class``
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
        new planner does not take are dropped.

    Raises
    ------
    ConfigError
        For every bad input of SPEC 7 (the field is a dotted path like ``sensors[1].altitude``).
    """
    model: DecisionFile = validate(DecisionFile, data, "a JSON object")
    problem = PlanningProblem(
        means=[t.mean for t in model.targets],
        covs=[t.cov for t in model.targets],
        positions=[s.position for s in model.sensors],
        headings=[s.heading for s in model.sensors],
        sensors=tuple(s.params() for s in model.sensors),
        horizon=model.horizon, steps_per_epoch=model.steps_per_epoch, dt=model.dt,
        process_noise=model.process_noise, world=MapRect(model.map.width, model.map.height),
        visibility=model.visibility, objective=model.objective,
        planning_detection=model.planning_detection,
        buildings=[b.row() for b in model.buildings])
    params = dict(model.planner.model_extra or {})
    if model.planner.seed is not None:
        params["seed"] = model.planner.seed
    if planner is None:
        name = model.planner.name
        settings = planner_settings(name, params)
    else:
        # The file's settings were written for its own planner: keep those the new one takes.
        name = planner
        settings = planner_settings(name, params, name_field="--planner", strict=False)
    return Decision(problem, name, settings)


def load_decision(path: str | Path, planner: str | None = None) -> Decision:
    """:func:`decision_from_dict` on a JSON file."""
    return decision_from_dict(io.read_json(path), planner)
