"""Where the untracked target-steps of a multi-target tracker come from.

A live target-step is *untracked* when no reported track is assigned to the target within c
(GOSPA's assignment, :func:`sensorplan.study.set_metrics.set_metrics`), the share that the
search-and-track rule (a) bounds.

``study DIR [--method pmb]``: a finished study's tables (reported tracks only). Each
untracked target-step is split by what became of the last track assigned to the target:
*taken* (a reported track within c, assigned to another target), *displaced* (the target's
last track still reported, farther than c), *unreported* (the target's last track no longer
reported: faded below the report threshold or pruned; the tables cannot tell which) and
*never* (the target never had a track). Also the share of all untracked target-steps in the
worst 10 % of runs.

``held DIR [--method pmb]``: a finished study's tables: every held target lost (the honesty
table's count) with its run, target, first step, length and class at the stretch's first
step (as for ``study``), and the count per target (a recorded truth is the same in every
run, so a target lost in many runs points at a place or a manoeuvre).

``tail DIR [DIR ...] [--method pmb] [--plot FILE.png [--label TEXT ...]]``: how the held
stretches' lengths fall off, pooled over finished studies' tables of one method: for each
length L (1, 5, 10, 15, 20, 25, 30, 40 steps) the stretches of L or more consecutive live
steps without a reported track after a target's first report, and the runs with one (the
honesty table counts L = 20). Whether the rule's 20 steps sit on a smooth tail or on a
separate failure. ``--method`` again for another method's table; ``--plot`` draws each
directory's share of runs against L (not pooled; ``--label`` names them), a panel per
method.

``closed-loop STUDY.toml --method pmb --seed S --runs R``: runs the method's closed loop on
seed S (a development seed, not a study's) and records every Bernoulli after every step,
reported or not, and each look's aim. Each untracked target-step is then
*taken* (as above); *faded* (a Bernoulli within c, its existence below the report
threshold; with its existence, whether it carries the target's last label, and whether it
was reported at the last decision: planning sees only reported tracks); *displaced* (no
Bernoulli within c, the target's last label still held by a Bernoulli beyond c);
*gone* (no Bernoulli within c, the target's last label pruned, or never had one). Per class:
the steps since the target was last detected and since a look was last aimed at the label.

``lost STUDY.toml --method pmb --seed S --runs R``: runs the closed loop likewise and lists
every held target lost (the honesty table's count: a target, after its first report, 20 or
more consecutive live steps without a reported track within c): its run, target, first step
and length, how many steps of the stretch some look detected it, how many of the 10 steps
before it, its median distance to the nearest platform during it, its class at the
stretch's first step (as for ``closed-loop``, with that Bernoulli's existence and distance),
in how many of the stretch's steps a look was aimed at that class's label, in how many
the target stood inside some platform's ground-range band (a look with the right heading
could have seen it, line of sight aside), in how many the Bernoullis within c of it
summed to the report threshold or more (existence split between duplicates), and the
step, if any, in the stretch or the 10 before it at which the target's last track was
*pulled*: its existence rose while no look detected the target, and it moved more than
10 m farther from the target (it took a detection that was not its target's). A stretch in which
the target was detected but no track formed is the tracker's failure; one in which it was
not detected, planning's (no look went there) or the sensor's.

``trace STUDY.toml --method pmb --seed S --run R --target J --steps A:B``: one run's closed
loop, printed step by step for target J from step A to B: the label GOSPA assigns it and
its last one, whether a look detected it, its speed, its ground range to each platform, the
label each platform's look was aimed at, the three Bernoullis nearest to it after the step
(label, existence, distance, position spread, position NEES) and the Bernoullis recycled
within 60 m of it during the step (their existence and distance). What a ``lost`` row
summarises, for reading one stretch.

    python scripts/untracked_diagnosis.py study runs/search_conditions_search
    python scripts/untracked_diagnosis.py held runs/honest_table_traffic_cleaned --method pg
    python scripts/untracked_diagnosis.py tail runs/search_resolved runs/search_established \
        --method pg
    python scripts/untracked_diagnosis.py closed-loop studies/search_conditions_search.toml \
        --method pmb --seed 120419 --runs 60 [--planning-threshold 0.1]
    python scripts/untracked_diagnosis.py lost studies/radar_lost_targets.toml --method pmb \
        --seed 120419 --runs 100
    python scripts/untracked_diagnosis.py trace \
        studies/development/search_four_platforms_dev.toml --method pg/4platforms \
        --seed 120453 --run 93 --target 5 --steps 110:140
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sensorplan.study.set_metrics import LOST_STEPS, set_metrics

CLASSES_STUDY = ("taken", "displaced", "unreported", "never")
CLASSES_LOOP = ("taken", "faded", "displaced", "gone")


def _last_label(target: np.ndarray, step: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Per row (sorted by target, then step): the label assigned to the target at its latest
    earlier-or-same step with an assignment (-1: none yet)."""
    out = np.full(len(label), -1, dtype=np.int64)
    order = np.lexsort((step, target))
    cur_t, cur = None, -1
    for k in order:
        if target[k] != cur_t:
            cur_t, cur = target[k], -1
        if label[k] >= 0:
            cur = label[k]
        out[k] = cur
    return out


def _worst_share(untracked: np.ndarray) -> float:
    """Share (%) of all untracked target-steps in the worst 10 % of runs (by count)."""
    n = max(1, int(round(0.1 * len(untracked))))
    return 100.0 * float(np.sort(untracked)[::-1][:n].sum()) / max(float(untracked.sum()), 1.0)


def _study_runs(directory: str, method: str) -> Iterator[tuple[Any, ...]]:
    """Per run of ``method`` in a finished study's tables (reported tracks only): the run,
    the live target-steps' step, target and position, the reported tracks' step, label and
    position, GOSPA's assignment at the study's cut-off and each target-step's last label.
    """
    from sensorplan.study.storage import load_study_dir

    tables = load_study_dir(directory)
    names = [m.name for m in tables.study.methods]
    if method not in names:
        raise MethodNotFound(f"--method: {directory} has no method {method!r} (its methods: "
                             f"{', '.join(names)})")
    c = float(tables.study.methods[0].settings.gospa_c)
    steps = tables.steps[(tables.steps["step"] >= 1) & (tables.steps["method"] == method)]
    tracks = tables.tracks[(tables.tracks["step"] >= 1) & (tables.tracks["method"] == method)]
    by_run = dict(tuple(tracks.groupby("run", observed=True)))
    for run, s in steps.groupby("run", observed=True):
        y = by_run.get(run, tracks.iloc[:0])
        step, target = s["step"].to_numpy(np.int64), s["target"].to_numpy(np.int64)
        xy = s[["x", "y"]].to_numpy(float)
        ystep, ylabel = y["step"].to_numpy(np.int64), y["label"].to_numpy(np.int64)
        yxy = y[["x", "y"]].to_numpy(float)
        sm = set_metrics(step - 1, target, xy, ystep - 1, ylabel, yxy, c,
                         n_steps=tables.study.steps)
        yield (run, step, target, xy, ystep, ylabel, yxy, c, sm,
               _last_label(target, step, sm.label))


def study_breakdown(directory: str, method: str) -> list[str]:
    """The breakdown of a finished study's untracked target-steps (module docstring)."""
    counts = dict.fromkeys(CLASSES_STUDY, 0)
    per_run_untracked, per_run_live = [], []
    for _, step, _target, xy, ystep, ylabel, yxy, c, sm, last in _study_runs(directory,
                                                                              method):
        gap = np.flatnonzero(~sm.assigned)
        per_run_untracked.append(len(gap))
        per_run_live.append(len(step))
        reported = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(ystep, ylabel))}
        for k in gap:
            at = ystep == step[k]
            d = np.hypot(*(yxy[at] - xy[k]).T)
            if np.any(d < c):
                counts["taken"] += 1
            elif last[k] < 0:
                counts["never"] += 1
            elif (int(step[k]), int(last[k])) in reported:
                counts["displaced"] += 1
            else:
                counts["unreported"] += 1
    u = np.array(per_run_untracked, dtype=float)
    live = np.array(per_run_live, dtype=float)
    total = u.sum()
    lines = [f"method {method}: {len(u)} runs, {int(total)} untracked of {int(live.sum())} "
             f"live target-steps ({100 * total / live.sum():.2f} %; mean of run shares "
             f"{100 * np.mean(u / live):.2f} %)",
             f"share of the untracked target-steps in the worst 10 % of runs: "
             f"{_worst_share(u):.1f} %",
             f"runs with no untracked target-step: {int(np.sum(u == 0))}"]
    lines += [f"  {k}: {v} ({100 * v / max(total, 1):.1f} %)" for k, v in counts.items()]
    return lines


def study_held(directory: str, method: str) -> list[str]:
    """Every held target lost in a finished study's tables (reported tracks only): its run,
    target, first step and length, and its class at the stretch's first step (as for
    ``study``); then the count per target, since a recorded truth is the same in every run.
    """
    lines = ["| run | target | first step | length | class at its first step |",
             "|--:|--:|--:|--:|---|"]
    per_target: dict[int, int] = {}
    runs = 0
    for run, step, target, xy, ystep, ylabel, yxy, c, sm, last in _study_runs(directory,
                                                                               method):
        runs += 1
        reported = set(zip(ystep.tolist(), ylabel.tolist()))
        for j, k, s0, n in target_stretches(step, target, sm.assigned):
            d = np.hypot(*(yxy[ystep == s0] - xy[k]).T)
            if np.any(d < c):
                cls = "taken"
            elif (s0, int(last[k])) in reported:
                cls = "displaced"
            else:
                cls = "unreported"
            per_target[j] = per_target.get(j, 0) + 1
            lines.append(f"| {run} | {j} | {s0} | {n} | {cls} |")
    lines.append(f"method {method}, {runs} runs: {sum(per_target.values())} held targets "
                 f"lost; per target (target: stretches): "
                 + ", ".join(f"{j}: {v}" for j, v in sorted(per_target.items(),
                                                           key=lambda kv: -kv[1])))
    return lines


class _Probe:
    """Records a run's Bernoullis after every step and each epoch's aimed labels."""

    def __init__(self) -> None:
        self.bern: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.aims: list[np.ndarray] = []           # per step: labels looked at (-1 none)
        self.decided: list[set[int]] = []          # per step: labels reported at the
        self.current_aims = np.zeros(0, dtype=np.int64)   # last decision
        self.current_decided: set[int] = set()
        self.covs: list[np.ndarray] = []           # per step: position covariances
        self.recycled: list[tuple[int, float, np.ndarray]] = []   # (step, r, mean)

    def install(self) -> Any:
        import sensorplan.simulation.run as run_mod
        from sensorplan.tracking.base import planning_tracks
        from sensorplan.tracking.pmb.tracker import PMBTracker

        probe = self
        make_tracker, epoch = run_mod.make_tracker, run_mod._Schedule.epoch
        prune = PMBTracker._prune

        def prune_(self: Any) -> None:
            if self.recycle_threshold > 0.0:
                low = self.bern.r < self.recycle_threshold
                # Recycled in a predict or look of the step the next update records.
                probe.recycled.extend((len(probe.bern) + 1, float(r), m.copy()) for r, m in
                                      zip(self.bern.r[low], self.bern.means[low, :2]))
            prune(self)

        def make(*args: Any, **kwargs: Any) -> Any:
            tracker = make_tracker(*args, **kwargs)
            update = tracker.update

            def recorded(looks: Any) -> Any:
                out = update(looks)
                b = tracker.bern
                probe.bern.append((b.r.copy(), b.means[:, :2].copy(), b.labels.copy()))
                probe.covs.append(b.covs[:, :2, :2].copy())
                probe.aims.append(probe.current_aims.copy())
                probe.decided.append(probe.current_decided)
                return out

            tracker.update = recorded
            return tracker

        def epoch_(self: Any, t: int, tracker: Any, record: Any) -> None:
            due = self.epoch_index == self.per_plan
            epoch(self, t, tracker, record)
            tracks = planning_tracks(tracker)
            if due:
                probe.current_decided = {int(v) for v in tracks.labels}
            probe.current_aims = np.where(self.aimed >= 0,
                                          tracks.labels[np.maximum(self.aimed, 0)]
                                          if len(tracks) else -1, -1)

        run_mod.make_tracker = make
        run_mod._Schedule.epoch = epoch_
        PMBTracker._prune = prune_                     # type: ignore[method-assign]
        return lambda: (setattr(run_mod, "make_tracker", make_tracker),
                        setattr(run_mod._Schedule, "epoch", epoch),
                        setattr(PMBTracker, "_prune", prune))


def _assignment(ep: Any, c: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """An episode's live target-steps (step, target, true position) and GOSPA's assignment
    of its reported tracks to them at cut-off ``c``."""
    t_idx, j_idx = np.nonzero(ep.alive[1:])
    step = t_idx + 1
    xy = ep.truth[step, j_idx, :2]
    ys = ep.track_step >= 1
    sm = set_metrics(step - 1, j_idx, xy, ep.track_step[ys] - 1, ep.track_label[ys],
                     ep.track_mean[ys, :2], c, n_steps=ep.truth.shape[0] - 1)
    return step, j_idx, xy, sm


def _recorded_run(study: Any, settings: Any, run: int) -> tuple[Any, _Probe, np.ndarray,
                                                                  np.ndarray, np.ndarray, Any,
                                                                  np.ndarray]:
    """Run ``run`` of ``study`` with ``settings`` under a :class:`_Probe`: the episode, the
    probe, the live target-steps and GOSPA's assignment (:func:`_assignment`, at the study
    cut-off) and each target-step's last assigned label (:func:`_last_label`)."""
    from sensorplan.simulation.run import run_episode

    probe = _Probe()
    restore = probe.install()
    try:
        ep = run_episode(study.scenario, settings, study.run_seed(run))
    finally:
        restore()
    step, j_idx, xy, sm = _assignment(ep, float(settings.gospa_c))
    return ep, probe, step, j_idx, xy, sm, _last_label(j_idx, step, sm.label)


def _classify(bern: tuple[np.ndarray, np.ndarray, np.ndarray], xy: np.ndarray, last: int,
              threshold: float, c: float) -> tuple[str, int, float, float]:
    """Class of one untracked target-step from the tracker's Bernoullis after that step
    (module docstring), with the label it concerns (-1: none) and that Bernoulli's existence
    and distance to the target (nan when there is none)."""
    r, pos, labels = bern
    d = np.hypot(*(pos - xy).T) if len(r) else np.zeros(0)
    near = d < c
    if (near & (r >= threshold)).any():
        return "taken", last, np.nan, np.nan
    if near.any():
        i = int(np.flatnonzero(near)[np.argmax(r[near])])
        return "faded", int(labels[i]), float(r[i]), float(d[i])
    if last >= 0 and np.any(labels == last):
        i = int(np.flatnonzero(labels == last)[0])
        return "displaced", last, float(r[i]), float(d[i])
    return "gone", last, np.nan, np.nan


def pulled_step(steps: list[int], bern: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                xy: np.ndarray, detected: np.ndarray, label: int,
                min_gain: float = 10.0) -> int | None:
    """The first of ``steps`` at which the Bernoulli labelled ``label`` was pulled off its
    target: its existence after the step above the one after the step before, the target
    not detected in the step (``detected`` per step), and its distance to the target
    (``xy`` per step) more than ``min_gain`` metres above the step before's. ``bern[i]``
    is the tracker after ``steps[i]``; None when no step qualifies or the label is absent."""
    def at(i: int) -> tuple[float, float] | None:
        r, pos, labels = bern[i]
        k = np.flatnonzero(labels == label)
        if not len(k):
            return None
        return float(r[k[0]]), float(np.hypot(*(pos[k[0]] - xy[i])))
    for i in range(1, len(steps)):
        before, now = at(i - 1), at(i)
        if (before is not None and now is not None and not detected[i]
                and now[0] > before[0] and now[1] > before[1] + min_gain):
            return steps[i]
    return None


def _existence_within(bern: tuple[np.ndarray, np.ndarray, np.ndarray], xy: np.ndarray,
                      c: float) -> float:
    """The summed existence of the Bernoullis nearer than ``c`` to ``xy``."""
    r, pos, _ = bern
    if not len(r):
        return 0.0
    return float(r[np.hypot(*(pos - xy).T) < c].sum())


class MethodNotFound(ValueError):
    """A study file has no method of the name asked for."""


def _study_method(study_file: str, method: str, seed: int, runs: int) -> tuple[Any, Any]:
    """The study of ``study_file`` on ``seed`` with ``runs`` runs, and its method named
    ``method`` (:class:`MethodNotFound`, naming the methods there are, if it has none of
    that name)."""
    from sensorplan.study.file import load_study

    study = dataclasses.replace(load_study(study_file), seed=seed, runs=runs)
    for m in study.methods:
        if m.name == method:
            return study, m
    raise MethodNotFound(f"--method: {study_file} has no method {method!r} (its methods: "
                     f"{', '.join(x.name for x in study.methods)})")


def _step_range(text: str) -> tuple[int, int]:
    """``A:B`` as two step numbers, 1 <= A <= B (argparse's type for ``--steps``)."""
    first, sep, last = text.partition(":")
    try:
        a, b = int(first), int(last)
    except ValueError:
        a, b = 0, -1
    if not sep or not 1 <= a <= b:
        raise argparse.ArgumentTypeError(f"must be FIRST:LAST with 1 <= FIRST <= LAST, got "
                                         f"{text!r}")
    return a, b


def loop_breakdown(study_file: str, method: str, seed: int, runs: int,
                   planning_threshold: float | None = None) -> list[str]:
    """Run ``runs`` closed loops of ``method`` on ``seed`` (with its tracker's
    ``planning_threshold`` replaced, if given) and break their untracked target-steps down
    (module docstring)."""
    study, m = _study_method(study_file, method, seed, runs)
    if planning_threshold is not None:
        tracker = dataclasses.replace(m.settings.tracker, planning_threshold=planning_threshold)
        m = dataclasses.replace(m, settings=dataclasses.replace(m.settings, tracker=tracker))
    threshold = float(m.settings.tracker.report_threshold)
    c = float(m.settings.gospa_c)
    counts = dict.fromkeys(CLASSES_LOOP, 0)
    faded_r: list[float] = []
    displaced_r: list[float] = []
    displaced_d: list[float] = []
    starts = dict.fromkeys(CLASSES_LOOP, 0)
    faded_same, faded_decided = 0, 0
    since_det: dict[str, list[int]] = {k: [] for k in CLASSES_LOOP}
    since_aim: dict[str, list[int]] = {k: [] for k in CLASSES_LOOP}
    per_run_u, per_run_live = [], []
    for run in range(runs):
        ep, probe, step, j_idx, xy, sm, last = _recorded_run(study, m.settings, run)
        detected = ep.measured[:, :, :].any(axis=2)                     # (S+1, M)
        gap = np.flatnonzero(~sm.assigned)
        row = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(step, j_idx))}
        per_run_u.append(len(gap))
        per_run_live.append(len(step))
        for k in gap:
            t, j = int(step[k]), int(j_idx[k])
            prev = np.flatnonzero(detected[1:t + 1, j])
            sd = t - (int(prev[-1]) + 1) if prev.size else t
            cls, lab, r_i, d_i = _classify(probe.bern[t - 1], xy[k], int(last[k]),
                                           threshold, c)
            if cls == "faded":
                faded_r.append(r_i)
                faded_same += int(lab == int(last[k]))
                faded_decided += int(lab in probe.decided[t - 1])
            elif cls == "displaced":
                displaced_r.append(r_i)
                displaced_d.append(d_i)
            aimed = [s for s in range(t) if lab >= 0 and np.any(probe.aims[s] == lab)]
            counts[cls] += 1
            before = row.get((t - 1, j))
            if before is None or sm.assigned[before]:
                starts[cls] += 1          # the first step of a stretch without a track
            since_det[cls].append(sd)
            since_aim[cls].append(t - (aimed[-1] + 1) if aimed else t)
    u, live = np.array(per_run_u, dtype=float), np.array(per_run_live, dtype=float)
    total = u.sum()
    lines = [f"method {method}, seed {seed}, {runs} runs: {int(total)} untracked of "
             f"{int(live.sum())} live target-steps (mean of run shares "
             f"{100 * np.mean(u / live):.2f} %, median {100 * np.median(u / live):.2f} %, "
             f"max {100 * np.max(u / live):.2f} %); planning threshold "
             f"{m.settings.tracker.planning_threshold}",
             f"share of the untracked target-steps in the worst 10 % of runs: "
             f"{_worst_share(u):.1f} %"]
    for k in CLASSES_LOOP:
        v = counts[k]
        row = f"  {k}: {v} ({100 * v / max(total, 1):.1f} %)"
        if v:
            row += (f"; steps since last detected median {np.median(since_det[k]):.0f} "
                    f"(90 % {np.percentile(since_det[k], 90):.0f}); since a look was aimed "
                    f"at its label median {np.median(since_aim[k]):.0f} "
                    f"(90 % {np.percentile(since_aim[k], 90):.0f})")
        lines.append(row)
    n_starts = sum(starts.values())
    lines.append(f"  stretches without a track: {n_starts}; class at their first step: "
                 + ", ".join(f"{k} {100 * v / max(n_starts, 1):.1f} %"
                             for k, v in starts.items()))
    if displaced_r:
        dr, dd = np.array(displaced_r), np.array(displaced_d)
        lines.append(f"  displaced: its Bernoulli's existence median {np.median(dr):.3f}, "
                     f"reported (>= threshold) {100 * np.mean(dr >= threshold):.1f} %; its "
                     f"distance to the target median {np.median(dd):.0f} m (90 % "
                     f"{np.percentile(dd, 90):.0f} m)")
    if faded_r:
        fr = np.array(faded_r)
        lines.append(f"  faded: existence median {np.median(fr):.3f}, quartiles "
                     f"{np.percentile(fr, 25):.3f}-{np.percentile(fr, 75):.3f}; >= 0.1: "
                     f"{100 * np.mean(fr >= 0.1):.1f} %, >= 0.01: "
                     f"{100 * np.mean(fr >= 0.01):.1f} %; carries the target's last label "
                     f"{100 * faded_same / len(fr):.1f} %; reported at the last decision "
                     f"(planned on) {100 * faded_decided / len(fr):.1f} %")
    return lines


def held_stretches(step: np.ndarray, assigned: np.ndarray, min_length: int = LOST_STEPS
                   ) -> list[tuple[int, int]]:
    """The stretches of at least ``min_length`` consecutive live steps without a track after
    a target's first report, as ``(first step, length)``.

    Parameters
    ----------
    step : (n,) int    the target's live steps, increasing
    assigned : (n,) bool    whether a track was assigned to it at each of them
    """
    hits = np.flatnonzero(assigned)
    out: list[tuple[int, int]] = []
    if hits.size == 0:
        return out
    st, a = step[hits[0]:], assigned[hits[0]:]
    # A stretch breaks at a track or at a gap in the target's life.
    breaks = a | np.r_[True, np.diff(st) != 1]
    first = 0
    for k in range(1, len(st) + 1):
        if k == len(st) or breaks[k]:
            run = np.flatnonzero(~a[first:k]) + first
            if run.size >= min_length:
                out.append((int(st[run[0]]), int(run.size)))
            first = k
    return out


def target_stretches(step: np.ndarray, target: np.ndarray, assigned: np.ndarray,
                     min_length: int = LOST_STEPS) -> Iterator[tuple[int, int, int, int]]:
    """Every target's held stretches (``held_stretches``) from rows of many targets, as
    ``(target, row of the stretch's first step, first step, length)``.

    Parameters
    ----------
    step, target : (n,) int    each row's step and target, in any order
    assigned : (n,) bool    whether a track was assigned to the row's target at its step
    """
    for j in np.unique(target):
        rows = np.flatnonzero(target == j)
        rows = rows[np.argsort(step[rows], kind="stable")]
        for s0, n in held_stretches(step[rows], assigned[rows], min_length):
            yield int(j), int(rows[np.searchsorted(step[rows], s0)]), s0, n


#: The stretch lengths ``tail`` counts from (steps).
TAIL_LENGTHS = (1, 5, 10, 15, 20, 25, 30, 40)


def tail_counts(per_run: list[list[int]], lengths: tuple[int, ...] = TAIL_LENGTHS
                ) -> list[tuple[int, int, int]]:
    """``(L, stretches of L or more steps, runs with one)`` for each L of ``lengths``, from
    each run's held stretch lengths ``per_run``."""
    n = np.array([k for run in per_run for k in run], dtype=np.int64)
    longest = np.array([max(run, default=0) for run in per_run], dtype=np.int64)
    return [(L, int(np.sum(n >= L)), int(np.sum(longest >= L))) for L in lengths]


def _tail_lengths(directory: str, method: str) -> list[list[int]]:
    """Each run's held stretch lengths (1 step or more) of ``method`` in a finished study."""
    return [[n for *_, n in target_stretches(step, target, sm.assigned, 1)]
            for _, step, target, *_rest, sm, _last in _study_runs(directory, method)]


def study_tail(directories: list[str], method: str) -> list[str]:
    """The ``tail`` table of ``method``'s held stretches, pooled over ``directories``."""
    per_run = [run for directory in directories
               for run in _tail_lengths(directory, method)]
    runs = len(per_run)
    lines = [f"method {method}, {runs} runs ({', '.join(directories)})", "",
             "| L (steps) | held stretches of L or more | runs with one (%) |",
             "|--:|--:|--:|"]
    lines += [f"| {L} | {k} | {r} ({100 * r / max(runs, 1):.2f} %) |"
              for L, k, r in tail_counts(per_run)]
    return lines


def tail_curve(per_run: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """``(L, share of runs (%) with a held stretch of L or more steps)`` for every L from 1
    to one past the longest stretch (where the share is 0)."""
    longest = max((max(run, default=0) for run in per_run), default=0)
    lengths = np.arange(1, longest + 2)
    runs = max(len(per_run), 1)
    share = np.array([100.0 * r / runs for _, _, r in tail_counts(per_run, tuple(lengths))])
    return lengths, share


def plot_tail(directories: list[str], methods: list[str], labels: list[str],
              path: str) -> str:
    """Draw each directory's :func:`tail_curve` (not pooled), a panel per method, on a log
    scale with the honesty rule's 20 steps and 1 run in 100 marked; written to ``path``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.6 * len(methods), 3.8), dpi=110, layout="constrained")
    axes = fig.subplots(1, len(methods), sharey=True, squeeze=False)[0]
    for ax, method in zip(axes, methods):
        for directory, label in zip(directories, labels):
            lengths, share = tail_curve(_tail_lengths(directory, method))
            ax.step(lengths, share, where="post", label=label)
        ax.axvline(LOST_STEPS, color="0.4", lw=0.8, ls="--")
        ax.axhline(1.0, color="0.4", lw=0.8, ls=":")
        ax.set_yscale("log", nonpositive="mask")
        ax.set_xlabel("L: untracked steps in a row after a first report")
        ax.set_title(method)
        ax.grid(True, which="major", lw=0.3)
    axes[0].set_ylabel("runs with a stretch of L or more (%)")
    axes[0].legend(fontsize="small", title="study", title_fontsize="small")
    fig.savefig(path, format="png", metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.15)
    return path


def lost_stretches(study_file: str, method: str, seed: int, runs: int,
                   first_run: int = 0) -> list[str]:
    """Run closed loops ``first_run`` to ``runs - 1`` of ``method`` on ``seed`` and list
    every held target lost with what happened during it (module docstring)."""
    study, m = _study_method(study_file, method, seed, runs)
    threshold = float(m.settings.tracker.report_threshold)
    c = float(m.settings.gospa_c)
    lines = ["| run | target | first step | length | steps detected in it | in the 10 before "
             "| median distance to the nearest platform (m) | class at its first step "
             "| existence, distance (m) | steps a look aimed at that label in it "
             "| steps in some platform's ground-range band | steps with existence "
             f"{threshold:g} within c | last track pulled at step |",
             "|--:|--:|--:|--:|--:|--:|--:|---|--:|--:|--:|--:|--:|"]
    detected_in, losing, classes = [], set(), []
    band = np.array([[sp.params.min_ground_range, sp.params.max_ground_range]
                     for sp in study.scenario.sensors])
    in_band, summed, steps, n_pulled = 0, 0, 0, 0
    for run in range(first_run, runs):
        ep, probe, step, j_idx, xy, sm, last = _recorded_run(study, m.settings, run)
        detected = ep.measured.any(axis=2)                               # (S+1, M)
        for j, k0, s0, n in target_stretches(step, j_idx, sm.assigned):
            s1 = s0 + n
            cls, lab, r_i, d_i = _classify(probe.bern[s0 - 1], xy[k0], int(last[k0]),
                                           threshold, c)
            aimed = sum(lab >= 0 and bool(np.any(probe.aims[t - 1] == lab))
                        for t in range(s0, s1))
            seen = int(detected[s0:s1, j].sum())
            before = int(detected[max(1, s0 - 10):s0, j].sum())
            gap = ep.sensor_positions[s0:s1] - ep.truth[s0:s1, j, None, :2]
            ground = np.hypot(gap[..., 0], gap[..., 1])                   # (n, N)
            dist = float(np.median(ground.min(axis=1)))
            # A look with the right heading could see it (line of sight aside).
            n_band = int(((ground >= band[:, 0]) & (ground <= band[:, 1]))
                         .any(axis=1).sum())
            # Existence enough to report it, were it not split between Bernoullis.
            n_sum = sum(_existence_within(probe.bern[t - 1], ep.truth[t, j, :2],
                                          c) >= threshold
                        for t in range(s0, s1))
            # The target's last track before the stretch, from 10 steps before it on.
            span = list(range(max(1, s0 - 10), s1))
            pulled = pulled_step(span, [probe.bern[t - 1] for t in span],
                                 ep.truth[span, j, :2], detected[span, j],
                                 int(last[k0]))
            n_pulled += pulled is not None
            in_band += n_band
            summed += n_sum
            steps += n
            detected_in.append(seen)
            classes.append(cls)
            losing.add(run)
            what = "" if np.isnan(r_i) else f"{r_i:.2f}, {d_i:.0f}"
            lines.append(f"| {run} | {j} | {s0} | {n} | {seen} | {before} | {dist:.0f} "
                         f"| {cls} | {what} | {aimed} | {n_band} | {n_sum} "
                         f"| {'' if pulled is None else pulled} |")
    d = np.array(detected_in)
    lines.append(f"method {method}, seed {seed}, runs {first_run}-{runs - 1}: {len(d)} held "
                 f"targets lost in "
                 f"{len(losing)} runs; detected in 0 steps of "
                 f"the stretch: {int(np.sum(d == 0))}, 1-2: {int(np.sum((d >= 1) & (d <= 2)))}"
                 f", 3 or more: {int(np.sum(d >= 3))}; class at the first step: "
                 + ", ".join(f"{k} {classes.count(k)}" for k in CLASSES_LOOP)
                 + f"; of their {steps} steps, {in_band} with the target in some platform's "
                 f"ground-range band, {summed} with the Bernoullis within c summing to the "
                 f"report threshold or more; {n_pulled} began with the last track pulled")
    return lines


def _nearest(bern: tuple[np.ndarray, np.ndarray, np.ndarray], covs: np.ndarray,
             xy: np.ndarray, n: int = 3) -> list[str]:
    """The ``n`` Bernoullis nearest to ``xy``: label, existence, distance, position spread
    (root of the covariance's trace) and NEES of the position error."""
    r, pos, labels = bern
    err = pos - xy
    d = np.hypot(err[:, 0], err[:, 1])
    out = []
    for i in np.argsort(d, kind="stable")[:n]:
        nees = float(err[i] @ np.linalg.solve(covs[i], err[i]))
        out.append(f"L{labels[i]} r={r[i]:.2f} d={d[i]:.0f} sd={np.sqrt(np.trace(covs[i])):.0f}"
                   f" nees={nees:.1f}")
    return out


def trace_target(study_file: str, method: str, seed: int, run: int, target: int,
                 first: int, last_step: int) -> list[str]:
    """One target's steps ``first..last_step`` in run ``run`` of ``method`` on ``seed``
    (module docstring)."""
    from sensorplan.models.radar.batch import detectable_points
    from sensorplan.models.sensors import radar_table

    study, m = _study_method(study_file, method, seed, run + 1)
    ep, probe, step, j_idx, xy, sm, last = _recorded_run(study, m.settings, run)
    detected = ep.measured.any(axis=2)
    table = radar_table(tuple(s.params for s in study.scenario.sensors))
    platforms = np.arange(len(study.scenario.sensors))
    lines = []
    for t in range(first, last_step + 1):
        k = np.flatnonzero((j_idx == target) & (step == t))
        if not len(k):
            continue
        k0 = int(k[0])
        truth = ep.truth[t, target]
        gap = truth[:2] - ep.sensor_positions[t]                            # (N, 2)
        ground = np.hypot(gap[:, 0], gap[:, 1])
        # Each look's probability of detecting the target where it truly is.
        pd = detectable_points(table, platforms, gap[:, :1], gap[:, 1:],
                               ep.sensor_headings[t], ep.sensor_positions[t],
                               study.scenario.building_array)[:, 0]
        near_recycled = [f"{r:.3f}@{np.hypot(*(mean - truth[:2])):.0f}m"
                         for s, r, mean in probe.recycled
                         if s == t and np.hypot(*(mean - truth[:2])) < 60.0]
        lines.append(f"{t:4d} label {int(sm.label[k0]):4d} (last {int(last[k0]):4d}) "
                     f"detected {int(detected[t, target])} "
                     f"at {np.round(truth[:2]).astype(int).tolist()} "
                     f"speed {np.hypot(*truth[2:4]):.1f} "
                     f"ground {np.round(ground).astype(int).tolist()} "
                     f"pd {np.round(pd, 2).tolist()} "
                     f"aims {probe.aims[t - 1].tolist()} | "
                     + "; ".join(_nearest(probe.bern[t - 1], probe.covs[t - 1], truth[:2]))
                     + (f" | recycled {', '.join(near_recycled)}" if near_recycled else ""))
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    a = sub.add_parser("study")
    a.add_argument("directory")
    a.add_argument("--method", default="pmb")
    h = sub.add_parser("held")
    h.add_argument("directory")
    h.add_argument("--method", default="pmb")
    tl = sub.add_parser("tail")
    tl.add_argument("directories", nargs="+", metavar="DIR")
    tl.add_argument("--method", action="append", dest="methods", metavar="METHOD",
                    help="a method's table (and panel); give it again for more "
                         "(default: pmb)")
    tl.add_argument("--plot", metavar="PNG",
                    help="also draw each directory's curve (not pooled), a panel per "
                         "method, to this file")
    tl.add_argument("--label", action="append", dest="labels", metavar="TEXT",
                    help="the plot's name for each directory, in order (default: the "
                         "directory's name)")
    b = sub.add_parser("closed-loop")
    b.add_argument("study_file")
    b.add_argument("--method", default="pmb")
    b.add_argument("--seed", type=int, required=True)
    b.add_argument("--runs", type=int, default=40)
    b.add_argument("--planning-threshold", type=float, default=None)
    c = sub.add_parser("lost")
    c.add_argument("study_file")
    c.add_argument("--method", default="pmb")
    c.add_argument("--seed", type=int, required=True)
    c.add_argument("--runs", type=int, default=40)
    c.add_argument("--first-run", type=int, default=0,
                   help="start at this run (to share the runs between processes)")
    t = sub.add_parser("trace")
    t.add_argument("study_file")
    t.add_argument("--method", default="pmb")
    t.add_argument("--seed", type=int, required=True)
    t.add_argument("--run", type=int, required=True)
    t.add_argument("--target", type=int, required=True)
    t.add_argument("--steps", required=True, type=_step_range,
                   help="first:last step, both printed")
    args = ap.parse_args(argv)
    if args.what == "tail" and args.labels and len(args.labels) != len(args.directories):
        ap.error(f"--label: give one per directory ({len(args.directories)} directories, "
                 f"{len(args.labels)} labels)")
    from sensorplan.errors import ConfigError

    try:
        _run(args)
    except (MethodNotFound, ConfigError) as e:
        ap.error(str(e))


def _run(args: argparse.Namespace) -> None:
    if args.what == "trace":
        print("\n".join(trace_target(args.study_file, args.method, args.seed, args.run,
                                       args.target, *args.steps)))
    elif args.what == "study":
        print("\n".join(study_breakdown(args.directory, args.method)))
    elif args.what == "held":
        print("\n".join(study_held(args.directory, args.method)))
    elif args.what == "tail":
        methods = args.methods or ["pmb"]
        for i, method in enumerate(methods):
            print(("\n" if i else "") + "\n".join(study_tail(args.directories, method)))
        if args.plot:
            labels = args.labels or [Path(d).name for d in args.directories]
            print(f"wrote {plot_tail(args.directories, methods, labels, args.plot)}")
    elif args.what == "lost":
        print("\n".join(lost_stretches(args.study_file, args.method, args.seed, args.runs,
                                        args.first_run)))
    else:
        print("\n".join(loop_breakdown(args.study_file, args.method, args.seed, args.runs,
                                        args.planning_threshold)))


if __name__ == "__main__":
    main()
