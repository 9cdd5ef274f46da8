"""Per-run drill-down of a study (``sensorplan replay``): re-simulate one (run, method).

A study stores tables, not episodes. Every run is a pure function of the study's resolved
configuration and the run's seed, so :func:`replay_run` rebuilds the study from
``config.resolved.json``, simulates run ``r`` of the method with seed
:meth:`Study.run_seed(r) <sensorplan.study.Study.run_seed>` and compares the result with what
the study stored for that run (errors, estimates, NEES, sensor poses and looks, reported
tracks): with the same code they agree to the last bit.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from .model import READABLE_FORMATS, Method, Study
from ..simulation.run import Episode, run_episode

#: Stored columns compared with the replay: table -> {column: Episode array (S+1, K)}.
_STEPS = {"error": "error", "nees": "nees", "x": "truth_x", "y": "truth_y",
          "x_est": "est_x", "y_est": "est_y"}
_SENSORS = {"x": "pos_x", "y": "pos_y", "heading": "sensor_headings", "target": "looked",
            "label": "looked_label", "missed": "missed"}
_TRACKS = {"x": "track_x", "y": "track_y", "existence": "track_r"}


@dataclass(frozen=True)
class Replay:
    """One re-simulated (run, method) of a study and how it compares with the stored run.

    Attributes
    ----------
    study : Study
    run : int
    method : Method
    episode : Episode
    stored : bool
        Whether the study holds this (run, method) (finished), so a comparison was made.
    differences : dict of str -> float
        Largest absolute difference per compared column (``steps.error`` in m, ...);
        empty when nothing is stored.
    damaged : str or None
        What is wrong with the stored (run, method) when it is damaged (then not compared).
    """

    study: Study
    run: int
    method: Method
    episode: Episode
    stored: bool
    differences: dict[str, float] = field(default_factory=dict)
    damaged: str | None = None

    @property
    def reproduced(self) -> bool | None:
        """True if every compared column is identical, None if nothing was stored."""
        if not self.stored:
            return None
        return all(v == 0.0 for v in self.differences.values())


def load_study_config(study_dir: str | Path) -> Study:
    """The study of a study directory, from its ``config.resolved.json``.

    Raises
    ------
    ConfigError
        Naming ``DIR``: not a study directory, unreadable, or another layout version.
    """
    config = Path(study_dir) / "config.resolved.json"
    if not config.exists():
        raise ConfigError("DIR", f"{study_dir} is not a study directory (no "
                          "config.resolved.json)")
    try:
        data = json.loads(config.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError("DIR", f"{config} cannot be read ({exc})") from None
    if not isinstance(data, dict) or data.get("format") not in READABLE_FORMATS:
        got = data.get("format") if isinstance(data, dict) else None
        raise ConfigError("DIR", f"{study_dir} was written by another sensorplan version "
                          f"(format {got!r}, this one reads "
                          f"{' and '.join(repr(f) for f in READABLE_FORMATS)})")
    try:
        return Study.from_resolved(data)
    except (ValueError, KeyError, TypeError) as exc:
        raise ConfigError("DIR", f"{config} cannot be read ({exc})") from None


def find_method(study: Study, name: str) -> int:
    """Index of the method called ``name``; a ConfigError naming ``--method`` otherwise."""
    names = study.method_names
    if name in names:
        return names.index(name)
    import difflib

    close = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise ConfigError("--method", f"the study has no method {name!r}{hint} (methods: "
                      + ", ".join(repr(n) for n in names) + ")")


def check_request(study_dir: str | Path, run: int, method: str) -> tuple[Study, int]:
    """The study of ``study_dir`` and the index of ``method``, after checking that run
    ``run`` and ``method`` exist in it (a ConfigError naming ``DIR``, ``--run`` or
    ``--method`` otherwise)."""
    study = load_study_config(study_dir)
    if isinstance(run, bool) or not isinstance(run, (int, np.integer)) \
            or not 0 <= run < study.runs:
        raise ConfigError("--run", f"must be a run index in 0..{study.runs - 1} (the study "
                          f"has {study.runs} runs), got {run!r}")
    return study, find_method(study, method)


def replay_run(study_dir: str | Path, run: int, method: str) -> Replay:
    """Re-simulate run ``run`` of method ``method`` of a study directory.

    Parameters
    ----------
    study_dir : path
        Written by :func:`sensorplan.study.run_study` (finished or not).
    run : int
        Run index, ``0 <= run < runs``.
    method : str
        A method name of the study.

    Returns
    -------
    Replay
        The episode and, if the study holds that (run, method), the largest difference of
        every stored column (all zero when the run is reproduced exactly).

    Raises
    ------
    ConfigError
        ``DIR``, ``--run`` or ``--method`` is not valid for this study.
    """
    study, m = check_request(study_dir, run, method)
    chosen = study.methods[m]
    episode = run_episode(study.scenario, chosen.settings, study.run_seed(int(run)))
    stored = _stored_tables(Path(study_dir), study, int(run), m)
    if stored is None or isinstance(stored, str):
        return Replay(study, int(run), chosen, episode, False, damaged=stored)
    return Replay(study, int(run), chosen, episode, True, _compare(episode, *stored))


def _stored_tables(out: Path, study: Study, run: int, m: int
                   ) -> tuple[Any, Any, Any] | str | None:
    """The stored ``steps``, ``sensors`` and ``tracks`` rows of (run, method m); None if
    that pair has not finished; what is wrong with it if it is damaged (a warning on stderr
    says so too: the replay is still drawn, without the comparison)."""
    import sys

    import pyarrow.parquet as pq

    from .storage import part_path, part_problem

    name = study.methods[m].name
    problem = part_problem(out, run, m) if part_path(out, run, m, "steps").exists() else None
    frames = []
    for table in ("steps", "sensors", "tracks"):
        part = part_path(out, run, m, table)
        whole = out / f"{table}.parquet"
        try:
            if problem is not None:
                break
            if part.exists():
                frames.append(pq.read_table(part).to_pandas())
            elif whole.exists():
                frames.append(pq.read_table(whole, filters=[("run", "=", run),
                                                            ("method", "=", name)]).to_pandas())
            else:
                return None
        except Exception as exc:  # noqa: BLE001 - any failure to read is damage
            problem = f"{(part if part.exists() else whole).name} cannot be read " \
                      f"({type(exc).__name__})"
            break
        if not len(frames[-1]):
            return None
    if problem is not None:
        sys.stdout.flush()
        sys.stderr.write(f"warning: {part.parent.name}/m{m:02d} of {out} is damaged "
                         f"({problem}); nothing to compare the replay with (run the study "
                         "command again to recompute it)\n")
        return problem
    return frames[0], frames[1], frames[2]


def _compare(episode: Episode, steps: Any, sensors: Any, tracks: Any) -> dict[str, float]:
    """Largest absolute difference of each stored column against the episode (inf when
    the shapes differ).

    The ``steps`` table holds the live targets only, with the errors of the tracks GOSPA
    assigns to them (:func:`~sensorplan.study.set_metrics.with_assigned_tracks`); the
    ``tracks`` table every reported track, compared in (step, label) order.
    """
    from .lifespan import looked_labels
    from .set_metrics import with_assigned_tracks

    live = np.asarray(episode.alive).reshape(-1)
    scored = with_assigned_tracks(episode)          # with the run's GOSPA cut-off
    per_target = {"error": scored.error, "nees": scored.nees,
                  "truth_x": episode.truth[..., 0], "truth_y": episode.truth[..., 1],
                  "est_x": scored.estimate[..., 0], "est_y": scored.estimate[..., 1]}
    ep = {k: np.asarray(v, dtype=float).reshape(-1)[live] for k, v in per_target.items()}
    ep.update({"pos_x": episode.sensor_positions[..., 0],
               "pos_y": episode.sensor_positions[..., 1],
               "sensor_headings": episode.sensor_headings, "looked": episode.looked,
               "looked_label": looked_labels(episode), "missed": episode.missed})
    order = np.lexsort((episode.track_label, episode.track_step))
    ep.update({"track_x": episode.track_mean[order, 0], "track_y": episode.track_mean[order, 1],
               "track_r": episode.track_existence[order]})
    out: dict[str, float] = {}
    for table, frame, columns, key in (("steps", steps, _STEPS, "target"),
                                       ("sensors", sensors, _SENSORS, "sensor"),
                                       ("tracks", tracks, _TRACKS, "label")):
        frame = frame.sort_values(["step", key])
        for column, name in columns.items():
            if column not in frame:             # a study of an older layout
                continue
            mine = np.asarray(ep[name], dtype=float)
            theirs = frame[column].to_numpy(dtype=float)
            if theirs.size != mine.size:
                out[f"{table}.{column}"] = math.inf
                continue
            with np.errstate(invalid="ignore"):
                d = np.abs(mine.reshape(-1) - theirs)
            # NaN in both places is equal; NaN in one is a difference.
            both_nan = np.isnan(mine.reshape(-1)) & np.isnan(theirs)
            d = np.where(both_nan, 0.0, np.where(np.isnan(d), np.inf, d))
            out[f"{table}.{column}"] = float(d.max()) if d.size else 0.0
    return out


def replay_dir_name(run: int, method: str) -> str:
    """Default output folder of a replay: ``run-00007-pg`` for a method whose name is safe
    in a file name (letters, digits, ``-``, ``.``, ``_``), else the name with every other
    character written ``_`` and the first 6 hex digits of the name's SHA-256 appended
    (``run-00007-OLF_pg_K_3-<6 hex>``), so that two methods never share a folder (``a b``
    and ``a_b``) and a method always gets the same one."""
    safe = "".join(c if c.isalnum() or c in "-._" else "_" for c in method)
    if safe != method or not safe:
        digest = hashlib.sha256(method.encode("utf-8", "surrogatepass")).hexdigest()[:6]
        safe = f"{safe.strip('_') or 'method'}-{digest}"
    return f"run-{run:05d}-{safe}"
