"""The mutual-information potential against an independent computation.

The reference here shares no code with ``sensorplan.planners.information``: it rebuilds the
headings,
H, R and p_vis from their definitions with scalar maths, and evaluates the information with the
paper's joint-Gaussian conditional-covariance formula (Lemma 1): the joint covariance of the
target state and every measurement of the plan, conditioned by a Schur complement.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sensorplan.models.angles import heading_rule
from sensorplan.planners import information
from sensorplan.planners.information import (covariance_recursion, evaluate, information_update,
                                             measured, phi_terms, potential, prepare)
from sensorplan.planners.problem import Plan, PlanningProblem
from sensorplan.models.sensors import SensorParams

RTOL = 1e-9          # information is compared at 1e-9 relative
ATOL = 1e-12         # nats; for terms that are (almost) zero


@pytest.fixture(params=["numba", "numpy"])
def backend(request, monkeypatch):
    """Run the test with the compiled kernels and with the pure-numpy reference path."""
    monkeypatch.setattr(information, "BACKEND", request.param)
    return request.param


# --------------------------------------------------------------------------- reference

def wrap(a: float) -> float:
    w = math.remainder(a, 2 * math.pi)
    return math.pi if w <= -math.pi else w


def ncdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def spec_F(dt: float) -> np.ndarray:
    return np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)


def spec_Q(dt: float, q: float) -> np.ndarray:
    a, b = dt**3 / 3, dt**2 / 2
    return q * np.array([[a, 0, b, 0], [0, a, 0, b], [b, 0, dt, 0], [0, b, 0, dt]])


class Reference:
    """Everything a decision defines for one problem, computed naively."""

    def __init__(self, problem: PlanningProblem):
        self.pr = problem
        # how often the turn limit binds (so that tests can check they exercise it)
        self.clipped_chain = self.clipped_gap = 0
        self.T = problem.horizon * problem.steps_per_epoch
        self.F = spec_F(problem.dt)
        self.Q = spec_Q(problem.dt, problem.process_noise)
        self.Fp = [np.linalg.matrix_power(self.F, t) for t in range(self.T + 1)]
        # Pbar(t) = F^t P0 F^tT + sum_{u<t} F^u Q F^uT: the explicit sum, not a recursion.
        noise = [np.zeros((4, 4))]
        for t in range(1, self.T + 1):
            noise.append(noise[-1] + self.Fp[t - 1] @ self.Q @ self.Fp[t - 1].T)
        self.Pbar = [[self.Fp[t] @ P0 @ self.Fp[t].T + noise[t] for t in range(self.T + 1)]
                     for P0 in problem.covs]

    def xbar(self, j: int, t: int) -> np.ndarray:
        return self.Fp[t] @ self.pr.means[j]

    def cross(self, j: int, t: int, s: int) -> np.ndarray:
        """Cov(x_t, x_s) of target j without measurements."""
        if t >= s:
            return self.Fp[t - s] @ self.Pbar[j][s]
        return self.Pbar[j][t] @ self.Fp[s - t].T

    def headings(self, plan: Plan) -> np.ndarray:
        pr, e = self.pr, self.pr.steps_per_epoch
        out = np.full((pr.n_sensors, pr.horizon), np.nan)
        for i, sp in enumerate(pr.sensors):
            th0 = float(pr.headings[i])
            prev, prev_assigned = th0, True                  # k = 1 turns from theta_0
            for k in range(1, pr.horizon + 1):
                j = int(plan.targets[i, k - 1])
                if j < 0:
                    prev_assigned = False
                    continue
                p = plan.positions[i, k - 1]
                aim = self.xbar(j, (k - 1) * e + 1)
                b = math.atan2(aim[1] - p[1], aim[0] - p[0])
                if prev_assigned:
                    turn = min(max(wrap(b - prev), -sp.max_turn), sp.max_turn)
                    th = prev + turn
                    # where the chain differs from "what is reachable in k epochs"
                    reach = th0 + min(max(wrap(b - th0), -k * sp.max_turn), k * sp.max_turn)
                    self.clipped_chain += abs(wrap(th - reach)) > 1e-6
                else:
                    turn = min(max(wrap(b - th0), -k * sp.max_turn), k * sp.max_turn)
                    th = th0 + turn
                    self.clipped_gap += abs(wrap(b - th0)) > sp.max_turn
                out[i, k - 1] = th
                prev, prev_assigned = th, True
        return out

    def look(self, sp: SensorParams, p: np.ndarray, theta: float, j: int, t: int):
        """(H, R, weight) of one look; weight 0 when it does not count."""
        x = self.xbar(j, t)
        dx, dy, z = x[0] - p[0], x[1] - p[1], sp.altitude
        g2 = dx * dx + dy * dy
        g, r = math.sqrt(g2), math.sqrt(g2 + z * z)
        H = np.array([[dx / r, dy / r, 0.0, 0.0], [-dy / g2, dx / g2, 0.0, 0.0]])
        bvec = np.array([math.cos(sp.depression) * math.cos(theta),
                         math.cos(sp.depression) * math.sin(theta), -math.sin(sp.depression)])
        cpsi = float(bvec @ np.array([dx, dy, -z])) / r
        snr = 10 ** (sp.snr_ref_db / 10) * (sp.range_ref / r) ** 4
        sr = sp.range_resolution / math.sqrt(2 * snr)
        sphi = (sp.beamwidth / cpsi) / (sp.monopulse_slope * math.sqrt(2 * snr))
        R = np.diag([sr * sr, sphi * sphi])
        d = wrap(math.atan2(dy, dx) - theta)
        if self.pr.visibility == "mean":
            ok = (sp.min_ground_range <= g <= sp.max_ground_range
                  and abs(d) <= sp.fov_half_angle and cpsi > 0)
            return H, R, float(ok)
        if g == 0 or cpsi <= 0:
            return H, R, 0.0
        C = self.Pbar[j][t][:2, :2]
        u = np.array([dx, dy]) / g
        v = np.array([-dy, dx]) / g
        sg = math.sqrt(float(u @ C @ u))
        sa = math.sqrt(float(v @ C @ v)) / g
        pv = ((ncdf((sp.max_ground_range - g) / sg) - ncdf((sp.min_ground_range - g) / sg))
              * (ncdf((sp.fov_half_angle - d) / sa) - ncdf((-sp.fov_half_angle - d) / sa)))
        return H, R, (pv if pv >= 1e-6 else 0.0)

    def measurements(self, plan: Plan):
        """Per target: list of (t, H, R_effective); and per player the counted looks."""
        pr, e = self.pr, self.pr.steps_per_epoch
        th = self.headings(plan)
        meas: list[list] = [[] for _ in range(pr.n_targets)]
        counts = np.zeros((pr.n_sensors, pr.horizon), dtype=int)
        for i, sp in enumerate(pr.sensors):
            for k in range(1, pr.horizon + 1):
                j = int(plan.targets[i, k - 1])
                if j < 0:
                    continue
                for t in range((k - 1) * e + 1, k * e + 1):
                    H, R, w = self.look(sp, plan.positions[i, k - 1], th[i, k - 1], j, t)
                    if w > 0:
                        meas[j].append((t, H, R / w))
                        counts[i, k - 1] += 1
        return meas, counts, th

    def lemma1(self, j: int, meas: list, t_end: int) -> float:
        """0.5 logdet Pbar(t_end) - 0.5 logdet Cov(x_t_end | measurements at t <= t_end)."""
        ms = [m for m in meas if m[0] <= t_end]
        Pt = self.Pbar[j][t_end]
        if not ms:
            return 0.0
        L = len(ms)
        Czz = np.zeros((2 * L, 2 * L))
        Cxz = np.zeros((4, 2 * L))
        for a, (ta, Ha, Ra) in enumerate(ms):
            Cxz[:, 2 * a:2 * a + 2] = self.cross(j, t_end, ta) @ Ha.T
            for b, (tb, Hb, _) in enumerate(ms):
                Czz[2 * a:2 * a + 2, 2 * b:2 * b + 2] = Ha @ self.cross(j, ta, tb) @ Hb.T
            Czz[2 * a:2 * a + 2, 2 * a:2 * a + 2] += Ra
        post = Pt - Cxz @ np.linalg.solve(Czz, Cxz.T)
        return 0.5 * (np.linalg.slogdet(Pt)[1] - np.linalg.slogdet(0.5 * (post + post.T))[1])

    def information(self, plan: Plan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        meas, counts, th = self.measurements(plan)
        info = np.zeros(self.pr.n_targets)
        for j in range(self.pr.n_targets):
            if self.pr.objective == "cumulative":
                info[j] = sum(self.lemma1(j, meas[j], t) for t in range(1, self.T + 1))
            else:
                info[j] = self.lemma1(j, meas[j], self.T)
        return info, counts, th


# --------------------------------------------------------------------------- Lemma 1

@pytest.mark.parametrize("objective", ["terminal", "cumulative"])
@pytest.mark.parametrize("visibility", ["probabilistic", "mean"])
def test_potential_equals_joint_gaussian_formula(rng, problem_factory, plan_factory, backend,
                                                 visibility, objective):
    positive = partial_counted = unassigned_rule = clipped_chain = clipped_gap = 0
    n_cases = 40
    for case in range(n_cases):
        N, M, K = (int(v) for v in rng.integers(1, 4, size=3))
        e = int(rng.integers(1, 3))
        # a small max_turn in some cases so that the turn limit binds along chains
        turn = {"max_turn": math.pi / 24} if case % 4 == 3 else None
        pr = problem_factory(rng, n_sensors=N, n_targets=M, horizon=K, steps_per_epoch=e,
                             visibility=visibility, objective=objective,
                             vary_sensors=bool(case % 2),
                             moves=((20.0, 40.0), (20.0,))[case % 3 == 2], sensor_kwargs=turn)
        plan = plan_factory(pr, rng, p_unassigned=(0.0, 0.3)[case % 2])
        phi, info = potential(pr, plan)
        ref = Reference(pr)
        want, counts, th = ref.information(plan)
        np.testing.assert_allclose(info, want, rtol=RTOL, atol=ATOL, err_msg=f"case {case}")
        assert phi == pytest.approx(want.sum(), rel=RTOL, abs=ATOL)
        ev = evaluate(prepare(pr), plan)
        np.testing.assert_array_equal(ev.measurements, counts)
        np.testing.assert_allclose(np.cos(ev.headings[plan.assigned]),
                                   np.cos(th[plan.assigned]), atol=1e-12)
        np.testing.assert_allclose(np.sin(ev.headings[plan.assigned]),
                                   np.sin(th[plan.assigned]), atol=1e-12)
        positive += phi > 0
        clipped_chain += ref.clipped_chain > 0
        clipped_gap += ref.clipped_gap > 0
        partial_counted += 0 < counts.sum() < plan.assigned.sum() * e
        a = plan.assigned
        unassigned_rule += bool((a[:, 1:] & ~a[:, :-1]).any())
    # the comparison is not vacuous
    assert positive >= n_cases // 2
    assert unassigned_rule >= 5
    assert clipped_chain >= 2 and clipped_gap >= 2
    if visibility == "mean":
        assert partial_counted >= 5


def test_unassigned_predecessor_turns_by_k_max_turn(backend):
    # One sensor, target at bearing 1.4 rad: epoch 2 after an unassigned epoch 1 may turn
    # 2 * max_turn = pi/2 >= 1.4 and points straight at it; with epoch 1 assigned it turns
    # max_turn per epoch along the chain.
    x0 = np.array([300.0 + 350 * math.cos(1.4), 300.0 + 350 * math.sin(1.4), 0.0, 0.0])
    pr = PlanningProblem(means=x0[None], covs=np.diag([100.0, 100, 1, 1])[None],
                         positions=np.array([[300.0, 300.0]]), headings=np.array([0.0]),
                         sensors=(SensorParams(),), horizon=3, process_noise=0.0,
                         visibility="mean")
    p = np.array([300.0, 300.0])
    gap = Plan(np.array([[[np.nan, np.nan], p, p]]), np.array([[-1, 0, 0]]))
    ev = evaluate(prepare(pr), gap)
    np.testing.assert_allclose(ev.headings[0, 1:], [1.4, 1.4], atol=1e-12)
    chain = Plan(np.array([[p, p, p]]), np.array([[0, 0, 0]]))
    ev2 = evaluate(prepare(pr), chain)
    np.testing.assert_allclose(ev2.headings[0], [math.pi / 4, 1.4, 1.4], atol=1e-12)
    # The first look of the chain is outside the +-pi/6 wedge (1.4 - pi/4 > pi/6).
    np.testing.assert_array_equal(ev2.measurements, [[0, 1, 1]])
    ref = Reference(pr)
    for plan, ev_ in ((gap, ev), (chain, ev2)):
        want, _, _ = ref.information(plan)
        assert ev_.potential == pytest.approx(want.sum(), rel=RTOL)


def test_chain_headings_turn_from_the_previous_epoch(backend):
    # Targets at bearings +1.0 and -1.0 rad; plan A, B, B with max_turn pi/4: the chain turns
    # to pi/4, back to 0, then to -pi/4 (not "-1.0, reachable from theta_0 in 2 epochs").
    c = np.array([300.0, 300.0])
    means = np.array([[*(c + 350 * np.array([math.cos(1.0), math.sin(1.0)])), 0, 0],
                      [*(c + 350 * np.array([math.cos(-1.0), math.sin(-1.0)])), 0, 0]])
    pr = PlanningProblem(means=means, covs=np.broadcast_to(np.diag([100.0, 100, 1, 1]), (2, 4, 4)),
                         positions=c[None], headings=np.array([0.0]), sensors=(SensorParams(),),
                         horizon=3, process_noise=0.0)
    plan = Plan(np.array([[c, c, c]]), np.array([[0, 1, 1]]))
    ev = evaluate(prepare(pr), plan)
    np.testing.assert_allclose(ev.headings[0], [math.pi / 4, 0.0, -math.pi / 4], atol=1e-12)
    want, _, th = Reference(pr).information(plan)
    np.testing.assert_allclose(th[0], ev.headings[0], atol=1e-12)
    np.testing.assert_allclose(ev.information, want, rtol=RTOL, atol=ATOL)


def numpy_chain_headings(ctx, i, k_first, positions, targets, prev_heading, prev_assigned):
    """The heading chain in numpy, vectorised over candidates (the second computation of the
    compiled one): bearing to the aim point, heading rule, ``k max_turn`` after a gap."""
    max_turn = ctx.max_turn[i]
    theta0 = ctx.problem.headings[i]
    out = np.empty(targets.shape)
    prev = np.asarray(prev_heading, dtype=float)
    for l in range(targets.shape[1]):
        k = k_first + l
        aim = ctx.aim[targets[:, l], k - 1]
        bearing = np.arctan2(aim[:, 1] - positions[:, l, 1], aim[:, 0] - positions[:, l, 0])
        if l == 0 and not prev_assigned:
            prev = heading_rule(theta0, bearing, k * max_turn)
        else:
            prev = heading_rule(prev, bearing, max_turn)
        out[:, l] = prev
    return out


@pytest.mark.parametrize("prev_assigned", [True, False])
def test_chain_headings_equal_the_numpy_heading_chain(rng, problem_factory, prev_assigned):
    """The compiled heading chain (one helper for every kernel) against the numpy one (numpy's
    and libm's atan2 differ in the last bit at times), and the headings of the compiled looks
    equal to it bit for bit."""
    from sensorplan.planners._chains_nb import chain_looks_nb

    clipped = 0
    for case in range(20):
        K = int(rng.integers(2, 5))
        turn = {"max_turn": float(rng.uniform(0.05, 1.0))}
        pr = problem_factory(rng, n_sensors=2, n_targets=3, horizon=K, sensor_kwargs=turn)
        ctx = prepare(pr)
        B, k_first = 50, int(rng.integers(1, K))
        L = K - k_first + 1
        pos = rng.uniform(0.0, 600.0, (B, L, 2))
        tgt = rng.integers(0, 3, (B, L))
        prev = rng.uniform(-math.pi, math.pi, B)
        i = case % 2
        got = information.chain_headings(ctx, i, k_first, pos, tgt, prev, prev_assigned)
        want = numpy_chain_headings(ctx, i, k_first, pos, tgt, prev, prev_assigned)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
        scalar = information.chain_headings(ctx, i, k_first, pos, tgt, 0.3, prev_assigned)
        np.testing.assert_allclose(
            scalar, numpy_chain_headings(ctx, i, k_first, pos, tgt, 0.3, prev_assigned),
            rtol=0, atol=1e-13)
        th, _, _ = chain_looks_nb(pos, tgt, k_first, pr.steps_per_epoch, 0.3, prev_assigned,
                                  float(pr.headings[i]), float(ctx.max_turn[i]), ctx.aim,
                                  ctx.xbar_xy, ctx.Cbar, ctx.probabilistic, ctx.radar[i], True,
                                  ctx.buildings)
        np.testing.assert_array_equal(th, scalar)
        step = np.abs(np.diff(np.unwrap(np.c_[prev, want], axis=1), axis=1))
        clipped += int(np.sum(np.isclose(step, ctx.max_turn[i], rtol=1e-12)))
    assert clipped > 50                       # the turn limit binds in many chains


def test_empty_plan_has_zero_potential(rng, problem_factory, backend):
    for objective in ("terminal", "cumulative"):
        pr = problem_factory(rng, n_sensors=2, n_targets=3, horizon=3, objective=objective)
        phi, info = potential(pr, Plan.empty(2, 3))
        # Equal up to round-off (the cumulative sum of log-dets is summed in another order).
        assert abs(phi) <= 1e-12 and np.all(np.abs(info) <= 1e-12)


def test_probabilistic_tends_to_mean_for_tiny_covariances(rng, problem_factory, plan_factory,
                                                          backend):
    differ = 0
    for _ in range(20):
        covs = np.broadcast_to(np.eye(4) * 1e-6, (3, 4, 4))
        kw = dict(n_sensors=2, n_targets=3, horizon=2, steps_per_epoch=2, process_noise=0.0,
                  covs=covs)
        seed = int(rng.integers(2**32))
        prob = problem_factory(np.random.default_rng(seed), visibility="probabilistic", **kw)
        mean = problem_factory(np.random.default_rng(seed), visibility="mean", **kw)
        plan = plan_factory(prob, rng)
        ev_p = evaluate(prepare(prob), plan)
        ev_m = evaluate(prepare(mean), plan)
        np.testing.assert_array_equal(ev_p.measurements, ev_m.measurements)
        np.testing.assert_allclose(ev_p.information, ev_m.information, rtol=1e-12, atol=0)
        differ += 0 < ev_m.measurements.sum() < 8
    assert differ >= 5


# --------------------------------------------------------------------------- kernels

def _random_spd(rng, n, shape=()):
    """Random SPD matrices with condition numbers below about 100."""
    A = rng.normal(size=shape + (n, n))
    S = A @ np.swapaxes(A, -1, -2) + n * np.eye(n)
    return S * rng.uniform(0.5, 400, size=shape + (1, 1))


def test_information_update_equals_information_form(rng):
    B = 200
    P = _random_spd(rng, 4, (B,))
    W = _random_spd(rng, 2, (B,)) * rng.uniform(1e-4, 1, size=(B, 1, 1))
    W[:20] = 0.0                                                       # no information
    v = rng.normal(size=(20, 2))
    W[20:40] = v[:, :, None] * v[:, None, :]                          # rank one
    post, gain = information_update(P, W)
    G = np.zeros((2, 4))
    G[0, 0] = G[1, 1] = 1.0
    for b in range(B):
        J = np.linalg.solve(P[b], np.eye(4)) + G.T @ W[b] @ G
        ref = np.linalg.solve(J, np.eye(4))
        scale = np.abs(P[b]).max()
        np.testing.assert_allclose(post[b], ref, rtol=1e-10, atol=1e-10 * scale)
        want = np.linalg.slogdet(P[b])[1] - np.linalg.slogdet(ref)[1]
        assert gain[b] == pytest.approx(want, rel=1e-10, abs=1e-10)
        np.testing.assert_array_equal(post[b], post[b].T)
        np.linalg.cholesky(post[b])
    np.testing.assert_allclose(post[:20], P[:20], rtol=1e-14, atol=0)
    assert np.all(gain[:20] == 0.0)


def test_covariance_recursion_equals_step_by_step_reference(rng, backend):
    F, Q = spec_F(1.0), spec_Q(1.0, 0.05)
    B, n = 30, 6
    P0 = _random_spd(rng, 4, (B,))
    W = _random_spd(rng, 2, (B, n)) * 1e-2
    W[:, ::2] = 0.0
    P_end, ld_end, ld_sum = covariance_recursion(P0, W, F, Q)
    G = np.eye(4)[:2]
    for b in range(B):
        P, total = P0[b], 0.0
        for t in range(n):
            P = F @ P @ F.T + Q
            P = np.linalg.solve(np.linalg.solve(P, np.eye(4)) + G.T @ W[b, t] @ G, np.eye(4))
            total += np.linalg.slogdet(P)[1]
        np.testing.assert_allclose(P_end[b], P, rtol=1e-9, atol=1e-9 * np.abs(P).max())
        assert ld_end[b] == pytest.approx(np.linalg.slogdet(P)[1], rel=1e-10, abs=1e-10)
        assert ld_sum[b] == pytest.approx(total, rel=1e-10, abs=1e-10)


def test_phi_terms_follow_the_definition_and_the_round_off_rule(rng):
    """Terms from explicit covariances (information form, matrix inverses), target by target
    and step by step; an unmeasured target's term is exactly 0, a measured one's at least 0."""
    F, Q = spec_F(1.0), spec_Q(1.0, 0.05)
    M, T = 6, 5
    P0 = _random_spd(rng, 4, (M,))
    W = _random_spd(rng, 2, (M, T)) * 1e-2
    W[:, ::2] = 0.0
    W[0] = 0.0                                                         # never measured
    W[1, :3] = 0.0                                                     # only at step 4
    G = np.eye(4)[:2]
    ld_bar, ld_post = np.zeros((M, T + 1)), np.zeros((M, T + 1))
    for j in range(M):
        Pb = P = P0[j]
        ld_bar[j, 0] = ld_post[j, 0] = np.linalg.slogdet(P0[j])[1]
        for t in range(1, T + 1):
            Pb, P = F @ Pb @ F.T + Q, F @ P @ F.T + Q
            P = np.linalg.inv(np.linalg.inv(P) + G.T @ W[j, t - 1] @ G)
            ld_bar[j, t], ld_post[j, t] = np.linalg.slogdet(Pb)[1], np.linalg.slogdet(P)[1]
    ld_end, ld_sum = ld_post[:, -1], ld_post[:, 1:].sum(axis=1)
    for cumulative in (False, True):
        want = np.zeros(M)
        for j in range(1, M):
            steps = range(1, T + 1) if cumulative else (T,)
            want[j] = sum(0.5 * (ld_bar[j, t] - ld_post[j, t]) for t in steps)
        got = phi_terms(ld_bar, ld_end, ld_sum, cumulative, measured(W))
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
        assert got[0] == 0.0 and np.all(want[1:] > 0)
    # The rule, on round-off: an unmeasured target 1e-13 apart is 0, a measured one just
    # below its reference is 0, and one batch of values per target broadcasts.
    ld_ref = np.array([0.0, 1.0, 3.0])                                  # (T + 1,) = (3,)
    ld = np.array([3.0 - 1e-13, 3.0 + 1e-15, 2.0])
    got = phi_terms(ld_ref, ld, ld, False, np.array([False, True, True]))
    np.testing.assert_array_equal(got, [0.0, 0.0, 0.5])
    np.testing.assert_array_equal(measured(np.zeros((2, 4, 2, 2))), [False, False])


def test_covariances_stay_positive_definite_over_long_recursions(rng):
    F, Q = spec_F(1.0), spec_Q(1.0, 0.05)
    B, n = 8, 2000
    P = np.broadcast_to(np.diag([400.0, 400, 4, 4]), (B, 4, 4)).copy()
    # intermittent, sometimes very strong measurements
    W = _random_spd(rng, 2, (B, n)) * 10.0 ** rng.uniform(-6, 4, size=(B, n, 1, 1))
    W[rng.random((B, n)) < 0.6] = 0.0
    for t in range(n):
        P = F @ P @ F.T + Q
        P, gain = information_update(P, W[:, t])
        assert np.all(gain >= 0)
        np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
        assert np.all(np.linalg.eigvalsh(P) > 0)


def _edge_problem(offset_g: float, heading0: float, visibility: str = "mean",
                  angle: float = 0.0):
    """One sensor at (300, 300), one still target at ground range offset_g, bearing angle."""
    x0 = np.array([300.0 + offset_g * math.cos(angle), 300.0 + offset_g * math.sin(angle),
                   0.0, 0.0])
    return PlanningProblem(means=x0[None], covs=np.diag([100.0, 100, 1, 1])[None],
                           positions=np.array([[300.0, 300.0]]),
                           headings=np.array([heading0]), sensors=(SensorParams(),),
                           horizon=1, process_noise=0.05, visibility=visibility)


STAY = Plan(np.array([[[300.0, 300.0]]]), np.array([[0]]))


def test_mean_visibility_edges_in_the_potential(backend):
    d = SensorParams()
    counted = {}
    cases = {
        "min": (d.min_ground_range, 0.0), "max": (d.max_ground_range, 0.0),
        "below_min": (d.min_ground_range - 1e-6, 0.0),
        "above_max": (d.max_ground_range + 1e-6, 0.0),
        # heading rule turns max_turn and stops exactly fov short of the target
        "az_edge": (350.0, -(d.max_turn + d.fov_half_angle)),
        "az_beyond": (350.0, -(d.max_turn + d.fov_half_angle + 1e-9)),
    }
    for name, (g, h0) in cases.items():
        ev = evaluate(prepare(_edge_problem(g, h0)), STAY)
        counted[name] = int(ev.measurements[0, 0])
        assert (ev.potential > 0) == bool(counted[name])
    assert counted == {"min": 1, "max": 1, "below_min": 0, "above_max": 0, "az_edge": 1,
                       "az_beyond": 0}


# Bearings where the computed ground range lands a rounding error outside the band (found
# by search): the inclusive bounds need their tolerance there.
@pytest.mark.parametrize("edge,angle", [("min_ground_range", 1.966),
                                        ("min_ground_range", -0.545),
                                        ("max_ground_range", -2.75), ("max_ground_range", 1.4)])
def test_mean_visibility_range_edge_is_inclusive_off_axis(backend, edge, angle):
    g = getattr(SensorParams(), edge)
    step = 1e-6 if edge == "max_ground_range" else -1e-6
    on = evaluate(prepare(_edge_problem(g, angle, angle=angle)), STAY)
    off = evaluate(prepare(_edge_problem(g + step, angle, angle=angle)), STAY)
    assert on.measurements[0, 0] == 1 and off.measurements[0, 0] == 0


# Bearings where the heading rule stops a rounding error *beyond* the wedge edge (found by
# search): the inclusive bound needs its tolerance there.
@pytest.mark.parametrize("angle", [0.27410390540137985, -1.4464727375963786, 2.0, -3.0])
def test_mean_visibility_azimuth_edge_is_inclusive_after_the_heading_rule(backend, angle):
    d = SensorParams()
    b = angle
    for sign in (1, -1):
        h0 = b - sign * (d.max_turn + d.fov_half_angle)
        on = evaluate(prepare(_edge_problem(350.0, h0, angle=angle)), STAY)
        h0 = b - sign * (d.max_turn + d.fov_half_angle + 1e-9)
        off = evaluate(prepare(_edge_problem(350.0, h0, angle=angle)), STAY)
        assert on.measurements[0, 0] == 1 and off.measurements[0, 0] == 0


def test_probabilistic_look_on_a_range_edge_counts_with_p_vis(backend):
    # Target still on the max range edge, sensor pointing at it: p_vis about 1/2 and the
    # information equals the reference (R / p_vis).
    pr = _edge_problem(SensorParams().max_ground_range, 0.0, "probabilistic")
    ev = evaluate(prepare(pr), STAY)
    want, counts, _ = Reference(pr).information(STAY)
    assert counts[0, 0] == 1 and ev.measurements[0, 0] == 1
    assert ev.potential == pytest.approx(want.sum(), rel=RTOL)
    full = evaluate(prepare(dataclasses.replace(pr, visibility="mean")), STAY)
    assert 0 < ev.potential < full.potential
