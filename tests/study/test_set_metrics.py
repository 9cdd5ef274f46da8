"""GOSPA and the set metrics (sensorplan.study.set_metrics).

GOSPA is checked against closed forms, against Stone Soup's ``GOSPAMetric`` and against a
brute-force minimum over every partial assignment written with the standard library only;
the batched version against the per-step one, bit for bit; the set metrics on small
hand-made tables whose answers are counted by hand.
"""

from __future__ import annotations

import datetime
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.study import set_metrics as sm
from sensorplan.study.set_metrics import gospa, gospa_over_time, set_metrics, target_metrics

SETTINGS = settings(max_examples=80, deadline=None)
PARTS = ("distance", "localisation", "missed", "false")


def random_sets(rng: np.random.Generator, n: int, m: int, c: float,
                d: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """n targets in a 100 m box; m tracks: noisy copies of some targets (some beyond c) and
    random points."""
    truth = rng.uniform(0.0, 100.0, (n, d))
    near = truth[rng.permutation(n)[:min(n, m)]] + rng.normal(0.0, 0.6 * c, (min(n, m), d))
    track = np.concatenate([near, rng.uniform(0.0, 100.0, (m - len(near), d))])
    return truth, track[rng.permutation(m)]


# -- closed forms ------------------------------------------------------------------------

def test_two_empty_sets_are_at_distance_zero() -> None:
    g = gospa(np.empty((0, 2)), np.empty((0, 2)), c=10.0)
    assert (g.distance, g.localisation, g.missed, g.false) == (0.0, 0.0, 0.0, 0.0)
    assert g.assignment.shape == (0,)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_only_misses_or_only_false_tracks_cost_c_squared_over_two_each(n: int) -> None:
    c = 7.0
    pts = np.arange(2.0 * n).reshape(n, 2)
    missed = gospa(pts, np.empty((0, 2)), c)
    np.testing.assert_allclose(missed.distance, math.sqrt(n * c**2 / 2), rtol=1e-15, atol=0)
    assert (missed.localisation, missed.missed, missed.false) == (0.0, n * c**2 / 2, 0.0)
    assert missed.assignment.tolist() == [-1] * n
    false = gospa([], pts, c)
    np.testing.assert_allclose(false.distance, math.sqrt(n * c**2 / 2), rtol=1e-15, atol=0)
    assert (false.localisation, false.missed, false.false) == (0.0, 0.0, n * c**2 / 2)


def test_one_pair_closer_than_c_is_localisation_only() -> None:
    g = gospa([[1.0, 2.0]], [[4.0, 6.0]], c=10.0)          # a 3-4-5 triangle
    assert (g.distance, g.localisation, g.missed, g.false) == (5.0, 25.0, 0.0, 0.0)
    assert g.assignment.tolist() == [0]
    g1 = gospa([[1.0, 2.0], [50.0, 50.0]], [[4.0, 6.0]], c=10.0, p=1)
    assert (g1.distance, g1.localisation, g1.missed) == (10.0, 5.0, 5.0)


@pytest.mark.parametrize("d", [12.0, 10.0])
def test_a_pair_at_c_or_beyond_is_one_miss_and_one_false_track(d: float) -> None:
    g = gospa([[0.0, 0.0]], [[0.6 * d, 0.8 * d]], c=10.0)
    assert (g.distance, g.localisation, g.missed, g.false) == (10.0, 0.0, 50.0, 50.0)
    assert g.assignment.tolist() == [-1]


def test_a_tie_does_not_change_the_value() -> None:
    # One track halfway between two targets: either target may take it.
    c = 10.0
    expected = math.sqrt(1.0 + c**2 / 2)
    for truth in ([[-1.0, 0.0], [1.0, 0.0]], [[1.0, 0.0], [-1.0, 0.0]]):
        g = gospa(truth, [[0.0, 0.0]], c)
        np.testing.assert_allclose(g.distance, expected, rtol=1e-15, atol=0)
        assert (g.localisation, g.missed, g.false) == (1.0, 50.0, 0.0)
        assert sorted(g.assignment.tolist()) == [-1, 0]
    # A pair at exactly c: assigned or not, it costs c^p.
    g = gospa([[0.0, 0.0], [20.0, 0.0]], [[10.0, 0.0]], c)
    assert (g.distance, g.missed, g.false) == (math.sqrt(150.0), 100.0, 50.0)


# -- two independent computations ----------------------------------------------------------

def brute_force(truth: np.ndarray, track: np.ndarray, c: float, p: float
                ) -> tuple[float, float, int]:
    """(GOSPA^p, localisation, pairs closer than c) by trying every partial assignment."""
    n, m = len(truth), len(track)
    best = (math.inf, 0.0, 0)
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                dist = [math.dist(truth[i], track[j]) for i, j in zip(rows, cols)]
                value = sum(min(x, c) ** p for x in dist) + c**p / 2 * (n + m - 2 * k)
                if value < best[0]:
                    close = [x for x in dist if x < c]
                    best = (value, sum(x**p for x in close), len(close))
    return best


@SETTINGS
@given(st.integers(0, 5), st.integers(0, 5), st.integers(0, 2**32 - 1),
       st.sampled_from([1.0, 2.0, 3.0]), st.sampled_from([2, 3]))
def test_gospa_is_the_minimum_over_every_partial_assignment(n: int, m: int, seed: int,
                                                            p: float, d: int) -> None:
    c = 30.0
    truth, track = random_sets(np.random.default_rng(seed), n, m, c, d)
    value, localisation, k = brute_force(truth, track, c, p)
    g = gospa(truth, track, c, p)
    np.testing.assert_allclose(g.distance, value ** (1 / p), rtol=1e-12, atol=0)
    np.testing.assert_allclose(g.localisation, localisation, rtol=1e-12, atol=0)
    assert (g.missed, g.false) == (c**p / 2 * (n - k), c**p / 2 * (m - k))
    assert (g.assignment >= 0).sum() == k


def stonesoup_gospa(truth: np.ndarray, track: np.ndarray, c: float, p: float,
                    rng: np.random.Generator):
    """Stone Soup's GOSPA of the positions, on (x, vx, y, vy) states whose velocities differ
    between the two sets (so a whole-state measure would give another answer)."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.state import State

    when = datetime.datetime(2024, 1, 1)

    def states(xy: np.ndarray) -> list[State]:
        v = rng.normal(0.0, 50.0, (len(xy), 2))
        return [State(np.array([[x], [vx], [y], [vy]]), timestamp=when)
                for (x, y), (vx, vy) in zip(xy, v)]

    metric = GOSPAMetric(c=c, p=p, measure=Euclidean(mapping=(0, 2)))
    single, assignment = metric.compute_gospa_metric(states(track), states(truth))
    return single.value, np.asarray(assignment)


@SETTINGS
@given(st.integers(0, 9), st.integers(0, 9), st.integers(0, 2**32 - 1),
       st.sampled_from([1.0, 2.0]))
def test_gospa_equals_stone_soups_on_positions(n: int, m: int, seed: int, p: float) -> None:
    pytest.importorskip("stonesoup")
    rng = np.random.default_rng(seed)
    c = 30.0
    truth, track = random_sets(rng, n, m, c)
    if n + m == 0:         # Stone Soup needs a state to take the time from: nothing to compare
        assert gospa(truth, track, c, p).distance == 0.0
        return
    theirs, their_assignment = stonesoup_gospa(truth, track, c, p, rng)
    ours = gospa(truth, track, c, p)
    for part in PARTS:
        np.testing.assert_allclose(getattr(ours, part), theirs[part], rtol=1e-9, atol=0,
                                   err_msg=part)
    if n and m:                    # Stone Soup gives no assignment when a set is empty
        np.testing.assert_array_equal(ours.assignment, their_assignment)


@SETTINGS
@given(st.integers(0, 6), st.integers(0, 6), st.integers(0, 6), st.integers(0, 2**32 - 1))
def test_gospa_is_a_metric(n1: int, n2: int, n3: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    c = 30.0
    x, y = random_sets(rng, n1, n2, c)
    z = random_sets(rng, n2, n3, c)[1]
    xy, yx = gospa(x, y, c), gospa(y, x, c)
    assert (xy.distance, xy.localisation, xy.missed, xy.false) == pytest.approx(
        (yx.distance, yx.localisation, yx.false, yx.missed), rel=1e-12, abs=0)
    assert gospa(x, x, c).distance == 0.0
    assert gospa(x, z, c).distance <= xy.distance + gospa(y, z, c).distance + 1e-9


# -- batched over time ---------------------------------------------------------------------

def padded_steps(rng: np.random.Generator, steps: int, n_max: int, m_max: int, c: float,
                 d: int = 2):
    """Random padded steps with holes in the masks and NaN in the unused slots."""
    truth = rng.uniform(0.0, 100.0, (steps, n_max, d))
    track = np.concatenate([truth[:, :min(n_max, m_max)], rng.uniform(
        0.0, 100.0, (steps, m_max - min(n_max, m_max), d))], axis=1)
    track += rng.normal(0.0, 0.5 * c, track.shape)
    alive = rng.random((steps, n_max)) < rng.uniform(0.0, 1.0, (steps, 1))
    present = rng.random((steps, m_max)) < rng.uniform(0.0, 1.0, (steps, 1))
    alive[0], present[1 % steps] = False, False             # an empty side
    truth[~alive], track[~present] = np.nan, np.inf
    return truth, alive, track, present


@pytest.mark.parametrize("n_max, m_max, d, p", [(6, 5, 2, 2.0), (4, 7, 3, 2.0),
                                                (5, 5, 2, 1.5), (3, 0, 2, 2.0),
                                                (40, 30, 2, 2.0)])
def test_over_time_equals_step_by_step_exactly(monkeypatch, rng, n_max: int, m_max: int,
                                               d: int, p: float) -> None:
    monkeypatch.setattr(sm, "_CHUNK_ENTRIES", 64)       # several chunks, some steps per chunk
    c = 25.0
    truth, alive, track, present = padded_steps(rng, 60, n_max, m_max, c, d)
    series = gospa_over_time(truth, alive, track, present, c, p)
    assert series.assignment.shape == (60, n_max)
    for s in range(60):
        one = gospa(truth[s][alive[s]], track[s][present[s]], c, p)
        for part in PARTS:
            assert getattr(series, part)[s] == getattr(one, part), (s, part)
        slots = np.flatnonzero(present[s])
        expected = np.full(n_max, -1)
        expected[alive[s]] = [slots[j] if j >= 0 else -1 for j in one.assignment]
        np.testing.assert_array_equal(series.assignment[s], expected)


def test_over_time_of_no_step_is_empty() -> None:
    series = gospa_over_time(np.empty((0, 3, 2)), np.empty((0, 3), bool),
                             np.empty((0, 4, 2)), np.empty((0, 4), bool), 10.0)
    assert series.distance.shape == (0,) and series.assignment.shape == (0, 3)


# -- set metrics on hand-made tables -------------------------------------------------------

def tables(targets: dict[int, dict[int, tuple[float, float]]],
           tracks: dict[int, dict[int, tuple[float, float]]]):
    """Long tables from {id: {step: position}} and {label: {step: position}}."""
    t = [(s, i, *xy) for i, rows in targets.items() for s, xy in rows.items()]
    y = [(s, label, *xy) for label, rows in tracks.items() for s, xy in rows.items()]
    ta, ya = np.array(t, dtype=float).reshape(-1, 4), np.array(y, dtype=float).reshape(-1, 4)
    return (ta[:, 0].astype(int), ta[:, 1].astype(int), ta[:, 2:],
            ya[:, 0].astype(int), ya[:, 1].astype(int), ya[:, 2:])


def still(x: float, steps) -> dict[int, tuple[float, float]]:
    """A point at (x, 0) at each of ``steps``."""
    return {s: (x, 0.0) for s in steps}


def near(x: float, steps) -> dict[int, tuple[float, float]]:
    """A track 3 m from (x, 0) at each of ``steps``."""
    return {s: (x + 3.0, 0.0) for s in steps}


C = 50.0
#: Targets 1000 m apart, so a track only ever fits the target it was put next to.
STORY = tables(
    targets={
        10: still(0, range(0, 8)),               # first reported at step 3
        11: still(1000, range(2, 8)),            # never reported
        12: still(2000, range(0, 8)),            # label 7, then 8 (after a gap), then 7
        13: still(3000, range(0, 8)),            # reported throughout: no switch
    },
    tracks={
        1: near(0, range(3, 8)),
        7: near(2000, [0, 1, 5]),
        8: near(2000, [3, 4]),
        5: near(3000, range(0, 8)),
        99: still(5000, [1, 2, 6]),               # far from every target
    })


def test_the_story_table() -> None:
    r = set_metrics(*STORY, c=C)
    t = r.targets
    np.testing.assert_array_equal(t.ids, [10, 11, 12, 13])
    np.testing.assert_array_equal(t.birth_step, [0, 2, 0, 0])
    np.testing.assert_array_equal(t.first_report_step, [3, -1, 0, 0])
    np.testing.assert_array_equal(t.report_delay, [3.0, np.nan, 0.0, 0.0])
    assert t.never_reported == 1
    np.testing.assert_array_equal(t.label_switches, [0, 0, 2, 0])
    np.testing.assert_array_equal(t.longest_unassigned, [3, 6, 2, 0])
    assert t.targets_lost == 0
    np.testing.assert_array_equal(r.n_targets, [3, 3, 4, 4, 4, 4, 4, 4])
    np.testing.assert_array_equal(r.n_tracks, [2, 3, 2, 3, 3, 3, 3, 2])
    np.testing.assert_array_equal(r.false_tracks, [0, 1, 1, 0, 0, 0, 1, 0])
    # The GOSPA of each step: 9 m^2 per assigned target, c^2/2 per miss and false track.
    k = np.array([2, 2, 1, 3, 3, 3, 2, 2])
    np.testing.assert_array_equal(r.gospa.localisation, 9.0 * k)
    np.testing.assert_array_equal(r.gospa.missed, C**2 / 2 * (r.n_targets - k))
    np.testing.assert_array_equal(r.gospa.false, C**2 / 2 * r.false_tracks)
    np.testing.assert_allclose(r.mean_gospa, r.gospa.distance.mean(), rtol=1e-15)


def test_per_row_answers_follow_the_input_order(rng) -> None:
    r = set_metrics(*STORY, c=C)
    t_perm, y_perm = rng.permutation(len(STORY[0])), rng.permutation(len(STORY[3]))
    shuffled = [col[t_perm] for col in STORY[:3]] + [col[y_perm] for col in STORY[3:]]
    q = set_metrics(*shuffled, c=C)
    np.testing.assert_array_equal(q.assigned, r.assigned[t_perm])
    np.testing.assert_array_equal(q.label, r.label[t_perm])
    np.testing.assert_array_equal(q.track_assigned, r.track_assigned[y_perm])
    for name in ("label_switches", "longest_unassigned", "first_report_step"):
        np.testing.assert_array_equal(getattr(q.targets, name), getattr(r.targets, name))
    # Row by row: target 12 at step 3 carries label 8; track 99 is never assigned.
    step, ident = STORY[0], STORY[1]
    assert r.label[(step == 3) & (ident == 12)].tolist() == [8]
    assert not r.track_assigned[STORY[4] == 99].any()
    assert r.label[~r.assigned].tolist() == [-1] * int((~r.assigned).sum())


@pytest.mark.parametrize("gap, lost", [(19, False), (20, True), (21, True)])
def test_a_target_is_lost_after_20_steps_without_a_track(gap: int, lost: bool) -> None:
    steps = range(gap + 2)
    r = set_metrics(*tables({4: still(0, steps)}, {1: near(0, [0, gap + 1])}), c=C).targets
    assert r.longest_unassigned.tolist() == [gap]
    assert r.lost.tolist() == [lost] and r.targets_lost == int(lost)
    assert r.label_switches.tolist() == [0]                 # the same label on both ends
    assert set_metrics(*tables({4: still(0, steps)}, {1: near(0, [0, gap + 1])}), c=C,
                       lost_steps=gap + 1).targets.targets_lost == 0


def test_a_step_without_the_target_ends_its_stretch() -> None:
    # Alive 0..11 and 13..24 (not at 12), never tracked: two stretches of 12.
    alive = [*range(0, 12), *range(13, 25)]
    r = set_metrics(*tables({4: still(0, alive)}, {}), c=C, lost_steps=13)
    t = r.targets
    assert t.longest_unassigned.tolist() == [12] and not t.lost.any()
    assert t.first_report_step.tolist() == [-1] and np.isnan(t.report_delay).all()
    assert r.gospa.distance.shape == (25,) and r.gospa.distance[12] == 0.0


def test_target_metrics_from_an_assigned_column() -> None:
    # Rows in no particular order; target 1's label 6 at an unassigned step is ignored.
    step = np.array([1, 0, 2, 3, 4, 0, 1, 5, 6, 7])
    ident = np.array([1, 1, 1, 1, 1, 2, 2, 2, 2, 2])
    assigned = np.array([False, True, True, True, True, False, False, False, True, True])
    label = np.array([6, 5, 5, 9, 9, -1, -1, -1, 3, 4])
    t = target_metrics(step, ident, assigned, label, lost_steps=2)
    assert t.ids.tolist() == [1, 2]
    assert t.birth_step.tolist() == [0, 0] and t.first_report_step.tolist() == [0, 6]
    assert t.label_switches.tolist() == [1, 1]
    # Target 2 is missing at steps 2..4: its unassigned stretches are 0-1 and 5.
    assert t.longest_unassigned.tolist() == [1, 2] and t.lost.tolist() == [False, True]


def test_no_rows_give_empty_answers() -> None:
    r = set_metrics([], [], np.empty((0, 2)), [], [], np.empty((0, 2)), c=C)
    assert r.targets.ids.shape == r.targets.lost.shape == r.gospa.distance.shape == (0,)
    assert math.isnan(r.mean_gospa)
    r = set_metrics([], [], [], [0, 2], [1, 1], [[0, 0], [1, 1]], c=C, n_steps=4)
    np.testing.assert_array_equal(r.false_tracks, [1, 0, 1, 0])
    np.testing.assert_array_equal(r.gospa.false, [C**2 / 2, 0, C**2 / 2, 0])


# -- bad input -----------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    (dict(c=0.0), "^c:"), (dict(c=-1.0), "^c:"), (dict(c=math.nan), "^c:"),
    (dict(c=1.0, p=0.5), "^p:"), (dict(c=1.0, alpha=1.0), "^alpha:"),
    (dict(c=1.0, truth_xy=[[0.0, 0.0, 0.0]]), "^track_xy:"),
    (dict(c=1.0, truth_xy=np.empty((0, 3))), "^track_xy: 2 coordinates"),
    (dict(c=1.0, track_xy=np.empty((2, 0))), "^track_xy:.*d >= 1"),
    (dict(c=1.0, truth_xy=[0.0, 1.0]), "^truth_xy:"),
    (dict(c=1.0, track_xy=[[0.0, math.inf]]), "^track_xy:.*non-finite"),
])
def test_gospa_names_the_bad_argument(kwargs, match) -> None:
    args = dict(truth_xy=[[0.0, 0.0]], track_xy=[[1.0, 1.0]]) | kwargs
    with pytest.raises(ValueError, match=match):
        gospa(**args)


def test_over_time_names_the_bad_argument() -> None:
    xy, live = np.zeros((3, 2, 2)), np.ones((3, 2), bool)
    nan = xy.copy()
    nan[1, 1, 0] = np.nan
    for args, match in [((xy, live.astype(int), xy, live), "^truth_alive:"),
                        ((xy, live, xy[:2], live[:2]), "^track_xy:.*steps"),
                        ((xy, live, xy[..., :1], live), "^track_xy:.*coordinates"),
                        ((xy, live, nan, live), "^track_xy:.*step 1, slot 1"),
                        ((xy[0], live[0], xy, live), "^truth_xy:"),
                        ((xy[..., :0], live, xy, live), "^truth_xy:.*d >= 1")]:
        with pytest.raises(ValueError, match=match):
            gospa_over_time(*args, c=1.0)


def test_set_metrics_names_the_bad_argument() -> None:
    good = list(STORY)
    for i, value, match in [(0, STORY[0] - 5, "^target_step:"),
                            (3, STORY[3].astype(float), "^track_step:"),
                            (1, STORY[1][:-1], "^target_id:"),
                            (2, np.where(STORY[2] == 2000, np.nan, STORY[2]), "^target_xy:"),
                            (5, np.c_[STORY[5], STORY[5][:, :1]], "^track_xy: 3 coord"),
                            (4, np.where(STORY[4] == 8, 5, STORY[4]),
                             "^track_label: 5 appears twice at step 3")]:
        with pytest.raises(ValueError, match=match):
            set_metrics(*(good[:i] + [value] + good[i + 1:]), c=C)
    twice = [np.append(col, col[:1], axis=0) for col in STORY[:3]] + good[3:]
    with pytest.raises(ValueError, match="^target_id: 10 appears twice at step 0"):
        set_metrics(*twice, c=C)
    with pytest.raises(ValueError, match="^lost_steps:"):
        set_metrics(*STORY, c=C, lost_steps=0)
    with pytest.raises(ValueError, match="^n_steps:"):
        set_metrics(*STORY, c=C, n_steps=7)
    with pytest.raises(ValueError, match="^c:"):
        set_metrics(*STORY, c=0.0)
    one = np.zeros(2, dtype=int)
    with pytest.raises(ValueError, match="^assigned:"):
        target_metrics(one, [1, 2], one, one)
    with pytest.raises(ValueError, match="^target_id: 1 appears twice at step 0"):
        target_metrics(one, [1, 1], one > 0, one)


@pytest.mark.parametrize("c", [50.0, 400.0])
def test_a_set_trackers_lost_share_is_its_live_target_steps_without_a_track(c: float) -> None:
    # Its errors are those of the assigned tracks, never above the cut-off: by the error
    # rule alone it could never lose a target (the run summary once said 0 % lost). With a
    # cut-off above the known-target tracker's 50 m lost threshold, a track assigned
    # between the two is held, not lost (the summary once counted it lost).
    import dataclasses

    from sensorplan.simulation.run import run_episode
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings
    from sensorplan.study.metrics import episode_errors

    scenario = dataclasses.replace(search_scenario(), birth_rate=0.25)
    settings = RunSettings(planner="random", steps=30, tracker=TrackerSettings(kind="pmb"),
                           gospa_c=c)
    ep = run_episode(scenario, settings, 20261203)
    every = [r for r in episode_errors(ep) if r.target == "all" and r.kind == "all"][0]
    # Independently: GOSPA's missed part counts c^2/2 for each live target left unassigned.
    series = sm.episode_set_metrics(ep).gospa
    unassigned = np.asarray(series.missed).sum() / (c * c / 2)
    alive = np.asarray(ep.alive)[1:].sum()
    assert unassigned > 0                                 # the premise: some were missed
    assert every.lost_share == pytest.approx(unassigned / alive, rel=1e-12)
