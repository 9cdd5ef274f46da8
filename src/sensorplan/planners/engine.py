r"""Fast, exact evaluation of Phi for a batch of changes to one sensor's actions.

The planners change one sensor's actions at a time: one player (i, k) in the game, two
consecutive epochs in ``pg-refine``'s local search. :meth:`GameState.evaluate_chains` returns
Phi for a whole batch of such changes in one vectorised pass and reuses everything the change
cannot touch:

* measurements of every other player are summed once per call into ``W_fixed (M, T, 2, 2)``;
* steps before the first changed epoch are the same for every candidate, so each target's
  covariance recursion up to step ``s0 = (k0 - 1) e`` is run once (the prefix);
* a candidate only changes the targets its own chain looks at (its epochs k0.. and, through
  the heading rule, the following assigned epochs of the same sensor); every other target
  keeps its baseline term, so only (candidate, affected target) pairs are recomputed.

Phi(c) = Phi_base + sum over affected targets j of (term_j(c) - term_j(base)), where "base"
is the plan with sensor i's changed chain removed. This is the definition of SPEC 4 regrouped,
and is tested equal to :func:`sensorplan.information.potential` to round-off.
"""

from __future__ import annotations

import numpy as np

from .._types import FloatArray, IntArray
from ..information import (Context, chain_headings, chain_information, covariance_recursion,
                           sum_by_target)
from ..problem import Plan


class GameState:
    """A (possibly partial) joint plan with its cached per-player information.

    Attributes
    ----------
    pos : (N, K) int      index of each player's position in its lattice ``R_k`` (-1 unassigned)
    tgt : (N, K) int      target of each player (-1 unassigned)
    heading : (N, K)      headings (NaN unassigned)
    W : (N, K, e, 2, 2)   information of each player's looks
    """

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.cumulative = ctx.problem.objective == "cumulative"
        N, K, e = ctx.N, ctx.K, ctx.e
        self.pos = np.full((N, K), -1, dtype=np.int64)
        self.tgt = np.full((N, K), -1, dtype=np.int64)
        self.heading = np.full((N, K), np.nan)
        self.W = np.zeros((N, K, e, 2, 2))

    # ----------------------------------------------------------------- plan access
    def copy(self) -> "GameState":
        other = GameState.__new__(GameState)
        other.ctx = self.ctx
        other.cumulative = self.cumulative
        other.pos, other.tgt = self.pos.copy(), self.tgt.copy()
        other.heading, other.W = self.heading.copy(), self.W.copy()
        return other

    def xy(self, i: int, k: int, idx: IntArray | int) -> FloatArray:
        """Ground position(s) of lattice index ``idx`` in ``R_k`` (k 1-based) of sensor i."""
        return self.ctx.lattices[i].positions[k][idx]

    def to_plan(self) -> Plan:
        N, K = self.ctx.N, self.ctx.K
        positions = np.full((N, K, 2), np.nan)
        for i in range(N):
            for k in range(1, K + 1):
                if self.pos[i, k - 1] >= 0:
                    positions[i, k - 1] = self.xy(i, k, self.pos[i, k - 1])
        return Plan(positions, self.tgt.copy())

    @classmethod
    def from_plan(cls, ctx: Context, plan: Plan) -> "GameState":
        state = cls(ctx)
        for i in range(ctx.N):
            for k in range(1, ctx.K + 1):
                if plan.targets[i, k - 1] >= 0:
                    idx = ctx.lattices[i].index_of(k, plan.positions[i, k - 1])
                    if idx < 0:
                        raise ValueError(f"plan position of sensor {i} epoch {k} not reachable")
                    state.pos[i, k - 1] = idx
                    state.tgt[i, k - 1] = plan.targets[i, k - 1]
            state.refresh(i)
        return state

    def assigned(self, i: int, k: int) -> bool:
        """Whether player (i, k) has an action; epoch 0 (the start pose) always counts."""
        return k == 0 or (1 <= k <= self.ctx.K and self.tgt[i, k - 1] >= 0)

    # ----------------------------------------------------------------- updates
    def set_action(self, i: int, k: int, pos_idx: int, target: int) -> None:
        """Give player (i, k) an action and refresh sensor i's headings and information."""
        self.pos[i, k - 1] = pos_idx
        self.tgt[i, k - 1] = target
        self.refresh(i)

    def set_chain(self, i: int, k0: int, pos_idx: IntArray, targets: IntArray) -> None:
        """Replace sensor i's actions in epochs ``k0 .. k0 + L - 1``."""
        L = len(pos_idx)
        self.pos[i, k0 - 1:k0 - 1 + L] = pos_idx
        self.tgt[i, k0 - 1:k0 - 1 + L] = targets
        self.refresh(i)

    def refresh(self, i: int) -> None:
        """Recompute sensor i's headings and look information from its actions."""
        ctx = self.ctx
        self.heading[i] = np.nan
        self.W[i] = 0.0
        k = 1
        while k <= ctx.K:
            if self.tgt[i, k - 1] < 0:
                k += 1
                continue
            k_end = self._run_end(i, k)
            ks = np.arange(k, k_end + 1)
            pos = np.stack([self.xy(i, kk, self.pos[i, kk - 1]) for kk in ks])[None]
            tgt = self.tgt[i, k - 1:k_end][None]
            prev_ok = k == 1
            th = chain_headings(ctx, i, k, pos, tgt, ctx.problem.headings[i], prev_ok)
            self.heading[i, k - 1:k_end] = th[0]
            self.W[i, k - 1:k_end] = chain_information(ctx, i, k, pos, th, tgt)[0][0]
            k = k_end + 1

    def _run_end(self, i: int, k: int) -> int:
        """Last epoch of the run of consecutive assigned epochs of sensor i from k on."""
        k_end = k
        while k_end < self.ctx.K and self.tgt[i, k_end] >= 0:
            k_end += 1
        return k_end

    # ----------------------------------------------------------------- evaluation
    def potential(self) -> float:
        """Phi of the current (partial) plan."""
        ctx = self.ctx
        W_t = sum_by_target(ctx, self.W, self.tgt)
        _, ld_end, ld_sum = covariance_recursion(np.asarray(ctx.problem.covs), W_t, ctx.F, ctx.Q,
                                                 self.cumulative)
        return float(self._phi_terms(ld_end, ld_sum).sum())

    def _phi_terms(self, ld_end: FloatArray, ld_sum: FloatArray) -> FloatArray:
        ctx = self.ctx
        if ctx.problem.objective == "cumulative":
            return 0.5 * (ctx.ld_bar[:, 1:].sum(axis=1) - ld_sum)
        return 0.5 * (ctx.ld_bar[:, -1] - ld_end)

    def evaluate_chains(self, i: int, k0: int, cand_pos: IntArray,
                        cand_tgt: IntArray) -> FloatArray:
        """Phi if sensor i's epochs ``k0 .. k0 + L - 1`` took each candidate chain.

        Parameters
        ----------
        i : int
        k0 : int                      first changed epoch (1-based)
        cand_pos : (C, L) int         lattice indices in ``R_{k0}``, ``R_{k0+1}``, ...
        cand_tgt : (C, L) int         targets

        Returns
        -------
        (C,) Phi of each candidate joint plan (every other action as in the state).
        """
        ctx = self.ctx
        C, L = cand_tgt.shape
        e, T, M = ctx.e, ctx.T, ctx.M
        # The chain continues through the following assigned epochs: their headings change.
        k_last = k0 + L - 1
        k_end = self._run_end(i, k_last + 1) if self.assigned(i, k_last + 1) and k_last < ctx.K \
            else k_last
        tail = np.arange(k_last + 1, k_end + 1)
        Lf = L + len(tail)
        pos_xy = np.empty((C, Lf, 2))
        tgt = np.empty((C, Lf), dtype=np.int64)
        for l in range(L):
            pos_xy[:, l] = self.xy(i, k0 + l, cand_pos[:, l])
        tgt[:, :L] = cand_tgt
        for l, kk in enumerate(tail, start=L):
            pos_xy[:, l] = self.xy(i, kk, self.pos[i, kk - 1])
            tgt[:, l] = self.tgt[i, kk - 1]
        prev_ok = self.assigned(i, k0 - 1)
        prev = self.heading[i, k0 - 2] if k0 > 1 and prev_ok else ctx.problem.headings[i]
        th = chain_headings(ctx, i, k0, pos_xy, tgt, prev, prev_ok)
        W_chain = chain_information(ctx, i, k0, pos_xy, th, tgt)[0]        # (C, Lf, e, 2, 2)

        # Everything but the changed chain.
        mask_tgt = self.tgt.copy()
        mask_tgt[i, k0 - 1:k_end] = -1
        W_fixed = sum_by_target(ctx, self.W, mask_tgt)                    # (M, T, 2, 2)
        s0 = (k0 - 1) * e
        covs = np.asarray(ctx.problem.covs)
        cum = self.cumulative
        P_pre, _, ld_pre = covariance_recursion(covs, W_fixed[:, :s0], ctx.F, ctx.Q, cum)
        _, ld_end_b, ld_sum_b = covariance_recursion(P_pre, W_fixed[:, s0:], ctx.F, ctx.Q, cum)
        phi_base = float(self._phi_terms(ld_end_b, ld_pre + ld_sum_b).sum())

        # (candidate, target) pairs the chain looks at.
        looks = np.zeros((C, M), dtype=bool)
        np.put_along_axis(looks, tgt, True, axis=1)
        c_pair, j_pair = np.nonzero(looks)
        W_pair = W_fixed[j_pair, s0:].copy()                              # (n, T - s0, 2, 2)
        for l in range(Lf):
            hit = (tgt[c_pair, l] == j_pair)[:, None, None, None]
            W_pair[:, l * e:(l + 1) * e] += np.where(hit, W_chain[c_pair, l], 0.0)
        _, ld_end, ld_sum = covariance_recursion(P_pre[j_pair], W_pair, ctx.F, ctx.Q, cum)
        if ctx.problem.objective == "cumulative":
            delta = 0.5 * (ld_sum_b[j_pair] - ld_sum)
        else:
            delta = 0.5 * (ld_end_b[j_pair] - ld_end)
        return phi_base + np.bincount(c_pair, weights=delta, minlength=C)

    # ----------------------------------------------------------------- player actions
    def player_actions(self, i: int, k: int) -> tuple[IntArray, IntArray]:
        """Feasible actions of player (i, k) in tie-break order (SPEC 4).

        Positions lie in ``R_k``, one move from ``p_{k-1}`` when (i, k-1) is assigned (or
        k = 1) and one move before ``p_{k+1}`` when (i, k+1) is assigned. Order: Euclidean
        distance from the reference position (``p_{k-1}`` when assigned, else ``p_0``), then
        the move order (the breadth-first order of ``R_k`` when the reference is ``p_0`` and
        k > 1), then the target index.

        Returns
        -------
        pos : (P * M,) int lattice indices in R_k;  tgt : (P * M,) int
        """
        lat = self.ctx.lattices[i]
        if self.assigned(i, k - 1):
            q = 0 if k == 1 else self.pos[i, k - 2]
            row = lat.child[k][q]
            cand = row[row >= 0]                         # already in move order
            ref = lat.positions[k - 1][q]
        else:
            cand = np.arange(len(lat.positions[k]))
            ref = lat.positions[0][0]
        if k < self.ctx.K and self.assigned(i, k + 1):
            parents = lat.parent_move[k + 1][self.pos[i, k]]
            cand = cand[np.isin(cand, parents[parents >= 0])]
        dist = np.rint(np.linalg.norm(lat.positions[k][cand] - ref, axis=1) * 1e6)
        cand = cand[np.argsort(dist, kind="stable")]
        M = self.ctx.M
        return np.repeat(cand, M), np.tile(np.arange(M), len(cand))


def choose(values: FloatArray, current: int = -1) -> int:
    """Index of the best value under SPEC 4's tie rule.

    Values within ``1e-9 max(1, |max|)`` of the maximum tie; the current action wins a tie,
    then the earliest index (callers order actions by distance, move, target).
    """
    vmax = float(values.max())
    near = values >= vmax - 1e-9 * max(1.0, abs(vmax))
    if current >= 0 and near[current]:
        return current
    return int(np.argmax(near))
