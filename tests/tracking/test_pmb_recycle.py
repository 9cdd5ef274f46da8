"""Bernoulli recycling in the PMB tracker: a Bernoulli below ``recycle_threshold`` becomes
undetected intensity on the grid. Checked: the cell masses against scipy's bivariate
normal distribution function, the mass the grid gains (closed form), the deposit's moments
against the Bernoulli's (Sheppard's correction for grouping at the cell centres), a target
found again from its recycled intensity, the settings' refusals, and recycling off leaving
a run as it was."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from sensorplan.config import load_simulation
from sensorplan.errors import ConfigError
from sensorplan.models import linear
from sensorplan.simulation.run import run_episode
from sensorplan.simulation.settings import TrackerSettings
from sensorplan.tracking.base import Looks
from sensorplan.tracking.pmb import undetected
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker

P0 = np.diag([400.0, 400.0, 4.0, 4.0])


def one_scan(z: np.ndarray) -> Looks:
    """A scan of the linear sensor (its pose is not used)."""
    return Looks(sensors=np.zeros(1, dtype=np.int64), aims=np.full(1, -1, dtype=np.int64),
                 positions=np.zeros((1, 2)), headings=np.zeros(1),
                 detections=(np.asarray(z, dtype=float).reshape(-1, 2),))


def rectangle_masses(grid: undetected.Grid, m: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Each cell's mass of N(m, P) by inclusion-exclusion of scipy's bivariate normal
    distribution function at the cell corners, row-major."""
    xs = np.linspace(0.0, grid.width, grid.nx + 1)
    ys = np.linspace(0.0, grid.height, grid.ny + 1)
    corners = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    F = multivariate_normal.cdf(corners, m, P, abseps=1e-12, releps=1e-12)
    F = F.reshape(grid.ny + 1, grid.nx + 1)
    return (F[1:, 1:] - F[:-1, 1:] - F[1:, :-1] + F[:-1, :-1]).reshape(-1)


GRID = undetected.make_grid(600.0, 600.0, 25.0, 10.5)


@pytest.mark.parametrize(("m", "P"), [
    ([300.0, 280.0], [[1600.0, 900.0], [900.0, 900.0]]),       # wide, correlated
    ([12.0, 590.0], [[400.0, -100.0], [-100.0, 300.0]]),       # in a corner, half off
    ([200.0, 200.0], [[4.0, 3.9], [3.9, 4.0]]),                # narrow, nearly singular
    ([130.0, 460.0], [[90.0, 0.0], [0.0, 2500.0]])])
def test_cell_masses_equal_the_bivariate_normal_distribution_function(m, P) -> None:
    got = undetected.cell_masses(GRID, np.array([m]), np.array([P]))[0]
    np.testing.assert_allclose(got, rectangle_masses(GRID, np.array(m), np.array(P)),
                               rtol=0.0, atol=1e-6)


def test_axis_aligned_cell_masses_are_products_of_the_axes() -> None:
    m, sd = np.array([[137.0, 512.0]]), np.array([31.0, 9.0])
    got = undetected.cell_masses(GRID, m, np.diag(sd ** 2)[None])[0].reshape(24, 24)
    edges = np.linspace(0.0, 600.0, 25)
    px = np.diff(norm.cdf(edges, m[0, 0], sd[0]))
    py = np.diff(norm.cdf(edges, m[0, 1], sd[1]))
    np.testing.assert_allclose(got, np.outer(py, px), rtol=0.0, atol=1e-15)


def test_the_deposit_sums_to_r_and_keeps_the_bernoullis_moments() -> None:
    r = np.array([0.07, 0.02])
    m = np.array([[300.0, 280.0], [380.0, 330.0]])   # 6 sd and more inside the map
    P = np.array([[[1600.0, 900.0], [900.0, 900.0]], [[700.0, -300.0], [-300.0, 1100.0]]])
    w = undetected.recycle(GRID, r, m, P)
    assert abs(w.sum() - r.sum()) <= 1e-15
    parts = [undetected.recycle(GRID, r[k:k + 1], m[k:k + 1], P[k:k + 1]) for k in range(2)]
    np.testing.assert_allclose(parts[0] + parts[1], w, rtol=0.0, atol=1e-18)
    # The deposit is sum_c w_c N([p_c, 0], P_u). Grouped at the centres, a Gaussian's mean
    # is kept and its variance grows by a^2 / 12 per axis (Sheppard); the cells' own P_u
    # adds a^2 / 12 again. Both exact to about exp(-2 pi^2 sigma^2 / a^2) < 1e-12 here;
    # what remains is the column quadrature of correlated Gaussians (about 1e-6 relative).
    a = 25.0
    for k in range(2):
        wk = parts[k]
        assert abs(wk.sum() - r[k]) <= 1e-15
        mean = wk @ GRID.centres / r[k]
        d = GRID.centres - mean
        cov = (wk[:, None, None] * d[:, :, None] * d[:, None, :]).sum(0) / r[k] + GRID.cov[:2, :2]
        np.testing.assert_allclose(mean, m[k], rtol=0.0, atol=1e-6)
        np.testing.assert_allclose(cov, P[k] + np.eye(2) * a * a / 6.0, rtol=0.0, atol=1e-3)


def test_a_gaussian_with_no_mass_on_the_map_goes_to_the_nearest_cell() -> None:
    w = undetected.recycle(GRID, np.array([0.05]), np.array([[-5000.0, 130.0]]),
                           np.array([np.eye(2)]))
    assert w.sum() == 0.05 and w[5 * 24 + 0] == 0.05


# Tight Gaussians just off the map whose computed mass on it is subnormal: dividing r by
# it overflowed. The first is a track the search preset recycled at 21 dB (below the map's
# bottom edge, 14 sd out: its mass there cancels to nothing); the second lies past a corner
# (about 37 sd right and 8.5 sd above: a product of two tails).
SUBNORMAL = [([536.160699634646, -12.996275743153298],
              [[9.014579544805946, -0.4686027770657998], [-0.4686027770657998, 0.836482557300719]],
              0 * 24 + 21),
             ([618.5, 604.25], [[0.25, 0.0], [0.0, 0.25]], 23 * 24 + 23)]


@pytest.mark.parametrize(("mean", "cov", "cell"), SUBNORMAL)
def test_a_gaussian_whose_mass_on_the_map_is_subnormal_goes_to_the_nearest_cell(
        mean, cov, cell) -> None:
    m, P = np.array([mean]), np.array([cov])
    on_map = undetected.cell_masses(GRID, m, P).sum()
    assert 0.0 < on_map < np.finfo(float).tiny
    w = undetected.recycle(GRID, np.array([0.05]), m, P)
    assert np.all(np.isfinite(w)) and w.sum() == 0.05 and w[cell] == 0.05


@pytest.mark.parametrize("map_edge", [None, "exit", "closed"])
def test_recycling_conserves_the_expected_number_of_targets(map_edge) -> None:
    # Existences after the predict's survival 0.8: 0.04, 0.0008 (below the pruning
    # threshold: recycled too), 0.24, 0.072 (its density mostly off the map), 0.8.
    r = np.array([0.05, 0.001, 0.3, 0.09, 1.0])
    means = np.array([[100.0, 100.0, 1.0, 0.0], [200.0, 50.0, 0.0, 0.0],
                      [150.0, 150.0, 0.0, 0.0], [298.0, 150.0, 3.0, 0.0],
                      [60.0, 240.0, 0.0, -1.0]])
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    model = MapModel(sensor, 1.0, (300.0, 300.0), velocity_var=2.0, map_edge=map_edge)
    births = undetected.birth_intensity(model.grid(), "edges", 0.05)
    on = PMBTracker(model, means=means, covs=P0, existence=r, survival_probability=0.8,
                    births="edges", birth_rate=0.05, initial_undetected=2.0,
                    recycle_threshold=0.1)
    off = PMBTracker(model, means=means, covs=P0, existence=r, survival_probability=0.8,
                     births="edges", birth_rate=0.05, initial_undetected=2.0,
                     prune_threshold=0.0)
    on.predict()
    off.predict()
    # What the predict left of each Bernoulli (the edge's truncation included), from the
    # tracker that neither prunes nor recycles.
    assert off.bern.labels.tolist() == [0, 1, 2, 3, 4]
    r_pred = off.bern.r
    expected_recycled = r_pred[[0, 1, 3]].sum()
    assert on.bern.labels.tolist() == [2, 4]
    np.testing.assert_array_equal(on.bern.r, r_pred[[2, 4]])
    np.testing.assert_array_equal(on.bern.means, off.bern.means[[2, 4]])
    base = 0.8 * 2.0 + births.sum()
    assert abs(off.undetected.sum() - base) <= 1e-12
    assert abs(on.undetected.sum() - (base + expected_recycled)) <= 1e-12
    assert on.recycled == 3 and abs(on.recycled_mass - expected_recycled) <= 1e-15
    # The expected number of targets, Bernoullis plus intensity, is what survival and the
    # map's edge leave.
    assert abs(on.undetected.sum() + on.bern.r.sum()
               - (off.undetected.sum() + off.bern.r.sum())) <= 1e-12


def test_a_recycled_target_is_found_again_where_it_went() -> None:
    # A target known at the start (existence 0.9) walks at 5 m/s; two scans miss it, which
    # leaves r = 0.9 -> 0.47 -> 0.08 (the missed-scan formula), below 0.1. Recycled, its
    # intensity sits where its track had predicted it; the third scan detects it there (and
    # two false alarms far away). Pruned at the same threshold it leaves nothing, and the
    # detection is taken for clutter. No intensity anywhere else: no births, none at the
    # start.
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    model = MapModel(sensor, 1.0, (300.0, 300.0), velocity_var=2.0, process_noise=0.05)
    start = np.array([[100.0, 150.0, 5.0, 0.0]])
    cov = np.diag([25.0, 25.0, 1.0, 1.0])
    on = PMBTracker(model, means=start, covs=cov, existence=0.9, prune_threshold=0.1,
                    recycle_threshold=0.1)
    off = PMBTracker(model, means=start, covs=cov, existence=0.9, prune_threshold=0.1)
    clutter = np.array([[20.0, 20.0], [280.0, 270.0]])
    for tr in (on, off):
        for _ in range(2):
            tr.predict()
            tr.update(one_scan(np.zeros((0, 2))))
        assert len(tr.bern) == 0
    assert on.recycled == 1 and off.recycled == 0
    r2 = 0.9
    for _ in range(2):
        r2 = 0.99 * r2
        r2 = r2 * 0.1 / (1.0 - 0.9 * r2)
    # Recycled after the second scan's thinning: all of it, where the track had it.
    assert abs(on.undetected.sum() - r2) <= 1e-12
    centre = on.undetected @ on.grid.centres / on.undetected.sum()
    # (the track's sd of about 6 m is narrower than a 25 m cell: grouped at the centres,
    # its mean is kept to within half a cell)
    assert np.hypot(*(centre - (start[0, :2] + 2 * np.array([5.0, 0.0])))) < 12.5
    assert off.undetected.sum() == 0.0
    # The third scan detects it: from the recycled intensity a Bernoulli starts there (the
    # pruned tracker has no intensity, so the detection is clutter); the fourth confirms it.
    for k, (noise, started) in enumerate((([0.4, -0.3], 0.1), ([-0.5, 0.2], 0.5))):
        truth = start[0, :2] + (3 + k) * np.array([5.0, 0.0])
        for tr in (on, off):
            tr.predict()
            tr.update(one_scan(np.vstack([truth + noise, clutter])))
        assert len(off.bern) == 0 and len(off.tracks()) == 0
        assert on.bern.labels.tolist() == [1]                  # a new label
        assert on.bern.r[0] > started
        assert np.hypot(*(on.bern.means[0, :2] - truth)) < 3.0
    assert on.tracks().labels.tolist() == [1]


@pytest.mark.parametrize(("kw", "needle"), [
    (dict(recycle_threshold=1.0), "recycle_threshold"),
    (dict(recycle_threshold=-0.1), "recycle_threshold"),
    (dict(recycle_threshold=1e-4), "recycle_threshold"),       # below prune_threshold
    (dict(recycle_threshold=0.5), "recycle_threshold")])       # at report_threshold
def test_inconsistent_recycle_thresholds_are_refused(kw, needle) -> None:
    with pytest.raises(ValueError, match=needle):
        PMBTracker(MapModel(linear.williams15(), 1.0, (300.0, 300.0)), **kw)
    with pytest.raises(ConfigError, match=needle):
        TrackerSettings(kind="pmb", **kw)


def test_naming_the_presets_recycling_leaves_a_run_as_it_was_and_off_changes_it() -> None:
    """The search preset recycles at 0.1: naming that value leaves a run bit for bit as it
    was; recycling off changes it (a faded track's existence no longer feeds the grid)."""
    cfg = load_simulation(preset="search", overrides={"steps": 30, "seed": 4})
    base = run_episode(cfg.scenario, cfg.settings, cfg.seed)
    tr = cfg.settings.tracker
    assert tr.recycle_threshold == 0.1
    on = dataclasses.replace(cfg.settings, tracker=dataclasses.replace(tr, recycle_threshold=0.1))
    off = dataclasses.replace(cfg.settings, tracker=dataclasses.replace(tr, recycle_threshold=0.0))
    same = run_episode(cfg.scenario, on, cfg.seed)
    other = run_episode(cfg.scenario, off, cfg.seed)
    for f in dataclasses.fields(base):
        if f.name not in ("planning_seconds", "settings"):
            a, b = getattr(base, f.name), getattr(same, f.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b, err_msg=f.name)
            else:
                assert a == b, f.name
    assert base.undetected is not None and other.undetected is not None
    assert not np.array_equal(base.undetected, other.undetected)


# ------------------------------------------------------------------ moving recycled components
def faded(motion: str, q: float = 0.05, world: float = 300.0, **kw) -> PMBTracker:
    """A tracker whose one Bernoulli (existence 0.05, walking at 5 m/s) is recycled at its
    first predict."""
    sensor = linear.LinearSensor((0.0, 0.0, world, world), 1.0, 0.9, 10.0)
    model = MapModel(sensor, 1.0, (world, world), velocity_var=2.0, process_noise=q)
    return PMBTracker(model, means=np.array([[100.0, 150.0, 5.0, 0.0]]),
                      covs=np.diag([25.0, 25.0, 1.0, 1.0]), existence=0.05,
                      recycle_threshold=0.1, recycle_motion=motion, **kw)


def test_a_moving_component_predicts_as_a_kalman_filter_and_survives() -> None:
    from sensorplan.models.motion import cv_matrices

    tr = faded("moving")
    F, Q = cv_matrices(1.0, 0.05)
    m, P, w = np.array([100.0, 150.0, 5.0, 0.0]), np.diag([25.0, 25.0, 1.0, 1.0]), 0.05
    for _ in range(4):
        tr.predict()
        m, P, w = F @ m, F @ P @ F.T + Q, 0.99 * w
        assert len(tr.bern) == 0 and tr.undetected.sum() == 0.0
        np.testing.assert_allclose(tr.moving_weights, [w], rtol=1e-14)
        np.testing.assert_allclose(tr.moving_means[0], m, rtol=1e-14)
        np.testing.assert_allclose(tr.moving_covs[0], P, rtol=1e-12, atol=1e-12)
    assert tr.recycled == 1


def test_a_missed_look_thins_a_moving_component_by_its_detection_probability() -> None:
    # The linear sensor sees the whole map with Pd 0.9: Pbar = 0.9 and the missed density is
    # the prior.
    tr = faded("moving")
    tr.predict()
    w, m, P = tr.moving_weights.copy(), tr.moving_means.copy(), tr.moving_covs.copy()
    tr.update(one_scan(np.zeros((0, 2))))
    np.testing.assert_allclose(tr.moving_weights, 0.1 * w, rtol=1e-12)
    np.testing.assert_allclose(tr.moving_means, m, rtol=1e-12)
    np.testing.assert_allclose(tr.moving_covs, P, rtol=1e-9, atol=1e-9)


def test_static_and_moving_recycling_keep_the_same_expected_number_of_targets() -> None:
    static, moving = faded("static"), faded("moving")
    for _ in range(5):
        static.predict()
        moving.predict()
        a = static.undetected_cells().sum() + static.bern.r.sum()
        b = moving.undetected_cells().sum() + moving.bern.r.sum()
        assert abs(a - b) <= 1e-15
        # The report planning reads is the cells with the components added.
        np.testing.assert_array_equal(moving.undetected_intensity().weights,
                                      moving.undetected_cells())


def test_a_component_spread_over_more_than_a_cell_goes_to_the_cells() -> None:
    # With q = 20 the position spread passes the 25 m cell within a few steps; its weight
    # then sits on the grid, the total kept.
    tr = faded("moving", q=20.0)
    for _ in range(12):
        tr.predict()
    assert tr.moving_weights.size == 0
    assert abs(tr.undetected.sum() - 0.05 * 0.99 ** 12) <= 1e-15


def test_a_moving_component_finds_the_target_where_it_went_and_a_static_one_does_not() -> None:
    # Recycled at the first predict at x = 105, the target walks on at 5 m/s; at step 8 it
    # is 35 m past where static recycling left its mass (more than a cell), and a detection
    # there starts a Bernoulli from the moving component with its velocity.
    # Its existence is the new-target closed form lambda / (lambda + kappa), lambda = w Pd
    # N(z; m, P + R) of the component alone (kappa: 10 false alarms over the map).
    static, moving = faded("static"), faded("moving")
    for tr in (static, moving):
        for _ in range(8):
            tr.predict()
    w, m, P = moving.moving_weights[0], moving.moving_means[0], moving.moving_covs[0]
    z = np.array([100.0, 150.0]) + 8 * np.array([5.0, 0.0]) + [0.3, -0.2]
    for tr in (static, moving):
        tr.update(one_scan(z[None]))
    lam = w * 0.9 * multivariate_normal.pdf(z, m[:2], P[:2, :2] + np.eye(2))
    kappa = 10.0 / 300.0 ** 2
    assert moving.bern.labels.tolist() == [1]
    assert abs(moving.bern.r[0] - lam / (lam + kappa)) <= 1e-12
    assert abs(moving.bern.means[0, 2] - 5.0) < 1.0             # the component's velocity
    np.testing.assert_allclose(moving.moving_weights, [0.1 * w], rtol=1e-12)
    # Static: the mass left 35 m behind gives the detection a new-target existence below
    # the pruning threshold, so no Bernoulli starts.
    assert len(static.bern) == 0


@pytest.mark.parametrize(("kw", "needle"), [
    (dict(recycle_motion="drifting", recycle_threshold=0.1), "recycle_motion"),
    (dict(recycle_motion="moving"), "recycle_motion"),
    (dict(recycle_motion="moving", recycle_threshold=0.1, mode_process_noise=(1.0, 5.0),
          switching=np.array([[0.9, 0.1], [0.1, 0.9]])), "recycle_motion")])
def test_moving_recycling_needs_recycling_and_one_motion_model(kw, needle) -> None:
    with pytest.raises(ValueError, match=needle):
        PMBTracker(MapModel(linear.williams15(), 1.0, (300.0, 300.0)), **kw)


def test_the_settings_name_the_trackers_recycle_motions_and_refuse_moving_alone() -> None:
    from sensorplan.simulation import settings as settings_module
    from sensorplan.tracking.pmb import tracker as tracker_module

    assert settings_module.RECYCLE_MOTIONS == tracker_module.RECYCLE_MOTIONS
    with pytest.raises(ConfigError, match="recycle_motion"):
        TrackerSettings(kind="pmb", recycle_motion="moving")
    with pytest.raises(ConfigError, match="recycle_motion"):
        TrackerSettings(kind="pmb", recycle_motion="moving", recycle_threshold=0.1,
                        bernoulli_model="imm")


def test_a_closed_loop_with_moving_recycling_repeats_and_records_where_they_went() -> None:
    # The run of the test above that recycles; with moving components the recorded
    # intensity (cells plus components) differs from the static one's, and repeats.
    # Moving components need one Gaussian per Bernoulli (the preset keeps two).
    cfg = load_simulation(preset="search", overrides={"steps": 30, "seed": 4})
    one = dataclasses.replace(cfg.settings.tracker, density_components=1)
    tr = dataclasses.replace(one, recycle_motion="moving")
    settings = dataclasses.replace(cfg.settings, tracker=tr)
    a = run_episode(cfg.scenario, settings, cfg.seed)
    b = run_episode(cfg.scenario, settings, cfg.seed)
    static = run_episode(cfg.scenario, dataclasses.replace(cfg.settings, tracker=one),
                         cfg.seed)
    assert a.undetected is not None and static.undetected is not None
    np.testing.assert_array_equal(a.undetected, b.undetected)
    assert not np.array_equal(a.undetected, static.undetected)
