"""The one vocabulary of input errors: types (``limits.coerce``) and ranges (``limits.Range``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.limits import (Param, Range, check_params, coerce, declared_params, param,
                               type_error)

#: (type, value, the value it becomes)
GOOD: list[tuple[Any, Any, Any]] = [
    (int, 3, 3), (int, np.int64(3), 3), (float, 2, 2.0), (float, np.float32(0.5), 0.5),
    (float, 1.5, 1.5), (bool, True, True), (bool, np.bool_(False), False), (str, "x", "x"),
    (Mapping, {"a": 1}, {"a": 1}), (tuple[float, ...], [1, 2.5], (1.0, 2.5)),
    (tuple[tuple[float, ...], ...], [[1], [2, 3]], ((1.0,), (2.0, 3.0))),
    (int | None, None, None), (int | None, 4, 4), (float | None, 3, 3.0),
    (Literal["a", "b"], "b", "b"), (Any, object, object), (tuple[int, str], [1, 2], [1, 2]),
]

#: (type, value, message)
BAD: list[tuple[Any, Any, str]] = [
    (int, 2.5, "must be an integer, got 2.5"), (int, True, "must be an integer, got True"),
    (int, np.bool_(True), "must be an integer, got np.True_"),
    (float, "1", "must be a number, got '1'"), (float, False, "must be a number, got False"),
    (float, 10**400, "must be a number, got " + repr(10**400)[:37] + "..."),
    (float, math.nan, "must be a finite number"), (float, math.inf, "must be a finite number"),
    (bool, 1, "must be true or false, got 1"), (str, 3, "must be a string, got 3"),
    (Mapping, [1], "must be a table, got [1]"), (tuple[float, ...], 1.0, "must be a list, got 1.0"),
    (tuple[float, ...], [1, "x"], "must be a number, got 'x'"),
    (int | None, "x", "must be an integer, got 'x'"),
    (Literal["a", "b"], "c", "must be one of 'a', 'b', got 'c'"),
]


@pytest.mark.parametrize("tp,value,want", GOOD)
def test_coerce_gives_the_value_as_its_type(tp: Any, value: Any, want: Any) -> None:
    got = coerce(tp, value)
    assert got == want and type(got) is type(want)


@pytest.mark.parametrize("tp,value,message", BAD)
def test_coerce_refuses_with_the_packages_words(tp: Any, value: Any, message: str) -> None:
    with pytest.raises(ValueError) as info:
        coerce(tp, value)
    assert str(info.value) == message


def test_infinite_numbers_pass_where_the_owner_decides() -> None:
    assert coerce(float, math.inf, finite=False) == math.inf
    assert type_error(int, "x" * 50) == "must be an integer, got '" + "x" * 36 + "..."


def test_one_type_error_reads_the_same_in_settings_planners_and_files() -> None:
    """The run settings, a planner's parameters and a file's model word the same mistake
    the same way."""
    from sensorplan.config.scenario import PlanningTable
    from sensorplan.config.validation import validate
    from sensorplan.planners import make_planner
    from sensorplan.simulation.settings import RunSettings

    errors = []
    for make in (lambda: RunSettings(horizon=1.5), lambda: make_planner("pg", max_inner=1.5),
                 lambda: validate(PlanningTable, {"horizon": 1.5})):
        with pytest.raises(ConfigError) as info:
            make()
        errors.append(info.value.message)
    assert errors == ["must be an integer, got 1.5"] * 3


@pytest.mark.parametrize("rng,value,message", [
    (Range(1, 1000), 0, "must be in [1, 1000], got 0"),
    (Range(1, 1000), 1000, ""),
    (Range(0.0, 1.0, lo_open=True, hi_open=True), 0.0, "must be in (0, 1), got 0.0"),
    (Range(0.0, 1.0, lo_open=True, hi_open=True), 0.5, ""),
    (Range(0.0, None, "m", lo_open=True), 0.0, "must be > 0 m, got 0.0"),
    (Range(None, 10.0, "m", magnitude=True), -11.0, "must be at most 10 m in magnitude, "
                                                     "got -11.0"),
    (Range(0.0, 1.0), math.nan, "must be in [0, 1], got nan"),
    (Range(0, None), 10**400, ""),                                   # a seed of any size
    (Range(0, None), -(10**30), "must be >= 0, got " + str(-(10**30))[:21] + "..."),
    (Range(0.0, None, "m", lo_open=True, inf=True), math.inf, ""),      # unlimited
    (Range(0.0, None, "m", lo_open=True, inf=True), math.nan, "must be > 0 m or inf, got nan"),
    (Range(0.0, None, "m", lo_open=True, inf=True), -math.inf, "must be > 0 m or inf, got -inf"),
    (Range(0.0, None, "s", lo_open=True), math.inf, "must be > 0 s, got inf"),
])
def test_a_range_says_what_it_allows_and_what_it_got(rng: Range, value: float,
                                                     message: str) -> None:
    assert rng.violation(value) == message
    assert rng.contains(value) == (message == "")


# ------------------------------------------------------------------ declarations


@dataclass(frozen=True)
class _Declared:
    """A planner-like dataclass declared as the planners are."""

    count: int = param(3, bounds=Range(1, None), help="How many.")
    share: float = param(0.5, bounds=Range(0.0, 1.0), help="What part.")
    mode: str = param("a", choices=("a", "b"), noun="mode", help="Which.")
    seed: int | None = param(0, bounds=Range(0, None), help="Seed.")
    plain: int = 7                                                 # not declared: not checked

    def __post_init__(self) -> None:
        check_params(self, "planner")


@pytest.mark.parametrize("kwargs,field,message", [
    ({"count": 0}, "planner.count", "must be >= 1, got 0"),
    ({"count": 2.5}, "planner.count", "must be an integer, got 2.5"),
    ({"share": 1.5}, "planner.share", "must be in [0, 1], got 1.5"),
    ({"share": math.inf}, "planner.share", "must be in [0, 1], got inf"),
    ({"mode": "c"}, "planner.mode", "unknown mode 'c'; choose from a, b"),
    ({"seed": -1}, "planner.seed", "must be >= 0, got -1"),
    # the first declared field that breaks its rule, in field order
    ({"mode": "c", "count": 0}, "planner.count", "must be >= 1, got 0"),
])
def test_a_declared_parameter_is_refused_in_the_shared_words(kwargs: dict[str, Any], field: str,
                                                              message: str) -> None:
    with pytest.raises(ConfigError) as info:
        _Declared(**kwargs)
    assert (info.value.field, info.value.message) == (field, message)


def test_declared_parameters_are_normalised_and_none_passes_where_the_type_allows_it() -> None:
    d = _Declared(count=np.int64(4), share=np.float32(0.25), seed=None, plain=-5)
    assert (d.count, d.share, d.seed, d.plain) == (4, 0.25, None, -5)
    assert type(d.count) is int and type(d.share) is float
    assert [f.name for f, _ in declared_params(_Declared)] == ["count", "share", "mode", "seed"]


def test_a_declaration_states_its_rule_in_the_ranges_words() -> None:
    rules = {f.name: p.rule() for f, p in declared_params(_Declared)}
    assert rules == {"count": ">= 1", "share": "in [0, 1]", "mode": "one of a, b",
                     "seed": ">= 0"}
    assert Param().rule() == ""


def test_every_builtin_planner_declares_every_setting_once() -> None:
    """Each built-in planner's settings are fields declared with param(): its default,
    help and rule in one place (a setting without a declaration would go unchecked)."""
    import dataclasses

    from sensorplan.planners import PLANNERS
    from sensorplan.planners.registry import BUILTIN, planner_settings_of

    for name in BUILTIN:
        cls = PLANNERS[name]
        declared = {f.name: p for f, p in declared_params(cls)}
        assert set(declared) == set(planner_settings_of(cls)), name
        for key, p in declared.items():
            assert p.help and (p.bounds is not None or p.allowed()), (name, key)
        # the defaults obey their own rules
        defaults = cls()
        for f in dataclasses.fields(cls):
            if f.name in declared:
                assert getattr(defaults, f.name) == f.default
