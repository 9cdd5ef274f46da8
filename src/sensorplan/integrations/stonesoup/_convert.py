"""Converters between sensorplan arrays and Stone Soup states and tracks (exact permutations)."""

from __future__ import annotations

import datetime
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from stonesoup.types.array import CovarianceMatrix, StateVector
from stonesoup.types.groundtruth import GroundTruthState
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track

from ..._types import FloatArray


# --------------------------------------------------------------------------------------------
# Converters
# --------------------------------------------------------------------------------------------

#: ``STONESOUP_ORDER[k]`` is the sensorplan index of Stone Soup state entry k:
#: Stone Soup ``[x, vx, y, vy]`` = sensorplan ``[x, y, vx, vy]`` taken at ``(0, 2, 1, 3)``.
#: The permutation is its own inverse, so the same index converts both ways.
STONESOUP_ORDER = (0, 2, 1, 3)
_ORDER = np.array(STONESOUP_ORDER)


def to_stonesoup_mean(x: Any) -> FloatArray:
    """Reorder states ``(..., 4)`` from ``[x, y, vx, vy]`` to Stone Soup's ``[x, vx, y, vy]``."""
    return np.asarray(x, dtype=float)[..., _ORDER]


def from_stonesoup_mean(v: Any) -> FloatArray:
    """Reorder states ``(..., 4)`` from Stone Soup's ``[x, vx, y, vy]`` to ``[x, y, vx, vy]``."""
    return np.asarray(v, dtype=float)[..., _ORDER]


def to_stonesoup_cov(P: Any) -> FloatArray:
    """Reorder covariances ``(..., 4, 4)`` (rows and columns) to Stone Soup's state order."""
    P = np.asarray(P, dtype=float)
    return P[..., _ORDER, :][..., :, _ORDER]


def from_stonesoup_cov(P: Any) -> FloatArray:
    """Reorder covariances ``(..., 4, 4)`` from Stone Soup's state order to ours."""
    return to_stonesoup_cov(P)


def to_gaussian_state(mean: Any, cov: Any,
                      timestamp: datetime.datetime | None = None) -> GaussianState:
    """A Stone Soup ``GaussianState`` from a mean ``(4,)`` and covariance ``(4, 4)`` (ours)."""
    return GaussianState(StateVector(to_stonesoup_mean(np.reshape(mean, 4))),
                         CovarianceMatrix(to_stonesoup_cov(cov)), timestamp=timestamp)


def from_gaussian_state(state: Any) -> tuple[FloatArray, FloatArray]:
    """Mean ``(4,)`` and covariance ``(4, 4)`` in our order from a Stone Soup Gaussian state."""
    sv = np.asarray(state.state_vector, dtype=float).reshape(4)
    return from_stonesoup_mean(sv), from_stonesoup_cov(np.asarray(state.covar, dtype=float))


def to_tracks(means: Any, covs: Any, timestamp: datetime.datetime | None = None) -> list[Track]:
    """One Stone Soup ``Track`` per target, each holding one ``GaussianState``.

    Parameters
    ----------
    means : (M, 4)   ``[x, y, vx, vy]``
    covs : (M, 4, 4)
    timestamp : datetime, optional

    Returns
    -------
    list of M tracks, in target order.
    """
    means = np.asarray(means, dtype=float)
    covs = np.broadcast_to(np.asarray(covs, dtype=float), means.shape + (4,))
    return [Track([to_gaussian_state(m, P, timestamp)]) for m, P in zip(means, covs)]


def from_tracks(tracks: Iterable[Any]) -> tuple[FloatArray, FloatArray]:
    """Means ``(M, 4)`` and covariances ``(M, 4, 4)`` (ours) of the tracks' latest states.

    The order is the iteration order of ``tracks``; see :func:`ordered_tracks` for sets.
    """
    pairs = [from_gaussian_state(t.state if isinstance(t, Track) else t) for t in tracks]
    if not pairs:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def ordered_tracks(tracks: Iterable[Track]) -> list[Track]:
    """Tracks as a list: a list or tuple keeps its order, any other iterable (a ``set``,
    Stone Soup's usual container) is sorted by ``track.id`` so the order never depends on
    hashing."""
    if isinstance(tracks, (list, tuple)):
        return list(tracks)
    return sorted(tracks, key=lambda t: str(getattr(t, "id", "")))


def to_ground_truth_state(x: Any, timestamp: datetime.datetime | None = None,
                          metadata: Mapping[str, Any] | None = None) -> GroundTruthState:
    """A Stone Soup ``GroundTruthState`` from a true state ``(4,)`` in our order."""
    return GroundTruthState(StateVector(to_stonesoup_mean(np.reshape(x, 4))),
                            timestamp=timestamp, metadata=dict(metadata or {}))


def _ground_xy(state: Any, mapping: Sequence[int]) -> FloatArray:
    """Ground positions ``(n, 2)`` of a Stone Soup state, state vector(s) or array."""
    sv = state.state_vector if hasattr(state, "state_vector") else state
    arr = np.asarray(sv, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    return np.stack([arr[mapping[0], :], arr[mapping[1], :]], axis=-1)
