"""The lost-target mode: a track that has lost its target becomes a density on a grid.

The references are independent: Monte Carlo samples of the continuous posterior (the
sensing region re-implemented here from its definition), closed forms of a random walk
and of a mixture's moments, and the tracker with the mode off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models.radar import measure_looks
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.known_map import map_reflection
from sensorplan.tracking.lost import (diffuse, detect_probability, initial_weights,
                                      make_lost_grid, miss, moments, reacquire, replay,
                                      step_variance, velocity_variance, MissLog)
from sensorplan.tracking.missed import miss_update
from sensorplan.tracking.tracker import KnownTargetTracker

PARAMS = SensorParams()
TABLE = radar_table((PARAMS,))
#: A sensor south of the map's centre looking north: its range band (250-450 m) and wedge
#: (+-30 degrees) cover part of a track at (300, 300).
SENSOR = np.array([300.0, -20.0])
HEADING = math.pi / 2 + 0.5


def in_view(xy: np.ndarray, sensor: np.ndarray = SENSOR, heading: float = HEADING
            ) -> np.ndarray:
    """The sensing region from its definition: range band and azimuth wedge on the ground."""
    d = xy - sensor
    g = np.hypot(d[:, 0], d[:, 1])
    off = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - heading)))
    return ((g >= PARAMS.min_ground_range) & (g <= PARAMS.max_ground_range)
            & (np.abs(off) <= PARAMS.fov_half_angle))


def grid(resolution: float = 5.0, buildings: np.ndarray | None = None):
    return make_lost_grid(600.0, 600.0, resolution, 10.5, 1.0, buildings)


def test_velocity_variance_is_the_uniform_speed_and_heading_second_moment():
    rng = np.random.default_rng(3)
    s = rng.uniform(3.0, 6.0, 400_000)
    vx = s * np.cos(rng.uniform(-np.pi, np.pi, s.size))
    assert abs(velocity_variance((3.0, 6.0)) - 10.5) == 0.0
    assert abs(np.mean(vx ** 2) - 10.5) < 0.05


def test_diffusion_keeps_the_weight_and_spreads_by_the_requested_variance():
    """Far from every wall a unit mass spreads with exactly the requested variance per
    axis and no covariance (each pass of the three-point kernel adds 2 kappa cells^2)."""
    lg = grid(10.0)
    w = np.zeros(lg.size)
    w[30 * lg.grid.nx + 30] = 1.0                       # the cell at (305, 305)
    for v in (3.0, 10.5, 210.0, 1000.0):
        out = diffuse(lg, w, v)
        assert abs(out.sum() - 1.0) < 1e-12
        assert out.min() >= 0.0
        mean, cov = moments(lg, out)
        np.testing.assert_allclose(mean[:2], [305.0, 305.0], atol=1e-9)
        cell = 100.0 / 12.0
        np.testing.assert_allclose(cov[:2, :2], np.diag([v + cell, v + cell]), rtol=1e-9,
                                   atol=1e-9)


def test_diffusion_never_crosses_a_wall():
    """A building's cells stay empty, and the mass next to the map's wall stays on the map
    (the walk is reflected), so the total is kept."""
    tower = np.array([[270.0, 270.0, 330.0, 330.0, 150.0]])
    lg = grid(10.0, tower)
    assert (~lg.free).sum() == 36                        # the 60 m block: 6 x 6 cells
    w = initial_weights(lg, np.array([300.0, 250.0, 0, 0]), np.diag([400.0, 400, 1, 1]))
    assert w[~lg.free].max() == 0.0
    for n in range(1, 30):
        w = diffuse(lg, w, step_variance(lg, n))
    assert w[~lg.free].max() == 0.0
    assert abs(w.sum() - 1.0) < 1e-12
    edge = np.zeros(lg.size)
    edge[0] = 1.0
    assert abs(diffuse(lg, edge, 500.0).sum() - 1.0) < 1e-12


def test_step_variance_adds_up_to_a_constant_unknown_velocity():
    """n steps of the increments add to n^2 sigma_v^2 dt^2: where a target with unknown
    constant velocity is after n steps."""
    lg = grid(10.0)
    for n in (1, 5, 40):
        total = sum(step_variance(lg, k) for k in range(1, n + 1))
        assert abs(total - n * n * 10.5) < 1e-9


def test_a_missed_look_thins_the_grid_as_bayes_rule_does_on_samples():
    """The grid after a miss against a Monte Carlo of the continuous posterior: samples of
    the prior, those in the sensing region dropped (with P_G = 1), moments of the rest; and
    the grid's probability of the miss against the share of samples kept."""
    lg = grid(5.0)
    m = np.array([300.0, 300.0, 0.0, 0.0])
    P = np.diag([60.0 ** 2, 50.0 ** 2, 1.0, 1.0])
    P[0, 1] = P[1, 0] = 900.0
    w0 = initial_weights(lg, m, P)
    det = detect_probability(lg, TABLE, 0, SENSOR, HEADING, None, 1.0)
    w, p_miss = miss(lg, w0, det)
    mean, cov = moments(lg, w)
    rng = np.random.default_rng(11)
    # The grid's prior is the track smoothed by a cell: sample that density.
    C = P[:2, :2] + np.diag([25.0 / 12, 25.0 / 12])
    xy = rng.multivariate_normal(m[:2], C, size=400_000)
    keep = ~in_view(xy)
    assert 0.3 < keep.mean() < 0.9                      # the look covers a good part
    assert abs(p_miss - keep.mean()) < 0.01
    ref_m = xy[keep].mean(axis=0)
    ref_c = np.cov(xy[keep].T)
    np.testing.assert_allclose(mean[:2], ref_m, atol=1.5)
    np.testing.assert_allclose(cov[:2, :2], ref_c, rtol=0.03, atol=40.0)


def test_a_miss_with_a_gate_keeps_a_thousandth_inside():
    lg = grid(10.0)
    w0 = np.full(lg.size, 1.0 / lg.size)
    det = detect_probability(lg, TABLE, 0, SENSOR, HEADING, None, 0.999)
    w, p = miss(lg, w0, det)
    inside = det > 0
    assert inside.any()
    np.testing.assert_allclose(w[inside] / w[~inside][0], 0.001, rtol=1e-12)
    assert abs(p - (1.0 - 0.999 * inside.mean())) < 1e-12


def test_a_building_hides_its_shadow_from_the_thinning():
    """A cell hidden behind a tall building from the sensor keeps its weight."""
    tower = np.array([[270.0, 270.0, 330.0, 330.0, 150.0]])
    lg = grid(10.0, tower)
    det = detect_probability(lg, TABLE, 0, np.array([300.0, -50.0]), math.pi / 2, tower, 1.0)
    bare = detect_probability(lg, TABLE, 0, np.array([300.0, -50.0]), math.pi / 2, None, 1.0)
    behind = bare.astype(bool) & ~det.astype(bool)
    assert behind.sum() > 5
    c = lg.grid.centres[behind]
    assert np.all(c[:, 1] > 270.0)                     # the shadow lies behind the tower


def test_moments_of_two_cells():
    lg = grid(10.0)
    w = np.zeros(lg.size)
    w[0], w[lg.grid.nx + 2] = 0.25, 0.75                # (5, 5) and (25, 15)
    mean, cov = moments(lg, w)
    np.testing.assert_allclose(mean, [20.0, 12.5, 0.0, 0.0], atol=1e-12)
    d = np.array([[-15.0, -7.5], [5.0, 2.5]])
    ref = 0.25 * np.outer(d[0], d[0]) + 0.75 * np.outer(d[1], d[1]) + np.eye(2) * 100 / 12
    np.testing.assert_allclose(cov[:2, :2], ref, atol=1e-9)
    np.testing.assert_allclose(cov[2:, 2:], np.eye(2) * 10.5, atol=1e-12)
    assert np.all(cov[:2, 2:] == 0.0)


def test_reacquisition_is_the_grid_posterior_given_the_detection():
    """Importance Monte Carlo: samples of the grid's mixture weighted by the exact
    likelihood of the detection; the posterior's moments against the re-initialised
    Gaussian."""
    lg = grid(10.0)
    w = initial_weights(lg, np.array([300.0, 330.0, 0, 0]), np.diag([60.0 ** 2, 60.0 ** 2,
                                                                       1, 1]))
    w, _ = miss(lg, w, detect_probability(lg, TABLE, 0, SENSOR, HEADING, None, 0.999))
    truth = np.array([[330.0, 350.0]])
    h, _, var, _ = measure_looks(TABLE, np.zeros(1, dtype=np.int64), truth, SENSOR[None],
                                 np.array([HEADING + 0.7]))
    z = h[0]
    got = reacquire(lg, w, z, SENSOR, HEADING + 0.7, TABLE, 0, 13.8155)
    assert got is not None
    mean, cov = got
    rng = np.random.default_rng(5)
    n = 400_000
    means, _ = lg.grid.cell_states()
    c = rng.choice(lg.size, size=n, p=w)
    x = means[c] + rng.standard_normal((n, 4)) * np.sqrt(np.diag(lg.grid.cov))
    hs, _, vs, _ = measure_looks(TABLE, np.zeros(n, dtype=np.int64), x[:, :2],
                                 np.broadcast_to(SENSOR, (n, 2)), np.full(n, HEADING + 0.7))
    nu = z - hs
    nu[:, 1] = np.angle(np.exp(1j * nu[:, 1]))
    lw = -0.5 * (nu ** 2 / vs).sum(axis=1) - 0.5 * np.log(vs).sum(axis=1)
    pw = np.exp(lw - lw.max())
    pw /= pw.sum()
    ref_m = pw @ x
    d = x - ref_m
    ref_c = (pw[:, None] * d).T @ d
    np.testing.assert_allclose(mean[:2], ref_m[:2], atol=0.3)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)[:2]), np.sqrt(np.diag(ref_c)[:2]),
                               rtol=0.1)
    np.testing.assert_allclose(mean[2:], [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(np.diag(cov)[2:], [10.5, 10.5], rtol=1e-9)


def test_reacquisition_with_no_cell_in_the_gate_is_none():
    lg = grid(10.0)
    w = np.zeros(lg.size)
    w[0] = 1.0                                          # surely at (5, 5)
    h, _, _, _ = measure_looks(TABLE, np.zeros(1, dtype=np.int64), np.array([[300.0, 350.0]]),
                               SENSOR[None], np.array([HEADING]))
    assert reacquire(lg, w, h[0], SENSOR, HEADING, TABLE, 0, 13.8155) is None


def test_replay_applies_each_step_then_its_misses():
    lg = grid(10.0)
    m = np.array([300.0, 300.0, 1.0, 0.0])
    P = np.diag([400.0, 400.0, 4.0, 4.0])
    log = MissLog.empty()
    log.add(2, 0, SENSOR, HEADING)
    log.add(2, 0, SENSOR, HEADING - 0.3)
    log.add(3, 0, SENSOR, HEADING + 0.3)
    got = replay(lg, m, P, 4, log, TABLE, None, 0.999)
    w = initial_weights(lg, m, P)
    for n, looks in ((1, ()), (2, (HEADING, HEADING - 0.3)), (3, (HEADING + 0.3,)), (4, ())):
        w = diffuse(lg, w, step_variance(lg, n))
        for hd in looks:
            w, _ = miss(lg, w, detect_probability(lg, TABLE, 0, SENSOR, hd, None, 0.999))
    np.testing.assert_array_equal(got, w)


# ---------------------------------------------------------------- in the tracker


def _tracker(lost: bool, probability: float = 0.01, **kw):
    m = np.array([[300.0, 300.0, 0.0, 0.0], [100.0, 500.0, 1.0, 0.0]])
    P = np.diag([400.0, 400.0, 4.0, 4.0])
    return KnownTargetTracker(m, P, 1.0, TABLE, process_noise=0.05, world=(600.0, 600.0),
                              gate_probability=0.999, reacquire=True, miss_update=miss_update,
                              lost_grid=grid(10.0) if lost else None,
                              lost_probability=probability, **kw)


def _miss_look(t: KnownTargetTracker, heading: float):
    from sensorplan.tracking.base import Looks

    return Looks(np.array([0]), np.array([0]), SENSOR[None], np.array([heading]),
                 (np.zeros((0, 2)),))


def test_runs_of_misses_make_a_track_lost_and_its_report_is_the_grid():
    t = _tracker(True)
    for k in range(12):
        t.predict()
        t.update(_miss_look(t, HEADING + 0.15 * math.sin(k)))
        if t.lost[0]:
            break
    assert t.lost[0] and not t.lost[1]
    assert t.log_run[0] < math.log(0.01)
    mean, cov = moments(t.lost_grid, t.lost_weights[0])
    np.testing.assert_array_equal(t.means[0], mean)
    np.testing.assert_array_equal(t.covs[0], cov)
    # the grid is the replay of every look since the start
    ref = replay(t.lost_grid, np.array([300.0, 300.0, 0, 0]), np.diag([400.0, 400, 4, 4]),
                 int(t.since[0]), t.miss_logs[0], TABLE, None, 0.999)
    np.testing.assert_allclose(t.lost_weights[0], ref, atol=1e-15)
    # a detection re-acquires it near the target
    from sensorplan.tracking.base import Looks

    t.predict()
    truth = np.array([[300.0, 330.0]])
    h, _, _, _ = measure_looks(TABLE, np.zeros(1, dtype=np.int64), truth,
                               np.array([[300.0, -150.0]]), np.array([math.pi / 2]))
    rec = t.update(Looks(np.array([0]), np.array([0]), np.array([[300.0, -150.0]]),
                         np.array([math.pi / 2]), (h,)))
    assert not t.lost[0] and rec.restarted[0] and rec.used[0] == 1
    assert np.hypot(*(t.means[0, :2] - truth[0])) < 5.0
    assert t.since[0] == 0 and t.log_run[0] == 0.0 and not t.miss_logs[0].steps


def test_a_mode_that_never_triggers_changes_nothing():
    """With a threshold no run of misses reaches, the tracks are the mode-off tracks bit
    for bit (the IMM too)."""
    imm = dict(mode_process_noise=(0.05, 5.0), switching=np.array([[0.95, 0.05],
                                                                    [0.1, 0.9]]))
    for kw in ({}, imm):
        a, b = _tracker(True, 1e-300, **kw), _tracker(False, **kw)
        for k in range(8):
            for t in (a, b):
                t.predict()
                t.update(_miss_look(t, HEADING + 0.2 * k))
            np.testing.assert_array_equal(a.means, b.means)
            np.testing.assert_array_equal(a.covs, b.covs)
        assert not a.lost.any()


def test_the_mode_records_what_the_missed_looks_did_as_the_mode_off_does():
    """The update's record (negative updates, inflations) is the mode-off record while no
    track is lost: a look that covers nearly all of a track inflates it in both."""
    a, b = _tracker(True, 1e-300), _tracker(False)
    for t in (a, b):
        t.predict()
    ra, rb = a.update(_miss_look(a, math.pi / 2)), b.update(_miss_look(b, math.pi / 2))
    assert rb.inflated[0]
    np.testing.assert_array_equal(ra.negative, rb.negative)
    np.testing.assert_array_equal(ra.inflated, rb.inflated)


def test_the_mode_refuses_imperfect_detection():
    table = radar_table((SensorParams(clutter_rate=1.0),))
    with pytest.raises(ValueError, match="ideal detection"):
        KnownTargetTracker(np.zeros((1, 4)) + 300.0, np.eye(4), 1.0, table,
                           process_noise=0.05, miss_update=miss_update,
                           lost_grid=grid(10.0))


# ---------------------------------------------------------------- reflected walls


def test_a_reflected_track_is_not_truncated_at_the_wall_again():
    """With ``reflect_walls`` the predicted track is the reflected density's moments
    (:func:`map_reflection`): truncating its Gaussian at the wall afterwards would count
    the wall twice (mean pushed in, variance cut)."""
    m = np.array([[599.0, 300.0, 4.0, 0.0]])
    P = np.diag([25.0, 25.0, 1.0, 1.0])[None]
    t = KnownTargetTracker(m, P, 1.0, TABLE, process_noise=0.05, world=(600.0, 600.0),
                           reflect_walls=True)
    F = t.F
    Pp = F @ P[0] @ F.T + t.Q
    ref_m, ref_P, applied = map_reflection((m[0] @ F.T)[None], (0.5 * (Pp + Pp.T))[None],
                                           600.0, 600.0)
    assert applied[0]
    t.predict()
    np.testing.assert_allclose(t.means, ref_m, atol=1e-12)
    np.testing.assert_allclose(t.covs, ref_P, atol=1e-12)
