"""The calibration scripts' arithmetic: scripts/existence_calibration.py's assignment of
Bernoullis to targets against a brute-force search over every matching, and
scripts/edge_exit_calibration.py's tally against a hand-made run."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from script_helpers import script_module


def best_matching(pos: np.ndarray, xy: np.ndarray, distance: float) -> tuple[float, set[int]]:
    """The largest sum of ``distance - d`` over one-to-one pairs nearer than ``distance``,
    and the Bernoullis it pairs: every partial matching tried."""
    d = np.hypot(pos[:, None, 0] - xy[None, :, 0], pos[:, None, 1] - xy[None, :, 1])
    best, hits = 0.0, set()
    B, T = d.shape
    for k in range(1, min(B, T) + 1):
        for rows in itertools.combinations(range(B), k):
            for cols in itertools.permutations(range(T), k):
                if all(d[r, c] < distance for r, c in zip(rows, cols)):
                    gain = float(sum(distance - d[r, c] for r, c in zip(rows, cols)))
                    if gain > best:
                        best, hits = gain, set(rows)
    return best, hits


@pytest.mark.parametrize("seed", range(30))
def test_bernoullis_with_a_target_are_the_best_matchings(seed: int) -> None:
    calib = script_module("existence_calibration")
    rng = np.random.default_rng(seed)
    B, T = int(rng.integers(0, 5)), int(rng.integers(0, 5))
    xy = rng.uniform(0.0, 60.0, (T, 2))
    # Bernoullis near the targets (several near one) and far from them.
    pos = rng.uniform(0.0, 60.0, (B, 2))
    if T:
        near = rng.random(B) < 0.6
        n = int(near.sum())
        pos[near] = xy[rng.integers(0, T, n)] + rng.normal(0.0, 8.0, (n, 2))
    hit = calib.with_target(pos, xy, 20.0)
    _, want = best_matching(pos, xy, 20.0)
    assert set(np.flatnonzero(hit).tolist()) == want


def test_two_bernoullis_on_one_target_give_it_to_one() -> None:
    calib = script_module("existence_calibration")
    pos = np.array([[0.0, 1.0], [0.0, 3.0], [50.0, 0.0]])
    hit = calib.with_target(pos, np.zeros((1, 2)), 20.0)
    assert hit.tolist() == [True, False, False]
    assert not calib.with_target(pos, np.array([[0.0, 23.0]]), 20.0)[0]   # 20 m: not nearer


def test_the_edge_tally_of_a_hand_made_run() -> None:
    calib = script_module("edge_exit_calibration")
    ps = 0.99
    # Steps 0..2; target 0 leaves in step 1 from 3 m inside the left edge, target 1 stays
    # 12 m inside the top edge, target 2 is in the middle.
    truth = np.zeros((3, 3, 4))
    truth[:, 0, :2] = [3.0, 300.0]
    truth[:, 1, :2] = [300.0, 588.0]
    truth[:, 2, :2] = [300.0, 300.0]
    alive = np.ones((3, 3), dtype=bool)
    alive[1:, 0] = False
    labels = np.array([5, 6, 7, 8, 9])
    m0 = np.array([[4.0, 300.0], [300.0, 590.0], [3.0, 301.0], [300.0, 330.0], [301.0, 300.0]])
    r0 = np.array([0.8, 0.9, 0.2, 0.9, 0.9])
    # Label 5 loses half at the edge, 6 a tenth; 7 is below 0.3, 8 is 30 m from any target,
    # 9 (in the middle) is pruned: none of those three counts.
    r1 = np.array([0.8 * ps * 0.5, 0.9 * ps * 0.9, 0.2 * ps, 0.9 * ps])
    step1 = (r0, m0, labels, r1, labels[:4])
    step2 = (r1[:2], m0[:2], labels[:2], r1[:2] * ps, labels[:2])   # target 0 is dead
    pairs, expected, left = calib.tally([step1, step2], truth, alive, 600.0, 600.0, ps)
    assert pairs.tolist() == [1, 0, 2, 0]          # 0-5 m: label 5; 10-20 m: label 6 twice
    np.testing.assert_allclose(expected, [0.5, 0.0, 0.1, 0.0], rtol=1e-12, atol=1e-15)
    assert left.tolist() == [1, 0, 0, 0]


def test_reached_before_is_each_label_s_highest_existence_at_earlier_steps() -> None:
    calib = script_module("existence_calibration")
    steps = [(np.array([0.4, 0.995]), np.array([3, 4])),
             (np.array([0.999, 0.2, 0.6]), np.array([3, 4, 5])),
             (np.array([0.05, 0.1]), np.array([3, 5]))]
    got = calib.reached_before(steps)
    assert [g.tolist() for g in got] == [[0.0, 0.0], [0.4, 0.995, 0.0], [0.999, 0.6]]


def test_bin_edges_must_run_from_0_to_1_increasing() -> None:
    calib = script_module("existence_calibration")
    assert calib.parse_edges("0,0.5,1") == (0.0, 0.5, 1.0 + 1e-12)
    for bad in ("0.1,1", "0,0.5,0.9", "0,0.5,0.5,1", "1"):
        with pytest.raises(Exception, match="edges must increase from 0 to 1"):
            calib.parse_edges(bad)
