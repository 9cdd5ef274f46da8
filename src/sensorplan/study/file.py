"""Study files (TOML): their strict model and the :class:`~sensorplan.study.model.Study`.

A study file names a scenario, the number of paired runs, their length, the root seed and a
list of methods; ``sensorplan study`` runs every method on every run (docs/studies.md)::

    description = "what this study is for"      # optional, free text
    runs = 100                                  # paired Monte Carlo runs
    steps = 100                                 # simulation steps per run
    seed = 2024                                 # root SeedSequence of the study

    [scenario]                                  # optional; default: preset = "paper"
    preset = "paper"                            # or: file = "../configs/paper.toml"
                                                # (relative to this file; its [planning],
                                                # [tracker] and [run] tables are not used)

    [defaults]                                  # optional: settings every method inherits
    steps_per_epoch = 2
    [defaults.tracker]
    miss_update = "negative"

    [[methods]]
    name = "paper/olf"                          # unique; used in tables and figures
    planner = "pg"                              # a planner name or package.module:Class
    horizon = 3                                 # and every other [planning] setting
    [methods.planner_params]                    # the planner's settings (pg: alpha, beta,
    alpha = 0.3                                 # max_inner, max_outer)
    [methods.tracker]                           # every [tracker] setting
    miss_update = "none"

The method settings are :mod:`sensorplan.simulation.settings`' ``planning`` and ``tracker``
sections;
each key is the method's value, else the one in ``[defaults]``, else the preset's
(:data:`sensorplan.simulation.scenario.PRESET_SETTINGS`: ``search`` and the scan presets
run the ``pmb`` tracker, ``search`` sets ``search_sectors``, the scan presets set
``gospa_c``), else the setting's default.
A scan preset (``williams15``, ``vo12``) plans nothing: its methods name no planner and no
other planning key (each refused, naming it).
``planner_params`` merge key by key: a method's own keys must be settings of its planner; a
key of ``[defaults.planner_params]`` applies to the methods whose planner takes it, and must
be taken by at least one.
"""

from __future__ import annotations

import dataclasses
import difflib
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, create_model

from ..config import files as io
from ..config.planners import RUN_SEED
from ..config.scenario import scenario_from_dict
from ..config.simulate import load_simulation, preset_scenario
from ..config.validation import (PositiveInt, Seed, Strict, given, section_model,
                                 setting_annotation, setting_type, validate)
from ..errors import ConfigError
from ..limits import check_run, check_study_size
from ..planners.registry import check_settings, instantiate, planner_class, planner_settings_of
from ..simulation.scenario import PRESET_SETTINGS, Scenario
from ..simulation.settings import (RunSettings, Setting, declared, field_type, is_group,
                                   limit_fields)
from .model import STUDY_KEYS, Method, Study


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


class StudyScenarioModel(Strict):
    preset: str | None = None
    file: str | None = None


def _groups(cls: type) -> dict[str, Any]:
    """Each nested settings group of ``cls`` as an optional sub-table model."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        tp = field_type(cls, f.name)
        if is_group(tp):
            section = declared(tp)[0][1].section
            out[f.name] = (section_model(tp, section, f"Method_{f.name}") | None, None)
    return out


#: A method's settings; a key left out inherits ``[defaults]``, then the setting's default.
MethodSettings = section_model(RunSettings, "planning", "MethodSettings",
                               "A method's settings (also the [defaults] table).",
                               **_groups(RunSettings))
MethodModel = create_model("MethodModel", __base__=MethodSettings,
                           name=(Annotated[str, AfterValidator(_method_name)], ...))
_STUDY_WIDE: dict[str, Any] = {f.name: (setting_annotation(RunSettings, f, s) | None, None)
                               for f, s in declared(RunSettings, "run")}
_STUDY_WIDE["steps"] = (setting_type(RunSettings, "steps"), ...)
StudyFile = create_model(
    "StudyFile", __base__=Strict, description=(str, ""), runs=(PositiveInt, ...),
    **_STUDY_WIDE, seed=(Seed, 0), scenario=(StudyScenarioModel, StudyScenarioModel()),
    defaults=(MethodSettings, MethodSettings()),
    # A model built at run time is a valid item type for pydantic, not for a type checker.
    methods=(Annotated[list[MethodModel], AfterValidator(_non_empty)], ...))  # type: ignore[valid-type, arg-type]


def _inherit(cls: type, own: dict[str, Any], inherited: dict[str, Any], own_at: str,
             inherited_at: str, origin: dict[str, str], prefix: str = "") -> dict[str, Any]:
    """Per key: the method's value, else the inherited one (absent: the field's default).

    ``origin`` receives, for each settings path given, where its value was written.
    """
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        key, path = f.name, prefix + f.name
        if is_group(field_type(cls, key)):
            out[key] = _inherit(field_type(cls, key), own.get(key, {}), inherited.get(key, {}),
                                f"{own_at}.{key}", f"{inherited_at}.{key}", origin, path + ".")
        elif key == "planner_params":
            continue                                 # merged key by key by the caller
        elif key in own:
            out[key], origin[path] = own[key], f"{own_at}.{key}"
        elif key in inherited:
            out[key], origin[path] = inherited[key], f"{inherited_at}.{key}"
    return out


def _study_scenario(model: StudyScenarioModel, base_dir: Path | None) -> tuple[Scenario, str]:
    if model.preset is not None and model.file is not None:
        raise ConfigError("scenario", "give preset or file, not both")
    if model.file is None:
        scenario = preset_scenario(model.preset, "scenario.preset")
        return scenario, f"preset {model.preset or 'paper'}"
    path = Path(model.file)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    try:
        data = io.read_input(path, "scenario")
        scenario = scenario_from_dict(data)
        # Its [planning], [tracker] and [run] tables are not used, but they are checked as a
        # run of the file would check them (its planner's settings against its planner):
        # a key that means nothing is an error here too, not silently dropped.
        load_simulation(path)
        return scenario, f"file {path}"
    except ConfigError as exc:
        where = exc.field if exc.field == str(path) else f"{path}: {exc.field}"
        raise ConfigError("scenario.file", f"{where}: {exc.message}") from None


def _no_planning(i: int, m: Any, defaults: dict[str, Any], scan: str) -> None:
    """Refuse method ``i``'s planning keys (its own or from ``[defaults]``) for a scan
    scenario: its sensor sees the whole map every step, nothing is planned."""
    own = given(m)
    for f, _ in declared(RunSettings, "planning"):
        at = (f"methods[{i}].{f.name}" if f.name in own else
              f"defaults.{f.name}" if f.name in defaults else None)
        if at is not None:
            raise ConfigError(at, f"planning does not apply to the {scan} scan (its linear "
                              "sensor sees the whole map every step): leave it out")


def _method(i: int, m: Any, defaults: dict[str, Any], study_wide: dict[str, Any],
            used: set[str], scan: bool = False) -> Method:
    """Method ``i``; adds to ``used`` the ``[defaults.planner_params]`` keys it takes
    (``scan``: the scenario plans nothing, so no planner is required)."""
    own = given(m)
    own.pop("name")
    origin: dict[str, str] = {}
    kwargs = _inherit(RunSettings, own, defaults, f"methods[{i}]", "defaults", origin)
    if "planner" not in kwargs and scan:
        kwargs["planner"] = RunSettings.__dataclass_fields__["planner"].default
        origin["planner"] = "scenario.preset"
    if "planner" not in kwargs:
        raise ConfigError(f"methods[{i}].planner", "is required (in the method or in "
                          "[defaults])")
    cls = planner_class(kwargs["planner"], origin["planner"])
    own_params = own.get("planner_params", {})
    own_at = f"methods[{i}].planner_params"
    settings = check_settings(cls, own_params, own_at, exclude=RUN_SEED, construct=False)
    inherited = {k: v for k, v in defaults.get("planner_params", {}).items()
                 if k not in own_params}
    settings.update(check_settings(cls, inherited, "defaults.planner_params", strict=False,
                                   exclude=RUN_SEED, construct=False))
    used.update(k for k in settings if k not in own_params)
    try:
        planner = instantiate(cls, settings)
    except ConfigError as exc:
        key = exc.field.removeprefix("planner").removeprefix(".")
        at = own_at if key in own_params or (not key and own_params) else \
            "defaults.planner_params"
        raise ConfigError(at + (f".{key}" if key else ""), exc.message) from None
    # Every setting of the planner, filled with its value, so that config.resolved.json
    # shows what ran (the seed comes from the run). Settings that are None (off) are left
    # out: a setting added later with a default of None leaves old study directories valid.
    filled = {k: getattr(planner, k) for k in planner_settings_of(cls)
              if k not in RUN_SEED and getattr(planner, k, None) is not None}
    if not dataclasses.is_dataclass(planner):
        filled = dict(settings)
    try:
        run_settings = RunSettings(planner_params=filled, **study_wide, **kwargs)
    except ConfigError as exc:
        field = origin.get(exc.field, f"methods[{i}].{exc.field}")
        raise ConfigError(field, exc.message) from None
    return Method(m.name, run_settings)


def _unused_defaults(defaults: dict[str, Any], used: set[str], methods: list[Method]) -> None:
    """A ``[defaults.planner_params]`` key that no method's planner takes is an error."""
    for key in defaults.get("planner_params", {}):
        if key in used:
            continue
        takes = sorted({k for m in methods for k in planner_settings_of(
            planner_class(m.settings.planner)) if k not in RUN_SEED})
        message = "no method's planner takes it"
        close = difflib.get_close_matches(key, takes, n=1)
        if close:
            message += f" (did you mean {close[0]!r}?)"
        raise ConfigError(f"defaults.planner_params.{key}",
                          message + f"; the methods' planners take: {', '.join(takes)}")


def _origin_of(method: Any, key: str, i: int) -> str:
    """Where method ``i``'s ``key`` was written: the method, else ``[defaults]``."""
    return f"methods[{i}].{key}" if getattr(method, key, None) is not None else \
        f"defaults.{key}"


def study_from_dict(data: Any, base_dir: str | Path | None = None) -> Study:
    """Validate a study table and build the :class:`~sensorplan.study.model.Study`.

    Parameters
    ----------
    data : object
        The parsed TOML (see the module docstring for the keys).
    base_dir : path, optional
        Directory that a relative ``scenario.file`` is relative to (the study file's).

    Raises
    ------
    ConfigError
        Naming the field with a dotted path such as ``methods[2].horizon`` (or
        ``defaults.horizon`` when the value came from ``[defaults]``).
    """
    model: Any = validate(StudyFile, data)
    scenario, source = _study_scenario(model.scenario, None if base_dir is None
                                       else Path(base_dir))
    defaults = given(model.defaults)
    study_wide = {k: getattr(model, k) for k in STUDY_KEYS if getattr(model, k) is not None}
    if model.scenario.file is None:
        # The preset's own settings, under the file's: its tracker under [defaults.tracker],
        # its study-wide keys (gospa_c; a study always gives its steps) under the file's.
        preset = PRESET_SETTINGS.get(model.scenario.preset or "paper", {})
        if preset.get("tracker"):
            defaults["tracker"] = {**preset["tracker"], **defaults.get("tracker", {})}
        for key, value in preset.get("planning", {}).items():
            defaults.setdefault(key, value)
        for key, value in preset.get("run", {}).items():
            if key in STUDY_KEYS and key != "steps":
                study_wide.setdefault(key, value)
    seen: dict[str, int] = {}
    methods: list[Method] = []
    used: set[str] = set()
    for i, m in enumerate(model.methods):
        if m.name in seen:
            raise ConfigError(f"methods[{i}].name", f"duplicate method name {m.name!r} "
                              f"(also methods[{seen[m.name]}])")
        seen[m.name] = i
        if scenario.scan is not None:
            _no_planning(i, m, defaults, scenario.scan)
        methods.append(_method(i, m, defaults, study_wide, used, scenario.scan is not None))
    _unused_defaults(defaults, used, methods)
    for i, m in enumerate(methods):
        # A planning key comes from the method or [defaults]; a run key is study-wide.
        def origin(key: str, s: Setting, i: int = i) -> str:
            return _origin_of(model.methods[i], key, i) if s.section == "planning" else key

        check_run(scenario, m.settings, limit_fields(origin, targets="scenario",
                                                     sensors="scenario", moves="scenario"))
    check_study_size(model.runs, len(methods), model.steps, len(scenario.targets))
    return Study(scenario=scenario, runs=model.runs, steps=model.steps, seed=model.seed,
                 methods=tuple(methods), description=model.description,
                 scenario_source=source)


def load_study(path: str | Path) -> Study:
    """:func:`study_from_dict` on a TOML file (a relative scenario file is relative to it)."""
    path = Path(path)
    return study_from_dict(io.read_input(path, "study"), base_dir=path.parent)


def parse_study(text: str, source: str = "<study>", base_dir: str | Path | None = None
                ) -> Study:
    """:func:`study_from_dict` on TOML text (the built-in demo study)."""
    return study_from_dict(io.parse_toml(text, source), base_dir=base_dir)
