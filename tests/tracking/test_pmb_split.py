"""Split hypotheses in the PMB tracker: a Bernoulli whose missed and detected hypotheses
each hold at least ``split_existence`` becomes two. Checked: the two parts' existences sum
to the merged Bernoulli's and their moment-matched mixture is the merged Gaussian; the
detected part is the Kalman update in closed form and the missed part the prior (a sensor
that sees everywhere leaves the density as it was); which part keeps the label; no split
when one hypothesis is weak or when the split would take a track out of the report; the
settings' refusals."""

from __future__ import annotations

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.models import linear
from sensorplan.simulation.settings import TrackerSettings
from sensorplan.tracking.pmb import hypotheses as hyp
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from looks_helpers import LINEAR_MEAN as MEAN
from looks_helpers import LINEAR_P0 as P0
from looks_helpers import linear_pmb, moments, one_scan


def tracker(split: float, existence: float = 0.99) -> PMBTracker:
    return linear_pmb(existence, split_existence=split)


def test_a_split_keeps_the_merged_existence_and_moments() -> None:
    z = np.array([[195.0, 150.0]])                   # 45 m off: about even odds
    on, off = tracker(0.1), tracker(0.0)
    on.update(one_scan(z))
    off.update(one_scan(z))
    assert len(off.bern) == 1 and len(on.bern) == 2 and on.splits == 1
    assert abs(on.bern.r.sum() - off.bern.r[0]) <= 1e-12
    mean, cov = moments(on.bern.r, on.bern.means, on.bern.covs)
    np.testing.assert_allclose(mean, off.bern.means[0], rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(cov, off.bern.covs[0], rtol=0.0, atol=1e-9)
    # The detected part: the Kalman update with H = [I 0], R = I, in closed form.
    S = P0[:2, :2] + np.eye(2)
    K = P0[:, :2] @ np.linalg.solve(S, np.eye(2))
    x = MEAN[0] + K @ (z[0] - MEAN[0, :2])
    P = P0 - K @ S @ K.T
    # The missed part: the prior (the sensor sees everywhere, so a miss leaves the
    # density).
    det_first = on.bern.r[0] >= on.bern.r[1]
    d, m = (0, 1) if det_first else (1, 0)
    np.testing.assert_allclose(on.bern.means[d], x, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(on.bern.covs[d], P, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(on.bern.means[m], MEAN[0], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(on.bern.covs[m], P0, rtol=0.0, atol=1e-12)
    # The larger part keeps the label; the other takes the next one.
    assert on.bern.labels.tolist() == [0, 1] and on.bern.r[0] >= on.bern.r[1]
    assert on.next_label == off.next_label + 1


def test_a_detection_near_the_track_is_merged_as_without_splitting() -> None:
    z = np.array([[152.0, 149.0]])
    on, off = tracker(0.1), tracker(0.0)
    on.update(one_scan(z))
    off.update(one_scan(z))
    assert on.splits == 0 and on.bern.labels.tolist() == [0]
    np.testing.assert_array_equal(on.bern.r, off.bern.r)
    np.testing.assert_array_equal(on.bern.means, off.bern.means)
    np.testing.assert_array_equal(on.bern.covs, off.bern.covs)


def _one_row(w_miss: float, w_det: float) -> tuple:
    h = hyp.Hypotheses(rows=np.array([0]), started=np.zeros(0, dtype=np.int64),
                       r_new=np.zeros(0), gauss=np.array([0]), unique=np.array([0]),
                       which=np.array([0]), det=np.array([0]), weight=np.array([w_det]),
                       group=np.array([0]), started_alone=0)
    xu, Pu = np.array([[10.0, 0.0, 0.0, 0.0]]), np.eye(4)[None]
    mm, mP = np.zeros((1, 4)), 4.0 * np.eye(4)[None]
    mean, cov = moments(np.array([w_miss, w_det]), np.concatenate([mm, xu]),
                        np.concatenate([mP, Pu]))
    return h, xu, Pu, (np.array([w_miss + w_det]), mean[None], cov[None]), mm, mP


@pytest.mark.parametrize(("w_miss", "w_det", "parts"), [
    (0.3, 0.6, (0.6, 0.3)),          # merged 0.9 reported, the detected part 0.6 too
    (0.45, 0.45, None),              # merged 0.9 reported, neither part would be
    (0.2, 0.25, (0.25, 0.2)),        # merged 0.45 not reported: split
    (0.05, 0.9, None),               # the missed part under split_existence
    (0.1, 0.3, (0.3, 0.1))])         # at split_existence exactly: split
def test_which_rows_split(w_miss: float, w_det: float, parts: tuple | None) -> None:
    h, xu, Pu, merged, mm, mP = _one_row(w_miss, w_det)
    r, m, P, r_new, m_new, P_new = tracker(0.1)._split(np.array([w_miss]), h, xu, Pu,
                                                       merged, mm, mP)
    if parts is None:
        assert len(r_new) == 0
        np.testing.assert_array_equal(r, merged[0])
        np.testing.assert_array_equal(m, merged[1])
        return
    assert (r[0], r_new[0]) == parts
    keep_det = w_det >= w_miss
    np.testing.assert_array_equal(m[0], xu[0] if keep_det else mm[0])
    np.testing.assert_array_equal(m_new[0], mm[0] if keep_det else xu[0])
    np.testing.assert_array_equal(P_new[0], mP[0] if keep_det else Pu[0])


@pytest.mark.parametrize(("kw", "key"), [
    (dict(split_existence=0.6), "split_existence"),
    (dict(split_existence=-0.1), "split_existence"),
    (dict(split_existence=1e-4), "split_existence"),            # below prune_threshold
    (dict(split_existence=0.1, bernoulli_model="imm"), "split_existence")])
def test_the_settings_refuse_a_split_they_cannot_run(kw: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=key):
        TrackerSettings(kind="pmb", **kw)


def test_the_tracker_refuses_a_split_with_modes_or_out_of_range() -> None:
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    model = MapModel(sensor, 1.0, (300.0, 300.0))
    for kw in (dict(split_existence=0.7), dict(split_existence=1e-4),
               dict(split_existence=0.1, mode_process_noise=(1.0, 5.0),
                    switching=np.array([[0.9, 0.1], [0.1, 0.9]]))):
        with pytest.raises(ValueError, match="split_existence"):
            PMBTracker(model, **kw)
