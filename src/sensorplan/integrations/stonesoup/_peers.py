r"""Stone Soup's own multi-target trackers, set up for the published filter benchmarks.

The peer comparison (``benchmarks/compare_trackers.py``) runs sensorplan's trackers and
Stone Soup's on the same detections of the ``williams15`` and ``vo12`` benchmarks
(:mod:`sensorplan.models.scripted`, sensor :mod:`sensorplan.models.linear`). This module
holds what the Stone Soup side needs:

- :class:`BenchmarkModel`: one benchmark's sensor, motion model and birth intensity as the
  source's filters use them, in both state orders, with :func:`benchmark_model`;
- :class:`GMPHDTracker`: the GM-PHD filter as Stone Soup's GM-PHD tutorial runs it (a
  ``GaussianMixtureHypothesiser`` over a ``DistanceHypothesiser``, a ``PHDUpdater``, a
  ``GaussianMixtureReducer``, birth components added before each scan), reporting at each
  scan the components whose weight exceeds a state threshold;
- :func:`jpda_tracker`: Stone Soup's JPDA (the exhaustive ``JPDA`` data associator, or
  ``JPDAwithLBP``, its loopy-belief-propagation approximation, over a ``PDAHypothesiser``;
  ``MultiTargetMixtureTracker``) with a ``MultiMeasurementInitiator`` (tentative tracks
  confirmed by ``min_points`` consecutive detections) and a deleter;
- :func:`to_detections`: one scan's positions as Stone Soup ``Detection``\ s.
"""

from __future__ import annotations

import datetime
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from stonesoup.base import Property
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.dataassociator.probability import JPDA, JPDAwithLBP
from stonesoup.deleter.base import Deleter
from stonesoup.deleter.error import CovarianceBasedDeleter
from stonesoup.deleter.time import UpdateTimeStepsDeleter
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.hypothesiser.gaussianmixture import GaussianMixtureHypothesiser
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import Mahalanobis
from stonesoup.mixturereducer.gaussianmixture import GaussianMixtureReducer
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import LinearGaussianTimeInvariantTransitionModel
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.reader import DetectionReader
from stonesoup.tracker.base import Tracker, _TrackerMixInNext
from stonesoup.tracker.simple import MultiTargetMixtureTracker
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState, TaggedWeightedGaussianState
from stonesoup.types.track import Track
from stonesoup.updater.kalman import KalmanUpdater
from stonesoup.updater.pointprocess import PHDUpdater

from ..._types import FloatArray
from ...models import linear
from ...models.motion import cv_matrices
from ...models.scripted import BENCHMARKS, Vo12, Williams15, dwna_matrices
from ._convert import to_stonesoup_cov, to_stonesoup_mean
from ._world import MapRect

#: GOSPA cut-off (m) of each benchmark: williams15's source's; vo12's is the toolbox's OSPA
#: cut-off (its source states none for GOSPA).
GOSPA_C = {"williams15": 10.0, "vo12": 100.0}

#: Stone Soup's JPDA data associators by class name: ``JPDA`` enumerates every joint
#: hypothesis of the tracks that share a gated detection (exact, exponential in their
#: number); ``JPDAwithLBP`` approximates the same association probabilities by loopy belief
#: propagation (Williams and Lau), at a cost linear in the gated pairs per iteration.
JPDA_ASSOCIATORS = {"JPDA": JPDA, "JPDAwithLBP": JPDAwithLBP}


@dataclass(frozen=True)
class BenchmarkModel:
    """A benchmark's filter model, as its source's filters use it.

    Attributes
    ----------
    name : str
    sensor : LinearSensor                 the scanning sensor (core frame = world frame here:
                                          both maps start at 0)
    world : MapRect                       the map
    dt : float                            s
    F, Q : (4, 4)                         motion model, sensorplan order ``[x, y, vx, vy]``
    survival : float                      p_S per step
    birth_means : (K, 4)                  birth components' means (sensorplan order)
    birth_covs : (K, 4, 4)                their covariances
    birth_weights : (K,)                  expected births per step of each
    initial_weights : (K,)                expected undetected targets at the start (the same
                                          densities)
    gospa_c : float                       GOSPA cut-off (m)
    """

    name: str
    sensor: linear.LinearSensor
    world: MapRect
    dt: float
    F: FloatArray
    Q: FloatArray
    survival: float
    birth_means: FloatArray
    birth_covs: FloatArray
    birth_weights: FloatArray
    initial_weights: FloatArray
    gospa_c: float

    @property
    def velocity_var(self) -> float:
        """The birth density's velocity variance (m^2/s^2), the mean over components and
        axes."""
        return float(np.mean(self.birth_covs[:, [2, 3], [2, 3]]))

    @property
    def measurement_model(self) -> LinearGaussian:
        """Stone Soup's ``LinearGaussian`` of the sensor."""
        return LinearGaussian(ndim_state=4, mapping=(0, 2),
                              noise_covar=linear.noise(self.sensor))

    @property
    def transition_model(self) -> LinearGaussianTimeInvariantTransitionModel:
        """Stone Soup's transition model with this ``F`` and ``Q`` (Stone Soup order)."""
        return LinearGaussianTimeInvariantTransitionModel(
            transition_matrix=to_stonesoup_cov(self.F), covariance_matrix=to_stonesoup_cov(self.Q))

    @property
    def clutter_density(self) -> float:
        """False alarms per m^2."""
        return linear.clutter_density(self.sensor)


def benchmark_model(name: str) -> BenchmarkModel:
    """The filter model of benchmark ``name`` (``williams15`` or ``vo12``): the source's
    sensor, motion model, survival and birth intensity (:mod:`sensorplan.models.scripted`)."""
    bench = BENCHMARKS[name]
    W, H = bench.world_size
    world = MapRect(0.0, 0.0, W, H)
    if isinstance(bench, Williams15):
        F, Q = cv_matrices(bench.dt, bench.q)
        means = np.array([bench.birth_mean])
        covs = np.diag(np.square(bench.birth_std))[None]
        return BenchmarkModel(name, linear.williams15(), world, bench.dt, F, Q,
                              bench.p_survive, means, covs, np.array([bench.birth_weight]),
                              np.array([bench.initial_weight]), GOSPA_C[name])
    assert isinstance(bench, Vo12)
    F, B = dwna_matrices(bench.dt)
    Q = bench.sigma_v ** 2 * B @ B.T
    sites = bench.birth_sites
    means = np.column_stack([sites, np.zeros((len(sites), 2))])
    covs = np.broadcast_to(np.diag(np.square(bench.birth_std)), (len(sites), 4, 4)).copy()
    weights = np.full(len(sites), bench.birth_weight)
    return BenchmarkModel(name, linear.vo12(), world, bench.dt, F, Q, bench.p_survive, means,
                          covs, weights, np.zeros(len(sites)), GOSPA_C[name])


def to_detections(z: FloatArray, time: datetime.datetime,
                  model: LinearGaussian) -> set[Detection]:
    """One scan's positions ``(n, 2)`` (world coordinates) as Stone Soup detections."""
    return {Detection(np.asarray(row, dtype=float).reshape(2, 1), timestamp=time,
                      measurement_model=model) for row in np.asarray(z, dtype=float)}


class GMPHDTracker(_TrackerMixInNext, Tracker):
    r"""The GM-PHD filter as Stone Soup's GM-PHD tutorial runs it, as a tracker.

    Before each scan the birth components are added to the mixture; the
    ``GaussianMixtureHypothesiser`` predicts and hypothesises, the ``PHDUpdater`` updates,
    the ``GaussianMixtureReducer`` prunes and merges. The tracks of a scan are the components
    whose weight exceeds each state threshold, as Stone Soup ``Track``\ s keyed by the
    component's tag; :meth:`reported` gives them for another threshold of the same run.
    """

    hypothesiser: GaussianMixtureHypothesiser = Property(doc="Hypothesiser of the mixture.")
    updater: PHDUpdater = Property(doc="PHD updater.")
    reducer: GaussianMixtureReducer = Property(doc="Pruning and merging.")
    birth_components: Sequence[TaggedWeightedGaussianState] = Property(
        doc="Birth components, each with the expected births per step as its weight.")
    initial_components: Sequence[TaggedWeightedGaussianState] = Property(
        default=(), doc="The mixture at the start.")
    state_threshold: float = Property(default=0.5, doc="Weight a component needs to be reported.")
    detector: DetectionReader = Property(default=None, doc="Detector of the scans.")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.mixture: list[TaggedWeightedGaussianState] = list(self.initial_components)
        self._tracks: dict[str, Track] = {}

    @property
    def tracks(self) -> set[Track]:
        return set(self._tracks.values())

    def reported(self, threshold: float) -> list[TaggedWeightedGaussianState]:
        """The current components whose weight exceeds ``threshold``."""
        return [c for c in self.mixture if float(c.weight) > threshold]

    def __next__(self) -> tuple[datetime.datetime, set[Track]]:
        time, detections = next(self.detector_iter)
        current = list(self.mixture)
        for birth in self.birth_components:
            born = TaggedWeightedGaussianState(birth.state_vector, birth.covar,
                                               weight=birth.weight, tag="birth",
                                               timestamp=time)
            current.append(born)
        hypotheses = self.hypothesiser.hypothesise(current, detections, timestamp=time,
                                                   order_by_detection=True)
        self.mixture = list(self.reducer.reduce(self.updater.update(hypotheses)))
        tracks: dict[str, Track] = {}
        for component in self.reported(self.state_threshold):
            track = self._tracks.get(component.tag)
            if track is None:
                track = Track([component], id=str(component.tag))
            else:
                track.append(component)
            tracks[component.tag] = track
        self._tracks = tracks
        return time, set(tracks.values())


def gmphd_tracker(model: BenchmarkModel, start_time: datetime.datetime,
                  state_threshold: float = 0.5, merge_threshold: float = 5.0,
                  prune_threshold: float = 1e-8, missed_distance: float = 3.0) -> GMPHDTracker:
    """Stone Soup's GM-PHD filter on a benchmark, with the GM-PHD tutorial's settings
    (Mahalanobis ``missed_distance = 3``, merge threshold 5, prune threshold 1e-8) and the
    benchmark's birth intensity (its components, means, covariances and weights) and
    initial intensity."""
    mm = model.measurement_model
    predictor = KalmanPredictor(model.transition_model)
    kalman_updater = KalmanUpdater(mm)
    base = DistanceHypothesiser(predictor, kalman_updater, Mahalanobis(),
                                missed_distance=missed_distance)
    hypothesiser = GaussianMixtureHypothesiser(base, order_by_detection=True)
    updater = PHDUpdater(kalman_updater, clutter_spatial_density=model.clutter_density,
                         prob_detection=model.sensor.detection_probability,
                         prob_survival=model.survival)
    reducer = GaussianMixtureReducer(prune_threshold=prune_threshold, pruning=True,
                                     merge_threshold=merge_threshold, merging=True)

    def components(weights: FloatArray, tag: str | None) -> list[TaggedWeightedGaussianState]:
        out = []
        for m, P, w in zip(model.birth_means, model.birth_covs, weights, strict=True):
            if w > 0:
                kw: dict[str, Any] = {} if tag is None else {"tag": tag}
                out.append(TaggedWeightedGaussianState(
                    to_stonesoup_mean(m).reshape(4, 1), to_stonesoup_cov(P), weight=float(w),
                    timestamp=start_time, **kw))
        return out

    return GMPHDTracker(hypothesiser=hypothesiser, updater=updater, reducer=reducer,
                        birth_components=components(model.birth_weights, "birth"),
                        initial_components=components(model.initial_weights, None),
                        state_threshold=state_threshold)


def jpda_tracker(model: BenchmarkModel, min_points: int, deleter: Deleter,
                 start_time: datetime.datetime,
                 associator: str = "JPDA") -> MultiTargetMixtureTracker:
    """Stone Soup's JPDA tracker on a benchmark.

    The data associator ``associator`` (``JPDA`` or ``JPDAwithLBP``,
    :data:`JPDA_ASSOCIATORS`) over a ``PDAHypothesiser`` (the sensor's ``P_d`` and
    clutter density, Stone Soup's default gate probability 0.95); new tracks from a
    ``MultiMeasurementInitiator``: each unassociated detection starts a tentative track
    (position from the detection, velocity prior of the birth density), tentative tracks
    are associated by ``GNNWith2DAssignment`` (Mahalanobis ``missed_distance = 3``) and
    dropped at their first missed scan, and one with ``min_points`` detections is confirmed:
    ``min_points``-of-``min_points`` confirmation. ``deleter`` deletes confirmed tracks.
    """
    if associator not in JPDA_ASSOCIATORS:
        raise ValueError(f"associator must be one of {sorted(JPDA_ASSOCIATORS)}, "
                         f"got {associator!r}")
    mm = model.measurement_model
    predictor = KalmanPredictor(model.transition_model)
    updater = KalmanUpdater(mm)
    pda = PDAHypothesiser(predictor=predictor, updater=updater,
                          clutter_spatial_density=model.clutter_density,
                          prob_detect=model.sensor.detection_probability)
    gnn = GNNWith2DAssignment(DistanceHypothesiser(predictor, updater, Mahalanobis(),
                                                   missed_distance=3))
    v = model.velocity_var
    prior = GaussianState(np.zeros((4, 1)), np.diag([0.0, v, 0.0, v]), timestamp=start_time)
    initiator = MultiMeasurementInitiator(prior_state=prior, measurement_model=mm,
                                          deleter=UpdateTimeStepsDeleter(1),
                                          data_associator=gnn, updater=updater,
                                          min_points=min_points)
    return MultiTargetMixtureTracker(initiator=initiator, deleter=deleter, detector=None,
                                     data_associator=JPDA_ASSOCIATORS[associator](pda),
                                     updater=updater)


def jpda_deleter(kind: str, model: BenchmarkModel) -> Deleter:
    """A deleter by name: ``steps3`` / ``steps5`` (``UpdateTimeStepsDeleter``: no detection in
    the last 3 / 5 scans) or ``covariance`` (``CovarianceBasedDeleter``: the position
    covariance's trace above 10 times the measurement noise's, ``10 tr R``)."""
    if kind.startswith("steps"):
        return UpdateTimeStepsDeleter(int(kind.removeprefix("steps")))
    if kind == "covariance":
        return CovarianceBasedDeleter(covar_trace_thresh=10.0 * 2 * model.sensor.noise_var,
                                      mapping=[0, 2])
    raise ValueError(f"deleter must be steps<N> or covariance, got {kind!r}")


def positions(states: Iterable[Any]) -> FloatArray:
    """Ground positions ``(n, 2)`` of Stone Soup states ``[x, vx, y, vy]``."""
    rows = [np.asarray(s.state_vector, dtype=float).reshape(-1)[[0, 2]] for s in states]
    return np.array(rows).reshape(-1, 2)


__all__ = ["GOSPA_C", "JPDA_ASSOCIATORS", "BenchmarkModel", "GMPHDTracker", "benchmark_model",
           "gmphd_tracker", "jpda_deleter", "jpda_tracker", "positions", "to_detections"]
