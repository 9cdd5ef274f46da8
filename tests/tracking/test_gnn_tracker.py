"""The GNN tracker: the contract, the M-of-N logic in closed form, the assignment against
brute-force enumeration, the initiator against the PMB's new Bernoulli, and closed-loop
runs on the search scenario.

The second computations share no code with the tracker: the assignment by enumerating
every feasible assignment, the costs from scipy's Gaussian density, the detections from
the radar's noise-free measurement.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from sensorplan.models import linear, radar
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.base import Tracker
from sensorplan.tracking.checks import CHECKS, Scene, check_tracker
from sensorplan.tracking.gnn import GNNTracker, gnn_assignment
from sensorplan.tracking.pmb.sensing import Look
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from sensorplan.tracking.registry import TRACKERS, tracker_class
from looks_helpers import MEANS, SENSORS, looks_of

P0 = np.diag([400.0, 400.0, 4.0, 4.0])
WORLD = (600.0, 600.0)


# ----------------------------------------------------------------------------- contract


@pytest.mark.parametrize("params", [SensorParams(), SensorParams(clutter_rate=1.0),
                                    SensorParams(detection="swerling1", clutter_rate=2.0)])
def test_the_gnn_meets_the_tracker_contract_with_the_radar(params: SensorParams) -> None:
    table = radar_table((params, params))
    heads = np.arctan2(MEANS[:, 1] - SENSORS[:, 1], MEANS[:, 0] - SENSORS[:, 0])
    h, _, _, seen = radar.measure_looks(table, np.arange(2), MEANS[:, :2], SENSORS, heads)
    assert seen.all()
    far = radar.measure_looks(table, np.zeros(1, dtype=np.int64), MEANS[:1, :2] + [40.0, 0.0],
                              SENSORS[:1], heads[:1])[0]
    dets = (np.concatenate([h[0:1] + [3.0, 0.001], far]), h[1:1])   # two detections; a miss
    scene = Scene(looks_of(np.arange(2), SENSORS, heads, dets))
    model = MapModel(table, 1.0, WORLD)
    report = check_tracker(lambda: GNNTracker(model, means=MEANS, covs=P0), scene)
    assert report.checks == tuple(CHECKS)
    assert tracker_class("gnn") is GNNTracker
    assert TRACKERS["gnn"] == "sensorplan.tracking.gnn:GNNTracker"
    assert isinstance(GNNTracker(model), Tracker)


def test_the_gnn_meets_the_tracker_contract_with_the_linear_sensor() -> None:
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 2.0)
    z = np.array([[100.0, 101.0], [20.0, 250.0], [290.0, 10.0]])
    scene = Scene(looks_of([0], np.zeros((1, 2)), [0.0], (z,)))
    report = check_tracker(lambda: GNNTracker(MapModel(sensor, 1.0, (300.0, 300.0)),
                                              means=[[100.0, 100.0, 1.0, 0.0]], covs=P0 / 4),
                           scene)
    assert report.checks == tuple(CHECKS)


@pytest.mark.parametrize(("key", "value"), [("confirm_hits", 0), ("confirm_hits", 4),
                                            ("confirm_looks", 1), ("delete_misses", 0)])
def test_bad_arguments_are_refused(key: str, value: float) -> None:
    # The map model's own fields are checked in test_map_model.py.
    with pytest.raises(ValueError, match=key):
        GNNTracker(MapModel(radar_table((SensorParams(),)), 1.0, WORLD), **{key: value})


# ----------------------------------------------------------------------------- M-of-N logic

TARGET = np.array([300.0, 300.0])
SENSOR = np.array([[50.0, 50.0]])
TOWARD = math.atan2(250.0, 250.0)                # boresight on the target
AWAY = TOWARD + math.pi                          # the target behind the sensor


def one_target() -> tuple[GNNTracker, np.ndarray]:
    """An ideal radar (Pd = 1 in its sensing region, no clutter) and the noise-free
    detection of a target standing at TARGET."""
    table = radar_table((SensorParams(),))
    z = radar.measure_looks(table, np.zeros(1, dtype=np.int64), TARGET[None], SENSOR,
                            np.array([TOWARD]))[0]
    return GNNTracker(MapModel(table, 1.0, WORLD)), z


def step(tr: GNNTracker, heading: float, z: np.ndarray) -> np.ndarray:
    tr.predict()
    tr.update(looks_of([0], SENSOR, [heading], (z,)))
    return tr.tracks().labels


def test_a_target_is_confirmed_at_its_second_look_and_deleted_at_its_fifth_miss() -> None:
    tr, z = one_target()
    none = np.zeros((0, 2))
    assert len(step(tr, TOWARD, z)) == 0          # look 1: a tentative track, not reported
    assert len(tr.labels) == 1 and not tr.confirmed[0]
    assert list(step(tr, TOWARD, z)) == [0]       # look 2: 2 hits in 2 looks, confirmed
    # The target is gone; the looks keep covering its predicted place.
    for miss in range(1, 5):
        assert list(step(tr, TOWARD, none)) == [0], f"deleted at miss {miss}"
        assert tr.misses[0] == miss
    assert len(step(tr, TOWARD, none)) == 0       # the 5th missed look deletes it
    assert len(tr.labels) == 0


def test_looks_that_do_not_cover_a_track_do_not_count_toward_its_deletion() -> None:
    tr, z = one_target()
    none = np.zeros((0, 2))
    step(tr, TOWARD, z)
    step(tr, TOWARD, z)
    for _ in range(4):
        step(tr, TOWARD, none)
    # Two looks the other way: the track's predicted mean is outside their sensing region.
    look = Look(0, SENSOR[0], AWAY)
    assert tr.sensing.detectable(tr.means[:, :2], look)[0] == 0.0
    for _ in range(2):
        assert list(step(tr, AWAY, none)) == [0]
    assert tr.misses[0] == 4
    assert len(step(tr, TOWARD, none)) == 0       # the 5th look at it that misses


def test_a_tentative_track_is_deleted_once_it_cannot_reach_its_hits() -> None:
    # 2 of 3: hit (start), miss, then a look that does not cover it, then a miss: deleted
    # at its 3rd look with 1 hit. A detection on the second look instead confirms it.
    tr, z = one_target()
    none = np.zeros((0, 2))
    step(tr, TOWARD, z)
    step(tr, TOWARD, none)
    assert (tr.hits[0], tr.looks[0], tr.confirmed[0]) == (1, 2, False)
    step(tr, AWAY, none)
    assert tr.looks[0] == 2
    step(tr, TOWARD, none)
    assert len(tr.labels) == 0 and tr.next_label == 1
    # 3 of 4 with a miss in between: confirmed at the 4th look.
    table = radar_table((SensorParams(),))
    tr = GNNTracker(MapModel(table, 1.0, WORLD), confirm_hits=3, confirm_looks=4)
    for k, d in enumerate((z, z, none, z)):
        assert len(step(tr, TOWARD, d)) == (1 if k == 3 else 0)
    assert list(tr.tracks().existence) == [1.0]


def test_two_looks_of_one_step_confirm_a_track_and_labels_persist() -> None:
    table = radar_table((SensorParams(), SensorParams()))
    xy = np.array([[50.0, 50.0], [550.0, 50.0]])
    heads = np.arctan2(TARGET[1] - xy[:, 1], TARGET[0] - xy[:, 0])
    h = radar.measure_looks(table, np.arange(2), np.repeat(TARGET[None], 2, 0), xy, heads)[0]
    tr = GNNTracker(MapModel(table, 1.0, WORLD), means=MEANS[1:], covs=P0)
    tr.predict()
    tr.update(looks_of([0, 1], xy, heads, (h[:1], h[1:])))
    assert list(tr.tracks().labels) == [0, 1]     # the known target keeps label 0


# ----------------------------------------------------------------------------- association


def brute_force(cost: np.ndarray) -> tuple[float, tuple[int, ...]]:
    """The least total cost over every assignment of rows to distinct finite columns or to
    nothing (cost 0), and that assignment."""
    n, m = cost.shape
    best: tuple[float, tuple[int, ...]] = (0.0, (-1,) * n)
    for choice in itertools.product(range(-1, m), repeat=n):
        cols = [c for c in choice if c >= 0]
        if len(cols) != len(set(cols)):
            continue
        total = sum(cost[i, c] for i, c in enumerate(choice) if c >= 0)
        if math.isfinite(total) and total < best[0]:
            best = (total, choice)
    return best


def test_the_assignment_is_the_least_cost_one_of_all_feasible_assignments() -> None:
    rng = np.random.default_rng(20261203)
    for _ in range(300):
        n, m = int(rng.integers(1, 5)), int(rng.integers(0, 6))
        cost = rng.normal(-1.0, 2.0, (n, m))
        cost[rng.random((n, m)) < 0.4] = np.inf                  # outside the gate
        got = gnn_assignment(cost)
        total, want = brute_force(cost)
        assert tuple(got) == want, (cost, got, want)
        used = got[got >= 0]
        assert len(used) == len(set(used))
        assert math.isclose(sum(cost[i, c] for i, c in enumerate(got) if c >= 0), total,
                            rel_tol=1e-12, abs_tol=1e-12)


def test_costs_are_the_negative_log_likelihood_ratio_against_clutter() -> None:
    # Linear sensor: Pd = 0.8 everywhere in its area, clutter density rate / area.
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 4.0, 0.8, 3.0)
    means = np.array([[100.0, 100.0, 0.0, 0.0], [110.0, 104.0, 0.0, 0.0],
                      [250.0, 250.0, 0.0, 0.0]])
    covs = np.stack([P0 / 16, P0 / 9, P0 / 25])
    tr = GNNTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=covs)
    Z = np.array([[102.0, 99.0], [108.0, 106.0], [20.0, 280.0]])
    cost, looked, _ = tr.costs(Look(0, np.zeros(2), 0.0), Z)
    assert looked.all()
    kappa = 3.0 / 300.0 ** 2
    for i in range(3):
        S = covs[i, :2, :2] + 4.0 * np.eye(2)
        for j in range(3):
            d2 = (Z[j] - means[i, :2]) @ np.linalg.solve(S, Z[j] - means[i, :2])
            if d2 >= -2.0 * math.log(1.0 - 0.999):
                assert cost[i, j] == np.inf
                continue
            lik = multivariate_normal(means[i, :2], S).pdf(Z[j])
            want = -math.log(0.8 * lik / ((1.0 - 0.8) * kappa))
            assert math.isclose(cost[i, j], want, rel_tol=1e-10), (i, j)
    assert np.isfinite(cost[:2, :2]).all() and np.isinf(cost[2, :2]).all()
    # The look: the two near tracks take the two near detections, the far one starts a
    # tentative track, the far track is a missed look.
    out = tr.update(looks_of([0], np.zeros((1, 2)), [0.0], (Z,)))
    assert list(out.used) == [2] and list(out.discarded) == [0]
    assert list(out.negative) == [False, False, True]
    assert list(tr.labels) == [0, 1, 2, 3] and list(tr.confirmed) == [True] * 3 + [False]


def test_a_new_track_has_the_density_the_pmb_gives_a_target_first_seen() -> None:
    # The PMB with a uniform undetected intensity and no Bernoulli starts one from each
    # detection; the GNN's tentative tracks have the same densities.
    table = radar_table((SensorParams(),))
    hd = TOWARD
    pts = np.array([[300.0, 300.0], [330.0, 250.0]])
    Z = radar.measure_looks(table, np.zeros(2, dtype=np.int64), pts, np.repeat(SENSOR, 2, 0),
                            np.full(2, hd))[0] + [[2.0, 0.003], [-4.0, -0.002]]
    looks = looks_of([0], SENSOR, [hd], (Z,))
    model = MapModel(table, 1.0, WORLD)
    pmb = PMBTracker(model, initial_undetected=3.0, prune_threshold=0.0)
    pmb.update(looks)
    gnn = GNNTracker(model)
    gnn.update(looks)
    assert len(pmb.bern) == len(gnn.labels) == 2
    np.testing.assert_allclose(gnn.means, pmb.bern.means, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(gnn.covs, pmb.bern.covs, rtol=1e-10, atol=1e-9)
    # one detection says nothing of the velocity: the prior's (mean 0, 10.5 m^2/s^2)
    np.testing.assert_allclose(gnn.means[:, 2:], 0.0, atol=1e-9)
    np.testing.assert_allclose(gnn.covs[:, 2:, 2:], np.broadcast_to(10.5 * np.eye(2),
                                                                    (2, 2, 2)), atol=1e-9)


def test_a_detection_off_the_map_starts_no_track() -> None:
    sensor = linear.LinearSensor((-200.0, -200.0, 500.0, 500.0), 1.0, 0.9, 1.0)
    tr = GNNTracker(MapModel(sensor, 1.0, (300.0, 300.0)))
    out = tr.update(looks_of([0], np.zeros((1, 2)), [0.0],
                             (np.array([[-150.0, -150.0], [150.0, 150.0]]),)))
    assert (list(out.used), list(out.discarded)) == ([0], [1])
    assert len(tr.labels) == 1 and np.allclose(tr.means[0, :2], 150.0, atol=1.0)


def test_a_track_that_leaves_the_map_dies_with_an_exit_edge_and_turns_with_a_closed_one(
        ) -> None:
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 0.0)
    start = np.array([[295.0, 150.0, 3.0, 0.0]])
    for edge, alive in (("exit", 1), (None, 3), ("closed", 3)):
        tr = GNNTracker(MapModel(sensor, 1.0, (300.0, 300.0), map_edge=edge), means=start,
                        covs=P0)
        tr.predict()
        n = [len(tr.tracks())]
        for _ in range(2):
            tr.predict()
            n.append(len(tr.tracks()))
        assert sum(n) == alive
        if edge == "closed":          # kept in the map, its mean turned back inward
            x = tr.tracks().means[0]
            assert 0.0 <= x[0] <= 300.0 and x[2] < 3.0


# ----------------------------------------------------------------------------- closed loop


def test_a_closed_loop_run_on_the_search_scenario_reports_gospa_and_repeats() -> None:
    import dataclasses

    from sensorplan.simulation import RunSettings, run_episode
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import TrackerSettings
    from sensorplan.study.set_metrics import episode_set_metrics

    sc = dataclasses.replace(search_scenario(), look_detects="all")
    s = RunSettings(planner="pg", steps=40, tracker=TrackerSettings(kind="gnn"))
    a = run_episode(sc, s, 11)
    sm = episode_set_metrics(a, c=50.0)
    assert sm.gospa.distance.shape == (40,) and np.all(np.isfinite(sm.gospa.distance))
    assert np.all(sm.gospa.distance >= 0.0)
    # the three targets known at the start are confirmed tracks 0..2 from the first step
    first = a.track_label[a.track_step == 1]
    assert {0, 1, 2} <= set(first.tolist())
    assert np.all(a.track_existence == 1.0)
    b = run_episode(sc, s, 11)
    for name in ("truth", "alive", "track_step", "track_label", "track_mean", "track_cov"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
