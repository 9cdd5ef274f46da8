"""The PMB tracker: the contract, closed forms, an exact hand-derived update, the grid's
thinning, labels, thresholds, and seeded scenes where it finds and deletes targets.

The second computations here share no code with the tracker: Kalman updates in
information form, Gaussian densities from scipy, the sensing region and Swerling detection
written from their definitions, segment-box occlusion by the slab method.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from sensorplan.models import linear, radar
from sensorplan.models.angles import wrap_angle
from sensorplan.models.motion import cv_matrices
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.base import Looks, Tracker, planning_tracks
from sensorplan.tracking.registry import TRACKERS
from sensorplan.tracking.checks import CHECKS, Scene, check_tracker
from sensorplan.tracking.missed import miss_update, standard_points
from sensorplan.tracking.pmb import undetected
from sensorplan.tracking.pmb.association import association_components, association_exact
from sensorplan.tracking.pmb.bernoulli import missed_existence
from sensorplan.tracking.pmb.sensing import Look
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from looks_helpers import MEANS, SENSORS, looks_of

P0 = np.diag([400.0, 400.0, 4.0, 4.0])
EXACT = 1e-12


def one_scan(z: np.ndarray) -> Looks:
    """A look of the linear sensor (its pose is not used)."""
    return looks_of([0], np.zeros((1, 2)), np.zeros(1), (np.asarray(z, dtype=float),))


def spd(rng: np.random.Generator, scale: np.ndarray) -> np.ndarray:
    A = rng.standard_normal((4, 4)) * 0.3 + np.eye(4)
    P = np.diag(scale) @ A @ A.T @ np.diag(scale)
    return 0.5 * (P + P.T)


# ----------------------------------------------------------------------------- contract


def radar_scene(params: SensorParams) -> tuple[np.ndarray, Scene]:
    table = radar_table((params, params))
    heads = np.arctan2(MEANS[:, 1] - SENSORS[:, 1], MEANS[:, 0] - SENSORS[:, 0])
    h, _, _, seen = radar.measure_looks(table, np.arange(2), MEANS[:, :2], SENSORS, heads)
    assert seen.all()
    far = radar.measure_looks(table, np.zeros(1, dtype=np.int64), MEANS[:1, :2] + [40.0, 0.0],
                              SENSORS[:1], heads[:1])[0]
    dets = (np.concatenate([h[0:1] + [3.0, 0.001], far]), h[1:1])   # two detections; a miss
    return table, Scene(looks_of(np.arange(2), SENSORS, heads, dets))


@pytest.mark.parametrize("params", [SensorParams(), SensorParams(clutter_rate=1.0),
                                    SensorParams(detection="swerling1", clutter_rate=2.0)])
def test_the_pmb_meets_the_tracker_contract_with_the_radar(params: SensorParams) -> None:
    table, sc = radar_scene(params)
    model = MapModel(table, 1.0, (600.0, 600.0))
    report = check_tracker(lambda: PMBTracker(model, means=MEANS, covs=P0, births="edges",
                                              birth_rate=0.1, initial_undetected=2.0), sc)
    assert report.checks == tuple(CHECKS)
    assert TRACKERS["pmb"] == "sensorplan.tracking.pmb.tracker:PMBTracker"
    assert isinstance(PMBTracker(model), Tracker)


def test_the_pmb_meets_the_tracker_contract_with_the_linear_sensor() -> None:
    sensor = linear.williams15()
    sc = Scene(one_scan([[100.0, 101.0], [20.0, 250.0], [290.0, 10.0]]))
    report = check_tracker(lambda: PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)),
                                              means=[[100.0, 100.0, 1.0, 0.0]], covs=P0 / 4,
                                              births="uniform", birth_rate=0.05,
                                              initial_undetected=1.0), sc)
    assert report.checks == tuple(CHECKS)


# ----------------------------------------------------------------------------- closed forms


def test_a_missed_look_gives_the_existence_formula_exactly() -> None:
    # Linear sensor, densities well inside its area: Pbar is Pd exactly and the density is
    # left as it was.
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 0.0)
    r = np.array([1.0, 0.95, 0.5, 0.2, 0.01])
    means = np.column_stack([np.linspace(100, 200, 5), np.full(5, 150.0), np.ones(5),
                             np.zeros(5)])
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 16,
                    existence=r, prune_threshold=0.0)
    tr.update(one_scan(np.zeros((0, 2))))
    pd = 0.9
    np.testing.assert_array_equal(tr.bern.r, r * (1.0 - pd) / (1.0 - r * pd))
    np.testing.assert_array_equal(tr.bern.means, means)
    np.testing.assert_array_equal(tr.bern.covs, np.broadcast_to(P0 / 16, (5, 4, 4)))
    assert tr.bern.r[0] == 1.0                    # a Bernoulli sure to exist stays sure
    # missed_existence at the corners: never detectable, surely detectable.
    np.testing.assert_array_equal(missed_existence(r, np.zeros(5)), r)
    np.testing.assert_array_equal(missed_existence(np.ones(2), np.ones(2)), np.zeros(2))


def test_a_missed_radar_look_uses_the_missed_look_quadrature() -> None:
    # Pbar is the probability mass the known-target tracker's missed-look update removes
    # (no gate factor), and the density is its result.
    table = radar_table(SensorParams(detection="swerling1", false_alarm_probability=1e-4))
    sxy, head = np.array([0.0, 0.0]), 0.3
    means = np.array([[330.0, 110.0, 1.0, 0.0], [420.0, 30.0, 0.0, 1.0],
                      [-300.0, 0.0, 0.0, 0.0]])                  # the last one: behind it
    covs = np.stack([np.diag([900.0, 400.0, 4.0, 4.0])] * 3)
    r = np.array([0.9, 0.6, 0.7])
    tr = PMBTracker(MapModel(table, 1.0, (600.0, 600.0)), means=means, covs=covs, existence=r)
    tr.update(looks_of([0], sxy[None], [head], (np.zeros((0, 2)),)))
    m, P, _, f = miss_update(means, covs, sxy, np.full(3, head), table, 0,
                             gate_probability=1.0, return_fraction=True)
    assert 0.0 < f[0] < 0.95 and 0.0 < f[1] < 0.95 and f[2] == 0.0
    np.testing.assert_allclose(tr.bern.r, r * (1 - f) / (1 - r * f), rtol=EXACT, atol=0)
    np.testing.assert_allclose(tr.bern.means[:2], m[:2], rtol=EXACT, atol=1e-12)
    np.testing.assert_allclose(tr.bern.covs[:2], P[:2], rtol=EXACT, atol=1e-9)
    # A Bernoulli the look could not have detected is left exactly as it was.
    np.testing.assert_array_equal(tr.bern.means[2], means[2])
    np.testing.assert_array_equal(tr.bern.covs[2], covs[2])


def kalman_information_form(m: np.ndarray, P: np.ndarray, z: np.ndarray,
                            R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The linear Kalman update in information form (the tracker uses the Joseph form)."""
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    J = np.linalg.inv(P) + H.T @ np.linalg.inv(R) @ H
    P_post = np.linalg.inv(J)
    m_post = P_post @ (np.linalg.inv(P) @ m + H.T @ np.linalg.inv(R) @ z)
    return m_post, P_post


def test_one_bernoulli_one_detection_equals_the_exact_update() -> None:
    # One cell of undetected intensity, one Bernoulli, one detection, clutter: the joint
    # associations are "the Bernoulli made z" and "it was missed, z is new or clutter".
    rng = np.random.default_rng(7)
    pd, R_var, rate, side = 0.9, 2.0, 3.0, 50.0
    sensor = linear.LinearSensor((0.0, 0.0, side, side), R_var, pd, rate)
    r, w_u, vv = 0.7, 0.4, 3.0
    m = np.array([24.0, 26.0, 1.0, -1.0])
    P = spd(rng, np.array([1.5, 1.5, 0.8, 0.8]))
    z = np.array([25.0, 24.5])
    tr = PMBTracker(MapModel(sensor, 1.0, (side, side), resolution=side, velocity_var=vv),
                    means=m[None], covs=P[None], existence=r, initial_undetected=w_u,
                    prune_threshold=0.0)
    out = tr.update_look(Look(0, np.zeros(2), 0.0), z[None])

    R = R_var * np.eye(2)
    lik = multivariate_normal(m[:2], P[:2, :2] + R).pdf(z)
    Pu = np.diag([side**2 / 12, side**2 / 12, vv, vv])
    cell = np.array([side / 2, side / 2, 0.0, 0.0])
    lam_u = w_u * pd * multivariate_normal(cell[:2], Pu[:2, :2] + R).pdf(z)
    kappa = rate / side**2
    w_det, w_miss, w_new = r * pd * lik, 1.0 - r * pd, lam_u + kappa
    total = w_det + w_miss * w_new
    p_det, p_miss = w_det / total, w_miss * w_new / total
    r_miss = r * (1.0 - pd) / (1.0 - r * pd)
    r_post = p_miss * r_miss + p_det
    m_det, P_det = kalman_information_form(m, P, z, R)
    b0, b1 = p_miss * r_miss / r_post, p_det / r_post
    m_post = b0 * m + b1 * m_det
    P_post = (b0 * (P + np.outer(m - m_post, m - m_post))
              + b1 * (P_det + np.outer(m_det - m_post, m_det - m_post)))
    r_new = p_miss * lam_u / w_new
    m_new, P_new = kalman_information_form(cell, Pu, z, R)

    np.testing.assert_allclose(out.marginals.p_det, [[p_det]], rtol=EXACT)
    assert tr.bern.labels.tolist() == [0, 1]
    np.testing.assert_allclose(tr.bern.r, [r_post, r_new], rtol=EXACT)
    np.testing.assert_allclose(tr.bern.means[0], m_post, rtol=EXACT)
    np.testing.assert_allclose(tr.bern.covs[0], P_post, rtol=EXACT, atol=EXACT)
    np.testing.assert_allclose(tr.bern.means[1], m_new, rtol=EXACT, atol=EXACT)
    np.testing.assert_allclose(tr.bern.covs[1], P_new, rtol=EXACT, atol=EXACT)
    np.testing.assert_allclose(tr.undetected, [w_u * (1.0 - pd)], rtol=EXACT)


def test_the_linear_missed_density_is_the_weighted_quadrature() -> None:
    # A density reaching over the area's edge: the points outside keep weight 1, those
    # inside 1 - Pd. The weighted moments written out point by point.
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.8, 0.0)
    m = np.array([5.0, 150.0, -1.0, 0.0])
    P = np.diag([100.0, 64.0, 4.0, 4.0])
    P[0, 2] = P[2, 0] = 10.0
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=m[None], covs=P[None],
                    existence=0.8)
    tr.update(one_scan(np.zeros((0, 2))))
    x = m + standard_points() @ np.linalg.cholesky(P).T
    inside = (x[:, 0] >= 0) & (x[:, 0] <= 300) & (x[:, 1] >= 0) & (x[:, 1] <= 300)
    w = np.where(inside, 0.2, 1.0)
    mean = (w[:, None] * x).sum(0) / w.sum()
    d = x - mean
    cov = (w[:, None, None] * d[:, :, None] * d[:, None, :]).sum(0) / w.sum()
    pbar = 0.8 * inside.mean()
    assert 0.3 < inside.mean() < 0.9
    np.testing.assert_allclose(tr.bern.r, [0.8 * (1 - pbar) / (1 - 0.8 * pbar)], rtol=EXACT)
    np.testing.assert_allclose(tr.bern.means[0], mean, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(tr.bern.covs[0], cov, rtol=1e-10, atol=1e-9)


def predicted(m: np.ndarray, P: np.ndarray, dt: float, q: float) -> tuple[np.ndarray, ...]:
    F, Q = cv_matrices(dt, q)
    return F @ m, F @ P @ F.T + Q


def test_predict_applies_survival_and_the_motion_model() -> None:
    sensor = linear.williams15()
    m = np.array([[100.0, 120.0, 2.0, -1.0], [150.0, 150.0, 0.0, 0.0]])
    P = np.stack([spd(np.random.default_rng(1), np.array([3.0, 3.0, 1.0, 1.0]))] * 2)
    tr = PMBTracker(MapModel(sensor, 2.0, (300.0, 300.0), process_noise=0.3, resolution=25.0),
                    means=m, covs=P, existence=[0.9, 0.4], survival_probability=0.95,
                    births="uniform", birth_rate=1.44, initial_undetected=2.88)
    tr.predict()
    for k in range(2):
        mk, Pk = predicted(m[k], P[k], 2.0, 0.3)
        np.testing.assert_allclose(tr.bern.means[k], mk, rtol=EXACT)
        np.testing.assert_allclose(tr.bern.covs[k], Pk, rtol=EXACT, atol=EXACT)
    np.testing.assert_allclose(tr.bern.r, [0.95 * 0.9, 0.95 * 0.4], rtol=EXACT)
    # 144 cells: 0.02 each at the start, then survival and 0.01 births each.
    np.testing.assert_allclose(tr.undetected, np.full(144, 0.95 * 0.02 + 0.01), rtol=EXACT)
    assert tr.planning_process_noise() == 0.3


def test_a_bernoulli_leaving_the_map_loses_existence_with_an_exit_edge() -> None:
    # Position variances with no x-y correlation: the mass on the map is a product of two
    # normal intervals after the predict.
    sensor = linear.williams15()
    m = np.array([[295.0, 150.0, 4.0, 0.0]])
    P = np.diag([9.0, 16.0, 1.0, 1.0])[None]
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0), process_noise=0.1, map_edge="exit"),
                    means=m, covs=P, existence=0.9, survival_probability=0.99,
                    report_threshold=0.3)
    corrected = tr.predict()
    mk, Pk = predicted(m[0], P[0], 1.0, 0.1)
    sx, sy = math.sqrt(Pk[0, 0]), math.sqrt(Pk[1, 1])
    mass = ((norm.cdf((300 - mk[0]) / sx) - norm.cdf(-mk[0] / sx))
            * (norm.cdf((300 - mk[1]) / sy) - norm.cdf(-mk[1] / sy)))
    np.testing.assert_allclose(tr.bern.r, [0.99 * 0.9 * mass], rtol=1e-12)
    assert corrected.tolist() == [True] and tr.bern.means[0, 0] < 300.0


def folded_moments(mu: np.ndarray, P: np.ndarray, wall: float) -> tuple[float, float, float]:
    """Mean x, mean vx and variance of x of a Gaussian state ``[x, y, vx, vy]`` whose part
    beyond the wall ``x = wall`` is mirrored back (``x -> 2 wall - x``, ``vx -> -vx``): the
    folded normal's closed form (the far wall's share is negligible here)."""
    s = math.sqrt(P[0, 0])
    a = (wall - mu[0]) / s
    tail, dens = norm.sf(a), norm.pdf(a)
    beyond = s * dens + (mu[0] - wall) * tail                     # E[(x - wall)+]
    ex = mu[0] - 2.0 * beyond
    ev = mu[2] - 2.0 * (mu[2] * tail + P[0, 2] / s * dens)        # E[vx 1{x > wall}]
    # E[(x - wall)^2 1{x > wall}] is unchanged by the fold: E[x'^2] = E[x^2] - 4 wall beyond.
    ex2 = P[0, 0] + mu[0] ** 2 - 4.0 * wall * beyond
    return ex, ev, ex2 - ex ** 2


@pytest.mark.parametrize("edge", ["exit", "closed"])
def test_a_bernoulli_predicted_across_the_wall_keeps_its_existence_only_in_a_closed_map(
        edge: str) -> None:
    # Its mean is predicted 1 m inside the wall x = 300 with a third of its mass beyond.
    sensor = linear.williams15()
    m = np.array([[295.0, 150.0, 4.0, 0.0]])
    P = np.diag([9.0, 16.0, 1.0, 1.0])[None]
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0), process_noise=0.1, map_edge=edge),
                    means=m, covs=P, existence=0.9, survival_probability=0.99,
                    report_threshold=0.3)
    corrected = tr.predict()
    mk, Pk = predicted(m[0], P[0], 1.0, 0.1)
    sx = math.sqrt(Pk[0, 0])
    on_map = norm.cdf((300 - mk[0]) / sx) - norm.cdf(-mk[0] / sx)   # y is far inside
    assert on_map < 0.75
    want = 0.99 * 0.9 * (on_map if edge == "exit" else 1.0)
    np.testing.assert_allclose(tr.bern.r, [want], rtol=1e-9)
    assert corrected.tolist() == [True]
    x = tr.bern.means[0]
    assert 0.0 <= x[0] < 300.0 and 0.0 <= x[1] <= 300.0
    if edge == "closed":
        # The reflected density's moments against the folded normal's closed form, to the
        # 512-point quadrature's accuracy (a few mm and mm/s on a 2 m spread).
        ex, ev, vx = folded_moments(mk, Pk, 300.0)
        np.testing.assert_allclose([x[0], x[2]], [ex, ev], atol=0.01)
        np.testing.assert_allclose(tr.bern.covs[0, 0, 0], vx, rtol=0.02)
        # The rest of the state is the prediction's (no y, vy coupling to x here).
        np.testing.assert_allclose(x[[1, 3]], mk[[1, 3]], atol=1e-9)


def test_a_closed_map_keeps_a_bernoulli_inside_through_many_walls() -> None:
    # A lost track (large covariance) drifting for 60 steps: with a closed map it neither
    # loses existence at the walls nor leaves the map; with an exit edge it fades.
    sensor = linear.williams15()
    m = np.array([[280.0, 20.0, 5.0, -4.0]])
    P = np.diag([400.0, 400.0, 4.0, 4.0])[None]
    out = {}
    for edge in ("exit", "closed"):
        tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0), process_noise=0.5,
                                 map_edge=edge),
                        means=m, covs=P, existence=1.0, survival_probability=0.999,
                        prune_threshold=0.0, report_threshold=0.3)
        for _ in range(60):
            tr.predict()
            if edge == "closed":
                x = tr.bern.means[0]
                assert 0.0 <= x[0] <= 300.0 and 0.0 <= x[1] <= 300.0
                assert np.all(np.linalg.eigvalsh(tr.bern.covs[0]) > 0.0)
        out[edge] = tr.bern.r[0]
    np.testing.assert_allclose(out["closed"], 0.999 ** 60, rtol=1e-12)
    assert out["exit"] < 0.5 * out["closed"]


# ----------------------------------------------------------------------------- the grid


def slab_hidden(sxy: np.ndarray, z: float, q: np.ndarray, boxes: np.ndarray) -> bool:
    """Whether the segment from ``(sxy, z)`` to ``(q, 0)`` passes through a box (slab test)."""
    p0 = np.array([sxy[0], sxy[1], z])
    d = np.array([q[0], q[1], 0.0]) - p0
    for x0, y0, x1, y1, h in boxes:
        lo, hi = 0.0, 1.0
        for k, (a, b) in enumerate(((x0, x1), (y0, y1), (0.0, h))):
            if abs(d[k]) < 1e-15:
                if not a < p0[k] < b:
                    lo, hi = 1.0, 0.0
                continue
            t0, t1 = sorted(((a - p0[k]) / d[k], (b - p0[k]) / d[k]))
            lo, hi = max(lo, t0), min(hi, t1)
        if lo < hi:
            return True
    return False


def test_a_look_thins_the_grid_by_pd_in_the_sensing_region_and_in_sight() -> None:
    params = SensorParams(detection="swerling1", false_alarm_probability=1e-5)
    table = radar_table(params)
    box = np.array([[320.0, 230.0, 380.0, 300.0, 60.0]])
    sxy, head = np.array([300.0, 0.0]), math.pi / 2
    tr = PMBTracker(MapModel(table, 1.0, (600.0, 600.0), buildings=box),
                    initial_undetected=36.0)
    before = tr.undetected.copy()
    tr.update(looks_of([0], sxy[None], [head], (np.zeros((0, 2)),)))
    c = tr.grid.centres
    d = c - sxy
    g = np.hypot(d[:, 0], d[:, 1])
    r = np.sqrt(g**2 + 500.0**2)
    in_band = (g >= 250.0) & (g <= 450.0)
    in_wedge = np.abs(wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - head)) <= math.pi / 6
    cos_dep, sin_dep = math.cos(math.radians(40)), math.sin(math.radians(40))
    front = (cos_dep * (d[:, 0] * math.cos(head) + d[:, 1] * math.sin(head))
             + sin_dep * 500.0) / r > 0
    seen = np.array([not slab_hidden(sxy, 500.0, q, box) for q in c])
    snr = 10 ** 1.5 * (600.0 / r) ** 4
    pd = 1e-5 ** (1.0 / (1.0 + snr))
    v = in_band & in_wedge & front & seen
    assert v.sum() > 50 and (in_band & in_wedge & ~seen).sum() >= 3
    np.testing.assert_allclose(tr.undetected, before * (1.0 - pd * v), rtol=EXACT, atol=0)


def test_birth_intensities_and_the_grid() -> None:
    g = undetected.make_grid(600.0, 590.0, 25.0, 10.5)
    assert (g.nx, g.ny) == (24, 24)
    np.testing.assert_allclose(g.cov[:2, :2], np.diag([25.0**2, (590 / 24) ** 2]) / 12)
    edges = undetected.birth_intensity(g, "edges", 0.2)
    assert (edges > 0).sum() == 4 * 24 - 4
    np.testing.assert_allclose(edges.sum(), 0.2, rtol=1e-14)
    np.testing.assert_allclose(undetected.birth_intensity(g, "uniform", 0.2), 0.2 / 576)
    assert not undetected.birth_intensity(g, "none", 0.2).any()
    with pytest.raises(ValueError, match="births"):
        undetected.birth_intensity(g, "sides", 0.2)
    with pytest.raises(ValueError, match="rate"):
        undetected.birth_intensity(g, "edges", -1.0)


def test_background_births_spread_evenly_and_let_a_detection_start_a_track_anywhere() -> None:
    model = MapModel(linear.williams15(), 1.0, (300.0, 300.0))
    plain = PMBTracker(model, births="edges", birth_rate=0.2, survival_probability=1.0)
    both = PMBTracker(model, births="edges", birth_rate=0.2, background_birth_rate=0.1,
                      survival_probability=1.0)
    C = plain.grid.size
    np.testing.assert_allclose(both.births - plain.births, 0.1 / C, rtol=1e-13, atol=0)
    np.testing.assert_allclose(both.births.sum(), 0.3, rtol=1e-14)
    # The same intensity given per cell is the same tracker.
    given = PMBTracker(model, births=undetected.birth_intensity(plain.grid, "edges", 0.2)
                       + np.full(C, 0.1 / C), survival_probability=1.0)
    # A detection in the middle of the map: the edge births put no target within reach of
    # it, so it starts no track; with background births it starts one.
    for tr in (plain, both, given):
        tr.predict()
        tr.update(one_scan([[150.0, 150.0]]))
    assert len(plain.bern) == 0
    assert len(both.bern) == 1 and 1e-3 < both.bern.r[0] < 0.5
    np.testing.assert_allclose(given.bern.r, both.bern.r, rtol=1e-12)
    np.testing.assert_allclose(given.bern.means, both.bern.means, rtol=1e-12)


# ----------------------------------------------------------------------------- management


def test_pruning_and_reporting_thresholds() -> None:
    sensor = linear.williams15()
    r = np.array([0.0015, 0.3, 0.5, 0.49999, 0.9])
    means = np.column_stack([np.linspace(50, 250, 5), np.full(5, 150.0), np.zeros((5, 2))])
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0, existence=r,
                    survival_probability=0.6)
    t = tr.tracks()
    assert t.labels.tolist() == [2, 4]                           # r >= 0.5 is reported
    np.testing.assert_array_equal(t.existence, [0.5, 0.9])
    flags = tr.predict()                                     # r * 0.6: 0.0009 < 1e-3
    assert flags.tolist() == [False, False]
    assert tr.bern.labels.tolist() == [1, 2, 3, 4]
    assert tr.tracks().labels.tolist() == [4]
    tr2 = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0, existence=r,
                     prune_threshold=0.2, report_threshold=0.25)
    tr2.update(looks_of([], np.zeros((0, 2)), np.zeros(0), ()))
    tr2.predict()
    assert tr2.bern.labels.tolist() == [1, 2, 3, 4]
    assert tr2.tracks().labels.tolist() == [1, 2, 3, 4]


@pytest.mark.parametrize(("planning", "report", "seen"), [
    (None, 0.5, [2, 4]),                 # default: the reported tracks
    (0.1, 0.5, [1, 2, 3, 4]),            # every Bernoulli at or above 0.1
    (0.3, 0.5, [1, 2, 3, 4]),            # r = 0.3 is at the threshold: seen
    (0.30001, 0.5, [2, 3, 4]),
    (0.9, 0.5, [2, 4]),                  # never above the report threshold
    (0.2, 0.25, [1, 2, 3, 4])])
def test_planning_sees_the_bernoullis_at_or_above_its_threshold(planning, report, seen) -> None:
    r = np.array([0.0015, 0.3, 0.5, 0.49999, 0.9])
    means = np.column_stack([np.linspace(50, 250, 5), np.full(5, 150.0), np.zeros((5, 2))])
    covs = P0 * np.linspace(1.0, 2.0, 5)[:, None, None]
    tr = PMBTracker(MapModel(linear.williams15(), 1.0, (300.0, 300.0)), means=means, covs=covs,
                    existence=r, report_threshold=report, planning_threshold=planning)
    got = tr.planning_tracks()
    assert got.labels.tolist() == seen
    # The Bernoullis as they are: their existence (planning's weights) and moments.
    np.testing.assert_array_equal(got.existence, r[seen])
    np.testing.assert_array_equal(got.means, means[seen])
    np.testing.assert_array_equal(got.covs, covs[seen])
    # Every reported track is among them.
    assert set(tr.tracks().labels.tolist()) <= set(seen)
    got.means[:] = 0.0                                          # a copy
    assert np.array_equal(tr.bern.means, means)


@pytest.mark.parametrize("termination", [1.0, 0.1])
def test_a_confirmed_track_is_reported_down_to_the_termination_threshold(termination) -> None:
    # Missed looks of a linear sensor (Pbar = Pd exactly) take r through the closed form
    # r (1 - Pd) / (1 - r Pd): with termination 0.1 a confirmed track is reported until r
    # falls below 0.1, without it until r falls below the report threshold 0.5. A
    # Bernoulli never confirmed (r0 = 0.4) is not reported on the way down either way.
    pd, report = 0.5, 0.5
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, pd, 0.0)
    r0 = np.array([0.99, 0.4])
    means = np.array([[100.0, 150.0, 0.0, 0.0], [200.0, 150.0, 0.0, 0.0]])
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 16,
                    existence=r0, survival_probability=1.0, prune_threshold=0.0,
                    report_threshold=report, termination_threshold=termination)
    r = r0.copy()
    kept = min(termination, report)
    for _ in range(14):
        tr.predict()
        tr.update(one_scan(np.zeros((0, 2))))
        r = r * (1.0 - pd) / (1.0 - r * pd)
        np.testing.assert_allclose(tr.bern.r, r, rtol=1e-12, atol=1e-15)
        want = [0] if r[0] >= kept else []
        assert tr.tracks().labels.tolist() == want
        # Every reported track is among those planning sees.
        assert set(want) <= set(tr.planning_tracks().labels.tolist())
    assert r[0] < kept                                  # the walk crossed the threshold


def test_a_terminated_track_is_confirmed_again_when_it_climbs_back() -> None:
    # Reported at 0.9 (confirmed), kept at 0.3 (above termination 0.2), terminated at 0.15,
    # not reported at 0.3 again, confirmed again at 0.6. Existence set by hand between steps
    # (no motion: survival 1 and a look that sees nothing of it).
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 0.0)
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=MEANS[:1], covs=P0,
                    existence=0.9, survival_probability=1.0, termination_threshold=0.2)
    seen = []
    for r in (0.3, 0.15, 0.3, 0.6, 0.3):
        tr.bern.r = np.array([r])
        tr.predict()
        seen.append(tr.tracks().labels.tolist())
    assert seen == [[0], [], [], [0], [0]]


def test_an_established_bernoulli_survives_with_its_own_probability() -> None:
    # Three Bernoullis of a linear sensor whose field of view (a metre square in a corner,
    # ten standard deviations away) sees nothing of them, so only the predicts move r: one
    # known (1: established from the start), one that reaches
    # 0.99 by hand after the first step (established from then on, even after it falls
    # again), one never above 0.9 (the tracker survival throughout).
    sensor = linear.LinearSensor((0.0, 0.0, 1.0, 1.0), 1.0, 1.0, 0.0)
    means = np.array([[60.0, 60.0, 0.0, 0.0], [150.0, 150.0, 0.0, 0.0],
                      [250.0, 250.0, 0.0, 0.0]])
    ps, pe = 0.9, 0.995
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 16,
                    existence=[1.0, 0.5, 0.9], survival_probability=ps,
                    established_survival=pe, established_existence=0.99)
    tr.predict()
    np.testing.assert_allclose(tr.bern.r, [pe, ps * 0.5, ps * 0.9], rtol=EXACT)
    tr.bern.r = np.array([tr.bern.r[0], 0.99, 0.5])
    tr.update(one_scan(np.zeros((0, 2))))
    assert tr.established.tolist() == [0, 1]
    r = tr.bern.r.copy()
    for _ in range(3):
        tr.predict()
        r = r * [pe, pe, ps]
        np.testing.assert_allclose(tr.bern.r, r, rtol=EXACT)
    # Without the setting every Bernoulli has the tracker survival, as before.
    plain = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 16,
                       existence=[1.0, 0.5, 0.9], survival_probability=ps)
    plain.predict()
    np.testing.assert_allclose(plain.bern.r, [ps, ps * 0.5, ps * 0.9], rtol=EXACT)
    assert plain.established.tolist() == []


def test_an_established_label_is_forgotten_when_its_bernoulli_is_pruned() -> None:
    # Missed looks with Pd = 1 send r to 0 exactly: the Bernoulli is pruned and its
    # label leaves the established ones; the other stays.
    sensor = linear.LinearSensor((0.0, 0.0, 150.0, 300.0), 1.0, 1.0, 0.0)
    means = np.array([[50.0, 150.0, 0.0, 0.0], [250.0, 150.0, 0.0, 0.0]])
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 400,
                    survival_probability=0.99, established_survival=1.0)
    assert tr.established.tolist() == [0, 1]
    tr.predict()
    tr.update(one_scan(np.zeros((0, 2))))
    assert tr.bern.labels.tolist() == [1]
    assert tr.established.tolist() == [1]


def test_planning_tracks_fall_back_to_the_reported_ones() -> None:
    from sensorplan.tracking.gnn import GNNTracker

    tr = GNNTracker(MapModel(linear.williams15(), 1.0, (300.0, 300.0)), means=MEANS[:2], covs=P0)
    assert not hasattr(tr, "planning_tracks")
    np.testing.assert_array_equal(planning_tracks(tr).labels, tr.tracks().labels)


@pytest.mark.parametrize(("key", "value"), [("report_threshold", 1.0), ("report_threshold", 0.0),
                                            ("planning_threshold", 0.0),
                                            ("planning_threshold", 1.0),
                                            ("termination_threshold", 0.0),
                                            ("termination_threshold", 1.5),
                                            ("prune_threshold", 1.0),
                                            ("survival_probability", 0.0),
                                            ("established_survival", 0.0),
                                            ("established_survival", 1.5),
                                            ("established_existence", 1.0),
                                            ("initial_undetected", -1.0), ("births", "sides"),
                                            ("background_birth_rate", -0.1),
                                            ("background_birth_rate", math.inf),
                                            ("births", np.ones(3)), ("existence", 1.5)])
def test_bad_settings_are_refused(key: str, value: object) -> None:
    # The map model's own fields are checked in test_map_model.py.
    with pytest.raises(ValueError, match=key):
        PMBTracker(MapModel(linear.williams15(), 1.0, (300.0, 300.0)), means=MEANS[:1],
                   covs=P0, **{key: value})


def run_linear(tr: PMBTracker, truth: list[np.ndarray], sensor: linear.LinearSensor,
               rng: np.random.Generator) -> list:
    """Steps of predict and one scan of the targets alive at each step; the reported
    tracks after each."""
    out = []
    for xy in truth:
        tr.predict()
        z, _ = linear.scan(sensor, xy, rng)
        tr.update(one_scan(z))
        out.append(tr.tracks())
    return out


def straight(start: np.ndarray, v: np.ndarray, steps: int) -> np.ndarray:
    return start + v * np.arange(1, steps + 1)[:, None]


def test_labels_persist_and_are_never_reused() -> None:
    sensor = linear.williams15()
    rng = np.random.default_rng(11)
    a = straight(np.array([60.0, 60.0]), np.array([1.0, 1.0]), 30)
    b = straight(np.array([220.0, 200.0]), np.array([-1.0, 0.0]), 30)
    truth = [np.stack([a[t], b[t]]) for t in range(30)]
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0), velocity_var=2.0, process_noise=0.05),
                    means=[[60.0, 60.0, 1.0, 1.0]], covs=P0 / 4, births="uniform",
                    birth_rate=0.02, initial_undetected=1.0)
    seen: set[int] = set()
    gone: set[int] = set()
    present_before: set[int] = {0}
    holder: dict[int, int] = {}
    for t in range(30):
        tr.predict()
        z, _ = linear.scan(sensor, truth[t], rng)
        tr.update(one_scan(z))
        present = set(tr.bern.labels.tolist())
        assert not (present & gone), "a label came back"
        new = present - present_before
        assert all(label >= tr.next_label - len(new) for label in new)
        assert tr.bern.labels.tolist() == sorted(present)
        gone |= present_before - present
        present_before = present
        seen |= present
        tracks = tr.tracks()
        for k, label in enumerate(tracks.labels):
            d = np.hypot(*(truth[t] - tracks.means[k, :2]).T)
            if d.min() < 5.0:
                holder.setdefault(int(np.argmin(d)), int(label))
                assert holder[int(np.argmin(d))] == label, "a target's label changed"
    assert holder[0] == 0 and 1 in holder and holder[1] > 0
    assert seen == set(range(tr.next_label))       # every label given out was a Bernoulli's


# ----------------------------------------------------------------------------- scenes


def test_the_pmb_finds_an_unnamed_target_and_deletes_one_that_vanished() -> None:
    # williams15's sensor (10 false alarms per scan over 300 x 300 m, Pd 0.9). Target A is
    # known at the start and disappears after step 6; target B was never named.
    sensor = linear.williams15()
    rng = np.random.default_rng(2026)
    a = straight(np.array([60.0, 60.0]), np.array([1.0, 1.0]), 6)
    b = straight(np.array([220.0, 200.0]), np.array([-1.0, 0.5]), 20)
    truth = [np.stack([a[t], b[t]]) if t < 6 else b[t:t + 1] for t in range(20)]
    tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0), velocity_var=2.0, process_noise=0.05),
                    means=[[60.0, 60.0, 1.0, 1.0]], covs=P0 / 4, births="uniform",
                    birth_rate=0.01, initial_undetected=1.0)
    reports = run_linear(tr, truth, sensor, rng)

    def held(tracks, xy, within=5.0) -> list[int]:
        d = np.hypot(*(tracks.means[:, :2] - xy).T) if len(tracks) else np.zeros(0)
        return tracks.labels[d < within].tolist()

    found = [t for t in range(20) if held(reports[t], b[t])]
    assert found and found[0] <= 3, f"B first confirmed at step {found[:1]}"
    assert all(held(reports[t], b[t]) for t in range(found[0], 20))
    assert all(0 in reports[t].labels for t in range(6))
    deleted = [t for t in range(6, 20) if 0 not in reports[t].labels]
    assert deleted and deleted[0] <= 9 and deleted == list(range(deleted[0], 20))
    false = [len(reports[t]) - len(held(reports[t], b[t])) - (0 in reports[t].labels)
             for t in range(20)]
    assert sum(false) <= 2, false


def test_the_pmb_finds_and_deletes_with_a_radar_in_clutter() -> None:
    # One radar staring north over a fixed region with 2 false alarms per look: target B
    # (unnamed) walks through it; the named Bernoulli at (250, 360) has no target.
    params = SensorParams(clutter_rate=2.0)
    table = radar_table(params)
    rng = np.random.default_rng(5)
    sxy, head = np.array([300.0, 0.0]), math.pi / 2
    b = straight(np.array([330.0, 330.0]), np.array([-1.0, 1.0]), 15)
    tr = PMBTracker(MapModel(table, 1.0, (600.0, 600.0)), means=[[250.0, 360.0, 0.0, 0.0]],
                    covs=P0 / 4, births="uniform", birth_rate=0.05, initial_undetected=2.0)
    confirmed, deleted = None, None
    for t in range(15):
        tr.predict()
        h, _, var, seen = radar.measure_looks(table, np.zeros(1, dtype=np.int64), b[t:t + 1],
                                              sxy[None], np.array([head]))
        assert seen.all()
        z = h + np.sqrt(var) * rng.standard_normal((1, 2))
        u = rng.random((int(rng.poisson(2.0)), 2))
        fa = radar.false_alarms(table, 0, sxy, head, u, rng.standard_normal((len(u), 2)))
        tr.update(looks_of([0], sxy[None], [head], (np.concatenate([z, fa]),)))
        tracks = tr.tracks()
        d = np.hypot(*(tracks.means[:, :2] - b[t]).T)
        if confirmed is None and np.any((d < 10.0) & (tracks.labels > 0)):
            confirmed = t
        if deleted is None and 0 not in tracks.labels:
            deleted = t
    assert confirmed is not None and confirmed <= 3
    assert deleted is not None and deleted <= 2
    assert 0 not in tr.bern.labels                      # pruned, not only unreported


# ----------------------------------------------------------------------------- association


def is_forest(w_det: np.ndarray) -> bool:
    gated = w_det > 0.0
    return all(gated[np.ix_(t, z)].sum() == t.size + z.size - 1
               for t, z in association_components(w_det))


def test_on_tree_shaped_graphs_the_marginals_equal_exact_enumeration() -> None:
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 5.0)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(60):
        n, m = 4, 5
        means = np.column_stack([rng.uniform(100, 140, n), rng.uniform(100, 110, n),
                                 np.zeros((n, 2))])
        r = rng.uniform(0.2, 1.0, n)
        tr = PMBTracker(MapModel(sensor, 1.0, (300.0, 300.0)), means=means, covs=P0 / 100,
                        existence=r, initial_undetected=5.0, prune_threshold=0.0)
        Z = np.column_stack([rng.uniform(95, 145, m), rng.uniform(98, 112, m)])
        out = tr.update_look(Look(0, np.zeros(2), 0.0), Z)
        w_miss, w_det, w_new = out.weights
        if not is_forest(w_det) or (w_det > 0).sum() < 3:
            continue
        checked += 1
        exact = association_exact(w_miss, w_det, w_new)
        np.testing.assert_allclose(out.marginals.p_det, exact.p_det, rtol=0, atol=1e-9)
        np.testing.assert_allclose(out.marginals.p_miss, exact.p_miss, rtol=0, atol=1e-9)
        np.testing.assert_allclose(out.marginals.p_new, exact.p_new, rtol=0, atol=1e-9)
        # and the existence each Bernoulli leaves with follows from the exact marginals
        r_miss = r * (1 - 0.9) / (1 - r * 0.9)
        np.testing.assert_allclose(tr.bern.r[:n], exact.p_miss * r_miss + exact.p_det.sum(1),
                                   rtol=0, atol=1e-9)
    assert checked >= 10, checked


# ----------------------------------------------------------------------------- the kernels


@pytest.mark.parametrize("detection", ["ideal", "swerling1"])
@pytest.mark.parametrize("with_buildings", [False, True])
def test_the_quadrature_fast_paths_give_the_radar_models_numbers(detection: str,
                                                                 with_buildings: bool) -> None:
    # Densities all around a look, of every size: the classes skip or shortcut the radar's
    # quadrature call; the probabilities must be the call's, bit for bit.
    from sensorplan.tracking.pmb.sensing import INSIDE, OUTSIDE, PARTLY, RadarSensing

    table = radar_table(SensorParams(detection=detection))
    box = np.array([[380.0, 20.0, 420.0, 90.0, 80.0]]) if with_buildings else None
    s = RadarSensing(table, box)
    rng = np.random.default_rng(4)
    B = 300
    ang = rng.uniform(-1.2, 1.2, B)
    g = rng.uniform(100.0, 600.0, B)
    means = np.column_stack([g * np.cos(ang), g * np.sin(ang), rng.normal(0, 2, (B, 2))])
    covs = np.stack([spd(rng, np.array([sd, sd * rng.uniform(0.3, 1.5), 1.0, 1.0]))
                     for sd in rng.uniform(0.5, 60.0, B)])
    look = Look(0, np.zeros(2), 0.2)
    rows, p, chol = s.quadrature(means, covs, look)
    kinds = s.classify(means, covs, look)
    assert {OUTSIDE, INSIDE, PARTLY} <= set(kinds.tolist())
    full = radar.detectable_quadrature(table, np.zeros(B, dtype=np.int64), means[:, :2],
                                       np.linalg.cholesky(covs), standard_points(),
                                       np.full(B, 0.2), np.zeros((B, 2)), box)
    np.testing.assert_array_equal(p, full[rows])
    others = np.setdiff1d(np.arange(B), rows)
    assert others.size and not full[others].any()                # skipped: nothing seen
    np.testing.assert_array_equal(chol, np.linalg.cholesky(covs[rows]))
    # The cells' detection probabilities the same way.
    cells = undetected.make_grid(600.0, 600.0, 25.0, 1.0).centres - [0.0, 300.0]
    ref = radar.detectable_points(table, np.array([0]), cells[None, :, 0], cells[None, :, 1],
                                  np.array([0.2]), np.zeros((1, 2)), box)[0]
    np.testing.assert_array_equal(s.detectable(cells, look), ref)


def test_pair_terms_and_updates_equal_numpy_solves() -> None:
    from sensorplan.tracking.pmb.bernoulli import pair_terms, updates
    from sensorplan.tracking.pmb.sensing import RadarSensing

    table = radar_table(SensorParams())
    s = RadarSensing(table)
    rng = np.random.default_rng(8)
    B, m = 7, 5
    means = np.column_stack([rng.uniform(280, 380, B), rng.uniform(-60, 60, B),
                             rng.normal(0, 2, (B, 2))])
    covs = np.stack([spd(rng, np.array([9.0, 6.0, 1.0, 1.0])) for _ in range(B)])
    look = Look(0, np.zeros(2), 0.0)
    h, Hp, var, _ = radar.measure_looks(table, np.zeros(B, dtype=np.int64), means[:, :2],
                                        np.zeros((B, 2)), np.zeros(B))
    Z = h[:m] + rng.normal(0, 1, (m, 2)) * [2.0, 0.004]
    t = pair_terms(s, look, means, covs, Z, 13.8)
    S = Hp @ covs[:, :2, :2] @ np.swapaxes(Hp, -1, -2) + np.stack([np.diag(v) for v in var])
    nu = Z[None] - h[:, None]
    nu[..., 1] = wrap_angle(nu[..., 1])
    d2 = np.einsum("bmi,bim->bm", nu, np.linalg.solve(S, np.swapaxes(nu, -1, -2)))
    ll = -0.5 * d2 - 0.5 * np.linalg.slogdet(S)[1][:, None] - math.log(2 * math.pi)
    np.testing.assert_allclose(t.nu, nu, rtol=EXACT, atol=1e-15)
    np.testing.assert_allclose(t.d2, d2, rtol=1e-10)
    np.testing.assert_allclose(t.log_lik, ll, rtol=1e-12, atol=1e-12)
    assert t.gated.tolist() == (d2 < 13.8).tolist()
    np.testing.assert_allclose(t.lik, np.where(d2 < 13.8, np.exp(ll), 0.0), rtol=1e-12)
    rows, cols = np.nonzero(t.gated)
    unique, which = np.unique(rows, return_inverse=True)
    x, P = updates(means, covs, t, unique, which, cols)
    for k, (i, j) in enumerate(zip(rows, cols)):
        H = np.hstack([Hp[i], np.zeros((2, 2))])
        K = covs[i] @ H.T @ np.linalg.inv(S[i])
        np.testing.assert_allclose(x[k], means[i] + K @ nu[i, j], rtol=EXACT, atol=1e-9)
        np.testing.assert_allclose(P[k], (np.eye(4) - K @ H) @ covs[i], rtol=1e-9, atol=1e-9)
    assert len(rows) >= 3


def test_mixture_moments_equal_a_plain_loop() -> None:
    from sensorplan.tracking.pmb.bernoulli import mixture_moments

    rng = np.random.default_rng(2)
    K, G = 12, 4
    w = rng.uniform(0.0, 1.0, K)
    groups = rng.integers(0, G - 1, K)                 # the last group gets nothing
    x = rng.normal(0, 10, (K, 4))
    P = np.stack([spd(rng, np.ones(4)) for _ in range(K)])
    total, m, C = mixture_moments(G, (w[:5], groups[:5], x[:5], P[:5]),
                                  (w[5:], groups[5:], x[5:], P[5:]))
    for g in range(G):
        k = groups == g
        np.testing.assert_allclose(total[g], w[k].sum(), rtol=EXACT)
        if not k.any():
            assert total[g] == 0.0
            continue
        b = w[k] / w[k].sum()
        mean = b @ x[k]
        cov = sum(bi * (Pi + np.outer(xi - mean, xi - mean)) for bi, xi, Pi in zip(b, x[k], P[k]))
        np.testing.assert_allclose(m[g], mean, rtol=EXACT, atol=1e-12)
        np.testing.assert_allclose(C[g], cov, rtol=EXACT, atol=1e-12)
