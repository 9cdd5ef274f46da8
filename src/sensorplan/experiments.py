"""Monte Carlo studies (SPEC 5, 6): paired runs, resumable execution, tidy tables, statistics.

A :class:`Study` runs every :class:`Method` on the same ``runs`` paired runs. Run ``r`` gets
the seed ``SeedSequence(study.seed, spawn_key=(r,))`` (the r-th child of
``SeedSequence(study.seed).spawn(runs)``) and every method receives that same sequence, so
``simulation.run_episode`` draws the same truths, initial estimates, sensor starts and
per-sensor noise for all of them: method differences are paired (common random numbers).

:func:`run_study` executes the missing (run, method) pairs in a local process pool, in this
process, or on Dask, and writes each finished pair at once as three small Parquet files
(temp name, then rename), so a study killed at any moment resumes with the same command and
never recomputes what is done. When every pair is done it writes the tidy tables
``steps.parquet``, ``decisions.parquet`` and ``sensors.parquet`` (see :data:`TABLE_DOC`).
The directory layout and the resume rules are in docs/studies.md.

The statistics (RMSE per run, across-run means with t-intervals, medians with
order-statistic intervals, paired differences) are functions of those tables; the report
(:mod:`sensorplan.report`) only draws and formats them. This module never imports
matplotlib.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import math
import multiprocessing
import os
import platform
import signal
import subprocess
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from ._types import FloatArray
from .errors import ConfigError
from .io import ensure_out_dir
from .scenario import Scenario
from .simulation import Episode, RunSettings, run_episode

#: Position error above which a target-step counts as lost (m), SPEC 6.
LOST_THRESHOLD = 50.0
#: Confidence level of every interval.
LEVEL = 0.95
#: Tidy tables, in the order a part's files are written (the last one marks it done).
TABLES = ("decisions", "sensors", "steps")
#: Layout version of a study directory.
FORMAT = "sensorplan-study/1"
#: Environment variables that limit BLAS/OpenMP threads in worker processes: with one
#: process per core, threaded linear algebra on 4x4 matrices only adds contention.
THREAD_LIMITS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                 "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS")

TABLE_DOC = {
    "steps": "one row per (run, method, step, target): run, method, step (0 = initial state, "
             "1..S), target, kind, error (m, |p_true - p_est|), nees (4-D NEES), measured "
             "(any sensor measured it at that step), measurements (how many did), "
             "negative_update, inflated (missed-look update / inflation, SPEC 3), x, y "
             "(true position, m), x_est, y_est (estimated position, m)",
    "decisions": "one row per (run, method, decision): run, method, decision (0-based), step "
                 "(time index of the decision), planning_seconds (wall time of the planner "
                 "call), phi (potential of the chosen plan, nats), converged (null for "
                 "planners without the notion), sweeps (null likewise)",
    "sensors": "one row per (run, method, step, sensor): run, method, step, sensor, x, y "
               "(ground position, m), heading (rad), target (looked-at target, -1 none), "
               "missed (the look missed: target truly outside the field of view), measured",
}


# ------------------------------------------------------------------------- the study


@dataclass(frozen=True)
class Method:
    """One named way of planning and tracking: everything a run needs besides its seed."""

    name: str
    settings: RunSettings

    def to_dict(self) -> dict[str, Any]:
        s = self.settings
        return {"name": self.name, "planner": s.planner,
                "planner_params": {k: _plain(v) for k, v in s.planner_params.items()},
                "horizon": s.horizon, "steps_per_epoch": s.steps_per_epoch,
                "execution": s.execution, "visibility": s.visibility,
                "objective": s.objective, "miss_update": s.miss_update}


@dataclass(frozen=True)
class Study:
    """A Monte Carlo study: ``runs`` paired runs of ``steps`` steps for every method.

    Attributes
    ----------
    scenario : Scenario
    runs, steps : int
    seed : int                   root of the study's ``SeedSequence``
    methods : tuple of Method    unique names; every ``settings.steps == steps``
    description : str
    scenario_source : str        where the scenario came from (provenance only)
    """

    scenario: Scenario
    runs: int
    steps: int
    seed: int
    methods: tuple[Method, ...]
    description: str = ""
    scenario_source: str = "preset paper"

    def __post_init__(self) -> None:
        object.__setattr__(self, "methods", tuple(self.methods))
        for name in ("runs", "steps"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(name, f"must be an integer >= 1, got {v!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ConfigError("seed", f"must be an integer >= 0, got {self.seed!r}")
        if not self.methods:
            raise ConfigError("methods", "at least one method is required")
        names = [m.name for m in self.methods]
        for i, m in enumerate(self.methods):
            if names.index(m.name) != i:
                raise ConfigError(f"methods[{i}].name", f"duplicate method name {m.name!r}")
            if m.settings.steps != self.steps:
                raise ConfigError(f"methods[{i}].steps", "must equal the study's steps")

    @property
    def method_names(self) -> list[str]:
        return [m.name for m in self.methods]

    def run_seed(self, run: int) -> np.random.SeedSequence:
        """Run ``run``'s seed: child ``run`` of ``SeedSequence(seed).spawn(runs)``.

        It does not depend on ``runs``, so a study with more runs shares its first runs.
        """
        return np.random.SeedSequence(self.seed, spawn_key=(int(run),))

    def tasks(self) -> list[tuple[int, int]]:
        """Every (run, method index), run-major."""
        return [(r, m) for r in range(self.runs) for m in range(len(self.methods))]

    def resolved(self) -> dict[str, Any]:
        """JSON-ready study with every default filled in (``config.resolved.json``)."""
        from .config import scenario_to_dict

        return {"format": FORMAT, "description": self.description,
                "scenario_source": self.scenario_source, "runs": self.runs,
                "steps": self.steps, "seed": self.seed,
                "scenario": scenario_to_dict(self.scenario),
                "methods": [m.to_dict() for m in self.methods]}

    @classmethod
    def from_resolved(cls, data: Mapping[str, Any]) -> "Study":
        """Inverse of :meth:`resolved` (the report rebuilds the study from its directory)."""
        from .config import scenario_from_dict

        steps = int(data["steps"])
        methods = tuple(
            Method(m["name"], RunSettings(
                planner=m["planner"], planner_params=m["planner_params"],
                horizon=m["horizon"], steps_per_epoch=m["steps_per_epoch"],
                execution=m["execution"], steps=steps, visibility=m["visibility"],
                objective=m["objective"], miss_update=m["miss_update"]))
            for m in data["methods"])
        return cls(scenario=scenario_from_dict(data["scenario"]), runs=int(data["runs"]),
                   steps=steps, seed=int(data["seed"]), methods=methods,
                   description=data.get("description", ""),
                   scenario_source=data.get("scenario_source", ""))


def _plain(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


#: Keys of config.resolved.json that decide the results (a resumed study must match them).
_RESULT_KEYS = ("format", "runs", "steps", "seed", "scenario", "methods")


def _differences(old: Any, new: Any, path: str = "") -> list[str]:
    """Dotted paths at which two JSON values differ."""
    if isinstance(old, dict) and isinstance(new, dict):
        out: list[str] = []
        for k in list(old) + [k for k in new if k not in old]:
            p = f"{path}.{k}" if path else str(k)
            if k not in old or k not in new:
                out.append(p)
            else:
                out += _differences(old[k], new[k], p)
        return out
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path} (length {len(old)} -> {len(new)})"]
        return [d for i, (a, b) in enumerate(zip(old, new))
                for d in _differences(a, b, f"{path}[{i}]")]
    return [] if old == new else [f"{path} ({json.dumps(old)} -> {json.dumps(new)})"]


# ------------------------------------------------------------------- one (run, method)


@dataclass
class TaskResult:
    """What a worker sends back: one (run, method)'s tables as columns, and its timing.

    Attributes
    ----------
    run, method : int
    tables : dict of table name -> dict of column name -> (rows,) array
    wall, cpu : float         the task's wall and process CPU time (s)
    planning : float          wall time inside planner calls (s)
    """

    run: int
    method: int
    tables: dict[str, dict[str, np.ndarray]]
    wall: float
    cpu: float
    planning: float


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
        ``{"steps": {...}, "decisions": {...}, "sensors": {...}}``; row order is step-major
        (then target or sensor) and decision order.
    """
    S1, M = episode.error.shape
    N = episode.looked.shape[1]
    D = episode.decision_steps.shape[0]
    kinds = np.asarray(episode.target_kinds, dtype=object)
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
        "x": episode.truth[..., 0].reshape(-1),
        "y": episode.truth[..., 1].reshape(-1),
        "x_est": episode.estimate[..., 0].reshape(-1),
        "y_est": episode.estimate[..., 1].reshape(-1),
    }
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
        "missed": np.asarray(episode.missed).reshape(-1),
        "measured": measured.any(axis=1).reshape(-1),
    }
    return {"steps": steps, "decisions": decisions, "sensors": sensors}


def run_task(study: Study, run: int, method: int) -> TaskResult:
    """Simulate method ``method`` (index) on run ``run`` and return its tables."""
    m = study.methods[method]
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        episode = run_episode(study.scenario, m.settings, study.run_seed(run))
    except ConfigError as exc:
        # A planner refusing mid-run (brute force above max_plans) names its own setting.
        field = exc.field.removeprefix("planner.").removeprefix("planner")
        raise ConfigError(f"methods[{method}].planner_params" + (f".{field}" if field else ""),
                          f"{exc.message} (method {m.name!r}, run {run})") from None
    tables = episode_tables(episode, run, m.name)
    return TaskResult(run, method, tables, time.perf_counter() - wall,
                      time.process_time() - cpu, float(np.sum(episode.planning_seconds)))


# ------------------------------------------------------------------------- executors

_WORKER_STUDY: Study | None = None


def _pool_init(study: Study) -> None:
    global _WORKER_STUDY
    _WORKER_STUDY = study
    # The parent handles Ctrl-C (it stops the pool); workers should not print tracebacks.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _RemoteConfigError(Exception):
    """A ConfigError raised in a worker, in a form that survives pickling.

    (``ConfigError(field, message)`` itself does not unpickle: its ``args`` hold one string.)
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(field, message)


def _guarded_task(study: Study, run: int, method: int) -> TaskResult:
    try:
        return run_task(study, run, method)
    except ConfigError as exc:
        raise _RemoteConfigError(exc.field, exc.message) from None


def _pool_task(run: int, method: int) -> TaskResult:
    assert _WORKER_STUDY is not None
    return _guarded_task(_WORKER_STUDY, run, method)


def _dask_task(study: Study, run: int, method: int) -> TaskResult:
    return _guarded_task(study, run, method)


@contextlib.contextmanager
def _thread_limits() -> Iterator[None]:
    """Set the thread-limit variables (unless the user set them) for child processes."""
    saved = {k: os.environ.get(k) for k in THREAD_LIMITS}
    for k in THREAD_LIMITS:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _in_process(study: Study, tasks: Sequence[tuple[int, int]]) -> Iterator[TaskResult]:
    for r, m in tasks:
        yield run_task(study, r, m)


def _process_pool(study: Study, tasks: Sequence[tuple[int, int]],
                  workers: int) -> Iterator[TaskResult]:
    # 'spawn' (not fork): workers start from a clean interpreter, which is portable and
    # safe with the threads that numba, BLAS or Dask may have started in this process.
    ctx = multiprocessing.get_context("spawn")
    with _thread_limits():
        pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                      initializer=_pool_init, initargs=(study,))
        try:
            # A bounded window of submitted tasks: Ctrl-C then cancels little work, and
            # results stream back as they finish.
            todo = iter(tasks)
            pending: set[cf.Future[TaskResult]] = set()
            for r, m in todo:
                pending.add(pool.submit(_pool_task, r, m))
                if len(pending) >= 2 * workers:
                    break
            while pending:
                done, pending = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
                for fut in done:
                    nxt = next(todo, None)
                    if nxt is not None:
                        pending.add(pool.submit(_pool_task, *nxt))
                    yield fut.result()
        except BaseException:
            # Running tasks would finish for nothing; there is no public way to stop them
            # before Python 3.14 (ProcessPoolExecutor.terminate_workers).
            procs = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                with contextlib.suppress(Exception):
                    proc.terminate()
            raise
        else:
            pool.shutdown(wait=True)


def _dask(study: Study, tasks: Sequence[tuple[int, int]], scheduler: str, workers: int,
          processes: bool) -> Iterator[TaskResult]:
    import logging

    from distributed import Client, LocalCluster, as_completed

    cluster = None
    with _thread_limits():
        if scheduler == "local":
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                   processes=processes, dashboard_address=None,
                                   silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            try:
                client = Client(scheduler, timeout="30s")
            except (OSError, TimeoutError) as exc:
                raise ConfigError("--scheduler", f"cannot connect to {scheduler} "
                                  f"({exc})") from None
    futures = []
    try:
        # Ship the study once to every worker instead of once per task.
        study_f = client.scatter(study, broadcast=True)
        futures = [client.submit(_dask_task, study_f, r, m, pure=False) for r, m in tasks]
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        with contextlib.suppress(Exception):
            client.cancel(futures)
        client.close()
        if cluster is not None:
            cluster.close()


def default_workers() -> int:
    """Cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


# ------------------------------------------------------------------- study directory


class StudyInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`run_study`; the finished pairs are on disk."""

    def __init__(self, done: int, total: int) -> None:
        super().__init__(f"{done} of {total} (run, method) pairs done")
        self.done = done
        self.total = total


@dataclass
class StudyRun:
    """What :func:`run_study` did.

    Attributes
    ----------
    out : Path
    total : int          (run, method) pairs in the study
    ran : int            pairs computed by this call (0: the study was already complete)
    wall : float         this call's wall time (s)
    timing : dict        this session's record in meta.json
    """

    out: Path
    total: int
    ran: int
    wall: float
    timing: dict[str, Any] = field(default_factory=dict)


def part_path(out: Path, run: int, method: int, table: str) -> Path:
    """File of one (run, method)'s table: ``parts/run-00007/m03.steps.parquet``."""
    return Path(out) / "parts" / f"run-{run:05d}" / f"m{method:02d}.{table}.parquet"


def _atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Write through a temporary name in the same directory, then rename.

    ``os.replace`` is atomic on POSIX, so readers (and a resumed study) see either the whole
    file or none of it, whatever moment the process is killed at.
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_json(path: Path, data: Any) -> None:
    def write(tmp: Path) -> None:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")
    _atomic_write(path, write)


def _arrow_table(columns: Mapping[str, np.ndarray]) -> Any:
    import pyarrow as pa

    arrays = {}
    for name, col in columns.items():
        if col.dtype == object:
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


def _write_part(out: Path, result: TaskResult) -> None:
    import pyarrow.parquet as pq

    for table in TABLES:                   # "steps" last: its presence marks the part done
        path = part_path(out, result.run, result.method, table)
        path.parent.mkdir(parents=True, exist_ok=True)
        tab = _arrow_table(result.tables[table])
        _atomic_write(path, lambda tmp, tab=tab: pq.write_table(tab, tmp))


def done_tasks(out: Path, study: Study) -> set[tuple[int, int]]:
    """(run, method) pairs whose files are all on disk."""
    return {(r, m) for r, m in study.tasks()
            if part_path(out, r, m, TABLES[-1]).exists()}


def _versions() -> dict[str, str]:
    from importlib import metadata

    out = {"python": platform.python_version()}
    for pkg in ("sensorplan", "numpy", "scipy", "numba", "pyarrow", "pandas", "dask",
                "distributed", "pydantic", "rich"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[pkg] = metadata.version(pkg)
    return out


def _git_describe() -> str | None:
    here = Path(__file__).resolve().parent
    try:
        res = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"], cwd=here,
                             capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout.strip() or None if res.returncode == 0 else None


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


@contextlib.contextmanager
def _locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out/.lock`` (released by the OS even on SIGKILL)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ConfigError("--out", f"{out} is in use by another sensorplan study "
                              "process") from None
        yield
    finally:
        os.close(fd)


def _prepare(out: Path, study: Study) -> None:
    """Create ``out`` or check that it holds this study; raise ConfigError otherwise."""
    resolved = study.resolved()
    config = out / "config.resolved.json"
    if config.exists():
        try:
            old = json.loads(config.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ConfigError("--out", f"{config} cannot be read ({exc})") from None
        diffs = _differences({k: old.get(k) for k in _RESULT_KEYS},
                             {k: resolved.get(k) for k in _RESULT_KEYS})
        if diffs:
            shown = "; ".join(diffs[:3]) + ("; ..." if len(diffs) > 3 else "")
            raise ConfigError("--out", f"{out} holds results of a different study "
                              f"(changed: {shown}); use another --out or delete it")
        return
    others = [p.name for p in out.iterdir() if p.name != ".lock"]
    if others:
        raise ConfigError("--out", f"{out} is not empty and is not a study directory "
                          f"(no config.resolved.json)")
    _write_json(config, resolved)


def _read_meta(out: Path) -> dict[str, Any]:
    try:
        return json.loads((out / "meta.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _write_meta(out: Path, study: Study, session: dict[str, Any], complete: bool) -> None:
    meta = _read_meta(out)
    sessions = [s for s in meta.get("sessions", []) if s.get("id") != session["id"]]
    sessions.append(session)
    meta.update({
        "format": FORMAT, "versions": _versions(), "git": _git_describe(),
        "platform": platform.platform(), "machine": platform.machine(),
        "processor": platform.processor() or None, "cpu_count": os.cpu_count(),
        "seed": study.seed, "root_entropy": study.seed, "runs": study.runs,
        "methods": study.method_names, "complete": complete,
        "wall_seconds": round(sum(s.get("wall_seconds", 0.0) for s in sessions), 3),
        "sessions": sessions,
    })
    _write_json(out / "meta.json", meta)


def consolidate(out: Path, study: Study) -> None:
    """Write ``steps/decisions/sensors.parquet`` from the parts, in (run, method) order."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tasks = study.tasks()
    for table in TABLES:
        tab = pa.concat_tables([pq.read_table(part_path(out, r, m, table)) for r, m in tasks])
        _atomic_write(out / f"{table}.parquet", lambda tmp, tab=tab: pq.write_table(tab, tmp))


def _clean_temporaries(out: Path) -> None:
    parts = out / "parts"
    if parts.exists():
        for tmp in parts.glob("run-*/.*.tmp*"):
            with contextlib.suppress(OSError):
                tmp.unlink()
    for tmp in out.glob(".*.tmp*"):
        with contextlib.suppress(OSError):
            tmp.unlink()


ProgressFn = Callable[[int, int, int], None]


def _local_errors(results: Iterable[TaskResult]) -> Iterator[TaskResult]:
    """Re-raise a worker's configuration error (a planner refusing mid-run) as ConfigError,
    naming the method's field."""
    try:
        yield from results
    except _RemoteConfigError as exc:
        raise ConfigError(*exc.args) from None


def run_study(study: Study, out: str | Path, *, workers: int | None = None,
              scheduler: str | None = None, processes: bool = True,
              progress: ProgressFn | None = None) -> StudyRun:
    """Run what is missing of ``study`` into directory ``out`` and write its tables.

    Parameters
    ----------
    study : Study
    out : path
        Study directory: created if missing; if it exists it must hold the same study
        (same ``config.resolved.json`` result keys), else ConfigError.
    workers : int, optional
        Worker processes (default: the cores available). 1 without ``scheduler`` runs in
        this process; more uses a ``ProcessPoolExecutor`` with the 'spawn' context.
    scheduler : str, optional
        Run on Dask distributed instead: a scheduler address (``tcp://host:8786``) or
        ``"local"`` for a ``LocalCluster`` started here with ``workers`` workers.
    processes : bool
        For ``scheduler="local"``: worker processes (default) or threads in this process.
    progress : callable(done, total, already), optional
        Called before the first task and after each one: pairs done by this call, pairs
        this call has to do, pairs that were already on disk.

    Returns
    -------
    StudyRun

    Raises
    ------
    ConfigError
        ``out`` holds another study, is not a study directory, or is locked by another
        process; a bad ``workers`` or ``scheduler``.
    StudyInterrupted
        On Ctrl-C; everything finished before is kept and a rerun resumes.
    """
    out = Path(out)
    if workers is None:
        workers = default_workers()
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ConfigError("--workers", f"must be an integer >= 1, got {workers!r}")
    if scheduler is not None and scheduler != "local" and "://" not in scheduler:
        raise ConfigError("--scheduler", f"must be 'local' or an address such as "
                          f"tcp://host:8786, got {scheduler!r}")
    ensure_out_dir(out)

    import pyarrow.parquet  # noqa: F401  (imported now, not inside the first write's timing)

    start_wall, start_cpu = time.perf_counter(), time.process_time()
    with _locked(out):
        _prepare(out, study)
        _clean_temporaries(out)
        done = done_tasks(out, study)
        todo = [t for t in study.tasks() if t not in done]
        if scheduler is not None:
            executor = f"dask {scheduler}" + (f" ({workers} workers)" if scheduler == "local"
                                              else "")
        elif workers == 1 or len(todo) <= 1:
            executor = "in process"
        else:
            executor = f"process pool ({workers} workers)"
        session: dict[str, Any] = {
            "id": f"{_now()}-{os.getpid()}", "started": _now(), "finished": None,
            "executor": executor if todo else "none (complete)", "tasks_run": 0,
            "tasks_before": len(done), "interrupted": False,
            # Per session: a resumed study may have been continued with other code.
            "sensorplan": _versions().get("sensorplan"), "git": _git_describe()}
        timing = {"compute_wall_seconds": 0.0, "compute_cpu_seconds": 0.0,
                  "planning_seconds": 0.0, "write_seconds": 0.0, "consolidate_seconds": 0.0}
        complete = not todo and all((out / f"{t}.parquet").exists() for t in TABLES)
        if complete:
            return StudyRun(out, len(study.tasks()), 0, time.perf_counter() - start_wall)
        _write_meta(out, study, session, complete=False)
        if progress is not None:
            progress(0, len(todo), len(done))
        n = 0
        finished = False
        try:
            if not todo:
                results: Iterable[TaskResult] = ()
            elif scheduler is not None:
                results = _dask(study, todo, scheduler, workers, processes)
            elif executor == "in process":
                results = _in_process(study, todo)
            else:
                results = _process_pool(study, todo, workers)
            for res in _local_errors(results):
                t0 = time.perf_counter()
                _write_part(out, res)
                timing["write_seconds"] += time.perf_counter() - t0
                timing["compute_wall_seconds"] += res.wall
                timing["compute_cpu_seconds"] += res.cpu
                timing["planning_seconds"] += res.planning
                n += 1
                if progress is not None:
                    progress(n, len(todo), len(done))
            t0 = time.perf_counter()
            consolidate(out, study)
            timing["consolidate_seconds"] = time.perf_counter() - t0
            finished = True
        except KeyboardInterrupt:
            session["interrupted"] = True
            raise StudyInterrupted(len(done) + n, len(study.tasks())) from None
        finally:
            wall = time.perf_counter() - start_wall
            session.update({k: round(v, 4) for k, v in timing.items()})
            session.update({"finished": _now(), "tasks_run": n, "wall_seconds": round(wall, 3),
                            "main_cpu_seconds": round(time.process_time() - start_cpu, 3)})
            with contextlib.suppress(Exception):
                _write_meta(out, study, session, complete=finished)
    return StudyRun(out, len(study.tasks()), n, wall, session)


# ------------------------------------------------------------------------ reading back


@dataclass
class StudyTables:
    """A study directory read back: the study, its metadata and its tables (pandas).

    ``complete`` is False when some (run, method) pairs are missing; the tables then hold
    the finished ones (read from the parts) and ``runs_done`` the runs finished by every
    method.
    """

    study: Study
    meta: dict[str, Any]
    steps: Any
    decisions: Any
    sensors: Any
    complete: bool
    runs_done: list[int]


def load_study_dir(out: str | Path) -> StudyTables:
    """Read a study directory written by :func:`run_study` (complete or not).

    Raises
    ------
    ConfigError
        ``out`` is not a study directory or holds no finished run.
    """
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = Path(out)
    config = out / "config.resolved.json"
    if not config.exists():
        raise ConfigError("DIR", f"{out} is not a study directory (no config.resolved.json)")
    try:
        study = Study.from_resolved(json.loads(config.read_text(encoding="utf-8")))
    except (ValueError, KeyError, TypeError) as exc:
        raise ConfigError("DIR", f"{config} cannot be read ({exc})") from None
    meta = _read_meta(out)
    complete = all((out / f"{t}.parquet").exists() for t in TABLES)
    if complete:
        frames = {t: pq.read_table(out / f"{t}.parquet").to_pandas() for t in TABLES}
        runs_done = list(range(study.runs))
    else:
        done = done_tasks(out, study)
        runs_done = [r for r in range(study.runs)
                     if all((r, m) in done for m in range(len(study.methods)))]
        if not runs_done:
            raise ConfigError("DIR", f"{out} holds no run finished by every method yet")
        tasks = [(r, m) for r in runs_done for m in range(len(study.methods))]
        frames = {t: pa.concat_tables([pq.read_table(part_path(out, r, m, t))
                                       for r, m in tasks]).to_pandas() for t in TABLES}
    order = pd.CategoricalDtype(study.method_names, ordered=True)
    for df in frames.values():
        df["method"] = df["method"].astype(order)
    frames["steps"]["kind"] = frames["steps"]["kind"].astype(
        pd.CategoricalDtype(sorted(set(study.scenario.target_kinds)), ordered=True))
    return StudyTables(study, meta, frames["steps"], frames["decisions"], frames["sensors"],
                       complete, runs_done)


# ------------------------------------------------------------------------- statistics


def t_interval(values: Any, level: float = LEVEL, axis: int = 0
               ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean and two-sided t confidence interval of the mean along ``axis``.

    ``mean -+ t_{(1+level)/2, n-1} * s / sqrt(n)`` with the sample standard deviation
    ``s`` (ddof = 1): ``scipy.stats.t.interval(level, n - 1, loc=mean, scale=s/sqrt(n))``.
    NaNs are ignored; bounds are NaN with fewer than 2 values.

    Returns
    -------
    mean, lo, hi : arrays (``values`` with ``axis`` removed; 0-d for 1-D input)
    """
    from scipy import stats

    x = np.asarray(values, dtype=float)
    ok = ~np.isnan(x)
    n = ok.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, np.nansum(x, axis=axis) / np.maximum(n, 1), np.nan)
        dev = np.where(ok, x - np.expand_dims(mean, axis), 0.0)
        var = (dev ** 2).sum(axis=axis) / np.maximum(n - 1, 1)
        sem = np.sqrt(var / np.maximum(n, 1))
        tq = stats.t.ppf(0.5 + level / 2, np.maximum(n - 1, 1))
        half = np.where(n >= 2, tq * sem, np.nan)
    return mean, mean - half, mean + half


def median_interval(values: Any, level: float = LEVEL) -> tuple[float, float, float]:
    """Median and a distribution-free confidence interval for it (order statistics).

    With ``B ~ Binomial(n, 1/2)`` and ``l`` the largest integer with
    ``P(B <= l - 1) <= (1 - level) / 2``, the interval ``[x_(l), x_(n-l+1)]`` (1-based order
    statistics) covers the population median with probability ``1 - 2 P(B <= l - 1) >=
    level``. Bounds are NaN when ``n`` is too small for the level (n < 6 at 95 %).
    """
    from scipy import stats

    x = np.sort(np.asarray(values, dtype=float)[~np.isnan(np.asarray(values, dtype=float))])
    n = x.size
    if n == 0:
        return math.nan, math.nan, math.nan
    med = float(np.median(x))
    lo_rank = int(stats.binom.ppf((1 - level) / 2, n, 0.5))
    # ppf gives the smallest l with P(B <= l) >= alpha/2, so P(B <= l - 1) < alpha/2.
    if lo_rank < 1:
        return med, math.nan, math.nan
    return med, float(x[lo_rank - 1]), float(x[n - lo_rank])


def kinds_with_all(study: Study) -> list[str]:
    """Target kinds of the scenario in first-seen order, then ``"all"`` if several."""
    kinds = list(dict.fromkeys(study.scenario.target_kinds))
    return kinds + ["all"] if len(kinds) > 1 else kinds


def run_metrics(tables: StudyTables) -> Any:
    """Per (method, run, kind) metrics over steps 1..S.

    Columns: method, run, kind (each target kind and ``all``), rmse (m; ``sqrt`` of the mean
    over steps 1..S and the kind's targets of error^2), mean_error (m), lost_share (share of
    those target-steps with error > :data:`LOST_THRESHOLD`), measured_share (share with at
    least one measurement), negative_share (share that got a missed-look update).
    """
    import pandas as pd

    d = tables.steps[tables.steps["step"] >= 1]
    d = d.assign(se=d["error"] ** 2, lost=d["error"] > LOST_THRESHOLD)
    agg = dict(mse=("se", "mean"), mean_error=("error", "mean"), lost_share=("lost", "mean"),
               measured_share=("measured", "mean"),
               negative_share=("negative_update", "mean"))
    per_kind = d.groupby(["method", "run", "kind"], observed=True).agg(**agg).reset_index()
    frames = [per_kind]
    if "all" in kinds_with_all(tables.study):
        everything = d.groupby(["method", "run"], observed=True).agg(**agg).reset_index()
        everything["kind"] = "all"
        frames.append(everything)
    out = pd.concat(frames, ignore_index=True)
    out["kind"] = pd.Categorical(out["kind"].astype(str), categories=kinds_with_all(
        tables.study), ordered=True)
    out["rmse"] = np.sqrt(out.pop("mse"))
    return out.sort_values(["method", "kind", "run"]).reset_index(drop=True)


def summary(metrics: Any, column: str = "rmse", level: float = LEVEL) -> Any:
    """Across-run statistics of a run metric per (method, kind).

    Columns: method, kind, n (runs), mean, mean_lo, mean_hi (t-interval), median,
    median_lo, median_hi (order-statistic interval).
    """
    import pandas as pd

    rows = []
    for (method, kind), g in metrics.groupby(["method", "kind"], observed=True, sort=True):
        x = g[column].to_numpy(float)
        mean, lo, hi = t_interval(x, level)
        med, mlo, mhi = median_interval(x, level)
        rows.append(dict(method=method, kind=kind, n=x.size, mean=float(mean),
                         mean_lo=float(lo), mean_hi=float(hi), median=med, median_lo=mlo,
                         median_hi=mhi))
    return pd.DataFrame(rows)


def references(study: Study) -> dict[str, dict[str, str | None]]:
    """The myopic and random method each method is compared with (paired differences).

    - ``random``: the first method with planner ``random``, the same ``miss_update`` (the
      tracker decides how a random policy tracks) and the same ``steps_per_epoch``; failing
      that, any with the same ``miss_update``.
    - ``myopic``: the first method with planner ``pg``, ``horizon = 1`` and the same
      ``visibility``, ``objective``, ``miss_update`` and ``steps_per_epoch``.

    A method is not compared with itself, a ``random`` method with nothing (myopic against
    random already shows that difference), and an entry is None when no method matches.
    """
    out: dict[str, dict[str, str | None]] = {}
    for m in study.methods:
        s = m.settings

        def first(pred: Callable[[RunSettings], bool], m: Method = m) -> str | None:
            for other in study.methods:
                if other.name != m.name and pred(other.settings):
                    return other.name
            return None

        rnd = first(lambda o: o.planner == "random" and o.miss_update == s.miss_update
                    and o.steps_per_epoch == s.steps_per_epoch)
        if rnd is None:
            rnd = first(lambda o: o.planner == "random" and o.miss_update == s.miss_update)
        myo = first(lambda o: o.planner == "pg" and o.horizon == 1
                    and o.visibility == s.visibility and o.objective == s.objective
                    and o.miss_update == s.miss_update
                    and o.steps_per_epoch == s.steps_per_epoch)
        if s.planner == "random":
            # random vs myopic is myopic vs random with the sign flipped.
            rnd = myo = None
        if s.planner == "pg" and s.horizon == 1:
            myo = None
        out[m.name] = {"myopic": myo, "random": rnd}
    return out


def paired_differences(metrics: Any, study: Study, column: str = "rmse",
                       level: float = LEVEL) -> Any:
    """Paired differences ``method - reference`` of a run metric, per run, summarized.

    For each method, each of its :func:`references` and each kind: ``d_r = x(method, r) -
    x(reference, r)`` over the runs both finished; the mean with its paired t-interval, the
    median with its order-statistic interval, and the share of runs where the method is
    lower (better).

    Columns: method, against (``myopic`` or ``random``), reference, kind, n, mean, mean_lo,
    mean_hi, median, median_lo, median_hi, better_share.
    """
    import pandas as pd

    wide = metrics.pivot_table(index=["kind", "run"], columns="method", values=column,
                               observed=True)
    rows = []
    for method, refs in references(study).items():
        for against in ("myopic", "random"):
            ref = refs[against]
            if ref is None or method not in wide or ref not in wide:
                continue
            for kind in kinds_with_all(study):
                if kind not in wide.index.get_level_values(0):
                    continue
                both = wide.loc[kind, [method, ref]].dropna()
                d = (both[method] - both[ref]).to_numpy(float)
                mean, lo, hi = t_interval(d, level)
                med, mlo, mhi = median_interval(d, level)
                rows.append(dict(method=method, against=against, reference=ref, kind=kind,
                                 n=d.size, mean=float(mean), mean_lo=float(lo),
                                 mean_hi=float(hi), median=med, median_lo=mlo,
                                 median_hi=mhi,
                                 better_share=float(np.mean(d < 0)) if d.size else math.nan))
    return pd.DataFrame(rows)


def rmse_over_time(tables: StudyTables, level: float = LEVEL) -> Any:
    """Position RMSE at each step per (method, kind) with a band across runs.

    At step t, with ``m_r(t)`` run r's mean over the kind's targets of error^2, the RMSE is
    ``sqrt(mean_r m_r(t))`` and the band is ``sqrt`` of the t-interval of that mean
    (clipped at 0): a 95 % interval for the RMSE of the step across runs.

    Columns: method, kind, step, rmse, lo, hi, n.
    """
    import pandas as pd

    st = tables.steps
    se = st.assign(se=st["error"] ** 2)
    frames = [se.groupby(["method", "kind", "step", "run"], observed=True)["se"].mean()
              .reset_index()]
    if "all" in kinds_with_all(tables.study):
        a = se.groupby(["method", "step", "run"], observed=True)["se"].mean().reset_index()
        a["kind"] = "all"
        frames.append(a)
    per_run = pd.concat(frames, ignore_index=True)
    per_run["kind"] = per_run["kind"].astype(str)
    rows = []
    for (method, kind), g in per_run.groupby(["method", "kind"], observed=True, sort=False):
        wide = g.pivot(index="run", columns="step", values="se")       # (runs, steps)
        mean, lo, hi = t_interval(wide.to_numpy(float), level, axis=0)
        rows.append(pd.DataFrame(dict(
            method=method, kind=kind, step=wide.columns.to_numpy(), rmse=np.sqrt(mean),
            lo=np.sqrt(np.clip(lo, 0.0, None)), hi=np.sqrt(np.clip(hi, 0.0, None)),
            n=wide.notna().sum(axis=0).to_numpy())))
    out = pd.concat(rows, ignore_index=True)
    out["method"] = out["method"].astype(tables.steps["method"].dtype)
    return out.sort_values(["method", "kind", "step"]).reset_index(drop=True)


def planning_summary(tables: StudyTables) -> Any:
    """Per method: decisions, planning time per decision (ms: mean, median, 90th
    percentile, max), total planning time per run (s), converged share and sweeps (mean,
    max) where the planner reports them, and the mean potential Phi (nats)."""
    import pandas as pd

    rows = []
    dec = tables.decisions
    for method, g in dec.groupby("method", observed=True, sort=True):
        ms = 1e3 * g["planning_seconds"].to_numpy(float)
        conv = g["converged"].dropna().astype(float).to_numpy()
        sweeps = g["sweeps"].dropna().astype(float).to_numpy()
        per_run = g.groupby("run")["planning_seconds"].sum().to_numpy(float)
        rows.append(dict(
            method=method, decisions=len(g), mean_ms=float(ms.mean()),
            median_ms=float(np.median(ms)), p90_ms=float(np.percentile(ms, 90)),
            max_ms=float(ms.max()), seconds_per_run=float(per_run.mean()),
            converged_share=float(conv.mean()) if conv.size else math.nan,
            sweeps_mean=float(sweeps.mean()) if sweeps.size else math.nan,
            sweeps_max=float(sweeps.max()) if sweeps.size else math.nan,
            phi_mean=float(g["phi"].mean())))
    return pd.DataFrame(rows)


def sensing_summary(tables: StudyTables) -> Any:
    """Per method, over sensor-steps 1..S: looks (share of sensor-steps pointed at a
    target), measurements per sensor-step, and the share of looks that missed."""
    import pandas as pd

    s = tables.sensors[tables.sensors["step"] >= 1]
    rows = []
    for method, g in s.groupby("method", observed=True, sort=True):
        looks = g["target"].to_numpy() >= 0
        rows.append(dict(method=method, look_share=float(looks.mean()),
                         measurements_per_sensor_step=float(g["measured"].mean()),
                         miss_share=float(g["missed"].to_numpy()[looks].mean())
                         if looks.any() else math.nan))
    return pd.DataFrame(rows)


# ------------------------------------------------------------------------------- demo

#: The study ``sensorplan demo`` runs; ``studies/demo.toml`` holds the same text (tested).
DEMO_STUDY = '''\
# The `sensorplan demo` study (built into the package; this file is the same study):
# the paper scenario with our defaults (probabilistic visibility, negative miss updates),
# a few short paired runs, the paper's planners plus the references. Under two minutes
# on 2 cores, report included:
#   sensorplan demo                              (or: make demo)
#   sensorplan study studies/demo.toml --out out/demo && sensorplan report out/demo
description = "Demo: the paper scenario with our defaults, 12 short paired runs"
runs = 12
steps = 60
seed = 20240601

[scenario]
preset = "paper"

[defaults]
steps_per_epoch = 2        # a decision every 2 steps, as in the paper's study

[[methods]]
name = "random"
planner = "random"

[[methods]]
name = "myopic"
planner = "pg"
horizon = 1

[[methods]]
name = "OL pg K=3"
planner = "pg"
horizon = 3
execution = "ol"

[[methods]]
name = "OLF pg K=3"
planner = "pg"
horizon = 3
execution = "olf"

[[methods]]
name = "OLF sequential-greedy K=3"
planner = "sequential-greedy"
horizon = 3
execution = "olf"
'''


def demo_study() -> Study:
    """The built-in demo study (:data:`DEMO_STUDY`)."""
    from .config import parse_study

    return parse_study(DEMO_STUDY, source="demo study")


def horizon_groups(study: Study, minimum: int = 3) -> list[list[Method]]:
    """Groups of methods that differ only in the horizon K (at least ``minimum`` distinct K),
    each sorted by K: the report plots RMSE and planning time against K for them.

    A K = 1 method joins the groups of either execution (OL and OLF are the same policy
    when K = 1).
    """
    groups: dict[str, list[Method]] = {}
    for m in study.methods:
        d = m.to_dict()
        for k in ("name", "horizon", "execution"):
            d.pop(k)
        groups.setdefault(json.dumps(d, sort_keys=True, default=str), []).append(m)
    out = []
    for members in groups.values():
        myopic = [m for m in members if m.settings.horizon == 1]
        executions = dict.fromkeys(m.settings.execution for m in members
                                   if m.settings.horizon > 1)
        for execution in executions:
            by_k: dict[int, Method] = {}
            for m in myopic + [m for m in members if m.settings.horizon > 1
                               and m.settings.execution == execution]:
                by_k.setdefault(m.settings.horizon, m)
            if len(by_k) >= minimum:
                out.append([by_k[k] for k in sorted(by_k)])
    return out
