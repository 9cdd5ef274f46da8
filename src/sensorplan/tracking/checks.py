"""The contract every tracker meets, as named checks (like :func:`check_planner`).

:func:`check_tracker` runs each check of :data:`CHECKS` on a tracker built by the caller
for a small scene, and raises :class:`TrackerCheckError` naming the first that fails.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .base import Looks, Tracker, TrackSet, UpdateRecord, planning_tracks


class TrackerCheckError(AssertionError):
    """A tracker broke its contract: the check's name and what went wrong."""


@dataclass(frozen=True)
class TrackerReport:
    """What :func:`check_tracker` checked: the names of the checks it ran."""

    checks: tuple[str, ...]

    def __str__(self) -> str:
        return f"{len(self.checks)} checks passed: {', '.join(self.checks)}"


def _fail(name: str, message: str) -> None:
    raise TrackerCheckError(f"tracker fails check {name!r}: {message}")


def _track_set(name: str, tracks: TrackSet) -> None:
    T = len(tracks.labels)
    shapes = (np.shape(tracks.means), np.shape(tracks.covs), np.shape(tracks.existence))
    if shapes != ((T, 4), (T, 4, 4), (T,)):
        _fail(name, f"tracks of {T} labels have means, covs, existence shaped {shapes}")
    if not np.issubdtype(np.asarray(tracks.labels).dtype, np.integer):
        _fail(name, "labels must be integers")
    if len(np.unique(tracks.labels)) != T:
        _fail(name, f"labels repeat: {list(tracks.labels)}")
    if not (np.all(np.isfinite(tracks.means)) and np.all(np.isfinite(tracks.covs))):
        _fail(name, "means and covariances must be finite")
    if np.any((tracks.existence < 0) | (tracks.existence > 1)):
        _fail(name, "existence must be probabilities in [0, 1]")
    covs = np.asarray(tracks.covs)
    if T and not np.allclose(covs, np.swapaxes(covs, -1, -2), rtol=1e-9, atol=1e-9):
        _fail(name, "covariances must be symmetric")
    if T and np.min(np.linalg.eigvalsh(covs)) <= 0.0:
        _fail(name, "covariances must be positive definite")


def _record(name: str, record: UpdateRecord, looks: Looks, n_tracks: int) -> None:
    L = len(looks.sensors)
    for field in ("negative", "inflated", "restarted", "map_corrected"):
        if np.shape(getattr(record, field)) != (n_tracks,):
            _fail(name, f"record.{field} must have one entry per track before the update")
    for field in ("used", "discarded"):
        if np.shape(getattr(record, field)) != (L,):
            _fail(name, f"record.{field} must have one entry per look")
    if np.any(np.asarray(record.used) + np.asarray(record.discarded) > looks.counts):
        _fail(name, "a look's used and discarded detections exceed what it returned")


def check_reports_valid_tracks(tracker: Tracker, scene: Scene) -> None:
    _track_set("reports_valid_tracks", tracker.tracks())


def check_predict_keeps_tracks_valid(tracker: Tracker, scene: Scene) -> None:
    before = tracker.tracks()
    n = len(before)
    corrected = tracker.predict()
    if np.shape(corrected) != (n,):
        _fail("predict_keeps_tracks_valid", "predict returns one flag per track")
    _track_set("predict_keeps_tracks_valid", tracker.tracks())


def check_update_accounts_for_every_look(tracker: Tracker, scene: Scene) -> None:
    tracker.predict()
    n = len(tracker.tracks())
    record = tracker.update(scene.looks)
    _record("update_accounts_for_every_look", record, scene.looks, n)
    _track_set("update_accounts_for_every_look", tracker.tracks())


def check_no_look_changes_only_the_prediction(tracker: Tracker, scene: Scene) -> None:
    tracker.predict()
    before = tracker.tracks()
    means, covs = np.array(before.means), np.array(before.covs)
    existence = np.array(before.existence)
    tracker.update(_no_looks())
    after = tracker.tracks()
    if not np.array_equal(after.labels, before.labels) or not (
            np.allclose(after.means, means, rtol=0, atol=1e-9)
            and np.allclose(after.covs, covs, rtol=0, atol=1e-9)
            and np.allclose(after.existence, existence, rtol=0, atol=1e-12)):
        _fail("no_look_changes_only_the_prediction",
              "an update with no look changed the tracks")


def _no_looks() -> Looks:
    return Looks(sensors=np.zeros(0, dtype=np.int64), aims=np.zeros(0, dtype=np.int64),
                 positions=np.zeros((0, 2)), headings=np.zeros(0), detections=())


def check_labels_come_only_from_detections(tracker: Tracker, scene: Scene) -> None:
    """Steps without looks start no track: every label reported after them was reported
    before, in the same order (a label is never given to another track)."""
    name = "labels_come_only_from_detections"
    before = np.asarray(tracker.tracks().labels)
    for _ in range(3):
        tracker.predict()
        tracker.update(_no_looks())
        now = np.asarray(tracker.tracks().labels)
        if not np.all(np.isin(now, before)):
            _fail(name, f"steps without looks reported new labels {sorted(set(now) - set(before))}")
        where = {int(label): k for k, label in enumerate(before)}
        if np.any(np.diff([where[int(label)] for label in now]) < 0):
            _fail(name, "steps without looks reordered the labels")
        before = now


def check_planning_process_noise_is_valid(tracker: Tracker, scene: Scene) -> None:
    """The planner's process noise: a finite q >= 0, or one per track planning sees."""
    name = "planning_process_noise_is_valid"
    for _ in range(2):
        q = np.asarray(tracker.planning_process_noise(), dtype=float)
        T = len(planning_tracks(tracker))
        if q.shape not in ((), (T,)):
            _fail(name, f"got shape {q.shape}; a float or one per planning track ({T},)")
        if not (np.all(np.isfinite(q)) and np.all(q >= 0.0)):
            _fail(name, "must be finite and >= 0")
        tracker.predict()
        tracker.update(scene.looks)


@dataclass(frozen=True)
class Scene:
    """A small scene to check a tracker on: a step's looks at its initial tracks."""

    looks: Looks


#: The named checks, in the order they run.
CHECKS: dict[str, Callable[[Tracker, Scene], None]] = {
    "reports_valid_tracks": check_reports_valid_tracks,
    "predict_keeps_tracks_valid": check_predict_keeps_tracks_valid,
    "update_accounts_for_every_look": check_update_accounts_for_every_look,
    "no_look_changes_only_the_prediction": check_no_look_changes_only_the_prediction,
    "labels_come_only_from_detections": check_labels_come_only_from_detections,
    "planning_process_noise_is_valid": check_planning_process_noise_is_valid,
}


def check_tracker(make: Callable[[], Tracker], scene: Scene) -> TrackerReport:
    """Run every check of :data:`CHECKS` on a fresh tracker from ``make()`` each.

    Raises
    ------
    TrackerCheckError
        Naming the first check that fails.
    """
    for check in CHECKS.values():
        tracker = make()
        if not isinstance(tracker, Tracker):
            _fail("protocol", f"{type(tracker).__name__} lacks predict, update, tracks or "
                  "planning_process_noise")
        check(tracker, scene)
    return TrackerReport(tuple(CHECKS))
