"""A planner written outside sensorplan: look at the nearest target (docs/planning.md).

Every sensor looks, in each epoch, at the target whose predicted position is nearest, and
takes the move (one per epoch, staying in the map) whose ground range to that target is
closest to ``standoff``. Use it as ``nearest`` after ``import nearest_planner``, as
``nearest_planner:NearestTargetPlanner`` with this directory on PYTHONPATH, or through an
entry point of an installed package (``[project.entry-points."sensorplan.planners"]``,
``nearest = "nearest_planner:NearestTargetPlanner"``).
"""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from sensorplan.planners import (Plan, finish, move_vectors, refuse_search, register,
                                 start_clock)


@register
@dataclass(frozen=True)
class NearestTargetPlanner:
    """Nearest predicted target, at about ``standoff`` m of ground range. Deterministic."""

    name: ClassVar[str] = "nearest"
    standoff: float = 350.0         # m; the default radar sees 250-450 m of ground range
    seed: int | None = 0            # unused; planners take a seed by convention

    def __post_init__(self) -> None:
        if not self.standoff >= 0.0:
            raise ValueError(f"standoff must be >= 0 m, got {self.standoff}")

    def plan(self, problem, rng=None):
        refuse_search(self.name, problem)           # it looks at tracks only
        start = start_clock()                       # the planner's own time starts here
        N, K = problem.n_sensors, problem.horizon
        positions, targets = np.empty((N, K, 2)), np.empty((N, K), dtype=np.int64)
        for i, sensor in enumerate(problem.sensors):
            p = np.array(problem.positions[i], dtype=float)
            for k in range(K):
                t = (k + 1) * problem.steps_per_epoch * problem.dt   # s, end of epoch k+1
                predicted = problem.means[:, :2] + t * problem.means[:, 2:]
                j = int(np.argmin(np.linalg.norm(predicted - p, axis=1)))
                moves = p + move_vectors(sensor.moves)
                moves = moves[problem.world.contains(moves)]
                gap = np.abs(np.linalg.norm(moves - predicted[j], axis=1) - self.standoff)
                p = moves[int(np.argmin(gap))]
                positions[i, k], targets[i, k] = p, j
        return finish(self.name, problem, Plan(positions, targets), start)


if __name__ == "__main__":
    from sensorplan.planners import check_planner

    check_planner(NearestTargetPlanner())
    print("NearestTargetPlanner passes check_planner")
