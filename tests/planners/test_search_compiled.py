"""The compiled parts of the search utilities and the search game's loop against the code
they replaced: the same bits kernel by kernel, and the same plans planner by planner (the
plain-numpy utilities of ``tests/search_reference.py`` and the loop of
``tests/search_game_reference.py`` as the oracle)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import search_game_reference
import search_reference
from sensorplan.models.angles import heading_rule, heading_rule_scalar, wrap_angle, wrap_scalar
from sensorplan.planners import make_planner, search
from sensorplan.planners._search_nb import (found_nb, heading_rule_nb, jsfp_steps_nb,
                                            look_information_nb, pair_terms_nb,
                                            player_pair_terms_nb)
from sensorplan.planners.contract_problems import paper_problem, searching
from sensorplan.planners.information import chain_information, cv_form
from sensorplan.planners.problem import Plan, PlanningProblem

TOWN = np.array([[200.0, 200.0, 300.0, 300.0, 40.0], [400.0, 100.0, 450.0, 350.0, 80.0]])


def swerling(problem: PlanningProblem) -> PlanningProblem:
    """``problem`` with Swerling 1 detection and two buildings (misses below 1 that vary)."""
    return dataclasses.replace(problem, buildings=TOWN, sensors=tuple(
        dataclasses.replace(s, detection="swerling1") for s in problem.sensors))


def decisions() -> list[tuple[str, PlanningProblem]]:
    """The search benchmark's decision (3 sensors, K = 3, e = 2, 8 targets, 12 sectors) on
    several seeds and grids, a cumulative one, and one with detection and buildings."""
    out = []
    for seed, cells in ((0, 24), (1, 16), (2, 10)):
        rng = np.random.default_rng(seed)
        p = paper_problem(rng, horizon=3, steps_per_epoch=2, n_sensors=3, n_targets=8)
        out.append((f"seed {seed}", searching(p, rng, 12, cells=cells)))
    rng = np.random.default_rng(7)
    cum = paper_problem(rng, horizon=2, objective="cumulative", n_sensors=2, n_targets=4)
    out.append(("cumulative", searching(cum, rng, (6, 9), cells=10)))
    rng = np.random.default_rng(8)
    out.append(("swerling, buildings", swerling(searching(
        paper_problem(rng, horizon=3, n_sensors=3, n_targets=5), rng, 8, cells=12))))
    return out


DECISIONS = decisions()


def candidate_rows(sctx: search.SearchContext, plan: Plan, i: int, k: int,
                   headings: np.ndarray) -> tuple[list[int], np.ndarray]:
    """Player (i, k)'s candidate chains' look epochs (offsets from k - 1) and pool rows."""
    pos, tgt, sec = search.player_actions(sctx, plan, i, k)
    chains = search.candidate_chains(sctx, plan, i, k, pos, tgt, sec, headings)
    ls = [l for l in range(sctx.ctx.K - k + 1) if l == 0 or chains[2][0, l]]
    pool = search._pool(sctx)
    return ls, np.stack([pool.rows(sctx, i, chains[0][:, l], chains[3][:, l]) for l in ls],
                        axis=1)


def found(*args: object) -> np.ndarray:
    """:func:`found_nb`'s mu of a first call (nothing kept from an earlier one)."""
    return found_nb(*args, False, *search.NO_FOUND)[0]


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_plans_are_those_of_the_reference(name: str, problem: PlanningProblem,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """pg (two seeds), sequential-greedy and dec-jsfp plan exactly as with the plain-numpy
    utilities and the game loop before its utilities were kept per player: the same plans,
    sweeps and convergence, Phi and each sweep's Phi equal to 1e-12."""
    runs = [("pg", 0), ("pg", 1), ("sequential-greedy", 0), ("dec-jsfp", 0)]
    fast = [make_planner(planner).plan(problem, rng=seed) for planner, seed in runs]
    monkeypatch.setattr(search, "candidate_potentials", search_reference.candidate_potentials)
    monkeypatch.setattr(search, "potential_game", search_game_reference.potential_game)
    for (planner, seed), got in zip(runs, fast):
        want = make_planner(planner).plan(problem, rng=seed)
        for f in ("positions", "targets", "sectors"):
            np.testing.assert_array_equal(getattr(got.plan, f), getattr(want.plan, f))
        assert got.potential == pytest.approx(want.potential, rel=1e-12, abs=1e-12)
        assert (got.converged, got.sweeps) == (want.converged, want.sweeps)
        np.testing.assert_allclose(got.trace, want.trace, rtol=1e-12, atol=1e-12)


def test_the_scalar_heading_rule_is_numpys_bit_for_bit() -> None:
    """The plain-Python and the compiled heading rule (and wrap) give numpy's bits, the
    edges of (-pi, pi] and zero turn limits among the inputs."""
    rng = np.random.default_rng(0)
    edges = [np.pi, -np.pi, 0.0, -0.0, 2 * np.pi, -2 * np.pi, 3 * np.pi,
             np.nextafter(np.pi, 4.0), np.nextafter(-np.pi, -4.0), 1e-300]
    a = np.concatenate([rng.uniform(-10.0, 10.0, 20_000), edges])
    want = wrap_angle(a)
    got = np.array([wrap_scalar(x) for x in a.tolist()])
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
    th = np.concatenate([rng.uniform(-4.0, 4.0, 20_000), edges])
    b = np.concatenate([rng.uniform(-4.0, 4.0, 20_000), edges[::-1]])
    m = rng.choice([0.0, 0.3, np.pi / 4, np.pi, 2 * np.pi], th.size)
    want = heading_rule(th, b, m)
    got = np.array([heading_rule_scalar(*x) for x in zip(th.tolist(), b.tolist(), m.tolist())])
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
    for turn in (0.0, 0.3, np.pi / 4, np.pi, 2 * np.pi):
        np.testing.assert_array_equal(heading_rule_nb(th, b, turn).view(np.int64),
                                      heading_rule(th, b, turn).view(np.int64))


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_look_information_is_chain_informations(name: str, problem: PlanningProblem) -> None:
    """The compiled track information of looks equals :func:`chain_information`'s bit for
    bit, sector looks (target -1) left as they were."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(1)
    B = 50
    for i in range(ctx.N):
        for kk in range(1, ctx.K + 1):
            pos = rng.uniform(0.0, 600.0, (B, 2))
            th = rng.uniform(-np.pi, np.pi, B)
            tgt = rng.integers(-1, ctx.M, B)
            W = np.full((B, ctx.e, 2, 2), 7.0)
            weight = np.full((B, ctx.e), 7.0)
            look_information_nb(ctx.radar, np.full(B, i), ctx.buildings, ctx.xbar, ctx.Cbar,
                                pos, th, tgt, np.full(B, kk), ctx.probabilistic, W, weight)
            want, counted = chain_information(ctx, i, kk, pos[:, None], th[:, None],
                                              np.maximum(tgt, 0)[:, None])
            track = tgt >= 0
            np.testing.assert_array_equal(W[track], want[track, 0])
            np.testing.assert_array_equal(weight[track] > 0, counted[track, 0])
            assert np.all(W[~track] == 7.0) and np.all(weight[~track] == 7.0)


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
@pytest.mark.parametrize("shared_q", [True, False])
def test_pair_terms_are_the_numpy_steps(name: str, problem: PlanningProblem,
                                        shared_q: bool) -> None:
    """The compiled (candidate, target) terms equal their numpy computation bit for bit:
    chains looking at one target twice, at none, existence below 1, one process noise per
    target or a shared one."""
    rng = np.random.default_rng(2)
    problem = dataclasses.replace(problem, existence=rng.uniform(0.3, 1.0, problem.n_targets))
    ctx = search.prepare(problem).ctx
    if not shared_q:
        ctx = dataclasses.replace(ctx, Q=ctx.Q * rng.uniform(0.5, 2.0, (ctx.M, 1, 1)))
    for k in range(1, ctx.K + 1):
        A, L = 40, ctx.K - k + 1
        base = np.zeros((ctx.M, ctx.T, 2, 2))
        G = rng.normal(0.0, 0.05, (ctx.M, ctx.T, 2, 2))
        base += G @ np.swapaxes(G, -1, -2) * (rng.random((ctx.M, ctx.T, 1, 1)) < 0.5)
        base_terms = search._target_terms(ctx, base, np.arange(ctx.M))
        tgt = rng.integers(-1, ctx.M, (A, L))
        tgt[0, :] = tgt[0, 0]                          # one target looked at in every epoch
        G = rng.normal(0.0, 0.05, (A, L, ctx.e, 2, 2))
        w = np.where((tgt >= 0)[..., None, None, None], G @ np.swapaxes(G, -1, -2), 0.0)
        want = search.pair_terms_numpy(ctx, base, base_terms, tgt, w, k)
        cumulative = ctx.problem.objective == "cumulative"
        ld_ref = ctx.ld_bar[:, 1:].sum(axis=-1) if cumulative else ctx.ld_bar[:, -1]
        got = pair_terms_nb(base, tgt, w, k - 1,
                            np.ascontiguousarray(ctx.problem.covs), ctx.F,
                            np.ascontiguousarray(ctx.Q), cumulative, *cv_form(ctx.F),
                            np.ascontiguousarray(ld_ref), np.ascontiguousarray(ctx.existence))
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_found_of_a_batch_is_each_candidates_alone(name: str, problem: PlanningProblem
                                                    ) -> None:
    """mu of candidates in one batch (whose cells' changes are kept for the next candidate)
    equals each candidate's computed alone bit for bit, and the reference mu to 1e-12."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(3)
    plan = search.random_plan(sctx, rng)
    headings = search.plan_headings(sctx, plan)
    pool = search._pool(sctx)
    n_look, k_look = np.nonzero(plan.assigned)
    row = np.concatenate([pool.rows(sctx, int(n), plan.positions[n, k_look[n_look == n]],
                                    headings[n, k_look[n_look == n]])
                          for n in np.unique(n_look)])
    for i in range(ctx.N):
        for k in range(1, ctx.K + 1):
            ls, rows = candidate_rows(sctx, plan, i, k, headings)
            rows = np.concatenate([rows, rows[::3]])   # repeated candidates among them
            other = (n_look != i) | (k_look < k - 1)
            args = (sctx.d0, sctx.births, sctx.survival, ctx.e, ctx.K, k - 1, i, n_look,
                    k_look, row)
            epochs = np.array(ls, dtype=np.int64) + (k - 1)
            batch = found(*args, rows, epochs, *pool.arrays())
            alone = np.array([found(*args, rows[a:a + 1], epochs, *pool.arrays())[0]
                              for a in range(len(rows))])
            np.testing.assert_array_equal(batch.view(np.int64), alone.view(np.int64))
            miss = np.ones((len(rows), ctx.K, len(sctx.centres)))
            for q in np.flatnonzero(other):
                idx, val = pool.row(int(row[q]))
                miss[:, k_look[q], idx] *= 1.0 - val
            for a in range(len(rows)):
                for q, l in enumerate(ls):
                    idx, val = pool.row(int(rows[a, q]))
                    miss[a, k - 1 + l, idx] *= 1.0 - val
            np.testing.assert_allclose(batch, search.expected_found(sctx, miss), rtol=1e-12,
                                       atol=1e-12)


def numpy_player_actions(sctx: search.SearchContext, plan, i: int, k: int) -> tuple:
    """Player (i, k)'s actions from :func:`search.sector_actions` and
    :func:`search.player_positions` (the numpy steps :func:`player_actions_nb` replaces)."""
    if k == 1:
        prev_h, prev_ok = float(sctx.ctx.problem.headings[i]), True
    else:
        prev_ok = bool(plan.assigned[i, k - 2])
        prev_h = float(search.plan_headings(sctx, plan)[i, k - 2]) if prev_ok else 0.0
    sectors = search.sector_actions(sctx, i, k, prev_h, prev_ok)
    pos = search.player_positions(sctx, plan, i, k)
    M = sctx.ctx.M
    looks_t = np.concatenate([np.arange(M), np.full(sectors.size, -1)])
    looks_s = np.concatenate([np.full(M, -1), sectors])
    return (np.repeat(pos, looks_t.size, axis=0), np.tile(looks_t, len(pos)),
            np.tile(looks_s, len(pos)))


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_player_actions_are_those_of_the_numpy_steps(name: str,
                                                     problem: PlanningProblem) -> None:
    """:func:`player_actions_nb` (through :func:`search.player_actions`) gives every player's
    actions of random and partial plans as :func:`search.sector_actions` and
    :func:`search.player_positions` do, bit for bit: positions at the map's edge, sector
    headings the turn limit merges, unassigned neighbouring epochs."""
    rng = np.random.default_rng(11)
    sctx = search.prepare(problem)
    plans = []
    for _ in range(6):
        plan = search.random_plan(sctx, rng)
        N, K = plan.targets.shape
        off = np.arange(K)[None, :] >= rng.integers(0, K + 1, N)[:, None]
        off |= rng.random((N, K)) < 0.2
        plans.append(type(plan)(np.where(off[..., None], np.nan, plan.positions),
                                np.where(off, -1, plan.targets), np.where(off, -1, plan.sectors)))
    # Sensors on the map's corners and edges: moves that leave the map.
    edge = search.random_plan(sctx, rng)
    corners = np.array([[0.0, 0.0], [problem.world.width, 0.5 * problem.world.height],
                        [-0.0, problem.world.height]])
    pos = edge.positions.copy()
    pos[:, 0] = corners[np.arange(len(pos)) % 3]
    plans.append(type(edge)(pos, edge.targets, edge.sectors))
    n_merged = n_cut = 0
    for plan in plans:
        for i in range(sctx.ctx.N):
            for k in range(1, sctx.ctx.K + 1):
                got = search.player_actions(dataclasses.replace(sctx, memo={}), plan, i, k)
                want = numpy_player_actions(sctx, plan, i, k)
                for g, w in zip(got, want):
                    assert g.dtype == w.dtype and g.shape == w.shape
                    assert g.tobytes() == w.tobytes()
                n_sec = int(np.unique(want[2][want[2] >= 0]).size)
                n_merged += n_sec < sctx.bearings[i].size
                n_pos = len(np.unique(want[0], axis=0))
                n_cut += n_pos < len(search.move_vectors(problem.sensors[i].moves))
    assert n_merged > 0 and n_cut > 0


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_evaluate_from_the_kept_looks_is_the_numpy_definition(
        name: str, problem: PlanningProblem, monkeypatch: pytest.MonkeyPatch) -> None:
    """:func:`search.evaluate` from the compiled track information and the look pool gives
    the plain-numpy definition's Phi, information, mu, headings and measurements bit for
    bit, on random and partial plans (a decision's pool shared by the plans)."""
    rng = np.random.default_rng(12)
    sctx = search.prepare(problem)
    plans = []
    for _ in range(8):
        plan = search.random_plan(sctx, rng)
        N, K = plan.targets.shape
        off = rng.random((N, K)) < 0.3
        plans.append(type(plan)(np.where(off[..., None], np.nan, plan.positions),
                                np.where(off, -1, plan.targets), np.where(off, -1, plan.sectors)))
    plans.append(make_planner("pg").plan(problem, rng=0).plan)
    for plan in plans:
        got = search.evaluate(sctx, plan)
        monkeypatch.setattr(search, "BACKEND", "numpy")
        want = search.evaluate(dataclasses.replace(sctx, memo={}), plan)
        monkeypatch.setattr(search, "BACKEND", "numba")
        assert got.potential == want.potential and got.found == want.found
        for g, w in ((got.information, want.information), (got.headings, want.headings),
                     (got.measurements, want.measurements)):
            assert g.dtype == w.dtype and g.shape == w.shape
            np.testing.assert_array_equal(g, w)
            assert g.tobytes() == w.tobytes() or np.isnan(w).any()


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_found_of_one_look_is_the_general_paths(name: str, problem: PlanningProblem) -> None:
    """mu of candidates whose chain has one look (the kernel's direct path) equals, bit for
    bit, mu of the same chains with a second look that covers no cell (the general path,
    each cell's cover counted)."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(13)
    plan = search.random_plan(sctx, rng)
    headings = search.plan_headings(sctx, plan)
    pool = search._pool(sctx)
    n_look, k_look = np.nonzero(plan.assigned)
    row = np.concatenate([pool.rows(sctx, int(n), plan.positions[n, k_look[n_look == n]],
                                    headings[n, k_look[n_look == n]])
                          for n in np.unique(n_look)])
    for i in range(ctx.N):
        empty = pool.rows(sctx, i, np.array([[1e7, 1e7]]), np.array([0.0]))[0]
        assert pool.row(int(empty))[0].size == 0
        pos, tgt, sec = search.player_actions(sctx, plan, i, 1)
        chains = search.candidate_chains(sctx, plan, i, 1, pos, tgt, sec, headings)
        first = pool.rows(sctx, i, chains[0][:, 0], chains[3][:, 0])
        args = (sctx.d0, sctx.births, sctx.survival, ctx.e, ctx.K, 0, i, n_look, k_look, row)
        epochs = np.array([0, 1], dtype=np.int64)
        one = np.stack([first, np.full_like(first, -1)], axis=1)
        two = np.stack([first, np.full_like(first, empty)], axis=1)
        got = found(*args, one, epochs, *pool.arrays())
        want = found(*args, two, epochs, *pool.arrays())
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
        assert got.size and np.isfinite(got).all()


def test_jsfp_steps_are_the_numpy_update_and_best_index() -> None:
    """:func:`jsfp_steps_nb` updates each player's running average as
    ``(t - 1) / t * ubar + u / t`` does and picks the actions :func:`search.best_index`
    picks, bit for bit: ties within the tolerance, the current action kept, values near 1
    and far from it, NaN."""
    rng = np.random.default_rng(14)
    for _ in range(100):
        sizes = rng.integers(1, 40, int(rng.integers(1, 6)))
        off = np.concatenate([[0], np.cumsum(sizes)])
        us, ubars, currents = [], [], []
        for n in sizes.tolist():
            scale = float(rng.choice([1e-3, 1.0, 1e4]))
            u = rng.normal(0.0, scale, n)
            u[rng.random(n) < 0.3] = u.max() - rng.choice([0.0, 1e-13, 1e-11]) * max(1, scale)
            if rng.random() < 0.05:
                u[rng.integers(n)] = np.nan
            us.append(u)
            ubars.append(rng.normal(0.0, scale, n))
            currents.append(int(rng.integers(-1, n)))
        t = int(rng.integers(1, 30))
        ubar = np.concatenate(ubars)
        now, avg = jsfp_steps_nb(np.concatenate(us), ubar, off, t, np.array(currents),
                                 search.TIE_TOL)
        for p, (u, old, current) in enumerate(zip(us, ubars, currents)):
            want_avg = (t - 1) / t * old + u / t
            assert ubar[off[p]:off[p + 1]].tobytes() == want_avg.tobytes()
            for got, arr in ((now[p], u), (avg[p], want_avg)):
                try:
                    want = search.best_index(arr, current)
                except IndexError:
                    want = -1
                assert got == want


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_a_players_terms_are_summed_information_and_pair_terms(
        name: str, problem: PlanningProblem) -> None:
    """:func:`player_pair_terms_nb` sums the others' information as
    :func:`information.sum_by_target` does and gives :func:`pair_terms_nb`'s terms, bit for
    bit, afresh and from its last call's terms when some of the others' looks changed."""
    rng = np.random.default_rng(15)
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    cumulative = ctx.problem.objective == "cumulative"
    ld_ref = ctx.ld_bar[:, 1:].sum(axis=-1) if cumulative else ctx.ld_bar[:, -1]
    fixed = (np.ascontiguousarray(ctx.problem.covs), ctx.F, np.ascontiguousarray(ctx.Q),
             cumulative, *cv_form(ctx.F), np.ascontiguousarray(ld_ref),
             np.ascontiguousarray(ctx.existence))
    for i in range(ctx.N):
        for k in range(1, ctx.K + 1):
            A, L = 40, ctx.K - k + 1
            tgt = rng.integers(-1, ctx.M, (A, L))
            G = rng.normal(0.0, 0.05, (A, L, ctx.e, 2, 2))
            w = np.where((tgt >= 0)[..., None, None, None], G @ np.swapaxes(G, -1, -2), 0.0)
            prev = prev_targets = prev_W = None
            for step in range(4):
                targets = rng.integers(-1, ctx.M, (ctx.N, ctx.K))
                G = rng.normal(0.0, 0.05, (ctx.N, ctx.K, ctx.e, 2, 2))
                W = np.where((targets >= 0)[..., None, None, None], G @ np.swapaxes(G, -1, -2),
                             0.0)
                if prev is not None and step % 2:
                    # Only some of the others' looks move: their targets' terms change.
                    keep = rng.random((ctx.N, ctx.K)) < 0.7
                    targets = np.where(keep, prev_targets, targets)
                    W = np.where(keep[..., None, None, None], prev_W, W)
                others = targets.copy()
                others[i, k - 1:] = -1
                base = search.sum_by_target(ctx, W, others)
                want = pair_terms_nb(base, tgt, w, k - 1, *fixed)
                has = prev is not None
                got, got_base = player_pair_terms_nb(
                    W, targets, i, k - 1, tgt, w, *fixed, has,
                    prev[1] if has else np.zeros((0, 0, 2, 2)),
                    prev[0] if has else np.zeros((0, 0)))
                assert got_base.tobytes() == base.tobytes()
                np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
                prev, prev_targets, prev_W = (got, got_base), targets, W


def found_in_order(args: tuple, rows: np.ndarray, epochs: np.ndarray, pool) -> np.ndarray:
    """mu of each candidate as :func:`found_nb` defines its order, in plain Python: the
    others' misses, mu before k0, each cell's tail; then per candidate the cells in the
    order they first appear look by look, each cell's change from its tail with the chain's
    misses there, summed in that order."""
    from sensorplan.planners._search_nb import _cell_tail

    d0, births, survival, e, K, k0, player, n_look, k_look, row = args
    C = len(d0)
    miss = np.ones((K, C))
    for q in range(len(row)):
        if n_look[q] == player and k_look[q] >= k0:
            continue
        idx, val = pool.row(int(row[q]))
        for c, v in zip(idx.tolist(), val.tolist()):
            miss[k_look[q], c] *= 1.0 - v
    d_k0, mu_pre = d0.copy(), 0.0
    for kk in range(k0):
        for c in range(C):
            d, m = d_k0[c], miss[kk, c]
            for _ in range(e):
                d = survival * d + births[c]
                mu_pre += d * (1.0 - m)
                d = d * m
            d_k0[c] = d
    L = K - k0
    tail = np.array([_cell_tail(d_k0[c], births[c], survival, e, miss, k0, c, np.ones(L))
                     for c in range(C)])
    tail_sum = 0.0
    for c in range(C):
        tail_sum += tail[c]
    base = mu_pre + tail_sum
    out = np.empty(len(rows))
    for a in range(len(rows)):
        chain: dict[int, np.ndarray] = {}
        for l in range(rows.shape[1]):
            if rows[a, l] < 0:
                continue
            idx, val = pool.row(int(rows[a, l]))
            for c, v in zip(idx.tolist(), val.tolist()):
                chain.setdefault(c, np.ones(L))[epochs[l] - k0] = 1.0 - v
        delta = 0.0
        for c, ch in chain.items():                  # first appearance, look by look
            delta += _cell_tail(d_k0[c], births[c], survival, e, miss, k0, c, ch) - tail[c]
        out[a] = base + delta
    return out


@pytest.mark.parametrize("name,problem", DECISIONS[1:], ids=[n for n, _ in DECISIONS[1:]])
def test_found_is_its_order_in_plain_python(name: str, problem: PlanningProblem) -> None:
    """found_nb's mu (one-look chains by the direct path, several looks by the first look's
    cells first) equals the plain-Python sum in its defining order bit for bit, on plans
    whose later epochs are assigned (chains of several looks that overlap) and not."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(17)
    pool = search._pool(sctx)
    for trial in range(2):
        plan = search.random_plan(sctx, rng)
        if trial:
            plan = type(plan)(plan.positions, np.where(np.arange(ctx.K) >= 2, -1, plan.targets),
                              np.where(np.arange(ctx.K) >= 2, -1, plan.sectors))
        headings = search.plan_headings(sctx, plan)
        n_look, k_look = np.nonzero(plan.assigned)
        row = np.concatenate([pool.rows(sctx, int(n), plan.positions[n, k_look[n_look == n]],
                                        headings[n, k_look[n_look == n]])
                              for n in np.unique(n_look)])
        for i in range(min(ctx.N, 2)):
            for k in range(1, ctx.K + 1):
                ls, rows = candidate_rows(sctx, plan, i, k, headings)
                epochs = np.array(ls, dtype=np.int64) + (k - 1)
                args = (sctx.d0, sctx.births, sctx.survival, ctx.e, ctx.K, k - 1, i,
                        np.ascontiguousarray(n_look), np.ascontiguousarray(k_look), row)
                got = found(*args, rows, epochs, *pool.arrays())
                want = found_in_order(args, rows, epochs, pool)
                np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_found_from_a_kept_call_is_a_first_calls(name: str, problem: PlanningProblem) -> None:
    """found_nb with what a player's last call kept (its candidates as before, the others'
    looks changed in one sensor, in none, in several, in every one) gives a first call's
    mu and kept misses and mu of the others, bit for bit."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(29)
    pool = search._pool(sctx)

    def planned(plan) -> tuple:
        headings = search.plan_headings(sctx, plan)
        n_look, k_look = np.nonzero(plan.assigned)
        row = np.concatenate([pool.rows(sctx, int(n), plan.positions[n, k_look[n_look == n]],
                                        headings[n, k_look[n_look == n]])
                              for n in np.unique(n_look)])
        return np.ascontiguousarray(n_look), np.ascontiguousarray(k_look), row

    first = search.random_plan(sctx, rng)
    headings = search.plan_headings(sctx, first)
    for i in range(ctx.N):
        for k in range(1, ctx.K + 1):
            ls, rows = candidate_rows(sctx, first, i, k, headings)
            rows = np.concatenate([rows, rows[::3]])   # repeated candidates among them
            epochs = np.array(ls, dtype=np.int64) + (k - 1)
            fixed = (sctx.d0, sctx.births, sctx.survival, ctx.e, ctx.K, k - 1, i)
            plan, kept = first, None
            for change in ("one", "none", "several", "every", "one"):
                if change != "none":
                    other = search.random_plan(sctx, rng)
                    moved = {"one": [(i + 1) % ctx.N], "several": [i, (i + 1) % ctx.N],
                             "every": list(range(ctx.N))}[change]
                    assert plan.sectors is not None and other.sectors is not None
                    pos_, tgt_, sec_ = (plan.positions.copy(), plan.targets.copy(),
                                        plan.sectors.copy())
                    for n in moved:
                        pos_[n], tgt_[n], sec_[n] = (other.positions[n], other.targets[n],
                                                     other.sectors[n])
                    plan = type(plan)(pos_, tgt_, sec_)
                args = (*fixed, *planned(plan), rows, epochs, *pool.arrays())
                want = found_nb(*args, False, *search.NO_FOUND)
                if kept is not None:
                    got = found_nb(*args, True, *kept)
                    np.testing.assert_array_equal(got[0].view(np.int64),
                                                  want[0].view(np.int64))
                    assert got[1].tobytes() == want[1].tobytes() and got[3] == want[3]
                    assert got[4].tobytes() == want[4].tobytes()
                    want = got
                kept = want[1:]


@pytest.mark.parametrize("name,problem", DECISIONS, ids=[n for n, _ in DECISIONS])
def test_a_switched_plans_kept_parts_are_a_fresh_plans(name: str, problem: PlanningProblem
                                                        ) -> None:
    """A plan switched from another (its headings, track looks and planned looks spliced
    from that plan's) keeps the same arrays, bit for bit, as the plan computed afresh."""
    sctx = search.prepare(problem)
    ctx = sctx.ctx
    rng = np.random.default_rng(31)
    # From no looks, as sequential-greedy (players assigned one by one), then any player.
    plan = Plan.empty(ctx.N, ctx.K)
    order = [(i, k) for k in range(1, ctx.K + 1) for i in range(ctx.N)]
    order += [(int(rng.integers(ctx.N)), int(rng.integers(1, ctx.K + 1))) for _ in range(6)]
    for i, k in order:
        # What candidate_potentials keeps with the plan, then a switch of one player.
        headings = search._plan_headings(sctx, plan)
        search._plan_track_looks(sctx, plan, headings)
        search._planned_looks(sctx, plan, headings, search._plan_memo(sctx, plan))
        pos, tgt, sec = search.player_actions(sctx, plan, i, k)
        b = int(rng.integers(len(tgt)))
        plan = search._switched(sctx, plan, i, k, pos[b], int(tgt[b]), int(sec[b]))
        assert "came_from" in search._plan_memo(sctx, plan)
        fresh = dataclasses.replace(sctx, memo={})
        got_h = search._plan_headings(sctx, plan)
        want_h = search._plan_headings(fresh, plan)
        assert got_h.tobytes() == want_h.tobytes()
        got_w = search._plan_track_looks(sctx, plan, got_h)
        want_w = search._plan_track_looks(fresh, plan, want_h)
        for g, w in zip(got_w, want_w):
            assert g.dtype == w.dtype and g.shape == w.shape and g.tobytes() == w.tobytes()
        got_l = search._planned_looks(sctx, plan, got_h, search._plan_memo(sctx, plan))
        want_l = search._planned_looks(fresh, plan, want_h, search._plan_memo(fresh, plan))
        # The pools number rows in their own order: compare the rows' cells and values.
        assert [g.tobytes() for g in got_l[:2]] == [w.tobytes() for w in want_l[:2]]
        for rg, rw in zip(got_l[2].tolist(), want_l[2].tolist()):
            for g, w in zip(search._pool(sctx).row(rg), search._pool(fresh).row(rw)):
                assert g.tobytes() == w.tobytes()
