"""Animation frames of a run of changing sets against those of known targets.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_set_animation.py [--steps 25]

A ``search``-scenario run (births at the edges, survival 0.97, ``pmb`` tracker, looks that
detect every target; ``--steps`` steps, seed 20261203) and the stored paper-preset run of
``tests/data/figure_paper_episode.npz`` (5 known targets, 30 steps): the median process CPU
time of one frame (``render`` after the frames' set-up, frames 1..S, 72 dpi), of the static
figure (``episode_figure`` and ``savefig``, after one untimed drawing), and their ratios.
CPU time, not wall time: on a shared machine wall time includes waiting for a core.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def frame_seconds(episode, scenario) -> float:
    from sensorplan.figures.animation import _Frames

    frames = _Frames(episode, scenario, 12.0, 72)
    frames.render(0)
    times = []
    for t in range(1, frames.S + 1):
        start = time.process_time()
        frames.render(t)
        times.append(time.process_time() - start)
    return float(np.median(times))


def figure_seconds(episode, scenario, out: Path) -> float:
    from sensorplan.figures.run import plot_episode

    plot_episode(episode, scenario, out)
    times = []
    for _ in range(3):
        start = time.process_time()
        plot_episode(episode, scenario, out)
        times.append(time.process_time() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=25)
    args = parser.parse_args()

    from sensorplan.config import load_simulation
    from sensorplan.simulation import Episode, run_episode
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings

    scenario = dataclasses.replace(search_scenario(), look_detects="all", birth_rate=0.25,
                                   survival_probability=0.97)
    tracker = TrackerSettings(kind="pmb", birth_rate=0.25, survival_probability=0.97)
    sets = run_episode(scenario, RunSettings(planner="pg", steps=args.steps, tracker=tracker),
                       20261203)
    known = Episode.load(ROOT / "tests" / "data" / "figure_paper_episode.npz")
    paper = load_simulation(preset="paper").scenario
    with tempfile.TemporaryDirectory() as tmp:
        rows = [("sets", sets, scenario), ("known", known, paper)]
        result = {name: (frame_seconds(ep, sc), figure_seconds(ep, sc, Path(tmp) / "f.png"))
                  for name, ep, sc in rows}
    print(f"{'run':<6} {'targets':>8} {'tracks/step':>12} {'frame (ms)':>11} {'figure (s)':>11}")
    for name, ep, _ in rows:
        per_step = np.bincount(ep.track_step).mean()
        print(f"{name:<6} {ep.alive.shape[1]:>8d} {per_step:>12.1f} "
              f"{1000 * result[name][0]:>11.1f} {result[name][1]:>11.2f}")
    print(f"ratio sets / known: frame {result['sets'][0] / result['known'][0]:.2f}, "
          f"figure {result['sets'][1] / result['known'][1]:.2f}")


if __name__ == "__main__":
    main()
