"""The batched search utilities (:func:`search.candidate_potentials`, compiled search term
and cached looks) against the reference definition and against the implementation they
replaced: equal Phi to round-off, the same plans."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import search_reference
from sensorplan.models.radar.batch import detectable_points
from sensorplan.models.sensors import FOV
from sensorplan.planners import make_planner, search
from sensorplan.planners._search_nb import detect_sparse
from sensorplan.planners.contract_problems import paper_problem, searching, tiny_problem
from sensorplan.planners.problem import Plan, PlanningProblem


def partial_plan(sctx: search.SearchContext, rng: np.random.Generator) -> Plan:
    """A random feasible plan whose sensors leave their last epochs unassigned from a random
    epoch on (as the planners' plans are while they are built)."""
    plan = search.random_plan(sctx, rng)
    assert plan.sectors is not None
    N, K = plan.targets.shape
    off = np.arange(K)[None, :] >= rng.integers(0, K + 1, N)[:, None]
    pos = np.where(off[..., None], np.nan, plan.positions)
    return Plan(pos, np.where(off, -1, plan.targets), np.where(off, -1, plan.sectors))


def problems() -> list[PlanningProblem]:
    rng = np.random.default_rng(3)
    out = [searching(tiny_problem(rng, 2000), rng, int(rng.integers(1, 9)))
           for _ in range(6)]
    out.append(searching(paper_problem(rng, horizon=3, n_targets=4), rng, 12, cells=12))
    cum = paper_problem(rng, horizon=2, objective="cumulative", visibility="mean")
    out.append(searching(cum, rng, (5, 8, 12), cells=10))
    one = searching(paper_problem(rng, horizon=2, n_sensors=2, n_targets=1), rng, 6, cells=8)
    out.append(dataclasses.replace(one, means=np.zeros((0, 4)), covs=np.zeros((0, 4, 4)),
                                   existence=np.zeros(0)))
    return out


@pytest.mark.parametrize("problem", problems())
def test_utilities_equal_the_reference_phi(problem: PlanningProblem) -> None:
    """Every candidate of every player of random partial plans: the batched utility equals
    Phi of the plan with that action (:func:`search.evaluate`, plain numpy) to 1e-12."""
    sctx = search.prepare(problem)
    rng = np.random.default_rng(0)
    for _ in range(3):
        plan = partial_plan(sctx, rng)
        for i in range(problem.n_sensors):
            for k in range(1, problem.horizon + 1):
                if k > 1 and not plan.assigned[i, k - 2]:
                    break                    # no planner asks: its predecessor has no position
                pos, tgt, sec = search.player_actions(sctx, plan, i, k)
                u = search.candidate_potentials(sctx, plan, i, k, pos, tgt, sec)
                phi = np.array([search.evaluate(sctx, search.with_action(
                    plan, i, k, pos[a], int(tgt[a]), int(sec[a]))).potential
                    for a in range(len(tgt))])
                np.testing.assert_allclose(u, phi, rtol=1e-12, atol=1e-12)


def searching_problems() -> list[PlanningProblem]:
    rng = np.random.default_rng(5)
    out = []
    for n in (2, 3, 5):
        p = paper_problem(rng, horizon=3, n_sensors=n, n_targets=6)
        out.append(searching(p, rng, 12, cells=16))
    out += [searching(tiny_problem(rng, 2000), rng, 6) for _ in range(3)]
    return out


@pytest.mark.parametrize("problem", searching_problems())
def test_plans_are_those_of_the_replaced_implementation(
        problem: PlanningProblem, monkeypatch: pytest.MonkeyPatch) -> None:
    """pg (two seeds) and sequential-greedy plan exactly as with the plain-numpy utilities
    they replaced (``tests/search_reference.py``), with Phi equal to 1e-12."""
    runs = [("pg", 0), ("pg", 1), ("sequential-greedy", 0)]
    fast = [make_planner(name).plan(problem, rng=seed) for name, seed in runs]
    monkeypatch.setattr(search, "candidate_potentials", search_reference.candidate_potentials)
    for (name, seed), got in zip(runs, fast):
        want = make_planner(name).plan(problem, rng=seed)
        for f in ("positions", "targets", "sectors"):
            np.testing.assert_array_equal(getattr(got.plan, f), getattr(want.plan, f))
        assert got.potential == pytest.approx(want.potential, rel=1e-12, abs=1e-12)
        assert (got.converged, got.sweeps) == (want.converged, want.sweeps)


TOWN = np.array([[200.0, 200.0, 300.0, 300.0, 40.0], [400.0, 100.0, 450.0, 350.0, 80.0]])


@pytest.mark.parametrize("kind", ["ideal", "swerling1 behind buildings"])
def test_the_look_pool_keeps_each_pose_once(kind: str) -> None:
    """A look's ``P_d v`` is computed once per pose, and its row equals :func:`search.detection`
    (the radar's dense evaluation) bit for bit, with and without buildings and detection."""
    rng = np.random.default_rng(1)
    problem = searching(paper_problem(rng, horizon=2), rng, 12, cells=12)
    if kind != "ideal":
        problem = dataclasses.replace(problem, buildings=TOWN, sensors=tuple(
            dataclasses.replace(s, detection="swerling1") for s in problem.sensors))
    sctx = search.prepare(problem)
    xy = np.array([[100.0, 200.0], [300.0, 300.0], [100.0, 200.0]])
    h = np.array([0.5, -2.0, 0.5])
    pool = search._pool(sctx)
    rows = pool.rows(sctx, 1, xy, h)
    assert rows[0] == rows[2] != rows[1] and pool.n_rows == 2
    again = pool.rows(sctx, 1, xy[::-1], h[::-1])
    np.testing.assert_array_equal(again, rows[::-1])
    assert pool.n_rows == 2
    assert pool.rows(sctx, 0, xy[:1], h[:1])[0] == 2          # another sensor, another look
    dense = search.detection(sctx, 1, xy, h)
    for b, r in enumerate(rows):
        idx, val = pool.row(int(r))
        got = np.zeros(len(sctx.centres))
        got[idx] = val
        np.testing.assert_array_equal(got, dense[b])
        assert np.all(val > 0)
    # Many random poses, the cells near the band's and the wedge's edges among them.
    xy = rng.uniform(0.0, 600.0, (200, 2))
    h = rng.uniform(-np.pi, np.pi, 200)
    rows = pool.rows(sctx, 2, xy, h)
    dense = search.detection(sctx, 2, xy, h)
    assert (dense > 0).any() and (dense[dense > 0] < 1).any() == (kind != "ideal")
    for b, r in enumerate(rows):
        idx, val = pool.row(int(r))
        got = np.zeros(len(sctx.centres))
        got[idx] = val
        np.testing.assert_array_equal(got, dense[b])


@pytest.mark.parametrize("kind", ["ideal", "swerling1 behind buildings"])
def test_looks_from_one_position_are_the_dense_detection(kind: str) -> None:
    """Runs of looks from one position (the position's part of the radar's tests computed
    once) give :func:`search.detection`'s values bit for bit: many headings per position,
    signed zeros, positions on cell centres and cells on the band's and wedge's edges."""
    rng = np.random.default_rng(4)
    problem = searching(paper_problem(rng, horizon=2), rng, 12, cells=16)
    if kind != "ideal":
        problem = dataclasses.replace(problem, buildings=TOWN, sensors=tuple(
            dataclasses.replace(s, detection="swerling1") for s in problem.sensors))
    sctx = search.prepare(problem)
    centres = sctx.centres
    spots = np.concatenate([rng.uniform(0.0, 600.0, (6, 2)), centres[[0, 37, 100]],
                            [[0.0, 300.0], [-0.0, 300.0], [0.0, -0.0]]])
    xy = np.repeat(spots, 40, axis=0)
    h = np.concatenate([rng.uniform(-np.pi, np.pi, 30), [0.0, -0.0, np.pi, -np.pi],
                        np.arange(6) * np.pi / 3] * len(spots))
    # Headings that put cells on the wedge's edges.
    g = centres[None, 5] - spots[:, None]
    edge = np.arctan2(g[..., 1], g[..., 0])[:, 0] + float(sctx.ctx.radar[0][FOV])
    h[::40] = edge
    counts, idx, val = detect_sparse(sctx.ctx.radar[0], centres, xy, h,
                                        sctx.ctx.buildings)
    dense = search.detection(sctx, 0, xy, h)
    starts = np.concatenate([[0], np.cumsum(counts)])
    for b in range(len(h)):
        got = np.zeros(len(centres))
        got[idx[starts[b]:starts[b + 1]]] = val[starts[b]:starts[b + 1]]
        np.testing.assert_array_equal(got, dense[b])
        assert np.all(np.diff(idx[starts[b]:starts[b + 1]]) > 0)
    assert (dense > 0).any()


def test_the_look_pool_keeps_its_rows_when_its_table_grows() -> None:
    """Poses entered before the pose table grows keep their rows; every pose is found again,
    a signed zero's pose is another pose (as the bytes of a pose are)."""
    rng = np.random.default_rng(5)
    problem = searching(paper_problem(rng, horizon=2), rng, 12, cells=8)
    sctx = search.prepare(problem)
    pool = search._pool(sctx)
    batches = [(rng.integers(0, 3), rng.uniform(0.0, 600.0, (700, 2)),
                rng.uniform(-np.pi, np.pi, 700)) for _ in range(8)]
    first = [pool.rows(sctx, int(n), xy, h) for n, xy, h in batches]
    assert pool.n_rows == 8 * 700 and len(pool.vals) >= 2 * pool.n_rows
    np.testing.assert_array_equal(np.concatenate(first), np.arange(8 * 700))
    for (n, xy, h), rows in zip(batches[::-1], first[::-1]):
        np.testing.assert_array_equal(pool.rows(sctx, int(n), xy, h), rows)
        # Each batch's rows, written in place after the earlier ones, are its own looks'.
        counts, idx, val = detect_sparse(sctx.ctx.radar[n], sctx.centres, xy, h,
                                         sctx.ctx.buildings)
        starts = np.concatenate([[0], np.cumsum(counts)])
        for b, r in enumerate(rows.tolist()):
            got_idx, got_val = pool.row(r)
            np.testing.assert_array_equal(got_idx, idx[starts[b]:starts[b + 1]])
            np.testing.assert_array_equal(got_val, val[starts[b]:starts[b + 1]])
    assert pool.n_rows == 8 * 700
    zero = pool.rows(sctx, 0, np.array([[0.0, 100.0], [-0.0, 100.0], [0.0, 100.0]]),
                     np.array([0.0, 0.0, -0.0]))
    assert len(set(zero.tolist())) == 3 and pool.n_rows == 8 * 700 + 3


@pytest.mark.parametrize("fov", [np.pi / 6, 2.0, np.pi])
def test_cells_near_the_wedge_edges_are_the_radars_decision(fov: float) -> None:
    """Cells within the wedge test's margin of an edge, either side (where
    :func:`detect_sparse_into_nb` takes the bearing's ``atan2`` instead of deciding by the
    cosine), and cells well inside or outside: the radar's own detection bit for bit, for a
    narrow, a wide (half-angle over 90 degrees) and an all-round field of view."""
    rng = np.random.default_rng(6)
    problem = searching(paper_problem(rng, horizon=2), rng, 12, cells=16)
    sctx = search.prepare(problem)
    centres = sctx.centres
    row = sctx.ctx.radar[0].copy()
    row[FOV] = fov
    spots = rng.uniform(0.0, 600.0, (4, 2))
    offsets = np.array([0.0, 1e-12, 1e-10, 5e-10, 2e-9, 1e-8, 1e-3])
    offsets = np.concatenate([offsets, -offsets[1:]])
    xy, h = [], []
    for spot in spots:
        for c in rng.choice(len(centres), 3, replace=False):
            g = centres[c] - spot
            for side in (1.0, -1.0):
                xy.append(np.repeat(spot[None], len(offsets), axis=0))
                h.append(np.arctan2(g[1], g[0]) + side * (fov + offsets))
    xy, h = np.concatenate(xy), np.concatenate(h)
    counts, idx, val = detect_sparse(row, centres, xy, h, sctx.ctx.buildings)
    dense = detectable_points(row[None], np.zeros(len(h), dtype=np.int64),
                              centres[None, :, 0] - xy[:, :1], centres[None, :, 1] - xy[:, 1:],
                              h, xy, sctx.ctx.buildings)
    starts = np.concatenate([[0], np.cumsum(counts)])
    for b in range(len(h)):
        got = np.zeros(len(centres))
        got[idx[starts[b]:starts[b + 1]]] = val[starts[b]:starts[b + 1]]
        np.testing.assert_array_equal(got, dense[b])
    assert (dense > 0).any() and (dense == 0).any()
