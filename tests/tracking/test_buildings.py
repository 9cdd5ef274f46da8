"""Known buildings in the tracker: no target is ever inside one, and targets turn at walls.

The sensing region, the line of sight and the targets' motion are re-implemented here from
their definitions (numpy, no library call), so that the Monte Carlo references do not go
through the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models.motion import cv_matrices
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.tracking.known_map import building_constraint, near_buildings
from sensorplan.tracking.missed import miss_update
from sensorplan.tracking.tracker import KnownTargetTracker

#: One 60 m block, 150 m tall (the town preset's central tower).
TOWER = np.array([[270.0, 270.0, 330.0, 330.0, 150.0]])
ALTITUDE = 500.0
PARAMS = SensorParams(altitude=ALTITUDE)
#: A sensor 350 m south of the tower's centre looking north: the tower is in its range band
#: and hides a strip behind it.
SENSOR = np.array([300.0, -50.0])
HEADING = math.pi / 2


def in_footprint(xy: np.ndarray, b: np.ndarray = TOWER) -> np.ndarray:
    x, y = xy[..., 0, None], xy[..., 1, None]
    return np.any((x > b[:, 0]) & (x < b[:, 2]) & (y > b[:, 1]) & (y < b[:, 3]), axis=-1)


def detectable(xy: np.ndarray, sensor: np.ndarray = SENSOR, heading: float = HEADING,
               b: np.ndarray = TOWER) -> np.ndarray:
    """In the field of view (range band, wedge) and in sight: the segment from the sensor
    at altitude to the ground point does not pass through the inside of a box."""
    d = xy - sensor
    g = np.hypot(d[:, 0], d[:, 1])
    off = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - heading)))
    view = ((g >= PARAMS.min_ground_range) & (g <= PARAMS.max_ground_range)
            & (np.abs(off) <= PARAMS.fov_half_angle))
    hidden = np.zeros(len(xy), dtype=bool)
    for x0, y0, x1, y1, h in b:
        # s in (lo, hi): the sight line P(s) = sensor + s d is below the roof and over the
        # footprint (each coordinate's interval of s, intersected).
        lo = np.full(len(xy), max(0.0, 1.0 - h / ALTITUDE))
        hi = np.ones(len(xy))
        for k, (a, c) in enumerate(((x0, x1), (y0, y1))):
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (a - sensor[k]) / d[:, k]
                t2 = (c - sensor[k]) / d[:, k]
            flat = d[:, k] == 0.0
            inside = (a < sensor[k]) & (sensor[k] < c)
            lo = np.where(flat, np.where(inside, lo, np.inf), np.maximum(lo, np.minimum(t1, t2)))
            hi = np.where(flat, hi, np.minimum(hi, np.maximum(t1, t2)))
        hidden |= lo < hi
    return view & ~hidden


def moments(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return X.mean(axis=0), np.cov(X.T, bias=True)


def assert_close_to(mean: np.ndarray, cov: np.ndarray, ref_mean: np.ndarray,
                    ref_cov: np.ndarray, mean_tol: float = 0.1, var_tol: float = 0.15) -> None:
    """Means within ``mean_tol`` reference standard deviations, variances within
    ``var_tol`` relative (the 512-point quadrature's error on truncated Gaussians is a few
    per cent: docs/model.md, section 4)."""
    sd = np.sqrt(np.diag(ref_cov))
    np.testing.assert_array_less(np.abs(mean - ref_mean) / sd, mean_tol)
    np.testing.assert_allclose(np.diag(cov), np.diag(ref_cov), rtol=var_tol)


def tracker(mean: np.ndarray, cov: np.ndarray, *, known_buildings: bool) -> KnownTargetTracker:
    return KnownTargetTracker(mean[None], cov[None], 1.0, radar_table((PARAMS,)),
                              process_noise=0.05, buildings=TOWER,
                              known_buildings=known_buildings, miss_update=miss_update)


def miss_look(t: KnownTargetTracker) -> None:
    from sensorplan.tracking.base import Looks

    t.update(Looks(sensors=np.array([0]), aims=np.array([0]), positions=SENSOR[None],
                   headings=np.array([HEADING]), detections=(np.zeros((0, 2)),)))


def test_a_miss_beside_a_building_conditions_on_the_miss_and_on_no_target_inside():
    """A look over a tower misses its target. The exact posterior of the Gaussian prior is
    its restriction to the places the look could not see and that are not inside the tower
    (Monte Carlo, 10^6 samples). The tracker with known buildings matches it; the update
    without them (the previous tracker) leaves 63 % of the track's mass inside the tower,
    its mean 28 m from the posterior's, inside the footprint."""
    m = np.array([300.0, 300.0, 1.0, 0.0])
    P = np.diag([40.0**2, 40.0**2, 4.0, 4.0])
    X = np.random.default_rng(20260311).multivariate_normal(m, P, 1_000_000)
    keep = ~detectable(X[:, :2]) & ~in_footprint(X[:, :2])
    ref_m, ref_P = moments(X[keep])

    new = tracker(m, P, known_buildings=True)
    miss_look(new)
    assert_close_to(new.means[0], new.covs[0], ref_m, ref_P)
    assert not in_footprint(new.means[0, :2][None])[0]

    old = tracker(m, P, known_buildings=False)
    miss_look(old)
    assert in_footprint(old.means[0, :2][None])[0]
    assert abs(old.means[0, 1] - ref_m[1]) > 0.5 * math.sqrt(ref_P[1, 1])


def test_repeated_misses_do_not_pile_the_track_into_the_building():
    """Ten steps of looks that miss: without known buildings each removes everything but
    the tower's footprint and the strip it hides, and 40 % of the track ends up inside the
    footprint, where no target can be; with them almost none does."""
    m = np.array([300.0, 300.0, 0.0, 0.0])
    P = np.diag([40.0**2, 40.0**2, 1.0, 1.0])
    share = {}
    for known in (True, False):
        t = tracker(m, P, known_buildings=known)
        for _ in range(10):
            t.predict()
            miss_look(t)
        X = np.random.default_rng(3).multivariate_normal(t.means[0], t.covs[0], 100_000)
        share[known] = in_footprint(X[:, :2]).mean()
    assert share[False] > 0.4
    assert share[True] < 0.1


def test_the_building_constraint_is_the_truncated_gaussian(rng):
    """No look: the track restricted to the outside of the footprints, against a Monte
    Carlo of the truncated Gaussian (with correlations)."""
    m = np.array([250.0, 290.0, 2.0, -1.0])
    A = rng.standard_normal((4, 4))
    P = np.diag([30.0**2, 25.0**2, 2.0, 2.0]) + 0.3 * A @ A.T
    P[0, 2] = P[2, 0] = 20.0
    P[0, 1] = P[1, 0] = 150.0
    X = np.random.default_rng(7).multivariate_normal(m, P, 1_000_000)
    ref_m, ref_P = moments(X[~in_footprint(X[:, :2])])
    m2, P2, applied, log_mass = building_constraint(m, P, TOWER)
    assert applied
    assert_close_to(m2, P2, ref_m, ref_P, mean_tol=0.05, var_tol=0.06)
    np.testing.assert_allclose(np.exp(log_mass), np.mean(~in_footprint(X[:, :2])), atol=0.03)


def test_tracks_clear_of_buildings_are_untouched_bit_for_bit():
    m = np.array([[100.0, 100.0, 1.0, 1.0], [300.0, 150.0, 0.0, 2.0]])
    P = np.broadcast_to(np.diag([100.0, 100.0, 1.0, 1.0]), (2, 4, 4)).copy()
    assert not near_buildings(m, P, TOWER).any()
    m2, P2, applied, log_mass = building_constraint(m, P, TOWER, reflect_dt=1.0)
    assert not applied.any()
    np.testing.assert_array_equal(m2, m)
    np.testing.assert_array_equal(P2, P)
    np.testing.assert_array_equal(log_mass, 0.0)


def test_a_track_driving_into_a_wall_turns_as_the_target_does():
    """A nearly certain track 4 m before the west wall at 5 m/s: one step later the target
    is 1 m back out of the wall with its velocity reversed, and so is the predicted track."""
    m = np.array([266.0, 300.0, 5.0, 0.0])
    P = np.diag([1e-4, 1e-4, 1e-6, 1e-6])
    t = KnownTargetTracker(m[None], P[None], 1.0, radar_table((PARAMS,)), process_noise=1e-6,
                           buildings=TOWER, known_buildings=True)
    t.predict()
    np.testing.assert_allclose(t.means[0], [269.0, 300.0, -5.0, 0.0], atol=1e-3)


def test_the_reflected_prediction_follows_the_targets_motion():
    """A track heading for the wall: the predicted track against a Monte Carlo of the
    targets' own motion (constant velocity with the filter's process noise, mirrored across
    the wall it entered through, velocity component reversed)."""
    q = 0.5
    m = np.array([262.0, 300.0, 5.0, 0.5])
    P = np.diag([4.0**2, 4.0**2, 1.0, 1.0])
    F, Q = cv_matrices(1.0, q)
    rng = np.random.default_rng(11)
    X0 = rng.multivariate_normal(m, P, 400_000)
    X0 = X0[~in_footprint(X0[:, :2])]
    X1 = X0 @ F.T + rng.multivariate_normal(np.zeros(4), Q, len(X0))
    # Entered through the west wall (x = 270) this step: mirror x, reverse vx. Points that
    # would enter through another wall are a negligible share here, and are dropped.
    came_in = in_footprint(X1[:, :2])
    west = came_in & (X0[:, 0] <= 270.0)
    X1[west, 0] = 540.0 - X1[west, 0]
    X1[west, 2] = -X1[west, 2]
    X1 = X1[~in_footprint(X1[:, :2])]
    ref_m, ref_P = moments(X1)
    t = KnownTargetTracker(m[None], P[None], 1.0, radar_table((PARAMS,)), process_noise=q,
                           buildings=TOWER, known_buildings=True)
    t.predict()
    assert ref_m[2] < 0.7 * m[2]                    # a real share of the mass turned
    assert_close_to(t.means[0], t.covs[0], ref_m, ref_P, mean_tol=0.1, var_tol=0.15)


@pytest.mark.parametrize("known", [True, False])
def test_without_buildings_the_option_changes_nothing(known):
    m = np.array([[250.0, 300.0, 5.0, 0.0]])
    P = np.diag([900.0, 900.0, 4.0, 4.0])[None]
    a = KnownTargetTracker(m, P, 1.0, radar_table((PARAMS,)), process_noise=0.05,
                           buildings=np.zeros((0, 5)), known_buildings=known)
    b = KnownTargetTracker(m, P, 1.0, radar_table((PARAMS,)), process_noise=0.05)
    for t in (a, b):
        t.predict()
    np.testing.assert_array_equal(a.means, b.means)
    np.testing.assert_array_equal(a.covs, b.covs)


def test_with_reflect_walls_a_track_turns_at_the_map_wall_as_the_target_does():
    """The map's walls, with ``reflect_walls``: a nearly certain track 2 m before the east
    wall at 5 m/s comes back 3 m inside with its velocity reversed; without the option the
    known map only truncates it (it stays at the wall, still heading out)."""
    m = np.array([[598.0, 300.0, 5.0, 0.0]])
    P = np.diag([1e-4, 1e-4, 1e-6, 1e-6])[None]
    for reflect in (True, False):
        t = KnownTargetTracker(m, P, 1.0, radar_table((PARAMS,)), process_noise=1e-6,
                               world=(600.0, 600.0), reflect_walls=reflect)
        t.predict()
        if reflect:
            np.testing.assert_allclose(t.means[0], [597.0, 300.0, -5.0, 0.0], atol=1e-3)
        else:
            assert t.means[0, 0] <= 600.0 and t.means[0, 2] > 4.0
