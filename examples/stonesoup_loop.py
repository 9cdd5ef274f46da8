# %% [markdown]
# # A Stone Soup tracking loop steered by a sensorplan planner
#
# Everything in the loop is Stone Soup: ground truth paths, an extended Kalman predictor
# and updater, tracks, platforms and sensors that act on actions returned by a sensor
# manager. From sensorplan come the radar (its measurement model and field of view), the
# platforms' move lattice and the manager, which plans with the potential-game planner
# (`pg`, K = 3 epochs, rolling horizon) and returns each platform's move and each radar's
# aim. Needs the extra: `pip install sensorplan[stonesoup]`.
#
# Run: `python examples/stonesoup_loop.py [--steps 50] [--out stonesoup_loop.png]`

# %%
"""A Stone Soup tracking loop steered by a sensorplan planner: Stone Soup's truth, EKF and
tracks; sensorplan's radar, move lattice and manager (pg, K = 3, rolling horizon)."""

from __future__ import annotations

import argparse
import datetime
import math
import time
from dataclasses import dataclass

import numpy as np
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity)
from stonesoup.platform import FixedPlatform
from stonesoup.predictor.kalman import ExtendedKalmanPredictor
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState, State
from stonesoup.types.track import Track
from stonesoup.updater.kalman import ExtendedKalmanUpdater

from sensorplan.integrations.stonesoup import (LatticeMovable, MapRect, SensorplanManager,
                                               SensorplanRadar, execute, from_gaussian_state)
from sensorplan.models.sensors import SensorParams

START = datetime.datetime(2024, 1, 1)
Q = 0.05                                     # m^2/s^3, truth and filter
P0 = np.diag([400.0, 4.0, 400.0, 4.0])       # Stone Soup order [x, vx, y, vy]


@dataclass
class LoopResult:
    """What the loop produced: Stone Soup objects and the position errors (steps, M)."""

    truths: list[GroundTruthPath]
    tracks: list[Track]
    platforms: list[FixedPlatform]
    errors: np.ndarray
    planning_seconds: list[float]


# %%
def build(rng: np.random.Generator, n_targets: int = 5):
    """Ground truths, tracks and platforms at the start time."""
    truths, tracks = [], []
    for _ in range(n_targets):
        x, y = rng.uniform(180.0, 420.0, 2)
        speed, course = rng.uniform(3.0, 6.0), rng.uniform(-math.pi, math.pi)
        sv = np.array([x, speed * math.cos(course), y, speed * math.sin(course)])
        truths.append(GroundTruthPath([GroundTruthState(sv, timestamp=START)]))
        estimate = sv + np.linalg.cholesky(P0) @ rng.standard_normal(4)
        tracks.append(Track([GaussianState(estimate, P0, timestamp=START)]))
    platforms = []
    for altitude in (490.0, 500.0, 510.0):
        x, y = rng.uniform(60.0, 540.0, 2)
        radar = SensorplanRadar(params=SensorParams(altitude=altitude),
                                heading=float(rng.uniform(-math.pi, math.pi)))
        movable = LatticeMovable(states=[State([[x], [y], [altitude]], timestamp=START)],
                                 position_mapping=(0, 1, 2), move_distances=(20.0, 40.0),
                                 world=MapRect(0.0, 0.0, 600.0, 600.0))
        platforms.append(FixedPlatform(movement_controller=movable, sensors=[radar]))
    return truths, tracks, platforms


# %%
def run(steps: int, seed: int = 0, planner: str = "pg", horizon: int = 3) -> LoopResult:
    """The tracking loop: plan, act, move the truth, predict, measure, update.

    Every random draw comes from generators made from ``seed`` (truth noise and radar noise
    from ``rng``, the planner from its own), so a run repeats exactly. Stone Soup's habit
    works too: with no ``rng`` / ``random_state`` passed, the radar and Stone Soup's models
    draw from NumPy's global state, and ``np.random.seed(seed)`` makes the run repeatable.
    """
    rng = np.random.default_rng(seed)
    truths, tracks, platforms = build(rng)
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q),
                                                        ConstantVelocity(Q)])
    predictor = ExtendedKalmanPredictor(transition)
    updater = ExtendedKalmanUpdater(measurement_model=None, use_joseph_cov=True)
    manager = SensorplanManager(platforms=platforms, planner=planner, horizon=horizon,
                                dt=1.0, process_noise=Q, rng=np.random.default_rng(seed + 1))
    radars = [p.sensors[0] for p in platforms]
    errors, seconds = [], []
    dt = datetime.timedelta(seconds=1)
    for k in range(1, steps + 1):
        now = START + k * dt
        start = time.perf_counter()
        config = manager.choose_actions(tracks, now)[0]       # list in: target order kept
        seconds.append(time.perf_counter() - start)
        execute(config, now)                                  # move, then turn toward the aim
        for truth in truths:
            sv = transition.function(truth.state, noise=True, random_state=rng, time_interval=dt)
            truth.append(GroundTruthState(sv, timestamp=now))
        for track in tracks:
            track.append(predictor.predict(track.state, timestamp=now))
        for radar in radars:
            track = radar.aim_target                          # the radar dwells on one track
            truth = truths[tracks.index(track)]
            for detection in radar.measure([truth.state], rng=rng):
                track.append(updater.update(SingleHypothesis(track.state, detection)))
        errors.append([math.hypot(*(np.ravel(t.state_vector)[[0, 2]]
                                    - np.ravel(tr.state_vector)[[0, 2]]))
                       for t, tr in zip(truths, tracks)])
    return LoopResult(truths, tracks, platforms, np.array(errors), seconds)


# %%
def plot(result: LoopResult, path: str) -> None:
    """Map of truths, tracks, platform paths and final fields of view; errors over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Wedge

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 5.5))
    for j, (truth, track) in enumerate(zip(result.truths, result.tracks)):
        tp = np.array([np.ravel(s.state_vector)[[0, 2]] for s in truth])
        ep = np.array([from_gaussian_state(s)[0][:2] for s in track])
        (line,) = ax.plot(tp[:, 0], tp[:, 1], "-", lw=2, alpha=0.5)
        ax.plot(ep[:, 0], ep[:, 1], ":", color=line.get_color(), lw=1.2)
        ax.plot(*tp[-1], "o", color=line.get_color())
        ax2.plot(result.errors[:, j], color=line.get_color(), label=f"target {j}")
    for platform in result.platforms:
        path_xy = np.array([np.ravel(s.state_vector)[:2] for s in platform.movement_controller])
        radar = platform.sensors[0]
        ax.plot(path_xy[:, 0], path_xy[:, 1], "k-", lw=0.6, alpha=0.5)
        ax.plot(*path_xy[-1], "k^", ms=7)
        p = radar.params
        ax.add_patch(Wedge(tuple(path_xy[-1]), p.max_ground_range,
                           math.degrees(radar.heading - p.fov_half_angle),
                           math.degrees(radar.heading + p.fov_half_angle),
                           width=p.max_ground_range - p.min_ground_range, alpha=0.12,
                           color="k"))
    ax.set(xlim=(0, 600), ylim=(0, 600), aspect="equal", xlabel="x (m)", ylabel="y (m)",
           title="truth (solid), Stone Soup tracks (dotted), platforms (black)")
    ax2.set(xlabel="step", ylabel="position error (m)", yscale="log",
            title=f"mean planning time {1e3 * np.mean(result.planning_seconds):.0f} ms/step")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# %%
def main(argv: list[str] | None = None) -> LoopResult:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--out", default="stonesoup_loop.png")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--planner", default="pg")
    parser.add_argument("--horizon", type=int, default=3)
    args = parser.parse_args(argv)
    result = run(args.steps, args.seed, args.planner, args.horizon)
    plot(result, args.out)
    rmse = np.sqrt(np.mean(result.errors**2, axis=0))
    print(f"position RMSE per target (m): {np.round(rmse, 1).tolist()}; plot: {args.out}")
    return result


if __name__ == "__main__":
    main()
