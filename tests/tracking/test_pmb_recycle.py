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
