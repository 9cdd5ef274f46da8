r"""The lost-target mode of the tracker of known targets: a point-mass density on a grid.

A single Gaussian cannot hold "anywhere not yet looked at": each missed look cuts it, the
prediction spreads it again over the places already looked at, the next look cuts again,
and a target lost for tens of steps ends with a small, confidently wrong track. When a
track's own evidence says it has lost its target, the tracker replaces its Gaussian by a
density on the cells of the multi-target trackers' grid
(:func:`sensorplan.tracking.pmb.undetected.make_grid`), normalised to one target:

.. math::
    p(x) = \sum_c w_c\, N(x;\ [p_c, 0],\ P_u),\qquad \sum_c w_c = 1,

with :math:`p_c` the centre of cell ``c``, :math:`P_u = \mathrm{diag}(a^2/12, b^2/12,
\sigma_v^2, \sigma_v^2)` (a uniform position over the ``a x b`` cell; a velocity of mean
zero and the speed prior's variance per axis). Cells whose centre lies inside a building's
footprint carry no weight (no target is ever inside one).

**When a track is lost.** The probability, under the track, of its run of missed looks
since its last detection is :math:`\prod_k (1 - f_k)`, :math:`f_k` the share of the track's
mass the ``k``-th look should have detected (the missed-look update's fraction, mixed over
the IMM's modes). Were the track right, the chance that this product ever falls below
:math:`\alpha` before the next detection is at most :math:`\alpha` (the run reaches the
first product below :math:`\alpha` only through the misses whose probability that product
is). So a product below :math:`\alpha` (``lost_probability``) rejects the track at level
:math:`\alpha`, and it becomes a grid.

**Entering: a replay.** The grid starts from the track as it stood after its last
detection (the anchor; the initial estimate for a target never detected), with cell
weights :math:`w_c \propto N(p_c;\ m, P + \mathrm{diag}(a^2/12, b^2/12))` (position
block), and replays every step since: the prediction, then that step's missed looks. So the
grid remembers every place looked at since the target was last seen, which the carved
Gaussian had forgotten.

**Predict: diffusion.** A target whose velocity is unknown, of variance
:math:`\sigma_v^2` per axis and constant, is :math:`n^2 \sigma_v^2 \Delta t^2` away (per axis
variance) from where it was ``n`` steps ago; the grid's ``n``-th step after the anchor
therefore spreads every cell's weight by a random walk of variance
:math:`(2n - 1)\,\sigma_v^2 \Delta t^2` per axis (the increment). The walk is a sequence of
passes of the three-point kernel :math:`[\kappa, 1 - 2\kappa, \kappa]` along each axis
(variance :math:`2\kappa` cells² a pass, :math:`\kappa \le 1/4`), and no weight crosses a
wall: between a cell and a neighbour off the map or inside a building nothing flows, so the
walk is reflected at the map's walls and the buildings', as the targets are. The weight is
conserved exactly. It is an approximation in two ways: a thinned grid has no
position-velocity correlation (the mass beside a look is not known to be moving away from
it), so it spreads back at the full prior speed (cautious); and a velocity known at the
anchor is not used (cautious too).

**A missed look** multiplies each cell's weight by the probability that the look gave no
gated detection of a target at the cell's centre, :math:`1 - P_G P_d v(p_c)`
(:func:`sensorplan.models.radar.detectable_points`: the range band, the azimuth wedge, the
line of sight past the buildings and the detection probability; the model the filter and
the simulator use), and renormalises (Bayes' rule for the point-mass density).

**The reported track** is the grid's first two moments (the mixture's), so the NEES
measures the grid honestly; the planner plans on them.

**A detection** of a lost target is gated against the grid: each cell's component is
updated by the extended Kalman filter with the detection and weighted by
:math:`w_c\, N(\nu_c; 0, S_c)` over the cells whose innovation passes the gate; the
posterior mixture is moment matched into the new Gaussian (its velocity keeps the grid's
prior: one detection says nothing of it), and the track leaves the lost mode. When no cell
passes the gate (the grid had excluded the place the target was found), the track restarts
from the detection (re-acquisition). The mixture's moments, rather than the two-point
initiation, since a detection with ideal detection and no false alarms is the target's,
and the grid already holds the prior the initiation would assume.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._types import BoolArray, FloatArray
from ..models import radar
from .ekf import innovations, mahalanobis2, position_update
from .pmb.undetected import Grid, make_grid, thin

#: Largest share of a cell's weight one diffusion pass moves to each neighbour.
MAX_KAPPA = 0.25


def velocity_variance(speed_range: tuple[float, float]) -> float:
    r"""Per-axis velocity variance of a target whose speed is uniform on ``[lo, hi]`` and
    whose heading is uniform: :math:`E[v_x^2] = E[s^2]/2 = (lo^2 + lo\,hi + hi^2)/6`.

    Examples
    --------
    >>> velocity_variance((3.0, 6.0))
    10.5
    """
    lo, hi = (float(s) for s in speed_range)
    return (lo * lo + lo * hi + hi * hi) / 6.0


@dataclass(frozen=True)
class LostGrid:
    """The grid of the lost-target mode over a map with buildings (see the module
    docstring).

    Attributes
    ----------
    grid : Grid                 the cells (``make_grid``)
    free : (C,) bool            cells whose centre is outside every footprint
    open_x : (ny, nx - 1) bool  weight may flow between horizontal neighbours
    open_y : (ny - 1, nx) bool  weight may flow between vertical neighbours
    velocity_var : float        :math:`\\sigma_v^2` (m^2/s^2)
    dt : float                  step (s)
    """

    grid: Grid
    free: BoolArray
    open_x: BoolArray
    open_y: BoolArray
    velocity_var: float
    dt: float

    @property
    def size(self) -> int:
        return self.grid.size


def make_lost_grid(width: float, height: float, resolution: float, velocity_var: float,
                   dt: float, buildings: FloatArray | None = None) -> LostGrid:
    """The lost-target grid of cells at most ``resolution`` m wide over ``[0, W] x [0, H]``,
    with the cells whose centre is inside a footprint of ``buildings`` ``(K, 5)`` closed."""
    grid = make_grid(width, height, resolution, velocity_var)
    free = np.ones(grid.size, dtype=bool)
    if buildings is not None and len(buildings):
        b = np.asarray(buildings, dtype=float).reshape(-1, 5)
        px, py = grid.centres[:, 0, None], grid.centres[:, 1, None]
        free = ~np.any((px > b[:, 0]) & (px < b[:, 2]) & (py > b[:, 1]) & (py < b[:, 3]),
                       axis=1)
    f2 = free.reshape(grid.ny, grid.nx)
    return LostGrid(grid, free, f2[:, 1:] & f2[:, :-1], f2[1:, :] & f2[:-1, :],
                    float(velocity_var), float(dt))


def initial_weights(lg: LostGrid, mean: FloatArray, cov: FloatArray) -> FloatArray:
    """Cell weights ``(C,)`` of a Gaussian track ``mean (4,)``, ``cov (4, 4)``: its position
    density smoothed by a cell's spread, at the free cells' centres, normalised. A track
    wholly inside closed cells gives the free cells nearest its mean."""
    g = lg.grid
    C = cov[:2, :2] + np.diag([g.cov[0, 0], g.cov[1, 1]])
    d = g.centres - mean[:2]
    q = np.einsum("ci,ci->c", d, np.linalg.solve(C, d.T).T)
    logw = np.where(lg.free, -0.5 * q, -np.inf)
    top = logw.max()
    if not math.isfinite(top):                                    # no free cell: none left
        raise ValueError("the lost-target grid has no free cell")
    w = np.exp(logw - top)
    return w / w.sum()


def diffuse(lg: LostGrid, weights: FloatArray, variance: float) -> FloatArray:
    """Weights ``(C,)`` after a random walk of ``variance`` (m^2 per axis) that never
    crosses a wall (the map's or a building's); the total weight is kept exactly."""
    g = lg.grid
    a, b = g.width / g.nx, g.height / g.ny
    w = np.array(weights, dtype=float).reshape(g.ny, g.nx)
    for axis, side, opened in ((1, a, lg.open_x), (0, b, lg.open_y)):
        s2 = variance / (side * side)                       # cells^2
        if s2 <= 0.0 or w.shape[axis] < 2:
            continue
        passes = max(1, math.ceil(s2 / (2.0 * MAX_KAPPA)))
        kappa = s2 / (2.0 * passes)
        for _ in range(passes):
            if axis == 1:
                flow = kappa * (w[:, :-1] - w[:, 1:]) * opened
                w[:, :-1] -= flow
                w[:, 1:] += flow
            else:
                flow = kappa * (w[:-1, :] - w[1:, :]) * opened
                w[:-1, :] -= flow
                w[1:, :] += flow
    return w.reshape(-1)


def step_variance(lg: LostGrid, n: int) -> float:
    """The diffusion of the ``n``-th step after the anchor (m^2 per axis):
    :math:`(2n - 1)\\,\\sigma_v^2 \\Delta t^2`."""
    return (2 * n - 1) * lg.velocity_var * lg.dt * lg.dt


def detect_probability(lg: LostGrid, table: FloatArray, sensor: int, sensor_xy: FloatArray,
                       heading: float, buildings: FloatArray | None,
                       gate_probability: float) -> FloatArray:
    """:math:`P_G P_d v(p_c)` at every cell centre ``(C,)``: the probability that a look
    gives a gated detection of a target there."""
    d = lg.grid.centres - np.asarray(sensor_xy, dtype=float)
    p = radar.detectable_points(table, np.array([sensor], dtype=np.int64), d[None, :, 0],
                                d[None, :, 1], np.array([float(heading)]),
                                np.asarray(sensor_xy, dtype=float)[None], buildings)[0]
    return gate_probability * p


def miss(lg: LostGrid, weights: FloatArray, detect: FloatArray) -> tuple[FloatArray, float]:
    """A missed look: weights ``(C,)`` thinned by ``detect`` ``(C,)`` and renormalised, and
    the grid's probability of the miss. A grid the look empties (it was sure the target was
    there: only without a gate) is replaced by the free cells the look did not cover,
    evenly."""
    w = thin(weights, detect)
    total = float(w.sum())
    if total > 0.0:
        return w / total, total
    w = (lg.free & (detect < 1.0)).astype(float)
    if not w.any():
        w = lg.free.astype(float)
    return w / w.sum(), 0.0


def moments(lg: LostGrid, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The grid density's mean ``(4,)`` and covariance ``(4, 4)`` (the mixture's)."""
    g = lg.grid
    m = weights @ g.centres
    d = g.centres - m
    mean = np.zeros(4)
    mean[:2] = m
    cov = np.array(g.cov, dtype=float)
    cov[:2, :2] += (weights[:, None] * d).T @ d
    return mean, 0.5 * (cov + cov.T)


def reacquire(lg: LostGrid, weights: FloatArray, z: FloatArray, sensor_xy: FloatArray,
              heading: float, table: FloatArray, sensor: int, gate: float | None
              ) -> tuple[FloatArray, FloatArray] | None:
    """The Gaussian of the grid's posterior given detection ``z`` ``(2,)`` (moment matched),
    or None when no cell with weight passes the gate ``gate`` (chi-square value; None:
    every cell)."""
    cells = np.flatnonzero(weights > 0.0)
    if cells.size == 0:
        return None
    means, covs = lg.grid.cell_states()
    x = means[cells]
    P = np.array(covs[cells])
    B = len(cells)
    zs = np.broadcast_to(np.asarray(z, dtype=float), (B, 2)).copy()
    sxy = np.broadcast_to(np.asarray(sensor_xy, dtype=float), (B, 2))
    hd = np.full(B, float(heading))
    sr = np.full(B, int(sensor), dtype=np.int64)
    nu, S, Hp, var = innovations(x, P, zs, sxy, hd, table, sr)
    d2 = mahalanobis2(nu, S)
    ok = np.ones(B, dtype=bool) if gate is None else d2 < gate
    if not ok.any():
        return None
    logl = -0.5 * d2[ok] - 0.5 * np.linalg.slogdet(S[ok])[1] + np.log(weights[cells[ok]])
    w = np.exp(logl - logl.max())
    w /= w.sum()
    xn, Pn = position_update(x[ok], P[ok], nu[ok], Hp[ok], var[ok])
    mean = w @ xn
    dev = xn - mean
    cov = np.einsum("b,bij->ij", w, Pn) + (w[:, None] * dev).T @ dev
    return mean, 0.5 * (cov + cov.T)


@dataclass
class MissLog:
    """The missed looks at one target since its anchor: the step after the anchor each was
    made at, and the look."""

    steps: list[int]
    sensors: list[int]
    positions: list[FloatArray]
    headings: list[float]

    @classmethod
    def empty(cls) -> MissLog:
        return cls([], [], [], [])

    def add(self, step: int, sensor: int, xy: FloatArray, heading: float) -> None:
        self.steps.append(int(step))
        self.sensors.append(int(sensor))
        self.positions.append(np.array(xy, dtype=float))
        self.headings.append(float(heading))


def replay(lg: LostGrid, anchor_mean: FloatArray, anchor_cov: FloatArray, n: int,
           log: MissLog, table: FloatArray, buildings: FloatArray | None,
           gate_probability: float) -> FloatArray:
    """The grid of a track from its anchor, predicted ``n`` steps with each step's missed
    looks (``log``) applied after that step's prediction, in order."""
    w = initial_weights(lg, anchor_mean, anchor_cov)
    k = 0
    for step in range(1, n + 1):
        w = diffuse(lg, w, step_variance(lg, step))
        while k < len(log.steps) and log.steps[k] == step:
            det = detect_probability(lg, table, log.sensors[k], log.positions[k],
                                     log.headings[k], buildings, gate_probability)
            w, _ = miss(lg, w, det)
            k += 1
    return w


__all__ = ["LostGrid", "MissLog", "detect_probability", "diffuse", "initial_weights",
           "make_lost_grid", "miss", "moments", "reacquire", "replay", "step_variance",
           "velocity_variance"]
