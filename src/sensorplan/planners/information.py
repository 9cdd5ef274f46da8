r"""Mutual-information potential of a plan and the batched kernels behind it.

The definition is stated in docs/planning.md, section 1.

Everything here is covariance-only: the means are predicted without updates,
``xbar_j(t) = F^t x_j(0)``, and measurements enter through their information in the
target's ground position,

.. math:: W = p\, H'^T R^{-1} H' \quad (2\times 2),

where ``H'`` is the position block of the Jacobian and ``p`` is ``p_vis`` (``probabilistic``
visibility; the look counts with ``R / p_vis``) or the 0/1 visibility of the predicted mean
(``mean``). Several measurements of one target at one step add their ``W``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..models import radar
from ..models.motion import (aim_points, cv_matrices, predict_covariance, predict_covariances,
                             predict_means)
from ..models.sensors import radar_table
from ._chains_nb import (chain_headings_nb, chain_looks_nb, covariance_recursion_nb,
                         sum_by_target_nb)
from .problem import Lattice, Plan, PlanningProblem, build_lattice, move_vectors

#: ``"numba"`` (default) or ``"numpy"``: which implementation of the covariance recursion,
#: the looks' information along chains and the sums by target runs; set
#: ``SENSORPLAN_BACKEND=numpy`` to measure or debug without those compiled kernels (the radar
#: model and the heading chain are always the compiled ones).
BACKEND = os.environ.get("SENSORPLAN_BACKEND", "numba")


def _c(a: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    """A writable C-contiguous array: one compiled specialisation per kernel, not one per
    memory layout or read-only flag (each new one costs a compilation at first use)."""
    a = np.asarray(a, dtype=dtype)
    if a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=dtype, order="C")


@dataclass(frozen=True)
class Context:
    """Per-decision precomputation shared by :func:`potential` and the planners.

    Attributes
    ----------
    F : (4, 4)
    Q : (1, 4, 4) or (M, 4, 4)  process noise, shared by every target or one per target
    xbar : (M, T + 1, 4)       predicted means
    Pbar : (M, T + 1, 4, 4)    covariances predicted without measurements
    ld_bar : (M, T + 1)        their log-determinants
    Cbar : (M, T + 1, 3)       their position blocks (c00, c01, c11), for p_vis
    aim : (M, K, 2)            ground position each target is predicted at on the first
                               step of each epoch (the heading rule aims there)
    radar : (N, C)             radar table, one row per sensor
    max_turn : (N,)            turn limit per epoch of each sensor (rad)
    lattices : list of Lattice one per sensor
    xbar_xy : (M, T + 1, 2)    predicted ground positions (contiguous, for the kernels)
    buildings : (B, 5)         boxes that can hide targets (a writeable copy, for the kernels)
    existence : (M,)           each target's weight in Phi, its probability of existence r
                               (a writeable copy, for the kernels)
    """

    problem: PlanningProblem
    F: FloatArray
    Q: FloatArray
    xbar: FloatArray
    Pbar: FloatArray
    ld_bar: FloatArray
    Cbar: FloatArray
    aim: FloatArray
    radar: FloatArray
    max_turn: FloatArray
    lattices: list[Lattice]
    xbar_xy: FloatArray
    buildings: FloatArray
    existence: FloatArray

    @property
    def K(self) -> int:
        return self.problem.horizon

    @property
    def e(self) -> int:
        return self.problem.steps_per_epoch

    @property
    def T(self) -> int:
        return self.problem.n_steps

    @property
    def M(self) -> int:
        return self.problem.n_targets

    @property
    def N(self) -> int:
        return self.problem.n_sensors

    @property
    def probabilistic(self) -> bool:
        """Whether planned looks count with their probability of seeing the target."""
        return self.problem.visibility == "probabilistic"

    def Q_rows(self, targets: IntArray | int | slice) -> FloatArray:
        """Process noise for the rows of a recursion over ``targets``: shared or per row."""
        if self.Q.shape[0] == 1:
            return self.Q
        return self.Q[np.atleast_1d(np.arange(self.M)[targets])]

    def steps(self, k: int) -> IntArray:
        """Simulation steps ``(k-1)e+1 .. ke`` of epoch ``k`` (1-based)."""
        return np.arange((k - 1) * self.e + 1, k * self.e + 1)


def prepare(problem: PlanningProblem, search: bool = False) -> Context:
    """Precompute predictions, aim points and reachable sets for one decision.

    A problem whose search is on is refused (:class:`~sensorplan.errors.ConfigError` on
    ``search``) unless ``search`` says the caller plans search looks
    (:mod:`sensorplan.planners.search`): the track-only Phi would ignore them.
    """
    if problem.searching and not search:
        from ..errors import ConfigError

        raise ConfigError("search", "this planner does not plan search looks yet; set "
                          "search to 'off' or use brute-force, pg, pg-refine, "
                          "random, raster or sequential-greedy")
    q = np.asarray(problem.process_noise, dtype=float)
    F, Q1 = cv_matrices(problem.dt, 1.0)
    if q.ndim == 0:
        F, Q = cv_matrices(problem.dt, float(q))
        Q = Q[None]
    else:
        Q = q[:, None, None] * Q1                                        # (M, 4, 4)
    T, e, K = problem.n_steps, problem.steps_per_epoch, problem.horizon
    xbar = predict_means(problem.means, F, T)
    Pbar = predict_covariances(problem.covs, F, Q, T)
    ld_bar = np.linalg.slogdet(Pbar)[1]
    aim = aim_points(problem.means, F, K, e)
    lattices = [build_lattice(problem.positions[i], move_vectors(s.moves), K, problem.world)
                for i, s in enumerate(problem.sensors)]
    Cbar = np.stack([Pbar[..., 0, 0], Pbar[..., 0, 1], Pbar[..., 1, 1]], axis=-1)
    xbar_xy = np.ascontiguousarray(xbar[..., :2])
    max_turn = np.array([float(s.max_turn) for s in problem.sensors])
    table = radar_table(problem.sensors, aware=problem.planning_detection == "aware")
    # A writeable copy: the problem's read-only array would be another kernel signature.
    buildings = np.array(problem.buildings, dtype=float, order="C").reshape(-1, 5)
    existence = np.array(problem.existence, dtype=float, order="C")
    return Context(problem, F, Q, xbar, Pbar, ld_bar, Cbar, aim, table, max_turn, lattices,
                   xbar_xy, buildings, existence)


def chain_headings(ctx: Context, i: int, k_first: int, positions: FloatArray,
                   targets: IntArray, prev_heading: FloatArray | float,
                   prev_assigned: bool) -> FloatArray:
    """Headings along a run of consecutive assigned epochs ``k_first ..`` of sensor ``i``
    (the compiled heading chain, :func:`~sensorplan.planners._chains_nb.chain_headings_nb`).

    Parameters
    ----------
    positions : (B, L, 2)
    targets : (B, L) int
    prev_heading : (B,) or float
        Heading in epoch ``k_first - 1`` (``theta_0`` when ``k_first = 1``).
    prev_assigned : bool
        Whether epoch ``k_first - 1`` is assigned (True when ``k_first = 1``). If not,
        the first epoch turns from ``theta_0`` by at most ``k_first * max_turn``.

    Returns
    -------
    (B, L) headings.
    """
    prev = np.broadcast_to(np.asarray(prev_heading, dtype=float), targets.shape[:1])
    return chain_headings_nb(_c(positions), _c(targets, np.int64), k_first, _c(prev),
                             bool(prev_assigned), float(ctx.problem.headings[i]),
                             float(ctx.max_turn[i]), ctx.aim)


def epoch_information(ctx: Context, i: int, k: int, positions: FloatArray,
                      headings: FloatArray, targets: IntArray) -> tuple[FloatArray, BoolArray]:
    """Information ``W`` of sensor ``i``'s looks in epoch ``k`` from a batch of poses.

    Parameters
    ----------
    positions : (B, 2)
    headings : (B,)
    targets : (B,) int

    Returns
    -------
    W : (B, e, 2, 2)
        Position information of the look at each step of the epoch (zero if it does not
        count).
    counted : (B, e) bool
        Whether each look counts in Phi (per the visibility mode).
    """
    W, counted = chain_information(ctx, i, k, positions[:, None], headings[:, None],
                                   targets[:, None])
    return W[:, 0], counted[:, 0]


def chain_looks(ctx: Context, i: int, k_first: int, positions: FloatArray, targets: IntArray,
                prev_heading: float, prev_assigned: bool, all_headings: bool = True
                ) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Headings and look information along runs of assigned epochs, in one call.

    :func:`chain_headings` followed by :func:`chain_information` (the numpy looks), or
    one compiled loop over candidates, epochs and steps.

    With ``all_headings=False`` the compiled path may leave the last epoch's heading NaN
    where none of its looks can count (the caller only wants ``W``).

    Returns
    -------
    headings : (B, L);  W : (B, L, e, 2, 2);  counted : (B, L, e) bool
    """
    if BACKEND == "numpy":
        th = chain_headings(ctx, i, k_first, positions, targets, prev_heading, prev_assigned)
        W, counted = chain_information(ctx, i, k_first, positions, th, targets)
        return th, W, counted
    th, W, weight = chain_looks_nb(
        _c(positions), _c(targets, np.int64),
        k_first, ctx.e, float(prev_heading), bool(prev_assigned),
        float(ctx.problem.headings[i]), float(ctx.max_turn[i]), ctx.aim, ctx.xbar_xy, ctx.Cbar,
        ctx.probabilistic, ctx.radar[i], all_headings, ctx.buildings)
    return th, W, weight > 0


def chain_information(ctx: Context, i: int, k0: int, positions: FloatArray,
                      headings: FloatArray, targets: IntArray) -> tuple[FloatArray, BoolArray]:
    """Information of sensor ``i``'s looks in epochs ``k0 .. k0 + L - 1``, in one batch.

    Parameters
    ----------
    positions : (B, L, 2)
    headings : (B, L)
    targets : (B, L) int

    Returns
    -------
    W : (B, L, e, 2, 2)    zero where a look does not count
    counted : (B, L, e) bool
    """
    L = targets.shape[1]
    steps = (k0 - 1) * ctx.e + 1 + np.arange(L * ctx.e).reshape(L, ctx.e)   # (L, e)
    tj = targets[:, :, None]
    tpos = ctx.xbar[tj, steps, :2]                                        # (B, L, e, 2)
    dx = tpos[..., 0] - positions[:, :, None, 0]
    dy = tpos[..., 1] - positions[:, :, None, 1]
    th = np.broadcast_to(headings[:, :, None], dx.shape)
    C = ctx.Cbar[tj, steps]                                               # (B, L, e, 3)
    W, weight = look_information(ctx, i, dx, dy, th, C, positions[:, :, None, :])
    return W, weight > 0


def look_information(ctx: Context, i: int, dx: FloatArray, dy: FloatArray, th: FloatArray,
                     C: FloatArray, sensor_xy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Information of looks by sensor ``i`` at ground offsets ``dx, dy`` with heading ``th``.

    Parameters
    ----------
    dx, dy, th : (...)
    C : (..., 3)          predicted position covariance entries (c00, c01, c11) of the target
    sensor_xy : (..., 2)  the sensor's ground position (buildings may hide the target)

    Returns
    -------
    W : (..., 2, 2)   ``w H'^T R^{-1} H'`` (:func:`sensorplan.models.radar.look`)
    weight : (...)    w: p_vis (``probabilistic``, 0 below 1e-6) or 0/1 (``mean``)
    """
    return radar.look_information(ctx.radar[i], dx, dy, th, C, ctx.probabilistic,
                                  ctx.buildings, sensor_xy)


#: W is inverted (Joseph form) only when det W > this * trace(W)^2, i.e. its condition number
#: is below ~4e12; nearly singular information (one-dimensional) uses the subtractive form.
JOSEPH_MIN_DET = 1e-12


def information_update(P: FloatArray, W: FloatArray) -> tuple[FloatArray, FloatArray]:
    r"""Covariance after adding position information ``W``, and ``log det(I + W C)``.

    The result is :math:`(P^{-1} + G^T W G)^{-1}`, :math:`G = [I_2\ 0]`, computed without
    inverting ``P``. For ``W`` positive definite it is the Kalman update with the equivalent
    noise :math:`R = W^{-1}` in Joseph form,

    .. math::
        K = P G^T (C + R)^{-1},\quad P^+ = (I - K G) P (I - K G)^T + K R K^T,\quad C = G P G^T,

    a sum of PSD terms that stays accurate when ``W C`` is large (the subtractive form
    :math:`P - P G^T (I + W C)^{-1} W G P`, used for a singular ``W``, loses digits there).
    ``W = 0`` leaves ``P`` unchanged. By the determinant lemma
    :math:`\log\det P^+ = \log\det P - \log\det(I + W C)`.

    Parameters
    ----------
    P : (..., 4, 4)
    W : (..., 2, 2) symmetric positive semidefinite

    Returns
    -------
    P_post : (..., 4, 4)
    logdet_gain : (...,)
    """
    C = P[..., :2, :2]
    A = np.eye(2) + W @ C
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    # Subtractive form (any W): S = A^{-1} W via the 2x2 adjugate; det(A) >= 1.
    adj = np.empty_like(A)
    adj[..., 0, 0] = A[..., 1, 1]
    adj[..., 1, 1] = A[..., 0, 0]
    adj[..., 0, 1] = -A[..., 0, 1]
    adj[..., 1, 0] = -A[..., 1, 0]
    S = (adj @ W) / det[..., None, None]
    S = 0.5 * (S + np.swapaxes(S, -1, -2))
    Pc = P[..., :, :2]                                                     # (..., 4, 2)
    Pn = P - Pc @ S @ np.swapaxes(Pc, -1, -2)
    # Joseph form where W is invertible.
    det_w = W[..., 0, 0] * W[..., 1, 1] - W[..., 0, 1] * W[..., 1, 0]
    ok = det_w > JOSEPH_MIN_DET * (W[..., 0, 0] + W[..., 1, 1]) ** 2
    if np.any(ok):
        safe = np.where(ok, det_w, 1.0)[..., None, None]
        R = np.stack([np.stack([W[..., 1, 1], -W[..., 0, 1]], -1),
                      np.stack([-W[..., 1, 0], W[..., 0, 0]], -1)], -2) / safe
        K = np.swapaxes(np.linalg.solve(C + R, np.swapaxes(Pc, -1, -2)), -1, -2)
        IKG = np.broadcast_to(np.eye(4), P.shape).copy()
        IKG[..., :, :2] -= K
        Pj = IKG @ P @ np.swapaxes(IKG, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
        Pn = np.where(ok[..., None, None], Pj, Pn)
    return 0.5 * (Pn + np.swapaxes(Pn, -1, -2)), np.log(det)


def covariance_recursion(P: FloatArray, W: FloatArray, F: FloatArray, Q: FloatArray,
                         need_sum: bool = True) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Run predict + information update over ``n`` steps, batched (compiled kernel).

    Parameters
    ----------
    P : (B, 4, 4)    covariance at the step before the first of the n steps
    W : (B, n, 2, 2) position information at each step
    F : (4, 4)
    Q : (4, 4), (1, 4, 4) or (B, 4, 4)   process noise, shared or one per row
    need_sum : bool  compute ``logdet_sum`` (the ``cumulative`` objective needs it)

    Returns
    -------
    P_end : (B, 4, 4)
    logdet_end : (B,)       log det of the covariance after the last step
    logdet_sum : (B,)       sum of log det over the n updated covariances (0 if not needed)
    """
    Q = np.asarray(Q, dtype=float)
    if Q.ndim == 2:
        Q = Q[None]
    if BACKEND == "numpy":
        return covariance_recursion_numpy(P, W, F, Q)
    cv, dt = cv_form(F)
    return covariance_recursion_nb(_c(P), _c(W), F, _c(Q), need_sum, cv, dt)


#: Whether a transition matrix (by its bytes) is the CWNA ``F(dt)``, and its ``dt``.
_CV_FORM: dict[bytes, tuple[bool, float]] = {}


def cv_form(F: FloatArray) -> tuple[bool, float]:
    """Whether ``F`` is the CWNA transition ``F(dt)`` (the kernels then predict in closed
    form), and its ``dt``."""
    key = F.tobytes()
    if key not in _CV_FORM:
        dt = float(F[0, 2])
        _CV_FORM[key] = (bool(np.array_equal(F, cv_matrices(dt, 0.0)[0])), dt)
    return _CV_FORM[key]


def covariance_recursion_numpy(P: FloatArray, W: FloatArray, F: FloatArray,
                               Q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pure-numpy reference of :func:`covariance_recursion` (tests, benchmarks)."""
    total = np.zeros(P.shape[0])
    for t in range(W.shape[1]):
        P = predict_covariance(P, F, Q)
        P, _ = information_update(P, W[:, t])
        total += np.linalg.slogdet(P)[1]
    return P, np.linalg.slogdet(P)[1], total


@dataclass(frozen=True)
class PlanEvaluation:
    """Phi of a plan with its parts.

    Attributes
    ----------
    potential : float          Phi (nats)
    information : (M,)         per-target terms of Phi
    headings : (N, K)          planned headings (NaN where unassigned)
    measurements : (N, K) int  looks that count in Phi, per player
    """

    potential: float
    information: FloatArray
    headings: FloatArray
    measurements: IntArray


def plan_information(ctx: Context, plan: Plan) -> tuple[FloatArray, FloatArray, IntArray]:
    """Every player's information contributions.

    Returns
    -------
    W : (N, K, e, 2, 2)   information of each player's looks (zero if unassigned)
    headings : (N, K)     NaN where unassigned
    counts : (N, K)       looks that count
    """
    N, K, e = ctx.N, ctx.K, ctx.e
    W = np.zeros((N, K, e, 2, 2))
    headings = np.full((N, K), np.nan)
    counts = np.zeros((N, K), dtype=np.int64)
    for i in range(N):
        for k0, k1 in assigned_runs(plan.targets[i] >= 0):
            pos = plan.positions[i, k0:k1][None]
            tgt = plan.targets[i, k0:k1][None]
            prev_ok = k0 == 0
            th, w, c = chain_looks(ctx, i, k0 + 1, pos, tgt, ctx.problem.headings[i], prev_ok)
            headings[i, k0:k1] = th[0]
            W[i, k0:k1] = w[0]
            counts[i, k0:k1] = c[0].sum(axis=-1)
    return W, headings, counts


def assigned_runs(assigned: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs ``[k0, k1)`` (0-based) of consecutive assigned epochs."""
    runs, k, K = [], 0, len(assigned)
    while k < K:
        if assigned[k]:
            k1 = k
            while k1 < K and assigned[k1]:
                k1 += 1
            runs.append((k, k1))
            k = k1
        else:
            k += 1
    return runs


def phi_terms(ld_bar: FloatArray, ld_end: FloatArray, ld_sum: FloatArray, cumulative: bool,
              measured: BoolArray, existence: FloatArray | float = 1.0) -> FloatArray:
    r"""Per-target terms of Phi from the log-dets of the measured covariance recursion.

    .. math::
        r_j \big(\tfrac12 \log\det \bar P_j(T) - \tfrac12 \log\det P_j(T \mid Z_j)\big)
        \quad\text{or}\quad
        r_j \sum_{t=1}^{T} \big(\tfrac12 \log\det \bar P_j(t)
                                - \tfrac12 \log\det P_j(t \mid Z_j)\big)

    (``terminal`` or ``cumulative``), ``r_j`` the target's probability of existence. The rule
    for round-off: an unmeasured target's term is exactly 0 (its two log-dets differ by
    round-off only), and a measured target's term is at least 0 (a measurement never
    increases the log-det; a term below 0 is round-off, about eps times the covariance's
    condition number, up to 1e12 in inputs). Every numpy evaluation of Phi goes through here,
    and this is its one weighting by ``r`` (the compiled engine's is in
    :func:`~sensorplan.planners._gains_nb._deltas`); the compiled engine's utilities are
    differences of the same terms before the round-off rule (it moves them by round-off
    only). With ``r = 1`` the product changes no bit.

    Parameters
    ----------
    ld_bar : (..., T + 1)   log det of ``Pbar_j(t)``, t = 0..T (``Context.ld_bar``)
    ld_end : (...,)         log det of ``P_j(T | Z_j)``
    ld_sum : (...,)         sum over t = 1..T of log det ``P_j(t | Z_j)`` (``cumulative``)
    cumulative : bool       the objective
    measured : (...,) bool  whether any of the target's looks counts (:func:`measured`)
    existence : (...,) or float, default 1
        the targets' probabilities of existence r, in [0, 1] (``Context.existence``)

    Returns
    -------
    (...,) float64   nats, >= 0
    """
    if cumulative:
        info = 0.5 * (ld_bar[..., 1:].sum(axis=-1) - ld_sum)
    else:
        info = 0.5 * (ld_bar[..., -1] - ld_end)
    return existence * np.where(measured, np.maximum(info, 0.0), 0.0)


def measured(W_target: FloatArray) -> BoolArray:
    """Whether each target has information, from its summed ``W_target (..., T, 2, 2)``."""
    return np.any(W_target != 0.0, axis=(-3, -2, -1))


def target_information(ctx: Context, W_target: FloatArray) -> FloatArray:
    """Per-target terms of Phi from the summed information ``W_target (M, T, 2, 2)``."""
    P0 = np.asarray(ctx.problem.covs)
    cumulative = ctx.problem.objective == "cumulative"
    _, ld_end, ld_sum = covariance_recursion(P0, W_target, ctx.F, ctx.Q, cumulative)
    return phi_terms(ctx.ld_bar, ld_end, ld_sum, cumulative, measured(W_target), ctx.existence)


def sum_by_target(ctx: Context, W: FloatArray, targets: IntArray) -> FloatArray:
    """Scatter player contributions ``W (N, K, e, 2, 2)`` into ``(M, T, 2, 2)`` by target."""
    if BACKEND == "numpy":
        out = np.zeros((ctx.M, ctx.T, 2, 2))
        n, k = np.nonzero(targets >= 0)
        for s in range(ctx.e):
            np.add.at(out, (targets[n, k], k * ctx.e + s), W[n, k, s])
        return out
    return sum_by_target_nb(_c(W), _c(targets, np.int64), ctx.M)


def evaluate(ctx: Context, plan: Plan) -> PlanEvaluation:
    """Phi, its per-target terms, headings and counted looks of ``plan``."""
    W, headings, counts = plan_information(ctx, plan)
    info = target_information(ctx, sum_by_target(ctx, W, plan.targets))
    return PlanEvaluation(float(info.sum()), info, headings, counts)


def potential(problem: PlanningProblem, plan: Plan) -> tuple[float, FloatArray]:
    r"""The potential Phi of a plan, in nats: the definition planners are held to.

    .. math::
        \Phi(a) = \sum_j r_j \big(\tfrac12 \log\det \bar P_j(T)
                   - \tfrac12 \log\det P_j(T \mid Z_j(a))\big)

    (``terminal``), or the same summed over t = 1..T (``cumulative``); ``r_j`` is the
    target's probability of existence (``problem.existence``, 1 by default). Unassigned
    players make no measurement.

    Returns
    -------
    phi : float
    information : (M,) per-target terms, summing to phi
    """
    ev = evaluate(prepare(problem), plan)
    return ev.potential, ev.information
