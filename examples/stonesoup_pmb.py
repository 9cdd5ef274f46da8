"""sensorplan's PMB tracker as a Stone Soup tracker, against Stone Soup's JPDA on the same scans.

Stone Soup's own simulators make the scenario: ``MultiTargetGroundTruthSimulator`` (targets
born and dying at random, constant-velocity motion) and ``SimpleDetectionSimulator`` (a
linear position sensor with missed detections and false alarms over the map). The scans are
recorded once; then ``PMBStoneSoupTracker`` (sensorplan's PMB tracker behind Stone Soup's
tracker interface) and Stone Soup's JPDA tracker (``JPDA`` data associator, 2-of-2
``MultiMeasurementInitiator``, ``UpdateTimeStepsDeleter(3)``) track the same scans. For each,
the mean over scans of GOSPA (p = 2, alpha = 2, cut-off --c, on positions) is printed twice:
from Stone Soup's ``GOSPAMetric`` and from sensorplan's ``set_metrics.gospa``; they agree.
"""

from __future__ import annotations

import argparse
import datetime
from collections.abc import Sequence
from typing import Any

import numpy as np
from stonesoup.deleter.time import UpdateTimeStepsDeleter
from stonesoup.measures import Euclidean
from stonesoup.metricgenerator.ospametric import GOSPAMetric
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity)
from stonesoup.simulator.simple import MultiTargetGroundTruthSimulator, SimpleDetectionSimulator
from stonesoup.types.state import GaussianState

from sensorplan.integrations.stonesoup import MapRect, PMBStoneSoupTracker, gaussian_cell_masses
from sensorplan.integrations.stonesoup._peers import BenchmarkModel, jpda_tracker
from sensorplan.models.linear import LinearSensor
from sensorplan.models.motion import cv_matrices
from sensorplan.study.set_metrics import gospa

T0 = datetime.datetime(2026, 1, 1)
#: The map, centred on 0 as Stone Soup scenarios often are (m).
WORLD = MapRect(-150.0, -150.0, 300.0, 300.0)
Q_MOTION = 0.05          # CWNA intensity (m^2/s^3)
PD, CLUTTER, R_VAR = 0.9, 5.0, 4.0
BIRTH_RATE, DEATH = 0.08, 0.01
VEL_VAR = 4.0            # birth velocity variance (m^2/s^2)


def simulate(steps: int, seed: int) -> tuple[list[datetime.datetime], list[set[Any]],
                                             list[list[Any]]]:
    """Stone Soup's simulators: each scan's time, detections and live truth states."""
    np.random.seed(seed)          # Stone Soup's models draw from NumPy's global state
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q_MOTION)] * 2)
    mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R_VAR * np.eye(2))
    truth = MultiTargetGroundTruthSimulator(
        transition_model=transition,
        initial_state=GaussianState([[0.0], [0.0], [0.0], [0.0]],
                                    np.diag([60.0**2, VEL_VAR, 60.0**2, VEL_VAR]), timestamp=T0),
        birth_rate=BIRTH_RATE, death_probability=DEATH, number_steps=steps + 1,
        initial_number_targets=3, seed=seed)
    x0, y0 = WORLD.x0, WORLD.y0
    meas_range = np.array([[x0, x0 + WORLD.width], [y0, y0 + WORLD.height]])
    detector = SimpleDetectionSimulator(groundtruth=truth, measurement_model=mm,
                                        meas_range=meas_range, detection_probability=PD,
                                        clutter_rate=CLUTTER, seed=seed + 1)
    times, scans, truths = [], [], []
    for k, (time, detections) in enumerate(detector):
        if k == 0:
            continue              # the prior's time: no scan yet
        times.append(time)
        scans.append(set(detections))
        truths.append([path[-1] for path in truth.current[1]])
    return times, scans, truths


def model_of() -> BenchmarkModel:
    """The scenario's filter model, as the peer trackers take it."""
    F, Q = cv_matrices(1.0, Q_MOTION)
    sensor = LinearSensor((0.0, 0.0, WORLD.width, WORLD.height), R_VAR, PD, CLUTTER)
    covs = np.diag([60.0**2, 60.0**2, VEL_VAR, VEL_VAR])[None]
    return BenchmarkModel("example", sensor, WORLD, 1.0, F, Q, 1.0 - DEATH,
                          np.zeros((1, 4)), covs, np.array([BIRTH_RATE]), np.array([3.0]), 10.0)


def pmb_tracker() -> PMBStoneSoupTracker:
    """The PMB tracker on the same model: births from the same Gaussian, per grid cell."""
    masses = gaussian_cell_masses(WORLD, 25.0, [[0.0, 0.0]], [[60.0, 60.0]], [1.0])
    model = model_of()
    return PMBStoneSoupTracker(
        measurement_model=model.measurement_model, world=WORLD, dt=1.0,
        detection_probability=PD, clutter_rate=CLUTTER,
        transition_model=CombinedLinearGaussianTransitionModel([ConstantVelocity(Q_MOTION)] * 2),
        settings={"births": BIRTH_RATE * masses, "survival_probability": 1.0 - DEATH,
                  "velocity_var": VEL_VAR},
        initial_intensity=3.0 * masses, start_time=T0)


def gospa_both(truths: Sequence[Sequence[Any]], tracks: Sequence[Sequence[Any]], c: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """GOSPA ``(S, 4)`` (distance, localisation, missed, false) of each scan, by Stone Soup's
    ``GOSPAMetric`` and by sensorplan's ``gospa``, on the positions ``[x, y]``."""
    metric = GOSPAMetric(c=c, p=2, measure=Euclidean(mapping=[0, 2]))
    ss, sp = [], []
    for truth, track in zip(truths, tracks, strict=True):
        if truth or track:
            value = metric.compute_gospa_metric(list(track), list(truth))[0].value
            ss.append([value[k] for k in ("distance", "localisation", "missed", "false")])
        else:
            ss.append([0.0] * 4)
        xy_t = np.array([np.ravel(s.state_vector)[[0, 2]] for s in truth]).reshape(-1, 2)
        xy_y = np.array([np.ravel(s.state_vector)[[0, 2]] for s in track]).reshape(-1, 2)
        g = gospa(xy_t, xy_y, c)
        sp.append([g.distance, g.localisation, g.missed, g.false])
    return np.array(ss, dtype=float), np.array(sp, dtype=float)


def run(steps: int, seed: int, c: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Both trackers on one simulated scenario: name -> (Stone Soup GOSPA, ours)."""
    times, scans, truths = simulate(steps, seed)
    trackers: dict[str, Any] = {
        "pmb (sensorplan)": pmb_tracker(),
        "JPDA (Stone Soup)": jpda_tracker(model_of(), 2, UpdateTimeStepsDeleter(3), T0)}
    out = {}
    for name, tracker in trackers.items():
        reported = []
        for time, scan in zip(times, scans, strict=True):
            _, tracks = tracker.update_tracker(time, scan)
            reported.append([t.state for t in tracks])
        out[name] = gospa_both(truths, reported, c)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=60, help="scans (default 60)")
    ap.add_argument("--seed", type=int, default=2026, help="simulation seed (default 2026)")
    ap.add_argument("--c", type=float, default=10.0, help="GOSPA cut-off, m (default 10)")
    args = ap.parse_args(argv)
    if args.steps < 1:
        ap.exit(2, f"error: --steps: must be >= 1, got {args.steps}\n")
    if not args.c > 0:
        ap.exit(2, f"error: --c: must be > 0, got {args.c}\n")
    for name, (ss, sp) in run(args.steps, args.seed, args.c).items():
        print(f"{name:<18} mean GOSPA {ss[:, 0].mean():6.2f} m (Stone Soup GOSPAMetric), "
              f"{sp[:, 0].mean():6.2f} m (sensorplan gospa); parts (m^2) "
              f"localisation {sp[:, 1].mean():.1f}, missed {sp[:, 2].mean():.1f}, "
              f"false {sp[:, 3].mean():.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
