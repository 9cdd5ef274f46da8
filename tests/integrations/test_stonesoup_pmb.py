"""The PMB tracker behind Stone Soup's tracker interface, the Stone Soup peer trackers of the
filter benchmarks, the example and the comparison script's metric.

Skipped cleanly where Stone Soup is not installed (the ``stonesoup`` extra).
"""

from __future__ import annotations

import datetime
import runpy
from pathlib import Path

import numpy as np
import pytest

stonesoup = pytest.importorskip("stonesoup")

from scipy.stats import norm  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel, ConstantVelocity)
from stonesoup.types.detection import Detection  # noqa: E402

from sensorplan.integrations.stonesoup import (MapRect, PMBStoneSoupTracker,  # noqa: E402
                                               gaussian_cell_masses)
from sensorplan.integrations.stonesoup._peers import (benchmark_model,  # noqa: E402
                                                      gmphd_tracker, jpda_deleter,
                                                      to_detections)
from sensorplan.integrations.stonesoup._pmb import motion_matrices  # noqa: E402
from sensorplan.models import linear  # noqa: E402
from sensorplan.models.motion import cv_matrices  # noqa: E402
from sensorplan.models.scripted import dwna_matrices  # noqa: E402
from sensorplan.study.set_metrics import gospa  # noqa: E402
from sensorplan.tracking.base import Looks  # noqa: E402
from sensorplan.tracking.pmb.map_tracker import MapModel  # noqa: E402
from sensorplan.tracking.pmb.tracker import PMBTracker  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
T0 = datetime.datetime(2026, 1, 1)
WORLD = MapRect(-150.0, -100.0, 300.0, 300.0)
MM = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))
SETTINGS = {"births": "uniform", "birth_rate": 0.02, "initial_undetected": 1.0,
            "velocity_var": 2.0}


def scans(steps: int, seed: int) -> list[np.ndarray]:
    """Core-frame scans of two straight targets with williams15's clutter and P_d."""
    rng = np.random.default_rng(seed)
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    out = []
    for k in range(1, steps + 1):
        xy = np.array([[60.0 + k, 60.0 + 0.5 * k], [220.0 - k, 200.0]])
        out.append(linear.scan(sensor, xy, rng)[0])
    return out


def adapter(**kw) -> PMBStoneSoupTracker:
    args = dict(measurement_model=MM, world=WORLD, dt=1.0, detection_probability=0.9,
                clutter_rate=10.0, settings=SETTINGS, start_time=T0)
    args.update(kw)
    return PMBStoneSoupTracker(**args)


def direct() -> PMBTracker:
    tracker_settings = {k: v for k, v in SETTINGS.items() if k != "velocity_var"}
    return PMBTracker(MapModel(linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0),
                               1.0, (300.0, 300.0), velocity_var=SETTINGS["velocity_var"]),
                      **tracker_settings)


def as_detections(z: np.ndarray, time: datetime.datetime) -> set[Detection]:
    return to_detections(z + WORLD.origin, time, MM)


def one_look(z: np.ndarray) -> Looks:
    return Looks(np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64), np.zeros((1, 2)),
                 np.zeros(1), (z,))


def test_the_adapter_reports_what_the_pmb_tracker_reports_on_the_same_scans():
    tracker, ref = adapter(), direct()
    for k, z in enumerate(scans(25, 3), start=1):
        time = T0 + datetime.timedelta(seconds=k)
        when, tracks = tracker.update_tracker(time, as_detections(z, time))
        ref.predict()
        # The adapter orders a scan by x then y; the reference gets the same order.
        ref.update(one_look(z[np.lexsort((z[:, 1], z[:, 0]))]))
        want = ref.tracks()
        assert when == time
        by_id = {t.id: t for t in tracks}
        assert sorted(by_id) == sorted(str(label) for label in want.labels)
        for j, label in enumerate(want.labels):
            state = by_id[str(label)].state
            assert state.timestamp == time
            mean = np.ravel(state.state_vector)
            np.testing.assert_allclose(mean[[0, 2]] - WORLD.origin, want.means[j, :2],
                                       rtol=0, atol=1e-9)
            np.testing.assert_allclose(mean[[1, 3]], want.means[j, 2:], rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.asarray(state.covar)[np.ix_([0, 2], [0, 2])],
                                       want.covs[j][:2, :2], rtol=1e-12, atol=0)
            assert float(state.existence_probability) == pytest.approx(want.existence[j],
                                                                       abs=1e-12)
    assert len(tracks) == 2                          # both targets held at the end


def test_a_track_keeps_its_object_and_id_for_its_life():
    tracker = adapter()
    seen: dict[str, object] = {}
    for k, z in enumerate(scans(20, 5), start=1):
        time = T0 + datetime.timedelta(seconds=k)
        _, tracks = tracker.update_tracker(time, as_detections(z, time))
        for t in tracks:
            assert seen.setdefault(t.id, t) is t
            assert t.state.timestamp == time
    assert tracker.tracks and all(len(t) > 1 for t in tracker.tracks)


def test_iterating_over_a_detector_gives_what_one_scan_at_a_time_gives():
    data = [(T0 + datetime.timedelta(seconds=k), as_detections(z, T0 + datetime.timedelta(
        seconds=k))) for k, z in enumerate(scans(12, 8), start=1)]
    a = adapter(detector=data)
    b = adapter()
    for (time, dets), (t_a, tracks_a) in zip(data, a, strict=True):
        t_b, tracks_b = b.update_tracker(time, dets)
        assert t_a == t_b
        assert {t.id: np.ravel(t.state.state_vector).tolist() for t in tracks_a} == \
            {t.id: np.ravel(t.state.state_vector).tolist() for t in tracks_b}


def test_a_gap_of_two_steps_predicts_twice():
    z = scans(3, 1)
    tracker, ref = adapter(), direct()
    for k in (1, 3):
        time = T0 + datetime.timedelta(seconds=k)
        tracker.update_tracker(time, as_detections(z[k - 1], time))
    ref.predict()
    ref.update(one_look(z[0][np.lexsort((z[0][:, 1], z[0][:, 0]))]))
    ref.predict()
    ref.predict()
    ref.update(one_look(z[2][np.lexsort((z[2][:, 1], z[2][:, 0]))]))
    np.testing.assert_allclose(tracker.pmb.bern.r, ref.bern.r, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="whole number of dt"):
        time = T0 + datetime.timedelta(seconds=4.5)
        tracker.update_tracker(time, set())


def test_other_measurement_models_are_refused_with_a_clear_error():
    with pytest.raises(TypeError, match="LinearGaussian"):
        adapter(measurement_model=CartesianToBearingRange(ndim_state=4, mapping=(0, 2),
                                                          noise_covar=np.eye(2)))
    with pytest.raises(ValueError, match="mapping"):
        adapter(measurement_model=LinearGaussian(ndim_state=4, mapping=(0, 1),
                                                 noise_covar=np.eye(2)))
    with pytest.raises(ValueError, match="sigma\\^2 I"):
        adapter(measurement_model=LinearGaussian(ndim_state=4, mapping=(0, 2),
                                                 noise_covar=np.diag([1.0, 2.0])))
    with pytest.raises(ValueError, match="transition_model"):
        adapter(settings={"motion": (np.eye(4), np.eye(4))})
    with pytest.raises(ValueError, match="settings: dt"):
        adapter(settings={"dt": 2.0})
    with pytest.raises(ValueError, match="resolution"):
        adapter(settings={"resolution": 0.0})


def test_the_settings_are_split_between_the_map_model_and_the_tracker():
    tracker = adapter(settings={"resolution": 30.0, "velocity_var": 2.0, "process_noise": 0.2,
                                "gate_probability": 0.99, "map_edge": "closed",
                                "report_threshold": 0.4, "survival_probability": 0.9,
                                "termination_threshold": 0.1})
    model = tracker.pmb.model
    assert (model.resolution, model.velocity_var, model.process_noise, model.gate_probability,
            model.map_edge) == (30.0, 2.0, 0.2, 0.99, "closed")
    assert (model.dt, model.world) == (1.0, (300.0, 300.0))
    assert tracker.pmb.grid.nx == tracker.pmb.grid.ny == 10                # 300 m / 30 m
    assert (tracker.pmb.report_threshold, tracker.pmb.survival_probability,
            tracker.pmb.termination_threshold) == (0.4, 0.9, 0.1)


def test_a_stonesoup_cv_model_is_the_cwna_model():
    model = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.3)] * 2)
    F, Q = motion_matrices(model, 2.0)
    F0, Q0 = cv_matrices(2.0, 0.3)
    np.testing.assert_allclose(F, F0, rtol=1e-14, atol=0)
    np.testing.assert_allclose(Q, Q0, rtol=1e-14, atol=0)


def test_cell_masses_are_the_gaussian_mass_of_each_cell():
    world = MapRect(-100.0, 0.0, 200.0, 100.0)
    masses = gaussian_cell_masses(world, 25.0, [[-20.0, 40.0], [60.0, 10.0]],
                                  [[30.0, 15.0], [5.0, 50.0]], [2.0, 0.5])
    assert masses.shape == (8 * 4,)
    # Cell (row 1, column 3): x in [-25, 0], y in [25, 50] (world), by scipy's normal cdf.
    want = 0.0
    for (mx, my), (sx, sy), w in zip([(-20.0, 40.0), (60.0, 10.0)], [(30.0, 15.0), (5.0, 50.0)],
                                     [2.0, 0.5]):
        want += w * ((norm.cdf(0.0, mx, sx) - norm.cdf(-25.0, mx, sx))
                     * (norm.cdf(50.0, my, sy) - norm.cdf(25.0, my, sy)))
    assert masses[1 * 8 + 3] == pytest.approx(want, rel=1e-12)
    # A component well inside the map puts all its weight on it.
    inside = gaussian_cell_masses(world, 25.0, [[0.0, 50.0]], [[3.0, 3.0]], [1.5])
    assert inside.sum() == pytest.approx(1.5, rel=1e-12)


def test_the_benchmarks_filter_models_are_their_sources():
    w = benchmark_model("williams15")
    F, Q = cv_matrices(1.0, 0.01)
    np.testing.assert_array_equal(w.F, F)
    np.testing.assert_array_equal(w.Q, Q)
    assert w.velocity_var == 1.0 and w.birth_weights.tolist() == [0.005]
    v = benchmark_model("vo12")
    F, B = dwna_matrices(1.0)
    np.testing.assert_allclose(v.Q, 25.0 * B @ B.T, rtol=1e-15)
    assert v.clutter_density == 30.0 / 2000.0**2
    # The Stone Soup transition model is the same model in Stone Soup's order.
    F_ss, Q_ss = motion_matrices(v.transition_model, 1.0)
    np.testing.assert_array_equal(F_ss, v.F)
    np.testing.assert_array_equal(Q_ss, v.Q)
    with pytest.raises(ValueError, match="deleter"):
        jpda_deleter("sometimes", v)


def test_a_higher_state_threshold_reports_a_subset():
    model = benchmark_model("williams15")
    tr = gmphd_tracker(model, T0)
    sensor = model.sensor
    rng = np.random.default_rng(4)
    for k in range(1, 8):
        time = T0 + datetime.timedelta(seconds=k)
        z, _ = linear.scan(sensor, np.array([[100.0, 100.0], [200.0, 150.0]]), rng)
        _, tracks = tr.update_tracker(time, to_detections(z, time, model.measurement_model))
        high = {id(c) for c in tr.reported(0.5)}
        low = {id(c) for c in tr.reported(0.25)}
        assert high <= low
        assert {t.state.tag for t in tracks} == {c.tag for c in tr.reported(0.5)}


def test_the_example_prints_gospa_that_stone_soup_and_sensorplan_agree_on():
    module = runpy.run_path(str(ROOT / "examples" / "stonesoup_pmb.py"), run_name="example")
    results = module["run"](15, 7, 10.0)
    assert set(results) == {"pmb (sensorplan)", "JPDA (Stone Soup)"}
    for ss, sp in results.values():
        assert ss.shape == sp.shape == (15, 4)
        np.testing.assert_allclose(sp, ss, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(sp[:, 0] ** 2, sp[:, 1:].sum(axis=1), rtol=1e-9)


def test_the_comparison_scripts_gospa_is_the_mean_of_each_steps_gospa():
    script = runpy.run_path(str(ROOT / "benchmarks" / "compare_trackers.py"),
                            run_name="script")
    truth, zs = script["draw_run"]("williams15", np.random.default_rng(12))
    truth2, zs2 = script["draw_run"]("williams15", np.random.default_rng(12))
    assert all(np.array_equal(a, b) for a, b in zip(zs, zs2, strict=True))
    # Tracks: each live target's position with noise, dropping the last one every other step.
    rng = np.random.default_rng(0)
    tracks = []
    for s, x in enumerate(truth):
        kept = x[: len(x) - s % 2]
        tracks.append(kept + rng.normal(0.0, 3.0, kept.shape))
    got = script["gospa_parts"](truth, tracks, 10.0)
    each = np.array([[g.distance, g.localisation, g.missed, g.false]
                     for g in (gospa(x, y, 10.0) for x, y in zip(truth, tracks, strict=True))])
    np.testing.assert_allclose(got, each.mean(axis=0), rtol=1e-12)
