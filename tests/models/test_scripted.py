"""Scripted truths of the published benchmarks: their schedules as the sources define them,
the trajectory recipes, and the replay as a population."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models.motion import cv_matrices
from sensorplan.models.scripted import (VO12, WILLIAMS15, ScriptedTruth, dwna_matrices,
                                        forward_trajectories, midpoint_trajectories,
                                        scripted_truth)


def replay(name):
    """Every step's (states, alive, birth_step, death_step) of a benchmark, from step 0."""
    truth = scripted_truth(name)
    out = [(truth.states, truth.alive, truth.birth_step, truth.death_step)]
    for _ in range(truth.steps):
        truth.step()
        out.append((truth.states, truth.alive, truth.birth_step, truth.death_step))
    return truth, out


# ------------------------------------------------------------------------------- vo12

#: The toolbox's gen_truth.m, as written there: tbirth, tdeath (last step present; K + 1
#: for the end), K = 100.
VO_TBIRTH = [1, 1, 1, 20, 20, 20, 40, 40, 60, 60, 80, 80]
VO_TDEATH = [70, 101, 70, 101, 101, 101, 101, 101, 101, 101, 101, 101]


def test_vo12_counts_follow_the_toolbox_loop():
    """truth.N(k) of the toolbox: a target is present at k = tbirth .. min(tdeath, K)."""
    K = 100
    expected = [sum(b <= k <= min(d, K) for b, d in zip(VO_TBIRTH, VO_TDEATH, strict=True))
                for k in range(K + 1)]
    truth, steps = replay("vo12")
    assert truth.steps == K
    assert [int(alive.sum()) for _, alive, _, _ in steps] == expected
    assert expected[1] == 3 and expected[70] == 10 and expected[71] == 8 and expected[100] == 10
    assert [len(alive) for _, alive, _, _ in steps] == \
        [sum(b <= k for b in VO_TBIRTH) for k in range(K + 1)]


def test_vo12_states_are_the_noiseless_lines_of_the_toolbox():
    """The state at step k of a target born at b is F^(k - b + 1) xstart (the toolbox moves
    the start state before storing it), shifted by +1000 m; a target last present at 70
    keeps its step-70 state afterwards."""
    _, steps = replay("vo12")
    x_start = np.array([[0, 0, 0, -10], [400, -10, -600, 5], [-800, 20, -200, -5],
                        [400, -7, -600, -4], [400, -2.5, -600, 10], [0, 7.5, 0, -5],
                        [-800, 12, -200, 7], [-200, 15, 800, -10], [-800, 3, -200, 15],
                        [-200, -3, 800, -15], [0, -20, 0, -15], [-200, 15, 800, -5]], float)
    for k, (x, alive, born, dies) in enumerate(steps):
        for j in range(len(x)):
            n = min(k, VO_TDEATH[j]) - VO_TBIRTH[j] + 1
            pos = x_start[j, [0, 2]] + n * x_start[j, [1, 3]] + 1000.0
            np.testing.assert_allclose(x[j], [*pos, x_start[j, 1], x_start[j, 3]], atol=1e-9)
            assert born[j] == VO_TBIRTH[j]
            assert dies[j] == (VO_TDEATH[j] + 1 if VO_TDEATH[j] < k else -1)
            assert alive[j] == (k <= VO_TDEATH[j])
        assert np.all((x[:, :2] >= 0) & (x[:, :2] <= 2000))
    np.testing.assert_allclose(steps[100][0][0], [1000.0, 300.0, 0.0, -10.0])


def test_vo12_parameters_in_this_package_s_coordinates():
    np.testing.assert_array_equal(VO12.birth_sites, [[1000, 1000], [1400, 400], [200, 800],
                                                     [800, 1800]])
    assert VO12.death_step == (71, -1, 71, -1, -1, -1, -1, -1, -1, -1, -1, -1)
    # Every target starts at one of the four birth sites.
    d = np.linalg.norm(VO12.start[:, None, :2] - VO12.birth_sites[None], axis=-1)
    assert np.all(d.min(axis=1) == 0.0)


# ------------------------------------------------------------------------- williams15

def test_williams15_schedule():
    """4 targets from step 1 to 81; target 0 is gone from the midpoint, step 41, on."""
    truth, steps = replay("williams15")
    assert truth.steps == 81 and WILLIAMS15.midpoint == 41
    counts = [int(alive.sum()) for _, alive, _, _ in steps]
    assert counts == [0] + [4] * 40 + [3] * 41
    x41, alive41, _, dies41 = steps[41]
    assert not alive41[0] and alive41[1:].all() and dies41[0] == 41
    np.testing.assert_array_equal(x41[0], steps[40][0][0])
    np.testing.assert_array_equal(steps[81][0][0], steps[40][0][0])


def test_williams15_targets_coalesce_at_the_midpoint():
    """At step 41 the live targets are within a few metres of the area's centre (the
    midpoint draw has standard deviation sqrt(0.1) m): the source's close-proximity
    crossing; 40 steps away they have drifted apart."""
    _, steps = replay("williams15")
    x = steps[41][0][1:]
    assert np.all(np.abs(x[:, :2] - 150.0) < 6 * math.sqrt(0.1))
    assert np.all(np.abs(x[:, 2:]) < 6 * math.sqrt(0.1))
    start = steps[1][0]
    assert np.max(np.ptp(start[:, :2], axis=0)) > 5.0


def test_williams15_is_the_same_in_every_run():
    a, b = scripted_truth("williams15"), scripted_truth("williams15")
    for _ in range(81):
        np.testing.assert_array_equal(a.step()[0], b.step()[0])
    with pytest.raises(ValueError, match="81 steps"):
        a.step()


def test_midpoint_recipe_moves_forward_and_backward_with_the_cwna_model():
    """x_{t+1} - F x_t is N(0, Q) on both sides of the midpoint (backward: F x_{t-1} = x_t + w):
    every increment's covariance within 4.5 standard errors of Q (q = 0.01), increments
    uncorrelated from step to step, and the midpoint states N(mean, 0.1 I)."""
    n, q = 400, 0.01
    mean = np.array([150.0, 150.0, 0.0, 0.0])
    traj = midpoint_trajectories(n, mean, 0.1, 41, 81, 1.0, q, np.random.default_rng(5))
    assert np.isnan(traj[0]).all()
    F, Q = cv_matrices(1.0, q)
    w = traj[2:] - traj[1:-1] @ F.T                      # (80, n, 4)
    flat = w.reshape(-1, 4)
    N = len(flat)
    C = flat.T @ flat / N
    se = np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / N)
    assert np.all(np.abs(C - Q) <= 4.5 * se)
    assert np.all(np.abs(flat.mean(axis=0)) <= 4.5 * np.sqrt(np.diag(Q) / N))
    lag = np.mean(w[1:, :, 2] * w[:-1, :, 2]) / Q[2, 2]
    assert abs(lag) <= 4.5 / math.sqrt(79 * n)
    mid = traj[41]
    assert np.all(np.abs(mid.mean(axis=0) - mean) <= 4.5 * math.sqrt(0.1 / n))
    assert np.all(np.abs(mid.var(axis=0) - 0.1) <= 4.5 * 0.1 * math.sqrt(2 / n))
    with pytest.raises(ValueError, match="2 midpoint - 1"):
        midpoint_trajectories(n, mean, 0.1, 41, 80, 1.0, q, np.random.default_rng(5))


def test_forward_recipe_with_dwna_noise():
    """With sigma_v > 0 each step adds B a, a ~ N(0, sigma_v^2 I_2): the increments lie in
    the span of B (exactly) and a's covariance is sigma_v^2 I within 4.5 standard errors."""
    n, sigma, S = 300, 5.0, 60
    start = np.tile([1000.0, 1000.0, 3.0, -2.0], (n, 1))
    born = np.repeat([1, 20, 40], n // 3)
    traj = forward_trajectories(start, born, S, 1.0, sigma, np.random.default_rng(3))
    F, B = dwna_matrices(1.0)
    a_all = []
    for t in range(1, S):
        live = born <= t
        w = traj[t + 1, live] - traj[t, live] @ F.T
        a, *_ = np.linalg.lstsq(B, w.T, rcond=None)
        np.testing.assert_allclose(a.T @ B.T, w, atol=1e-9)
        a_all.append(a.T)
        assert np.isnan(traj[t, ~live]).all()
    a = np.concatenate(a_all)
    C = a.T @ a / len(a)
    se = sigma**2 * np.sqrt(np.array([[2, 1], [1, 2]]) / len(a))
    assert np.all(np.abs(C - sigma**2 * np.eye(2)) <= 4.5 * se)
    with pytest.raises(ValueError, match="generator"):
        forward_trajectories(start, born, S, 1.0, sigma)


def test_scripted_truth_checks_its_schedule():
    traj = np.zeros((5, 2, 4))
    with pytest.raises(ValueError, match="ascending"):
        ScriptedTruth(traj, [3, 1], [-1, -1])
    with pytest.raises(ValueError, match="after its birth"):
        ScriptedTruth(traj, [1, 2], [1, -1])
    with pytest.raises(ValueError, match="agree"):
        ScriptedTruth(traj, [1], [-1])
