"""Running a study: each (run, method) as a task, in this process, a local process pool
or on Dask, with the results written as they arrive (:func:`run_study`).

Run ``r`` gets the seed ``SeedSequence(study.seed, spawn_key=(r,))`` and every method
receives that same sequence, so ``simulation.run_episode`` draws the same truths, initial
estimates, sensor starts and per-sensor noise for all of them: method differences are
paired (common random numbers). Results do not depend on the executor.
"""

from __future__ import annotations

import ast
import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import signal
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeGuard, cast

import numpy as np

from ..config.files import ensure_out_dir, write_failed
from ..errors import ConfigError
from ..planners.checks import PlanRejected
from ..simulation.run import run_episode
from .model import Study
from .storage import (check_parts, clean_temporaries, consolidate, git_describe, locked, now,
                      part_path, prepare, remove_part, tables_intact, versions, write_meta,
                      write_part)
from .tables import TaskResult, episode_tables

#: Environment variables that limit threads in worker processes (BLAS/OpenMP, and the
#: planning engine's): with one process per core, more threads only add contention.
THREAD_LIMITS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                 "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS",
                 "SENSORPLAN_THREADS")


def run_task(study: Study, run: int, method: int) -> TaskResult:
    """Simulate method ``method`` (index) on run ``run`` and return its tables."""
    from .._compiled.jit import loaded

    m = study.methods[method]
    _warm()
    kernels = loaded()
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        episode = run_episode(study.scenario, m.settings, study.run_seed(run))
    except PlanRejected as exc:
        # A planner that breaks its contract invalidates the comparison: the study stops.
        raise ConfigError(f"methods[{method}].planner",
                          f"{exc.message} (method {m.name!r}, run {run})") from None
    except ConfigError as exc:
        # A planner refusing mid-run (brute force above max_plans) names its own setting.
        field = exc.field.removeprefix("planner.").removeprefix("planner")
        raise ConfigError(f"methods[{method}].planner_params" + (f".{field}" if field else ""),
                          f"{exc.message} (method {m.name!r}, run {run})") from None
    tables = episode_tables(episode, run, m.name)
    return TaskResult(run, method, tables, time.perf_counter() - wall,
                      time.process_time() - cpu, float(np.sum(episode.planning_seconds)),
                      loaded() - kernels)


def _warm() -> None:
    """Load the compiled kernels as a whole run will use them (once per process), so that
    no task's time, and no decision's, includes it: numba's kernels, since the tracker's
    first step would load numba anyway (:func:`sensorplan._compiled.prepare.warm_for_runs`)."""
    from .._compiled.prepare import warm_for_runs
    from ..planners._chains_nb import warm_up

    warm_for_runs()
    warm_up()


# ------------------------------------------------------------------------- executors

_WORKER_STUDY: Study | None = None


def _pool_init(study: Study) -> None:
    global _WORKER_STUDY
    _WORKER_STUDY = study
    # The parent handles Ctrl-C (it stops the pool); workers should not print tracebacks.
    # (They start with SIGINT ignored already: see _spawning.)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _warm()


@contextlib.contextmanager
def _spawning() -> Iterator[None]:
    """Ignore Ctrl-C while worker processes are started: a started process inherits the
    ignored signal, so a Ctrl-C pressed while it imports (before its initializer runs)
    cannot print its traceback. The parent's own handler is restored right after."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:                    # not the main thread: signals are not ours
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _pool_task(run: int, method: int) -> TaskResult:
    assert _WORKER_STUDY is not None
    return run_task(_WORKER_STUDY, run, method)


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


#: Longest wait for a worker's result before the study's own code runs again.
WAIT_SECONDS = 0.2


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
            with _spawning():                 # the first submit starts the workers
                for r, m in todo:
                    pending.add(pool.submit(_pool_task, r, m))
                    if len(pending) >= 2 * workers:
                        break
            while pending:
                # Back in this frame every 0.2 s: the command line's Ctrl-C and SIGTERM
                # handlers defer while concurrent.futures' code runs (an exception raised
                # inside it can leave its locks held), so this is where they land.
                done, pending = cf.wait(pending, timeout=WAIT_SECONDS,
                                        return_when=cf.FIRST_COMPLETED)
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
            # Wait for them (and kill the stubborn), so that none outlives the study.
            for proc in procs:
                with contextlib.suppress(Exception):
                    proc.join(5)
                    if proc.is_alive():
                        proc.kill()
                        proc.join(5)
            raise
        else:
            pool.shutdown(wait=True)


#: Address schemes of Dask's communication layer (``distributed.comm``).
DASK_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def _dask_client(scheduler: str, workers: int, processes: bool) -> tuple[Any, Any]:
    """A Dask client of ``scheduler`` (and the LocalCluster it started, else None);
    ConfigError naming ``--scheduler`` when it cannot connect."""
    import logging

    from distributed import Client, LocalCluster

    with _thread_limits():
        if scheduler == "local":
            with _spawning():
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                       processes=processes, dashboard_address=None,
                                       silence_logs=logging.ERROR)
            return Client(cluster), cluster
        try:
            return Client(scheduler, timeout="30s"), None
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise ConfigError("--scheduler", f"cannot connect to {scheduler} "
                              f"({exc})") from None


class StudyLost(RuntimeError):
    """The Dask cluster lost the study (every worker holding it died); the finished pairs
    are on disk and a rerun resumes."""

    def __init__(self, done: int, total: int, why: str) -> None:
        super().__init__(why)
        self.done, self.total, self.why = done, total, why


def _lost(exc: BaseException) -> str | None:
    """Why a Dask result failed, if the cluster (not the task) failed: lost workers."""
    import concurrent.futures

    name = type(exc).__name__
    if isinstance(exc, concurrent.futures.CancelledError) or name in (
            "FutureCancelledError", "KilledWorker", "CommClosedError", "CancelledError"):
        return f"{name}: {exc}" if str(exc) else name
    return None


def _dask(study: Study, tasks: Sequence[tuple[int, int]], client: Any,
          cluster: Any) -> Iterator[TaskResult]:
    from distributed import as_completed

    futures = []
    try:
        # Ship the study once to every worker instead of once per task.
        study_f = client.scatter(study, broadcast=True)
        futures = [client.submit(run_task, study_f, r, m, pure=False) for r, m in tasks]
        for fut in as_completed(futures):
            try:
                result = fut.result()
            except Exception as exc:
                why = _lost(exc)
                if why is None:
                    raise
                raise _DaskLost(why) from None
            yield result
    finally:
        with contextlib.suppress(Exception):
            client.cancel(futures)
        with contextlib.suppress(Exception):
            client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()


class _DaskLost(Exception):
    """Raised by :func:`_dask`; :func:`run_study` adds the counts (:class:`StudyLost`)."""


def default_workers() -> int:
    """Cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


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
    done : int           pairs on disk after this call (``total`` once the study is
                         complete; fewer after a call that ran some of its methods)
    """

    out: Path
    total: int
    ran: int
    wall: float
    timing: dict[str, Any] = field(default_factory=dict)
    done: int | None = None

    def __post_init__(self) -> None:
        if self.done is None:
            self.done = self.total

    @property
    def complete(self) -> bool:
        """Whether every (run, method) pair of the study is done."""
        return self.done == self.total


def _is_main_guard(node: ast.AST) -> TypeGuard[ast.If]:
    """``if __name__ == "__main__":`` (either operand order)."""
    if not (isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
            and len(node.test.ops) == 1 and isinstance(node.test.ops[0], ast.Eq)):
        return False
    sides = [node.test.left, *node.test.comparators]
    return (any(isinstance(s, ast.Name) and s.id == "__name__" for s in sides)
            and any(isinstance(s, ast.Constant) and s.value == "__main__" for s in sides))


def _within(stmt: ast.stmt, line: int) -> bool:
    return stmt.lineno <= line <= (stmt.end_lineno or stmt.lineno)


def _guarded(body: list[ast.stmt], line: int) -> bool:
    """Whether ``line`` lies in the body of a main guard among ``body`` (at any depth)."""
    for stmt in body:
        if not _within(stmt, line):
            continue
        if _is_main_guard(stmt):
            return any(_within(s, line) for s in stmt.body)      # not its ``else:``
        inner = [s for name in ("body", "orelse", "finalbody") for s in getattr(stmt, name, [])]
        inner += [s for h in getattr(stmt, "handlers", []) for s in h.body]
        return _guarded(inner, line)
    return False


def unguarded_script() -> str | None:
    """The script whose top-level code is calling us outside ``if __name__ == "__main__":``.

    Worker processes started with 'spawn' (the pool, a Dask LocalCluster) run the main
    module again (multiprocessing skips only a package's ``__main__``), so such a call
    would run again in every worker. None when the main module is safe or cannot be read.
    """
    main = sys.modules.get("__main__")
    spec_name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if main is None or spec_name.endswith("__main__") or not getattr(main, "__file__", None):
        return None
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_globals is main.__dict__
                                     and frame.f_code.co_name == "<module>"):
        frame = frame.f_back  # type: ignore[assignment]
    if frame is None:
        return None                     # the script's top level has finished: no rerun
    path = frame.f_code.co_filename
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return None
    return None if _guarded(tree.body, frame.f_lineno) else path


ProgressFn = Callable[[int, int, int], None]


def run_study(study: Study, out: str | Path, *, workers: int | None = None,
              scheduler: str | None = None, processes: bool = True,
              progress: ProgressFn | None = None,
              methods: Sequence[str] | None = None) -> StudyRun:
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
    methods : sequence of str, optional
        Run only these methods (names of ``study``'s methods); the directory still holds
        the whole study, and another call runs the rest. The tables are written once
        every method has run; until then :func:`load_study_dir` reads the methods that
        have.

    Returns
    -------
    StudyRun

    Raises
    ------
    ConfigError
        ``out`` holds another study, is not a study directory, or is locked by another
        process; a bad ``workers`` or ``scheduler``.
    RuntimeError
        Worker processes are needed but the call runs in a script's top-level code outside
        an ``if __name__ == "__main__":`` block (the workers would run the script again).
    StudyInterrupted
        On Ctrl-C; everything finished before is kept and a rerun resumes.
    """
    out = Path(out)
    workers = _check_executor(workers, scheduler, processes)
    chosen = _chosen_methods(study, methods)
    ensure_out_dir(out)

    import pyarrow.parquet  # noqa: F401  (imported now, not inside the first write's timing)

    start = time.perf_counter()
    with locked(out):
        done = _open_study_dir(out, study)
        todo = [t for t in study.tasks() if t not in done and t[1] in chosen]
        # The tables are the whole study's: written once its last pair is done.
        whole = len(done) + len(todo) == len(study.tasks())
        if not todo and (not whole or tables_intact(out, study)):
            return StudyRun(out, len(study.tasks()), 0, time.perf_counter() - start,
                            done=len(done))
        executor = _Executor(study, todo, workers, scheduler, processes)
        try:
            session = _Session(out, study, executor.name if todo else "none (complete)",
                               len(done), consolidate=whole)
            try:
                session.run(executor, _progress_calls(progress), len(todo))
            finally:
                executor.close()
                session.finish()
        finally:
            executor.close()
    return StudyRun(out, len(study.tasks()), session.ran, session.wall, session.record,
                    done=len(done) + session.ran)


def _chosen_methods(study: Study, methods: Sequence[str] | None) -> set[int]:
    """The indices of the methods to run (all of them when ``methods`` is None)."""
    names = study.method_names
    if methods is None:
        return set(range(len(names)))
    if isinstance(methods, str) or not methods:
        raise ConfigError("--methods", f"must be a non-empty list of method names, got "
                          f"{methods!r}")
    unknown = [m for m in methods if m not in names]
    if unknown:
        raise ConfigError("--methods", f"unknown method {unknown[0]!r}; the study's methods "
                          f"are {', '.join(names)}")
    return {names.index(m) for m in methods}


def _check_executor(workers: int | None, scheduler: str | None, processes: bool) -> int:
    """The number of workers, after checking the executor's arguments (see
    :func:`run_study`)."""
    if workers is None:
        workers = default_workers()
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ConfigError("--workers", f"must be an integer >= 1, got {workers!r}")
    if scheduler is not None and scheduler != "local" and "://" not in scheduler:
        raise ConfigError("--scheduler", f"must be 'local' or an address such as "
                          f"tcp://host:8786, got {scheduler!r}")
    if scheduler is not None and scheduler != "local":
        scheme = scheduler.split("://", 1)[0].lower()
        if scheme not in DASK_SCHEMES:
            raise ConfigError("--scheduler", f"unknown address scheme {scheme!r} in "
                              f"{scheduler!r}; use {', '.join(DASK_SCHEMES)} (e.g. "
                              "tcp://host:8786) or 'local'")
    if (workers > 1 and scheduler is None) or (scheduler == "local" and processes):
        script = unguarded_script()
        if script is not None:
            raise RuntimeError(
                f"run_study starts worker processes, which run {script} again, so call it "
                f"under `if __name__ == \"__main__\":` in that script (or pass workers=1)")
    return workers


def _open_study_dir(out: Path, study: Study) -> set[tuple[int, int]]:
    """Make ``out`` hold ``study`` and return the (run, method) pairs already done: a new
    directory, the same study, or the same study with more runs; damaged parts removed to
    run again (never trusted, never fatal)."""
    grown_from = prepare(out, study)
    clean_temporaries(out)
    done, damaged = check_parts(out, study)
    for (r, m), problem in sorted(damaged.items()):
        # Removed first: a part that cannot be removed is then the only line.
        remove_part(out, r, m)
        _say(f"warning: {part_path(out, r, m, 'steps').parent.name}/m{m:02d} is damaged "
             f"({problem}); running it again")
    if grown_from is not None:
        _say(f"note: {out} held {grown_from} runs of this study; adding runs "
             f"{grown_from}..{study.runs - 1}")
    return set(done)


class _Executor:
    """Where the missing pairs run: in this process, a process pool, or Dask."""

    def __init__(self, study: Study, todo: list[tuple[int, int]], workers: int,
                 scheduler: str | None, processes: bool) -> None:
        self.study, self.todo, self.workers = study, todo, workers
        self.client = self.cluster = None
        pool = scheduler is None and workers > 1 and len(todo) > 1
        if todo and (pool or (scheduler == "local" and processes)):
            # Said (and, on a fresh cache, compiled) once here, not in every worker;
            # before any worker or cluster exists, so that a Ctrl-C here leaves none.
            from .._compiled.prepare import before_workers

            before_workers()
        if scheduler is not None:
            self.name = f"dask {scheduler}" + (f" ({workers} workers)"
                                               if scheduler == "local" else "")
            if todo:
                # Connected before anything is reported: a bad address is the only line.
                self.client, self.cluster = _dask_client(scheduler, workers, processes)
        elif workers == 1 or len(todo) <= 1:
            self.name = "in process"
        else:
            self.name = f"process pool ({workers} workers)"

    def results(self) -> Iterable[TaskResult]:
        if not self.todo:
            return ()
        if self.client is not None:
            return _dask(self.study, self.todo, self.client, self.cluster)
        if self.name == "in process":
            return _in_process(self.study, self.todo)
        return _process_pool(self.study, self.todo, self.workers)

    def close(self) -> None:
        """Close the Dask client and cluster (closed already unless never started)."""
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close()
            if self.cluster is not None:
                with contextlib.suppress(Exception):
                    self.cluster.close()


class _Session:
    """One call's work on a study directory: what it ran and how long it took, recorded in
    ``meta.json`` as it starts and when it ends (interrupted or not)."""

    def __init__(self, out: Path, study: Study, executor: str, before: int,
                 consolidate: bool = True) -> None:
        self.out, self.study, self.before = out, study, before
        self.consolidate = consolidate
        self.start_wall, self.start_cpu = time.perf_counter(), time.process_time()
        self.record: dict[str, Any] = {
            "id": f"{now()}-{os.getpid()}", "started": now(), "finished": None,
            "executor": executor, "tasks_run": 0, "tasks_before": before,
            "interrupted": False,
            # Per session: a resumed study may have been continued with other code.
            "sensorplan": versions().get("sensorplan"), "git": git_describe()}
        self.timing = {"compute_wall_seconds": 0.0, "compute_cpu_seconds": 0.0,
                       "planning_seconds": 0.0, "write_seconds": 0.0,
                       "consolidate_seconds": 0.0}
        self.ran, self.wall, self.finished = 0, 0.0, False
        try:
            write_meta(out, study, self.record, complete=False)
        except OSError as exc:
            raise write_failed(exc) from None

    def run(self, executor: _Executor, progress: Callable[..., None] | None, todo: int
            ) -> None:
        """Write every result as it comes, then consolidate the tables."""
        if progress is not None:
            progress(0, todo, self.before)
        try:
            for res in executor.results():
                t0 = time.perf_counter()
                self._write(write_part, self.out, res)
                self.timing["write_seconds"] += time.perf_counter() - t0
                self.timing["compute_wall_seconds"] += res.wall
                self.timing["compute_cpu_seconds"] += res.cpu
                self.timing["planning_seconds"] += res.planning
                self.ran += 1
                if progress is not None:
                    progress(self.ran, todo, self.before,
                             seconds=None if res.loaded else res.wall)
            if self.consolidate:
                t0 = time.perf_counter()
                self._write(consolidate, self.out, self.study)
                self.timing["consolidate_seconds"] = time.perf_counter() - t0
                self.finished = True
        except KeyboardInterrupt:
            self.record["interrupted"] = True
            raise StudyInterrupted(self.before + self.ran, len(self.study.tasks())) from None
        except _DaskLost as exc:
            self.record["interrupted"] = True
            raise StudyLost(self.before + self.ran, len(self.study.tasks()), str(exc)) from None

    @staticmethod
    def _write(write: Callable[..., None], *args: Any) -> None:
        try:
            write(*args)
        except OSError as exc:
            raise write_failed(exc) from None

    def finish(self) -> None:
        """Record the session's end in ``meta.json`` (never raising: the study is safe)."""
        self.wall = time.perf_counter() - self.start_wall
        self.record.update({k: round(v, 4) for k, v in self.timing.items()})
        self.record.update({"finished": now(), "tasks_run": self.ran,
                            "wall_seconds": round(self.wall, 3),
                            "main_cpu_seconds": round(time.process_time() - self.start_cpu,
                                                      3)})
        with contextlib.suppress(Exception):
            write_meta(self.out, self.study, self.record, complete=self.finished)


def _progress_calls(progress: ProgressFn | None) -> Callable[..., None] | None:
    """The progress callback, called with ``seconds=`` (a pair's compute time; None for a
    pair that loaded or compiled kernels, which the next ones will not: no time to
    extrapolate from) only if it takes it: checked once, not at every pair."""
    if progress is None:
        return None
    if _takes_seconds(progress):
        return cast(Callable[..., None], progress)

    def call(done: int, total: int, already: int, seconds: float | None = None) -> None:
        progress(done, total, already)

    return call


def _takes_seconds(progress: Callable[..., Any]) -> bool:
    """Whether a progress callback accepts the keyword ``seconds`` (a pair's compute time)."""
    import inspect

    try:
        inspect.signature(progress).bind(0, 0, 0, seconds=0.0)
    except (TypeError, ValueError):
        return False
    return True


def _say(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
