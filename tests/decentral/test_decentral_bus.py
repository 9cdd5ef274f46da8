"""The message bus: one process per agent, same decisions as in-process, no leaked process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("zmq")

from factories import paper_problem
from sensorplan.decentral import AgentSpec, LinkModel, assemble, decision_key, run_inproc
from sensorplan.decentral.bus import Bus
from sensorplan.planners.information import prepare

SRC = str(Path(__file__).resolve().parents[2] / "src")
TESTS = str(Path(__file__).resolve().parents[1])


def running(pid: int) -> bool:
    """The process exists and is not a zombie (an exited child nobody reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


def wait_gone(pids, seconds: float = 15.0) -> list[int]:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        left = [p for p in pids if running(p)]
        if not left:
            return []
        time.sleep(0.05)
    return [p for p in pids if running(p)]


@pytest.fixture(scope="module")
def planner():
    """One bus planner (three agent processes) shared by the module's fast tests."""
    from sensorplan.planners import make_planner

    p = make_planner("dec-jsfp", transport="bus", p_loss=0.1)
    p.plan(paper_problem(np.random.default_rng(0), horizon=1), rng=0)     # starts the bus
    pids = p.pids
    assert len(pids) == 3 and all(running(q) for q in pids)
    yield p
    p.close()
    assert wait_gone(pids) == []          # no agent process outlives the run
    assert p.pids == ()


LOSSY = {"p_loss": 0.3, "delay": 1, "comm_range": 300.0}
CASES = [                         # (how agents play, links); budgets keep lossy runs short
    (AgentSpec("jsfp"), {}),
    (AgentSpec("jsfp", rounds=25), LOSSY),
    (AgentSpec("best-response", rounds=6), LOSSY),
    (AgentSpec("sequential"), LOSSY),
    (AgentSpec("jsfp", rounds=40, communicate=False), {}),
]


def test_bus_gives_the_inproc_decisions(planner):
    bus = planner._bus(3)
    rng = np.random.default_rng(21)
    problems = (paper_problem(rng, horizon=3),
                paper_problem(rng, horizon=2, visibility="mean", objective="cumulative"))
    for n, (spec, kw) in enumerate(CASES):
        for problem in problems:
            ctx = prepare(problem)
            gen = np.random.default_rng(n)
            link = LinkModel(decision_key(gen), np.array(problem.positions), **kw)
            ref = run_inproc(ctx, spec, link, gen)
            got, failed = bus.decide(problem, spec, link, gen)
            assert failed == set() and set(got) == set(ref) == {0, 1, 2}
            for i in ref:
                a, b = ref[i], got[i]
                for name in ("pos", "tgt", "belief_pos", "belief_tgt"):
                    np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
                assert (a.gen_state, a.settled, a.converged, a.sweeps, a.completed, a.trace,
                        a.rounds, a.sent, a.counts) == (
                    b.gen_state, b.settled, b.converged, b.sweeps, b.completed, b.trace,
                    b.rounds, b.sent, b.counts)
            log = assemble(ctx, got, failed).log
            assert log == assemble(ctx, ref, ()).log
            if not spec.communicate:
                assert log.sent == log.received == 0           # never read a message
            else:
                assert log.received == log.sent > 0
                assert (log.lost + log.out_of_range > 0) == bool(kw)


def test_bus_planner_equals_the_inproc_planner(planner):
    from sensorplan.planners import make_planner

    problem = paper_problem(np.random.default_rng(22), horizon=2)
    pids = planner.pids
    ref = make_planner("dec-jsfp", p_loss=0.1).plan(problem, rng=5)
    for _ in range(2):                                 # the processes serve many decisions
        got = planner.plan(problem, rng=5)
        np.testing.assert_array_equal(got.plan.targets, ref.plan.targets)
        np.testing.assert_array_equal(got.plan.positions, ref.plan.positions)
        assert got.log == ref.log and got.potential == ref.potential
    assert planner.pids == pids


COORDINATOR = textwrap.dedent("""
    import sys
    sys.path[:0] = [{src!r}, {tests!r}]
    import numpy as np
    from factories import paper_problem
    from sensorplan.planners import make_planner
    import sensorplan.decentral
    planner = make_planner("dec-jsfp", transport="bus", timeout=5.0, p_loss=0.2, delay=1)
    problem = paper_problem(np.random.default_rng(0), horizon=3)
    planner.plan(problem, rng=0)
    print(" ".join(map(str, planner.pids)), flush=True)
    seed = 1
    while True:                       # until interrupted; the planner is never closed here
        print("deciding", flush=True)
        planner.plan(problem, rng=seed)
        seed += 1
""")


def socket_dirs(pids) -> set[str]:
    """The bus directories the agent processes were started with (from their command line)."""
    out = set()
    for pid in pids:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            args = f.read().decode().split("\0")
        out.add(args[args.index("--dir") + 1])
    return out


def start_coordinator(new_session: bool = False):
    proc = subprocess.Popen([sys.executable, "-c", COORDINATOR.format(src=SRC, tests=TESTS)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=new_session)
    line = proc.stdout.readline()
    if not line:
        proc.kill()
        raise AssertionError(proc.stderr.read())
    pids = [int(p) for p in line.split()]
    assert len(pids) == 3 and all(running(p) for p in pids)
    # The second "deciding": one loop decision is done and the next under way.
    for _ in range(2):
        assert proc.stdout.readline().strip() == "deciding", proc.stderr.read()
    return proc, pids


@pytest.mark.slow
@pytest.mark.parametrize("group", [False, True], ids=["coordinator", "process-group"])
def test_sigint_ends_every_agent(group):
    """SIGINT to the coordinator alone, or to its whole process group (Ctrl-C)."""
    proc, pids = start_coordinator(new_session=group)
    if group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    proc.wait(timeout=30)
    assert wait_gone(pids) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_agents_exit_when_the_coordinator_dies(sig):
    proc, pids = start_coordinator()
    sockets = socket_dirs(pids)
    assert sockets
    proc.send_signal(sig)
    proc.wait(timeout=30)
    assert wait_gone(pids) == []
    assert not any(os.path.exists(d) for d in sockets)      # the orphans cleaned up


@pytest.mark.slow
def test_killed_agent_is_lost_and_the_others_finish():
    problem = paper_problem(np.random.default_rng(23), horizon=3)
    ctx = prepare(problem)
    spec = AgentSpec("jsfp", rounds=3000)
    with Bus(3, timeout=3.0) as b:
        pids = b.pids
        gen = np.random.default_rng(0)
        # delay 1: no equilibrium is ever verified, so the decision runs for a while
        link = LinkModel(decision_key(gen), np.array(problem.positions), delay=1)
        killer = threading.Timer(0.3, os.kill, (pids[1], signal.SIGKILL))
        start = time.monotonic()
        killer.start()
        got, failed = b.decide(problem, spec, link, gen)
        killer.join()
        assert time.monotonic() - start < 60
        assert failed == {1} and set(got) == {0, 2}
        res = assemble(ctx, got, failed)
        assert res.log.failed == (1,) and np.all(res.tgt[1] == -1)
        assert np.all(res.tgt[[0, 2]] >= 0)
        for o in got.values():
            assert o.failed == (1,) and np.all(o.belief_tgt[1] == -1)
        assert not running(pids[1])
        # the next decisions go on without it, exactly as in-process without it
        link2 = LinkModel(decision_key(gen), np.array(problem.positions))
        got2, failed2 = b.decide(problem, AgentSpec("jsfp"), link2, gen)
        ref2 = run_inproc(ctx, AgentSpec("jsfp"), link2, gen, failed=(1,))
        assert failed2 == {1} and set(got2) == set(ref2) == {0, 2}
        for i in ref2:
            np.testing.assert_array_equal(got2[i].tgt, ref2[i].tgt)
    assert wait_gone(pids) == []


@pytest.mark.slow
def test_closed_loop_on_the_bus_equals_inproc_and_pg():
    from sensorplan.decentral import run_agents
    from sensorplan.decentral.bus import open_buses
    from sensorplan.simulation.scenario import paper_scenario
    from sensorplan.simulation import RunSettings, run_episode

    before = open_buses()
    sc = paper_scenario()
    kw = {"horizon": 3, "steps_per_epoch": 2, "steps": 12}
    ref = run_episode(sc, RunSettings(planner="pg", **kw), 4)
    inproc, logs_in = run_agents(sc, RunSettings(planner="dec-jsfp", **kw), 4)
    bus_ep, logs_bus = run_agents(
        sc, RunSettings(planner="dec-jsfp", planner_params={"transport": "bus"}, **kw), 4)
    for name in ("truth", "estimate", "sensor_positions", "looked", "potential"):
        np.testing.assert_array_equal(getattr(inproc, name), getattr(ref, name))
        np.testing.assert_array_equal(getattr(bus_ep, name), getattr(ref, name))
    assert logs_in == logs_bus and len(logs_bus) == len(ref.decision_steps)
    assert open_buses() == before


@pytest.mark.slow
def test_episode_goes_on_when_an_agent_process_is_killed():
    from sensorplan.decentral import run_agents
    from sensorplan.decentral.bus import open_buses
    from sensorplan.simulation.scenario import paper_scenario
    from sensorplan.simulation import RunSettings

    before = {id(b) for b in open_buses()}
    killed = []

    def progress(t, S):
        if t == 4 and not killed:              # between decisions (every 2 steps)
            bus = next(b for b in open_buses() if id(b) not in before)
            killed.append(bus.pids[1])
            os.kill(bus.pids[1], signal.SIGKILL)

    settings = RunSettings(planner="dec-jsfp", horizon=2, steps_per_epoch=2, steps=12,
                           planner_params={"transport": "bus", "timeout": 3.0})
    start = time.monotonic()
    ep, logs = run_agents(paper_scenario(), settings, 6, progress)
    assert time.monotonic() - start < 120
    assert killed and wait_gone(killed) == []
    assert [log.failed for log in logs] == [()] * 2 + [(1,)] * 4
    # from the first decision after the kill (step 4) platform 1 holds still and looks at
    # nothing; the others keep planning and looking
    assert np.all(ep.looked[5:, 1] == -1)
    assert np.all(ep.sensor_positions[5:, 1] == ep.sensor_positions[4, 1])
    assert np.all(ep.looked[5:, [0, 2]] >= 0)
    assert {id(b) for b in open_buses()} <= before
