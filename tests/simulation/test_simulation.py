"""Closed-loop simulation: determinism, pairing, execution schedule, recording, files."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pytest

from sensorplan.simulation import episode as episode_module
from sensorplan.simulation import run as simulation
from sensorplan.models.angles import heading_rule, wrap_angle
from sensorplan.models.motion import cv_matrices
from sensorplan.tracking.tracker import KnownTargetTracker
from sensorplan.errors import ConfigError
from sensorplan.planners import PLANNERS, PlanResult
from sensorplan.planners.problem import MapRect, Plan, PlanningProblem, move_vectors
from sensorplan.simulation.scenario import Scenario, SensorSpec, TargetSpec, paper_scenario
from radar_reference import cos_boresight, noise_std, visible
from sensorplan.models.sensors import SensorParams
from sensorplan.simulation.settings import TrackerSettings
from sensorplan.simulation import Episode, RunSettings, run_episode, run_streams


#: The plain tracker these tests were written for: one CV filter, no gate, no map.
PLAIN = dict(model="cv", process_noise=0.05, gate=False, reacquire=False, known_map=False)


def settings(miss_update: str = "none", **kw) -> RunSettings:
    base = dict(planner="random", steps=30, steps_per_epoch=2, horizon=1,
                tracker=TrackerSettings(miss_update=miss_update, **PLAIN))
    base.update(kw)
    return RunSettings(**base)


def assert_episodes_equal(a: Episode, b: Episode) -> None:
    for name in episode_module._ARRAYS:
        if name == "planning_seconds":   # wall-clock time
            continue
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@dataclass(frozen=True)
class ScriptedPlanner:
    """Test planner: sensor i moves +20 m in x (or stays at the edge) each epoch and looks
    at target (i + k + decision) % M; it records every problem it receives."""

    name: ClassVar[str] = "scripted"
    problems: ClassVar[list] = []
    plans: ClassVar[list] = []

    def plan(self, problem: PlanningProblem, rng=None) -> PlanResult:
        N, K, M = problem.n_sensors, problem.horizon, problem.n_targets
        d = len(self.problems)
        pos = np.empty((N, K, 2))
        tgt = np.empty((N, K), dtype=np.int64)
        for i in range(N):
            p = np.array(problem.positions[i])
            for k in range(K):
                if p[0] + 20.0 <= problem.world.width:
                    p = p + [20.0, 0.0]
                pos[i, k] = p
                tgt[i, k] = (i + k + d) % M
        plan = Plan(pos, tgt)
        self.problems.append(problem)
        self.plans.append(plan)
        return PlanResult(self.name, plan, 1.5 + d, np.zeros(M), np.zeros((N, K)),
                          np.zeros((N, K), dtype=np.int64), converged=bool(d % 2), sweeps=d)


@pytest.fixture
def scripted(monkeypatch):
    monkeypatch.setitem(PLANNERS, "scripted", ScriptedPlanner)
    ScriptedPlanner.problems.clear()
    ScriptedPlanner.plans.clear()
    return ScriptedPlanner


class TestSettings:
    @pytest.mark.parametrize("field,value,path", [
        ("horizon", 0, "horizon"), ("steps_per_epoch", 0, "steps_per_epoch"),
        ("steps", 0, "steps"), ("horizon", 1.5, "horizon"), ("steps", True, "steps"),
        ("execution", "closed", "execution"), ("visibility", "maybe", "visibility"),
        ("objective", "sum", "objective"), ("planner_params", 3, "planner_params"),
        ("tracker", {"miss_update": "positive"}, "tracker.miss_update"),
        ("tracker", {"miss_updat": "none"}, "tracker.miss_updat"), ("tracker", 1, "tracker")])
    def test_bad_values_name_the_field(self, field, value, path):
        with pytest.raises(ConfigError) as err:
            RunSettings(**{field: value})
        assert err.value.field == path

    def test_unknown_planner_and_bad_params(self):
        with pytest.raises(ConfigError) as err:
            RunSettings(planner="nope")
        assert err.value.field.startswith("planner")
        with pytest.raises(ConfigError) as err:
            RunSettings(planner="random", planner_params={"bogus": 1})
        assert err.value.field.startswith("planner")

    def test_bad_seed(self):
        with pytest.raises(ConfigError) as err:
            run_episode(paper_scenario(), settings(steps=2), -1)
        assert err.value.field == "seed"


class TestDeterminism:
    def test_same_seed_same_episode_and_identical_file(self, tmp_path):
        a = run_episode(paper_scenario(), settings(), 42)
        b = run_episode(paper_scenario(), settings(), 42)
        assert_episodes_equal(a, b)
        # Saved files: identical bytes apart from the wall-clock planning times.
        b2 = replace(b, planning_seconds=a.planning_seconds)
        a.save(tmp_path / "a.npz")
        b2.save(tmp_path / "b.npz")
        assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()

    def test_different_seeds_differ(self):
        a = run_episode(paper_scenario(), settings(), 1)
        b = run_episode(paper_scenario(), settings(), 2)
        assert not np.allclose(a.truth[0], b.truth[0])
        assert not np.allclose(a.sensor_positions[0], b.sensor_positions[0])
        assert not np.array_equal(a.looked[1:], b.looked[1:])

    def test_seed_sequence_is_not_consumed(self):
        ss = np.random.SeedSequence(7, spawn_key=(3,))
        a = run_episode(paper_scenario(), settings(steps=10), ss)
        b = run_episode(paper_scenario(), settings(steps=10), ss)
        assert_episodes_equal(a, b)
        assert ss.n_children_spawned == 0
        assert a.seed_entropy == 7 and a.seed_spawn_key == (3,)
        assert_episodes_equal(run_episode(paper_scenario(), settings(steps=10), 7),
                              run_episode(paper_scenario(), settings(steps=10),
                                          np.random.SeedSequence(7)))

    def test_streams_are_the_spawned_children(self):
        streams = run_streams(5)
        children = np.random.SeedSequence(5).spawn(8)
        # New streams are appended: the first four keep the values they always had.
        assert list(streams) == ["truth", "init", "noise", "planner", "detection", "clutter",
                                "target_detection", "births"]
        for s, c in zip(streams.values(), children):
            np.testing.assert_array_equal(s.generate_state(4), c.generate_state(4))


class _RecordingTracker(KnownTargetTracker):
    calls: ClassVar[list] = []

    def update_detections(self, sensors, targets, z, sensor_xy, heading):
        self.calls.append((np.array(sensors), np.array(z)))
        return super().update_detections(sensors, targets, z, sensor_xy, heading)


def recovered_noise(ep: Episode, calls, scenario: Scenario) -> dict[tuple[int, int], np.ndarray]:
    """The standard normals behind each measurement, from z and the recorded truth."""
    steps = [t for t in range(1, len(ep.truth)) if ep.measured[t].any()]
    assert len(steps) == len(calls)
    out = {}
    for t, (sensors, z) in zip(steps, calls):
        for i, zi in zip(sensors, z):
            p = scenario.sensors[i].params
            j = ep.looked[t, i]
            dx, dy = ep.truth[t, j, :2] - ep.sensor_positions[t, i]
            r = math.sqrt(dx * dx + dy * dy + p.altitude**2)
            sr, sp = noise_std(r, cos_boresight(dx, dy, ep.sensor_headings[t, i], p), p)
            out[(t, int(i))] = np.array([(zi[0] - r) / sr,
                                         float(wrap_angle(zi[1] - math.atan2(dy, dx))) / sp])
    return out


class TestPairing:
    def test_two_planners_share_truth_initial_estimates_and_noise(self, monkeypatch):
        monkeypatch.setattr(simulation, "tracker_class", lambda kind: _RecordingTracker)
        sc = paper_scenario()
        S, seed = 40, 3
        streams = run_streams(seed)
        reference = [np.random.default_rng(c).standard_normal((S, 2))
                     for c in streams["noise"].spawn(len(sc.sensors))]
        episodes = []
        for planner in ("random", "sequential-greedy"):
            _RecordingTracker.calls = []
            ep = run_episode(sc, settings(planner=planner, steps=S), seed)
            noise = recovered_noise(ep, _RecordingTracker.calls, sc)
            assert len(noise) > 5
            for (t, i), n in noise.items():
                np.testing.assert_allclose(n, reference[i][t - 1], rtol=1e-6, atol=1e-6)
            episodes.append(ep)
        a, b = episodes
        np.testing.assert_array_equal(a.truth, b.truth)
        np.testing.assert_array_equal(a.estimate[0], b.estimate[0])
        np.testing.assert_array_equal(a.sensor_positions[0], b.sensor_positions[0])
        np.testing.assert_array_equal(a.sensor_headings[0], b.sensor_headings[0])
        assert not np.array_equal(a.looked, b.looked)        # the methods did differ

    def test_miss_option_does_not_change_truth_or_noise_streams(self):
        a = run_episode(paper_scenario(), settings(miss_update="none"), 8)
        b = run_episode(paper_scenario(), settings(miss_update="negative"), 8)
        np.testing.assert_array_equal(a.truth, b.truth)
        np.testing.assert_array_equal(a.estimate[0], b.estimate[0])
        np.testing.assert_array_equal(a.sensor_positions[0], b.sensor_positions[0])
        assert b.negative_update.any() and not np.array_equal(a.estimate, b.estimate)


class TestSchedule:
    @pytest.mark.parametrize("execution,expected", [("olf", [0, 2, 4, 6, 8, 10]),
                                                    ("ol", [0, 6])])
    def test_decision_steps(self, execution, expected):
        ep = run_episode(paper_scenario(), settings(horizon=3, steps_per_epoch=2, steps=12,
                                           execution=execution), 0)
        np.testing.assert_array_equal(ep.decision_steps, expected)
        assert len(ep.planning_seconds) == len(ep.potential) == len(expected)
        assert np.all(np.isnan(ep.converged)) and np.all(np.isnan(ep.sweeps))

    @pytest.mark.parametrize("execution", ["ol", "olf"])
    def test_plans_are_executed_as_planned(self, scripted, execution):
        sc = paper_scenario()
        K, e, S = 3, 2, 14
        ep = run_episode(sc, settings(planner="scripted", horizon=K, steps_per_epoch=e,
                                      steps=S, execution=execution), 4)
        per_plan = K if execution == "ol" else 1
        assert len(scripted.problems) == len(ep.decision_steps)
        for d, (s, problem, plan) in enumerate(zip(ep.decision_steps, scripted.problems,
                                                   scripted.plans)):
            assert s == d * per_plan * e
            # The problem is the tracker's state and the poses at the decision time.
            np.testing.assert_array_equal(problem.means, ep.estimate[s])
            np.testing.assert_array_equal(problem.covs, ep.cov[s])
            np.testing.assert_array_equal(problem.positions, ep.sensor_positions[s])
            np.testing.assert_array_equal(problem.headings, ep.sensor_headings[s])
            assert (problem.horizon, problem.steps_per_epoch) == (K, e)
            assert problem.sensors == tuple(x.params for x in sc.sensors)
            for k in range(per_plan):
                for t in range(s + k * e + 1, min(s + (k + 1) * e, S) + 1):
                    np.testing.assert_array_equal(ep.sensor_positions[t],
                                                  plan.positions[:, k])
                    np.testing.assert_array_equal(ep.looked[t], plan.targets[:, k])
        np.testing.assert_array_equal(ep.potential, 1.5 + np.arange(len(ep.potential)))
        np.testing.assert_array_equal(ep.converged, np.arange(len(ep.potential)) % 2)
        np.testing.assert_array_equal(ep.sweeps, np.arange(len(ep.potential)))

    def test_poses_change_only_at_epoch_starts_by_moves_and_the_heading_rule(self):
        sc = paper_scenario()
        e = 3
        ep = run_episode(sc, settings(steps=30, steps_per_epoch=e, horizon=2,
                                      execution="ol"), 9)
        F, _ = cv_matrices(sc.dt, sc.process_noise)
        moves = move_vectors(sc.sensors[0].params.moves)
        for t in range(1, 31):
            dp = ep.sensor_positions[t] - ep.sensor_positions[t - 1]
            if (t - 1) % e:
                np.testing.assert_array_equal(dp, 0.0)
                np.testing.assert_array_equal(ep.sensor_headings[t], ep.sensor_headings[t - 1])
                np.testing.assert_array_equal(ep.looked[t], ep.looked[t - 1])
                continue
            for i, spec in enumerate(sc.sensors):
                assert np.min(np.abs(moves - dp[i]).max(axis=1)) < 1e-6
                aim = F @ ep.estimate[t - 1, ep.looked[t, i]]
                p = ep.sensor_positions[t, i]
                bearing = math.atan2(aim[1] - p[1], aim[0] - p[0])
                expected = heading_rule(ep.sensor_headings[t - 1, i], bearing,
                                        spec.params.max_turn)
                assert abs(wrap_angle(ep.sensor_headings[t, i] - expected)) < 1e-9
            assert np.all(sc.world.contains(ep.sensor_positions[t]))

    def test_progress_callback(self):
        seen = []
        run_episode(paper_scenario(), settings(steps=7), 0,
                    progress=lambda d, n: seen.append((d, n)))
        assert seen == [(t, 7) for t in range(1, 8)]


class TestRecording:
    def test_missed_exactly_when_target_truly_outside_fov(self):
        sc = paper_scenario()
        ep = run_episode(sc, settings(steps=60), 12)
        S = 60
        assert np.all(ep.looked[0] == -1) and not ep.missed[0].any()
        assert not ep.measured[0].any()
        for i, spec in enumerate(sc.sensors):
            j = ep.looked[1:, i]
            assert np.all(j >= 0)
            vis = visible(ep.truth[np.arange(1, S + 1), j], ep.sensor_positions[1:, i],
                          ep.sensor_headings[1:, i], spec.params)
            np.testing.assert_array_equal(ep.missed[1:, i], ~vis)
            np.testing.assert_array_equal(ep.measured[np.arange(1, S + 1), j, i], vis)
        # Nothing is measured that was not looked at.
        looked_mask = np.zeros_like(ep.measured)
        for i in range(len(sc.sensors)):
            looked_mask[np.arange(1, S + 1), ep.looked[1:, i], i] = True
        assert not (ep.measured & ~looked_mask).any()
        assert 0 < ep.missed[1:].mean() < 1
        assert not ep.negative_update.any() and not ep.inflated.any()

    def test_metrics_are_consistent(self):
        ep = run_episode(paper_scenario(), settings(), 5)
        d = ep.truth[..., :2] - ep.estimate[..., :2]
        np.testing.assert_allclose(ep.error, np.sqrt((d**2).sum(-1)), rtol=1e-12)
        e = ep.truth - ep.estimate
        expected = np.einsum("tmi,tmij,tmj->tm", e, np.linalg.inv(ep.cov), e)
        np.testing.assert_allclose(ep.nees, expected, rtol=1e-8)
        np.testing.assert_allclose(ep.rmse(), np.sqrt((ep.error[1:] ** 2).mean(0)))
        S, M, N = 30, 5, 3
        assert ep.truth.shape == (S + 1, M, 4) and ep.cov.shape == (S + 1, M, 4, 4)
        assert ep.measured.shape == (S + 1, M, N) and ep.looked.shape == (S + 1, N)
        assert ep.target_kinds == ("cv", "cv", "cv", "dubins", "dubins")
        P = ep.cov
        np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
        np.linalg.cholesky(P)

    def test_save_load_round_trip(self, tmp_path):
        ep = run_episode(paper_scenario(), settings(planner_params={"seed": 3}, horizon=2,
                                           execution="ol"), 6)
        ep.save(tmp_path / "ep.npz")
        back = Episode.load(tmp_path / "ep.npz")
        for name in episode_module._ARRAYS:
            a, b = getattr(ep, name), getattr(back, name)
            if a is None:     # the search records and the undetected intensity: a run
                # without search whose tracker (known targets) keeps none
                assert b is None and (name.startswith("search") or name == "undetected"), name
                continue
            assert a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        assert back.settings == ep.settings
        assert back.target_kinds == ep.target_kinds
        assert back.seed_entropy == ep.seed_entropy == 6


def always_visible_scenario() -> Scenario:
    """One cv target and one sensor whose field of view is the whole ground."""
    params = SensorParams(depression=math.pi / 2, fov_half_angle=math.pi,
                          min_ground_range=1e-6, max_ground_range=1e5)
    return Scenario(world=MapRect(), targets=(TargetSpec("cv", position=(300.0, 300.0)),),
                    sensors=(SensorSpec(params, position=(150.0, 150.0), heading=0.0),))


class TestTracking:
    def test_a_sensor_that_always_sees_keeps_errors_bounded(self):
        ep = run_episode(always_visible_scenario(), settings(steps=200, steps_per_epoch=1), 21)
        assert ep.measured[1:, 0, 0].all() and not ep.missed.any()
        assert ep.error[1:].max() < 60.0
        assert ep.rmse()[0] < 15.0
        # Without measurements the position variance would have grown to about
        # 20^2 + q T^3 / 3 ~ 1.3e5 m^2; measured every step it stays small.
        assert ep.cov[-1, 0, 0, 0] < 100.0

    def test_negative_miss_updates_follow_the_misses(self):
        sc = paper_scenario()
        ep = run_episode(sc, settings(steps=60, miss_update="negative"), 12)
        S = 60
        expected = np.zeros_like(ep.negative_update)
        for i in range(len(sc.sensors)):
            t = np.flatnonzero(ep.missed[:, i])
            expected[t, ep.looked[t, i]] = True
        np.testing.assert_array_equal(ep.negative_update, expected)
        assert not (ep.inflated & ~ep.negative_update).any()
        assert ep.negative_update.any()
        assert_episodes_equal(ep, run_episode(sc, settings(steps=60, miss_update="negative"),
                                              12))
        # "none" turns the updates off, and the truth is unchanged.
        off = run_episode(sc, settings(steps=60, miss_update="none"), 12)
        assert not off.negative_update.any()
        np.testing.assert_array_equal(off.truth, ep.truth)
        assert S == len(ep.truth) - 1

    def test_negative_update_is_the_kernel_applied_in_sensor_order(self, monkeypatch):
        from sensorplan.tracking import missed
        calls = []
        kernel = missed.miss_update

        def spy(means, covs, sensor_xy, heading, table, sensor):
            calls.append((np.array(means), np.array(covs), np.array(sensor_xy),
                          np.array(heading)))
            return kernel(means, covs, sensor_xy, heading, table, sensor)

        monkeypatch.setattr(missed, "miss_update", spy)
        ep = run_episode(paper_scenario(), settings(steps=20, miss_update="negative"), 13)
        assert sum(len(c[0]) for c in calls) == ep.missed.sum()
        # Every call touches distinct tracks.
        for m, *_ in calls:
            assert len({tuple(r) for r in m}) == len(m)


def test_none_reproduces_a_tracker_without_the_feature(monkeypatch):
    """``miss_update = "none"`` never touches the missed-look code and gives exactly the
    tracks of a tracker whose miss update is a no-op (the feature removed)."""
    import sensorplan.simulation.run as sim

    def forbidden():
        raise AssertionError("the miss-update kernel was requested with miss_update='none'")

    monkeypatch.setattr(sim, "_miss_update_kernel", forbidden)
    off = run_episode(paper_scenario(), settings(steps=40), 21)
    assert off.missed.any()                       # there were misses to learn from

    def identity(means, covs, sensor_xy, heading, table, sensor):
        return np.array(means), np.array(covs), np.zeros(len(means), dtype=bool)

    monkeypatch.setattr(sim, "_miss_update_kernel", lambda: identity)
    noop = run_episode(paper_scenario(), settings(steps=40, miss_update="negative"), 21)
    for name in ("truth", "estimate", "cov", "error", "measured", "looked", "missed"):
        np.testing.assert_array_equal(getattr(off, name), getattr(noop, name), err_msg=name)


def test_a_run_records_its_reported_tracks_as_a_set(tmp_path) -> None:
    from sensorplan.study.set_metrics import episode_set_metrics
    from sensorplan.study.set_metrics import gospa

    ep = run_episode(paper_scenario(), settings(steps=12), 4)
    S1, M = ep.truth.shape[:2]
    assert ep.alive.all()
    # a tracker of known targets reports every target's track, labelled with its index
    np.testing.assert_array_equal(ep.track_step, np.repeat(np.arange(S1), M))
    np.testing.assert_array_equal(ep.track_label, np.tile(np.arange(M), S1))
    np.testing.assert_array_equal(ep.track_mean.reshape(S1, M, 4), ep.estimate)
    np.testing.assert_array_equal(ep.track_cov.reshape(S1, M, 4, 4), ep.cov)
    # GOSPA of each step, against an independent per-step computation
    sm = episode_set_metrics(ep, c=50.0)
    for t in (1, 6, 12):
        want = gospa(ep.truth[t, :, :2], ep.estimate[t, :, :2], 50.0)
        np.testing.assert_allclose(sm.gospa.distance[t - 1], want.distance, rtol=1e-12)
    # an episode file written before the set records existed reads with the same records
    path = tmp_path / "e.npz"
    ep.save(path)
    import zipfile
    old = tmp_path / "old.npz"
    with zipfile.ZipFile(path) as zin, zipfile.ZipFile(old, "w") as zout:
        for item in zin.infolist():
            if not item.filename.startswith(("alive", "track_")):
                zout.writestr(item, zin.read(item.filename))
    back = Episode.load(old)
    for name in ("alive", "track_step", "track_label", "track_mean", "track_cov",
                 "track_existence"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ep, name))


def test_a_multi_target_tracker_finds_targets_nobody_named() -> None:
    import dataclasses

    from sensorplan.simulation.scenario import radar_scenario
    from sensorplan.study.set_metrics import episode_set_metrics

    # Targets born at the edges, none known to the tracker: every track is a found one.
    sc = dataclasses.replace(radar_scenario(), births="edges", birth_rate=0.05,
                             initial_targets=2, look_detects="all")
    s = RunSettings(planner="pg", steps=60, tracker=TrackerSettings(kind="pmb"))
    ep = run_episode(sc, s, 7)
    assert ep.alive[0].sum() == 2 and ep.alive.shape[1] >= 2
    sm = episode_set_metrics(ep, c=50.0)
    assert np.all(np.isfinite(sm.gospa.distance))
    # Tracks are reported once found; a reported track's label is kept for its life.
    assert len(np.unique(ep.track_label[ep.track_step > 30])) > 0
    assert ((ep.track_existence >= 0.5) & (ep.track_existence <= 1.0)).all()
    # half the run's steps end with every live target within c of a reported track
    found = sm.gospa.missed == 0
    assert found.mean() > 0.5, found.mean()
    # each live target's error is that of the track GOSPA assigns to it (NaN without one)
    from sensorplan.study.set_metrics import with_assigned_tracks

    a = with_assigned_tracks(ep)
    steps, ids = np.nonzero(ep.alive[1:])
    for k in np.flatnonzero(sm.assigned)[::7]:
        t, j = steps[k] + 1, ids[k]
        row = np.flatnonzero((ep.track_step == t) & (ep.track_label == sm.label[k]))
        np.testing.assert_array_equal(a.estimate[t, j], ep.track_mean[row[0]])
        assert a.error[t, j] == np.hypot(*(ep.truth[t, j, :2] - ep.track_mean[row[0], :2]))
    assert np.isnan(a.error[steps[~sm.assigned] + 1, ids[~sm.assigned]]).all()


def test_a_multi_target_trackers_map_edge_follows_the_scenarios_truth_by_default() -> None:
    import dataclasses

    from sensorplan.simulation.run import map_edge
    from sensorplan.simulation.scenario import (SensorSpec, benchmark_scenario,
                                                radar_scenario, search_scenario)

    auto = TrackerSettings(kind="pmb")
    assert auto.map_edge == "scenario"
    # The walls turn the radar preset's targets back (and targets born anywhere); the
    # search preset's are born at the edges and die when they leave; a scripted truth's
    # cross the walls.
    assert map_edge(radar_scenario(), auto) == "closed"
    assert map_edge(dataclasses.replace(radar_scenario(), births="uniform", birth_rate=0.1,
                                        survival_probability=0.99), auto) == "closed"
    assert search_scenario().births == "edges"
    assert map_edge(search_scenario(), auto) == "exit"
    assert map_edge(benchmark_scenario("vo12", (SensorSpec(),)), auto) == "exit"
    for edge in ("exit", "closed"):                        # a written value wins
        for sc in (radar_scenario(), search_scenario()):
            assert map_edge(sc, TrackerSettings(kind="pmb", map_edge=edge)) == edge


def test_a_closed_map_edge_run_repeats_and_differs_from_an_exit_one() -> None:
    import dataclasses

    from sensorplan.simulation.scenario import radar_scenario

    sc = dataclasses.replace(radar_scenario(), look_detects="all")
    eps = {}
    for edge in ("closed", "closed", "exit"):
        s = RunSettings(planner="pg", steps=30,
                        tracker=TrackerSettings(kind="pmb", map_edge=edge))
        eps.setdefault(edge, []).append(run_episode(sc, s, 5))
    a, b = eps["closed"]
    for name in ("truth", "track_step", "track_label", "track_mean", "track_cov",
                 "track_existence"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.settings.tracker.map_edge == "closed"
    # The truth is the same; the tracks are not (this run's tracks meet the walls).
    c = eps["exit"][0]
    np.testing.assert_array_equal(a.truth, c.truth)
    assert not (a.track_mean.shape == c.track_mean.shape
                and np.array_equal(a.track_mean, c.track_mean))


def test_a_multi_target_tracker_needs_looks_that_detect_every_target(tmp_path, capsys) -> None:
    from cli_helpers import run

    f = tmp_path / "s.toml"
    f.write_text('[tracker]\nkind = "pmb"\n[[targets]]\nkind = "cv"\n[[sensors]]\n')
    code, out, err = run(capsys, "simulate", f, "--steps", "3", "--out", tmp_path / "o")
    assert (code, out) == (2, "")
    assert err.splitlines() == ["error: look_detects: a multi-target tracker needs looks that "
                                "detect every live target in view: look_detects = 'all'"]


def test_a_multi_target_trackers_flags_are_per_track_not_per_target() -> None:
    # 5 targets; a multi-target tracker reported 6 tracks before its predict and 5 after
    # (one fell below the report threshold): its flags, one per reported track, are not
    # the targets' even when there are as many, and must not be recorded as theirs.
    from sensorplan.simulation.episode import Recorder, Sensed
    from sensorplan.tracking.base import Looks, TrackSet, UpdateRecord

    M, N = 5, 3
    rng = np.random.default_rng(0)
    truth = rng.uniform(0.0, 600.0, (M, 4))
    tracks = TrackSet(means=truth.copy(), covs=np.repeat(np.eye(4)[None], M, 0),
                      existence=np.ones(M), labels=np.arange(M))
    looks = Looks(sensors=np.arange(N), aims=np.array([5, 0, -1]),
                  positions=np.zeros((N, 2)), headings=np.zeros(N),
                  detections=tuple(np.zeros((0, 2)) for _ in range(N)))
    sensed = Sensed(seen=np.zeros(N, dtype=bool), missed=np.zeros(N, dtype=bool),
                    false_alarms=np.zeros(N, dtype=np.int16),
                    measured=np.zeros((M, N), dtype=bool))
    flags = np.ones(M, dtype=bool)
    update = UpdateRecord(flags, flags, flags, flags, np.zeros(N, dtype=np.int64),
                          np.zeros(N, dtype=np.int64))
    predicted = np.ones(M + 1, dtype=bool)
    for known in (False, True):
        rec = Recorder(2, M, N, known_targets=known)
        rec.start(truth, tracks, np.zeros((N, 2)), np.zeros(N))
        if known:                                     # a known tracker's are per target
            rec.step(1, truth, np.ones(M, dtype=bool), tracks, np.array([0, 1, -1]), looks,
                     sensed, np.zeros(M, dtype=bool), update)
        else:
            rec.step(1, truth, np.ones(M, dtype=bool), tracks, np.array([5, 0, -1]), looks,
                     sensed, predicted, update)
        for name in ("negative_update", "inflated", "restarted", "map_corrected"):
            assert rec.arrays[name][1].all() == known, name
