"""Decentralized planning with the in-process transport: equivalence, links, faults."""

from __future__ import annotations

import math

import numpy as np
import pytest

import sensorplan.decentral as dec
from factories import paper_problem, tiny_problem
from sensorplan.decentral import (
                                  AgentSpec,
                                  InprocTransport,
                                  LinkModel,
                                  Message,
                                  assemble,
                                  decision_key,
                                  decode,
                                  encode,
                                  run_inproc,
                                  )
from sensorplan.errors import ConfigError
from sensorplan.planners.information import prepare
from sensorplan.planners import make_planner, potential_game
from sensorplan.planners.epoch_game import warm_engine
from sensorplan.planners.engine import GameState, choose
from sensorplan.planners.problem import TIE_TOL, check_plan

MODES = [(v, o) for v in ("probabilistic", "mean") for o in ("terminal", "cumulative")]
DEC = ("dec-jsfp", "dec-independent", "dec-sequential")


def problems(seed: int, visibility: str = "probabilistic", objective: str = "terminal"):
    """The planner-contract problems: four tiny ones and paper decisions with K = 2, 3."""
    rng = np.random.default_rng(seed)
    out = [tiny_problem(rng, max_plans=20_000, visibility=visibility, objective=objective)
           for _ in range(4)]
    out += [paper_problem(rng, horizon=h, visibility=visibility, objective=objective)
            for h in (2, 3)]
    return out


def same_plan(a, b) -> bool:
    return (np.array_equal(a.plan.targets, b.plan.targets)
            and np.array_equal(a.plan.positions, b.plan.positions, equal_nan=True))


def decide(problem, spec: AgentSpec, seed: int = 0, p_loss: float = 0.0, delay: int = 0,
           comm_range: float = math.inf, **kw):
    """One in-process decision; returns (assembled result, outcomes)."""
    ctx = prepare(problem)
    gen = np.random.default_rng(seed)
    link = LinkModel(decision_key(gen), np.array(problem.positions), p_loss, delay, comm_range)
    out = run_inproc(ctx, spec, link, gen, **kw)
    return assemble(ctx, out, set(range(ctx.N)) - set(out)), out


# ---------------------------------------------------------------------- equivalence
@pytest.mark.parametrize("visibility,objective", MODES)
def test_lossless_jsfp_is_centralized_pg(visibility, objective, monkeypatch):
    """Same seed, bit-identical plan, same generator state afterwards, one round per
    JSFP iteration of pg (counted by instrumenting pg's epoch loop) plus the round in which
    the agents announce they are settled."""
    iterations = []
    warm_engine()          # its tiny warm-up game would otherwise be counted as pg's
    epoch = potential_game.jsfp_epoch

    def counted(*args, **kw):
        for state in epoch(*args, **kw):
            iterations[-1] += 1
            yield state

    monkeypatch.setattr(potential_game, "jsfp_epoch", counted)
    for problem in problems(7, visibility, objective):
        for seed in range(3):
            g_pg, g_dec = np.random.default_rng(seed), np.random.default_rng(seed)
            iterations.append(0)
            ref = make_planner("pg").plan(problem, rng=g_pg)
            got = make_planner("dec-jsfp").plan(problem, rng=g_dec)
            assert same_plan(ref, got)
            assert got.potential == ref.potential
            assert g_pg.bit_generator.state == g_dec.bit_generator.state
            log = got.log
            assert log.rounds == iterations[-1] + 1
            assert log.converged == (ref.converged,) * problem.n_sensors
            assert log.sweeps == (ref.sweeps,) * problem.n_sensors
            assert log.stale == 0 and log.lost == 0 and log.completed == (0,) * problem.n_sensors
            n = problem.n_sensors
            assert log.sent == log.delivered == log.received == log.rounds * n * (n - 1)


def test_lossless_jsfp_closed_loop_equals_pg():
    from sensorplan.simulation.scenario import paper_scenario
    from sensorplan.simulation import RunSettings, run_episode

    sc = paper_scenario()
    kw = {"horizon": 2, "steps_per_epoch": 2, "steps": 10}
    ref = run_episode(sc, RunSettings(planner="pg", **kw), 3)
    with dec.recording() as logs:
        got = run_episode(sc, RunSettings(planner="dec-jsfp", **kw), 3)
    for name in ("truth", "estimate", "cov", "sensor_positions", "sensor_headings", "looked",
                 "potential"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    assert len(logs) == len(ref.decision_steps) == 5
    assert all(log.lost == 0 and log.stale == 0 for log in logs)


def test_too_few_rounds_is_not_pg_but_complete():
    """The budget binds: fewer rounds than pg's iterations, yet every player is assigned."""
    problem = paper_problem(np.random.default_rng(1), horizon=3)
    ref = make_planner("pg").plan(problem, rng=0)
    got = make_planner("dec-jsfp", rounds=1).plan(problem, rng=0)
    check_plan(problem, got.plan)
    assert got.log.rounds == 1
    # one round assigns epoch K only; epochs K-1..1 are filled in alone
    assert got.log.completed == (2, 2, 2)
    assert got.potential <= ref.potential + 1e-9 * ref.potential


# ---------------------------------------------------------------------- contract
# The planner contract (tests/planners/test_planner_contract.py) covers every dec-* planner.
@pytest.mark.parametrize("name", ["dec-jsfp", "dec-independent"])
def test_best_response_mode_contract(name):
    problem = paper_problem(np.random.default_rng(4), horizon=3)
    got = make_planner(name, mode="best-response").plan(problem, rng=2)
    check_plan(problem, got.plan)
    again = make_planner(name, mode="best-response").plan(problem, rng=2)
    assert same_plan(got, again) and got.log == again.log


# ---------------------------------------------------------------------- independent
@pytest.mark.parametrize("mode", ["jsfp", "best-response"])
def test_independent_agents_never_touch_the_transport(mode):
    problem = paper_problem(np.random.default_rng(2), horizon=2)
    for communicate in (False, True):
        net = InprocTransport()
        got, _ = decide(problem, AgentSpec(mode, communicate=communicate), transport=net)
        if communicate:          # the instrument works: talking agents do use it
            assert sum(net.reads.values()) > 0 and sum(net.sends.values()) > 0
        else:
            assert not net.reads and not net.sends
            assert got.log.sent == got.log.received == got.log.delivered == 0


@pytest.mark.parametrize("mode", ["jsfp", "best-response"])
def test_total_loss_is_independent(mode):
    for problem in problems(5)[2:]:
        for seed in (0, 1):
            g_lost, g_ind = np.random.default_rng(seed), np.random.default_rng(seed)
            lost = make_planner("dec-jsfp", p_loss=1.0, mode=mode).plan(problem, rng=g_lost)
            ind = make_planner("dec-independent", mode=mode).plan(problem, rng=g_ind)
            assert same_plan(lost, ind)
            assert g_lost.bit_generator.state == g_ind.bit_generator.state
            assert lost.log.lost == lost.log.sent and lost.log.delivered == 0
            assert (lost.log.sent > 0) == (problem.n_sensors > 1)


def test_independent_agent_sees_only_itself():
    """Each independent agent's plan is a best response with every other platform
    unassigned: no single-player change of its own raises Phi of its plan alone."""
    problem = paper_problem(np.random.default_rng(8), horizon=2)
    _, out = decide(problem, AgentSpec("best-response", communicate=False))
    ctx = prepare(problem)
    for i, o in out.items():
        assert np.all(o.belief_tgt[np.arange(ctx.N) != i] == -1)
        state = GameState(ctx)
        state.pos[i], state.tgt[i] = o.pos, o.tgt
        state.refresh(i)
        phi = state.potential()
        for k in range(1, ctx.K + 1):
            pos, tgt = state.player_actions(i, k)
            alt = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
            assert alt.max() <= phi + TIE_TOL * max(1.0, phi)


# ---------------------------------------------------------------------- links
def test_seeded_loss_gives_the_same_run_twice_and_seeds_matter():
    problem = paper_problem(np.random.default_rng(3), horizon=3)
    logs = []
    for seed in range(4):
        a = make_planner("dec-jsfp", p_loss=0.3, delay=1, rounds=40).plan(problem, rng=seed)
        b = make_planner("dec-jsfp", p_loss=0.3, delay=1, rounds=40).plan(problem, rng=seed)
        assert same_plan(a, b) and a.log == b.log and a.potential == b.potential
        logs.append((a.log.lost, a.log.delivered))
        check_plan(problem, a.plan)
    assert len(set(logs)) > 1


def test_loss_draw_is_keyed_not_ordered():
    link = LinkModel((1, 2, 3), np.zeros((3, 2)), p_loss=0.3)
    keys = [(r, s, d) for r in range(1, 400) for s in range(3) for d in range(3) if s != d]
    forward = [link.lost(*k) for k in keys]
    backward = [link.lost(*k) for k in reversed(keys)][::-1]
    assert forward == backward
    # Bernoulli(0.3) over 2394 draws: 4 standard deviations is 0.037
    assert abs(np.mean(forward) - 0.3) < 4 * math.sqrt(0.3 * 0.7 / len(keys))
    other = LinkModel((1, 2, 4), np.zeros((3, 2)), p_loss=0.3)
    assert forward != [other.lost(*k) for k in keys]
    rounds = range(1, 200)             # every part of the key matters
    draws = {(s, d): [link.lost(r, s, d) for r in rounds] for s, d in [(0, 1), (0, 2), (1, 0)]}
    assert draws[0, 1] != draws[0, 2] and draws[0, 1] != draws[1, 0]


def test_delay_longer_than_the_budget_is_independent():
    """Nothing sent can arrive within the budget, so agents play as if alone."""
    problem = paper_problem(np.random.default_rng(6), horizon=2)
    for rounds in (3, 6):
        late = make_planner("dec-jsfp", delay=rounds, rounds=rounds).plan(problem, rng=1)
        ind = make_planner("dec-independent", rounds=rounds).plan(problem, rng=1)
        assert same_plan(late, ind)
        n = problem.n_sensors
        assert late.log.delivered == 0 and late.log.in_flight == late.log.sent > 0
        assert late.log.sent == late.log.rounds * n * (n - 1)


def test_delay_delivers_after_the_given_rounds(monkeypatch):
    """A message sent in round r is first believed at the end of round r + delay."""
    problem = paper_problem(np.random.default_rng(6), horizon=2)
    seen: dict[tuple[int, int, int], int] = {}

    class Spy(dec.Agent):
        def end_round(self, rnd, delivered):
            for m in delivered:
                seen.setdefault((self.i, m.sender, m.round), rnd)
            super().end_round(rnd, delivered)

    monkeypatch.setattr(dec.decision, "Agent", Spy)
    for delay in (0, 1, 2):
        seen.clear()
        got, _ = decide(problem, AgentSpec("jsfp", rounds=8), delay=delay)
        assert seen and all(r == sent + delay for (_, _, sent), r in seen.items())
        n = problem.n_sensors
        assert got.log.in_flight == min(delay, got.log.rounds) * n * (n - 1)


def test_range_cuts_links():
    problem = paper_problem(np.random.default_rng(9), horizon=2)
    d = np.linalg.norm(problem.positions[:, None] - problem.positions[None], axis=-1)
    close = d[np.triu_indices(3, 1)].min()
    far = make_planner("dec-jsfp", comm_range=close / 2).plan(problem, rng=0)
    ind = make_planner("dec-independent").plan(problem, rng=0)
    assert same_plan(far, ind) and far.log.out_of_range == far.log.sent
    # a range covering every pair is a perfect link
    full = make_planner("dec-jsfp", comm_range=float(d.max()) + 1.0).plan(problem, rng=0)
    assert same_plan(full, make_planner("pg").plan(problem, rng=0))
    # one pair in range: each message counts iff its pair is within range
    mid = float(np.sort(d[np.triu_indices(3, 1)])[0]) + 1e-6
    some = make_planner("dec-jsfp", comm_range=mid).plan(problem, rng=0)
    assert some.log.out_of_range == some.log.rounds * 4          # 2 of 3 pairs cut


def test_duplicated_and_late_messages_change_nothing():
    """A transport that delivers every message twice and replays old rounds' messages
    gives the same plans; the extras are counted as ignored."""

    class Noisy(InprocTransport):
        def __init__(self):
            super().__init__()
            self.history: list[tuple[int, bytes, list[int]]] = []

        def send(self, sender, data, to):
            to = list(to)
            n = super().send(sender, data, to)
            super().send(sender, data, to)                   # duplicate
            for old_sender, old, old_to in self.history[-6:-3]:   # replay rounds back
                super().send(old_sender, old, [j for j in old_to if j in to or j == sender])
            self.history.append((sender, data, to))
            return n

    problem = paper_problem(np.random.default_rng(10), horizon=3)
    for kw in ({}, {"p_loss": 0.3, "delay": 1}):
        spec = AgentSpec("jsfp", rounds=60)
        clean, _ = decide(problem, spec, seed=4, **kw)
        noisy, _ = decide(problem, spec, seed=4, transport=Noisy(), **kw)
        np.testing.assert_array_equal(clean.pos, noisy.pos)
        np.testing.assert_array_equal(clean.tgt, noisy.tgt)
        assert noisy.log.ignored > clean.log.ignored
        assert noisy.log.delivered == clean.log.delivered


def test_announced_switches_are_void_at_an_equilibrium():
    """In a round where every player is at a best response the epoch game ends and nobody
    switches: garbling the announced actions of such rounds changes nothing."""
    import dataclasses

    class Garble(InprocTransport):
        garbled = 0

        def receive(self, me):
            msgs = [decode(d) for q in self.queues.values() for d in q]
            eq_round = msgs and all(m.best and m.cond is not None for m in msgs) and len(
                {(m.round, m.sweep, m.epoch, m.iteration) for m in msgs}) == 1
            if eq_round:
                for j, q in self.queues.items():
                    out = []
                    for d in q:
                        m = decode(d)
                        tgt = (m.cond[1] + 1) % problem.n_targets
                        out.append(encode(dataclasses.replace(m, cond=(m.cond[0], tgt))))
                        Garble.garbled += 1
                    self.queues[j] = out
            return super().receive(me)

    problem = paper_problem(np.random.default_rng(15), horizon=3)
    spec = AgentSpec("jsfp")
    clean, _ = decide(problem, spec, seed=3)
    garbled, _ = decide(problem, spec, seed=3, transport=Garble())
    assert Garble.garbled > 0
    np.testing.assert_array_equal(clean.tgt, garbled.tgt)
    assert garbled.log.stale == 0


def test_agent_ignores_duplicates_and_older_rounds():
    problem = paper_problem(np.random.default_rng(11), horizon=2)
    ctx = prepare(problem)
    gen = np.random.default_rng(0)
    agent = dec.Agent(ctx, 0, AgentSpec("best-response"), gen)
    K = ctx.K
    plan_new = (np.zeros(K, dtype=np.int64), np.zeros(K, dtype=np.int64))
    plan_old = (np.zeros(K, dtype=np.int64), np.ones(K, dtype=np.int64))
    new = Message(0, 3, 1, 0, 0, 0, False, True, *plan_new)
    old = Message(0, 2, 1, 0, 0, 0, False, True, *plan_old)
    agent.step(3)
    agent.end_round(3, [new, new])
    agent.step(4)
    agent.end_round(4, [old])
    np.testing.assert_array_equal(agent.view.tgt[1], plan_new[1])
    assert agent.ignored == 2


def test_message_roundtrip():
    m = Message(7, 12, 2, 3, 1, 4, True, False, np.array([3, -1, 0]), np.array([1, -1, 2]),
                (5, 1))
    back = decode(encode(m))
    assert (back.decision, back.round, back.sender, back.sweep, back.epoch, back.iteration,
            back.settled, back.best, back.cond) == (7, 12, 2, 3, 1, 4, True, False, (5, 1))
    np.testing.assert_array_equal(back.pos, m.pos)
    np.testing.assert_array_equal(back.tgt, m.tgt)
    assert decode(encode(Message(0, 1, 0, 0, 0, 0, False, True, m.pos, m.tgt))).cond is None
    with pytest.raises(ValueError):
        decode(encode(m)[:-1])


# ---------------------------------------------------------------------- sequential
def reference_sequential(problem):
    """Platform by platform, epoch by epoch, the Phi-maximising action (second computation
    with the engine's evaluation only)."""
    ctx = prepare(problem)
    state = GameState(ctx)
    for i in range(ctx.N):
        for k in range(1, ctx.K + 1):
            pos, tgt = state.player_actions(i, k)
            phi = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
            best = choose(phi)
            state.set_action(i, k, int(pos[best]), int(tgt[best]))
    return state


def test_sequential_is_platform_by_platform_greedy():
    for problem in problems(12):
        got = make_planner("dec-sequential").plan(problem)
        ref = reference_sequential(problem)
        np.testing.assert_array_equal(got.plan.targets, ref.tgt)
        assert got.log.rounds == problem.n_sensors
        if problem.n_sensors == 1:
            assert same_plan(got, make_planner("sequential-greedy").plan(problem))


def test_sequential_with_total_loss_is_everyone_first():
    problem = paper_problem(np.random.default_rng(13), horizon=2)
    got = make_planner("dec-sequential", p_loss=1.0).plan(problem)
    ctx = prepare(problem)
    for i in range(ctx.N):       # each agent decides as if it were the only one
        alone = GameState(ctx)
        for k in range(1, ctx.K + 1):
            pos, tgt = alone.player_actions(i, k)
            best = choose(alone.evaluate_chains(i, k, pos[:, None], tgt[:, None]))
            alone.set_action(i, k, int(pos[best]), int(tgt[best]))
        np.testing.assert_array_equal(got.plan.targets[i], alone.tgt[i])


# ---------------------------------------------------------------------- faults
def test_lost_agent_holds_still_and_others_finish():
    problem = paper_problem(np.random.default_rng(14), horizon=3)
    spec = AgentSpec("jsfp", rounds=200)
    got, out = decide(problem, spec, seed=2, fail_at={1: 4})
    again, _ = decide(problem, spec, seed=2, fail_at={1: 4})
    assert got.log == again.log
    assert got.log.failed == (1,) and set(out) == {0, 2}
    assert np.all(got.tgt[1] == -1)
    assert np.all(got.tgt[[0, 2]] >= 0)
    for o in out.values():
        assert np.all(o.belief_tgt[1] == -1) and o.failed == (1,)
    ctx = prepare(problem)
    plan = dec.decision.to_plan(ctx, got.pos, got.tgt)
    check_plan(problem, plan, complete=False)
    assert np.all(np.isnan(plan.positions[1]))


# ---------------------------------------------------------------------- settings
@pytest.mark.parametrize("name,params,field", [
    ("dec-jsfp", {"p_loss": -0.1}, "planner.p_loss"),
    ("dec-jsfp", {"p_loss": 1.5}, "planner.p_loss"),
    ("dec-jsfp", {"p_loss": math.nan}, "planner.p_loss"),
    ("dec-sequential", {"p_loss": 2}, "planner.p_loss"),
    ("dec-jsfp", {"rounds": 0}, "planner.rounds"),
    ("dec-jsfp", {"rounds": 2.5}, "planner.rounds"),
    ("dec-independent", {"rounds": -3}, "planner.rounds"),
    ("dec-jsfp", {"delay": -1}, "planner.delay"),
    ("dec-jsfp", {"delay": 1.5}, "planner.delay"),
    ("dec-jsfp", {"comm_range": -5.0}, "planner.comm_range"),
    ("dec-jsfp", {"comm_range": 0.0}, "planner.comm_range"),
    ("dec-sequential", {"comm_range": -1}, "planner.comm_range"),
    ("dec-jsfp", {"mode": "gossip"}, "planner.mode"),
    ("dec-independent", {"mode": "sequential"}, "planner.mode"),
    ("dec-jsfp", {"transport": "carrier-pigeon"}, "planner.transport"),
    ("dec-sequential", {"transport": "mqtt"}, "planner.transport"),
    ("dec-jsfp", {"timeout": 0}, "planner.timeout"),
    ("dec-jsfp", {"alpha": 1.0}, "planner.alpha"),
])
def test_bad_settings_name_the_field(name, params, field):
    with pytest.raises(ConfigError) as err:
        make_planner(name, **params)
    assert err.value.field == field


def test_good_edge_settings_are_accepted():
    make_planner("dec-jsfp", p_loss=0, delay=0, rounds=1, comm_range=math.inf)
    make_planner("dec-jsfp", p_loss=1.0, comm_range=1e-3, mode="best-response")
