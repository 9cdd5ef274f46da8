r"""GOSPA and the set metrics of a multi-target tracker, computed from arrays.

A multi-target tracker reports a set of labelled tracks at each step; the truth is a set of
live targets with identities. This module scores one against the other:

- :func:`gospa` is the generalised optimal sub-pattern assignment distance (GOSPA, with
  alpha = 2) between two point sets of one step, split into its localisation, missed and
  false parts;
- :func:`gospa_over_time` is the same for many steps at once, from padded arrays and masks;
- :func:`target_metrics` gives, per target and from its assignments step by step, the
  steps from birth to the first report, the label switches and the longest stretch without
  a track (a target without one for 20 steps or more is *lost*);
- :func:`set_metrics` takes a run's long tables (one row per (step, target) and one per
  (step, track)), assigns the tracks as GOSPA does and returns all of the above plus the
  false tracks per step.

Everything is numpy and :func:`scipy.optimize.linear_sum_assignment`; the only Python loop
runs over steps, one assignment problem each, and skips steps with no target or no track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from .._types import BoolArray, FloatArray, IntArray

if TYPE_CHECKING:  # pragma: no cover
    from ..simulation.episode import Episode

#: A live target unassigned for this many consecutive steps or more is lost.
LOST_STEPS = 20
#: Cost-matrix entries built at once by :func:`gospa_over_time`: 2**15 float64 (256 KiB)
#: keep the temporaries in cache; 16 MiB chunks were 30 % slower.
_CHUNK_ENTRIES = 1 << 15


@dataclass(frozen=True)
class Gospa:
    """GOSPA (alpha = 2) of one step and its parts.

    The parts are contributions to the p-th power of the distance, so
    ``distance ** p == localisation + missed + false`` (up to round-off).

    Attributes
    ----------
    distance : float    GOSPA distance (units of the positions, e.g. m)
    localisation : float    sum of ``d ** p`` over assigned pairs (d < c)
    missed : float    ``c ** p / 2`` per target without a track
    false : float    ``c ** p / 2`` per track without a target
    assignment : (n,) int64    track index of each target, -1 if missed
    """

    distance: float
    localisation: float
    missed: float
    false: float
    assignment: IntArray


@dataclass(frozen=True)
class GospaSeries:
    """:class:`Gospa` of each of S steps: its fields with a leading step axis, ``(S,)``
    float64 and ``assignment (S, n_max)`` int64 (track slot of each target slot, -1 also
    where the slot holds no live target); step ``t`` is :meth:`step`."""

    distance: FloatArray
    localisation: FloatArray
    missed: FloatArray
    false: FloatArray
    assignment: IntArray

    def step(self, t: int) -> Gospa:
        """The :class:`Gospa` of step ``t`` (its target slots as its ``assignment``)."""
        return Gospa(float(self.distance[t]), float(self.localisation[t]),
                     float(self.missed[t]), float(self.false[t]), self.assignment[t])


def gospa(truth_xy: npt.ArrayLike, track_xy: npt.ArrayLike, c: float, p: float = 2.0,
          alpha: float = 2.0) -> Gospa:
    r"""GOSPA distance between the true and the reported positions of one step.

    With the cut-off distance :math:`d^{(c)}(x, y) = \min(\lVert x - y \rVert_2, c)` and
    :math:`\gamma` ranging over the partial assignments (sets of disjoint pairs
    :math:`(i, j)` of a target :math:`x_i \in X` and a track :math:`y_j \in Y`),

    .. math::

        \mathrm{GOSPA}_p^{(c, 2)}(X, Y) = \Bigl( \min_{\gamma} \sum_{(i, j) \in \gamma}
            d^{(c)}(x_i, y_j)^p + \frac{c^p}{2} \bigl(|X| + |Y| - 2 |\gamma|\bigr)
            \Bigr)^{1/p}.

    A pair at distance :math:`\geq c` costs :math:`c^p`, the same as leaving both ends
    unassigned, so the value does not depend on which of the two an optimal assignment
    chooses; such pairs are reported as one missed target and one false track. The parts
    are contributions to the p-th power of the distance, as García-Fernández, Rahmathullah
    and Svensson (2017) and Stone Soup's ``GOSPAMetric`` report them:

    .. math::

        L = \sum_{(i, j) \in \gamma,\ d < c} d(x_i, y_j)^p, \qquad
        M = \frac{c^p}{2} (|X| - k), \qquad F = \frac{c^p}{2} (|Y| - k),

    with :math:`k` the number of pairs at distance below :math:`c`, and
    :math:`\mathrm{GOSPA} = (L + M + F)^{1/p}`.

    Parameters
    ----------
    truth_xy : (n, d) float    positions of the live targets (m); n may be 0
    track_xy : (m, d) float    positions of the reported tracks (m); m may be 0
    c : float    cut-off distance (m), > 0
    p : float    order, >= 1
    alpha : float    must be 2: the only alpha with a localisation/missed/false split

    Returns
    -------
    Gospa
        The distance (m), its parts (m^p) and the assignment ((n,) track index, -1).

    Raises
    ------
    ValueError
        On ``c <= 0``, ``p < 1``, ``alpha != 2``, arrays that are not (k, d) with the same
        d, or a non-finite position.

    Examples
    --------
    >>> g = gospa([[0.0, 0.0], [100.0, 0.0]], [[3.0, 4.0]], c=10.0)
    >>> float(g.distance), float(g.localisation), float(g.missed), float(g.false)
    (8.660254037844387, 25.0, 50.0, 0.0)
    >>> g.assignment.tolist()
    [0, -1]
    """
    if alpha != 2:
        raise ValueError(f"alpha: only alpha = 2 is supported, got {alpha!r}")
    truth = _points(truth_xy, "truth_xy")
    track = _points(track_xy, "track_xy")
    d = _dimension(truth, track, "truth_xy", "track_xy")
    truth, track = truth.reshape(len(truth), d), track.reshape(len(track), d)
    series = gospa_over_time(truth[None], np.ones((1, len(truth)), bool), track[None],
                             np.ones((1, len(track)), bool), c, p)
    return series.step(0)


def gospa_over_time(truth_xy: npt.ArrayLike, truth_alive: npt.ArrayLike,
                    track_xy: npt.ArrayLike, track_present: npt.ArrayLike, c: float,
                    p: float = 2.0) -> GospaSeries:
    """GOSPA (alpha = 2) of each of S steps, from padded arrays; see :func:`gospa`.

    Each step's value equals :func:`gospa` of that step's live targets and present tracks,
    in slot order, bit for bit. Positions in slots that the masks leave out are ignored
    (they may be NaN).

    Parameters
    ----------
    truth_xy : (S, n_max, d) float    target positions (m)
    truth_alive : (S, n_max) bool    which target slots hold a live target
    track_xy : (S, m_max, d) float    track positions (m)
    track_present : (S, m_max) bool    which track slots hold a reported track
    c : float    cut-off distance (m), > 0
    p : float    order, >= 1

    Returns
    -------
    GospaSeries
        (S,) distance (m) and parts (m^p); (S, n_max) track slot per target slot, -1.

    Raises
    ------
    ValueError
        On ``c <= 0``, ``p < 1``, a mask that is not boolean or does not match its
        positions, different S or d, or a non-finite live position.

    Notes
    -----
    Every step is an assignment problem on ``min(d^p, c^p)`` between its live targets and
    present tracks: a rectangular assignment of all of the smaller set on these capped
    costs has the same optimum as the partial assignment of the definition, since a capped
    pair costs what its two unassigned ends cost. The cost matrices are built for many steps
    at once (live slots first); only the solver runs step by step, on the live block.
    """
    cp, p = _check_c_p(c, p)
    truth, alive = _padded(truth_xy, truth_alive, "truth_xy", "truth_alive")
    track, present = _padded(track_xy, track_present, "track_xy", "track_present")
    if track.shape[1] == 0:                 # one empty slot keeps the indexing below valid
        track, present = np.zeros(track.shape[:1] + (1,) + track.shape[2:]), \
            np.zeros((len(track), 1), dtype=bool)
    if len(track) != len(truth):
        raise ValueError(f"track_xy: {len(track)} steps, truth_xy has {len(truth)}")
    if truth.shape[2] != track.shape[2]:
        raise ValueError(f"track_xy: {track.shape[2]} coordinates per point, truth_xy has "
                         f"{truth.shape[2]}")
    truth, t_order = _live_first(truth, alive)
    track, y_order = _live_first(track, present)
    n, m = alive.sum(axis=1), present.sum(axis=1)
    col = _solve_steps(truth, n, track, m, cp, p)
    # The chosen pairs' costs, recomputed with the arithmetic the solver saw.
    cost = _pair_cost(truth, np.take_along_axis(track, np.maximum(col, 0)[None], axis=2), p)
    col[(col >= 0) & ~(cost < cp)] = -1             # capped pairs: a miss and a false track
    k = (col >= 0).sum(axis=1)
    localisation = _sequential_sum(np.where(col >= 0, cost, 0.0))
    missed = 0.5 * cp * (n - k)
    false = 0.5 * cp * (m - k)
    total = localisation + missed + false
    distance = np.sqrt(total) if p == 2.0 else total ** (1.0 / p)
    # Back to the caller's slots.
    if y_order is not None:
        col = np.where(col >= 0, np.take_along_axis(y_order, np.maximum(col, 0), axis=1), -1)
    assignment = col
    if t_order is not None:
        assignment = np.empty_like(col)
        np.put_along_axis(assignment, t_order, col, axis=1)
    return GospaSeries(distance, localisation, missed, false, assignment)


def _live_first(xy: FloatArray, live: BoolArray) -> tuple[FloatArray, IntArray | None]:
    """Coordinate-major (d, S, k) positions, each step's live slots first in slot order.

    Also returns the (S, k) slot order, or None where the live slots already come first.
    """
    if np.all(live[:, 1:] <= live[:, :-1]):
        return np.ascontiguousarray(xy.transpose(2, 0, 1)), None
    order = np.argsort(~live, axis=1, kind="stable")
    return np.take_along_axis(xy.transpose(2, 0, 1), order[None], axis=2), order


def _solve_steps(truth: FloatArray, n: IntArray, track: FloatArray, m: IntArray, cp: float,
                 p: float) -> IntArray:
    """Optimal assignment of each step on capped costs.

    ``truth`` (d, S, n_max) and ``track`` (d, S, m_max) hold each step's live slots first;
    ``n``, ``m`` (S,) count them. Returns (S, n_max) int64: the track (compact index) of each
    compact target slot, -1.
    """
    steps, n_max = truth.shape[1:]
    col = np.full((steps, n_max), -1, dtype=np.int64)
    chunk = max(1, _CHUNK_ENTRIES // max(1, n_max * track.shape[2]))
    solve = np.flatnonzero((n > 0) & (m > 0))       # the others have nothing to assign
    for start in range(0, len(solve), chunk):
        which = solve[start:start + chunk]
        cost = _pair_cost(truth[:, which, :, None], track[:, which, None, :], p)
        np.minimum(cost, cp, out=cost)
        for i, (s, ns, ms) in enumerate(zip(which.tolist(), n[which].tolist(),
                                            m[which].tolist())):
            rows, cols = linear_sum_assignment(cost[i, :ns, :ms])
            col[s, rows] = cols
    return col


def _pair_cost(a: FloatArray, b: FloatArray, p: float) -> FloatArray:
    """``|a - b| ** p`` for coordinate-major points (coordinates on axis 0, the rest
    broadcast), one coordinate at a time.

    Summing coordinates in a fixed order makes each entry independent of the batch shape.
    """
    sq = np.subtract(a[0], b[0])
    np.multiply(sq, sq, out=sq)
    diff = np.empty_like(sq) if len(a) > 1 else sq
    for j in range(1, len(a)):
        np.subtract(a[j], b[j], out=diff)
        np.multiply(diff, diff, out=diff)
        sq += diff
    if p != 2.0:
        np.sqrt(sq, out=sq)
        sq **= p
    return sq


def _sequential_sum(a: FloatArray) -> FloatArray:
    """Sum over the last axis, left to right, so zeros anywhere leave it unchanged."""
    if a.shape[-1] == 0:
        return np.zeros(a.shape[:-1])
    return np.cumsum(a, axis=-1)[..., -1]


@dataclass(frozen=True)
class TargetMetrics:
    """Per-target metrics of one run; see :func:`target_metrics`.

    Attributes
    ----------
    ids : (U,) int64    the targets, sorted
    birth_step : (U,) int64    first step alive
    first_report_step : (U,) int64    first step with an assigned track, -1 if never
    report_delay : (U,) float64    steps from birth to first report, NaN if never
    label_switches : (U,) int64    label changes between successive assigned steps
    longest_unassigned : (U,) int64    longest run of consecutive live, unassigned steps
    lost : (U,) bool    ``longest_unassigned >= lost_steps``
    """

    ids: IntArray
    birth_step: IntArray
    first_report_step: IntArray
    report_delay: FloatArray
    label_switches: IntArray
    longest_unassigned: IntArray
    lost: BoolArray

    @property
    def targets_lost(self) -> int:
        """How many targets the run lost."""
        return int(self.lost.sum())

    @property
    def never_reported(self) -> int:
        """How many targets were never assigned a track."""
        return int((self.first_report_step < 0).sum())


def target_metrics(step: npt.ArrayLike, target_id: npt.ArrayLike, assigned: npt.ArrayLike,
                   label: npt.ArrayLike, lost_steps: int = LOST_STEPS) -> TargetMetrics:
    """Report delay, label switches and losses of each target, from its assignments.

    - The *report delay* is the number of steps from a target's birth (its first step in
      the table) to the first step it is assigned; a target never assigned has none (NaN).
    - A *label switch* is a change of the assigned label between one step at which the
      target is assigned and the next such step; unassigned steps in between are skipped.
    - A target is *lost* when it stays alive and unassigned for ``lost_steps`` or more
      consecutive steps; a step at which it is not in the table ends the stretch.

    Parameters
    ----------
    step : (R,) int    step of each row; one row per live (step, target)
    target_id : (R,) int    the target, unique within a step
    assigned : (R,) bool    a track is assigned to the target at that step
    label : (R,) int    the assigned track's label (ignored where not assigned)
    lost_steps : int    consecutive unassigned steps that make a target lost, >= 1

    Returns
    -------
    TargetMetrics
    """
    if isinstance(lost_steps, bool) or not isinstance(lost_steps, int | np.integer) \
            or lost_steps < 1:
        raise ValueError(f"lost_steps: must be an integer >= 1, got {lost_steps!r}")
    s = _int_column(step, "step")
    t = _int_column(target_id, "target_id", len(s))
    lab = _int_column(label, "label", len(s))
    a = np.asarray(assigned)
    if a.dtype != np.bool_ or a.shape != s.shape:
        raise ValueError(f"assigned: must be a boolean ({len(s)},) array, got {a.dtype} "
                         f"{a.shape}")
    order = np.lexsort((s, t))                           # by target, then step
    s, t, a, lab = s[order], t[order], a[order], lab[order]
    same = t[1:] == t[:-1]
    if np.any(same & (s[1:] == s[:-1])):
        i = int(np.argmax(same & (s[1:] == s[:-1])))
        raise ValueError(f"target_id: {t[i]} appears twice at step {s[i]}")
    starts = np.flatnonzero(np.append(True, ~same)) if len(t) else t
    ids = t[starts]
    never = np.iinfo(np.int64).max
    first = (np.minimum.reduceat(np.where(a, s, never), starts) if len(t) else t.copy())
    first[first == never] = -1
    birth = s[starts]
    # Switches: successive assigned rows of one target with different labels.
    ta, la = t[a], lab[a]
    change = (ta[1:] == ta[:-1]) & (la[1:] != la[:-1])
    switches = np.bincount(np.searchsorted(ids, ta[1:][change]), minlength=len(ids))
    # Runs of rows with the same target, consecutive steps and the same assigned state.
    new = np.append(True, ~same | (s[1:] != s[:-1] + 1) | (a[1:] != a[:-1]))
    run = np.flatnonzero(new) if len(t) else t
    length = np.diff(np.append(run, len(t)))
    gap = ~a[run]
    longest = np.zeros(len(ids), dtype=np.int64)
    np.maximum.at(longest, np.searchsorted(ids, t[run[gap]]), length[gap])
    return TargetMetrics(ids, birth, first, np.where(first >= 0, first - birth, np.nan),
                         switches.astype(np.int64), longest, longest >= lost_steps)


@dataclass(frozen=True)
class SetMetrics:
    """The set metrics of one run; see :func:`set_metrics`.

    Attributes
    ----------
    gospa : GospaSeries    (S,) GOSPA distance (m) and its parts (m^p) per step
    n_targets, n_tracks : (S,) int64    live targets, reported tracks per step
    false_tracks : (S,) int64    reported tracks assigned to no target
    assigned : (R,) bool    per target row (input order): a track is assigned within c
    label : (R,) int64    the assigned track's label; -1 where ``assigned`` is False
    track_assigned : (Q,) bool    per track row (input order): assigned to a target
    targets : TargetMetrics    report delay, label switches, losses per target
    """

    gospa: GospaSeries
    n_targets: IntArray
    n_tracks: IntArray
    false_tracks: IntArray
    assigned: BoolArray
    label: IntArray
    track_assigned: BoolArray
    targets: TargetMetrics

    @property
    def mean_gospa(self) -> float:
        """Mean GOSPA distance over the run's steps (m); NaN for a run of no step."""
        d = self.gospa.distance
        return float(d.mean()) if d.size else math.nan


def set_metrics(target_step: npt.ArrayLike, target_id: npt.ArrayLike,
                target_xy: npt.ArrayLike, track_step: npt.ArrayLike,
                track_label: npt.ArrayLike, track_xy: npt.ArrayLike, c: float, *,
                p: float = 2.0, lost_steps: int = LOST_STEPS,
                n_steps: int | None = None) -> SetMetrics:
    """Set metrics of one run from its long tables of live targets and reported tracks.

    At each step the reported tracks are assigned to the live targets as GOSPA assigns them
    (:func:`gospa`; a target counts as assigned only to a track closer than ``c``). A
    reported track assigned to no target is a *false track*; the per-target metrics follow
    from the assignments (:func:`target_metrics`).

    Parameters
    ----------
    target_step : (R,) int    step (0-based) of each target row
    target_id : (R,) int    identity of the target, unique within a step
    target_xy : (R, d) float    true position (m)
    track_step : (Q,) int    step of each track row
    track_label : (Q,) int    label of the track, unique within a step
    track_xy : (Q, d) float    reported position (m)
    c : float    GOSPA cut-off (m), > 0
    p : float    GOSPA order, >= 1
    lost_steps : int    consecutive unassigned steps that make a target lost, >= 1
    n_steps : int, optional    steps in the run (0 .. n_steps - 1); default: one past the
        last step in either table. Steps with no row score 0.

    Returns
    -------
    SetMetrics

    Raises
    ------
    ValueError
        On a bad ``c``, ``p``, ``lost_steps`` or ``n_steps``, columns of different lengths,
        negative or non-integer steps, a target or label twice in one step, or a
        non-finite position.
    """
    t_step = _int_column(target_step, "target_step")
    t_id = _int_column(target_id, "target_id", len(t_step))
    t_xy = _points(target_xy, "target_xy", len(t_step))
    y_step = _int_column(track_step, "track_step")
    y_label = _int_column(track_label, "track_label", len(y_step))
    y_xy = _points(track_xy, "track_xy", len(y_step))
    for steps, name in ((t_step, "target_step"), (y_step, "track_step")):
        if steps.size and steps.min() < 0:
            raise ValueError(f"{name}: steps must be >= 0, got {steps.min()}")
    last = max(t_step.max(initial=-1), y_step.max(initial=-1))
    if n_steps is None:
        n_steps = int(last) + 1
    elif isinstance(n_steps, bool) or not isinstance(n_steps, int | np.integer) \
            or n_steps <= last:
        raise ValueError(f"n_steps: must be an integer above the last step {last}, "
                         f"got {n_steps!r}")
    d = _dimension(t_xy, y_xy, "target_xy", "track_xy")
    t_rows, t_slot = _cells(t_step, t_id, n_steps, "target_id")
    y_rows, y_slot = _cells(y_step, y_label, n_steps, "track_label")
    series = gospa_over_time(_scatter(t_xy, t_step, t_slot, t_rows.shape, d), t_rows >= 0,
                             _scatter(y_xy, y_step, y_slot, y_rows.shape, d), y_rows >= 0, c, p)
    # Per target row: the track row assigned to it (-1).
    slot_of = series.assignment[t_step, t_slot]
    track_row = np.where(slot_of >= 0, y_rows[t_step, np.maximum(slot_of, 0)], -1)
    assigned = track_row >= 0
    label = np.full(len(t_step), -1, dtype=np.int64)
    label[assigned] = y_label[track_row[assigned]]
    track_assigned = np.zeros(len(y_step), dtype=bool)
    track_assigned[track_row[assigned]] = True
    n_tracks = np.bincount(y_step, minlength=n_steps)
    return SetMetrics(
        series, np.bincount(t_step, minlength=n_steps), n_tracks,
        n_tracks - np.bincount(y_step[track_assigned], minlength=n_steps), assigned, label,
        track_assigned, target_metrics(t_step, t_id, assigned, label, lost_steps))


def _cells(step: IntArray, key: IntArray, n_steps: int,
           name: str) -> tuple[IntArray, IntArray]:
    """Place a long table's rows in (step, slot) cells, slots in key order per step.

    Returns (n_steps, n_max >= 1) int64, the row of each cell (-1: empty), and (R,) the
    slot of each row.
    """
    # Tables are usually written sorted by (step, key); then no sort is needed.
    later = (step[1:] > step[:-1]) | ((step[1:] == step[:-1]) & (key[1:] > key[:-1]))
    order = np.arange(len(step)) if later.all() else np.lexsort((key, step))
    s, k = step[order], key[order]
    twice = (s[1:] == s[:-1]) & (k[1:] == k[:-1])
    if twice.any():
        i = int(np.argmax(twice))
        raise ValueError(f"{name}: {k[i]} appears twice at step {s[i]}")
    rank = np.arange(len(s)) - np.searchsorted(s, s, side="left")
    # At least one slot, so that a table without rows still indexes.
    rows = np.full((n_steps, max(1, int(rank.max(initial=-1)) + 1)), -1, dtype=np.int64)
    rows[s, rank] = order
    slot = np.empty(len(s), dtype=np.int64)
    slot[order] = rank
    return rows, slot


def _scatter(xy: FloatArray, step: IntArray, slot: IntArray, shape: tuple[int, ...],
             d: int) -> FloatArray:
    """(S, n_max, d) positions of a long table's rows in their cells; zeros elsewhere."""
    out = np.zeros(shape + (d,))
    out[step, slot] = xy.reshape(len(xy), d)
    return out


def _check_c_p(c: float, p: float) -> tuple[float, float]:
    """Validate the cut-off and the order; return ``(c ** p, p)`` as floats."""
    c, p = float(c), float(p)
    if not (math.isfinite(c) and c > 0):
        raise ValueError(f"c: the cut-off distance must be finite and > 0, got {c!r}")
    if not (math.isfinite(p) and p >= 1):
        raise ValueError(f"p: the order must be finite and >= 1, got {p!r}")
    return c ** p, p


def _points(xy: npt.ArrayLike, name: str, rows: int | None = None) -> FloatArray:
    """(k, d >= 1) float64 finite positions; an empty 1-D array is an empty set (0, 0)."""
    a = np.asarray(xy, dtype=np.float64)
    if a.ndim == 1 and a.size == 0:
        a = a.reshape(0, 0)
    if a.ndim != 2 or (len(a) and not a.shape[1]):
        raise ValueError(f"{name}: must be a (k, d) array of positions, d >= 1, got shape "
                         f"{a.shape}")
    if rows is not None and len(a) != rows:
        raise ValueError(f"{name}: {len(a)} rows, expected {rows}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: non-finite position in row "
                         f"{int(np.argmin(np.isfinite(a).all(axis=1)))}")
    return a


def _dimension(a: FloatArray, b: FloatArray, name_a: str, name_b: str) -> int:
    """The points' common dimension d; a (0, 0) set takes the other's (2 if both)."""
    if a.shape[1] and b.shape[1] and a.shape[1] != b.shape[1]:
        raise ValueError(f"{name_b}: {b.shape[1]} coordinates per row, {name_a} has "
                         f"{a.shape[1]}")
    return max(a.shape[1], b.shape[1]) or 2


def _padded(xy: npt.ArrayLike, mask: npt.ArrayLike, name: str,
            mask_name: str) -> tuple[FloatArray, BoolArray]:
    """(S, k, d) float64 positions, zero where masked out, and the (S, k) bool mask."""
    a = np.asarray(xy, dtype=np.float64)
    live = np.asarray(mask)
    if a.ndim != 3 or a.shape[2] == 0:
        raise ValueError(f"{name}: must be an (S, k, d) array, d >= 1, got shape {a.shape}")
    if live.dtype != np.bool_ or live.shape != a.shape[:2]:
        raise ValueError(f"{mask_name}: must be a boolean {a.shape[:2]} array, got "
                         f"{live.dtype} {live.shape}")
    bad = live & ~np.isfinite(a).all(axis=2)
    if bad.any():
        s, i = np.argwhere(bad)[0]
        raise ValueError(f"{name}: non-finite position at step {s}, slot {i}")
    return np.where(live[..., None], a, 0.0), live


def _int_column(x: npt.ArrayLike, name: str, rows: int | None = None) -> IntArray:
    """(R,) int64 column; integer dtypes only (an empty column may be of any dtype)."""
    a = np.asarray(x)
    if a.ndim != 1:
        raise ValueError(f"{name}: must be a 1-D column, got shape {a.shape}")
    if a.size and (a.dtype == np.bool_ or not np.issubdtype(a.dtype, np.integer)):
        raise ValueError(f"{name}: must hold integers, got {a.dtype}")
    if rows is not None and len(a) != rows:
        raise ValueError(f"{name}: {len(a)} rows, expected {rows}")
    return a.astype(np.int64, copy=False)


#: GOSPA's cut-off distance (m) unless a study or command sets it.
GOSPA_CUTOFF = 50.0


def episode_set_metrics(episode: Episode, c: float = GOSPA_CUTOFF) -> SetMetrics:
    """GOSPA (its localisation, missed and false parts) and the per-target set metrics of a
    run: the live targets' true positions against the tracker's reported tracks at every
    step (:func:`set_metrics`), steps 1..S.

    Returns
    -------
    SetMetrics
    """
    S1, M = episode.alive.shape
    steps, ids = np.nonzero(episode.alive)
    keep = (steps > 0)
    rows = episode.track_step > 0
    return set_metrics(steps[keep] - 1, ids[keep], episode.truth[steps[keep], ids[keep], :2],
                       episode.track_step[rows] - 1, episode.track_label[rows],
                       episode.track_mean[rows, :2], c, n_steps=S1 - 1)


def with_assigned_tracks(episode: Episode, c: float = GOSPA_CUTOFF) -> Episode:
    """The run with each live target's estimate, covariance, error and NEES those of the
    track GOSPA assigns to it at each step (NaN where none is within ``c``, and where the
    target is not alive), for a tracker whose tracks are not its targets (a multi-target
    tracker). A run of the tracker of known targets is returned as it is: track j is
    target j.
    """
    import dataclasses

    from ..tracking.ekf import nees

    if episode.settings.tracker.kind == "known":
        return episode
    S1, M = episode.alive.shape
    steps, ids = np.nonzero(episode.alive[1:])
    sm = episode_set_metrics(episode, c)
    estimate = np.full((S1, M, 4), np.nan)
    cov = np.full((S1, M, 4, 4), np.nan)
    rows = episode.track_step > 0
    t_step, t_label = episode.track_step[rows], episode.track_label[rows]
    # the track row of each assigned (step, label): both tables are step-major
    key = t_step * (int(t_label.max(initial=0)) + 1) + t_label
    order = np.argsort(key, kind="stable")
    ok = sm.assigned
    want = (steps[ok] + 1) * (int(t_label.max(initial=0)) + 1) + sm.label[ok]
    at = order[np.searchsorted(key[order], want)]
    estimate[steps[ok] + 1, ids[ok]] = episode.track_mean[rows][at]
    cov[steps[ok] + 1, ids[ok]] = episode.track_cov[rows][at]
    truth = episode.truth
    error = np.hypot(truth[..., 0] - estimate[..., 0], truth[..., 1] - estimate[..., 1])
    with np.errstate(invalid="ignore"):
        n = np.full((S1, M), np.nan)
        fin = np.isfinite(estimate[..., 0])
        n[fin] = nees(truth[fin], estimate[fin], cov[fin])
    return dataclasses.replace(episode, estimate=estimate, cov=cov, error=error, nees=n)
