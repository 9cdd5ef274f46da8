"""Tests of the missed-look update (``miss_update = "negative"``).

The sensing region is re-implemented here from its definition in polar form (ground range band and
azimuth wedge; ``cos psi > 0`` never binds for a wedge narrower than 90 degrees), so that
the counts and the Monte Carlo do not go through the library's radar model.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models.angles import wrap_angle
from sensorplan.tracking import missed
from sensorplan.models.motion import cv_matrices, predict_covariance
from sensorplan.tracking.missed import (INFLATE_FRACTION, MIN_OUTSIDE, N_POINTS, SOBOL_SEED,
                                        inside_fraction, miss_update, standard_points)
from sensorplan.models.sensors import SensorParams, radar_table

PARAMS = SensorParams()
ORIGIN = np.zeros(2)
IU = np.triu_indices(4)


def in_region(xy: np.ndarray, sensor_xy: np.ndarray, heading: float,
              params: SensorParams = PARAMS) -> np.ndarray:
    """The field of view on ground positions ``(..., 2)``, written independently."""
    d = xy - sensor_xy
    g = np.hypot(d[..., 0], d[..., 1])
    bearing = np.arctan2(d[..., 1], d[..., 0])
    return ((g >= params.min_ground_range) & (g <= params.max_ground_range)
            & (np.abs(wrap_angle(bearing - heading)) <= params.fov_half_angle))


def count_inside(mean: np.ndarray, cov: np.ndarray, sensor_xy: np.ndarray, heading: float,
                 params: SensorParams = PARAMS) -> int:
    """How many of the module's 512 points, mapped through ``cholesky(cov)``, are inside."""
    y = mean + standard_points() @ np.linalg.cholesky(cov).T
    return int(np.count_nonzero(in_region(y[:, :2], sensor_xy, heading, params)))


def polar(g: float, b: float) -> np.ndarray:
    return np.array([g * math.cos(b), g * math.sin(b)])


def track_cov(scale: float = 1.0, angle: float = 0.0) -> np.ndarray:
    """A track covariance with position-velocity and x-y correlations (5 steps of CV motion
    from a diagonal one, rotated by ``angle``)."""
    F, _ = cv_matrices(1.0, 0.05)
    F5 = np.linalg.matrix_power(F, 5)
    P = F5 @ np.diag([30.0**2, 20.0**2, 3.0**2, 3.0**2]) @ F5.T
    c, s = math.cos(angle), math.sin(angle)
    R = np.kron(np.eye(2), np.array([[c, -s], [s, c]]))
    P = scale * (R @ P @ R.T)
    return 0.5 * (P + P.T)


def assert_spd(P: np.ndarray) -> None:
    np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
    assert np.all(np.linalg.eigvalsh(P) > 0.0)


# --------------------------------------------------------------------------- point set


def test_standard_points_are_exactly_whitened():
    X = standard_points()
    assert X.shape == (N_POINTS, 4)
    np.testing.assert_allclose(X.mean(axis=0), 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(X.T @ X / N_POINTS, np.eye(4), rtol=0, atol=1e-13)
    assert not X.flags.writeable
    # Standard normal in distribution as well: marginal quartiles near +-0.674.
    q = np.quantile(X, [0.25, 0.75], axis=0)
    np.testing.assert_allclose(q, [[-0.6745] * 4, [0.6745] * 4], atol=0.05)


def test_standard_points_are_deterministic_and_seeded():
    X = standard_points().copy()
    standard_points.cache_clear()
    np.testing.assert_array_equal(standard_points(), X)
    assert not np.array_equal(standard_points(N_POINTS, SOBOL_SEED + 1), X)
    with pytest.raises(ValueError, match="power of two"):
        standard_points(500)


# --------------------------------------------------------------------------- Monte Carlo

#: name -> (mean, covariance, sensor position, heading). The sensor sees the annular sector
#: 250..450 m within +-30 degrees of its heading.
GEOMETRIES = {
    # the mean on the inner range edge: the region takes about half of the ellipse
    "half": (np.array([250.0, 10.0, 2.0, -1.0]), track_cov(1.0, 0.5), ORIGIN, 0.0),
    # the mean beside the wedge: the region takes a sliver (a few per cent)
    "sliver": (np.r_[polar(350.0, math.pi / 6 + 0.14), 1.0, 1.0], track_cov(1.0, 1.2),
               ORIGIN, 0.0),
    # the mean in the blind disc under the sensor; the band takes a slice of a wide ellipse
    "blind-disc": (np.array([120.0, 20.0, 0.0, 2.0]), track_cov(10.0, 0.3), ORIGIN, 0.0),
    # the mean on the outer corner of the sector, sensor elsewhere and turned
    "corner": (np.r_[np.array([100.0, -50.0]) + polar(450.0, 2.0 + math.pi / 6), -2.0, 0.0],
               track_cov(1.0, -0.4), np.array([100.0, -50.0]), 2.0),
}

MC_SAMPLES = 100_000
RQMC_REPLICATES = 32
Z_TOL = 4.0


@pytest.mark.parametrize("name", list(GEOMETRIES))
def test_moments_match_monte_carlo(name):
    """Moment-matched mean and covariance vs a 1e5-sample Monte Carlo of the truncation.

    Tolerance per moment (4 mean entries, 10 covariance entries): ``Z_TOL`` standard errors
    of the difference, ``sqrt(se_mc^2 + se_q^2)``. ``se_mc`` is the Monte Carlo standard error
    estimated from the samples (std of ``d_i`` resp. ``d_i d_j`` over sqrt(n)); ``se_q``, the
    error of the 512-point quadrature, is the spread of the same estimator over 32
    independently scrambled Sobol sets (scrambling makes the fixed set one draw of that
    randomised-QMC estimator). Measured: ``se_q`` is 0.05-0.3 times the error of 512 plain
    Monte Carlo points, the same order as ``se_mc``; max |z| over all moments is about 2.5.
    """
    mean, cov, sxy, th = GEOMETRIES[name]
    rng = np.random.default_rng(2024)
    y = mean + rng.standard_normal((MC_SAMPLES, 4)) @ np.linalg.cholesky(cov).T
    inside = in_region(y[:, :2], sxy, th)
    assert 0.01 < inside.mean() < 0.9        # the geometry really truncates
    y = y[~inside]
    n = len(y)
    mc_mean = y.mean(axis=0)
    d = y - mc_mean
    prod = d[:, :, None] * d[:, None, :]
    mc_cov = prod.mean(axis=0)
    se_mc = np.concatenate([d.std(axis=0), prod.std(axis=0)[IU]]) / math.sqrt(n)

    reps = []
    for s in range(RQMC_REPLICATES):
        X = standard_points(N_POINTS, 7000 + s)
        m_r, P_r, _ = miss_update(mean, cov, sxy, th, PARAMS, points=X)
        reps.append(np.concatenate([m_r, P_r[IU]]))
    se_q = np.std(reps, axis=0, ddof=1)

    new_mean, new_cov, inflated = miss_update(mean, cov, sxy, th, PARAMS)
    assert not inflated
    diff = np.concatenate([new_mean, new_cov[IU]]) - np.concatenate([mc_mean, mc_cov[IU]])
    z = diff / np.sqrt(se_mc**2 + se_q**2)
    assert np.all(np.abs(z) <= Z_TOL), f"{name}: z = {np.round(z, 2)}"


# --------------------------------------------------------------------------- invariants


def test_region_without_mass_leaves_tracks_unchanged():
    """Tracks whose 512 points all miss the region keep mean and covariance (1e-9)."""
    means = np.array([[300.0, 0.0, 3.0, -1.0],      # on the boresight but 5 km away
                      [100.0, 20.0, 0.0, 0.0],      # in the blind disc
                      [-350.0, 0.0, 1.0, 1.0],      # in the range band behind the sensor
                      [5.0e4, -3.0e4, 30.0, 2.0]])  # far away, large numbers
    sensors = np.array([[-4700.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    covs = np.array([track_cov(1.0, 0.2), track_cov(0.5, 1.0), track_cov(2.0, -0.7),
                     track_cov(50.0, 0.1)])
    headings = np.zeros(4)
    for j in range(4):
        assert count_inside(means[j], covs[j], sensors[j], 0.0) == 0
    new_means, new_covs, inflated = miss_update(means, covs, sensors, headings, PARAMS)
    assert not inflated.any()
    for j in range(4):
        np.testing.assert_allclose(new_means[j], means[j], rtol=1e-9,
                                   atol=1e-9 * np.sqrt(covs[j].diagonal()).max())
        np.testing.assert_allclose(new_covs[j], covs[j], rtol=0,
                                   atol=1e-9 * np.abs(covs[j]).max())


@pytest.mark.parametrize("case", ["inner edge", "outer edge", "wedge edge"])
def test_miss_pushes_mean_out_and_shrinks_covariance_across_the_edge(case):
    """With the region's edge through the mean, the mean moves out of the region along the
    edge's outward normal ``u`` and the variance ``u^T P u`` across the edge shrinks."""
    P = track_cov(1.0, 0.8)
    if case == "inner edge":      # the region lies beyond; u points back toward the sensor
        xy, u = polar(250.0, 0.1), -polar(1.0, 0.1)
    elif case == "outer edge":    # the region lies nearer; u points away from the sensor
        xy, u = polar(450.0, -0.1), polar(1.0, -0.1)
    else:                         # the region is clockwise of the mean
        b = math.pi / 6
        xy, u = polar(350.0, b), polar(1.0, b + math.pi / 2)
    mean = np.r_[xy, 1.0, -2.0]
    new_mean, new_cov, inflated = miss_update(mean, P, ORIGIN, 0.0, PARAMS)
    assert not inflated
    sd_u = math.sqrt(u @ P[:2, :2] @ u)
    assert (new_mean[:2] - xy) @ u > 0.3 * sd_u
    assert u @ new_cov[:2, :2] @ u < 0.8 * (u @ P[:2, :2] @ u)
    assert_spd(new_cov)


def _bisect(make, lo, hi, target, width=1e-6):
    """Parameter values ``a`` (count >= target) and ``b`` (count < target) ``width`` apart, for
    a count that is >= target at ``lo`` and < target at ``hi``. The width keeps the point
    that crosses the edge well clear of the 1e-9 m tolerance of the inclusive bounds."""
    assert make(lo) >= target > make(hi)
    while abs(hi - lo) > width:
        mid = 0.5 * (lo + hi)
        if make(mid) >= target:
            lo = mid
        else:
            hi = mid
    return lo, hi


#: Inflate when f >= 0.95; with 512 points that is 487 or more inside.
K_INFLATE = 487


def test_spec_constants():
    assert (N_POINTS, INFLATE_FRACTION) == (512, 0.95)
    assert math.ceil(0.95 * 512) == K_INFLATE


@pytest.mark.parametrize("how", ["scale covariance", "move mean"])
def test_inflation_triggers_exactly_at_the_threshold(how):
    """Cases with 487 and 486 points inside (f = 0.951 and 0.949), found by bisection on the
    covariance scale or the mean position with the points counted here."""
    centre = polar(350.0, 0.0)
    P0 = track_cov(0.05, 0.3)
    if how == "scale covariance":
        def state(a):
            return np.r_[centre, 1.0, 0.5], a * P0
        a_in, a_out = _bisect(lambda a: count_inside(*state(a), ORIGIN, 0.0), 0.1, 400.0,
                              K_INFLATE)
    else:
        def state(a):
            return np.r_[centre + [a, 0.0], 1.0, 0.5], P0
        a_in, a_out = _bisect(lambda a: count_inside(*state(a), ORIGIN, 0.0), 0.0, 100.0,
                              K_INFLATE)
    counts = [count_inside(*state(a), ORIGIN, 0.0) for a in (a_in, a_out)]
    assert counts == [K_INFLATE, K_INFLATE - 1]
    np.testing.assert_array_equal(
        inside_fraction(*state(a_in), ORIGIN, 0.0, PARAMS), K_INFLATE / N_POINTS)

    m_in, P_in = state(a_in)
    new_mean, new_cov, inflated = miss_update(m_in, P_in, ORIGIN, 0.0, PARAMS)
    assert inflated
    np.testing.assert_array_equal(new_mean, m_in)
    grow = np.diag([200.0**2 / 4, 200.0**2 / 4, 0.0, 0.0])
    np.testing.assert_allclose(new_cov, P_in + grow, rtol=1e-15, atol=1e-12)
    assert np.linalg.eigvalsh(new_cov - P_in).min() >= -1e-9 * np.abs(P_in).max()
    assert_spd(new_cov)

    m_out, P_out = state(a_out)
    new_mean, new_cov, inflated = miss_update(m_out, P_out, ORIGIN, 0.0, PARAMS)
    assert not inflated
    # Truncated to the 26 points outside: their mean and (1/n) covariance, computed here in
    # state space. (Not smaller than P: the points left are in the tails on both sides.)
    y = m_out + standard_points() @ np.linalg.cholesky(P_out).T
    y = y[~in_region(y[:, :2], ORIGIN, 0.0)]
    assert len(y) == N_POINTS - K_INFLATE + 1
    d = y - y.mean(axis=0)
    np.testing.assert_allclose(new_mean, y.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(new_cov, d.T @ d / len(y), rtol=1e-9, atol=1e-9 * P_out.max())
    assert_spd(new_cov)


def test_inflation_uses_each_tracks_own_range_band():
    """Per-track sensors: each track grows by its own sensor's (g_max - g_min)^2 / 4, and an
    inflation never makes a covariance smaller."""
    sensors = [SensorParams(min_ground_range=250.0, max_ground_range=450.0),
               SensorParams(min_ground_range=100.0, max_ground_range=700.0),
               SensorParams(min_ground_range=300.0, max_ground_range=320.0)]
    means = np.array([[350.0, 0.0, 0.0, 0.0], [400.0, 0.0, 1.0, 0.0], [310.0, 0.0, 0.0, 0.0]])
    covs = np.array([track_cov(0.02, 0.0), track_cov(0.5, 1.0), np.diag([1.0, 4.0, 1.0, 1.0])])
    new_means, new_covs, inflated = miss_update(means, covs, np.zeros((3, 2)), np.zeros(3),
                                                radar_table(sensors), np.arange(3))
    assert inflated.all()
    for j, s in enumerate(sensors):
        span2 = (s.max_ground_range - s.min_ground_range) ** 2 / 4
        np.testing.assert_allclose(new_covs[j] - covs[j], np.diag([span2, span2, 0, 0]),
                                   atol=1e-9)
        assert np.linalg.eigvalsh(new_covs[j] - covs[j]).min() >= -1e-9
    np.testing.assert_array_equal(new_means, means)


def test_too_few_points_left_fall_back_to_inflation():
    """With a small point set, f < 0.95 can leave fewer than MIN_OUTSIDE points; the update
    then inflates instead of fitting a degenerate covariance."""
    X16 = standard_points(16)
    P = track_cov(0.05, 0.3)
    results = {}
    for a in np.geomspace(1.0, 1000.0, 200):
        mean = np.r_[350.0, 0.0, 0.0, 0.0]
        y = mean + X16 @ np.linalg.cholesky(a * P).T
        n_out = int(np.count_nonzero(~in_region(y[:, :2], ORIGIN, 0.0)))
        if n_out not in results:
            results[n_out] = miss_update(mean, a * P, ORIGIN, 0.0, PARAMS, points=X16)
    assert {1, MIN_OUTSIDE - 1, MIN_OUTSIDE} <= set(results)
    for n_out, (_, new_cov, inflated) in results.items():
        assert inflated == (n_out < MIN_OUTSIDE), n_out
        assert_spd(new_cov)


def test_batched_equals_one_track_at_a_time(rng):
    """One batched call with per-track sensors (rows of a table) equals separate calls."""
    B = 7
    sensors = [SensorParams(altitude=490.0 + 10 * (j % 3), fov_half_angle=0.3 + 0.05 * j,
                            min_ground_range=200.0 + 10 * j) for j in range(B)]
    means = np.column_stack([rng.uniform(200, 400, (B, 2)), rng.normal(0, 3, (B, 2))])
    covs = np.array([track_cov(rng.uniform(0.3, 3.0), rng.uniform(-3, 3)) for _ in range(B)])
    bearing = rng.uniform(-math.pi, math.pi, B)
    sxy = means[:, :2] - rng.uniform(230, 470, (B, 1)) * np.column_stack(
        [np.cos(bearing), np.sin(bearing)])
    headings = bearing + rng.uniform(-0.5, 0.5, B)
    new_means, new_covs, inflated = miss_update(means, covs, sxy, headings,
                                                radar_table(sensors), np.arange(len(sensors)))
    for j in range(B):
        m, P, f = miss_update(means[j], covs[j], sxy[j], headings[j], sensors[j])
        np.testing.assert_allclose(new_means[j], m, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(new_covs[j], P, rtol=1e-12, atol=1e-9)
        assert inflated[j] == f


def test_deterministic_bit_for_bit(rng):
    """Same inputs, same outputs bit for bit, also with the point set recomputed."""
    B = 5
    means = np.column_stack([rng.uniform(200, 400, (B, 2)), rng.normal(0, 3, (B, 2))])
    covs = np.array([track_cov(rng.uniform(0.3, 3.0), rng.uniform(-3, 3)) for _ in range(B)])
    sxy = means[:, :2] - rng.uniform(200, 400, (B, 2))
    headings = rng.uniform(-math.pi, math.pi, B)
    first = miss_update(means, covs, sxy, headings, PARAMS)
    # Recompute the point set from scratch as a fresh process would.
    standard_points.cache_clear()
    missed._default_point_set.cache_clear()
    second = miss_update(means.copy(), covs.copy(), sxy.copy(), headings.copy(), PARAMS)
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)


def test_covariances_stay_spd_over_10000_steps_with_random_misses():
    """8 tracks, 10,000 steps of CV prediction (q = 0.05), each followed by a miss from a
    random sensor pose around each track (ground range 0-600 m, heading within 60 degrees of
    the track). Three tracks also get a position fix (sd 15 m, Joseph form) every 4 steps,
    so that their covariance stays near the size of the sensing region and truncations and
    inflations keep happening; three every 100 steps (sawtooth from tens to a few hundred
    metres); two never (their position sd grows to about 1e5 m)."""
    rng = np.random.default_rng(99)
    B, steps = 8, 10_000
    F, Q = cv_matrices(1.0, 0.05)
    H = np.eye(2, 4)
    R = 15.0**2 * np.eye(2)
    period = np.array([4, 4, 4, 100, 100, 100, steps + 1, steps + 1])
    means = np.column_stack([rng.uniform(0, 600, (B, 2)), rng.normal(0, 3, (B, 2))])
    covs = np.broadcast_to(np.diag([400.0, 400.0, 4.0, 4.0]), (B, 4, 4)).copy()
    bearing = rng.uniform(-math.pi, math.pi, (steps, B))
    ground = rng.uniform(0.0, 600.0, (steps, B, 1))
    turn = rng.uniform(-math.pi / 3, math.pi / 3, (steps, B))
    look = ground * np.stack([np.cos(bearing), np.sin(bearing)], axis=-1)
    symmetric = True
    n_trunc = n_infl = 0
    for t in range(steps):
        means = means @ F.T
        covs = predict_covariance(covs, F, Q)
        # miss_update's Cholesky factorisation raises if a covariance is not PD.
        new_means, covs, inflated = miss_update(means, covs, means[:, :2] - look[t],
                                                bearing[t] + turn[t], PARAMS)
        symmetric &= np.array_equal(covs, np.swapaxes(covs, -1, -2))
        n_infl += int(inflated.sum())
        moved = np.abs(new_means[:, :2] - means[:, :2]).max(axis=1) > 1e-3 * np.sqrt(
            covs[:, 0, 0])
        n_trunc += int(np.count_nonzero(moved & ~inflated))
        means = new_means
        fixed = t % period == period - 1
        if fixed.any():
            P = covs[fixed]
            K = np.swapaxes(np.linalg.solve(H @ P @ H.T + R, H @ P), -1, -2)
            z = means[fixed, :2] + rng.normal(0.0, 15.0, (len(P), 2))
            means[fixed] += (K @ (z - means[fixed, :2])[:, :, None])[..., 0]
            A = np.eye(4) - K @ H
            P = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
            covs[fixed] = 0.5 * (P + np.swapaxes(P, -1, -2))
    assert symmetric
    assert np.all(np.isfinite(means))
    assert np.all(np.linalg.eigvalsh(covs) > 0)
    assert n_trunc > 3_000 and n_infl > 1_000, (n_trunc, n_infl)
