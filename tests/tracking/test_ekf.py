"""EKF: the update against independent forms, NEES consistency, long-run definiteness."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import chi2

from radar_reference import jacobian, measure, noise_cov, stack_params, take_params
from sensorplan.models.motion import cv_matrices, predict_covariance
from sensorplan.tracking.ekf import (joseph_update, nees, position_update, predict,
                                     standard_update, update, update_rounds)
from sensorplan.planners.problem import MapRect
from sensorplan.simulation.scenario import Scenario, SensorSpec, TargetSpec, make_truth
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.tracker import KnownTargetTracker


def table_of(params: SensorParams) -> np.ndarray:
    """Radar table with one row per entry of stacked (or scalar) parameters."""
    names = [f.name for f in dataclasses.fields(SensorParams)
             if f.name not in ("moves", "detection")]
    cols = [np.atleast_1d(np.asarray(getattr(params, n), dtype=float)) for n in names]
    n = max(len(c) for c in cols)
    return radar_table([SensorParams(**{k: float(np.broadcast_to(c, (n,))[i])
                                        for k, c in zip(names, cols)}) for i in range(n)])


def random_covariance(rng: np.random.Generator, pos_sd=(5.0, 30.0), vel_sd=(0.5, 3.0)):
    """A random well-conditioned SPD state covariance with correlated entries."""
    sd = np.concatenate([rng.uniform(*pos_sd, size=2), rng.uniform(*vel_sd, size=2)])
    A = rng.normal(size=(4, 4))
    S = A @ A.T + 4.0 * np.eye(4)
    d = np.sqrt(np.diag(S))
    P = S / np.outer(d, d) * np.outer(sd, sd)
    return 0.5 * (P + P.T)


def varied_params(rng: np.random.Generator, n: int) -> SensorParams:
    """Stacked ``(n,)`` parameters drawn around the defaults."""
    return stack_params([SensorParams(
        altitude=float(rng.uniform(400, 600)), depression=float(rng.uniform(0.4, 0.9)),
        snr_ref_db=float(rng.uniform(10, 20)), range_ref=float(rng.uniform(500, 700)),
        beamwidth=float(rng.uniform(0.03, 0.07)), monopulse_slope=float(rng.uniform(1.2, 2)),
        range_resolution=float(rng.uniform(20, 40))) for _ in range(n)])


def geometry(rng: np.random.Generator, B: int):
    """Targets ``(B, 4)`` and sensor poses in front of them (cos psi > 0)."""
    x = np.column_stack([rng.uniform(0, 600, (B, 2)), rng.uniform(-5, 5, (B, 2))])
    bearing = rng.uniform(-np.pi, np.pi, B)
    g = rng.uniform(250, 450, B)
    sensor_xy = x[:, :2] - g[:, None] * np.column_stack([np.cos(bearing), np.sin(bearing)])
    heading = bearing + rng.uniform(-0.5, 0.5, B)
    return x, sensor_xy, heading


class TestLinearization:
    def test_update_linearises_with_the_reference_model(self, rng):
        """One update with a zero innovation's gain equals the reference H and R."""
        B = 300
        x, sxy, th = geometry(rng, B)
        params = varied_params(rng, B)
        P = np.array([random_covariance(rng) for _ in range(B)])
        z = measure(x, sxy, params.altitude) + rng.normal(size=(B, 2)) * [2.0, 0.003]
        got = update(x, P, z, sxy, th, table_of(params), np.arange(B))
        H = jacobian(x, sxy, params.altitude)
        R = noise_cov(x, sxy, th, params)
        inn = z - measure(x, sxy, params.altitude)
        inn[:, 1] = (inn[:, 1] + np.pi) % (2 * np.pi) - np.pi
        want = joseph_update(x, P, inn, H, R)
        np.testing.assert_allclose(got[0], want[0], rtol=1e-11, atol=1e-9)
        np.testing.assert_allclose(got[1], want[1], rtol=1e-11, atol=1e-9)

    def test_rows_default_to_the_first(self, rng):
        x, sxy, th = geometry(rng, 5)
        P = np.tile(np.diag([100.0, 100.0, 1.0, 1.0]), (5, 1, 1))
        z = measure(x, sxy, 500.0)
        a = update(x, P, z, sxy, th, radar_table(SensorParams()))
        b = update(x, P, z, sxy, th, np.tile(radar_table(SensorParams()), (5, 1)), np.arange(5))
        for u, v in zip(a, b):
            np.testing.assert_array_equal(u, v)


def well_conditioned(rng: np.random.Generator, B: int):
    P = np.array([random_covariance(rng, (5.0, 30.0), (0.5, 3.0)) for _ in range(B)])
    x = rng.normal(size=(B, 4))
    H = rng.normal(size=(B, 2, 4)) * np.array([1.0, 1.0, 0.3, 0.3])
    sd = rng.uniform(1.0, 10.0, size=(B, 2))
    R = np.zeros((B, 2, 2))
    R[:, 0, 0], R[:, 1, 1] = sd[:, 0] ** 2, sd[:, 1] ** 2
    R[:, 0, 1] = R[:, 1, 0] = 0.3 * sd[:, 0] * sd[:, 1]
    innovation = rng.normal(size=(B, 2))
    return x, P, innovation, H, R


class TestUpdateForms:
    def test_joseph_equals_standard_update(self, rng):
        x, P, inn, H, R = well_conditioned(rng, 200)
        xj, Pj = joseph_update(x, P, inn, H, R)
        xs, Ps = standard_update(x, P, inn, H, R)
        np.testing.assert_allclose(xj, xs, rtol=1e-9, atol=1e-9)
        scale = np.abs(P).max(axis=(1, 2))[:, None, None]
        assert np.all(np.abs(Pj - Ps) <= 1e-9 * scale)

    def test_joseph_equals_information_form(self, rng):
        x, P, inn, H, R = well_conditioned(rng, 100)
        _, Pj = joseph_update(x, P, inn, H, R)
        Ht = np.swapaxes(H, -1, -2)
        J = np.linalg.inv(P) + Ht @ np.linalg.solve(R, H)
        np.testing.assert_allclose(Pj @ J, np.broadcast_to(np.eye(4), Pj.shape), atol=1e-9)

    def test_position_update_equals_general_joseph(self, rng):
        x, P, inn, H, R = well_conditioned(rng, 100)
        Hp = H[:, :, :2]
        H[:, :, 2:] = 0.0
        var = rng.uniform(0.5, 20.0, size=(100, 2))
        R = np.zeros((100, 2, 2))
        R[:, 0, 0], R[:, 1, 1] = var[:, 0], var[:, 1]
        xa, Pa = position_update(x, P, inn, Hp, var)
        xb, Pb = joseph_update(x, P, inn, H, R)
        np.testing.assert_allclose(xa, xb, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Pa, Pb, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(Pa, np.swapaxes(Pa, -1, -2))

    def test_update_equals_textbook_ekf(self, rng):
        B = 50
        x, sxy, th = geometry(rng, B)
        params = varied_params(rng, B)
        P = np.array([random_covariance(rng) for _ in range(B)])
        z = measure(x, sxy, params.altitude) + rng.normal(size=(B, 2)) * [2.0, 0.003]
        xa, Pa = update(x, P, z, sxy, th, table_of(params), np.arange(B))
        H = jacobian(x, sxy, params.altitude)
        R = noise_cov(x, sxy, th, params)
        for b in range(B):
            S = H[b] @ P[b] @ H[b].T + R[b]
            K = P[b] @ H[b].T @ np.linalg.inv(S)
            y = z[b] - measure(x[b], sxy[b], params.altitude[b])
            y[1] = (y[1] + np.pi) % (2 * np.pi) - np.pi
            np.testing.assert_allclose(xa[b], x[b] + K @ y, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(Pa[b], (np.eye(4) - K @ H[b]) @ P[b], rtol=1e-7,
                                       atol=1e-9)

    def test_bearing_innovation_is_wrapped(self):
        # Target just across the -x axis from the sensor: predicted azimuth near +pi, the
        # measurement near -pi. Unwrapped, the innovation would be about -2 pi.
        x = np.array([[-400.0, 1.0, 0.0, 0.0]])
        sxy = np.zeros((1, 2))
        P = np.diag([100.0, 100.0, 1.0, 1.0])[None]
        params = SensorParams()
        z = measure(np.array([[-400.0, -1.0]]), sxy, params.altitude)
        assert z[0, 1] < -3.1 and measure(x, sxy, params.altitude)[0, 1] > 3.1
        xa, _ = update(x, P, z, sxy, np.array([np.pi]), radar_table(params))
        assert -1.0 - 1e-6 < xa[0, 1] < 1.0 and abs(xa[0, 0] + 400.0) < 1.0

    def test_predict_matches_dynamics(self, rng):
        F, Q = cv_matrices(0.7, 0.3)
        P = np.array([random_covariance(rng) for _ in range(4)])
        x = rng.normal(size=(4, 4))
        xp, Pp = predict(x, P, F, Q)
        np.testing.assert_allclose(xp, x @ F.T, rtol=1e-14)
        np.testing.assert_allclose(Pp, predict_covariance(P, F, Q), rtol=1e-14)

    def test_nees_closed_form(self, rng):
        P = np.array([random_covariance(rng) for _ in range(6)])
        e = rng.normal(size=(6, 4))
        expected = [float(v @ np.linalg.inv(Pi) @ v) for v, Pi in zip(e, P)]
        np.testing.assert_allclose(nees(e, np.zeros_like(e), P), expected, rtol=1e-10)


class TestTracker:
    def setup(self, rng, M=4, N=5):
        x, sxy, th = geometry(rng, N)
        params = varied_params(rng, N)
        means = np.column_stack([x[:, :2][:M] + rng.normal(0, 10, (M, 2)), x[:M, 2:]])
        covs = np.array([random_covariance(rng) for _ in range(M)])
        return x, sxy, th, params, means, covs

    def test_rounds(self):
        assert [r.tolist() for r in update_rounds(np.array([2, 0, 1]))] == [[0, 1, 2]]
        assert [r.tolist() for r in update_rounds(np.array([3, 1, 3, 3, 1, 0]))] == [
            [0, 1, 5], [2, 4], [3]]
        assert [r.tolist() for r in update_rounds(np.array([], dtype=np.int64))] == [[]]

    def test_batched_updates_equal_sequential_single_updates(self, rng):
        x, sxy, th, params, means, covs = self.setup(rng)
        sensors = np.array([0, 1, 2, 3, 4])
        targets = np.array([1, 3, 1, 0, 1])           # target 1 measured three times
        z = measure(x[:, :2][np.array([0, 1, 0, 3, 0])] + 3.0, sxy, params.altitude)
        tr = KnownTargetTracker(means, covs, 1.0, table_of(params), process_noise=0.05)
        tr.update_detections(sensors, targets, z, sxy, th)
        m, P = means.copy(), covs.copy()
        for s, j in zip(sensors, targets):  # sensor order, one measurement at a time
            m[[j]], P[[j]] = update(m[[j]], P[[j]], z[[s]], sxy[[s]], th[[s]],
                                    table_of(take_params(params, [s])))
        np.testing.assert_allclose(tr.means, m, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(tr.covs, P, rtol=1e-13, atol=1e-12)
        np.testing.assert_array_equal(tr.covs[2], covs[2])    # an unmeasured track is untouched
        np.testing.assert_array_equal(tr.means[2], means[2])

    def test_predict_all_tracks(self, rng):
        *_, params, means, covs = self.setup(rng)
        tr = KnownTargetTracker(means, covs, 2.0, table_of(params), process_noise=0.1)
        tr.predict()
        F, Q = cv_matrices(2.0, 0.1)
        np.testing.assert_allclose(tr.means, means @ F.T)
        np.testing.assert_allclose(tr.covs, predict_covariance(covs, F, Q))


def consistency_setup(n_runs: int, seed: int):
    """n_runs independent always-observed CV targets, one per track (a batch of runs)."""
    world = MapRect(1e7, 1e7)
    sc = Scenario(world=world, targets=tuple(TargetSpec("cv") for _ in range(n_runs)),
                  sensors=(SensorSpec(),), process_noise=0.05)
    rng = np.random.default_rng(seed)
    h = rng.uniform(-np.pi, np.pi, n_runs)
    v = rng.uniform(3, 6, n_runs)
    truth0 = np.column_stack([np.full(n_runs, 5e6), np.full(n_runs, 5e6), v * np.cos(h),
                              v * np.sin(h)])
    P0 = np.diag([20.0**2, 20.0**2, 2.0**2, 2.0**2])
    est0 = truth0 + rng.standard_normal((n_runs, 4)) @ np.linalg.cholesky(P0).T
    return sc, rng, truth0, est0, P0


class TestConsistency:
    def test_mean_nees_inside_chi_square_bounds(self):
        n_runs, steps = 200, 60
        sc, rng, truth0, est0, P0 = consistency_setup(n_runs, 11)
        truth = make_truth(sc, truth0, rng)
        tracker = KnownTargetTracker(est0, P0, sc.dt, radar_table(SensorParams()),
                          process_noise=sc.process_noise)
        # The sensor flies with each target, 350 m behind it in x (constant geometry).
        offset = np.array([350.0, 0.0])
        heading = np.zeros(n_runs)
        sensors = np.zeros(n_runs, dtype=np.int64)
        targets = np.arange(n_runs)
        lo, hi = chi2.ppf([0.025, 0.975], 4 * n_runs) / n_runs
        mean_nees = []
        for _ in range(steps):
            x = truth.step()
            tracker.predict()
            sxy = x[:, :2] - offset
            R = noise_cov(x, sxy, heading, SensorParams())
            noise = rng.standard_normal((n_runs, 2)) * np.sqrt(
                np.stack([R[:, 0, 0], R[:, 1, 1]], axis=-1))
            z = measure(x, sxy, 500.0) + noise
            tracker.update_detections(sensors, targets, z, sxy, heading)
            mean_nees.append(nees(x, tracker.means, tracker.covs).mean())
        mean_nees = np.array(mean_nees)
        assert lo <= mean_nees[-1] <= hi, (lo, mean_nees[-1], hi)
        # A consistent filter is inside its 95% band at about 95% of the steps (after the
        # first 10, where linearising at a 20 m initial error inflates NEES a little).
        tail = mean_nees[10:]
        inside = np.mean((tail >= lo) & (tail <= hi))
        assert inside >= 0.85, (inside, mean_nees)

    def test_overconfident_filter_fails_the_same_check(self):
        # Sanity of the check itself: a filter that believes R is 100 times smaller is
        # outside the band.
        n_runs = 200
        sc, rng, truth0, est0, P0 = consistency_setup(n_runs, 11)
        truth = make_truth(sc, truth0, rng)
        params = SensorParams(range_resolution=3.0, beamwidth=math.radians(0.3))
        tracker = KnownTargetTracker(est0, P0, sc.dt, radar_table(params),
                          process_noise=sc.process_noise)
        offset = np.array([350.0, 0.0])
        heading = np.zeros(n_runs)
        for _ in range(30):
            x = truth.step()
            tracker.predict()
            sxy = x[:, :2] - offset
            R = noise_cov(x, sxy, heading, SensorParams())
            z = measure(x, sxy, 500.0) + rng.standard_normal((n_runs, 2)) * np.sqrt(
                np.stack([R[:, 0, 0], R[:, 1, 1]], axis=-1))
            tracker.update_detections(np.zeros(n_runs, dtype=np.int64), np.arange(n_runs), z, sxy,
                           heading)
        hi = chi2.ppf(0.975, 4 * n_runs) / n_runs
        assert nees(x, tracker.means, tracker.covs).mean() > hi

    def test_covariances_stay_spd_over_10000_steps(self):
        rng = np.random.default_rng(77)
        M, N = 3, 4
        sc = Scenario(world=MapRect(1e8, 1e8), targets=tuple(TargetSpec("cv") for _ in range(M)),
                      sensors=(SensorSpec(),))
        truth0 = np.column_stack([np.full((M, 2), 5e7), rng.uniform(-5, 5, (M, 2))])
        truth = make_truth(sc, truth0, rng)
        params = varied_params(rng, N)
        tracker = KnownTargetTracker(truth0 + rng.normal(0, 10, (M, 4)) * [1, 1, 0.1, 0.1],
                          np.diag([400.0, 400.0, 4.0, 4.0]), 1.0, table_of(params),
                          process_noise=0.05)
        for step in range(10_000):
            x = truth.step()
            tracker.predict()
            on = rng.random(N) < 0.3                       # intermittent looks
            targets = rng.integers(M, size=N)[on]          # sometimes the same target twice
            sensors = np.flatnonzero(on)
            if len(sensors):
                ang = rng.uniform(-np.pi, np.pi, len(sensors))
                g = rng.uniform(250, 450, len(sensors))
                sxy = x[targets, :2] - g[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
                th = ang + rng.uniform(-0.5, 0.5, len(sensors))
                R = noise_cov(x[targets], sxy, th, take_params(params, sensors))
                z = measure(x[targets], sxy, params.altitude[sensors]) + rng.standard_normal(
                    (len(sensors), 2)) * np.sqrt(np.stack([R[:, 0, 0], R[:, 1, 1]], -1))
                tracker.update_detections(sensors, targets, z, sxy, th)
            P = tracker.covs
            assert np.array_equal(P, np.swapaxes(P, -1, -2)), step
            np.linalg.cholesky(P)  # raises if not positive definite
        assert np.all(np.isfinite(tracker.means))

    @pytest.mark.parametrize("prior_sd", [1e3, 1e5])
    def test_joseph_stays_spd_with_precise_measurements_and_vague_priors(self, prior_sd, rng):
        # A large prior against sub-metre range noise: the regime Joseph form is for.
        x, sxy, th = geometry(rng, 50)
        P = np.tile(np.diag([prior_sd**2, prior_sd**2, 1e2, 1e2]), (50, 1, 1))
        params = SensorParams(range_resolution=0.5)
        z = measure(x, sxy, params.altitude)
        for _ in range(20):
            x, P = update(x, P, z, sxy, th, radar_table(params))
            np.linalg.cholesky(P)
