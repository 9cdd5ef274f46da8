"""One planning decision: the problem value, plans, moves and reachable sets.

A :class:`PlanningProblem` holds everything a planner receives; a :class:`Plan` holds every
player's action as arrays ``positions (N, K, 2)``, ``targets (N, K)`` and ``sectors (N, K)``
(a look has a target or a search sector, the other is -1; both -1 and NaN positions for an
unassigned player).
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass, field
from collections.abc import Iterator
from typing import Any

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..errors import ConfigError
from ..limits import MAX_BUILDINGS, RANGES, check_count
from ..models.sensors import SensorParams
from .objective import (OBJECTIVES, PLANNING_DETECTIONS, REWARDS, SEARCH_MODES,  # noqa: F401
                        TRACK_EXISTENCE_MODES, VISIBILITY_MODES, Objective, Visibility)

#: The 8 lattice directions in move order.
DIRECTIONS = np.array([(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)],
                      dtype=float)
#: Positions closer than this (m) are the same position.
POSITION_TOL = 1e-6
#: Relative tolerance of ties between values of Phi: ``a`` beats ``b`` only if
#: ``a > b + TIE_TOL * max(1, |Phi|)`` (every planner and the decentralized agents use it).
TIE_TOL = 1e-9



def move_vectors(distances: tuple[float, ...] | list[float]) -> FloatArray:
    """The moves in order: stay, then ``s * d`` for each distance s and direction d.

    Returns
    -------
    (1 + 8 * len(distances), 2) float64; diagonal moves are ``s * sqrt(2)`` long.
    """
    if isinstance(distances, tuple):
        # A sensor's moves are the same at every decision: build them once (read-only).
        return _move_vectors_of(distances)
    return _move_vectors(distances)


def _move_vectors(distances: tuple[float, ...] | list[float]) -> FloatArray:
    out = [np.zeros((1, 2))] + [s * DIRECTIONS for s in distances]
    return np.concatenate(out, axis=0)


@functools.lru_cache(maxsize=64)
def _move_vectors_of(distances: tuple[float, ...]) -> FloatArray:
    moves = _move_vectors(distances)
    moves.flags.writeable = False
    return moves


@dataclass(frozen=True)
class MapRect:
    """The ground rectangle ``[0, width] x [0, height]`` (m); its edge is inside."""

    width: float = 600.0
    height: float = 600.0

    def contains(self, xy: FloatArray, tol: float = POSITION_TOL) -> np.ndarray:
        """Boolean mask of ground positions ``(..., 2)`` inside the closed map."""
        xy = np.asarray(xy, dtype=float)
        return ((xy[..., 0] >= -tol) & (xy[..., 0] <= self.width + tol)
                & (xy[..., 1] >= -tol) & (xy[..., 1] <= self.height + tol))

    def outside(self, xy: Any) -> str:
        """The message for a ground position ``(2,)`` outside the map: its value and the
        map's bounds, ``[700, 100] is outside the map [0, 600] x [0, 600] m``."""
        x, y = (float(v) for v in np.asarray(xy, dtype=float).ravel()[:2])
        return (f"[{x:g}, {y:g}] is outside the map [0, {self.width:g}] x "
                f"[0, {self.height:g}] m")


@dataclass(frozen=True)
class Lattice:
    """Reachable sets of one platform: ``R_0 .. R_K`` and the moves between them.

    Attributes
    ----------
    positions : list of (n_k, 2) arrays
        ``R_k`` in breadth-first order (parents in order, moves in order).
    parent_move : list of (n_k, n_moves) int arrays
        ``parent_move[k][p, m]``: index in ``R_{k-1}`` of ``R_k[p] - move_m``, or -1.
    child : list of (n_{k-1}, n_moves) int arrays
        ``child[k][q, m]``: index in ``R_k`` of ``R_{k-1}[q] + move_m``, or -1 if outside.
    """

    positions: list[FloatArray]
    parent_move: list[IntArray]
    child: list[IntArray]
    moves: FloatArray

    def random_walk(self, rng: np.random.Generator) -> Iterator[tuple[int, FloatArray]]:
        """A path through ``R_1 .. R_K``, each step's move drawn uniformly among those that
        stay in the map: yields ``(k, position)`` after each draw, so that a caller draws
        its look of epoch k before the next move (the random planners' order of draws)."""
        q = 0
        for k in range(1, len(self.positions)):
            options = np.flatnonzero(self.child[k][q] >= 0)
            q = int(self.child[k][q, options[rng.integers(len(options))]])
            yield k, self.positions[k][q]

    def index_of(self, k: int, xy: FloatArray) -> int:
        """Index of ground position ``xy`` in ``R_k`` (-1 if not reachable)."""
        d = np.abs(self.positions[k] - np.asarray(xy, dtype=float)).max(axis=1)
        hits = np.flatnonzero(d <= POSITION_TOL * 10)
        return int(hits[0]) if hits.size else -1


def _position_keys(offsets: FloatArray) -> np.ndarray:
    """One integer per offset, equal iff the offsets agree on a 1e-6 m grid."""
    q = np.rint(offsets / POSITION_TOL).astype(np.int64)
    if len(q) == 0:
        return np.zeros(0, dtype=np.int64)
    lo = q.min(axis=0)
    span = q.max(axis=0) - lo + 1
    if float(span[0]) * float(span[1]) < 2.0**62:
        return (q[:, 0] - lo[0]) * span[1] + (q[:, 1] - lo[1])
    # Huge maps: fall back to one 16-byte key per row (still exact).
    return np.ascontiguousarray(q).view(np.dtype((np.void, 16))).ravel()


def _common_step(moves: FloatArray) -> int:
    """Largest step (in 1e-6 m units) of which every move component is a multiple; 0 if none."""
    # A sensor's moves are the same at every decision: compute once per move set.
    return _common_step_of(np.ascontiguousarray(moves, dtype=float).tobytes())


@functools.lru_cache(maxsize=64)
def _common_step_of(moves_bytes: bytes) -> int:
    moves = np.frombuffer(moves_bytes, dtype=float)
    q = np.rint(np.abs(moves) / POSITION_TOL).astype(np.int64).ravel()
    if not np.allclose(q * POSITION_TOL, np.abs(moves).ravel(), rtol=0, atol=1e-9):
        return 0
    return int(np.gcd.reduce(q[q > 0])) if np.any(q > 0) else 0


def _first_occurrences(offsets: FloatArray, grid: int) -> tuple[IntArray, IntArray]:
    """Index of each distinct offset's first occurrence, and each offset's distinct index.

    With a common move step the offsets are points of a small integer grid and a dense
    table finds duplicates in linear time; otherwise a sort (``np.unique``) does.
    """
    if grid > 0 and len(offsets):
        g = np.rint(offsets / (grid * POSITION_TOL)).astype(np.int64)
        lo = g.min(axis=0)
        span = g.max(axis=0) - lo + 1
        if int(span[0]) * int(span[1]) <= 4 * len(offsets) + 1_000_000:
            cell = (g[:, 0] - lo[0]) * span[1] + (g[:, 1] - lo[1])
            first_at = np.full(int(span[0]) * int(span[1]), len(offsets), dtype=np.int64)
            np.minimum.at(first_at, cell, np.arange(len(offsets)))
            cells = np.flatnonzero(first_at < len(offsets))
            index = np.full(first_at.size, -1, dtype=np.int64)
            index[cells] = np.arange(cells.size)
            return first_at[cells], index[cell]
    _, first, inverse = np.unique(_position_keys(offsets), return_index=True,
                                  return_inverse=True)
    return first, inverse.ravel()


def build_lattice(p0: FloatArray, moves: FloatArray, K: int, world: MapRect) -> Lattice:
    """Reachable sets ``R_k = {p + m : p in R_{k-1}, m a move, inside the map}``, k = 0..K."""
    p0 = np.asarray(p0, dtype=float)
    moves = np.asarray(moves, dtype=float)
    reach = K * float(np.abs(moves).max(initial=0.0))
    # Whether the corners p0 -/+ reach lie in the map (MapRect.contains on floats: the
    # same comparisons without a dozen array calls).
    (x, y), tol = p0.tolist(), POSITION_TOL
    if all(-tol <= c <= w + tol for c, w in ((x - reach, world.width), (y - reach, world.height),
                                             (x + reach, world.width), (y + reach, world.height))):
        # No K-step path can leave the map: the sets are the unbounded lattice's, shifted.
        base = _unbounded_lattice(moves.tobytes(), K)
        return Lattice([p0 + x for x in base.positions], base.parent_move, base.child, moves)
    return _build_lattice(p0, moves, K, world)


@functools.lru_cache(maxsize=64)
def _unbounded_lattice(moves_bytes: bytes, K: int) -> Lattice:
    moves = np.frombuffer(moves_bytes, dtype=float).reshape(-1, 2)
    return _build_lattice(np.zeros(2), moves, K, None)


def _build_lattice(p0: FloatArray, moves: FloatArray, K: int,
                   world: MapRect | None) -> Lattice:
    from ._lattice_nb import lattice_nb             # compiled; imported late (cold start)

    # Writeable copies: a read-only array is another numba signature, compiled again.
    p0 = np.array(p0, dtype=float, order="C")
    moves = np.array(moves, dtype=float, order="C")
    bounded = world is not None
    width = float(world.width) if world is not None else 0.0
    height = float(world.height) if world is not None else 0.0
    flat, start, child_flat, parent_flat = lattice_nb(p0, moves, K, bounded, width, height,
                                                       POSITION_TOL, _common_step(moves))
    positions = [flat[start[k]:start[k + 1]] for k in range(K + 1)]
    parent_move = [parent_flat[start[k]:start[k + 1]] for k in range(K + 1)]
    child: list[IntArray] = [np.zeros((0, len(moves)), dtype=np.int64)]
    child += [child_flat[start[k - 1]:start[k]] for k in range(1, K + 1)]
    return Lattice(positions, parent_move, child, moves)


@dataclass(frozen=True)
class UndetectedIntensity:
    """The undetected targets' Poisson intensity on a grid, as planning uses it.

    Attributes
    ----------
    centres : (C, 2)      cell centres (m)
    weights : (C,)        D_u: expected number of undetected targets in each cell now
    births : (C,)         expected births in each cell per step
    survival : float      probability that a target survives one step, in [0, 1]
    cell_cov : (2, 2)     position covariance of a target known only to lie in a cell
                          (``diag(a^2/12, b^2/12)`` for ``a x b`` cells); it fixes the
                          default weight of a found target
    weight : float or None
        Nats a newly found target is worth (w of the search term); None: the information
        of its first detection (:func:`sensorplan.planners.search.first_detection_weight`).
    """

    centres: FloatArray
    weights: FloatArray
    births: FloatArray
    survival: float = 1.0
    cell_cov: FloatArray = field(default_factory=lambda: np.diag([625.0 / 12, 625.0 / 12]))
    weight: float | None = None

    def __post_init__(self) -> None:
        for name in ("centres", "weights", "births", "cell_cov"):
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        object.__setattr__(self, "survival", float(self.survival))

    def validate(self) -> None:
        """Raise :class:`ConfigError` naming the field (``undetected.*``) unless valid."""
        C = len(self.centres)
        if self.centres.shape != (C, 2) or C < 1:
            raise ConfigError("undetected.centres", f"expected shape (C, 2) with C >= 1, got "
                              f"{self.centres.shape}")
        for name in ("centres", "weights", "births", "cell_cov"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ConfigError(f"undetected.{name}", "must be finite")
        for name in ("weights", "births"):
            v = getattr(self, name)
            if v.shape != (C,):
                raise ConfigError(f"undetected.{name}", f"expected shape ({C},), got {v.shape}")
            if np.any(v < 0):
                raise ConfigError(f"undetected.{name}", "must be >= 0")
        if not 0.0 <= self.survival <= 1.0:
            raise ConfigError("undetected.survival", f"must be in [0, 1], got {self.survival:g}")
        if self.cell_cov.shape != (2, 2):
            raise ConfigError("undetected.cell_cov", "expected shape (2, 2)")
        check_covariance(self.cell_cov, "undetected.cell_cov")
        if self.weight is not None and not (math.isfinite(self.weight) and self.weight >= 0):
            raise ConfigError("undetected.weight", "must be a finite number >= 0")


def _readonly(a: object, dtype: type = float) -> np.ndarray:
    arr: np.ndarray = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class PlanningProblem:
    """Everything one planning decision needs.

    Attributes
    ----------
    means : (M, 4)
        Target means ``[x, y, vx, vy]`` now (time 0).
    covs : (M, 4, 4)
        Target covariances now.
    positions : (N, 2)
        Platform ground positions (m).
    headings : (N,)
        Platform headings (rad).
    sensors : tuple of SensorParams, length N
    horizon : int
        K, in epochs.
    steps_per_epoch : int
        e; the horizon ends at T = K e steps.
    dt : float
        Simulation step (s).
    process_noise : float or (M,)
        q of the filter model (m^2/s^3): one for every target, or one per target (an IMM
        tracker's effective q).
    world : MapRect
    visibility : {"probabilistic", "mean"}
    objective : {"cumulative", "terminal"}
        ``cumulative`` (default): information summed over the horizon's steps;
        ``terminal``: at the horizon's end (the paper's).
    planning_detection : {"ignore", "aware"}
        ``aware``: a planned look's information also counts its detection probability and
        the clutter (:func:`sensorplan.models.radar.look`); ``ignore``: only whether the target is
        in view.
    buildings : (B, 5)
        Boxes ``x0, y0, x1, y1, height`` (m) that can hide targets; a planned look counts
        with the probability that none does (empty: open ground).
    existence : (M,), optional
        Each target's probability of existence r in [0, 1] (default: all 1). Target j's
        information enters Phi, and so every player's utility, multiplied by r_j: a track
        that is probably not a real target is worth that much less to look at. Always an
        ``(M,)`` array once the problem is built.
    reported : (M,) bool, optional
        Whether each track is reported (default: all). The ``gospa`` reward values a
        reported track by how much the plan shrinks its covariance, and one not reported
        (a multi-target tracker's Bernoulli below its report threshold) as a target to
        find: its existence times the chance that the plan's looks detect it times the
        bound a find removes; the ``information`` reward values every track alike, so with
        it every track must be reported. None once built when every track is.
    search : {"off", "on"}
        ``off`` (default): looks point at tracks and Phi is their information. ``on``: a
        look may also point at a search sector, and Phi adds ``w mu``, the value of the
        undetected targets the plan is expected to find (:mod:`sensorplan.planners.search`).
    search_sectors : int or tuple of int, one per sensor
        Search sectors of each sensor (with ``search="on"``): ``S > 0`` absolute bearings
        ``2 pi s / S``, s = 0..S-1, around the platform; 0 (default): none. One number
        applies to every sensor; always a tuple once the problem is built.
    undetected : UndetectedIntensity or None
        The undetected intensity; required with ``search="on"``.
    elapsed_epochs : int
        Epochs of the run before this decision (default 0: the first decision, or one on
        its own). Phi does not depend on it; a planner that follows a fixed schedule
        (``raster``) reads its phase from it, so that the schedule goes on from one
        decision to the next instead of starting again.
    reward : {"information", "gospa"}
        What Phi measures with search on. ``information`` (default): the tracks' information
        plus ``w mu``. ``gospa``: how much the plan lowers the expected GOSPA bound, in m^2
        (:mod:`sensorplan.planners.gospa_bound`); needs ``search="on"``.
    gospa_c : float
        GOSPA's cut-off c (m, > 0; default 50) of the ``gospa`` reward.
    find_tail : int
        Steps after the horizon over which the ``gospa`` reward still counts a find (a
        target found, or a track not reported confirmed), each weighted by the chance it
        survives: a target not found now stays missed until search finds it, while a
        track's covariance is restored by the next look at it, so its reduction counts
        over the horizon only. 0 (default): the bound over the horizon alone.
    track_existence : {"fixed", "resolved"}
        What a look does to a reported track in the ``gospa`` reward. ``fixed`` (default):
        it shrinks the track's covariance; its existence is taken as it is. ``resolved``:
        every look whose beam covers the track's predicted mean also tells whether it
        exists, valued as the bound under the report decision that minimises it
        (:mod:`sensorplan.planners.gospa_bound`).
    """

    means: FloatArray
    covs: FloatArray
    positions: FloatArray
    headings: FloatArray
    sensors: tuple[SensorParams, ...]
    horizon: int
    steps_per_epoch: int = 1
    dt: float = 1.0
    process_noise: float | FloatArray = 0.05
    world: MapRect = field(default_factory=MapRect)
    visibility: str = "probabilistic"
    objective: str = "cumulative"
    planning_detection: str = "aware"
    buildings: FloatArray = field(default_factory=lambda: np.zeros((0, 5)))
    existence: FloatArray | None = None
    reported: BoolArray | None = None
    search: str = "off"
    search_sectors: int | tuple[int, ...] = 0
    undetected: UndetectedIntensity | None = None
    elapsed_epochs: int = 0
    reward: str = "information"
    gospa_c: float = 50.0
    find_tail: int = 0
    track_existence: str = "fixed"

    def __post_init__(self) -> None:
        # Read-only copies: planners cannot mutate the caller's arrays (or each other's).
        for name in ("means", "covs", "positions", "headings"):
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        existence = np.ones(len(self.means)) if self.existence is None else self.existence
        object.__setattr__(self, "existence", _readonly(existence))
        if self.reported is not None:
            reported = np.array(self.reported)          # dtype kept: validate() checks it
            reported.setflags(write=False)
            # Every track reported is stored as None, so that replacing the tracks keeps it.
            object.__setattr__(self, "reported", None if reported.dtype == np.bool_
                               and reported.all() else reported)
        object.__setattr__(self, "buildings", _readonly(check_buildings(
            self.buildings, self.world, [float(s.altitude) for s in self.sensors])))
        object.__setattr__(self, "sensors", tuple(self.sensors))
        if np.ndim(self.process_noise) > 0:
            object.__setattr__(self, "process_noise", _readonly(self.process_noise))
        else:
            object.__setattr__(self, "process_noise", float(self.process_noise))
        if isinstance(self.search_sectors, (list, tuple, np.ndarray)):
            object.__setattr__(self, "search_sectors", tuple(self.search_sectors))
        self.validate()

    @property
    def n_sensors(self) -> int:
        return len(self.sensors)

    @property
    def n_targets(self) -> int:
        return len(self.means)

    @property
    def n_steps(self) -> int:
        """T = K e, the last step of the horizon."""
        return self.horizon * self.steps_per_epoch

    def validate(self) -> None:
        """Check the semantic rules of a decision; raise :class:`ConfigError` naming the field."""
        M = len(self.means)
        if M < 1 and self.search != "on":
            # With search on, a decision may have no track yet: every look searches.
            raise ConfigError("targets", "at least one target is required (with search "
                              "off)")
        if self.means.shape != (M, 4):
            raise ConfigError("targets.mean", f"expected shape ({M}, 4), got {self.means.shape}")
        if self.covs.shape != (M, 4, 4):
            raise ConfigError("targets.cov", f"expected shape ({M}, 4, 4), got {self.covs.shape}")
        N = len(self.sensors)
        if N < 1:
            raise ConfigError("sensors", "at least one sensor is required")
        if self.positions.shape != (N, 2):
            raise ConfigError("sensors.position", f"expected shape ({N}, 2)")
        if self.headings.shape != (N,):
            raise ConfigError("sensors.heading", f"expected shape ({N},)")
        for name, value in (("dt", self.dt), ("map.width", self.world.width),
                            ("map.height", self.world.height)):
            if not math.isfinite(value):
                raise ConfigError(name, "must be a finite number")
        q = np.asarray(self.process_noise)
        if q.ndim > 0 and q.shape != (M,):
            raise ConfigError("process_noise", f"must be a number or one per target ({M}), "
                              f"got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ConfigError("process_noise", "must be a finite number")
        if self.dt <= 0:
            raise ConfigError("dt", "must be > 0")
        if np.any(q < 0):
            raise ConfigError("process_noise", "must be >= 0")
        if self.world.width <= 0 or self.world.height <= 0:
            raise ConfigError("map", "width and height must be > 0")
        if int(self.horizon) != self.horizon or self.horizon < 1:
            raise ConfigError("horizon", "must be an integer >= 1")
        if int(self.steps_per_epoch) != self.steps_per_epoch or self.steps_per_epoch < 1:
            raise ConfigError("steps_per_epoch", "must be an integer >= 1")
        if self.visibility not in VISIBILITY_MODES:
            raise ConfigError("visibility",
                              f"must be one of {VISIBILITY_MODES}, got {self.visibility!r}")
        if self.objective not in OBJECTIVES:
            raise ConfigError("objective", f"must be one of {OBJECTIVES}, got {self.objective!r}")
        if self.planning_detection not in PLANNING_DETECTIONS:
            raise ConfigError("planning_detection", f"must be one of {PLANNING_DETECTIONS}, "
                              f"got {self.planning_detection!r}")
        if not np.all(np.isfinite(self.means)):
            j = int(np.flatnonzero(~np.all(np.isfinite(self.means), axis=1))[0])
            raise ConfigError(f"targets[{j}].mean", "must be finite")
        check_existence(self.existence, M)
        if self.reported is not None:
            reported = np.asarray(self.reported)
            if reported.shape != (M,) or reported.dtype != np.bool_:
                raise ConfigError("targets.reported", f"expected ({M},) booleans, got "
                                  f"shape {reported.shape} of {reported.dtype}")
        e = self.elapsed_epochs
        if isinstance(e, bool) or not isinstance(e, (int, np.integer)) or e < 0:
            raise ConfigError("elapsed_epochs", f"must be an integer >= 0, got {e!r}")
        self._validate_search(N)
        self._validate_reward()
        if not _covariances_ok(self.covs):           # one batched check; locate on failure
            for j in range(M):
                check_covariance(self.covs[j], f"targets[{j}].cov")
        for i, s in enumerate(self.sensors):
            _validate_sensor(s, f"sensors[{i}]")
            if not np.all(np.isfinite(self.positions[i])):
                raise ConfigError(f"sensors[{i}].position", "must be finite")
            if not np.isfinite(self.headings[i]):
                raise ConfigError(f"sensors[{i}].heading", "must be finite")
            if not self.world.contains(self.positions[i]):
                raise ConfigError(f"sensors[{i}].position", self.world.outside(self.positions[i]))


    def _validate_search(self, N: int) -> None:
        if self.search not in SEARCH_MODES:
            raise ConfigError("search", f"must be one of {SEARCH_MODES}, got {self.search!r}")
        sectors = self.search_sectors
        if isinstance(sectors, tuple):
            if len(sectors) != N:
                raise ConfigError("search_sectors", f"must be one number or one per sensor "
                                  f"({N}), got {len(sectors)}")
            fields = [f"sensors[{i}].search_sectors" for i in range(N)]
        else:
            sectors, fields = (sectors,) * N, ["search_sectors"] * N
        for s, name in zip(sectors, fields):
            if (isinstance(s, bool) or not isinstance(s, numbers.Real) or not math.isfinite(s)
                    or int(s) != s or s < 0):
                raise ConfigError(name, f"must be an integer >= 0, got {s!r}")
        if self.search == "on":
            if self.undetected is None:
                raise ConfigError("undetected", "is required when search is on")
            self.undetected.validate()
            outside = ~self.world.contains(self.undetected.centres)
            if outside.any():
                c = int(np.flatnonzero(outside)[0])
                raise ConfigError(f"undetected.centres[{c}]",
                                  self.world.outside(self.undetected.centres[c]))
            if not any(sectors):
                # Search looks need bearings to point at; 0 is only right for some sensors.
                raise ConfigError(fields[0], "search is on but no sensor has a search "
                                  "sector; give at least one sensor search_sectors >= 1, or "
                                  "set search to 'off'")

    def _validate_reward(self) -> None:
        if self.reward not in REWARDS:
            raise ConfigError("reward", f"must be one of {REWARDS}, got {self.reward!r}")
        c = self.gospa_c
        if (isinstance(c, bool) or not isinstance(c, numbers.Real) or not math.isfinite(c)
                or c <= 0):
            raise ConfigError("gospa_c", f"must be a finite number > 0, got {c!r}")
        tail = self.find_tail
        if isinstance(tail, bool) or not isinstance(tail, numbers.Integral) or tail < 0:
            raise ConfigError("find_tail", f"must be a whole number of steps >= 0, got "
                              f"{tail!r}")
        if self.track_existence not in TRACK_EXISTENCE_MODES:
            raise ConfigError("track_existence", f"must be one of {TRACK_EXISTENCE_MODES}, "
                              f"got {self.track_existence!r}")
        if self.reward != "gospa":
            if self.track_existence != "fixed":
                raise ConfigError("track_existence", "'resolved' is a term of the 'gospa' "
                                  "reward only; leave it 'fixed' with reward 'information'")
            if tail:
                raise ConfigError("find_tail", "counts finds in the 'gospa' reward only; "
                                  "leave it 0 with reward 'information'")
            if self.reported is not None:
                j = int(np.flatnonzero(~np.asarray(self.reported))[0])
                raise ConfigError(f"targets[{j}].reported", "a track not reported is valued "
                                  "apart by the 'gospa' reward only; with reward "
                                  "'information' every track must be reported")
            return
        if self.search != "on":
            # The bound's missed-target part is what search lowers; without it a track
            # reward needs the information objective's engine.
            raise ConfigError("reward", "'gospa' needs search = 'on' (with search off use "
                              "reward 'information')")
        assert self.undetected is not None
        if self.undetected.weight is not None:
            raise ConfigError("undetected.weight", "is the information reward's nats per "
                              "found target; leave it out with reward 'gospa' (the bound "
                              "derives a found target's value)")

    @property
    def sector_counts(self) -> tuple[int, ...]:
        """Each sensor's number of search sectors (0 with search off: no sector looks)."""
        if not self.searching:
            return (0,) * len(self.sensors)
        s = self.search_sectors
        if not isinstance(s, tuple):
            return (int(s),) * len(self.sensors)
        return tuple(int(v) for v in s)

    @property
    def searching(self) -> bool:
        """Whether planning searches (``search == "on"``)."""
        return self.search == "on"


def check_existence(existence: Any, M: int) -> None:
    """Raise :class:`ConfigError` unless ``existence`` is ``(M,)`` finite numbers in [0, 1]
    (the field is ``targets.existence``, or ``targets[j].existence`` for one bad value)."""
    r = np.asarray(existence)
    if r.shape != (M,):
        raise ConfigError("targets.existence", f"expected shape ({M},), got {r.shape}")
    bad = ~np.isfinite(r)
    if bad.any():
        raise ConfigError(f"targets[{int(np.flatnonzero(bad)[0])}].existence",
                          "must be a finite number")
    bad = (r < 0.0) | (r > 1.0)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise ConfigError(f"targets[{j}].existence", f"must be in [0, 1], got {r[j]:g}")


def check_buildings(buildings: Any, world: MapRect, altitudes: object) -> FloatArray:
    """The buildings as a ``(B, 5)`` array ``x0, y0, x1, y1, height``, checked.

    Each is 5 finite numbers with ``x0 < x1``, ``y0 < y1``, inside the map and ``height > 0``;
    every sensor flies above the tallest. Raises :class:`ConfigError` naming the field.
    """
    rows = [tuple(np.ravel(np.asarray(b, dtype=float))) for b in np.atleast_1d(
        np.asarray(buildings, dtype=object)) if np.size(b)] if np.size(buildings) else []
    check_count(len(rows), MAX_BUILDINGS, "buildings", "buildings")
    W, H = world.width, world.height
    tallest = 0.0
    for k, b in enumerate(rows):
        if len(b) != 5 or not all(math.isfinite(v) for v in b):
            raise ConfigError(f"buildings[{k}]", "must be 5 finite numbers: x0, y0, x1, y1, "
                              "height")
        x0, y0, x1, y1, h = b
        if not (x0 < x1 and y0 < y1):
            raise ConfigError(f"buildings[{k}].box", "must have x0 < x1 and y0 < y1")
        if not (0.0 <= x0 and x1 <= W and 0.0 <= y0 and y1 <= H):
            raise ConfigError(f"buildings[{k}].box", f"must lie inside the map [0, {W:g}] "
                              f"x [0, {H:g}]")
        if h <= 0:
            raise ConfigError(f"buildings[{k}].height", "must be > 0")
        RANGES["building_height"].check(h, f"buildings[{k}].height")
        tallest = max(tallest, h)
    for i, z in enumerate(np.asarray(altitudes, dtype=float).reshape(-1)):
        if rows and z <= tallest:
            raise ConfigError(f"sensors[{i}].altitude", f"must be above every building "
                              f"(the tallest is {tallest:g} m)")
    return np.array(rows, dtype=float).reshape(-1, 5)


_VALID_SENSORS: set[SensorParams] = set()


def _validate_sensor(params: SensorParams, prefix: str) -> None:
    # Sensors are frozen values reused at every decision of a run: validate each once.
    if params in _VALID_SENSORS:
        return
    params.validate(prefix)
    if len(_VALID_SENSORS) < 10_000:
        _VALID_SENSORS.add(params)


def _covariances_ok(P: FloatArray) -> bool:
    """Batched version of :func:`check_covariance` for ``(M, 4, 4)``: True if all pass."""
    if not np.all(np.isfinite(P)):
        return False
    scale = np.maximum(1.0, np.abs(P).max(axis=(1, 2)))
    if np.any(np.abs(P - np.swapaxes(P, 1, 2)).max(axis=(1, 2)) > 1e-9 * scale):
        return False
    try:
        np.linalg.cholesky(0.5 * (P + np.swapaxes(P, 1, 2)))
    except np.linalg.LinAlgError:
        return False
    return True


def check_covariance(P: FloatArray, field_name: str) -> None:
    """Raise :class:`ConfigError` unless ``P`` is finite, symmetric (1e-9 rel.) and PD."""
    P = np.asarray(P, dtype=float)
    if not np.all(np.isfinite(P)):
        raise ConfigError(field_name, "must be finite")
    scale = max(1.0, float(np.abs(P).max()))
    if np.abs(P - P.T).max() > 1e-9 * scale:
        raise ConfigError(field_name, "must be symmetric")
    try:
        np.linalg.cholesky(0.5 * (P + P.T))
    except np.linalg.LinAlgError:
        raise ConfigError(field_name, "must be positive definite") from None


@dataclass(frozen=True)
class Plan:
    """Every player's action: ``plan[i][k-1]`` is sensor i's action in epoch k.

    Attributes
    ----------
    positions : (N, K, 2)
        Ground positions; NaN where the player is unassigned.
    targets : (N, K) int
        Target looked at; -1 where unassigned or where the look is a search look.
    sectors : (N, K) int
        Search sector looked at (:attr:`PlanningProblem.search_sectors`); -1 where the look
        points at a target or the player is unassigned (default: all -1). A look has a
        target or a sector, never both.
    """

    positions: FloatArray
    targets: IntArray
    sectors: IntArray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "positions", _readonly(self.positions))
        object.__setattr__(self, "targets", _readonly(self.targets, np.int64))
        sectors = np.full(self.targets.shape, -1) if self.sectors is None else self.sectors
        object.__setattr__(self, "sectors", _readonly(sectors, np.int64))

    @property
    def assigned(self) -> np.ndarray:
        assert self.sectors is not None
        return (self.targets >= 0) | (self.sectors >= 0)

    @property
    def searches(self) -> bool:
        """Whether any look is a search look."""
        assert self.sectors is not None
        return bool(np.any(self.sectors >= 0))

    @classmethod
    def empty(cls, n_sensors: int, horizon: int) -> Plan:
        return cls(np.full((n_sensors, horizon, 2), np.nan),
                   np.full((n_sensors, horizon), -1, dtype=np.int64))


class PlanError(ValueError):
    """A plan that is not feasible for its problem (:func:`check_plan`).

    Attributes
    ----------
    sensor : int or None     the first sensor whose action is wrong (None: the whole plan)
    epoch : int or None      its epoch, 1..K (None: the whole plan)
    detail : str             what is wrong, without the sensor and epoch
    """

    def __init__(self, detail: str, sensor: int | None = None,
                 epoch: int | None = None) -> None:
        self.sensor, self.epoch, self.detail = sensor, epoch, detail
        where = "" if sensor is None else f"sensor {sensor} epoch {epoch}: "
        super().__init__(where + detail)

    def __reduce__(self) -> tuple[type, tuple[str, int | None, int | None]]:
        # Rebuilt from its parts, so that it crosses process boundaries intact.
        return (type(self), (self.detail, self.sensor, self.epoch))


def check_plan(problem: PlanningProblem, plan: Plan, complete: bool = True,
               holding: tuple[int, ...] = ()) -> None:
    """Raise :class:`PlanError` (a ``ValueError``) unless ``plan`` is feasible for ``problem``.

    Checks shapes, that targets exist, that every position lies in the map and in ``R_k``
    and differs from the previous assigned position by a move (from ``p_0`` at k = 1).
    With ``complete`` every player must be assigned, except the sensors in ``holding``,
    which must have no action in any epoch (they hold station and look at nothing: a
    decentralized planner's lost agents). The error names the first sensor and epoch
    (sensor-major order) that breaks a rule.
    """
    N, K, M = problem.n_sensors, problem.horizon, problem.n_targets
    if plan.positions.shape != (N, K, 2) or plan.targets.shape != (N, K):
        raise PlanError(f"plan has shapes {plan.positions.shape} and {plan.targets.shape}, "
                        f"expected ({N}, {K}, 2) and ({N}, {K})")
    assert plan.sectors is not None
    if plan.sectors.shape != (N, K):
        raise PlanError(f"plan has sectors of shape {plan.sectors.shape}, expected ({N}, {K})")
    if plan.searches:
        _check_sectors(problem, plan)
    lowest = np.full((N, 1), 0 if complete else -1)
    for i in holding:
        if not 0 <= i < N:
            raise PlanError(f"holding sensor {i} does not exist (the sensors are 0..{N - 1})")
        acting = np.flatnonzero(plan.assigned[i])
        if acting.size:
            raise PlanError("a holding sensor has an action (it holds station and looks at "
                            "nothing in every epoch)", i, int(acting[0]) + 1)
        lowest[i] = -1
    # A search look has no target (its sector is checked above).
    targets = plan.targets
    bad = (plan.sectors < 0) & ((targets >= M) | (targets < lowest))
    if bad.any():
        i, k = (int(v) for v in np.argwhere(bad)[0])
        j = int(targets[i, k])
        if j == -1:
            raise PlanError("no action (every sensor needs a move and a target in every "
                            "epoch)", i, k + 1)
        raise PlanError(f"target {j} does not exist (the targets are 0..{M - 1})", i, k + 1)
    _check_moves(problem, plan)


def _check_sectors(problem: PlanningProblem, plan: Plan) -> None:
    assert plan.sectors is not None
    if not problem.searching:
        i, k = (int(v) for v in np.argwhere(plan.sectors >= 0)[0])
        raise PlanError("a search look, but the problem's search is off", i, k + 1)
    both = (plan.sectors >= 0) & (plan.targets >= 0)
    if both.any():
        i, k = (int(v) for v in np.argwhere(both)[0])
        raise PlanError("a look has a target and a sector (it points at one)", i, k + 1)
    S = np.asarray(problem.sector_counts, dtype=np.int64)[:, None]
    bad = (plan.sectors >= S) | (plan.sectors < -1)
    if bad.any():
        i, k = (int(v) for v in np.argwhere(bad)[0])
        raise PlanError(f"sector {int(plan.sectors[i, k])} does not exist (sensor {i} has "
                        f"{int(S[i, 0])} search sectors)", i, k + 1)


def _check_moves(problem: PlanningProblem, plan: Plan) -> None:
    K = problem.horizon
    for i, s in enumerate(problem.sensors):
        moves = move_vectors(s.moves)
        lat: Lattice | None = None
        prev = problem.positions[i]
        prev_assigned = True
        for k in range(K):
            if not plan.assigned[i, k]:
                prev_assigned = False
                continue
            p = plan.positions[i, k]
            if not np.isfinite(p).all():
                raise PlanError(f"position {p} is not a number", i, k + 1)
            if not problem.world.contains(p):
                raise PlanError(f"position {problem.world.outside(p)}", i, k + 1)
            if prev_assigned:
                # One move from a position in R_{k-1}, inside the map: so in R_k too.
                if np.min(np.abs(p - prev - moves).max(axis=1)) > POSITION_TOL * 10:
                    raise PlanError(f"position {p} is not one move from {prev}", i, k + 1)
            else:
                if lat is None:
                    lat = build_lattice(problem.positions[i], moves, K, problem.world)
                if lat.index_of(k + 1, p) < 0:
                    raise PlanError(f"position {p} is not reachable from "
                                    f"{problem.positions[i]} in {k + 1} epochs", i, k + 1)
            prev, prev_assigned = p, True
