"""Threads for the planning engine's independent kernel calls.

An epoch game's players each need their candidate chains' looks
(:func:`~sensorplan.planners._pairs_nb.chain_pairs_nb`): independent computations, one per
player, in kernels that release the GIL. They run on a few threads, so one decision uses the
machine's cores. Each call computes the same numbers whatever thread runs it, so plans are the
same for any number of threads.

The number of threads is ``SENSORPLAN_THREADS`` (a whole number >= 1), by default the cores
this process may use, at most :data:`MAX_THREADS`. A study's worker processes get 1: they
already use every core between them.

The pool is a few daemon threads waiting on a condition (``concurrent.futures`` would add
40 ms to the start of every ``sensorplan plan``); the calling thread works on its batch too.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable, Sequence
from typing import Any

from ..errors import ConfigError

#: Threads used by default at most (an epoch game's batches rarely keep more busy).
MAX_THREADS = 4
#: The environment variable that sets the number of threads.
ENV = "SENSORPLAN_THREADS"

_pending: list[_Batch] = []          # one entry per helper a batch asks for
_posted = threading.Condition()
_helpers = 0


def parse_threads(value: str) -> int:
    """The number of threads ``value`` (of :data:`ENV`) names; ConfigError naming the
    variable if it is not a whole number >= 1."""
    text = value.strip()
    if not text.isdigit() or int(text) < 1:
        raise ConfigError(ENV, f"must be a whole number of threads >= 1, got {value!r} "
                               "(or unset it)")
    return int(text)


def n_threads() -> int:
    """Threads the engine uses: :data:`ENV` if set, else the usable cores (at most
    :data:`MAX_THREADS`)."""
    value = os.environ.get(ENV)
    if value is not None:
        return parse_threads(value)
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:                         # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, MAX_THREADS))


class _Batch:
    """Jobs taken one at a time, in order, by the calling thread and its helpers."""

    def __init__(self, fn: Callable[..., Any], jobs: Sequence[tuple], helpers: int) -> None:
        self.fn, self.jobs = fn, jobs
        self.results: list[Any] = [None] * len(jobs)
        self.error: BaseException | None = None
        self.stop = False
        self._next = itertools.count()             # next() is atomic under the GIL
        self._left = helpers
        self._done = threading.Condition()

    def work(self) -> None:
        n = len(self.jobs)
        for x in self._next:
            if x >= n or self.stop:
                return
            try:
                self.results[x] = self.fn(*self.jobs[x])
            except BaseException as exc:           # handed to the calling thread
                self.error = self.error or exc
                self.stop = True

    def help(self) -> None:
        try:
            self.work()
        finally:
            with self._done:
                self._left -= 1
                self._done.notify()

    def wait(self) -> None:
        with self._done:
            while self._left:
                self._done.wait()


def _helper() -> None:
    while True:
        with _posted:
            while not _pending:
                _posted.wait()
            batch = _pending.pop()
        batch.help()


def run_all(fn: Callable[..., Any], jobs: Sequence[tuple], threads: int) -> list[Any]:
    """``[fn(*args) for args in jobs]``, on ``threads`` threads when there is more than one
    job (results in the order of ``jobs``; the first error is raised)."""
    helpers = min(threads, len(jobs)) - 1
    if helpers <= 0:
        return [fn(*args) for args in jobs]
    batch = _Batch(fn, jobs, helpers)
    with _posted:
        _start(helpers)
        _pending.extend([batch] * helpers)
        _posted.notify(helpers)
    try:
        batch.work()
    finally:
        batch.stop = True                          # e.g. Ctrl-C: helpers take no new job
        batch.wait()
    if batch.error is not None:
        raise batch.error
    return batch.results


def _forget_helpers() -> None:
    """In a forked child: the parent's helper threads do not exist there."""
    global _pending, _posted, _helpers
    _pending, _posted, _helpers = [], threading.Condition(), 0


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_helpers)


def _start(helpers: int) -> None:
    global _helpers
    while _helpers < helpers:
        threading.Thread(target=_helper, name=f"sensorplan-{_helpers + 1}", daemon=True).start()
        _helpers += 1
