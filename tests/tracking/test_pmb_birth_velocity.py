"""The PMB's inward velocity prior for targets first seen on the map's boundary: the
cells' moments against the truth's own edge-birth sampler, and what it changes for a
target entering at an edge."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models import linear
from sensorplan.models.population import edge_births
from sensorplan.tracking.pmb import undetected
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker
from looks_helpers import looks_of


def test_the_cells_priors_are_the_moments_of_the_truths_edge_births() -> None:
    """Births drawn by the truth's sampler (positions on the perimeter, inward headings,
    uniform speeds) binned into the cells of a map with non-square cells: each boundary
    cell's sample mean and covariance of the velocity match its prior within sampling
    error (four standard errors), corners included."""
    W, H, speeds = 100.0, 60.0, (3.0, 6.0)
    grid = undetected.make_grid(W, H, 25.0, 10.5)              # 4 x 3 cells of 25 x 20 m
    mean, cov = undetected.cell_velocities(grid, speeds)
    x = edge_births(400_000, np.random.default_rng(4), (W, H), speeds)
    col = np.minimum((x[:, 0] / (W / grid.nx)).astype(int), grid.nx - 1)
    row = np.minimum((x[:, 1] / (H / grid.ny)).astype(int), grid.ny - 1)
    cell = row * grid.nx + col
    checked = 0
    for c in np.unique(cell):
        v = x[cell == c, 2:]
        n = len(v)
        se_mean = np.sqrt(np.diag(np.cov(v.T)) / n)
        np.testing.assert_array_less(np.abs(v.mean(axis=0) - mean[c]), 4 * se_mean)
        sample = np.cov(v.T)
        # The standard error of a second moment is about its scale times sqrt(2 / n).
        np.testing.assert_allclose(sample, cov[c], rtol=0, atol=4 * 12.0 * math.sqrt(2 / n))
        checked += 1
    assert checked == 10                       # every boundary cell of the 4 x 3 grid
    inside = np.setdiff1d(np.arange(grid.size), np.unique(cell))
    np.testing.assert_array_equal(mean[inside], 0.0)
    np.testing.assert_array_equal(cov[inside], np.broadcast_to(10.5 * np.eye(2),
                                                               (len(inside), 2, 2)))


def entering(birth_velocity: str) -> PMBTracker:
    """A tracker of a map with an exit edge that has just seen a target at the bottom
    edge, moving inward (its first detection)."""
    sensor = linear.LinearSensor((0.0, 0.0, 600.0, 600.0), 1.0, 0.9, 1.0)
    model = MapModel(sensor, 1.0, (600.0, 600.0), velocity_var=10.5, speed_range=(3.0, 6.0),
                     map_edge="exit")
    tr = PMBTracker(model, births="edges", birth_rate=0.5, birth_velocity=birth_velocity)
    tr.predict()
    tr.update(looks_of([0], np.zeros((1, 2)), np.zeros(1), (np.array([[300.0, 2.0]]),)))
    return tr


def test_a_target_entering_at_an_edge_is_expected_to_head_inward() -> None:
    iso, inward = entering("isotropic"), entering("inward")
    assert len(iso.bern) == len(inward.bern) == 1
    np.testing.assert_array_equal(iso.bern.r, inward.bern.r)       # the same detection
    np.testing.assert_allclose(iso.bern.means[0, 2:], 0.0, atol=1e-9)
    # The first detection measures position only: the velocity keeps the cell's prior.
    np.testing.assert_allclose(inward.bern.means[0, 2:], [0.0, 2.0 / math.pi * 4.5],
                               rtol=1e-9)
    assert inward.bern.covs[0, 3, 3] < iso.bern.covs[0, 3, 3]
    # Heading inward, less of the predicted density leaves the map: more existence kept.
    iso.predict()
    inward.predict()
    assert inward.bern.r[0] > iso.bern.r[0]


def test_inward_needs_edge_births_and_the_speeds() -> None:
    sensor = linear.LinearSensor((0.0, 0.0, 600.0, 600.0), 1.0, 0.9, 1.0)
    known = MapModel(sensor, 1.0, (600.0, 600.0), speed_range=(3.0, 6.0))
    with pytest.raises(ValueError, match="birth_velocity"):
        PMBTracker(known, births="uniform", birth_rate=0.1, birth_velocity="inward")
    with pytest.raises(ValueError, match="birth_velocity"):
        PMBTracker(MapModel(sensor, 1.0, (600.0, 600.0)), births="edges", birth_rate=0.1,
                   birth_velocity="inward")
    with pytest.raises(ValueError, match="birth_velocity"):
        PMBTracker(known, births="edges", birth_velocity="outward")
    with pytest.raises(ValueError, match="speed_range"):
        MapModel(sensor, 1.0, (600.0, 600.0), speed_range=(6.0, 3.0))
