"""The record of one closed-loop run (:class:`Episode`) and the recorder that fills it.

Every per-step array of a run is declared once, in :data:`STEP_ARRAYS` (its shape, type and
initial value); the recorder allocates them from it, and :meth:`Episode.save` and
:meth:`Episode.load` store exactly the arrays the dataclass declares.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from .._types import BoolArray, FloatArray, IntArray, IntegerArray
from ..tracking.base import Looks, TrackSet, UpdateRecord
from ..tracking.ekf import nees
from .settings import RunSettings

def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


@dataclass(frozen=True)
class Episode:
    """Everything recorded in one closed-loop run.

    Index 0 of the step axis is the initial state, ``1..S`` the state after each step; step
    ``t`` is the move from time ``t - 1`` to ``t`` and its looks measure the truth at ``t``.

    Attributes
    ----------
    target_kinds : (M,) tuple of str
    truth : (S+1, M, 4)               true states
    estimate : (S+1, M, 4)            filter means after the step's updates
    cov : (S+1, M, 4, 4)              filter covariances
    error : (S+1, M)                  position error ``|p_true - p_est|`` (m)
    nees : (S+1, M)                   full-state NEES
    measured : (S+1, M, N) bool       ``measured[t, j, i]``: sensor i measured target j at t
    looked : (S+1, N) int             target sensor i pointed at during step t (-1: none,
                                      always at t = 0)
    missed : (S+1, N) bool            sensor i's look at step t missed (target truly
                                      outside its field of view)
    negative_update : (S+1, M) bool   track j got a negative (missed-look) update at t
    inflated : (S+1, M) bool          track j got the f >= 0.95 inflation at t
    gated_out : (S+1, M, N) bool      sensor i's detection of target j at t fell outside the
                                      validation gate (discarded, or used to restart)
    restarted : (S+1, M) bool         track j was restarted from a detection at t
    map_corrected : (S+1, M) bool     the known map corrected track j at t
    detections : (S+1, N) int         detections sensor i's look returned at t (its target's
                                      and false alarms)
    false_alarms : (S+1, N) int       of which false alarms
    used : (S+1, N) int               detections the tracker used
    discarded : (S+1, N) int          detections outside the validation gate
    alive : (S+1, M) bool             target j is in the world at t (all, without births)
    track_step : (R,) int             the tracks the tracker reported, one row per track and
    track_label : (R,) int            step: the step, the track's label, its mean,
    track_mean : (R, 4)               covariance and probability of existence (a tracker of
    track_cov : (R, 4, 4)             known targets reports every target's track, labelled
    track_existence : (R,)            with its index, existence 1)
    sensor_positions : (S+1, N, 2)    pose during step t (initial pose at t = 0)
    sensor_headings : (S+1, N)
    decision_steps : (D,) int         time index at which each decision was taken
    planning_seconds : (D,)           each decision's planning time (s): the planner's own
                                      measure (``PlanResult.seconds``, without one-off
                                      start-up), else the wall time of its call
    potential : (D,)                  Phi of each decision's plan (nats)
    converged : (D,)                  1.0/0.0, NaN for planners without the notion
    sweeps : (D,)                     NaN for planners without the notion
    settings : RunSettings
    seed_entropy : int                entropy of the run's SeedSequence
    seed_spawn_key : tuple of int     its spawn key (the run's seed is
                                      ``SeedSequence(seed_entropy, spawn_key=seed_spawn_key)``)
    searched : (S+1, N) int or None   with search on: the search sector sensor i's look
                                      pointed at during step t (-1: a track or none); None
                                      with search off (the file then has no such entry)
    search_found : (D,) or None       with search on: mu of each decision's plan, the
                                      expected number of undetected targets it finds
    search_term : (D,) or None        with search on: w mu, the search term of its Phi (nats)
    undetected : (S+1, ny, nx) float32 or None
                                      a tracker that keeps an intensity of undetected
                                      targets (``pmb``): the expected number of them in each
                                      cell of its grid after step t's update (t = 0: at the
                                      start), row 0 at the map's bottom edge (y = 0), column
                                      0 at x = 0; its sum is the expected number of
                                      undetected targets. None for other trackers (the file
                                      then has no such entry). float32: 4 bytes a cell and
                                      step before compression
    """

    target_kinds: tuple[str, ...]
    truth: FloatArray
    estimate: FloatArray
    cov: FloatArray
    error: FloatArray
    nees: FloatArray
    measured: BoolArray
    looked: IntArray
    missed: BoolArray
    negative_update: BoolArray
    inflated: BoolArray
    gated_out: BoolArray
    restarted: BoolArray
    map_corrected: BoolArray
    detections: IntegerArray
    false_alarms: IntegerArray
    used: IntegerArray
    discarded: IntegerArray
    alive: BoolArray
    track_step: IntArray
    track_label: IntArray
    track_mean: FloatArray
    track_cov: FloatArray
    track_existence: FloatArray
    sensor_positions: FloatArray
    sensor_headings: FloatArray
    decision_steps: IntArray
    planning_seconds: FloatArray
    potential: FloatArray
    converged: FloatArray
    sweeps: FloatArray
    settings: RunSettings
    seed_entropy: int
    seed_spawn_key: tuple[int, ...] = ()
    searched: IntArray | None = None
    search_found: FloatArray | None = None
    search_term: FloatArray | None = None
    undetected: np.ndarray | None = None

    def rmse(self) -> FloatArray:
        """Position RMSE ``(M,)`` of each target over steps ``1..S`` (m)."""
        return np.sqrt(np.mean(self.error[1:] ** 2, axis=0))

    def save(self, path: str | Path) -> Path:
        """Write every array and a JSON metadata entry to an ``.npz`` file.

        The archive is byte-for-byte reproducible: its entries are written in a fixed order
        with a fixed timestamp, and the one wall-clock quantity, ``planning_seconds``, goes
        to a sidecar ``<name>.timing.json``, so the same seed gives identical ``.npz`` files.

        Returns the path of the sidecar.
        """
        path = Path(path)
        meta = {"target_kinds": list(self.target_kinds), "settings": self.settings.to_dict(),
                "seed_entropy": self.seed_entropy,
                "seed_spawn_key": [int(k) for k in self.seed_spawn_key]}
        # The search records exist only with search on: a run without keeps today's file.
        entries = [(name, np.ascontiguousarray(getattr(self, name))) for name in _ARRAYS
                   if getattr(self, name) is not None]
        entries.append(("meta", np.array(json.dumps(meta, sort_keys=True, default=_json))))
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for name, arr in entries:
                buf = io.BytesIO()
                np.lib.format.write_array(buf, arr, allow_pickle=False)
                info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                zf.writestr(info, buf.getvalue())
        sidecar = _timing_path(path)
        sidecar.write_text(json.dumps({"planning_seconds": self.planning_seconds.tolist()}))
        return sidecar

    @classmethod
    def load(cls, path: str | Path) -> Episode:
        """Read an episode written by :meth:`save` (timings NaN if the sidecar is missing)."""
        path = Path(path)
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in _ARRAYS if name in data}
            meta = json.loads(str(data["meta"]))
        if "alive" not in arrays:
            arrays.update(_known_target_sets(arrays["estimate"], arrays["cov"]))
        sidecar = _timing_path(path)
        if sidecar.exists():
            seconds = np.array(json.loads(sidecar.read_text())["planning_seconds"], dtype=float)
        else:
            seconds = np.full(len(arrays["decision_steps"]), np.nan)
        return cls(target_kinds=tuple(meta["target_kinds"]),
                   settings=RunSettings.from_dict(meta["settings"], trusted=True),
                   seed_entropy=meta["seed_entropy"],
                   seed_spawn_key=tuple(int(k) for k in meta.get("seed_spawn_key", ())),
                   planning_seconds=seconds, **arrays)


def _known_target_sets(estimate: FloatArray, cov: FloatArray) -> dict[str, np.ndarray]:
    """The set records of a run of known targets (for files written before they existed):
    every target alive, every target's track reported with its index as label."""
    S1, M = estimate.shape[:2]
    return {"alive": np.ones((S1, M), dtype=bool),
            "track_step": np.repeat(np.arange(S1, dtype=np.int64), M),
            "track_label": np.tile(np.arange(M, dtype=np.int64), S1),
            "track_mean": estimate.reshape(-1, 4), "track_cov": cov.reshape(-1, 4, 4),
            "track_existence": np.ones(S1 * M)}


def _timing_path(path: Path) -> Path:
    return path.with_name(path.stem + ".timing.json")


def _json(v: Any) -> Any:
    """JSON fallback for planner parameters (numpy scalars, arrays, tuples)."""
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"cannot store {type(v).__name__} in episode metadata")


#: Every per-step array of a run, ``(S+1, ...)``: its trailing shape (``M`` targets, ``N``
#: sensors), type and initial value (None: every step writes it). The derived ``error`` and
#: ``nees`` are computed from ``truth``, ``estimate`` and ``cov`` at the end.
STEP_ARRAYS: dict[str, tuple[tuple[str | int, ...], type, Any]] = {
    "truth": (("M", 4), np.float64, None),
    "estimate": (("M", 4), np.float64, None),
    "cov": (("M", 4, 4), np.float64, None),
    "measured": (("M", "N"), np.bool_, False),
    "looked": (("N",), np.int64, -1),
    "missed": (("N",), np.bool_, False),
    "negative_update": (("M",), np.bool_, False),
    "inflated": (("M",), np.bool_, False),
    "gated_out": (("M", "N"), np.bool_, False),
    "restarted": (("M",), np.bool_, False),
    "map_corrected": (("M",), np.bool_, False),
    "detections": (("N",), np.int16, 0),
    "false_alarms": (("N",), np.int16, 0),
    "used": (("N",), np.int16, 0),
    "discarded": (("N",), np.int16, 0),
    "alive": (("M",), np.bool_, True),
    "sensor_positions": (("N", 2), np.float64, None),
    "sensor_headings": (("N",), np.float64, None),
}
#: The arrays an episode file stores, in the dataclass's order (the one wall-clock quantity,
#: ``planning_seconds``, goes to a sidecar so that the same seed gives the same file).
_ARRAYS = tuple(f.name for f in fields(Episode)
                if f.name not in ("target_kinds", "planning_seconds", "settings",
                                  "seed_entropy", "seed_spawn_key"))


@dataclass(frozen=True)
class Sensed:
    """What one step's looks did in truth (the simulator knows it; the tracker does not).

    Attributes
    ----------
    seen : (N,) bool          each sensor detected the target it looked at
    missed : (N,) bool        each assigned sensor's look did not detect its target
    false_alarms : (N,) int   false alarms each look returned
    measured : (M, N) bool    which sensor detected which target (None: only the aimed ones,
                              as ``seen`` says)
    """

    seen: BoolArray
    missed: BoolArray
    false_alarms: IntegerArray
    measured: BoolArray | None = None


class Recorder:
    """Fills a run's arrays step by step and makes the :class:`Episode` (see
    :data:`STEP_ARRAYS`)."""

    def __init__(self, steps: int, n_targets: int, n_sensors: int,
                 known_targets: bool = True) -> None:
        self.steps, self.n_sensors = steps, n_sensors
        # Whether the tracker's update flags are per target (a tracker of known targets)
        # or per reported track (a multi-target tracker: their count may equal the
        # targets' by chance).
        self.known_targets = known_targets
        self.arrays: dict[str, np.ndarray] = {}
        for name in STEP_ARRAYS:
            self.arrays[name] = self._new(name, n_targets)
        self.decisions: list[tuple[int, float, float, float, float]] = []
        self.tracks: list[tuple[int, TrackSet]] = []
        # With search on (:meth:`search`): each step's sector looks and each decision's mu
        # and w mu.
        self.searched: IntArray | None = None
        self.search_terms: list[tuple[float, float]] = []
        # With a tracker that keeps an undetected intensity (:meth:`intensity`): its grid
        # after each step's update.
        self.undetected: np.ndarray | None = None

    def _new(self, name: str, n_targets: int) -> np.ndarray:
        shape, dtype, fill = STEP_ARRAYS[name]
        dims: dict[str | int, int] = {"M": n_targets, "N": self.n_sensors}
        full = (self.steps + 1, *(dims[d] if d in dims else int(d) for d in shape))
        if fill is None:                    # written at every step (NaN before a target's birth)
            fill = np.nan if np.issubdtype(dtype, np.floating) else 0
        return np.full(full, fill, dtype=dtype)

    def _grow(self, n_targets: int) -> None:
        """Room for ``n_targets`` target slots (targets born during the run); a slot's rows
        before its birth hold NaN and ``alive`` False."""
        m = self.arrays["alive"].shape[1]
        if n_targets <= m:
            return
        for name, (shape, _, _) in STEP_ARRAYS.items():
            if "M" in shape:
                extra = self._new(name, n_targets - m)
                if name == "alive":
                    extra[:] = False
                self.arrays[name] = np.concatenate([self.arrays[name], extra], axis=1)

    def start(self, truth: FloatArray, tracks: TrackSet, positions: FloatArray,
              headings: FloatArray) -> None:
        """The state at time 0."""
        self.pose(0, positions, headings)
        a = self.arrays
        a["truth"][0], a["estimate"][0], a["cov"][0] = truth, tracks.means, tracks.covs
        self._tracks(0, tracks)

    def _tracks(self, t: int, tracks: TrackSet) -> None:
        self.tracks.append((t, tracks.copy()))

    def pose(self, t: int, positions: FloatArray, headings: FloatArray) -> None:
        self.arrays["sensor_positions"][t] = positions
        self.arrays["sensor_headings"][t] = headings

    def decision(self, t: int, seconds: float, potential: float, converged: float,
                 sweeps: float) -> None:
        """A decision taken at time index ``t``."""
        self.decisions.append((t, seconds, potential, converged, sweeps))

    def search(self, t: int, sectors: IntArray) -> None:
        """With search on: the sector each sensor's look points at during step ``t`` (-1:
        none)."""
        if self.searched is None:
            self.searched = np.full((self.steps + 1, self.n_sensors), -1, dtype=np.int64)
        self.searched[t] = sectors

    def intensity(self, t: int, centres: FloatArray, weights: FloatArray) -> None:
        """The tracker's undetected intensity after step ``t``'s update: ``weights`` ``(C,)``
        expected undetected targets in the cells whose centres ``(C, 2)`` are row-major
        (``c = row * nx + column``, rows from y = 0 up)."""
        if self.undetected is None:
            nx = len(np.unique(centres[:, 0]))
            self.undetected = np.zeros((self.steps + 1, len(weights) // nx, nx),
                                       dtype=np.float32)
        self.undetected[t] = np.asarray(weights).reshape(self.undetected.shape[1:])

    def search_term(self, found: float, term: float) -> None:
        """With search on: the last decision's mu and w mu (nats)."""
        self.search_terms.append((found, term))

    def step(self, t: int, truth: FloatArray, alive: BoolArray, tracks: TrackSet,
             aimed: IntArray, looks: Looks, sensed: Sensed, predicted: BoolArray,
             update: UpdateRecord) -> None:
        """Step ``t``: the truth (``(M, 4)`` target slots, which are ``alive``), the tracks
        after the updates, and what the looks did.

        ``aimed`` ``(N,)`` is the target each sensor looked at (-1: none). The per-target
        records of a tracker of known targets (``estimate``, ``cov`` and the update flags)
        are its tracks in target order; other trackers' tracks are in the set records.
        """
        self._grow(len(truth))
        a = self.arrays
        M = len(truth)
        a["truth"][t, :M], a["alive"][t, :M] = truth, alive
        a["alive"][t, M:] = False
        if len(tracks) == M and np.array_equal(tracks.labels, np.arange(M)):
            a["estimate"][t, :M], a["cov"][t, :M] = tracks.means, tracks.covs
        self._tracks(t, tracks)
        a["looked"][t], a["missed"][t] = aimed, sensed.missed
        if sensed.measured is not None:
            a["measured"][t, :len(sensed.measured)] = sensed.measured
        else:
            n = np.flatnonzero(sensed.seen)
            a["measured"][t, aimed[n], n] = True
        i = looks.sensors
        a["detections"][t, i] = looks.counts
        a["false_alarms"][t, i] = sensed.false_alarms[i]
        a["used"][t, i], a["discarded"][t, i] = update.used, update.discarded
        g = i[update.gated_out] if len(update.gated_out) else i[:0]
        a["gated_out"][t, aimed[g], g] = True
        if self.known_targets and len(update.negative) == M:
            a["negative_update"][t, :M], a["inflated"][t, :M] = update.negative, update.inflated
            a["restarted"][t, :M] = update.restarted
            a["map_corrected"][t, :M] = predicted | update.map_corrected

    def episode(self, target_kinds: tuple[str, ...], settings: RunSettings,
                seed: np.random.SeedSequence) -> Episode:
        a = self.arrays
        truth, estimate, cov = a["truth"], a["estimate"], a["cov"]
        error = np.hypot(truth[..., 0] - estimate[..., 0], truth[..., 1] - estimate[..., 1])
        d = np.array(self.decisions, dtype=float).reshape(-1, 5)
        steps = [np.full(len(ts), t, dtype=np.int64) for t, ts in self.tracks]
        return Episode(
            track_step=np.concatenate(steps),
            track_label=np.concatenate([ts.labels for _, ts in self.tracks]).astype(np.int64),
            track_mean=np.concatenate([ts.means for _, ts in self.tracks]).reshape(-1, 4),
            track_cov=np.concatenate([ts.covs for _, ts in self.tracks]).reshape(-1, 4, 4),
            track_existence=np.concatenate([ts.existence for _, ts in self.tracks]),
            target_kinds=target_kinds, error=error, nees=nees(truth, estimate, cov),
            decision_steps=d[:, 0].astype(np.int64), planning_seconds=d[:, 1],
            potential=d[:, 2], converged=d[:, 3], sweeps=d[:, 4], settings=settings,
            seed_entropy=_entropy(seed), seed_spawn_key=tuple(seed.spawn_key),
            **self._search_records(), **a)

    def _search_records(self) -> dict[str, np.ndarray]:
        out = {} if self.undetected is None else {"undetected": self.undetected}
        if self.searched is None:
            return out
        f = np.array(self.search_terms, dtype=float).reshape(-1, 2)
        return {**out, "searched": self.searched, "search_found": f[:, 0],
                "search_term": f[:, 1]}


def _entropy(ss: np.random.SeedSequence) -> Any:
    """The sequence's entropy: an int (a list of ints if it was built from one)."""
    e: Any = ss.entropy
    return int(e) if _is_int(e) or isinstance(e, int) else [int(v) for v in e]
