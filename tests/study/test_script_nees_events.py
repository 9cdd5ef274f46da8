"""scripts/nees_events.py: the NEES split into position and velocity parts, by target kind,
and its rows for a multi-target tracker (the tracks GOSPA assigns)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
from script_helpers import ROOT, script_module

nees_events = script_module("nees_events")


def _random_covs(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, 4, 4))
    return A @ A.transpose(0, 2, 1) + 0.5 * np.eye(4)


def test_the_parts_are_each_block_s_own_quadratic_form() -> None:
    rng = np.random.default_rng(11)
    P = _random_covs(rng, 50)
    truth, est = rng.normal(size=(50, 4)), rng.normal(size=(50, 4))
    position, velocity = nees_events.nees_parts(truth, est, P)
    # second computation: through the Cholesky factor of each block
    for s, got in ((slice(0, 2), position), (slice(2, 4), velocity)):
        L = np.linalg.cholesky(P[:, s, s])
        w = np.linalg.solve(L, (truth - est)[:, s, None])[..., 0]
        np.testing.assert_allclose(got, (w * w).sum(axis=1), rtol=1e-12)


def test_with_a_block_diagonal_covariance_the_parts_sum_to_the_whole() -> None:
    from sensorplan.tracking.ekf import nees

    rng = np.random.default_rng(12)
    P = _random_covs(rng, 40)
    P[:, :2, 2:] = 0.0
    P[:, 2:, :2] = 0.0
    truth, est = rng.normal(size=(40, 4)), rng.normal(size=(40, 4))
    position, velocity = nees_events.nees_parts(truth, est, P)
    np.testing.assert_allclose(position + velocity, nees(truth, est, P), rtol=1e-12)


def test_errors_drawn_from_the_covariance_give_parts_of_mean_two() -> None:
    rng = np.random.default_rng(13)
    n = 20_000
    P = _random_covs(rng, n)
    e = np.einsum("nij,nj->ni", np.linalg.cholesky(P), rng.normal(size=(n, 4)))
    position, velocity = nees_events.nees_parts(e, np.zeros((n, 4)), P)
    # each is chi-square(2): mean 2, sd 2, so the mean of n has sd 2 / sqrt(n) = 0.014
    assert abs(position.mean() - 2.0) < 0.06 and abs(velocity.mean() - 2.0) < 0.06


def test_a_missing_estimate_gives_nan_parts() -> None:
    truth = np.zeros((2, 3, 4))
    est = np.ones((2, 3, 4))
    est[1, 2] = np.nan
    P = np.broadcast_to(np.eye(4), (2, 3, 4, 4)).copy()
    P[1, 2] = np.nan
    position, velocity = nees_events.nees_parts(truth, est, P)
    assert np.isnan(position[1, 2]) and np.isnan(velocity[1, 2])
    np.testing.assert_allclose(np.delete(position.ravel(), 5), 2.0)


def test_parts_table_averages_each_kind_and_all() -> None:
    df = pd.DataFrame({"kind": ["cv", "cv", "dubins"], "nees": [1.0, 3.0, 8.0],
                       "nees_pos": [0.5, 1.5, 6.0], "nees_vel": [0.25, 0.75, 1.0]})
    lines = nees_events.parts_table(df).splitlines()
    assert lines[2] == "| cv | 2 | 2.00 | 1.00 | 0.50 |"
    assert lines[3] == "| dubins | 1 | 8.00 | 6.00 | 1.00 |"
    assert lines[4] == "| all | 3 | 4.00 | 2.67 | 0.67 |"


def test_a_multi_target_tracker_s_rows_are_its_assigned_tracks() -> None:
    from sensorplan.simulation.run import run_episode
    from sensorplan.study.file import load_study
    from sensorplan.study.set_metrics import with_assigned_tracks

    study = load_study(ROOT / "studies" / "honest_table_search_mixture.toml")
    settings = dataclasses.replace(study.methods[0].settings, steps=15)
    ep = run_episode(study.scenario, settings, np.random.SeedSequence(3, spawn_key=(0,)))
    rows = nees_events.episode_rows(ep, study.scenario, 0)
    assigned = with_assigned_tracks(ep)
    ok = np.isfinite(assigned.nees[1:])
    assert ok.sum() > 0 and len(rows["nees"]) == ok.sum()
    np.testing.assert_array_equal(rows["nees"], assigned.nees[1:][ok])
    position, velocity = nees_events.nees_parts(assigned.truth, assigned.estimate,
                                                assigned.cov)
    np.testing.assert_array_equal(rows["nees_pos"], position[1:][ok])
    np.testing.assert_array_equal(rows["nees_vel"], velocity[1:][ok])
    assert np.isfinite(rows["nees_pos"]).all() and np.isfinite(rows["nees_vel"]).all()
