"""Is a PMB tracker's probability of existence calibrated? A reliability table.

Runs a study method's closed loop on a seed (a development seed, not a study's) and, after
every step's update, assigns the tracker's Bernoullis (every one, reported or not) to the
live targets, one to one, minimising the summed distance, pairs farther apart than
``--distance`` left out (scipy's ``linear_sum_assignment``). By bins of existence it prints
how many Bernoullis there were, their mean existence, and the share of them assigned to a
target. For a calibrated tracker the two agree: of the Bernoullis at existence 0.3, about
3 in 10 have a target. With ``--established E`` it prints the table twice: for the
Bernoullis whose existence had reached E at an earlier step (held tracks that faded) and
for the others (tracks clutter or a first detection started), which a filter without
memory of a track's history can calibrate differently.

    python scripts/existence_calibration.py studies/development/search_edge_exit_dev.toml \
        --method pmb --seed 120453 --runs 8
    python scripts/existence_calibration.py studies/development/traffic_crossing_dev.toml \
        --method pg/imm --seed 120476 --runs 12 --distance 500 --established 0.99 \
        --edges 0,0.01,0.03,0.06,0.1,0.2,0.3,0.5,0.7,0.9,0.99,1
"""

from __future__ import annotations

import argparse
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


def parse_edges(text: str) -> tuple[float, ...]:
    """Bin edges from ``"0,0.1,...,1"``: increasing, from 0 to 1 (the last bin takes 1)."""
    edges = [float(v) for v in text.split(",")]
    if len(edges) < 2 or edges[0] != 0.0 or edges[-1] != 1.0 or np.any(np.diff(edges) <= 0):
        raise argparse.ArgumentTypeError(f"edges must increase from 0 to 1, got {text!r}")
    return tuple(edges[:-1]) + (1.0 + 1e-12,)


def reached_before(steps: list[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
    """Per step, for each Bernoulli ``(r (B,), labels (B,))``: the highest existence its
    label had at the earlier steps (0 at its first)."""
    peak: dict[int, float] = {}
    out = []
    for r, labels in steps:
        out.append(np.array([peak.get(int(k), 0.0) for k in labels]))
        for k, x in zip(labels, r):
            peak[int(k)] = max(peak.get(int(k), 0.0), float(x))
    return out


def table(title: str, edges: tuple[float, ...], count: np.ndarray, mass: np.ndarray,
          assigned: np.ndarray) -> list[str]:
    """A reliability table's lines (the bins of ``edges`` with Bernoullis)."""
    lines = [title, "| existence | Bernoulli-steps | mean existence | share with a target |",
             "|---|--:|--:|--:|"]
    for b in range(len(count)):
        if count[b]:
            lines.append(f"| {edges[b]:g}-{min(edges[b + 1], 1.0):g} | {count[b]} "
                         f"| {mass[b] / count[b]:.3f} | {assigned[b] / count[b]:.3f} |")
    return lines


def reliability(study_file: str, method: str, seed: int, runs: int,
                distance: float, established: float | None = None,
                edges: tuple[float, ...] = EDGES) -> list[str]:
    """The table (module docstring) over ``runs`` runs of ``method`` on ``seed``, by the
    bins of ``edges``; with ``established``, one for the Bernoulli-steps whose label had
    reached that existence before and one for the rest."""
    from sensorplan.simulation.run import run_episode
    from sensorplan.study.file import load_study

    study = dataclasses.replace(load_study(study_file), seed=seed, runs=runs)
    m = next(x for x in study.methods if x.name == method)
    nb = len(edges) - 1
    groups = 1 if established is None else 2
    count = np.zeros((groups, nb), dtype=np.int64)
    mass = np.zeros((groups, nb))
    assigned = np.zeros((groups, nb), dtype=np.int64)
    for run in range(runs):
        probe = _Probe()
        restore = probe.install()
        try:
            ep = run_episode(study.scenario, m.settings, study.run_seed(run))
        finally:
            restore()
        before = reached_before([(r, labels) for r, _, labels in probe.bern])
        for t, ((r, pos, _), peak) in enumerate(zip(probe.bern, before), start=1):
            if t >= ep.truth.shape[0] or not len(r):
                continue
            hit = with_target(pos, ep.truth[t, np.flatnonzero(ep.alive[t]), :2], distance)
            bins = np.searchsorted(edges, r, side="right") - 1
            group = (np.zeros(len(r), dtype=np.int64) if established is None
                     else (peak < established).astype(np.int64))
            np.add.at(count, (group, bins), 1)
            np.add.at(mass, (group, bins), r)
            np.add.at(assigned, (group, bins), hit)
    head = f"method {method}, seed {seed}, {runs} runs, targets within {distance:g} m"
    if established is None:
        return table(head, edges, count[0], mass[0], assigned[0])
    return (table(f"{head}; Bernoullis that had reached existence {established:g} before",
                  edges, count[0], mass[0], assigned[0]) + [""]
            + table(f"{head}; Bernoullis that had not", edges, count[1], mass[1],
                    assigned[1]))


def main(argv: list[str] | None = None) -> None:
    p = closed_loop_parser(__doc__)
    p.add_argument("--distance", type=float, default=20.0)
    p.add_argument("--established", type=float, default=None,
                   help="split the table by whether a Bernoulli's existence had reached "
                        "this at an earlier step")
    p.add_argument("--edges", type=parse_edges, default=EDGES,
                   help="the bins' edges, comma-separated, from 0 to 1 (default "
                        f"{','.join(f'{e:g}' for e in EDGES[:-1])},1)")
    a = p.parse_args(argv)
    print("\n".join(reliability(a.study_file, a.method, a.seed, a.runs, a.distance,
                                 a.established, a.edges)))


if __name__ == "__main__":
    main()
