"""What ``sensorplan simulate`` runs: a scenario file or preset, plus option overrides."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..limits import check_run
from ..simulation.scenario import PRESET_SETTINGS, Scenario
from ..simulation.scenario import PRESETS as SCENARIO_PRESETS
from ..simulation.settings import RunSettings, all_settings, limit_fields
from . import files as io
from .planners import RUN_SEED, planner_settings, replaced_planner_settings
from .scenario import ScenarioFile, SettingsTables
from .validation import given, validate

#: Built-in scenarios for ``sensorplan simulate --preset`` and study files.
PRESETS = tuple(SCENARIO_PRESETS)

#: Run setting -> (section, key) in a scenario file, and the run's seed.
FILE_KEYS = {f.name: (s.section, f.name) for _, _, f, s in all_settings()}
FILE_KEYS["seed"] = ("run", "seed")
#: Field names of a scenario file in the size limits' errors.
RUN_FIELDS = limit_fields(lambda key, s: f"{s.section}.{key}", targets="targets",
                          sensors="sensors", moves="sensors[{i}].moves")
#: RunSettings field path -> its path in a scenario file.
_FILE_PATHS = {path: f"{s.section}.{f.name}" for _, path, f, s in all_settings()}


@dataclass(frozen=True)
class SimulationConfig:
    """Everything ``sensorplan simulate`` runs: scenario, run settings and the run's seed."""

    scenario: Scenario
    settings: RunSettings
    seed: int


#: Words that mean a boolean: given where a scenario file is expected, a flag's value.
BOOLEAN_WORDS = ("true", "false", "yes", "no", "on", "off")


def option_name(key: str) -> str:
    """The ``simulate`` option of an override key: its first declared name, else
    ``--key-with-dashes``."""
    for _, _, f, s in all_settings():
        if f.name == key and s.cli:
            return s.cli[0]
    return "--" + key.replace("_", "-")


def _rename(exc: ConfigError, renames: Mapping[str, str]) -> ConfigError:
    for old, new in renames.items():
        if exc.field == old or exc.field.startswith(old + ".") or exc.field.startswith(old + "["):
            return ConfigError(new + exc.field[len(old):], exc.message)
    return exc


def preset_scenario(name: str | None, field: str) -> Scenario:
    """The built-in scenario ``name`` (None: ``paper``); an unknown name (the empty one
    too) names ``field``, with the closest preset."""
    import difflib

    name = "paper" if name is None else name
    if name not in PRESETS:
        close = difflib.get_close_matches(name.lower(), PRESETS, n=1, cutoff=0.5)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(field, f"unknown preset {name!r}{hint}; choose from "
                          f"{', '.join(PRESETS)}")
    try:
        return SCENARIO_PRESETS[name]()
    except ConfigError as exc:
        # A preset that cannot be built here (traffic's records not fetched): name the
        # option or key that asked for it.
        raise ConfigError(field, exc.message) from None


def read_scenario_file(path: str | Path) -> dict[str, Any]:
    """Parse a scenario TOML file, with a hint for the usual mix-ups: a missing file named
    like a preset (``simulate paper``) and a single-decision JSON file."""
    path = Path(path)
    if not path.exists() and str(path) in PRESETS:
        raise ConfigError(str(path), f"no such file (for the built-in scenario, write "
                          f"--preset {path})")
    if path.is_file():
        try:
            with path.open("rb") as f:
                start = f.read(512).lstrip()
        except OSError:
            start = b""
        if path.suffix.lower() == ".json" or start.startswith(b"{"):
            raise ConfigError(str(path), "is a JSON file: a single decision is planned with "
                              "sensorplan plan; simulate reads a scenario TOML file (see "
                              "configs/paper.toml)")
    return io.read_input(path, "scenario")


def load_simulation(path: str | Path | None = None, preset: str | None = None,
                    overrides: Mapping[str, Any] | None = None) -> SimulationConfig:
    """Scenario file or preset, plus command-line overrides, as a :class:`SimulationConfig`.

    Parameters
    ----------
    path : path, optional
        A scenario TOML file (:mod:`sensorplan.config.scenario`); its ``[planning]``,
        ``[tracker]`` and ``[run]`` tables give the run settings and seed.
    preset : str, optional
        A name in :data:`PRESETS` (``paper``:
        :func:`~sensorplan.simulation.scenario.paper_scenario` with
        default run settings). Give ``path`` or ``preset``, not both; neither means ``paper``.
    overrides : mapping, optional
        Run settings by field name (``horizon``, ``miss_update``, ...) and ``seed``; ``None``
        values are ignored. They replace the file's values; errors in them name the option
        (``--horizon``).

    Raises
    ------
    ConfigError
    """
    given_ = {k: v for k, v in (overrides or {}).items() if v is not None}
    unknown = sorted(set(given_) - set(FILE_KEYS))
    if unknown:
        raise ConfigError(option_name(unknown[0]), "is not a simulation setting")
    if path is not None and str(path).lower() in BOOLEAN_WORDS and not Path(path).exists():
        # "--gate false": the flag took no value, and the word became the scenario file.
        raise ConfigError(str(path), f"no such file (a flag such as --gate takes no value: "
                          f"write --gate or --no-gate, not --gate {path})")
    if path is not None and preset is not None:
        raise ConfigError("--preset", "give a scenario file or --preset, not both")
    if path is None:
        scenario = preset_scenario(preset, "--preset")
        # The preset's own settings, as a file's tables would give them.
        data: dict[str, Any] = {section: dict(values) for section, values in
                                PRESET_SETTINGS.get(preset or "paper", {}).items()}
    else:
        data = read_scenario_file(path)
    planning = data.get("planning")
    own = planning.get("planner") if isinstance(planning, dict) else None   # the file's own
    renames: dict[str, str] = {}
    for key, value in given_.items():
        section, name = FILE_KEYS[key]
        if not isinstance(data.setdefault(section, {}), dict):
            continue                                # the model reports the bad section
        data[section][name] = value
        renames[f"{section}.{name}"] = option_name(key)
    try:
        if path is None:
            tables: Any = validate(SettingsTables, data)
        else:
            tables = validate(ScenarioFile, data)
            scenario = tables.scenario()
        _no_planning_with_scan(scenario, given(tables.planning), given_)
        settings = _run_settings(tables, planner_overridden="planner" in given_,
                                 own_planner=own if isinstance(own, str) else None)
        check_run(scenario, settings, RUN_FIELDS)
    except ConfigError as exc:
        if exc.field == "tracker.reacquire" and given_.get("gate") is False \
                and "reacquire" not in given_:
            # The option given is what to change, not the file key it collided with.
            raise ConfigError("--no-gate", "re-acquisition needs the gate (it restarts a "
                              "track from a detection outside it): add --no-reacquire"
                              ) from None
        if exc.field == "planning.search" and path is None and "kind" in given_ \
                and "search" not in given_:
            # The preset chose search; the tracker given is what the user asked for.
            raise ConfigError("--tracker", f"the {preset} preset plans search looks, which "
                              f"need the pmb tracker (it keeps the intensity of undetected "
                              f"targets), not {given_['kind']!r}: add --search off to "
                              f"track with it") from None
        raise _rename(exc, renames) from None
    return SimulationConfig(scenario, settings, tables.run.seed)


def _no_planning_with_scan(scenario: Scenario, planning: Mapping[str, Any],
                           options: Mapping[str, Any]) -> None:
    """Refuse planning settings for a scenario whose sensor scans the whole map (``scan``):
    there is nothing to plan, so a planner or horizon given would be silently ignored."""
    if scenario.scan is None:
        return
    planning_keys = [f.name for _, _, f, s in all_settings() if s.section == "planning"]
    for key in planning_keys:
        if key in options:
            field = option_name(key)
        elif key in planning:
            field = f"planning.{key}"
        else:
            continue
        raise ConfigError(field, f"planning does not apply to the {scenario.scan} scan (its "
                          "linear sensor sees the whole map every step): leave it out")


def _run_settings(tables: Any, planner_overridden: bool = False,
                  own_planner: str | None = None) -> RunSettings:
    """RunSettings from a file's settings tables: given keys, else the fields' defaults
    (``own_planner``: the file's planner, when ``--planner`` replaced it)."""
    planning, run = given(tables.planning), given(tables.run)
    run.pop("seed", None)
    kwargs: dict[str, Any] = {**planning, **run, "tracker": given(tables.tracker)}
    default = RunSettings.__dataclass_fields__["planner"].default
    name = kwargs.get("planner", default)
    params = kwargs.pop("planner_params", {})
    if planner_overridden:
        # The file's settings were meant for its own planner: a key it does not take is
        # still an error; of the others, keep those the new one takes.
        kwargs["planner_params"] = replaced_planner_settings(
            own_planner or str(default), name, params, name_field="planning.planner",
            params_field="planning.planner_params", exclude=RUN_SEED)
    else:
        kwargs["planner_params"] = planner_settings(
            name, params, name_field="planning.planner",
            params_field="planning.planner_params", exclude=RUN_SEED)
    try:
        return RunSettings(**kwargs)
    except ConfigError as exc:
        raise _rename(exc, _FILE_PATHS) from None
