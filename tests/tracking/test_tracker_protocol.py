"""The tracker protocol: the known-target tracker meets it, the contract check catches a
tracker that breaks it, and labels map back to tracks."""

from __future__ import annotations

import numpy as np
import pytest

from sensorplan.models.radar import measure_looks
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.simulation.run import tracks_index
from sensorplan.tracking.base import Looks, Tracker, TrackSet, UpdateRecord
from sensorplan.tracking.checks import CHECKS, Scene, TrackerCheckError, check_tracker
from sensorplan.tracking.tracker import KnownTargetTracker

P0 = np.diag([400.0, 400.0, 4.0, 4.0])
MEANS = np.array([[300.0, 300.0, 1.0, 0.0], [250.0, 420.0, 0.0, 1.0]])
SENSORS = np.array([[50.0, 50.0], [500.0, 100.0]])


def scene(params: SensorParams) -> tuple[np.ndarray, Scene]:
    table = radar_table((params, params))
    heads = np.arctan2(MEANS[:, 1] - SENSORS[:, 1], MEANS[:, 0] - SENSORS[:, 0])
    h, _, _, seen = measure_looks(table, np.arange(2), MEANS[:, :2], SENSORS, heads)
    assert seen.all()
    dets = (h[0:1] + [3.0, 0.001], h[1:1])          # one detection, one empty look (a miss)
    looks = Looks(sensors=np.arange(2), aims=np.arange(2), positions=SENSORS, headings=heads,
                  detections=dets)
    return table, Scene(looks)


@pytest.mark.parametrize("params", [SensorParams(), SensorParams(clutter_rate=1.0)])
def test_the_known_target_tracker_meets_the_contract(params: SensorParams) -> None:
    table, sc = scene(params)
    report = check_tracker(lambda: KnownTargetTracker(MEANS, P0, 1.0, table,
                                                      process_noise=0.05,
                                                      gate_probability=0.999), sc)
    assert report.checks == tuple(CHECKS)
    assert str(report).startswith(f"{len(CHECKS)} checks passed")
    tracker = KnownTargetTracker(MEANS, P0, 1.0, table, process_noise=0.05)
    assert isinstance(tracker, Tracker)
    tracks = tracker.tracks()
    np.testing.assert_array_equal(tracks.labels, [0, 1])
    np.testing.assert_array_equal(tracks.existence, [1.0, 1.0])


class _Broken(KnownTargetTracker):
    """Reports one flag fewer than it has tracks."""

    def update(self, looks: Looks) -> UpdateRecord:
        rec = super().update(looks)
        return UpdateRecord(rec.negative[:-1], rec.inflated, rec.restarted, rec.map_corrected,
                            rec.used, rec.discarded)


class _Shaky(KnownTargetTracker):
    """Reports a covariance that is not positive definite."""

    def tracks(self) -> TrackSet:
        t = super().tracks()
        covs = t.covs.copy()
        covs[0, 0, 0] = -1.0
        return TrackSet(t.means, covs, t.existence, t.labels)


@pytest.mark.parametrize(("cls", "check"), [(_Broken, "update_accounts_for_every_look"),
                                            (_Shaky, "reports_valid_tracks")])
def test_the_contract_check_names_what_a_broken_tracker_breaks(cls: type, check: str) -> None:
    table, sc = scene(SensorParams())
    with pytest.raises(TrackerCheckError, match=f"check '{check}'"):
        check_tracker(lambda: cls(MEANS, P0, 1.0, table, process_noise=0.05), sc)


def test_looks_need_one_entry_per_look() -> None:
    with pytest.raises(ValueError, match="one entry per look"):
        Looks(sensors=np.arange(2), aims=np.arange(1), positions=np.zeros((2, 2)),
              headings=np.zeros(2), detections=(np.zeros((0, 2)),) * 2)


def test_labels_map_back_to_the_tracks_that_carry_them() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        labels = rng.choice(50, size=rng.integers(0, 12), replace=False)
        tracks = TrackSet(np.zeros((len(labels), 4)), np.tile(np.eye(4), (len(labels), 1, 1)),
                          np.ones(len(labels)), labels)
        asked = rng.integers(-1, 50, size=7)
        got = tracks_index(tracks, asked)
        for a, g in zip(asked, got):
            want = int(np.flatnonzero(labels == a)[0]) if a >= 0 and a in labels else -1
            assert g == want
