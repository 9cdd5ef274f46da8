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

from dataclasses import dataclass

import numpy as np

from .._types import FloatArray, IntArray
from ..information import Context, chain_looks, covariance_recursion, sum_by_target
from ..problem import TIE_TOL, Plan


@dataclass
class _ChainCache:
    """What :meth:`GameState.chain_gains` keeps between calls for one player."""

    key: tuple
    c_pair: IntArray
    j_pair: IntArray
    W_add: FloatArray
    W_rows: FloatArray         # the other players' looks each delta was computed with
    delta: FloatArray


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
        self._cache: dict = {}
        self._actions: dict = {}

    # ----------------------------------------------------------------- plan access
    def copy(self) -> "GameState":
        other = GameState.__new__(GameState)
        other.ctx = self.ctx
        other.cumulative = self.cumulative
        other.pos, other.tgt = self.pos.copy(), self.tgt.copy()
        other.heading, other.W = self.heading.copy(), self.W.copy()
        other._cache = {}
        other._actions = self._actions          # depends only on the lattices: share it
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
            th, W, _ = chain_looks(ctx, i, k, pos, tgt, ctx.problem.headings[i], k == 1)
            self.heading[i, k - 1:k_end] = th[0]
            self.W[i, k - 1:k_end] = W[0]
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
        gains, base = self.chain_gains(i, k0, cand_pos, cand_tgt, with_base=True)
        return base + gains

    def chain_gains(self, i: int, k0: int, cand_pos: IntArray, cand_tgt: IntArray,
                    with_base: bool = False) -> tuple[FloatArray, float]:
        """Marginal contribution of each candidate chain: Phi(chain) - Phi(no chain).

        "No chain" leaves sensor i's epochs ``k0 ..`` up to the end of the assigned run that
        follows unassigned. The gain differs from Phi by a term that does not depend on the
        candidate, so it is a valid utility for every player whose action the chain holds
        (SPEC 4) and the game's decisions are the same with either.

        Returns
        -------
        gains : (C,)
        base : float    Phi(no chain) if ``with_base``, else NaN
        """
        ctx = self.ctx
        C, L = cand_tgt.shape
        # The chain continues through the following assigned epochs: their headings change.
        k_last = k0 + L - 1
        k_end = self._run_end(i, k_last + 1) if self.assigned(i, k_last + 1) and k_last < ctx.K \
            else k_last
        prev_ok = self.assigned(i, k0 - 1)
        prev = self.heading[i, k0 - 2] if k0 > 1 and prev_ok else ctx.problem.headings[i]

        mask_tgt = self.tgt.copy()
        mask_tgt[i, k0 - 1:k_end] = -1
        W_fixed = sum_by_target(ctx, self.W, mask_tgt)                    # (M, T, 2, 2)
        s0 = (k0 - 1) * ctx.e
        # The chain's own looks depend only on the chain; a (candidate, target) term depends
        # on them and on the other players' looks at that target. Both are cached, so a call
        # recomputes only the terms of targets whose other looks changed since the last call
        # for this player (in JSFP: the targets the neighbours switched to or from).
        key = (k0, L, prev_ok, float(prev), cand_pos.tobytes(), cand_tgt.tobytes(),
               self.pos[i, k_last:k_end].tobytes(), self.tgt[i, k_last:k_end].tobytes())
        entry = self._cache.get((i, k0, L))
        if entry is None or entry.key != key:
            c_pair, j_pair, W_add = self._chain_looks(i, k0, cand_pos, cand_tgt, k_end, prev,
                                                      prev_ok)
            entry = _ChainCache(key, c_pair, j_pair, W_add, np.full_like(W_fixed, np.nan),
                                np.zeros(len(c_pair)))
            self._cache[(i, k0, L)] = entry
        stale = np.any(entry.W_rows != W_fixed, axis=(1, 2, 3))           # (M,) NaN != all
        base = np.nan
        redo = np.flatnonzero(stale)
        if with_base:
            redo = np.arange(ctx.M)
        if redo.size:
            covs = np.asarray(ctx.problem.covs)[redo]
            cum = self.cumulative
            Q = ctx.Q_rows(redo)
            P_pre, _, ld_pre = covariance_recursion(covs, W_fixed[redo, :s0], ctx.F, Q, cum)
            _, ld_end_b, ld_sum_b = covariance_recursion(P_pre, W_fixed[redo, s0:], ctx.F, Q,
                                                         cum)
            if with_base:
                base = float(self._phi_terms(ld_end_b, ld_pre + ld_sum_b).sum())
            where = np.full(ctx.M, -1)
            where[redo] = np.arange(redo.size)
            sel = np.flatnonzero(stale[entry.j_pair])
            if sel.size:
                r = where[entry.j_pair[sel]]
                W_pair = W_fixed[entry.j_pair[sel], s0:] + entry.W_add[sel]
                _, ld_end, ld_sum = covariance_recursion(P_pre[r], W_pair, ctx.F,
                                                         ctx.Q_rows(entry.j_pair[sel]), cum)
                if cum:
                    entry.delta[sel] = 0.5 * (ld_sum_b[r] - ld_sum)
                else:
                    entry.delta[sel] = 0.5 * (ld_end_b[r] - ld_end)
            entry.W_rows[stale] = W_fixed[stale]
        return np.bincount(entry.c_pair, weights=entry.delta, minlength=C), base

    def contributing(self, i: int, k0: int, L: int = 1) -> IntArray:
        """Candidates of the last :meth:`chain_gains` call for (i, k0, L) with a look that counts.

        The others have gain exactly 0 against any other players' actions.
        """
        c = self._cache[(i, k0, L)].c_pair                # sorted by candidate
        return c[np.r_[True, c[1:] != c[:-1]]] if c.size else c

    def restrict(self, i: int, k0: int, keep: IntArray, cand_pos: IntArray,
                 cand_tgt: IntArray) -> None:
        """Carry the cache of player (i, k0) over to the candidate subset ``keep``.

        ``cand_pos, cand_tgt`` are the kept candidates, ``(len(keep), 1)``; the next
        :meth:`chain_gains` call with them then reuses the looks already computed.
        """
        entry = self._cache[(i, k0, 1)]
        remap = np.full(int(keep.max()) + 1 if keep.size else 0, -1, dtype=np.int64)
        remap[keep] = np.arange(keep.size)
        inside = entry.c_pair < remap.size
        inside[inside] = remap[entry.c_pair[inside]] >= 0
        entry.key = entry.key[:4] + (cand_pos.tobytes(), cand_tgt.tobytes()) + entry.key[6:]
        entry.c_pair = remap[entry.c_pair[inside]]
        entry.j_pair = entry.j_pair[inside]
        entry.W_add = entry.W_add[inside]
        entry.delta = entry.delta[inside]

    def _chain_looks(self, i: int, k0: int, cand_pos: IntArray, cand_tgt: IntArray,
                     k_end: int, prev: float,
                     prev_ok: bool) -> tuple[IntArray, IntArray, FloatArray]:
        """The information every candidate chain adds to each target it looks at.

        Returns
        -------
        c_pair, j_pair : (n,) int   every (candidate, target) pair with a look that counts
        W_add : (n, T - s0, 2, 2)   that pair's information from step ``s0 + 1`` on
        """
        ctx = self.ctx
        C, L = cand_tgt.shape
        e, M = ctx.e, ctx.M
        Lf = k_end - k0 + 1
        pos_xy = np.empty((C, Lf, 2))
        tgt = np.empty((C, Lf), dtype=np.int64)
        for l in range(L):
            pos_xy[:, l] = self.xy(i, k0 + l, cand_pos[:, l])
        tgt[:, :L] = cand_tgt
        for l in range(L, Lf):
            kk = k0 + l
            pos_xy[:, l] = self.xy(i, kk, self.pos[i, kk - 1])
            tgt[:, l] = self.tgt[i, kk - 1]
        _, W_chain, counted = chain_looks(ctx, i, k0, pos_xy, tgt, prev, prev_ok,
                                          all_headings=False)            # (C, Lf, e, 2, 2)
        # A look that does not count adds nothing: its target keeps its baseline term.
        counts = counted.any(axis=2)                                      # (C, Lf)
        c_idx, l_idx = np.nonzero(counts)
        if Lf == 1:                     # one look per candidate: pairs are already unique
            c_pair, j_pair = c_idx, tgt[c_idx, 0]
        else:
            c_pair, j_pair = np.divmod(np.unique(c_idx * M + tgt[c_idx, l_idx]), M)
        W_add = np.zeros((len(c_pair), ctx.T - (k0 - 1) * e, 2, 2))
        for l in range(Lf):
            hit = (tgt[c_pair, l] == j_pair)[:, None, None, None]
            W_add[:, l * e:(l + 1) * e] = np.where(hit, W_chain[c_pair, l], 0.0)
        return c_pair, j_pair, W_add

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
        pred = (0 if k == 1 else int(self.pos[i, k - 2])) if self.assigned(i, k - 1) else -1
        succ = int(self.pos[i, k]) if k < self.ctx.K and self.assigned(i, k + 1) else -1
        key = (i, k, pred, succ)
        if key not in self._actions:
            self._actions[key] = self._player_actions(i, k)
        return self._actions[key]

    def _player_actions(self, i: int, k: int) -> tuple[IntArray, IntArray]:
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


def choose(values: FloatArray, current: int = -1, scale: float | None = None) -> int:
    """Index of the best value under SPEC 4's tie rule.

    Values within ``1e-9 max(1, scale)`` of the maximum tie (``scale`` = |Phi|, by default
    the largest value); the current action wins a tie, then the earliest index (callers
    order actions by distance, move, target).
    """
    vmax = float(values.max())
    scale = abs(vmax) if scale is None else scale
    near = values >= vmax - TIE_TOL * max(1.0, scale)
    if current >= 0 and near[current]:
        return current
    return int(np.argmax(near))
