"""Game facts of the planners: equilibria, the exact potential, quality against the optimum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.planners.information import potential, prepare
from sensorplan.planners import make_planner
from sensorplan.planners.engine import GameState
from sensorplan.planners.potential_game import jsfp_epoch
from sensorplan.planners.problem import TIE_TOL, MapRect, Plan, PlanningProblem, check_plan
from sensorplan.models.sensors import SensorParams

from factories import paper_problem, tiny_problem


def _with_action(plan: Plan, i: int, k: int, xy, j: int) -> Plan:
    pos, tgt = plan.positions.copy(), plan.targets.copy()
    pos[i, k - 1], tgt[i, k - 1] = xy, j
    return Plan(pos, tgt)


def _feasible_actions(problem, plan, i, k):
    """Every action of player (i, k) enumerated from scratch (no engine code)."""
    ctx = prepare(problem)
    lat = ctx.lattices[i]
    out = []
    for xy in lat.positions[k]:
        for j in range(problem.n_targets):
            candidate = _with_action(plan, i, k, xy, j)
            try:
                check_plan(problem, candidate)
            except ValueError:
                continue
            out.append(candidate)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_converged_pg_plan_is_a_pure_nash_equilibrium(seed):
    rng = np.random.default_rng(100 + seed)
    problem = tiny_problem(rng, max_plans=10**9) if seed % 2 else paper_problem(rng, horizon=2)
    result = make_planner("pg").plan(problem, rng=seed)
    assert result.converged
    phi = potential(problem, result.plan)[0]
    tol = TIE_TOL * max(1.0, abs(phi))
    for i in range(problem.n_sensors):
        for k in range(1, problem.horizon + 1):
            for deviation in _feasible_actions(problem, result.plan, i, k):
                assert potential(problem, deviation)[0] <= phi + tol


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_batched_utilities_equal_the_potential_of_each_deviation(seed):
    """Exact potential: a unilateral change moves the player's utility exactly as Phi."""
    rng = np.random.default_rng(seed)
    problem = tiny_problem(rng, max_plans=10**12, objective=("terminal", "cumulative")[seed % 2])
    plan = make_planner("random").plan(problem, rng=seed).plan
    state = GameState.from_plan(prepare(problem), plan)
    i = int(rng.integers(problem.n_sensors))
    k = int(rng.integers(1, problem.horizon + 1))
    pos, tgt = state.player_actions(i, k)
    utilities = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
    base = potential(problem, plan)[0]
    cur = np.flatnonzero((pos == state.pos[i, k - 1]) & (tgt == state.tgt[i, k - 1]))[0]
    for c in rng.choice(len(pos), size=min(6, len(pos)), replace=False):
        deviation = _with_action(plan, i, k, state.xy(i, k, pos[c]), int(tgt[c]))
        delta_phi = potential(problem, deviation)[0] - base
        np.testing.assert_allclose(utilities[c] - utilities[cur], delta_phi,
                                   rtol=1e-9, atol=1e-9 * max(1.0, abs(base)))


def test_jsfp_running_average_and_exit():
    problem = paper_problem(np.random.default_rng(4), horizon=2)
    state = GameState(prepare(problem))
    history = []
    for it in jsfp_epoch(state, 2, np.random.default_rng(0), 0.3, 0.999, 50):
        history.append(it)
    assert history[-1].equilibrium                         # ended at a Nash point
    for n, it in enumerate(history[:-1], start=1):         # ubar = mean of past utilities
        for i in range(problem.n_sensors):
            mean = np.mean([h.utilities[i] for h in history[:n]], axis=0)
            np.testing.assert_allclose(it.averages[i], mean, rtol=1e-12, atol=1e-12)


def _quality_rows(n_problems: int):
    rng = np.random.default_rng(2024)
    rows = []
    for s in range(n_problems):
        problem = tiny_problem(rng)
        opt = make_planner("brute-force").plan(problem).potential
        res = {name: make_planner(name).plan(problem, rng=s)
               for name in ("pg", "pg-refine", "sequential-greedy")}
        ratio = {n: (r.potential / opt if opt > 1e-12 else 1.0) for n, r in res.items()}
        rows.append((ratio, res))
    return rows


def test_quality_against_the_exact_optimum_on_200_tiny_problems():
    rows = _quality_rows(200)
    pg = np.array([r["pg"] for r, _ in rows])
    refine = np.array([r["pg-refine"] for r, _ in rows])
    assert pg.mean() >= 0.95
    assert np.mean([res["pg"].converged for _, res in rows]) >= 0.99
    assert refine.mean() >= 0.99
    assert np.mean(refine >= 0.95) >= 0.97
    for _, res in rows:
        floor = max(res["pg"].potential, res["sequential-greedy"].potential)
        assert res["pg-refine"].potential >= floor - TIE_TOL * max(1.0, floor)
        assert res["pg-refine"].converged


def _hole_problem(target_xy, sensor_xy=(300.0, 300.0), heading=0.0, horizon=1,
                  visibility="mean"):
    cov = np.diag([25.0, 25.0, 1.0, 1.0])
    return PlanningProblem(np.array([[*target_xy, 0.0, 0.0]]), cov[None], np.array([sensor_xy]),
                           np.array([heading]), (SensorParams(),), horizon=horizon,
                           visibility=visibility)


def test_sensor_hole_nothing_visible_gives_zero_and_a_valid_plan():
    # Right under the sensor: inside the blind disc from everywhere reachable in one epoch.
    problem = _hole_problem((300.0, 300.0))
    for name in ("pg", "pg-refine", "sequential-greedy", "brute-force", "random"):
        result = make_planner(name).plan(problem)
        check_plan(problem, result.plan)
        assert result.potential == 0.0


def test_target_visible_only_after_two_moves_needs_lookahead():
    # Ground range 250 - 40 * 2 ... the target sits 170 m away: inside the blind disc (250 m)
    # until the sensor has backed off 80 m, i.e. two 40 m moves.
    problem2 = _hole_problem((470.0, 300.0), heading=0.0, horizon=2)
    problem1 = _hole_problem((470.0, 300.0), heading=0.0, horizon=1)
    assert make_planner("brute-force").plan(problem1).potential == 0.0
    assert make_planner("pg").plan(problem1).potential == 0.0
    r2 = make_planner("pg").plan(problem2)
    assert r2.potential > 0.0
    np.testing.assert_allclose(r2.potential, make_planner("brute-force").plan(problem2).potential,
                               rtol=1e-9)
    # the first epoch already moves away from the target (lookahead), to x = 260
    assert r2.plan.positions[0, 0, 0] < 300.0


@pytest.mark.parametrize("horizon", [1, 8])
@pytest.mark.parametrize("corner", [(0.0, 0.0), (600.0, 600.0), (0.0, 600.0)])
def test_corner_start_one_sensor_one_target(horizon, corner):
    problem = PlanningProblem(np.array([[300.0, 300.0, 2.0, -1.0]]),
                              np.diag([400.0, 400.0, 4.0, 4.0])[None], np.array([corner]),
                              np.array([math.pi / 4]), (SensorParams(),), horizon=horizon,
                              world=MapRect())
    for name in ("pg", "pg-refine", "sequential-greedy", "random"):
        result = make_planner(name).plan(problem, rng=0)
        check_plan(problem, result.plan)
        assert np.all(problem.world.contains(result.plan.positions))
    assert make_planner("pg").plan(problem).converged


@pytest.mark.parametrize("seed", range(8))
def test_engine_utilities_equal_the_plain_computation_bit_for_bit(seed):
    """The epoch-game kernel (shared baselines, cached terms, dirty lists) and the per-player
    kernel give exactly the utilities of the plain dense computation, also after switches."""
    from sensorplan.planners.epoch_game import EpochGame

    from engine_reference import dense_gains

    rng = np.random.default_rng(seed)
    objective = ("terminal", "cumulative")[seed % 2]
    visibility = ("probabilistic", "mean")[(seed // 2) % 2]
    if seed < 4:
        problem = paper_problem(rng, horizon=3, n_sensors=4, n_targets=6,
                                visibility=visibility, objective=objective)
    else:
        problem = tiny_problem(rng, max_plans=10**12, visibility=visibility,
                               objective=objective)
    plan = make_planner("random").plan(problem, rng=seed).plan
    state = GameState.from_plan(prepare(problem), plan)
    k = int(rng.integers(1, problem.horizon + 1))
    for i in range(problem.n_sensors):
        # Every candidate (duplicates of earlier candidates included) by the per-player path.
        pos, tgt = state.player_actions(i, k)
        np.testing.assert_array_equal(state.copy().chain_gains(i, k, pos[:, None],
                                                               tgt[:, None])[0],
                                      dense_gains(state, i, k, pos[:, None], tgt[:, None]))
        # Make some current actions duplicates (kept only as the current action).
        entry = state.copy()._game_pairs(i, k, state.player_positions(i, k),
                                          state.action_token(i, k))
        if entry.dups.size and rng.random() < 0.7:
            c = int(entry.dups[rng.integers(entry.dups.size)])
            state.set_action(i, k, int(pos[c]), int(tgt[c]))
    game = EpochGame(state, k)
    for _ in range(3):
        u = game.split(game.utilities())
        for i in range(problem.n_sensors):
            pos, tgt = game.actions[i]
            np.testing.assert_array_equal(u[i], dense_gains(state, i, k, pos[:, None],
                                                            tgt[:, None]))
            fresh = state.copy()
            np.testing.assert_array_equal(
                fresh.chain_gains(i, k, pos[:, None], tgt[:, None])[0], u[i])
        for i in range(problem.n_sensors):            # some players switch
            if rng.random() < 0.6:
                pos, tgt = game.actions[i]
                c = int(rng.integers(len(pos)))
                state.set_action(i, k, int(pos[c]), int(tgt[c]))
                game.cur[i] = c
