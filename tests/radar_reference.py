"""The radar model written out in plain numpy: the tests' independent second computation.

This is the slow, readable version of what :mod:`sensorplan.models.radar` computes with compiled
kernels (range, bearing, Jacobian, noise, field of view and the probability of seeing a
target whose position is uncertain). It shares no code with the library's radar: the tests
check the two against each other to 1e-12.

Every function broadcasts over leading batch axes; sensor parameters are a
:class:`~sensorplan.models.sensors.SensorParams` whose fields may be floats or arrays (see
:func:`stack_params`).
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np
from scipy.special import ndtr

from sensorplan.models.sensors import SensorParams

RANGE_TOL = 1e-9
ANGLE_TOL = 1e-12
P_VIS_MIN = 1e-6


FloatArray = BoolArray = np.ndarray


def wrap_angle(a: Any) -> FloatArray:
    """Wrap to (-pi, pi], independently of :func:`sensorplan.models.angles.wrap_angle`."""
    a = np.asarray(a, dtype=float)
    w = np.arctan2(np.sin(a), np.cos(a))
    return np.where(w <= -math.pi, w + 2 * math.pi, w)


_SCALAR_FIELDS = tuple(f.name for f in fields(SensorParams)
                       if f.name not in ("moves", "detection"))


def stack_params(params: list[SensorParams] | tuple[SensorParams, ...]) -> SensorParams:
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
    r"""Range (m) and azimuth (rad) noise standard deviations (SNR model and error floors).

    .. math::
        \mathrm{SNR} = 10^{\mathrm{snr_{ref}}/10} (r_{ref}/r)^4,\quad
        \sigma_r = \Big|\Big(\frac{\Delta r}{\sqrt{2\,\mathrm{SNR}}}, f_r\Big)\Big|,\quad
        \sigma_\phi = \Big|\Big(\frac{\beta / \cos\psi}{k_m \sqrt{2\,\mathrm{SNR}}},
        f_\phi\Big)\Big|
    """
    snr = 10.0 ** (np.asarray(params.snr_ref_db) / 10.0) * (np.asarray(params.range_ref) / r) ** 4
    root = np.sqrt(2.0 * snr)
    sigma_r = np.hypot(np.asarray(params.range_resolution) / root,
                       np.asarray(params.range_error_floor, dtype=float))
    with np.errstate(divide="ignore"):
        sigma_phi = np.hypot((np.asarray(params.beamwidth) / cos_psi)
                             / (np.asarray(params.monopulse_slope) * root),
                             np.asarray(params.azimuth_error_floor, dtype=float))
    return sigma_r, sigma_phi


def noise_cov(x: FloatArray, sensor_xy: FloatArray, heading: Any,
              params: SensorParams) -> FloatArray:
    """Measurement noise covariance ``R`` ``(..., 2, 2)`` at target states or positions."""
    dx, dy = ground_offset(np.asarray(x)[..., :2], sensor_xy)
    r = np.sqrt(dx * dx + dy * dy + np.asarray(params.altitude, dtype=float) ** 2)
    sr, sp = noise_std(r, cos_boresight(dx, dy, heading, params), params)
    R = np.zeros(np.broadcast(sr, sp).shape + (2, 2))
    R[..., 0, 0] = sr * sr
    R[..., 1, 1] = sp * sp
    return R


def visible_offset(dx: FloatArray, dy: FloatArray, heading: Any, params: SensorParams) -> BoolArray:
    """Field-of-view test on ground offsets (bounds inclusive)."""
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

    Linearised at the mean, with ground range and azimuth treated as independent:

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


def look_information(params: SensorParams, visibility: str, dx: FloatArray, dy: FloatArray,
                     th: FloatArray, C: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Weight and ``weight * H'^T R^-1 H'`` of planned looks; ``C`` is ``(..., 3)``."""
    if visibility == "mean":
        weight = visible_offset(dx, dy, th, params).astype(float)
    else:
        Cm = np.stack([C[..., 0], C[..., 1], C[..., 1], C[..., 2]], axis=-1)
        Cm = Cm.reshape(C.shape[:-1] + (2, 2))
        weight = detection_probability(np.stack([dx, dy], axis=-1), Cm, np.zeros(2), th,
                                       params)
        weight = np.where(weight >= P_VIS_MIN, weight, 0.0)
    return information_matrix(dx, dy, th, params, weight), weight


def information_matrix(dx: FloatArray, dy: FloatArray, heading: FloatArray,
                       params: SensorParams, weight: FloatArray) -> FloatArray:
    """``weight * H'^T R^-1 H'`` from the explicit Jacobian and noise (zero where weight = 0)."""
    H = position_jacobian(dx, dy, params.altitude)                       # (..., 2, 2)
    r = np.sqrt(dx * dx + dy * dy + np.asarray(params.altitude, dtype=float) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sr, sp = noise_std(r, cos_boresight(dx, dy, heading, params), params)
        Rinv = np.zeros(H.shape)
        Rinv[..., 0, 0] = 1.0 / (sr * sr)
        Rinv[..., 1, 1] = 1.0 / (sp * sp)
        W = np.swapaxes(H, -1, -2) @ Rinv @ H
    return np.where((weight > 0)[..., None, None], weight[..., None, None] * W, 0.0)
