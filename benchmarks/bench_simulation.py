"""Simulation speed: a preset, ``random`` planner, e = 2, K = 1 (docs/benchmarks.md).

Prints the median over repetitions of the time per simulation step (total run time /
steps, planning included) and its split into planning (building the planning problem and
the planner's call) and everything else, both in wall-clock time and in this process's CPU
time (``time.process_time``; robust when other jobs share the machine). One untimed run
comes first (imports, compiled kernels, caches).

    .venv/bin/python benchmarks/bench_simulation.py [--preset paper|radar|urban|swarm]
        [--config FILE.toml] [--steps 100] [--repeats 20] [--miss-update negative|none] [--profile]
        [--set KEY=VALUE ...]

``--preset`` picks a built-in scenario with the run settings ``sensorplan simulate --preset
NAME`` gives it (tracker, association, planning modes), with this script's planner, K, e,
steps and miss update on top: ``radar`` is Swerling 1 detection with clutter and the
``pmb`` tracker, ``urban`` the paper's scenario among buildings; ``--config`` reads a
scenario file instead (``configs/radar.toml``: the radar with the known-target PDA
tracker, what the radar target below was set for). ``--set`` overrides any other run
setting as ``simulate``'s options do (``--set model=cv --set known_map=false``), to see
what a part of the tracker costs.

Targets: <= 1 ms per step on the paper preset, <= 1.5 ms on configs/radar.toml, so that
studies are bound by planning, not by simulation.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import platform
import pstats
import statistics
import time
from pathlib import Path

import numpy as np

from sensorplan.simulation import run as simulation
from sensorplan.config.simulate import PRESETS, load_simulation
from sensorplan.simulation import run_episode


class _DecisionClock:
    """Accumulates wall and CPU time spent building planning problems and planning."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.wall = 0.0
        self.cpu = 0.0

    def timed(self, fn):  # noqa: ANN001, ANN201
        def wrapper(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
            w, c = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.wall += time.perf_counter() - w
                self.cpu += time.process_time() - c
        return wrapper

    def install(self) -> None:
        """Wrap the simulator's problem constructor and planner factory."""
        simulation.PlanningProblem = self.timed(simulation.PlanningProblem)
        make = simulation.make_planner

        def make_timed(name, **params):  # noqa: ANN001, ANN003, ANN202
            planner = make(name, **params)
            return _Timed(planner, self)
        simulation.make_planner = make_timed


class _Timed:
    def __init__(self, planner, clock: _DecisionClock) -> None:  # noqa: ANN001
        self.plan = clock.timed(planner.plan)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", choices=PRESETS, default="paper",
                    help="built-in scenario, with the run settings simulate gives it")
    ap.add_argument("--config", type=Path, default=None, metavar="FILE.toml",
                    help="scenario file instead of --preset (its run settings too)")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--planner", default="random")
    ap.add_argument("--horizon", type=int, default=1)
    ap.add_argument("--steps-per-epoch", type=int, default=2)
    ap.add_argument("--miss-update", choices=("negative", "none"), default="negative")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first repetition")
    ap.add_argument("--profile", action="store_true", help="print a cProfile of all runs")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="another run setting (value read as JSON if it parses, else text)")
    args = ap.parse_args()
    extra = {}
    for item in args.set:
        key, _, text = item.partition("=")
        try:
            extra[key] = json.loads(text)
        except json.JSONDecodeError:
            extra[key] = text

    # What `sensorplan simulate --preset NAME --planner ... -K ... -e ... --steps ...` runs.
    overrides = {"planner": args.planner, "horizon": args.horizon,
                 "steps_per_epoch": args.steps_per_epoch, "steps": args.steps,
                 "miss_update": args.miss_update, **extra}
    config = (load_simulation(args.config, overrides=overrides) if args.config is not None
              else load_simulation(preset=args.preset, overrides=overrides))
    scenario, settings = config.scenario, config.settings
    clock = _DecisionClock()
    clock.install()
    run_episode(scenario, settings, args.seed)  # warm-up: imports, caches
    wall, cpu, plan_wall, plan_cpu = [], [], [], []
    profiler = cProfile.Profile() if args.profile else None
    for r in range(args.repeats):
        clock.reset()
        if profiler:
            profiler.enable()
        w0, c0 = time.perf_counter(), time.process_time()
        run_episode(scenario, settings, args.seed + r)
        w1, c1 = time.perf_counter(), time.process_time()
        if profiler:
            profiler.disable()
        wall.append(1e3 * (w1 - w0) / args.steps)
        cpu.append(1e3 * (c1 - c0) / args.steps)
        plan_wall.append(1e3 * clock.wall / args.steps)
        plan_cpu.append(1e3 * clock.cpu / args.steps)
    med = statistics.median
    source = f"{args.config}" if args.config is not None else f"{args.preset} preset"
    print(f"{source}, planner={args.planner}, K={args.horizon}, "
          f"e={args.steps_per_epoch}, miss_update={settings.tracker.miss_update}, "
          f"{args.steps} steps x {args.repeats} runs "
          f"(python {platform.python_version()}, numpy {np.__version__})")
    if args.preset != "paper" or args.config is not None or extra:
        s0 = scenario.sensors[0].params
        print(f"N={len(scenario.sensors)}, M={len(scenario.targets)}, "
              f"buildings={len(scenario.buildings)}, detection={s0.detection}, "
              f"clutter_rate={s0.clutter_rate}, tracker={settings.tracker.kind} "
              f"{settings.tracker.model}, "
              f"association={settings.tracker.association}, "
              f"planning_detection={settings.planning_detection}, "
              f"planning_occlusion={settings.planning_occlusion}"
              + "".join(f", {k}={v}" for k, v in extra.items()))
    for name, tot, pl in (("wall", wall, plan_wall), ("cpu ", cpu, plan_cpu)):
        sim = [a - b for a, b in zip(tot, pl)]
        print(f"{name} median ms per step: {med(tot):.3f}  (planning {med(pl):.3f}, "
              f"simulation {med(sim):.3f}; min {min(tot):.3f}, max {max(tot):.3f})")
    if profiler:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
