r"""sensorplan's Poisson multi-Bernoulli tracker as a Stone Soup tracker.

:class:`PMBStoneSoupTracker` iterates ``(time, tracks)`` over a Stone Soup detector, as Stone
Soup's own trackers do, or takes one scan at a time (:meth:`~PMBStoneSoupTracker.update_tracker`).
Each scan goes to :class:`sensorplan.tracking.pmb.tracker.PMBTracker` as one look of the
linear position sensor (:mod:`sensorplan.models.linear`); the Bernoullis it reports become
Stone Soup :class:`~stonesoup.types.track.Track`\ s whose id is the Bernoulli's label and
whose states are :class:`BernoulliGaussianState`\ s carrying the existence probability.

Two sensors are offered. The linear position sensor that scans the whole map: a Stone
Soup ``LinearGaussian`` measurement model with ``ndim_state = 4``, ``mapping = (0, 2)``
(the position of Stone Soup's ``[x, vx, y, vy]``) and an isotropic ``noise_covar = sigma^2
I``; any other measurement model is refused with a ``TypeError`` or ``ValueError`` naming
what is wrong. Or sensorplan's aimed radars (:class:`SensorplanRadar`, ``radars``): each scan
is one look of every radar from its pose at the scan, so a look sees only its sensing
region, and the undetected intensity is thinned there only (what makes search worth
planning, :meth:`PMBStoneSoupTracker.undetected_intensity`).
"""

from __future__ import annotations

import datetime
import math
from dataclasses import fields
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.special import ndtr
from stonesoup.base import Property
from stonesoup.models.base import GaussianModel, LinearModel
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.base import TransitionModel
from stonesoup.reader import DetectionReader
from stonesoup.tracker.base import Tracker, _TrackerMixInNext
from stonesoup.types.detection import Detection
from stonesoup.types.numeric import Probability
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track

from ..._types import FloatArray
from ...models.linear import LinearSensor
from ...models.sensors import radar_table
from ...planners.problem import UndetectedIntensity
from ...tracking.base import Looks
from ...tracking.pmb.map_tracker import MapModel
from ...tracking.pmb.tracker import PMBTracker
from ...tracking.pmb.undetected import make_grid
from ._actionables import SensorplanRadar
from ._convert import from_stonesoup_cov, to_stonesoup_cov, to_stonesoup_mean
from ._measurement import RadarMeasurementModel
from ._world import MapRect

#: Relative tolerance of a scan's time gap against a whole number of steps.
_TIME_TOL = 1e-6
#: Largest difference (m, rad) between a detection's radar pose and a managed radar's.
_POSE_TOL = 1e-9
#: The keys of ``settings`` that are fields of the map model (the adapter gives the sensor,
#: the step, the map and the motion itself).
_MODEL_SETTINGS = tuple(f.name for f in fields(MapModel)
                        if f.name not in ("measurement", "dt", "world", "motion"))


class BernoulliGaussianState(GaussianState):
    """A Gaussian state of a Bernoulli: the target's density given that it exists, and the
    probability that it exists."""

    existence_probability: Probability = Property(
        default=Probability(1.0), doc="Probability that the target exists.")


def linear_sensor(model: Any, world: MapRect, detection_probability: float,
                  clutter_rate: float) -> LinearSensor:
    """The linear position sensor (in the core's frame, ``[0, W] x [0, H]``) that a Stone
    Soup ``LinearGaussian`` position model describes over ``world``.

    Raises
    ------
    TypeError
        ``model`` is not a ``LinearGaussian``.
    ValueError
        Its ``ndim_state`` is not 4, its ``mapping`` is not ``(0, 2)``, or its noise is not
        ``sigma^2 I``.
    """
    if not isinstance(model, LinearGaussian):
        raise TypeError("measurement_model: the PMB tracker takes Stone Soup's LinearGaussian "
                        f"position model only, got {type(model).__name__}")
    if model.ndim_state != 4 or tuple(int(i) for i in model.mapping) != (0, 2):
        raise ValueError("measurement_model: must measure the position of a [x, vx, y, vy] "
                         f"state (ndim_state=4, mapping=(0, 2)), got ndim_state="
                         f"{model.ndim_state}, mapping={tuple(model.mapping)}")
    R = np.asarray(model.covar(), dtype=float)
    var = float(R[0, 0])
    if R.shape != (2, 2) or not np.allclose(R, var * np.eye(2), rtol=1e-12, atol=0.0):
        raise ValueError("measurement_model: noise_covar must be sigma^2 I (the same variance "
                         f"on x and y, uncorrelated), got {R.tolist()}")
    return LinearSensor(area=(0.0, 0.0, world.width, world.height), noise_var=var,
                        detection_probability=float(detection_probability),
                        clutter_rate=float(clutter_rate))


def motion_matrices(model: TransitionModel, dt: float
                    ) -> tuple[FloatArray, FloatArray]:
    """``F (4, 4)`` and ``Q (4, 4)`` of a Stone Soup linear-Gaussian transition model over
    ``dt`` seconds, in sensorplan's state order ``[x, y, vx, vy]``."""
    if not (isinstance(model, TransitionModel) and isinstance(model, LinearModel)
            and isinstance(model, GaussianModel) and model.ndim_state == 4):
        raise TypeError("transition_model: must be a linear-Gaussian model of a 4-D "
                        f"[x, vx, y, vy] state, got {type(model).__name__}")
    step = datetime.timedelta(seconds=dt)
    F = np.asarray(model.matrix(time_interval=step), dtype=float)
    Q = np.asarray(model.covar(time_interval=step), dtype=float)
    return from_stonesoup_cov(F), from_stonesoup_cov(Q)


def gaussian_cell_masses(world: MapRect, resolution: float, means: Any, stds: Any,
                         weights: Any) -> FloatArray:
    """Expected number of targets in each cell of the PMB tracker's grid, ``(C,)``, of a
    Gaussian mixture intensity over ground positions: the mass each component puts on each
    cell (mass off the map is lost).

    Parameters
    ----------
    world : MapRect              the map (world coordinates)
    resolution : float           the tracker's ``resolution`` (m)
    means : (K, 2)               components' ground means, world coordinates (m)
    stds : (K, 2)                their standard deviations along x and y (m)
    weights : (K,)               their weights (expected numbers of targets)
    """
    grid = make_grid(world.width, world.height, resolution, 1.0)
    mu = np.asarray(means, dtype=float).reshape(-1, 2) - world.origin
    sd = np.asarray(stds, dtype=float).reshape(-1, 2)
    w = np.asarray(weights, dtype=float).reshape(-1)
    ex = np.linspace(0.0, grid.width, grid.nx + 1)
    ey = np.linspace(0.0, grid.height, grid.ny + 1)
    px = np.diff(ndtr((ex[None, :] - mu[:, :1]) / sd[:, :1]), axis=1)     # (K, nx)
    py = np.diff(ndtr((ey[None, :] - mu[:, 1:]) / sd[:, 1:]), axis=1)     # (K, ny)
    # Row-major cells: c = row * nx + column.
    return np.einsum("k,ky,kx->yx", w, py, px).reshape(-1)


class PMBStoneSoupTracker(_TrackerMixInNext, Tracker):
    """sensorplan's PMB tracker behind Stone Soup's tracker interface (see the module
    docstring).

    Iterating gives ``(time, tracks)`` for each scan of :attr:`detector`;
    :meth:`update_tracker` takes one scan. The tracks are the Bernoullis the PMB tracker
    reports (existence at least its ``report_threshold``, or, once confirmed, its
    ``termination_threshold``); a Bernoulli keeps its :class:`Track` (id: its label as text)
    for its life, also across steps where it is not reported.
    """

    measurement_model: LinearGaussian = Property(
        default=None, doc="The linear position sensor: a LinearGaussian with mapping (0, 2), "
                          "noise sigma^2 I (or give ``radars``).")
    world: MapRect = Property(
        doc="The map: the area the sensor scans, false alarms fall in and the undetected "
            "intensity's grid covers (world coordinates).")
    dt: float = Property(doc="Time between scans (s); a gap of k dt predicts k times.")
    detection_probability: float = Property(default=0.9, doc="P_d of a target on the map.")
    clutter_rate: float = Property(default=0.0, doc="Expected false alarms per scan.")
    transition_model: TransitionModel = Property(
        default=None, doc="Motion model; default the PMB tracker's CWNA with its "
                          "process_noise.")
    settings: Mapping[str, Any] = Property(
        default=None, doc="Further keywords of PMBTracker (births, birth_rate, "
                          "background_birth_rate, survival_probability, thresholds, "
                          "initial_undetected, edge_exit ...) and "
                          "of its MapModel (process_noise, resolution, velocity_var, "
                          "gate_probability, map_edge).")
    initial_intensity: np.ndarray = Property(
        default=None, doc="(C,) expected undetected targets per grid cell at the start "
                          "(instead of the settings' initial_undetected spread evenly).")
    start_time: datetime.datetime = Property(
        default=None, doc="Time of the prior; default one dt before the first scan.")
    detector: DetectionReader = Property(default=None, doc="Detector of the scans.")
    radars: Sequence[SensorplanRadar] = Property(
        default=None, doc="Aimed radars instead of the linear sensor: each scan is one look "
                          "of each, from its pose at the scan; their params give detection "
                          "and clutter (not detection_probability and clutter_rate).")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if (self.measurement_model is None) == (self.radars is None):
            raise ValueError("give either measurement_model (the linear sensor) or radars")
        measurement: LinearSensor | FloatArray
        if self.radars is not None:
            self.radars = list(self.radars)
            if not self.radars or not all(isinstance(r, SensorplanRadar) for r in self.radars):
                raise TypeError("radars: must be one or more SensorplanRadars")
            measurement = radar_table([r.params for r in self.radars])
        else:
            self.sensor = linear_sensor(self.measurement_model, self.world,
                                        self.detection_probability, self.clutter_rate)
            measurement = self.sensor
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be > 0, got {self.dt!r}")
        kwargs_pmb = dict(self.settings or {})
        if "motion" in kwargs_pmb:
            raise ValueError("settings: give the motion as transition_model")
        for given in ("measurement", "dt", "world"):
            if given in kwargs_pmb:
                raise ValueError(f"settings: {given} is not a setting (the adapter's "
                                 "measurement_model, dt and world give it)")
        # The settings that belong to the map model go there, the rest to the tracker.
        kwargs_model = {k: kwargs_pmb.pop(k) for k in _MODEL_SETTINGS if k in kwargs_pmb}
        if self.transition_model is not None:
            kwargs_model["motion"] = motion_matrices(self.transition_model, self.dt)
        model = MapModel(measurement, self.dt, (self.world.width, self.world.height),
                         **kwargs_model)
        self.pmb = PMBTracker(model, **kwargs_pmb)
        if self.initial_intensity is not None:
            w = np.array(self.initial_intensity, dtype=float).reshape(-1)
            if w.shape != self.pmb.undetected.shape or not np.all(np.isfinite(w) & (w >= 0)):
                raise ValueError(f"initial_intensity must be {self.pmb.grid.size} values >= 0, "
                                 "one per grid cell")
            # The tracker holds its undetected intensity as this plain array.
            self.pmb.undetected = w
        self._time = self.start_time
        self._all: dict[int, Track] = {}
        self._current: set[Track] = set()

    @property
    def tracks(self) -> set[Track]:
        return set(self._current)

    def __next__(self) -> tuple[datetime.datetime, set[Track]]:
        time, detections = next(self.detector_iter)
        return self._scan(time, detections)

    def _steps_to(self, time: datetime.datetime) -> int:
        if self._time is None:
            return 1
        gap = (time - self._time).total_seconds() / self.dt
        k = round(gap)
        if k < 1 or abs(gap - k) > _TIME_TOL * max(1.0, gap):
            raise ValueError(f"scan at {time}: {gap * self.dt:g} s after the previous one, not a "
                             f"positive whole number of dt = {self.dt:g} s")
        return int(k)

    def undetected_intensity(self, weight: float | None = None) -> UndetectedIntensity:
        """The undetected targets' Poisson intensity now (after the last scan), as planning
        takes it: cell centres in the core's frame (world minus the map's origin), expected
        undetected targets per cell, births per step, survival per step and a cell's
        position covariance; ``weight`` is the nats a newly found target is worth (None:
        the information of its first detection)."""
        grid = self.pmb.grid
        return UndetectedIntensity(np.array(grid.centres), self.pmb.undetected_cells(),
                                   np.array(self.pmb.births),
                                   float(self.pmb.survival_probability),
                                   np.array(grid.cov[:2, :2]), weight)

    def looks(self, detections: Iterable[Detection]) -> Looks:
        """One scan of the radars: a look of each radar from its pose now, with the
        detections its measurement model names (the radar at the same position and
        heading), each look's sorted by range then azimuth."""
        assert self.radars is not None
        poses = [(r.ground_position - self.world.origin, float(r.heading)) for r in self.radars]
        rows: list[list[FloatArray]] = [[] for _ in self.radars]
        for det in detections:
            model = det.measurement_model
            if not isinstance(model, RadarMeasurementModel):
                raise TypeError("detections: with radars every detection must carry its "
                                "radar's RadarMeasurementModel, got "
                                f"{type(model).__name__}")
            xy = np.asarray(model.sensor_xy, dtype=float) - self.world.origin
            at = [i for i, (p, h) in enumerate(poses)
                  if np.abs(p - xy).max() <= _POSE_TOL and abs(h - model.heading) <= _POSE_TOL]
            if not at:
                raise ValueError(f"detections: a detection from a radar at {tuple(xy)} heading "
                                 f"{model.heading:g} rad, which is none of the tracker's radars")
            rows[at[0]].append(np.asarray(det.state_vector, dtype=float).reshape(2))
        Z = []
        for r in rows:
            z = np.array(r).reshape(-1, 2)
            Z.append(z[np.lexsort((z[:, 1], z[:, 0]))])
        L = len(self.radars)
        return Looks(np.arange(L, dtype=np.int64), np.full(L, -1, dtype=np.int64),
                     np.array([p for p, _ in poses]), np.array([h for _, h in poses]),
                     tuple(Z))

    def measurements(self, detections: Iterable[Detection]) -> FloatArray:
        """Positions ``(n, 2)`` in the core's frame of a scan's detections, in a fixed order
        (sorted by x, then y: a set's order would vary between runs)."""
        rows = []
        for det in detections:
            model = det.measurement_model
            if model is not None and model is not self.measurement_model:
                linear_sensor(model, self.world, self.detection_probability, self.clutter_rate)
                if not (np.array_equal(model.covar(), self.measurement_model.covar())):
                    raise ValueError("detections: a detection's measurement model differs from "
                                     "the tracker's")
            rows.append(np.asarray(det.state_vector, dtype=float).reshape(2))
        if not rows:
            return np.zeros((0, 2))
        z = np.array(rows) - self.world.origin
        return z[np.lexsort((z[:, 1], z[:, 0]))]

    def _scan(self, time: datetime.datetime,
              detections: Iterable[Detection]) -> tuple[datetime.datetime, set[Track]]:
        for _ in range(self._steps_to(time)):
            self.pmb.predict()
        if self.radars is not None:
            self.pmb.update(self.looks(detections))
        else:
            z = self.measurements(detections)
            self.pmb.update(Looks(np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64),
                                  np.zeros((1, 2)), np.zeros(1), (z,)))
        self._time = time
        reported = self.pmb.tracks()
        means = to_stonesoup_mean(reported.means)
        means[:, [0, 2]] += self.world.origin
        covs = to_stonesoup_cov(reported.covs)
        current = set()
        for k, label in enumerate(reported.labels.tolist()):
            state = BernoulliGaussianState(means[k].reshape(4, 1), covs[k], timestamp=time,
                                           existence_probability=Probability(
                                               float(reported.existence[k])))
            track = self._all.get(label)
            if track is None:
                track = self._all[label] = Track([state], id=str(label))
            else:
                track.append(state)
            current.add(track)
        self._current = current
        # A pruned Bernoulli's label never comes back: forget its track.
        alive = set(self.pmb.bern.labels.tolist())
        for label in [lb for lb in self._all if lb not in alive]:
            del self._all[label]
        return time, set(current)


__all__ = ["BernoulliGaussianState", "PMBStoneSoupTracker", "gaussian_cell_masses",
           "linear_sensor", "motion_matrices"]
