"""PMB data association: loopy belief propagation against exact enumeration.

Belief propagation is exact on tree-shaped association graphs, so there the two agree to
round-off; on loopy graphs it is an approximation, checked against a measured bound, and
its fixed point is checked against textbook sum-product (``pmb_reference.lbp_generic``).
"""

from __future__ import annotations

import doctest
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmb_reference import lbp_dense, lbp_generic
from sensorplan.tracking.pmb import association
from sensorplan.tracking.pmb.tracker import MIN_WEIGHT
from sensorplan.tracking.pmb.association import (association_components, association_exact,
                                                 association_lbp)

SETTINGS = settings(max_examples=40, deadline=None)
#: Belief propagation against exact enumeration on trees, and against the generic
#: sum-product fixed point on loopy graphs (absolute, on probabilities).
EXACT_TOL = 1e-9
#: The measurement side sums to one only at the fixed point: to within the iteration's
#: tolerance (1e-10 relative on the messages; measured deviations up to 3e-11).
SIDE_TOL = 1e-9
#: Loopy graphs: measured on the 300 cases of test_lbp_is_close_to_exact_on_loopy_graphs
#: (seed 0): worst absolute error 0.074, mean of the per-case worst errors 0.0080. Over 20
#: seeds (6000 cases) the worst was 0.173 and the means 0.0064-0.0085. The bounds sit above
#: all of those: belief propagation's error on a strongly ambiguous 5 x 5 cluster is several
#: percent, while the mean agrees with Williams and Lau (2014)'s "typically below 1e-2".
LOOPY_WORST = 0.2
LOOPY_MEAN = 0.02


# ------------------------------------------------------------------ problems


def weights(rng: np.random.Generator, gated: np.ndarray) -> tuple[np.ndarray, ...]:
    """PMB-like weights on a gating mask ``(n, m)``: existence r in [0.05, 1], P_d in
    [0.5, 0.99], likelihoods of a whitened 2-D Gaussian inside a 99 % gate, and new-target
    plus clutter intensities of 0.001-0.05 per whitened unit area."""
    n, m = gated.shape
    r, pd = rng.uniform(0.05, 1.0, n), rng.uniform(0.5, 0.99, n)
    lik = np.exp(-0.5 * rng.uniform(0.0, 9.21, (n, m))) / (2.0 * np.pi)
    w_det = np.where(gated, (r * pd)[:, None] * lik, 0.0)
    return 1.0 - r * pd, w_det, rng.uniform(0.001, 0.05, m)


def is_forest(w_det: np.ndarray) -> bool:
    """Whether every connected component has one edge fewer than nodes."""
    gated = w_det > 0.0
    return all(gated[np.ix_(t, z)].sum() == t.size + z.size - 1
               for t, z in association_components(w_det))


def forest(rng: np.random.Generator, kind: str) -> np.ndarray:
    """A tree-shaped gating mask of a random size up to 6 x 6.

    ``one_track``: each measurement in at most one track's gate; ``one_measurement``:
    each track gates at most one measurement; ``bipartite``: random edges kept when they
    join two components (union-find), a random bipartite forest.
    """
    n, m = (int(k) for k in rng.integers(1, 7, size=2))
    gated = np.zeros((n, m), dtype=bool)
    if kind == "one_track":
        owner = rng.integers(-1, n, size=m)
        gated[owner[owner >= 0], np.flatnonzero(owner >= 0)] = True
    elif kind == "one_measurement":
        chosen = rng.integers(-1, m, size=n)
        gated[np.flatnonzero(chosen >= 0), chosen[chosen >= 0]] = True
    else:
        root = list(range(n + m))

        def find(x: int) -> int:
            while root[x] != x:
                x = root[x]
            return x

        for e in rng.permutation(n * m):
            i, j = divmod(int(e), m)
            if rng.random() < 0.7 and find(i) != find(n + j):
                root[find(i)] = find(n + j)
                gated[i, j] = True
    return gated


def loopy(rng: np.random.Generator, max_size: int = 5) -> np.ndarray:
    """A dense random gating mask (each pair gated with probability 0.7), 2 to
    ``max_size`` tracks and measurements, with at least one cycle."""
    while True:
        n, m = (int(k) for k in rng.integers(2, max_size + 1, size=2))
        gated = rng.random((n, m)) < 0.7
        if not is_forest(gated.astype(float)):
            return gated


def worst_error(a: association.AssociationMarginals,
                b: association.AssociationMarginals) -> float:
    return max(np.max(np.abs(a.p_det - b.p_det), initial=0.0),
               np.max(np.abs(a.p_miss - b.p_miss), initial=0.0),
               np.max(np.abs(a.p_new - b.p_new), initial=0.0))


def assert_same(a: association.AssociationMarginals, b: association.AssociationMarginals,
                atol: float) -> None:
    np.testing.assert_allclose(a.p_det, b.p_det, rtol=0, atol=atol)
    np.testing.assert_allclose(a.p_miss, b.p_miss, rtol=0, atol=atol)
    np.testing.assert_allclose(a.p_new, b.p_new, rtol=0, atol=atol)


# ------------------------------------------------------------------ closed forms


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
@pytest.mark.parametrize("w_miss, w_det, w_new", [(0.5, 2.0, 1.0), (0.9, 1e-3, 0.02),
                                                  (1e-4, 3.0, 7.0), (0.3, 0.3, 1.0)])
def test_one_track_one_measurement(solve, w_miss, w_det, w_new) -> None:
    # Two joint associations: detected (weight w_det, the measurement is the track's) or
    # missed (w_miss, and the measurement is new or clutter: w_new).
    r = solve([w_miss], [[w_det]], [w_new])
    z = w_det + w_miss * w_new
    np.testing.assert_allclose(r.p_det, [[w_det / z]], rtol=1e-14, atol=0)
    np.testing.assert_allclose(r.p_miss, [w_miss * w_new / z], rtol=1e-14, atol=0)
    np.testing.assert_allclose(r.p_new, [w_miss * w_new / z], rtol=1e-14, atol=0)
    assert r.converged


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_two_tracks_share_one_measurement(solve) -> None:
    # Three joint associations: nobody (wm1 wm2 wn), track 1 (wd1 wm2), track 2 (wm1 wd2).
    wm, wd, wn = np.array([0.4, 0.7]), np.array([[1.5], [0.6]]), np.array([0.2])
    z = wm[0] * wm[1] * wn[0] + wd[0, 0] * wm[1] + wm[0] * wd[1, 0]
    r = solve(wm, wd, wn)
    np.testing.assert_allclose(r.p_det[:, 0], [wd[0, 0] * wm[1] / z, wm[0] * wd[1, 0] / z],
                               rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.p_new, [wm[0] * wm[1] * wn[0] / z], rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.p_miss, 1.0 - r.p_det[:, 0], rtol=1e-13, atol=0)


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_one_track_two_measurements(solve) -> None:
    # Three joint associations: missed (wm wn1 wn2), measurement 1 (wd1 wn2), 2 (wd2 wn1).
    wm, wd, wn = 0.3, np.array([0.8, 2.5]), np.array([0.1, 0.4])
    z = wm * wn[0] * wn[1] + wd[0] * wn[1] + wd[1] * wn[0]
    r = solve([wm], [wd], wn)
    np.testing.assert_allclose(r.p_det[0], [wd[0] * wn[1] / z, wd[1] * wn[0] / z],
                               rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.p_miss, [wm * wn[0] * wn[1] / z], rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.p_new, 1.0 - r.p_det[0], rtol=1e-13, atol=0)


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_no_measurements(solve) -> None:
    r = solve([0.2, 0.9, 0.5], np.zeros((3, 0)), np.zeros(0))
    assert r.p_det.shape == (3, 0) and r.p_new.shape == (0,)
    np.testing.assert_array_equal(r.p_miss, [1.0, 1.0, 1.0])
    assert r.iterations == 0 and r.converged


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_no_tracks(solve) -> None:
    r = solve(np.zeros(0), np.zeros((0, 2)), [0.1, 3.0])
    assert r.p_det.shape == (0, 2) and r.p_miss.shape == (0,)
    np.testing.assert_array_equal(r.p_new, [1.0, 1.0])
    assert r.iterations == 0 and r.converged


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_a_measurement_outside_every_gate_and_a_track_without_measurements(solve) -> None:
    wm, wn = np.array([0.3, 0.6]), np.array([0.05, 0.2])
    wd = np.array([[0.8, 0.0],       # measurement 1 is in no gate
                   [0.0, 0.0]])      # track 1 gates nothing
    r = solve(wm, wd, wn)
    z = wd[0, 0] + wm[0] * wn[0]
    np.testing.assert_allclose(r.p_det, [[wd[0, 0] / z, 0.0], [0.0, 0.0]], rtol=1e-14, atol=0)
    np.testing.assert_allclose(r.p_miss, [wm[0] * wn[0] / z, 1.0], rtol=1e-14, atol=0)
    np.testing.assert_allclose(r.p_new, [wm[0] * wn[0] / z, 1.0], rtol=1e-14, atol=0)


def test_the_docstring_examples_run() -> None:
    failed, tried = doctest.testmod(association)
    assert tried >= 3 and failed == 0


# ------------------------------------------------------------------ against exact


@pytest.mark.parametrize("kind", ["one_track", "one_measurement", "bipartite"])
def test_lbp_equals_exact_on_trees(kind: str) -> None:
    rng = np.random.default_rng(["one_track", "one_measurement", "bipartite"].index(kind))
    edges = 0
    for _ in range(150):
        w = weights(rng, forest(rng, kind))
        assert is_forest(w[1])
        edges += int((w[1] > 0).sum())
        r = association_lbp(*w)
        assert r.converged
        assert_same(r, association_exact(*w), EXACT_TOL)
    assert edges > 300                       # the forests are not mostly empty


def test_lbp_is_close_to_exact_on_loopy_graphs() -> None:
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(300):
        w = weights(rng, loopy(rng))
        r = association_lbp(*w)
        assert r.converged
        errors.append(worst_error(r, association_exact(*w)))
    assert max(errors) <= LOOPY_WORST
    assert np.mean(errors) <= LOOPY_MEAN
    assert max(errors) > 1e-3                # the graphs are loopy: BP is not exact there


def test_lbp_reaches_the_sum_product_fixed_point_on_loopy_graphs() -> None:
    rng = np.random.default_rng(1)
    for _ in range(12):
        w = weights(rng, loopy(rng, max_size=4))
        r = association_lbp(*w, tol=1e-13)
        p_det, p_miss, p_new = lbp_generic(*w)
        np.testing.assert_allclose(r.p_det, p_det, rtol=0, atol=EXACT_TOL)
        np.testing.assert_allclose(r.p_miss, p_miss, rtol=0, atol=EXACT_TOL)
        np.testing.assert_allclose(r.p_new, p_new, rtol=0, atol=EXACT_TOL)


@pytest.mark.parametrize("n, m, per_track", [(3, 4, 2), (10, 10, 3), (50, 50, 3), (20, 8, 5)])
def test_compiled_lbp_equals_the_dense_numpy_iteration(n: int, m: int, per_track: int) -> None:
    rng = np.random.default_rng(n * m)
    gated = np.zeros((n, m), dtype=bool)
    for i in range(n):
        gated[i, rng.choice(m, size=per_track, replace=False)] = True
    w = weights(rng, gated)
    # 25 sweeps (tol = 0 stops only where the messages stop changing at all, which
    # round-off decides), then to the default tolerance.
    for tol, max_iter in ((0.0, 25), (1e-10, 1000)):
        r = association_lbp(*w, tol=tol, max_iter=max_iter)
        p_det, p_miss, p_new, _, converged = lbp_dense(*w, tol=tol, max_iter=max_iter)
        atol = 1e-12 if tol == 0.0 else EXACT_TOL
        np.testing.assert_allclose(r.p_det, p_det, rtol=0, atol=atol)
        np.testing.assert_allclose(r.p_miss, p_miss, rtol=0, atol=atol)
        np.testing.assert_allclose(r.p_new, p_new, rtol=0, atol=atol)
        assert r.converged == converged or tol == 0.0


def test_lbp_reports_when_it_stops_before_converging() -> None:
    w = weights(np.random.default_rng(3), np.ones((4, 4), dtype=bool))
    r = association_lbp(*w, max_iter=2)
    assert (r.iterations, r.converged) == (2, False)
    assert association_lbp(*w).iterations > 2


def test_exact_enumeration_equals_a_brute_force_over_all_assignments() -> None:
    # Every a in {miss, 0..m-1}^n, invalid ones (a measurement twice, an ungated pair)
    # dropped: a second enumeration with nothing in common but the weight formula.
    rng = np.random.default_rng(4)
    for _ in range(20):
        w_miss, w_det, w_new = weights(rng, rng.random((3, 4)) < 0.6)
        n, m = w_det.shape
        p_det, p_miss, p_new, total = np.zeros((n, m)), np.zeros(n), np.zeros(m), 0.0
        for a in itertools.product(range(-1, m), repeat=n):
            used = [j for j in a if j >= 0]
            if len(set(used)) < len(used) or any(w_det[i, j] == 0 for i, j in enumerate(a)
                                                 if j >= 0):
                continue
            weight = math.prod(w_det[i, j] if j >= 0 else w_miss[i] for i, j in enumerate(a))
            weight *= math.prod(w_new[j] for j in range(m) if j not in used)
            total += weight
            for i, j in enumerate(a):
                if j >= 0:
                    p_det[i, j] += weight
                else:
                    p_miss[i] += weight
            p_new[[j for j in range(m) if j not in used]] += weight
        r = association_exact(w_miss, w_det, w_new)
        np.testing.assert_allclose(r.p_det, p_det / total, rtol=0, atol=1e-13)
        np.testing.assert_allclose(r.p_miss, p_miss / total, rtol=0, atol=1e-13)
        np.testing.assert_allclose(r.p_new, p_new / total, rtol=0, atol=1e-13)


@pytest.mark.parametrize("n, m", [(1, 1), (2, 3), (4, 4), (5, 3)])
def test_exact_enumerates_every_matching_of_a_complete_graph(n: int, m: int) -> None:
    # Matchings of the complete bipartite graph K(n, m): sum over k of C(n,k) C(m,k) k!.
    count = sum(math.comb(n, k) * math.comb(m, k) * math.factorial(k)
                for k in range(min(n, m) + 1))
    assign, taken = association._enumerate(np.ones((n, m), dtype=bool), 10**6)
    assert assign.shape == (count, n) and taken.shape == (count, m)
    assert len({tuple(a) for a in assign}) == count        # all different
    np.testing.assert_array_equal(taken.sum(axis=1), (assign >= 0).sum(axis=1))


def test_exact_refuses_too_many_hypotheses() -> None:
    w = weights(np.random.default_rng(5), np.ones((6, 6), dtype=bool))    # 13327 of them
    with pytest.raises(ValueError, match="max_hypotheses"):
        association_exact(*w, max_hypotheses=10_000)
    assert association_exact(*w).converged


# ------------------------------------------------------------------ properties


@st.composite
def problems(draw):
    """Weights of a random forest or loopy graph, from a drawn seed."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["one_track", "one_measurement", "bipartite", "loopy"]))
    return weights(rng, loopy(rng) if kind == "loopy" else forest(rng, kind))


@SETTINGS
@given(problems(), st.sampled_from([association_lbp, association_exact]))
def test_the_marginals_are_probabilities(w, solve) -> None:
    r = solve(*w)
    for p in (r.p_det, r.p_miss, r.p_new):
        assert np.all((p >= 0.0) & (p <= 1.0))
    assert np.all(r.p_det[w[1] == 0.0] == 0.0)               # never an ungated pair
    np.testing.assert_allclose(r.p_miss + r.p_det.sum(axis=1), 1.0, rtol=0, atol=1e-13)
    side = 1e-13 if solve is association_exact else SIDE_TOL
    np.testing.assert_allclose(r.p_new + r.p_det.sum(axis=0), 1.0, rtol=0, atol=side)


@SETTINGS
@given(problems(), st.sampled_from([association_lbp, association_exact]),
       st.integers(0, 2**32 - 1))
def test_scaling_a_track_or_a_measurement_leaves_the_marginals(w, solve, seed) -> None:
    w_miss, w_det, w_new = (x.copy() for x in w)
    rng = np.random.default_rng(seed)
    i, j = rng.integers(w_det.shape[0]), rng.integers(w_det.shape[1])
    row, col = 10.0 ** rng.uniform(-3, 3, size=2)
    w_miss[i] *= row
    w_det[i] *= row
    w_new[j] *= col
    w_det[:, j] *= col
    assert_same(solve(w_miss, w_det, w_new), solve(*w), EXACT_TOL)


@SETTINGS
@given(problems(), st.sampled_from([association_lbp, association_exact]))
def test_components_solved_apart_equal_the_whole(w, solve) -> None:
    w_miss, w_det, w_new = w
    n, m = w_det.shape
    whole = solve(*w)
    p_det, p_miss, p_new = np.zeros((n, m)), np.zeros(n), np.zeros(m)
    parts = association_components(w_det)
    for t, z in parts:
        r = solve(w_miss[t], w_det[np.ix_(t, z)], w_new[z])
        p_det[np.ix_(t, z)], p_miss[t], p_new[z] = r.p_det, r.p_miss, r.p_new
    # The components partition the tracks and the measurements, and no gated pair
    # crosses two of them.
    np.testing.assert_array_equal(np.sort(np.concatenate([t for t, _ in parts])), np.arange(n))
    np.testing.assert_array_equal(np.sort(np.concatenate([z for _, z in parts])), np.arange(m))
    assert sum(int((w_det[np.ix_(t, z)] > 0).sum()) for t, z in parts) == (w_det > 0).sum()
    atol = 1e-13 if solve is association_exact else SIDE_TOL
    np.testing.assert_allclose(p_det, whole.p_det, rtol=0, atol=atol)
    np.testing.assert_allclose(p_miss, whole.p_miss, rtol=0, atol=atol)
    np.testing.assert_allclose(p_new, whole.p_new, rtol=0, atol=atol)


def test_components_of_a_small_graph() -> None:
    w_det = np.array([[0.0, 1.0, 0.0, 0.0],
                      [0.0, 0.0, 0.0, 0.0],
                      [2.0, 0.0, 0.0, 3.0],
                      [0.0, 0.0, 0.0, 4.0]])
    parts = [(t.tolist(), z.tolist()) for t, z in association_components(w_det)]
    assert parts == [([0], [1]), ([1], []), ([2, 3], [0, 3]), ([], [2])]


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
@pytest.mark.parametrize("w_miss, w_det, w_new, match", [
    ([0.5, 0.5], [[1.0]], [1.0], "shape"),
    ([0.5], [[1.0, 1.0]], [1.0], "shape"),
    ([0.5], [[-1.0]], [1.0], "w_det must be >= 0"),
    ([0.0], [[1.0]], [1.0], "w_miss must be > 0"),
    ([0.5], [[1.0]], [0.0], "w_new must be > 0"),
    ([0.5], [[np.nan]], [1.0], "w_det must be finite"),
    ([np.inf], [[1.0]], [1.0], "w_miss must be finite"),
])
def test_bad_weights_are_refused(solve, w_miss, w_det, w_new, match) -> None:
    with pytest.raises(ValueError, match=match):
        solve(w_miss, w_det, w_new)


@pytest.mark.parametrize("kw, match", [({"tol": -1.0}, "tol"), ({"tol": np.nan}, "tol"),
                                       ({"max_iter": 0}, "max_iter")])
def test_bad_iteration_settings_are_refused(kw, match) -> None:
    with pytest.raises(ValueError, match=match):
        association_lbp([0.5], [[1.0]], [1.0], **kw)


@pytest.mark.parametrize("solve", [association_lbp, association_exact])
def test_a_sure_track_and_a_sure_detection_stay_finite(solve) -> None:
    # Ideal detection (P_d = 1) and no false alarms: a Bernoulli surely there and surely
    # detectable (r = 1, Pbar = 1) and a detection that neither clutter nor the undetected
    # intensity can explain both get the tracker's smallest weight, MIN_WEIGHT. The ratio
    # form multiplies their inverses, which overflowed (1e300 * 1e300) and made every
    # marginal NaN: the tracker then dropped a track of existence 1 whose target it had just
    # detected. The detection is the track's.
    r = solve([MIN_WEIGHT], [[1.0]], [MIN_WEIGHT])
    np.testing.assert_allclose(r.p_det, [[1.0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.p_miss, [0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.p_new, [0.0], rtol=0, atol=1e-12)
    # Beside a Bernoulli that the look could miss and that gates nothing.
    r = solve([1.0, MIN_WEIGHT], [[0.0], [1.0]], [MIN_WEIGHT])
    np.testing.assert_allclose(r.p_det, [[0.0], [1.0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.p_miss, [1.0, 0.0], rtol=0, atol=1e-12)
