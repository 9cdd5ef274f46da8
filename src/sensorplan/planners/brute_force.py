r"""The ``brute-force`` baseline: the exact maximum of Phi over every feasible joint plan.

A sensor's *options* are its feasible position chains ``p_1 .. p_K`` (each step one move
inside the map) times the ``M^K`` target sequences; the joint space is the product of the
sensors' options.

Why it is fast. A sensor's headings and looks depend only on its own option, so every
option's position information ``W`` (per epoch and step) is computed once, batched; in fact
a look in epoch k depends only on the option's chain and targets up to k, so it is computed
once per such prefix. Phi then separates over targets,

.. math:: \Phi(a) = \sum_j f_j\Big(\sum_i W_{ij}(a_i)\Big),

where ``W_ij(a_i)`` is ``(T, 2, 2)``: sensor ``i``'s information about target ``j`` at every
step under option ``a_i`` (zero where it looks elsewhere or does not see ``j``), and ``f_j``
is the target's term of Phi, weighted by its probability of existence
(:func:`~sensorplan.planners.information.phi_terms` of
:func:`~sensorplan.planners.information.covariance_recursion`, exactly as
:func:`~sensorplan.planners.information.target_information` computes it). For each target the
options of a sensor collapse into a few *contribution classes* (all options that never see
``j`` share the zero class; with K = 1 the rest differ only by position), so ``f_j`` is
evaluated once per combination of classes and gathered for every joint plan. A target's
values over all class combinations are tabulated up front while they fit the memory budget
(every combination occurs, the joint space being a full product); otherwise they are
computed per chunk for the combinations that occur in it (``np.unique``).

Enumeration order (this fixes ties). Joint plans are enumerated with sensor 0's option
varying slowest. A sensor's options are ordered by chain, the chains lexicographically by
their move indices (the move order, ``stay`` first, epoch 1 slowest), then by target
sequence lexicographically (epoch 1 slowest). The planner returns the *first* plan in this
order whose Phi is within ``1e-9 max(1, |Phi*|)`` of the maximum ``Phi*`` (the tie
tolerance), so rounding differences between equal-valued plans cannot change the choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._types import FloatArray, IntArray
from ..errors import ConfigError
from ..limits import Range, param
from .base import PlanResult, RngLike, finish, register, start_clock
from .information import (Context, chain_headings, covariance_recursion, epoch_information,
                          measured, phi_terms, prepare)
from .problem import TIE_TOL, Lattice, Plan, PlanningProblem
from .registry import PlannerSettings, seed_param

#: Class combinations per batch of the covariance recursion (bounds its temporaries).
_F_BATCH = 1 << 15
#: Largest joint-plan count whose flat indices fit int64 comfortably.
_INDEX_LIMIT = 1 << 62


def count_chains(lattice: Lattice, K: int) -> int:
    """Number of feasible position chains ``p_1 .. p_K`` of one platform, exactly.

    Dynamic programming over the reachable sets: the number of chains ending at each
    position of ``R_k`` is the sum over its in-map parents in ``R_{k-1}`` (Python integers,
    no overflow).
    """
    counts = np.ones(1, dtype=object)
    for k in range(1, K + 1):
        child = lattice.child[k]
        q, m = np.nonzero(child >= 0)
        nxt = np.zeros(len(lattice.positions[k]), dtype=object)
        np.add.at(nxt, child[q, m], counts[q])
        counts = nxt
    return int(counts.sum())


def count_joint_plans(problem: PlanningProblem, ctx: Context | None = None) -> int:
    """Number of complete feasible joint plans: ``prod_i (chains_i * M^K)``, exactly."""
    ctx = prepare(problem) if ctx is None else ctx
    K, M = problem.horizon, problem.n_targets
    total = 1
    for lat in ctx.lattices:
        total *= count_chains(lat, K) * M**K
    return total


def _chain_tree(lattice: Lattice, K: int) -> tuple[list[IntArray], list[IntArray]]:
    """Chain prefixes level by level, in move-lexicographic order.

    Returns
    -------
    last : list, ``last[k]`` (n_k,)    position index in ``R_k`` of each length-k prefix
    parent : list, ``parent[k]`` (n_k,) index of its length-(k-1) prefix (``parent[0]`` empty)
    """
    last = [np.zeros(1, dtype=np.int64)]
    parent = [np.zeros(0, dtype=np.int64)]
    for k in range(1, K + 1):
        nxt = lattice.child[k][last[-1]]                                   # (n_{k-1}, n_moves)
        c, m = np.nonzero(nxt >= 0)                                        # prefix-major order
        parent.append(c)
        last.append(nxt[c, m])
    return last, parent


def _ancestors(parent: list[IntArray], K: int) -> list[IntArray]:
    """``anc[k][c]``: the length-k prefix of final chain ``c`` (``anc[0]`` unused)."""
    anc = [np.zeros(0, dtype=np.int64)] * (K + 1)
    anc[K] = np.arange(len(parent[K]), dtype=np.int64)
    for k in range(K - 1, 0, -1):
        anc[k] = parent[k + 1][anc[k + 1]]
    return anc


def enumerate_chains(lattice: Lattice, K: int) -> IntArray:
    """Every feasible chain as position indices ``(n_chains, K)`` (column k-1 indexes R_k).

    Ordered lexicographically by move index (the move order), epoch 1 slowest.
    """
    last, parent = _chain_tree(lattice, K)
    anc = _ancestors(parent, K)
    return np.stack([last[k][anc[k]] for k in range(1, K + 1)], axis=1).reshape(-1, K)


def _hash_constants(n: int) -> np.ndarray:
    """``n`` fixed odd 64-bit multipliers (splitmix64 of 1..n): deterministic, no RNG."""
    z = np.arange(1, n + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return np.asarray((z ^ (z >> np.uint64(31))) | np.uint64(1))


def _row_ids(rows: FloatArray, mult: np.ndarray) -> tuple[IntArray, int]:
    """Exact ids of equal rows ``(n, d)`` (no negative zeros): a linear hash groups them,
    a comparison with each group's first row confirms it; a collision falls back to an
    exact ``np.unique(axis=0)``.

    Returns
    -------
    ids : (n,) int    equal rows, and only they, share an id
    n_ids : int
    """
    h = (rows.view(np.uint64) * mult).sum(axis=1, dtype=np.uint64)       # wraps mod 2^64
    _, first, ids = np.unique(h, return_index=True, return_inverse=True)
    ids = ids.reshape(-1)
    if not np.array_equal(rows, rows[first[ids]]):
        _, ids = np.unique(rows, axis=0, return_inverse=True)
        ids = ids.reshape(-1)
    return ids.astype(np.int64), int(ids.max()) + 1 if len(ids) else 0


def _tuple_ids(parts: IntArray, radix: list[int]) -> tuple[IntArray, IntArray]:
    """Exact ids of equal integer rows ``parts (n, K)`` with ``0 <= parts[:, k] < radix[k]``.

    Returns
    -------
    ids : (n,)      in increasing order of the rows (mixed radix, column 0 most significant)
    first : (U,)    the first row of each id
    """
    key = parts[:, 0].astype(np.int64)
    span = radix[0]
    for k in range(1, parts.shape[1]):
        if span * radix[k] >= _INDEX_LIMIT:          # keep the mixed-radix key in int64
            _, key = np.unique(key, return_inverse=True)
            key = key.reshape(-1)
            span = int(key.max()) + 1
        key = key * radix[k] + parts[:, k]
        span *= radix[k]
    _, first, ids = np.unique(key, return_index=True, return_inverse=True)
    return ids.reshape(-1).astype(np.int64), first.astype(np.int64)


@dataclass(frozen=True)
class _SensorOptions:
    """One sensor's options and their per-target contribution classes.

    Attributes
    ----------
    positions : (n_chains, K, 2)     chain positions
    sequences : (M^K, K) int         target sequences
    cls : (M, n_options) int         class of each option for each target
    reps : list of (n_cls_j, T, 2, 2) the information each class carries about target j
    """

    positions: FloatArray
    sequences: IntArray
    cls: IntArray
    reps: list[FloatArray]

    @property
    def n_options(self) -> int:
        return int(self.cls.shape[1])

    def action(self, option: int) -> tuple[FloatArray, IntArray]:
        """Positions ``(K, 2)`` and targets ``(K,)`` of one option."""
        chain, seq = divmod(option, len(self.sequences))
        return self.positions[chain], self.sequences[seq]


def _sensor_options(ctx: Context, i: int) -> _SensorOptions:
    """Every option's information, and the options' contribution classes per target.

    A look in epoch k depends only on the option's *prefix*: its chain and target sequence
    up to k (through the heading chain). Headings and ``W`` are therefore computed once per
    prefix, level by level (prefix ``(c_k, s_k)`` extends ``(parent(c_k), s_k // M)``),
    and options refer to their prefixes by index. Equal looks get equal ids; an option's
    contribution to target j is the tuple over epochs of the ids of its nonzero looks at j,
    and options with equal tuples form one class.
    """
    K, M, e, T = ctx.K, ctx.M, ctx.e, ctx.T
    lat = ctx.lattices[i]
    last, parent = _chain_tree(lat, K)
    anc = _ancestors(parent, K)
    chain_pos = np.stack([lat.positions[k][last[k][anc[k]]] for k in range(1, K + 1)],
                         axis=1).reshape(-1, K, 2)
    seqs = np.indices((M,) * K).reshape(K, -1).T.astype(np.int64)        # lexicographic
    n_chains, n_seq = len(chain_pos), M**K
    n = n_chains * n_seq
    mult = _hash_constants(e * 4)
    theta = np.full((1, 1), float(ctx.problem.headings[i]))             # level 0
    looks_w: list[FloatArray] = []           # per level: (n_prefixes, e * 4)
    prefix = np.empty((n, K), dtype=np.int64)       # option -> its prefix at each level
    look_id = np.empty((n, K), dtype=np.int64)      # option -> id of its look (0: no info)
    radix: list[int] = []
    for k in range(1, K + 1):
        n_c, n_s = len(last[k]), M**k
        # s_k = s_{k-1} * M + j: each parent heading repeated for the M new targets.
        prev = np.repeat(theta[parent[k]], M, axis=1).reshape(-1)
        pos = np.repeat(lat.positions[k][last[k]], n_s, axis=0)           # (n_c * n_s, 2)
        tgt = np.tile(np.arange(M, dtype=np.int64), n_c * n_s // M)
        th = chain_headings(ctx, i, k, pos[:, None], tgt[:, None], prev, True)[:, 0]
        W, _ = epoch_information(ctx, i, k, pos, th, tgt)
        rows = W.reshape(len(pos), e * 4) + 0.0     # -0.0 -> 0.0: equal values, equal bits
        ids, n_ids = _row_ids(rows, mult)
        ids = np.where(rows.any(axis=1), ids + 1, 0)
        theta = th.reshape(n_c, n_s)
        looks_w.append(rows)
        prefix[:, k - 1] = ((anc[k] * n_s)[:, None]
                            + (np.arange(n_seq) // M**(K - k))[None, :]).reshape(-1)
        look_id[:, k - 1] = ids[prefix[:, k - 1]]
        radix.append(n_ids + 1)
    tgt_opt = np.tile(seqs, (n_chains, 1))                                 # (n, K)
    cls = np.empty((M, n), dtype=np.int64)
    reps: list[FloatArray] = []
    for j in range(M):
        parts = np.where(tgt_opt == j, look_id, 0)
        cls[j], first = _tuple_ids(parts, radix)
        rep = np.zeros((len(first), K, e * 4))
        for k in range(K):
            on = parts[first, k] > 0
            rep[on, k] = looks_w[k][prefix[first[on], k]]
        reps.append(rep.reshape(len(first), T, 2, 2))
    return _SensorOptions(chain_pos, seqs, cls, reps)


class _TargetTerm:
    """``f_j`` over combinations of the sensors' contribution classes for one target.

    A combination is a mixed-radix key over the sensors' class counts, sensor 0 most
    significant.
    """

    def __init__(self, ctx: Context, j: int, options: list[_SensorOptions]) -> None:
        self.ctx, self.j = ctx, j
        self.reps = [o.reps[j] for o in options]
        self.radix = tuple(len(r) for r in self.reps)
        n_keys = math.prod(self.radix)
        strides = [math.prod(self.radix[i + 1:]) for i in range(len(self.radix))]
        #: Per sensor: each option's class times its stride, so a key is a sum.
        self.scaled = [o.cls[j] * s for o, s in zip(options, strides)]
        self.n_keys = n_keys
        self.table: FloatArray | None = None
        self.P0 = np.asarray(ctx.problem.covs[j], dtype=float)
        self.Q = ctx.Q_rows(j)
        self.cumulative = ctx.problem.objective == "cumulative"

    def tabulate(self) -> None:
        """Evaluate ``f_j`` on every class combination once."""
        self.table = self.values(np.arange(self.n_keys, dtype=np.int64))

    def values(self, keys: IntArray) -> FloatArray:
        """``f_j`` at class-combination keys ``(U,)``, in batches (bounded memory)."""
        out = np.empty(len(keys))
        for s in range(0, len(keys), _F_BATCH):
            idx = np.unravel_index(keys[s:s + _F_BATCH], self.radix)
            W = self.reps[0][idx[0]]
            for rep, c in zip(self.reps[1:], idx[1:]):
                W = W + rep[c]
            P = np.broadcast_to(self.P0, (len(W), 4, 4))
            # Same recursion and terms as information.target_information.
            _, ld_end, ld_sum = covariance_recursion(P, W, self.ctx.F, self.Q,
                                                     need_sum=self.cumulative)
            out[s:s + _F_BATCH] = phi_terms(self.ctx.ld_bar[self.j], ld_end, ld_sum,
                                            self.cumulative, measured(W),
                                            self.ctx.existence[self.j])
        return out


@register
@dataclass(frozen=True)
class BruteForcePlanner(PlannerSettings):
    """Exact maximiser of Phi by enumerating every feasible joint plan.

    Parameters
    ----------
    max_plans : int
        Refuse (``ConfigError`` on ``planner.max_plans``) when the number of joint plans is
        larger; counted exactly before any heavy work.
    seed : int or None
        Unused (the planner is deterministic); accepted for a uniform interface.
    chunk : int
        Joint plans evaluated per vectorised chunk. Memory is about 40 bytes per plan of
        the chunk (up to about 80 when a target's values are not tabulated), so about
        40-80 MB at the default, plus the per-target tables (at most ``chunk`` floats in
        all) and each sensor's options (a few hundred bytes per option).

    Notes
    -----
    ``PlanResult.potential`` is recomputed from the plan by the one definition of Phi;
    ``PlanResult.trace`` holds one value, the maximum as the fast search computed it (the
    two agree to rounding).

    Ties: the first plan in enumeration order within ``1e-9 max(1, |Phi*|)`` of the
    maximum (the module docstring gives the order: sensor 0 slowest; chains by move index,
    then target sequences, lexicographically).
    """

    name: ClassVar[str] = "brute-force"
    plans_search: ClassVar[bool] = True
    max_plans: int = param(2_000_000, bounds=Range(1, None),
                           help="Most joint plans the planner enumerates.")
    seed: int | None = seed_param()
    chunk: int = param(1 << 20, bounds=Range(1, None),
                       help="Joint plans evaluated per vectorised chunk.")

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult:
        start = start_clock()
        if problem.searching:
            return self._plan_search(problem, start)
        ctx = prepare(problem)
        n_joint = count_joint_plans(problem, ctx)
        if n_joint > self.max_plans:
            raise ConfigError("planner.max_plans", f"brute force over {n_joint} joint plans "
                              f"exceeds max_plans={self.max_plans}")
        if n_joint >= _INDEX_LIMIT:  # pragma: no cover - unreachable in practice
            raise ConfigError("planner.max_plans", f"{n_joint} joint plans cannot be indexed")
        options = [_sensor_options(ctx, i) for i in range(ctx.N)]
        terms = [_TargetTerm(ctx, j, options) for j in range(ctx.M)]
        budget = self.chunk
        for term in terms:           # tabulate the targets whose tables fit the budget
            if term.n_keys <= budget:
                term.tabulate()
                budget -= term.n_keys
        best, phi_max = _search(options, terms, self.chunk)
        N, K = ctx.N, ctx.K
        positions = np.empty((N, K, 2))
        targets = np.empty((N, K), dtype=np.int64)
        for i, (opt, o) in enumerate(zip(options, best)):
            positions[i], targets[i] = opt.action(o)
        return finish(self.name, ctx, Plan(positions, targets), start, trace=(phi_max,))

    def _plan_search(self, problem: PlanningProblem, start: float) -> PlanResult:
        # Plain numpy over every joint plan with track and sector looks (small cases).
        from . import search

        sctx = search.prepare(problem)
        lats = sctx.ctx.lattices
        n_joint = search.count_plans(sctx, [count_chains(lat, sctx.ctx.K) for lat in lats])
        if n_joint > self.max_plans:
            raise ConfigError("planner.max_plans", f"brute force over {n_joint} joint plans "
                              f"exceeds max_plans={self.max_plans}")
        plan, phi_max = search.brute_force(
            sctx, [enumerate_chains(lat, sctx.ctx.K) for lat in lats])
        return finish(self.name, problem, plan, start, trace=(phi_max,))


class _Chunks:
    """Joint-plan chunks: a range of the leading sensors' options times all trailing ones.

    The trailing sensors ``t..N-1`` are the longest suffix whose option product fits in a
    chunk; each chunk takes ``b`` consecutive prefix combinations, so its flat joint index
    (sensor 0 slowest) is ``prefix * n_tail + tail``.
    """

    def __init__(self, sizes: list[int], chunk: int) -> None:
        t = len(sizes)
        while t > 0 and math.prod(sizes[t - 1:]) <= chunk:
            t -= 1
        self.sizes, self.t = sizes, t
        self.n_tail = math.prod(sizes[t:])
        self.n_prefix = math.prod(sizes[:t])
        self.per_chunk = max(1, chunk // self.n_tail)
        self.count = -(-self.n_prefix // self.per_chunk)

    def prefix(self, c: int) -> tuple[int, int, tuple[IntArray, ...]]:
        """Chunk ``c``'s first flat prefix index, its length, and the prefix options."""
        lo = c * self.per_chunk
        idx = np.arange(lo, min(lo + self.per_chunk, self.n_prefix), dtype=np.int64)
        opts = np.unravel_index(idx, self.sizes[:self.t]) if self.t else ()
        return lo, len(idx), tuple(opts)


def _chunk_phi(chunks: _Chunks, c: int, terms: list[_TargetTerm]) -> FloatArray:
    """Phi of every joint plan of chunk ``c``, flat in enumeration order."""
    t = chunks.t
    _, n_pre, pre = chunks.prefix(c)
    phi: FloatArray | None = None
    for term in terms:
        pre_key = np.zeros(n_pre, dtype=np.int64)
        for i in range(t):
            pre_key += term.scaled[i][pre[i]]
        tail_key = np.zeros(1, dtype=np.int64)
        for s in term.scaled[t:]:
            tail_key = (tail_key[:, None] + s[None, :]).reshape(-1)
        keys = (pre_key[:, None] + tail_key[None, :]).reshape(-1)
        if term.table is not None:
            vals = term.table[keys]
        else:
            uniq, inv = np.unique(keys, return_inverse=True)
            vals = term.values(uniq)[inv.reshape(-1)]
        phi = vals if phi is None else phi + vals
    assert phi is not None
    return phi


def _search(options: list[_SensorOptions], terms: list[_TargetTerm],
            chunk: int) -> tuple[tuple[int, ...], float]:
    """Option index per sensor of the first plan within the tie tolerance of the maximum,
    and the maximum as the fast evaluation computed it."""
    sizes = [o.n_options for o in options]
    chunks = _Chunks(sizes, chunk)
    maxima = np.empty(chunks.count)
    last: FloatArray | None = None
    for c in range(chunks.count):
        last = _chunk_phi(chunks, c, terms)
        maxima[c] = last.max()
    best = float(maxima.max())
    floor = best - TIE_TOL * max(1.0, abs(best))
    c = int(np.flatnonzero(maxima >= floor)[0])
    phi = last if c == chunks.count - 1 and last is not None else _chunk_phi(chunks, c, terms)
    pos = int(np.flatnonzero(phi >= floor)[0])
    lo = c * chunks.per_chunk
    flat = (lo + pos // chunks.n_tail) * chunks.n_tail + pos % chunks.n_tail
    return tuple(int(o) for o in np.unravel_index(flat, sizes)), best
