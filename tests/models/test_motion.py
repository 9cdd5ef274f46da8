"""The filter's CWNA motion model."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec

from sensorplan.models.motion import (aim_points, cv_matrices, predict_covariance,
                                      predict_covariances, predict_means)

G = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def spec_F(dt: float) -> np.ndarray:
    return np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)


def spec_Q(dt: float, q: float) -> np.ndarray:
    a, b = dt**3 / 3, dt**2 / 2
    return q * np.array([[a, 0, b, 0], [0, a, 0, b], [b, 0, dt, 0], [0, b, 0, dt]])


@pytest.mark.parametrize("dt,q", [(1.0, 0.05), (0.5, 1.0), (2.3, 0.7), (1e-3, 10.0), (1.0, 0.0)])
def test_matrices_equal_spec(dt, q):
    F, Q = cv_matrices(dt, q)
    np.testing.assert_allclose(F, spec_F(dt), rtol=1e-15, atol=0)
    np.testing.assert_allclose(Q, spec_Q(dt, q), rtol=1e-14, atol=0)
    np.testing.assert_array_equal(Q, Q.T)


@pytest.mark.parametrize("dt,q", [(1.0, 0.05), (0.5, 1.0), (2.3, 0.7)])
def test_Q_is_the_integral_of_the_continuous_noise(dt, q):
    def integrand(s: float) -> np.ndarray:
        Fs = spec_F(s)
        return Fs @ G @ G.T @ Fs.T * q

    integral, err = quad_vec(integrand, 0.0, dt, epsabs=1e-14, epsrel=1e-13)
    _, Q = cv_matrices(dt, q)
    np.testing.assert_allclose(Q, integral, rtol=1e-11, atol=1e-14)


def test_F_is_a_semigroup():
    F1, _ = cv_matrices(0.7, 0.1)
    F2, _ = cv_matrices(1.3, 0.1)
    F3, _ = cv_matrices(2.0, 0.1)
    np.testing.assert_allclose(F1 @ F2, F3, rtol=1e-14, atol=1e-15)


def test_predict_means_are_matrix_powers(rng):
    F, _ = cv_matrices(0.8, 0.05)
    x0 = rng.normal(size=(3, 2, 4)) * [100, 100, 3, 3]
    out = predict_means(x0, F, 5)
    assert out.shape == (3, 2, 6, 4)
    for t in range(6):
        np.testing.assert_allclose(out[..., t, :], x0 @ np.linalg.matrix_power(F, t).T,
                                   rtol=1e-13, atol=1e-10)
    # closed form: position advances by t dt v
    np.testing.assert_allclose(out[..., 5, :2], x0[..., :2] + 5 * 0.8 * x0[..., 2:],
                               rtol=1e-13, atol=1e-10)


@pytest.mark.parametrize("K,e", [(1, 1), (3, 2), (4, 1), (2, 3)])
def test_aim_points_are_the_means_at_each_epochs_first_step(rng, K, e):
    dt = 0.7
    x0 = rng.normal(size=(3, 4)) * [100, 100, 3, 3]
    out = aim_points(x0, spec_F(dt), K, e)
    assert out.shape == (3, K, 2) and out.flags.c_contiguous
    for k in range(1, K + 1):
        t = (k - 1) * e + 1
        np.testing.assert_allclose(out[:, k - 1], x0[:, :2] + t * dt * x0[:, 2:],
                                   rtol=1e-13, atol=1e-10)


def test_predict_covariances_equal_explicit_sums(rng):
    dt, q = 1.0, 0.3
    F, Q = spec_F(dt), spec_Q(dt, q)
    A = rng.normal(size=(2, 4, 4))
    P0 = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    out = predict_covariances(P0, F, Q, 4)
    assert out.shape == (2, 5, 4, 4)
    for t in range(5):
        Ft = np.linalg.matrix_power(F, t)
        ref = Ft @ P0 @ Ft.T
        for u in range(t):
            Fu = np.linalg.matrix_power(F, u)
            ref = ref + Fu @ Q @ Fu.T
        np.testing.assert_allclose(out[:, t], ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(out[:, t], np.swapaxes(out[:, t], -1, -2))
    one = predict_covariance(P0, F, Q)
    np.testing.assert_allclose(one, out[:, 1], rtol=1e-15, atol=0)
