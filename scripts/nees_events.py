"""Where a tracker's NEES comes from: every target-step of a few runs, labelled by event.

Runs one method of a study file on a few runs (the study's scenario and settings, a seed
given here) and writes one row per run, step and target: NEES, position error, and what
happened to the track and the truth that step and how long ago each event last happened:
a detection used, a look that missed in the open (target truly outside the field of view),
a look that missed because a building hid the target, a map correction, an inflation, a
restart, the truth bouncing off a wall (a velocity jump the filter's model calls
impossible), and the number of steps since the target was last measured.

    python scripts/nees_events.py studies/urban.toml "myopic cumulative" --runs 20 \
        --seed 61001 --out runs/diag/urban.parquet [--set tracker.known_map=false ...]
    python scripts/nees_events.py --summary runs/diag/urban.parquet

The summary prints the ANEES and the share of NEES above 13.28 by event class (the class
of a target-step is its most recent event within the last 5 steps, else "quiet" or
"unobserved k" by the time since the last detection), each class's share of all
target-steps and of the summed NEES: where the excess comes from. A second table splits
the ANEES by target kind into its position and velocity parts (each the NEES of that
2-vector under its own block of the covariance: 2 for an honest filter), which tells a
motion model too cautious for one kind of target from an error in the position.

For a multi-target tracker (``pmb``, ``gnn``) a target-step's estimate is the track GOSPA
assigns to it (target-steps without one are left out), as for the study tables' ANEES;
its looks aim at tracks, not targets, so only "detected" (by the simulator's record of
which target a detection came from) and the time since it label those target-steps.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from sensorplan.errors import ConfigError

#: NEES above this is in the top 1 % of chi-square(4).
NEES_HIGH = 13.28
#: A velocity jump (m/s, either axis, in one step) the CWNA truth (q = 0.05) never makes:
#: the truth bounced off a wall.
BOUNCE_JUMP = 2.0
#: Steps an event stays the label of a target-step.
WINDOW = 5


def _settings_with(settings: Any, assignments: list[str]) -> Any:
    """``settings`` with ``key=value`` (``tracker.key=value`` for tracker settings) set."""
    import json

    tracker_changes: dict[str, Any] = {}
    changes: dict[str, Any] = {}
    for text in assignments:
        key, _, value = text.partition("=")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        if isinstance(parsed, list):
            parsed = tuple(tuple(v) if isinstance(v, list) else v for v in parsed)
        if key.startswith("tracker."):
            tracker_changes[key.removeprefix("tracker.")] = parsed
        else:
            changes[key] = parsed
    if tracker_changes:
        changes["tracker"] = dataclasses.replace(settings.tracker, **tracker_changes)
    return dataclasses.replace(settings, **changes)


def episode_rows(ep: Any, scenario: Any, run: int) -> dict[str, np.ndarray]:
    """One row per step 1..S and target of episode ``ep``, with the event labels (for a
    multi-target tracker, one row per target-step with an assigned track)."""
    from sensorplan.models.sensors import radar_table
    from sensorplan.study.set_metrics import with_assigned_tracks

    known = ep.settings.tracker.kind == "known"
    ep = with_assigned_tracks(ep)
    table = radar_table(tuple(s.params for s in scenario.sensors))
    blds = scenario.building_array
    S1, M, _ = ep.truth.shape
    none = np.zeros((S1, M), dtype=bool)
    open_miss, hidden_miss = _missed_looks(ep, table, blds) if known else (none, none)
    detected = ep.measured.any(axis=2)
    jump = np.zeros((S1, M), dtype=bool)
    jump[1:] = (np.abs(np.diff(ep.truth[..., 2:], axis=0)) > BOUNCE_JUMP).any(axis=2)
    events = {"detected": detected, "open_miss": open_miss, "hidden_miss": hidden_miss,
              "map": ep.map_corrected, "inflated": ep.inflated, "restart": ep.restarted,
              "bounce": jump}
    position, velocity = nees_parts(ep.truth, ep.estimate, ep.cov)
    rows: dict[str, np.ndarray] = {
        "run": np.full((S1 - 1) * M, run), "step": np.repeat(np.arange(1, S1), M),
        "target": np.tile(np.arange(M), S1 - 1),
        "kind": np.tile(np.array(ep.target_kinds), S1 - 1),
        "nees": ep.nees[1:].ravel(), "error": ep.error[1:].ravel(),
        "nees_pos": position[1:].ravel(), "nees_vel": velocity[1:].ravel(),
        "in_building": _building_mass(ep, blds)[1:].ravel(),
        "truth_in_view": (_truth_in_view(ep, table) if known else none)[1:].ravel(),
        "pos_sd": np.sqrt(np.trace(ep.cov[1:, :, :2, :2], axis1=2, axis2=3)).ravel(),
    }
    for name, ev in events.items():
        since = np.full((S1, M), 10**6)
        last = np.full(M, -10**6)
        for t in range(S1):
            last = np.where(ev[t], t, last)
            since[t] = t - last
        rows[name] = ev[1:].ravel()
        rows["since_" + name] = since[1:].ravel()
    keep = np.isfinite(rows["nees"])          # a multi-target tracker's unassigned steps
    return {name: column[keep] for name, column in rows.items()}


def _missed_looks(ep: Any, table: np.ndarray, blds: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Which target-steps ``(S+1, M)`` had a look at them miss in the open (the target
    truly outside the field of view), and which a look that a building hid it from (a
    tracker of known targets: look i at step t aims at target ``looked[t, i]``)."""
    from sensorplan.models import radar
    from sensorplan.models.sensors import ALTITUDE

    S1, M, _ = ep.truth.shape
    N = ep.looked.shape[1]
    hidden_miss = np.zeros((S1, M), dtype=bool)
    open_miss = np.zeros((S1, M), dtype=bool)
    for t in range(1, S1):
        for i in range(N):
            j = ep.looked[t, i]
            if j < 0 or not ep.missed[t, i]:
                continue
            hid = bool(len(blds)) and bool(radar.hidden_looks(
                blds, ep.sensor_positions[t, i][None], table[i:i + 1, ALTITUDE],
                ep.truth[t, j, :2][None])[0])
            if hid:
                hidden_miss[t, j] = True
            else:
                open_miss[t, j] = True
    return open_miss, hidden_miss


def _building_mass(ep: Any, blds: np.ndarray) -> np.ndarray:
    """Share of each track's position mass inside a building footprint ``(S+1, M)`` (512
    quadrature points), where no target can be."""
    from sensorplan.models.truth import inside_buildings
    from sensorplan.tracking.missed import standard_points

    if len(blds) == 0:
        return np.zeros(ep.nees.shape)
    x = standard_points()[:, :2]
    ok = np.isfinite(ep.estimate[..., 0])          # a multi-target tracker's assigned steps
    L = np.linalg.cholesky(ep.cov[ok][:, :2, :2])
    pts = ep.estimate[ok][:, None, :2] + np.einsum("nij,sj->nsi", L, x)
    out = np.full(ok.shape, np.nan)
    out[ok] = inside_buildings(pts, blds).mean(axis=-1)
    return out


def _truth_in_view(ep: Any, table: np.ndarray) -> np.ndarray:
    """Whether any sensor that looked at the target had it in its field of view (ignoring
    buildings) ``(S+1, M)``."""
    from sensorplan.models import radar

    S1, M, _ = ep.truth.shape
    out = np.zeros((S1, M), dtype=bool)
    for t in range(1, S1):
        i = np.flatnonzero(ep.looked[t] >= 0)
        if i.size:
            j = ep.looked[t, i]
            vis = radar.measure_looks(table, i, ep.truth[t, j, :2], ep.sensor_positions[t, i],
                                      ep.sensor_headings[t, i])[3]
            out[t, j[vis]] = True
    return out


def nees_parts(truth: np.ndarray, estimate: np.ndarray, cov: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """NEES of the position ``[x, y]`` and of the velocity ``[vx, vy]`` alone, each under
    its own 2 x 2 block of ``cov (..., 4, 4)`` (chi-square(2) for an honest filter: mean 2).
    NaN where the estimate is NaN (no track assigned)."""
    from sensorplan.tracking.ekf import nees

    ok = np.isfinite(estimate[..., 0])

    def part(s: slice) -> np.ndarray:
        out = np.full(ok.shape, np.nan)
        out[ok] = nees(truth[ok][:, s], estimate[ok][:, s], cov[ok][:, s, s])
        return out

    return part(slice(0, 2)), part(slice(2, 4))


def collect(study_path: str, method: str, runs: int, seed: int, assignments: list[str],
            preset: str | None = None, steps: int | None = None,
            episodes: str | None = None) -> Any:
    import pandas as pd

    from sensorplan.simulation.run import run_episode
    from sensorplan.study.file import load_study

    study = load_study(study_path)
    names = [m.name for m in study.methods]
    if method not in names:
        raise ConfigError("method", f"{method!r} is not a method of {study_path} "
                                    f"(methods: {', '.join(names)})")
    settings = _settings_with(study.methods[names.index(method)].settings, assignments)
    if steps is not None:
        settings = dataclasses.replace(settings, steps=steps)
    scenario = study.scenario
    if preset is not None:
        from sensorplan.simulation.scenario import PRESETS

        scenario = PRESETS[preset]()
    parts = []
    for r in range(runs):
        ep = run_episode(scenario, settings, np.random.SeedSequence(seed, spawn_key=(r,)))
        rows = pd.DataFrame(episode_rows(ep, scenario, r))
        parts.append(rows)
        if episodes:
            Path(episodes).mkdir(parents=True, exist_ok=True)
            ep.save(Path(episodes) / f"run_{r}.npz")
        print(f"run {r}: ANEES {rows['nees'].mean():.2f} over {len(rows)} target-steps, "
              f"median error {rows['error'].median():.1f} m", file=sys.stderr, flush=True)
    return pd.concat(parts, ignore_index=True)


def label(df: Any) -> Any:
    """Each target-step's class: its most recent event within :data:`WINDOW` steps (the
    priority order breaks ties within a step), else quiet / unobserved by the time since
    the last detection."""
    order = ["restart", "inflated", "hidden_miss", "bounce", "open_miss", "map"]
    cls = np.where(df["since_detected"] == 0, "detected", "")
    best = np.full(len(df), WINDOW + 1)
    for name in order:
        s = df["since_" + name].to_numpy()
        take = (s <= WINDOW) & (s < best)
        cls = np.where(take, np.char.add(name, np.char.add(" +", s.astype(str))), cls)
        best = np.where(take, s, best)
    since = df["since_detected"].to_numpy()
    quiet = np.where(since <= 5, "unobserved 1-5",
                     np.where(since <= 20, "unobserved 6-20", "unobserved > 20"))
    cls = np.where(cls == "", quiet, cls)
    return cls


def summary(df: Any, coarse: bool = True) -> str:
    df = df.copy()
    cls = label(df)
    if coarse:
        cls = np.array([c.split(" +")[0] + (" (0-5 steps ago)" if " +" in c else "")
                        for c in cls])
    df["class"] = cls
    total = df["nees"].sum()
    g = df.groupby("class")
    out = ["| class | target-steps | share | ANEES | NEES > 13.28 | share of summed NEES |"
           " median error (m) |", "|---|--:|--:|--:|--:|--:|--:|"]
    for name, d in sorted(g, key=lambda kv: -kv[1]["nees"].sum()):
        out.append(f"| {name} | {len(d)} | {100 * len(d) / len(df):.1f} % | "
                   f"{d['nees'].mean():.2f} | {100 * (d['nees'] > NEES_HIGH).mean():.1f} % | "
                   f"{100 * d['nees'].sum() / total:.1f} % | {d['error'].median():.1f} |")
    runs = df.groupby("run")["nees"].mean()
    out.append(f"\nall: {len(df)} target-steps, ANEES {df['nees'].mean():.2f}, "
               f"NEES > 13.28 {100 * (df['nees'] > NEES_HIGH).mean():.1f} %, "
               f"median run ANEES {runs.median():.2f}, ANEES without the worst run "
               f"{df[df['run'] != runs.idxmax()]['nees'].mean():.2f}")
    if "nees_vel" in df:
        out += ["", parts_table(df)]
    return "\n".join(out)


def parts_table(df: Any) -> str:
    """The ANEES by target kind and in all, with its position and velocity parts (each 2
    for an honest filter, the whole 4)."""
    out = ["| target kind | target-steps | ANEES (4) | position part (2) | velocity part (2) |",
           "|---|--:|--:|--:|--:|"]
    groups = [(str(k), d) for k, d in df.groupby("kind")] + [("all", df)]
    for name, d in groups:
        out.append(f"| {name} | {len(d)} | {d['nees'].mean():.2f} | "
                   f"{d['nees_pos'].mean():.2f} | {d['nees_vel'].mean():.2f} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("study", nargs="?")
    p.add_argument("method", nargs="?")
    p.add_argument("--runs", type=int, default=10)
    p.add_argument("--seed", type=int, default=61001)
    p.add_argument("--preset", help="run this preset instead of the study's scenario")
    p.add_argument("--steps", type=int, help="steps per run instead of the study's")
    p.add_argument("--episodes", metavar="DIR", help="also save every episode here")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--out")
    p.add_argument("--summary", metavar="PARQUET")
    p.add_argument("--fine", action="store_true", help="one class per event and lag")
    a = p.parse_args(argv)
    import pandas as pd

    if a.summary:
        print(summary(pd.read_parquet(a.summary), coarse=not a.fine))
        return
    try:
        df = collect(a.study, a.method, a.runs, a.seed, a.set, a.preset, a.steps,
                     a.episodes)
    except ConfigError as err:
        p.error(str(err))
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        df.to_parquet(a.out)
    print(summary(df, coarse=not a.fine))


if __name__ == "__main__":
    main()
