"""The ``raster`` baseline: its sweep orders and revisit schedule against their definitions
(computed again here, independently), feasibility under the turn limit on random problems,
Phi recomputed, and the contract."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.models.angles import heading_rule, wrap_angle
from sensorplan.models.sensors import SensorParams
from sensorplan.planners import check_planner, make_planner
from sensorplan.planners import information, search
from sensorplan.planners.contract_problems import paper_problem
from sensorplan.planners.problem import (Plan, PlanningProblem, UndetectedIntensity,
                                         check_plan)
from sensorplan.planners.raster import (SWEEPS, RasterPlanner, looks, revisit_order,
                                        schedule, sweep_order)


def search_problem(rng: np.random.Generator, sectors: tuple[int, ...] | None = None,
                   horizon: int | None = None, elapsed: int | None = None,
                   max_turn: float | None = None) -> PlanningProblem:
    """A random problem that searches: 1-3 sensors with their own sector counts (at least
    one > 0) and turn limits, 1-4 targets of different uncertainty and existence, a grid of
    cells over the map, any point of the run."""
    N = len(sectors) if sectors is not None else int(rng.integers(1, 4))
    M = int(rng.integers(1, 5))
    if sectors is None:
        sectors = tuple(int(s) for s in rng.integers(0, 10, N))
        if not any(sectors):
            sectors = (int(rng.integers(1, 10)),) + sectors[1:]
    sensors = tuple(SensorParams(max_turn=float(rng.uniform(math.pi / 16, math.pi))
                                 if max_turn is None else max_turn,
                                 moves=(20.0,)) for _ in range(N))
    sd = rng.uniform(5.0, 60.0, M)
    covs = np.array([np.diag([d * d, (1.5 * d) ** 2, 4.0, 4.0]) for d in sd])
    xs = 50.0 + 100.0 * np.arange(6)
    centres = np.array([(x, y) for y in xs for x in xs])
    u = UndetectedIntensity(centres, rng.uniform(0.0, 0.1, len(centres)),
                            np.full(len(centres), 0.001), 0.98)
    return PlanningProblem(
        means=np.c_[rng.uniform(0, 600, (M, 2)), rng.normal(0, 2, (M, 2))], covs=covs,
        positions=rng.uniform(0, 600, (N, 2)), headings=rng.uniform(-math.pi, math.pi, N),
        sensors=sensors, horizon=int(rng.integers(1, 7)) if horizon is None else horizon,
        existence=rng.choice([0.2, 0.5, 0.9, 1.0], M), search="on", search_sectors=sectors,
        undetected=u, elapsed_epochs=int(rng.integers(0, 40)) if elapsed is None else elapsed)


def cycle_length(S: int, r: int, look: int) -> int:
    """Looks of a sensor that hold S sweep looks, from sweep look ``look`` of the run on: S,
    plus the revisits among them. Looks come in blocks of r, the last of each a revisit; a
    sweep look at place q = (look - 1) mod r of its block has r - 1 - q sweep looks left in
    it (itself included), so the S sweep looks span floor((q + S - 1) / (r - 1)) revisits."""
    if r < 2:
        return S
    q = (look - 1) % r
    return S + (q + S - 1) // (r - 1)


# --------------------------------------------------------------------- the schedule


@pytest.mark.parametrize("S", range(1, 13))
def test_sweep_orders_are_their_closed_forms(S: int) -> None:
    assert sweep_order(S, "counterclockwise").tolist() == list(range(S))
    assert sweep_order(S, "clockwise").tolist() == [0] + list(range(S - 1, 0, -1))
    assert sweep_order(S, "interleaved").tolist() == (list(range(0, S, 2))
                                                      + list(range(1, S, 2)))
    for sweep in SWEEPS:
        assert sorted(sweep_order(S, sweep).tolist()) == list(range(S))
    # Clockwise is decreasing bearing: each step turns by -2 pi / S.
    b = 2 * np.pi * sweep_order(S, "clockwise") / S
    np.testing.assert_allclose(wrap_angle(np.diff(b)), wrap_angle(np.full(S - 1, -2 * np.pi / S)),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("sweep", SWEEPS)
@pytest.mark.parametrize("r", [0, 2, 3, 4, 7])
@pytest.mark.parametrize("S", [1, 2, 5, 8])
def test_one_cycle_visits_every_sector_once(sweep: str, r: int, S: int) -> None:
    """From a sweep look on, the next cycle_length(S, r, look) looks hold exactly S sweep looks,
    one per sector, and end with a sweep look; and with a turn limit of pi every sector is
    its own action, so the plan names exactly those sectors."""
    rng = np.random.default_rng(S * 100 + r)
    cycles = 0
    for start in range(0, 2 * max(r, 1) + S):
        L = cycle_length(S, r, start + 1)
        p = search_problem(rng, sectors=(S,), horizon=L, elapsed=start, max_turn=math.pi)
        targets, sectors = schedule(p, sweep, r)
        if sectors[0, 0] < 0:                  # the cycle starts at a sweep look
            continue
        assert sorted(sectors[0][sectors[0] >= 0].tolist()) == list(range(S))
        assert sectors[0, -1] >= 0
        plan = RasterPlanner(sweep=sweep, revisit_every=r).plan(p).plan
        assert np.array_equal(plan.sectors, sectors)
        assert np.array_equal(plan.targets, targets)
        cycles += 1
    assert cycles >= min(max(r - 1, 1), 2)


def test_the_schedule_goes_on_from_one_decision_to_the_next() -> None:
    """A decision at epoch e0 of the run with horizon K asks for the looks of epochs
    e0+1..e0+K of one long decision from the start: the kinds and the sectors."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        long = search_problem(rng, horizon=30, elapsed=0)
        e0, K = int(rng.integers(0, 25)), int(rng.integers(1, 6))
        later = PlanningProblem(**{**{f: getattr(long, f) for f in
                                      long.__dataclass_fields__}, "horizon": K,
                                   "elapsed_epochs": e0})
        sweep, r = str(rng.choice(SWEEPS)), int(rng.integers(0, 5))
        t_long, s_long = schedule(long, sweep, r)
        t, s = schedule(later, sweep, r)
        assert np.array_equal(s, s_long[:, e0:e0 + K])
        assert np.array_equal(t >= 0, t_long[:, e0:e0 + K] >= 0)


def reference_schedule(p: PlanningProblem, sweep: str, r: int) -> tuple[list, list]:
    """The schedule's definition, look by look, in plain Python."""
    M = p.n_targets
    key = [(p.existence[j] < 0.5, -(p.covs[j][0][0] + p.covs[j][1][1]), j) for j in range(M)]
    queue = [j for _, _, j in sorted(key)]
    targets = [[-1] * p.horizon for _ in range(p.n_sensors)]
    sectors = [[-1] * p.horizon for _ in range(p.n_sensors)]
    c = 0
    for k in range(1, p.horizon + 1):
        n = p.elapsed_epochs + k
        for i, S in enumerate(p.sector_counts):
            if S == 0 or (r > 0 and n % r == 0):
                targets[i][k - 1] = queue[c % M]
                c += 1
            else:
                sweeps_before = sum(1 for m in range(1, n) if not (r > 0 and m % r == 0))
                order = {"counterclockwise": list(range(S)),
                         "clockwise": [(-s) % S for s in range(S)],
                         "interleaved": list(range(0, S, 2)) + list(range(1, S, 2))}[sweep]
                sectors[i][k - 1] = order[sweeps_before % S]
    return targets, sectors


def test_the_schedule_is_its_definition() -> None:
    rng = np.random.default_rng(11)
    for _ in range(60):
        p = search_problem(rng)
        sweep, r = str(rng.choice(SWEEPS)), int(rng.integers(0, 6))
        t, s = schedule(p, sweep, r)
        rt, rs = reference_schedule(p, sweep, r)
        assert t.tolist() == rt and s.tolist() == rs


def test_revisits_take_confirmed_then_uncertain_tracks_first() -> None:
    p = paper_problem(np.random.default_rng(0), n_targets=4)
    covs = np.array(p.covs)
    covs[:, 0, 0] = [100.0, 900.0, 400.0, 900.0]
    p = PlanningProblem(p.means, covs, p.positions, p.headings, p.sensors, horizon=3,
                        existence=np.array([1.0, 0.3, 0.5, 1.0]))
    assert revisit_order(p).tolist() == [3, 2, 0, 1]
    # Search off: every look revisits, epoch by epoch, sensor by sensor, in that order.
    plan = make_planner("raster").plan(p).plan
    assert plan.targets.T.ravel().tolist() == [3, 2, 0, 1, 3, 2, 0, 1, 3]
    assert not plan.searches


def test_without_a_track_every_look_sweeps() -> None:
    """A searching decision before the first track: nothing to revisit, so look n of the run
    takes sweep position n - 1 whatever revisit_every; a sensor without sectors has no look."""
    none = np.zeros(0, dtype=np.int64)
    for r in (0, 2, 3):
        targets, sectors = looks((5, 3), none, 7, 4, "counterclockwise", r)
        assert (targets == -1).all()
        assert sectors.tolist() == [[(7 + k - 1) % 5 for k in range(1, 5)],
                                    [(7 + k - 1) % 3 for k in range(1, 5)]]
    with pytest.raises(ConfigError, match=r"^sensors\[1\]\.search_sectors: raster has no look"):
        looks((5, 0), none, 0, 2, "clockwise", 3)


# ----------------------------------------------------------------- plan and Phi


def test_plans_are_feasible_hold_station_and_keep_the_turn_limit() -> None:
    rng = np.random.default_rng(3)
    for _ in range(40):
        p = search_problem(rng)
        sweep, r = str(rng.choice(SWEEPS)), int(rng.integers(0, 5))
        res = RasterPlanner(sweep=sweep, revisit_every=r).plan(p)
        plan = res.plan
        check_plan(p, plan, complete=True)
        assert np.array_equal(plan.positions, np.repeat(p.positions[:, None], p.horizon, 1))
        # The headings are those of the looks asked for: each sector named stands for the
        # heading its wanted sector reaches, and is a distinct action of its player.
        t, s = schedule(p, sweep, r)
        sctx = search.prepare(p)
        wanted = search.plan_headings(sctx, Plan(plan.positions, t, s))
        np.testing.assert_allclose(res.headings, wanted, rtol=0, atol=1e-12)
        prev = np.array(p.headings)
        turn = np.array([sn.max_turn for sn in p.sensors])
        assert np.all(np.abs(wrap_angle(res.headings - np.c_[prev, res.headings[:, :-1]]))
                      <= turn[:, None] + 1e-12)
        for i in range(p.n_sensors):
            for k in range(1, p.horizon + 1):
                if plan.sectors[i, k - 1] >= 0:
                    h0 = prev[i] if k == 1 else res.headings[i, k - 2]
                    assert plan.sectors[i, k - 1] in search.sector_actions(sctx, i, k, h0, True)
                    b = 2 * np.pi * plan.sectors[i, k - 1] / p.sector_counts[i]
                    assert abs(wrap_angle(heading_rule(h0, b, turn[i])
                                          - res.headings[i, k - 1])) <= 1e-12


def test_reported_phi_is_phi_recomputed() -> None:
    rng = np.random.default_rng(8)
    for _ in range(12):
        p = search_problem(rng)
        res = RasterPlanner(sweep=str(rng.choice(SWEEPS)),
                            revisit_every=int(rng.integers(0, 5))).plan(p)
        phi, info, found = search.potential(p, res.plan)
        np.testing.assert_allclose(res.potential, phi, rtol=1e-12, atol=0)
        np.testing.assert_allclose(res.information, info, rtol=1e-12, atol=0)
        if res.plan.searches:
            assert found > 0 or not np.any(res.measurements[res.plan.sectors >= 0])
    off = paper_problem(np.random.default_rng(4), horizon=3)
    res = make_planner("raster").plan(off)
    phi, info = information.potential(off, res.plan)
    np.testing.assert_allclose([res.potential, *res.information], [phi, *info], rtol=1e-12,
                               atol=0)


def test_deterministic_whatever_the_rng() -> None:
    p = search_problem(np.random.default_rng(2), horizon=5)
    a, b = (make_planner("raster", sweep="interleaved").plan(p, rng=s) for s in (0, 99))
    assert np.array_equal(a.plan.sectors, b.plan.sectors)
    assert np.array_equal(a.plan.targets, b.plan.targets) and a.potential == b.potential


def test_other_settings_pass_the_contract() -> None:
    check_planner(RasterPlanner(sweep="interleaved", revisit_every=2))


@pytest.mark.parametrize(("key", "value", "message"), [
    ("sweep", "spiral", "unknown sweep 'spiral'; choose from clockwise, counterclockwise, "
                        "interleaved"),
    ("revisit_every", -1, "must be >= 0, got -1"),
    ("revisit_every", 1.5, "must be an integer, got 1.5"),
])
def test_bad_settings_name_the_key(key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        make_planner("raster", **{key: value})
    assert (err.value.field, err.value.message) == (f"planner.{key}", message)


def test_the_run_epoch_is_checked() -> None:
    p = paper_problem(np.random.default_rng(0))
    base = {f: getattr(p, f) for f in p.__dataclass_fields__}
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ConfigError, match="^elapsed_epochs: must be an integer >= 0"):
            PlanningProblem(**{**base, "elapsed_epochs": bad})
