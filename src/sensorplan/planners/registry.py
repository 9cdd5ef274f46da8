"""Which planner a name means, and checking the settings given to it.

Wherever a planner is chosen by name (``planner.name`` of a plan file, ``planner`` of a
scenario's ``[planning]`` table or of a study method, ``sensorplan simulate --planner``, the
Stone Soup manager), the name is one of:

- a built-in name: ``pg``, ``pg-refine``, ``sequential-greedy``, ``brute-force``, ``random``,
  ``raster`` and the decentralized ``dec-jsfp``, ``dec-independent``, ``dec-sequential``;
- a name registered in this process with :func:`register`;
- the name of an entry point in the group ``sensorplan.planners`` of an installed
  distribution (its value is ``package.module:Class``);
- ``package.module:Class`` itself: the class is imported from its module.

Names are known without importing any planner: a built-in is a ``module:Class`` string
imported on first use, an entry point is loaded when its name is resolved. So listing the
names (:data:`PLANNERS`) is cheap, and the packages that define planners never have to be
imported by this one.

A planner's settings are its dataclass fields (or, for a class that is not a dataclass, its
constructor's keyword arguments): :func:`check_settings` accepts a key if and only if the
chosen planner has that setting, checks each value's type against the field's annotation and
leaves the rules on values to the planner's own constructor. The built-in planners declare
each setting once, as the run settings are declared: a field made by
:func:`~sensorplan.limits.param` gives its default, help and rule, and
:class:`PlannerSettings` checks them all when the planner is made.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import inspect
import sys
import typing
from collections.abc import Iterator, Mapping, MutableMapping
from typing import Any

from ..errors import ConfigError
from ..limits import Range, check_params, coerce, param

#: Entry-point group through which installed distributions add planners.
ENTRY_POINT_GROUP = "sensorplan.planners"

#: The built-in planners: name -> ``module:Class``, imported when first used.
BUILTIN: dict[str, str] = {
    "pg": "sensorplan.planners.potential_game:PotentialGamePlanner",
    "pg-refine": "sensorplan.planners.refine:RefinedPlanner",
    "sequential-greedy": "sensorplan.planners.greedy:SequentialGreedyPlanner",
    "brute-force": "sensorplan.planners.brute_force:BruteForcePlanner",
    "random": "sensorplan.planners.random_plan:RandomPlanner",
    "raster": "sensorplan.planners.raster:RasterPlanner",
    "dec-jsfp": "sensorplan.decentral.planners:DecentralJSFPPlanner",
    "dec-independent": "sensorplan.decentral.planners:DecentralIndependentPlanner",
    "dec-sequential": "sensorplan.decentral.planners:DecentralSequentialPlanner",
}

_REGISTERED: dict[str, Any] = {}
_ENTRY_POINTS: dict[tuple[str, ...], dict[str, Any]] = {}


def register(cls: Any) -> Any:
    """Class decorator: make planner ``cls`` available under ``cls.name`` in this process.

    A planner class has a class attribute ``name`` (str) and a method
    ``plan(problem, rng=None) -> PlanResult``. A built-in name cannot be taken by another
    class.

    Raises
    ------
    TypeError
        ``cls`` is not a planner class.
    ValueError
        ``cls.name`` is a built-in planner's name.
    """
    problem = _not_a_planner(cls)
    if problem:
        raise TypeError(f"cannot register {cls!r}: {problem}")
    name = cls.name
    if name in BUILTIN and _reference(cls) != BUILTIN[name]:
        raise ValueError(f"cannot register {_reference(cls)} as {name!r}: that is the "
                         f"built-in {BUILTIN[name]}")
    _REGISTERED[name] = cls
    return cls


def _reference(cls: Any) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def planner_label(planner: Any) -> str:
    """How messages and run headers name a planner (an instance or class).

    Its ``name`` in quotes, as the plan's ``planner`` key has it; for a class that is not
    built in, followed by where it lives (``'nearest' (nearest_planner:NearestTargetPlanner)``),
    so that a message about a planner of another package says which code to look at.
    """
    cls = planner if isinstance(planner, type) else type(planner)
    name = getattr(planner, "name", None)
    if not isinstance(name, str):
        return _reference(cls)
    reference = _reference(cls)
    if BUILTIN.get(name) == reference:
        return repr(name)
    return f"{name!r} ({reference})"


def _not_a_planner(cls: Any) -> str:
    """Why ``cls`` is not a planner class ('' if it is one)."""
    if not isinstance(cls, type):
        return "not a class"
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        return "it needs a class attribute `name` (a non-empty string)"
    if not callable(getattr(cls, "plan", None)):
        return "it needs a method `plan(problem, rng=None)`"
    return ""


def _entry_points() -> dict[str, Any]:
    """Entry points of the group by name (read once per ``sys.path``)."""
    key = tuple(sys.path)
    if key not in _ENTRY_POINTS:
        from importlib.metadata import entry_points

        found: dict[str, Any] = {}
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            found.setdefault(ep.name, ep)            # the first on sys.path wins, as imports
        _ENTRY_POINTS.clear()
        _ENTRY_POINTS[key] = found
    return _ENTRY_POINTS[key]


def planner_names() -> tuple[str, ...]:
    """Every planner name known in this process, sorted: built-in, registered, entry points.

    ``package.module:Class`` references are accepted too but are not listed.
    """
    return tuple(sorted(set(BUILTIN) | set(_REGISTERED) | set(_entry_points())))


def unknown_planner(name: Any) -> str:
    """The error message for a name that is no planner: close names, then every name."""
    known = planner_names()
    message = f"unknown planner {name!r}"
    close = difflib.get_close_matches(str(name), known, n=1)
    if close:
        message += f" (did you mean {close[0]!r}?)"
    return (message + f"; choose from {', '.join(known)}, or give a planner class as "
            "'package.module:Class'")


def _import_class(reference: str, field: str) -> Any:
    module_name, _, attr = reference.partition(":")
    if not module_name or not attr:
        raise ConfigError(field, f"{reference!r} is not a planner reference of the form "
                          "'package.module:Class'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(field, f"cannot import {module_name!r} for planner {reference!r} "
                          f"({exc}); is it installed or on PYTHONPATH?") from None
    obj: Any = module
    for part in attr.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise ConfigError(field, f"module {module_name!r} has no {attr!r} (planner "
                              f"{reference!r})")
    problem = _not_a_planner(obj)
    if problem:
        raise ConfigError(field, f"{reference!r} is not a planner class: {problem}")
    return obj


def planner_class(name: str, field: str = "planner.name") -> Any:
    """The class of planner ``name`` (a registered name or ``package.module:Class``).

    Imports the planner's module on first use. Errors name ``field``.

    Raises
    ------
    ConfigError
        Unknown name (with close matches and every known name), a reference that cannot be
        imported, or something that is not a planner class.
    """
    if not isinstance(name, str):
        raise ConfigError(field, f"must be a planner name (a string), got {name!r}")
    if ":" in name:
        return _import_class(name, field)
    if name in BUILTIN:
        return _import_class(BUILTIN[name], field)
    if name in _REGISTERED:
        return _REGISTERED[name]
    ep = _entry_points().get(name)
    if ep is None:
        raise ConfigError(field, unknown_planner(name))
    where = f"entry point {name!r} ({ep.value}) of group {ENTRY_POINT_GROUP}"
    try:
        cls = ep.load()
    except Exception as exc:  # noqa: BLE001 - a broken plugin is bad input, in one line
        raise ConfigError(field, f"{where} cannot be loaded ({type(exc).__name__}: "
                          f"{exc})") from None
    problem = _not_a_planner(cls)
    if problem:
        raise ConfigError(field, f"{where} is not a planner class: {problem}")
    if cls.name != name:
        raise ConfigError(field, f"{where} loads a planner named {cls.name!r}; the entry "
                          "point must have the planner's name")
    return cls


class Registry(MutableMapping[str, type]):
    """Mapping of every known planner name to its class (imported on access).

    ``name in PLANNERS``, ``sorted(PLANNERS)`` and ``len(PLANNERS)`` import nothing.
    ``PLANNERS[name] = cls`` registers ``cls`` under ``name`` in this process (as
    :func:`register` does under ``cls.name``), ``del PLANNERS[name]`` removes such a
    registration; built-in names can be neither replaced nor removed.
    """

    def __setitem__(self, name: str, cls: type) -> None:
        problem = _not_a_planner(cls)
        if problem:
            raise TypeError(f"cannot register {cls!r}: {problem}")
        if name in BUILTIN:
            raise ValueError(f"{name!r} is a built-in planner")
        _REGISTERED[name] = cls

    def __delitem__(self, name: str) -> None:
        if name in BUILTIN or name not in _REGISTERED:
            raise KeyError(name)
        del _REGISTERED[name]

    def __getitem__(self, name: str) -> type:
        if name not in self:
            raise KeyError(name)
        return planner_class(name)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in planner_names()

    def __iter__(self) -> Iterator[str]:
        return iter(planner_names())

    def __len__(self) -> int:
        return len(planner_names())

    def __repr__(self) -> str:
        return f"PLANNERS({', '.join(planner_names())})"


#: Every known planner by name (see the module docstring).
PLANNERS: Mapping[str, type] = Registry()


# ------------------------------------------------------------------------- settings


class PlannerSettings:
    """Base of a planner dataclass whose settings are declared with
    :func:`~sensorplan.limits.param`: when it is made, each is checked (type, then rule) in
    field order, and the first that breaks its rule is a :class:`ConfigError` naming
    ``planner.<key>`` (:func:`~sensorplan.limits.check_params`)."""

    def __post_init__(self) -> None:
        check_params(self, "planner")


def seed_param() -> Any:
    """The declaration of a planner's ``seed`` (a new field for each planner class)."""
    return param(0, bounds=Range(0, None),
                 help="Seed of the planner's own generator when plan gets no rng (None: "
                      "fresh entropy).")


def planner_settings_of(cls: Any) -> dict[str, Any]:
    """A planner's settings: name -> type annotation (``Any`` when unknown).

    The init fields of a dataclass not starting with ``_``, else the constructor's keyword
    arguments.
    """
    if dataclasses.is_dataclass(cls):
        names = [f.name for f in dataclasses.fields(cls) if f.init and not f.name.startswith("_")]
    else:
        try:
            params = inspect.signature(cls).parameters.values()
        except (TypeError, ValueError):
            return {}
        names = [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
                 and not p.name.startswith("_")]
    try:
        # getattr: mypy refuses ``cls.__init__`` on a type (unsound in general).
        hints = typing.get_type_hints(cls if dataclasses.is_dataclass(cls)
                                      else getattr(cls, "__init__"))  # noqa: B009
    except Exception:  # noqa: BLE001 - unresolvable annotations: the constructor checks
        hints = {}
    return {n: hints.get(n, Any) for n in names}


def check_settings(name: Any, params: Mapping[str, Any], prefix: str = "planner", *,
                   strict: bool = True, exclude: Mapping[str, str] | None = None,
                   construct: bool = True, keep_none: bool = False) -> dict[str, Any]:
    """Check the settings ``params`` for planner ``name`` and return them normalised.

    Parameters
    ----------
    name : str or class
        A planner name (:func:`planner_class`) or class.
    params : mapping
        Setting -> value. ``None`` values of the planner's settings are dropped (the planner
        keeps its default; a file has no other way to leave a key out) unless
        ``keep_none``; a key it does not have is an error whatever its value.
    prefix : str
        Errors name ``<prefix>.<key>`` (``planning.planner_params.alpha``); the planner's
        own errors on ``planner.<key>`` are renamed the same way.
    strict : bool
        Keys the planner does not have are errors; with False they are dropped (settings
        written for another planner, as when ``--planner`` replaces a file's planner).
    exclude : mapping, optional
        Settings that may not be given here -> why (e.g. ``seed``: the run's seed drives
        the planner); always errors when given.
    construct : bool
        Instantiate the planner once, so that its constructor checks the values.
    keep_none : bool
        Pass ``None`` values on (``seed=None``: an unseeded planner) instead of dropping them.

    Raises
    ------
    ConfigError
        An unknown key (with the closest setting and every allowed one), a value of the
        wrong type, or a value the planner's constructor rejects.
    """
    cls = planner_class(name) if isinstance(name, str) else name
    label = name if isinstance(name, str) else cls.name
    exclude = dict(exclude or {})
    fields = planner_settings_of(cls)
    allowed = [k for k in fields if k not in exclude]
    out: dict[str, Any] = {}
    for key, value in params.items():
        key = str(key)
        if key in exclude and value is not None:
            raise ConfigError(f"{prefix}.{key}", exclude[key])
        if key not in fields:
            if not strict:
                continue
            message = f"unknown key for planner {label!r}"
            close = difflib.get_close_matches(key, allowed, n=1)
            if close:
                message += f" (did you mean {close[0]!r}?)"
            message += f"; allowed: {', '.join(allowed)}" if allowed else "; it takes none"
            raise ConfigError(f"{prefix}.{key}", message)
        if value is None and not keep_none:
            continue                # only a key the planner has may be left at its default
        try:
            # A planner may take an infinite number (comm_range = inf); its own check decides.
            out[key] = coerce(fields[key], value, finite=False)
        except ValueError as exc:
            raise ConfigError(f"{prefix}.{key}", str(exc)) from None
    if construct:
        instantiate(cls, out, prefix)
    return out


def instantiate(cls: Any, settings: Mapping[str, Any], prefix: str = "planner") -> Any:
    """``cls(**settings)`` with every failure as a :class:`ConfigError` under ``prefix``.

    The planner's own ``ConfigError("planner.<key>")`` becomes ``<prefix>.<key>``; a
    ``ValueError`` or ``TypeError`` whose message starts with a given setting's name names
    that setting, any other names ``prefix``.
    """
    try:
        return cls(**settings)
    except ConfigError as exc:
        field = exc.field
        if field == "planner" or field.startswith("planner."):
            field = prefix + field[len("planner"):]
        raise ConfigError(field, exc.message) from None
    except (TypeError, ValueError, OverflowError) as exc:
        text = str(exc)
        first = text.split(" ", 1)[0].strip("'\"`:,")
        field = f"{prefix}.{first}" if first in settings else prefix
        raise ConfigError(field, text) from None


def make_planner(name: str, **params: Any) -> Any:
    """A planner by name (or ``package.module:Class``) with the given settings.

    Raises
    ------
    ConfigError
        ``planner.name`` for an unknown name; ``planner.<key>`` for an unknown setting, a
        value of the wrong type or a value the planner rejects.
    """
    cls = planner_class(name)
    return instantiate(cls, check_settings(cls, params, construct=False, keep_none=True))


__all__ = ["BUILTIN", "ENTRY_POINT_GROUP", "PLANNERS", "PlannerSettings", "Registry",
           "check_settings", "instantiate", "make_planner", "planner_class", "planner_label",
           "planner_names", "planner_settings_of", "register", "seed_param", "unknown_planner"]
