r"""Fast, exact evaluation of Phi for a batch of changes to one sensor's actions.

The planners change one sensor's actions at a time: one player (i, k) in the game, two
consecutive epochs in ``pg-refine``'s local search. :meth:`GameState.chain_gains` returns,
for a whole batch of such changes, each one's gain ``Phi(chain) - Phi(no chain)``, and
:class:`~sensorplan.planners.epoch_game.EpochGame` the utilities of every player of an epoch
game at once. Both reuse everything a change cannot touch:

* a candidate only changes the targets its own chain looks at (its epochs k0.. and, through
  the heading rule, the following assigned epochs of the same sensor); every other target
  keeps its baseline term, so only (candidate, affected target) *pairs* are evaluated, and a
  pair's term is kept until the other players' information at its target changes;
* steps before a pair's first look are the baseline's, so its recursion starts there;
* the other players' information, the baselines and the prefix up to the game's epoch are
  shared between candidates and players wherever they are the same numbers.

Phi(c) = Phi_base + sum over affected targets j of (term_j(c) - term_j(base)), where "base"
is the plan with sensor i's changed chain removed; a target's term carries its weight, the
probability of existence ``r_j`` (applied once, to each pair's term change). This is the
definition of Phi regrouped; the compiled kernels (:mod:`~sensorplan.planners._pairs_nb`,
:mod:`~sensorplan.planners._gains_nb`) compute every term with the same operations in the
same order as the plain dense computation, so utilities are bit for bit its values
(``tests/engine_reference.py``), and equal :func:`sensorplan.planners.information.potential`'s
differences to round-off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._compiled.threads import n_threads
from .._types import BoolArray, FloatArray, IntArray
from ._gains_nb import gains_nb
from ._pairs_nb import candidate_sets_nb, chain_pairs_nb, game_chains_nb, player_positions_nb
from .information import (Context, _c, chain_looks, covariance_recursion, cv_form, measured,
                          phi_terms, sum_by_target)
from .problem import TIE_TOL, Plan


#: Makes candidate chains followed by a sensor's fixed later epochs (see GameState._pairs_job).
Chains = Callable[[FloatArray, IntArray], tuple[FloatArray, IntArray]]


@dataclass
class Pairs:
    """One player's candidate chains, as the (candidate, target) pairs whose looks count.

    ``data`` holds each pair's information (w00, w01, w11) from its first non-zero step on
    (:func:`~sensorplan.planners._pairs_nb.chain_pairs_nb`); ``delta`` its cached term change
    and ``rows`` the other players' information it was computed with (NaN: never).
    """

    key: tuple
    n_cand: int
    lo: int                    # sensor i's removed epochs, 0-based [lo, hi)
    hi: int
    c_pair: IntArray
    j_pair: IntArray
    first: IntArray
    count: IntArray
    offset: IntArray
    data: FloatArray
    delta: FloatArray
    rows: FloatArray           # (M, T, 3)
    contrib: IntArray          # candidates with a look that counts (sorted)
    free: int                  # the first candidate without one (-1 if none)
    owners: IntArray           # candidates that hold pairs (sorted)
    dups: IntArray             # candidates whose pairs equal an earlier one's (left out) ...
    dup_of: IntArray           # ... and that earlier candidate: the same utility, always
    view: tuple | None = None  # an epoch game's (current action, kept actions, c_loc, ...)
    # An epoch game's entry: the player's action token and positions, and the sensor's
    # change count when the key last held (while it is unchanged, so is the key).
    token: tuple | None = None
    cand: IntArray | None = None
    changes: int = -1


@dataclass
class PairsJob:
    """A cache miss of :meth:`GameState._cached_pairs`: what the entry needs besides the
    kernels' results, and ``make()``, the kernels' arguments (made when the job runs, so that
    a batch holds only its running jobs' inputs).
    """

    i: int
    k0: int
    L: int
    key: tuple
    k_end: int
    make: Callable[[], tuple]
    size: int = 0              # candidates times epochs of the chains, when known


def pair_kernels(job: PairsJob) -> tuple:
    """:func:`chain_pairs_nb` then :func:`candidate_sets_nb` on its pairs (one thread's job:
    both release the GIL); what the cache entry keeps of them, with the number of candidates.
    """
    c_pair, j_pair, first, count, offset, data, rep = chain_pairs_nb(*job.make())
    owners, dups, contrib, free = candidate_sets_nb(c_pair, rep)
    return (c_pair, j_pair, first, count, offset, data, owners, dups, contrib, free, rep[dups],
            len(rep))


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
        self._phi: tuple[int, float] | None = None
        self.version = 0                    # bumped by every change of an action
        self.changes = [0] * N              # ... and per sensor
        self._covs = _c(np.array(ctx.problem.covs))        # writable copies for the kernels
        self._Q = _c(np.array(ctx.Q))
        self._rows_buf: dict[int, FloatArray] = {}
        self.threads = n_threads()          # for the independent kernels of an epoch game

    # ----------------------------------------------------------------- plan access
    def copy(self) -> GameState:
        other = GameState.__new__(GameState)
        other.ctx = self.ctx
        other.cumulative = self.cumulative
        other.pos, other.tgt = self.pos.copy(), self.tgt.copy()
        other.heading, other.W = self.heading.copy(), self.W.copy()
        other._cache = {}
        other._actions = self._actions          # depends only on the lattices: share it
        other._phi = None
        other.version = 0
        other.changes = [0] * self.ctx.N
        other._covs, other._Q = self._covs, self._Q
        other._rows_buf = {}
        other.threads = self.threads
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
    def from_plan(cls, ctx: Context, plan: Plan) -> GameState:
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

    def complete(self) -> bool:
        """Whether every player has an action."""
        return bool(np.all(self.tgt >= 0))

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
        self.version += 1
        self.changes[i] += 1
        self.heading[i] = np.nan
        self.W[i] = 0.0
        k = 1
        while k <= ctx.K:
            if self.tgt[i, k - 1] < 0:
                k += 1
                continue
            k_end = self._run_end(i, k)
            ks = range(k, k_end + 1)
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
        """Phi of the current (partial) plan (cached until an action changes)."""
        if self._phi is not None and self._phi[0] == self.version:
            return self._phi[1]
        ctx = self.ctx
        W_t = sum_by_target(ctx, self.W, self.tgt)
        _, ld_end, ld_sum = covariance_recursion(np.asarray(ctx.problem.covs), W_t, ctx.F, ctx.Q,
                                                 self.cumulative)
        phi = float(phi_terms(ctx.ld_bar, ld_end, ld_sum, self.cumulative, measured(W_t),
                              ctx.existence).sum())
        self._phi = (self.version, phi)
        return phi

    def _measured_without(self, i: int, lo: int, hi: int) -> BoolArray:
        """Which targets the plan measures with sensor i's epochs ``lo .. hi - 1`` (0-based)
        left out (as :func:`~sensorplan.planners.information.measured` of their sum: looks
        are positive semidefinite, so a sum is zero only if every look is)."""
        looks = (self.tgt >= 0) & np.any(self.W != 0.0, axis=(2, 3, 4))       # (N, K)
        looks[i, lo:hi] = False
        out = np.zeros(self.ctx.M, dtype=bool)
        out[self.tgt[looks]] = True
        return out

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
                    with_base: bool = False, token: tuple | None = None
                    ) -> tuple[FloatArray, float]:
        """Marginal contribution of each candidate chain: Phi(chain) - Phi(no chain).

        "No chain" leaves sensor i's epochs ``k0 ..`` up to the end of the assigned run that
        follows unassigned. The gain differs from Phi by a term that does not depend on the
        candidate, so it is a valid utility for every player whose action the chain holds
        and the game's decisions are the same with either.

        ``token`` names the candidate set when the caller knows it (see
        :meth:`action_token`), so that the cache recognises it without comparing arrays.

        Returns
        -------
        gains : (C,)
        base : float    Phi(no chain) if ``with_base``, else NaN
        """
        entry = self._pairs(i, k0, cand_pos, cand_tgt, token)
        s0 = (k0 - 1) * self.ctx.e
        gains, ld_pre, ld_end, ld_sum = self._gains(
            s0, np.array([i]), np.array([entry.lo]), np.array([entry.hi]),
            np.array([0, len(entry.c_pair)]), entry.c_pair, entry.j_pair, entry.first,
            entry.count, entry.offset, entry.data, entry.delta, entry.rows[None],
            np.array([0, entry.n_cand]), with_base)
        base = np.nan
        if with_base:
            base = float(phi_terms(self.ctx.ld_bar, ld_end, ld_pre + ld_sum, self.cumulative,
                                   self._measured_without(i, entry.lo, entry.hi),
                                   self.ctx.existence).sum())
        if entry.dups.size:
            gains[entry.dups] = gains[entry.dup_of]     # identical pairs, identical sums
        return gains, base

    def _gains(self, s0: int, sensor: IntArray, lo: IntArray, hi: IntArray,
               pair_off: IntArray, c_loc: IntArray, j_pair: IntArray, first: IntArray,
               count: IntArray, offset: IntArray, data: FloatArray, delta: FloatArray,
               rows: FloatArray, cand_off: IntArray,
               all_targets: bool) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        ctx = self.ctx
        cv, dt = cv_form(ctx.F)
        return gains_nb(self.W, self.tgt, self._covs, ctx.F, self._Q, cv, dt,
                        self.cumulative, ctx.existence, s0, sensor, lo, hi, pair_off, c_loc,
                        j_pair, first, count, offset, data, delta, rows, cand_off, all_targets)

    def _pairs(self, i: int, k0: int, cand_pos: IntArray, cand_tgt: IntArray,
               token: tuple | None) -> Pairs:
        """The cached pairs of sensor i's candidate chains from epoch k0 (computed if the
        chain's context or the candidates changed)."""
        cands = token if token is not None else (cand_pos.tobytes(), cand_tgt.tobytes())
        C, L = cand_tgt.shape

        def chains(tail_xy: FloatArray, tail_tgt: IntArray) -> tuple[FloatArray, IntArray]:
            pos_xy = np.empty((C, L + len(tail_tgt), 2))
            tgt = np.empty((C, L + len(tail_tgt)), dtype=np.int64)
            pos_xy[:, :L] = self.xy_chains(i, k0, cand_pos)
            tgt[:, :L] = cand_tgt
            pos_xy[:, L:] = tail_xy
            tgt[:, L:] = tail_tgt
            return pos_xy, tgt

        return self._cached_pairs(i, k0, L, cands, chains)

    def _game_pairs(self, i: int, k: int, cand: IntArray, token: tuple) -> Pairs:
        """:meth:`_pairs` of player (i, k)'s actions: positions ``cand`` times every target."""
        return self._completed(self._game_pairs_job(i, k, cand, token))

    def _game_pairs_job(self, i: int, k: int, cand: IntArray,
                        token: tuple) -> Pairs | PairsJob:
        """:meth:`_game_pairs`, or on a cache miss the job that computes them (see
        :meth:`_pairs_done`)."""
        M = self.ctx.M

        def chains(tail_xy: FloatArray, tail_tgt: IntArray) -> tuple[FloatArray, IntArray]:
            return game_chains_nb(self.xy(i, k, cand), M, tail_xy, tail_tgt)

        return self._pairs_job(i, k, 1, token, chains, len(cand) * M)

    def xy_chains(self, i: int, k0: int, cand_pos: IntArray) -> FloatArray:
        """Ground positions ``(C, L, 2)`` of candidate chains ``cand_pos (C, L)`` from k0."""
        out = np.empty(cand_pos.shape + (2,))
        for l in range(cand_pos.shape[1]):
            out[:, l] = self.xy(i, k0 + l, cand_pos[:, l])
        return out

    def _cached_pairs(self, i: int, k0: int, L: int, cands: tuple, chains: Chains) -> Pairs:
        return self._completed(self._pairs_job(i, k0, L, cands, chains))

    def _completed(self, found: Pairs | PairsJob) -> Pairs:
        """``found`` if it is a cache entry, else its job run on this thread."""
        return found if isinstance(found, Pairs) else self._pairs_done(found, pair_kernels(found))

    def _pairs_job(self, i: int, k0: int, L: int, cands: tuple, chains: Chains,
                   n_cand: int = 0) -> Pairs | PairsJob:
        """The cached entry of sensor i's candidates ``cands`` from epoch k0 if it still holds,
        else the kernels' job that computes it (``chains(tail_xy, tail_tgt)`` makes the
        candidate chains followed by the sensor's fixed later epochs)."""
        ctx = self.ctx
        # The chain continues through the following assigned epochs: their headings change.
        k_last = k0 + L - 1
        k_end = self._run_end(i, k_last + 1) if self.assigned(i, k_last + 1) and k_last < ctx.K \
            else k_last
        prev_ok = self.assigned(i, k0 - 1)
        prev = self.heading[i, k0 - 2] if k0 > 1 and prev_ok else ctx.problem.headings[i]
        # The chain's own looks depend only on the chain; a (candidate, target) term depends
        # on them and on the other players' looks at that target. Both are cached, so a call
        # recomputes only the terms of targets whose other looks changed since the last call
        # for this player (in JSFP: the targets the neighbours switched to or from).
        key = (k0, L, prev_ok, float(prev), cands, self.pos[i, k_last:k_end].tobytes(),
               self.tgt[i, k_last:k_end].tobytes())
        entry = self._cache.get((i, k0, L))
        if entry is not None and entry.key == key:
            return entry

        def make() -> tuple:
            n = k_end - k_last
            tail_xy = np.empty((n, 2))
            tail_tgt = np.empty(n, dtype=np.int64)
            for l in range(n):
                kk = k_last + 1 + l
                tail_xy[l] = self.xy(i, kk, self.pos[i, kk - 1])
                tail_tgt[l] = self.tgt[i, kk - 1]
            pos_xy, tgt = chains(tail_xy, tail_tgt)
            return (pos_xy, tgt, k0, ctx.e, float(prev), bool(prev_ok),
                    float(ctx.problem.headings[i]), float(ctx.max_turn[i]), ctx.aim, ctx.xbar_xy,
                    ctx.Cbar, ctx.probabilistic, ctx.radar[i], ctx.T - (k0 - 1) * ctx.e,
                    ctx.buildings)

        return PairsJob(i, k0, L, key, k_end, make, n_cand * (k_end - k0 + 1))

    def _pairs_done(self, job: PairsJob, out: tuple) -> Pairs:
        """The cache entry of ``job`` from its kernels' results ``out``."""
        ctx = self.ctx
        i, k0, L = job.i, job.k0, job.L
        c_pair, j_pair, first, count, offset, data, owners, dups, contrib, free, dup_of, C = out
        if L == 1:
            # Rows of the players of epoch k0 live in one buffer, passed whole to the game.
            buf = self._rows_buf.get(k0)
            if buf is None:
                buf = self._rows_buf[k0] = np.full((ctx.N, ctx.M, ctx.T, 3), np.nan)
            rows = buf[i]
            rows[:] = np.nan
        else:
            rows = np.full((ctx.M, ctx.T, 3), np.nan)
        entry = Pairs(job.key, C, k0 - 1, job.k_end, c_pair, j_pair, first, count, offset,
                       data, np.zeros(len(c_pair)), rows, contrib, free, owners, dups, dup_of)
        self._cache[(i, k0, L)] = entry
        return entry

    def forget(self, i: int, k0: int, L: int = 1) -> None:
        """Drop the cached pairs of (i, k0, L) (e.g. an initialisation set never used again)."""
        self._cache.pop((i, k0, L), None)

    # ----------------------------------------------------------------- player actions
    def player_actions(self, i: int, k: int) -> tuple[IntArray, IntArray]:
        """Feasible actions of player (i, k) in tie-break order.

        Positions lie in ``R_k``, one move from ``p_{k-1}`` when (i, k-1) is assigned (or
        k = 1) and one move before ``p_{k+1}`` when (i, k+1) is assigned. Order: Euclidean
        distance from the reference position (``p_{k-1}`` when assigned, else ``p_0``), then
        the move order (the breadth-first order of ``R_k`` when the reference is ``p_0`` and
        k > 1), then the target index.

        Returns
        -------
        pos : (P * M,) int lattice indices in R_k;  tgt : (P * M,) int
        """
        cand = self.player_positions(i, k)
        M = self.ctx.M
        return np.repeat(cand, M), np.tile(np.arange(M), len(cand))

    def player_positions(self, i: int, k: int) -> IntArray:
        """The feasible positions of player (i, k) in tie-break order (lattice indices in
        ``R_k``); its actions are these positions times every target, position-major."""
        key = self.action_token(i, k)
        cand = self._actions.get(key)
        if cand is None:
            cand = self._player_positions(i, k)
            if key[3] >= 0:
                # Sets after an unassigned predecessor (the initialisation's, up to all of
                # R_k) are used once: not kept.
                self._actions[key] = cand
        return cand

    def action_token(self, i: int, k: int) -> tuple:
        """A key that determines the feasible actions of player (i, k): ``(i, k, p_{k-1},
        p_{k+1})`` as lattice indices (-1 when that neighbour is unassigned)."""
        K = self.ctx.K
        tgt = self.tgt
        pred = (0 if k == 1 else int(self.pos[i, k - 2])) if k == 1 or tgt[i, k - 2] >= 0 else -1
        succ = int(self.pos[i, k]) if k < K and tgt[i, k] >= 0 else -1
        return ("actions", i, k, pred, succ)

    def _player_positions(self, i: int, k: int) -> IntArray:
        lat = self.ctx.lattices[i]
        if self.assigned(i, k - 1):
            q = 0 if k == 1 else self.pos[i, k - 2]
            cand = lat.child[k][q]                       # in move order; -1 outside the map
            cand = cand[cand >= 0]
            ref = lat.positions[k - 1][q]
        else:
            cand = np.arange(len(lat.positions[k]))
            ref = lat.positions[0][0]
        parents, use = _NONE, False
        if k < self.ctx.K and self.assigned(i, k + 1):
            parents, use = lat.parent_move[k + 1][self.pos[i, k]], True
        return player_positions_nb(lat.positions[k], cand, _c(parents, np.int64), use, _c(ref))


_NONE = np.zeros(0, dtype=np.int64)

def choose(values: FloatArray, current: int = -1, scale: float | None = None) -> int:
    """Index of the best value under the tie rule.

    Values within ``TIE_TOL max(1, scale)`` of the maximum tie (``scale`` = |Phi|, by default
    the largest value); the current action wins a tie, then the earliest index (callers
    order actions by distance, move, target).
    """
    vmax = float(values.max())
    scale = abs(vmax) if scale is None else scale
    near = values >= vmax - TIE_TOL * max(1.0, scale)
    if current >= 0 and near[current]:
        return current
    return int(np.argmax(near))
