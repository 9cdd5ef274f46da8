r"""The radar-like sensor (SPEC 2): geometry, Jacobian, field of view, SNR noise.

Every kernel broadcasts over leading batch axes: target positions ``(..., 2)`` (or states
``(..., 4)``), sensor ground positions ``(..., 2)``, headings ``(...)``. Sensor parameters
come from a :class:`SensorParams` whose fields may be floats or arrays broadcastable to the
batch (see :func:`stack_params`), so many sensors are evaluated in one call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from scipy.special import ndtr

from ._types import BoolArray, FloatArray
from .angles import wrap_angle
from .errors import ConfigError

#: Tolerances for the inclusive field-of-view bounds: a point computed to lie exactly on an
#: edge can land a rounding error outside it.
RANGE_TOL = 1e-9
ANGLE_TOL = 1e-12
#: Looks with a smaller detection probability do not count (SPEC 4).
P_VIS_MIN = 1e-6


@dataclass(frozen=True)
class SensorParams:
    """Platform and radar parameters of one sensor (SPEC 2 defaults).

    Attributes
    ----------
    altitude : float
        Platform altitude z_i (m).
    moves : tuple of float
        Move distances s (m); each gives the 8 lattice directions.
    max_turn : float
        Largest heading change per epoch (rad).
    fov_half_angle : float
        Azimuth half-width of the field of view (rad).
    min_ground_range, max_ground_range : float
        Ground-range band of the field of view (m).
    depression : float
        Boresight depression below the horizon (rad).
    snr_ref_db, range_ref : float
        SNR (dB) at the reference slant range (m).
    beamwidth : float
        Beamwidth (rad).
    monopulse_slope : float
        Monopulse slope (dimensionless).
    range_resolution : float
        Range resolution (m).
    """

    altitude: Any = 500.0
    moves: tuple[float, ...] = (20.0, 40.0)
    max_turn: Any = math.pi / 4
    fov_half_angle: Any = math.pi / 6
    min_ground_range: Any = 250.0
    max_ground_range: Any = 450.0
    depression: Any = math.radians(40.0)
    snr_ref_db: Any = 15.0
    range_ref: Any = 600.0
    beamwidth: Any = math.radians(3.0)
    monopulse_slope: Any = 1.6
    range_resolution: Any = 30.0

    def validate(self, prefix: str = "sensor") -> None:
        """Raise :class:`ConfigError` naming the field if a value breaks SPEC 7's rules."""
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if f.name == "moves" else (value,)
            for v in np.atleast_1d(np.asarray(values, dtype=float)).ravel():
                if not np.isfinite(v):
                    raise ConfigError(f"{prefix}.{f.name}", "must be a finite number")
        positive = ("altitude", "min_ground_range", "max_ground_range", "range_ref",
                    "beamwidth", "monopulse_slope", "range_resolution", "fov_half_angle")
        for name in positive:
            if np.any(np.asarray(getattr(self, name)) <= 0):
                raise ConfigError(f"{prefix}.{name}", "must be > 0")
        if len(self.moves) == 0:
            raise ConfigError(f"{prefix}.moves", "must list at least one move distance")
        if any(m <= 0 for m in self.moves):
            raise ConfigError(f"{prefix}.moves", "move distances must be > 0")
        if np.any(np.asarray(self.max_turn) < 0):
            raise ConfigError(f"{prefix}.max_turn", "must be >= 0")
        if np.any(np.asarray(self.min_ground_range) > np.asarray(self.max_ground_range)):
            raise ConfigError(f"{prefix}.min_ground_range", "must be <= max_ground_range")


_SCALAR_FIELDS = tuple(f.name for f in fields(SensorParams) if f.name != "moves")


def stack_params(params: "list[SensorParams] | tuple[SensorParams, ...]") -> SensorParams:
    """One :class:`SensorParams` whose scalar fields are ``(N,)`` arrays, one per sensor."""
    kwargs = {name: np.array([getattr(p, name) for p in params], dtype=float)
              for name in _SCALAR_FIELDS}
    return SensorParams(moves=(), **kwargs)


def take_params(params: SensorParams, index: Any) -> SensorParams:
    """Index every array field of stacked parameters (e.g. ``[:, None]`` to add an axis)."""
    kwargs = {name: np.asarray(getattr(params, name))[index] for name in _SCALAR_FIELDS}
    return SensorParams(moves=params.moves, **kwargs)


def ground_offset(target_xy: FloatArray, sensor_xy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Ground offset ``(dx, dy)`` of targets ``(..., 2)`` from sensors ``(..., 2)``."""
    target_xy = np.asarray(target_xy, dtype=float)
    sensor_xy = np.asarray(sensor_xy, dtype=float)
    return target_xy[..., 0] - sensor_xy[..., 0], target_xy[..., 1] - sensor_xy[..., 1]


def measure(x: FloatArray, sensor_xy: FloatArray, altitude: Any) -> FloatArray:
    """Noise-free measurement ``[r, phi]`` of states ``(..., 4)`` (or positions ``(..., 2)``).

    ``r`` is the slant range (m) including the altitude, ``phi = atan2(dy, dx)`` the azimuth.
    """
    dx, dy = ground_offset(np.asarray(x)[..., :2], sensor_xy)
    r = np.sqrt(dx * dx + dy * dy + np.asarray(altitude, dtype=float) ** 2)
    return np.stack([r, np.arctan2(dy, dx)], axis=-1)


def position_jacobian(dx: FloatArray, dy: FloatArray, altitude: Any) -> FloatArray:
    r"""Jacobian of ``[r, phi]`` with respect to the target's ground position.

    .. math:: H' = \begin{bmatrix} dx/r & dy/r \\ -dy/g^2 & dx/g^2 \end{bmatrix}

    Returns
    -------
    (..., 2, 2); the velocity columns of the full Jacobian are zero.
    """
    g2 = dx * dx + dy * dy
    r = np.sqrt(g2 + np.asarray(altitude, dtype=float) ** 2)
    H = np.empty(np.broadcast(dx, dy, r).shape + (2, 2))
    H[..., 0, 0] = dx / r
    H[..., 0, 1] = dy / r
    with np.errstate(divide="ignore", invalid="ignore"):
        H[..., 1, 0] = -dy / g2
        H[..., 1, 1] = dx / g2
    return H


def jacobian(x: FloatArray, sensor_xy: FloatArray, altitude: Any) -> FloatArray:
    """Full analytic Jacobian ``(..., 2, 4)`` of ``[r, phi]`` w.r.t. ``[x, y, vx, vy]``."""
    dx, dy = ground_offset(np.asarray(x)[..., :2], sensor_xy)
    Hp = position_jacobian(dx, dy, altitude)
    H = np.zeros(Hp.shape[:-1] + (4,))
    H[..., :2] = Hp
    return H


def cos_boresight(dx: FloatArray, dy: FloatArray, heading: Any, params: SensorParams) -> FloatArray:
    r"""Cosine of the angle psi between line of sight and boresight.

    .. math:: \cos\psi = b\cdot u,\ b = (\cos\delta\cos\theta, \cos\delta\sin\theta,
              -\sin\delta),\ u = (dx, dy, -z)/r
    """
    z = np.asarray(params.altitude, dtype=float)
    dep = np.asarray(params.depression, dtype=float)
    r = np.sqrt(dx * dx + dy * dy + z * z)
    horiz = dx * np.cos(heading) + dy * np.sin(heading)
    return (np.cos(dep) * horiz + np.sin(dep) * z) / r


def noise_std(r: FloatArray, cos_psi: FloatArray,
              params: SensorParams) -> tuple[FloatArray, FloatArray]:
    r"""Range (m) and azimuth (rad) noise standard deviations (SPEC 2, SNR model).

    .. math::
        \mathrm{SNR} = 10^{\mathrm{snr_{ref}}/10} (r_{ref}/r)^4,\quad
        \sigma_r = \frac{\Delta r}{\sqrt{2\,\mathrm{SNR}}},\quad
        \sigma_\phi = \frac{\beta / \cos\psi}{k_m \sqrt{2\,\mathrm{SNR}}}
    """
    snr = 10.0 ** (np.asarray(params.snr_ref_db) / 10.0) * (np.asarray(params.range_ref) / r) ** 4
    root = np.sqrt(2.0 * snr)
    sigma_r = np.asarray(params.range_resolution) / root
    with np.errstate(divide="ignore"):
        sigma_phi = (np.asarray(params.beamwidth) / cos_psi) / (np.asarray(params.monopulse_slope) * root)
    return sigma_r, sigma_phi


def noise_cov(x: FloatArray, sensor_xy: FloatArray, heading: Any, params: SensorParams) -> FloatArray:
    """Measurement noise covariance ``R`` ``(..., 2, 2)`` at target states or positions."""
    dx, dy = ground_offset(np.asarray(x)[..., :2], sensor_xy)
    r = np.sqrt(dx * dx + dy * dy + np.asarray(params.altitude, dtype=float) ** 2)
    sr, sp = noise_std(r, cos_boresight(dx, dy, heading, params), params)
    R = np.zeros(np.broadcast(sr, sp).shape + (2, 2))
    R[..., 0, 0] = sr * sr
    R[..., 1, 1] = sp * sp
    return R


def visible_offset(dx: FloatArray, dy: FloatArray, heading: Any, params: SensorParams) -> BoolArray:
    """Field-of-view test on ground offsets (bounds inclusive; SPEC 2)."""
    g = np.hypot(dx, dy)
    in_band = (g >= np.asarray(params.min_ground_range) - RANGE_TOL) & (
        g <= np.asarray(params.max_ground_range) + RANGE_TOL)
    off = np.abs(wrap_angle(np.arctan2(dy, dx) - heading))
    in_wedge = off <= np.asarray(params.fov_half_angle) + ANGLE_TOL
    return in_band & in_wedge & (cos_boresight(dx, dy, heading, params) > 0.0)


def visible(x: FloatArray, sensor_xy: FloatArray, heading: Any, params: SensorParams) -> BoolArray:
    """Whether targets ``(..., 2|4)`` lie in the field of view of sensors at ``sensor_xy``."""
    dx, dy = ground_offset(np.asarray(x)[..., :2], sensor_xy)
    return visible_offset(dx, dy, heading, params)


def detection_probability(mean_xy: FloatArray, C: FloatArray, sensor_xy: FloatArray,
                          heading: Any, params: SensorParams) -> FloatArray:
    r"""Probability ``p_vis`` that a target with ground position ``N(mean, C)`` is visible.

    Linearised at the mean, with ground range and azimuth treated as independent (SPEC 4):

    .. math::
        p = [\Phi(\tfrac{g_{max}-\bar g}{s_g}) - \Phi(\tfrac{g_{min}-\bar g}{s_g})]
            [\Phi(\tfrac{f-d}{s_\phi}) - \Phi(\tfrac{-f-d}{s_\phi})],\quad
        s_g^2 = u^T C u,\ s_\phi^2 = v^T C v / \bar g^2

    Parameters
    ----------
    mean_xy : (..., 2)
    C : (..., 2, 2)   position covariance
    sensor_xy : (..., 2)
    heading : (...)

    Returns
    -------
    (...,) float64 in [0, 1]; 0 when ``gbar = 0`` or ``cos psi <= 0`` at the mean.
    """
    dx, dy = ground_offset(mean_xy, sensor_xy)
    g = np.hypot(dx, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        ux, uy = dx / g, dy / g
        var_g = ux * ux * C[..., 0, 0] + 2 * ux * uy * C[..., 0, 1] + uy * uy * C[..., 1, 1]
        var_v = uy * uy * C[..., 0, 0] - 2 * ux * uy * C[..., 0, 1] + ux * ux * C[..., 1, 1]
        sd_g = np.sqrt(np.maximum(var_g, 0.0))
        sd_phi = np.sqrt(np.maximum(var_v, 0.0)) / g
        d = wrap_angle(np.arctan2(dy, dx) - heading)
        fov = np.asarray(params.fov_half_angle)
        p_range = _interval_mass(np.asarray(params.min_ground_range) - g,
                                 np.asarray(params.max_ground_range) - g, sd_g)
        p_az = _interval_mass(-fov - d, fov - d, sd_phi)
    p = p_range * p_az
    ok = (g > 0) & (cos_boresight(dx, dy, heading, params) > 0.0)
    return np.where(ok, p, 0.0)


def _interval_mass(lo: FloatArray, hi: FloatArray, sd: FloatArray) -> FloatArray:
    """``Ncdf(hi/sd) - Ncdf(lo/sd)``; a zero ``sd`` gives the indicator of ``lo <= 0 <= hi``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a = ndtr(hi / sd) - ndtr(lo / sd)
    point = ((lo <= 0) & (hi >= 0)).astype(float)
    return np.where(sd > 0, a, point)
