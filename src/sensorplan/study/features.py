"""The features a grid study varies: one function per feature (docs/studies.md, "Grid
studies").

A scenario feature maps ``(scenario, value) -> scenario``; the ``setting`` feature maps
``(run settings, key, value) -> run settings`` (or None for a method whose planner does not
take the key). A bad value raises ``ValueError`` with the reason; the grid file names the
axis (``axes[i].values``).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Callable
from typing import Any

from ..config.planners import RUN_SEED
from ..errors import ConfigError
from ..models.sensors import SensorParams
from ..planners.registry import planner_class, planner_settings_of
from ..simulation.scenario import Scenario, town_buildings
from ..simulation.settings import RunSettings, all_settings

#: Largest half size (m) of the town's buildings: at 70 m neighbouring blocks touch.
TOWN_MAX = 70.0


def _number(value: Any, *, inf: bool = False) -> float:
    """``value`` as a float: a number (not a bool), never NaN, infinite only if ``inf``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"must be a number, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not (inf and v > 0)):
        raise ValueError("must be a finite number" + (" or inf" if inf else "")
                         + f", got {value!r}")
    return v


def _every_sensor(scenario: Scenario, change: Callable[[SensorParams], SensorParams]
                  ) -> Scenario:
    sensors = tuple(dataclasses.replace(s, params=change(s.params)) for s in scenario.sensors)
    return _rebuilt(scenario, sensors=sensors)


def _rebuilt(scenario: Scenario, **changes: Any) -> Scenario:
    """``dataclasses.replace`` with the scenario's own checks turned into a ValueError."""
    try:
        return dataclasses.replace(scenario, **changes)
    except ConfigError as exc:
        raise ValueError(f"makes the scenario invalid ({exc.field}: {exc.message})") from None


def sensor_speed(scenario: Scenario, value: Any) -> Scenario:
    """Every sensor's move distances (``moves``) times ``value`` (> 0); 1 keeps them (the
    paper's 20 and 40 m per step)."""
    v = _number(value)
    if v <= 0:
        raise ValueError(f"must be > 0, got {value!r}")
    return _every_sensor(scenario, lambda p: dataclasses.replace(
        p, moves=tuple(float(m) * v for m in p.moves)))


def min_ground_range(scenario: Scenario, value: Any) -> Scenario:
    """Every sensor's ``min_ground_range`` (m), the radius of the blind disc under it:
    > 0 and below every sensor's ``max_ground_range``."""
    v = _number(value)
    if v <= 0:
        raise ValueError(f"must be > 0 m, got {value!r}")
    for i, s in enumerate(scenario.sensors):
        if not v < float(s.params.max_ground_range):
            raise ValueError(f"must be below max_ground_range ({float(s.params.max_ground_range):g}"
                             f" m of sensors[{i}]), got {value!r}")
    return _every_sensor(scenario, lambda p: dataclasses.replace(p, min_ground_range=v))


def town(scenario: Scenario, value: Any) -> Scenario:
    """The buildings: ``town_buildings(half_size=value)`` (a 3 x 3 block grid in the
    middle of the paper's map), none for 0; ``value`` in [0, 70) m. Replaces the
    scenario's own buildings."""
    v = _number(value)
    if not 0.0 <= v < TOWN_MAX:
        raise ValueError(f"must be in [0, {TOWN_MAX:g}) m, got {value!r}")
    return _rebuilt(scenario, buildings=town_buildings(half_size=v) if v > 0 else ())


def snr_ref_db(scenario: Scenario, value: Any) -> Scenario:
    """Every sensor detects a Swerling 1 target with ``snr_ref_db = value`` (dB at the
    reference range; the SNR also sets the measurement noise); ``inf``: ideal detection
    with the scenario's own ``snr_ref_db`` for the noise."""
    v = _number(value, inf=True)
    if math.isinf(v):
        return _every_sensor(scenario, lambda p: dataclasses.replace(p, detection="ideal"))
    return _every_sensor(scenario, lambda p: dataclasses.replace(
        p, detection="swerling1", snr_ref_db=v))


def clutter_rate(scenario: Scenario, value: Any) -> Scenario:
    """Every sensor's ``clutter_rate``: false detections per look (Poisson), >= 0."""
    v = _number(value)
    if v < 0:
        raise ValueError(f"must be >= 0, got {value!r}")
    return _every_sensor(scenario, lambda p: dataclasses.replace(p, clutter_rate=v))


def birth_rate(scenario: Scenario, value: Any) -> Scenario:
    """The scenario's ``birth_rate``: expected target births per step, >= 0; the scenario
    must have births (``births`` other than ``none``). The trackers' birth model follows it
    (:func:`tracker_birth_rate`)."""
    v = _number(value)
    if v < 0:
        raise ValueError(f"must be >= 0, got {value!r}")
    if scenario.births == "none":
        raise ValueError('needs a scenario whose targets are born (births other than "none", '
                         'e.g. the search preset)')
    return _rebuilt(scenario, birth_rate=v)


def tracker_birth_rate(settings: RunSettings, value: Any) -> RunSettings:
    """A method's settings with its tracker's ``birth_rate`` set to the scenario's: a
    tracker with a birth model is told the rate the targets are born at, as a preset's is.
    A tracker without one (``known``) is left as it is."""
    if settings.tracker.kind == "known":
        return settings
    return dataclasses.replace(settings, tracker=dataclasses.replace(
        settings.tracker, birth_rate=float(value)))


#: Scenario features by name.
SCENARIO_FEATURES: dict[str, Callable[[Scenario, Any], Scenario]] = {
    "sensor_speed": sensor_speed, "min_ground_range": min_ground_range, "town": town,
    "snr_ref_db": snr_ref_db, "clutter_rate": clutter_rate, "birth_rate": birth_rate}
#: Scenario features that the methods' settings follow (the trackers' model of the scenario).
METHODS_FOLLOW: dict[str, Callable[[RunSettings, Any], RunSettings]] = {
    "birth_rate": tracker_birth_rate}
#: Every feature a grid axis may name.
FEATURES = (*SCENARIO_FEATURES, "setting")
#: What a figure calls the axis of each scenario feature: its name, then what its values
#: are, in their unit (the values stay as the grid file writes them).
AXIS_TITLES = {
    "sensor_speed": "sensor_speed (x the moves)",
    "min_ground_range": "min_ground_range (m)",
    "town": "town: half width of a block (m)",
    "snr_ref_db": "snr_ref_db (dB)",
    "clutter_rate": "clutter_rate (per look)",
    "birth_rate": "birth_rate (births per step)",
}


def axis_title(name: str) -> str:
    """The title of a grid axis in figures (:data:`AXIS_TITLES`; a ``setting`` axis's key
    as it is): ``town`` reads as the half width of a block, so that its values 20, 30, 40
    are blocks 40, 60, 80 m wide."""
    return AXIS_TITLES.get(name, name)
#: Per-method settings a ``setting`` axis may set directly (not the planner, not the
#: study-wide ones such as ``steps``).
METHOD_SETTINGS = tuple(path for _, path, _, s in all_settings()
                        if s.section != "run" and path not in ("planner", "planner_params"))
_PARAMS = "planner_params."


def planner_takes(settings: RunSettings, name: str) -> bool:
    """Whether the planner of ``settings`` has the setting ``name`` (its seed excluded: the
    run's seed drives it)."""
    return name not in RUN_SEED and name in planner_settings_of(planner_class(settings.planner))


def check_setting_key(key: str, methods: list[RunSettings]) -> None:
    """A ``setting`` axis's key: ``planner_params.NAME`` taken by at least one method's
    planner, or a per-method setting; ValueError otherwise."""
    if key.startswith(_PARAMS):
        name = key[len(_PARAMS):]
        if not any(planner_takes(s, name) for s in methods):
            taken = sorted({k for s in methods for k in planner_settings_of(
                planner_class(s.planner)) if k not in RUN_SEED})
            close = difflib.get_close_matches(name, taken, n=1)
            raise ValueError(f"no method's planner takes {name!r}"
                             + (f" (did you mean {_PARAMS + close[0]!r}?)" if close else "")
                             + f"; the methods' planners take: {', '.join(taken)}")
        return
    if key not in METHOD_SETTINGS:
        close = difflib.get_close_matches(key, [*METHOD_SETTINGS, _PARAMS + "alpha"], n=1)
        raise ValueError(f"unknown setting {key!r}" + (f" (did you mean {close[0]!r}?)"
                                                        if close else "")
                         + f"; use planner_params.NAME or one of {', '.join(METHOD_SETTINGS)}")


def setting(settings: RunSettings, key: str, value: Any) -> RunSettings | None:
    """``settings`` with ``key`` set to ``value``; None when ``key`` is
    ``planner_params.NAME`` and the method's planner does not take NAME (the method is left
    as it is). The settings' own checks apply (ConfigError)."""
    if key.startswith(_PARAMS):
        name = key[len(_PARAMS):]
        if not planner_takes(settings, name):
            return None
        return dataclasses.replace(settings, planner_params={**settings.planner_params,
                                                             name: value})
    if "." in key:
        group, name = key.split(".", 1)
        inner = dataclasses.replace(getattr(settings, group), **{name: value})
        return dataclasses.replace(settings, **{group: inner})
    return dataclasses.replace(settings, **{key: value})
