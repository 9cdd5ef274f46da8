"""What both planning rewards with search (information, :mod:`.search`; the GOSPA bound,
:mod:`.gospa_bound`) share: what a look sees of the undetected intensity's grid, and a
player's candidate chains of looks."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..models import radar
from ._search_nb import heading_rule_nb
from .information import Context
from .problem import Plan


class Cells(Protocol):
    """The decision's tracks context and the grid's cell centres."""

    @property
    def ctx(self) -> Context: ...
    @property
    def centres(self) -> FloatArray: ...
    @property
    def bearings(self) -> list[FloatArray]: ...


def detection(cells: Cells, i: int, positions: FloatArray, headings: FloatArray
              ) -> FloatArray:
    """``P_d v`` at every cell centre for looks of sensor i: ``(B, C)`` from poses
    ``positions (B, 2)``, ``headings (B,)`` (the radar's one implementation, the call the
    multi-target tracker thins its undetected cells with)."""
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    d = cells.centres[None, :, :] - positions[:, None, :]
    B = len(positions)
    return radar.detectable_points(cells.ctx.radar, np.full(B, i, dtype=np.int64), d[..., 0],
                                   d[..., 1], np.asarray(headings, dtype=float).reshape(B),
                                   positions, cells.ctx.buildings)


def candidate_chains(cells: Cells, plan: Plan, i: int, k: int, positions: FloatArray,
                     targets: IntArray, sectors: IntArray, headings: FloatArray
                     ) -> tuple[FloatArray, IntArray, BoolArray, FloatArray]:
    """Sensor i's epochs k..K under each of A candidate actions for player (i, k).

    Returns
    -------
    pos (A, L, 2), tgt (A, L), assigned (A, L), th (A, L)
        ``L = K - k + 1``: the plan's later epochs with epoch k replaced by the candidate,
        and the looks' headings by the heading rule from epoch k-1's heading (``headings``
        are the plan's, ``(N, K)``); NaN where a later epoch is unassigned.
    """
    ctx = cells.ctx
    A, L = len(targets), ctx.K - k + 1
    assert plan.sectors is not None
    pos = np.repeat(plan.positions[i, k - 1:][None], A, axis=0)
    tgt = np.repeat(plan.targets[i, k - 1:][None], A, axis=0)
    sec = np.repeat(plan.sectors[i, k - 1:][None], A, axis=0)
    pos[:, 0], tgt[:, 0], sec[:, 0] = positions, targets, sectors
    assigned = (tgt >= 0) | (sec >= 0)
    th = np.full((A, L), np.nan)
    theta0, turn = float(ctx.problem.headings[i]), float(ctx.max_turn[i])
    prev_ok = k == 1 or bool(plan.assigned[i, k - 2])
    h = np.full(A, theta0 if k == 1 or not prev_ok else float(headings[i, k - 2]))
    for l in range(L):
        kk = k + l
        if not assigned[0, l] and l > 0:       # later epochs: the same for every candidate
            prev_ok = False
            continue
        if ctx.M:
            aim = ctx.aim[np.maximum(tgt[:, l], 0), kk - 1]
            toward = np.arctan2(aim[:, 1] - pos[:, l, 1], aim[:, 0] - pos[:, l, 0])
        else:                                   # no track: every look is a sector look
            toward = np.zeros(A)
        b = np.where(sec[:, l] >= 0, cells.bearings[i][np.maximum(sec[:, l], 0)]
                     if cells.bearings[i].size else 0.0, toward)
        h = (heading_rule_nb(h, b, turn) if prev_ok
             else heading_rule_nb(np.full(A, theta0), b, kk * turn))
        th[:, l] = h
        prev_ok = True
    return pos, tgt, assigned, th
