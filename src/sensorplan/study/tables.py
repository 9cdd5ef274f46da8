"""The tidy tables of a study: one row per (run, method, step, target), per decision, per
(run, method, step, sensor), per reported track and step, and per step's GOSPA, built from
episodes (:func:`episode_tables`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._types import FloatArray
from ..simulation.run import Episode
from .lifespan import looked_labels, slot_kinds
from .set_metrics import episode_set_metrics, with_assigned_tracks

#: Tidy tables, in the order a part's files are written (the last one marks it done).
TABLES = ("decisions", "sensors", "tracks", "gospa", "steps")

#: What each table holds, column by column.
TABLE_DOC = {
    "steps": "one row per (run, method, step, live target): run, method, step (0 = initial "
             "state, 1..S), target, kind, error (m, |p_true - p_est|; for a multi-target "
             "tracker of the track GOSPA assigns to it, empty when none), nees (4-D NEES), "
             "measured "
             "(any sensor measured it at that step), measurements (how many did), "
             "negative_update, inflated (missed-look update / inflation), gated_out "
             "(detections of it that fell outside its validation gate), restarted (the track "
             "was restarted from a detection), map_corrected (the known map truncated it), "
             "x, y (true position, m), x_est, y_est (estimated position, m)",
    "decisions": "one row per (run, method, decision): run, method, decision (0-based), step "
                 "(time index of the decision), planning_seconds (wall time of the planner "
                 "call), phi (potential of the chosen plan, nats), converged (null for "
                 "planners without the notion), sweeps (null likewise), mu (with search on: "
                 "the undetected targets the plan expects to find; null with search off), "
                 "search_term (with search on: w mu, Phi's search term, nats; null likewise)",
    "sensors": "one row per (run, method, step, sensor): run, method, step, sensor, x, y "
               "(ground position, m), heading (rad), target (looked-at target, -1 none; for "
               "a multi-target tracker the looked-at track's index in the set the epoch "
               "started from), label (the looked-at track's label, -1 none; the target for "
               "a tracker of known targets), missed (the look missed: target truly outside "
               "the field of view), measured",
    "tracks": "one row per (run, method, step, reported track): run, method, step, label "
              "(the track's label, kept for its life), x, y (its position estimate, m), "
              "existence (its probability of being a real target)",
    "gospa": "one row per (run, method, step >= 1): run, method, step, gospa (m), "
             "localisation, missed, false (its three parts, m^2: they sum to gospa^2), "
             "targets (live targets), tracks (reported tracks), false_tracks (reported tracks "
             "assigned to no target); cut-off c = 50 m, alpha = 2, p = 2; with a tracker "
             "that keeps an intensity of undetected targets (pmb) also undetected (the "
             "expected number of targets never detected after the step's update: the "
             "intensity's sum) and intensity (that intensity on the tracker's grid, float32, "
             "row-major from the map's corner at the origin, at the steps of "
             "intensity_steps(S) only, else null)",
}

#: Steps of a run at which the study stores the whole undetected intensity grid
#: (:func:`intensity_steps`): enough for the report's small multiples at little cost.
INTENSITY_SNAPSHOTS = 5


def intensity_steps(steps: int) -> list[int]:
    """The steps (of ``1..steps``) at which a study stores the undetected intensity grid:
    :data:`INTENSITY_SNAPSHOTS` equally spaced, the last one ``steps``.

    Examples
    --------
    >>> intensity_steps(200), intensity_steps(3)
    ([40, 80, 120, 160, 200], [1, 2, 3])
    """
    k = np.arange(1, INTENSITY_SNAPSHOTS + 1)
    return sorted({max(1, int(round(steps * i / INTENSITY_SNAPSHOTS))) for i in k})


@dataclass
class TaskResult:
    """What a worker sends back: one (run, method)'s tables as columns, and its timing.

    Attributes
    ----------
    run, method : int
    tables : dict of table name -> dict of column name -> (rows,) array
    wall, cpu : float         the task's wall and process CPU time (s)
    planning : float          wall time inside planner calls (s)
    loaded : int              compiled kernel versions the task had to load or compile
                              (0: its time is the simulation's alone)
    """

    run: int
    method: int
    tables: dict[str, dict[str, np.ndarray]]
    wall: float
    cpu: float
    planning: float
    loaded: int = 0


def episode_tables(episode: Episode, run: int, method: str) -> dict[str, dict[str, np.ndarray]]:
    """The tidy rows of one episode (see :data:`TABLE_DOC`), as column arrays.

    Parameters
    ----------
    episode : Episode
    run : int
    method : str

    Returns
    -------
    dict
        ``{"steps": {...}, "decisions": {...}, "sensors": {...}, "tracks": {...},
        "gospa": {...}}``; row order is step-major (then target, sensor or track) and
        decision order.
    """
    sm = episode_set_metrics(episode)               # with the run's GOSPA cut-off
    episode = with_assigned_tracks(episode)
    S1, M = episode.error.shape
    N = episode.looked.shape[1]
    D = episode.decision_steps.shape[0]
    # Slot s moves as template s mod T: with births there are more slots than templates.
    kinds = np.asarray(slot_kinds(tuple(episode.target_kinds), M), dtype=object)
    measured = np.asarray(episode.measured)                            # (S+1, M, N)
    steps = {
        "run": np.full(S1 * M, run, dtype=np.int32),
        "method": np.full(S1 * M, method, dtype=object),
        "step": np.repeat(np.arange(S1, dtype=np.int32), M),
        "target": np.tile(np.arange(M, dtype=np.int16), S1),
        "kind": np.tile(kinds, S1),
        "error": episode.error.reshape(-1),
        "nees": episode.nees.reshape(-1),
        "measured": measured.any(axis=2).reshape(-1),
        "measurements": measured.sum(axis=2).astype(np.int8).reshape(-1),
        "negative_update": np.asarray(episode.negative_update).reshape(-1),
        "inflated": np.asarray(episode.inflated).reshape(-1),
        "gated_out": np.asarray(episode.gated_out).sum(axis=2).astype(np.int8).reshape(-1),
        "restarted": np.asarray(episode.restarted).reshape(-1),
        "map_corrected": np.asarray(episode.map_corrected).reshape(-1),
        "x": episode.truth[..., 0].reshape(-1),
        "y": episode.truth[..., 1].reshape(-1),
        "x_est": episode.estimate[..., 0].reshape(-1),
        "y_est": episode.estimate[..., 1].reshape(-1),
    }
    live = np.asarray(episode.alive).reshape(-1)          # live targets only (births, deaths)
    if not live.all():
        steps = {k: v[live] for k, v in steps.items()}
    converged = np.asarray(episode.converged, dtype=float)
    sweeps = np.asarray(episode.sweeps, dtype=float)
    decisions = {
        "run": np.full(D, run, dtype=np.int32),
        "method": np.full(D, method, dtype=object),
        "decision": np.arange(D, dtype=np.int32),
        "step": np.asarray(episode.decision_steps, dtype=np.int32),
        "planning_seconds": np.asarray(episode.planning_seconds, dtype=float),
        "phi": np.asarray(episode.potential, dtype=float),
        # NaN marks "no notion of convergence"; it becomes a null in Parquet.
        "converged": converged,
        "sweeps": sweeps,
        "mu": _per_decision(episode.search_found, D),
        "search_term": _per_decision(episode.search_term, D),
    }
    sensors = {
        "run": np.full(S1 * N, run, dtype=np.int32),
        "method": np.full(S1 * N, method, dtype=object),
        "step": np.repeat(np.arange(S1, dtype=np.int32), N),
        "sensor": np.tile(np.arange(N, dtype=np.int16), S1),
        "x": episode.sensor_positions[..., 0].reshape(-1),
        "y": episode.sensor_positions[..., 1].reshape(-1),
        "heading": episode.sensor_headings.reshape(-1),
        "target": np.asarray(episode.looked, dtype=np.int16).reshape(-1),
        "label": looked_labels(episode).reshape(-1),
        "missed": np.asarray(episode.missed).reshape(-1),
        "measured": measured.any(axis=1).reshape(-1),
    }
    R, G = len(episode.track_step), S1 - 1
    tracks = {
        "run": np.full(R, run, dtype=np.int32),
        "method": np.full(R, method, dtype=object),
        "step": np.asarray(episode.track_step, dtype=np.int32),
        "label": np.asarray(episode.track_label, dtype=np.int64),
        "x": episode.track_mean[:, 0], "y": episode.track_mean[:, 1],
        "existence": np.asarray(episode.track_existence, dtype=float),
    }
    gospa = {
        "run": np.full(G, run, dtype=np.int32),
        "method": np.full(G, method, dtype=object),
        "step": np.arange(1, S1, dtype=np.int32),
        "gospa": sm.gospa.distance, "localisation": sm.gospa.localisation,
        "missed": sm.gospa.missed, "false": sm.gospa.false,
        "targets": np.asarray(sm.n_targets, dtype=np.int32),
        "tracks": np.asarray(sm.n_tracks, dtype=np.int32),
        "false_tracks": np.asarray(sm.false_tracks, dtype=np.int32),
    }
    if episode.undetected is not None:
        grid = np.asarray(episode.undetected, dtype=np.float32).reshape(S1, -1)
        gospa["undetected"] = grid[1:].sum(axis=1, dtype=np.float64)
        snaps = np.full(G, None, dtype=object)
        for t in intensity_steps(G):
            snaps[t - 1] = grid[t]
        gospa["intensity"] = snaps
    return {"steps": steps, "decisions": decisions, "sensors": sensors, "tracks": tracks,
            "gospa": gospa}


def arrow_table(columns: Mapping[str, np.ndarray]) -> Any:
    """A pyarrow table of :func:`episode_tables` columns (NaN ``converged``/``sweeps`` as
    nulls, objects as strings)."""
    import pyarrow as pa

    arrays = {}
    for name, col in columns.items():
        if name == "intensity":
            arrays[name] = pa.array([None if v is None else np.asarray(v, np.float32)
                                     for v in col], type=pa.list_(pa.float32()))
        elif col.dtype == object:
            arrays[name] = pa.array(col.tolist(), type=pa.string())
        elif name in ("converged", "sweeps"):
            mask = np.isnan(col)
            values = col if name == "converged" else np.nan_to_num(col)
            typ = pa.bool_() if name == "converged" else pa.int32()
            arrays[name] = pa.array(values.astype(bool if name == "converged" else np.int32),
                                    mask=mask, type=typ)
        else:
            arrays[name] = pa.array(col)
    return pa.table(arrays)


def _per_decision(values: Any, n: int) -> FloatArray:
    """A per-decision record of search runs; NaN (null in Parquet) without search."""
    if values is None:
        return np.full(n, np.nan)
    return np.asarray(values, dtype=float).reshape(n)
