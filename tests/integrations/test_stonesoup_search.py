"""Search in the Stone Soup bridge: the PMB adapter's aimed radars and undetected intensity,
sector aims, the reward that values search and the manager that plans it.

Skipped cleanly where Stone Soup is not installed (the ``stonesoup`` extra).
"""

from __future__ import annotations

import datetime
import math
import runpy
from pathlib import Path

import numpy as np
import pytest

stonesoup = pytest.importorskip("stonesoup")

from stonesoup.platform import FixedPlatform  # noqa: E402
from stonesoup.types.state import State  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402

from sensorplan.errors import ConfigError  # noqa: E402
from sensorplan.integrations import stonesoup as ss  # noqa: E402
from sensorplan.integrations.stonesoup._convert import (to_stonesoup_cov,  # noqa: E402
                                                        to_stonesoup_mean)
from sensorplan.models import radar  # noqa: E402
from sensorplan.models.angles import heading_rule, wrap_angle  # noqa: E402
from sensorplan.models.sensors import SensorParams, radar_table  # noqa: E402
from sensorplan.planners import search  # noqa: E402
from sensorplan.planners.problem import (Plan, PlanningProblem,  # noqa: E402
                                         UndetectedIntensity)
from sensorplan.tracking.base import Looks  # noqa: E402
from sensorplan.tracking.pmb.map_tracker import MapModel  # noqa: E402
from sensorplan.tracking.pmb.tracker import PMBTracker  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
T0 = datetime.datetime(2026, 1, 1)
T1 = T0 + datetime.timedelta(seconds=1)
WORLD = ss.MapRect(-300.0, -300.0, 600.0, 600.0)     # an origin off 0: frames must agree
PARAMS = SensorParams(detection="swerling1", snr_ref_db=10.0, range_ref=700.0,
                      false_alarm_probability=1e-4, moves=(20.0,))


def _platforms(positions, headings, sectors=8, params=PARAMS):
    out = []
    for (x, y), h in zip(positions, headings):
        rad = ss.SensorplanRadar(params=params, heading=float(h), search_sectors=sectors)
        ctl = ss.LatticeMovable(states=[State([[x], [y], [params.altitude]], timestamp=T0)],
                                position_mapping=(0, 1, 2), move_distances=params.moves,
                                world=WORLD)
        out.append(FixedPlatform(movement_controller=ctl, sensors=[rad]))
    return out


def _tracker(radars, rng, resolution=50.0):
    """A PMB adapter with an uneven undetected intensity (so sectors differ in value)."""
    n = math.ceil(WORLD.width / resolution) * math.ceil(WORLD.height / resolution)
    return ss.PMBStoneSoupTracker(radars=radars, world=WORLD, dt=1.0, start_time=T0,
                                  settings={"births": "edges", "birth_rate": 0.2,
                                            "survival_probability": 0.98,
                                            "resolution": resolution},
                                  initial_intensity=rng.gamma(0.5, 0.2, n))


def _tracks(means, covs, existence):
    """Tracks whose states carry an existence probability (world frame, Stone Soup order)."""
    out = []
    for k, (m, P, r) in enumerate(zip(means, covs, existence)):
        state = ss.BernoulliGaussianState(to_stonesoup_mean(m).reshape(4, 1),
                                          to_stonesoup_cov(P), timestamp=T0,
                                          existence_probability=float(r))
        out.append(Track([state], id=f"t{k}"))
    return out


def _world_means(rng, M):
    xy = rng.uniform(-200.0, 200.0, (M, 2))
    v = rng.normal(0.0, 3.0, (M, 2))
    means = np.hstack([xy, v])
    A = rng.normal(size=(M, 4, 4)) * np.array([10.0, 10.0, 1.0, 1.0])[:, None]
    covs = A @ np.swapaxes(A, -1, -2) + np.diag([25.0, 25.0, 0.5, 0.5])
    return means, covs


def test_pmb_adapter_with_radars_is_the_core_tracker_fed_the_same_looks(rng):
    platforms = _platforms([(-100.0, 0.0), (150.0, 50.0)], [0.3, 2.0])
    radars = [p.sensors[0] for p in platforms]
    tracker = _tracker(radars, rng)
    core = PMBTracker(MapModel(radar_table([PARAMS, PARAMS]), 1.0, (600.0, 600.0),
                               resolution=50.0),
                      births="edges", birth_rate=0.2, survival_probability=0.98)
    core.undetected = tracker.pmb.undetected.copy()
    truth = [State(np.array([[x], [0.0], [y], [0.0]]), timestamp=T1)
             for x, y in ((150.0, 100.0), (0.0, 250.0), (200.0, -50.0))]
    for t, when in enumerate((T1, T1 + datetime.timedelta(seconds=1))):
        truth = [State(s.state_vector, timestamp=when) for s in truth]
        gen = np.random.default_rng(t)
        dets = set()
        for r in radars:
            dets |= r.measure(truth, rng=gen)
        tracker.update_tracker(when, dets)
        # The core tracker gets each radar's detections, from its pose, in core frame.
        Z = []
        for r in radars:
            mine = [d for d in dets if tuple(d.measurement_model.sensor_xy)
                    == tuple(r.ground_position)]
            z = np.array([np.asarray(d.state_vector, float).ravel() for d in mine]).reshape(-1, 2)
            Z.append(z[np.lexsort((z[:, 1], z[:, 0]))])
        core.predict()
        core.update(Looks(np.arange(2), np.full(2, -1),
                          np.array([r.ground_position - WORLD.origin for r in radars]),
                          np.array([r.heading for r in radars]), tuple(Z)))
        np.testing.assert_array_equal(tracker.pmb.undetected, core.undetected)
        np.testing.assert_array_equal(tracker.pmb.bern.r, core.bern.r)
    u = tracker.undetected_intensity(weight=2.0)
    np.testing.assert_array_equal(u.weights, core.undetected)
    np.testing.assert_array_equal(u.centres, core.grid.centres)
    assert u.survival == 0.98 and u.weight == 2.0
    assert u.births.sum() == pytest.approx(0.2, rel=1e-12)


def test_one_scan_thins_the_intensity_only_where_a_radar_looked(rng):
    (platform,) = _platforms([(0.0, 0.0)], [0.0])
    rad = platform.sensors[0]
    tracker = _tracker([rad], rng)
    before = tracker.pmb.undetected.copy()
    tracker.update_tracker(T1, set())
    centres = tracker.pmb.grid.centres
    d = centres - (rad.ground_position - WORLD.origin)
    p = radar.detectable_points(radar_table(PARAMS), np.zeros(1, dtype=np.int64), d[None, :, 0],
                                d[None, :, 1], np.array([rad.heading]),
                                (rad.ground_position - WORLD.origin)[None], np.zeros((0, 5)))[0]
    predicted = 0.98 * before + tracker.pmb.births
    np.testing.assert_allclose(tracker.pmb.undetected, predicted * (1.0 - p), rtol=1e-12)
    assert (p > 0).any() and (p == 0).any()


def test_aim_generator_offers_each_distinct_sector_heading_once():
    # A 20 degree turn limit maps every far sector to one of the two extreme headings.
    params = SensorParams(max_turn=math.radians(20.0))
    (platform,) = _platforms([(0.0, 0.0)], [0.1], sectors=12, params=params)
    rad = platform.sensors[0]
    (gen,) = rad.actions(T1)
    offered = [a for a in gen if isinstance(a.target, ss.SearchSector)]
    bearings = 2.0 * np.pi * np.arange(12) / 12
    reached = [float(heading_rule(0.1, b, params.max_turn)) for b in bearings]
    distinct = []
    for h in reached:
        if not any(abs(float(wrap_angle(h - g))) <= 1e-12 for g in distinct):
            distinct.append(h)
    assert len(offered) == len(distinct) < 12
    headings = []
    for a in offered:
        assert a in gen
        probe = _platforms([(0.0, 0.0)], [0.1], params=params)[0].sensors[0]
        ss.execute({probe: [a]}, T1)
        headings.append(probe.heading)
    assert sorted(headings) == pytest.approx(sorted(distinct), abs=1e-12)


def _configs(platforms, tracks, rng, n):
    """n random configurations: a move per platform and an aim (track or sector) per radar."""
    radars = [p.sensors[0] for p in platforms]
    ss.set_aim_candidates(radars, tracks, 1.0)
    choices = []
    for p, r in zip(platforms, radars):
        (mg,) = p.actions(T1)
        (ag,) = r.actions(T1)
        choices.append((p, list(mg), r, list(ag)))
    for _ in range(n):
        config = {}
        for p, moves, r, aims in choices:
            config[p] = (moves[rng.integers(len(moves))],)
            config[r] = (aims[rng.integers(len(aims))],)
        yield config


def test_reward_is_the_potential_with_search_of_the_same_decision(rng):
    means, covs = _world_means(rng, 3)
    existence = np.array([0.9, 0.6, 1.0])
    platforms = _platforms([(-150.0, -100.0), (120.0, 80.0)], [0.4, -2.5])
    radars = [p.sensors[0] for p in platforms]
    tracker = _tracker(radars, rng)
    tracks = _tracks(means, covs, existence)
    reward = ss.SearchAndTrackReward(tracker=tracker)
    # The same decision written out by hand, in the planner's frame.
    u = UndetectedIntensity(np.array(tracker.pmb.grid.centres), tracker.pmb.undetected.copy(),
                            tracker.pmb.births.copy(), 0.98,
                            np.diag([50.0 ** 2 / 12, 50.0 ** 2 / 12]))
    start = np.array([[-150.0, -100.0], [120.0, 80.0]]) - WORLD.origin
    core_means = means.copy()
    core_means[:, :2] -= WORLD.origin
    problem = PlanningProblem(means=core_means, covs=covs, positions=start,
                              headings=np.array([0.4, -2.5]), sensors=(PARAMS, PARAMS),
                              horizon=1, existence=existence, search="on", search_sectors=8,
                              undetected=u)
    ids = {t.id: j for j, t in enumerate(tracks)}
    found = 0
    for config in _configs(platforms, tracks, rng, 25):
        targets, sectors, pos = np.full((2, 1), -1), np.full((2, 1), -1), np.zeros((2, 1, 2))
        for i, (p, r) in enumerate(zip(platforms, radars)):
            (move,) = config[p]
            (aim,) = config[r]
            pos[i, 0] = np.ravel(move.target_value)[:2] - WORLD.origin
            if isinstance(aim.target, ss.SearchSector):
                sectors[i, 0] = aim.target.index
            else:
                targets[i, 0] = ids[aim.target.id]
        phi, _, mu = search.potential(problem, Plan(pos, targets, sectors))
        found += mu > 0
        assert reward(config, set(tracks), T1) == pytest.approx(phi, rel=1e-12, abs=1e-12)
    assert found > 0


def test_manager_with_search_chooses_stonesoups_brute_force_optimum(rng):
    from stonesoup.sensormanager import BruteForceSensorManager

    means, covs = _world_means(rng, 2)
    platforms = _platforms([(-50.0, 20.0)], [1.0])
    rad = platforms[0].sensors[0]
    tracker = _tracker([rad], rng)
    tracks = _tracks(means, covs, [0.8, 0.7])
    ss.set_aim_candidates([rad], tracks, 1.0)
    reward = ss.SearchAndTrackReward(tracker=tracker)
    (best_config,), (best,) = BruteForceSensorManager(
        platforms={platforms[0]}, sensors={rad}, reward_function=reward).choose_actions(
        set(tracks), T1, return_reward=True)
    mgr = ss.SensorplanManager(platforms=platforms, planner="brute-force", search="on",
                               tracker=tracker)
    [config] = mgr.choose_actions(set(tracks), T1)
    assert mgr.last_result.potential == pytest.approx(best, rel=1e-12)
    assert reward(config, set(tracks), T1) == pytest.approx(best, rel=1e-12)
    ((move,), (aim,)) = config[platforms[0]], config[rad]
    ((best_move,), (best_aim,)) = best_config[platforms[0]], best_config[rad]
    assert move.move_index == best_move.move_index
    assert aim.target == best_aim.target


@pytest.mark.parametrize("planner", ["pg", "brute-force", "sequential-greedy"])
def test_with_no_tracks_every_beam_searches(rng, planner):
    platforms = _platforms([(-150.0, -100.0), (120.0, 80.0)], [0.4, -2.5])
    radars = [p.sensors[0] for p in platforms]
    tracker = _tracker(radars, rng)
    mgr = ss.SensorplanManager(platforms=platforms, planner=planner, search="on",
                               tracker=tracker)
    headings = [r.heading for r in radars]
    [config] = mgr.choose_actions(set(), T1)
    # mu > 0: some look finds something, so searching beats holding.
    assert mgr.last_result.potential > 0
    for r in radars:
        (aim,) = config[r]
        assert isinstance(aim.target, ss.SearchSector) and not aim.hold
        assert aim.bearing == aim.target.bearing
    ss.execute(config, T1)
    for r, h in zip(radars, headings):
        (aim,) = config[r]
        assert r.heading == pytest.approx(float(heading_rule(h, aim.bearing, r.params.max_turn)),
                                          abs=1e-12)
    np.testing.assert_allclose(mgr.planned_positions()[:, 0],
                               [r.ground_position for r in radars], atol=1e-9)


def test_search_off_plans_as_before_whatever_the_tracks_existence(rng):
    means, covs = _world_means(rng, 3)
    platforms = _platforms([(-150.0, -100.0), (120.0, 80.0)], [0.4, -2.5])
    radars = [p.sensors[0] for p in platforms]
    tracker = _tracker(radars, rng)
    tracks = _tracks(means, covs, [0.55, 0.6, 0.99])
    off = ss.SensorplanManager(platforms=platforms, planner="brute-force", search="off",
                               tracker=tracker)
    [config] = off.choose_actions(set(tracks), T1)
    plain = ss.SensorplanManager(platforms=platforms, planner="brute-force")
    [expected] = plain.choose_actions(set(ss.to_tracks(*_core_of(tracks), T0)), T1)
    assert off.last_problem.searching is False
    np.testing.assert_array_equal(off.last_problem.existence, np.ones(3))
    np.testing.assert_array_equal(off.last_result.plan.targets, plain.last_result.plan.targets)
    np.testing.assert_array_equal(off.last_result.plan.positions,
                                  plain.last_result.plan.positions)
    for p, r in zip(platforms, radars):
        assert config[p][0].move_index == expected[p][0].move_index
        assert config[r][0].target_value == expected[r][0].target_value
        assert config[r][0].bearing is None


def _core_of(tracks):
    ordered = ss.ordered_tracks(tracks)
    return ss.from_tracks(ordered)


def test_search_needs_the_tracker_on_the_platforms_map(rng):
    platforms = _platforms([(0.0, 0.0)], [0.0])
    with pytest.raises(ConfigError, match="tracker"):
        ss.SensorplanManager(platforms=platforms, search="on")
    other = ss.PMBStoneSoupTracker(radars=[platforms[0].sensors[0]],
                                   world=ss.MapRect(0.0, 0.0, 600.0, 600.0), dt=1.0)
    mgr = ss.SensorplanManager(platforms=platforms, search="on", tracker=other)
    with pytest.raises(ValueError, match="map"):
        mgr.choose_actions(set(), T1)


def test_example_runs_reduced():
    out = runpy.run_path(str(ROOT / "examples" / "stonesoup_search.py"), run_name="example")
    table = out["compare"](seeds=(0,), steps=6)
    assert set(table) == set(out["METHODS"])
    for row in table.values():
        assert np.isfinite(row["gospa"]).all() and (row["gospa"] >= 0).all()
        assert ((row["found"] >= 0) & (row["found"] <= row["born"])).all()
