"""The PMB tracker with IMM modes in its Bernoullis: the contract, the single model it
reduces to, and one predict-update-predict cycle against a second computation written from
the IMM's and the Bernoulli's definitions (information-form Kalman updates, scipy
densities, numpy mixing; none of the tracker's kernels)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from sensorplan.models import linear, radar
from sensorplan.models.motion import cv_matrices
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.base import Looks, planning_tracks
from sensorplan.tracking.checks import CHECKS, Scene, check_tracker
from sensorplan.tracking.imm import stationary
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from looks_helpers import MEANS, SENSORS, looks_of

P0 = np.diag([400.0, 400.0, 4.0, 4.0])
PI = np.array([[0.9, 0.1], [0.25, 0.75]])
EXACT = 1e-12


def radar_steps(table: np.ndarray, steps: int, seed: int) -> list[Looks]:
    """Two radars staring at two targets walking straight, with Swerling-free detection
    noise and clutter: the same looks for every tracker compared."""
    rng = np.random.default_rng(seed)
    out = []
    for t in range(steps):
        xy = MEANS[:, :2] + (t + 1) * MEANS[:, 2:]
        heads = np.arctan2(xy[:, 1] - SENSORS[:, 1], xy[:, 0] - SENSORS[:, 0])
        h, _, var, seen = radar.measure_looks(table, np.arange(2), xy, SENSORS, heads)
        dets = []
        for n in range(2):
            z = (h[n:n + 1] + np.sqrt(var[n]) * rng.standard_normal((1, 2)))[
                : int(seen[n] and rng.random() < 0.85)]
            u = rng.random((int(rng.poisson(1.0)), 2))
            fa = radar.false_alarms(table, n, SENSORS[n], heads[n], u,
                                    rng.standard_normal((len(u), 2)))
            dets.append(np.concatenate([z, fa]))
        out.append(looks_of(np.arange(2), SENSORS, heads, tuple(dets)))
    return out


def radar_model(edge: str | None = "exit") -> MapModel:
    params = SensorParams(clutter_rate=1.0)
    return MapModel(radar_table((params, params)), 1.0, (600.0, 600.0), process_noise=0.5,
                    map_edge=edge)


def test_the_imm_pmb_meets_the_tracker_contract() -> None:
    model = radar_model()
    looks = radar_steps(model.measurement, 1, 0)[0]
    report = check_tracker(lambda: PMBTracker(
        model, means=MEANS, covs=P0, births="edges", birth_rate=0.1, initial_undetected=2.0,
        mode_process_noise=(0.05, 5.0), switching=PI, planning_threshold=0.05), Scene(looks))
    assert report.checks == tuple(CHECKS)


@pytest.mark.parametrize("edge_exit", ["outside", "crossing"])
@pytest.mark.parametrize("modes", [((0.5,), [[1.0]]), ((0.5, 0.5), PI)])
def test_modes_of_one_q_are_the_single_model(modes: tuple, edge_exit: str) -> None:
    """One mode, or two with the same q, is the single-model Bernoulli: through births,
    clutter, starts, the map's exit edge and pruning, every reported number to 1e-12."""
    model = radar_model()
    kw = dict(means=MEANS, covs=P0, births="edges", birth_rate=0.2, initial_undetected=1.0,
              edge_exit=edge_exit)
    single = PMBTracker(model, **kw)
    imm = PMBTracker(model, mode_process_noise=modes[0], switching=np.array(modes[1]), **kw)
    for looks in radar_steps(model.measurement, 25, 3):
        for tr in (single, imm):
            tr.predict()
            tr.update(looks)
        a, b = single.tracks(), imm.tracks()
        assert a.labels.tolist() == b.labels.tolist()
        np.testing.assert_allclose(b.existence, a.existence, rtol=EXACT, atol=EXACT)
        np.testing.assert_allclose(b.means, a.means, rtol=EXACT, atol=1e-9)
        np.testing.assert_allclose(b.covs, a.covs, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(imm.undetected, single.undetected, rtol=1e-10, atol=1e-15)
    assert single.next_label > 2                         # the scene started Bernoullis
    np.testing.assert_allclose(imm.planning_process_noise(), 0.5, rtol=EXACT)


def kalman_information(m: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray,
                       R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman update in information form (a second computation)."""
    Y = np.linalg.solve(P, np.eye(4)) + H.T @ np.linalg.solve(R, H)
    P_post = np.linalg.solve(Y, np.eye(4))
    y = np.linalg.solve(P, m) + H.T @ np.linalg.solve(R, z)
    return P_post @ y, P_post


def imm_predict(mu: np.ndarray, x: np.ndarray, P: np.ndarray, F: np.ndarray,
                Qs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IMM mixing and prediction from the definitions, mode by mode."""
    R = len(mu)
    c = np.array([sum(PI[i, j] * mu[i] for i in range(R)) for j in range(R)])
    xs, Ps = [], []
    for j in range(R):
        w = np.array([PI[i, j] * mu[i] / c[j] for i in range(R)])
        x0 = sum(w[i] * x[i] for i in range(R))
        P0_ = sum(w[i] * (P[i] + np.outer(x[i] - x0, x[i] - x0)) for i in range(R))
        xs.append(F @ x0)
        Ps.append(F @ P0_ @ F.T + Qs[j])
    return c / c.sum(), np.array(xs), np.array(Ps)


def test_one_cycle_matches_the_imm_bernoulli_written_from_its_definition() -> None:
    """One named Bernoulli, two modes, the linear sensor: predict, a scan with one
    detection (the Bernoulli or clutter), predict again. Every mode's probability, mean and
    covariance, the existence and the combined track against a second computation."""
    pd, lam, sigma2 = 0.8, 3.0, 25.0
    sensor = linear.LinearSensor((0.0, 0.0, 1000.0, 1000.0), sigma2, pd, lam)
    q = (0.2, 20.0)
    r0 = 0.9
    m0, C0 = np.array([500.0, 500.0, 3.0, -1.0]), np.diag([100.0, 80.0, 4.0, 2.0])
    tr = PMBTracker(MapModel(sensor, 1.0, (1000.0, 1000.0)), means=m0[None], covs=C0,
                    existence=r0, mode_process_noise=q, switching=PI, prune_threshold=0.0)
    z = np.array([505.0, 497.0])
    tr.predict()
    tr.update(looks_of([0], np.zeros((1, 2)), np.zeros(1), (z[None],)))
    tr.predict()

    F = cv_matrices(1.0, 0.0)[0]
    Qs = np.stack([cv_matrices(1.0, v)[1] for v in q])
    mu = stationary(PI)
    mu, x, P = imm_predict(mu, np.array([m0, m0]), np.array([C0, C0]), F, Qs)
    r = 0.99 * r0                                        # the default survival
    H, Rm = np.eye(2, 4), sigma2 * np.eye(2)
    lik = np.array([multivariate_normal(H @ x[j], H @ P[j] @ H.T + Rm).pdf(z)
                    for j in range(2)])
    l_b = mu @ lik
    kappa = lam / 1000.0 ** 2
    w_det, w_miss = r * pd * l_b, 1.0 - r * pd
    p_det = w_det / (w_det + w_miss * kappa)
    # Each mode: its missed hypothesis (the density unchanged: Pd is the same everywhere)
    # and its detection.
    weights, xs, Ps = [], [], []
    for j in range(2):
        a = (1.0 - p_det) * r * mu[j] * (1.0 - pd) / (1.0 - r * pd)
        b = p_det * mu[j] * lik[j] / l_b
        xu, Pu = kalman_information(x[j], P[j], z, H, Rm)
        mean = (a * x[j] + b * xu) / (a + b)
        cov = (a * (P[j] + np.outer(x[j] - mean, x[j] - mean))
               + b * (Pu + np.outer(xu - mean, xu - mean))) / (a + b)
        weights.append(a + b)
        xs.append(mean)
        Ps.append(cov)
    r_post = sum(weights)
    mu_post = np.array(weights) / r_post
    mu2, x2, P2 = imm_predict(mu_post, np.array(xs), np.array(Ps), F, Qs)
    b_ = tr.bern
    np.testing.assert_allclose(b_.r, [0.99 * r_post], rtol=EXACT)
    np.testing.assert_allclose(b_.mode_probs[0], mu2, rtol=1e-11)
    np.testing.assert_allclose(b_.mode_means[0], x2, rtol=EXACT, atol=1e-10)
    np.testing.assert_allclose(b_.mode_covs[0], P2, rtol=1e-10, atol=1e-10)
    mean = mu2 @ x2
    cov = sum(mu2[j] * (P2[j] + np.outer(x2[j] - mean, x2[j] - mean)) for j in range(2))
    np.testing.assert_allclose(b_.means[0], mean, rtol=EXACT, atol=1e-10)
    np.testing.assert_allclose(b_.covs[0], cov, rtol=1e-10, atol=1e-10)
    # The planner's q: each track's modes one step ahead.
    np.testing.assert_allclose(tr.planning_process_noise(), [(mu2 @ PI) @ np.array(q)],
                               rtol=EXACT)


def test_a_turn_moves_the_mode_probability_to_the_manoeuvre_mode() -> None:
    """A target that turns hard after flying straight: the manoeuvre mode's probability
    rises while it turns, and the track follows it closer than the quiet mode alone."""
    sensor = linear.LinearSensor((0.0, 0.0, 3000.0, 3000.0), 4.0, 1.0, 0.0)
    model = MapModel(sensor, 1.0, (3000.0, 3000.0), process_noise=0.01)
    start = np.array([500.0, 1500.0, 30.0, 0.0])
    imm = PMBTracker(model, means=start[None], covs=np.diag([4.0, 4.0, 1.0, 1.0]),
                     mode_process_noise=(0.01, 50.0), switching=PI)
    rng = np.random.default_rng(9)
    x = start.copy()
    manoeuvre = []
    for t in range(40):
        turn = 20 <= t < 30                              # 9 degrees a step: 4.7 m/s^2
        if turn:
            c, s = math.cos(math.radians(9.0)), math.sin(math.radians(9.0))
            x[2:] = [c * x[2] - s * x[3], s * x[2] + c * x[3]]
        x[:2] += x[2:]
        z = x[:2] + 2.0 * rng.standard_normal(2)
        imm.predict()
        imm.update(looks_of([0], np.zeros((1, 2)), np.zeros(1), (z[None],)))
        manoeuvre.append(imm.bern.mode_probs[0, 1])
    assert max(manoeuvre[:20]) < 0.3 < min(manoeuvre[22:30])
    assert len(planning_tracks(imm)) == 1


def test_bad_modes_are_refused_naming_the_argument() -> None:
    model = radar_model()
    with pytest.raises(ValueError, match="switching"):
        PMBTracker(model, mode_process_noise=(0.1, 1.0), switching=np.array([[1.0, 0.0]]))
    with pytest.raises(ValueError, match="switching"):
        PMBTracker(model, mode_process_noise=(0.1, 1.0), switching=np.array([[0.5, 0.6],
                                                                              [0.5, 0.5]]))
    with pytest.raises(ValueError, match="mode_process_noise"):
        PMBTracker(model, mode_process_noise=(-1.0, 1.0), switching=PI)
    with pytest.raises(ValueError, match="go together"):
        PMBTracker(model, mode_process_noise=(0.1, 1.0))
    own = MapModel(model.measurement, 1.0, (600.0, 600.0), motion=cv_matrices(1.0, 1.0))
    with pytest.raises(ValueError, match="own motion"):
        PMBTracker(own, mode_process_noise=(0.1, 1.0), switching=PI)


def test_at_an_exit_edge_each_mode_keeps_its_own_mass_on_the_map() -> None:
    """A Bernoulli heading out of the map: the wide manoeuvre mode has more of its density
    off the map than the quiet one, so the existence is multiplied by the modes' total mass
    on the map and the quiet mode gains probability (masses from scipy's normal CDF, the
    predicted modes from the definitions)."""
    from scipy.stats import norm

    model = radar_model("exit")
    m0, C0 = np.array([590.0, 300.0, 4.0, 0.0]), np.diag([9.0, 9.0, 1.0, 1.0])
    q = (0.05, 30.0)
    tr = PMBTracker(model, means=m0[None], covs=C0, mode_process_noise=q, switching=PI,
                    survival_probability=1.0)
    tr.predict()
    F = cv_matrices(1.0, 0.0)[0]
    Qs = np.stack([cv_matrices(1.0, v)[1] for v in q])
    mu, x, P = imm_predict(stationary(PI), np.array([m0, m0]), np.array([C0, C0]), F, Qs)
    mass = np.array([np.prod([norm.cdf(600.0, x[j, k], math.sqrt(P[j, k, k]))
                              - norm.cdf(0.0, x[j, k], math.sqrt(P[j, k, k]))
                              for k in (0, 1)]) for j in range(2)])
    assert mass[0] > mass[1]
    np.testing.assert_allclose(tr.bern.r, [mu @ mass], rtol=1e-9)
    np.testing.assert_allclose(tr.bern.mode_probs[0], mu * mass / (mu @ mass), rtol=1e-9)
