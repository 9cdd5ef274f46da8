"""Planner settings from input files: checking them and building the planner.

A file's planner settings are open-ended but strict: a key is accepted if and only if the
chosen planner has that setting (:func:`sensorplan.planners.registry.check_settings`), and
the planner's own constructor checks the values. Errors name the file's field:
``planner.<key>`` in a plan file, ``planning.planner_params.<key>`` in a scenario,
``methods[i].planner_params.<key>`` in a study.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError
from ..planners.registry import check_settings, instantiate, planner_class

if TYPE_CHECKING:  # pragma: no cover
    from ..planners import Planner

#: Why a scenario or study may not set the planner's seed.
RUN_SEED = {"seed": "is not a setting here: the run's seed drives the planner ([run] seed of "
                    "a scenario, seed of a study)"}


def planner_settings(name: str, params: Mapping[str, Any], name_field: str = "planner.name",
                     params_field: str = "planner", *, strict: bool = True,
                     exclude: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The settings ``params`` checked for planner ``name`` (``None`` values dropped).

    Parameters
    ----------
    name : str
        A planner name or ``package.module:Class``.
    params : mapping
        Candidate settings.
    name_field, params_field : str
        Field paths used in errors: the planner's name, and the table of its settings.
    strict : bool
        With False, keys the planner does not take are dropped instead of refused (the
        file's settings were written for another planner: ``--planner`` replaced it).
    exclude : mapping, optional
        Settings not allowed in this file -> why (:data:`RUN_SEED`).

    Raises
    ------
    ConfigError
        Unknown planner (``name_field``, with close matches and every known name), unknown
        key (``params_field.key``, with the closest setting), bad type or a value the
        planner rejects.
    """
    cls = planner_class(name, name_field)
    return check_settings(cls, params, params_field, strict=strict, exclude=exclude)


def replaced_planner_settings(own: str, name: str, params: Mapping[str, Any],
                              name_field: str, params_field: str, *,
                              exclude: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The settings of a file written for planner ``own``, for planner ``name`` that
    replaces it (``--planner``): a key ``own`` does not have either (a typo) is still an
    error naming ``params_field.key``; of the others, those ``name`` takes are checked and
    kept, the rest dropped. An ``own`` that names no planner is not checked (the option
    replaces it)."""
    from ..planners.registry import check_settings as _check

    try:
        own_cls = planner_class(own, "planner")
    except ConfigError:
        own_cls = None
    if own_cls is not None:
        # Keys only: the values of settings the new planner drops are never used.
        _check(own_cls, dict.fromkeys(params), params_field, construct=False)
    return planner_settings(name, params, name_field, params_field, strict=False,
                            exclude=exclude)


def build_planner(name: str, settings: Mapping[str, Any], field: str = "planner") -> Planner:
    """The planner ``name`` with checked ``settings``; failures name ``field``'s keys."""
    return instantiate(planner_class(name, field + ".name"), settings, field)


def planner_hint(exc: ConfigError) -> ConfigError:
    """``exc`` with a suggestion added when it reports an unknown planner name that is a
    known one in other letters' case or part of one (``PG`` -> ``pg``, ``greedy`` ->
    ``sequential-greedy``), which a close-match search misses."""
    import re

    from ..planners.registry import planner_names

    match = re.match(r"unknown planner '([^']*)'(;| \(did you mean)", exc.message)
    if match is None or match.group(2) != ";":
        return exc
    name = match.group(1).lower().replace("_", "-").strip()
    names = planner_names()
    parts = [n for n in names if n == name] or (
        [n for n in names if name in n or n in name] if len(name) >= 3 else [])
    if not parts:
        return exc
    hint = f" (did you mean {parts[0]!r}?)"
    head = match.group(0)[:-1]
    return ConfigError(exc.field, head + hint + exc.message[len(head):])
