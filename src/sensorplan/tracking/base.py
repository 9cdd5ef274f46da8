"""What every tracker offers the closed loop: the looks it is given and the tracks it reports.

A step of the closed loop is: the tracker predicts (:meth:`Tracker.predict`); the sensors
look, and each look returns its detections (:class:`Looks`); the tracker updates with them
(:meth:`Tracker.update`) and reports its tracks (:meth:`Tracker.tracks`), which the planner
plans on. Nothing outside a tracker assumes that track ``j`` is target ``j``: a tracker of
known targets labels its tracks with the targets' indices, a multi-target tracker with
labels of its own, and reports each track's probability of existence.

Trackers are registered by kind (:data:`sensorplan.tracking.registry.TRACKERS`), as
planners are by name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .._types import BoolArray, FloatArray, IntArray


@dataclass(frozen=True)
class Looks:
    """One step's looks and the detections each returned.

    Attributes
    ----------
    sensors : (L,) int        the looking sensors (rows of the radar table), in sensor order
    aims : (L,) int           the track each look pointed its beam at (a label)
    positions : (L, 2)        the sensors' ground positions (m)
    headings : (L,)           their headings (rad)
    detections : L arrays ``(n_l, 2)``   ``[r, phi]`` of each look's detections (m, rad),
                              in the order the sensor reported them
    """

    sensors: IntArray
    aims: IntArray
    positions: FloatArray
    headings: FloatArray
    detections: tuple[FloatArray, ...]

    def __post_init__(self) -> None:
        L = len(self.sensors)
        if not (len(self.aims) == len(self.positions) == len(self.headings)
                == len(self.detections) == L):
            raise ValueError("looks: sensors, aims, positions, headings and detections must "
                             "have one entry per look")

    @property
    def counts(self) -> IntArray:
        """(L,) the number of detections of each look."""
        return np.array([len(d) for d in self.detections], dtype=np.int64)


class Rows:
    """Arrays with one row per track (or Bernoulli), each with its ``labels`` entry: the
    length is the number of rows."""

    labels: IntArray

    def __len__(self) -> int:
        return len(self.labels)


@dataclass(frozen=True)
class TrackSet(Rows):
    """The tracks a tracker reports at one time.

    Attributes
    ----------
    means : (T, 4)            ``[x, y, vx, vy]``
    covs : (T, 4, 4)
    existence : (T,)          probability that each track is a real target (1 for a tracker
                              of known targets)
    labels : (T,) int         each track's label, kept for the track's life
    """

    means: FloatArray
    covs: FloatArray
    existence: FloatArray
    labels: IntArray

    def copy(self) -> TrackSet:
        """A copy of the arrays (a tracker's own change with its next step)."""
        return TrackSet(np.array(self.means), np.array(self.covs), np.array(self.existence),
                        np.array(self.labels))


@dataclass(frozen=True)
class UpdateRecord:
    """What one step's update did, for the run's record.

    Attributes
    ----------
    negative : (T,) bool      tracks that got a missed-look (negative) update
    inflated : (T,) bool      tracks whose missed-look update inflated them instead
    restarted : (T,) bool     tracks restarted from a detection
    map_corrected : (T,) bool tracks the known map corrected after the updates
    used : (L,) int           detections of each look applied to a track
    discarded : (L,) int      detections of each look outside every gate
    gated_out : (L,) bool     a look's single detection fell outside its track's gate
    """

    negative: BoolArray
    inflated: BoolArray
    restarted: BoolArray
    map_corrected: BoolArray
    used: IntArray
    discarded: IntArray
    gated_out: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))


@dataclass(frozen=True)
class UndetectedReport:
    """The intensity of targets that exist but were never detected, on a grid of cells, as
    a tracker that keeps one reports it (planning's search looks aim where they may be).

    Attributes
    ----------
    centres : (C, 2)       cell centres (m)
    weights : (C,)         expected number of undetected targets in each cell now
    births : (C,)          expected births in each cell per step
    survival : float       probability that a target survives one step
    cell_cov : (2, 2)      position covariance of a target known only to lie in a cell
    """

    centres: FloatArray
    weights: FloatArray
    births: FloatArray
    survival: float
    cell_cov: FloatArray


def undetected_report(tracker: Any) -> UndetectedReport | None:
    """The tracker's undetected intensity, from its optional method
    ``undetected_intensity()``; None for a tracker that keeps none (it cannot plan search
    looks)."""
    report = getattr(tracker, "undetected_intensity", None)
    return report() if callable(report) else None


@runtime_checkable
class Tracker(Protocol):
    """A tracker in the closed loop (see the module docstring)."""

    def predict(self) -> BoolArray:
        """Predict every track one step; returns ``(T,)`` the tracks the map corrected."""
        ...

    def update(self, looks: Looks) -> UpdateRecord:
        """Update the tracks with one step's looks."""
        ...

    def tracks(self) -> TrackSet:
        """The tracks as they stand."""
        ...

    def planning_process_noise(self) -> float | FloatArray:
        """The process noise the planner should predict each reported track with."""
        ...

    # A tracker that keeps the intensity of undetected targets also offers
    # ``undetected_intensity() -> UndetectedReport`` (optional: :func:`undetected_report`).
    # One that lets planning see tracks it does not report offers
    # ``planning_tracks() -> TrackSet`` (optional: :func:`planning_tracks`).


def planning_tracks(tracker: Any) -> TrackSet:
    """The tracks planning sees: the tracker's optional ``planning_tracks()`` (a
    multi-target tracker may let planning see tracks below its report threshold, each
    weighted by its existence), else its reported :meth:`Tracker.tracks`."""
    tracks = getattr(tracker, "planning_tracks", None)
    return tracks() if callable(tracks) else tracker.tracks()


def given_tracks(means: Any, covs: Any) -> tuple[FloatArray, FloatArray]:
    """The tracks a multi-target tracker starts with: ``means`` ``(M, 4)`` and ``covs``
    (``(M, 4, 4)`` or one ``(4, 4)`` for all) as new arrays; none for ``means`` None.

    Raises
    ------
    ValueError
        ``means`` without ``covs``.
    """
    if means is None:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    if covs is None:
        raise ValueError("covs are needed with means")
    m0 = np.array(means, dtype=float).reshape(-1, 4)
    return m0, np.array(np.broadcast_to(covs, m0.shape + (4,)), dtype=float)


def motion_matrices(dt: float, process_noise: float, motion: Any = None
                    ) -> tuple[FloatArray, FloatArray]:
    """A multi-target tracker's motion model: ``motion`` ``(F, Q)`` as given (a benchmark's
    own), else the constant-velocity model of step ``dt`` (s, > 0) with white-noise
    acceleration ``process_noise`` (q, m^2/s^3, >= 0).

    Raises
    ------
    ValueError
        ``dt`` or ``process_noise`` out of range.
    """
    from ..models.motion import cv_matrices

    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    if not (math.isfinite(process_noise) and process_noise >= 0.0):
        raise ValueError(f"process_noise must be >= 0, got {process_noise!r}")
    if motion is None:
        return cv_matrices(float(dt), float(process_noise))
    F, Q = (np.array(a, dtype=float).reshape(4, 4) for a in motion)
    return F, Q
