"""Is a PMB tracker's probability of existence calibrated? A reliability table.

Runs a study method's closed loop on a seed (a development seed, not a study's) and, after
every step's update, assigns the tracker's Bernoullis (every one, reported or not) to the
live targets, one to one, minimising the summed distance, pairs farther apart than
``--distance`` left out (scipy's ``linear_sum_assignment``). By bins of existence it prints
how many Bernoullis there were, their mean existence, and the share of them assigned to a
target. For a calibrated tracker the two agree: of the Bernoullis at existence 0.3, about
3 in 10 have a target.

    python scripts/existence_calibration.py studies/development/search_edge_exit_dev.toml \
        --method pmb --seed 120453 --runs 8
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

sys.path.insert(0, str(Path(__file__).resolve().parent))
from edge_exit_calibration import closed_loop_parser  # noqa: E402
from untracked_diagnosis import _Probe  # noqa: E402  (the same recording of Bernoullis)

#: Bins of existence.
EDGES = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0 + 1e-12)


def with_target(pos: np.ndarray, xy: np.ndarray, distance: float) -> np.ndarray:
    """``(B,) bool``: which Bernoullis at ``pos (B, 2)`` the one-to-one assignment to the
    targets at ``xy (T, 2)`` of least summed distance (pairs at ``distance`` or farther
    count as ``distance``, and are not assigned) gives a target."""
    hit = np.zeros(len(pos), dtype=bool)
    if len(pos) and len(xy):
        d = np.hypot(pos[:, None, 0] - xy[None, :, 0], pos[:, None, 1] - xy[None, :, 1])
        rows, cols = linear_sum_assignment(np.minimum(d, distance))
        hit[rows[d[rows, cols] < distance]] = True
    return hit


def reliability(study_file: str, method: str, seed: int, runs: int,
                distance: float) -> list[str]:
    """The table (module docstring) over ``runs`` runs of ``method`` on ``seed``."""
    from sensorplan.simulation.run import run_episode
    from sensorplan.study.file import load_study

    study = dataclasses.replace(load_study(study_file), seed=seed, runs=runs)
    m = next(x for x in study.methods if x.name == method)
    nb = len(EDGES) - 1
    count = np.zeros(nb, dtype=np.int64)
    mass = np.zeros(nb)
    assigned = np.zeros(nb, dtype=np.int64)
    for run in range(runs):
        probe = _Probe()
        restore = probe.install()
        try:
            ep = run_episode(study.scenario, m.settings, study.run_seed(run))
        finally:
            restore()
        for t, (r, pos, _) in enumerate(probe.bern, start=1):
            if t >= ep.truth.shape[0] or not len(r):
                continue
            hit = with_target(pos, ep.truth[t, np.flatnonzero(ep.alive[t]), :2], distance)
            bins = np.searchsorted(EDGES, r, side="right") - 1
            np.add.at(count, bins, 1)
            np.add.at(mass, bins, r)
            np.add.at(assigned, bins, hit)
    lines = [f"method {method}, seed {seed}, {runs} runs, targets within {distance:g} m",
             "| existence | Bernoulli-steps | mean existence | share with a target |",
             "|---|--:|--:|--:|"]
    for b in range(nb):
        if count[b]:
            lines.append(f"| {EDGES[b]:g}-{min(EDGES[b + 1], 1.0):g} | {count[b]} "
                         f"| {mass[b] / count[b]:.3f} | {assigned[b] / count[b]:.3f} |")
    return lines


def main(argv: list[str] | None = None) -> None:
    p = closed_loop_parser(__doc__)
    p.add_argument("--distance", type=float, default=20.0)
    a = p.parse_args(argv)
    print("\n".join(reliability(a.study_file, a.method, a.seed, a.runs, a.distance)))


if __name__ == "__main__":
    main()
