"""The one radar model (:mod:`sensorplan.models.radar`): closed forms, edge cases, and agreement
with the independent numpy computation of ``radar_reference`` to 1e-12.

The helpers below call the library's compiled radar with the shapes the tests want; they
build a radar table per call, one row per parameter set.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import radar_reference as ref
from sensorplan.models import radar
from sensorplan.models.radar import ANGLE_TOL, RANGE_TOL
from sensorplan.models.sensors import COLUMNS, SensorParams, radar_table

DEF = SensorParams()


def _table(p: SensorParams, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Radar table of ``p`` (fields scalars or arrays broadcast to ``shape``) and row indices."""
    names = [f.name for f in dataclasses.fields(SensorParams)
             if f.name not in ("moves", "detection")]
    arrays = np.broadcast_arrays(*[np.asarray(getattr(p, n), dtype=float) for n in names],
                                 np.empty(shape))[:-1]
    flat = [a.ravel() for a in arrays]
    rows = [SensorParams(**{n: float(v[k]) for n, v in zip(names, flat)})
            for k in range(flat[0].size)]
    return radar_table(rows), np.arange(len(rows)).reshape(shape)


def _looks(x, s, heading, p=DEF):
    x, s = np.asarray(x, dtype=float), np.asarray(s, dtype=float)
    shape = np.broadcast_shapes(x.shape[:-1], s.shape[:-1], np.shape(heading))
    table, idx = _table(p, shape)
    return radar.measure_looks(table, idx, np.broadcast_to(x[..., :2], shape + (2,)),
                               np.broadcast_to(s, shape + (2,)),
                               np.broadcast_to(heading, shape))


def measure(x, s, altitude):
    return _looks(x, s, 0.0, SensorParams(altitude=altitude))[0]


def jacobian(x, s, altitude):
    Hp = _looks(x, s, 0.0, SensorParams(altitude=altitude))[1]
    return np.concatenate([Hp, np.zeros(Hp.shape)], axis=-1)


def position_jacobian(dx, dy, altitude):
    return ref.position_jacobian(dx, dy, altitude)


def noise_cov(x, s, heading, p):
    var = _looks(x, s, heading, p)[2]
    R = np.zeros(var.shape + (2,))
    R[..., 0, 0], R[..., 1, 1] = var[..., 0], var[..., 1]
    return R


def visible(x, s, heading, p):
    return _looks(x, s, heading, p)[3]


def cos_boresight(dx, dy, heading, p):
    shape = np.broadcast_shapes(np.shape(dx), np.shape(dy), np.shape(heading))
    table, idx = _table(p, shape)
    out = np.empty(shape)
    for k in np.ndindex(shape):
        row = table[idx[k]]
        ddx, ddy = float(np.broadcast_to(dx, shape)[k]), float(np.broadcast_to(dy, shape)[k])
        h = float(np.broadcast_to(heading, shape)[k])
        r = math.sqrt(ddx * ddx + ddy * ddy + row[1])
        out[k] = radar.cos_psi(row, ddx, ddy, math.cos(h), math.sin(h), r)
    return out


def noise_std(r, cos_psi, p):
    row = radar_table(p)[0]
    var_r, var_phi = radar.noise_variances(row, float(r) ** 2, float(cos_psi))
    return math.sqrt(var_r), math.sqrt(var_phi)


def detection_probability(mean, C, s, heading, p):
    """p_vis through the planner's look kernel (0 below the 1e-6 threshold)."""
    mean, s = np.asarray(mean, dtype=float), np.asarray(s, dtype=float)
    C = np.asarray(C, dtype=float)
    shape = np.broadcast_shapes(mean.shape[:-1], s.shape[:-1], np.shape(heading), C.shape[:-2])
    d = np.broadcast_to(mean - s, shape + (2,))
    C3 = np.stack([C[..., 0, 0], C[..., 0, 1], C[..., 1, 1]], axis=-1)
    row = radar_table(p)[0]
    return radar.look_information(row, d[..., 0], d[..., 1], np.broadcast_to(heading, shape),
                                  np.broadcast_to(C3, shape + (3,)), True)[1]
# Steps past an edge: well above the tolerances and the rounding of the test geometry.
RANGE_STEP = 1e-6
ANGLE_STEP = 1e-9
assert RANGE_STEP > 100 * RANGE_TOL and ANGLE_STEP > 100 * ANGLE_TOL


def wrap(a: float) -> float:
    """(-pi, pi] without the library."""
    w = math.remainder(a, 2 * math.pi)
    return math.pi if w <= -math.pi else w


def ncdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


# --------------------------------------------------------------------------- geometry

def test_measure_closed_form():
    z = measure(np.array([300.0, 400.0, 7.0, -2.0]), np.array([0.0, 0.0]), 500.0)
    np.testing.assert_allclose(z, [math.sqrt(500000.0), math.atan2(400, 300)], rtol=1e-15)
    z = measure(np.array([[10.0, 20.0], [10.0, -30.0]]), np.array([40.0, 20.0]), 100.0)
    np.testing.assert_allclose(z, [[math.sqrt(900 + 10000), math.pi],
                                   [math.sqrt(900 + 2500 + 10000), math.atan2(-50, -30)]],
                               rtol=1e-15)


def test_jacobian_matches_central_differences(rng):
    n = 400
    sensor = rng.uniform(0, 600, size=(n, 2))
    g = rng.uniform(20.0, 1000.0, size=n)               # not too close to the nadir
    a = rng.uniform(-math.pi, math.pi, size=n)
    x = np.column_stack([sensor + g[:, None] * np.column_stack([np.cos(a), np.sin(a)]),
                         rng.normal(0, 5, size=(n, 2))])
    alt = rng.uniform(100.0, 1000.0, size=n)
    H = jacobian(x, sensor, alt)
    assert H.shape == (n, 2, 4)
    h = 1e-3
    fd = np.empty((n, 2, 4))
    for c in range(4):
        dxp = x.copy()
        dxm = x.copy()
        dxp[:, c] += h
        dxm[:, c] -= h
        zp, zm = measure(dxp, sensor, alt), measure(dxm, sensor, alt)
        diff = zp - zm
        diff[:, 1] = [wrap(v) for v in diff[:, 1]]       # azimuth may cross +-pi
        fd[:, :, c] = diff / (2 * h)
    for row in range(2):
        scale = np.linalg.norm(H[:, row, :], axis=1, keepdims=True)
        assert np.all(np.abs(H[:, row, :] - fd[:, row, :]) <= 1e-6 * np.abs(fd[:, row, :])
                      + 1e-9 * scale)
    # Velocity columns are exactly zero; the position block is position_jacobian.
    assert np.all(H[:, :, 2:] == 0.0)
    np.testing.assert_allclose(
        H[:, :, :2], position_jacobian(x[:, 0] - sensor[:, 0], x[:, 1] - sensor[:, 1], alt),
        rtol=0, atol=0)
    # the closed form, written out
    dx, dy = x[:, 0] - sensor[:, 0], x[:, 1] - sensor[:, 1]
    r = np.sqrt(dx**2 + dy**2 + alt**2)
    np.testing.assert_allclose(H[:, 0, 0], dx / r, rtol=1e-14)
    np.testing.assert_allclose(H[:, 1, 1], dx / (dx**2 + dy**2), rtol=1e-14)


def test_jacobian_broadcasts_targets_against_sensors(rng):
    x = rng.uniform(0, 600, size=(5, 1, 4))
    s = rng.uniform(0, 600, size=(1, 3, 2))
    H = jacobian(x, s, 500.0)
    assert H.shape == (5, 3, 2, 4)
    for a in range(5):
        for b in range(3):
            np.testing.assert_allclose(H[a, b], jacobian(x[a, 0], s[0, b], 500.0), rtol=1e-15)


# --------------------------------------------------------------------------- field of view

def _point(sensor, g, a):
    return np.array([sensor[0] + g * math.cos(a), sensor[1] + g * math.sin(a)])


@pytest.mark.parametrize("heading", [0.0, 0.7, math.pi, -math.pi + 0.1, math.pi - 0.2, -2.5])
def test_fov_edges_are_inclusive_and_just_beyond_is_outside(heading):
    sensor = np.array([123.4, 56.7])
    p = DEF
    fov, gmin, gmax = p.fov_half_angle, p.min_ground_range, p.max_ground_range
    inside = [(gmin, heading), (gmax, heading), (350.0, heading + fov), (350.0, heading - fov),
              (gmin, heading + fov), (gmax, heading - fov), (gmin + RANGE_STEP, heading)]
    outside = [(gmin - RANGE_STEP, heading), (gmax + RANGE_STEP, heading),
               (350.0, heading + fov + ANGLE_STEP), (350.0, heading - fov - ANGLE_STEP),
               (gmin - RANGE_STEP, heading + fov), (350.0, heading + math.pi),
               (100.0, heading), (0.0, heading)]
    for g, a in inside:
        assert visible(_point(sensor, g, a), sensor, heading, p), (g, a)
    for g, a in outside:
        assert not visible(_point(sensor, g, a), sensor, heading, p), (g, a)
    # batched call agrees with the scalar ones
    pts = np.array([_point(sensor, g, a) for g, a in inside + outside])
    np.testing.assert_array_equal(visible(pts, sensor, heading, p),
                                  [True] * len(inside) + [False] * len(outside))


def test_fov_edges_with_other_parameters():
    p = SensorParams(fov_half_angle=0.3, min_ground_range=100.0, max_ground_range=180.0,
                     altitude=200.0)
    s = np.zeros(2)
    for g, a, want in [(100.0, 0.3, True), (180.0, -0.3, True), (180.0 + RANGE_STEP, 0, False),
                       (100.0 - RANGE_STEP, 0, False), (150.0, 0.3 + ANGLE_STEP, False),
                       (150.0, -0.3 - ANGLE_STEP, False)]:
        assert bool(visible(_point(s, g, a), s, 0.0, p)) is want, (g, a)


def test_not_visible_when_cos_psi_is_not_positive():
    # A wedge all around (fov = pi) and a boresight tilted 0.2 rad *up*: a point abeam is in
    # the range band and the wedge, but below the boresight plane by more than 90 degrees.
    p = SensorParams(fov_half_angle=math.pi, depression=-0.2)
    s = np.array([300.0, 300.0])
    abeam = _point(s, 300.0, math.pi / 2)
    ahead = _point(s, 300.0, 0.0)
    dx, dy = abeam - s
    assert cos_boresight(dx, dy, 0.0, p) < 0
    assert not visible(abeam, s, 0.0, p)
    assert visible(ahead, s, 0.0, p)
    # Behind the sensor with a shallow depression: cos psi < 0 as well.
    q = SensorParams(fov_half_angle=math.pi, depression=0.1)
    behind = _point(s, 300.0, math.pi)
    assert cos_boresight(*(behind - s), 0.0, q) < 0
    assert not visible(behind, s, 0.0, q)
    # and p_vis is zero there even when the target is certainly at the point
    C = np.eye(2) * 1e-6
    assert detection_probability(abeam, C, s, 0.0, p) == 0.0
    assert detection_probability(behind, C, s, 0.0, q) == 0.0
    assert detection_probability(ahead, C, s, 0.0, p) == pytest.approx(1.0)


def test_cos_boresight_equals_explicit_3d_angle(rng):
    n = 300
    dx, dy = rng.uniform(-800, 800, size=(2, n))
    theta = rng.uniform(-math.pi, math.pi, size=n)
    alt = rng.uniform(100, 900, size=n)
    dep = rng.uniform(-0.5, 1.5, size=n)
    p = SensorParams(altitude=alt, depression=dep)
    got = cos_boresight(dx, dy, theta, p)
    for m in range(n):
        # The boresight as a rotation of the x axis: about -y by dep (nose down), then about z.
        cz, sz = math.cos(theta[m]), math.sin(theta[m])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        cd, sd = math.cos(dep[m]), math.sin(dep[m])
        Ry = np.array([[cd, 0, sd], [0, 1, 0], [-sd, 0, cd]])
        b = Rz @ Ry @ np.array([1.0, 0.0, 0.0])
        los = np.array([dx[m], dy[m], 0.0]) - np.array([0.0, 0.0, alt[m]])
        psi = math.atan2(np.linalg.norm(np.cross(b, los)), float(b @ los))
        assert got[m] == pytest.approx(math.cos(psi), abs=1e-12)


# --------------------------------------------------------------------------- noise

def test_noise_closed_forms_at_reference_range():
    snr = 10**1.5
    sr, sp = noise_std(600.0, 1.0, DEF)
    assert float(sr) == pytest.approx(30 / math.sqrt(2 * snr), rel=1e-14)
    assert float(sp) == pytest.approx(math.radians(3) / (1.6 * math.sqrt(2 * snr)), rel=1e-14)
    # sigma ~ r^2 (SNR ~ r^-4); sigma_phi ~ 1 / cos psi
    sr2, sp2 = noise_std(300.0, 0.5, DEF)
    assert float(sr2) == pytest.approx(float(sr) / 4, rel=1e-14)
    assert float(sp2) == pytest.approx(float(sp) / 4 * 2, rel=1e-14)


@pytest.mark.parametrize("heading", [0.0, 2.0, -math.pi / 2])
def test_noise_cov_on_the_boresight_at_600_m(heading):
    # A target on the boresight at slant range 600 m: psi = 0, r = 600.
    dep = DEF.depression
    p = SensorParams(altitude=600 * math.sin(dep))
    s = np.array([50.0, 80.0])
    x = np.concatenate([_point(s, 600 * math.cos(dep), heading), [1.0, 2.0]])
    dx, dy = x[:2] - s
    assert float(cos_boresight(dx, dy, heading, p)) == pytest.approx(1.0, abs=1e-14)
    R = noise_cov(x, s, heading, p)
    snr = 10**1.5
    np.testing.assert_allclose(
        R, np.diag([(30 / math.sqrt(2 * snr))**2,
                    (math.radians(3) / (1.6 * math.sqrt(2 * snr)))**2]), rtol=1e-12, atol=0)


def test_noise_cov_general_geometry_matches_spec(rng):
    p = SensorParams(altitude=480.0, snr_ref_db=12.0, range_ref=550.0, beamwidth=0.04,
                     monopulse_slope=1.4, range_resolution=20.0, depression=0.6)
    s = rng.uniform(0, 600, size=(50, 2))
    x = s + rng.uniform(-400, 400, size=(50, 2))
    th = rng.uniform(-3, 3, size=50)
    R = noise_cov(x, s, th, p)
    for m in range(50):
        dx, dy = x[m] - s[m]
        r = math.sqrt(dx * dx + dy * dy + 480.0**2)
        b = np.array([math.cos(0.6) * math.cos(th[m]), math.cos(0.6) * math.sin(th[m]),
                      -math.sin(0.6)])
        cpsi = float(b @ np.array([dx, dy, -480.0])) / r
        snr = 10**1.2 * (550.0 / r)**4
        want = np.diag([(20 / math.sqrt(2 * snr))**2,
                        (0.04 / cpsi / (1.4 * math.sqrt(2 * snr)))**2])
        np.testing.assert_allclose(R[m], want, rtol=1e-12, atol=0)


# --------------------------------------------------------------------------- the table


def test_table_rows_equal_per_sensor_calls(rng):
    ps = [SensorParams(), SensorParams(altitude=490.0, fov_half_angle=0.4, max_ground_range=420.0),
          SensorParams(altitude=510.0, min_ground_range=200.0, depression=0.5)]
    table = radar_table(ps)
    assert table.shape == (3, len(COLUMNS)) and table.flags.c_contiguous
    assert table[1, COLUMNS.index("altitude")] == 490.0
    s = rng.uniform(100, 500, size=(3, 2))
    th = rng.uniform(-3, 3, size=3)
    x = rng.uniform(-200, 800, size=(200, 1, 2))
    h, H, var, vis = radar.measure_looks(table, np.arange(3), x, s, th)
    assert vis.shape == (200, 3)
    for i, p in enumerate(ps):
        one = radar.measure_looks(radar_table(p), 0, x[:, 0], s[i], th[i])
        for a, b in zip((h, H, var, vis), one):
            np.testing.assert_array_equal(a[:, i], b)
    assert vis.any() and not vis.all()


# --------------------------------------------------------------------------- p_vis

def _linearised(mean, C, s, heading, p):
    """gbar, sd_g, d, sd_phi per their definition, written out independently."""
    dx, dy = float(mean[0] - s[0]), float(mean[1] - s[1])
    g = math.hypot(dx, dy)
    u = np.array([dx, dy]) / g
    v = np.array([-dy, dx]) / g
    return (g, math.sqrt(float(u @ C @ u)), wrap(math.atan2(dy, dx) - heading),
            math.sqrt(float(v @ C @ v)) / g)


def test_p_vis_matches_monte_carlo_of_the_linearised_gaussian(rng):
    p = DEF
    n = 200_000
    checked = 0
    for case in range(12):
        s = rng.uniform(100, 500, size=2)
        heading = rng.uniform(-math.pi, math.pi)
        # means near an edge of the band and of the wedge so that p is strictly inside (0, 1)
        g0 = rng.choice([p.min_ground_range, p.max_ground_range]) + rng.normal(0, 15)
        a0 = heading + rng.choice([-1, 1]) * p.fov_half_angle + rng.normal(0, 0.05)
        if case % 3 == 0:
            g0, a0 = rng.uniform(260, 440), heading + rng.uniform(-0.3, 0.3)
        mean = _point(s, g0, a0)
        A = rng.normal(size=(2, 2))
        C = A @ A.T * rng.uniform(20, 400) + 5 * np.eye(2)
        got = float(detection_probability(mean, C, s, heading, p))
        gbar, sd_g, d, sd_phi = _linearised(mean, C, s, heading, p)
        g = rng.normal(gbar, sd_g, size=n)
        off = d + rng.normal(0.0, sd_phi, size=n)
        hit = ((g >= p.min_ground_range) & (g <= p.max_ground_range)
               & (np.abs(off) <= p.fov_half_angle))
        est = hit.mean()
        sigma = math.sqrt(max(got * (1 - got), 1e-12) / n)
        assert abs(est - got) <= 4 * sigma + 1e-12, (case, est, got)
        checked += 0.02 < got < 0.98
    assert checked >= 6           # the comparison is not only at 0 and 1


def test_p_vis_closed_form_against_independent_formula(rng):
    p = SensorParams(fov_half_angle=0.4, min_ground_range=220.0, max_ground_range=430.0)
    for _ in range(50):
        s = rng.uniform(0, 600, size=2)
        heading = rng.uniform(-math.pi, math.pi)
        mean = _point(s, rng.uniform(150, 500), heading + rng.uniform(-0.7, 0.7))
        A = rng.normal(size=(2, 2))
        C = A @ A.T * rng.uniform(1, 900) + np.eye(2)
        gbar, sd_g, d, sd_phi = _linearised(mean, C, s, heading, p)
        want = ((ncdf((430 - gbar) / sd_g) - ncdf((220 - gbar) / sd_g))
                * (ncdf((0.4 - d) / sd_phi) - ncdf((-0.4 - d) / sd_phi)))
        got = float(detection_probability(mean, C, s, heading, p))
        if want < radar.P_VIS_MIN:          # such looks do not count: weight exactly 0
            assert got == 0.0
        else:
            assert got == pytest.approx(want, rel=1e-9, abs=1e-15)


def test_p_vis_tiny_covariance_is_the_visibility_indicator(rng):
    n = 2000
    s = np.array([300.0, 300.0])
    heading = 0.8
    g = rng.uniform(0.5, 600, size=n)
    a = rng.uniform(-math.pi, math.pi, size=n)
    mean = s + g[:, None] * np.column_stack([np.cos(a), np.sin(a)])
    vis = visible(mean, s, heading, DEF)
    for C in (np.eye(2) * 1e-10, np.zeros((2, 2))):
        pv = detection_probability(mean, np.broadcast_to(C, (n, 2, 2)), s, heading, DEF)
        np.testing.assert_array_equal(pv, vis.astype(float))
    assert 50 < vis.sum() < n - 50


def test_p_vis_at_a_range_edge_is_half_the_azimuth_factor():
    s = np.array([100.0, 200.0])
    heading = -2.9
    sd = 5.0
    C = sd**2 * np.eye(2)
    for edge in (DEF.max_ground_range, DEF.min_ground_range):
        for off in (0.0, 0.3, -0.5, 0.52):
            mean = _point(s, edge, heading + off)
            g = math.hypot(*(mean - s))
            sphi = sd / g
            fov = DEF.fov_half_angle
            az = ncdf((fov - off) / sphi) - ncdf((-fov - off) / sphi)
            got = float(detection_probability(mean, C, s, heading, DEF))
            assert got == pytest.approx(0.5 * az, rel=1e-12, abs=1e-300), (edge, off)
    # and exactly on an azimuth edge, deep inside the band: one half
    mean = _point(s, 350.0, heading + DEF.fov_half_angle)
    assert float(detection_probability(mean, C, s, heading, DEF)) == pytest.approx(0.5, rel=1e-12)


def test_p_vis_zero_at_the_nadir_and_batched_shapes(rng):
    s = np.array([10.0, 20.0])
    assert float(detection_probability(s.copy(), np.eye(2) * 100, s, 0.0, DEF)) == 0.0
    mean = rng.uniform(0, 600, size=(4, 3, 2))
    C = np.broadcast_to(np.eye(2) * 50, (4, 3, 2, 2))
    sensors = rng.uniform(0, 600, size=(4, 1, 2))
    th = rng.uniform(-3, 3, size=(4, 1))
    pv = detection_probability(mean, C, sensors, th, DEF)
    assert pv.shape == (4, 3)
    assert np.all((pv >= 0) & (pv <= 1))
    for a in range(4):
        for b in range(3):
            assert pv[a, b] == float(detection_probability(mean[a, b], C[a, b], sensors[a, 0],
                                                           th[a, 0], DEF))


# --------------------------------------------------------------------------- reference


def _varied(rng, n):
    return [SensorParams(altitude=float(rng.uniform(60, 900)),
                         fov_half_angle=float(rng.uniform(0.1, math.pi)),
                         min_ground_range=float(rng.uniform(1, 250)),
                         max_ground_range=float(rng.uniform(260, 700)),
                         depression=float(rng.uniform(-0.3, 1.4)),
                         snr_ref_db=float(rng.uniform(0, 25)),
                         range_ref=float(rng.uniform(300, 900)),
                         beamwidth=float(rng.uniform(0.01, 0.1)),
                         monopulse_slope=float(rng.uniform(1.0, 2.0)),
                         range_resolution=float(rng.uniform(5, 50)),
                         range_error_floor=float(rng.uniform(0, 5)),
                         azimuth_error_floor=float(rng.uniform(0, 4e-3)))
            for _ in range(n)]


def test_measurement_model_equals_the_reference(rng):
    """Range, azimuth, Jacobian, noise and field of view: compiled vs plain numpy."""
    n = 4000
    ps = _varied(rng, 7)
    table = radar_table(ps)
    idx = rng.integers(0, 7, size=n)
    s = rng.uniform(0, 600, size=(n, 2))
    x = s + rng.uniform(-800, 800, size=(n, 2))
    th = rng.uniform(-4, 4, size=n)
    h, H, var, vis = radar.measure_looks(table, idx, x, s, th)
    st = ref.stack_params([ps[i] for i in idx])
    np.testing.assert_allclose(h, ref.measure(x, s, st.altitude), rtol=1e-12, atol=0)
    np.testing.assert_allclose(H, ref.jacobian(x, s, st.altitude)[..., :2], rtol=1e-12, atol=0)
    R = ref.noise_cov(x, s, th, st)
    np.testing.assert_allclose(var, np.stack([R[:, 0, 0], R[:, 1, 1]], -1), rtol=1e-12, atol=0)
    want = ref.visible(x, s, th, st)
    np.testing.assert_array_equal(vis, want)
    assert 0.05 < want.mean() < 0.95           # both outcomes are exercised


@pytest.mark.parametrize("visibility", ["probabilistic", "mean"])
def test_look_information_equals_the_reference(rng, visibility):
    """p_vis (or the mean's visibility) and p H'^T R^-1 H': compiled vs plain numpy."""
    for p in _varied(rng, 6):
        n = 3000
        dx, dy = rng.uniform(-800, 800, size=(2, n))
        th = rng.uniform(-4, 4, size=n)
        A = rng.normal(size=(n, 2, 2))
        Cm = A @ np.swapaxes(A, 1, 2) * rng.uniform(1, 2000, size=(n, 1, 1))
        C = np.stack([Cm[:, 0, 0], Cm[:, 0, 1], Cm[:, 1, 1]], axis=-1)
        W, w = radar.look_information(radar_table(p)[0], dx, dy, th, C,
                                      visibility == "probabilistic")
        W_ref, w_ref = ref.look_information(p, visibility, dx, dy, th, C)
        # Where the reference sits within round-off of the 1e-6 threshold the two may
        # differ in which side they land; nowhere else.
        edge = np.abs(w_ref - radar.P_VIS_MIN) < 1e-12
        # p is a probability: absolute agreement (a difference of two normal CDFs near 1
        # loses relative digits when p is small, in either computation).
        np.testing.assert_allclose(w[~edge], w_ref[~edge], rtol=0, atol=1e-12)
        # The information per unit weight, H'^T R^-1 H', to 1e-12 relative.
        ok = (w > 0) & (w_ref > 0)
        unit, unit_ref = W[ok] / w[ok, None, None], W_ref[ok] / w_ref[ok, None, None]
        scale = np.abs(unit_ref).max(axis=(1, 2), keepdims=True)
        assert np.all(np.abs(unit - unit_ref) <= 1e-12 * scale)
        np.testing.assert_array_equal(W[(w == 0)], 0.0)
        assert ok.sum() > 10 and (w == 0).any()


def test_visible_points_equals_the_per_look_test(rng):
    table = radar_table(_varied(rng, 3))
    sensor = np.array([2, 0, 1, 1])
    dx, dy = rng.uniform(-700, 700, size=(2, 4, 300))
    th = rng.uniform(-4, 4, size=4)
    got = radar.visible_points(table, sensor, dx, dy, th)
    s = np.zeros((4, 300, 2))
    want = radar.measure_looks(table, sensor[:, None], np.stack([dx, dy], -1), s,
                               th[:, None])[3]
    np.testing.assert_array_equal(got, want)


def test_the_normal_interval_skips_erfc_only_where_the_formula_gives_exactly_one():
    # Ncdf(hi/sd) - Ncdf(lo/sd) with both bounds far out is 1.0 in floating point; the model
    # returns 1.0 there without the two erfc calls. It must equal the formula bit for bit
    # everywhere, on both sides of the threshold and at it.
    from sensorplan.models.radar.model import SURE_SIGMAS, _interval

    def formula(lo: float, hi: float, sd: float) -> float:
        ncdf = lambda x: 0.5 * math.erfc(-x / math.sqrt(2.0))  # noqa: E731
        return ncdf(hi / sd) - ncdf(lo / sd)

    rng = np.random.default_rng(5)
    sd = rng.uniform(0.1, 50.0, 4000)
    za = np.concatenate([-rng.uniform(0.0, 40.0, 2000), -SURE_SIGMAS - rng.exponential(0.3, 2000)])
    zb = np.concatenate([rng.uniform(0.0, 40.0, 2000), SURE_SIGMAS + rng.exponential(0.3, 2000)])
    edge = [np.nextafter(SURE_SIGMAS, 0.0), SURE_SIGMAS, np.nextafter(SURE_SIGMAS, 99.0)]
    cases = [(a * s, b * s, s) for a, b, s in zip(rng.permutation(za), zb, sd)]
    cases += [(-x, y, 1.0) for x in edge for y in edge]
    skipped = 0
    for lo, hi, s in cases:
        assert _interval(lo, hi, s) == formula(lo, hi, s), (lo, hi, s)
        skipped += lo / s <= -SURE_SIGMAS and hi / s >= SURE_SIGMAS
    assert skipped > 500                      # the shortcut was taken, and agreed


@pytest.mark.parametrize("aware", [False, True])
def test_a_radar_row_as_a_tuple_gives_the_same_looks_bit_for_bit(rng, aware):
    # The planner's inner loop passes the row as a tuple (row_values) and calls the open-sky
    # range test where no building stands; both must be the array row's model exactly.
    from sensorplan.models.radar.model import look_range_clear, row_values

    table = radar_table([DEF, dataclasses.replace(DEF, detection="swerling1",
                                                   fov_half_angle=0.4)], aware=aware)
    none = np.zeros((0, 5))
    for row in table:
        rv = row_values(row)
        assert len(rv) == len(COLUMNS) and rv == tuple(row)     # a column added: update it
        g = rng.uniform(1.0, 700.0, 300)
        az = rng.uniform(-np.pi, np.pi, 300)
        dx, dy = g * np.cos(az), g * np.sin(az)
        c = rng.uniform(1.0, 900.0, (300, 2))
        c01 = rng.uniform(-0.9, 0.9, 300) * np.sqrt(c[:, 0] * c[:, 1])
        heading = rng.uniform(-np.pi, np.pi, 300)
        counted = 0
        for b in range(300):
            for prob in (True, False):
                cov = (c[b, 0], c01[b], c[b, 1])
                arr = radar.look_range(row, none, 5.0, 7.0, dx[b], dy[b], *cov, prob)
                assert look_range_clear(rv, dx[b], dy[b], *cov, prob) == arr
                assert radar.reach(rv, *cov, prob) == radar.reach(row, *cov, prob)
                p, g2, gg = arr
                a = radar.look_at_azimuth(row, dx[b], dy[b], g2, gg, p, az[b], heading[b],
                                          *cov, prob)
                assert radar.look_at_azimuth(rv, dx[b], dy[b], g2, gg, p, az[b], heading[b],
                                             *cov, prob) == a
                counted += a[0] > 0
        assert counted > 50                    # looks that count were compared, not only zeros


def test_the_clutter_density_integrates_to_the_clutter_rate_over_the_sensing_region() -> None:
    p = SensorParams(clutter_rate=3.0)
    row = radar_table((p,))[0]
    r_lo = math.hypot(p.altitude, p.min_ground_range)
    r_hi = math.hypot(p.altitude, p.max_ground_range)
    r = np.linspace(r_lo, r_hi, 20001)
    rho = radar.clutter_densities(row, r)
    # over the region: azimuth width 2 fov times the integral over slant range (trapezoid)
    total = 2 * p.fov_half_angle * float(np.sum(0.5 * (rho[1:] + rho[:-1]) * np.diff(r)))
    np.testing.assert_allclose(total, 3.0, rtol=1e-9)
    # the compiled scalar is the same model
    assert radar.clutter_density(row, 700.0) == radar.clutter_densities(row, 700.0)
    # a range outside the band is clipped to it when asked
    assert radar.clutter_densities(row, 1.0, in_region=True) == radar.clutter_densities(row, r_lo)
    assert float(radar.clutter_densities(radar_table((SensorParams(),))[0], 700.0)) == 0.0


def test_false_alarms_are_measured_noisy_points_of_the_sensing_region() -> None:
    table = radar_table((SensorParams(clutter_rate=5.0),))
    rng = np.random.default_rng(4)
    u, e = rng.random((40, 2)), rng.standard_normal((40, 2))
    sxy, heading = np.array([100.0, 200.0]), 0.7
    z = radar.false_alarms(table, 0, sxy, heading, u, e)
    # the same composed by hand: points, their measurement, noise, wrap, points in the region
    xy = radar.clutter_points(table[0], sxy, heading, u)
    h, _, var, inside = radar.measure_looks(table, np.zeros(40, dtype=np.int64), xy, sxy,
                                            np.full(40, heading))
    want = h + np.sqrt(var) * e
    want[:, 1] = np.angle(np.exp(1j * want[:, 1]))
    np.testing.assert_allclose(z, want[inside], rtol=1e-12, atol=1e-12)
    assert 0 < len(z) <= 40
    noiseless = radar.false_alarms(table, 0, sxy, heading, u, None)
    np.testing.assert_array_equal(noiseless[:, 0], h[inside, 0])
    assert radar.false_alarms(table, 0, sxy, heading, np.zeros((0, 2)), None).shape == (0, 2)


def test_error_floors_bound_the_noise_and_zero_floors_change_nothing(rng):
    """sigma^2 = the SNR model's + floor^2 (the same rounding as adding it), never below
    the floor; without floors the SNR model's c r^4."""
    floored = dataclasses.replace(DEF, range_error_floor=3.0,
                                  azimuth_error_floor=math.radians(0.1))
    table = radar_table([DEF, floored])
    n = 2000
    s = rng.uniform(0, 600, size=(n, 2))
    x = s + rng.uniform(-3000, 3000, size=(n, 2))
    th = rng.uniform(-4, 4, size=n)
    _, _, bare, _ = radar.measure_looks(table, np.zeros(n, dtype=np.int64), x, s, th)
    _, _, var, _ = radar.measure_looks(table, np.ones(n, dtype=np.int64), x, s, th)
    np.testing.assert_array_equal(var, bare + [9.0, math.radians(0.1) ** 2])
    r = np.sqrt(((x - s) ** 2).sum(-1) + DEF.altitude ** 2)
    c_r = DEF.range_resolution ** 2 / (2 * 10 ** (DEF.snr_ref_db / 10) * DEF.range_ref ** 4)
    np.testing.assert_allclose(bare[:, 0], c_r * r ** 4, rtol=1e-12, atol=0)   # no floor
    assert (var[:, 0] >= 9.0).all() and (var[:, 1] >= math.radians(0.1) ** 2).all()
