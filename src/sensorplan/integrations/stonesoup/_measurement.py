"""The radar as a Stone Soup measurement model."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from stonesoup.base import Property
from stonesoup.models.base import GaussianModel, ReversibleModel
from stonesoup.models.measurement.base import MeasurementModel
from stonesoup.types.angle import Bearing
from stonesoup.types.array import CovarianceMatrix, StateVector, StateVectors

from ..._types import FloatArray
from ...models import radar
from ...models.angles import wrap_angle
from ...models.sensors import SensorParams, radar_table

from ._convert import _ground_xy


def noise_source(rng: Any, own: Any) -> Any:
    """Where noise is drawn from: ``rng`` when given, else ``own`` (a generator from an
    explicit seed), else NumPy's global state.

    The global fallback is deliberate and confined to the Stone Soup bridge: Stone Soup's
    models draw from ``np.random`` when no seed is given, and its users make runs repeatable
    with ``np.random.seed``. Everywhere else sensorplan takes explicit generators.
    """
    if rng is not None:
        return rng
    if own is not None:
        return own
    # The module's functions draw from the global RandomState that np.random.seed seeds and
    # Stone Soup's models use; it has the standard_normal a Generator has.
    return np.random


# --------------------------------------------------------------------------------------------
# Measurement model
# --------------------------------------------------------------------------------------------


class RadarMeasurementModel(MeasurementModel, GaussianModel, ReversibleModel):
    r"""sensorplan's radar as a Stone Soup measurement model: ``z = [r, phi]``.

    .. math::
        r = \sqrt{dx^2 + dy^2 + z_i^2},\quad \phi = \operatorname{atan2}(dy, dx),\quad
        R = \operatorname{diag}(\sigma_r^2, \sigma_\phi^2)

    with the SNR-dependent standard deviations of the one radar model
    (:func:`sensorplan.models.radar.measure_looks`).
    The measurement order is ours, range first (Stone Soup's own ``CartesianToBearingRange``
    puts the bearing first); the azimuth entry is a Stone Soup ``Bearing``, so innovations
    are wrapped by Stone Soup's updaters.

    ``R`` depends on the target's state. :meth:`covar` evaluates it at ``state`` when given,
    otherwise at the state of the latest :meth:`jacobian` call, which is where Stone Soup's
    ``ExtendedKalmanUpdater`` linearises (it calls ``jacobian(prediction)`` before every
    ``covar()``): the filter's ``R`` is therefore taken at its predicted state, as in
    sensorplan's own filter.

    The model works on any state layout whose ground x and y sit at ``mapping`` (4-D
    ``[x, vx, y, vy]``, 6-D ``[x, vx, y, vy, z, vz]``, ...): :meth:`jacobian` has one column
    per entry of the state it is given. A target's z does not enter (targets are on the
    ground; the radar's altitude is ``params.altitude``).

    Randomness (Stone Soup's convention): :meth:`rvs` draws from ``random_state`` when given,
    else from the model's own generator when ``seed`` is set
    (``numpy.random.default_rng(seed)``), else from NumPy's global state ``np.random``, so
    ``np.random.seed(...)`` makes a run repeatable.

    The field of view is not part of a measurement model; :class:`SensorplanRadar` applies it.
    """

    ndim_state: int = Property(default=4, doc="Number of target state dimensions.")
    mapping: Sequence[int] = Property(
        default=(0, 2), doc="Indices of the target's ground x and y in the state vector "
                            "(Stone Soup order ``[x, vx, y, vy]``: ``(0, 2)``).")
    sensor_xy: Sequence[float] = Property(doc="Ground position ``(x, y)`` of the platform (m).")
    heading: float = Property(default=0.0, doc="Platform heading theta (rad); enters R "
                                               "through the boresight angle psi.")
    params: SensorParams = Property(default_factory=SensorParams,
                                    doc="Radar parameters (altitude, SNR model, ...).")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.sensor_xy = tuple(float(v) for v in np.asarray(self.sensor_xy, float).ravel()[:2])
        self._linearised_at: FloatArray | None = None
        # Stone Soup's convention: an explicit seed gives the model its own stream, no seed
        # means NumPy's global state (see rvs).
        self._rng = None if self.seed is None else np.random.default_rng(self.seed)
        self._table = radar_table(self.params)

    def _radar(self, xy: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, Any]:
        """The radar model at ground positions ``(n, 2)``: h, H', var, visible."""
        return radar.measure_looks(self._table, 0, xy, np.array(self.sensor_xy), self.heading)

    @property
    def ndim_meas(self) -> int:
        return 2

    def function(self, state: Any, noise: Any = False, **kwargs: Any) -> StateVector:
        """``[r, phi]`` of a state (``StateVector``) or states (``StateVectors``, one column
        each). ``noise=True`` adds a draw from ``N(0, R)`` with ``R`` at each state."""
        xy = _ground_xy(state, self.mapping)                                    # (n, 2)
        z = self._radar(xy)[0].T                                                # (2, n)
        if noise is True:
            noise = self.rvs(num_samples=z.shape[1], state=state, **kwargs)
        elif noise is False or noise is None:
            noise = 0.0
        return np.array([[0.0], [Bearing(0.0)]]) + StateVectors(z) + noise

    def jacobian(self, state: Any, **kwargs: Any) -> FloatArray:
        r"""Analytic Jacobian ``(2, n)`` at one state of ``n`` entries, in Stone Soup's
        order; zero outside the ground position columns ``mapping``.

        .. math:: \partial r/\partial x = dx/r,\ \partial r/\partial y = dy/r,\
                  \partial\phi/\partial x = -dy/g^2,\ \partial\phi/\partial y = dx/g^2

        Also records the state so that :meth:`covar` evaluates ``R`` there.
        """
        xy = _ground_xy(state, self.mapping)
        if xy.shape[0] != 1:
            raise ValueError("jacobian takes one state")
        Hp = self._radar(xy)[1][0]                                              # (2, 2)
        sv = state.state_vector if hasattr(state, "state_vector") else state
        H = np.zeros((2, np.shape(sv)[0]))
        H[:, self.mapping[0]] = Hp[:, 0]
        H[:, self.mapping[1]] = Hp[:, 1]
        self._linearised_at = xy[0].copy()
        return H

    def _noise_point(self, state: Any) -> FloatArray:
        if state is not None:
            xy = _ground_xy(state, self.mapping)
            return xy if xy.shape[0] > 1 else xy[0]
        if self._linearised_at is None:
            raise ValueError("RadarMeasurementModel: R depends on the target state; pass "
                             "state= or call jacobian(state) first")
        return self._linearised_at

    def covar(self, state: Any = None, **kwargs: Any) -> CovarianceMatrix:
        """Noise covariance ``R`` ``(2, 2)`` at ``state`` (default: the latest linearisation
        point, see the class docstring)."""
        xy = self._noise_point(state)
        if xy.ndim > 1:
            raise ValueError("covar takes one state")
        return CovarianceMatrix(np.diag(self._radar(xy[None])[2][0]))

    def noise_std(self, state: Any = None) -> FloatArray:
        """Standard deviations ``(n, 2)`` (range m, azimuth rad) at the state(s)."""
        xy = np.atleast_2d(self._noise_point(state))
        return np.sqrt(self._radar(xy)[2])

    def scaled_noise(self, state: Any, unit: Any) -> StateVector:
        """Noise ``(2, 1)`` equal to ``sqrt(R(state)) @ unit`` for standard normals ``unit``
        ``(2,)``: lets a simulation reuse its own random streams (common random numbers)."""
        sd = self.noise_std(state)[0]
        return StateVector(sd * np.asarray(unit, dtype=float).reshape(2))

    def rvs(self, num_samples: int = 1, random_state: Any = None, state: Any = None,
            **kwargs: Any) -> StateVector | StateVectors:
        """Draws from ``N(0, R)``; ``R`` at ``state`` (one column per state when several).

        ``random_state``: a ``numpy.random.Generator`` or ``RandomState``. Without it, the
        model's own generator when ``seed`` is set, else NumPy's global state (Stone Soup's
        convention: ``np.random.seed`` makes the draws repeatable).
        """
        gen = noise_source(random_state, self._rng)
        sd = self.noise_std(state)                                              # (n, 2)
        n = max(num_samples, sd.shape[0])
        draws = (np.broadcast_to(sd, (n, 2)) * gen.standard_normal((n, 2))).T
        return StateVector(draws) if n == 1 else StateVectors(draws)

    def logpdf(self, state1: Any, state2: Any, **kwargs: Any) -> float:
        """Log-likelihood of measurement ``state1`` given target state ``state2`` (``R`` at
        ``state2``; azimuth difference wrapped)."""
        diff = np.asarray(state1.state_vector, dtype=float).reshape(2) - np.asarray(
            self.function(state2), dtype=float).reshape(2)
        diff[1] = float(wrap_angle(diff[1]))
        var = self.noise_std(state2)[0] ** 2
        return float(-0.5 * np.sum(diff * diff / var) - 0.5 * np.sum(np.log(2 * np.pi * var)))

    def pdf(self, state1: Any, state2: Any, **kwargs: Any) -> float:
        return float(np.exp(self.logpdf(state1, state2, **kwargs)))

    def inverse_function(self, detection: Any, **kwargs: Any) -> StateVector:
        """Ground position of a measurement (range minus altitude, then azimuth); other
        state entries zero."""
        r, phi = np.asarray(detection.state_vector, dtype=float).reshape(2)
        g = math.sqrt(max(r * r - float(self.params.altitude) ** 2, 0.0))
        out = np.zeros(max(int(self.ndim_state), max(self.mapping[:2]) + 1))
        out[self.mapping[0]] = self.sensor_xy[0] + g * math.cos(phi)
        out[self.mapping[1]] = self.sensor_xy[1] + g * math.sin(phi)
        return StateVector(out)
