"""The honest-tracking options: IMM, validation gate, re-acquisition, the known map."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2, truncnorm

import radar_reference as ref
from sensorplan.models.motion import cv_matrices
from sensorplan.tracking.known_map import map_constraint, truncated_normal_moments
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.tracker import KnownTargetTracker, gate_threshold, stationary

P0 = np.diag([400.0, 400.0, 4.0, 4.0])
TABLE = radar_table(SensorParams())


def looks_at(rng, means, n):
    """Sensor poses 300 m from each of ``n`` targets, heading at them (in view)."""
    a = rng.uniform(-math.pi, math.pi, n)
    sxy = means[:n, :2] - 300.0 * np.column_stack([np.cos(a), np.sin(a)])
    return sxy, a


# ------------------------------------------------------------------------------ the IMM


def test_imm_with_equal_modes_is_the_single_filter(rng):
    """Two modes with the same q: mixing, mode likelihoods and combination change nothing."""
    M = 4
    means = np.column_stack([rng.uniform(200, 400, (M, 2)), rng.normal(0, 3, (M, 2))])
    kw = dict(gate_probability=0.999, reacquire=True, world=(600.0, 600.0))
    single = KnownTargetTracker(means, P0, 1.0, TABLE, process_noise=0.3, **kw)
    imm = KnownTargetTracker(means, P0, 1.0, TABLE, process_noise=0.3, mode_process_noise=(0.3,
                             0.3),
                  switching=np.array([[0.9, 0.1], [0.2, 0.8]]), **kw)
    truth = means.copy()
    F, _ = cv_matrices(1.0, 0.0)
    sensors = np.arange(M) % 1
    for t in range(60):
        truth = truth @ F.T
        for tr in (single, imm):
            tr.predict()
        sxy, hd = looks_at(rng, truth, M)
        h = ref.measure(truth, sxy, 500.0)
        z = h + rng.normal(size=(M, 2)) * [3.0, 0.004]
        look = rng.random(M) < 0.7
        i = np.flatnonzero(look)
        if t % 7 == 3:               # a missed look now and then
            for tr in (single, imm):
                tr.miss(sensors[:1], np.array([t % M]), sxy[:1] + 5000.0, hd[:1])
        for tr in (single, imm):
            tr.update_detections(sensors[i], i, z[i], sxy[i], hd[i])
        np.testing.assert_allclose(imm.means, single.means, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(imm.covs, single.covs, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(imm.planning_process_noise(), np.full(M, 0.3), rtol=1e-12)


def test_stationary_distribution():
    Pi = np.array([[0.95, 0.05], [0.2, 0.8]])
    pi = stationary(Pi)
    np.testing.assert_allclose(pi @ Pi, pi, atol=1e-15)
    np.testing.assert_allclose(pi, [0.8, 0.2], rtol=1e-12)


def test_a_manoeuvre_raises_the_high_noise_mode(rng):
    m = np.array([[300.0, 300.0, 5.0, 0.0]])
    tr = KnownTargetTracker(m, P0, 1.0, TABLE, process_noise=0.05, mode_process_noise=(0.05, 5.0),
                 switching=np.array([[0.95, 0.05], [0.1, 0.9]]))
    truth = m.copy()
    F, _ = cv_matrices(1.0, 0.0)
    high = []
    for t in range(40):
        if t == 25:
            truth[0, 2:] = [0.0, 5.0]           # a sharp turn
        truth = truth @ F.T
        tr.predict()
        sxy, hd = looks_at(rng, truth, 1)
        z = ref.measure(truth, sxy, 500.0) + rng.normal(size=(1, 2)) * [1.0, 0.001]
        tr.update_detections(np.zeros(1, dtype=int), np.zeros(1, dtype=int), z, sxy, hd)
        high.append(tr.mode_probs[0, 1])
    high = np.array(high)
    # Quiet before the turn, the high-noise mode takes over right after it, then fades.
    assert high[15:25].max() < 0.2 < 0.8 < high[25:30].max()
    assert high[-1] < 0.5
    np.testing.assert_allclose(tr.mode_probs.sum(axis=1), 1.0, rtol=1e-14)


# ------------------------------------------------------------------------------ the gate


@pytest.mark.parametrize("p", [0.9, 0.99, 0.999, 0.9999])
def test_gate_threshold_is_the_chi2_quantile(p):
    assert gate_threshold(p) == pytest.approx(chi2.ppf(p, 2), rel=1e-12)
    assert gate_threshold(0.999) == pytest.approx(13.8155, abs=1e-4)


def _detection_at_distance(mean, cov, sxy, heading, d2, direction):
    """A measurement whose innovation under the track has squared Mahalanobis distance d2."""
    st = ref.stack_params([SensorParams()])
    h = ref.measure(mean[None], sxy[None], st.altitude)[0]
    H = ref.jacobian(mean[None], sxy[None], st.altitude)[0]
    R = ref.noise_cov(mean[None], sxy[None], np.array([heading]), st)[0]
    S = H @ cov @ H.T + R
    L = np.linalg.cholesky(S)
    u = direction / np.linalg.norm(direction) * math.sqrt(d2)
    return h + L @ u


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.3, -1.0), (-1.0, 2.0)])
def test_a_detection_just_inside_the_gate_is_used_and_just_outside_is_not(direction):
    mean = np.array([300.0, 280.0, 2.0, -1.0])
    sxy = np.array([40.0, 100.0])
    heading = math.atan2(280.0 - 100.0, 300.0 - 40.0)
    gamma = gate_threshold(0.999)
    for factor, used in ((1 - 1e-6, True), (1 + 1e-6, False)):
        tr = KnownTargetTracker(mean[None], P0, 1.0, TABLE, process_noise=0.05,
                                gate_probability=0.999)
        z = _detection_at_distance(mean, P0, sxy, heading, factor * gamma,
                                   np.array(direction))
        res = tr.update_detections(np.zeros(1, dtype=int), np.zeros(1, dtype=int), z[None],
                                   sxy[None],
                        np.array([heading]))
        assert bool(res.used[0]) is used and bool(res.gated_out[0]) is not used
        if used:
            assert not np.array_equal(tr.means[0], mean)
        else:
            np.testing.assert_array_equal(tr.means[0], mean)      # discarded: untouched
            np.testing.assert_array_equal(tr.covs[0], P0)


def test_re_acquisition_restarts_at_the_inverse_measurement():
    mean = np.array([300.0, 280.0, 2.0, -1.0])
    sxy = np.array([40.0, 100.0])
    heading = 0.5
    z = np.array([620.0, 0.9])                       # far from the track
    tr = KnownTargetTracker(mean[None], P0, 1.0, TABLE, process_noise=0.05, gate_probability=0.999,
                 reacquire=True, restart_velocity_var=(4.0, 9.0))
    res = tr.update_detections(np.zeros(1, dtype=int), np.zeros(1, dtype=int), z[None], sxy[None],
                    np.array([heading]))
    assert res.gated_out[0] and res.restarted[0] and not res.used[0]
    # Independent inverse: ground range from the slant range, then polar to Cartesian.
    g = math.sqrt(z[0] ** 2 - 500.0 ** 2)
    want_xy = sxy + g * np.array([math.cos(z[1]), math.sin(z[1])])
    np.testing.assert_allclose(tr.means[0, :2], want_xy, rtol=1e-13)
    np.testing.assert_array_equal(tr.means[0, 2:], [0.0, 0.0])
    # Documented covariance: J R J^T, J = d(x, y)/d(r, phi), R at the measured point.
    R = ref.noise_cov(want_xy[None], sxy[None], np.array([heading]),
                      ref.stack_params([SensorParams()]))[0]
    J = np.array([[z[0] / g * math.cos(z[1]), -g * math.sin(z[1])],
                  [z[0] / g * math.sin(z[1]), g * math.cos(z[1])]])
    np.testing.assert_allclose(tr.covs[0, :2, :2], J @ R @ J.T, rtol=1e-11)
    np.testing.assert_array_equal(tr.covs[0, 2:, 2:], np.diag([4.0, 9.0]))
    np.testing.assert_array_equal(tr.covs[0, :2, 2:], 0.0)


def test_re_acquisition_needs_the_gate():
    with pytest.raises(ValueError, match="gate"):
        KnownTargetTracker(np.zeros((1, 4)), P0, 1.0, TABLE, process_noise=0.05, reacquire=True)


# ------------------------------------------------------------------------------ the map


def test_truncated_normal_moments_against_scipy(rng):
    a = rng.uniform(-8, 8, 400)
    b = a + rng.exponential(2.0, 400)
    cases = [(a, b), (np.full(5, -np.inf), np.array([-30.0, -5, 0, 5, 30])),
             (np.array([-30.0, -5, 0, 5, 30]), np.full(5, np.inf)),
             (np.array([20.0, 35.0]), np.array([21.0, 40.0]))]          # far in a tail
    for lo, hi in cases:
        mean, var, log_mass = truncated_normal_moments(lo, hi)
        m_ref, v_ref = truncnorm.stats(lo, hi, moments="mv")
        np.testing.assert_allclose(mean, m_ref, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(var, v_ref, rtol=1e-6, atol=1e-9)
        assert np.all((mean >= lo) & (mean <= hi)) and np.all((var > 0) & (var <= 1))
        np.testing.assert_allclose(np.exp(log_mass), _mass(lo, hi), rtol=1e-9)


def _mass(lo, hi):
    """Ncdf(hi) - Ncdf(lo), taken in the lower tail for accuracy."""
    from scipy.special import ndtr
    return np.where(lo > -hi, ndtr(-lo) - ndtr(-hi), ndtr(hi) - ndtr(lo))


def test_the_map_never_moves_a_track_deep_inside(rng):
    m = np.column_stack([rng.uniform(150, 450, (50, 2)), rng.normal(0, 3, (50, 2))])
    P = np.tile(np.diag([100.0, 100.0, 4.0, 4.0]), (50, 1, 1))
    m2, P2, applied, log_mass = map_constraint(m, P, 600.0, 600.0)
    assert not applied.any()
    np.testing.assert_array_equal(m2, m)
    np.testing.assert_array_equal(P2, P)
    np.testing.assert_array_equal(log_mass, 0.0)


def _random_cov(rng):
    A = rng.normal(size=(4, 4)) * np.array([30.0, 30.0, 2.0, 2.0])[:, None]
    return A @ A.T + np.diag([1.0, 1.0, 0.1, 0.1])


def test_the_map_pulls_a_mean_inside_and_never_increases_a_variance(rng):
    n = 500
    m = np.column_stack([rng.uniform(-300, 900, (n, 2)), rng.normal(0, 3, (n, 2))])
    P = np.array([_random_cov(rng) for _ in range(n)])
    m2, P2, applied, _ = map_constraint(m, P, 600.0, 600.0)
    outside = (m[:, :2] < 0).any(axis=1) | (m[:, :2] > 600).any(axis=1)
    assert applied[outside].all() and outside.sum() > 100
    assert np.all((m2[:, :2] >= 0) & (m2[:, :2] <= 600))
    # Never an increase of any variance, in any direction: P - P' is PSD.
    for a, b in zip(P, P2):
        assert np.linalg.eigvalsh(a - b).min() >= -1e-9 * np.abs(a).max()
        np.linalg.cholesky(b)
    assert np.all(np.diagonal(P2, axis1=1, axis2=2) <= np.diagonal(P, axis1=1, axis2=2)
                  * (1 + 1e-12))


def test_the_map_truncation_matches_the_truncated_gaussian_moments(rng):
    """One axis crossing the edge, no correlation with the other: exact 1-D truncation."""
    m = np.array([[-20.0, 300.0, 1.0, 0.0]])
    P = np.diag([900.0, 100.0, 4.0, 4.0])[None].copy()
    P[0, 0, 2] = P[0, 2, 0] = 30.0                   # x correlated with vx
    m2, P2, applied, _ = map_constraint(m, P, 600.0, 600.0)
    s = 30.0
    mu, var = truncnorm.stats((0 - -20.0) / s, (600 + 20.0) / s, moments="mv")
    assert m2[0, 0] == pytest.approx(-20.0 + s * mu, rel=1e-9)
    assert P2[0, 0, 0] == pytest.approx(s * s * var, rel=1e-7)
    # vx moves by the regression coefficient of vx on x
    assert m2[0, 2] == pytest.approx(1.0 + 30.0 / 900.0 * (s * mu), rel=1e-9)
    assert m2[0, 1] == 300.0 and P2[0, 1, 1] == 100.0


def test_tracker_applies_the_map_after_predict():
    m = np.array([[595.0, 300.0, 8.0, 0.0]])          # about to leave the map
    tr = KnownTargetTracker(m, P0, 1.0, TABLE, process_noise=0.05, world=(600.0, 600.0))
    corrected = tr.predict()
    assert corrected[0] and tr.means[0, 0] <= 600.0
    free = KnownTargetTracker(m, P0, 1.0, TABLE, process_noise=0.05)
    free.predict()
    assert free.means[0, 0] > 600.0


# ------------------------------------------------------------------------------ options off


@pytest.mark.parametrize("seed", [3, 8])
def test_the_paper_configuration_reproduces_its_recorded_tracks(seed):
    """Every option off: the tracks of the paper's configuration equal those the code gave
    before the options existed (tests/data/paper_rows_golden.npz, written by commit be1378b
    with the script in tests/data/README.md), to rtol 1e-12: a refactor may change the
    order of a sum, not the result. Runs of one version are bit for bit the same (the
    determinism tests in tests/simulation/)."""
    from pathlib import Path

    from sensorplan.simulation.scenario import paper_scenario
    from sensorplan.simulation.settings import TrackerSettings
    from sensorplan.simulation import RunSettings, run_episode

    golden = np.load(Path(__file__).parents[1] / "data" / "paper_rows_golden.npz")
    s = RunSettings(planner="pg", horizon=3, steps_per_epoch=2, execution="olf", steps=40,
                    visibility="mean", objective="terminal",
                    tracker=TrackerSettings(miss_update="none", model="cv", process_noise=0.05,
                                            gate=False, reacquire=False, known_map=False))
    ep = run_episode(paper_scenario(), s, seed)
    np.testing.assert_allclose(ep.estimate, golden[f"estimate_{seed}"], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ep.cov, golden[f"cov_{seed}"], rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(ep.looked, golden[f"looked_{seed}"])


# ------------------------------------------------------------------------------ bad settings


@pytest.mark.parametrize("table,field", [
    ("process_noise = -0.1", "tracker.process_noise"),
    ("gate_probability = 1.0", "tracker.gate_probability"),
    ("gate_probability = 0.0", "tracker.gate_probability"),
    ("switching = [[0.9, 0.2], [0.1, 0.9]]", "tracker.switching"),
    ("switching = [[0.9, 0.1]]", "tracker.switching"),
    ("mode_process_noise = [0.05, -1.0]", "tracker.mode_process_noise"),
    ("model = \"kalman\"", "tracker.model"),
    ("bernoulli_model = \"kalman\"", "tracker.bernoulli_model"),
    ("births = \"uniform\"\nbirth_velocity = \"inward\"", "tracker.birth_velocity"),
    ("gate = false", "tracker.reacquire"),
    ("recycle_motion = \"moving\"", "tracker.recycle_motion"),
])
def test_bad_tracker_settings_exit_2_naming_the_field(table, field, tmp_path, capsys):
    from cli_helpers import assert_bad_input, run

    scenario = tmp_path / "s.toml"
    scenario.write_text(f"[tracker]\n{table}\n[[targets]]\n[[sensors]]\n")
    line = assert_bad_input(run(capsys, "simulate", scenario, "--steps", "2", "--out",
                                tmp_path / "out"), field)
    if "switching = [[0.9, 0.2]" in table:
        assert "row 0 must sum to 1" in line


# ------------------------------------------------------------------------------ NEES statistics


def test_nees_band_covers_a_consistent_filter_in_95_percent_of_seeds():
    """A linear Gaussian Kalman filter with the true model: the average NEES over 100
    independent runs at one step lies in its 95 % chi-square band for about 95 % of seeds
    (at least 90 of 100 here), and an overconfident filter's does not."""
    from sensorplan.tracking.ekf import joseph_update, nees, predict
    from sensorplan.study.metrics import nees_band

    runs, seeds, steps = 100, 100, 25
    F, Q = cv_matrices(1.0, 0.3)
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 1] = 1.0
    R = np.diag([25.0, 16.0])
    rng = np.random.default_rng(2024)
    B = runs * seeds
    x = rng.multivariate_normal(np.zeros(4), P0, size=B)            # truth
    m = np.zeros((B, 4))                                            # estimate
    P = np.broadcast_to(P0, (B, 4, 4)).copy()
    LQ, LR = np.linalg.cholesky(Q), np.linalg.cholesky(R)
    Hb, Rb = np.broadcast_to(H, (B, 2, 4)), np.broadcast_to(R, (B, 2, 2))
    for _ in range(steps):
        x = x @ F.T + rng.standard_normal((B, 4)) @ LQ.T
        m, P = predict(m, P, F, Q)
        z = x[:, :2] + rng.standard_normal((B, 2)) @ LR.T
        m, P = joseph_update(m, P, z - m[:, :2], Hb, Rb)
    per_seed = nees(x, m, P).reshape(seeds, runs).mean(axis=1)
    lo, hi = nees_band(runs)
    assert lo < 4.0 < hi
    inside = np.count_nonzero((per_seed >= lo) & (per_seed <= hi))
    assert inside >= 90, inside
    # The same errors judged by a filter that is twice too confident fall outside.
    over = nees(x, m, P / 2.0).reshape(seeds, runs).mean(axis=1)
    assert np.count_nonzero((over >= lo) & (over <= hi)) <= 10


def test_a_look_that_detects_every_target_never_restarts_a_track_from_another_targets_detection():
    from sensorplan.models.radar import measure_looks
    from sensorplan.tracking.base import Looks

    means = np.array([[300.0, 300.0, 0.0, 0.0], [300.0, 420.0, 0.0, 0.0]])
    sxy, hd = np.array([[50.0, 300.0]]), np.array([0.2])
    # the look aims at target 0 and returns only target 1's detection (far outside 0's gate)
    h, _, _, seen = measure_looks(TABLE, np.zeros(1, dtype=np.int64), means[1:2, :2], sxy, hd)
    assert seen.all()
    looks = Looks(sensors=np.zeros(1, dtype=np.int64), aims=np.zeros(1, dtype=np.int64),
                  positions=sxy, headings=hd, detections=(h,))
    opts = dict(process_noise=0.05, gate_probability=0.999, reacquire=True)
    one_target = KnownTargetTracker(means, P0, 1.0, TABLE, **opts)
    rec = one_target.update(looks)             # a look at 0 returns 0's: the track restarts
    assert rec.restarted[0]
    every = KnownTargetTracker(means, P0, 1.0, TABLE, detects_all=True, **opts)
    rec = every.update(looks)                  # it is another target's: discarded
    assert not rec.restarted.any() and rec.used[0] == 0 and rec.discarded[0] == 1
    np.testing.assert_array_equal(every.means, means)
