"""Stone Soup interop: converters, measurement model, EKF, manager, reward, example.

Skipped cleanly where Stone Soup is not installed (the ``stonesoup`` extra).
"""

from __future__ import annotations

import dataclasses
import datetime
import itertools
import math
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

stonesoup = pytest.importorskip("stonesoup")

from stonesoup.types.angle import Bearing  # noqa: E402
from stonesoup.models.base import Model  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel, ConstantVelocity)
from stonesoup.movable.grid import NStepDirectionalGridMovable  # noqa: E402
from stonesoup.platform import FixedPlatform  # noqa: E402
from stonesoup.predictor.kalman import ExtendedKalmanPredictor  # noqa: E402
from stonesoup.types.array import StateVector  # noqa: E402
from stonesoup.types.detection import Clutter, Detection, TrueDetection  # noqa: E402
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState  # noqa: E402
from stonesoup.types.hypothesis import SingleHypothesis  # noqa: E402
from stonesoup.types.state import GaussianState, State  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402
from stonesoup.updater.kalman import ExtendedKalmanUpdater  # noqa: E402

from sensorplan.tracking import ekf  # noqa: E402
from sensorplan.models.angles import wrap_angle  # noqa: E402
from sensorplan.models.motion import cv_matrices  # noqa: E402
from sensorplan.errors import ConfigError  # noqa: E402
from sensorplan.planners.information import potential  # noqa: E402
from sensorplan.integrations import stonesoup as ss  # noqa: E402
from sensorplan.planners import make_planner  # noqa: E402
from sensorplan.planners.problem import MapRect, Plan, PlanningProblem, move_vectors  # noqa: E402
from sensorplan.simulation.scenario import draw_initial, make_truth, paper_scenario  # noqa: E402
from sensorplan.simulation.settings import TrackerSettings  # noqa: E402
from radar_reference import jacobian, measure, noise_cov, visible  # noqa: E402
from sensorplan.models.sensors import SensorParams, radar_table  # noqa: E402
from sensorplan.simulation import RunSettings, run_episode, run_streams  # noqa: E402

T0 = datetime.datetime(2024, 1, 1)
ROOT = Path(__file__).resolve().parents[2]


def _covariance(rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(4, 4)) * np.array([15.0, 15.0, 1.5, 1.5])[:, None]
    return A @ A.T + np.diag([25.0, 25.0, 0.5, 0.5])


def _transition(q: float) -> CombinedLinearGaussianTransitionModel:
    return CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])


def _platforms(positions, headings, altitudes=(490.0, 500.0, 510.0), **movable):
    out = []
    for (x, y), h, z in zip(positions, headings, altitudes):
        radar = ss.SensorplanRadar(params=SensorParams(altitude=z), heading=float(h))
        ctl = ss.LatticeMovable(states=[State([[x], [y], [z]], timestamp=T0)],
                                position_mapping=(0, 1, 2), **movable)
        out.append(FixedPlatform(movement_controller=ctl, sensors=[radar]))
    return out


def test_the_core_never_imports_stonesoup():
    # Walk the package tree by hand: pkgutil.walk_packages would import the integrations
    # subpackages in order to recurse into them.
    code = ("import importlib, os, pkgutil, sys, sensorplan\n"
            "def walk(path, prefix):\n"
            "    for m in pkgutil.iter_modules(path, prefix):\n"
            "        if m.name.startswith('sensorplan.integrations.'):\n"
            "            continue\n"
            "        importlib.import_module(m.name)\n"
            "        if m.ispkg:\n"
            "            walk([os.path.join(path[0], m.name.rsplit('.', 1)[1])], m.name + '.')\n"
            "walk(sensorplan.__path__, 'sensorplan.')\n"
            "bad = sorted(n for n in sys.modules if n.split('.')[0] == 'stonesoup')\n"
            "assert not bad, bad\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


# ------------------------------------------------------------------------------ converters


def test_state_order_is_the_documented_permutation():
    np.testing.assert_array_equal(ss.to_stonesoup_mean([1.0, 2.0, 3.0, 4.0]), [1, 3, 2, 4])
    P = np.arange(16.0).reshape(4, 4)
    Pss = ss.to_stonesoup_cov(P)
    for a, b in itertools.product(range(4), repeat=2):
        assert Pss[a, b] == P[ss.STONESOUP_ORDER[a], ss.STONESOUP_ORDER[b]]


def test_converters_round_trip_exactly(rng):
    means = rng.normal(300.0, 100.0, size=(5, 4))
    covs = np.stack([_covariance(rng) for _ in range(5)])
    np.testing.assert_array_equal(ss.from_stonesoup_mean(ss.to_stonesoup_mean(means)), means)
    np.testing.assert_array_equal(ss.from_stonesoup_cov(ss.to_stonesoup_cov(covs)), covs)
    tracks = ss.to_tracks(means, covs, T0)
    assert all(t.state.timestamp == T0 for t in tracks)
    m2, P2 = ss.from_tracks(tracks)
    np.testing.assert_array_equal(m2, means)
    np.testing.assert_array_equal(P2, covs)
    # Stone Soup -> ours -> Stone Soup.
    g = GaussianState(rng.normal(size=4), _covariance(rng), timestamp=T0)
    back = ss.to_gaussian_state(*ss.from_gaussian_state(g), timestamp=T0)
    np.testing.assert_array_equal(np.asarray(back.state_vector), np.asarray(g.state_vector))
    np.testing.assert_array_equal(np.asarray(back.covar), np.asarray(g.covar))
    # The Stone Soup state really is [x, vx, y, vy]: its CV model moves x by vx.
    x = ss.to_gaussian_state(means[0], covs[0], T0)
    moved = _transition(0.05).function(x, noise=False, time_interval=datetime.timedelta(seconds=2))
    F, _ = cv_matrices(2.0, 0.05)
    np.testing.assert_allclose(ss.from_stonesoup_mean(np.ravel(moved)), F @ means[0],
                               rtol=1e-14)


def test_ordered_tracks_is_deterministic_for_sets(rng):
    means = rng.normal(size=(4, 4))
    tracks = ss.to_tracks(means, np.eye(4) * 10, T0)
    assert ss.ordered_tracks(tracks) == tracks                       # lists keep their order
    # A set is ordered by content (first state's time, then state vector): the same for
    # copies with other (random, uuid4) ids, whatever the set's iteration order.
    by_x = [tracks[k] for k in np.argsort(means[:, 0])]
    assert ss.ordered_tracks(set(tracks)) == by_x
    copies = [Track(list(t.states), id=f"z{k}") for k, t in enumerate(tracks)]
    assert [t.state for t in ss.ordered_tracks(set(copies))] == [t.state for t in by_x]
    later = Track([GaussianState(tracks[0].state_vector, tracks[0].covar,
                                 timestamp=T0 + datetime.timedelta(seconds=1))])
    assert ss.ordered_tracks({later, *tracks})[-1] is later          # then by first time


# ------------------------------------------------------------------------ measurement model


def _model(rng, heading=0.4, altitude=505.0):
    params = SensorParams(altitude=altitude)
    return ss.RadarMeasurementModel(sensor_xy=(120.0, 80.0), heading=heading, params=params)


def test_measurement_model_matches_the_core_sensor(rng):
    model = _model(rng)
    for _ in range(20):
        x = np.array([rng.uniform(0, 600), rng.uniform(0, 600), *rng.normal(0, 3, 2)])
        state = ss.to_gaussian_state(x, np.eye(4), T0)
        z = model.function(state)
        expected = measure(x, np.array([120.0, 80.0]), 505.0)
        assert float(z[0, 0]) == pytest.approx(expected[0], rel=1e-15)
        assert float(wrap_angle(float(z[1, 0]) - expected[1])) == pytest.approx(0.0, abs=1e-14)
        H = model.jacobian(state)
        H_core = jacobian(x, np.array([120.0, 80.0]), 505.0)
        np.testing.assert_allclose(H, H_core[:, ss.STONESOUP_ORDER], rtol=1e-14, atol=0)
        # Stone Soup's own (forward-difference) Jacobian of our function agrees to its
        # accuracy; central differences agree to 1e-7.
        np.testing.assert_allclose(Model.jacobian(model, state), H, rtol=1e-4, atol=1e-9)
        H_cd = np.zeros((2, 4))
        for k in range(4):
            d = np.zeros(4)
            d[k] = 1e-4
            zp = model.function(ss.to_gaussian_state(x + d, np.eye(4)))
            zm = model.function(ss.to_gaussian_state(x - d, np.eye(4)))
            diff = np.asarray(zp, float).ravel() - np.asarray(zm, float).ravel()
            diff[1] = wrap_angle(diff[1])
            H_cd[:, ss.STONESOUP_ORDER.index(k)] = diff / 2e-4
        np.testing.assert_allclose(H_cd, H, rtol=1e-7, atol=1e-12)
        R = noise_cov(x, np.array([120.0, 80.0]), 0.4, SensorParams(altitude=505.0))
        np.testing.assert_allclose(model.covar(), R, rtol=1e-14)      # at the linearisation
        np.testing.assert_allclose(model.covar(state=state), R, rtol=1e-14)


def test_covar_depends_on_the_state_and_needs_one():
    model = _model(None)
    with pytest.raises(ValueError, match="depends on the target state"):
        model.covar()
    near = ss.to_gaussian_state([300.0, 80.0, 0, 0], np.eye(4))
    far = ss.to_gaussian_state([560.0, 80.0, 0, 0], np.eye(4))
    assert model.covar(state=far)[0, 0] > model.covar(state=near)[0, 0]   # SNR falls with r^4


def test_inverse_function_recovers_the_ground_position():
    model = _model(None)
    x = np.array([431.0, 250.0, 1.0, -2.0])
    z = Detection(model.function(ss.to_gaussian_state(x, np.eye(4))), measurement_model=model)
    back = np.ravel(model.inverse_function(z))
    np.testing.assert_allclose(back[[0, 2]], x[:2], rtol=1e-12)


def test_rvs_scales_with_the_noise_at_the_state(rng):
    model = _model(None)
    state = ss.to_gaussian_state([430.0, 330.0, 0, 0], np.eye(4))
    sd = np.sqrt(np.diag(model.covar(state=state)))
    draws = np.asarray(model.rvs(20000, random_state=rng, state=state), dtype=float)
    np.testing.assert_allclose(draws.std(axis=1), sd, rtol=0.03)
    unit = np.array([0.3, -1.2])
    np.testing.assert_allclose(np.ravel(model.scaled_noise(state, unit)), sd * unit, rtol=1e-14)


# -------------------------------------------------------------------- EKF against our EKF


@pytest.mark.parametrize("joseph", [False, True])
def test_stonesoup_ekf_with_our_model_equals_our_ekf(rng, joseph):
    q, dt = 0.05, 1.0
    predictor = ExtendedKalmanPredictor(_transition(q))
    updater = ExtendedKalmanUpdater(measurement_model=None, use_joseph_cov=joseph)
    F, Q = cv_matrices(dt, q)
    params = [SensorParams(altitude=a) for a in (490.0, 510.0)]
    for case in range(12):
        x0 = np.array([300.0, 300.0, *rng.normal(0, 3, 2)])
        P0 = _covariance(rng)
        xp, Pp = ekf.predict(x0[None], P0[None], F, Q)
        pred = predictor.predict(ss.to_gaussian_state(x0, P0, T0),
                                 timestamp=T0 + datetime.timedelta(seconds=dt))
        np.testing.assert_allclose(ss.from_gaussian_state(pred)[0], xp[0], rtol=1e-12)
        np.testing.assert_allclose(ss.from_gaussian_state(pred)[1], Pp[0], rtol=1e-12)
        # Two sensors in sequence; the second one sees the target across the +-pi cut
        # (its sensor sits east of the target, at the same y).
        state_ss, x, P = pred, xp, Pp
        for s, p in enumerate(params):
            sensor_xy = (np.array([xp[0, 0] - 350.0, xp[0, 1] + 60.0]) if s == 0
                         else np.array([xp[0, 0] + 320.0, xp[0, 1] - (case % 3 - 1) * 1e-3]))
            heading = math.atan2(xp[0, 1] - sensor_xy[1], xp[0, 0] - sensor_xy[0])
            z = measure(x[0] + np.r_[rng.normal(0, 5, 2), 0, 0], sensor_xy, p.altitude)
            z[1] = wrap_angle(z[1])
            x, P = ekf.update(x, P, z[None], sensor_xy[None], np.array([heading]),
                              radar_table(p))
            model = ss.RadarMeasurementModel(sensor_xy=tuple(sensor_xy), heading=heading,
                                             params=p)
            det = Detection(np.array([[0.0], [Bearing(0.0)]]) + np.array([[z[0]], [z[1]]]),
                            measurement_model=model, timestamp=pred.timestamp)
            state_ss = updater.update(SingleHypothesis(state_ss, det))
            m_ss, P_ss = ss.from_gaussian_state(state_ss)
            np.testing.assert_allclose(m_ss, x[0], rtol=1e-6, atol=1e-9)
            np.testing.assert_allclose(P_ss, P[0], rtol=1e-6, atol=1e-9 * np.abs(P).max())


# ----------------------------------------------------------------------- radar and movable


def test_radar_field_of_view_matches_the_core(rng):
    (platform,) = _platforms([(300.0, 280.0)], [0.7])
    radar = platform.sensors[0]
    pts = rng.uniform(0, 600, size=(400, 2))
    got = [radar.is_detectable(ss.to_ground_truth_state([p[0], p[1], 0, 0])) for p in pts]
    want = visible(pts, np.array([300.0, 280.0]), 0.7, radar.params)
    np.testing.assert_array_equal(got, want)
    assert 20 < want.sum() < 380


def test_radar_measures_visible_truths_with_noise_at_the_truth(rng):
    (platform,) = _platforms([(100.0, 100.0)], [math.pi / 4])
    radar = platform.sensors[0]
    seen = ss.to_ground_truth_state([340.0, 330.0, 1.0, 1.0], T0)
    hidden = ss.to_ground_truth_state([110.0, 120.0, 1.0, 1.0], T0)       # in the blind disc
    dets = radar.measure([seen, hidden], noise=False)
    assert len(dets) == 1
    (det,) = dets
    assert det.groundtruth_path is seen
    np.testing.assert_allclose(np.asarray(det.state_vector, float).ravel(),
                               measure(np.array([340.0, 330.0]), np.array([100.0, 100.0]), 490.0),
                               rtol=1e-14)
    unit = np.array([1.5, -0.5])
    noisy = radar.measure([seen], noise=radar.measurement_model.scaled_noise(seen, unit))
    sd = np.sqrt(np.diag(noise_cov(np.array([340.0, 330.0]), np.array([100.0, 100.0]),
                                   math.pi / 4, radar.params)))
    (nd,) = noisy
    diff = np.asarray(nd.state_vector, float).ravel() - np.asarray(det.state_vector, float).ravel()
    np.testing.assert_allclose(diff, sd * unit, rtol=1e-9)


def test_lattice_movable_offers_the_spec_moves_inside_the_map():
    (platform,) = _platforms([(20.0, 300.0)], [0.0])
    (gen,) = platform.actions(T0 + datetime.timedelta(seconds=1))
    actions = list(gen)
    moves = move_vectors((20.0, 40.0))
    ends = np.array([np.ravel(a.target_value)[:2] for a in actions])
    expected = np.array([20.0, 300.0]) + moves
    inside = MapRect().contains(expected)
    np.testing.assert_array_equal(ends, expected[inside])
    assert [a.move_index for a in actions] == list(np.flatnonzero(inside))
    assert len(actions) == 17 - 3                         # the three 40 m moves west leave
    assert gen.action_from_value((0.0, 300.0)).move_index == 5      # 20 m west
    assert gen.action_from_value((25.0, 300.0)) is None
    platform.add_actions([gen.action_for_move(2)])                  # 20 m north-east
    platform.act(T0 + datetime.timedelta(seconds=1))
    np.testing.assert_array_equal(np.ravel(platform.position), [40.0, 320.0, 490.0])


@pytest.mark.parametrize("order", ["platform_first", "sensor_first"])
def test_radar_turns_by_the_heading_rule_from_the_new_position(order):
    (platform,) = _platforms([(300.0, 300.0)], [0.0])
    radar = platform.sensors[0]
    t1 = T0 + datetime.timedelta(seconds=1)
    (move_gen,) = platform.actions(t1)
    (aim_gen,) = radar.actions(t1)
    move = move_gen.action_for_move(3)            # (-20, +20)
    aim = aim_gen.action((0.0, 600.0))
    pairs = [(platform, move), (radar, aim)]
    if order == "sensor_first":
        pairs.reverse()
    for actionable, action in pairs:
        actionable.add_actions([action])
        actionable.act(t1)
    bearing = math.atan2(600.0 - 320.0, 0.0 - 280.0)
    assert radar.heading == pytest.approx(min(bearing, math.pi / 4), abs=1e-15)
    # No new aim: the heading stays during the epoch.
    platform.act(T0 + datetime.timedelta(seconds=2))
    radar.act(T0 + datetime.timedelta(seconds=2))
    assert radar.heading == pytest.approx(math.pi / 4, abs=1e-15)


# --------------------------------------------------------------------------------- manager


def _decision(rng, n_sensors=3, n_targets=5):
    means = np.column_stack([rng.uniform(150, 450, (n_targets, 2)),
                             rng.uniform(-4, 4, (n_targets, 2))])
    covs = np.stack([np.diag([400.0, 400.0, 4.0, 4.0]) for _ in range(n_targets)])
    positions = rng.uniform(60, 540, size=(n_sensors, 2))
    headings = rng.uniform(-math.pi, math.pi, n_sensors)
    return means, covs, positions, headings


@pytest.mark.parametrize("planner,horizon,e,visibility", [
    ("pg", 1, 1, "probabilistic"), ("pg", 3, 2, "probabilistic"),
    ("sequential-greedy", 2, 1, "mean"), ("brute-force", 1, 2, "mean")])
@pytest.mark.parametrize("sensor_first", [False, True])
def test_manager_actions_execute_the_planners_first_epoch(rng, planner, horizon, e,
                                                          visibility, sensor_first):
    means, covs, positions, headings = _decision(rng, n_sensors=3 if planner != "brute-force"
                                                 else 2)
    platforms = _platforms(positions, headings)
    tracks = ss.to_tracks(means, covs, T0)
    mgr = ss.SensorplanManager(platforms=platforms, planner=planner, horizon=horizon,
                               steps_per_epoch=e, visibility=visibility, rng=7)
    t1 = T0 + datetime.timedelta(seconds=e)
    [config] = mgr.choose_actions(tracks, t1)
    assert set(map(id, config)) == set(map(id, mgr.actionables))
    # Our planner on the same decision, built independently.
    sensors = tuple(SensorParams(altitude=z) for z in (490.0, 500.0, 510.0)[:len(platforms)])
    problem = PlanningProblem(means=means, covs=covs, positions=positions, headings=headings,
                              sensors=sensors, horizon=horizon, steps_per_epoch=e,
                              visibility=visibility)
    expected = make_planner(planner).plan(problem, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(mgr.last_result.plan.targets, expected.plan.targets)
    items = list(config.items())
    if sensor_first:
        items.reverse()
    for actionable, actions in items:
        actionable.add_actions(actions)
        actionable.act(t1)
    for i, platform in enumerate(platforms):
        np.testing.assert_allclose(np.ravel(platform.position)[:2],
                                   expected.plan.positions[i, 0], rtol=0, atol=1e-6)
        assert platform.sensors[0].heading == pytest.approx(expected.headings[i, 0], abs=1e-12)
        (aim,) = config[platform.sensors[0]]
        assert aim.target is tracks[int(expected.plan.targets[i, 0])]


def test_manager_takes_a_planner_from_outside_with_its_settings(rng, nearest_on_path):
    reference = "nearest_planner:NearestTargetPlanner"
    means, covs, positions, headings = _decision(rng)
    platforms = _platforms(positions, headings)
    mgr = ss.SensorplanManager(platforms=platforms, planner=reference, horizon=2,
                               planner_params={"standoff": 300.0}, rng=2)
    mgr.choose_actions(ss.to_tracks(means, covs, T0), T0 + datetime.timedelta(seconds=1))
    sensors = tuple(SensorParams(altitude=z) for z in (490.0, 500.0, 510.0))
    problem = PlanningProblem(means=means, covs=covs, positions=positions, headings=headings,
                              sensors=sensors, horizon=2)
    expected = make_planner(reference, standoff=300.0).plan(problem)
    assert mgr.last_result.planner == "nearest"
    np.testing.assert_array_equal(mgr.last_result.plan.targets, expected.plan.targets)
    np.testing.assert_array_equal(mgr.last_result.plan.positions, expected.plan.positions)
    with pytest.raises(ConfigError) as err:
        ss.SensorplanManager(platforms=platforms, planner=reference,
                             planner_params={"stand_off": 300.0})
    assert err.value.field == "planner.stand_off"
    assert "did you mean 'standoff'?" in err.value.message


def test_manager_refuses_a_plan_that_breaks_the_contract(rng):
    # The platforms are not moved when the planner's plan cannot be executed.
    means, covs, positions, headings = _decision(rng)
    platforms = _platforms(positions, headings)
    mgr = ss.SensorplanManager(platforms=platforms, planner="broken_planners:Teleport",
                               horizon=2, rng=2)
    with pytest.raises(ConfigError, match=r"'teleport' \(broken_planners:Teleport\) broke the "
                                          r"planner contract \(sensor 0 epoch 1\)"):
        mgr.choose_actions(ss.to_tracks(means, covs, T0), T0 + datetime.timedelta(seconds=1))
    assert mgr.last_result is None


def test_manager_plans_again_from_the_executed_state(rng):
    means, covs, positions, headings = _decision(rng)
    platforms = _platforms(positions, headings)
    mgr = ss.SensorplanManager(platforms=platforms, horizon=2, rng=1)
    tracks = ss.to_tracks(means, covs, T0)
    t1 = T0 + datetime.timedelta(seconds=1)
    ss.execute(mgr.choose_actions(tracks, t1)[0], t1)
    tracks2 = ss.to_tracks(means, covs, t1)
    mgr.choose_actions(tracks2, t1 + datetime.timedelta(seconds=1))
    np.testing.assert_array_equal(mgr.last_problem.positions,
                                  np.stack([np.ravel(p.position)[:2] for p in platforms]))
    np.testing.assert_array_equal(mgr.last_problem.headings,
                                  [p.sensors[0].heading for p in platforms])


def test_manager_rejects_unsupported_actionables(rng):
    means, covs, positions, headings = _decision(rng, n_sensors=1)
    tracks = ss.to_tracks(means, covs, T0)
    grid = FixedPlatform(movement_controller=NStepDirectionalGridMovable(
        states=[State([[300.0], [300.0]], timestamp=T0)], position_mapping=(0, 1)),
        sensors=[ss.SensorplanRadar()])
    with pytest.raises(TypeError, match="LatticeMovable"):
        ss.SensorplanManager(platforms=[grid]).choose_actions(tracks, T0)
    (two,) = _platforms(positions, headings)
    two.add_sensor(ss.SensorplanRadar())
    with pytest.raises(TypeError, match="exactly one SensorplanRadar"):
        ss.SensorplanManager(platforms=[two]).choose_actions(tracks, T0)
    (ok,) = _platforms(positions, headings)
    with pytest.raises(TypeError, match="mounted"):
        ss.SensorplanManager(platforms=[ok], sensors={ss.SensorplanRadar()}).choose_actions(
            tracks, T0)
    with pytest.raises(ValueError, match="same time"):
        mixed = ss.to_tracks(means[:2], covs[:2], T0)
        mixed[1].append(GaussianState(mixed[1].state_vector, mixed[1].covar,
                                      timestamp=T0 + datetime.timedelta(seconds=1)))
        ss.SensorplanManager(platforms=[ok]).choose_actions(mixed, T0)


# ------------------------------------------------------------------ mutual-information reward


def test_mi_reward_equals_the_potential_of_the_equivalent_plan(rng):
    q = 0.05
    reward = ss.MutualInformationReward(predictor=ExtendedKalmanPredictor(_transition(q)),
                                        updater=ExtendedKalmanUpdater(None))
    checked = nonzero = 0
    for _ in range(4):
        means, covs, positions, headings = _decision(rng, n_sensors=2, n_targets=3)
        platforms = _platforms(positions, headings)
        radars = [p.sensors[0] for p in platforms]
        tracks = ss.to_tracks(means, covs, T0)
        t1 = T0 + datetime.timedelta(seconds=1)
        ss.set_aim_candidates(radars, tracks, 1.0)
        problem = PlanningProblem(means=means, covs=covs, positions=positions,
                                  headings=headings,
                                  sensors=tuple(r.params for r in radars), horizon=1,
                                  visibility="mean")
        gens = [(next(iter(p.actions(t1))), next(iter(r.actions(t1))))
                for p, r in zip(platforms, radars)]
        for _ in range(25):
            config, pos, tgt = {}, [], []
            for (mg, ag), p, r in zip(gens, platforms, radars):
                move = list(mg)[rng.integers(len(list(mg)))]
                aim = list(ag)[rng.integers(3)]
                config[p], config[r] = (move,), (aim,)
                pos.append(np.ravel(move.target_value)[:2])
                tgt.append(tracks.index(aim.target))
            value = reward(config, set(tracks), t1)
            phi, _ = potential(problem, Plan(np.array(pos)[:, None], np.array(tgt)[:, None]))
            assert value == pytest.approx(phi, rel=1e-9, abs=1e-12)
            checked += 1
            nonzero += phi > 0
    assert checked == 100 and nonzero >= 10


def test_stonesoups_expected_kl_divergence_with_our_radar_is_kl_of_prior_to_posterior(rng):
    """What docs/stonesoup.md says Stone Soup's own information reward computes with our
    radar and Gaussian tracks: for every track whose predicted mean is in a radar's field of
    view (all of them, not only the aimed one), KL(prediction || update) at a noise-free
    measurement at that mean, 0.5 (log det P+ - log det P- - n + tr(P+^-1 P-)), which is not
    the mutual information 0.5 log det P- / det P+ of our potential. One platform, so the
    order of Stone Soup's set of sensors cannot matter."""
    import copy

    from stonesoup.sensormanager.reward import ExpectedKLDivergence

    from radar_reference import visible as ref_visible

    q = 0.05
    F, Q = cv_matrices(1.0, q)
    predictor, updater = ExtendedKalmanPredictor(_transition(q)), ExtendedKalmanUpdater(None)
    reward = ExpectedKLDivergence(predictor=predictor, updater=updater)
    t1 = T0 + datetime.timedelta(seconds=1)
    checked = several = 0
    for _ in range(30):
        means, covs, positions, headings = _decision(rng, n_sensors=1, n_targets=4)
        covs = np.stack([_covariance(rng) for _ in range(4)])
        (platform,) = _platforms(positions, headings)
        radar = platform.sensors[0]
        tracks = ss.to_tracks(means, covs, T0)
        ss.set_aim_candidates([radar], tracks, 1.0)
        (mg,), (ag,) = platform.actions(t1), radar.actions(t1)
        move = list(mg)[rng.integers(len(list(mg)))]
        aim = list(ag)[rng.integers(4)]
        config = {platform: (move,), radar: (aim,)}
        value = reward(config, set(tracks), t1)
        # Independently: act a copy, predict with the core's filter, test the field of view
        # with the reference model, update with the core's EKF at z = h(predicted mean).
        acted = copy.deepcopy(platform)
        acted.add_actions([move])
        acted.act(t1)
        seen = acted.sensors[0]
        seen.add_actions([aim])
        seen.act(t1)
        xy, heading = seen.ground_position, seen.heading
        xp, Pp = ekf.predict(means, covs, F, Q)
        expected, in_view = 0.0, 0
        for j in range(4):
            if not ref_visible(xp[j], xy, heading, radar.params):
                continue
            z = measure(xp[j], xy, radar.params.altitude)
            _, P1 = ekf.update(xp[j:j + 1], Pp[j:j + 1], z[None], xy[None],
                               np.array([heading]), radar_table(radar.params))
            a, b = Pp[j], P1[0]
            expected += 0.5 * (np.linalg.slogdet(b)[1] - np.linalg.slogdet(a)[1] - 4
                               + np.trace(np.linalg.solve(b, a)))
            in_view += 1
        assert value == pytest.approx(expected, rel=1e-7, abs=1e-9)
        checked += 1
        several += in_view >= 2
    assert checked == 30 and several >= 3


def test_stonesoup_brute_force_with_the_mi_reward_finds_our_optimum(rng):
    from stonesoup.sensormanager import BruteForceSensorManager, GreedySensorManager

    means, covs, positions, headings = _decision(rng, n_sensors=1, n_targets=3)
    side = 1.0 if means[0, 0] > 300.0 else -1.0                 # target 0 within reach
    positions[0] = means[0, :2] - np.array([side * 330.0, 0.0])
    headings[0] = (0.0 if side > 0 else math.pi) + 0.5
    platforms = _platforms(positions, headings)
    radars = [p.sensors[0] for p in platforms]
    tracks = ss.to_tracks(means, covs, T0)
    t1 = T0 + datetime.timedelta(seconds=1)
    ss.set_aim_candidates(radars, tracks, 1.0)
    reward = ss.MutualInformationReward(predictor=ExtendedKalmanPredictor(_transition(0.05)),
                                        updater=ExtendedKalmanUpdater(None))
    (config,), (best,) = BruteForceSensorManager(
        platforms=set(platforms), reward_function=reward).choose_actions(
        set(tracks), t1, return_reward=True)
    problem = PlanningProblem(means=means, covs=covs, positions=positions, headings=headings,
                              sensors=(radars[0].params,), horizon=1, visibility="mean")
    optimum = make_planner("brute-force").plan(problem).potential
    assert optimum > 0
    assert best == pytest.approx(optimum, rel=1e-9)
    (greedy,) = GreedySensorManager(platforms=set(platforms),
                                    reward_function=reward).choose_actions(set(tracks), t1)
    assert set(greedy) == {platforms[0], radars[0]}
    # With return_tracks (what Stone Soup's MCTS needs) the updated tracks come back too.
    reward_t = ss.MutualInformationReward(predictor=reward.predictor, updater=reward.updater,
                                          return_tracks=True)
    value, updated = reward_t(config, tracks, t1)
    assert value == pytest.approx(best, rel=1e-12)
    assert len(updated) == 3 and all(u.state.timestamp == t1 for u in updated)
    assert all(len(t) == 1 for t in tracks)                       # the inputs are untouched


# ------------------------------------------------------------- closed loop against the core


def _stonesoup_episode(seed: int, steps: int, settings: RunSettings):
    """run_episode's loop written with Stone Soup types (miss_update 'none')."""
    scenario = paper_scenario()
    streams = run_streams(seed)
    truth_rng = np.random.default_rng(streams["truth"])
    init_rng = np.random.default_rng(streams["init"])
    init = draw_initial(scenario, truth_rng, init_rng)
    truth = make_truth(scenario, init.truth, truth_rng)
    N = len(scenario.sensors)
    noise = np.stack([np.random.default_rng(c).standard_normal((steps, 2))
                      for c in streams["noise"].spawn(N)], axis=1)
    platforms = _platforms(init.positions, init.headings)
    radars = [p.sensors[0] for p in platforms]
    tracks = ss.to_tracks(init.estimate, np.array(scenario.initial_cov), T0)
    predictor = ExtendedKalmanPredictor(_transition(scenario.process_noise))
    updater = ExtendedKalmanUpdater(None, use_joseph_cov=True)
    mgr = ss.SensorplanManager(platforms=platforms, planner=settings.planner,
                               horizon=settings.horizon,
                               steps_per_epoch=settings.steps_per_epoch,
                               visibility=settings.visibility,
                               rng=np.random.default_rng(streams["planner"]))
    out = []
    for t in range(1, steps + 1):
        now = T0 + datetime.timedelta(seconds=t)
        if (t - 1) % settings.steps_per_epoch == 0:
            end = now + datetime.timedelta(seconds=settings.steps_per_epoch - 1)
            ss.execute(mgr.choose_actions(tracks, end)[0], now)
        x_true = truth.step()
        for track in tracks:
            track.append(predictor.predict(track.state, timestamp=now))
        for i, radar in enumerate(radars):
            target = radar.aim_target
            j = tracks.index(target)
            gt = ss.to_ground_truth_state(x_true[j], now)
            model = radar.measurement_model
            dets = radar.measure([gt], noise=model.scaled_noise(gt, noise[t - 1, i]))
            for det in dets:
                target.append(updater.update(SingleHypothesis(target.state, det)))
        out.append(ss.from_tracks(tracks)[0])
    return np.array(out)


@pytest.mark.parametrize("horizon,e", [(1, 1), (2, 2)])
def test_stonesoup_loop_with_our_manager_reproduces_run_episode(horizon, e):
    steps = 8
    settings = RunSettings(planner="pg", horizon=horizon, steps_per_epoch=e, steps=steps,
                           tracker=TrackerSettings(miss_update="none", model="cv",
                                                   process_noise=0.05, gate=False,
                                                   reacquire=False, known_map=False))
    episode = run_episode(paper_scenario(), settings, seed=11)
    got = _stonesoup_episode(11, steps, settings)
    assert episode.measured[1:].any()
    np.testing.assert_allclose(got, episode.estimate[1:], rtol=1e-6, atol=1e-6)


# ---------------------------------------------------------------------------------- example


def test_example_runs_short_and_tracks_stay_finite(tmp_path):
    module = runpy.run_path(str(ROOT / "examples" / "stonesoup_loop.py"), run_name="example")
    out = tmp_path / "loop.png"
    result = module["main"](["--steps", "6", "--out", str(out)])
    assert out.exists() and out.stat().st_size > 0
    assert len(result.tracks) == 5
    for track in result.tracks:
        assert track.state.timestamp == T0 + datetime.timedelta(seconds=6)
        assert len(track) >= 7                       # start, 6 predictions, the updates
        for state in track:
            assert np.all(np.isfinite(np.asarray(state.state_vector, dtype=float)))
            assert np.all(np.isfinite(np.asarray(state.covar, dtype=float)))
    assert np.all(np.isfinite(result.errors))
    # Reproducible: the same seed gives the same run, another seed another one.
    again = module["run"](6, 0)
    np.testing.assert_array_equal(again.errors, result.errors)
    assert np.abs(module["run"](6, 1).errors[-1] - result.errors[-1]).max() > 1e-6


# ------------------------------------------------------- seeding: Stone Soup's convention


@pytest.fixture
def global_numpy_state():
    """Restore NumPy's global state after a test that seeds it."""
    saved = np.random.get_state()
    yield
    np.random.set_state(saved)


def _global_seed_loop(radar_seed=None, steps=4):
    """A small Stone Soup loop with no generator passed anywhere: truth noise, measurement
    noise (and planning, seeded by the manager's rng) as a Stone Soup user writes it."""
    transition = _transition(0.05)
    platforms = [
        FixedPlatform(movement_controller=ss.LatticeMovable(
            states=[State([[x], [y], [z]], timestamp=T0)], position_mapping=(0, 1, 2)),
            sensors=[ss.SensorplanRadar(params=SensorParams(altitude=z), heading=h,
                                        seed=radar_seed)])
        for x, y, z, h in ((40.0, 300.0, 490.0, 0.0), (300.0, 560.0, 510.0, -math.pi / 2))]
    starts = ([330.0, 2.0, 310.0, -1.0], [280.0, -1.5, 250.0, 2.5])
    truths = [GroundTruthPath([GroundTruthState(sv, timestamp=T0)]) for sv in starts]
    tracks = [Track([GaussianState(sv, np.diag([100.0, 4.0, 100.0, 4.0]), timestamp=T0)])
              for sv in starts]
    mgr = ss.SensorplanManager(platforms=platforms, rng=0)
    predictor = ExtendedKalmanPredictor(transition)
    updater = ExtendedKalmanUpdater(None)
    out = []
    for k in range(1, steps + 1):
        now = T0 + datetime.timedelta(seconds=k)
        ss.execute(mgr.choose_actions(tracks, now)[0], now)
        for truth in truths:
            truth.append(GroundTruthState(transition.function(
                truth.state, noise=True, time_interval=datetime.timedelta(seconds=1)),
                timestamp=now))
        for track in tracks:
            track.append(predictor.predict(track.state, timestamp=now))
        for platform in platforms:
            radar = platform.sensors[0]
            j = tracks.index(radar.aim_target)
            for det in radar.measure([truths[j].state]):
                out.append(np.asarray(det.state_vector, dtype=float).ravel())
                tracks[j].append(updater.update(SingleHypothesis(tracks[j].state, det)))
    assert len(out) >= steps                       # the radars do see their targets
    return np.array(out)


def test_np_random_seed_makes_a_stonesoup_loop_repeatable(global_numpy_state):
    np.random.seed(1990)
    first = _global_seed_loop()
    np.random.seed(1990)
    again = _global_seed_loop()
    np.testing.assert_array_equal(again, first)
    np.random.seed(1991)
    other = _global_seed_loop()
    assert other.shape != first.shape or np.abs(other - first).max() > 1e-6
    # An explicit seed gives each radar its own stream: the global seed no longer moves the
    # measurement noise (only the truth, drawn by Stone Soup from the global state).
    np.random.seed(7)
    seeded = _global_seed_loop(radar_seed=3)
    np.random.seed(7)
    np.testing.assert_array_equal(_global_seed_loop(radar_seed=3), seeded)
    np.random.seed(7)
    assert np.abs(_global_seed_loop(radar_seed=4) - seeded).max() > 1e-6


def test_noise_comes_from_rng_then_seed_then_the_global_state(global_numpy_state):
    model = _model(None)
    state = ss.to_gaussian_state([430.0, 330.0, 0, 0], np.eye(4))
    sd = np.sqrt(np.diag(model.covar(state=state)))
    np.random.seed(5)
    draw = np.ravel(model.rvs(state=state))
    np.testing.assert_array_equal(draw, sd * np.random.RandomState(5).standard_normal(2))
    seeded = ss.RadarMeasurementModel(sensor_xy=(120.0, 80.0), heading=0.4,
                                      params=SensorParams(altitude=505.0), seed=3)
    np.testing.assert_array_equal(np.ravel(seeded.rvs(state=state)),
                                  sd * np.random.default_rng(3).standard_normal(2))
    np.testing.assert_array_equal(np.ravel(seeded.rvs(state=state,
                                                      random_state=np.random.default_rng(9))),
                                  sd * np.random.default_rng(9).standard_normal(2))
    # The radar: rng argument, else its seed, else the global state.
    (platform,) = _platforms([(100.0, 100.0)], [math.pi / 4])
    radar = platform.sensors[0]
    truth = ss.to_ground_truth_state([340.0, 330.0, 1.0, 1.0], T0)
    clean = np.ravel(np.asarray(next(iter(radar.measure([truth], noise=False))).state_vector,
                                dtype=float))
    sd_t = radar.measurement_model.noise_std(truth)[0]

    def noise_of(**kw):
        (det,) = radar.measure([truth], **kw)
        return np.ravel(np.asarray(det.state_vector, dtype=float)) - clean

    np.random.seed(11)
    np.testing.assert_allclose(noise_of(), sd_t * np.random.RandomState(11).standard_normal(2),
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(noise_of(rng=np.random.default_rng(2)),
                               sd_t * np.random.default_rng(2).standard_normal(2),
                               rtol=1e-9, atol=1e-12)
    radar.seed = 6                                   # setting the seed restarts the stream
    np.testing.assert_allclose(noise_of(), sd_t * np.random.default_rng(6).standard_normal(2),
                               rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------- 6-D tracks


def _six_d(mean4, cov4, rng, timestamp=T0):
    """A Stone Soup 6-D state [x, vx, y, vy, z, vz] whose ground marginal is (mean4, cov4)
    (ours), with z correlated to the ground entries."""
    A = rng.normal(size=(6, 6))
    C = A @ A.T + 6 * np.eye(6)
    C[:4, :4] = ss.to_stonesoup_cov(cov4)
    while np.linalg.eigvalsh(C).min() <= 0:          # shrink the cross terms until PD
        C[:4, 4:] *= 0.5
        C[4:, :4] *= 0.5
    sv = np.r_[ss.to_stonesoup_mean(mean4), 100.0 + rng.normal(), rng.normal()]
    return GaussianState(sv, C, timestamp=timestamp)


def test_six_d_tracks_plan_on_their_ground_marginal(rng):
    means, covs, positions, headings = _decision(rng)
    tracks4 = ss.to_tracks(means, covs, T0)
    tracks6 = [Track([_six_d(m, P, rng)]) for m, P in zip(means, covs)]
    m6, P6 = ss.from_tracks(tracks6)
    np.testing.assert_array_equal(m6, means)
    np.testing.assert_array_equal(P6, covs)
    t1 = T0 + datetime.timedelta(seconds=1)
    configs = []
    for tracks in (tracks4, tracks6):
        platforms = _platforms(positions, headings)
        mgr = ss.SensorplanManager(platforms=platforms, horizon=2, rng=5)
        [config] = mgr.choose_actions(tracks, t1)
        ss.execute(config, t1)
        configs.append((mgr.last_result.plan, [np.ravel(p.position) for p in platforms],
                        [p.sensors[0].heading for p in platforms],
                        [tracks.index(config[p.sensors[0]][0].target) for p in platforms]))
    (plan4, pos4, head4, tgt4), (plan6, pos6, head6, tgt6) = configs
    np.testing.assert_array_equal(plan6.positions, plan4.positions)
    np.testing.assert_array_equal(plan6.targets, plan4.targets)
    np.testing.assert_array_equal(pos6, pos4)
    assert head6 == head4 and tgt6 == tgt4


def test_other_state_layouts_need_mappings(rng):
    means, covs, positions, headings = _decision(rng, n_sensors=1, n_targets=2)
    platforms = _platforms(positions, headings)
    t1 = T0 + datetime.timedelta(seconds=1)
    five = [Track([GaussianState(np.r_[ss.to_stonesoup_mean(m), 0.0], np.eye(5), timestamp=T0)])
            for m in means]
    with pytest.raises(ConfigError, match=r"tracks\[0\]\.state: a 5-D state; expected Stone "
                                          r"Soup's \[x, vx, y, vy\] \(4-D\) or \[x, vx, y, vy, z, "
                                          r"vz\] \(6-D\), or give position_mapping"):
        ss.SensorplanManager(platforms=platforms).choose_actions(five, t1)
    # Our own order [x, y, vx, vy], named by the mappings, gives the same plan.
    ours = [Track([GaussianState(m, P, timestamp=T0)]) for m, P in zip(means, covs)]
    mapped = ss.SensorplanManager(platforms=platforms, position_mapping=(0, 1),
                                  velocity_mapping=(2, 3), rng=1)
    mapped.choose_actions(ours, t1)
    plain = ss.SensorplanManager(platforms=_platforms(positions, headings), rng=1)
    plain.choose_actions(ss.to_tracks(means, covs, T0), t1)
    np.testing.assert_array_equal(mapped.last_problem.means, plain.last_problem.means)
    np.testing.assert_array_equal(mapped.last_problem.covs, plain.last_problem.covs)
    np.testing.assert_array_equal(mapped.last_result.plan.targets, plain.last_result.plan.targets)
    with pytest.raises(ConfigError, match="must name four different entries"):
        ss.from_tracks(ours, position_mapping=(0, 1), velocity_mapping=(1, 7))


def test_six_d_ekf_update_equals_the_four_d_update_on_the_ground(rng):
    q = 0.05
    pred4 = ExtendedKalmanPredictor(_transition(q))
    pred6 = ExtendedKalmanPredictor(CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(q)] * 3))
    updater = ExtendedKalmanUpdater(None, use_joseph_cov=True)
    (platform,) = _platforms([(40.0, 300.0)], [0.0])
    radar = platform.sensors[0]
    t1 = T0 + datetime.timedelta(seconds=1)
    for _ in range(5):
        x = np.array([340.0 + rng.normal(0, 20), 300.0 + rng.normal(0, 20), *rng.normal(0, 2, 2)])
        P = _covariance(rng)
        s6 = _six_d(x, P, rng)
        s4 = ss.to_gaussian_state(x, P, T0)
        truth6 = GroundTruthState(np.r_[ss.to_stonesoup_mean(x + np.r_[3.0, -2.0, 0, 0]),
                                        100.0, 0.0], timestamp=t1)
        (det,) = radar.measure([truth6], noise=False)
        assert det.measurement_model.ndim_state == 6
        # Any model of this radar linearises a 6-D state with six columns, zero off the ground.
        H6 = radar.measurement_model.jacobian(s6)
        H4 = radar.measurement_model.jacobian(s4)
        np.testing.assert_array_equal(H6[:, :4], H4)
        np.testing.assert_array_equal(H6[:, 4:], 0.0)
        post6 = updater.update(SingleHypothesis(pred6.predict(s6, timestamp=t1), det))
        det4 = Detection(det.state_vector, measurement_model=radar.measurement_model,
                         timestamp=t1)
        post4 = updater.update(SingleHypothesis(pred4.predict(s4, timestamp=t1), det4))
        m6, P6 = ss.from_gaussian_state(post6)
        m4, P4 = ss.from_gaussian_state(post4)
        np.testing.assert_allclose(m6, m4, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(P6, P4, rtol=1e-9, atol=1e-9 * np.abs(P4).max())


def test_mi_reward_of_six_d_tracks_equals_that_of_their_ground_marginals(rng):
    q = 0.05
    reward4 = ss.MutualInformationReward(predictor=ExtendedKalmanPredictor(_transition(q)),
                                         updater=ExtendedKalmanUpdater(None))
    reward6 = ss.MutualInformationReward(predictor=ExtendedKalmanPredictor(
        CombinedLinearGaussianTransitionModel([ConstantVelocity(q)] * 3)),
        updater=ExtendedKalmanUpdater(None))
    t1 = T0 + datetime.timedelta(seconds=1)
    nonzero = 0
    for _ in range(3):
        means, covs, positions, headings = _decision(rng, n_sensors=2, n_targets=3)
        platforms = _platforms(positions, headings)
        radars = [p.sensors[0] for p in platforms]
        tracks4 = ss.to_tracks(means, covs, T0)
        tracks6 = [Track([_six_d(m, P, rng)]) for m, P in zip(means, covs)]
        move_gens = [next(iter(p.actions(t1))) for p in platforms]
        for _ in range(8):
            picks = [(list(mg)[rng.integers(len(list(mg)))], rng.integers(3)) for mg in move_gens]
            values = []
            for tracks, reward in ((tracks4, reward4), (tracks6, reward6)):
                ss.set_aim_candidates(radars, tracks, 1.0)
                config = {}
                for (move, j), p, r in zip(picks, platforms, radars):
                    (aim_gen,) = r.actions(t1)
                    config[p], config[r] = (move,), (list(aim_gen)[j],)
                    assert config[r][0].target is tracks[j]
                values.append(reward(config, tracks, t1))
            assert values[1] == pytest.approx(values[0], rel=1e-9, abs=1e-12)
            nonzero += values[0] > 0
    assert nonzero >= 3


# ----------------------------------------------------------------- no tracks: stay and hold


def test_no_tracks_returns_stay_and_hold(rng):
    means, covs, positions, headings = _decision(rng)
    platforms = _platforms(positions, headings)
    radars = [p.sensors[0] for p in platforms]
    mgr = ss.SensorplanManager(platforms=platforms, horizon=2, rng=4)
    t1, t2 = T0 + datetime.timedelta(seconds=1), T0 + datetime.timedelta(seconds=2)
    # First aim every radar at a point behind it: the turn is limited, so the aim is not
    # reached and a second turn toward it would change the heading.
    for p, r in zip(platforms, radars):
        (ag,) = r.actions(t1)
        behind = np.ravel(p.position)[:2] - 100 * np.array([math.cos(r.heading),
                                                            math.sin(r.heading)])
        ss.execute({r: [ag.action(behind)]}, t1)
    before = ([np.ravel(p.position).copy() for p in platforms], [r.heading for r in radars],
              [r.aim for r in radars])
    for empty in ([], set()):
        [config] = mgr.choose_actions(empty, t2)
        assert set(map(id, config)) == set(map(id, mgr.actionables))
        for p, r in zip(platforms, radars):
            (move,) = config[p]
            (aim,) = config[r]
            assert move.move_index == 0 and aim.hold
        ss.execute(config, t2)
        after = ([np.ravel(p.position) for p in platforms], [r.heading for r in radars],
                 [r.aim for r in radars])
        np.testing.assert_array_equal(after[0], before[0])
        assert after[1] == before[1] and after[2] == before[2]
        assert mgr.last_result is None and mgr.last_problem is None and mgr.last_tracks == []
    # Holding draws nothing from the manager's generator: the next plan is a fresh one's.
    tracks = ss.to_tracks(means, covs, t2)
    t3 = T0 + datetime.timedelta(seconds=3)
    mgr.choose_actions(tracks, t3)
    fresh = ss.SensorplanManager(platforms=platforms, horizon=2, rng=4)
    fresh.choose_actions(tracks, t3)
    np.testing.assert_array_equal(mgr.last_result.plan.targets, fresh.last_result.plan.targets)
    # A radar that never aimed holds too (no aim, heading unchanged).
    (p0,) = _platforms([(300.0, 300.0)], [0.3])
    [config] = ss.SensorplanManager(platforms=[p0]).choose_actions([], t1)
    ss.execute(config, t1)
    assert p0.sensors[0].aim is None and p0.sensors[0].heading == 0.3


# ---------------------------------------------------------------- maps with any origin


def test_map_origin_translates_exactly(rng):
    # The same decision twice: on [0, 600]^2, and shifted by (-300, -300) onto a map
    # centred on 0. Integer coordinates make every shift exact, so everything must agree
    # bit for bit after the shift.
    shift = np.array([-300.0, -300.0])
    means = np.column_stack([rng.integers(150, 450, (5, 2)), rng.integers(-4, 5, (5, 2))])
    means = means.astype(float)
    covs = np.stack([np.diag([400.0, 400.0, 4.0, 4.0])] * 5)
    positions = rng.integers(60, 540, size=(3, 2)).astype(float)
    headings = rng.uniform(-math.pi, math.pi, 3)
    t1 = T0 + datetime.timedelta(seconds=1)
    runs = []
    for offset, world in ((np.zeros(2), ss.MapRect(0, 0, 600, 600)),
                          (shift, ss.MapRect(-300, -300, 600, 600))):
        platforms = _platforms(positions + offset, headings, world=world)
        moved = means.copy()
        moved[:, :2] += offset
        mgr = ss.SensorplanManager(platforms=platforms, horizon=3, rng=2)
        [config] = mgr.choose_actions(ss.to_tracks(moved, covs, T0), t1)
        aims = [config[p.sensors[0]][0].target_value for p in platforms]
        planned = mgr.planned_positions()
        ss.execute(config, t1)
        runs.append((mgr, np.array(aims), planned,
                     np.stack([np.ravel(p.position)[:2] for p in platforms]),
                     [p.sensors[0].heading for p in platforms]))
    (m0, aims0, plan0, pos0, head0), (m1, aims1, plan1, pos1, head1) = runs
    np.testing.assert_array_equal(m1.last_problem.means, m0.last_problem.means)
    np.testing.assert_array_equal(m1.last_problem.positions, m0.last_problem.positions)
    np.testing.assert_array_equal(m1.last_result.plan.positions, m0.last_result.plan.positions)
    np.testing.assert_array_equal(m1.last_result.plan.targets, m0.last_result.plan.targets)
    np.testing.assert_array_equal(aims1, aims0 + shift)
    np.testing.assert_array_equal(plan1, plan0 + shift)
    np.testing.assert_array_equal(pos1, pos0 + shift)
    np.testing.assert_array_equal(plan0, m0.last_result.plan.positions)     # origin 0: as is
    assert head1 == head0


def test_map_origin_executes_the_planners_plan(rng):
    # An awkward origin: the plan, made in the planner's frame, executes in world
    # coordinates; positions come from the lattice moves bit for bit.
    origin = np.array([-512.3, 77.7])
    world = ss.MapRect(*origin, 600.0, 600.0)
    means, covs, positions, headings = _decision(rng)
    platforms = _platforms(positions + origin, headings, world=world)
    start = np.stack([np.ravel(p.position)[:2] for p in platforms])
    world_means = means.copy()
    world_means[:, :2] += origin
    mgr = ss.SensorplanManager(platforms=platforms, horizon=2, rng=7)
    t1 = T0 + datetime.timedelta(seconds=1)
    [config] = mgr.choose_actions(ss.to_tracks(world_means, covs, T0), t1)
    planned = mgr.planned_positions()
    ss.execute(config, t1)
    problem = PlanningProblem(means=world_means - np.r_[origin, 0, 0], covs=covs,
                              positions=start - origin, headings=headings,
                              sensors=tuple(SensorParams(altitude=z)
                                            for z in (490.0, 500.0, 510.0)), horizon=2)
    expected = make_planner("pg").plan(problem, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(mgr.last_result.plan.targets, expected.plan.targets)
    moves = move_vectors((20.0, 40.0))
    for i, p in enumerate(platforms):
        (move,) = config[p]
        now = np.ravel(p.position)[:2]
        np.testing.assert_array_equal(now, start[i] + moves[move.move_index])
        np.testing.assert_array_equal(planned[i, 0], now)
        np.testing.assert_allclose(planned[i], expected.plan.positions[i] + origin,
                                   rtol=0, atol=1e-9)
        assert p.sensors[0].heading == pytest.approx(expected.headings[i, 0], abs=1e-12)
        assert world.contains(planned[i]).all()


def test_out_of_map_errors_state_the_bounds(rng):
    means, covs, _, _ = _decision(rng, n_targets=2)
    tracks = ss.to_tracks(means, covs, T0)
    centred = ss.MapRect(-500, -500, 1000, 1000)
    assert str(centred) == "[-500, 500] x [-500, 500]"
    ok, out = _platforms([(0.0, 0.0), (-600.0, 20.0)], [0.0, 0.0], world=centred)
    for given in (tracks, []):
        with pytest.raises(ConfigError) as err:
            ss.SensorplanManager(platforms=[ok, out]).choose_actions(given, T0)
        assert str(err.value) == (
            "sensors[1].position: (-600, 20) is outside the map [-500, 500] x [-500, 500]; "
            "set LatticeMovable(world=MapRect(x0, y0, width, height))")
        assert err.value.field == "sensors[1].position"
    (default,) = _platforms([(-100.0, 20.5)], [0.0])
    assert default.movement_controller.world == ss.MapRect(0, 0, 600, 600)
    with pytest.raises(ConfigError) as err:
        ss.SensorplanManager(platforms=[default]).choose_actions(tracks, T0)
    assert str(err.value) == (
        "sensors[0].position: (-100, 20.5) is outside the map [0, 600] x [0, 600] "
        "(LatticeMovable's default world); set LatticeMovable(world=MapRect(x0, y0, width, "
        "height))")
    # Other map mistakes.
    with pytest.raises(TypeError):
        ss.MapRect(600, 600)                     # the core's (width, height) is not an origin
    with pytest.raises(ConfigError, match=r"world\.height: must be > 0"):
        ss.MapRect(0, 0, 600, 0)
    (a,) = _platforms([(10.0, 10.0)], [0.0], world=ss.MapRect(0, 0, 600, 600))
    (b,) = _platforms([(10.0, 10.0)], [0.0], world=ss.MapRect(0, 0, 600, 601))
    with pytest.raises(ValueError, match="share one map"):
        ss.SensorplanManager(platforms=[a, b]).choose_actions(tracks, T0)
    # The core's map is read as [0, W] x [0, H].
    (c,) = _platforms([(10.0, 10.0)], [0.0], world=MapRect(800.0, 400.0))
    assert c.movement_controller.world == ss.MapRect(0, 0, 800, 400)
    assert not c.movement_controller.world_is_default


def test_lattice_moves_respect_a_shifted_map():
    world = ss.MapRect(-300.0, -300.0, 600.0, 600.0)
    (platform,) = _platforms([(-280.0, 0.0)], [0.0], world=world)
    (gen,) = platform.actions(T0 + datetime.timedelta(seconds=1))
    ends = np.array([np.ravel(a.target_value)[:2] for a in gen])
    expected = np.array([-280.0, 0.0]) + move_vectors((20.0, 40.0))
    np.testing.assert_array_equal(ends, expected[expected[:, 0] >= -300.0])
    assert len(ends) == 17 - 3


def test_a_radar_offset_from_its_platform_is_refused(rng):
    means, covs, positions, headings = _decision(rng, n_sensors=1)
    (platform,) = _platforms(positions, headings)
    platform.sensors[0].mounting_offset = np.array([[5.0], [0.0], [0.0]])
    with pytest.raises(ValueError, match="mounting_offset"):
        ss.SensorplanManager(platforms=[platform]).choose_actions(
            ss.to_tracks(means, covs, T0), T0)


def test_a_radar_at_another_height_than_its_altitude_is_refused(rng):
    means, covs, positions, headings = _decision(rng, n_sensors=1)
    tracks = ss.to_tracks(means, covs, T0)
    (platform,) = _platforms(positions, headings, altitudes=(100.0,))
    radar = platform.sensors[0]
    radar.params = SensorParams(altitude=500.0)              # the platform flies at z = 100
    truth = ss.to_ground_truth_state(means[0], T0)
    message = ("params.altitude: is 500 m, but the radar is at z = 100 m (its platform's z "
               "plus the mounting offset); the radar measures from params.altitude, so make "
               "them equal: SensorParams(altitude=100), or the platform at z = 500")
    for use in (lambda: radar.measure([truth]), lambda: radar.measurement_model,
                lambda: radar.is_detectable(truth), lambda: radar.detection_probability(truth),
                lambda: radar.clutter_spatial_density()):
        with pytest.raises(ConfigError) as err:
            use()
        assert str(err.value) == message
    with pytest.raises(ConfigError) as err:
        ss.SensorplanManager(platforms=[platform]).choose_actions(
            tracks, T0 + datetime.timedelta(seconds=1))
    assert err.value.field == "sensors[0].params.altitude"
    # The radar's height is the platform's z plus the mounting offset's: a platform on the
    # ground carrying the radar 500 m up is the radar at 500 m, and plans as one at z = 500.
    radar.mounting_offset = np.array([[0.0], [0.0], [400.0]])
    (level,) = _platforms(positions, headings, altitudes=(500.0,))
    for p in (platform, level):
        p.sensors[0].params = SensorParams(altitude=500.0)
    plans = [ss.SensorplanManager(platforms=[p], horizon=2).choose_actions(
        tracks, T0 + datetime.timedelta(seconds=1)) for p in (platform, level)]
    assert [np.ravel(a.target_value).tolist() for a in plans[0][0][platform]] == \
        [np.ravel(a.target_value)[:2].tolist() + [100.0] for a in plans[1][0][level]]
    # A 2-D platform has no height: params.altitude alone counts.
    flat = FixedPlatform(movement_controller=ss.LatticeMovable(
        states=[State([[positions[0, 0]], [positions[0, 1]]], timestamp=T0)],
        position_mapping=(0, 1)), sensors=[ss.SensorplanRadar(params=SensorParams(
            altitude=500.0), heading=float(headings[0]))])
    assert flat.sensors[0].measurement_model.params.altitude == 500.0


@pytest.mark.parametrize("e", [1, 2])
def test_choose_actions_refuses_a_timestamp_other_than_the_first_epochs_end(rng, e):
    means, covs, positions, headings = _decision(rng, n_sensors=2)
    tracks = ss.to_tracks(means, covs, T0)
    manager = ss.SensorplanManager(platforms=_platforms(positions, headings), horizon=2,
                                   steps_per_epoch=e, dt=1.0, rng=0)
    steps = "" if e == 1 else "2 x 1 s = "
    for gap, fix in ((10.0, f" (or set dt={10 / e:g} for epochs of 10 s)"), (0.0, ""),
                     (e + 0.5, f" (or set dt={(e + 0.5) / e:g} for epochs of {e + 0.5:g} s)")):
        with pytest.raises(ConfigError) as err:
            manager.choose_actions(tracks, T0 + datetime.timedelta(seconds=gap))
        assert str(err.value) == (
            f"timestamp: is {gap:g} s after the tracks' time, but this manager plans epochs "
            f"of steps_per_epoch x dt = {steps}{e} s: give the end of the first epoch, the "
            f"tracks' time + {e} s{fix}")
        assert manager.last_result is None                  # nothing was planned
    (config,) = manager.choose_actions(tracks, T0 + datetime.timedelta(seconds=e))
    assert len(config) == 4 and manager.last_result is not None
    # With dt = 10 s the 10 s gap is one epoch (e = 1): the manager plans 10 s steps.
    slow = ss.SensorplanManager(platforms=_platforms(positions, headings), dt=10.0 / e,
                                steps_per_epoch=e, rng=0)
    slow.choose_actions(tracks, T0 + datetime.timedelta(seconds=10))
    assert slow.last_problem is not None and slow.last_problem.dt == 10.0 / e


# ------------------------------------------------------------------- Stone Soup YAML


def test_yaml_round_trip_of_a_manager_setup(rng):
    from ruamel.yaml.representer import RepresenterError
    from stonesoup.serialise import YAML

    means, covs, positions, headings = _decision(rng)
    world = ss.MapRect(-100.0, -50.0, 700.0, 650.0)
    platforms = _platforms(positions, headings, world=world, move_distances=(15.0, 30.0))
    platforms[1].sensors[0].seed = 5
    mgr = ss.SensorplanManager(platforms=platforms, planner="pg", planner_params={"alpha": 0.4},
                               horizon=2, visibility="mean", rng=3)
    t1, t2 = T0 + datetime.timedelta(seconds=1), T0 + datetime.timedelta(seconds=2)
    ss.execute(mgr.choose_actions(ss.to_tracks(means, covs, T0), t1)[0], t1)   # mid-run
    text = YAML().dumps(mgr)
    loaded = YAML().load(text)
    assert type(loaded) is ss.SensorplanManager
    assert (loaded.planner, dict(loaded.planner_params), loaded.horizon, loaded.visibility,
            loaded.rng) == ("pg", {"alpha": 0.4}, 2, "mean", 3)
    for p, q in zip(platforms, loaded.platforms):
        r, s = p.sensors[0], q.sensors[0]
        assert q.movement_controller.world == world
        assert tuple(q.movement_controller.move_distances) == (15.0, 30.0)
        assert s.params == r.params and s.heading == r.heading and s.seed == r.seed
        assert tuple(s.aim) == tuple(r.aim)
        np.testing.assert_array_equal(np.ravel(q.position), np.ravel(p.position))
        assert s.movement_controller is q.movement_controller           # still mounted
    # The loaded setup plans as the original does (same seed, same state).
    tracks = ss.to_tracks(means, covs, t1)
    [c0] = ss.SensorplanManager(platforms=platforms, planner="pg",
                                planner_params={"alpha": 0.4}, horizon=2, visibility="mean",
                                rng=3).choose_actions(tracks, t2)
    [c1] = loaded.choose_actions(tracks, t2)
    for p, q in zip(platforms, loaded.platforms):
        np.testing.assert_array_equal(np.ravel(c1[q][0].target_value),
                                      np.ravel(c0[p][0].target_value))
        assert c1[q.sensors[0]][0].target is c0[p.sensors[0]][0].target
    assert YAML().load(YAML().dumps(loaded)).horizon == 2                    # and again
    with pytest.raises(RepresenterError, match="integer seed"):
        YAML().dumps(ss.SensorplanManager(platforms=platforms, rng=np.random.default_rng(1)))


# ------------------------------------------------ missed detections and clutter (the radar)

RADAR_XY = np.array([100.0, 100.0])
RADAR_HEADING = math.pi / 4


def _radar(**params):
    """A radar at RADAR_XY (altitude 490 m) looking along RADAR_HEADING."""
    (platform,) = _platforms([tuple(RADAR_XY)], [RADAR_HEADING])
    radar = platform.sensors[0]
    radar.params = SensorParams(altitude=490.0, **params)
    return radar


def _pd_closed_form(xy, params: SensorParams) -> float:
    """Swerling 1, square-law detector: Pd = Pfa ** (1 / (1 + SNR)), SNR at the slant range."""
    r = math.sqrt(float(np.sum((np.asarray(xy) - RADAR_XY) ** 2)) + params.altitude ** 2)
    snr = 10.0 ** (params.snr_ref_db / 10.0) * (params.range_ref / r) ** 4
    return params.false_alarm_probability ** (1.0 / (1.0 + snr))


def _in_view_at(g: float, d: float = 0.0) -> np.ndarray:
    """The ground point at ground range g and azimuth offset d from the radar's heading."""
    return RADAR_XY + g * np.array([math.cos(RADAR_HEADING + d), math.sin(RADAR_HEADING + d)])


def _z(det) -> np.ndarray:
    return np.asarray(det.state_vector, dtype=float).ravel()


def test_default_measure_draws_only_the_noise_as_before(global_numpy_state):
    """Ideal detection, no clutter: a detection per truth in view with noise N(0, R(truth)),
    two standard normals per truth in view in list order and nothing else drawn."""
    radar = _radar()
    points = [_in_view_at(300.0, 0.1), np.array([110.0, 120.0]), _in_view_at(420.0, -0.3),
              _in_view_at(260.0, 0.4)]                      # the second is in the blind disc
    truths = [ss.to_ground_truth_state([p[0], p[1], 1.0, -1.0], T0) for p in points]
    seen = visible(np.array(points), RADAR_XY, RADAR_HEADING, radar.params)
    assert seen.tolist() == [True, False, True, True]

    def expected(gen):
        out = {}
        for truth, p, s in zip(truths, points, seen):
            if s:
                sd = np.sqrt(np.diag(noise_cov(p, RADAR_XY, RADAR_HEADING, radar.params)))
                out[id(truth)] = measure(p, RADAR_XY, 490.0) + sd * gen.standard_normal(2)
        return out

    for source in ("rng", "seed", "global"):
        if source == "rng":
            gen, replay = np.random.default_rng(3), np.random.default_rng(3)
            dets = radar.measure(truths, rng=gen)
        elif source == "seed":
            radar.seed = 4
            dets = radar.measure(truths)
            gen, replay = radar.rng, np.random.default_rng(4)
            radar.seed = None
        else:
            np.random.seed(5)
            dets = radar.measure(truths)
            gen, replay = np.random, np.random.RandomState(5)
        want = expected(replay)
        assert all(type(d) is TrueDetection for d in dets)
        got = {id(d.groundtruth_path): _z(d) for d in dets}
        assert got.keys() == want.keys()
        for k, z in want.items():
            np.testing.assert_allclose(got[k], z, rtol=1e-12, atol=1e-12)
        # Nothing more was drawn: the next draw of the source is the replay's next draw.
        assert gen.standard_normal() == replay.standard_normal()


def test_detection_frequencies_match_pd_within_binomial_bounds():
    radar = _radar(detection="swerling1", false_alarm_probability=1e-6)
    gen = np.random.default_rng(2024)
    n = 1500
    pds = []
    for g, d in ((255.0, 0.2), (350.0, -0.4), (445.0, 0.0)):
        p = _in_view_at(g, d)
        truth = ss.to_ground_truth_state([p[0], p[1], 0.0, 0.0], T0)
        pd = _pd_closed_form(p, radar.params)
        assert radar.detection_probability(truth) == pytest.approx(pd, rel=1e-12)
        hits = sum(len(radar.measure([truth], rng=gen)) for _ in range(n))
        assert abs(hits - n * pd) <= 4.0 * math.sqrt(n * pd * (1.0 - pd)), (g, hits, n * pd)
        pds.append(pd)
    # The three ranges have clearly different Pd (the test could tell them apart).
    assert pds[0] - pds[1] > 0.05 and pds[1] - pds[2] > 0.05
    # A truth out of view is never detected and draws nothing.
    out = ss.to_ground_truth_state([110.0, 120.0, 0.0, 0.0], T0)
    before = gen.bit_generator.state
    assert radar.measure([out] * 50, rng=gen) == set()
    assert gen.bit_generator.state == before
    # Ideal detection: Pd = 1.
    assert _radar().detection_probability(out) == 1.0


def test_clutter_counts_are_poisson_with_mean_clutter_rate():
    lam = 2.5
    radar = _radar(clutter_rate=lam)
    gen = np.random.default_rng(99)
    t1 = T0 + datetime.timedelta(seconds=3)
    counts = []
    for _ in range(3000):
        dets = radar.measure([], rng=gen, timestamp=t1)
        assert all(type(d) is Clutter and d.timestamp == t1 for d in dets)
        counts.append(len(dets))
    counts = np.array(counts)
    n = len(counts)
    assert abs(counts.mean() - lam) <= 4.0 * math.sqrt(lam / n)
    # Poisson: variance = mean (the sample variance's variance is (lam + 2 lam^2) / n).
    assert abs(counts.var(ddof=1) - lam) <= 4.0 * math.sqrt((lam + 2 * lam * lam) / n)
    p0 = math.exp(-lam)
    assert abs(np.mean(counts == 0) - p0) <= 4.0 * math.sqrt(p0 * (1 - p0) / n)
    # No clutter: nothing drawn, nothing reported.
    quiet = _radar()
    before = gen.bit_generator.state
    assert quiet.measure([], rng=gen, timestamp=t1) == set()
    assert gen.bit_generator.state == before


@pytest.mark.parametrize("fov", [math.pi / 6, 0.95 * math.pi])
def test_clutter_lies_in_the_sensing_region_uniform_in_area(fov):
    """Noise-free clutter inverted through the measurement model: every point in the field of
    view (band, wedge and cos psi > 0, by the independent reference), uniform in area."""
    from scipy import stats

    lam = 4.0
    radar = _radar(clutter_rate=lam, fov_half_angle=fov)
    p = radar.params
    gen = np.random.default_rng(7)
    calls = 1500
    dets = [d for _ in range(calls) for d in radar.measure([], noise=False, rng=gen,
                                                           timestamp=T0)]
    xy = np.array([np.ravel(d.measurement_model.inverse_function(d))[[0, 2]] for d in dets])
    assert all(d.measurement_model.sensor_xy == tuple(RADAR_XY) for d in dets)
    assert visible(xy, RADAR_XY, RADAR_HEADING, p).all()
    g = np.hypot(*(xy - RADAR_XY).T)
    d = wrap_angle(np.arctan2(*(xy - RADAR_XY).T[::-1]) - RADAR_HEADING)
    g2min, g2max = p.min_ground_range ** 2, p.max_ground_range ** 2
    # Independent Monte Carlo of the region (uniform in area over band x wedge, then the
    # cos psi > 0 cut): the share of the band x wedge that is in view.
    ref = np.random.default_rng(1).random((200_000, 2))
    gr = np.sqrt(g2min + ref[:, 0] * (g2max - g2min))
    ar = RADAR_HEADING + fov * (2 * ref[:, 1] - 1)
    ref_xy = RADAR_XY + gr[:, None] * np.column_stack([np.cos(ar), np.sin(ar)])
    keep = visible(ref_xy, RADAR_XY, RADAR_HEADING, p)
    share = keep.mean()
    mean = lam * share
    assert abs(len(dets) / calls - mean) <= 4.0 * math.sqrt(mean / calls)
    if fov < math.pi / 2:
        assert share == 1.0
        # Uniform in area: the ground-area CDF of g is uniform, and so is the azimuth.
        assert stats.kstest((g * g - g2min) / (g2max - g2min), "uniform").pvalue > 1e-3
        assert stats.kstest((d + fov) / (2 * fov), "uniform").pvalue > 1e-3
        # Uniform in ground range instead would be rejected at this sample size.
        wrong = (g - p.min_ground_range) / (p.max_ground_range - p.min_ground_range)
        assert stats.kstest(wrong, "uniform").pvalue < 1e-6
    else:
        assert 0.3 < share < 0.99                 # part of the wedge is behind the boresight
        # Same distribution as the reference points that are in view (two-sample test).
        ref_g = gr[keep]
        assert stats.ks_2samp(g, ref_g).pvalue > 1e-3


def test_clutter_and_misses_draw_in_the_documented_order():
    """One look with a swerling1 target in view and clutter, replayed independently: the
    truth's uniform, its noise if detected, the count, the positions, the clutter noise."""
    lam = 3.0
    radar = _radar(detection="swerling1", clutter_rate=lam)
    p = radar.params
    target = _in_view_at(330.0, 0.15)
    truth = ss.to_ground_truth_state([target[0], target[1], 2.0, 0.0], T0)
    pd = _pd_closed_form(target, p)
    for seed in range(12):
        dets = radar.measure([truth], rng=np.random.default_rng(seed))
        g = np.random.default_rng(seed)
        want_true = None
        if g.random() < pd:
            sd = np.sqrt(np.diag(noise_cov(target, RADAR_XY, RADAR_HEADING, p)))
            want_true = measure(target, RADAR_XY, 490.0) + sd * g.standard_normal(2)
        n = g.poisson(lam)
        u = g.random((n, 2))
        e = g.standard_normal((n, 2))
        gr = np.sqrt(p.min_ground_range ** 2
                     + u[:, 0] * (p.max_ground_range ** 2 - p.min_ground_range ** 2))
        ar = RADAR_HEADING + p.fov_half_angle * (2 * u[:, 1] - 1)
        pts = RADAR_XY + gr[:, None] * np.column_stack([np.cos(ar), np.sin(ar)])
        sd = np.sqrt(np.diagonal(noise_cov(pts, RADAR_XY, RADAR_HEADING, p), axis1=-2,
                                 axis2=-1))
        want_clutter = measure(pts, RADAR_XY, 490.0) + sd * e
        want_clutter[:, 1] = wrap_angle(want_clutter[:, 1])
        trues = [d for d in dets if type(d) is TrueDetection]
        clutter = sorted((_z(d) for d in dets if type(d) is Clutter), key=tuple)
        assert len(trues) == (want_true is not None)
        if trues:
            np.testing.assert_allclose(_z(trues[0]), want_true, rtol=1e-12, atol=1e-12)
            assert trues[0].groundtruth_path is truth
        assert len(clutter) == n
        np.testing.assert_allclose(np.reshape(clutter, (-1, 2)),
                                   np.reshape(sorted(want_clutter.tolist()), (-1, 2)),
                                   rtol=1e-12, atol=1e-12)
        # Every detection of the look carries the radar's measurement model of the truth's
        # dimension, and the truth's time.
        models = {id(d.measurement_model) for d in dets}
        assert len(models) <= 1
        assert all(d.measurement_model.ndim_state == 4 and d.timestamp == T0 for d in dets)


def test_clutter_spatial_density_closed_forms():
    lam = 1.5
    radar = _radar(clutter_rate=lam)
    p = radar.params
    area = p.fov_half_angle * (p.max_ground_range ** 2 - p.min_ground_range ** 2)
    r_min = math.hypot(p.min_ground_range, p.altitude)
    r_max = math.hypot(p.max_ground_range, p.altitude)
    for g in (250.0, 333.0, 450.0):
        x = _in_view_at(g, 0.2)
        r = math.hypot(g, p.altitude)
        rho = radar.clutter_spatial_density(ss.to_gaussian_state([x[0], x[1], 0, 0], np.eye(4)))
        assert rho == pytest.approx(lam * r / area, rel=1e-12)
    # Over the region (r in [r_min, r_max], azimuth over 2 fov) the density integrates to lam.
    rr = np.linspace(r_min, r_max, 20001)
    integral = 2 * p.fov_half_angle * np.trapezoid(lam * rr / area, rr)
    assert integral == pytest.approx(lam, rel=1e-9)
    # The constant approximation: the average density, = rho at the middle slant range.
    const = radar.clutter_spatial_density()
    assert const == pytest.approx(lam / (2 * p.fov_half_angle * (r_max - r_min)), rel=1e-12)
    assert const == pytest.approx(lam * 0.5 * (r_min + r_max) / area, rel=1e-12)
    assert _radar().clutter_spatial_density() == 0.0


def test_stonesoup_pda_on_our_detections_equals_the_pda_formula():
    """Stone Soup's PDAHypothesiser, PDA and PDAUpdater on a look with the target and
    clutter, with the radar's Pd and clutter density, against the PDA equations in numpy,
    across the azimuth cut at +-pi."""
    from stonesoup.dataassociator.probability import PDA
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.types.numeric import Probability
    from stonesoup.updater.probability import PDAUpdater

    (platform,) = _platforms([(420.0, 300.0)], [math.pi])
    radar = platform.sensors[0]
    radar.params = SensorParams(altitude=490.0, detection="swerling1", clutter_rate=2.0)
    mean = np.array([100.0, 300.0, 1.0, -0.5])                   # ours; azimuth about pi
    P = np.diag([150.0, 120.0, 2.0, 2.0])
    P[0, 1] = P[1, 0] = 40.0
    track = Track([ss.to_gaussian_state(mean, P, T0)])
    model = radar.measurement_model
    # The target's detection just across the cut, and a false alarm.
    zs = [(math.hypot(322.0, 490.0) + 3.0, -math.pi + 0.004),
          (math.hypot(300.0, 490.0), math.pi - 0.05)]
    dets = [Detection(StateVector([[r], [Bearing(phi)]]), timestamp=T0, measurement_model=model)
            for r, phi in zs]
    predictor = ExtendedKalmanPredictor(_transition(0.05))
    updater = PDAUpdater(measurement_model=model)
    pd = radar.detection_probability(track.state)
    rho = radar.clutter_spatial_density(track.state)
    gate = 0.999
    hyp = PDAHypothesiser(predictor=predictor, updater=updater, prob_detect=Probability(pd),
                          clutter_spatial_density=rho, prob_gate=Probability(gate))
    hypotheses = PDA(hypothesiser=hyp).associate([track], dets, T0)
    post = updater.update(hypotheses[track])
    assert len(hypotheses[track]) == 3                            # both are inside the gate
    # The PDA equations (Bar-Shalom, Daum and Huang 2009), independently.
    H = jacobian(mean, np.array([420.0, 300.0]), 490.0)
    R = noise_cov(mean, np.array([420.0, 300.0]), math.pi, radar.params)
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    zhat = measure(mean, np.array([420.0, 300.0]), 490.0)
    nus = [np.array([_z(d)[0] - zhat[0], wrap_angle(_z(d)[1] - zhat[1])]) for d in dets]
    like = [pd * math.exp(-0.5 * nu @ np.linalg.solve(S, nu)) / math.sqrt(
        np.linalg.det(2 * math.pi * S)) / rho for nu in nus]
    total = 1 - pd * gate + sum(like)
    beta0, betas = (1 - pd * gate) / total, [lk / total for lk in like]
    nu = sum(b * v for b, v in zip(betas, nus))
    spread = sum(b * np.outer(v, v) for b, v in zip(betas, nus)) - np.outer(nu, nu)
    want_mean = mean + K @ nu
    want_cov = beta0 * P + (1 - beta0) * (P - K @ S @ K.T) + K @ spread @ K.T
    got_mean, got_cov = ss.from_gaussian_state(post)
    np.testing.assert_allclose(got_mean, want_mean, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got_cov, want_cov, rtol=1e-8, atol=1e-9)
    assert abs(got_mean[1] - mean[1]) < 20                       # not flung across the cut


def test_ordered_detections_is_a_fixed_order(rng):
    radar = _radar(clutter_rate=6.0)
    dets = radar.measure([], rng=rng, timestamp=T0)
    assert len(dets) >= 3
    first = ss.ordered_detections(dets)
    shuffled = list(dets)
    rng.shuffle(shuffled)
    assert ss.ordered_detections(shuffled) == first
    keys = [tuple(_z(d)) for d in first]
    assert keys == sorted(keys)


# ------------------------------------------------ the manager plans expecting them


def test_manager_plans_with_planning_detection(rng):
    means, covs, positions, headings = _decision(rng)
    tracks = ss.to_tracks(means, covs, T0)
    t1 = T0 + datetime.timedelta(seconds=1)
    detection = {"detection": "swerling1", "false_alarm_probability": 1e-5,
                 "clutter_rate": 3.0}
    results = {}
    for mode in ("aware", "ignore", None):
        platforms = _platforms(positions, headings)
        for platform in platforms:
            radar = platform.sensors[0]
            radar.params = dataclasses.replace(radar.params, **detection)
        kw = {} if mode is None else {"planning_detection": mode}
        mgr = ss.SensorplanManager(platforms=platforms, planner="brute-force", horizon=1,
                                   rng=0, **kw)
        mgr.choose_actions(tracks, t1)
        problem = mgr.last_problem
        assert problem.planning_detection == (mode or "aware")     # default: aware
        assert all((s.detection, s.false_alarm_probability, s.clutter_rate)
                   == ("swerling1", 1e-5, 3.0) for s in problem.sensors)
        assert mgr.last_result.potential == pytest.approx(
            potential(problem, mgr.last_result.plan)[0], rel=1e-9)
        results[mode or "default"] = (problem, mgr.last_result)
    aware, ignore = results["aware"], results["ignore"]
    plan = aware[1].plan
    # The same plan is worth less when misses and clutter count, and the planner knew it.
    phi_aware = potential(aware[0], plan)[0]
    phi_ignore = potential(dataclasses.replace(aware[0], planning_detection="ignore"), plan)[0]
    assert 0 < phi_aware < phi_ignore
    # Brute force is optimal for the objective it was given: the plan made ignoring misses
    # and clutter is worth no more under the aware objective.
    assert potential(aware[0], ignore[1].plan)[0] <= phi_aware * (1 + 1e-12)
    assert results["default"][1].potential == aware[1].potential
    with pytest.raises(ConfigError) as err:
        ss.SensorplanManager(platforms=_platforms(positions, headings),
                             planning_detection="always")
    assert err.value.field == "planning_detection"


def test_yaml_keeps_detection_settings(rng):
    from stonesoup.serialise import YAML

    _, _, positions, headings = _decision(rng)
    platforms = _platforms(positions, headings)
    platforms[0].sensors[0].params = SensorParams(altitude=490.0, detection="swerling1",
                                                  false_alarm_probability=1e-4,
                                                  clutter_rate=0.5)
    mgr = ss.SensorplanManager(platforms=platforms, planning_detection="ignore", rng=1)
    loaded = YAML().load(YAML().dumps(mgr))
    assert loaded.planning_detection == "ignore"
    assert loaded.platforms[0].sensors[0].params == platforms[0].sensors[0].params


# ------------------------------------------------ the PDA example


def test_pda_example_runs_short_and_repeats_with_np_random_seed(tmp_path, global_numpy_state):
    module = runpy.run_path(str(ROOT / "examples" / "stonesoup_pda_loop.py"),
                            run_name="example")
    out = tmp_path / "pda.png"
    result = module["main"](["--steps", "5", "--out", str(out)])
    assert out.exists() and out.stat().st_size > 0
    assert result.looks == 15 and result.false_alarms > 0
    assert result.detected < result.in_view                   # misses happen
    for track in result.tracks:
        assert track.state.timestamp == T0 + datetime.timedelta(seconds=5)
        for state in track:
            assert np.all(np.isfinite(np.asarray(state.state_vector, dtype=float)))
            assert np.all(np.isfinite(np.asarray(state.covar, dtype=float)))
    # np.random.seed(seed) inside run: the same seed repeats the run bit for bit, even
    # after other draws from the global state; another seed gives another run.
    np.random.standard_normal(7)
    again = module["run"](5, 0)
    np.testing.assert_array_equal(again.errors, result.errors)
    assert (again.detected, again.false_alarms) == (result.detected, result.false_alarms)
    other = module["run"](5, 1)
    assert np.abs(other.errors - result.errors).max() > 1e-6
