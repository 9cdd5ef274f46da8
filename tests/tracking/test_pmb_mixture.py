"""Mixture densities in the PMB tracker (``density_components > 1``). Checked: Runnalls'
greedy reduction against a loop written out pair by pair, and that it keeps each mixture's
weight, mean and covariance; a one-component Bernoulli's first look keeps its missed and
detected hypotheses as the two components, in closed form (the prior and the Kalman
update), with the existence and moment-matched density of the merging tracker; the predict
commutes with moment matching; a later detection at one component takes the weight back;
the contract, and what every step keeps on a radar run with births, clutter and the map's
exit edge; the refusals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sensorplan.errors import ConfigError
from sensorplan.simulation.settings import TrackerSettings
from sensorplan.tracking.checks import CHECKS, Scene, check_tracker
from sensorplan.tracking.pmb import mixture
from sensorplan.tracking.pmb.tracker import PMBTracker
from looks_helpers import LINEAR_MEAN as MEAN
from looks_helpers import LINEAR_P0 as P0
from looks_helpers import MEANS as RADAR_MEANS
from looks_helpers import linear_pmb, moments, one_scan
from test_pmb_modes import radar_model, radar_steps


def tracker(components: int, **kw: object) -> PMBTracker:
    return linear_pmb(density_components=components, **kw)


def random_mixture(rng: np.random.Generator, K: int) -> tuple[np.ndarray, ...]:
    w = rng.uniform(0.05, 1.0, K)
    m = rng.normal(0.0, 20.0, (K, 4))
    A = rng.normal(0.0, 3.0, (K, 4, 4))
    P = A @ np.swapaxes(A, 1, 2) + 2.0 * np.eye(4)
    return w, m, P


def reduce_written_out(w: np.ndarray, m: np.ndarray, P: np.ndarray, keep: int
                       ) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Runnalls' greedy reduction of one mixture, pair by pair in plain loops."""
    comps = [(float(w[k]), m[k], P[k]) for k in range(len(w))]
    while len(comps) > keep:
        best, pair, merged = np.inf, (0, 0), comps[0]
        for i, j in itertools.combinations(range(len(comps)), 2):
            (wi, mi, Pi), (wj, mj, Pj) = comps[i], comps[j]
            mean, cov = moments(np.array([wi, wj]), np.stack([mi, mj]), np.stack([Pi, Pj]))
            cost = 0.5 * ((wi + wj) * np.linalg.slogdet(cov)[1]
                          - wi * np.linalg.slogdet(Pi)[1] - wj * np.linalg.slogdet(Pj)[1])
            if cost < best:
                best, pair, merged = cost, (i, j), (wi + wj, mean, cov)
        comps[pair[0]] = merged
        del comps[pair[1]]
    return comps


@pytest.mark.parametrize(("K", "keep"), [(4, 2), (6, 3), (5, 1)])
def test_reduction_agrees_with_the_loop_and_keeps_the_moments(K: int, keep: int) -> None:
    rng = np.random.default_rng(20261206)
    mixtures = [random_mixture(rng, K) for _ in range(5)]
    w, m, P = (np.stack(a) for a in zip(*mixtures, strict=True))
    rw, rm, rP = mixture.reduce(w, m, P, keep)
    assert rw.shape == (5, keep) and rm.shape == (5, keep, 4) and rP.shape == (5, keep, 4, 4)
    for row, (wk, mk, Pk) in enumerate(mixtures):
        loop = reduce_written_out(wk, mk, Pk, keep)
        np.testing.assert_allclose(rw[row], [c[0] for c in loop], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(rm[row], [c[1] for c in loop], rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(rP[row], [c[2] for c in loop], rtol=0.0, atol=1e-9)
        mean, cov = moments(wk, mk, Pk)
        r_mean, r_cov = moments(rw[row], rm[row], rP[row])
        np.testing.assert_allclose(r_mean, mean, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(r_cov, cov, rtol=0.0, atol=1e-9)


def test_no_rows_reduce_to_no_rows() -> None:
    w, m, P = mixture.reduce(np.zeros((0, 4)), np.zeros((0, 4, 4)), np.zeros((0, 4, 4, 4)), 2)
    assert w.shape == (0, 2) and m.shape == (0, 2, 4) and P.shape == (0, 2, 4, 4)


def test_components_of_weight_zero_merge_first() -> None:
    rng = np.random.default_rng(7)
    w, m, P = random_mixture(rng, 4)
    w[[1, 3]] = 0.0
    m[3], P[3] = 0.0, 0.0                      # a group no hypothesis reached: no moments
    rw, rm, rP = mixture.reduce(w[None], m[None], P[None], 2)
    np.testing.assert_array_equal(rw[0], w[[0, 2]])
    np.testing.assert_array_equal(rm[0], m[[0, 2]])
    np.testing.assert_allclose(rP[0], P[[0, 2]], rtol=0.0, atol=1e-12)


def test_the_first_look_keeps_the_missed_and_the_detected_hypothesis() -> None:
    z = np.array([[195.0, 150.0]])                   # 45 m off: about even odds
    mix, merge = tracker(2), tracker(1)
    mix.update(one_scan(z))
    merge.update(one_scan(z))
    assert len(mix.bern) == len(merge.bern) == 1
    assert abs(mix.bern.r[0] - merge.bern.r[0]) <= 1e-12
    np.testing.assert_allclose(mix.bern.means[0], merge.bern.means[0], rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(mix.bern.covs[0], merge.bern.covs[0], rtol=0.0, atol=1e-9)
    mu, cm, cP = mix.bern.mode_probs[0], mix.bern.mode_means[0], mix.bern.mode_covs[0]
    assert abs(mu.sum() - 1.0) <= 1e-12 and np.all(mu > 0.1)
    # The missed part is the prior (the sensor sees everywhere alike); the detected part
    # the Kalman update with H = [I 0], R = I, in closed form.
    S = P0[:2, :2] + np.eye(2)
    K = P0[:, :2] @ np.linalg.solve(S, np.eye(2))
    x = MEAN[0] + K @ (z[0] - MEAN[0, :2])
    Pd = P0 - K @ S @ K.T
    missed = int(np.argmin(np.linalg.norm(cm[:, :2] - MEAN[0, :2], axis=1)))
    np.testing.assert_allclose(cm[missed], MEAN[0], rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(cP[missed], P0, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(cm[1 - missed], x, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(cP[1 - missed], Pd, rtol=0.0, atol=1e-9)


def test_the_predict_commutes_with_moment_matching() -> None:
    t = tracker(2)
    t.update(one_scan(np.array([[195.0, 150.0]])))
    before = t.bern.means.copy(), t.bern.covs.copy()
    t.predict()
    m = t.F @ before[0][0]
    P = t.F @ before[1][0] @ t.F.T + t.Q
    np.testing.assert_allclose(t.bern.means[0], m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(t.bern.covs[0], P, rtol=0.0, atol=1e-9)
    mean, cov = moments(t.bern.mode_probs[0], t.bern.mode_means[0], t.bern.mode_covs[0])
    np.testing.assert_allclose(mean, m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(cov, P, rtol=0.0, atol=1e-9)


def test_a_detection_at_one_component_takes_the_weight_back() -> None:
    mix = tracker(2)
    mix.update(one_scan(np.array([[195.0, 150.0]])))
    mu = mix.bern.mode_probs[0].copy()
    cm = mix.bern.mode_means[0, :, :2]
    missed = int(np.argmin(np.linalg.norm(cm - MEAN[0, :2], axis=1)))
    mix.predict()
    z = mix.bern.mode_means[0, missed, :2][None]      # where the target is, had it been missed
    mix.update(one_scan(z))
    assert len(mix.bern) == 1
    near = int(np.argmin(np.linalg.norm(mix.bern.mode_means[0, :, :2] - z, axis=1)))
    assert mix.bern.mode_probs[0, near] > 0.5 > mu[missed]
    assert np.linalg.norm(mix.bern.mode_means[0, near, :2] - z) < 1.0     # R = I


def radar_tracker(components: int, edge_exit: str = "outside") -> PMBTracker:
    return PMBTracker(radar_model(), means=RADAR_MEANS, covs=P0, births="edges",
                      birth_rate=0.2, initial_undetected=1.0, density_components=components,
                      edge_exit=edge_exit)


def test_the_mixture_pmb_meets_the_tracker_contract() -> None:
    model = radar_model()
    looks = radar_steps(model.measurement, 1, 0)[0]
    report = check_tracker(lambda: radar_tracker(2), Scene(looks))
    assert report.checks == tuple(CHECKS)


@pytest.mark.parametrize("edge_exit", ["outside", "crossing"])
def test_every_step_keeps_the_mixture_whole(edge_exit: str) -> None:
    """Through births, clutter, starts, the exit edge (either charge) and pruning: each
    Bernoulli's weights sum to 1, its components are covariances, and its density is their
    moment-matched Gaussian; some Bernoullis hold two components of weight."""
    t = radar_tracker(2, edge_exit)
    apart = 0
    for looks in radar_steps(t.model.measurement, 25, 3):
        t.predict()
        t.update(looks)
        b = t.bern
        assert np.all((b.r >= 0.0) & (b.r <= 1.0))
        np.testing.assert_allclose(b.mode_probs.sum(axis=1), 1.0, rtol=0.0, atol=1e-12)
        assert np.all(np.linalg.eigvalsh(b.mode_covs) > 0.0)
        for i in range(len(b)):
            mean, cov = moments(b.mode_probs[i], b.mode_means[i], b.mode_covs[i])
            np.testing.assert_allclose(b.means[i], mean, rtol=0.0, atol=1e-9)
            np.testing.assert_allclose(b.covs[i], cov, rtol=0.0, atol=1e-9)
        apart += int(np.count_nonzero(b.mode_probs.min(axis=1) > 0.05))
    assert apart > 0


def test_placeholder_components_skipped_by_the_missed_look_change_nothing(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The missed-look update skips components of weight 0 (placeholders no hypothesis
    reaches): 25 steps give the same existences, labels, weights and densities as
    updating every component, to the last bit."""
    skipping = radar_tracker(3, "crossing")
    every = radar_tracker(3, "crossing")
    full = PMBTracker._missed

    def missed_every(self, means, covs, look, among=None):  # type: ignore[no-untyped-def]
        return full(self, means, covs, look)

    placeholders = 0
    for looks in radar_steps(skipping.model.measurement, 25, 3):
        skipping.predict()
        skipping.update(looks)
        with monkeypatch.context() as patched:
            patched.setattr(PMBTracker, "_missed", missed_every)
            every.predict()
            every.update(looks)
        a, b = skipping.bern, every.bern
        np.testing.assert_array_equal(a.labels, b.labels)
        np.testing.assert_array_equal(a.r, b.r)
        np.testing.assert_array_equal(a.mode_probs, b.mode_probs)
        np.testing.assert_array_equal(a.means, b.means)
        np.testing.assert_array_equal(a.covs, b.covs)
        live = a.mode_probs > 0.0
        np.testing.assert_array_equal(a.mode_means[live], b.mode_means[live])
        placeholders += int(np.count_nonzero(~live))
    assert placeholders > 0


def test_the_planner_predicts_with_the_one_motion_model() -> None:
    t = tracker(3)
    assert t.planning_process_noise() == t.process_noise


@pytest.mark.parametrize("kw", [dict(split_existence=0.1),
                                dict(mode_process_noise=(0.1, 1.0),
                                     switching=np.array([[0.9, 0.1], [0.1, 0.9]])),
                                dict(recycle_threshold=0.1, recycle_motion="moving")])
def test_a_mixture_refuses_what_it_cannot_carry(kw: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="density_components"):
        tracker(2, **kw)


@pytest.mark.parametrize("bad", [0, 9, 2.0])
def test_the_tracker_refuses_a_bad_number_of_components(bad: object) -> None:
    with pytest.raises(ValueError, match="density_components"):
        tracker(bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("kw", [dict(bernoulli_model="imm"), dict(split_existence=0.1),
                                dict(recycle_threshold=0.1, recycle_motion="moving")])
def test_the_settings_name_density_components(kw: dict[str, object]) -> None:
    with pytest.raises(ConfigError) as err:
        TrackerSettings(kind="pmb", density_components=2, **kw)  # type: ignore[arg-type]
    assert err.value.field == "density_components"


def test_the_settings_take_the_trackers_range_of_components() -> None:
    assert TrackerSettings(kind="pmb", density_components=mixture.MAX_COMPONENTS)
    with pytest.raises(ConfigError, match="density_components"):
        TrackerSettings(kind="pmb", density_components=mixture.MAX_COMPONENTS + 1)
    with pytest.raises(ConfigError, match="density_components"):
        TrackerSettings(kind="pmb", density_components=0)
