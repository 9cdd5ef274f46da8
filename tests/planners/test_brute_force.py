"""The ``brute-force`` planner against an explicit, independent enumeration.

The reference enumerates every sensor's move sequences with ``itertools.product`` (in-map
check done here, not with the library's lattice), every target sequence, and every joint
combination, and calls :func:`sensorplan.planners.information.potential` on each :class:`Plan`.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.planners.information import potential
from sensorplan.planners import PLANNERS, make_planner
from sensorplan.planners import brute_force as bf
from sensorplan.planners.brute_force import BruteForcePlanner, count_joint_plans
from sensorplan.planners.problem import Plan, PlanningProblem, check_plan, move_vectors

from factories import lattice_problem
from sensorplan.models.sensors import SensorParams

RTOL = 1e-9


def explicit_chains(problem: PlanningProblem, i: int) -> list[np.ndarray]:
    """Sensor ``i``'s feasible position chains ``(K, 2)``, move sequences in lexicographic
    order, with an in-map test written independently of the library."""
    moves = move_vectors(problem.sensors[i].moves)
    W, H = problem.world.width, problem.world.height
    out = []
    for seq in itertools.product(range(len(moves)), repeat=problem.horizon):
        path = problem.positions[i] + np.cumsum(moves[list(seq)], axis=0)
        if np.all((path >= -1e-6) & (path <= np.array([W, H]) + 1e-6)):
            out.append(path)
    return out


def explicit_plans(problem: PlanningProblem):
    """Every joint plan in the documented order (sensor 0 slowest; chains, then targets)."""
    K, M = problem.horizon, problem.n_targets
    per_sensor = [[(c, np.array(s)) for c in explicit_chains(problem, i)
                   for s in itertools.product(range(M), repeat=K)]
                  for i in range(problem.n_sensors)]
    for combo in itertools.product(*per_sensor):
        yield Plan(np.stack([c for c, _ in combo]), np.stack([s for _, s in combo]))


def explicit_optimum(problem: PlanningProblem) -> tuple[float, Plan, int]:
    """Max of Phi by calling ``potential`` on every plan; the first plan within the tie
    tolerance of it; the number of plans."""
    plans = list(explicit_plans(problem))
    values = np.array([potential(problem, p)[0] for p in plans])
    best = float(values.max())
    first = int(np.flatnonzero(values >= best - RTOL * max(1.0, abs(best)))[0])
    return best, plans[first], len(plans)


CASES = [
    # (n_sensors, n_targets, horizon, steps_per_epoch, size, starts)
    (2, 3, 1, 1, 60.0, [(30.0, 30.0), (0.0, 60.0)]),
    (2, 3, 1, 2, 60.0, [(30.0, 30.0), (60.0, 0.0)]),
    (1, 3, 2, 1, 60.0, [(30.0, 30.0)]),
    (1, 2, 2, 2, 60.0, [(0.0, 30.0)]),
    (2, 1, 2, 1, 30.0, [(0.0, 0.0), (30.0, 30.0)]),
    (2, 2, 2, 1, 30.0, [(0.0, 0.0), (30.0, 30.0)]),      # 4096 plans: 2-5 s each
]
MODES = [(v, o) for o in ("terminal", "cumulative") for v in ("probabilistic", "mean")]
PARAMS = [pytest.param(c, v, o, marks=[pytest.mark.slow] if c == 5 and m else [])
          for c in range(len(CASES)) for m, (v, o) in enumerate(MODES)]


@pytest.mark.parametrize(("case", "visibility", "objective"), PARAMS)
def test_matches_explicit_enumeration(case: int, visibility: str, objective: str) -> None:
    N, M, K, e, size, starts = CASES[case]
    problem = lattice_problem(100 + case, n_sensors=N, n_targets=M, horizon=K,
                           steps_per_epoch=e, visibility=visibility, objective=objective,
                           size=size, starts=starts)
    best, first, count = explicit_optimum(problem)
    assert best > 0.0, "degenerate test problem: nothing is ever seen"
    assert count_joint_plans(problem) == count
    result = BruteForcePlanner().plan(problem)
    check_plan(problem, result.plan)
    np.testing.assert_allclose(result.potential, best, rtol=RTOL, atol=0.0)
    np.testing.assert_allclose(potential(problem, result.plan)[0], best, rtol=RTOL, atol=0.0)
    np.testing.assert_allclose(result.information.sum(), result.potential, rtol=RTOL)
    # The fast evaluation's own maximum (trace) equals the definition's.
    np.testing.assert_allclose(result.trace, [best], rtol=RTOL, atol=0.0)
    # Ties: the first maximum in the documented enumeration order.
    np.testing.assert_array_equal(result.plan.targets, first.targets)
    np.testing.assert_allclose(result.plan.positions, first.positions, rtol=0, atol=1e-6)


@pytest.mark.parametrize("chunk", [1, 5, 100])
@pytest.mark.parametrize("visibility", ["probabilistic", "mean"])
def test_chunking_does_not_change_the_result(chunk: int, visibility: str) -> None:
    """Small chunks force many chunks, a split inside the sensors (64 options each) and
    per-chunk ``np.unique`` instead of tables; the plan must be the same."""
    problem = lattice_problem(7, n_sensors=2, n_targets=2, horizon=2, visibility=visibility,
                           size=30.0, starts=[(0.0, 0.0), (30.0, 0.0)])
    ref = BruteForcePlanner().plan(problem)
    res = BruteForcePlanner(chunk=chunk).plan(problem)
    np.testing.assert_allclose(res.potential, ref.potential, rtol=RTOL, atol=0.0)
    np.testing.assert_array_equal(res.plan.targets, ref.plan.targets)
    np.testing.assert_allclose(res.plan.positions, ref.plan.positions, rtol=0, atol=1e-6)


def test_chunking_keeps_the_first_of_tied_maxima_across_chunks() -> None:
    """Two identical targets make every optimum come in tied pairs; with one-plan chunks
    the first of them must still win (equals the explicit first maximum)."""
    problem = lattice_problem(3, n_sensors=1, n_targets=2, horizon=1, size=60.0,
                           starts=[(30.0, 30.0)])
    twin = PlanningProblem(means=np.repeat(problem.means[:1], 2, axis=0),
                           covs=np.repeat(problem.covs[:1], 2, axis=0),
                           positions=problem.positions, headings=problem.headings,
                           sensors=problem.sensors, horizon=1, world=problem.world)
    best, first, _ = explicit_optimum(twin)
    assert best > 0.0
    for chunk in (1, 2, 1 << 20):
        res = BruteForcePlanner(chunk=chunk).plan(twin)
        assert res.plan.targets[0, 0] == 0 == first.targets[0, 0]
        np.testing.assert_allclose(res.plan.positions, first.positions, rtol=0, atol=1e-6)


@pytest.mark.parametrize("shift", [1e-9, -1e-9])
def test_near_ties_within_tolerance_keep_the_first(shift: float) -> None:
    """Target 1 is target 0 moved by ``shift`` metres, so the two best plans differ by far
    less than the tie tolerance but not bit for bit, the later one higher for one of the
    signs; the first (target 0) must win, with one chunk or with one plan per chunk."""
    problem = lattice_problem(3, n_sensors=1, n_targets=1, horizon=1, size=60.0,
                           starts=[(30.0, 30.0)])
    means = np.repeat(problem.means, 2, axis=0)
    means[1, :2] += shift
    twin = PlanningProblem(means=means, covs=np.repeat(problem.covs, 2, axis=0),
                           positions=problem.positions, headings=problem.headings,
                           sensors=problem.sensors, horizon=1, world=problem.world)
    values = {j: BruteForcePlanner().plan(PlanningProblem(
        means=means[j:j + 1], covs=problem.covs, positions=problem.positions,
        headings=problem.headings, sensors=problem.sensors, horizon=1,
        world=problem.world)).potential for j in (0, 1)}
    assert values[0] != values[1] and values[0] == pytest.approx(values[1], rel=RTOL)
    for chunk in (1, 1 << 20):
        res = BruteForcePlanner(chunk=chunk).plan(twin)
        assert res.plan.targets[0, 0] == 0


def test_all_ties_give_the_first_plan() -> None:
    """Nothing visible anywhere (``mean``): Phi = 0 everywhere and the plan is the first
    one, every sensor staying and looking at target 0."""
    problem = lattice_problem(5, n_sensors=2, n_targets=2, horizon=2, visibility="mean",
                           target_box=(5000.0, 6000.0))
    result = BruteForcePlanner().plan(problem)
    assert result.potential == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_array_equal(result.plan.targets, 0)
    expected = np.repeat(np.asarray(problem.positions)[:, None, :], 2, axis=1)
    np.testing.assert_allclose(result.plan.positions, expected, rtol=0, atol=1e-6)


@pytest.mark.parametrize("horizon", [1, 2, 3])
@pytest.mark.parametrize("start", [(0.0, 0.0), (60.0, 30.0), (30.0, 30.0)])
def test_count_matches_explicit_enumeration(horizon: int, start: tuple[float, float]) -> None:
    problem = lattice_problem(11, n_sensors=2, n_targets=3, horizon=horizon, size=60.0,
                           starts=[start, (30.0, 60.0)])
    chains = [len(explicit_chains(problem, i)) for i in range(2)]
    assert count_joint_plans(problem) == math.prod(c * 3**horizon for c in chains)


def test_count_with_two_move_distances() -> None:
    """17 moves (20 and 40 m) near a corner of the paper's map, K = 3."""
    sensors = (SensorParams(), SensorParams(altitude=490.0))
    problem = PlanningProblem(means=np.array([[300.0, 300.0, 1.0, 0.0]]),
                              covs=np.diag([400.0, 400.0, 4.0, 4.0])[None],
                              positions=np.array([[20.0, 40.0], [300.0, 590.0]]),
                              headings=np.zeros(2), sensors=sensors, horizon=3)
    chains = [len(explicit_chains(problem, i)) for i in range(2)]
    assert chains[0] < 17**3 and chains[1] < 17**3
    assert count_joint_plans(problem) == chains[0] * chains[1]


def test_refuses_above_max_plans(monkeypatch: pytest.MonkeyPatch) -> None:
    problem = lattice_problem(2, n_sensors=2, n_targets=3, horizon=1, size=60.0,
                           starts=[(30.0, 30.0), (0.0, 0.0)])
    n = count_joint_plans(problem)
    assert n == (9 * 3) * (4 * 3)
    BruteForcePlanner(max_plans=n).plan(problem)          # exactly at the limit: allowed

    def no_heavy_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("options computed before the plan count was checked")

    monkeypatch.setattr(bf, "_sensor_options", no_heavy_work)
    with pytest.raises(ConfigError) as info:
        BruteForcePlanner(max_plans=n - 1).plan(problem)
    assert info.value.field == "planner.max_plans"
    assert str(n) in info.value.message and f"max_plans={n - 1}" in info.value.message


def test_refuses_the_non_myopic_paper_space_quickly() -> None:
    """N = 3, M = 5, K = 3 with every move in the map: (17^3 * 5^3)^3 plans, counted
    exactly and refused by default."""
    sensors = tuple(SensorParams(altitude=z) for z in (490.0, 500.0, 510.0))
    rng = np.random.default_rng(0)
    problem = PlanningProblem(
        means=np.column_stack([rng.uniform(100, 500, (5, 2)), rng.normal(0, 3, (5, 2))]),
        covs=np.broadcast_to(np.diag([400.0, 400.0, 4.0, 4.0]), (5, 4, 4)),
        positions=rng.uniform(120.0, 480.0, (3, 2)), headings=np.zeros(3), sensors=sensors,
        horizon=3, steps_per_epoch=2)
    n = (17**3 * 5**3) ** 3
    assert count_joint_plans(problem) == n
    with pytest.raises(ConfigError, match=f"{n} joint plans exceed"):
        make_planner("brute-force").plan(problem)


def test_registered_and_validated() -> None:
    assert PLANNERS["brute-force"] is BruteForcePlanner
    planner = make_planner("brute-force", max_plans=10, seed=None, chunk=4)
    assert (planner.max_plans, planner.chunk) == (10, 4)
    with pytest.raises(ConfigError, match="planner.chunk"):
        BruteForcePlanner(chunk=0)
    for bad in (0, 2.5, "many", True):
        with pytest.raises(ConfigError, match="planner.max_plans"):
            BruteForcePlanner(max_plans=bad)  # type: ignore[arg-type]


def test_deterministic_and_does_not_mutate_the_problem() -> None:
    problem = lattice_problem(9, n_sensors=2, n_targets=2, horizon=1, size=60.0)
    before = {name: np.array(getattr(problem, name), copy=True)
              for name in ("means", "covs", "positions", "headings")}
    a = BruteForcePlanner(seed=1).plan(problem, rng=123)
    b = BruteForcePlanner(seed=2).plan(problem)
    np.testing.assert_array_equal(a.plan.targets, b.plan.targets)
    np.testing.assert_array_equal(a.plan.positions, b.plan.positions)
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(problem, name), value)


@pytest.mark.parametrize("visibility", ["probabilistic", "mean"])
@pytest.mark.parametrize("horizon", [1, 2])
def test_contribution_classes_carry_each_options_information(visibility: str,
                                                             horizon: int) -> None:
    """Every option's class carries exactly the information the option's own plan gives
    each target (``plan_information``); with K = 1 the classes of target j are the zero
    class plus one per position whose look at j counts."""
    from sensorplan.planners.information import plan_information, prepare

    problem = lattice_problem(21, n_sensors=1, n_targets=3, horizon=horizon, steps_per_epoch=2,
                           visibility=visibility, size=60.0, starts=[(30.0, 30.0)])
    ctx = prepare(problem)
    opts = bf._sensor_options(ctx, 0)
    chains = explicit_chains(problem, 0)
    seqs = list(itertools.product(range(3), repeat=horizon))
    assert opts.n_options == len(chains) * len(seqs)
    counted = np.zeros((3, len(chains)), dtype=bool)
    for o in range(opts.n_options):
        c, s = divmod(o, len(seqs))
        pos, tgt = opts.action(o)
        np.testing.assert_allclose(pos, chains[c], rtol=0, atol=1e-6)
        np.testing.assert_array_equal(tgt, seqs[s])
        W, _, counts = plan_information(ctx, Plan(pos[None], tgt[None]))
        for j in range(3):
            own = np.where((tgt == j)[:, None, None, None], W[0], 0.0).reshape(-1, 2, 2)
            np.testing.assert_allclose(opts.reps[j][opts.cls[j, o]], own, rtol=1e-12,
                                       atol=0.0)
        if horizon == 1:
            counted[tgt[0], c] |= counts[0, 0] > 0
    if horizon == 1:
        n_cls = [len(r) for r in opts.reps]
        assert n_cls == [1 + int(counted[j].sum()) for j in range(3)]
        assert counted.any() and (visibility == "probabilistic" or not counted.all())


def test_row_ids_exact_even_when_every_hash_collides() -> None:
    """With zero multipliers every row hashes to 0; the exact fallback must still give
    equal ids to equal rows only."""
    rng = np.random.default_rng(0)
    base = rng.normal(size=(6, 8))
    rows = base[rng.integers(0, 6, size=50)] + 0.0
    mult = bf._hash_constants(8)
    for m in (mult, np.zeros(8, dtype=np.uint64)):
        ids, n_ids = bf._row_ids(rows, m)
        assert n_ids == len(np.unique(rows, axis=0))
        same = ids[:, None] == ids[None, :]
        equal = (rows[:, None, :] == rows[None, :, :]).all(axis=2)
        np.testing.assert_array_equal(same, equal)
