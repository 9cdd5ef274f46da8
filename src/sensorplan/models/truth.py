r"""Ground-truth target motion, batched over targets.

Two kinds of truth, both mirrored at the walls of the map ``[0, W] x [0, H]``:

``cv``
    The filter's own model, :math:`x_{t+1} = F x_t + w_t`, :math:`w_t \sim N(0, Q)`, drawn as
    :math:`w = L \epsilon` with :math:`L L^T = Q` and :math:`\epsilon` standard normal. A
    position that leaves the map is mirrored back inside and that velocity component flips
    sign (:func:`mirror`, any number of reflections).
``dubins``
    Constant speed :math:`v`, heading :math:`h`, turn rate :math:`\omega` held for
    ``turn_hold`` seconds and then redrawn uniformly from
    :math:`[-\omega_{max}, \omega_{max}]`. Motion along an arc is integrated exactly
    (:func:`dubins_arc`); a redraw inside a step splits the step. At the walls the position
    is mirrored and the heading reflected (:math:`h \to \pi - h` across a vertical wall,
    :math:`h \to -h` across a horizontal one). The vehicle keeps its turn rate across a
    reflection (its steering does not change); only the part of the step after the wall is
    mirrored, so within that step the turn is mirrored too.

With ``walls="open"`` the map's walls do nothing (buildings still reflect): a target may
leave the map, and the caller decides what that means (targets born at the edges die
there, :mod:`sensorplan.models.population`).

Randomness: :class:`TruthModel` spawns one child generator per target from the truth
generator it is given (``Generator.spawn``), so a target's motion depends on nothing but the
truth generator and its own index - not on the other targets, the filter, the sensors or
the planner. ``cv`` targets draw their normals in fixed blocks (the stream is consumed in
order, so the values do not depend on when a block is drawn); ``dubins`` targets draw one
uniform per redraw, the first at the start. Targets added later (:meth:`TruthModel.add`)
bring their own generators; removing a target (:meth:`TruthModel.remove`) leaves the others'
streams as they were.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from .._types import BoolArray, FloatArray, IntArray
from .angles import wrap_angle
from .motion import cv_matrices

#: Steps of ``cv`` process noise drawn per block.
NOISE_BLOCK = 256
#: Relative tolerance (of ``turn_hold``) under which a redraw is due within a step.
REDRAW_TOL = 1e-9


def mirror(p: FloatArray, length: float | FloatArray) -> tuple[FloatArray, BoolArray]:
    """Fold coordinates into ``[0, length]`` as a reflecting pair of walls would.

    Handles any number of reflections: with ``u = p mod 2L`` the folded coordinate is ``u``
    if ``u <= L`` else ``2L - u``; the direction of motion is reversed iff the fold used the
    mirrored branch. Coordinates already inside are returned unchanged (bit for bit).

    Parameters
    ----------
    p : (...) float64      coordinates (m)
    length : float or (...) float64
        Wall distance ``L > 0`` (m).

    Returns
    -------
    folded : (...) float64 in [0, L]
    flipped : (...) bool   whether the velocity component changes sign

    Examples
    --------
    >>> mirror(np.array([-1.0, 5.0, 11.0, 23.0]), 10.0)
    (array([1., 5., 9., 3.]), array([ True, False,  True, False]))
    """
    two_l = 2.0 * np.asarray(length, dtype=float)
    u = np.mod(p, two_l)
    flipped = u > length
    return np.where(flipped, two_l - u, u), flipped


def dubins_arc(xy: FloatArray, speed: FloatArray, heading: FloatArray, turn_rate: FloatArray,
               tau: FloatArray | float) -> tuple[FloatArray, FloatArray]:
    r"""Exact constant-speed, constant-turn-rate motion for a time ``tau``.

    With :math:`a = \omega \tau / 2`,

    .. math::
        \Delta x = v \tau \cos(h + a) \frac{\sin a}{a},\quad
        \Delta y = v \tau \sin(h + a) \frac{\sin a}{a},\quad h' = h + 2a,

    which equals :math:`(v/\omega)(\sin(h+\omega\tau) - \sin h, \cos h - \cos(h+\omega\tau))`
    and tends to the straight line as :math:`\omega \to 0` without cancellation
    (the ratio is taken as 1 at :math:`a = 0`).

    Parameters
    ----------
    xy : (..., 2)   ground positions (m)
    speed, heading, turn_rate, tau : (...)   m/s, rad, rad/s, s

    Returns
    -------
    xy : (..., 2)
    heading : (...) wrapped to (-pi, pi]
    """
    a = 0.5 * turn_rate * tau
    # sin(a)/a, exactly 1 at a = 0 (np.sinc does the same with more overhead).
    nonzero = a != 0.0
    ratio = np.where(nonzero, np.sin(a) / np.where(nonzero, a, 1.0), 1.0)
    s = speed * tau * ratio
    mid = heading + a
    out = np.empty_like(xy)
    out[..., 0] = xy[..., 0] + s * np.cos(mid)
    out[..., 1] = xy[..., 1] + s * np.sin(mid)
    return out, wrap_angle(heading + 2.0 * a)


#: Most reflections off building walls resolved in one step (a corner, or two buildings).
MAX_REFLECTIONS = 4


def inside_buildings(xy: FloatArray, buildings: FloatArray) -> BoolArray:
    """Whether ground points ``(..., 2)`` are strictly inside a building's footprint.

    ``buildings`` is ``(B, 5)``: ``x0, y0, x1, y1, height``. A point on a wall is outside.
    """
    xy = np.asarray(xy, dtype=float)
    if len(buildings) == 0:
        return np.zeros(xy.shape[:-1], dtype=bool)
    b = np.asarray(buildings, dtype=float)
    x, y = xy[..., 0, None], xy[..., 1, None]
    return np.any((x > b[:, 0]) & (x < b[:, 2]) & (y > b[:, 1]) & (y < b[:, 3]), axis=-1)


def reflect_off_buildings(old: FloatArray, new: FloatArray, buildings: FloatArray
                          ) -> tuple[FloatArray, BoolArray]:
    """Mirror points that moved into a building back out across the wall they crossed.

    A point that moved from ``old`` (outside) to ``new`` (inside a footprint) crossed the
    wall the segment enters through last (the later of its x and y entry times); it is
    mirrored across that wall, like a wall of the map, and that velocity component changes
    sign. Repeated up to :data:`MAX_REFLECTIONS` times (corners, neighbouring buildings);
    a point still inside after that stays at ``old`` with both components flipped.

    Parameters
    ----------
    old, new : (M, 2) ground positions before and after the step (m)
    buildings : (B, 5) ``x0, y0, x1, y1, height``

    Returns
    -------
    xy : (M, 2) outside every footprint
    flipped : (M, 2) bool, whether each velocity component changes sign
    """
    xy = np.array(new, dtype=float)
    flipped = np.zeros(xy.shape, dtype=bool)
    if len(buildings) == 0:
        return xy, flipped
    b = np.asarray(buildings, dtype=float)
    for m in np.flatnonzero(inside_buildings(xy, b)):
        start = np.array(old[m], dtype=float)
        for _ in range(MAX_REFLECTIONS):
            hit = np.flatnonzero((xy[m, 0] > b[:, 0]) & (xy[m, 0] < b[:, 2])
                                 & (xy[m, 1] > b[:, 1]) & (xy[m, 1] < b[:, 3]))
            if hit.size == 0:
                break
            x0, y0, x1, y1 = b[hit[0], :4]
            d = xy[m] - start
            # Entry time through each pair of walls (the wall facing the start point).
            tx = ((x0 if d[0] > 0 else x1) - start[0]) / d[0] if d[0] != 0 else -np.inf
            ty = ((y0 if d[1] > 0 else y1) - start[1]) / d[1] if d[1] != 0 else -np.inf
            if tx >= ty:
                wall = x0 if d[0] > 0 else x1
                start = np.array([wall, start[1] + tx * d[1]])
                xy[m, 0] = 2.0 * wall - xy[m, 0]
                flipped[m, 0] ^= True
            else:
                wall = y0 if d[1] > 0 else y1
                start = np.array([start[0] + ty * d[0], wall])
                xy[m, 1] = 2.0 * wall - xy[m, 1]
                flipped[m, 1] ^= True
        else:
            if inside_buildings(xy[m], b):
                xy[m] = old[m]
                flipped[m] = True
    return xy, flipped


#: What the walls of the map do: reflect targets back inside, or nothing.
WALLS = ("mirror", "open")


class TruthModel:
    """Batched true motion of M targets (:func:`sensorplan.simulation.scenario.make_truth`
    builds one from a scenario).

    Parameters
    ----------
    kinds : (M,) sequence of {"cv", "dubins"}
    initial_states : (M, 4)
        True ``[x, y, vx, vy]`` at time 0 (inside the map). A ``dubins`` target's speed and
        heading are those of its initial velocity.
    rng : numpy.random.Generator
        The truth generator; one child per target is spawned from it.
    turn_hold : (M,) float
        s between turn-rate draws (used for ``dubins`` targets only).
    max_turn_rate : (M,) float
        rad/s, turn rates are drawn from ``[-max_turn_rate, max_turn_rate]`` (``dubins``).
    world_size : (2,) float
        Map width and height (m): walls at ``x = 0, W`` and ``y = 0, H``.
    dt : float
        Step (s).
    process_noise : float
        q (m^2/s^3) of the ``cv`` targets' CWNA model.
    buildings : (B, 5), optional
        Building footprints and heights ``x0, y0, x1, y1, h``: targets reflect off their
        walls as off the map's (:func:`reflect_off_buildings`).
    walls : {"mirror", "open"}
        ``mirror`` (default): the map's walls reflect targets (:func:`mirror`); ``open``:
        targets pass through them and may leave the map.

    Attributes
    ----------
    states : (M, 4)
        Current true states; :meth:`step`, :meth:`add` and :meth:`remove` replace (do not
        mutate) this array.
    """

    def __init__(self, kinds: Sequence[str] | npt.NDArray[np.str_], initial_states: FloatArray,
                 rng: np.random.Generator, *, turn_hold: Sequence[float] | FloatArray,
                 max_turn_rate: Sequence[float] | FloatArray,
                 world_size: Sequence[float] | FloatArray, dt: float,
                 process_noise: float, buildings: FloatArray | None = None,
                 walls: str = "mirror") -> None:
        if walls not in WALLS:
            raise ValueError(f"walls must be one of {WALLS}, got {walls!r}")
        self.walls = walls
        self.width, self.height = (float(v) for v in world_size)
        self.buildings = np.zeros((0, 5)) if buildings is None else np.asarray(
            buildings, dtype=float).reshape(-1, 5)
        self.dt = float(dt)
        self.F, Q = cv_matrices(self.dt, process_noise)
        # Cholesky of Q(dt, q) = q Q(dt, 1): Q(dt, 1) is positive definite for dt > 0,
        # and q = 0 (allowed) gives no noise instead of a failed factorisation.
        _, Q1 = cv_matrices(self.dt, 1.0)
        self.L = np.sqrt(process_noise) * np.linalg.cholesky(Q1)
        self._size = np.array([self.width, self.height])
        self.states = np.zeros((0, 4))
        self._rngs: list[np.random.Generator] = []
        self.cv = np.zeros(0, dtype=np.int64)
        self.dub = np.zeros(0, dtype=np.int64)
        # cv noise: a block of NOISE_BLOCK steps per target and where each target is in it.
        self._noise = np.empty((0, NOISE_BLOCK, 4))
        self._noise_at = np.zeros(0, dtype=np.int64)
        self.turn_hold = np.zeros(0)
        self.max_turn_rate = np.zeros(0)
        self.xy = np.zeros((0, 2))
        self.speed = np.zeros(0)
        self.heading = np.zeros(0)
        self.turn_rate = np.zeros(0)
        self.time_left = np.zeros(0)
        self._redraw_tol = np.zeros(0)
        M = len(np.asarray(kinds, dtype=str).reshape(-1))
        self.add(kinds, initial_states, rng.spawn(M), turn_hold=turn_hold,
                 max_turn_rate=max_turn_rate)
        self.time = 0.0

    @property
    def n_targets(self) -> int:
        """Number of targets moved by :meth:`step`."""
        return len(self.states)

    def add(self, kinds: Sequence[str] | npt.NDArray[np.str_], states: FloatArray,
            rngs: Sequence[np.random.Generator], *, turn_hold: Sequence[float] | FloatArray,
            max_turn_rate: Sequence[float] | FloatArray) -> None:
        """Append targets after the present ones (rows ``n_targets ..``), each moving with
        its own generator of ``rngs``; a ``dubins`` target draws its first turn rate from
        it now. Shapes as in the constructor, with K new targets."""
        kind = np.asarray(kinds, dtype=str).reshape(-1)
        new = np.array(states, dtype=float)
        K = len(kind)
        if new.shape != (K, 4):
            raise ValueError(f"initial_states must have shape ({K}, 4), got {new.shape}")
        hold = np.asarray(turn_hold, dtype=float).reshape(-1)
        rate = np.asarray(max_turn_rate, dtype=float).reshape(-1)
        if hold.shape != (K,) or rate.shape != (K,):
            raise ValueError(f"turn_hold and max_turn_rate must have shape ({K},)")
        if len(rngs) != K:
            raise ValueError(f"one generator per target is needed: {K}, got {len(rngs)}")
        bad = sorted(set(kind) - {"cv", "dubins"})
        if bad:
            raise ValueError(f"unknown target kind {bad[0]!r}")
        m0 = self.n_targets
        self.states = np.concatenate([self.states, new]) if m0 else new
        self._rngs.extend(rngs)
        cv = np.flatnonzero(kind == "cv")
        self.cv = np.concatenate([self.cv, m0 + cv])
        self._noise = np.concatenate([self._noise, np.empty((len(cv), NOISE_BLOCK, 4))])
        self._noise_at = np.concatenate([self._noise_at,
                                         np.full(len(cv), NOISE_BLOCK, dtype=np.int64)])
        d = np.flatnonzero(kind == "dubins")
        n0 = len(self.dub)
        self.dub = np.concatenate([self.dub, m0 + d])
        self.turn_hold = np.concatenate([self.turn_hold, hold[d]])
        self.max_turn_rate = np.concatenate([self.max_turn_rate, rate[d]])
        self.xy = np.concatenate([self.xy, new[d, :2]])
        self.speed = np.concatenate([self.speed, np.hypot(new[d, 2], new[d, 3])])
        self.heading = np.concatenate([self.heading, np.arctan2(new[d, 3], new[d, 2])])
        self.turn_rate = np.concatenate(
            [self.turn_rate, np.array([self._draw_turn_rate(n0 + n) for n in range(len(d))])])
        self.time_left = np.concatenate([self.time_left, hold[d]])
        self._redraw_tol = REDRAW_TOL * self.turn_hold

    def remove(self, rows: Sequence[int] | IntArray) -> None:
        """Drop the targets at ``rows``; the others keep their order, states and streams."""
        drop = np.asarray(rows, dtype=np.int64).reshape(-1)
        if drop.size == 0:
            return
        keep = np.ones(self.n_targets, dtype=bool)
        keep[drop] = False
        renumber = np.cumsum(keep) - 1
        kc, kd = keep[self.cv], keep[self.dub]
        self.cv = renumber[self.cv[kc]]
        self._noise = self._noise[kc]
        self._noise_at = self._noise_at[kc]
        self.dub = renumber[self.dub[kd]]
        for name in ("turn_hold", "max_turn_rate", "xy", "speed", "heading", "turn_rate",
                     "time_left", "_redraw_tol"):
            setattr(self, name, getattr(self, name)[kd])
        self._rngs = [r for r, k in zip(self._rngs, keep, strict=True) if k]
        self.states = self.states[keep]

    def _draw_turn_rate(self, n: int) -> float:
        """A fresh turn rate for the n-th dubins target, from that target's own stream."""
        w = self.max_turn_rate[n]
        return float(self._rngs[self.dub[n]].uniform(-w, w))

    def _cv_noise(self) -> FloatArray:
        """Process noise ``(M_cv, 4)`` for one step, drawn per target in blocks."""
        need = np.flatnonzero(self._noise_at == NOISE_BLOCK)
        if need.size:
            raw = np.stack([self._rngs[self.cv[n]].standard_normal((NOISE_BLOCK, 4))
                            for n in need])
            self._noise[need] = raw @ self.L.T
            self._noise_at[need] = 0
        w = self._noise[np.arange(len(self.cv)), self._noise_at]
        self._noise_at += 1
        return w

    def _advance_dubins(self) -> None:
        """Move the dubins targets along their arcs for ``dt``, redrawing turn rates."""
        dt = self.dt
        tol = self._redraw_tol
        if not np.any(self.time_left <= dt + tol):
            # The usual step: no redraw falls inside it.
            self.xy, self.heading = dubins_arc(self.xy, self.speed, self.heading,
                                               self.turn_rate, dt)
            self.time_left = self.time_left - dt
            return
        remaining = np.full(len(self.dub), dt)
        while True:
            # A redraw is due inside this (sub)step where the hold runs out before it ends.
            due = self.time_left <= remaining + tol
            tau = np.where(due, np.minimum(self.time_left, remaining), remaining)
            self.xy, self.heading = dubins_arc(self.xy, self.speed, self.heading,
                                               self.turn_rate, tau)
            self.time_left = np.where(due, self.turn_hold, self.time_left - tau)
            for n in np.flatnonzero(due):
                self.turn_rate[n] = self._draw_turn_rate(int(n))
            remaining = np.where(due, remaining - tau, 0.0)
            remaining[remaining <= tol] = 0.0
            if not remaining.any():
                return

    def step(self) -> FloatArray:
        """Advance every target by ``dt``; return the new true states ``(M, 4)``."""
        new = np.empty_like(self.states)
        if len(self.cv):
            new[self.cv] = self.states[self.cv] @ self.F.T + self._cv_noise()
        if len(self.dub):
            self._advance_dubins()
            new[self.dub, :2] = self.xy
            new[self.dub, 2] = self.speed * np.cos(self.heading)
            new[self.dub, 3] = self.speed * np.sin(self.heading)
        if self.walls == "mirror":
            folded, flipped = mirror(new[:, :2], self._size)
        else:
            folded, flipped = new[:, :2], np.zeros((len(new), 2), dtype=bool)
        if len(self.buildings) and self.walls == "open":
            folded, off_walls = reflect_off_buildings(self.states[:, :2], folded,
                                                      self.buildings)
            flipped = flipped ^ off_walls
        elif len(self.buildings):
            # A wall of a building near the edge of the map can send a point out of the
            # map and back: alternate the two reflections until it is outside every
            # building and inside the map.
            for _ in range(MAX_REFLECTIONS):
                bounced, off_walls = reflect_off_buildings(self.states[:, :2], folded,
                                                           self.buildings)
                flipped = flipped ^ off_walls
                folded, off_map = mirror(bounced, self._size)
                flipped = flipped ^ off_map
                if not off_map.any():
                    break
        new[:, :2] = folded
        new[:, 2:] = np.where(flipped, -new[:, 2:], new[:, 2:])
        if len(self.dub):
            self.xy = folded[self.dub]
            fd = flipped[self.dub]
            if fd.any():
                h = np.where(fd[:, 0], np.pi - self.heading, self.heading)
                self.heading = wrap_angle(np.where(fd[:, 1], -h, h))
        self.states = new
        self.time += self.dt
        return new
