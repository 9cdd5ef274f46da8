"""Run settings: how one closed-loop run plans, executes and tracks, each declared once.

Every setting is one field of :class:`RunSettings` (or of its nested
:class:`TrackerSettings`) declared with :func:`setting`, whose metadata (a
:class:`Setting`) says everything the rest of the package needs:

- its one-sentence help text (the docs), and for ``--help`` a brief one that fits a line
  or two at 80 columns;
- its section: the table of a scenario file that holds it (``[planning]``, ``[tracker]`` or
  ``[run]``); the key is the field name everywhere (files, study methods, resolved configs);
- its ``sensorplan simulate`` option names (``--horizon``, ``-K``), if it has any;
- its rule besides the type annotation: choices, a :class:`~sensorplan.limits.Range` or a
  custom check (the type and range errors are worded by :mod:`sensorplan.limits`).

From this one declaration come the checks of ``__post_init__`` (:func:`check_fields`), the
strict file models (:func:`sensorplan.config.validation.section_model`), the ``simulate`` options
(:mod:`sensorplan.cli.app`), study methods with their per-key inheritance
(:mod:`sensorplan.study.file`) and the resolved files (:meth:`RunSettings.to_dict`,
:meth:`RunSettings.from_dict`). Adding a setting is adding a field here (and its docs).

Sections map to study files like this: ``planning`` keys are flat in ``[defaults]`` and
``[[methods]]``; ``tracker`` keys live in their sub-table ``[methods.tracker]`` /
``[defaults.tracker]``; ``run`` keys are study-wide top-level keys.
"""

from __future__ import annotations

import contextvars
import dataclasses
import functools
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import ConfigError
from ..limits import (MAX_PLAN_STEPS, MAX_SEARCH_SECTORS, MAX_STEPS, RANGES, SIZE_SETTINGS,
                      Param, Range, coerce)
from ..planners.objective import (OBJECTIVES, PLANNING_DETECTIONS,
                                  PLANNING_OCCLUSIONS, REWARDS, SEARCH_MODES,
                                  TRACK_EXISTENCE_MODES, UNREPORTED_MODES,
                                  VISIBILITY_MODES)
from ..tracking.registry import tracker_kinds

EXECUTIONS = ("ol", "olf")
MISS_UPDATES = ("negative", "none")
TRACKER_MODELS = ("cv", "imm")
ASSOCIATIONS = ("pda", "nearest")
#: Tables of a scenario file that hold run settings, in file order.
SECTIONS = ("planning", "tracker", "run")


@dataclass(frozen=True, kw_only=True)
class Setting(Param):
    """How one run setting is written, checked and documented (a field's metadata): a
    :class:`~sensorplan.limits.Param` (its help, brief, option names, placeholder and rule)
    with the table that holds it.

    Attributes
    ----------
    help : str            one sentence for the docs (docs/cli.md lists every option)
    brief : str           a few words for ``--help`` (its choices are added); '' for
                          settings without options
    section : str         ``planning``, ``tracker`` or ``run`` (see the module docstring)
    cli : tuple of str    option names of ``sensorplan simulate`` (none: file-only setting)
    label : str           short column heading in reports (default: the key)
    names : callable      known values listed in the help when the list is open (other
                          values may pass ``check``: a planner given as module:Class)
    """

    help: str
    section: str
    label: str = ""
    names: Callable[[], tuple[str, ...]] | None = None


def setting(default: Any = dataclasses.MISSING, *, help: str, section: str,
            default_factory: Any = dataclasses.MISSING, **rule: Any) -> Any:
    """A dataclass field carrying its :class:`Setting` (keyword arguments as there)."""
    meta = {"setting": Setting(help=help, section=section, **rule)}
    return field(default=default, default_factory=default_factory, metadata=meta)


#: The settings only the PMB tracker reads, and only the GNN tracker.
PMB_SETTINGS = ("births", "birth_rate", "background_birth_rate", "survival_probability",
                "established_survival", "established_existence",
                "report_threshold", "prune_threshold", "recycle_threshold",
                "recycle_motion", "split_existence", "density_components",
                "planning_threshold",
                "termination_threshold", "edge_exit", "bernoulli_model", "birth_velocity")
GNN_SETTINGS = ("confirm_hits", "confirm_looks", "delete_misses")
#: The settings only the lost-target mode of the tracker of known targets reads.
LOST_SETTINGS = ("lost_probability", "lost_resolution")
#: The settings only a multi-target tracker reads.
MULTI_TARGET_SETTINGS = ("map_edge", *PMB_SETTINGS, "grid_resolution", *GNN_SETTINGS)
#: A multi-target tracker's model of the map's edge: as the scenario's truth, or one of
#: :data:`sensorplan.tracking.known_map.MAP_EDGES` (exit, closed).
MAP_EDGE_CHOICES = ("scenario", "exit", "closed")
#: What the PMB tracker charges a track's existence at an exit edge:
#: :data:`sensorplan.tracking.known_map.EDGE_EXITS` (named here without importing the
#: tracking modules, as the map edges are).
EDGE_EXITS = ("outside", "crossing")
#: What the PMB tracker makes of a recycled track:
#: :data:`sensorplan.tracking.pmb.tracker.RECYCLE_MOTIONS` (named here likewise).
RECYCLE_MOTIONS = ("static", "moving")
#: The PMB tracker's velocity prior of a target first detected:
#: :data:`sensorplan.tracking.pmb.undetected.BIRTH_VELOCITIES`.
BIRTH_VELOCITIES = ("isotropic", "inward")


def _births() -> tuple[str, ...]:
    from ..models.population import BIRTHS

    return BIRTHS


def builtin_planners() -> tuple[str, ...]:
    """The built-in planner names, sorted (for help texts: no plugin is looked up)."""
    from ..planners.registry import BUILTIN

    return tuple(sorted(BUILTIN))


def known_planner(name: str) -> None:
    """Raise ``ValueError(message)`` unless ``name`` is a planner (a known name or a
    ``package.module:Class`` that imports as one)."""
    from ..planners.registry import planner_class

    try:
        planner_class(name)
    except ConfigError as exc:
        raise ValueError(exc.message) from None


#: True while settings are read back from a finished run (:meth:`_Settings.from_dict` with
#: ``trusted``): the planner is then neither imported nor instantiated.
_TRUSTED: contextvars.ContextVar[bool] = contextvars.ContextVar("sensorplan_trusted",
                                                                 default=False)


class _Settings:
    """Shared behaviour of the settings dataclasses: checks and dict conversion."""

    def __post_init__(self) -> None:
        check_fields(self)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary of every field (nested groups as nested dictionaries)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if isinstance(v, _Settings):
                v = v.to_dict()
            elif isinstance(v, Mapping):
                v = {k: _plain(x) for k, x in v.items()}
            out[f.name] = _plain(v)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, trusted: bool = False) -> Any:
        """Inverse of :meth:`to_dict`; unknown keys are a :class:`ConfigError`.

        With ``trusted`` (settings a finished run wrote, read back by ``sensorplan report``)
        the planner and its settings are taken as written: its class is not imported, so a
        study run with a planner from another package reads back where that package is not
        installed. Every other setting is checked as usual.
        """
        names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        for key in data:
            if key not in names:
                raise ConfigError(str(key), f"unknown key; allowed: {', '.join(names)}")
        token = _TRUSTED.set(trusted or _TRUSTED.get())
        try:
            return cls(**data)
        finally:
            _TRUSTED.reset(token)


def _plain(v: Any) -> Any:
    """A JSON-ready value: numpy scalars as Python numbers, tuples as lists."""
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    return v.item() if _is_numpy(v) and getattr(v, "ndim", None) == 0 else v


# numpy is not imported here (the command line's help reads the settings): its scalars are
# recognised by their module.
def _is_numpy(v: Any) -> bool:
    return type(v).__module__ == "numpy"


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def field_type(cls: type, name: str) -> Any:
    """The declared type of a settings field (``int``, ``float``, ``str``, ``bool``,
    ``Mapping`` for tables, ``tuple`` for lists, ``typing.Union`` for a number or a list,
    or a nested settings class)."""
    tp = _hints(cls)[name]
    origin = typing.get_origin(tp)
    return typing.Union if origin is types.UnionType else origin or tp


def cli_type(cls: type, name: str) -> Any:
    """The type of a setting's command-line option: the field's type, or for a number or
    a list (``int | tuple[int, ...]``) the number (one value for every sensor)."""
    tp = field_type(cls, name)
    if tp is typing.Union:
        return next(a for a in typing.get_args(_hints(cls)[name])
                    if typing.get_origin(a) is not tuple)
    return tp


def field_hint(cls: type, name: str) -> Any:
    """The full type hint of a settings field (``tuple[float, ...]`` for a list)."""
    return _hints(cls)[name]


def is_group(tp: Any) -> bool:
    """Whether a field type is a nested settings class (a sub-table such as ``tracker``)."""
    return isinstance(tp, type) and issubclass(tp, _Settings)


def declared(cls: type, section: str | None = None) -> list[tuple[dataclasses.Field[Any],
                                                                   Setting]]:
    """The fields of ``cls`` declared with :func:`setting` (optionally of one section)."""
    out = []
    for f in dataclasses.fields(cls):
        s = f.metadata.get("setting")
        if s is not None and (section is None or s.section == section):
            out.append((f, s))
    return out


def check_fields(obj: Any, unchecked: tuple[str, ...] = ()) -> None:
    """Check (and normalise) every field of a settings dataclass from its declaration.

    Integers become ``int``, numbers ``float``, tables ``dict``; a nested group given as a
    mapping becomes its settings class. Fields in ``unchecked`` get their type checked but
    not their rule.

    Raises
    ------
    ConfigError
        Naming the field (``horizon``, ``tracker.miss_update``) with the rule it breaks.
    """
    cls = type(obj)
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        tp = field_type(cls, f.name)
        if is_group(tp):
            if isinstance(v, Mapping):
                try:
                    v = tp.from_dict(v)
                except ConfigError as exc:
                    raise ConfigError(f"{f.name}.{exc.field}", exc.message) from None
            elif not isinstance(v, tp):
                raise ConfigError(f.name, f"must be a {tp.__name__} or a table, got {v!r}")
            object.__setattr__(obj, f.name, v)
            continue
        s: Setting | None = f.metadata.get("setting")
        if s is None:
            continue
        try:
            v = coerce(field_hint(cls, f.name) if tp in (tuple, typing.Union) else tp, v)
            if f.name not in unchecked:
                s.validate(v)
        except ValueError as exc:
            raise ConfigError(f.name, str(exc)) from None
        object.__setattr__(obj, f.name, v)


# ------------------------------------------------------------------------ the settings


def _switching_matrix(value: tuple[tuple[float, ...], ...]) -> None:
    """A Markov switching matrix: square, entries in [0, 1], every row summing to 1."""
    R = len(value)
    if R < 1 or any(len(row) != R for row in value):
        raise ValueError(f"must be a square matrix (one row per mode), got {R} row(s) of "
                         f"lengths {[len(row) for row in value]}")
    for i, row in enumerate(value):
        if any(not 0.0 <= p <= 1.0 for p in row):
            raise ValueError(f"row {i}: probabilities must be in [0, 1], got {list(row)}")
        if abs(sum(row) - 1.0) > 1e-9:
            raise ValueError(f"row {i} must sum to 1, got {sum(row)!r}")


def _sector_counts(value: int | tuple[int, ...]) -> None:
    """One count, or one per sensor, each in [0, MAX_SEARCH_SECTORS]."""
    counts = (value,) if isinstance(value, int) else value
    if not counts:
        raise ValueError("must be a number or a list of one number per sensor, got []")
    for s in counts:
        if not 0 <= s <= MAX_SEARCH_SECTORS:
            raise ValueError(f"must be in [0, {MAX_SEARCH_SECTORS}], got {s}")


def sector_counts(value: int | tuple[int, ...], n_sensors: int) -> tuple[int, ...]:
    """Each sensor's search sectors from ``search_sectors`` (one number for all)."""
    return (value,) * n_sensors if isinstance(value, int) else tuple(value)


#: Most IMM modes.
MAX_MODES = 16


def _mode_noises(value: tuple[float, ...]) -> None:
    if len(value) < 2:
        raise ValueError(f"must list at least two modes, got {len(value)}")
    if len(value) > MAX_MODES:
        raise ValueError(f"must list at most {MAX_MODES} modes, got {len(value)}")
    q_range = RANGES["process_noise"]
    if not all(q_range.contains(q) for q in value):
        raise ValueError(f"every mode's q must be {q_range.text()}, got {list(value)}")


@dataclass(frozen=True)
class TrackerSettings(_Settings):
    """How the run's trackers filter the measurements (the ``[tracker]`` table).

    The defaults were chosen by a measured sweep on the paper scenario with a rule fixed
    beforehand (``studies/tracker_sweep.toml``, docs/results.md): an IMM with modes of q =
    0.05 and 5, the gate, re-acquisition and the known map; ``process_noise`` (the cv
    model's q) is the best cv candidate of the same sweep. ``studies/paper.toml``'s paper
    rows turn every option off.
    """

    kind: str = setting(
        "known", section="tracker", cli=("--tracker",), metavar="KIND", label="tracker",
        choices=tracker_kinds, noun="tracker kind", brief="The tracker (kind)",
        help="The tracker: known (one track per target known from the start, the paper's), "
             "pmb (a Poisson multi-Bernoulli tracker that finds, confirms and deletes "
             "targets) or gnn (global nearest neighbour association with M-of-N track "
             "logic, the engineer's baseline).")
    miss_update: str = setting(
        "negative", section="tracker", cli=("--miss-update",), metavar="MODE",
        brief="A look that misses: negative (update with it) or none (the paper's)",
        label="miss update", choices=MISS_UPDATES, noun="miss update",
        help="Tracker's reaction to a look that misses its target: negative (update with the "
             "negative information) or none (the paper's).")
    model: str = setting(
        "imm", section="tracker", cli=("--tracker-model",), metavar="MODEL",
        brief="The tracker's motion model: cv or imm",
        label="model", choices=TRACKER_MODELS, noun="tracker model",
        help="The filter's motion model: cv (one constant-velocity model with q = "
             "process_noise) or imm (interacting multiple models: CWNA modes with the q's of "
             "mode_process_noise and Markov switching).")
    process_noise: float = setting(
        1.0, section="tracker", cli=("--tracker-q",), metavar="Q", label="q",
        brief="q of the cv tracker (m^2/s^3)",
        bounds=RANGES["process_noise"],
        help="q (m^2/s^3) of the cv filter; the truth's q is the scenario's process_noise.")
    mode_process_noise: tuple[float, ...] = setting(
        (0.05, 5.0), section="tracker", label="IMM q's", check=_mode_noises,
        help="q (m^2/s^3) of each IMM mode, quiet first (model = imm, or a PMB tracker's "
             "bernoulli_model = imm).")
    switching: tuple[tuple[float, ...], ...] = setting(
        ((0.95, 0.05), (0.1, 0.9)), section="tracker", label="IMM switching",
        check=_switching_matrix,
        help="IMM switching matrix: row i gives the probabilities of moving from mode i to "
             "each mode in one step (rows sum to 1).")
    gate: bool = setting(
        True, section="tracker", cli=("--gate/--no-gate",), label="gate",
        brief="Use only detections inside the track's gate",
        help="Use a detection only inside the validation gate of its track.")
    gate_probability: float = setting(
        0.999, section="tracker", cli=("--gate-probability",), metavar="P",
        label="gate probability", bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        brief="Probability that a track's own detection is inside its gate",
        help="Probability that a track's own detection falls inside its gate (the gate is "
             "the chi-square(2) quantile of it).")
    reacquire: bool = setting(
        True, section="tracker", cli=("--reacquire/--no-reacquire",), label="re-acquire",
        brief="Restart a track from a detection outside the gate (needs --gate)",
        help="Restart a track from a detection of its target outside the gate (needs the "
             "gate; off when false alarms are on).")
    association: str = setting(
        "pda", section="tracker", cli=("--association",), metavar="NAME",
        brief="How detections among false alarms update a track: pda or nearest",
        label="association", choices=ASSOCIATIONS, noun="association",
        help="How a look's detections update its track when the sensor reports false "
             "alarms: pda (probabilistic data association over the gated detections) or "
             "nearest (the gated detection closest to the track).")
    known_map: bool = setting(
        True, section="tracker", cli=("--known-map/--no-known-map",), label="known map",
        brief="Keep tracks inside the map",
        help="Truncate a track that leaves the map to the map (targets never leave it).")
    known_buildings: bool = setting(
        False, section="tracker", label="known buildings",
        help="Keep tracks out of the buildings (targets never enter one) and predict them "
             "turning at the walls, as targets do.")
    reflect_walls: bool = setting(
        False, section="tracker", label="reflect walls",
        help="Predict the part of a track that leaves the map reflected off its walls, as "
             "targets are (needs known_map).")
    lost_mode: bool = setting(
        False, section="tracker", label="lost mode",
        help="Turn a track that has lost its target (its run of missed looks since its last "
             "detection is improbable under it: below lost_probability) into a density on a "
             "grid over the map, thinned by every missed look, until a detection finds the "
             "target again (needs the negative miss update and ideal detection).")
    lost_probability: float = setting(
        0.01, section="tracker", label="lost probability",
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        help="A track is lost when the probability of its run of misses under it falls "
             "below this (the test's rate of false alarms for a right track).")
    lost_resolution: float = setting(
        10.0, section="tracker", label="lost grid resolution", bounds=Range(1.0, 1e5),
        help="Side (m) of the cells of a lost track's grid.")
    births: str = setting(
        "edges", section="tracker", label="tracker births", choices=lambda: _births(),
        noun="births",
        help="A multi-target tracker's model of where targets are born: edges (on the map's "
             "boundary), uniform (anywhere) or none.")
    birth_velocity: str = setting(
        "isotropic", section="tracker", label="birth velocity", choices=BIRTH_VELOCITIES,
        noun="birth velocity",
        help="The PMB tracker's velocity prior of a target it detects for the first time: "
             "isotropic (mean zero, the scenario's speeds in any direction) or inward (with "
             "edges births, a target first seen on the map's boundary heading inward at the "
             "scenario's speeds, as edge births do).")
    map_edge: str = setting(
        "scenario", section="tracker", label="map edge", choices=MAP_EDGE_CHOICES,
        noun="map edge",
        help="What a multi-target tracker assumes of a target that reaches the map's edge: "
             "exit (it leaves and is gone, so a track predicted off the map loses "
             "existence), closed (it turns back, so a track is reflected back in and keeps "
             "its existence) or scenario (exit when the scenario's targets are born at the "
             "edges or scripted, closed when its walls turn them back).")
    bernoulli_model: str = setting(
        "cv", section="tracker", label="Bernoulli model", choices=TRACKER_MODELS,
        noun="Bernoulli model",
        help="The motion model of each PMB track: cv (one constant-velocity model with q = "
             "process_noise) or imm (interacting multiple models: CWNA modes with the q's of "
             "mode_process_noise and Markov switching, mixed in every track).")
    edge_exit: str = setting(
        "outside", section="tracker", label="edge exit", choices=EDGE_EXITS,
        noun="edge exit",
        help="With an exit edge, what the PMB tracker's track near the edge loses of its "
             "existence in a step: outside (its predicted density's mass off the map) or "
             "crossing (the probability that a target on the map at the step's start "
             "crosses the edge during it; the part of the density already off the map is "
             "where no live target is, and is not charged again; the search preset's).")
    birth_rate: float = setting(
        0.02, section="tracker", label="tracker birth rate", bounds=Range(0.0, 100.0),
        help="A multi-target tracker's expected number of births per step over the map.")
    background_birth_rate: float = setting(
        0.0, section="tracker", label="background birth rate", bounds=Range(0.0, 100.0),
        help="The PMB tracker's expected births per step spread evenly over the map on top "
             "of its births: its allowance for targets where its birth model puts none, "
             "chiefly a target whose track it lost, so that a detection anywhere can start a "
             "track and search looks return to places not looked at lately (0: none).")
    survival_probability: float = setting(
        0.99, section="tracker", label="tracker survival",
        bounds=Range(0.0, 1.0, lo_open=True),
        help="A multi-target tracker's probability that a target survives a step.")
    established_survival: float = setting(
        0.0, section="tracker", label="established survival",
        bounds=Range(0.0, 1.0),
        help="The PMB tracker's probability that the target of an established track (one "
             "whose probability of existence has once reached established_existence, so "
             "seldom one that clutter started) survives a step, which can then be nearer "
             "the targets' own while survival_probability also clears clutter's tracks; "
             "below 1, as at 1 a track at existence 1 never loses it to missed looks (0: "
             "every track survives with survival_probability).")
    established_existence: float = setting(
        0.99, section="tracker", label="established existence",
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        help="The probability of existence at which a PMB track becomes established (see "
             "established_survival).")
    report_threshold: float = setting(
        0.5, section="tracker", label="report threshold",
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        help="A multi-target tracker reports (and plans on) the tracks whose probability of "
             "existence is at least this.")
    prune_threshold: float = setting(
        1e-3, section="tracker", label="prune threshold",
        bounds=Range(0.0, 1.0, hi_open=True),
        help="A multi-target tracker forgets the tracks whose probability of existence falls "
             "below this.")
    recycle_threshold: float = setting(
        0.0, section="tracker", label="recycle threshold",
        bounds=Range(0.0, 1.0, hi_open=True),
        help="The PMB tracker turns a track whose probability of existence falls below this "
             "into undetected intensity where it was instead of forgetting it (0: off; else "
             "at least prune_threshold and below report_threshold).")
    recycle_motion: str = setting(
        "static", section="tracker", label="recycle motion", choices=RECYCLE_MOTIONS,
        noun="recycle motion",
        help="What a recycled PMB track becomes: static (its existence on the grid's cells "
             "where it was) or moving (a Gaussian part of the undetected intensity that "
             "moves as targets do until it spreads over more than a cell; needs recycling "
             "on and the cv Bernoulli model).")
    split_existence: float = setting(
        0.0, section="tracker", label="split existence", bounds=Range(0.0, 0.5),
        help="The PMB tracker keeps a track's missed and detected hypotheses after a look as "
             "two tracks, instead of merging them into one, when each holds at least this "
             "probability of existence, so a stray detection does not pull the whole track "
             "off its target (0: off, merge always, as every preset does; else at least "
             "prune_threshold, and the cv Bernoulli model).")
    density_components: int = setting(
        1, section="tracker", label="density components", bounds=Range(1, 8),
        help="The Gaussian components each PMB track's density keeps after a look: 1 merges "
             "its missed and detected hypotheses into one Gaussian (every preset but search, "
             "which keeps 2); more keeps "
             "that many within the one track, merging the pairs that lose least (Runnalls' "
             "cost), so a detection that is not its target's moves weight between them "
             "instead of the whole track (the cv Bernoulli model, split_existence 0, "
             "recycle_motion static).")
    planning_threshold: float = setting(
        0.1, section="tracker", label="planning threshold",
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
        help="The PMB tracker's planning sees every track whose probability of existence is "
             "at least the smaller of this and report_threshold, weighted by its existence, "
             "so a track below the report threshold can still be looked at.")
    termination_threshold: float = setting(
        1.0, section="tracker", label="termination threshold",
        bounds=Range(0.0, 1.0, lo_open=True),
        help="The PMB tracker keeps reporting a confirmed track (one whose probability of "
             "existence reached report_threshold) while its existence is at least the "
             "smaller of this and report_threshold, as radar trackers confirm and terminate "
             "tracks on their existence (1: no hysteresis).")
    grid_resolution: float = setting(
        25.0, section="tracker", label="grid resolution", bounds=Range(1.0, 1e5),
        help="Side (m) of the map cells on which a multi-target tracker keeps the expected "
             "number of targets not yet detected (the GNN tracker: from which it starts a "
             "track).")
    confirm_hits: int = setting(
        2, section="tracker", label="confirm hits", bounds=Range(1, 100),
        help="The GNN tracker confirms a tentative track at this many hits within its first "
             "confirm_looks looks at it (at most confirm_looks).")
    confirm_looks: int = setting(
        3, section="tracker", label="confirm looks", bounds=Range(1, 100),
        help="The looks at a tentative track within which the GNN tracker needs confirm_hits "
             "hits, or deletes it.")
    delete_misses: int = setting(
        5, section="tracker", label="delete misses", bounds=Range(1, 1000),
        help="The GNN tracker deletes a track after this many consecutive missed looks at it "
             "(a look whose sensing region holds its predicted position, in sight).")

    def __post_init__(self) -> None:
        check_fields(self)
        if len(self.switching) != len(self.mode_process_noise):
            raise ConfigError("switching", f"must have one row per mode "
                              f"({len(self.mode_process_noise)}), got {len(self.switching)}")
        if self.confirm_hits > self.confirm_looks:
            raise ConfigError("confirm_hits", f"must be at most confirm_looks "
                              f"({self.confirm_looks}), got {self.confirm_hits}")
        if self.recycle_threshold > 0.0 and not (
                self.prune_threshold <= self.recycle_threshold < self.report_threshold):
            raise ConfigError("recycle_threshold", f"must be 0 (off) or at least "
                              f"prune_threshold ({self.prune_threshold}) and below "
                              f"report_threshold ({self.report_threshold}), got "
                              f"{self.recycle_threshold}")
        if self.recycle_motion == "moving" and (self.recycle_threshold == 0.0
                                                or self.bernoulli_model != "cv"):
            raise ConfigError("recycle_motion", f"moving needs recycling on (recycle_threshold "
                              f"> 0, got {self.recycle_threshold}) and bernoulli_model = "
                              f"\"cv\" (got \"{self.bernoulli_model}\")")
        if self.split_existence > 0.0 and (self.split_existence < self.prune_threshold
                                           or self.bernoulli_model != "cv"):
            raise ConfigError("split_existence", f"must be 0 (off) or at least "
                              f"prune_threshold ({self.prune_threshold}) with "
                              f"bernoulli_model = \"cv\" (got {self.split_existence} and "
                              f"\"{self.bernoulli_model}\")")
        if self.density_components > 1 and (self.bernoulli_model != "cv"
                                            or self.split_existence > 0.0
                                            or self.recycle_motion != "static"):
            raise ConfigError("density_components", f"more than 1 needs bernoulli_model = "
                              f"\"cv\", split_existence = 0 and recycle_motion = "
                              f"\"static\" (got \"{self.bernoulli_model}\", "
                              f"{self.split_existence} and \"{self.recycle_motion}\"); set "
                              f"density_components = 1 for the others")
        if self.birth_velocity == "inward" and self.births != "edges":
            raise ConfigError("birth_velocity", f"inward needs births = \"edges\" (targets "
                              f"born on the map's boundary), got births = "
                              f"\"{self.births}\"")
        if self.reacquire and not self.gate:
            raise ConfigError("reacquire", "needs gate = true (a detection outside the gate "
                              "triggers it)")

    def unused(self, edge: str | None = None) -> tuple[str, ...]:
        """The settings that change nothing with the others as they are: the cv filter's q
        (``process_noise``) with the IMM, the IMM's q's and switching with cv, the gate
        probability without the gate, a multi-target tracker's settings with the tracker of
        known targets, that tracker's with a multi-target one, the PMB's and the GNN's
        own settings with the other, and ``edge_exit`` where the map's edge is ``edge =
        "closed"`` (the edge the tracker resolved ``map_edge`` to for its scenario; None:
        not known). (A run's header leaves them out.)"""
        if self.kind != "known":               # a multi-target tracker: cv, its own births
            out = ("miss_update", "model", "mode_process_noise", "switching", "gate",
                   "reacquire", "association", "known_map", "known_buildings",
                   "reflect_walls", *LOST_SETTINGS, "lost_mode") + (
                       PMB_SETTINGS if self.kind == "gnn" else GNN_SETTINGS)
            if self.kind == "pmb" and edge == "closed":
                out += ("edge_exit",)
            if self.kind == "pmb" and self.bernoulli_model == "imm":
                # The IMM's q's and switching are read; the single model's q is not.
                out = tuple(k for k in out if k not in ("mode_process_noise", "switching"))
                out += ("process_noise",)
            return out
        out = ("process_noise",) if self.model == "imm" else ("mode_process_noise",
                                                              "switching")
        return out + (() if self.gate else ("gate_probability",)) + (
            () if self.lost_mode else LOST_SETTINGS) + MULTI_TARGET_SETTINGS

    def bernoulli_options(self) -> dict[str, Any]:
        """The IMM keyword arguments of :class:`sensorplan.tracking.pmb.tracker.PMBTracker`
        for these settings (none for ``bernoulli_model = "cv"``)."""
        import numpy as np

        if self.bernoulli_model != "imm":
            return {}
        return dict(mode_process_noise=self.mode_process_noise,
                    switching=np.array(self.switching))

    def tracker_options(self) -> dict[str, Any]:
        """Keyword arguments of :class:`sensorplan.tracking.tracker.KnownTargetTracker` for
        these settings."""
        import numpy as np

        imm = self.model == "imm"
        return dict(process_noise=self.process_noise,
                    mode_process_noise=self.mode_process_noise if imm else None,
                    switching=np.array(self.switching) if imm else None,
                    gate_probability=self.gate_probability if self.gate else None,
                    reacquire=self.reacquire, association=self.association,
                    known_buildings=self.known_buildings, reflect_walls=self.reflect_walls,
                    lost_probability=self.lost_probability)


@dataclass(frozen=True)
class RunSettings(_Settings):
    """How one closed-loop run plans, executes and tracks (see the module docstring).

    Attributes
    ----------
    planner : str                  a planner name or ``package.module:Class``
                                   (:func:`sensorplan.planners.make_planner`)
    planner_params : dict          the planner's settings, e.g. ``{"alpha": 0.3}``: exactly
                                   the fields the planner's class has
    horizon : int                  K, epochs per plan (>= 1)
    steps_per_epoch : int          e, simulation steps per epoch (>= 1)
    execution : {"ol", "olf"}      ``ol`` executes all K epochs before replanning, ``olf``
                                   only the first
    visibility : {"probabilistic", "mean"}
    objective : {"cumulative", "terminal"}  summed over the horizon (default) or at its end
    planning_detection : {"aware", "ignore"}
    planning_occlusion : {"aware", "ignore"}
    search : {"off", "on"}         plan search looks (needs ``tracker.kind = "pmb"``)
    search_sectors : int or tuple of int
                                   search sectors of every sensor, or one per sensor (> 0
                                   with search on)
    reward : {"auto", "information", "gospa"}
                                   what planning with search on maximises: information
                                   plus the value of targets found, or the reduction of
                                   the expected GOSPA bound (cut-off ``gospa_c``);
                                   ``auto`` (default) becomes ``gospa`` with search on,
                                   ``information`` with search off
    unreported : {"localise", "confirm"}
                                   how the ``gospa`` reward values a planned track the
                                   tracker does not report: by its covariance, or as a
                                   target to find (no effect on the ``information`` reward)
    find_tail : int                steps after the horizon over which the ``gospa``
                                   reward still counts a find (>= 0; default 0: none)
    track_existence : {"fixed", "resolved"}
                                   whether the ``gospa`` reward values what a look tells
                                   about a reported track's existence (``resolved``) or
                                   only how it shrinks its covariance (``fixed``, default)
    steps : int                    simulation steps S (>= 1)
    gospa_c : float                GOSPA cut-off c (m, > 0) of the run's set metrics
    tracker : TrackerSettings      (a mapping is accepted and converted)

    Raises
    ------
    ConfigError
        A value breaks its rule, the planner is unknown, or ``planner_params`` has a key
        the planner does not take or a value it rejects (``planner_params.<key>``).
    """

    planner: str = setting(
        "pg", section="planning", cli=("--planner",), metavar="NAME", noun="planner",
        brief="Planner: a name or package.module:Class",
        names=builtin_planners, check=known_planner,
        help="Planner that chooses the sensors' moves and looks: a planner name or "
             "package.module:Class.")
    planner_params: Mapping[str, Any] = setting(
        section="planning", default_factory=dict, label="planner settings",
        help="Settings of the planner: its constructor's keyword arguments (an unknown key "
             "is an error).")
    horizon: int = setting(
        1, section="planning", cli=("--horizon", "-K"), metavar="K", label="K",
        brief="Planning horizon in epochs (1 = myopic)",
        bounds=Range(1, MAX_PLAN_STEPS),
        help="Planning horizon in epochs (1 = myopic).")
    steps_per_epoch: int = setting(
        1, section="planning", cli=("--steps-per-epoch", "-e"), metavar="E", label="e",
        brief="Simulation steps per epoch: a decision every E steps",
        bounds=Range(1, MAX_PLAN_STEPS),
        help="Simulation steps per epoch: a decision every E steps.")
    execution: str = setting(
        "olf", section="planning", cli=("--execution",), metavar="MODE",
        brief="Replan after all K epochs (ol) or after the first (olf)",
        choices=EXECUTIONS, noun="execution mode",
        help="ol: execute all K epochs of a plan, then replan; olf: execute the first epoch, "
             "then replan (rolling horizon).")
    visibility: str = setting(
        "probabilistic", section="planning", cli=("--visibility",), metavar="MODE",
        brief="Planned looks count: probabilistic (by their chance of a view) or mean (iff "
              "the mean is seen)",
        choices=VISIBILITY_MODES, noun="visibility mode",
        help="Which planned looks count in the planning objective: probabilistic (weighted "
             "by the chance the target is in view) or mean (the paper's: iff the predicted "
             "mean is in view).")
    objective: str = setting(
        "cumulative", section="planning", cli=("--objective",), metavar="NAME",
        brief="Information summed over the horizon (cumulative) or at its end (terminal, "
              "the paper's)",
        choices=OBJECTIVES, noun="objective",
        help="cumulative (information summed over the horizon's steps; the default, chosen "
             "by the lookahead map in docs/results.md) or terminal (at the horizon's end, "
             "the paper's).")
    planning_detection: str = setting(
        "aware", section="planning", cli=("--planning-detection",), metavar="MODE",
        brief="Planning counts detection and clutter (aware) or not (ignore)",
        label="detection in planning", choices=PLANNING_DETECTIONS, noun="planning detection",
        help="aware: a planned look's information counts its detection probability and the "
             "clutter (no change for ideal sensors without false alarms); ignore: only "
             "whether the target is in view.")
    planning_occlusion: str = setting(
        "aware", section="planning", cli=("--planning-occlusion",), metavar="MODE",
        brief="Planning counts buildings that hide targets (aware) or not (ignore)",
        label="occlusion in planning", choices=PLANNING_OCCLUSIONS, noun="planning occlusion",
        help="aware: a planned look counts with the probability that no building hides the "
             "target (no change without buildings); ignore: the planner does not know the "
             "buildings.")
    search: str = setting(
        "off", section="planning", cli=("--search",), metavar="MODE",
        brief="Plan search looks for targets not yet tracked: off or on (needs --tracker pmb "
              "and --search-sectors)",
        choices=SEARCH_MODES, noun="search mode",
        help="off: looks point at tracks only; on: a look may also point at a search sector, "
             "and the planning objective adds the expected number of undetected targets the "
             "plan finds, each worth the information of its first detection (needs "
             "tracker.kind = pmb, whose undetected intensity says where they may be).")
    search_sectors: int | tuple[int, ...] = setting(
        0, section="planning", cli=("--search-sectors",), metavar="S", label="search sectors",
        brief="Search sectors of every sensor with --search on (> 0)",
        check=_sector_counts,
        help="Search sectors with search on: one number for every sensor, or (in files) a "
             "list with one per sensor; S sectors are S absolute bearings equally spaced "
             "around the platform (each > 0 with search on; the search preset sets 6, "
             "which its radar's 60-degree beam tiles the circle with).")
    reward: str = setting(
        "auto", section="planning", cli=("--reward",), metavar="NAME",
        brief="Plan for the GOSPA bound (gospa) or information; auto: gospa with --search "
              "on",
        choices=("auto", *REWARDS), noun="reward",
        help="What planning maximises: gospa (how much the plan lowers the expected GOSPA "
             "bound with cut-off --gospa-c: c^2/2 per missed target, min(tr P, c^2) per "
             "tracked one; needs --search on) or information (the tracks' information, "
             "plus with search on the value of the targets found); auto, the default, is "
             "gospa with search on and information with search off.")
    unreported: str = setting(
        "localise", section="planning", cli=("--unreported",), metavar="MODE",
        brief="How the gospa reward values a planned track below the report threshold: "
              "localise or confirm",
        choices=UNREPORTED_MODES, noun="unreported mode",
        help="How the gospa reward values a track planning sees but the tracker does not "
             "report (existence between planning_threshold and report_threshold): localise "
             "(default) as a reported one, by how much the plan shrinks its covariance; "
             "confirm as a target to find, its existence times the chance that the plan's "
             "looks detect it at its predicted mean times the bound a find removes (a "
             "missed target's c^2/2 less a first detection's), since unreported it costs a "
             "missed target whatever its covariance (the information reward weighs every "
             "track by its existence, reported or not, whichever this is).")
    find_tail: int = setting(
        0, section="planning", cli=("--find-tail",), metavar="L", label="find tail",
        bounds=Range(0, MAX_STEPS),
        brief="Steps after the horizon over which the gospa reward still counts a find "
              "(0: none)",
        help="Steps after the planning horizon over which the gospa reward still counts a "
             "find (a target found, or a track not reported confirmed), each weighted by the "
             "chance it survives; a target not found now stays missed until search finds "
             "it, while the next look at a track restores its covariance, so a track's "
             "reduction counts over the horizon only (0, the default: the bound over the "
             "horizon alone; needs reward gospa).")
    track_existence: str = setting(
        "fixed", section="planning", cli=("--track-existence",), metavar="MODE",
        brief="What a look does to a reported track's existence in the gospa reward: "
              "fixed or resolved",
        choices=TRACK_EXISTENCE_MODES, noun="track existence mode",
        help="What a look does to a reported track in the gospa reward: fixed (default) "
             "shrinks its covariance, its existence taken as it is; resolved also tells "
             "whether it exists: every look whose beam covers the track's predicted mean "
             "detects it or lowers its existence, and a track whose existence falls far "
             "enough costs less not reported, so the reward counts how much the expected "
             "bound under the better report decision drops (most for tracks near that "
             "point; needs reward gospa).")
    steps: int = setting(
        100, section="run", cli=("--steps", "-n"), metavar="N", bounds=Range(1, MAX_STEPS),
        brief="Simulation steps of the run",
        help="Simulation steps of the run.")
    gospa_c: float = setting(
        50.0, section="run", cli=("--gospa-c",), metavar="C", label="GOSPA c",
        bounds=Range(0.0, 1e7, lo_open=True),
        brief="GOSPA cut-off distance c (m) of the run's set metrics (williams15 and "
              "vo12 set 10 and 100)",
        help="Cut-off distance c (m) of GOSPA (alpha = 2, p = 2), beyond which a track is "
             "false and a target missed; presets may set their own (williams15: 10, vo12: "
             "100).")
    tracker: TrackerSettings = field(default_factory=TrackerSettings)

    def __post_init__(self) -> None:
        if self.reward == "auto":
            # The GOSPA-bound reward beat the information reward with search on, myopic
            # and K = 3 alike (docs/results.md, section 15.3); without search only
            # information is defined.
            object.__setattr__(self, "reward",
                               "gospa" if self.search == "on" else "information")
        if _TRUSTED.get():
            check_fields(self, unchecked=("planner",))
            return
        check_fields(self)
        self._check_search()
        # Checking the settings instantiates the planner once: bad values show now, not
        # mid-study.
        from ..planners.registry import check_settings

        object.__setattr__(self, "planner_params", check_settings(
            self.planner, self.planner_params, "planner_params", keep_none=True))

    def _check_search(self) -> None:
        """Search on needs a tracker that keeps an undetected intensity, and sectors; the
        gospa reward needs search on."""
        if self.track_existence != "fixed" and self.reward != "gospa":
            raise ConfigError("track_existence", f"'resolved' is a term of the 'gospa' "
                              f"reward (with search on), got reward {self.reward!r}; leave "
                              f"it 'fixed'")
        if self.find_tail and self.reward != "gospa":
            raise ConfigError("find_tail", f"counts finds in the 'gospa' reward only (with "
                              f"search on), got reward {self.reward!r}; leave it 0")
        if self.search != "on":
            if self.reward == "gospa":
                raise ConfigError("reward", "'gospa' needs search = 'on' (with search off "
                                  "use reward 'information')")
            return
        if self.tracker.kind != "pmb":
            raise ConfigError("search", f"needs a tracker that keeps the intensity of "
                              f"undetected targets (tracker.kind = 'pmb'), got "
                              f"{self.tracker.kind!r}; or turn search off (search = 'off')")
        if min(sector_counts(self.search_sectors, 1)) < 1:
            raise ConfigError("search_sectors", "must be > 0 with search on (the number of "
                              "bearings a search look may point at)")
        from ..planners.base import search_planner_names
        from ..planners.registry import planner_class

        if getattr(planner_class(self.planner), "plans_search", False) is not True:
            raise ConfigError("search", f"planner {self.planner!r} does not plan search "
                              f"looks; choose one that does ({', '.join(search_planner_names())}) "
                              "or search = 'off'")


def all_settings(cls: type = RunSettings, prefix: str = ""
                 ) -> list[tuple[type, str, dataclasses.Field[Any], Setting]]:
    """Every declared setting as ``(settings class, path, field, Setting)``, in declaration
    order, with paths dotted through nested groups (``tracker.miss_update``)."""
    out: list[tuple[type, str, dataclasses.Field[Any], Setting]] = []
    for f in dataclasses.fields(cls):
        tp = field_type(cls, f.name)
        if is_group(tp):
            out += all_settings(tp, f"{prefix}{f.name}.")
        elif "setting" in f.metadata:
            out.append((cls, prefix + f.name, f, f.metadata["setting"]))
    return out


def limit_fields(path: Callable[[str, Setting], str], **structure: str) -> dict[str, str]:
    """The field names for the size limits' errors (:func:`sensorplan.limits.check_run`):
    each setting they read (:data:`sensorplan.limits.SIZE_SETTINGS`) as the caller's input
    spells it, ``path(key, setting)``, plus the input's own ``structure`` (``targets``,
    ``sensors``, ``moves``)."""
    return {**{p: path(p, s) for _, p, _, s in all_settings() if p in SIZE_SETTINGS},
            **structure}


def default_of(f: dataclasses.Field[Any]) -> Any:
    """A field's default value (calling its factory)."""
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return f.default
