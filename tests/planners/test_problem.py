"""Moves, reachable sets, plans and the problem value."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.planners.problem import (MapRect, Plan, PlanningProblem, build_lattice, check_plan,
                                         move_vectors)
from sensorplan.models.sensors import SensorParams

TOL = 1e-6
SPEC_DIRS = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)]


def test_move_vectors_in_spec_order():
    mv = move_vectors((20.0, 40.0))
    want = [(0, 0)] + [(20 * a, 20 * b) for a, b in SPEC_DIRS] + [(40 * a, 40 * b)
                                                                  for a, b in SPEC_DIRS]
    np.testing.assert_array_equal(mv, np.array(want, dtype=float))
    lengths = np.hypot(mv[:, 0], mv[:, 1])
    np.testing.assert_allclose(lengths[1:9], [20, 20 * math.sqrt(2)] * 4, rtol=1e-15)
    assert move_vectors((15.0,)).shape == (9, 2)


def test_map_is_closed():
    w = MapRect(600.0, 400.0)
    inside = np.array([[0, 0], [600, 400], [600, 0], [0, 400], [300, 200], [600 + 1e-8, 0]])
    outside = np.array([[-1e-5, 0], [600 + 1e-5, 10], [10, 400 + 1e-5], [10, -1]])
    assert w.contains(inside).all()
    assert not w.contains(outside).any()


# --------------------------------------------------------------------------- reachable sets

def _dedupe(points: np.ndarray) -> np.ndarray:
    out: list[np.ndarray] = []
    for p in points:
        if not out or np.abs(np.array(out) - p).max(axis=1).min() > TOL:
            out.append(p)
    return np.array(out).reshape(-1, 2)


def _inside(p, world):
    return (-TOL <= p[0] <= world.width + TOL) and (-TOL <= p[1] <= world.height + TOL)


def brute_reachable(p0, distances, k, world) -> np.ndarray:
    """Ends of every k-move sequence whose every intermediate position is in the map."""
    moves = [(0.0, 0.0)] + [(s * a, s * b) for s in distances for a, b in SPEC_DIRS]
    ends = []
    for seq in itertools.product(range(len(moves)), repeat=k):
        x, y = float(p0[0]), float(p0[1])
        ok = True
        for m in seq:
            x, y = x + moves[m][0], y + moves[m][1]
            if not _inside((x, y), world):
                ok = False
                break
        if ok:
            ends.append((x, y))
    return _dedupe(np.array(ends))


def _same_set(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b)
    d = np.abs(a[:, None, :] - b[None, :, :]).max(axis=2)
    assert (d.min(axis=1) <= TOL).all() and (d.min(axis=0) <= TOL).all()


CASES = [
    ((300.3, 299.7), (20.0, 40.0), MapRect()),       # interior
    ((0.0, 0.0), (20.0, 40.0), MapRect()),           # corner
    ((600.0, 600.0), (20.0, 40.0), MapRect()),       # opposite corner
    ((560.0, 40.0), (20.0, 40.0), MapRect()),        # +40 lands exactly on the edge
    ((5.0, 595.0), (20.0,), MapRect()),              # near a corner, one move distance
    ((250.0, 250.0), (20.0,), MapRect()),            # interior, one move distance
    ((10.0, 25.0), (20.0, 40.0), MapRect(50.0, 30.0)),  # a tiny map
    ((0.0, 0.0), (13.0, 29.0), MapRect(100.0, 80.0)),   # incommensurate distances
]


@pytest.mark.parametrize("p0,distances,world", CASES)
def test_reachable_sets_equal_brute_force(p0, distances, world):
    K = 3
    lat = build_lattice(np.array(p0), move_vectors(distances), K, world)
    assert len(lat.positions) == K + 1
    np.testing.assert_allclose(lat.positions[0], [p0], atol=0)
    for k in range(1, K + 1):
        _same_set(lat.positions[k], brute_reachable(p0, distances, k, world))
        # no duplicates within the lattice itself
        assert len(_dedupe(lat.positions[k])) == len(lat.positions[k])


@pytest.mark.parametrize("p0,distances,world", CASES)
def test_parent_and_child_tables_are_consistent(p0, distances, world):
    K = 3
    mv = move_vectors(distances)
    lat = build_lattice(np.array(p0), mv, K, world)
    for k in range(1, K + 1):
        prev, cur = lat.positions[k - 1], lat.positions[k]
        ch, pm = lat.child[k], lat.parent_move[k]
        assert ch.shape == (len(prev), len(mv)) and pm.shape == (len(cur), len(mv))
        for q in range(len(prev)):
            for m in range(len(mv)):
                target = prev[q] + mv[m]
                if _inside(target, world):
                    assert ch[q, m] >= 0
                    np.testing.assert_allclose(cur[ch[q, m]], target, atol=TOL)
                    assert pm[ch[q, m], m] == q
                else:
                    assert ch[q, m] == -1
        for p in range(len(cur)):
            for m in range(len(mv)):
                src = cur[p] - mv[m]
                d = np.abs(prev - src).max(axis=1)
                hit = np.flatnonzero(d <= TOL)
                assert pm[p, m] == (hit[0] if hit.size else -1)
            assert (pm[p] >= 0).any()                 # every position has a parent
        # breadth-first order: first (parent, move) reaching each position increases
        firsts = [min((q, m) for q, m in zip(*np.nonzero(ch == p))) for p in range(len(cur))]
        assert firsts == sorted(firsts)
        # index_of finds each position
        for p in range(len(cur)):
            assert lat.index_of(k, cur[p]) == p
        assert lat.index_of(k, cur[0] + np.array([0.5, 0.0])) == -1


def test_interior_reachable_counts():
    # One epoch: the 17 moves. One move distance: king moves, so k epochs reach the
    # (2k + 1)^2 box.
    lat = build_lattice(np.array([300.0, 300.0]), move_vectors((20.0, 40.0)), 1, MapRect())
    assert len(lat.positions[1]) == 17
    lat = build_lattice(np.array([300.0, 300.0]), move_vectors((20.0,)), 3, MapRect())
    assert [len(p) for p in lat.positions] == [1, 9, 25, 49]


# --------------------------------------------------------------------------- plans

def test_random_plans_are_feasible(rng, problem_factory, plan_factory):
    for _ in range(30):
        pr = problem_factory(rng, n_sensors=int(rng.integers(1, 4)), n_targets=2,
                          horizon=int(rng.integers(1, 4)))
        check_plan(pr, plan_factory(pr, rng))
        check_plan(pr, plan_factory(pr, rng, p_unassigned=0.4), complete=False)


def _one_sensor_problem(p0=(300.0, 300.0), K=3):
    return PlanningProblem(means=np.array([[300.0, 0.0, 1.0, 0.0]]),
                           covs=np.diag([100.0, 100.0, 1.0, 1.0])[None],
                           positions=np.array([p0]), headings=np.array([0.0]),
                           sensors=(SensorParams(),), horizon=K)


def test_check_plan_accepts_and_rejects():
    pr = _one_sensor_problem()
    p0 = np.array([300.0, 300.0])

    def plan(pos, tgt):
        return Plan(np.array([pos], dtype=float), np.array([tgt]))

    nan = [np.nan, np.nan]
    good = plan([p0 + [40, 0], p0 + [60, 20], p0 + [60, 20]], [0, 0, 0])
    check_plan(pr, good)
    # two moves in one epoch after an assigned epoch
    with pytest.raises(ValueError):
        check_plan(pr, plan([p0 + [40, 0], p0 + [120, 0], p0 + [120, 0]], [0, 0, 0]))
    # in R_2, but 80 m from the assigned epoch-1 position
    with pytest.raises(ValueError):
        check_plan(pr, plan([p0 + [40, 0], p0 + [-40, 0], p0 + [-40, 0]], [0, 0, 0]))
    # ... which is fine when epoch 1 is unassigned
    check_plan(pr, plan([nan, p0 + [-40, 0], p0 + [-40, 0]], [-1, 0, 0]), complete=False)
    # first epoch must be one move from p0
    with pytest.raises(ValueError):
        check_plan(pr, plan([p0 + [60, 0], p0 + [60, 0], p0 + [60, 0]], [0, 0, 0]))
    # after an unassigned epoch only R_k counts: +80 is reachable in two epochs
    check_plan(pr, plan([nan, p0 + [80, 0], p0 + [100, 0]], [-1, 0, 0]), complete=False)
    with pytest.raises(ValueError):                                # ... but not +120
        check_plan(pr, plan([nan, p0 + [120, 0], p0 + [120, 0]], [-1, 0, 0]), complete=False)
    with pytest.raises(ValueError):                                # complete plans only
        check_plan(pr, plan([nan, p0 + [80, 0], p0 + [100, 0]], [-1, 0, 0]))
    with pytest.raises(ValueError):                                # unknown target
        check_plan(pr, plan([p0, p0, p0], [0, 1, 0]))
    with pytest.raises(ValueError):
        check_plan(pr, plan([p0, p0, p0], [0, -2, 0]))
    with pytest.raises(ValueError):                                # not on the lattice
        check_plan(pr, plan([p0 + [20, 0], p0 + [30, 0], p0 + [30, 0]], [0, 0, 0]))
    with pytest.raises(ValueError):                                # wrong shape
        check_plan(pr, Plan(np.zeros((1, 2, 2)), np.zeros((1, 2), dtype=int)))


def test_check_plan_rejects_leaving_the_map():
    pr = _one_sensor_problem(p0=(0.0, 0.0), K=1)
    check_plan(pr, Plan(np.array([[[20.0, 20.0]]]), np.array([[0]])))
    with pytest.raises(ValueError):
        check_plan(pr, Plan(np.array([[[-20.0, 0.0]]]), np.array([[0]])))


def test_plan_empty_and_readonly():
    plan = Plan.empty(2, 3)
    assert plan.positions.shape == (2, 3, 2) and not plan.assigned.any()
    with pytest.raises(ValueError):
        plan.targets[0, 0] = 1


# --------------------------------------------------------------------------- problem value

def test_problem_copies_and_freezes_inputs(rng):
    means = np.array([[300.0, 300.0, 1.0, 0.0]])
    covs = np.diag([100.0, 100.0, 1.0, 1.0])[None].copy()
    pos = np.array([[100.0, 100.0]])
    pr = PlanningProblem(means=means, covs=covs, positions=pos, headings=np.array([0.0]),
                         sensors=(SensorParams(),), horizon=2)
    means[0, 0] = -1.0
    pos[0, 0] = 5.0
    assert pr.means[0, 0] == 300.0 and pr.positions[0, 0] == 100.0
    with pytest.raises(ValueError):
        pr.covs[0, 0, 0] = 1.0
    assert pr.n_steps == 2 and pr.n_sensors == 1 and pr.n_targets == 1


def _base(**over):
    kw = dict(means=np.array([[300.0, 300.0, 1.0, 0.0]]),
              covs=np.diag([100.0, 100.0, 1.0, 1.0])[None], positions=np.array([[100.0, 100.0]]),
              headings=np.array([0.0]), sensors=(SensorParams(),), horizon=2)
    kw.update(over)
    return kw


@pytest.mark.parametrize("over,field", [
    (dict(dt=0.0), "dt"),
    (dict(dt=float("nan")), "dt"),
    (dict(process_noise=-1.0), "process_noise"),
    (dict(horizon=0), "horizon"),
    (dict(steps_per_epoch=0), "steps_per_epoch"),
    (dict(visibility="maybe"), "visibility"),
    (dict(objective="final"), "objective"),
    (dict(covs=np.diag([100.0, -1.0, 1.0, 1.0])[None]), "targets[0].cov"),
    (dict(covs=(np.diag([100.0, 100.0, 1.0, 1.0]) + np.triu(np.ones((4, 4)), 1))[None]),
     "targets[0].cov"),
    (dict(means=np.array([[300.0, np.inf, 1.0, 0.0]])), "targets[0].mean"),
    (dict(positions=np.array([[700.0, 100.0]])), "sensors[0].position"),
    (dict(sensors=(SensorParams(altitude=0.0),)), "sensors[0].altitude"),
    (dict(sensors=(SensorParams(min_ground_range=500.0),)), "sensors[0].min_ground_range"),
    (dict(sensors=(SensorParams(moves=(20.0, -1.0)),)), "sensors[0].moves"),
    (dict(sensors=(SensorParams(fov_half_angle=0.0),)), "sensors[0].fov_half_angle"),
    (dict(world=MapRect(0.0, 100.0)), "map"),
])
def test_problem_validation_names_the_field(over, field):
    with pytest.raises(ConfigError) as err:
        PlanningProblem(**_base(**over))
    assert err.value.field == field
