"""The one vocabulary of input errors: types (``limits.coerce``) and ranges (``limits.Range``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.limits import Range, coerce, type_error

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
])
def test_a_range_says_what_it_allows_and_what_it_got(rng: Range, value: float,
                                                     message: str) -> None:
    assert rng.violation(value) == message
    assert rng.contains(value) == (message == "")
