"""Targets weighted by their probability of existence r: Phi = sum_j r_j term_j.

The weighting is checked against a second computation written here (the per-target recursion
in information form with explicit matrices, each term times r), as a potential (a unilateral
change moves the player's utility as it moves Phi), by its scaling, by the exact no-op of
r = 1 for every planner, and by what r = 0 means for a planner's choice.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from factories import lattice_problem, paper_problem, tiny_problem
from sensorplan.errors import ConfigError
from sensorplan.models.sensors import SensorParams
from sensorplan.planners import PLANNERS, make_planner
from sensorplan.planners.brute_force import BruteForcePlanner
from sensorplan.planners.contract_problems import contract_problems, weighted
from sensorplan.planners.engine import GameState
from sensorplan.planners.epoch_game import EpochGame
from sensorplan.planners.information import (Context, phi_terms, plan_information, potential,
                                             prepare)
from sensorplan.planners.problem import MapRect, Plan, PlanningProblem, move_vectors


def with_existence(problem: PlanningProblem, r) -> PlanningProblem:
    return dataclasses.replace(problem, existence=np.asarray(r, dtype=float))


def random_weights(rng: np.random.Generator, M: int) -> np.ndarray:
    """Uniform in [0, 1] with some exact 0s and 1s."""
    r = rng.uniform(0.0, 1.0, M)
    r[rng.random(M) < 0.2] = 0.0
    r[rng.random(M) < 0.2] = 1.0
    return r


def second_phi(problem: PlanningProblem, plan: Plan,
               ctx: Context | None = None) -> tuple[float, np.ndarray]:
    """Weighted Phi written out: the looks' information from the library (the radar model is
    tested on its own), then per target the covariance-only recursion in information form
    with the SPEC matrices, ``P <- (P^-1 + G^T W G)^-1``, and the term times r."""
    ctx = prepare(problem) if ctx is None else ctx
    W, _, _ = plan_information(ctx, plan)                              # (N, K, e, 2, 2)
    dt, q, e = problem.dt, float(problem.process_noise), problem.steps_per_epoch
    F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)
    a, b = dt**3 / 3, dt**2 / 2
    Q = q * np.array([[a, 0, b, 0], [0, a, 0, b], [b, 0, dt, 0], [0, b, 0, dt]])
    G = np.eye(4)[:2]
    T = problem.n_steps
    terms = np.zeros(problem.n_targets)
    for j in range(problem.n_targets):
        Wj = np.zeros((T, 2, 2))
        for i, k in itertools.product(range(problem.n_sensors), range(problem.horizon)):
            if plan.targets[i, k] == j:
                Wj[k * e:(k + 1) * e] += W[i, k]
        if not Wj.any():
            continue                                   # never measured: exactly 0
        Pb = P = np.array(problem.covs[j])
        gains = []
        for t in range(T):
            Pb, P = F @ Pb @ F.T + Q, F @ P @ F.T + Q
            P = np.linalg.inv(np.linalg.inv(P) + G.T @ Wj[t] @ G)
            gains.append(0.5 * (np.linalg.slogdet(Pb)[1] - np.linalg.slogdet(P)[1]))
        info = sum(gains) if problem.objective == "cumulative" else gains[-1]
        terms[j] = problem.existence[j] * info
    return float(terms.sum()), terms


def every_plan(problem: PlanningProblem):
    """Every complete joint plan, enumerated with an in-map test written here."""
    K, M = problem.horizon, problem.n_targets
    W, H = problem.world.width, problem.world.height
    options = []
    for i in range(problem.n_sensors):
        moves = move_vectors(problem.sensors[i].moves)
        chains = []
        for seq in itertools.product(range(len(moves)), repeat=K):
            path = problem.positions[i] + np.cumsum(moves[list(seq)], axis=0)
            if np.all((path >= -1e-6) & (path <= np.array([W, H]) + 1e-6)):
                chains.append(path)
        options.append([(c, np.array(s)) for c in chains
                        for s in itertools.product(range(M), repeat=K)])
    for combo in itertools.product(*options):
        yield Plan(np.stack([c for c, _ in combo]), np.stack([s for _, s in combo]))


# ------------------------------------------------------------------- the definition


@pytest.mark.parametrize("seed", range(6))
def test_potential_equals_the_weighted_second_computation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    objective = ("terminal", "cumulative")[seed % 2]
    problem = paper_problem(rng, horizon=2, objective=objective,
                            visibility=("probabilistic", "mean")[(seed // 2) % 2])
    problem = with_existence(problem, random_weights(rng, problem.n_targets))
    for s in range(3):
        plan = make_planner("random").plan(problem, rng=s).plan
        phi, info = potential(problem, plan)
        want_phi, want = second_phi(problem, plan)
        np.testing.assert_allclose(info, want, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(phi, want_phi, rtol=1e-9, atol=1e-9)
        assert np.all(info[problem.existence == 0.0] == 0.0)


@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
def test_half_weights_halve_phi_and_every_utility(objective: str) -> None:
    rng = np.random.default_rng(5)
    problem = paper_problem(rng, horizon=3, objective=objective)
    half = with_existence(problem, np.full(problem.n_targets, 0.5))
    for s in range(4):
        plan = make_planner("random").plan(problem, rng=s).plan
        phi, info = potential(problem, plan)
        phi_h, info_h = potential(half, plan)
        np.testing.assert_allclose(phi_h, 0.5 * phi, rtol=1e-12, atol=0.0)
        np.testing.assert_allclose(info_h, 0.5 * info, rtol=1e-12, atol=0.0)
        assert phi > 0.0
        # The compiled engine's utilities (the planners' numbers) scale the same way.
        state, state_h = (GameState.from_plan(prepare(p), plan) for p in (problem, half))
        for i, k in ((0, 1), (problem.n_sensors - 1, problem.horizon)):
            pos, tgt = state.player_actions(i, k)
            u = state.chain_gains(i, k, pos[:, None], tgt[:, None], with_base=True)
            u_h = state_h.chain_gains(i, k, pos[:, None], tgt[:, None], with_base=True)
            np.testing.assert_allclose(u_h[0], 0.5 * u[0], rtol=1e-12, atol=0.0)
            np.testing.assert_allclose(u_h[1], 0.5 * u[1], rtol=1e-12, atol=0.0)


def test_phi_terms_multiply_each_term_by_its_weight(rng: np.random.Generator) -> None:
    M, T = 5, 4
    ld_bar = rng.normal(size=(M, T + 1))
    ld_end = ld_bar[:, -1] - rng.uniform(0.0, 2.0, M)
    ld_sum = ld_bar[:, 1:].sum(axis=1) - rng.uniform(0.0, 5.0, M)
    measured = np.array([True, True, False, True, True])
    r = np.array([0.0, 0.25, 0.5, 1.0, 0.8])
    for cumulative in (False, True):
        plain = phi_terms(ld_bar, ld_end, ld_sum, cumulative, measured)
        got = phi_terms(ld_bar, ld_end, ld_sum, cumulative, measured, r)
        np.testing.assert_array_equal(got, r * plain)
        assert got[0] == 0.0 and got[2] == 0.0
        np.testing.assert_array_equal(
            phi_terms(ld_bar, ld_end, ld_sum, cumulative, measured, np.ones(M)), plain)


# -------------------------------------------------------------------- the potential


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_utility_differences_equal_weighted_phi_differences(seed: int) -> None:
    """Exact potential with random weights: for a unilateral change of player (i, k) its
    utility moves as Phi does (to round-off: the engine and the definition are two
    computations)."""
    rng = np.random.default_rng(seed)
    problem = tiny_problem(rng, max_plans=10**12, objective=("terminal", "cumulative")[seed % 2])
    problem = with_existence(problem, random_weights(rng, problem.n_targets))
    plan = make_planner("random").plan(problem, rng=seed).plan
    state = GameState.from_plan(prepare(problem), plan)
    i = int(rng.integers(problem.n_sensors))
    k = int(rng.integers(1, problem.horizon + 1))
    pos, tgt = state.player_actions(i, k)
    utilities = state.evaluate_chains(i, k, pos[:, None], tgt[:, None])
    base = potential(problem, plan)[0]
    cur = np.flatnonzero((pos == state.pos[i, k - 1]) & (tgt == state.tgt[i, k - 1]))[0]
    for c in rng.choice(len(pos), size=min(8, len(pos)), replace=False):
        xy = state.xy(i, k, pos[c])
        p, t = plan.positions.copy(), plan.targets.copy()
        p[i, k - 1], t[i, k - 1] = xy, int(tgt[c])
        delta_phi = potential(problem, Plan(p, t))[0] - base
        np.testing.assert_allclose(utilities[c] - utilities[cur], delta_phi,
                                   rtol=1e-9, atol=1e-9 * max(1.0, abs(base)))


@pytest.mark.parametrize("seed", range(4))
def test_weighted_engine_utilities_equal_the_plain_computation_bit_for_bit(seed: int) -> None:
    """With weights, both compiled paths (one player's candidates, a whole epoch game) give
    exactly the utilities of the dense reference computation, weighted there."""
    from engine_reference import dense_gains

    rng = np.random.default_rng(40 + seed)
    problem = paper_problem(rng, horizon=3, n_sensors=4, n_targets=6,
                            objective=("terminal", "cumulative")[seed % 2],
                            visibility=("probabilistic", "mean")[seed // 2])
    problem = with_existence(problem, random_weights(rng, problem.n_targets))
    plan = make_planner("random").plan(problem, rng=seed).plan
    state = GameState.from_plan(prepare(problem), plan)
    k = int(rng.integers(1, problem.horizon + 1))
    for i in range(problem.n_sensors):
        pos, tgt = state.player_actions(i, k)
        np.testing.assert_array_equal(
            state.copy().chain_gains(i, k, pos[:, None], tgt[:, None])[0],
            dense_gains(state, i, k, pos[:, None], tgt[:, None]))
    game = EpochGame(state, k)
    try:
        u = game.split(game.utilities())
        for i in range(problem.n_sensors):
            pos, tgt = game.actions[i]
            np.testing.assert_array_equal(u[i], dense_gains(state, i, k, pos[:, None],
                                                            tgt[:, None]))
    finally:
        game.close()


# ------------------------------------------------------------------- the planners


@pytest.mark.parametrize("case", range(4))
def test_brute_force_finds_the_best_weighted_plan(case: int) -> None:
    """Brute force against every joint plan evaluated by the second computation."""
    objective = ("terminal", "cumulative")[case % 2]
    N, M, K = ((2, 3, 1), (1, 3, 2))[case // 2]
    problem = lattice_problem(200 + case, n_sensors=N, n_targets=M, horizon=K,
                              objective=objective, size=60.0)
    rng = np.random.default_rng(case)
    problem = with_existence(problem, [0.0, rng.uniform(0.05, 0.95), 1.0])
    ctx = prepare(problem)
    values = [second_phi(problem, plan, ctx)[0] for plan in every_plan(problem)]
    best = max(values)
    assert best > 0.0, "degenerate test problem: nothing is ever seen"
    result = BruteForcePlanner().plan(problem)
    np.testing.assert_allclose(result.potential, best, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(second_phi(problem, result.plan)[0], best, rtol=1e-9, atol=0.0)
    # Weights at most 1 never raise Phi, and here they change the best value.
    plain = BruteForcePlanner().plan(dataclasses.replace(problem, existence=None))
    assert plain.potential > result.potential


#: The planners that choose by Phi (brute force on a tiny problem), and two with a time
#: budget (the anytime path).
DETERMINISTIC = [(name, {}) for name in ("pg", "pg-refine", "sequential-greedy", "brute-force",
                                          "dec-jsfp", "dec-sequential", "dec-independent")]
DETERMINISTIC += [("pg", {"time_budget": 60.0}), ("sequential-greedy", {"time_budget": 60.0})]


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_unit_weights_change_no_bit(name: str) -> None:
    """r = 1 everywhere (what the ``known`` tracker reports) gives the plan, Phi, terms and
    trace of a problem without weights, bit for bit."""
    cases = [c for c in contract_problems() if c.tiny and "weighted" not in c.label][::3]
    if name != "brute-force":
        cases += [c for c in contract_problems() if not c.tiny][:2]
    for case in cases:
        ones = with_existence(case.problem, np.ones(case.problem.n_targets))
        a = make_planner(name).plan(case.problem, rng=3)
        b = make_planner(name).plan(ones, rng=3)
        np.testing.assert_array_equal(a.plan.targets, b.plan.targets, err_msg=case.label)
        np.testing.assert_array_equal(a.plan.positions, b.plan.positions, err_msg=case.label)
        assert a.potential == b.potential, case.label
        np.testing.assert_array_equal(a.information, b.information, err_msg=case.label)
        assert a.trace == b.trace and a.converged == b.converged, case.label


def twin_targets(n_sensors: int, horizon: int) -> PlanningProblem:
    """Two targets with the same mean and covariance, every sensor seeing them at once: any
    look at one is worth exactly what the same look at the other is."""
    mean = [400.0, 400.0, 2.0, -1.0]
    cov = np.diag([400.0, 400.0, 4.0, 4.0])
    angles = 2 * math.pi * np.arange(n_sensors) / n_sensors
    pos = 400.0 + 350.0 * np.c_[np.cos(angles), np.sin(angles)]
    return PlanningProblem(np.array([mean, mean]), np.array([cov, cov]), pos,
                           angles + math.pi, tuple(SensorParams() for _ in angles),
                           horizon=horizon, world=MapRect(800.0, 800.0))


@pytest.mark.parametrize(("name", "params"), DETERMINISTIC)
@pytest.mark.parametrize("r1", [0.3, 1.0])
def test_a_target_with_r_0_is_never_preferred(name: str, params: dict, r1: float) -> None:
    """Twin targets, the first with r = 0: every look that counts goes to the second, and the
    first's term is exactly 0. (Without weights some look goes to the first: the tie rule
    prefers the lower index, and a second target is worth more than a second look.)"""
    N, K = (1, 2) if name == "brute-force" else (3, 2)
    problem = twin_targets(N, K)
    twins = make_planner(name, **params).plan(problem, rng=0)
    assert np.any(twins.plan.targets[twins.measurements > 0] == 0)
    result = make_planner(name, **params).plan(with_existence(problem, [0.0, r1]), rng=0)
    looks = result.measurements > 0
    assert looks.any()
    assert np.all(result.plan.targets[looks] == 1)
    assert result.information[0] == 0.0 and result.information[1] > 0.0


def test_an_r_0_target_adds_nothing_to_phi(rng: np.random.Generator) -> None:
    problem = paper_problem(rng, horizon=2)
    r = np.ones(problem.n_targets)
    r[2] = 0.0
    zero = with_existence(problem, r)
    for s in range(4):
        plan = make_planner("random").plan(problem, rng=s).plan
        phi, info = potential(problem, plan)
        phi0, info0 = potential(zero, plan)
        assert info0[2] == 0.0
        np.testing.assert_array_equal(np.delete(info0, 2), np.delete(info, 2))
        np.testing.assert_allclose(phi0, phi - info[2], rtol=1e-12)


def test_the_contract_problems_include_weighted_ones() -> None:
    cases = [c for c in contract_problems() if "weighted" in c.label]
    assert any(c.tiny for c in cases) and any(not c.tiny for c in cases)
    for c in cases:
        r = c.problem.existence
        assert r.min() == 0.0 and r.max() == 1.0 and np.any((r > 0) & (r < 1))
    other = weighted(tiny_problem(np.random.default_rng(1)), np.random.default_rng(2))
    assert other.existence.min() == 0.0


# ------------------------------------------------------------------ validation


@pytest.mark.parametrize(("r", "field"), [
    ([0.5], "targets.existence"), ([[0.5, 0.5]], "targets.existence"),
    ([0.5, np.nan], "targets[1].existence"), ([np.inf, 0.5], "targets[0].existence"),
    ([1.5, 0.5], "targets[0].existence"), ([0.5, -1e-9], "targets[1].existence")])
def test_bad_existence_names_the_field(r, field: str) -> None:
    problem = twin_targets(1, 1)
    with pytest.raises(ConfigError) as err:
        with_existence(problem, r)
    assert err.value.field == field


def test_existence_defaults_to_ones_and_is_read_only() -> None:
    problem = twin_targets(1, 1)
    np.testing.assert_array_equal(problem.existence, [1.0, 1.0])
    r = np.array([0.2, 0.7])
    given_r = with_existence(problem, r)
    r[0] = 0.9                                          # the problem keeps its own copy
    np.testing.assert_array_equal(given_r.existence, [0.2, 0.7])
    with pytest.raises(ValueError):
        given_r.existence[0] = 0.5
