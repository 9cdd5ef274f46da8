"""Running a grid study (:func:`run_grid`), its directory, and its statistics per cell.

A grid directory holds ``grid.json`` (the resolved grid) and one ordinary study directory
per cell, ``DIR/<slug>/``, each run by :func:`~sensorplan.study.execution.run_study`, one
cell after another: resumable like a study, with one progress report across cells.
:func:`grid_statistics` reads it back into one row per (comparison, cell) with the study
metrics of :mod:`.metrics`.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config.files import ensure_out_dir
from ..errors import ConfigError
from .execution import StudyInterrupted, StudyRun, run_study
from .grid import Grid
from .lifespan import study_has_sets
from .metrics import (consistency, gospa_run_metrics, kinds_with_all, paired_differences,
                      planning_summary, run_metrics, set_methods, summary)
from .storage import (RESULT_KEYS, differences, done_tasks, git_describe, load_study_dir,
                      locked, now, versions)

#: Layout version of a grid directory.
GRID_FORMAT = "sensorplan-grid/1"
GRID_JSON = "grid.json"


def _plain(value: Any) -> Any:
    """JSON-ready: non-finite floats as the strings ``inf``, ``-inf``, ``nan``."""
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def grid_resolved(grid: Grid) -> dict[str, Any]:
    """The content of ``grid.json``: the file as parsed, the axes, every cell (slug, value
    positions and values, description) and the comparisons."""
    axes = [{"name": a.name, "feature": a.feature, "key": a.key, "values": _plain(a.values),
             "labels": list(a.labels), "base_index": a.base_index} for a in grid.axes]
    cells = [{"slug": c.slug, "index": list(c.index),
              "values": {a.name: a.labels[k] for a, k in zip(grid.axes, c.index)},
              "description": c.study.description, "notes": list(c.notes)}
             for c in grid.cells]
    s = grid.study
    return {"format": GRID_FORMAT, "description": grid.description, "design": grid.design,
            "runs": s.runs, "steps": s.steps, "seed": s.seed, "methods": s.method_names,
            "axes": axes, "cells": cells,
            "comparisons": [{"method": c.method, "reference": c.reference, "label": c.label}
                            for c in grid.comparisons],
            "comparisons_from": "file" if grid.comparisons_given else "references",
            "file": _plain(grid.file),
            "code": {"sensorplan": versions().get("sensorplan"), "git": git_describe()}}


def _identity(resolved: dict[str, Any]) -> dict[str, Any]:
    """What decides a grid's results: the file but its description and comparisons (only
    the report uses them), and the cells it expands to (their names are directories)."""
    file = {k: v for k, v in resolved.get("file", {}).items()
            if k not in ("description", "comparisons")}
    return {"format": resolved.get("format"), "file": file,
            "cells": [c.get("slug") for c in resolved.get("cells", [])]}


def read_grid_json(out: str | Path, field: str = "DIR") -> dict[str, Any]:
    """``grid.json`` of a grid directory; ConfigError naming ``field`` if unreadable."""
    path = Path(out) / GRID_JSON
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(field, f"{path} cannot be read ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != GRID_FORMAT:
        got = data.get("format") if isinstance(data, dict) else None
        raise ConfigError(field, f"{path.parent} was written by another sensorplan version "
                          f"(format {got!r}, this one uses {GRID_FORMAT!r})")
    return data


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)


def prepare_grid(out: Path, grid: Grid) -> None:
    """Write ``grid.json``, or check that ``out`` holds this grid (and that no cell
    directory holds another study) before anything runs; ConfigError naming ``--out``."""
    new = grid_resolved(grid)
    path = out / GRID_JSON
    if path.exists():
        old = read_grid_json(out, "--out")
        diffs = differences(_identity(old), _identity(new))
        if diffs:
            shown = "; ".join(diffs[:3]) + ("; ..." if len(diffs) > 3 else "")
            raise ConfigError("--out", f"{out} holds results of a different grid (changed: "
                              f"{shown}); use another --out or delete it")
        for cell in grid.cells:
            config = out / cell.slug / "config.resolved.json"
            if not config.exists():
                continue
            try:
                stored = json.loads(config.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise ConfigError("--out", f"{config} cannot be read ({exc})") from None
            resolved = cell.study.resolved()
            diffs = differences({k: stored.get(k) for k in RESULT_KEYS},
                                {k: resolved.get(k) for k in RESULT_KEYS})
            if diffs:
                shown = "; ".join(diffs[:3]) + ("; ..." if len(diffs) > 3 else "")
                raise ConfigError("--out", f"{out / cell.slug} holds results of a different "
                                  f"study (changed: {shown}); use another --out or delete it")
        new["sessions"] = old.get("sessions", [])
    elif any(p.name != ".lock" for p in out.iterdir()):
        raise ConfigError("--out", f"{out} is not empty and is not a grid directory (no "
                          f"{GRID_JSON})")
    new.setdefault("sessions", []).append({"started": now(), **new["code"]})
    _write_json(path, new)


class GridInterrupted(StudyInterrupted):
    """Ctrl-C during :func:`run_grid`; every finished (run, method) pair is on disk."""

    def __init__(self, done: int, total: int, cell: str) -> None:
        super().__init__(done, total)
        self.cell = cell


@dataclass
class GridRun:
    """What :func:`run_grid` did: pairs in the grid, pairs run by this call, wall time (s)
    and each cell's :class:`~sensorplan.study.execution.StudyRun`."""

    out: Path
    total: int
    ran: int
    wall: float
    cells: dict[str, StudyRun] = field(default_factory=dict)


def run_grid(grid: Grid, out: str | Path, *, workers: int | None = None,
             scheduler: str | None = None, processes: bool = True,
             progress: Callable[[int, int, int], None] | None = None) -> GridRun:
    """Run what is missing of every cell of ``grid``, one cell after another, into ``out``.

    The execution options are those of :func:`~sensorplan.study.execution.run_study`
    (which runs each cell into ``out/<slug>``); ``progress(done, total, already)`` counts
    (run, method) pairs across all cells.

    Raises
    ------
    ConfigError
        ``out`` holds another grid, a cell directory another study, or ``out`` is not a
        grid directory; bad ``workers``/``scheduler``.
    GridInterrupted
        On Ctrl-C; what finished is kept and a rerun resumes.
    """
    out = Path(out)
    ensure_out_dir(out)
    start = time.perf_counter()
    with locked(out):
        prepare_grid(out, grid)
        before = {c.slug: len(done_tasks(out / c.slug, c.study))
                  if (out / c.slug / "config.resolved.json").exists() else 0
                  for c in grid.cells}
        total = sum(len(c.study.tasks()) for c in grid.cells)
        already = sum(before.values())
        ran, runs, started = 0, {}, False
        for cell in grid.cells:
            def report(done: int, todo: int, _: int, offset: int = ran) -> None:
                nonlocal started
                # The first cell with work to do reports (0, ...) once its options and
                # directory are checked: then the overall count starts.
                if progress is not None and (done or not started):
                    started = True
                    progress(min(offset + done, total - already), total - already, already)
            try:
                res = run_study(cell.study, out / cell.slug, workers=workers,
                                scheduler=scheduler, processes=processes, progress=report)
            except StudyInterrupted as exc:
                done = already + ran + exc.done - before[cell.slug]
                raise GridInterrupted(done, total, cell.slug) from None
            except ConfigError as exc:
                if exc.field in ("--workers", "--scheduler"):
                    raise
                raise ConfigError(exc.field, f"cell {cell.slug}: {exc.message}") from None
            runs[cell.slug] = res
            ran += res.ran
    return GridRun(out, total, ran, time.perf_counter() - start, runs)


# ------------------------------------------------------------------------ statistics


def _kind(study: Any) -> str:
    """The kind that covers every target: ``all``, or the one kind of the scenario."""
    kinds = kinds_with_all(study)
    return "all" if "all" in kinds else kinds[0]


def _verdict(n: int, lo: float, hi: float) -> str:
    if n == 0:
        return "not run"
    if hi < 0:
        return "better"
    if lo > 0:
        return "worse"
    return "inconclusive"


def judged_by(studies: Any) -> str:
    """What a grid's (or a study's) comparisons are judged by: ``gospa`` when any of the
    studies has a method with a multi-target tracker or a truth whose targets are born,
    die or are scripted (:func:`~.lifespan.study_has_sets`), else ``rmse``.

    A multi-target tracker's errors exist only where a track is assigned to a target, so
    its RMSE and ANEES leave out exactly the target-steps it missed; GOSPA charges them.
    """
    return "gospa" if any(study_has_sets(s) for s in studies) else "rmse"


def cell_statistics(tables: Any, pairs: list[tuple[str, str]],
                    metric: str = "rmse") -> list[dict[str, Any]]:
    """Per ``(method, reference)``, over every target: the paired difference of ``metric``
    (``rmse``, or ``gospa``: the run's mean GOSPA; :func:`~.metrics.paired_differences`),
    each side's ANEES and diverged runs (:func:`~.metrics.consistency`) and mean planning
    time per decision (ms, :func:`~.metrics.planning_summary`) in one study's tables. With
    ``gospa``, also each side's mean GOSPA with its 95 % t-interval (``gospa_method``,
    ``gospa_method_lo``, ... ``gospa_reference_hi``)."""
    kind = _kind(tables.study)
    per_run = gospa_run_metrics(tables) if metric == "gospa" else run_metrics(tables)
    diffs = paired_differences(per_run, tables.study, column=metric, pairs=pairs)
    honest = consistency(tables)
    honest = honest[honest["kind"] == kind].set_index("method")
    plan = planning_summary(tables).set_index("method")
    level = summary(per_run, "gospa").set_index("method") if metric == "gospa" else None
    rows = []
    for method, ref in pairs:
        d = diffs[(diffs["method"] == method) & (diffs["reference"] == ref)
                  & (diffs["kind"] == kind)].iloc[0]
        row: dict[str, Any] = {k: float(d[k]) for k in (
            "mean", "mean_lo", "mean_hi", "median", "median_lo", "median_hi", "better_share")}
        row["n"] = int(d["n"])
        for side, name in (("method", method), ("reference", ref)):
            row[f"anees_{side}"] = float(honest.loc[name, "anees"])
            row[f"diverged_{side}"] = int(honest.loc[name, "diverged"])
            row[f"ms_{side}"] = float(plan.loc[name, "mean_ms"])
            if level is not None:
                g = level.loc[name]
                row[f"gospa_{side}"] = float(g["mean"])
                row[f"gospa_{side}_lo"] = float(g["mean_lo"])
                row[f"gospa_{side}_hi"] = float(g["mean_hi"])
        row["verdict"] = _verdict(row["n"], row["mean_lo"], row["mean_hi"])
        rows.append(row)
    return rows


def _cell_tables(out: Path, info: dict[str, Any]) -> dict[str, Any]:
    """Each cell's tables (None where the cell has not run)."""
    found: dict[str, Any] = {}
    for cell in info["cells"]:
        try:
            found[cell["slug"]] = load_study_dir(out / cell["slug"])
        except ConfigError:
            found[cell["slug"]] = None
    return found


def _judge(info: dict[str, Any], tables: dict[str, Any]) -> str:
    """:func:`judged_by` over the cells that have run, written into ``info`` with the
    methods that have a multi-target tracker in any cell (``set_methods``)."""
    studies = [t.study for t in tables.values() if t is not None]
    info["judged_by"] = judged_by(studies)
    info["set_methods"] = list(dict.fromkeys(n for s in studies for n in set_methods(s)))
    # A study-wide setting: every method of a cell has the same cut-off.
    info["gospa_c"] = float(studies[0].methods[0].settings.gospa_c) if studies else math.nan
    return str(info["judged_by"])


def grid_statistics(out: str | Path) -> tuple[dict[str, Any], Any]:
    """``grid.json`` and one row per (comparison, cell) of a grid directory.

    Columns: comparison (index into ``grid.json``'s comparisons), cell (slug), status
    (``complete``, ``partial`` or ``not run``), runs_done, and for a cell that has run the
    columns of :func:`cell_statistics` (NaN otherwise; verdict ``not run``). The
    difference is over every target (kind ``all``) of the metric :func:`judged_by` picks:
    RMSE, or for a grid of changing sets the run's mean GOSPA (then with each side's mean
    GOSPA too). ``diverged`` counts runs whose largest position error exceeds
    ``metrics.DIVERGED_THRESHOLD`` (m). The returned ``grid.json`` content gains
    ``judged_by`` (``rmse`` or ``gospa``), ``set_methods`` (the methods with a
    multi-target tracker) and ``gospa_c`` (GOSPA's cut-off, m).
    """
    import pandas as pd

    out = Path(out)
    info = read_grid_json(out)
    pairs = [(c["method"], c["reference"]) for c in info["comparisons"]]
    found = _cell_tables(out, info)
    metric = _judge(info, found)
    rows = []
    for cell in info["cells"]:
        tables = found[cell["slug"]]
        stats = cell_statistics(tables, pairs, metric) if tables is not None else \
            [{"verdict": "not run", "n": 0} for _ in pairs]
        status = "not run" if tables is None else ("complete" if tables.complete
                                                   else "partial")
        done = 0 if tables is None else len(tables.runs_done)
        for k, s in enumerate(stats):
            rows.append({"comparison": k, "cell": cell["slug"], "status": status,
                         "runs_done": done, **s})
    columns = ["comparison", "cell", "status", "runs_done", "n", "mean", "mean_lo", "mean_hi",
               "median", "median_lo", "median_hi", "better_share", "anees_method",
               "anees_reference", "diverged_method", "diverged_reference", "ms_method",
               "ms_reference", "verdict"]
    if metric == "gospa":
        columns[-1:-1] = [f"gospa_{side}{end}" for side in ("method", "reference")
                          for end in ("", "_lo", "_hi")]
    return info, pd.DataFrame(rows).reindex(columns=columns)



def method_statistics(out: str | Path) -> Any:
    """Every method in every cell that has run, over every target: one row each.

    Columns: cell, method, n (runs), rmse, rmse_lo, rmse_hi (mean position RMSE, m, with
    its 95 % t-interval, :func:`~.metrics.summary`), lost, lost_lo, lost_hi (share of
    target-steps with error above 50 m, same statistics), anees, diverged
    (:func:`~.metrics.consistency`). For a multi-target tracker RMSE and ANEES are over the
    target-steps with an assigned track and lost is the share without one
    (:func:`~.metrics.run_metrics`). A grid judged by GOSPA (:func:`judged_by`) adds
    gospa, gospa_lo, gospa_hi (the run's mean GOSPA, m, same statistics) and the mean
    localisation, missed and false parts (m^2).
    """
    import pandas as pd

    out = Path(out)
    info = read_grid_json(out)
    found = _cell_tables(out, info)
    by_gospa = _judge(info, found) == "gospa"
    rows = []
    for cell in info["cells"]:
        tables = found[cell["slug"]]
        if tables is None:
            continue
        kind = _kind(tables.study)
        metrics = run_metrics(tables)
        rmse = summary(metrics, "rmse")
        lost = summary(metrics, "lost_share")
        honest = consistency(tables)
        sets = gospa_run_metrics(tables) if by_gospa else None
        for method in tables.study.method_names:
            def pick(df: Any, m: str = method, k: str = kind) -> Any:
                return df[(df["method"] == m) & (df["kind"] == k)].iloc[0]
            r, lo, h = pick(rmse), pick(lost), pick(honest)
            row = {"cell": cell["slug"], "method": method, "n": int(r["n"]),
                   "rmse": r["mean"], "rmse_lo": r["mean_lo"], "rmse_hi": r["mean_hi"],
                   "lost": lo["mean"], "lost_lo": lo["mean_lo"], "lost_hi": lo["mean_hi"],
                   "anees": float(h["anees"]), "diverged": int(h["diverged"])}
            if sets is not None:
                mine = sets[sets["method"] == method]
                g = pick(summary(mine, "gospa"))
                row.update(gospa=g["mean"], gospa_lo=g["mean_lo"], gospa_hi=g["mean_hi"],
                           **{part: float(mine[part].mean())
                              for part in ("localisation", "missed", "false")})
            rows.append(row)
    columns = ["cell", "method", "n", "rmse", "rmse_lo", "rmse_hi", "lost", "lost_lo",
               "lost_hi", "anees", "diverged"]
    if by_gospa:
        columns += ["gospa", "gospa_lo", "gospa_hi", "localisation", "missed", "false"]
    return pd.DataFrame(rows, columns=columns)
