"""Stone Soup interop (issue 7): converters, measurement model, EKF, manager, reward, example.

Skipped cleanly where Stone Soup is not installed (the ``stonesoup`` extra).
"""

from __future__ import annotations

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
from stonesoup.types.detection import Detection  # noqa: E402
from stonesoup.types.hypothesis import SingleHypothesis  # noqa: E402
from stonesoup.types.state import GaussianState, State  # noqa: E402
from stonesoup.updater.kalman import ExtendedKalmanUpdater  # noqa: E402

from sensorplan import ekf  # noqa: E402
from sensorplan.angles import wrap_angle  # noqa: E402
from sensorplan.dynamics import cv_matrices  # noqa: E402
from sensorplan.information import potential  # noqa: E402
from sensorplan.integrations import stonesoup as ss  # noqa: E402
from sensorplan.planners import make_planner  # noqa: E402
from sensorplan.problem import MapRect, Plan, PlanningProblem, move_vectors  # noqa: E402
from sensorplan.scenario import draw_initial, make_truth, paper_scenario  # noqa: E402
from sensorplan.settings import TrackerSettings  # noqa: E402
from radar_reference import jacobian, measure, noise_cov, visible  # noqa: E402
from sensorplan.sensors import SensorParams, radar_table  # noqa: E402
from sensorplan.simulation import RunSettings, run_episode, run_streams  # noqa: E402

T0 = datetime.datetime(2024, 1, 1)
ROOT = Path(__file__).resolve().parents[1]


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
    tracks = ss.to_tracks(rng.normal(size=(4, 4)), np.eye(4) * 10, T0)
    assert ss.ordered_tracks(tracks) == tracks                       # lists keep their order
    by_id = sorted(tracks, key=lambda t: str(t.id))
    assert ss.ordered_tracks(set(tracks)) == by_id


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
                           tracker=TrackerSettings(miss_update="none"))
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
