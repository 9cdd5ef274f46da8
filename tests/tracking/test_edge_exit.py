"""What a track loses of its existence at a map edge that targets leave.

The second computations share no code with the tracker: scipy's multivariate normal
distribution for the bivariate probabilities, and for the crossing probability a
one-dimensional integral over the start position (scipy's ``quad``) of the conditional
normal of the end position.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.stats import multivariate_normal, norm

from sensorplan.models import linear
from sensorplan.models.motion import cv_matrices
from sensorplan.tracking.known_map import (EDGE_EXITS, bivariate_normal_cdf,
                                           crossing_log_mass, map_constraint)
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker


def test_the_bivariate_normal_cdf_equals_scipys() -> None:
    rng = np.random.default_rng(3)
    h, k = rng.normal(0.0, 2.0, (2, 200))
    rho = rng.uniform(-0.999, 0.999, 200)
    # Zeros, equal bounds and correlations near +-1 are where the formula has its branches.
    h[:4], k[:4] = [0.0, 0.0, 1.3, -0.7], [0.0, -1.1, 1.3, -0.7]
    rho[:4] = [0.4, -0.6, 0.9999, -0.9999]
    got = bivariate_normal_cdf(h, k, rho)
    want = [multivariate_normal(cov=[[1.0, r], [r, 1.0]]).cdf([a, b])
            for a, b, r in zip(h, k, rho)]
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-9)


def crossing_by_quadrature(m: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray,
                           axis: int, L: float) -> float:
    """``P(end off [0, L] | start on it)`` on one axis: the start position's density times
    the end position's conditional normal tails, integrated over the start."""
    m1, P1, C = F @ m, F @ P @ F.T + Q, P @ F.T
    s0 = math.sqrt(P[axis, axis])
    gain = C[axis, axis] / P[axis, axis]
    sd = math.sqrt(P1[axis, axis] - C[axis, axis] * gain)

    def f(x: float) -> float:
        mu = m1[axis] + gain * (x - m[axis])
        return float(norm.pdf(x, m[axis], s0) * (norm.cdf(0.0, mu, sd) + norm.sf(L, mu, sd)))

    lo, hi = max(0.0, m[axis] - 12 * s0), min(L, m[axis] + 12 * s0)
    num = integrate.quad(f, lo, hi, points=[min(max(m[axis], lo), hi)], epsabs=1e-15,
                         epsrel=1e-12, limit=200)[0]
    return num / (norm.cdf(L, m[axis], s0) - norm.cdf(0.0, m[axis], s0))


def random_state(rng: np.random.Generator, width: float, height: float
                 ) -> tuple[np.ndarray, ...]:
    """A state near a random edge (or a corner) with a random covariance."""
    x = rng.choice([rng.uniform(-3.0, 15.0), width - rng.uniform(-3.0, 15.0),
                    rng.uniform(50.0, width - 50.0)])
    y = rng.choice([rng.uniform(-3.0, 15.0), height - rng.uniform(-3.0, 15.0),
                    rng.uniform(50.0, height - 50.0)])
    m = np.array([x, y, *rng.normal(0.0, 3.0, 2)])
    A = rng.standard_normal((4, 4)) * 0.3 + np.eye(4)
    P = np.diag([4.0, 4.0, 1.5, 1.5]) @ A @ A.T @ np.diag([4.0, 4.0, 1.5, 1.5])
    return m, 0.5 * (P + P.T)


def test_the_crossing_probability_equals_an_integral_over_the_start() -> None:
    rng = np.random.default_rng(8)
    F, Q = cv_matrices(1.0, 0.7)
    W, H = 600.0, 400.0
    states = [random_state(rng, W, H) for _ in range(40)]
    m = np.stack([s[0] for s in states])
    P = np.stack([s[1] for s in states])
    got = crossing_log_mass(m, P, F, Q, W, H)
    want = [math.log1p(-crossing_by_quadrature(mi, Pi, F, Q, 0, W))
            + math.log1p(-crossing_by_quadrature(mi, Pi, F, Q, 1, H)) for mi, Pi in states]
    assert np.min(want) < -0.05                   # some of them are likely to leave
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-12)


def test_a_start_known_exactly_crosses_as_its_end_density_lies_off_the_map() -> None:
    # With the start position (almost) certain, being on the map at the start is certain,
    # and crossing is the end position's normal tail beyond the edge.
    F, Q = cv_matrices(1.0, 0.5)
    m = np.array([597.0, 300.0, 1.5, 0.0])
    P = np.diag([1e-10, 1e-10, 2.0, 2.0])
    m1, P1 = F @ m, F @ P @ F.T + Q
    off = norm.sf(600.0, m1[0], math.sqrt(P1[0, 0])) + norm.cdf(0.0, m1[0], math.sqrt(P1[0, 0]))
    np.testing.assert_allclose(crossing_log_mass(m, P, F, Q, 600.0, 600.0),
                               math.log1p(-off), rtol=1e-9)


def test_crossing_charges_less_than_the_mass_off_the_map() -> None:
    # Start and end positions are positively correlated, so a target on the map at the start
    # is less likely to end off it than the unconditioned end density says (one edge near).
    rng = np.random.default_rng(5)
    F, Q = cv_matrices(1.0, 1.0)
    for _ in range(30):
        m = np.array([rng.uniform(300.0, 610.0), 300.0, rng.normal(0.0, 2.0), 0.0])
        P = np.diag([rng.uniform(1.0, 60.0), 9.0, rng.uniform(0.1, 6.0), 1.0])
        m1, P1 = F @ m, F @ P @ F.T + Q
        assert (P @ F.T)[0, 0] > 0.0
        outside = norm.sf(600.0, m1[0], math.sqrt(P1[0, 0]))
        assert crossing_log_mass(m, P, F, Q, 600.0, 600.0) >= math.log1p(-outside) - 1e-15


def near_edge_tracker(edge: str, edge_exit: str) -> PMBTracker:
    m = np.array([[594.0, 150.0, 0.8, -3.0], [300.0, 150.0, 1.0, 0.0]])
    P = np.stack([np.diag([9.0, 16.0, 2.0, 2.0])] * 2)
    return PMBTracker(MapModel(linear.williams15(), 1.0, (600.0, 300.0), process_noise=0.3,
                               map_edge=edge),
                      means=m, covs=P, existence=0.9, survival_probability=0.99,
                      report_threshold=0.3, edge_exit=edge_exit)


def test_the_pmb_charges_the_crossing_at_an_exit_edge() -> None:
    F, Q = cv_matrices(1.0, 0.3)
    tr = near_edge_tracker("exit", "crossing")
    m0, P0 = tr.bern.means.copy(), tr.bern.covs.copy()
    corrected = tr.predict()
    stay = math.log1p(-crossing_by_quadrature(m0[0], P0[0], F, Q, 0, 600.0))
    stay += math.log1p(-crossing_by_quadrature(m0[0], P0[0], F, Q, 1, 300.0))
    np.testing.assert_allclose(tr.bern.r, [0.99 * 0.9 * math.exp(stay), 0.99 * 0.9],
                               rtol=1e-9)
    # The density is truncated to the map as with the other rule: only the charge differs.
    want_m, want_P, applied, log_mass = map_constraint(F @ m0[0], F @ P0[0] @ F.T + Q,
                                                       600.0, 300.0)
    assert applied and corrected.tolist() == [True, False] and stay > log_mass
    np.testing.assert_allclose(tr.bern.means[0], want_m, rtol=1e-12)
    np.testing.assert_allclose(tr.bern.covs[0], want_P, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("edge_exit", EDGE_EXITS)
def test_a_closed_edge_charges_nothing_whatever_the_exit_rule(edge_exit: str) -> None:
    tr = near_edge_tracker("closed", edge_exit)
    tr.predict()
    np.testing.assert_allclose(tr.bern.r, [0.99 * 0.9] * 2, rtol=1e-15)


def test_an_unknown_exit_rule_is_refused() -> None:
    with pytest.raises(ValueError, match="edge_exit"):
        near_edge_tracker("exit", "teleport")


def test_the_settings_name_the_same_exit_rules_and_map_edges() -> None:
    # The run settings name them without importing the tracking modules.
    from sensorplan.simulation import settings
    from sensorplan.tracking import known_map

    assert settings.EDGE_EXITS == known_map.EDGE_EXITS
    assert settings.MAP_EDGE_CHOICES == ("scenario", *known_map.MAP_EDGES)
