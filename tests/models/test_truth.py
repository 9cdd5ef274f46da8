"""Ground-truth motion: wall mirror, exact Dubins arcs, cv statistics, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.models.motion import cv_matrices
from sensorplan.planners.problem import MapRect
from sensorplan.simulation.scenario import Scenario, SensorSpec, TargetSpec, make_truth
from sensorplan.models.truth import NOISE_BLOCK, TruthModel, dubins_arc, mirror


def make_model(kinds, x0, rng, width=600.0, height=600.0, dt=1.0, q=0.05, turn_hold=10.0,
               max_turn_rate=0.1) -> TruthModel:
    """A truth model from arrays; every target shares ``turn_hold`` and ``max_turn_rate``."""
    M = len(kinds)
    return TruthModel(kinds, x0, rng, turn_hold=np.full(M, turn_hold),
                      max_turn_rate=np.full(M, max_turn_rate), world_size=(width, height),
                      dt=dt, process_noise=q)


def reflect_by_hand(p: float, length: float) -> tuple[float, int]:
    """Unfold one coordinate by walking it back across the walls one reflection at a time."""
    flips = 0
    while p < 0 or p > length:
        p = -p if p < 0 else 2 * length - p
        flips += 1
    return p, flips


def euler_dubins(xy, speed, heading, rates, switch_times, t_end, n_sub_per_s=4000):
    """Fine explicit Euler integration of piecewise-constant turn rates (one target)."""
    h = 1.0 / n_sub_per_s
    n = int(round(t_end * n_sub_per_s))
    x, y, th = float(xy[0]), float(xy[1]), float(heading)
    out = {}
    for k in range(n):
        t = k * h
        w = rates[int(np.searchsorted(switch_times, t + 0.5 * h, side="right"))]
        x += speed * math.cos(th) * h
        y += speed * math.sin(th) * h
        th += w * h
        out[k + 1] = (x, y)
    return out


class TestMirror:
    def test_inside_points_are_unchanged_bit_for_bit(self, rng):
        p = rng.uniform(0.0, 600.0, size=1000)
        p = np.concatenate([p, [0.0, 600.0]])
        folded, flipped = mirror(p, 600.0)
        np.testing.assert_array_equal(folded, p)
        assert not flipped.any()

    def test_matches_reflection_walk_for_many_reflections(self, rng):
        p = rng.uniform(-5000.0, 5000.0, size=2000)
        folded, flipped = mirror(p, 70.0)
        expected = [reflect_by_hand(float(v), 70.0) for v in p]
        np.testing.assert_allclose(folded, [e[0] for e in expected], atol=1e-9)
        np.testing.assert_array_equal(flipped, [e[1] % 2 == 1 for e in expected])
        assert folded.min() >= 0.0 and folded.max() <= 70.0

    def test_per_axis_lengths_broadcast(self):
        folded, flipped = mirror(np.array([[-1.0, 12.0], [11.0, 3.0]]), np.array([10.0, 5.0]))
        np.testing.assert_allclose(folded, [[1.0, 2.0], [9.0, 3.0]])
        np.testing.assert_array_equal(flipped, [[True, False], [True, False]])


class TestDubinsArc:
    def test_matches_fine_euler_integration(self, rng):
        B = 8
        xy = rng.uniform(0.0, 100.0, size=(B, 2))
        speed = rng.uniform(3.0, 6.0, size=B)
        heading = rng.uniform(-np.pi, np.pi, size=B)
        w = np.concatenate([rng.uniform(-0.1, 0.1, size=B - 2), [0.0, 1e-13]])
        tau = rng.uniform(0.5, 10.0, size=B)
        got, got_h = dubins_arc(xy, speed, heading, w, tau)
        n = 20000
        p = xy.copy()
        th = heading.copy()
        h = tau / n
        for _ in range(n):
            p[:, 0] += speed * np.cos(th) * h
            p[:, 1] += speed * np.sin(th) * h
            th += w * h
        # Euler's global error here is at most v |w| tau^2 / (2 n) < 2e-3 m.
        np.testing.assert_allclose(got, p, atol=3e-3, rtol=0)
        np.testing.assert_allclose(np.cos(got_h - th), 1.0, atol=1e-12)

    def test_straight_line_limit(self):
        xy = np.array([[10.0, 20.0]])
        for w in (0.0, 1e-15, -1e-12):
            got, h = dubins_arc(xy, np.array([5.0]), np.array([0.3]), np.array([w]),
                                np.array([4.0]))
            np.testing.assert_allclose(got, xy + 20.0 * np.array([[math.cos(0.3),
                                                                   math.sin(0.3)]]),
                                       atol=1e-9, rtol=0)
            np.testing.assert_allclose(h, 0.3 + w * 4.0, atol=1e-15)

    def test_closed_form_circle(self):
        # A quarter circle of radius v / w = 50 m from the origin heading +x, turning left.
        got, h = dubins_arc(np.zeros((1, 2)), np.array([5.0]), np.array([0.0]),
                            np.array([0.1]), np.array([5 * np.pi]))
        np.testing.assert_allclose(got, [[50.0, 50.0]], atol=1e-9)
        np.testing.assert_allclose(h, [np.pi / 2], atol=1e-12)

    def test_two_arcs_compose(self, rng):
        xy = rng.uniform(0.0, 100.0, size=(5, 2))
        v, th, w = rng.uniform(1, 6, 5), rng.uniform(-3, 3, 5), rng.uniform(-0.2, 0.2, 5)
        a, ha = dubins_arc(xy, v, th, w, 1.3)
        b, hb = dubins_arc(a, v, ha, w, 2.1)
        c, hc = dubins_arc(xy, v, th, w, 3.4)
        np.testing.assert_allclose(b, c, atol=1e-9)
        np.testing.assert_allclose(np.cos(hb - hc), 1.0, atol=1e-12)


class TestTruthModel:
    def test_dubins_with_redraws_inside_steps_matches_euler(self):
        # dt = 0.7 does not divide turn_hold = 10: redraws at 10, 20 s fall inside steps and
        # must split them. No walls within reach (huge map).
        x0 = np.array([[5e5, 5e5, 4.0, 3.0]])
        model = make_model(["dubins"], x0, np.random.default_rng(7), width=1e6, height=1e6,
                           dt=0.7)
        # The target's own stream: initial rate, then one uniform per redraw.
        child = np.random.default_rng(7).spawn(1)[0]
        rates = [child.uniform(-0.1, 0.1) for _ in range(4)]
        steps = 40  # 28 s
        traj = np.array([model.step()[0] for _ in range(steps)])
        ref = euler_dubins(x0[0, :2], 5.0, math.atan2(3.0, 4.0), rates, [10.0, 20.0, 30.0],
                           steps * 0.7)
        sub = 4000 * 0.7
        ref_xy = np.array([ref[int(round((t + 1) * sub))] for t in range(steps)])
        np.testing.assert_allclose(traj[:, :2], ref_xy, atol=5e-3, rtol=0)
        np.testing.assert_allclose(np.hypot(traj[:, 2], traj[:, 3]), 5.0, rtol=1e-12)

    def test_redraw_at_exact_step_boundary(self):
        # dt = 1 and turn_hold = 10: the rate in steps 11..20 is the second draw.
        x0 = np.array([[5e5, 5e5, 5.0, 0.0]])
        model = make_model(["dubins"], x0, np.random.default_rng(3), width=1e6, height=1e6,
                           dt=1.0)
        child = np.random.default_rng(3).spawn(1)[0]
        r0, r1 = child.uniform(-0.1, 0.1), child.uniform(-0.1, 0.1)
        traj = np.array([model.step()[0] for _ in range(15)])
        headings = np.arctan2(traj[:, 3], traj[:, 2])
        np.testing.assert_allclose(np.diff(headings[:10]), r0, atol=1e-12)
        np.testing.assert_allclose(np.diff(headings[10:]), r1, atol=1e-12)

    def test_cv_without_noise_is_the_folded_straight_line(self, rng):
        M = 20
        x0 = np.column_stack([rng.uniform(0, 100, M), rng.uniform(0, 80, M),
                              rng.uniform(-250, 250, M), rng.uniform(-250, 250, M)])
        model = make_model(["cv"] * M, x0, rng, width=100.0, height=80.0, q=0.0)
        for t in range(1, 60):
            x = model.step()
            fx, flip_x = mirror(x0[:, 0] + t * x0[:, 2], 100.0)
            fy, flip_y = mirror(x0[:, 1] + t * x0[:, 3], 80.0)
            np.testing.assert_allclose(x[:, 0], fx, atol=1e-6)
            np.testing.assert_allclose(x[:, 1], fy, atol=1e-6)
            np.testing.assert_array_equal(x[:, 2], np.where(flip_x, -x0[:, 2], x0[:, 2]))
            np.testing.assert_array_equal(x[:, 3], np.where(flip_y, -x0[:, 3], x0[:, 3]))

    def test_straight_dubins_is_the_folded_straight_line(self, rng):
        M = 10
        x0 = np.column_stack([rng.uniform(0, 90, M), rng.uniform(0, 120, M),
                              rng.uniform(-200, 200, M), rng.uniform(-200, 200, M)])
        model = make_model(["dubins"] * M, x0, rng, width=90.0, height=120.0,
                           max_turn_rate=0.0)
        for t in range(1, 40):
            x = model.step()
            fx, flip_x = mirror(x0[:, 0] + t * x0[:, 2], 90.0)
            fy, flip_y = mirror(x0[:, 1] + t * x0[:, 3], 120.0)
            np.testing.assert_allclose(x[:, :2], np.column_stack([fx, fy]), atol=1e-6)
            np.testing.assert_allclose(x[:, 2], np.where(flip_x, -x0[:, 2], x0[:, 2]),
                                       atol=1e-9)
            np.testing.assert_allclose(x[:, 3], np.where(flip_y, -x0[:, 3], x0[:, 3]),
                                       atol=1e-9)

    def test_mirrored_tracks_stay_in_the_map(self, rng):
        M = 60
        kinds = ["cv", "dubins"] * (M // 2)
        speed = rng.uniform(1.0, 400.0, M)      # up to several reflections per step
        h = rng.uniform(-np.pi, np.pi, M)
        x0 = np.column_stack([rng.uniform(0, 200, M), rng.uniform(0, 150, M),
                              speed * np.cos(h), speed * np.sin(h)])
        model = make_model(kinds, x0, rng, width=200.0, height=150.0, q=5.0, turn_hold=3.0,
                           max_turn_rate=0.5)
        dub = np.array([k == "dubins" for k in kinds])
        for _ in range(2000):
            x = model.step()
            assert np.all((x[:, 0] >= 0) & (x[:, 0] <= 200) & (x[:, 1] >= 0) & (x[:, 1] <= 150))
        np.testing.assert_allclose(np.hypot(x[dub, 2], x[dub, 3]), speed[dub], rtol=1e-9)

    def test_cv_one_step_statistics_without_walls(self):
        dt, q = 1.0, 0.05
        M, steps = 100, 200                    # 20000 increments
        x0 = np.tile([5e6, 5e6, 4.0, -3.0], (M, 1))
        model = make_model(["cv"] * M, x0, np.random.default_rng(2024), width=1e7, height=1e7,
                           dt=dt, q=q)
        F, Q = cv_matrices(dt, q)
        prev = x0
        w = []
        for _ in range(steps):
            x = model.step()
            w.append(x - prev @ F.T)
            prev = x
        w = np.concatenate(w)
        n = len(w)
        # Mean within 4.5 standard errors; covariance entries within 4.5 standard errors
        # of the sample covariance of Gaussian data, (Q_ii Q_jj + Q_ij^2) / n.
        se_mean = np.sqrt(np.diag(Q) / n)
        assert np.all(np.abs(w.mean(axis=0)) <= 4.5 * se_mean)
        C = np.cov(w.T)
        se_cov = np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / n)
        assert np.all(np.abs(C - Q) <= 4.5 * se_cov)
        # Increments of one target at consecutive steps are uncorrelated.
        wt = w.reshape(steps, M, 4)
        lag = np.mean(wt[1:, :, 0] * wt[:-1, :, 0]) / Q[0, 0]
        assert abs(lag) <= 4.5 / math.sqrt((steps - 1) * M)

    def test_zero_process_noise_is_allowed(self):
        model = make_model(["cv"], np.array([[100.0, 100.0, 1.0, 2.0]]),
                           np.random.default_rng(0), q=0.0)
        np.testing.assert_allclose(model.step(), [[101.0, 102.0, 1.0, 2.0]], atol=1e-12)


class TestDeterminism:
    def run(self, kinds, x0, seed, steps=300):
        model = make_model(kinds, x0, np.random.default_rng(seed), width=300.0, height=250.0,
                           q=0.5, turn_hold=4.0)
        return np.array([model.step() for _ in range(steps)])

    def x0(self, rng, M):
        return np.column_stack([rng.uniform(0, 300, M), rng.uniform(0, 250, M),
                                rng.uniform(-6, 6, M), rng.uniform(-6, 6, M)])

    def test_same_seed_same_truth_different_seed_differs(self, rng):
        kinds = ["cv", "dubins", "cv"]
        x0 = self.x0(rng, 3)
        a = self.run(kinds, x0, 5)
        np.testing.assert_array_equal(a, self.run(kinds, x0, 5))
        b = self.run(kinds, x0, 6)
        assert np.all(np.abs(a[-1] - b[-1]).max(axis=1) > 1e-3)

    def test_a_target_depends_only_on_its_own_stream(self, rng):
        # Adding a target after the others does not change their trajectories, across
        # several noise blocks.
        x0 = self.x0(rng, 3)
        steps = 2 * NOISE_BLOCK + 10
        a = self.run(["cv", "dubins"], x0[:2], 9, steps)
        b = self.run(["cv", "dubins", "cv"], x0, 9, steps)
        np.testing.assert_array_equal(a, b[:, :2])

    def test_bad_initial_shape(self):
        with pytest.raises(ValueError, match="shape"):
            make_model(["cv", "cv"], np.zeros((3, 4)), np.random.default_rng(0))
        with pytest.raises(ValueError, match="shape"):
            TruthModel(["cv", "dubins"], np.zeros((2, 4)), np.random.default_rng(0),
                       turn_hold=[10.0], max_turn_rate=[0.1, 0.1], world_size=(600.0, 600.0),
                       dt=1.0, process_noise=0.05)


def _scenario() -> Scenario:
    targets = (TargetSpec("cv"), TargetSpec("dubins", turn_hold=3.0, max_turn_rate=0.3),
               TargetSpec("dubins", turn_hold=7.0, max_turn_rate=0.05))
    return Scenario(world=MapRect(250.0, 180.0), dt=0.5, process_noise=0.3, targets=targets,
                    sensors=(SensorSpec(),))


def _start(rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.uniform(0, 180, 3), rng.uniform(0, 180, 3),
                            rng.uniform(-6, 6, 3), rng.uniform(-6, 6, 3)])


def test_make_truth_passes_every_target_and_map_field(rng):
    """make_truth equals the model built from the scenario's arrays by hand, and the
    per-target turn settings matter (the scenario's targets differ in them)."""
    sc, x0 = _scenario(), _start(rng)
    got = make_truth(sc, x0, np.random.default_rng(4))
    ref = TruthModel(["cv", "dubins", "dubins"], x0, np.random.default_rng(4),
                     turn_hold=[10.0, 3.0, 7.0], max_turn_rate=[0.1, 0.3, 0.05],
                     world_size=(250.0, 180.0), dt=0.5, process_noise=0.3)
    a = np.array([got.step() for _ in range(80)])
    b = np.array([ref.step() for _ in range(80)])
    np.testing.assert_array_equal(a, b)
    same = TruthModel(["cv", "dubins", "dubins"], x0, np.random.default_rng(4),
                      turn_hold=[10.0, 7.0, 3.0], max_turn_rate=[0.1, 0.05, 0.3],
                      world_size=(250.0, 180.0), dt=0.5, process_noise=0.3)
    c = np.array([same.step() for _ in range(80)])
    assert not np.allclose(a[:, 1:], c[:, 1:])




class TestAddRemoveOpenWalls:
    """Targets added and removed while the others move on, and walls that let targets out."""

    def x0(self, rng, M):
        return np.column_stack([rng.uniform(0, 300, M), rng.uniform(0, 250, M),
                                rng.uniform(-6, 6, M), rng.uniform(-6, 6, M)])

    def model(self, kinds, x0, seed, walls="mirror", buildings=None):
        M = len(kinds)
        return TruthModel(kinds, x0, np.random.default_rng(seed), turn_hold=np.full(M, 4.0),
                          max_turn_rate=np.full(M, 0.1), world_size=(300.0, 250.0), dt=1.0,
                          process_noise=0.5, buildings=buildings, walls=walls)

    @pytest.mark.parametrize("kind", ["cv", "dubins"])
    def test_an_added_target_moves_as_a_model_started_then(self, rng, kind):
        # The added target's noise blocks start when it is added, not in step with the
        # others'; its motion equals a one-target model started at that moment with a
        # parent whose first child is the generator given to add().
        x0 = self.x0(rng, 3)
        a = self.model(["cv", "dubins", "cv"], x0, 9)
        alone = self.model(["cv", "dubins", "cv"], x0, 9)
        for _ in range(37):
            a.step()
            alone.step()
        xb = self.x0(rng, 1)
        a.add([kind], xb, [np.random.default_rng(21).spawn(1)[0]], turn_hold=[4.0],
              max_turn_rate=[0.1])
        ref = self.model([kind], xb, 21)
        for _ in range(2 * NOISE_BLOCK + 5):
            x = a.step()
            np.testing.assert_array_equal(x[:3], alone.step())
            np.testing.assert_array_equal(x[3:], ref.step())

    def test_removing_targets_leaves_the_others_bit_for_bit(self, rng):
        kinds = ["cv", "dubins", "cv", "dubins", "cv"]
        x0 = self.x0(rng, 5)
        a, b = self.model(kinds, x0, 3), self.model(kinds, x0, 3)
        for t in range(NOISE_BLOCK + 30):
            if t == 100:
                b.remove([1, 2])
            xa, xb = a.step(), b.step()
            np.testing.assert_array_equal(xb, xa if t < 100 else xa[[0, 3, 4]])
        assert b.n_targets == 3 and len(b.cv) == 2 and len(b.dub) == 1

    def test_open_walls_let_a_target_through(self, rng):
        x0 = np.array([[290.0, 5.0, 4.0, -1.0], [10.0, 125.0, -3.0, 0.5]])
        m = TruthModel(["cv", "dubins"], x0, rng, turn_hold=[10.0, 10.0],
                       max_turn_rate=[0.1, 0.0], world_size=(300.0, 250.0), dt=1.0,
                       process_noise=0.0, walls="open")
        for t in range(1, 21):
            np.testing.assert_allclose(m.step(), x0 + t * np.hstack([x0[:, 2:], 0 * x0[:, 2:]]),
                                       atol=1e-9)

    def test_open_walls_keep_the_buildings(self):
        # Heading +x into a building whose wall is at x = 100: mirrored back across it.
        m = TruthModel(["cv"], np.array([[96.0, 50.0, 5.0, 0.0]]), np.random.default_rng(0),
                       turn_hold=[10.0], max_turn_rate=[0.1], world_size=(300.0, 250.0),
                       dt=1.0, process_noise=0.0, buildings=np.array([[100.0, 0.0, 150.0,
                                                                       100.0, 20.0]]),
                       walls="open")
        np.testing.assert_allclose(m.step(), [[99.0, 50.0, -5.0, 0.0]], atol=1e-12)

    def test_unknown_walls_or_kind(self):
        with pytest.raises(ValueError, match="walls"):
            self.model(["cv"], np.zeros((1, 4)), 0, walls="bounce")
        with pytest.raises(ValueError, match="kind"):
            self.model(["cv", "boat"], np.zeros((2, 4)), 0)
