# %% [markdown]
# # One planning decision, every planner, against the exact optimum
#
# A small version of the paper's problem: two UAVs that move 40 m per epoch (9 moves),
# three targets, a two-epoch horizon (531,441 joint plans).
# Every registered planner solves it; `brute-force` gives the exact optimum of the same
# objective. Run: `.venv/bin/python examples/one_decision.py`.

# %%
import numpy as np

from sensorplan import PlanningProblem, SensorParams, potential
from sensorplan.planners import PLANNERS, make_planner

rng = np.random.default_rng(3)
problem = PlanningProblem(
    means=np.c_[rng.uniform(150, 450, (3, 2)), rng.normal(0, 3, (3, 2))],
    covs=np.tile(np.diag([400.0, 400.0, 4.0, 4.0]), (3, 1, 1)),
    positions=np.array([[100.0, 120.0], [500.0, 480.0]]),
    headings=np.array([0.5, -2.5]),
    sensors=(SensorParams(altitude=490.0, moves=(40.0,)),
             SensorParams(altitude=510.0, moves=(40.0,))),
    horizon=2, steps_per_epoch=2)

# %%
optimum = make_planner("brute-force").plan(problem).potential
print(f"{'planner':<18} {'Phi (nats)':>10} {'of optimum':>10} {'ms':>8}  converged")
for name in sorted(PLANNERS):
    result = make_planner(name).plan(problem, rng=0)
    assert abs(result.potential - potential(problem, result.plan)[0]) < 1e-9 * optimum
    print(f"{name:<18} {result.potential:10.3f} {result.potential / optimum:10.3f} "
          f"{1e3 * result.seconds:8.1f}  {result.converged}")

# %%
best = make_planner("pg-refine").plan(problem, rng=0)
for i in range(problem.n_sensors):
    for k in range(problem.horizon):
        x, y = best.plan.positions[i, k]
        print(f"sensor {i}, epoch {k + 1}: fly to ({x:.0f}, {y:.0f}) m, "
              f"heading {best.headings[i, k]:+.2f} rad, look at target {best.plan.targets[i, k]}")
