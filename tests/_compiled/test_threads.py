"""The engine's threads: any number of them gives the same plans, bit for bit."""

from __future__ import annotations

import os
import sys
import threading

import numpy as np
import pytest

from sensorplan._compiled.threads import n_threads, parse_threads, run_all
from sensorplan.errors import ConfigError
from sensorplan.planners import epoch_game, make_planner

from factories import paper_problem
from planner_reference import scale_problem


def test_run_all_keeps_the_order_of_the_jobs_on_any_number_of_threads() -> None:
    jobs = [(i, 3) for i in range(25)]
    want = [i * 3 for i in range(25)]
    for threads in (1, 2, 3, 8):
        assert run_all(lambda a, b: a * b, jobs, threads) == want
    assert run_all(lambda a: a, [], 4) == []


def test_run_all_raises_the_error_of_a_job_and_stays_usable() -> None:
    def job(x: int) -> int:
        if x == 5:
            raise ValueError("job 5")
        return x

    with pytest.raises(ValueError, match="job 5"):
        run_all(job, [(i,) for i in range(12)], 3)
    assert run_all(job, [(i,) for i in range(5)], 3) == list(range(5))


def test_callers_on_several_threads_share_the_helpers() -> None:
    # Planners run from a user's own threads (or a Dask worker's): every batch completes,
    # with its own results.
    out: dict[int, list] = {}

    def caller(c: int) -> None:
        out[c] = [run_all(lambda a, b: a * b + c, [(i, 2) for i in range(9)], 3)
                  for _ in range(50)]

    callers = [threading.Thread(target=caller, args=(c,)) for c in range(4)]
    for t in callers:
        t.start()
    for t in callers:
        t.join(60)
    assert not any(t.is_alive() for t in callers)
    for c in range(4):
        assert out[c] == [[2 * i + c for i in range(9)]] * 50


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork only")
def test_a_forked_child_starts_its_own_helpers() -> None:
    run_all(lambda a: a, [(1,), (2,)], 2)              # the parent has a helper now
    pid = os.fork()
    if pid == 0:                                       # pragma: no cover (the child)
        ok = run_all(lambda a: a + 1, [(i,) for i in range(4)], 2) == [1, 2, 3, 4]
        os._exit(0 if ok else 1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    helpers = [t for t in threading.enumerate() if t.name.startswith("sensorplan-")]
    assert all(t.daemon for t in helpers)              # none keeps a process alive


def test_the_thread_count_comes_from_the_environment(monkeypatch) -> None:
    monkeypatch.setenv("SENSORPLAN_THREADS", " 3 ")
    assert n_threads() == 3
    monkeypatch.delenv("SENSORPLAN_THREADS")
    assert 1 <= n_threads() <= 4
    for bad in ("0", "-2", "x", "2.0", ""):
        with pytest.raises(ConfigError, match="SENSORPLAN_THREADS"):
            parse_threads(bad)


@pytest.fixture
def split_everything(monkeypatch) -> list[int]:
    """Every batch of an epoch game runs on threads, however small; counts the batches that
    really were split."""
    monkeypatch.setattr(epoch_game, "PARALLEL_PAIRS", 0)
    monkeypatch.setattr(epoch_game, "PARALLEL_LOOKS", 0)
    split = [0]

    def counting(fn, jobs, threads):
        split[0] += threads > 1 and len(jobs) > 1
        return run_all(fn, jobs, threads)

    monkeypatch.setattr(epoch_game, "run_all", counting)
    return split


def _plan_bits(planner: str, threads: str, monkeypatch, **settings) -> tuple:
    monkeypatch.setenv("SENSORPLAN_THREADS", threads)
    # Large initialisation sets (every position of R_K times every target), several
    # players: the batches really are split between threads.
    problem = scale_problem(n_sensors=6, n_targets=12, horizon=4, width=1200.0, seed=3)
    r = make_planner(planner, **settings).plan(problem, np.random.default_rng(11))
    return (r.plan.positions.tobytes(), r.plan.targets.tobytes(), float(r.potential).hex(),
            r.converged, r.sweeps)


@pytest.mark.parametrize("planner", ["pg", "pg-refine"])
def test_plans_are_the_same_on_one_thread_and_on_three(planner, monkeypatch,
                                                        split_everything) -> None:
    one = _plan_bits(planner, "1", monkeypatch)
    assert split_everything[0] == 0
    assert _plan_bits(planner, "3", monkeypatch) == one
    assert split_everything[0] > 10                    # looks and utilities both
    assert _plan_bits(planner, "2", monkeypatch) == one


def test_small_batches_stay_on_the_calling_thread(monkeypatch) -> None:
    # A paper-size decision: handing its small batches to a thread only costs time.
    monkeypatch.setenv("SENSORPLAN_THREADS", "2")
    split = [0]

    def counting(fn, jobs, threads):
        split[0] += threads > 1 and len(jobs) > 1
        return run_all(fn, jobs, threads)

    monkeypatch.setattr(epoch_game, "run_all", counting)
    make_planner("pg").plan(paper_problem(np.random.default_rng(0)))
    assert split[0] == 0
    make_planner("pg").plan(scale_problem(n_sensors=4, n_targets=20, horizon=4, seed=1))
    assert split[0] > 0                                # the initialisation's looks


def test_a_time_budget_is_checked_between_batches(monkeypatch, split_everything) -> None:
    # With a budget the players' pairs are computed a thread-count at a time, with a check
    # between: a budget far larger than needed still gives the unbudgeted plan.
    free = _plan_bits("pg", "2", monkeypatch)
    assert _plan_bits("pg", "2", monkeypatch, time_budget=1e6)[:4] == free[:4]


if __name__ == "__main__":                             # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
