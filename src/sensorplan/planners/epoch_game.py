"""An epoch game: the players (i, k), i = 0..N-1, of one epoch, batched for the compiled
kernels (see :mod:`sensorplan.planners.engine` for what is reused and why the utilities are
exact, and :mod:`sensorplan._compiled.threads` for the threads).
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

import numpy as np

from .._compiled.threads import run_all
from .._types import FloatArray, IntArray
from ._gains_nb import game_block_nb, game_totals_nb, index_pairs_nb
from ._pairs_nb import player_view_nb
from .engine import GameState, Pairs, PairsJob, pair_kernels
from .information import _c, cv_form
from .problem import TIE_TOL

#: Below these amounts of work a batch runs on the calling thread alone: handing work to
#: another thread and waiting for it costs more than it saves (a paper-size decision took
#: 50 % longer on two threads). An iteration's players' part runs on threads when about
#: PARALLEL_PAIRS pair terms are recomputed; the players' looks when their candidate chains
#: hold PARALLEL_LOOKS candidate epochs; an iteration's bookkeeping when the game has
#: PARALLEL_CANDIDATES kept actions.
PARALLEL_PAIRS = 4000
PARALLEL_LOOKS = 20000
PARALLEL_CANDIDATES = 20000
#: With a time budget, an iteration with much to recompute is cut into this many blocks per
#: thread, with a check between rounds: the swarm's first game took 0.1 s uninterrupted.
BUDGET_BLOCKS = 8


class EpochGame:
    """The players (i, k), i = 0..N-1, of one epoch game, batched for the compiled kernels.

    Each player's feasible actions are fixed for the whole game (only epoch k changes), and
    so are its chain's looks. Actions whose looks never count have utility exactly 0 whatever
    the others do; only the first of them in tie order (and the current action) can ever be
    chosen, so the game is played on the rest: same decisions, far fewer candidates.

    Attributes
    ----------
    actions : list of (pos, tgt)   each player's kept actions, in tie order
    cur : (N,) int                 index of each player's current action (-1 unassigned)
    cand_off : (N + 1,) int        player i's utilities are ``u[cand_off[i]:cand_off[i+1]]``
    """

    def __init__(self, state: GameState, k: int, check: Callable[[], None] | None = None
                 ) -> None:
        self.state, self.k = state, k
        self._check = check
        N = state.ctx.N
        self.actions: list[tuple[IntArray, IntArray]] = []
        self.cur = np.full(N, -1, dtype=np.int64)
        self._init_sets = []
        entries, c_loc, aliases = [], [], []
        M = state.ctx.M
        tgt_k = state.tgt[:, k - 1]
        for i, token, cand, entry in self._entries(check):
            if token[3] < 0 and k > 1:
                self._init_sets.append(i)
            # Kept: candidates holding pairs, the first without a counting look, the current
            # action. A duplicate (same pairs as an earlier candidate) can only be chosen as
            # the current action; it then takes its original's utility.
            at = (int(state.pos[i, k - 1]), int(tgt_k[i])) if tgt_k[i] >= 0 else (-1, -1)
            if entry.view is None or entry.view[0] != at:
                pos, tgt, cur_loc, loc, alias = player_view_nb(
                    cand, M, at[0], at[1], entry.owners, entry.free, entry.dups, entry.dup_of,
                    entry.c_pair)
                entry.view = (at, (pos, tgt), cur_loc, loc, alias)
            _, actions, self.cur[i], loc, alias = entry.view
            self.actions.append(actions)
            entries.append(entry)
            c_loc.append(loc)
            aliases.append(alias)
        if check is not None:
            check()                   # safe points between the set-up's longer parts
        sizes = np.array([len(a[0]) for a in self.actions])
        self.cand_off = np.r_[0, np.cumsum(sizes)]
        al = np.array([(self.cand_off[i] + self.cur[i], self.cand_off[i] + a)
                       for i, a in enumerate(aliases) if a >= 0], dtype=np.int64).reshape(-1, 2)
        self._alias_dst, self._alias_src = al[:, 0].copy(), al[:, 1].copy()
        n_pairs = np.array([len(en.c_pair) for en in entries])
        n_data = np.array([len(en.data) for en in entries])
        self._pair_off = np.r_[0, np.cumsum(n_pairs)]
        data_off = np.r_[0, np.cumsum(n_data)]
        cat = np.concatenate
        self._c_loc = cat(c_loc)
        self._j = cat([en.j_pair for en in entries])
        self._first = cat([en.first for en in entries])
        self._count = cat([en.count for en in entries])
        self._offset = cat([en.offset for en in entries])
        self._offset += np.repeat(data_off[:-1], n_pairs)      # rows in the game's data
        self._data = _c(cat([en.data for en in entries]))
        self._delta = cat([en.delta for en in entries])
        self._rows = state._rows_buf[k]          # every entry's rows are views into it
        self._hi = np.array([en.hi for en in entries])
        for i, en in enumerate(entries):
            # The cache keeps working on the game's buffer (views): no copy back needed.
            en.delta = self._delta[self._pair_off[i]:self._pair_off[i + 1]]
        if check is not None:
            check()
        ctx = state.ctx
        self._by_t, self._t_off, self._cp_off = index_pairs_nb(
            self._pair_off, self._c_loc, self._j, self.cand_off, ctx.M)
        n = int(self.cand_off[-1])
        self._gcache = np.zeros(n)
        self._none = np.zeros(0)
        self._dirty = np.zeros(n, dtype=bool)
        self._dlist = np.empty(n, dtype=np.int64)
        self._seen = np.full((N, ctx.M), -1, dtype=np.int64)
        self._tot_ver = np.zeros(ctx.M, dtype=np.int64)
        S = ctx.T - (k - 1) * ctx.e
        self._shared = np.zeros(1, dtype=bool)
        self._pre = np.empty((ctx.M, 4, 4))
        self._tot_rows = np.full((ctx.M, ctx.T, 3), np.nan)
        self._tot_pred = np.empty((ctx.M, S, 4, 4))
        self._tot_part = np.empty((ctx.M, S))
        self._tot_ld = np.empty((ctx.M, 2))
        # Blocks of players for the threads, contiguous and of about equal numbers of pairs
        # (a block writes only its players' entries, and lists its candidates to sum again
        # in its own part of _dlist); one block when the iteration has little work. With a
        # time budget, BUDGET_BLOCKS times as many, run a thread-count at a time with a
        # check between (a game's first iteration recomputes every pair: a long stretch).
        self._total = int(self._pair_off[-1])
        nb = max(1, state.threads)
        self._blocks = self._player_blocks(nb if check is None else nb * BUDGET_BLOCKS)
        # An iteration with little to recompute but many actions: its bookkeeping is short,
        # one block per thread.
        self._step_blocks = self._blocks if check is None else self._player_blocks(nb)
        self._has_pair = np.diff(self._t_off, axis=1).any(axis=0)   # targets with a pair

    def _player_blocks(self, n: int) -> list[tuple[int, int]]:
        """Up to ``n`` contiguous blocks of players with about equal numbers of pairs."""
        N = self.state.ctx.N
        n = max(1, min(n, N))
        cut = np.searchsorted(self._pair_off, self._total * np.arange(1, n) / n)
        bounds = sorted({0, N} | {int(c) for c in np.clip(cut, 1, N - 1)})
        return list(pairwise(bounds))

    def _entries(self, check: Callable[[], None] | None
                 ) -> list[tuple[int, tuple, IntArray, Pairs]]:
        """Every player's ``(i, action token, positions, pairs)``; the pairs not cached are
        computed on the state's threads, a batch at a time (every player at once, or with a
        time budget as many as there are threads, ``check`` between batches)."""
        state, k, N = self.state, self.k, self.state.ctx.N
        cache, changes = state._cache, state.changes
        step = N if check is None else max(1, state.threads)
        out = []
        for a in range(0, N, step):
            if check is not None and a > 0:
                check()                          # a time budget's safe point
            batch = []
            for i in range(a, min(a + step, N)):
                entry = cache.get((i, k, 1))
                if entry is not None and entry.token is not None and entry.changes == changes[i]:
                    # Sensor i unchanged since this entry's key last held: it still does.
                    batch.append((i, entry.token, entry.cand, entry))
                    continue
                token = state.action_token(i, k)
                cand = state.player_positions(i, k)
                batch.append((i, token, cand, state._game_pairs_job(i, k, cand, token)))
            jobs = [x[3] for x in batch if isinstance(x[3], PairsJob)]
            threads = state.threads if sum(job.size for job in jobs) >= PARALLEL_LOOKS else 1
            done = iter(run_all(pair_kernels, [(job,) for job in jobs], threads))
            for i, token, cand, found in batch:
                if isinstance(found, PairsJob):
                    found = state._pairs_done(found, next(done))
                found.token, found.cand, found.changes = token, cand, changes[i]
                out.append((i, token, cand, found))
        return out

    def utilities(self) -> FloatArray:
        """Every player's utility of each kept action (marginal contributions), concatenated."""
        return self._iterate(0, self._none, 0.0)[0]

    def iteration(self, ubar: FloatArray, t: int,
                  scale: float) -> tuple[FloatArray, bool, FloatArray, IntArray]:
        """JSFP iteration ``t``: the utilities ``u`` of every player's kept actions, the
        equilibrium test, running averages and best responses.

        The equilibrium: no player can raise its utility by more than
        ``TIE_TOL max(1, scale)``. Otherwise ``ubar <- (t-1)/t ubar + u/t`` and each player's
        best response is ``argmax ubar`` under the tie rule (see :func:`choose`).

        Returns
        -------
        u : utilities (concatenated, a new array);  equilibrium : bool;
        ubar : new averages (``ubar`` itself at an equilibrium);
        best : (N,) indices into each player's kept actions (-1 at an equilibrium)
        """
        u, eq, new, best = self._iterate(t, ubar, TIE_TOL * max(1.0, scale))
        if eq:
            return u, True, ubar, np.full(len(best), -1, dtype=np.int64)
        return u, False, new, best

    def _iterate(self, t: int, ubar: FloatArray,
                 tol: float) -> tuple[FloatArray, bool, FloatArray, IntArray]:
        """:func:`game_block_nb` on every block of players (``t`` 0: utilities only)."""
        st = self.state
        ctx = st.ctx
        cv, dt = cv_form(ctx.F)
        Wtot, first_call, changed = game_totals_nb(
            st.W, st.tgt, st._covs, ctx.F, st._Q, cv, dt, st.cumulative, self.k, self._has_pair,
            self._shared, self._pre, self._tot_rows, self._tot_ver, self._tot_pred,
            self._tot_part, self._tot_ld)
        n = int(self.cand_off[-1])
        u = np.empty(n)
        new = np.empty(n) if t > 0 else u
        best = self.cur.copy()
        common = (st.W, st.tgt, ctx.F, st._Q, cv, dt, st.cumulative, ctx.existence, self.k,
                  self._hi, self._c_loc, self._j, self._first, self._count, self._offset,
                  self._data, self._delta, self._rows, self._by_t, self._t_off, self.cand_off,
                  self._dirty, self._dlist, self._seen, Wtot, self._pre, self._tot_ver,
                  self._tot_pred, self._tot_part, self._tot_ld, first_call, self._cp_off,
                  self._gcache, self._alias_dst, self._alias_src, u, ubar, t, tol, new, best)
        # Pair terms this iteration recomputes, roughly: all at first, then those of the
        # targets whose total changed; every candidate's running average.
        redo = self._total if first_call else changed * self._total / ctx.M
        if redo >= PARALLEL_PAIRS:
            blocks = self._blocks
        elif t > 0 and n >= PARALLEL_CANDIDATES:
            blocks = self._step_blocks
        else:
            blocks = [(0, ctx.N)]
        step = len(blocks) if self._check is None else max(1, st.threads)
        eq = True
        for a in range(0, len(blocks), step):
            if a > 0 and self._check is not None:
                self._check()                # a time budget's safe point
            for ok in run_all(game_block_nb, [(b0, b1) + common for b0, b1 in blocks[a:a + step]],
                              st.threads):
                eq &= ok
        return u, eq, new, best

    def split(self, values: FloatArray) -> list[FloatArray]:
        """Per-player views of concatenated values."""
        return [values[a:b] for a, b in pairwise(self.cand_off.tolist())]

    def close(self) -> None:
        """Forget the initialisation sets' pairs (their actions are never offered again)."""
        for i in self._init_sets:
            self.state.forget(i, self.k)


_ENGINE_WARM = False


def warm_engine() -> None:
    """Compile (or load from numba's cache) the engine's kernels once, on a tiny decision."""
    global _ENGINE_WARM
    if _ENGINE_WARM:
        return
    _ENGINE_WARM = True
    from ..models.sensors import SensorParams
    from .information import prepare
    from .problem import PlanningProblem

    problem = PlanningProblem(np.array([[300.0, 300.0, 1.0, 0.0]]),
                              np.diag([400.0, 400.0, 4.0, 4.0])[None], np.array([[0.0, 300.0]]),
                              np.array([0.0]), (SensorParams(),), horizon=2)
    state = GameState(prepare(problem))
    game = EpochGame(state, 2)
    try:
        ubar = np.zeros(int(game.cand_off[-1]))
        for t in (1, 2):            # unassigned, then assigned: both code paths compiled
            _, _, ubar, best = game.iteration(ubar, t, abs(state.potential()))
            if best[0] >= 0:
                pos, tgt = game.actions[0]
                state.set_action(0, 2, int(pos[best[0]]), int(tgt[best[0]]))
                game.cur[0] = best[0]
    finally:
        game.close()
    pos, tgt = state.player_actions(0, 1)
    state.chain_gains(0, 1, pos[:, None], tgt[:, None], with_base=True)
