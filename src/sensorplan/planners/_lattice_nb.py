"""Compiled breadth-first pass building the reachable sets (``problem.build_lattice``).

The same sets, in the same order, as the array version it replaced: ``R_k`` lists the
positions ``p + m`` (``p`` in ``R_{k-1}`` in order, moves in their order) that lie in the map,
each the first time it is seen; two positions are the same when their offsets from the start
round to the same point of a 1e-6 m grid.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._compiled.jit import njit, numba_globals


def _numba_names() -> dict[str, Any]:
    """numba's typed dictionary, for the sets on a fine grid (set when numba loads)."""
    from numba import types
    from numba.typed import Dict

    return {"Dict": Dict, "types": types, "_KEY": types.UniTuple(types.int64, 2)}


Dict: Any = None                    # numba's names, set by _numba_names when numba loads
types: Any = None
_KEY: Any = None
numba_globals(__name__, _numba_names)


@njit(cache=True)
def lattice_nb(p0: np.ndarray, moves: np.ndarray, K: int, bounded: bool, width: float,
               height: float, tol: float, grid: int) -> tuple:
    """Reachable sets of one platform, flattened.

    Parameters
    ----------
    p0 : (2,)          start position (m)
    moves : (n_moves, 2)
    bounded : bool     keep only positions inside ``[0, width] x [0, height]`` (tolerance
                       ``tol``, as :meth:`sensorplan.planners.problem.MapRect.contains`)
    grid : int         common step of the moves in units of ``tol`` (0 if none): positions
                       are then points of that grid, found in a dense table (the same
                       positions as the 1e-6 m keys give)

    Returns
    -------
    positions : (n, 2)          ``R_0 .. R_K`` one after the other
    start : (K + 2,) int        ``R_k`` is ``positions[start[k]:start[k + 1]]``
    child : (n, n_moves) int    row ``start[k-1] + q``: index in ``R_k`` of ``R_{k-1}[q] +
                                move_m`` or -1 (rows of ``R_K`` unused)
    parent : (n, n_moves) int   row ``start[k] + p``: index in ``R_{k-1}`` of ``R_k[p] -
                                move_m`` or -1 (rows of ``R_0`` are -1)
    """
    n_moves = moves.shape[0]
    step = grid * tol
    reach = 0.0
    for m in range(n_moves):
        reach = max(reach, abs(moves[m, 0]), abs(moves[m, 1]))
    R = 0
    if grid > 0:
        R = int(np.ceil(K * reach / step)) + 2
        if (2 * R + 1) ** 2 > 1_000_000:           # a fine grid: use the keys instead
            R = 0
    dense = R > 0
    # Room for every level (grown if needed): a coarse grid's points within reach, or a
    # guess.
    cap = 1
    for k in range(1, K + 1):
        if dense:
            cap += (2 * int(np.ceil(k * reach / step)) + 3) ** 2
        else:
            cap += 4 * n_moves * k
    positions = np.empty((cap, 2))
    child = np.full((cap, n_moves), -1, dtype=np.int64)
    parent = np.full((cap, n_moves), -1, dtype=np.int64)
    start = np.zeros(K + 2, dtype=np.int64)
    positions[0, 0] = p0[0]
    positions[0, 1] = p0[1]
    start[1] = 1
    side = 2 * R + 1 if dense else 1
    table = np.full(side * side if dense else 1, -1, dtype=np.int64)
    stamp = np.full(side * side if dense else 1, -1, dtype=np.int64)
    for k in range(1, K + 1):
        seen = Dict.empty(key_type=_KEY, value_type=types.int64)
        n = start[k]
        for q in range(start[k - 1], start[k]):
            if n + n_moves > positions.shape[0]:       # room for this parent's children
                positions, child, parent = _grow(positions, child, parent)
            for m in range(n_moves):
                x = positions[q, 0] + moves[m, 0]
                y = positions[q, 1] + moves[m, 1]
                if bounded and not (x >= -tol and x <= width + tol and y >= -tol
                                    and y <= height + tol):
                    continue
                if dense:
                    cell = ((np.int64(np.rint((x - p0[0]) / step)) + R) * side
                            + np.int64(np.rint((y - p0[1]) / step)) + R)
                    idx = table[cell] if stamp[cell] == k else -1
                else:
                    key = (np.int64(np.rint((x - p0[0]) / tol)),
                           np.int64(np.rint((y - p0[1]) / tol)))
                    idx = seen[key] if key in seen else -1   # not .get: AOT-compilable
                if idx < 0:
                    idx = n - start[k]
                    if dense:
                        table[cell] = idx
                        stamp[cell] = k
                    else:
                        seen[key] = idx
                    positions[n, 0] = x
                    positions[n, 1] = y
                    n += 1
                child[q, m] = idx
                parent[start[k] + idx, m] = q - start[k - 1]
        start[k + 1] = n
    end = start[K + 1]
    return positions[:end], start, child[:end], parent[:end]


@njit(cache=True)
def _grow(positions: np.ndarray, child: np.ndarray, parent: np.ndarray) -> tuple:
    n = positions.shape[0]
    p2 = np.empty((2 * n, 2))
    p2[:n] = positions
    c2 = np.full((2 * n, child.shape[1]), -1, dtype=np.int64)
    c2[:n] = child
    a2 = np.full((2 * n, parent.shape[1]), -1, dtype=np.int64)
    a2[:n] = parent
    return p2, c2, a2
