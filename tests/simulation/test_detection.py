"""Missed detections, false alarms, association, and planning that expects them."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import radar_reference as ref
from sensorplan.models import radar
from sensorplan.tracking.missed import miss_update
from sensorplan.models.sensors import AREA, SensorParams, radar_table
from sensorplan.simulation import run_streams
from sensorplan.simulation.sensing import DetectionDraws
from sensorplan.tracking.tracker import KnownTargetTracker

RADAR = SensorParams(detection="swerling1", false_alarm_probability=1e-4, clutter_rate=3.0)


def test_swerling_pd_closed_form():
    row = radar_table(RADAR)[0]
    for r in (300.0, 600.0, 900.0):
        snr = 10 ** 1.5 * (600.0 / r) ** 4
        assert radar.detection_probability(row, r * r) == pytest.approx(
            1e-4 ** (1.0 / (1.0 + snr)), rel=1e-13)
    assert radar.detection_probability(radar_table(SensorParams())[0], 600.0 ** 2) == 1.0


def test_detection_frequencies_match_pd_within_binomial_bounds():
    """Over many steps the share of detections of a target in view matches Pd."""
    table = radar_table([RADAR, SensorParams(detection="swerling1",
                                             false_alarm_probability=1e-6, altitude=450.0)])
    S = 20_000
    draws = DetectionDraws(table, run_streams(11), S)
    target = np.array([[400.0, 300.0], [300.0, 650.0]])
    sensor = np.array([[100.0, 300.0], [300.0, 300.0]])
    pd = radar.detection_probabilities(table, np.arange(2), target, sensor)
    hits = np.array([draws.detected(t, target, sensor) for t in range(1, S + 1)])
    for i in range(2):
        k = hits[:, i].sum()
        lo, hi = stats.binom.ppf([0.0005, 0.9995], S, pd[i])
        assert lo <= k <= hi, (i, k / S, pd[i])
    assert 0.3 < pd.min() < pd.max() < 0.95                 # both are strictly uncertain


def test_the_clutter_count_is_poisson_with_mean_lambda():
    table = radar_table([RADAR, SensorParams(clutter_rate=0.4)])
    S = 20_000
    counts = DetectionDraws(table, run_streams(3), S).counts          # (S, 2)
    for i, lam in enumerate((3.0, 0.4)):
        c = counts[:, i]
        # mean within 4 standard errors; variance equal to the mean (Poisson dispersion)
        assert abs(c.mean() - lam) < 4 * math.sqrt(lam / S)
        assert abs(c.var() / c.mean() - 1.0) < 0.05
        # chi-square goodness of fit of the counts 0..6+
        k = np.arange(7)
        observed = np.array([(c == v).sum() for v in k[:-1]] + [(c >= 6).sum()])
        expected = S * np.append(stats.poisson.pmf(k[:-1], lam), stats.poisson.sf(5, lam))
        keep = expected > 5
        chi = ((observed[keep] - expected[keep]) ** 2 / expected[keep]).sum()
        assert stats.chi2.sf(chi, keep.sum() - 1) > 1e-4


def test_no_clutter_point_lies_outside_the_sensing_region():
    p = SensorParams(clutter_rate=5.0, fov_half_angle=0.9, range_resolution=1e-6,
                     beamwidth=1e-9)           # near-noiseless, so measurements show the points
    table = radar_table([p])
    S = 400
    draws = DetectionDraws(table, run_streams(5), S)
    rng = np.random.default_rng(0)
    n = 0
    for t in range(1, S + 1):
        sxy = rng.uniform(0, 600, 2)
        heading = rng.uniform(-math.pi, math.pi)
        sets, false = draws.looks(t, np.array([False]), np.zeros((1, 2)), sxy[None],
                                  np.array([heading]), np.array([True]))
        Z = sets[0]
        assert len(Z) == false[0] <= draws.counts[t - 1, 0]
        if len(Z):
            g = np.sqrt(np.maximum(Z[:, 0] ** 2 - 500.0 ** 2, 0.0))
            xy = sxy + g[:, None] * np.column_stack([np.cos(Z[:, 1]), np.sin(Z[:, 1])])
            st = ref.stack_params([p])
            assert ref.visible(xy, sxy, heading, st).all()
            n += len(Z)
    assert n > 1000


def _track_and_sensor():
    mean = np.array([[300.0, 280.0, 2.0, -1.0]])
    cov = np.diag([400.0, 400.0, 4.0, 4.0])[None]
    sxy = np.array([[40.0, 100.0]])
    heading = np.array([math.atan2(180.0, 260.0)])
    return mean, cov, sxy, heading


def test_pda_without_clutter_and_with_pd_one_is_the_plain_update():
    mean, cov, sxy, heading = _track_and_sensor()
    rng = np.random.default_rng(3)
    st = ref.stack_params([SensorParams()])
    z = ref.measure(mean, sxy, st.altitude) + rng.normal(size=(1, 2)) * [2.0, 0.003]
    plain = KnownTargetTracker(mean, cov, 1.0, radar_table(SensorParams()), process_noise=0.05,
                    gate_probability=0.999)
    plain.update_detections(np.zeros(1, int), np.zeros(1, int), z, sxy, heading)
    # Clutter so thin that a detection is surely the target's, and Pd = 1: beta_1 -> 1.
    pda = KnownTargetTracker(mean, cov, 1.0, radar_table(SensorParams(clutter_rate=1e-12)),
                  process_noise=0.05, gate_probability=0.999)
    pda.update_sets(np.zeros(1, int), np.zeros(1, int), [z], sxy, heading)
    np.testing.assert_allclose(pda.means, plain.means, rtol=1e-12)
    np.testing.assert_allclose(pda.covs, plain.covs, rtol=1e-9, atol=1e-9)


def test_pda_weights_a_far_clutter_detection_down():
    mean, cov, sxy, heading = _track_and_sensor()
    st = ref.stack_params([SensorParams()])
    z = ref.measure(mean, sxy, st.altitude)
    far = z + np.array([[30.0, 0.0]])                 # a false alarm 30 m off, in the gate
    table = radar_table(SensorParams(clutter_rate=1.0))
    tr = KnownTargetTracker(mean, cov, 1.0, table, process_noise=0.05, gate_probability=0.999)
    res = tr.update_sets(np.zeros(1, int), np.zeros(1, int), [np.vstack([z, far])], sxy,
                         heading)
    assert res.used[0] == 2 and res.discarded[0] == 0
    # The estimate moves little toward the false alarm, and the covariance keeps the
    # association uncertainty (larger than a single-detection update's).
    single = KnownTargetTracker(mean, cov, 1.0, table, process_noise=0.05, gate_probability=0.999)
    single.update_sets(np.zeros(1, int), np.zeros(1, int), [z], sxy, heading)
    assert np.linalg.norm(tr.means[0, :2] - mean[0, :2]) < 10.0
    assert np.trace(tr.covs[0, :2, :2]) > np.trace(single.covs[0, :2, :2])
    np.linalg.cholesky(tr.covs[0])


def test_generalised_miss_update_with_pd_one_is_the_old_rule():
    """Ideal detection, no gate: the outputs of the code before the generalisation
    (tests/data/miss_update_golden.npz, written by commit 0c5d23e), to rtol 1e-12."""
    g = np.load(Path(__file__).parents[1] / "data" / "miss_update_golden.npz")
    table = radar_table([SensorParams(), SensorParams(altitude=490.0, fov_half_angle=0.4),
                         SensorParams(min_ground_range=200.0, max_ground_range=420.0)])
    m, P, infl = miss_update(g["means"], g["covs"], g["sxy"], g["heading"], table, g["sensor"])
    np.testing.assert_allclose(m, g["out_means"], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(P, g["out_covs"], rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(infl, g["inflated"])
    m1, P1, _ = miss_update(g["means"], g["covs"], g["sxy"], g["heading"], table, g["sensor"],
                            gate_probability=1.0)
    np.testing.assert_allclose(m1, g["out_means"], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(P1, g["out_covs"], rtol=1e-12, atol=1e-9)


def test_a_miss_with_pd_below_one_teaches_less():
    mean, cov, _, _ = _track_and_sensor()
    sxy, heading = mean[:, :2] - np.array([[440.0, 0.0]]), np.zeros(1)   # on the band's edge
    ideal = miss_update(mean, cov, sxy, heading, radar_table(SensorParams()), 0)
    weak = miss_update(mean, cov, sxy, heading, radar_table(RADAR), 0, gate_probability=0.999)
    # The track is in view: a miss moves it; with Pd < 1 it moves (and shrinks) it less.
    assert 0 < np.linalg.norm(weak[0] - mean) < np.linalg.norm(ideal[0] - mean)


# ------------------------------------------------------------------------------ planning


def test_the_clutter_factor_is_in_the_unit_interval_and_decreases_with_lambda():
    S = (400.0, 0.0, 1e-5)
    for pd in (0.2, 0.6, 1.0):
        qs = []
        for lam in (0.0, 0.1, 0.5, 1.0, 3.0, 10.0, 100.0):
            row = radar_table(SensorParams(clutter_rate=lam))[0]
            qs.append(radar.clutter_factor(row, pd, 600.0, *S))
        qs = np.array(qs)
        assert qs[0] == 1.0 and np.all((qs > 0) & (qs <= 1)) and np.all(np.diff(qs) < 0)


def test_aware_planning_with_ideal_detection_and_no_clutter_is_todays_potential(rng):
    from factories import make_problem, random_plan
    from sensorplan.planners.information import potential

    for _ in range(5):
        problem = make_problem(rng, n_sensors=2, n_targets=3, horizon=2)
        plan = random_plan(problem, rng)
        ignore = potential(dataclasses.replace(problem, planning_detection="ignore"), plan)
        aware = potential(dataclasses.replace(problem, planning_detection="aware"), plan)
        assert aware[0] == ignore[0]
        np.testing.assert_array_equal(aware[1], ignore[1])


def test_aware_planning_counts_pd_and_clutter(rng):
    from factories import make_problem, random_plan
    from sensorplan.planners.information import potential

    problem = make_problem(rng, n_sensors=2, n_targets=3, horizon=2,
                           sensor_kwargs=dict(detection="swerling1",
                                              false_alarm_probability=1e-4, clutter_rate=3.0))
    plan = random_plan(problem, rng)
    ignore = potential(dataclasses.replace(problem, planning_detection="ignore"), plan)[0]
    aware = potential(dataclasses.replace(problem, planning_detection="aware"), plan)[0]
    assert 0 < aware < ignore


def _irf_monte_carlo(pd: float, lam: float, rng: np.random.Generator, n: int) -> float:
    """The clutter factor from its definition (see scripts/irf_fit.py), independently."""
    g2 = stats.chi2.ppf(0.999, 2)
    free = 1.0 - (1.0 + g2 / 2.0) * math.exp(-g2 / 2.0)
    b = (1.0 - pd * 0.999) * lam / pd
    m = rng.poisson(lam * math.pi * g2, n)
    zt = rng.standard_normal((n, 2))
    det = (rng.random(n) < pd) & ((zt ** 2).sum(1) <= g2)
    total = 0.0
    for k in range(n):
        pts = np.sqrt(g2 * rng.random(m[k]))[:, None] * np.column_stack(
            [np.cos(a := rng.uniform(0, 2 * math.pi, m[k])), np.sin(a)])
        if det[k]:
            pts = np.vstack([pts, zt[k]])
        w = np.exp(-0.5 * (pts ** 2).sum(1)) / (2 * math.pi)
        s = (w[:, None] * pts).sum(0) / (b + w.sum())
        total += s @ s / 2.0
    return total / n / (pd * free)


@pytest.mark.parametrize("pd,lam", [(1.0, 0.01), (0.7, 0.1), (0.5, 1.0)])
def test_the_clutter_factor_matches_its_definition_within_the_documented_error(pd, lam):
    rng = np.random.default_rng(9)
    mc = _irf_monte_carlo(pd, lam, rng, 4000)
    # lam_w = rho sqrt(det S): choose S and the row so that lam_w equals lam exactly.
    row = radar_table(SensorParams(clutter_rate=1.0))[0]
    r = 600.0
    s = lam * row[AREA] / r               # rho sqrt(det S) = (1 * r / A) * s = lam
    got = radar.clutter_factor(row, pd, r, s, 0.0, s)
    assert got == pytest.approx(mc, rel=0.2)
