# %% [markdown]
# # Missed detections and clutter: Stone Soup's PDA in a loop steered by sensorplan
#
# The loop of `stonesoup_loop.py` with real radar conditions. The radars detect a target in
# view with the Swerling 1 probability `Pd` (about 0.5-0.7 over the sensing region) and
# report about one false alarm per look (Stone Soup `Clutter`), as sensorplan's `radar`
# preset does. The tracks are kept by Stone Soup's own probabilistic data association: a
# `PDAHypothesiser` given each look's `Pd` and clutter density by the radar, the `PDA`
# associator and the `PDAUpdater`. The manager plans expecting missed detections and clutter
# (`planning_detection="aware"`, its default).
#
# Randomness is Stone Soup's habit: `np.random.seed(seed)` at the start, and every draw
# (initial states, the truth's motion, detections, misses and false alarms) comes from
# NumPy's global state; the planner has its own seeded generator. The same seed repeats the
# run exactly. Needs the extra: `pip install sensorplan[stonesoup]`.
#
# Run: `python examples/stonesoup_pda_loop.py [--steps 40] [--out stonesoup_pda_loop.png]`

# %%
"""Missed detections and clutter: the loop of stonesoup_loop.py with Swerling 1 detection
and about one false alarm per look, tracked by Stone Soup's probabilistic data association."""

from __future__ import annotations

import argparse
import datetime
import math
import time
from dataclasses import dataclass, field

import numpy as np
from stonesoup.dataassociator.probability import PDA
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity)
from stonesoup.platform import FixedPlatform
from stonesoup.predictor.kalman import ExtendedKalmanPredictor
from stonesoup.types.detection import Clutter, TrueDetection
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState
from stonesoup.types.numeric import Probability
from stonesoup.types.state import GaussianState, State
from stonesoup.types.track import Track
from stonesoup.updater.probability import PDAUpdater

from sensorplan.integrations.stonesoup import (LatticeMovable, MapRect, SensorplanManager,
                                               SensorplanRadar, execute, from_gaussian_state,
                                               ordered_detections)
from sensorplan.simulation.scenario import RADAR_DETECTION
from sensorplan.models.sensors import SensorParams

START = datetime.datetime(2024, 1, 1)
Q = 0.05                                     # m^2/s^3, truth and filter
P0 = np.diag([400.0, 4.0, 400.0, 4.0])       # Stone Soup order [x, vx, y, vy]


@dataclass
class LoopResult:
    """What the loop produced: Stone Soup objects, position errors (steps, M) and counts."""

    truths: list[GroundTruthPath]
    tracks: list[Track]
    platforms: list[FixedPlatform]
    errors: np.ndarray
    planning_seconds: list[float]
    looks: int = 0
    in_view: int = 0                         # looks whose target was in the field of view
    detected: int = 0                        # ... and detected
    false_alarms: int = 0
    clutter_xy: list[np.ndarray] = field(default_factory=list)


# %%
def build(n_targets: int = 5, **detection):
    """Ground truths, tracks and platforms at the start time (draws from np.random)."""
    truths, tracks = [], []
    for _ in range(n_targets):
        x, y = np.random.uniform(180.0, 420.0, 2)
        speed, course = np.random.uniform(3.0, 6.0), np.random.uniform(-math.pi, math.pi)
        sv = np.array([x, speed * math.cos(course), y, speed * math.sin(course)])
        truths.append(GroundTruthPath([GroundTruthState(sv, timestamp=START)]))
        estimate = sv + np.linalg.cholesky(P0) @ np.random.standard_normal(4)
        tracks.append(Track([GaussianState(estimate, P0, timestamp=START)]))
    platforms = []
    for altitude in (490.0, 500.0, 510.0):
        x, y = np.random.uniform(60.0, 540.0, 2)
        radar = SensorplanRadar(params=SensorParams(altitude=altitude, **detection),
                                heading=float(np.random.uniform(-math.pi, math.pi)))
        movable = LatticeMovable(states=[State([[x], [y], [altitude]], timestamp=START)],
                                 position_mapping=(0, 1, 2), world=MapRect(0, 0, 600, 600))
        platforms.append(FixedPlatform(movement_controller=movable, sensors=[radar]))
    return truths, tracks, platforms


# %%
def run(steps: int, seed: int = 0, planner: str = "pg", horizon: int = 3,
        clutter_rate: float = RADAR_DETECTION["clutter_rate"],
        planning_detection: str = "aware") -> LoopResult:
    """Plan, act, move the truth, predict, look, associate (PDA), update.

    ``np.random.seed(seed)`` makes the run repeatable, as in Stone Soup's tutorials.
    """
    np.random.seed(seed)
    detection = dict(RADAR_DETECTION, clutter_rate=clutter_rate)
    truths, tracks, platforms = build(**detection)
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q),
                                                        ConstantVelocity(Q)])
    predictor = ExtendedKalmanPredictor(transition)
    # The PDA updater needs a measurement model for the missed-detection hypothesis (which
    # has no detection to carry one): the looking radar's, set before each update.
    updater = PDAUpdater(measurement_model=None)
    hypothesiser = PDAHypothesiser(predictor=predictor, updater=updater,
                                   clutter_spatial_density=None, prob_detect=Probability(1),
                                   prob_gate=Probability(0.99))
    associator = PDA(hypothesiser=hypothesiser)
    manager = SensorplanManager(platforms=platforms, planner=planner, horizon=horizon,
                                dt=1.0, process_noise=Q, planning_detection=planning_detection,
                                rng=seed + 1)
    radars = [p.sensors[0] for p in platforms]
    out = LoopResult(truths, tracks, platforms, np.empty((0, len(tracks))), [])
    errors = []
    dt = datetime.timedelta(seconds=1)
    for k in range(1, steps + 1):
        now = START + k * dt
        start = time.perf_counter()
        config = manager.choose_actions(tracks, now)[0]       # a list in: target order kept
        out.planning_seconds.append(time.perf_counter() - start)
        execute(config, now)                                  # move, then turn toward the aim
        for truth in truths:
            sv = transition.function(truth.state, noise=True, time_interval=dt)
            truth.append(GroundTruthState(sv, timestamp=now))
        for track in tracks:
            track.append(predictor.predict(track.state, timestamp=now))
        for radar in radars:
            track = radar.aim_target                          # the radar dwells on one track
            truth = truths[tracks.index(track)]
            detections = radar.measure([truth.state])         # np.random's global state
            # What the tracker may know: Pd and clutter density at the track's prediction.
            hypothesiser.prob_detect = Probability(radar.detection_probability(track.state))
            # (None without clutter: Stone Soup then estimates it from the gated detections.)
            rho = radar.clutter_spatial_density(track.state)
            hypothesiser.clutter_spatial_density = rho if rho > 0 else None
            updater.measurement_model = radar.measurement_model
            hypotheses = associator.associate([track], ordered_detections(detections), now)
            track.append(updater.update(hypotheses[track]))
            out.looks += 1
            out.in_view += radar.is_detectable(truth.state)
            out.detected += sum(isinstance(d, TrueDetection) for d in detections)
            false = [d for d in detections if isinstance(d, Clutter)]
            out.false_alarms += len(false)
            out.clutter_xy += [np.ravel(d.measurement_model.inverse_function(d))[[0, 2]]
                               for d in false]
        errors.append([math.hypot(*(np.ravel(t.state_vector)[[0, 2]]
                                    - np.ravel(tr.state_vector)[[0, 2]]))
                       for t, tr in zip(truths, tracks)])
    out.errors = np.array(errors)
    return out


# %%
def plot(result: LoopResult, path: str) -> None:
    """Map of truths, tracks, platforms and false alarms; position errors over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 5.5))
    if result.clutter_xy:
        c = np.array(result.clutter_xy)
        ax.plot(c[:, 0], c[:, 1], ".", color="0.6", ms=3, label="false alarms")
    for j, (truth, track) in enumerate(zip(result.truths, result.tracks)):
        tp = np.array([np.ravel(s.state_vector)[[0, 2]] for s in truth])
        ep = np.array([from_gaussian_state(s)[0][:2] for s in track])
        (line,) = ax.plot(tp[:, 0], tp[:, 1], "-", lw=2, alpha=0.5)
        ax.plot(ep[:, 0], ep[:, 1], ":", color=line.get_color(), lw=1.2)
        ax2.plot(result.errors[:, j], color=line.get_color(), label=f"target {j}")
    for platform in result.platforms:
        xy = np.array([np.ravel(s.state_vector)[:2] for s in platform.movement_controller])
        ax.plot(xy[:, 0], xy[:, 1], "k-", lw=0.6, alpha=0.5)
        ax.plot(*xy[-1], "k^", ms=7)
    ax.set(xlim=(-200, 800), ylim=(-200, 800), aspect="equal", xlabel="x (m)", ylabel="y (m)",
           title="truth (solid), PDA tracks (dotted), false alarms (grey)")
    ax2.set(xlabel="step", ylabel="position error (m)", yscale="log",
            title=f"{result.detected}/{result.in_view} looks in view detected, "
                  f"{result.false_alarms} false alarms")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# %%
def main(argv: list[str] | None = None) -> LoopResult:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--out", default="stonesoup_pda_loop.png")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--planner", default="pg")
    parser.add_argument("--horizon", type=int, default=3)
    parser.add_argument("--clutter-rate", type=float, default=RADAR_DETECTION["clutter_rate"])
    parser.add_argument("--planning-detection", choices=("aware", "ignore"), default="aware")
    args = parser.parse_args(argv)
    result = run(args.steps, args.seed, args.planner, args.horizon, args.clutter_rate,
                 args.planning_detection)
    plot(result, args.out)
    rmse = np.sqrt(np.mean(result.errors**2, axis=0))
    print(f"looks {result.looks}, target in view {result.in_view}, detected {result.detected}, "
          f"false alarms {result.false_alarms}")
    print(f"position RMSE per target (m): {np.round(rmse, 1).tolist()}; plot: {args.out}")
    return result


if __name__ == "__main__":
    main()
