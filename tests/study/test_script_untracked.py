"""scripts/untracked_diagnosis.py's held-target stretches against the honesty table's
longest gap (scripts/honest_table.py), a second computation written step by step."""

from __future__ import annotations

import numpy as np
import pytest

from script_helpers import ROOT, script_module


@pytest.mark.parametrize("seed", range(40))
def test_held_stretches_agree_with_the_longest_gap(seed: int) -> None:
    diag = script_module("untracked_diagnosis")
    honest = script_module("honest_table")
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 200))
    # Live steps with occasional gaps in the target's life; tracks in long runs.
    step = np.cumsum(rng.choice([1, 1, 1, 1, 1, 1, 1, 1, 1, 3], size=n))
    assigned = np.repeat(rng.random(n // 10 + 1) < 0.6, 10)[:n]
    assigned ^= rng.random(n) < 0.05
    for min_length in (1, 5, 20):
        got = diag.held_stretches(step, assigned, min_length)
        longest = honest.longest_gap_held(step, assigned)
        assert max((k for _, k in got), default=0) == (longest if longest >= min_length
                                                        else 0)
        for s0, k in got:
            i = int(np.searchsorted(step, s0))
            # Consecutive live steps, none with a track, after the first report.
            assert not assigned[i:i + k].any() and np.all(np.diff(step[i:i + k]) == 1)
            assert assigned[:i].any()


def test_held_stretches_of_a_hand_made_target() -> None:
    diag = script_module("untracked_diagnosis")
    step = np.arange(1, 61)
    assigned = np.zeros(60, dtype=bool)
    assigned[[4, 30]] = True                      # first report at step 5, again at 31
    # Steps 6..30 (25 steps) and 32..60 (29); the 4 steps before the first report are not
    # held.
    assert diag.held_stretches(step, assigned) == [(6, 25), (32, 29)]
    assert diag.held_stretches(step, assigned, 26) == [(32, 29)]
    assert diag.held_stretches(step, np.zeros(60, dtype=bool)) == []


@pytest.mark.parametrize("seed", range(10))
def test_target_stretches_of_shuffled_rows_match_each_target_alone(seed: int) -> None:
    diag = script_module("untracked_diagnosis")
    rng = np.random.default_rng(seed)
    steps, targets, assigned, expected = [], [], [], []
    for j in (4, 0, 9):
        n = int(rng.integers(1, 120))
        st = int(rng.integers(1, 50)) + np.arange(n)
        a = np.repeat(rng.random(n // 8 + 1) < 0.5, 8)[:n]
        expected += [(j, s0, k) for s0, k in diag.held_stretches(st, a, 3)]
        steps.append(st), targets.append(np.full(n, j)), assigned.append(a)
    step, target, a = (np.concatenate(v) for v in (steps, targets, assigned))
    order = rng.permutation(len(step))
    step, target, a = step[order], target[order], a[order]
    got = list(diag.target_stretches(step, target, a, 3))
    assert sorted((j, s0, k) for j, _, s0, k in got) == sorted(expected)
    for j, row, s0, _ in got:
        # The row named is the target's row at the stretch's first step.
        assert target[row] == j and step[row] == s0 and not a[row]


def test_each_class_of_an_untracked_target_step() -> None:
    diag = script_module("untracked_diagnosis")
    target = np.array([0.0, 0.0])
    pos = np.array([[30.0, 40.0], [10.0, 0.0], [200.0, 0.0]])     # 50 m, 10 m, 200 m away
    labels = np.array([7, 8, 9])
    c, threshold = 50.0, 0.5

    def classify(r: list[float], last: int) -> tuple:
        return diag._classify((np.array(r), pos, labels), target, last, threshold, c)

    # A reported Bernoulli within c (10 m): another target took it.
    assert classify([0.9, 0.6, 0.9], 9)[0] == "taken"
    # Within c only below the report threshold: the nearer-than-c one of highest existence.
    assert classify([0.9, 0.3, 0.9], 9) == ("faded", 8, 0.3, 10.0)
    # At exactly c a Bernoulli is not within it, so with none nearer the label is followed.
    r = [0.9, 0.0, 0.8]
    pos_far = pos.copy()
    pos_far[1] = [0.0, 60.0]
    got = diag._classify((np.array(r), pos_far, labels), target, 9, threshold, c)
    assert got == ("displaced", 9, 0.8, 200.0)
    got = diag._classify((np.array(r), pos_far, labels), target, 5, threshold, c)
    assert got[:2] == ("gone", 5) and np.isnan(got[2])
    empty = (np.zeros(0), np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
    assert diag._classify(empty, target, -1, threshold, c)[:2] == ("gone", -1)


def test_existence_within_c_sums_only_the_nearer_bernoullis() -> None:
    diag = script_module("untracked_diagnosis")
    pos = np.array([[3.0, 4.0], [0.0, 50.0], [-10.0, 0.0]])       # 5 m, 50 m, 10 m
    bern = (np.array([0.3, 0.9, 0.25]), pos, np.array([1, 2, 3]))
    assert diag._existence_within(bern, np.zeros(2), 50.0) == pytest.approx(0.55, abs=1e-15)
    assert diag._existence_within(bern, np.zeros(2), 50.001) == pytest.approx(1.45, abs=1e-15)
    empty = (np.zeros(0), np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
    assert diag._existence_within(empty, np.zeros(2), 50.0) == 0.0


def test_nearest_bernoullis_with_their_spread_and_nees() -> None:
    diag = script_module("untracked_diagnosis")
    pos = np.array([[100.0, 0.0], [2.0, 3.0], [0.0, -20.0]])
    covs = np.array([np.eye(2), np.diag([4.0, 9.0]), np.diag([16.0, 9.0])])
    bern = (np.array([0.9, 0.4, 0.7]), pos, np.array([7, 8, 9]))
    got = diag._nearest(bern, covs, np.zeros(2), n=2)
    # Errors (2, 3) with variances (4, 9): NEES 1 + 1; (0, -20) with (16, 9): 400 / 9.
    assert got == ["L8 r=0.40 d=4 sd=4 nees=2.0", "L9 r=0.70 d=20 sd=5 nees=44.4"]


def test_a_pulled_track_is_found_at_its_step() -> None:
    diag = script_module("untracked_diagnosis")
    labels = np.array([4, 9])
    xy = np.zeros((5, 2))

    def bern(r4: float, x4: float) -> tuple:
        return (np.array([r4, 0.9]), np.array([[x4, 0.0], [500.0, 0.0]]), labels)

    # Label 4: 5 m off, then 8 m (a miss), then 30 m with its existence up while the
    # target went undetected (a pull at step 13), then further.
    seq = [bern(0.95, 5.0), bern(0.90, 8.0), bern(0.97, 30.0), bern(0.80, 45.0),
           bern(0.99, 46.0)]
    steps = [10, 11, 13, 14, 15]
    none = np.zeros(5, dtype=bool)
    assert diag.pulled_step(steps, seq, xy, none, 4) == 13
    # Detected at that step: the rise is the target's own detection, not a pull; step 15
    # rises by 1 m only.
    assert diag.pulled_step(steps, seq, xy, np.array([0, 0, 1, 0, 0], bool), 4) is None
    # A jump of exactly min_gain is not enough; an absent label is never pulled.
    assert diag.pulled_step(steps, seq, xy, none, 4, min_gain=22.0) is None
    assert diag.pulled_step(steps, seq, xy, none, 7) is None


def test_trace_and_lost_refuse_bad_steps_and_unknown_methods(capsys) -> None:
    diag = script_module("untracked_diagnosis")
    study = str(ROOT / "studies" / "development" / "search_split_dev.toml")
    assert diag._step_range("110:140") == (110, 140)
    for bad in ("110-140", "140:110", "0:5", "a:b", "7"):
        with pytest.raises(SystemExit) as e:
            diag.main(["trace", study, "--seed", "1",
                       "--run", "0", "--target", "0", "--steps", bad])
        assert e.value.code == 2
        assert "--steps" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        diag.main(["lost", study, "--method", "nope",
                   "--seed", "1", "--runs", "1"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--method" in err and "'nope'" in err and "pmb/split0.1" in err


@pytest.mark.parametrize("seed", range(20))
def test_tail_counts_agree_with_a_count_stretch_by_stretch(seed: int) -> None:
    diag = script_module("untracked_diagnosis")
    rng = np.random.default_rng(seed)
    per_run = [[int(k) for k in rng.integers(1, 45, size=rng.integers(0, 6))]
               for _ in range(int(rng.integers(1, 30)))]
    got = diag.tail_counts(per_run)
    assert [L for L, _, _ in got] == list(diag.TAIL_LENGTHS)
    for L, stretches, runs in got:
        want_stretches = want_runs = 0
        for run in per_run:
            hit = False
            for k in run:
                if k >= L:
                    want_stretches += 1
                    hit = True
            want_runs += hit
        assert (stretches, runs) == (want_stretches, want_runs)


def test_tail_counts_of_hand_made_runs() -> None:
    diag = script_module("untracked_diagnosis")
    # Run 0: stretches of 3, 22 and 25 steps; run 1: none; run 2: one of 20.
    got = {L: (k, r) for L, k, r in diag.tail_counts([[3, 22, 25], [], [20]])}
    assert got[1] == (4, 2) and got[5] == (3, 2) and got[20] == (3, 2)
    assert got[25] == (1, 1) and got[30] == (0, 0)


def test_tail_curve_of_hand_made_runs() -> None:
    diag = script_module("untracked_diagnosis")
    # Three runs: longest stretches 3, 5 and none.
    lengths, share = diag.tail_curve([[3, 1], [5], []])
    assert lengths.tolist() == [1, 2, 3, 4, 5, 6]
    np.testing.assert_allclose(share, [200 / 3, 200 / 3, 200 / 3, 100 / 3, 100 / 3, 0.0],
                               rtol=0, atol=1e-12)
    lengths, share = diag.tail_curve([[], []])
    assert lengths.tolist() == [1] and share.tolist() == [0.0]


def test_tail_plot_draws_a_panel_per_method(tmp_path, monkeypatch) -> None:
    diag = script_module("untracked_diagnosis")
    runs = {("a", "pg"): [[3], [25]], ("b", "pg"): [[1]], ("a", "sg"): [[2]],
            ("b", "sg"): [[]]}
    monkeypatch.setattr(diag, "_tail_lengths", lambda d, m: runs[(d, m)])
    path = diag.plot_tail(["a", "b"], ["pg", "sg"], ["A", "B"], str(tmp_path / "t.png"))
    assert open(path, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_tail_refuses_labels_that_do_not_match_the_directories(capsys) -> None:
    diag = script_module("untracked_diagnosis")
    with pytest.raises(SystemExit) as e:
        diag.main(["tail", "x", "y", "--plot", "p.png", "--label", "only one"])
    assert e.value.code == 2
    assert "--label" in capsys.readouterr().err
