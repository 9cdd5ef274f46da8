"""The tracker's compiled kernels give the numpy expressions' results bit for bit.

Each kernel replaced numpy code for speed only; the numpy code lives on here as the
reference, and every comparison is exact (``assert_array_equal``), not to a tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import log_ndtr

from sensorplan.models import radar
from sensorplan.tracking._imm_nb import combine_rows
from sensorplan.tracking.known_map import map_constraint
from sensorplan.tracking.missed import standard_points
from sensorplan.models.sensors import SensorParams, radar_table

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def _moments_numpy(alpha, beta):
    flip = alpha > -beta
    a = np.where(flip, -beta, alpha)
    b = np.where(flip, -alpha, beta)
    la, lb = log_ndtr(a), log_ndtr(b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_mass = lb + np.log1p(-np.exp(la - lb))
        fa, fb = np.isfinite(a), np.isfinite(b)
        pa = np.where(fa, np.exp(-0.5 * a * a - _LOG_SQRT_2PI - log_mass), 0.0)
        pb = np.where(fb, np.exp(-0.5 * b * b - _LOG_SQRT_2PI - log_mass), 0.0)
        mean = pa - pb
        var = 1.0 + np.where(fa, a * pa, 0.0) - np.where(fb, b * pb, 0.0) - mean * mean
    var = np.clip(var, 1e-12, 1.0)
    mean = np.clip(mean, a, b)
    return np.where(flip, -mean, mean), var, log_mass


def _axis_numpy(means, covs, k, lo, hi):
    s2 = covs[:, k, k]
    s = np.sqrt(s2)
    mu, var, log_mass = _moments_numpy((lo - means[:, k]) / s, (hi - means[:, k]) / s)
    u = covs[:, :, k] / s2[:, None]
    new_means = means + u * (s * mu)[:, None]
    new_covs = covs - (s2 * (1.0 - var))[:, None, None] * u[:, :, None] * u[:, None, :]
    return new_means, 0.5 * (new_covs + np.swapaxes(new_covs, -1, -2)), log_mass


def _map_numpy(m, P, W, H):
    m, P = m.copy(), P.copy()
    sx, sy = 3.0 * np.sqrt(P[:, 0, 0]), 3.0 * np.sqrt(P[:, 1, 1])
    hit = ((m[:, 0] - sx < 0.0) | (m[:, 0] + sx > W) | (m[:, 1] - sy < 0.0)
           | (m[:, 1] + sy > H))
    log_mass = np.zeros(len(m))
    mh, Ph, lx = _axis_numpy(m[hit], P[hit], 0, 0.0, W)
    mh, Ph, ly = _axis_numpy(mh, Ph, 1, 0.0, H)
    mh[:, 0] = np.clip(mh[:, 0], 0.0, W)
    mh[:, 1] = np.clip(mh[:, 1], 0.0, H)
    m[hit], P[hit], log_mass[hit] = mh, Ph, lx + ly
    return m, P, hit, log_mass


def _random_tracks(rng, n, spread=1.0):
    A = rng.normal(size=(n, 4, 4)) * np.array([30.0, 30.0, 2.0, 2.0])[:, None] * spread
    P = A @ np.swapaxes(A, -1, -2) + np.diag([1.0, 1.0, 0.1, 0.1])
    m = np.column_stack([rng.uniform(-200, 800, (n, 2)), rng.normal(0, 3, (n, 2))])
    return m, P


@pytest.mark.parametrize("spread", [0.01, 1.0, 30.0])
def test_map_constraint_is_the_numpy_formula_bit_for_bit(rng, spread):
    m, P = _random_tracks(rng, 400, spread)
    got = map_constraint(m, P, 600.0, 600.0)
    want = _map_numpy(m, P, 600.0, 600.0)
    assert want[2].sum() > 100
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


@pytest.mark.parametrize("R", [1, 2, 3])
def test_moment_matching_is_the_einsum_formula_bit_for_bit(rng, R):
    M = 7
    mu = rng.dirichlet(np.ones(R), M)
    x = rng.normal(size=(M, R, 4)) * 100.0
    _, P = _random_tracks(rng, M * R)
    P = P.reshape(M, R, 4, 4)
    rows = np.array([5, 0, 3])
    means, covs = np.zeros((M, 4)), np.zeros((M, 4, 4))
    combine_rows(mu, x, P, rows, means, covs)
    m = np.einsum("br,brd->bd", mu[rows], x[rows])
    d = x[rows] - m[:, None]
    C = np.einsum("br,brde->bde", mu[rows], P[rows] + d[..., :, None] * d[..., None, :])
    np.testing.assert_array_equal(means[rows], m)
    np.testing.assert_array_equal(covs[rows], 0.5 * (C + np.swapaxes(C, -1, -2)))
    assert not np.delete(means, rows, axis=0).any()


@pytest.mark.parametrize("fov", [0.3, math.pi / 6, 1.5, 3.0, math.pi])
def test_quadrature_detection_is_the_pointwise_model(rng, fov):
    """The wedge shortcut never changes a point's detection probability, also at the
    wedge's edges and for wedges of half-angle pi/2 and more."""
    table = radar_table([SensorParams(fov_half_angle=fov),
                         SensorParams(fov_half_angle=fov, detection="swerling1")])
    x = standard_points()
    B = 60
    sensor = rng.integers(0, 2, B)
    heading = rng.uniform(-4.0, 4.0, B)
    # Means at random places, some exactly on a wedge edge, spread from 1 m to 300 m.
    g = rng.uniform(0.0, 800.0, B)
    edge = heading + np.where(rng.random(B) < 0.5, -fov, fov)
    ang = np.where(rng.random(B) < 0.5, edge, rng.uniform(-4.0, 4.0, B))
    base = np.column_stack([g * np.cos(ang), g * np.sin(ang)])
    _, P = _random_tracks(rng, B, 0.3)
    chol = np.linalg.cholesky(P * rng.uniform(0.001, 30.0, B)[:, None, None])
    got = radar.detectable_quadrature(table, sensor, base, chol, x, heading)
    dx = base[:, 0, None] + chol[:, 0, 0, None] * x[:, 0]
    dy = base[:, 1, None] + chol[:, 1, 0, None] * x[:, 0] + chol[:, 1, 1, None] * x[:, 1]
    want = radar.detectable_points(table, sensor, dx, dy, heading)
    assert 0.0 < np.count_nonzero(want) < want.size
    np.testing.assert_array_equal(got, want)


def test_measure_looks_flat_path_equals_the_broadcasting_path(rng):
    table = radar_table([SensorParams(), SensorParams(altitude=300.0)])
    B = 9
    sensor = rng.integers(0, 2, B)
    txy, sxy = rng.uniform(0, 600, (B, 2)), rng.uniform(0, 600, (B, 2))
    heading = rng.uniform(-4, 4, B)
    flat = radar.measure_looks(table, sensor, txy, sxy, heading)
    column = radar.measure_looks(table, sensor[:, None], txy[:, None], sxy[:, None],
                                 heading[:, None])
    for f, c in zip(flat, column):
        np.testing.assert_array_equal(f, c[:, 0])


def _miss_numpy(means, covs, sxy, heading, table, sensor, gate):
    from sensorplan.tracking.missed import INFLATE_FRACTION, MIN_OUTSIDE, _inside, _point_set
    from sensorplan.models.sensors import G_MAX, G_MIN

    x, xx = _point_set(None)
    S = x.shape[0]
    chol = np.linalg.cholesky(covs)
    w = 1.0 - gate * _inside(means, chol, x, sxy, heading, table, sensor)
    n_out = w.sum(axis=-1)
    inflated = ((S - n_out) / S >= INFLATE_FRACTION) | (n_out < MIN_OUTSIDE)
    n = np.where(inflated, S, n_out).astype(float)
    mu = (w @ x) / n[..., None]
    second = (w @ xx).reshape(w.shape[:-1] + (4, 4)) / n[..., None, None]
    C = second - mu[..., :, None] * mu[..., None, :]
    new_means = means + (chol @ mu[..., :, None])[..., 0]
    new_covs = chol @ C @ np.swapaxes(chol, -1, -2)
    span = table[sensor, G_MAX] - table[sensor, G_MIN]
    grow = np.zeros(np.shape(span) + (4, 4))
    grow[..., 0, 0] = grow[..., 1, 1] = 0.25 * span * span
    new_means = np.where(inflated[..., None], means, new_means)
    new_covs = np.where(inflated[..., None, None], covs + grow, new_covs)
    new_covs = 0.5 * (new_covs + np.swapaxes(new_covs, -1, -2))
    return new_means, new_covs, inflated, (S - n_out) / S


@pytest.mark.parametrize("gate", [1.0, 0.999])
def test_miss_update_is_the_numpy_formula_bit_for_bit(rng, gate):
    from sensorplan.tracking.missed import miss_update

    table = radar_table([SensorParams(), SensorParams(detection="swerling1")])
    L, R = 40, 2
    heading = rng.uniform(-3.0, 3.0, (L, 1))
    sxy = rng.uniform(0.0, 600.0, (L, 1, 2))
    g = rng.uniform(150.0, 350.0, (L, R))
    means = np.zeros((L, R, 4))
    means[..., 0] = sxy[..., 0] + g * np.cos(heading + rng.normal(0, 0.5, (L, R)))
    means[..., 1] = sxy[..., 1] + g * np.sin(heading + rng.normal(0, 0.5, (L, R)))
    _, P = _random_tracks(rng, L * R, 0.5)
    covs = P.reshape(L, R, 4, 4) * rng.choice([0.01, 1.0, 10.0], (L, R))[..., None, None]
    sensor = np.repeat(rng.integers(0, 2, (L, 1)), R, axis=1)
    got = miss_update(means, covs, sxy, heading, table, sensor, gate_probability=gate,
                      return_fraction=True)
    want = _miss_numpy(means, covs, sxy, heading, table, sensor, gate)
    assert 0 < want[2].sum() < want[2].size
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("R", [2, 3, 4])
def test_imm_mixing_is_the_einsum_formula_bit_for_bit(rng, R):
    from sensorplan.tracking._imm_nb import mix

    M = 6
    mu = rng.dirichlet(np.ones(R), M)
    Pi = rng.dirichlet(np.ones(R) * 3.0, R)
    c = np.maximum(mu @ Pi, 1e-300)
    x = rng.normal(size=(M, R, 4)) * 100.0
    _, P = _random_tracks(rng, M * R)
    P = P.reshape(M, R, 4, 4)
    w = mu[:, :, None] * Pi[None] / c[:, None, :]
    x0 = np.einsum("mij,mid->mjd", w, x)
    d = x[:, :, None, :] - x0[:, None, :, :]
    P0 = np.einsum("mij,mijde->mjde", w, P[:, :, None] + d[..., :, None] * d[..., None, :])
    got_x0, got_P0 = mix(mu, Pi, c, x, P)
    np.testing.assert_array_equal(got_x0, x0)
    np.testing.assert_array_equal(got_P0, P0)


@pytest.mark.parametrize("m", [1, 2, 5, 9])
def test_pda_sums_are_the_einsum_formulas_bit_for_bit(rng, m):
    from sensorplan.tracking._imm_nb import pda_covariances, pda_spread

    R = 3
    beta = rng.dirichlet(np.ones(m + 1), R)[:, :m]
    nu = rng.normal(size=(R, m, 2)) * np.array([5.0, 0.01])
    nu_c, spread = pda_spread(beta, nu)
    want_c = np.einsum("rm,rmk->rk", beta, nu)
    np.testing.assert_array_equal(nu_c, want_c)
    np.testing.assert_array_equal(
        spread, np.einsum("rm,rmk,rml->rkl", beta, nu, nu) - want_c[:, :, None] * want_c[:, None])
    _, P = _random_tracks(rng, 3 * R)
    P, Pc, KSK = P.reshape(3, R, 4, 4)
    beta0 = 1.0 - beta.sum(axis=1)
    Pn = beta0[:, None, None] * P + (1.0 - beta0)[:, None, None] * Pc + KSK
    out = P.copy()
    pda_covariances(out, Pc, KSK, beta0, out)                 # in place, as the tracker calls it
    np.testing.assert_array_equal(out, 0.5 * (Pn + np.swapaxes(Pn, -1, -2)))


@pytest.mark.parametrize("R", [2, 3, 7])
def test_mode_reweighting_is_the_numpy_formula_bit_for_bit(rng, R):
    from sensorplan.tracking._imm_nb import floored_rows, normalise_rows, shifted_by_max

    M = 9
    probs = rng.dirichlet(np.ones(R), M)
    probs[0, 0] = 0.0                                        # floored to 1e-300
    L = rng.normal(size=(5, R)) * 30.0
    L[1, :] = -np.inf                                        # all modes impossible: NaN
    L[2, 0] = np.inf
    rows = np.array([0, 4, 2, 8, 6])
    with np.errstate(invalid="ignore"):
        logw = np.log(np.maximum(probs[rows], 1e-300)) + L
        logw -= logw.max(axis=1, keepdims=True)
        w = np.exp(logw)
        want = probs.copy()
        want[rows] = w / w.sum(axis=1, keepdims=True)
        got_w = np.exp(shifted_by_max(np.log(floored_rows(probs, rows, 1e-300)), L))
    np.testing.assert_array_equal(got_w, w)
    got = probs.copy()
    normalise_rows(got_w, got, rows)
    np.testing.assert_array_equal(got, want)


def test_pda_likelihoods_are_the_numpy_formula_bit_for_bit(rng):
    from sensorplan.models.sensors import AREA, CLUTTER_RATE, COLUMNS
    from sensorplan.tracking._imm_nb import pda_likelihoods, pda_weights

    R, m = 3, 4
    pd = rng.uniform(0.2, 1.0, R)
    density = np.exp(-rng.uniform(0.0, 40.0, (R, m)))
    ranges = rng.uniform(100.0, 900.0, m)
    rate, area, pg = 1.3, 2.5e5, 0.999
    row = np.zeros(len(COLUMNS))
    row[CLUTTER_RATE], row[AREA] = rate, area
    rho = rate * ranges / area
    lik = pd[:, None] * density / (2.0 * math.pi) / rho[None]
    none = 1.0 - pd * pg
    den = none + lik.sum(axis=1)
    got_lik, got_none, positive = pda_likelihoods(pd, density, ranges, row, pg)
    np.testing.assert_array_equal(got_lik, lik)
    np.testing.assert_array_equal(got_none, none)
    assert positive
    got_den, beta, beta0, ok = pda_weights(got_lik, got_none, got_lik.sum(axis=1))
    np.testing.assert_array_equal(got_den, den)
    np.testing.assert_array_equal(beta, lik / den[:, None])
    np.testing.assert_array_equal(beta0, none / den)
    assert ok
    ranges[1] = -5.0                                          # a range below the region's
    assert not pda_likelihoods(pd, density, ranges, row, pg)[2]
    assert not pda_weights(lik, np.zeros(R), np.zeros(R))[3]  # den = 0


def test_position_update_is_the_numpy_formula_bit_for_bit(rng):
    from sensorplan.tracking.ekf import position_update

    B = 6
    _, P = _random_tracks(rng, B)
    x = rng.normal(size=(B, 4)) * 100.0
    inn = rng.normal(size=(B, 2)) * np.array([3.0, 0.01])
    # Every other row of a larger array: the strided views PDA passes.
    Hp = (rng.normal(size=(2 * B, 2, 2)) * 0.5)[::2]
    var = rng.uniform(0.1, 10.0, (2 * B, 2))[::2] * np.array([1.0, 1e-5])
    PHt = P[:, :, :2] @ np.swapaxes(Hp, -1, -2)
    S = Hp @ PHt[:, :2, :]
    S[:, 0, 0] += var[:, 0]
    S[:, 1, 1] += var[:, 1]
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)
    x_new = x + K[:, :, 0] * inn[:, 0:1] + K[:, :, 1] * inn[:, 1:2]
    A = np.tile(np.eye(4), (B, 1, 1))
    A[:, :, :2] -= K @ Hp
    Kv = K * var[:, None, :]
    P_new = A @ P @ np.swapaxes(A, -1, -2) + Kv @ np.swapaxes(K, -1, -2)
    got_x, got_P = position_update(x, P, inn, Hp, var)
    np.testing.assert_array_equal(got_x, x_new)
    np.testing.assert_array_equal(got_P, 0.5 * (P_new + np.swapaxes(P_new, -1, -2)))
