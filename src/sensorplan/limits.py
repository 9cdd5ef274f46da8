"""The largest request sensorplan accepts, and the range of every physical input.

Valid but absurd inputs (a horizon of a million epochs, 2,000 move distances, a covariance
of 1e300) would otherwise run for hours, exhaust memory or overflow. Every limit here is
documented (docs/cli.md, "Limits"), is checked before any work starts, and is reported as
one :class:`~sensorplan.errors.ConfigError` naming the field to change.

Two kinds of limit:

- **ranges** of single values (:data:`RANGES`): physical magnitudes far beyond any radar
  or scenario this package models, chosen so that no intermediate quantity can overflow or
  lose all precision;
- **joint sizes** of a request: a decision's reachable positions and work
  (:func:`check_decision_size`), a run's recorded arrays (:func:`check_run_size`) and a
  study's tables (:func:`check_study_size`).

It also holds the one vocabulary of input errors that every layer uses: a value of the
wrong type (:func:`coerce`, :func:`type_error`: "must be an integer, got 2.5"), a value
out of its :class:`Range` ("must be in (0, 1), got 1.0") or not one of its choices
("unknown mode 'x'; choose from jsfp, best-response"), and the one way to declare such a
rule with a value's default and help: a dataclass field made by :func:`param` (a planner's
settings, checked by :func:`check_params`) or by the run settings' ``setting`` (a
:class:`Param` with a section; :mod:`sensorplan.simulation.settings`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Union

from .errors import ConfigError

#: Longest planning look-ahead, horizon x steps per epoch (simulation steps).
MAX_PLAN_STEPS = 1_000
#: Most move distances of one sensor (each gives 8 lattice moves).
MAX_MOVE_DISTANCES = 16
#: Most targets and sensors of a decision or scenario.
MAX_TARGETS = 1_000
MAX_SENSORS = 100
#: Most entries of the reachable-set tables of a decision: for every sensor, the sum over
#: epochs k = 1..K of (|R_{k-1}| + |R_k|) x (number of moves). About 16 bytes each.
MAX_LATTICE_ENTRIES = 50_000_000
#: Most work of a decision: sensors x targets x look-ahead steps x reachable positions
#: summed over the epochs (about 1e7 per second and sweep on one core).
MAX_DECISION_WORK = 500_000_000
#: Most simulation steps of a run.
MAX_STEPS = 100_000
#: Largest estimated memory of one run's recorded arrays (bytes).
MAX_RUN_BYTES = 1_000_000_000
#: Most rows of a study's ``steps`` table (runs x methods x (steps + 1) x targets).
MAX_STUDY_ROWS = 20_000_000
#: Largest process noise q of a scenario or tracker model (m^2/s^3).
MAX_Q = 1e6
#: Most turn-rate draws of a dubins target in one simulation step (dt / turn_hold).
MAX_TURNS_PER_STEP = 1_000
#: Most runs of a study.
MAX_RUNS = 100_000
#: Most buildings of a decision or scenario.
MAX_BUILDINGS = 10_000
#: Most search sectors of one sensor (one a degree: narrower sectors than any beam).
MAX_SEARCH_SECTORS = 360
#: Most cells of a decision's undetected grid (planning holds a few candidates x epochs x
#: cells arrays: 10,000 cells keep them to tens of MB).
MAX_UNDETECTED_CELLS = 10_000
#: Most cells of a grid study.
MAX_GRID_CELLS = 1_000
#: Longest name of a grid cell (bytes): its study directory's name.
MAX_CELL_NAME = 255
#: Most agent processes of the decentralized planners' ``bus`` transport (one per sensor;
#: about 100 MB and a few seconds of start-up each).
MAX_BUS_AGENTS = 16
#: Buildings that cost a planned look as much as the rest of it does: a look tests its line
#: of sight against every building (measured: 10,000 buildings make a decision about 100
#: times slower).
BUILDINGS_PER_LOOK = 100


@dataclass(frozen=True)
class Range:
    """An allowed interval of one input value, with its unit.

    ``lo_open`` / ``hi_open`` exclude the bound; ``None`` is unbounded on that side, and
    with ``inf`` (no upper bound) the value may also be infinite ("unlimited").
    """

    lo: float | None
    hi: float | None
    unit: str = ""
    lo_open: bool = False
    hi_open: bool = False
    magnitude: bool = False          # the bounds apply to the absolute value
    inf: bool = False                # +inf is in the range (hi must be None)

    def contains(self, value: float) -> bool:
        """Whether ``value`` (a finite number; an integer of any size; +inf with ``inf``)
        is in the range."""
        v = abs(value) if self.magnitude else value
        if not isinstance(v, numbers.Integral) and not math.isfinite(v):
            return self.inf and v == math.inf
        if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
            return False
        if self.hi is not None and (v > self.hi or (self.hi_open and v == self.hi)):
            return False
        return True

    def text(self) -> str:
        """``in (0, 1e+06] m``-style description."""
        unit = f" {self.unit}" if self.unit else ""
        if self.magnitude:
            return f"at most {_num(self.hi)}{unit} in magnitude"
        if self.lo is None:
            return f"{'<' if self.hi_open else '<='} {_num(self.hi)}{unit}"
        if self.hi is None:
            return (f"{'>' if self.lo_open else '>='} {_num(self.lo)}{unit}"
                    f"{' or inf' if self.inf else ''}")
        return (f"in {'(' if self.lo_open else '['}{_num(self.lo)}, {_num(self.hi)}"
                f"{')' if self.hi_open else ']'}{unit}")

    def violation(self, value: float) -> str:
        """Why ``value`` is out of the range ("must be in (0, 1), got 1.0"); '' if it is in."""
        if self.contains(value):
            return ""
        return f"must be {self.text()}, got {_shown(value)}"

    def check(self, value: float, field: str, hint: str = "") -> None:
        """Raise :class:`ConfigError` naming ``field`` unless ``value`` is in the range."""
        message = self.violation(value)
        if message:
            raise ConfigError(field, message + hint)


def _num(x: float | None) -> str:
    if x is None:  # pragma: no cover - guarded by the callers
        return "inf"
    if x == math.pi:
        return "pi"
    if x == math.pi / 2:
        return "pi/2"
    if x == 2 * math.pi:
        return "2pi"
    return f"{x:g}"


def _shown(value: float) -> str:
    text = repr(float(value)) if not isinstance(value, int) else str(value)
    return text if len(text) <= 24 else text[:21] + "..."


# ------------------------------------------------------------------ declarations


@dataclass(frozen=True, kw_only=True)
class Param:
    """How one input value is documented and checked beyond its type: the metadata of a
    dataclass field made by :func:`param` (a planner's setting) or, with a section, by the
    run settings' ``setting`` (:class:`~sensorplan.simulation.settings.Setting`).

    Attributes
    ----------
    help : str            one sentence for the docs
    brief : str           a few words for ``--help`` ('' : ``help``)
    cli : tuple of str    the command-line option names that set it, if any
    metavar : str         the option's value placeholder
    choices : tuple or callable
                          allowed values (strings), or a function returning them when they
                          are only known at run time
    noun : str            what a value is called in errors: "unknown <noun> 'x'; choose from"
    bounds : Range        the allowed interval of a number ("must be in [1, 1000], got 0")
    check : callable      extra rule: raises ValueError with the message
    """

    help: str = ""
    brief: str = ""
    cli: tuple[str, ...] = ()
    metavar: str = "VALUE"
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] = ()
    noun: str = "value"
    bounds: Range | None = None
    check: Callable[[Any], None] | None = None

    def allowed(self) -> tuple[str, ...]:
        """The allowed values (empty: no list)."""
        return self.choices() if callable(self.choices) else self.choices

    def validate(self, value: Any) -> None:
        """Raise ``ValueError(message)`` if a value of the right type breaks the rule
        (``None``, where the type allows it, breaks none)."""
        if value is None:
            return
        choices = self.allowed()
        if choices and value not in choices:
            raise ValueError(f"unknown {self.noun} {value!r}; choose from {', '.join(choices)}")
        message = self.bounds.violation(value) if self.bounds is not None else ""
        if message:
            raise ValueError(message)
        if self.check is not None:
            self.check(value)

    def rule(self) -> str:
        """The rule in words, for help texts: "in [0, 1]", "one of jsfp, best-response"."""
        if self.allowed():
            return f"one of {', '.join(self.allowed())}"
        return self.bounds.text() if self.bounds is not None else ""


def param(default: Any = dataclasses.MISSING, *, default_factory: Any = dataclasses.MISSING,
          **declaration: Any) -> Any:
    """A dataclass field carrying its :class:`Param` (keyword arguments as there)."""
    return dataclasses.field(default=default, default_factory=default_factory,
                             metadata={"param": Param(**declaration)})


def declared_params(cls: Any) -> list[tuple[dataclasses.Field[Any], Param]]:
    """The fields of dataclass ``cls`` declared with :func:`param`, in field order."""
    return [(f, f.metadata["param"]) for f in dataclasses.fields(cls) if "param" in f.metadata]


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def check_params(obj: Any, prefix: str) -> None:
    """Check and normalise every field of dataclass ``obj`` declared with :func:`param`, in
    field order: its type (:func:`coerce` of its annotation; an infinite number is left to
    the range), then its :class:`Param` rule.

    Raises
    ------
    ConfigError
        Naming ``<prefix>.<key>`` of the first field that breaks its type or rule.
    """
    cls: type = type(obj)
    hints = _hints(cls)
    for f, p in declared_params(obj):
        try:
            value = coerce(hints[f.name], getattr(obj, f.name), finite=False)
            p.validate(value)
        except ValueError as exc:
            raise ConfigError(f"{prefix}.{f.name}", str(exc)) from None
        object.__setattr__(obj, f.name, value)


# ------------------------------------------------------------------------ types

#: What a value of each plain type must be, in errors: "must be <words>, got ...".
TYPE_WORDS: dict[Any, str] = {bool: "true or false", int: "an integer", float: "a number",
                              str: "a string", list: "a list", tuple: "a list",
                              Mapping: "a table", dict: "a table"}


def shown(value: Any) -> str:
    """``value`` as an error shows what it got: its repr, cut at 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def type_error(tp: Any, value: Any) -> str:
    """The message for ``value`` where type ``tp`` is wanted: "must be an integer, got 2.5"."""
    return f"must be {TYPE_WORDS[tp]}, got {shown(value)}"


# numpy is not imported here (the command line's help reads the settings): its scalars are
# recognised by the numbers ABCs, which numpy registers them with, and by their module.
def _is_bool(v: Any) -> bool:
    return isinstance(v, bool) or (type(v).__module__ == "numpy"
                                   and type(v).__name__ in ("bool", "bool_"))


def coerce(tp: Any, value: Any, finite: bool = True) -> Any:
    """``value`` as type ``tp``, or ``ValueError`` with the package's words for it.

    The one type check of settings, planner parameters and (through :data:`TYPE_WORDS`) the
    file models. ``int`` takes any integer but a bool (numpy's too) and gives an ``int``;
    ``float`` any real number but a bool, as a ``float`` (finite unless ``finite`` is
    False); ``bool`` true or false; ``str`` a string; ``Mapping``/``dict`` a table, as a
    ``dict``; ``tuple[X, ...]`` a list or tuple of X, as a tuple; ``X | None`` None or an X
    (the first alternative's message); ``Literal[...]`` one of its values. Any other type is
    not checked here (its owner checks it).

    Raises
    ------
    ValueError
        "must be an integer, got 2.5", "must be a finite number", ...
    """
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None and len(args) < len(typing.get_args(tp)):
            return None
        first: ValueError | None = None
        for a in args:
            try:
                return coerce(a, value, finite)
            except ValueError as exc:
                first = first or exc
        raise first or ValueError(f"must be None, got {shown(value)}")
    if origin is Literal:
        allowed = typing.get_args(tp)
        if value in allowed:
            return value
        raise ValueError(f"must be one of {', '.join(repr(a) for a in allowed)}, "
                         f"got {shown(value)}")
    if origin is tuple and typing.get_args(tp)[1:] == (Ellipsis,):
        if not isinstance(value, (list, tuple)):
            raise ValueError(type_error(tuple, value))
        inner = typing.get_args(tp)[0]
        return tuple(coerce(inner, x, finite) for x in value)
    if tp is bool:
        if not _is_bool(value):
            raise ValueError(type_error(bool, value))
        return bool(value)
    if tp is int:
        if not isinstance(value, numbers.Integral) or _is_bool(value):
            raise ValueError(type_error(int, value))
        return int(value)
    if tp is float:
        if not isinstance(value, numbers.Real) or _is_bool(value):
            raise ValueError(type_error(float, value))
        try:
            out = float(value)
        except OverflowError:              # an integer literal no float can hold
            raise ValueError(type_error(float, value)) from None
        if finite and not math.isfinite(out):
            raise ValueError("must be a finite number")
        return out
    if tp is str:
        if not isinstance(value, str):
            raise ValueError(type_error(str, value))
        return value
    if tp is Mapping or tp is dict or origin in (Mapping, dict):
        if not isinstance(value, Mapping):
            raise ValueError(type_error(Mapping, value))
        return dict(value)
    return value


#: Largest length (m): map sides, positions, altitudes, ranges, moves, boxes.
LENGTH = 1e8
#: Ranges of the physical inputs by name (scenario, plan and sensor keys).
RANGES: dict[str, Range] = {
    "length": Range(0.0, LENGTH, "m", lo_open=True),
    "coordinate": Range(None, LENGTH, "m", magnitude=True),
    "dt": Range(1e-3, 3600.0, "s"),
    "process_noise": Range(0.0, MAX_Q, "m^2/s^3"),
    "speed": Range(0.0, 1e4, "m/s"),
    "velocity": Range(None, 1e4, "m/s", magnitude=True),
    # Any angle is a direction, but one beyond a full turn is degrees written as radians.
    "heading": Range(None, 2 * math.pi, "rad", magnitude=True),
    "turn_hold": Range(1e-3, 1e6, "s"),
    "max_turn_rate": Range(0.0, math.pi, "rad/s"),
    "fov_half_angle": Range(0.0, math.pi, "rad", lo_open=True),
    "max_turn": Range(0.0, math.pi, "rad"),
    "depression": Range(0.0, math.pi / 2, "rad", lo_open=True),
    "beamwidth": Range(1e-4, math.pi / 2, "rad"),
    "snr_ref_db": Range(-100.0, 100.0, "dB"),
    "range_ref": Range(1.0, 1e6, "m"),
    "range_resolution": Range(1e-2, 1e4, "m"),
    "range_error_floor": Range(0.0, 1e4, "m"),
    "azimuth_error_floor": Range(0.0, 0.1, "rad"),
    "monopulse_slope": Range(0.1, 10.0),
    "clutter_rate": Range(0.0, 1e3, "per look"),
    "probability": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "altitude": Range(1.0, 1e5, "m"),
    "ground_range": Range(0.0, LENGTH, "m"),
    "covariance": Range(None, 1e14, magnitude=True),
    "velocity_variance": Range(0.0, 1e8, "m^2/s^2"),
    "building_height": Range(0.0, LENGTH, "m", lo_open=True),
    "birth_rate": Range(0.0, 100.0, "per step"),
    "cell_size": Range(1e-3, LENGTH, "m"),
    "cell_intensity": Range(0.0, 1e6, "targets"),
    "found_weight": Range(0.0, 1e6, "nats"),
}


#: Highest signal-to-noise ratio a radar may reach, at its closest range (its altitude):
#: beyond it the measurement noise is so small against the covariances that the
#: information matrices lose all precision (dB).
MAX_PEAK_SNR_DB = 120.0
#: Smallest range (m) and azimuth (rad) noise standard deviation of a radar, at its closest
#: range: measurements more precise than this make the covariances of planning lose all
#: precision against the prior uncertainty a target may have.
MIN_RANGE_SIGMA = 1e-3
MIN_AZIMUTH_SIGMA = 1e-6
#: Largest ratio of a given covariance's largest to smallest eigenvalue, and its smallest
#: eigenvalue (a standard deviation of about 3e-5 m or m/s).
MAX_CONDITION = 1e12
MIN_EIGENVALUE = 1e-9


def check_radar_precision(snr_ref_db: float, range_ref: float, altitude: float,
                          range_resolution: float, beamwidth: float, monopulse_slope: float,
                          min_ground_range: float, prefix: str,
                          range_error_floor: float = 0.0,
                          azimuth_error_floor: float = 0.0) -> None:
    """Refuse a radar too precise to compute with: its SNR at the altitude (the closest
    possible range), ``snr_ref_db + 40 log10(range_ref / altitude)``, above
    :data:`MAX_PEAK_SNR_DB`, or its noise there below :data:`MIN_RANGE_SIGMA` in range
    (``range_resolution / sqrt(2 SNR)`` and the range error floor in quadrature) or
    :data:`MIN_AZIMUTH_SIGMA` in azimuth (``beamwidth / monopulse_slope / sqrt(2 SNR)`` and
    the azimuth error floor in quadrature), or the ground position noise that the azimuth
    gives at the nearest ground range it sees (``min_ground_range`` times that azimuth
    noise) below :data:`MIN_RANGE_SIGMA`. Fields are ``prefix.<key>``."""
    peak = snr_ref_db + 40.0 * math.log10(range_ref / altitude)
    if peak > MAX_PEAK_SNR_DB:
        raise ConfigError(f"{prefix}.snr_ref_db", f"with range_ref {range_ref:g} m and "
                          f"altitude {altitude:g} m the SNR at the closest range would be "
                          f"{peak:.4g} dB, above the limit of {MAX_PEAK_SNR_DB:g} dB (lower "
                          "snr_ref_db or range_ref, or raise the altitude)")
    root = math.sqrt(2.0 * 10.0 ** (peak / 10.0))
    sigma_r = math.hypot(range_resolution / root, range_error_floor)
    if sigma_r < MIN_RANGE_SIGMA:
        raise ConfigError(f"{prefix}.range_resolution", f"gives a range noise of "
                          f"{sigma_r:.3g} m at the closest range (SNR {peak:.4g} dB), below "
                          f"the limit of {MIN_RANGE_SIGMA:g} m")
    sigma_phi = math.hypot(beamwidth / monopulse_slope / root, azimuth_error_floor)
    if sigma_phi < MIN_AZIMUTH_SIGMA:
        raise ConfigError(f"{prefix}.beamwidth", f"gives an azimuth noise of "
                          f"{sigma_phi:.3g} rad at the closest range (with monopulse_slope "
                          f"{monopulse_slope:g}, SNR {peak:.4g} dB), below the limit of "
                          f"{MIN_AZIMUTH_SIGMA:g} rad")
    if min_ground_range * sigma_phi < MIN_RANGE_SIGMA:
        raise ConfigError(f"{prefix}.min_ground_range", f"a target {min_ground_range:g} m "
                          f"away on the ground would be located to "
                          f"{min_ground_range * sigma_phi:.3g} m across the line of sight "
                          f"(azimuth noise {sigma_phi:.3g} rad), below the limit of "
                          f"{MIN_RANGE_SIGMA:g} m: raise min_ground_range to at least "
                          f"{MIN_RANGE_SIGMA / sigma_phi:.3g} m")


def check_sensor_precision(params: Any, prefix: str) -> None:
    """:func:`check_radar_precision` of a :class:`~sensorplan.models.sensors.SensorParams` (scalar
    fields). Input files (decision, scenario) apply it to every sensor; problems built in
    Python are not bound by it."""
    p = params
    check_radar_precision(float(p.snr_ref_db), float(p.range_ref), float(p.altitude),
                          float(p.range_resolution), float(p.beamwidth),
                          float(p.monopulse_slope), float(p.min_ground_range), prefix,
                          float(p.range_error_floor), float(p.azimuth_error_floor))


def check_covariance_scale(P: Any, field: str) -> None:
    """Refuse a given covariance ``(4, 4)`` (symmetric and positive definite, checked
    before) with entries above the ``covariance`` range, a velocity variance above the
    ``velocity_variance`` range (a standard deviation of the largest speed), an eigenvalue
    below
    :data:`MIN_EIGENVALUE` or a condition number above :data:`MAX_CONDITION`."""
    import numpy as np

    P = np.asarray(P, dtype=float)
    for v in P.ravel():
        RANGES["covariance"].check(float(v), field)
    for k in (2, 3):
        RANGES["velocity_variance"].check(float(P[k, k]), f"{field}[{k}][{k}]")
    vals = np.linalg.eigvalsh(0.5 * (P + P.T))
    if vals[0] < MIN_EIGENVALUE:
        raise ConfigError(field, f"must have eigenvalues >= {MIN_EIGENVALUE:g}, got "
                          f"{vals[0]:.3g}")
    if vals[-1] > MAX_CONDITION * vals[0]:
        raise ConfigError(field, f"is too ill-conditioned: largest / smallest eigenvalue "
                          f"= {vals[-1] / vals[0]:.3g}, at most {MAX_CONDITION:g}")


def check_count(n: int, most: int, field: str, what: str) -> None:
    if n > most:
        raise ConfigError(field, f"at most {most} {what} are supported, got {n}")


def grid_step(moves: Sequence[float]) -> float:
    """The largest step (m) of which every move distance is a multiple, on the 1e-6 m grid
    that tells positions apart (as the reachable sets do); 0 when there is none."""
    unit = 1e-6
    q = [round(abs(float(m)) / unit) for m in moves]
    if any(abs(n * unit - abs(float(m))) > 1e-9 for n, m in zip(q, moves)):
        return 0.0
    g = math.gcd(*q) if q else 0
    return g * unit


def lattice_sizes(moves: Sequence[float], horizon: int, width: float,
                  height: float) -> list[float]:
    """Upper bounds of |R_0|, ..., |R_K|: the positions a sensor can reach in k epochs.

    Moves that are multiples of a common step ``g`` keep a sensor on a grid of spacing
    ``g``: at most ``(2 k s_max / g + 1)`` points per axis, and no more than the map holds;
    without a common step every move sequence may end elsewhere (``n_moves ** k``).
    """
    n_moves = 1 + 8 * len(moves)
    g = grid_step(moves)
    s_max = max((abs(float(m)) for m in moves), default=0.0)
    sizes = [1.0]
    for k in range(1, horizon + 1):
        count = sizes[-1] * n_moves
        if g > 0:
            per_x = min(2.0 * k * s_max / g + 1.0, width / g + 1.0)
            per_y = min(2.0 * k * s_max / g + 1.0, height / g + 1.0)
            count = min(count, per_x * per_y)
        sizes.append(count)
        if count > 1e30:                               # far beyond any limit: stop growing
            sizes.extend([count] * (horizon - k))
            break
    return sizes


#: The run settings the size limits read (:func:`check_run`); their callers name them in
#: errors through :func:`sensorplan.simulation.settings.limit_fields`.
SIZE_SETTINGS = ("horizon", "steps_per_epoch", "steps", "search_sectors")


def check_decision_size(horizon: int, steps_per_epoch: int, n_targets: int,
                        moves: Sequence[Sequence[float]], width: float, height: float,
                        fields: dict[str, str], n_buildings: int = 0) -> None:
    """Refuse a decision (or a run's decisions) too large to plan (see the module limits).

    Parameters
    ----------
    horizon, steps_per_epoch : int      K and e
    n_targets : int
    moves : sequence (one per sensor) of move distances (m)
    width, height : float               the map (m)
    fields : dict
        The names of the fields in the caller's input: keys ``horizon``,
        ``steps_per_epoch``, ``targets``, ``sensors`` and ``moves`` (a format string with
        ``{i}``, e.g. ``"sensors[{i}].moves"``).
    n_buildings : int
        Buildings that can hide a target: each planned look tests them all, so the work
        grows by ``1 + n_buildings / BUILDINGS_PER_LOOK`` (named ``buildings`` when they
        tip it over the limit).

    Raises
    ------
    ConfigError
    """
    check_count(n_targets, MAX_TARGETS, fields["targets"], "targets")
    check_count(len(moves), MAX_SENSORS, fields["sensors"], "sensors")
    T = horizon * steps_per_epoch
    if T > MAX_PLAN_STEPS:
        field = fields["steps_per_epoch"] if steps_per_epoch > horizon else fields["horizon"]
        raise ConfigError(field, f"the planning look-ahead horizon x steps_per_epoch = {T} "
                          f"steps exceeds the limit of {MAX_PLAN_STEPS}")
    work = 0.0
    for i, distances in enumerate(moves):
        check_count(len(distances), MAX_MOVE_DISTANCES, fields["moves"].format(i=i),
                    "move distances")
        sizes = lattice_sizes(distances, horizon, width, height)
        n_moves = 1 + 8 * len(distances)
        entries = [(sizes[k - 1] + sizes[k]) * n_moves for k in range(1, horizon + 1)]
        if entries[0] > MAX_LATTICE_ENTRIES:
            raise ConfigError(fields["moves"].format(i=i), f"{len(distances)} move distances "
                              f"on a grid this fine give {entries[0]:.3g} reachable-set "
                              f"entries in one epoch, above the limit of "
                              f"{MAX_LATTICE_ENTRIES:.3g}")
        if sum(entries) > MAX_LATTICE_ENTRIES:
            raise ConfigError(fields["horizon"], f"the reachable positions of sensor {i} over "
                              f"{horizon} epochs need {sum(entries):.3g} table entries, above "
                              f"the limit of {MAX_LATTICE_ENTRIES:.3g}")
        work += sum(sizes[1:]) * n_targets * T
    if work > MAX_DECISION_WORK:
        field = fields["horizon"] if horizon > 1 else fields["targets"]
        raise ConfigError(field, f"one decision would take about {work:.3g} units of work "
                          f"(sensors x targets x look-ahead steps x reachable positions), "
                          f"above the limit of {MAX_DECISION_WORK:.3g}")
    slower = 1.0 + n_buildings / BUILDINGS_PER_LOOK
    if work * slower > MAX_DECISION_WORK:
        raise ConfigError("buildings", f"{n_buildings} buildings make one decision about "
                          f"{slower:.3g} times the work ({work * slower:.3g} units: sensors x "
                          f"targets x look-ahead steps x reachable positions x (1 + buildings "
                          f"/ {BUILDINGS_PER_LOOK})), above the limit of "
                          f"{MAX_DECISION_WORK:.3g}")


def run_bytes(steps: int, n_targets: int, n_sensors: int) -> float:
    """Estimated memory (bytes) of one run's recorded arrays (``Episode``)."""
    M, N = n_targets, n_sensors
    return (steps + 1) * (210.0 * M + 60.0 * N + 2.0 * M * N)


def check_run_size(steps: int, n_targets: int, n_sensors: int, field: str) -> None:
    """Refuse a run longer than :data:`MAX_STEPS` or whose arrays exceed
    :data:`MAX_RUN_BYTES`; ``field`` names the steps setting."""
    if steps > MAX_STEPS:
        raise ConfigError(field, f"must be at most {MAX_STEPS}, got {steps}")
    size = run_bytes(steps, n_targets, n_sensors)
    if size > MAX_RUN_BYTES:
        raise ConfigError(field, f"{steps} steps of {n_targets} targets and {n_sensors} "
                          f"sensors would record about {size / 1e9:.3g} GB, above the limit "
                          f"of {MAX_RUN_BYTES / 1e9:g} GB")


def check_study_size(runs: int, n_methods: int, steps: int, n_targets: int) -> None:
    """Refuse a study with more than :data:`MAX_RUNS` runs or whose ``steps`` table would
    exceed :data:`MAX_STUDY_ROWS` rows."""
    if runs > MAX_RUNS:
        raise ConfigError("runs", f"must be at most {MAX_RUNS}, got {runs}")
    rows = runs * n_methods * (steps + 1) * n_targets
    if rows > MAX_STUDY_ROWS:
        raise ConfigError("runs", f"{runs} runs x {n_methods} methods x {steps + 1} steps x "
                          f"{n_targets} targets = {rows:.3g} table rows, above the limit of "
                          f"{MAX_STUDY_ROWS:.3g}")


def check_run(scenario: Any, settings: Any, fields: dict[str, str]) -> None:
    """:func:`check_decision_size` for the decisions of a run of ``settings``
    (:class:`~sensorplan.simulation.settings.RunSettings`) on ``scenario``
    (:class:`~sensorplan.simulation.scenario.Scenario`; sensors anywhere on the map) and
    :func:`check_run_size` for its steps.

    ``fields`` names the fields as :func:`check_decision_size` wants, plus ``steps``.
    """
    if settings.tracker.kind == "known" and not scenario.known_targets:
        raise ConfigError(fields.get("tracker.kind", "tracker.kind"),
                          "a tracker of known targets needs every target known from the "
                          "start (births = 'none', survival_probability = 1, no scripted "
                          "truth); choose a multi-target tracker")
    if getattr(scenario, "scan", None) is not None and settings.tracker.kind != "pmb":
        raise ConfigError(fields.get("tracker.kind", "tracker.kind"),
                          f"the {scenario.scan} scan's linear sensor is tracked by the pmb "
                          f"tracker only, got {settings.tracker.kind!r}")
    if settings.tracker.kind != "known" and scenario.look_detects != "all":
        raise ConfigError("look_detects", "a multi-target tracker needs looks that detect "
                          "every live target in view: look_detects = 'all'")
    most = getattr(scenario, "truth_steps", None)
    if most is not None and settings.steps > most:
        raise ConfigError(fields["steps"], f"must be at most {most} (the scripted "
                          f"{scenario.scripted} truth's length), got {settings.steps}")
    M, N = len(scenario.targets), len(scenario.sensors)
    sectors = getattr(settings, "search_sectors", 0)
    if getattr(settings, "search", "off") == "on" and not isinstance(sectors, int) \
            and len(sectors) != N:
        raise ConfigError(fields.get("search_sectors", "search_sectors"),
                          f"must be one number or one per sensor ({N}), got {len(sectors)}")
    check_decision_size(settings.horizon, settings.steps_per_epoch, M,
                        [s.params.moves for s in scenario.sensors], scenario.world.width,
                        scenario.world.height, fields, len(scenario.buildings))
    check_run_size(settings.steps, M, N, fields["steps"])


def check_bus_agents(n_agents: int, field: str) -> None:
    """Refuse more than :data:`MAX_BUS_AGENTS` agent processes on the ``bus`` transport
    (``field`` names the transport setting)."""
    if n_agents > MAX_BUS_AGENTS:
        raise ConfigError(field, f"the bus transport runs one process per sensor (about 100 "
                          f"MB and a few seconds of start-up each): at most {MAX_BUS_AGENTS} "
                          f"sensors, got {n_agents}; use transport \"inproc\" for more")
