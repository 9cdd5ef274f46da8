"""Decentralized planning with search on: the agents plan track and sector looks against the
same undetected intensity, follow the centralized ``pg`` with search exactly over perfect
links, and reach pure Nash equilibria of Phi with search."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from factories import paper_problem, tiny_problem
from sensorplan.decentral import (AgentSpec, LinkModel, Message, assemble, decision_key,
                                  decode, encode, run_inproc)
from sensorplan.decentral.decision import decision_context, to_plan
from sensorplan.planners import make_planner, search
from sensorplan.planners.contract_problems import search_contract_problems, searching
from sensorplan.planners.problem import TIE_TOL, Plan, check_plan

DEC = ("dec-jsfp", "dec-independent", "dec-sequential")


def search_problems(seed: int) -> list:
    """The planner contract's searching problems and paper decisions with K = 2, 3 (6
    sectors, a 10 x 10 grid) in both visibility modes."""
    rng = np.random.default_rng(seed)
    out = [c.problem for c in search_contract_problems()]
    out += [searching(paper_problem(rng, horizon=h, visibility=v), rng, 6, cells=10)
            for h, v in ((2, "probabilistic"), (3, "mean"))]
    return out


def same_plan(a, b) -> bool:
    return (np.array_equal(a.plan.targets, b.plan.targets)
            and np.array_equal(a.plan.sectors, b.plan.sectors)
            and np.array_equal(a.plan.positions, b.plan.positions, equal_nan=True))


def assert_equilibrium(problem, plan: Plan) -> None:
    """No single player (i, k) raises Phi with search by another of its actions: every
    deviation's Phi recomputed by the reference definition (``search.potential``)."""
    phi = search.potential(problem, plan)[0]
    sctx = search.prepare(problem)
    for i in range(problem.n_sensors):
        for k in range(1, problem.horizon + 1):
            pos, tgt, sec = search.player_actions(sctx, plan, i, k)
            for a in range(len(tgt)):
                dev = search.with_action(plan, i, k, pos[a], int(tgt[a]), int(sec[a]))
                assert search.potential(problem, dev)[0] <= phi + TIE_TOL * max(1.0, abs(phi))


# ---------------------------------------------------------------------- equivalence
def test_lossless_jsfp_with_search_is_centralized_pg(monkeypatch):
    """Same seed, bit-identical plan (positions, targets, sectors), Phi, generator state,
    convergence and sweeps as pg with search; N K rounds of greedy start, one round per
    JSFP iteration of pg (counted from its utility calls) and the settling round."""
    calls = [0]
    real = search.candidate_potentials

    def counted(*args, **kw):
        calls[0] += 1
        return real(*args, **kw)

    for problem in search_problems(7):
        N, K = problem.n_sensors, problem.horizon
        for seed in range(2):
            g_pg, g_dec = np.random.default_rng(seed), np.random.default_rng(seed)
            calls[0] = 0
            with monkeypatch.context() as mp:
                mp.setattr(search, "candidate_potentials", counted)
                ref = make_planner("pg").plan(problem, rng=g_pg)
            iterations = (calls[0] - N * K) // N         # greedy start: N K calls, then N each
            got = make_planner("dec-jsfp").plan(problem, rng=g_dec)
            assert same_plan(ref, got)
            assert got.potential == ref.potential and got.found == ref.found
            assert g_pg.bit_generator.state == g_dec.bit_generator.state
            log = got.log
            assert log.rounds == N * K + iterations + 1
            assert log.converged == (ref.converged,) * N
            assert log.sweeps == (ref.sweeps,) * N
            assert log.stale == 0 and log.lost == 0 and log.completed == (0,) * N
            assert log.sent == log.delivered == log.rounds * N * (N - 1)


def test_lossless_jsfp_with_search_reaches_a_pure_nash_equilibrium():
    for problem in search_problems(8)[-3:]:
        got = make_planner("dec-jsfp").plan(problem, rng=1)
        assert got.log.converged == (True,) * problem.n_sensors
        check_plan(problem, got.plan)
        phi, info, mu = search.potential(problem, got.plan)
        np.testing.assert_allclose(got.potential, phi, rtol=1e-9)
        np.testing.assert_allclose(got.information, info, rtol=1e-9, atol=1e-12)
        assert_equilibrium(problem, got.plan)


def test_settled_best_response_with_search_is_an_equilibrium():
    """Best response ends when a round changes nothing: then every player is at a best
    response to the others' actual plans (perfect links)."""
    for problem in search_problems(9)[-2:]:
        got = make_planner("dec-jsfp", mode="best-response", rounds=50).plan(problem, rng=0)
        assert all(got.log.settled) and got.log.stale == 0
        assert_equilibrium(problem, got.plan)


def reference_sequential(problem, alone: bool = False) -> Plan:
    """Platform by platform, epoch by epoch, the action whose Phi with search (reference
    definition, one plan at a time) is highest, ties to the first; ``alone``: every agent
    as if the others were unassigned."""
    sctx = search.prepare(problem)
    joint = Plan.empty(problem.n_sensors, problem.horizon)
    for i in range(problem.n_sensors):
        plan = Plan.empty(problem.n_sensors, problem.horizon) if alone else joint
        for k in range(1, problem.horizon + 1):
            pos, tgt, sec = search.player_actions(sctx, plan, i, k)
            phi = np.array([search.evaluate(sctx, search.with_action(
                plan, i, k, pos[a], int(tgt[a]), int(sec[a]))).potential
                for a in range(len(tgt))])
            top = phi.max()
            a = int(np.flatnonzero(phi >= top - TIE_TOL * max(1.0, abs(top)))[0])
            plan = search.with_action(plan, i, k, pos[a], int(tgt[a]), int(sec[a]))
        pos_, tgt_, sec_ = (joint.positions.copy(), joint.targets.copy(),
                            joint.sectors.copy())  # type: ignore[union-attr]
        pos_[i], tgt_[i], sec_[i] = plan.positions[i], plan.targets[i], plan.sectors[i]
        joint = Plan(pos_, tgt_, sec_)
    return joint


@pytest.mark.parametrize("p_loss", [0.0, 1.0])
def test_sequential_with_search_is_platform_by_platform_greedy(p_loss):
    for problem in search_problems(12)[:5]:
        got = make_planner("dec-sequential", p_loss=p_loss).plan(problem)
        ref = reference_sequential(problem, alone=p_loss == 1.0)
        np.testing.assert_array_equal(got.plan.targets, ref.targets)
        np.testing.assert_array_equal(got.plan.sectors, ref.sectors)
        np.testing.assert_allclose(got.plan.positions, ref.positions, rtol=0, atol=1e-6)
        assert got.log.rounds == problem.n_sensors
        if problem.n_sensors == 1:
            assert same_plan(got, make_planner("sequential-greedy").plan(problem))


# ---------------------------------------------------------------------- links
@pytest.mark.parametrize("mode", ["jsfp", "best-response"])
def test_total_loss_with_search_is_independent(mode):
    for problem in search_problems(5)[-2:]:
        g_lost, g_ind = np.random.default_rng(3), np.random.default_rng(3)
        lost = make_planner("dec-jsfp", p_loss=1.0, mode=mode).plan(problem, rng=g_lost)
        ind = make_planner("dec-independent", mode=mode).plan(problem, rng=g_ind)
        assert same_plan(lost, ind)
        assert g_lost.bit_generator.state == g_ind.bit_generator.state
        assert lost.log.delivered == 0 and lost.log.lost == lost.log.sent > 0


def test_lossy_search_decisions_are_complete_and_repeat():
    problem = search_problems(6)[-1]
    kw = {"p_loss": 0.3, "delay": 1, "rounds": 40}
    a = make_planner("dec-jsfp", **kw).plan(problem, rng=4)
    b = make_planner("dec-jsfp", **kw).plan(problem, rng=4)
    check_plan(problem, a.plan)
    assert same_plan(a, b) and a.log == b.log and a.log.lost > 0
    np.testing.assert_allclose(a.potential, search.potential(problem, a.plan)[0], rtol=1e-9)


def test_short_budget_is_filled_in_alone_in_epoch_order():
    """One round: only agent 0 takes its greedy turn (epoch 1); every other player is
    filled in alone, k = 1..K (a search player moves from its previous epoch)."""
    problem = search_problems(10)[-1]
    got = make_planner("dec-jsfp", rounds=1).plan(problem, rng=0)
    check_plan(problem, got.plan)
    K = problem.horizon
    assert got.log.rounds == 1
    assert got.log.completed == (K - 1,) + (K,) * (problem.n_sensors - 1)


def test_lost_agent_holds_still_with_search():
    problem = search_problems(14)[-1]
    ctx = decision_context(problem)
    gen = np.random.default_rng(2)
    link = LinkModel(decision_key(gen), np.array(problem.positions), 0.0, 0, math.inf)
    out = run_inproc(ctx, AgentSpec("jsfp", rounds=200), link, gen, fail_at={1: 4})
    got = assemble(ctx, out, ())
    assert got.log.failed == (1,) and set(out) == {0, 2}
    assert got.sec is not None and np.all(got.sec[1] == -1) and np.all(got.tgt[1] == -1)
    plan = to_plan(ctx.ctx, got.pos, got.tgt, got.sec)
    check_plan(problem, plan, complete=False)
    assert np.all(np.isnan(plan.positions[1])) and plan.assigned[[0, 2]].all()


def test_search_message_roundtrip():
    pos = np.array([[120.0 + 1e-13, 80.5], [np.nan, np.nan], [140.25, 100.0]])
    m = Message(7, 12, 2, 3, 1, 4, True, False, pos, np.array([1, -1, -1]),
                (130.0 + 3e-14, 90.0, -1, 4), np.array([-1, -1, 2]))
    data = encode(m)
    assert len(data) == 27 + 24 * 3 + 24
    back = decode(data)
    assert back.searching and back.cond == m.cond
    np.testing.assert_array_equal(back.pos, pos)               # exact, NaN included
    np.testing.assert_array_equal(back.tgt, m.tgt)
    np.testing.assert_array_equal(back.sec, m.sec)
    after = back.looks_after(False)
    np.testing.assert_array_equal(after[0][0], m.cond[:2])
    assert (after[1][0], after[2][0]) == (-1, 4)
    bare = dataclasses.replace(m, cond=None)
    assert decode(encode(bare)).cond is None and len(encode(bare)) == 27 + 24 * 3
    with pytest.raises(ValueError):
        decode(data[:-1])


# ---------------------------------------------------------------------- search off
def test_search_off_problems_keep_the_track_agents():
    """A problem whose search is off is the track-only decision, message for message."""
    problem = tiny_problem(np.random.default_rng(3), 200)
    ctx = decision_context(problem)
    assert not hasattr(ctx, "sctx") and type(ctx).__name__ == "Context"
    got = make_planner("dec-jsfp").plan(problem, rng=0)
    assert got.found is None and not got.plan.searches


# ---------------------------------------------------------------------- closed loop
def searching_loop(planner: str, **params):
    from sensorplan.config import load_simulation

    cfg = load_simulation(preset="search", overrides={"search": "on", "steps": 5, "seed": 3,
                                                      "horizon": 2, "planner": planner})
    scenario = dataclasses.replace(cfg.scenario, initial_targets=0)
    return scenario, dataclasses.replace(cfg.settings, planner_params=params), cfg.seed


def test_lossless_jsfp_closed_loop_with_search_equals_pg():
    from sensorplan.decentral import run_agents
    from sensorplan.simulation.run import run_episode

    ref = run_episode(*searching_loop("pg"))
    got, logs = run_agents(*searching_loop("dec-jsfp"))
    assert (ref.searched >= 0).any()                  # the loop does search
    for name in ("truth", "sensor_positions", "sensor_headings", "looked", "searched",
                 "potential", "search_found", "search_term"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    assert len(logs) == len(ref.decision_steps) and all(log.stale == 0 for log in logs)


@pytest.mark.slow
def test_search_on_the_bus_equals_inproc():
    pytest.importorskip("zmq")
    from sensorplan.decentral.bus import Bus

    problem = search_problems(15)[-2]
    ctx = decision_context(problem)
    lossy = {"p_loss": 0.3, "delay": 1, "comm_range": 300.0}
    with Bus(problem.n_sensors) as bus:
        pids = bus.pids
        for n, (spec, kw) in enumerate([(AgentSpec("jsfp"), {}),
                                        (AgentSpec("jsfp", rounds=25), lossy),
                                        (AgentSpec("sequential"), lossy)]):
            gen = np.random.default_rng(n)
            link = LinkModel(decision_key(gen), np.array(problem.positions), **kw)
            ref = run_inproc(ctx, spec, link, gen)
            got, failed = bus.decide(problem, spec, link, gen)
            assert failed == set() and set(got) == set(ref)
            for i in ref:
                for name in ("pos", "tgt", "sec", "belief_pos", "belief_tgt", "belief_sec"):
                    np.testing.assert_array_equal(getattr(got[i], name), getattr(ref[i], name))
                assert (got[i].gen_state, got[i].trace, got[i].counts) == (
                    ref[i].gen_state, ref[i].trace, ref[i].counts)
            assert assemble(ctx, got, failed).log == assemble(ctx, ref, ()).log
    from test_decentral_bus import wait_gone

    assert wait_gone(pids) == []


@pytest.mark.parametrize("name", DEC)
def test_every_decentral_planner_declares_search(name):
    from sensorplan.planners import plans_search
    from sensorplan.planners.registry import planner_class

    assert plans_search(planner_class(name))


SCENARIO = """
look_detects = "all"
births = "edges"
birth_rate = 0.05
initial_targets = 0

[planning]
horizon = 2
search = "on"
search_sectors = 6

[tracker]
kind = "pmb"

[[targets]]
kind = "cv"

[[sensors]]
altitude = 490.0
position = [150.0, 150.0]
heading = 0.78

[[sensors]]
altitude = 510.0
position = [450.0, 450.0]
heading = -2.35
"""

SEARCH_STUDY = """
runs = 2
steps = 4
seed = 5
[scenario]
file = "scenario.toml"
[defaults]
horizon = 2
search = "on"
search_sectors = 6
[defaults.tracker]
kind = "pmb"
[[methods]]
name = "dec"
planner = "dec-jsfp"
[[methods]]
name = "lossy"
planner = "dec-jsfp"
planner_params = {p_loss = 0.3, rounds = 30}
[[methods]]
name = "central"
planner = "pg"
"""


@pytest.mark.slow
def test_search_study_is_the_same_for_any_number_of_workers(tmp_path):
    """Seeds belong to runs, not to workers: one worker or two give the same tables; with
    perfect links the agents' runs are pg's."""
    import pandas as pd

    from sensorplan import study as studies
    from sensorplan.study import parse_study

    (tmp_path / "scenario.toml").write_text(SCENARIO)
    study = parse_study(SEARCH_STUDY, base_dir=tmp_path)
    assert all(m.settings.search == "on" for m in study.methods)
    for workers in (1, 2):
        res = studies.run_study(study, tmp_path / str(workers), workers=workers)
        assert res.ran == res.total == 6
    one, two = (studies.load_study_dir(tmp_path / str(w)) for w in (1, 2))
    for name in studies.TABLES:
        a, b = getattr(one, name), getattr(two, name)
        if name == "decisions":
            a, b = a.drop(columns="planning_seconds"), b.drop(columns="planning_seconds")
        pd.testing.assert_frame_equal(a, b, check_exact=True, obj=name)
    sensors = one.sensors
    dec = sensors[sensors["method"] == "dec"].drop(columns="method").reset_index(drop=True)
    central = sensors[sensors["method"] == "central"].drop(columns="method").reset_index(
        drop=True)
    pd.testing.assert_frame_equal(dec, central, check_exact=True)
