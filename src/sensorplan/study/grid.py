"""Grid studies: the methods of a study over a set of scenario variants (cells).

A grid file is a study file (docs/studies.md) plus a design, axes and comparisons::

    design = "star"                 # or "full"
    [[axes]]
    feature = "sensor_speed"        # see sensorplan.study.features
    values = [0.125, 0.25, 0.5, 1.0]
    base = 1.0                      # one of values; the centre of a star design
    [[axes]]
    feature = "setting"             # a run setting, applied to the methods that take it
    key = "planner_params.p_loss"
    values = [0.0, 0.1]
    base = 0.0
    [[comparisons]]                 # the paired differences drawn in the heat maps
    method = "olf3 terminal e1"
    reference = "myopic e1"
    label = "K=3 terminal vs myopic (e=1)"     # optional

A ``star`` design has the base cell (every axis at its base) and, per axis, one cell per
other value with the other axes at their bases: ``1 + sum(n_i - 1)`` cells. ``full`` has
every combination: ``prod(n_i)`` cells. Every cell is an ordinary
:class:`~sensorplan.study.model.Study` with the file's runs, steps and seed, so run ``r``
of every cell starts from the same random streams, and within a cell the methods are paired
as in any study. :mod:`.grid_run` runs them.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, create_model

from ..config import files as io
from ..config.validation import Strict, choice, validate
from ..errors import ConfigError
from ..limits import MAX_CELL_NAME, MAX_GRID_CELLS
from .features import FEATURES, METHODS_FOLLOW, SCENARIO_FEATURES, check_setting_key, setting
from .file import StudyFile, study_from_dict
from .metrics import references
from .model import Method, Study

#: Designs of a grid.
DESIGNS = ("star", "full")
#: Keys of a grid file besides those of a study file.
GRID_KEYS = ("design", "axes", "comparisons")
#: What a value written into a directory name may contain.
_SAFE = re.compile(r"^[A-Za-z0-9_.+-]+$")


def _non_empty(what: str) -> AfterValidator:
    def check(value: list[Any]) -> list[Any]:
        if not value:
            raise ValueError(f"at least one {what} is required")
        return value
    return AfterValidator(check)


class AxisModel(Strict):
    feature: Annotated[str, choice(FEATURES, "feature")]
    values: Annotated[list[Any], _non_empty("value")]
    base: Any = None
    key: str | None = None


class ComparisonModel(Strict):
    method: str
    reference: str
    label: str | None = None


#: The keys a grid file adds to a study file.
_GRID_FIELDS: dict[str, Any] = {
    "design": (Annotated[str, choice(DESIGNS, "design")], "star"),
    "axes": (Annotated[list[AxisModel], _non_empty("axis")], ...),
    "comparisons": (list[ComparisonModel], [])}
GridFile = create_model("GridFile", __base__=StudyFile, **_GRID_FIELDS)


def value_text(value: Any) -> str:
    """How a value is written in a cell's name and the report: ``0.25``, ``1`` (for 1.0),
    ``inf``, ``true``, a string as it is."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        if value.is_integer() and abs(value) < 1e15:
            return str(int(value))
        return repr(value)
    if isinstance(value, str):
        if not _SAFE.match(value):
            raise ValueError(f"{value!r} cannot name a cell directory (use letters, digits "
                             "and _ . + -)")
        return value
    raise ValueError(f"must be numbers, strings or true/false, got {value!r}")


@dataclass(frozen=True)
class Axis:
    """One varied feature: its values and (star design) its base value.

    ``name`` is the feature, or for a ``setting`` axis its key; ``labels`` are the values
    as :func:`value_text` writes them.
    """

    feature: str
    values: tuple[Any, ...]
    base: Any = None
    key: str | None = None

    @property
    def name(self) -> str:
        return self.key if self.feature == "setting" and self.key else self.feature

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(value_text(v) for v in self.values)

    @property
    def base_index(self) -> int | None:
        return None if self.base is None else self.labels.index(value_text(self.base))


@dataclass(frozen=True)
class Comparison:
    """A paired comparison drawn in the report: ``method - reference``."""

    method: str
    reference: str
    label: str


@dataclass(frozen=True)
class Cell:
    """One scenario variant: ``index[i]`` is the position of axis ``i``'s value; ``notes``
    name the methods a setting axis leaves out."""

    slug: str
    index: tuple[int, ...]
    study: Study
    notes: tuple[str, ...] = ()

    def values(self, axes: tuple[Axis, ...]) -> tuple[Any, ...]:
        return tuple(a.values[k] for a, k in zip(axes, self.index))


@dataclass(frozen=True)
class Grid:
    """A grid study: the base study (the file without its grid keys), the axes, the cells
    in run order and the comparisons (``comparisons_given``: written in the file, else the
    methods' own references)."""

    study: Study
    design: str
    axes: tuple[Axis, ...]
    cells: tuple[Cell, ...]
    comparisons: tuple[Comparison, ...]
    comparisons_given: bool
    file: dict[str, Any]

    @property
    def description(self) -> str:
        return self.study.description


def cell_indices(axes: tuple[Axis, ...], design: str) -> list[tuple[int, ...]]:
    """The cells' value positions, in run order: star, the base first, then each axis's
    other values in file order; full, the cartesian product (last axis fastest)."""
    if design == "full":
        return list(itertools.product(*(range(len(a.values)) for a in axes)))
    base = tuple(a.base_index or 0 for a in axes)
    out = [base]
    for i, a in enumerate(axes):
        out += [base[:i] + (k,) + base[i + 1:] for k in range(len(a.values))
                if k != a.base_index]
    return out


def cell_slug(axes: tuple[Axis, ...], index: tuple[int, ...], design: str) -> str:
    """A cell's name (and sub-directory): ``base``, ``sensor_speed=0.25`` (star: the axis
    off its base) or ``a=1,b=2`` (full: every axis)."""
    shown = [i for i, (a, k) in enumerate(zip(axes, index))
             if design == "full" or k != a.base_index]
    if not shown:
        return "base"
    return ",".join(f"{axes[i].name}={axes[i].labels[index[i]]}" for i in shown)


def _apply(base: Study, axes: tuple[Axis, ...], index: tuple[int, ...],
           only: int | None = None) -> tuple[Study, list[str]]:
    """The base study with the axes' values at ``index`` (only axis ``only`` if given);
    also the notes on methods a setting was left out for."""
    scenario, methods, notes = base.scenario, list(base.methods), []
    for i, (axis, k) in enumerate(zip(axes, index)):
        if only is not None and i != only:
            continue
        value, text = axis.values[k], axis.labels[k]
        field = f"axes[{i}].values"
        if axis.feature != "setting":
            try:
                scenario = SCENARIO_FEATURES[axis.feature](scenario, value)
            except ValueError as exc:
                raise ConfigError(field, f"{text}: {exc}") from None
            follow = METHODS_FOLLOW.get(axis.feature)
            if follow is not None:
                methods = [Method(m.name, follow(m.settings, value)) for m in methods]
            continue
        assert axis.key is not None
        left_out = []
        for j, m in enumerate(methods):
            try:
                settings = setting(m.settings, axis.key, value)
            except ConfigError as exc:
                raise ConfigError(field, f"{text}: {exc.message} (for methods[{j}], "
                                  f"{m.name!r})") from None
            if settings is None:
                left_out.append(m.name)
            else:
                methods[j] = Method(m.name, settings)
        if left_out:
            whose = "its planner does" if len(left_out) == 1 else "their planners do"
            notes.append(f"{axis.key} is left out for {', '.join(left_out)} ({whose} not "
                         "take it)")
    return dataclasses.replace(base, scenario=scenario, methods=tuple(methods)), notes


def _axes(models: list[Any], design: str, study: Study) -> tuple[Axis, ...]:
    axes: list[Axis] = []
    names: dict[str, int] = {}
    for i, m in enumerate(models):
        at = f"axes[{i}]"
        if m.feature == "setting":
            if m.key is None:
                raise ConfigError(f"{at}.key", "is required for a setting axis (e.g. "
                                  "\"planner_params.p_loss\")")
            try:
                check_setting_key(m.key, [x.settings for x in study.methods])
            except ValueError as exc:
                raise ConfigError(f"{at}.key", str(exc)) from None
        elif m.key is not None:
            raise ConfigError(f"{at}.key", f"only a setting axis takes a key (this one "
                              f"varies {m.feature!r})")
        axis = Axis(m.feature, tuple(m.values), m.base, m.key)
        try:
            labels = axis.labels
        except ValueError as exc:
            raise ConfigError(f"{at}.values", str(exc)) from None
        dup = next((t for k, t in enumerate(labels) if t in labels[:k]), None)
        if dup is not None:
            raise ConfigError(f"{at}.values", f"duplicate value {dup}")
        if m.base is None and design == "star":
            raise ConfigError(f"{at}.base", "is required for a star design (the value of "
                              "the centre cell; one of values)")
        if m.base is not None:
            try:
                ok = value_text(m.base) in labels
            except ValueError:
                ok = False
            if not ok:
                raise ConfigError(f"{at}.base", f"must be one of the values "
                                  f"({', '.join(labels)}), got {m.base!r}")
        if axis.name in names:
            raise ConfigError(f"{at}.{'key' if m.feature == 'setting' else 'feature'}",
                              f"{axis.name} is already varied by axes[{names[axis.name]}]")
        names[axis.name] = i
        axes.append(axis)
    return tuple(axes)


def _comparisons(models: list[Any], study: Study) -> tuple[tuple[Comparison, ...], bool]:
    names = study.method_names
    out = []
    for k, c in enumerate(models):
        for role in ("method", "reference"):
            name = getattr(c, role)
            if name not in names:
                raise ConfigError(f"comparisons[{k}].{role}", f"unknown method {name!r}; the "
                                  f"methods are: {', '.join(names)}")
        if c.method == c.reference:
            raise ConfigError(f"comparisons[{k}].reference", "must differ from method")
        out.append(Comparison(c.method, c.reference, c.label or f"{c.method} vs "
                                                                f"{c.reference}"))
    if out:
        return tuple(out), True
    for method, refs in references(study).items():
        for against in ("myopic", "random"):
            ref = refs[against]
            if ref is not None:
                out.append(Comparison(method, ref, f"{method} vs {ref}"))
    if not out:
        raise ConfigError("comparisons", "none given, and no method has a myopic or random "
                          "reference to fall back on; add [[comparisons]] tables")
    return tuple(out), False


def grid_from_dict(data: Any, base_dir: str | Path | None = None) -> Grid:
    """Validate a grid table and build the :class:`Grid` with every cell's study.

    Raises
    ------
    ConfigError
        Naming the field: a study key as in a study file, ``axes[i].values`` (a value the
        feature does not take), ``axes[i].base``, ``axes[i].key``,
        ``comparisons[k].method``, ...
    """
    model: Any = validate(GridFile, data)
    # Counted before anything is built: a million values would take hours to check.
    sizes = [len(m.values) for m in model.axes]
    n_cells = math.prod(sizes) if model.design == "full" else 1 + sum(n - 1 for n in sizes)
    if n_cells > MAX_GRID_CELLS:
        raise ConfigError("axes", f"the {model.design} design has {n_cells:,} cells, above the "
                          f"limit of {MAX_GRID_CELLS:,} (values per axis: "
                          f"{', '.join(map(str, sizes))})")
    study = study_from_dict({k: v for k, v in data.items() if k not in GRID_KEYS},
                            base_dir=base_dir)
    axes = _axes(model.axes, model.design, study)
    comparisons, given = _comparisons(model.comparisons, study)
    # Each value on its own first, so that a bad one names its own axis.
    for i, a in enumerate(axes):
        for k in range(len(a.values)):
            _apply(study, axes, tuple(k if j == i else 0 for j in range(len(axes))), only=i)
    cells = []
    for index in cell_indices(axes, model.design):
        slug = cell_slug(axes, index, model.design)
        if len(slug.encode()) > MAX_CELL_NAME:
            raise ConfigError("axes", f"cell {slug[:60]}...: its name (the cell's directory) "
                              f"would be {len(slug.encode())} bytes, above the "
                              f"{MAX_CELL_NAME} a file system allows; vary fewer axes in a "
                              "full design, or write shorter values")
        try:
            cell_study, notes = _apply(study, axes, index)
        except ConfigError as exc:
            raise ConfigError("axes", f"cell {slug}: {exc.field}: {exc.message}") from None
        text = "; ".join(f"{a.name} = {a.labels[k]}" for a, k in zip(axes, index))
        description = (f"{study.description} | " if study.description else "") + \
            f"grid cell {slug}: {text}" + "".join(f"; {n}" for n in notes)
        cell_study = dataclasses.replace(
            cell_study, description=description,
            scenario_source=f"{study.scenario_source}, grid cell {slug}")
        cells.append(Cell(slug, index, cell_study, tuple(notes)))
    return Grid(study, model.design, axes, tuple(cells), comparisons, given, dict(data))


def load_grid(path: str | Path) -> Grid:
    """:func:`grid_from_dict` on a TOML file (a relative scenario file is relative to it)."""
    path = Path(path)
    return grid_from_dict(io.read_input(path, "grid"), base_dir=path.parent)
