"""Planner settings from input files: which a planner takes, and building it."""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from ..planners import Planner


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
    from ..planners import PLANNERS

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
    from ..planners import make_planner

    try:
        return make_planner(name, **settings)
    except ConfigError as exc:
        raise ConfigError(field if exc.field == "planner" else exc.field, exc.message) from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(field, str(exc)) from None
