r"""A linear position sensor covering a rectangular area: the published filter benchmarks'.

The Poisson multi-Bernoulli literature tests its filters on a sensor that measures every
target's position directly (the ``williams15`` benchmark, after Williams 2015: a
300 x 300 m area, :math:`P_d = 0.9`, 10 false alarms per scan, :math:`R = I`; the ``vo12``
benchmark, after Vo and Vo 2012: a 2000 x 2000 m area, :math:`P_d = 0.98`, 30 false alarms
per scan, :math:`R = 100 I`).
This module is that sensor, once: one scan of the whole area gives

.. math::
    z = H x + v,\qquad H = \begin{bmatrix} 1 & 0 & 0 & 0 \\ 0 & 1 & 0 & 0 \end{bmatrix},
    \qquad v \sim N(0, \sigma^2 I_2),

for each target inside the area :math:`A = [x_0, x_1] \times [y_0, y_1]` with probability
:math:`P_d` (targets outside it are never detected), plus a Poisson number (mean
:math:`\lambda`) of false alarms uniform over :math:`A`, so the clutter intensity is
:math:`\kappa(z) = \lambda / |A|` on :math:`A` (1/m^2). Planners do not apply to it: it has
no pose, no field of view and nothing to steer.

State order ``[x, y, vx, vy]``, row vectors ``(..., 4)``; measurements ``[x, y]`` (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._types import BoolArray, FloatArray

#: The measurement matrix: the state's position.
H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
H.flags.writeable = False


@dataclass(frozen=True)
class LinearSensor:
    """A linear position sensor that scans a rectangle (see the module docstring).

    Attributes
    ----------
    area : (x0, y0, x1, y1)
        The rectangle the sensor covers, and the false alarms fall in (m).
    noise_var : float
        :math:`\\sigma^2`, the variance of each position coordinate's noise (m^2); R is
        ``noise_var * I``.
    detection_probability : float in (0, 1]
        :math:`P_d` of a target inside the area.
    clutter_rate : float >= 0
        Expected number of false alarms per scan.
    """

    area: tuple[float, float, float, float]
    noise_var: float = 1.0
    detection_probability: float = 0.9
    clutter_rate: float = 0.0

    def __post_init__(self) -> None:
        x0, y0, x1, y1 = (float(a) for a in self.area)
        if not (math.isfinite(x0 + y0 + x1 + y1) and x1 > x0 and y1 > y0):
            raise ValueError(f"area must be a finite (x0, y0, x1, y1) with x1 > x0 and "
                             f"y1 > y0, got {self.area!r}")
        if not (math.isfinite(self.noise_var) and self.noise_var > 0.0):
            raise ValueError(f"noise_var must be > 0, got {self.noise_var!r}")
        if not 0.0 < self.detection_probability <= 1.0:
            raise ValueError("detection_probability must be in (0, 1], got "
                             f"{self.detection_probability!r}")
        if not (math.isfinite(self.clutter_rate) and self.clutter_rate >= 0.0):
            raise ValueError(f"clutter_rate must be >= 0, got {self.clutter_rate!r}")

    @property
    def size(self) -> float:
        """|A|, the area's size (m^2)."""
        x0, y0, x1, y1 = self.area
        return (x1 - x0) * (y1 - y0)


def williams15() -> LinearSensor:
    """The ``williams15`` benchmark's sensor (after Williams 2015): 300 x 300 m, Pd 0.9, 10
    false alarms per scan, R = I."""
    return LinearSensor(area=(0.0, 0.0, 300.0, 300.0), noise_var=1.0,
                        detection_probability=0.9, clutter_rate=10.0)


def vo12() -> LinearSensor:
    """The ``vo12`` benchmark's sensor (after Vo and Vo 2012): 2000 x 2000 m, Pd 0.98, 30
    false alarms per scan, R = 100 I."""
    return LinearSensor(area=(0.0, 0.0, 2000.0, 2000.0), noise_var=100.0,
                        detection_probability=0.98, clutter_rate=30.0)


def measure(sensor: LinearSensor, xy: FloatArray) -> FloatArray:
    """Noise-free measurements ``H x`` of ground positions ``(..., 2)`` (or states
    ``(..., 4)``): ``(..., 2)``, a copy."""
    return np.array(np.asarray(xy, dtype=float)[..., :2])


def jacobian() -> FloatArray:
    """``H``, ``(2, 4)`` (read-only): the measurement is linear, its Jacobian constant."""
    return H


def noise(sensor: LinearSensor) -> FloatArray:
    """``R = noise_var * I``, ``(2, 2)`` (m^2)."""
    return sensor.noise_var * np.eye(2)


def in_area(sensor: LinearSensor, xy: FloatArray) -> BoolArray:
    """Whether ground positions ``(..., 2)`` lie in the covered area (edges included)."""
    xy = np.asarray(xy, dtype=float)
    x0, y0, x1, y1 = sensor.area
    return (xy[..., 0] >= x0) & (xy[..., 0] <= x1) & (xy[..., 1] >= y0) & (xy[..., 1] <= y1)


def detection_probabilities(sensor: LinearSensor, xy: FloatArray) -> FloatArray:
    """Probability that one scan detects a target at ground positions ``(..., 2)``:
    :math:`P_d` inside the area, 0 outside."""
    return np.where(in_area(sensor, xy), sensor.detection_probability, 0.0)


def clutter_density(sensor: LinearSensor) -> float:
    """:math:`\\kappa = \\lambda / |A|`, the false alarms' intensity on the area (1/m^2)."""
    return sensor.clutter_rate / sensor.size


def scan(sensor: LinearSensor, xy: FloatArray, rng: np.random.Generator
         ) -> tuple[FloatArray, BoolArray]:
    """One scan of targets at ground positions ``(M, 2)``: each target inside the area is
    detected with probability Pd and measured with noise; then the false alarms.

    The draws, in order: M uniforms (detection), M x 2 normals (noise, drawn for every
    target so that the stream does not depend on which were detected), the Poisson count of
    false alarms and its uniform positions.

    Returns
    -------
    z : (k, 2)        the detections: the detected targets' in target order, then the false
                      alarms
    detected : (M,) bool
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    M = len(xy)
    u = rng.random(M)
    normals = rng.standard_normal((M, 2))
    detected = in_area(sensor, xy) & (u < sensor.detection_probability)
    z = xy[detected] + math.sqrt(sensor.noise_var) * normals[detected]
    n = int(rng.poisson(sensor.clutter_rate))
    x0, y0, x1, y1 = sensor.area
    clutter = np.column_stack([x0 + (x1 - x0) * rng.random(n), y0 + (y1 - y0) * rng.random(n)])
    return np.concatenate([z, clutter]), detected


__all__ = ["H", "LinearSensor", "clutter_density", "detection_probabilities", "in_area",
           "jacobian", "measure", "noise", "scan", "vo12", "williams15"]
