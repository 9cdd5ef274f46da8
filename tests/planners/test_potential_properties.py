"""Invariants of the potential on small random problems (hypothesis)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.models.motion import predict_covariance
from sensorplan.planners.information import (evaluate, information_update, plan_information,
                                             potential, prepare, sum_by_target)
from sensorplan.planners.problem import TIE_TOL, Plan, check_plan, move_vectors
from sensorplan.models.sensors import SensorParams

SETTINGS = settings(max_examples=60, deadline=None)
# Phi and its terms are non-negative up to round-off of the log-determinants.
ROUND = 1e-12


@st.composite
def problems(draw, min_sensors=1):
    """(problem kwargs, seed) for factories.make_problem."""
    kw = dict(n_sensors=draw(st.integers(min_sensors, 3)), n_targets=draw(st.integers(1, 3)),
              horizon=draw(st.integers(1, 3)), steps_per_epoch=draw(st.integers(1, 2)),
              visibility=draw(st.sampled_from(["probabilistic", "mean"])),
              objective=draw(st.sampled_from(["terminal", "cumulative"])),
              vary_sensors=draw(st.booleans()),
              moves=draw(st.sampled_from([(20.0, 40.0), (20.0,), (30.0,)])))
    return kw, draw(st.integers(0, 2**32 - 1))


def tol(phi: float) -> float:
    return TIE_TOL * max(1.0, abs(phi))


@SETTINGS
@given(problems(), st.sampled_from([0.0, 0.3, 0.7]))
def test_potential_is_nonnegative_and_sums_its_terms(problem_factory, plan_factory, case, p_un):
    kw, seed = case
    rng = np.random.default_rng(seed)
    pr = problem_factory(rng, **kw)
    plan = plan_factory(pr, rng, p_unassigned=p_un)
    phi, info = potential(pr, plan)
    assert np.all(np.isfinite(info))
    assert phi >= -ROUND
    assert np.all(info >= -ROUND)
    assert math.isclose(phi, float(info.sum()), rel_tol=1e-12, abs_tol=1e-15)
    assert info.shape == (pr.n_targets,)


def _assignable(plan: Plan) -> list[tuple[int, int]]:
    """Unassigned players whose assignment changes no other player's heading."""
    a = plan.assigned
    N, K = a.shape
    return [(i, k) for i in range(N) for k in range(K)
            if not a[i, k] and (k == K - 1 or not a[i, k + 1])]


@SETTINGS
@given(problems(), st.data())
def test_assigning_an_unassigned_player_never_lowers_phi(problem_factory, plan_factory, case,
                                                         data):
    kw, seed = case
    rng = np.random.default_rng(seed)
    pr = problem_factory(rng, **kw)
    plan = plan_factory(pr, rng, p_unassigned=0.5)
    free = _assignable(plan)
    if not free:
        plan = Plan.empty(pr.n_sensors, pr.horizon)
        free = _assignable(plan)
    i, k = free[data.draw(st.integers(0, len(free) - 1))]
    mv = move_vectors(pr.sensors[i].moves)
    if k == 0 or plan.assigned[i, k - 1]:
        start, steps = (pr.positions[i] if k == 0 else plan.positions[i, k - 1]), 1
    else:  # after an unassigned epoch any point of R_k will do: walk k + 1 moves from p_0
        start, steps = pr.positions[i], k + 1
    p = np.array(start, dtype=float)
    for _ in range(steps):
        cand = p + mv
        ok = np.flatnonzero(pr.world.contains(cand))
        p = cand[ok[data.draw(st.integers(0, len(ok) - 1))]]
    positions = plan.positions.copy()
    targets = plan.targets.copy()
    positions[i, k] = p
    targets[i, k] = data.draw(st.integers(0, pr.n_targets - 1))
    more = Plan(positions, targets)
    check_plan(pr, more, complete=False)
    phi0, info0 = potential(pr, plan)
    phi1, info1 = potential(pr, more)
    assert phi1 >= phi0 - tol(phi0)
    assert np.all(info1 >= info0 - 1e-9 * np.maximum(1.0, np.abs(info0)))
    # only the looked-at target's term can change
    others = np.arange(pr.n_targets) != targets[i, k]
    np.testing.assert_allclose(info1[others], info0[others], rtol=1e-12, atol=1e-12)
    # other players' headings are untouched
    h0 = evaluate(prepare(pr), plan).headings
    h1 = evaluate(prepare(pr), more).headings
    np.testing.assert_array_equal(h1[plan.assigned], h0[plan.assigned])


@SETTINGS
@given(problems(), st.integers(0, 2**32 - 1), st.booleans())
def test_adding_a_sensor_never_lowers_phi(problem_factory, plan_factory, case, seed2, idle):
    kw, seed = case
    rng = np.random.default_rng(seed)
    pr = problem_factory(rng, **kw)
    plan = plan_factory(pr, rng, p_unassigned=0.3)
    r2 = np.random.default_rng(seed2)
    # The new sensor looks from near a random target, toward it.
    j = int(r2.integers(pr.n_targets))
    b = r2.uniform(-math.pi, math.pi)
    new_xy = np.clip(pr.means[j, :2] - r2.uniform(280, 420) * np.array([math.cos(b), math.sin(b)]),
                     0.0, [pr.world.width, pr.world.height])
    bigger = dataclasses.replace(
        pr, positions=np.vstack([pr.positions, new_xy]),
        headings=np.append(pr.headings, b + r2.uniform(-0.3, 0.3)),
        sensors=pr.sensors + (SensorParams(altitude=float(r2.choice([490.0, 500.0, 510.0]))),))
    extra = (Plan.empty(1, pr.horizon) if idle
             else plan_factory(dataclasses.replace(
                 bigger, positions=bigger.positions[-1:], headings=bigger.headings[-1:],
                 sensors=bigger.sensors[-1:]), r2, p_unassigned=0.2))
    plan2 = Plan(np.concatenate([plan.positions, extra.positions]),
                 np.concatenate([plan.targets, extra.targets]))
    check_plan(bigger, plan2, complete=False)
    phi0, info0 = potential(pr, plan)
    phi1, info1 = potential(bigger, plan2)
    if idle:
        np.testing.assert_allclose(info1, info0, rtol=1e-12, atol=1e-14)
    assert phi1 >= phi0 - tol(phi0)
    assert np.all(info1 >= info0 - 1e-9 * np.maximum(1.0, np.abs(info0)))


@SETTINGS
@given(problems(), st.sampled_from([0.0, 0.3]))
def test_covariances_stay_positive_definite_and_below_the_prior(problem_factory, plan_factory,
                                                                case, p_un):
    kw, seed = case
    rng = np.random.default_rng(seed)
    pr = problem_factory(rng, **kw)
    plan = plan_factory(pr, rng, p_unassigned=p_un)
    ctx = prepare(pr)
    W, _, _ = plan_information(ctx, plan)
    Wt = sum_by_target(ctx, W, plan.targets)
    assert np.all(np.linalg.eigvalsh(Wt) >= -1e-12 * np.abs(Wt).max(initial=1.0))
    P = np.array(pr.covs)
    for t in range(ctx.T):
        P = predict_covariance(P, ctx.F, ctx.Q)
        P, gain = information_update(P, Wt[:, t])
        assert np.all(gain >= 0)
        np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
        np.linalg.cholesky(P)
        # measurements only shrink: Pbar(t) - P is positive semidefinite
        gap = np.linalg.eigvalsh(ctx.Pbar[:, t + 1] - P)
        assert np.all(gap >= -1e-9 * np.abs(ctx.Pbar[:, t + 1]).max())
