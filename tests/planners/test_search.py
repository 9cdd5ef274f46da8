"""Search looks and the value of search in Phi: closed forms, an independent brute force,
the potential property and the deduplication of sectors."""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math

import numpy as np
import pytest

import search_problems
from search_problems import SWERLING, problem, sector_plan, swerling_pd
from sensorplan.errors import ConfigError
from sensorplan.models.sensors import SensorParams
from sensorplan.planners import search
from sensorplan.planners.problem import (Plan, PlanError, PlanningProblem, UndetectedIntensity,
                                         check_plan, move_vectors)
from sensorplan.planners.registry import make_planner

#: The intensity grid these tests plan on: a found target is worth 1 nat unless set.
grid = functools.partial(search_problems.grid, weight=1.0)


def test_one_cell_one_look_finds_d_times_pd() -> None:
    # The cell lies on the boresight of sector 0 (bearing 0) at 350 m.
    prob = problem([(100.0, 300.0)], [0.0], grid([(450.0, 300.0)], 0.7))
    phi, info, mu = search.potential(prob, sector_plan(prob, [[0]]))
    assert mu == pytest.approx(0.7 * swerling_pd(SWERLING, 350.0), rel=1e-12)
    assert 0.0 < swerling_pd(SWERLING, 350.0) < 1.0
    assert info.tolist() == [0.0]
    assert phi == pytest.approx(mu, rel=1e-12)              # weight 1, no track term


def test_a_look_away_finds_nothing() -> None:
    prob = problem([(100.0, 300.0)], [0.0], grid([(450.0, 300.0)], 0.7))
    # Sector 2 points at bearing pi: the turn limit (pi/4) leaves the cell out of the wedge.
    assert search.potential(prob, sector_plan(prob, [[2]]))[2] == 0.0


def test_two_looks_over_one_cell_in_one_epoch() -> None:
    cell = (300.0, 300.0)
    prob = problem([(0.0, 300.0), (300.0, 0.0)], [0.0, math.pi / 2], grid([cell], 0.9))
    p1, p2 = swerling_pd(SWERLING, 300.0), swerling_pd(SWERLING, 300.0)
    mu = search.potential(prob, sector_plan(prob, [[0], [1]]))[2]
    assert mu == pytest.approx(0.9 * (1.0 - (1.0 - p1) * (1.0 - p2)), rel=1e-12)


def test_thinning_survival_and_births_across_epochs() -> None:
    pS, b, d0 = 0.9, 0.02, 0.5
    prob = problem([(100.0, 300.0)], [0.0], grid([(500.0, 300.0)], d0, b, pS), horizon=3)
    P = swerling_pd(SWERLING, 400.0)
    mu = search.potential(prob, sector_plan(prob, [[0, 0, 0]]))[2]
    expected, D = 0.0, d0
    for _ in range(3):
        D = pS * D + b
        expected += D * P
        D *= 1.0 - P
    assert mu == pytest.approx(expected, rel=1e-12)
    # Every step of an epoch is a look: two steps per epoch thin twice.
    prob2 = problem([(100.0, 300.0)], [0.0], grid([(500.0, 300.0)], d0, b, pS), horizon=1,
                    steps_per_epoch=2)
    D, expected = pS * d0 + b, 0.0
    expected += D * P
    D = pS * D * (1.0 - P) + b
    expected += D * P
    assert search.potential(prob2, sector_plan(prob2, [[0]]))[2] == pytest.approx(
        expected, rel=1e-12)


def test_sectors_that_map_to_one_heading_are_one_action() -> None:
    prob = problem([(300.0, 300.0)], [0.0], grid([(10.0, 10.0)], 0.1), sectors=8)
    sctx = search.prepare(prob)
    kept = search.sector_actions(sctx, 0, 1, 0.0, True)
    turn = SWERLING.max_turn
    h = [0.0 + float(np.clip(math.remainder(2 * math.pi * s / 8, 2 * math.pi), -turn, turn))
         for s in range(8)]
    classes = sorted({round(v, 9) for v in h})
    assert len(kept) == len(classes) == 3
    # The first sector of each heading, and every sector's heading is a kept one's.
    firsts = sorted(min(s for s in range(8) if round(h[s], 9) == c) for c in classes)
    assert kept.tolist() == firsts
    pos, tgt, sec = search.player_actions(sctx, Plan.empty(1, 1), 0, 1)
    n_positions = len(np.unique(pos, axis=0))
    assert len(tgt) == n_positions * (prob.n_targets + 3)
    assert sorted(set(sec[sec >= 0].tolist())) == firsts


def mixed_problem(horizon: int = 2) -> PlanningProblem:
    xs = 37.3 + 91.0 * np.arange(6)
    centres = [(x, y) for y in xs for x in xs]
    rng = np.random.default_rng(7)
    u = grid(centres, list(rng.uniform(0.01, 0.1, len(centres))), 0.002, 0.97, weight=None)
    return problem([(300.0, 300.0), (60.0, 520.0)], [0.3, -1.0], u, sectors=6,
                   horizon=horizon, sensor=SensorParams(moves=(20.0,)), existence=0.6,
                   means=[[120.0, 90.0, 2.0, 1.0], [480.0, 420.0, -1.0, 0.5]])


def test_utilities_are_phi_differences() -> None:
    prob = mixed_problem()
    sctx = search.prepare(prob)
    plan = make_planner("pg", max_outer=2).plan(prob, rng=3).plan
    for i in range(prob.n_sensors):
        for k in range(1, prob.horizon + 1):
            pos, tgt, sec = search.player_actions(sctx, plan, i, k)
            assert (sec >= 0).any() and (tgt >= 0).any()
            u = search.candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
            phi = np.array([search.evaluate(sctx, search.with_action(
                plan, i, k, pos[a], int(tgt[a]), int(sec[a]))).potential
                for a in range(len(tgt))])
            assert np.ptp(phi) > 0
            np.testing.assert_allclose(u - u[0], phi - phi[0], rtol=0, atol=1e-12)


class HeadingTie(Exception):
    """A look's bearing is exactly behind the platform's heading (see :func:`independent_mu`)."""


def independent_mu(prob: PlanningProblem, xy: np.ndarray, sectors: np.ndarray,
                   ties: bool = False) -> float:
    """mu by the formula, from scratch: ideal detection, the field of view by geometry.
    Sector -1 is a look at the (still) target 0: its bearing from the platform. With
    ``ties``, raises :class:`HeadingTie` when a look's bearing is within 1e-9 rad of
    exactly behind the heading (which way the heading rule turns is then rounding's)."""
    s, u = prob.sensors[0], prob.undetected
    assert u is not None
    S = prob.sector_counts[0]
    h, D, mu = float(prob.headings[0]), np.array(u.weights, dtype=float), 0.0
    for k in range(prob.horizon):
        bearing = (2 * math.pi * sectors[k] / S if sectors[k] >= 0 else
                   math.atan2(prob.means[0, 1] - xy[k, 1], prob.means[0, 0] - xy[k, 0]))
        turn = math.remainder(bearing - h, 2 * math.pi)
        if ties and abs(abs(turn) - math.pi) < 1e-9:
            # A sector exactly behind: which way the heading rule turns is decided by the
            # last bit of the angles, not by the formula checked here.
            raise HeadingTie
        h += float(np.clip(turn, -s.max_turn, s.max_turn))
        d = u.centres - xy[k]
        g = np.hypot(d[:, 0], d[:, 1])
        off = np.abs(np.remainder(np.arctan2(d[:, 1], d[:, 0]) - h + math.pi, 2 * math.pi)
                     - math.pi)
        seen = (g >= s.min_ground_range) & (g <= s.max_ground_range) & (off <= s.fov_half_angle)
        D = u.survival * D + u.births
        mu += float(D[seen].sum())
        D = np.where(seen, 0.0, D)
    return mu


def test_brute_force_is_the_optimum_of_an_independent_enumeration() -> None:
    xs = 41.7 + 83.0 * np.arange(7)
    centres = [(x, y) for y in xs for x in xs]
    w = np.random.default_rng(11).uniform(0.0, 0.2, len(centres))
    u = grid(centres, list(w), 0.003, 0.95)
    # The target stands still (aimed at where it is), r = 0: Phi is w mu.
    prob = problem([(290.0, 310.0)], [0.4], u, sectors=4, horizon=2,
                   sensor=SensorParams(moves=(20.0,)), existence=0.0)
    res = make_planner("brute-force").plan(prob)
    check_plan(prob, res.plan)
    moves = [np.zeros(2)] + [20.0 * np.array(d) for d in
                             [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1),
                              (1, -1)]]
    best = -1.0
    p0 = prob.positions[0]
    for m1, m2 in itertools.product(moves, repeat=2):
        xy = np.array([p0 + m1, p0 + m1 + m2])
        for seq in itertools.product(range(-1, 4), repeat=2):
            best = max(best, independent_mu(prob, xy, np.array(seq)))
    assert best > 0
    assert res.potential == pytest.approx(best, rel=1e-12)


def test_pg_with_search_reaches_an_equilibrium_and_searches() -> None:
    prob = mixed_problem()
    res = make_planner("pg").plan(prob, rng=5)
    check_plan(prob, res.plan)
    assert res.converged
    sctx = search.prepare(prob)
    # No player gains by a unilateral change.
    for i in range(prob.n_sensors):
        for k in range(1, prob.horizon + 1):
            pos, tgt, sec = search.player_actions(sctx, res.plan, i, k)
            u = search.candidate_potentials(sctx, res.plan, i, k, pos, tgt, sec)
            assert u.max() <= res.potential + 1e-9 * max(1.0, abs(res.potential))


def test_search_off_plans_exactly_as_before() -> None:
    base = mixed_problem()
    off = PlanningProblem(means=base.means, covs=base.covs, positions=base.positions,
                          headings=base.headings, sensors=base.sensors, horizon=2,
                          existence=base.existence)
    ignored = PlanningProblem(means=base.means, covs=base.covs, positions=base.positions,
                              headings=base.headings, sensors=base.sensors, horizon=2,
                              existence=base.existence, search="off", search_sectors=6,
                              undetected=base.undetected)
    a = make_planner("pg").plan(off, rng=2)
    b = make_planner("pg").plan(ignored, rng=2)
    assert a.potential == b.potential
    assert np.array_equal(a.plan.positions, b.plan.positions)
    assert np.array_equal(a.plan.targets, b.plan.targets)
    assert off.search == "off" and off.sector_counts == (0, 0)
    assert not a.plan.searches


def test_search_planners_refuse_a_time_budget() -> None:
    # Every registered planner plans search looks now; the budgeted search game is not built.
    for name in ("pg", "pg-refine", "sequential-greedy"):
        with pytest.raises(ConfigError, match="planner.time_budget"):
            make_planner(name, time_budget=1.0).plan(mixed_problem(1))


def test_sequential_greedy_is_each_players_best_response_to_the_earlier_ones() -> None:
    prob = mixed_problem()
    sctx = search.prepare(prob)
    res = make_planner("sequential-greedy").plan(prob)
    check_plan(prob, res.plan)
    plan = Plan.empty(prob.n_sensors, prob.horizon)
    for k in range(1, prob.horizon + 1):
        for i in range(prob.n_sensors):
            pos, tgt, sec = search.player_actions(sctx, plan, i, k)
            phi = [search.evaluate(sctx, search.with_action(plan, i, k, pos[a], int(tgt[a]),
                                                            int(sec[a]))).potential
                   for a in range(len(tgt))]
            a = int(np.argmax(phi))
            plan = search.with_action(plan, i, k, pos[a], int(tgt[a]), int(sec[a]))
    assert np.array_equal(plan.targets, res.plan.targets)
    assert np.array_equal(plan.sectors, res.plan.sectors)
    np.testing.assert_allclose(plan.positions, res.plan.positions, rtol=0, atol=1e-9)
    assert res.potential == search.evaluate(sctx, res.plan).potential


def test_random_plans_are_feasible_and_use_sectors() -> None:
    prob = mixed_problem()
    plans = [make_planner("random").plan(prob, rng=s).plan for s in range(8)]
    for p in plans:
        check_plan(prob, p)
    assert any(p.searches for p in plans) and any((p.targets >= 0).any() for p in plans)
    again = make_planner("random").plan(prob, rng=3).plan
    assert np.array_equal(again.sectors, plans[3].sectors)


def test_bad_search_inputs() -> None:
    base = mixed_problem(1)
    kw = dict(means=base.means, covs=base.covs, positions=base.positions,
              headings=base.headings, sensors=base.sensors, horizon=1)
    with pytest.raises(ConfigError, match="undetected"):
        PlanningProblem(**kw, search="on")                       # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="^search"):
        PlanningProblem(**kw, search="yes")                      # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"sensors\[1\].search_sectors"):
        PlanningProblem(**kw, search_sectors=(2, -1))            # type: ignore[arg-type]
    bad = UndetectedIntensity(np.zeros((2, 2)), np.array([0.1, -0.1]), np.zeros(2))
    with pytest.raises(ConfigError, match="undetected.weights"):
        PlanningProblem(**kw, search="on", undetected=bad)       # type: ignore[arg-type]
    with pytest.raises(PlanError, match="does not exist"):
        check_plan(base, sector_plan(base, [[6], [0]]))
    with pytest.raises(PlanError, match="target and a sector"):
        check_plan(base, Plan(np.repeat(base.positions[:, None], 1, 1), np.zeros((2, 1)),
                              np.zeros((2, 1))))


def test_the_track_term_is_todays_phi() -> None:
    prob = mixed_problem()
    off = PlanningProblem(means=prob.means, covs=prob.covs, positions=prob.positions,
                          headings=prob.headings, sensors=prob.sensors, horizon=2,
                          existence=prob.existence)
    res = make_planner("pg").plan(off, rng=1)
    ev = search.evaluate(search.prepare(prob), res.plan)
    np.testing.assert_allclose(ev.information, res.information, rtol=1e-12, atol=0)
    np.testing.assert_allclose(ev.headings, res.headings, rtol=0, atol=1e-12)
    assert np.array_equal(ev.measurements, res.measurements)
    assert ev.found > 0          # track looks thin the cells they cover too


def test_search_counts_and_grids_that_cannot_be_are_refused() -> None:
    base = mixed_problem(1)
    kw = dict(means=base.means, covs=base.covs, positions=base.positions,
              headings=base.headings, sensors=base.sensors, horizon=1, search="on",
              undetected=base.undetected)
    for bad, field in [(2.5, "search_sectors"), ("6", "search_sectors"),
                       (float("nan"), "search_sectors"), ((6,), "search_sectors"),
                       ((6, "a"), r"sensors\[1\].search_sectors"),
                       ((6, math.inf), r"sensors\[1\].search_sectors"),
                       (0, "search_sectors"), ((0, 0), r"sensors\[0\].search_sectors")]:
        with pytest.raises(ConfigError, match=f"^{field}: "):
            PlanningProblem(**kw, search_sectors=bad)                # type: ignore[arg-type]
    assert PlanningProblem(**kw, search_sectors=(0, 3)).sector_counts == (0, 3)
    assert PlanningProblem(**kw, search_sectors=4.0).sector_counts == (4, 4)  # type: ignore
    u = base.undetected
    assert u is not None
    outside = UndetectedIntensity(np.array(u.centres) + [0.0, 400.0], u.weights, u.births)
    with pytest.raises(ConfigError, match=r"^undetected.centres\[\d+\]: \[.*\] is outside "):
        PlanningProblem(**{**kw, "undetected": outside}, search_sectors=6)  # type: ignore


def test_no_tracks_is_a_search_decision() -> None:
    # Without tracks Phi is w mu alone: the same as with one track of existence 0 (whose
    # information counts nothing), for every planner with search.
    u = grid([(450.0, 100.0), (100.0, 450.0), (347.0, 347.0)], [0.2, 0.3, 0.5])
    with_phantom = problem([(100.0, 100.0)], [0.0], u, sectors=8)
    empty = dataclasses.replace(with_phantom, means=np.zeros((0, 4)), covs=np.zeros((0, 4, 4)),
                                existence=np.zeros(0))
    moves = move_vectors(SWERLING.moves) + with_phantom.positions[0]
    best = max(search.potential(with_phantom, Plan(m[None, None], np.full((1, 1), -1),
                                                   np.full((1, 1), s)))[0]
               for m in moves if with_phantom.world.contains(m) for s in range(8))
    assert best > 0.0
    for name in ("brute-force", "pg", "sequential-greedy", "random", "raster"):
        result = make_planner(name).plan(empty, np.random.default_rng(0))
        check_plan(empty, result.plan, complete=True)
        assert (result.plan.targets == -1).all() and (result.plan.sectors >= 0).all()
        phi = search.potential(empty, result.plan)[0]
        assert phi == pytest.approx(search.potential(with_phantom, result.plan)[0], abs=1e-12)
        assert phi == pytest.approx(result.potential, abs=1e-12)
        if name not in ("random", "raster"):          # the two that do not maximise Phi
            assert phi == pytest.approx(best, abs=1e-12)


def test_no_tracks_needs_search_on() -> None:
    with pytest.raises(ConfigError, match="at least one target"):
        PlanningProblem(means=np.zeros((0, 4)), covs=np.zeros((0, 4, 4)),
                        positions=np.array([[300.0, 300.0]]), headings=np.zeros(1),
                        sensors=(SWERLING,), horizon=1)


def test_a_closed_loop_problems_mu_is_the_formulas() -> None:
    """The problem the closed loop builds from the PMB tracker (the search preset before any
    track: every look searches), with one ideal sensor and K = 2: mu of sector plans equals
    the formula computed from scratch (:func:`independent_mu`)."""
    import dataclasses

    from sensorplan.config import load_simulation
    from sensorplan.simulation import run as run_module
    from sensorplan.simulation.run import run_episode

    cfg = load_simulation(preset="search", overrides={"search": "on", "steps": 4, "seed": 5,
                                                      "reward": "information"})
    problems: list[PlanningProblem] = []
    real = run_module.checked_plan

    def spy(planner, problem, rng=None, decision=None):  # type: ignore[no-untyped-def]
        problems.append(problem)
        return real(planner, problem, rng, decision)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_module, "checked_plan", spy)
        run_episode(dataclasses.replace(cfg.scenario, initial_targets=0), cfg.settings, 5)
    loop = problems[-1]
    assert loop.n_targets == 0 and loop.undetected is not None
    assert loop.undetected.weights.sum() > 0 and loop.undetected.births.sum() > 0
    ideal = dataclasses.replace(loop.sensors[0], detection="ideal", clutter_rate=0.0)
    prob = dataclasses.replace(loop, sensors=(ideal,), positions=loop.positions[:1],
                               headings=loop.headings[:1], search_sectors=6, horizon=2)
    xy = np.repeat(prob.positions, 2, axis=0)
    checked = 0
    for seq in itertools.product(range(6), repeat=2):
        mu = search.potential(prob, sector_plan(prob, [list(seq)]))[2]
        try:
            expected = independent_mu(prob, xy, np.array(seq), ties=True)
        except HeadingTie:
            continue
        assert mu == pytest.approx(expected, rel=1e-12)
        checked += mu > 0
    assert checked > 0
