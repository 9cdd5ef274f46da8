"""Reference plans of the engine-based planners, recorded before the planning speed-ups.

The planners' fast paths (caches, compiled kernels, skipped candidates) must not change any
decision: the same input and seed must give the same plan, bit for bit, and the same Phi to
round-off. :data:`CASES` lists the problems; ``tests/data/planner_reference.npz`` holds the
plans the code gave at commit 5a3b30c (before the speed-ups), written by running this module:

    PYTHONPATH=src python tests/planner_reference.py tests/data/planner_reference.npz

and ``tests/planners/test_plans_equal_recorded.py`` compares the current code against it.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable

import numpy as np

from factories import paper_problem, tiny_problem
from sensorplan.planners.problem import MapRect, PlanningProblem
from sensorplan.models.sensors import SensorParams


def scale_problem(n_sensors: int = 20, n_targets: int = 50, horizon: int = 10,
                  width: float = 2000.0, seed: int = 0) -> PlanningProblem:
    """The planning benchmark's scale case (``benchmarks/bench_planning.py``), with the
    terminal objective its references and figures were recorded with."""
    rng = np.random.default_rng(seed)
    W = width
    means = np.c_[rng.uniform(100, W - 100, (n_targets, 2)), rng.normal(0, 3, (n_targets, 2))]
    covs = np.tile(np.diag([400.0, 400.0, 4.0, 4.0]), (n_targets, 1, 1))
    sensors = tuple(SensorParams(altitude=490.0 + 10.0 * (i % 3)) for i in range(n_sensors))
    return PlanningProblem(means, covs, rng.uniform(50, W - 50, (n_sensors, 2)),
                           rng.uniform(-math.pi, math.pi, n_sensors), sensors, horizon=horizon,
                           world=MapRect(W, W), objective="terminal")


def swarm_problem(horizon: int = 5, steps_per_epoch: int = 1, seed: int = 0,
                  n_sensors: int | None = None, n_targets: int | None = None) -> PlanningProblem:
    """A first decision of :func:`sensorplan.simulation.scenario.swarm_scenario` (optionally its
    first
    ``n_sensors`` sensors and ``n_targets`` targets)."""
    from sensorplan.simulation.scenario import draw_initial, swarm_scenario

    sc = swarm_scenario()
    ss = np.random.SeedSequence(seed).spawn(2)
    ini = draw_initial(sc, np.random.default_rng(ss[0]), np.random.default_rng(ss[1]))
    N = n_sensors or len(sc.sensors)
    M = n_targets or len(sc.targets)
    covs = np.tile(np.array(sc.initial_cov), (M, 1, 1))
    return PlanningProblem(ini.estimate[:M], covs, ini.positions[:N], ini.headings[:N],
                           tuple(s.params for s in sc.sensors[:N]), horizon=horizon,
                           steps_per_epoch=steps_per_epoch, dt=sc.dt,
                           process_noise=sc.process_noise, world=sc.world,
                           objective="terminal")


def _paper(seed: int, **kw) -> PlanningProblem:
    return paper_problem(np.random.default_rng(seed), **kw)


def _per_target_q(seed: int) -> PlanningProblem:
    p = _paper(seed, horizon=3)
    q = np.random.default_rng(seed + 1).uniform(0.01, 2.0, p.n_targets)
    return PlanningProblem(p.means, p.covs, p.positions, p.headings, p.sensors, horizon=3,
                           steps_per_epoch=2, process_noise=q, objective="terminal")


def _with(p: PlanningProblem, **kw) -> PlanningProblem:
    fields = dict(means=p.means, covs=p.covs, positions=p.positions, headings=p.headings,
                  sensors=p.sensors, horizon=p.horizon, steps_per_epoch=p.steps_per_epoch,
                  dt=p.dt, process_noise=p.process_noise, world=p.world,
                  visibility=p.visibility, objective=p.objective)
    return PlanningProblem(**{**fields, **kw})


def _tiny(seed: int, **kw) -> PlanningProblem:
    return tiny_problem(np.random.default_rng(seed), **kw)


ENGINE = ("pg", "pg-refine", "sequential-greedy")

#: name -> (problem builder, planners, planner rng)
CASES: dict[str, tuple[Callable[[], PlanningProblem], tuple[str, ...], int]] = {
    "paper_k3": (lambda: _paper(10, horizon=3), ENGINE, 0),
    "paper_k3_seed7": (lambda: _paper(11, horizon=3), ENGINE, 7),
    "paper_k4_mean_cumulative": (lambda: _paper(12, horizon=4, visibility="mean",
                                                objective="cumulative"), ENGINE, 1),
    "paper_k2_e1_cumulative": (lambda: _paper(13, horizon=2, steps_per_epoch=1,
                                              objective="cumulative"), ENGINE, 2),
    "paper_per_target_q": (lambda: _per_target_q(14), ENGINE, 3),
    "paper_n6_m12_k3": (lambda: _paper(15, horizon=3, n_sensors=6, n_targets=12), ENGINE, 4),
    "tiny_a": (lambda: _tiny(20), ENGINE, 0),
    "tiny_b": (lambda: _tiny(21, visibility="mean"), ENGINE, 1),
    "tiny_c": (lambda: _tiny(22, objective="cumulative"), ENGINE, 2),
    "tiny_d": (lambda: _tiny(23, visibility="probabilistic"), ENGINE, 3),
    "scale_k3": (lambda: scale_problem(horizon=3), ENGINE, 0),
    "scale_k10": (lambda: scale_problem(), ("pg",), 0),
    "scale_k4_e2_mean": (lambda: _with(scale_problem(horizon=4), steps_per_epoch=2,
                                       visibility="mean"), ("pg", "sequential-greedy"), 5),
    "swarm_small": (lambda: swarm_problem(horizon=3, n_sensors=30, n_targets=60), ENGINE, 0),
    "swarm_k5": (lambda: swarm_problem(), ("pg",), 0),
}


def record(path: str) -> None:
    from sensorplan.planners import make_planner

    out: dict[str, np.ndarray] = {}
    for case, (build, planners, seed) in CASES.items():
        problem = build()
        for name in planners:
            r = make_planner(name).plan(problem, rng=seed)
            key = f"{case}/{name}"
            out[f"{key}/positions"] = np.asarray(r.plan.positions)
            out[f"{key}/targets"] = np.asarray(r.plan.targets)
            out[f"{key}/potential"] = np.array(r.potential)
            out[f"{key}/converged"] = np.array(-1 if r.converged is None else int(r.converged))
            out[f"{key}/sweeps"] = np.array(-1 if r.sweeps is None else r.sweeps)
            print(f"{key}: Phi {r.potential:.6f}, {r.seconds:.2f} s", flush=True)
    np.savez_compressed(path, **out)


if __name__ == "__main__":
    record(sys.argv[1])
