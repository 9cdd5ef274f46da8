"""Strict models of the input files and the translation of their errors.

Every input file (the single-decision JSON, scenario and study TOML) is parsed by strict
pydantic v2 models built on :class:`Strict`: unknown keys are errors, no int is accepted as
a bool or a float as an int (ints are accepted where floats are expected), and every float
must be finite. The models are then turned into the frozen dataclasses of the core, whose
own checks apply the semantic rules. Every bad input becomes one
:class:`~sensorplan.errors.ConfigError` naming the field with a dotted path such as
``sensors[1].altitude`` (:func:`validate`).

The tables that hold run settings are generated from their one declaration in
:mod:`sensorplan.simulation.settings` (:func:`section_model`).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import types
import typing
from collections.abc import Mapping
from typing import TYPE_CHECKING, Annotated, Any, Union

from pydantic import (
                      AfterValidator,
                      BaseModel,
                      ConfigDict,
                      PlainValidator,
                      ValidationError,
                      ValidationInfo,
                      create_model,
                      field_validator,
                      )

from ..errors import ConfigError
from ..limits import RANGES, Range, coerce, shown, type_error
from ..models.sensors import ANGLE_FIELDS, SensorParams
from ..planners.problem import MapRect
from ..simulation.settings import Setting, declared, field_hint, field_type, is_group

# --------------------------------------------------------------------------- field types


def _length(n: int, what: str) -> AfterValidator:
    def check(value: list[Any]) -> list[Any]:
        if len(value) != n:
            raise ValueError(f"must be {what}, got {len(value)} item(s)")
        return value
    return AfterValidator(check)


def choice(valid: tuple[str, ...], what: str) -> AfterValidator:
    """A validator accepting one of ``valid``; errors read "unknown <what> 'x'; choose from"."""
    def check(value: str) -> str:
        if value not in valid:
            raise ValueError(f"unknown {what} {value!r}; choose from {', '.join(valid)}")
        return value
    return AfterValidator(check)


Vec2 = Annotated[list[float], _length(2, "a list of 2 numbers")]
Vec4 = Annotated[list[float], _length(4, "a list of 4 numbers")]
Matrix4 = Annotated[list[Vec4], _length(4, "a 4x4 matrix (4 rows of 4 numbers)")]
def in_range(r: Range) -> AfterValidator:
    """A validator of a number in ``r``, worded as every range ("must be >= 1, got 0")."""
    def check(value: Any) -> Any:
        message = r.violation(value)
        if message:
            raise ValueError(message)
        return value
    return AfterValidator(check)


PositiveInt = Annotated[int, in_range(Range(1, None))]
Seed = Annotated[int, in_range(Range(0, None))]


class Strict(BaseModel):
    """Base of every file model: unknown keys, loose types and non-finite floats fail."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


_SP = SensorParams()
_MAP = MapRect()


class MapModel(Strict):
    width: float = _MAP.width
    height: float = _MAP.height


class BuildingModel(Strict):
    """One building: its footprint ``box = [x0, y0, x1, y1]`` (m) and its height (m)."""

    box: Annotated[list[float], _length(4, "a list of 4 numbers: x0, y0, x1, y1")]
    height: float

    def row(self) -> tuple[float, float, float, float, float]:
        return (*self.box, self.height)  # type: ignore[return-value]


def _degrees_range(name: str) -> Range:
    """The range of ``<name>_deg``: the radian range of ``name`` in degrees."""
    r = RANGES[name]
    return Range(None if r.lo is None else math.degrees(r.lo),
                 None if r.hi is None else math.degrees(r.hi), r.unit.replace("rad", "deg"),
                 r.lo_open, r.hi_open, r.magnitude)


def one_spelling(name: str, value: float | None, given: Any) -> float | None:
    """Check ``<name>_deg = value`` (degrees): in range, and not given together with the
    radian key ``name`` (``given``: its validated value, None if absent)."""
    if value is None:
        return None
    if given is not None:
        raise ValueError(f"give {name} (radians) or {name}_deg (degrees), not both")
    message = _degrees_range(name).violation(value)
    if message:
        raise ValueError(message)
    return value


def radians_of(model: BaseModel, name: str, default: Any) -> Any:
    """The angle ``name`` of a model in radians: its radian key, else its ``_deg`` key
    converted, else ``default``."""
    value = getattr(model, name)
    if value is not None:
        return value
    degrees = getattr(model, name + "_deg")
    return default if degrees is None else math.radians(degrees)


def _file_list(hint: Any) -> Any:
    """A list type of a file for a ``tuple[X, ...]`` setting (nested for a matrix)."""
    inner = typing.get_args(hint)[0]
    # types.GenericAlias(list, (x,)) is list[x], spelled so that a type checker accepts a
    # runtime value as the item type.
    item = _file_list(inner) if typing.get_origin(inner) is tuple else inner
    return types.GenericAlias(list, (item,))


class _SensorParamsBase(Strict):
    """What the file model of :class:`~sensorplan.models.sensors.SensorParams` adds to its
    fields: one spelling per angle (and of ``heading``, for the file sensors that declare
    ``heading`` and ``heading_deg``), and the dataclass it gives."""

    @field_validator(*(f"{name}_deg" for name in (*ANGLE_FIELDS, "heading")),
                     check_fields=False)
    @classmethod
    def _one_spelling(cls, value: float | None, info: ValidationInfo) -> float | None:
        name = str(info.field_name).removesuffix("_deg")
        return one_spelling(name, value, info.data.get(name))

    def params(self) -> SensorParams:
        kwargs = {f.name: getattr(self, f.name) for f in dataclasses.fields(SensorParams)
                  if f.name not in ANGLE_FIELDS}
        for name in ANGLE_FIELDS:
            kwargs[name] = radians_of(self, name, getattr(_SP, name))
        kwargs["moves"] = tuple(kwargs["moves"])
        return SensorParams(**kwargs)


def _sensor_fields() -> dict[str, Any]:
    """The file fields of :class:`~sensorplan.models.sensors.SensorParams`, from its
    declaration: each field with its default (a list for a tuple; a choice checked as
    declared); an angle optional, with its ``<name>_deg`` twin after every field."""
    hints = typing.get_type_hints(SensorParams)
    out: dict[str, Any] = {}
    for f in dataclasses.fields(SensorParams):
        tp, rule, default = hints[f.name], f.metadata, getattr(_SP, f.name)
        if rule["angle"]:
            out[f.name] = (float | None, None)
        elif typing.get_origin(tp) is tuple:
            out[f.name] = (_file_list(tp), list(default))
        elif rule["choices"]:
            out[f.name] = (Annotated[tp, choice(rule["choices"], rule["noun"])], default)
        else:
            out[f.name] = (tp, default)
    out.update({f"{name}_deg": (float | None, None) for name in ANGLE_FIELDS})
    return out


if TYPE_CHECKING:
    class SensorParamsModel(_SensorParamsBase):
        pass
else:
    #: Every :class:`~sensorplan.models.sensors.SensorParams` field with its default, derived
    #: from the dataclass; each angle may be given in radians (``fov_half_angle``) or in
    #: degrees (``fov_half_angle_deg``), not both.
    SensorParamsModel = create_model(
        "SensorParamsModel", __base__=_SensorParamsBase, **_sensor_fields(),
        __doc__="Every SensorParams field, with its default; each angle in radians or in "
                "degrees (<name>_deg), not both.")


#: A planner's settings: a table whose keys and values the planner's class decides
#: (:func:`sensorplan.planners.registry.check_settings`), so any planner's settings pass here.
PlannerParams = dict[str, Any]


# ------------------------------------------------------------ tables from the settings


def _rule(s: Setting) -> AfterValidator:
    def check(value: Any) -> Any:
        s.validate(value)
        return value
    return AfterValidator(check)


def setting_annotation(cls: type, f: dataclasses.Field[Any], s: Setting) -> Any:
    """The strict file type of a declared setting: its declared type plus its rule."""
    tp = field_type(cls, f.name)
    if tp is Mapping or tp is dict:
        return PlannerParams
    if tp is tuple:
        return Annotated[_file_list(field_hint(cls, f.name)), _rule(s)]
    if tp is typing.Union:
        # A number or a list of them: the settings' own type check words the error (a
        # union's error would name the alternative pydantic tried last).
        hint = field_hint(cls, f.name)

        def either(value: Any) -> Any:
            try:
                v = coerce(hint, value)
            except ValueError:
                raise ValueError(f"must be an integer or a list of integers, got "
                                 f"{shown(value)}") from None
            s.validate(v)
            return v
        return Annotated[Any, PlainValidator(either)]
    if tp not in (int, float, str, bool):  # pragma: no cover - caught by the settings tests
        raise TypeError(f"no file type for setting {f.name} of type {tp!r}")
    return Annotated[tp, _rule(s)]


def setting_type(cls: type, name: str) -> Any:
    """:func:`setting_annotation` of the field ``name`` of ``cls`` (required, not optional)."""
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    return setting_annotation(cls, f, f.metadata["setting"])


def section_model(cls: type, section: str, name: str, doc: str = "",
                  **extra: Any) -> type[Strict]:
    """A strict model of one section's settings of ``cls``, every key optional.

    A missing key is ``None`` (the caller inherits or takes the field's default); a nested
    settings group of ``cls`` whose settings are all of ``section`` becomes an optional
    sub-table. ``extra`` adds ``name=(type, default)`` fields that are not run settings.
    """
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        tp = field_type(cls, f.name)
        s = f.metadata.get("setting")
        if s is not None and s.section == section:
            fields[f.name] = (setting_annotation(cls, f, s) | None, None)
        elif is_group(tp) and declared(tp) and all(g.section == section
                                                   for _, g in declared(tp)):
            sub = section_model(tp, section, f"{name}_{f.name}")
            fields[f.name] = (sub | None, None)
    fields.update(extra)
    return create_model(name, __base__=Strict, __doc__=doc or None, **fields)


def given(model: BaseModel | None) -> dict[str, Any]:
    """The keys a section model was given (non-None), sub-tables as dictionaries."""
    if model is None:
        return {}
    out = {}
    for key in type(model).model_fields:
        v = getattr(model, key)
        if isinstance(v, BaseModel):
            out[key] = given(v)
        elif v is not None:
            out[key] = v
    return out


# ------------------------------------------------------------------- error translation


def _dotted(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        # An empty key is shown as "" (a key of nothing but a dot would read as no key).
        name = str(part) if str(part) else '""'
        out += f"[{part}]" if isinstance(part, int) else (f".{name}" if out else name)
    return out or "(top level)"


def _unwrap(tp: Any) -> Any:
    while True:
        origin = typing.get_origin(tp)
        if origin is Annotated:
            tp = typing.get_args(tp)[0]
        elif origin in (Union, types.UnionType):
            tp = next(a for a in typing.get_args(tp) if a is not type(None))
        else:
            return tp


def _as_model(tp: Any) -> type[BaseModel] | None:
    tp = _unwrap(tp)
    return tp if isinstance(tp, type) and issubclass(tp, BaseModel) else None


def _model_at(model: type[BaseModel], loc: tuple[Any, ...]) -> type[BaseModel] | None:
    tp: Any = model
    for part in loc:
        tp = _unwrap(tp)
        if isinstance(part, int):
            args = typing.get_args(tp)
            if not args:
                return None
            tp = args[0]
        elif isinstance(tp, type) and issubclass(tp, BaseModel) and part in tp.model_fields:
            tp = tp.model_fields[part].annotation
        else:
            return None
    return _as_model(tp)


def _unknown_key(parent: type[BaseModel] | None, key: str) -> str:
    allowed = list(parent.model_fields) if parent is not None else []
    message = "unknown key"
    # A key that belongs in a sub-table (a tracker setting among the planning ones).
    homes = [f"{name}.{key}" for name, info in (parent.model_fields.items() if parent else ())
             if (sub := _as_model(info.annotation)) is not None and key in sub.model_fields]
    close = homes[:1] or difflib.get_close_matches(key, allowed, n=1)
    if close:
        message += f" (did you mean {close[0]!r}?)"
    if allowed:
        message += f"; allowed: {', '.join(allowed)}"
    return message


#: pydantic's type errors -> the type whose words (:func:`sensorplan.limits.type_error`) they
#: get, as the same type error gets them in the API.
_TYPE_ERRORS = {"float_type": float, "int_type": int, "string_type": str, "bool_type": bool,
                "list_type": list}


def translate(exc: ValidationError, model: type[BaseModel], container: str) -> ConfigError:
    """One :class:`ConfigError` for the first error pydantic found."""
    err = exc.errors()[0]
    loc = tuple(err["loc"])
    kind = err["type"]
    field = _dotted(loc)
    if kind == "extra_forbidden":
        message = _unknown_key(_model_at(model, loc[:-1]), str(loc[-1]))
    elif kind == "missing":
        message = "is required"
    elif kind == "finite_number":
        message = "must be a finite number"
    elif kind in _TYPE_ERRORS:
        message = type_error(_TYPE_ERRORS[kind], err.get("input"))
    elif kind in ("model_type", "model_attributes_type", "dict_type"):
        message = f"must be {container}"
    elif kind == "value_error":
        message = err["msg"].removeprefix("Value error, ")
    else:
        message = err["msg"].replace("Input should be", "must be")
    return ConfigError(field, message)


def validate(model: type[BaseModel], data: Any, container: str = "a table") -> Any:
    """``model.model_validate(data)`` with the first error as a :class:`ConfigError`.

    ``container`` names what a nested value must be (``"a table"``, ``"a JSON object"``).
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise translate(exc, model, container) from None
