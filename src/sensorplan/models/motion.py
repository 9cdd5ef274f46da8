r"""The filter's motion model: continuous white-noise acceleration.

State order is ``[x, y, vx, vy]``; arrays are row vectors shaped ``(..., 4)``.
"""

from __future__ import annotations

import functools

import numpy as np

from .._types import FloatArray


def cv_matrices(dt: float, q: float) -> tuple[FloatArray, FloatArray]:
    r"""Transition ``F(dt)`` and process noise ``Q(dt)`` of the CWNA model.

    .. math::
        F = \begin{bmatrix} I & dt I \\ 0 & I \end{bmatrix},\quad
        Q = q \begin{bmatrix} dt^3/3\, I & dt^2/2\, I \\ dt^2/2\, I & dt\, I \end{bmatrix}

    Parameters
    ----------
    dt : float
        Step (s), > 0.
    q : float
        Process noise intensity (m^2/s^3), >= 0.

    Returns
    -------
    F, Q : (4, 4) float64
    """
    F, unit_Q = _cv_templates(float(dt))
    return F.copy(), q * unit_Q


@functools.lru_cache(maxsize=64)
def _cv_templates(dt: float) -> tuple[FloatArray, FloatArray]:
    """``F(dt)`` and ``Q(dt)`` for ``q = 1`` (read-only): built once per step length, as
    every decision and filter step asks for the same ones."""
    eye = np.eye(2)
    F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
    unit_Q = np.block([[dt**3 / 3 * eye, dt**2 / 2 * eye], [dt**2 / 2 * eye, dt * eye]])
    F.flags.writeable = False
    unit_Q.flags.writeable = False
    return F, unit_Q


def predict_means(x0: FloatArray, F: FloatArray, steps: int) -> FloatArray:
    """Means predicted ``0..steps`` steps ahead without updates.

    Parameters
    ----------
    x0 : (..., 4)
    F : (4, 4)
    steps : int

    Returns
    -------
    (..., steps + 1, 4)
    """
    x0 = np.asarray(x0, dtype=float)
    out = np.empty(x0.shape[:-1] + (steps + 1, 4))
    out[..., 0, :] = x0
    for t in range(1, steps + 1):
        out[..., t, :] = out[..., t - 1, :] @ F.T
    return out


def aim_points(means: FloatArray, F: FloatArray, horizon: int = 1,
               steps_per_epoch: int = 1) -> FloatArray:
    """Ground positions the heading rule aims at: each mean predicted, without updates, to
    the first step of each epoch, ``xbar((k-1) e + 1)[:2]`` for k = 1..K.

    Parameters
    ----------
    means : (..., 4)         the means at the decision (step 0)
    F : (4, 4)
    horizon : int            K epochs
    steps_per_epoch : int    e steps each

    Returns
    -------
    (..., K, 2)  C-contiguous
    """
    xbar = predict_means(means, F, (horizon - 1) * steps_per_epoch + 1)
    return np.ascontiguousarray(xbar[..., 1::steps_per_epoch, :2])


def predict_covariance(P: FloatArray, F: FloatArray, Q: FloatArray) -> FloatArray:
    """One prediction step ``F P F^T + Q`` for ``(..., 4, 4)`` covariances, symmetrised."""
    Pp = F @ P @ F.T + Q
    return 0.5 * (Pp + np.swapaxes(Pp, -1, -2))


def predict_covariances(P0: FloatArray, F: FloatArray, Q: FloatArray, steps: int) -> FloatArray:
    """Covariances predicted ``0..steps`` steps ahead without measurements.

    Returns
    -------
    (..., steps + 1, 4, 4)
    """
    P0 = np.asarray(P0, dtype=float)
    out = np.empty(P0.shape[:-2] + (steps + 1, 4, 4))
    out[..., 0, :, :] = P0
    for t in range(1, steps + 1):
        out[..., t, :, :] = predict_covariance(out[..., t - 1, :, :], F, Q)
    return out
