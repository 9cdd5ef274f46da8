"""The linear position sensor of the published filter benchmarks."""

from __future__ import annotations

import numpy as np
import pytest

from sensorplan.models import linear


def test_measurement_jacobian_and_noise() -> None:
    s = linear.LinearSensor((0.0, 0.0, 300.0, 200.0), noise_var=4.0,
                            detection_probability=0.8, clutter_rate=6.0)
    x = np.array([[10.0, 20.0, 1.0, -1.0], [299.0, 0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(linear.measure(s, x), x[:, :2])
    # The Jacobian by central differences of the measurement of the whole state.
    eps = 1e-3
    J = np.column_stack([(linear.measure(s, x[0] + eps * e) - linear.measure(s, x[0] - eps * e))
                         / (2 * eps) for e in np.eye(4)])
    np.testing.assert_allclose(J, linear.jacobian(), rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(linear.noise(s), 4.0 * np.eye(2))
    assert linear.clutter_density(s) == 6.0 / 60000.0
    assert s.size == 60000.0
    inside = linear.in_area(s, np.array([[0.0, 0.0], [300.0, 200.0], [300.1, 5.0],
                                         [5.0, -0.1]]))
    assert inside.tolist() == [True, True, False, False]
    np.testing.assert_array_equal(
        linear.detection_probabilities(s, np.array([[5.0, 5.0], [-5.0, 5.0]])), [0.8, 0.0])


def test_the_benchmark_sensors() -> None:
    w, v = linear.williams15(), linear.vo12()
    assert (w.area, w.noise_var, w.detection_probability, w.clutter_rate) == (
        (0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    assert (v.area, v.noise_var, v.detection_probability, v.clutter_rate) == (
        (0.0, 0.0, 2000.0, 2000.0), 100.0, 0.98, 30.0)


def test_scans_detect_with_pd_and_scatter_clutter_over_the_area() -> None:
    s = linear.LinearSensor((0.0, 0.0, 100.0, 50.0), noise_var=1.0,
                            detection_probability=0.7, clutter_rate=4.0)
    rng = np.random.default_rng(0)
    xy = np.array([[50.0, 25.0], [150.0, 25.0]])          # the second is outside the area
    n = 4000
    detected, clutter, errors = 0, [], []
    for _ in range(n):
        z, d = linear.scan(s, xy, rng)
        assert not d[1]
        detected += int(d[0])
        errors.append(z[: int(d[0])] - xy[0])
        clutter.append(z[int(d[0]):])
    c = np.concatenate(clutter)
    e = np.concatenate(errors)
    # Binomial and Poisson counts within 4 standard deviations; uniform positions.
    assert abs(detected / n - 0.7) < 4 * np.sqrt(0.21 / n)
    assert abs(len(c) / n - 4.0) < 4 * np.sqrt(4.0 / n)
    assert linear.in_area(s, c).all()
    assert abs(c[:, 0].mean() - 50.0) < 4 * 100 / np.sqrt(12 * len(c))
    np.testing.assert_allclose(e.std(axis=0), [1.0, 1.0], atol=0.05)
    # Same generator state, same scan.
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    np.testing.assert_array_equal(linear.scan(s, xy, a)[0], linear.scan(s, xy, b)[0])


@pytest.mark.parametrize("kwargs", [{"area": (0.0, 0.0, 0.0, 1.0)},
                                    {"area": (0.0, 0.0, 1.0, 1.0), "noise_var": 0.0},
                                    {"area": (0.0, 0.0, 1.0, 1.0), "detection_probability": 0.0},
                                    {"area": (0.0, 0.0, 1.0, 1.0), "clutter_rate": -1.0}])
def test_bad_parameters_are_refused(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        linear.LinearSensor(**kwargs)
