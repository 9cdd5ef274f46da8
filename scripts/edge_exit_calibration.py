"""How well a PMB tracker's charge at an exit edge predicts the targets that leave.

Runs a study method's closed loop on a seed (a development seed, not a study's) and, at
every predict, pairs each Bernoulli of existence at least 0.3 with the live target nearest
its mean (within 10 m). The existence the predict takes at the map's edge (what is left
after survival) is the tracker's probability that the target leaves in that step; summed
over the pairs it is the number of exits the tracker expects. The truth says how many of
those targets did leave in the step. Both are printed by the target's distance to the
nearest edge at the step's start: a target at speed s can only leave from within s dt.

    python scripts/edge_exit_calibration.py studies/development/search_edge_exit_dev.toml \
        --method pmb --seed 120453 --runs 8
    python scripts/edge_exit_calibration.py studies/development/search_edge_exit_dev.toml \
        --method pmb/crossing --seed 120453 --runs 8
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import numpy as np

#: Distance bands to the nearest edge (m).
BANDS = (0.0, 5.0, 10.0, 20.0, 40.0)
MIN_EXISTENCE, MAX_DISTANCE = 0.3, 10.0


def _recorded(study: Any, settings: Any, run: int) -> tuple[Any, list[tuple[np.ndarray, ...]]]:
    """One closed-loop run; every predict's Bernoullis before and after it."""
    import sensorplan.simulation.run as run_mod

    record: list[tuple[np.ndarray, ...]] = []
    make_tracker = run_mod.make_tracker

    def make(*args: Any, **kwargs: Any) -> Any:
        tracker = make_tracker(*args, **kwargs)
        predict = tracker.predict

        def recorded() -> Any:
            b = tracker.bern
            before = (b.r.copy(), b.means[:, :2].copy(), b.labels.copy())
            out = predict()
            record.append(before + (tracker.bern.r.copy(), tracker.bern.labels.copy()))
            return out

        tracker.predict = recorded
        return tracker

    run_mod.make_tracker = make
    try:
        episode = run_mod.run_episode(study.scenario, settings, study.run_seed(run))
    finally:
        run_mod.make_tracker = make_tracker
    return episode, record


def tally(record: list[tuple[np.ndarray, ...]], truth: np.ndarray, alive: np.ndarray,
          width: float, height: float, survival: float
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per distance band (:data:`BANDS`): the pairs, the exits the tracker expects and the
    targets that left, from one run's predicts ``record`` (as :func:`_recorded` keeps it:
    existence, position and label before each predict, existence and label after) and its
    truth ``(S + 1, M, 4)``, ``alive (S + 1, M)``."""
    nb = len(BANDS) - 1
    pairs = np.zeros(nb, dtype=np.int64)
    expected = np.zeros(nb)
    left = np.zeros(nb, dtype=np.int64)
    for t, (r0, m0, l0, r1, l1) in enumerate(record, start=1):
        if t >= truth.shape[0]:
            break
        live = np.flatnonzero(alive[t - 1])
        if not len(live) or not len(r0):
            continue
        xy = truth[t - 1, live, :2]
        after = dict(zip(l1.tolist(), r1.tolist()))
        for i in np.flatnonzero(r0 >= MIN_EXISTENCE):
            if int(l0[i]) not in after:              # pruned: not a charge at the edge
                continue
            d = np.hypot(*(xy - m0[i]).T)
            j = int(np.argmin(d))
            if d[j] > MAX_DISTANCE:
                continue
            x, y = xy[j]
            band = int(np.searchsorted(BANDS, min(x, y, width - x, height - y), side="right")) - 1
            if not 0 <= band < nb:
                continue
            expected[band] += max(0.0, 1.0 - after[int(l0[i])] / (r0[i] * survival))
            left[band] += not alive[t, live[j]]
            pairs[band] += 1
    return pairs, expected, left


def calibration(study_file: str, method: str, seed: int, runs: int) -> list[str]:
    """The table (module docstring) over ``runs`` runs of ``method`` on ``seed``."""
    from sensorplan.study.file import load_study

    study = dataclasses.replace(load_study(study_file), seed=seed, runs=runs)
    m = next(x for x in study.methods if x.name == method)
    survival = float(m.settings.tracker.survival_probability)
    W, H = study.scenario.world.width, study.scenario.world.height
    nb = len(BANDS) - 1
    pairs = np.zeros(nb, dtype=np.int64)
    expected = np.zeros(nb)
    left = np.zeros(nb, dtype=np.int64)
    for run in range(runs):
        ep, record = _recorded(study, m.settings, run)
        p, e, lf = tally(record, ep.truth, ep.alive, W, H, survival)
        pairs += p
        expected += e
        left += lf
    lines = [f"method {method}, seed {seed}, {runs} runs "
             f"(edge exit {m.settings.tracker.edge_exit}, process noise "
             f"{m.settings.tracker.process_noise:g})",
             "| target's distance to the edge (m) | pairs | exits the tracker expects "
             "| targets that left |", "|---|--:|--:|--:|"]
    for b in range(nb):
        lines.append(f"| {BANDS[b]:g}-{BANDS[b + 1]:g} | {pairs[b]} | {expected[b]:.1f} "
                     f"| {left[b]} |")
    lines.append(f"| all | {pairs.sum()} | {expected.sum():.1f} | {left.sum()} |")
    return lines


def closed_loop_parser(doc: str) -> argparse.ArgumentParser:
    """The arguments of a script that reruns a study method's closed loop on a seed: the
    study file, ``--method``, ``--seed`` and ``--runs``."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("study_file")
    p.add_argument("--method", default="pmb")
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--runs", type=int, default=8)
    return p


def main(argv: list[str] | None = None) -> None:
    a = closed_loop_parser(__doc__).parse_args(argv)
    print("\n".join(calibration(a.study_file, a.method, a.seed, a.runs)))


if __name__ == "__main__":
    main()
