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
from ...errors import ConfigError


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


def ground_index(ndim: int, position_mapping: Sequence[int] | None = None,
                 velocity_mapping: Sequence[int] | None = None,
                 field: str = "state") -> tuple[int, int, int, int]:
    """Indices of ``[x, y, vx, vy]`` (our order) in a Stone Soup state of ``ndim`` entries.

    Without mappings, Stone Soup's constant-velocity layouts are recognised:
    ``[x, vx, y, vy]`` (4-D) and ``[x, vx, y, vy, z, vz]`` (6-D) give ``(0, 2, 1, 3)``. Any
    other state needs ``position_mapping`` (its first two entries: ground x and y) and
    ``velocity_mapping`` (vx and vy), as on Stone Soup's platforms and sensors.

    Raises
    ------
    ConfigError
        Naming ``field``, when the state's layout is not known or a mapping does not fit it.
    """
    if position_mapping is None and velocity_mapping is None:
        if ndim in (4, 6):
            return STONESOUP_ORDER
        raise ConfigError(field, f"a {ndim}-D state; expected Stone Soup's [x, vx, y, vy] (4-D) "
                                 "or [x, vx, y, vy, z, vz] (6-D), or give position_mapping="
                                 "(ix, iy) and velocity_mapping=(ivx, ivy)")
    pm = (0, 2) if position_mapping is None else tuple(position_mapping)
    vm = (1, 3) if velocity_mapping is None else tuple(velocity_mapping)
    idx = (*pm[:2], *vm[:2])
    if len(pm) < 2 or len(vm) < 2 or any(
            not isinstance(k, (int, np.integer)) or not 0 <= k < ndim for k in idx) \
            or len(set(idx)) != 4:
        raise ConfigError(field, f"position_mapping {pm} and velocity_mapping {vm} must name "
                                 f"four different entries of the {ndim}-D state "
                                 "(ground x, y, then vx, vy)")
    return tuple(int(k) for k in idx)  # type: ignore[return-value]


def from_gaussian_state(state: Any, position_mapping: Sequence[int] | None = None,
                        velocity_mapping: Sequence[int] | None = None,
                        field: str = "state") -> tuple[FloatArray, FloatArray]:
    """Mean ``(4,)`` and covariance ``(4, 4)`` in our order from a Stone Soup Gaussian state.

    A state with more entries (6-D ``[x, vx, y, vy, z, vz]``, or any layout named by the
    mappings, see :func:`ground_index`) gives its ground marginal: the ground position and
    velocity entries of the mean and the matching block of the covariance.
    """
    sv = np.asarray(state.state_vector, dtype=float).ravel()
    idx = list(ground_index(sv.size, position_mapping, velocity_mapping, field))
    P = np.asarray(state.covar, dtype=float)
    if P.shape != (sv.size, sv.size):
        raise ConfigError(field, f"covariance of shape {P.shape} does not match the "
                                 f"{sv.size}-D state")
    return sv[idx], P[np.ix_(idx, idx)]


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


def from_tracks(tracks: Iterable[Any], position_mapping: Sequence[int] | None = None,
                velocity_mapping: Sequence[int] | None = None) -> tuple[FloatArray, FloatArray]:
    """Means ``(M, 4)`` and covariances ``(M, 4, 4)`` (ours) of the tracks' latest states
    (ground marginals of larger states, see :func:`from_gaussian_state`).

    The order is the iteration order of ``tracks``; see :func:`ordered_tracks` for sets.
    """
    pairs = [from_gaussian_state(t.state if isinstance(t, Track) else t, position_mapping,
                                 velocity_mapping, field=f"tracks[{j}].state")
             for j, t in enumerate(tracks)]
    if not pairs:
        return np.zeros((0, 4)), np.zeros((0, 4, 4))
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def _track_key(track: Any) -> tuple[Any, ...]:
    """Sort key of a track from its content: the first state's time and state vector, then
    ``track.id``. Stone Soup draws track ids from ``uuid4`` (not from NumPy), so an order by id
    alone would change from run to run even with ``np.random.seed``."""
    if isinstance(track, Track):
        first = track[0] if len(track) else None
    else:
        first = getattr(track, "state", track)
    ts = getattr(first, "timestamp", None)
    sv = tuple(np.asarray(getattr(first, "state_vector", ()), dtype=float).ravel().tolist())
    return (ts is not None, ts or datetime.datetime.min, sv, str(getattr(track, "id", "")))


def ordered_tracks(tracks: Iterable[Track]) -> list[Track]:
    """Tracks as a list: a list or tuple keeps its order, any other iterable (a ``set``,
    Stone Soup's usual container) is sorted by each track's first state (its time, then its
    state vector), then ``track.id``. That order depends neither on hashing nor on Stone Soup's
    random track ids, so a loop seeded with ``np.random.seed`` plans the same way every run."""
    if isinstance(tracks, (list, tuple)):
        return list(tracks)
    return sorted(tracks, key=_track_key)


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
    if max(mapping[0], mapping[1]) >= arr.shape[0]:
        raise ValueError(f"position_mapping {tuple(mapping)} does not fit a state of "
                         f"{arr.shape[0]} entries (ground x and y are expected at "
                         f"{mapping[0]} and {mapping[1]})")
    return np.stack([arr[mapping[0], :], arr[mapping[1], :]], axis=-1)
