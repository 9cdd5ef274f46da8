"""The multi-target trackers' tests' scenes: one step's looks, the two targets and two
sensors the contract checks use, one Bernoulli under a sensor that sees the whole map, and
the moment-matched Gaussian of a mixture written out."""

from __future__ import annotations

import numpy as np

from sensorplan.models import linear
from sensorplan.tracking.base import Looks
from sensorplan.tracking.pmb.map_tracker import MapModel
from sensorplan.tracking.pmb.tracker import PMBTracker

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


#: One Bernoulli's prior on the 300 m map of :func:`linear_pmb`.
LINEAR_P0 = np.diag([400.0, 400.0, 4.0, 4.0])
LINEAR_MEAN = np.array([[150.0, 150.0, 1.0, -1.0]])


def one_scan(z: np.ndarray) -> Looks:
    """One look of sensor 0 holding detections ``z (m, 2)``."""
    return looks_of([0], np.zeros((1, 2)), [0.0], (np.asarray(z, dtype=float).reshape(-1, 2),))


def linear_pmb(existence: float = 0.99, **options: object) -> PMBTracker:
    """A PMB tracker of one Bernoulli (:data:`LINEAR_MEAN`, :data:`LINEAR_P0`) under a
    linear position sensor over the whole 300 m map (R = I, Pd 0.9, 10 false alarms a
    scan), with ``options``."""
    sensor = linear.LinearSensor((0.0, 0.0, 300.0, 300.0), 1.0, 0.9, 10.0)
    model = MapModel(sensor, 1.0, (300.0, 300.0), velocity_var=2.0)
    return PMBTracker(model, means=LINEAR_MEAN, covs=LINEAR_P0, existence=existence,
                      **options)  # type: ignore[arg-type]


def moments(w: np.ndarray, m: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The moment-matched Gaussian of components with weights ``w`` (normalised here)."""
    a = w / w.sum()
    mean = np.einsum("k,ki->i", a, m)
    d = m - mean
    return mean, np.einsum("k,kij->ij", a, P + np.einsum("ki,kj->kij", d, d))
