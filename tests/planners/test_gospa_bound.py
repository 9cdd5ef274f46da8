"""The GOSPA-bound reward: closed forms, the batched form against the reference, an
independent computation of the expected bound, the potential property, brute force against
an independent enumeration, the planners, and the default left bit-identical."""

from __future__ import annotations

import dataclasses
import itertools
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import search_problems
from search_problems import SWERLING, grid, sector_plan, swerling_pd
from sensorplan.errors import ConfigError
from sensorplan.models import radar
from sensorplan.models.sensors import SensorParams
from sensorplan.planners import gospa_bound, search
from sensorplan.planners.checks import check_result
from sensorplan.planners.information import epoch_information
from sensorplan.planners.problem import Plan, PlanningProblem, UndetectedIntensity, check_plan
from sensorplan.planners.registry import make_planner
from sensorplan.simulation.settings import RunSettings

def problem(positions: list[tuple[float, float]], headings: list[float], u: UndetectedIntensity,
            *args: Any, objective: str = "terminal", c: float = 50.0,
            **kwargs: Any) -> PlanningProblem:
    """:func:`search_problems.problem` with the GOSPA-bound reward at cut-off ``c``."""
    return search_problems.problem(positions, headings, u, *args, objective=objective,
                                   reward="gospa", gospa_c=c, **kwargs)


def mixed_problem(horizon: int = 2, objective: str = "cumulative", steps_per_epoch: int = 1,
                  c: float = 50.0, reported: list[bool] | None = None,
                  find_tail: int = 0, track_existence: str = "fixed") -> PlanningProblem:
    """Two sensors, two moving tracks (r = 0.6 and 1; ``reported`` by default) and a 6 x 6
    grid with births; finds counted ``find_tail`` steps after the horizon."""
    xs = 37.3 + 91.0 * np.arange(6)
    centres = [(x, y) for y in xs for x in xs]
    rng = np.random.default_rng(7)
    u = grid(centres, list(rng.uniform(0.01, 0.1, len(centres))), 0.002, 0.97)
    return problem([(300.0, 300.0), (60.0, 520.0)], [0.3, -1.0], u, sectors=6,
                   horizon=horizon, sensor=SensorParams(moves=(20.0,)), existence=[0.6, 1.0],
                   means=[[120.0, 90.0, 2.0, 1.0], [480.0, 420.0, -1.0, 0.5]],
                   steps_per_epoch=steps_per_epoch, objective=objective, c=c,
                   reported=None if reported is None else np.array(reported),
                   find_tail=find_tail, track_existence=track_existence)


def expected_bound(prob: PlanningProblem, plan: Plan | None) -> float:
    """The expected GOSPA bound summed over the steps (``cumulative``) or at the last one,
    from scratch: each track's ``r min(tr P, c^2) + (1 - r) c^2 / 2`` by the information form
    of the Kalman update (an explicit inverse), and the undetected and found targets as two
    pools that survive alike, the found ones costing their first detection's bound; a track
    not reported is two such pools of its own (mass r), seen by the looks at its predicted
    mean alone. The pools go on ``find_tail`` steps after the horizon without a look, those
    steps counted too. With ``track_existence = "resolved"`` a reported track whose looks
    all miss it through step t has its existence by Bayes' rule and costs the smaller of
    reported and not (its localisation taken without a look, capped at c^2/2), a detected
    one as before. ``plan None``: no look at all."""
    c2 = prob.gospa_c ** 2
    sctx = search.prepare(prob)
    ctx = sctx.ctx
    T, e, M = ctx.T, ctx.e, ctx.M
    W = np.zeros((M, T, 2, 2))
    miss = np.ones((prob.horizon, len(sctx.centres)))
    miss_track = np.ones((M, T))
    if plan is not None:
        headings = search.plan_headings(sctx, plan)
        for i, k in itertools.product(range(prob.n_sensors), range(1, prob.horizon + 1)):
            if not plan.assigned[i, k - 1]:
                continue
            xy, th, j = plan.positions[i, k - 1], headings[i, k - 1], int(plan.targets[i, k - 1])
            if j >= 0:
                w, _ = epoch_information(ctx, i, k, xy[None], np.array([th]), np.array([j]))
                W[j, (k - 1) * e:k * e] += w[0]
            miss[k - 1] *= 1.0 - search.detection(sctx, i, xy[None], np.array([th]))[0]
            for j, t in itertools.product(range(M), range((k - 1) * e, k * e)):
                # The track's predicted mean as the one cell of a grid of its own.
                at = SimpleNamespace(ctx=ctx, centres=ctx.xbar[j, t + 1, :2][None],
                                     bearings=sctx.bearings)
                miss_track[j, t] *= 1.0 - search.detection(at, i, xy[None], np.array([th]))[0, 0]
    Cf = np.linalg.inv(np.linalg.inv(np.asarray(prob.undetected.cell_cov)) + first_detection(
        ctx, prob))
    h = min(float(np.trace(Cf)), c2)
    L = prob.find_tail
    miss = np.vstack([miss, np.ones((-(-L // e), miss.shape[1]))])
    miss_track = np.hstack([miss_track, np.ones((M, L))])
    per_step = np.zeros(T)
    pools = np.zeros(T + L)
    u = prob.undetected
    for j in range(M):
        P, r = np.asarray(prob.covs[j], dtype=float), float(prob.existence[j])
        if prob.reported is not None and not prob.reported[j]:
            missed, found_j = r, 0.0
            for t in range(T + L):
                missed = u.survival * missed
                found_j = u.survival * found_j + missed * (1.0 - miss_track[j, t])
                missed = missed * miss_track[j, t]
                pools[t] += c2 / 2 * missed + min(h, c2 / 2) * found_j
            continue
        Pbar = P
        for t in range(T):
            P = ctx.F @ P @ ctx.F.T + ctx.Q_rows(j)[0]
            G = np.zeros((4, 4))
            G[:2, :2] = W[j, t]
            P = np.linalg.inv(np.linalg.inv(P) + G)
            per_step[t] += r * min(P[0, 0] + P[1, 1], c2) + (1.0 - r) * c2 / 2
            Pbar = ctx.F @ Pbar @ ctx.F.T + ctx.Q_rows(j)[0]
            if prob.track_existence == "resolved":
                # The no-detection branch: reported as a linear bound would have it, or the
                # better of reported and not under its posterior existence.
                rt, q = r * u.survival ** (t + 1), float(np.prod(miss_track[j, :t + 1]))
                loc = min(Pbar[0, 0] + Pbar[1, 1], c2 / 2)
                kept = rt * q + (1.0 - rt)
                post = rt * q / kept
                linear = kept * (post * loc + (1.0 - post) * c2 / 2)
                best = kept * min(post * loc + (1.0 - post) * c2 / 2, post * c2 / 2)
                per_step[t] -= linear - best
    undetected, found = np.array(u.weights, dtype=float), np.zeros(len(u.weights))
    for t in range(T + L):
        undetected = u.survival * undetected + u.births
        found = u.survival * found + undetected * (1.0 - miss[t // e])
        undetected = undetected * miss[t // e]
        # A found target's bound beats a missed one's only if its track is good enough.
        pools[t] += c2 / 2 * undetected.sum() + min(h, c2 / 2) * found.sum()
    if prob.objective == "cumulative":
        return float(per_step.sum() + pools.sum())
    return float(per_step[-1] + pools[T - 1:].sum())


def first_detection(ctx: object, prob: PlanningProblem) -> np.ndarray:
    """The position information of one detection on sensor 0's boresight at mid band."""
    s = prob.sensors[0]
    C = np.asarray(prob.undetected.cell_cov)
    mid = 0.5 * (s.min_ground_range + s.max_ground_range)
    W, p = radar.look_information(ctx.radar[0], np.array([mid]), np.array([0.0]),  # type: ignore[attr-defined]
                                  np.array([0.0]), np.array([[C[0, 0], C[0, 1], C[1, 1]]]),
                                  True, ctx.buildings, np.zeros((1, 2)))  # type: ignore[attr-defined]
    return np.asarray(W[0] / p[0])


def independent_phi(prob: PlanningProblem, plan: Plan) -> float:
    return expected_bound(prob, None) - expected_bound(prob, plan)


# ------------------------------------------------------------------ closed forms


@pytest.mark.parametrize("survival", [1.0, 0.9])
@pytest.mark.parametrize("tail", [0, 1, 7])
def test_step_weights_are_the_survival_sums(survival: float, tail: int) -> None:
    """A find at step s counts at each later step it is alive: at T (terminal) or from s
    to T (cumulative), and at T + 1..T + tail."""
    T = 5
    terminal = gospa_bound.step_weights(survival, T, False, tail)
    cumulative = gospa_bound.step_weights(survival, T, True, tail)
    after = range(T + 1, T + tail + 1)
    for s in range(1, T + 1):
        assert terminal[s - 1] == pytest.approx(
            sum(survival ** (t - s) for t in [T, *after]), rel=1e-14)
        assert cumulative[s - 1] == pytest.approx(
            sum(survival ** (t - s) for t in [*range(s, T + 1), *after]), rel=1e-14)


def test_a_found_targets_value_is_the_missed_cost_less_its_first_detections_bound() -> None:
    prob = mixed_problem()
    sctx = search.prepare(prob)
    assert sctx.gospa is not None
    W = first_detection(sctx.ctx, prob)
    C = np.asarray(prob.undetected.cell_cov)
    Cf = np.linalg.inv(np.linalg.inv(C) + W)
    np.testing.assert_allclose(gospa_bound.found_covariance(sctx), Cf, rtol=1e-12)
    assert sctx.gospa.found_value == pytest.approx(50.0 ** 2 / 2 - np.trace(Cf), rel=1e-12)
    # The same detection fixes the information reward's w.
    assert search.first_detection_weight(sctx.ctx, C) == pytest.approx(
        0.5 * np.linalg.slogdet(np.eye(2) + W @ C)[1], rel=1e-12)
    # A cut-off below the detection's spread: a find is worth nothing, not a loss.
    small = dataclasses.replace(prob, gospa_c=0.5 * math.sqrt(np.trace(Cf)))
    assert search.prepare(small).gospa.found_value == 0.0  # type: ignore[union-attr]


@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
def test_one_cell_one_look_finds_its_share_of_the_bound(objective: str) -> None:
    # The cell lies on sector 0's boresight at 350 m; three epochs, survival and births.
    pS, b, d0, K = 0.9, 0.02, 0.7, 3
    prob = problem([(100.0, 300.0)], [0.0], grid([(450.0, 300.0)], d0, b, pS), horizon=K,
                   objective=objective)
    P = swerling_pd(SWERLING, 350.0)
    D, f = d0, []
    for _ in range(K):
        D = pS * D + b
        f.append(D * P)
        D *= 1.0 - P
    g = search.prepare(prob).gospa.found_value  # type: ignore[union-attr]
    alive = [sum(f[s] * pS ** (t - s) for s in range(t + 1)) for t in range(K)]
    want = g * (sum(alive) if objective == "cumulative" else alive[-1])
    ev = search.evaluate(search.prepare(prob), sector_plan(prob, [[0] * K]))
    assert ev.potential == pytest.approx(want, rel=1e-12)
    assert ev.found == pytest.approx(sum(f), rel=1e-12)
    assert ev.information.tolist() == [0.0]                 # r = 0: no track term
    assert ev.potential == pytest.approx(ev.weight * ev.found, rel=1e-12)


@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
@pytest.mark.parametrize("c", [50.0, 9.0, 12.0])
@pytest.mark.parametrize("reported", [None, [False, True]])
@pytest.mark.parametrize("tail", [0, 3])
@pytest.mark.parametrize("existence", ["fixed", "resolved"])
def test_phi_is_the_expected_bound_the_plan_removes(objective: str, c: float,
                                                     reported: list[bool] | None,
                                                     tail: int, existence: str) -> None:
    """Against the bound computed from scratch (tracks by explicit inverses, the found and
    undetected targets as pools, a resolved track's existence by Bayes' rule): with c = 9
    every track is clipped at c^2 before a look."""
    for e in (1, 2):
        prob = mixed_problem(objective=objective, steps_per_epoch=e, c=c, reported=reported,
                             find_tail=tail, track_existence=existence)
        sctx = search.prepare(prob)
        for seed in range(3):
            plan = search.random_plan(sctx, np.random.default_rng(seed))
            want = independent_phi(prob, plan)
            got = search.evaluate(sctx, plan)
            assert got.potential == pytest.approx(want, rel=1e-9, abs=1e-9)
            assert got.potential == pytest.approx(got.information.sum()
                                                  + got.weight * got.found, rel=1e-12)
            assert got.potential >= 0.0 and np.all(got.information >= 0.0)


@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
def test_a_track_not_reported_is_found_not_localised(objective: str) -> None:
    """Ideal detection, one sensor, one still track (r = 0.3) on sector 0's boresight at
    350 m and no undetected targets: looking there finds it with probability r p_S (then
    r p_S^2, ...), each find worth g; looking away is worth nothing; reported, the same look
    is worth r times its covariance's bound reduction instead."""
    pS, r, K = 0.9, 0.3, 2
    u = grid([(20.0, 20.0)], 0.0, 0.0, pS)
    kw = dict(sectors=2, horizon=K, sensor=SensorParams(), existence=r,
              means=[[450.0, 300.0, 0.0, 0.0]], objective=objective)
    hidden = problem([(100.0, 300.0)], [0.0], u, reported=np.array([False]), **kw)
    sctx = search.prepare(hidden)
    g = sctx.gospa.found_value  # type: ignore[union-attr]
    toward = search.evaluate(sctx, sector_plan(hidden, [[0] * K]))
    # Found at step 1 with probability r p_S, alive at step 2 with p_S more.
    want = g * r * pS * (pS + 1.0 if objective == "cumulative" else pS)
    assert toward.potential == pytest.approx(want, rel=1e-12)
    assert toward.found == pytest.approx(r * pS, rel=1e-12)
    assert toward.information[0] == 0.0
    assert search.evaluate(sctx, sector_plan(hidden, [[1] * K])).potential == 0.0
    shown = dataclasses.replace(hidden, reported=np.array([True]))
    seen = search.evaluate(search.prepare(shown), sector_plan(shown, [[0] * K]))
    assert seen.found == 0.0 and seen.potential == pytest.approx(seen.information[0])


@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
def test_a_look_that_surely_detects_a_track_resolves_its_false_track_cost(
        objective: str) -> None:
    """Ideal detection, one sensor, one still reported track (r = 0.9) on sector 0's
    boresight: with its existence resolved, a look there tells for sure whether it exists,
    so beyond its localisation it removes the false-track cost (1 - r_t) c^2/2 of each step
    counted (r_t = r p_S^t); looking away is still worth nothing."""
    pS, r, K, c = 0.9, 0.9, 2, 50.0
    u = grid([(20.0, 20.0)], 0.0, 0.0, pS)
    kw = dict(sectors=2, horizon=K, sensor=SensorParams(), existence=r,
              means=[[450.0, 300.0, 0.0, 0.0]], objective=objective, c=c)
    fixed = problem([(100.0, 300.0)], [0.0], u, **kw)
    resolved = dataclasses.replace(fixed, track_existence="resolved")
    look, away = sector_plan(fixed, [[0] * K]), sector_plan(fixed, [[1] * K])
    base = search.evaluate(search.prepare(fixed), look).potential
    sctx = search.prepare(resolved)
    # Reported is the better decision without a look: E(1) = 0 at both steps.
    assert np.all(sctx.gospa.resolved_cost < c * c / 2 * (1 - 0.19 / 0.81))  # type: ignore[union-attr]
    stakes = [(1.0 - r * pS ** t) * c * c / 2 for t in (1, 2)]
    want = sum(stakes) if objective == "cumulative" else stakes[-1]
    got = search.evaluate(sctx, look)
    assert got.potential - base == pytest.approx(want, rel=1e-12)
    assert got.information[0] - base == pytest.approx(want, rel=1e-12)
    assert search.evaluate(sctx, away).potential == 0.0


def test_resolved_existence_values_most_the_tracks_near_the_report_point() -> None:
    """One look of detection probability p at a reported track: the existence term is
    E(1 - p) - E(1), E(Q) = max(0, (1 - r) c^2/2 - r Q (c^2/2 - L)): 0 for a sure track and
    for one a miss leaves reported, largest near the point where reporting stops paying."""
    c2, L, p = 2500.0, 100.0, 0.65
    gctx = SimpleNamespace(c2=c2, cumulative=False)
    terms = []
    for r in (1.0, 0.95, 0.8, 0.6, 0.52):
        gctx.resolved_existence = np.array([[r]])
        gctx.resolved_cost = np.array([[L]])
        got = float(gospa_bound._existence_terms(gctx, np.array([[1.0 - p]]))[0])  # type: ignore[arg-type]
        stake, gain = (1 - r) * c2 / 2, r * (c2 / 2 - L)
        assert got == pytest.approx(max(0.0, stake - (1 - p) * gain) - max(0.0, stake - gain),
                                    rel=1e-12, abs=1e-12)
        terms.append(got)
    assert terms[0] == 0.0 and terms[1] == 0.0 and terms[2] == 0.0
    assert 0.0 < terms[3] < terms[4]


def test_reported_flags_are_checked() -> None:
    prob = mixed_problem()
    with pytest.raises(ConfigError) as err:
        dataclasses.replace(prob, reported=np.array([False]))
    assert err.value.field == "targets.reported"
    with pytest.raises(ConfigError) as err:
        dataclasses.replace(prob, reported=np.array([1, 0]))
    assert err.value.field == "targets.reported"
    info = dataclasses.replace(prob, reward="information")
    with pytest.raises(ConfigError) as err:
        dataclasses.replace(info, reported=np.array([True, False]))
    assert err.value.field == "targets[1].reported"
    assert dataclasses.replace(info, reported=np.array([True, True])).reported is None


# ------------------------------------------------------------------ batched and potential


@pytest.mark.parametrize("objective,e", [("terminal", 1), ("cumulative", 1),
                                         ("cumulative", 2), ("terminal", 2)])
@pytest.mark.parametrize("reported,tail,existence", [
    (None, 0, "fixed"), ([False, True], 0, "fixed"), ([False, False], 0, "fixed"),
    ([False, True], 4, "fixed"), (None, 0, "resolved"), ([False, True], 0, "resolved"),
    ([True, False], 3, "resolved")])
def test_the_batched_form_equals_the_reference(objective: str, e: int,
                                               reported: list[bool] | None, tail: int,
                                               existence: str) -> None:
    prob = mixed_problem(objective=objective, steps_per_epoch=e, reported=reported,
                         find_tail=tail, track_existence=existence)
    sctx = search.prepare(prob)
    plans = [search.random_plan(sctx, np.random.default_rng(s)) for s in range(2)]
    plans.append(make_planner("sequential-greedy").plan(prob).plan)
    for plan in plans:
        for i, k in itertools.product(range(prob.n_sensors), range(1, prob.horizon + 1)):
            pos, tgt, sec = search.player_actions(sctx, plan, i, k)
            u = search.candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
            ref = np.array([search.evaluate(sctx, search.with_action(
                plan, i, k, pos[a], int(tgt[a]), int(sec[a]))).potential
                for a in range(len(tgt))])
            np.testing.assert_allclose(u, ref, rtol=0, atol=1e-12 * max(1.0, ref.max()))


@pytest.mark.parametrize("reported,tail,existence", [
    (None, 0, "fixed"), ([False, True], 0, "fixed"), ([False, True], 5, "fixed"),
    (None, 0, "resolved"), ([True, False], 2, "resolved")])
def test_a_unilateral_change_moves_phi_by_the_players_utility_change(
        reported: list[bool] | None, tail: int, existence: str) -> None:
    """Exact potential: u(a') - u(a) of player (i, k) equals the change of the expected
    bound computed from scratch when only that player changes."""
    prob = mixed_problem(reported=reported, find_tail=tail, track_existence=existence)
    sctx = search.prepare(prob)
    plan = make_planner("pg", max_outer=2).plan(prob, rng=3).plan
    rng = np.random.default_rng(0)
    for i, k in itertools.product(range(prob.n_sensors), range(1, prob.horizon + 1)):
        pos, tgt, sec = search.player_actions(sctx, plan, i, k)
        u = search.candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
        assert np.ptp(u) > 0
        for a, b in rng.integers(len(tgt), size=(3, 2)):
            pa = search.with_action(plan, i, k, pos[a], int(tgt[a]), int(sec[a]))
            pb = search.with_action(plan, i, k, pos[b], int(tgt[b]), int(sec[b]))
            assert u[a] - u[b] == pytest.approx(
                independent_phi(prob, pa) - independent_phi(prob, pb), rel=1e-9, abs=1e-8)


# ------------------------------------------------------------------ planners


def test_brute_force_is_the_optimum_of_an_independent_enumeration() -> None:
    xs = 41.7 + 83.0 * np.arange(7)
    centres = [(x, y) for y in xs for x in xs]
    w = np.random.default_rng(11).uniform(0.0, 0.2, len(centres))
    u = grid(centres, list(w), 0.003, 0.95)
    prob = problem([(150.0, 300.0)], [0.0], u, sectors=2, horizon=2,
                   sensor=SensorParams(moves=(20.0,)), existence=0.7,
                   means=[[480.0, 300.0, 1.0, 0.0]], objective="cumulative", c=20.0)
    res = make_planner("brute-force").plan(prob)
    check_plan(prob, res.plan)
    moves = [np.zeros(2)] + [20.0 * np.array(d) for d in
                             [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1),
                              (1, -1)]]
    p0 = prob.positions[0]
    looks = [(0, -1), (-1, 0), (-1, 1)]
    best = -1.0
    for m1, m2 in itertools.product(moves, repeat=2):
        xy = np.array([[p0 + m1, p0 + m1 + m2]])
        for (t1, s1), (t2, s2) in itertools.product(looks, repeat=2):
            plan = Plan(xy, np.array([[t1, t2]]), np.array([[s1, s2]]))
            best = max(best, independent_phi(prob, plan))
    assert res.potential > res.information.sum() > 0    # both parts count
    assert res.potential == pytest.approx(best, rel=1e-9)
    for name in ("pg", "sequential-greedy", "random"):
        assert make_planner(name).plan(prob, rng=1).potential <= res.potential * (1 + 1e-9)


@pytest.mark.parametrize("name", ["pg", "sequential-greedy", "brute-force", "random"])
def test_search_planners_plan_the_gospa_reward(name: str) -> None:
    prob = mixed_problem(horizon=1)
    res = make_planner(name).plan(prob, rng=2)
    check_result(make_planner(name), prob, res)
    phi, info, mu = search.potential(prob, res.plan)
    assert res.potential == phi and np.array_equal(res.information, info)
    assert res.found == mu and res.search_term == pytest.approx(phi - info.sum(), rel=1e-12)


def test_pg_ends_at_an_equilibrium_of_the_gospa_game() -> None:
    prob = mixed_problem()
    res = make_planner("pg").plan(prob, rng=5)
    assert res.converged
    sctx = search.prepare(prob)
    for i, k in itertools.product(range(prob.n_sensors), range(1, prob.horizon + 1)):
        pos, tgt, sec = search.player_actions(sctx, res.plan, i, k)
        u = search.candidate_potentials(sctx, res.plan, i, k, pos, tgt, sec)
        assert u.max() <= res.potential + 1e-9 * max(1.0, res.potential)


def test_the_information_reward_is_left_bit_identical() -> None:
    """The default: the same plans and the same Phi bits whatever gospa_c says."""
    base = dataclasses.replace(mixed_problem(), reward="information")
    other = dataclasses.replace(base, gospa_c=7.0)
    assert PlanningProblem.__dataclass_fields__["reward"].default == "information"
    for name in ("pg", "sequential-greedy"):
        a, b = make_planner(name).plan(base, rng=1), make_planner(name).plan(other, rng=1)
        assert a.potential == b.potential and a.found == b.found
        assert np.array_equal(a.plan.positions, b.plan.positions)
        assert np.array_equal(a.plan.sectors, b.plan.sectors)  # type: ignore[arg-type]
    assert search.prepare(base).gospa is None
    assert RunSettings().reward == "information"


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("change,field", [
    ({"reward": "gospel"}, "reward"),
    ({"reward": "gospa", "search": "off"}, "reward"),
    ({"gospa_c": 0.0}, "gospa_c"),
    ({"gospa_c": float("inf")}, "gospa_c"),
    ({"gospa_c": True}, "gospa_c"),
    ({"find_tail": -1}, "find_tail"),
    ({"find_tail": 2.0}, "find_tail"),
    ({"find_tail": True}, "find_tail"),
    ({"find_tail": 3, "reward": "information"}, "find_tail"),
    ({"track_existence": "sure"}, "track_existence"),
    ({"track_existence": "resolved", "reward": "information"}, "track_existence"),
])
def test_bad_reward_inputs_name_the_field(change: dict[str, object], field: str) -> None:
    prob = mixed_problem()
    with pytest.raises(ConfigError) as info:
        dataclasses.replace(prob, **change)
    assert info.value.field == field


def test_a_found_weight_in_nats_is_refused_with_the_gospa_reward() -> None:
    prob = mixed_problem()
    u = dataclasses.replace(prob.undetected, weight=2.0)
    with pytest.raises(ConfigError) as info:
        dataclasses.replace(prob, undetected=u)
    assert info.value.field == "undetected.weight"
    dataclasses.replace(prob, undetected=u, reward="information")   # its own reward takes it


def test_run_settings_refuse_resolved_existence_without_the_gospa_reward() -> None:
    with pytest.raises(ConfigError) as info:
        RunSettings(track_existence="resolved")
    assert info.value.field == "track_existence"
    with pytest.raises(ConfigError) as info:
        RunSettings(track_existence="certain")
    assert info.value.field == "track_existence"


def test_run_settings_refuse_gospa_without_search() -> None:
    with pytest.raises(ConfigError) as info:
        RunSettings(reward="gospa")
    assert info.value.field == "reward"
    with pytest.raises(ConfigError) as info:
        RunSettings(reward="entropy")
    assert info.value.field == "reward"
