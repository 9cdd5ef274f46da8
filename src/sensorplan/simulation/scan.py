"""Runs of a published benchmark as its source runs it: a linear sensor scans the whole map.

A scenario with ``scan`` (:attr:`~sensorplan.simulation.scenario.Scenario.scan`) has no
platforms: every step its benchmark's linear position sensor
(:func:`sensorplan.models.linear.benchmark_sensor`) sees every live target on the map with
probability Pd, plus a Poisson number of false alarms uniform over the map, and the
``pmb`` tracker updates with that one scan. Nothing is planned.

The tracker's filter model is the benchmark's (:func:`filter_model`): its motion model,
survival probability, birth intensity and initial intensity of targets present but not
yet detected, each Gaussian of the source put on the tracker's grid of cells by its mass
in each cell. The tracker's gate, pruning and reporting thresholds and grid resolution
are the run's ``[tracker]`` settings; its ``births``, ``birth_rate``,
``survival_probability`` and ``process_noise`` are the benchmark's and not used; a
``background_birth_rate`` is added to the benchmark's births (none by default).

Randomness: the run's ``truth`` stream would draw a truth that is redrawn per run (neither
benchmark's is: :mod:`sensorplan.models.scripted`); the ``noise`` stream draws every scan
(:func:`sensorplan.models.linear.scan`: detections, noise, false alarms, in that order).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from .._types import FloatArray
from ..models import linear
from ..models.motion import cv_matrices
from ..models.scripted import (BENCHMARKS, TARGET_KIND, Vo12, Williams15, dwna_matrices,
                               scripted_truth)
from ..tracking.base import Looks
from ..tracking.pmb.map_tracker import MapModel
from ..tracking.pmb.tracker import PMBTracker
from .episode import Episode, Recorder, Sensed
from .scenario import Scenario
from .settings import RunSettings


@dataclass(frozen=True)
class FilterModel:
    """A benchmark's filter model, as the ``pmb`` tracker takes it.

    Attributes
    ----------
    F, Q : (4, 4)             linear-Gaussian motion model, state ``[x, y, vx, vy]``
    survival_probability : float
    birth_means : (B, 2)      positions of the Gaussian birth components (m)
    birth_std : (B, 2)        their position standard deviations (m)
    birth_weights : (B,)      their expected births per step
    initial_weights : (B,)    expected targets present but undetected at the start, per
                              component (same densities)
    velocity_var : float      each velocity component's prior variance (m^2/s^2)
    """

    F: FloatArray
    Q: FloatArray
    survival_probability: float
    birth_means: FloatArray
    birth_std: FloatArray
    birth_weights: FloatArray
    initial_weights: FloatArray
    velocity_var: float


def filter_model(name: str) -> FilterModel:
    """The filter model of benchmark ``name`` (see :mod:`sensorplan.models.scripted` for
    the values and their sources)."""
    bench = BENCHMARKS[name]
    if isinstance(bench, Williams15):
        F, Q = cv_matrices(bench.dt, bench.q)
        return FilterModel(F, Q, bench.p_survive, np.array([bench.birth_mean[:2]]),
                           np.array([bench.birth_std[:2]]), np.array([bench.birth_weight]),
                           np.array([bench.initial_weight]), bench.birth_std[2] ** 2)
    assert isinstance(bench, Vo12)
    F, B = dwna_matrices(bench.dt)
    n = len(bench.birth_sites)
    return FilterModel(F, bench.sigma_v ** 2 * B @ B.T, bench.p_survive, bench.birth_sites,
                       np.tile(bench.birth_std[:2], (n, 1)), np.full(n, bench.birth_weight),
                       np.zeros(n), bench.birth_std[2] ** 2)


def cell_masses(width: float, height: float, nx: int, ny: int, means: FloatArray,
                std: FloatArray, weights: FloatArray) -> FloatArray:
    """Expected number ``(nx * ny,)`` (row-major, as the tracker's grid) of a weighted sum
    of axis-aligned Gaussians in each cell of the ``nx x ny`` grid on ``[0, W] x [0, H]``:
    each component's weight times its probability mass in the cell (mass off the map is
    lost)."""
    xs = np.linspace(0.0, width, nx + 1)
    ys = np.linspace(0.0, height, ny + 1)
    mx = np.diff(ndtr((xs[None, :] - means[:, :1]) / std[:, :1]), axis=1)     # (B, nx)
    my = np.diff(ndtr((ys[None, :] - means[:, 1:]) / std[:, 1:]), axis=1)     # (B, ny)
    return np.einsum("b,by,bx->yx", np.asarray(weights, float), my, mx).reshape(-1)


def make_scan_tracker(scenario: Scenario, settings: RunSettings) -> PMBTracker:
    """The ``pmb`` tracker of a scan scenario with its benchmark's filter model."""
    assert scenario.scan is not None
    model = filter_model(scenario.scan)
    tr = settings.tracker
    W, H = scenario.world.width, scenario.world.height
    map_model = MapModel(linear.benchmark_sensor(scenario.scan), scenario.dt, (W, H),
                         motion=(model.F, model.Q), resolution=tr.grid_resolution,
                         velocity_var=model.velocity_var,
                         gate_probability=tr.gate_probability)
    grid = map_model.grid()
    births = cell_masses(W, H, grid.nx, grid.ny, model.birth_means, model.birth_std,
                         model.birth_weights)
    tracker = PMBTracker(map_model, survival_probability=model.survival_probability,
                         births=births, background_birth_rate=tr.background_birth_rate,
                         prune_threshold=tr.prune_threshold,
                         report_threshold=tr.report_threshold,
                         recycle_threshold=tr.recycle_threshold,
                         termination_threshold=tr.termination_threshold)
    # The source's initial intensity has the birth density, not the even spread the
    # tracker's ``initial_undetected`` gives.
    tracker.undetected = cell_masses(W, H, grid.nx, grid.ny, model.birth_means,
                                     model.birth_std, model.initial_weights)
    return tracker


def run_scan_episode(scenario: Scenario, settings: RunSettings,
                     streams: dict[str, np.random.SeedSequence], seed: np.random.SeedSequence,
                     progress: Callable[[int, int], None] | None = None) -> Episode:
    """One run of a scan scenario (see the module docstring); the arguments as
    :func:`sensorplan.simulation.run.run_episode` has them. The episode records the scan
    as one sensor at the map's centre (heading 0) that looks at no track."""
    assert scenario.scan is not None
    S = settings.steps
    truth = scripted_truth(scenario.scan, np.random.default_rng(streams["truth"]))
    if S > truth.steps:
        raise ValueError(f"the {scenario.scan} truth has {truth.steps} steps, not {S}")
    sensor = linear.benchmark_sensor(scenario.scan)
    rng = np.random.default_rng(streams["noise"])
    tracker = make_scan_tracker(scenario, settings)
    centre = np.array([[scenario.world.width / 2, scenario.world.height / 2]])
    heading = np.zeros(1)
    aimed = np.full(1, -1, dtype=np.int64)
    record = Recorder(S, 0, 1)
    record.start(np.zeros((0, 4)), tracker.tracks(), centre, heading)
    for t in range(1, S + 1):
        x_true, alive = truth.step()
        predicted = tracker.predict()
        live = np.flatnonzero(alive)
        z, detected_live = linear.scan(sensor, x_true[live, :2], rng)
        detected = np.zeros((len(alive), 1), dtype=bool)
        detected[live, 0] = detected_live
        looks = Looks(np.zeros(1, dtype=np.int64), aimed, centre, heading, (z,))
        n_false = np.array([len(z) - int(detected_live.sum())], dtype=np.int64)
        sensed = Sensed(seen=np.zeros(1, dtype=bool), missed=np.zeros(1, dtype=bool),
                        false_alarms=n_false, measured=detected)
        update = tracker.update(looks)
        record.pose(t, centre, heading)
        record.step(t, x_true, alive, tracker.tracks(), aimed, looks, sensed, predicted,
                    update)
        if progress is not None:
            progress(t, S)
    kinds = (TARGET_KIND,) * record.arrays["alive"].shape[1]
    return record.episode(kinds, settings, seed)
