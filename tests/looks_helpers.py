"""The multi-target trackers' tests' scenes: one step's looks, and the two targets and
two sensors the contract checks use."""

from __future__ import annotations

import numpy as np

from sensorplan.tracking.base import Looks

#: Two targets ``[x, y, vx, vy]`` and two sensor positions on the 600 m map.
MEANS = np.array([[300.0, 300.0, 1.0, 0.0], [250.0, 420.0, 0.0, 1.0]])
SENSORS = np.array([[50.0, 50.0], [500.0, 100.0]])


def looks_of(sensors: np.ndarray | list[int], xy: np.ndarray, heads: np.ndarray | list[float],
             detections: tuple[np.ndarray, ...]) -> Looks:
    """Looks of ``sensors`` from ``xy (L, 2)`` with ``heads (L,)`` and each look's
    detections; no look aimed at a track."""
    return Looks(sensors=np.asarray(sensors, dtype=np.int64),
                 aims=np.full(len(sensors), -1, dtype=np.int64),
                 positions=np.asarray(xy, dtype=float).reshape(-1, 2),
                 headings=np.asarray(heads, dtype=float), detections=detections)
