"""What ``sensorplan agents`` runs: a simulation whose planner is decentralized.

The scenario file or preset and the ``simulate`` options are read as for ``simulate``
(:func:`~sensorplan.config.simulate.load_simulation`). The planner is ``--planner`` (one of
:data:`DECENTRAL`), else the file's when it is decentralized, else ``dec-jsfp``; a file's
planner settings that the chosen planner does not take are dropped, as with ``--planner``.
The link and agent options then set the planner's settings; the planner checks them, and an
error names the option (``--p-loss``; the command line passes each setting's option, from
its declaration in :mod:`sensorplan.decentral.params`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..limits import check_bus_agents
from ..planners.registry import check_settings
from .simulate import SimulationConfig, load_simulation

#: The decentralized planners, one agent per platform (docs/decentral.md).
DECENTRAL = ("dec-jsfp", "dec-independent", "dec-sequential")


def load_agents(path: str | Path | None = None, preset: str | None = None,
                overrides: Mapping[str, Any] | None = None,
                agent: Mapping[str, Any] | None = None,
                options: Mapping[str, str] | None = None) -> SimulationConfig:
    """Scenario, run settings and seed of an episode with one agent per platform.

    Parameters
    ----------
    path, preset, overrides
        As for :func:`~sensorplan.config.simulate.load_simulation`; ``overrides["planner"]``
        must be one of :data:`DECENTRAL`.
    agent : mapping, optional
        Planner settings from the agent options, by setting (``None`` values are ignored).
    options : mapping, optional
        The option that sets each setting (``p_loss`` -> ``--p-loss``), as errors name it;
        when given, a key of ``agent`` without one is an error. Without it errors name
        ``planning.planner_params.<key>``.

    Raises
    ------
    ConfigError
        As ``load_simulation``; ``--planner`` for a planner that is not decentralized; the
        option of a link or agent setting the planner does not take or rejects.
    """
    overrides = dict(overrides or {})
    chosen = overrides.get("planner")
    if chosen is not None and chosen not in DECENTRAL:
        raise ConfigError("--planner", f"must be a decentralized planner ({', '.join(DECENTRAL)}"
                          f"), got {chosen!r}")
    cfg = load_simulation(path, preset, overrides)
    if cfg.settings.planner not in DECENTRAL:
        cfg = load_simulation(path, preset, {**overrides, "planner": DECENTRAL[0]})
    given = {k: v for k, v in (agent or {}).items() if v is not None}
    named = dict(options or {})

    def field_of(key: str) -> str:
        """How errors name setting ``key``: the option that set it, else the file's key."""
        return named[key] if key in given and key in named else f"planning.planner_params.{key}"

    unknown = sorted(set(given) - set(named)) if options is not None else []
    if unknown:
        raise ConfigError(unknown[0], "is not an agent option")
    settings = cfg.settings
    params = {**settings.planner_params, **given}
    try:
        params = check_settings(settings.planner, params, "planner")
    except ConfigError as exc:
        key = exc.field.removeprefix("planner.")
        raise ConfigError(field_of(key), exc.message) from None
    if params.get("transport") == "bus":                    # checked before anything runs
        check_bus_agents(len(cfg.scenario.sensors), field_of("transport"))
    return dataclasses.replace(cfg, settings=dataclasses.replace(settings,
                                                                 planner_params=params))
