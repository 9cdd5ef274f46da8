"""scripts/traffic_motion_q.py's motion scores against the closed form of the CWNA
covariance's inverse."""

from __future__ import annotations

import numpy as np

from script_helpers import script_module


def test_scores_match_the_closed_form_and_vanish_on_straight_flight() -> None:
    mq = script_module("traffic_motion_q")
    rng = np.random.default_rng(7)
    T = 5.0
    # Two aircraft over four steps, the second alive for two steps only (NaN elsewhere).
    states = rng.normal(0.0, 50.0, size=(4, 2, 4))
    states[[0, 3], 1] = np.nan
    got = mq.motion_scores(states, T)
    want = []
    for j, ks in ((0, (0, 1, 2)), (1, (1,))):
        for k in ks:
            a, b = states[k, j], states[k + 1, j]
            w = b - np.r_[a[:2] + T * a[2:], a[2:]]
            # Q(1)^-1 = 12 / T^4 [[T, -T^2/2], [-T^2/2, T^3/3]] per axis.
            want.append(sum(12 / T ** 4 * (T * w[i] ** 2 - T ** 2 * w[i] * w[i + 2]
                                           + T ** 3 / 3 * w[i + 2] ** 2) for i in (0, 1)))
    np.testing.assert_allclose(np.sort(got), np.sort(want), rtol=1e-12)
    # Constant velocity scores 0.
    t = np.arange(6.0)[:, None]
    line = np.concatenate([np.c_[100 + 30 * T * t, -20 * T * t], np.tile([30.0, -20.0],
                                                                          (6, 1))], axis=1)
    np.testing.assert_allclose(mq.motion_scores(line[:, None, :], T), 0.0, atol=1e-9)


def test_one_mode_fit_is_the_mean_score_over_four() -> None:
    mq = script_module("traffic_motion_q")
    rng = np.random.default_rng(11)
    seqs = [rng.chisquare(4, size=n) * 30.0 for n in (5, 40, 1)]
    q, Pi, _ = mq.fit_modes(seqs, 1)
    np.testing.assert_allclose(q, [np.concatenate(seqs).mean() / 4.0], rtol=1e-12)
    assert Pi.tolist() == [[1.0]]


def test_two_mode_fit_recovers_a_simulated_switching_motion() -> None:
    """Scores drawn from a known two-mode hidden Markov model (a residual under a mode with
    q scores q times a chi-square(4) against Q(1)): the fit finds its q's and switching."""
    mq = script_module("traffic_motion_q")
    rng = np.random.default_rng(12)
    q_true = np.array([4.0, 60.0])
    Pi_true = np.array([[0.85, 0.15], [0.2, 0.8]])
    seqs = []
    for _ in range(60):
        mode, s = 0, []
        for _ in range(200):
            s.append(q_true[mode] * rng.chisquare(4))
            mode = int(rng.random() < Pi_true[mode, 1])
        seqs.append(np.array(s))
    q, Pi, ll = mq.fit_modes(seqs, 2)
    np.testing.assert_allclose(q, q_true, rtol=0.08)
    np.testing.assert_allclose(Pi, Pi_true, atol=0.04)
    # EM never lowers the likelihood: more iterations reach at least as high.
    _, _, ll_short = mq.fit_modes(seqs, 2, iterations=3)
    assert ll >= ll_short
