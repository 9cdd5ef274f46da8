"""Search and track in a Stone Soup loop: a manager whose reward values search, beside Stone
Soup's own managers whose rewards see only tracks.

One scenario: a 600 m x 600 m map, two fixed radars (sensorplan's, swerling-1 detection,
clutter) that each look in one 60 degree beam per second, and targets that appear over
time anywhere on the map (none at the start) and leave at its edge. Every method uses the
same truth, the same detection model and the same tracker (sensorplan's PMB tracker behind
Stone Soup's tracker interface, :class:`PMBStoneSoupTracker`); only the sensor manager
differs:

- ``search``: Stone Soup's ``BruteForceSensorManager`` with :class:`SearchAndTrackReward`
  (Phi with search: existence-weighted track information plus the undetected targets a
  look is expected to find, from the tracker's undetected intensity);
- ``sp-search``: :class:`SensorplanManager` with ``search="on"`` (the ``pg`` planner); the
  only method that also moves its platforms (one lattice move a step);
- ``ss-brute``: Stone Soup's ``BruteForceSensorManager`` with its own
  ``UncertaintyRewardFunction``, which sees only tracks;
- ``ss-random``: Stone Soup's ``RandomSensorManager`` (one per radar).

Every manager is offered the same looks: each track's predicted position and each of the
radar's 8 search sectors (those the turn limit maps to one heading are one look).

Printed per method: mean GOSPA over steps (sensorplan's ``set_metrics.gospa``, p = 2,
alpha = 2, c = 50 m) and the targets found (ever assigned to a reported track) out of
those born, for each seed. An illustration on a few seeds, not a study.

Run: ``python examples/stonesoup_search.py [--seeds 0 1 2 3] [--steps 40]``
"""

from __future__ import annotations

import argparse
import datetime
import math
import random
from collections.abc import Sequence
from typing import Any

import numpy as np
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity)
from stonesoup.platform import FixedPlatform
from stonesoup.predictor.kalman import ExtendedKalmanPredictor
from stonesoup.sensormanager import BruteForceSensorManager, RandomSensorManager
from stonesoup.sensormanager.reward import UncertaintyRewardFunction
from stonesoup.types.groundtruth import GroundTruthState
from stonesoup.types.state import State
from stonesoup.updater.kalman import ExtendedKalmanUpdater

from sensorplan.integrations.stonesoup import (LatticeMovable, MapRect, PMBStoneSoupTracker,
                                               SearchAndTrackReward, SensorplanManager,
                                               SensorplanRadar, execute,
                                               from_tracks, ordered_tracks, set_aim_candidates,
                                               to_stonesoup_mean)
from sensorplan.models.motion import cv_matrices
from sensorplan.models.sensors import SensorParams
from sensorplan.study.set_metrics import gospa

T0 = datetime.datetime(2026, 1, 1)
WORLD = MapRect(-300.0, -300.0, 600.0, 600.0)
DT, Q = 1.0, 0.05                     # step (s); CWNA intensity of truth and filter (m^2/s^3)
N_TARGETS = 6                         # targets born per run, at times in the first 60 %
SECTORS = 8
C = 50.0                              # GOSPA cut-off (m)
RADAR = SensorParams(detection="swerling1", clutter_rate=1.0)
SITES = ((-220.0, -180.0, 0.8), (220.0, 180.0, -2.4))     # x, y (m), heading (rad)
METHODS = ("search", "sp-search", "ss-brute", "ss-random")


def births(rng: np.random.Generator, steps: int) -> list[tuple[int, np.ndarray]]:
    """``(step, state [x, y, vx, vy])`` of each target: born uniformly on the map (core frame
    shifted to world), speed uniform in [3, 6] m/s in a uniform direction."""
    out = []
    for _ in range(N_TARGETS):
        k = int(rng.integers(0, max(1, int(0.6 * steps))))
        xy = WORLD.origin + rng.uniform([0.0, 0.0], [WORLD.width, WORLD.height])
        s, a = rng.uniform(3.0, 6.0), rng.uniform(-math.pi, math.pi)
        out.append((k, np.array([xy[0], xy[1], s * math.cos(a), s * math.sin(a)])))
    return sorted(out, key=lambda b: b[0])


def truth_run(seed: int, steps: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each step's live target states ``(n, 4)`` and their target numbers ``(n,)``."""
    rng = np.random.default_rng([seed, 0])
    F, Qm = cv_matrices(DT, Q)
    L = np.linalg.cholesky(Qm)
    plan = births(rng, steps)
    alive: dict[int, np.ndarray] = {}
    states, ids = [], []
    for k in range(steps):
        for j, (when, x0) in enumerate(plan):
            if when == k:
                alive[j] = x0
        for j in list(alive):
            x = F @ alive[j] + L @ rng.standard_normal(4)
            if WORLD.contains(x[:2]):
                alive[j] = x
            else:
                del alive[j]                  # a target that leaves the map is gone
        states.append(np.array([alive[j] for j in sorted(alive)]).reshape(-1, 4))
        ids.append(np.array(sorted(alive), dtype=np.int64))
    return states, ids


def sensors(seed: int) -> tuple[list[FixedPlatform], list[SensorplanRadar]]:
    """The two platforms at their sites and their radars."""
    platforms = []
    for i, (x, y, h) in enumerate(SITES):
        radar = SensorplanRadar(params=RADAR, heading=h, search_sectors=SECTORS,
                                seed=10 * seed + i)
        ctl = LatticeMovable(states=[State([[x], [y], [RADAR.altitude]], timestamp=T0)],
                             position_mapping=(0, 1, 2), world=WORLD)
        platforms.append(FixedPlatform(movement_controller=ctl, sensors=[radar]))
    return platforms, [p.sensors[0] for p in platforms]


def tracker_of(radars: Sequence[SensorplanRadar], steps: int) -> PMBStoneSoupTracker:
    """The PMB tracker every method uses: births anywhere at the scenario's rate."""
    rate = N_TARGETS / max(1, int(0.6 * steps))
    return PMBStoneSoupTracker(radars=radars, world=WORLD, dt=DT, start_time=T0,
                               settings={"births": "uniform", "birth_rate": rate,
                                         "survival_probability": 0.99, "resolution": 50.0,
                                         "process_noise": Q, "initial_undetected": 0.5})


def manager_of(method: str, platforms: list[FixedPlatform], radars: list[SensorplanRadar],
               tracker: PMBStoneSoupTracker, seed: int) -> Any:
    """The method's sensor manager (a list of them for ``ss-random``)."""
    if method == "sp-search":
        return SensorplanManager(platforms=platforms, planner="pg", dt=DT, process_noise=Q,
                                 search="on", tracker=tracker, rng=seed)
    if method == "search":
        return BruteForceSensorManager(sensors=set(radars), reward_function=SearchAndTrackReward(
            tracker=tracker, dt=DT, process_noise=Q))
    if method == "ss-brute":
        transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q)] * 2)
        reward = UncertaintyRewardFunction(ExtendedKalmanPredictor(transition),
                                           ExtendedKalmanUpdater(None))
        return BruteForceSensorManager(sensors=set(radars), reward_function=reward)
    return [RandomSensorManager(sensors={r}) for r in radars]


def choose(method: str, manager: Any, radars: list[SensorplanRadar], tracks: set[Any],
           when: datetime.datetime) -> dict[Any, Any]:
    """One step's configuration of the method's manager."""
    if method == "sp-search":
        return manager.choose_actions(tracks, when)[0]
    set_aim_candidates(radars, tracks, DT)     # the track looks Stone Soup's managers see
    if method in ("search", "ss-brute"):
        return manager.choose_actions(tracks, when)[0]
    config: dict[Any, Any] = {}
    for m in manager:
        config.update(m.choose_actions(tracks, when)[0])
    return config


def run(method: str, seed: int, steps: int) -> tuple[float, int, int]:
    """Mean GOSPA (m), targets found and targets born of one run."""
    np.random.seed(seed)            # Stone Soup's habits: its rewards draw from NumPy ...
    random.seed(seed)               # ... and its random manager from Python's generator
    states, ids = truth_run(seed, steps)
    platforms, radars = sensors(seed)
    tracker = tracker_of(radars, steps)
    manager = manager_of(method, platforms, radars, tracker, seed)
    detect = np.random.default_rng([seed, 1])
    tracks: set[Any] = set()
    found: set[int] = set()
    values = []
    for k in range(steps):
        when = T0 + datetime.timedelta(seconds=DT * (k + 1))
        execute(choose(method, manager, radars, tracks, when), when)
        truths = [GroundTruthState(to_stonesoup_mean(x).reshape(4, 1), timestamp=when)
                  for x in states[k]]
        detections: set[Any] = set()
        for radar in radars:
            detections |= radar.measure(truths, rng=detect)
        _, tracks = tracker.update_tracker(when, detections)
        est = from_tracks(ordered_tracks(tracks))[0][:, :2]
        g = gospa(states[k][:, :2], est, C)
        values.append(g.distance)
        found.update(int(j) for j in ids[k][g.assignment >= 0])
    born = len({int(j) for step in ids for j in step})
    return float(np.mean(values)), len(found), born


def compare(seeds: Sequence[int] = (0, 1, 2, 3), steps: int = 40) -> dict[str, dict[str, Any]]:
    """Every method on every seed: ``{method: {"gospa", "found", "born"}}`` arrays by seed."""
    table: dict[str, dict[str, Any]] = {}
    for method in METHODS:
        rows = [run(method, s, steps) for s in seeds]
        table[method] = {key: np.array([r[n] for r in rows])
                         for n, key in enumerate(("gospa", "found", "born"))}
    return table


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--steps", type=int, default=40)
    args = parser.parse_args(argv)
    table = compare(args.seeds, args.steps)
    print(f"{len(args.seeds)} seeds x {args.steps} steps; mean GOSPA (m, c = {C:g}) and "
          "targets found / born per seed")
    for method, row in table.items():
        per_seed = "  ".join(f"{g:5.1f} {f}/{b}" for g, f, b in
                             zip(row["gospa"], row["found"], row["born"]))
        print(f"{method:10s} mean GOSPA {row['gospa'].mean():5.1f}  found "
              f"{row['found'].sum():2d}/{row['born'].sum():2d}  | {per_seed}")


if __name__ == "__main__":
    main()
