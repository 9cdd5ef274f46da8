r"""The Poisson intensity of targets that exist but have never been detected, on a grid.

The map :math:`[0, W] \times [0, H]` is cut into ``nx = ceil(W / d)`` columns and
``ny = ceil(H / d)`` rows of equal cells (``d`` the resolution, so a cell is at most
``d`` wide). The undetected intensity is a Gaussian mixture with one component per cell
``c``,

.. math::
    D_u(x) = \sum_c w_c\, N(x;\ [p_c, 0],\ P_u),\qquad
    P_u = \mathrm{diag}(a^2/12,\ b^2/12,\ \sigma_v^2,\ \sigma_v^2),

with :math:`p_c` the cell's centre, :math:`a \times b` its size (a position variance equal
to a uniform distribution's over the cell) and a velocity prior of mean zero and variance
:math:`\sigma_v^2` per axis. :math:`w_c` is the expected number of undetected targets in
the cell. (A PMB tracker with edge births may give the boundary cells the velocity of a
target born there heading inward instead: :func:`cell_velocities`.)

- **Predict**: :math:`w_c \leftarrow p_S\, w_c + b_c` with :math:`b_c` the expected number
  of births in the cell per step (:func:`birth_intensity`). The components keep their
  means and covariance: the intensity does not drift or spread with the motion model (an
  approximation; the exact prediction would widen each component by the motion model's
  step and correlate position with velocity).
- **Thinning by a look**: a look that covers the cell and could have detected a target
  there makes it less likely that one is hiding there,
  :math:`w_c \leftarrow w_c\, (1 - P_d(p_c)\, v(p_c))`, with :math:`v = 1` when the
  cell's centre lies in the look's sensing region and in sight, else 0 (both evaluated at
  the centre only).
- **Detection weight**: a detection :math:`z` of the look has the undetected intensity's
  weight :math:`\lambda_u(z) = \sum_c w_c P_d(p_c) v(p_c)\, N(z;\ h(p_c),\ S_c)`, with
  :math:`S_c = H_c P_u H_c^T + R_c` linearised at the centre, summed over the cells whose
  innovation passes the tracker's gate.
- **Recycling** (:func:`recycle`): a Bernoulli of low existence :math:`r` with position
  density :math:`N(m, P)` is approximated as a Poisson component and added:
  :math:`w_c \leftarrow w_c + r\, M_c / \sum_{c'} M_{c'}`, with :math:`M_c` the mass of
  :math:`N(m, P)` in cell ``c``. The grid's total rises by exactly :math:`r`: the mass
  the Gaussian puts off the map is spread over the map in proportion (its position
  density truncated to the map), because the tracker's prediction has already charged the
  map's edge to :math:`r` (``exit``) or reflected the density back in (``closed``). Cells
  inside buildings receive their mass as they receive births (the grid does not model
  buildings; a look cannot thin a cell it does not see). The deposit keeps the position
  mean; its covariance is :math:`P` plus twice a cell's
  (:math:`\mathrm{diag}(a^2/6, b^2/6)`: the cells' own :math:`P_u` and the grouping of the
  mass at the centres, Sheppard's correction), and its velocity is the grid's prior.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

from ..._types import FloatArray

_TINY = float(np.finfo(float).tiny)

#: Kinds of birth intensity :func:`birth_intensity` spreads a birth rate over.
BIRTHS = ("none", "edges", "uniform")


@dataclass(frozen=True)
class Grid:
    """The cells of the undetected intensity (see the module docstring).

    Attributes
    ----------
    width, height : float         the map ``[0, W] x [0, H]`` (m)
    nx, ny : int                  columns and rows of cells
    centres : (C,) x 2 -> (C, 2)  cell centres, row-major (``c = row * nx + column``), m
    cov : (4, 4)                  :math:`P_u`, every component's covariance
    """

    width: float
    height: float
    nx: int
    ny: int
    centres: FloatArray
    cov: FloatArray

    @property
    def size(self) -> int:
        """Number of cells C."""
        return self.nx * self.ny

    def cell_states(self) -> tuple[FloatArray, FloatArray]:
        """Each cell's component as a state density: means ``(C, 4)`` (the centre, at rest)
        and covariances ``(C, 4, 4)`` (:attr:`cov`, a read-only broadcast view)."""
        means = np.zeros((self.size, 4))
        means[:, :2] = self.centres
        return means, np.broadcast_to(self.cov, (self.size, 4, 4))

    @property
    def cell_area(self) -> float:
        """Area of one cell (m^2)."""
        return self.width * self.height / self.size


def make_grid(width: float, height: float, resolution: float, velocity_var: float) -> Grid:
    """The grid of cells at most ``resolution`` m wide over ``[0, W] x [0, H]``.

    Parameters
    ----------
    width, height : float > 0     map size (m)
    resolution : float > 0        largest cell side (m)
    velocity_var : float > 0      :math:`\\sigma_v^2`, each velocity component's prior
                                  variance (m^2/s^2)

    Examples
    --------
    >>> g = make_grid(600.0, 600.0, 25.0, 10.5)
    >>> g.nx, g.ny, g.centres[0].tolist(), float(g.cov[0, 0])
    (24, 24, [12.5, 12.5], 52.083333333333336)
    """
    for name, v in (("width", width), ("height", height), ("resolution", resolution),
                    ("velocity_var", velocity_var)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{name} must be > 0, got {v!r}")
    nx = max(1, math.ceil(width / resolution - 1e-9))
    ny = max(1, math.ceil(height / resolution - 1e-9))
    a, b = width / nx, height / ny
    cx = (np.arange(nx) + 0.5) * a
    cy = (np.arange(ny) + 0.5) * b
    centres = np.column_stack([np.tile(cx, ny), np.repeat(cy, nx)])
    cov = np.diag([a * a / 12.0, b * b / 12.0, float(velocity_var), float(velocity_var)])
    centres.flags.writeable = False
    cov.flags.writeable = False
    return Grid(float(width), float(height), nx, ny, centres, cov)


def birth_intensity(grid: Grid, kind: str, rate: float) -> FloatArray:
    """Expected births per step in each cell, ``(C,)``, summing to ``rate``.

    Parameters
    ----------
    grid : Grid
    kind : {"none", "edges", "uniform"}
        ``none``: no births; ``edges``: spread evenly over the cells on the map's boundary
        (the targets of edge births enter there); ``uniform``: spread in proportion to area
        over every cell (all cells are equal, so evenly).
    rate : float >= 0
        Expected births per step over the whole map.

    Examples
    --------
    >>> g = make_grid(100.0, 100.0, 25.0, 1.0)
    >>> b = birth_intensity(g, "edges", 1.2)
    >>> int((b > 0).sum()), float(b.sum())
    (12, 1.2)
    """
    if kind not in BIRTHS:
        raise ValueError(f"births must be one of {BIRTHS}, got {kind!r}")
    if not (math.isfinite(rate) and rate >= 0.0):
        raise ValueError(f"birth rate must be >= 0, got {rate!r}")
    out = np.zeros(grid.size)
    if kind == "none" or rate == 0.0:
        return out
    if kind == "uniform":
        out[:] = rate / grid.size
        return out
    col = np.tile(np.arange(grid.nx), grid.ny)
    row = np.repeat(np.arange(grid.ny), grid.nx)
    edge = (col == 0) | (col == grid.nx - 1) | (row == 0) | (row == grid.ny - 1)
    out[edge] = rate / int(edge.sum())
    return out


#: The velocity priors of the cells: :func:`cell_velocities`.
BIRTH_VELOCITIES = ("isotropic", "inward")


def cell_velocities(grid: Grid, speed_range: tuple[float, float]
                    ) -> tuple[FloatArray, FloatArray]:
    r"""Each cell's velocity prior ``(C, 2)`` means and ``(C, 2, 2)`` covariances when
    targets are born on the map's boundary heading inward (the ``edges`` births of a
    truth: the side's inward normal :math:`n` plus an angle uniform in
    :math:`(-\pi/2, \pi/2)`, a speed :math:`s` uniform in ``speed_range``).

    A boundary cell's prior is those births' velocity moments: along :math:`n` the mean
    :math:`rac{2}{\pi} E[s]` and the variance :math:`E[s^2]/2 - (rac{2}{\pi}E[s])^2`,
    along the side the mean 0 and the variance :math:`E[s^2]/2`. A corner cell mixes its
    two sides' priors (moment matched) with weights in proportion to its extent along
    each (births are uniform over the perimeter by length). Every other cell keeps the
    isotropic prior: mean 0, variance :math:`E[s^2]/2` per axis (:attr:`Grid.cov`'s).

    Examples
    --------
    >>> g = make_grid(100.0, 100.0, 25.0, 10.5)
    >>> m, P = cell_velocities(g, (3.0, 6.0))
    >>> [round(float(v), 3) for v in m[1]], round(float(P[1, 1, 1]), 3)   # bottom side
    ([0.0, 2.865], 2.293)
    >>> m[5].tolist(), P[5].tolist()                                       # inside
    ([0.0, 0.0], [[10.5, 0.0], [0.0, 10.5]])
    """
    lo, hi = (float(v) for v in speed_range)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi):
        raise ValueError(f"speed_range must be (lo, hi) with 0 <= lo <= hi, got "
                         f"{speed_range!r}")
    mean_s, mean_s2 = 0.5 * (lo + hi), (lo * lo + lo * hi + hi * hi) / 3.0
    mu = 2.0 / math.pi * mean_s
    across, along = 0.5 * mean_s2 - mu * mu, 0.5 * mean_s2
    C = grid.size
    means = np.zeros((C, 2))
    covs = np.broadcast_to(along * np.eye(2), (C, 2, 2)).copy()
    col = np.tile(np.arange(grid.nx), grid.ny)
    row = np.repeat(np.arange(grid.ny), grid.nx)
    a, b = grid.width / grid.nx, grid.height / grid.ny
    # Each side: its cells, its inward normal, and a cell's extent along it.
    sides = ((row == 0, (0.0, 1.0), a), (col == grid.nx - 1, (-1.0, 0.0), b),
             (row == grid.ny - 1, (0.0, -1.0), a), (col == 0, (1.0, 0.0), b))
    weight = np.zeros(C)
    first = np.zeros((C, 2))
    second = np.zeros((C, 2, 2))
    for cells, normal, extent in sides:
        n = np.array(normal)
        t = np.array([-n[1], n[0]])
        m = mu * n
        P = across * np.outer(n, n) + along * np.outer(t, t)
        weight[cells] += extent
        first[cells] += extent * m
        second[cells] += extent * (P + np.outer(m, m))
    edge = weight > 0.0
    means[edge] = first[edge] / weight[edge, None]
    covs[edge] = (second[edge] / weight[edge, None, None]
                  - np.einsum("ci,cj->cij", means[edge], means[edge]))
    return means, covs


def predict(weights: FloatArray, survival_probability: float, births: FloatArray
            ) -> FloatArray:
    """:math:`p_S w + b`, ``(C,)``: survival, then the step's births."""
    return survival_probability * weights + births


def thin(weights: FloatArray, detect: FloatArray) -> FloatArray:
    """:math:`w_c (1 - P_d(p_c) v(p_c))`, ``(C,)``: what a look that detected nothing of a
    cell's targets leaves of its intensity (``detect`` is :math:`P_d v` at each centre)."""
    return weights * (1.0 - detect)


#: Gauss-Legendre nodes and weights on [-1, 1] of each column's integral in :func:`cell_masses`.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)


def cell_masses(grid: Grid, means: FloatArray, covs: FloatArray) -> FloatArray:
    r"""Probability mass of each position Gaussian in each cell, ``(K, C)`` (row-major).

    The mass in column ``i`` (``x`` in :math:`[x_i, x_{i+1}]`) and row ``j`` is
    :math:`\int_{x_i}^{x_{i+1}} N(x; m_x, P_{xx})\, [\Phi(\frac{y_{j+1} - \mu(x)}{s})
    - \Phi(\frac{y_j - \mu(x)}{s})]\, dx`, with :math:`y` given :math:`x` Gaussian of mean
    :math:`\mu(x) = m_y + P_{xy} / P_{xx}\, (x - m_x)` and variance
    :math:`s^2 = P_{yy} - P_{xy}^2 / P_{xx}`. It is integrated over
    :math:`t = \Phi((x - m_x) / \sqrt{P_{xx}})` by 8-point Gauss-Legendre on each column's
    interval of ``t``: exact (to rounding) when :math:`P_{xy} = 0`, where the bracket does
    not depend on ``x``; the tests bound the error of correlated ones.

    Parameters
    ----------
    grid : Grid
    means : (K, 2) float64      position means (m)
    covs : (K, 2, 2) float64    position covariances (m^2), positive definite

    Returns
    -------
    (K, C) float64   masses in [0, 1]; a row sums to the Gaussian's mass on the map
    """
    means = np.asarray(means, dtype=float).reshape(-1, 2)
    covs = np.asarray(covs, dtype=float).reshape(-1, 2, 2)
    K = len(means)
    xs = np.linspace(0.0, grid.width, grid.nx + 1)
    ys = np.linspace(0.0, grid.height, grid.ny + 1)
    pxx = np.maximum(covs[:, 0, 0], _TINY)
    pxy, pyy = covs[:, 0, 1], covs[:, 1, 1]
    sx = np.sqrt(pxx)
    beta = pxy / pxx
    s = np.sqrt(np.maximum(pyy - pxy * beta, np.maximum(1e-12 * pyy, _TINY)))
    tx = ndtr((xs[None, :] - means[:, :1]) / sx[:, None])                  # (K, nx + 1)
    lo, width = tx[:, :-1], np.diff(tx, axis=1)                             # (K, nx)
    t = lo[..., None] + 0.5 * width[..., None] * (_GL_NODES + 1.0)         # (K, nx, 8)
    wq = 0.5 * width[..., None] * _GL_WEIGHTS                               # (K, nx, 8)
    u = np.clip(ndtri(np.clip(t, _TINY, 1.0 - 1e-16)), -40.0, 40.0)
    mu = means[:, 1, None, None] + beta[:, None, None] * sx[:, None, None] * u
    ty = ndtr((ys - mu[..., None]) / s[:, None, None, None])               # (K, nx, 8, ny+1)
    mass = np.einsum("kxn,kxny->kyx", wq, np.diff(ty, axis=-1))            # (K, ny, nx)
    return np.clip(mass.reshape(K, -1), 0.0, 1.0)


def recycle(grid: Grid, r: FloatArray, means: FloatArray, covs: FloatArray) -> FloatArray:
    """The intensity ``(C,)`` that Bernoullis of existence ``r (K,)`` and position densities
    ``N(means (K, 2), covs (K, 2, 2))`` become on the cells: each one's cell masses
    (:func:`cell_masses`) scaled to sum to its ``r`` (see the module docstring). A
    Gaussian with no mass on the map that floating point can hold puts its ``r`` in the
    cell nearest its mean (a mass on the map below the smallest normal double counts as
    none). The result sums to ``r.sum()`` up to rounding."""
    r = np.asarray(r, dtype=float).reshape(-1)
    out = np.zeros(grid.size)
    if r.size == 0:
        return out
    masses = cell_masses(grid, means, covs)                                 # (K, C)
    on_map = masses.sum(axis=1)
    # A subnormal mass on the map (a tight Gaussian just off it, where the tails cancel)
    # is no mass: dividing r by it overflows, and its few bits are rounding. From the
    # smallest normal double on, r / on_map is finite and each product at most r.
    some = on_map >= np.finfo(float).tiny
    out += (r[some] / on_map[some]) @ masses[some]
    if not some.all():
        m = np.asarray(means, dtype=float).reshape(-1, 2)[~some]
        col = np.clip((m[:, 0] / grid.width * grid.nx).astype(np.int64), 0, grid.nx - 1)
        row = np.clip((m[:, 1] / grid.height * grid.ny).astype(np.int64), 0, grid.ny - 1)
        np.add.at(out, row * grid.nx + col, r[~some])
    return out


__all__ = ["BIRTHS", "BIRTH_VELOCITIES", "Grid", "birth_intensity", "cell_masses",
           "cell_velocities", "make_grid", "predict", "recycle", "thin"]
