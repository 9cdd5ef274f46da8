r"""Scripted truths of published multi-target tracking benchmarks.

A scripted truth fixes each target's birth and death step and a recipe for its trajectory,
as its source does, instead of drawing births and deaths at random
(:mod:`sensorplan.models.population`). Every parameter of a benchmark is in one place, its
:class:`Williams15` or :class:`Vo12` instance (:data:`BENCHMARKS`), documented with its
source. Values the source does not state are marked **choice**.

Steps: the source's scan ``k = 1, 2, ...`` is step ``k`` here; step 0 is before the first
scan. A target is alive at step ``t`` iff ``birth_step <= t < death_step``; ``death_step =
-1`` means it lives to the end. States are ``[x, y, vx, vy]`` (the sources write
``[x, vx, y, vy]``) on the map ``[0, W] x [0, H]``; targets are not mirrored at the map's
walls (the sources have none) and stay alive if they leave it.

``williams15``
    J. L. Williams, "Marginal multi-Bernoulli filters: RFS derivation of MHT, JIPDA and
    association-based MeMBer", IEEE Trans. Aerospace and Electronic Systems 51(3), 2015,
    simulation section, as implemented by A. F. García-Fernández's MATLAB code
    (github.com/Agarciafernandez/MTT, ``PMBM filter/ScenarioWilliams15.m`` and
    ``TrajectoryWilliams15.m``, "modified from the source files in arXiv:1203.2995"):
    4 targets, 81 steps, 300 x 300 m. At the midpoint, step 41, every target's state is
    drawn from ``N([150, 150, 0, 0], 0.1 I)``, so they coalesce there; the trajectories are
    then run forward and backward from it with the CWNA model ``q = 0.01`` (``x_{t+1} = F
    x_t + w``, backward ``x_{t-1} = F^{-1} (x_t + w)``, one forward then one backward draw
    per step away from the midpoint). All 4 are present from step 1; target 0 dies at the
    midpoint (absent from step 41 on: the source's ``t_death = (Nsteps + 1) / 2``).
    **Redrawn per run: no.** The source draws the trajectories once per experiment (with
    MATLAB's ``randn('seed', 9)``, which numpy cannot reproduce) and redraws only the
    measurements per Monte Carlo run; here they are drawn once from
    ``numpy.random.default_rng(Williams15.truth_seed)`` (**choice**: seed 0).
``vo12``
    The linear-Gaussian example of B.-N. Vo and W.-K. Ma, "The Gaussian mixture probability
    hypothesis density filter" (IEEE Trans. Signal Processing 54(11), 2006) and of the
    CPHD / GLMB papers of B.-T. Vo, B.-N. Vo and co-authors, as defined by their RFS
    tracking toolbox (ba-tuong.vo-au.com/codes.html; ``gms/gen_truth.m`` and
    ``gms/gen_model.m``): 12 targets, 100 steps, the region ``[-1000, 1000]^2`` (shifted
    here by +1000 m on both axes to ``[0, 2000]^2``), born at steps 1, 1, 1, 20, 20, 20,
    40, 40, 60, 60, 80, 80 at the four birth sites ``(0, 0), (400, -600), (-800, -200),
    (-200, 800)``; targets 0 and 2 are last present at step 70. The recorded state at the
    birth step is the start state moved once (``targetstate = gen_newstate_fn(...)`` comes
    before it is stored). The toolbox generates the truth **noiseless** (constant
    velocity); its filter model is discrete white-noise acceleration with ``sigma_v = 5``
    m/s^2 (``Q = sigma_v^2 B B^T``, ``B = [T^2/2; T]`` per axis), available here as
    ``Vo12.truth_sigma_v`` (0: the source's noiseless truth). **Redrawn per run: no** (the
    truth is deterministic).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from .motion import cv_matrices


@dataclass(frozen=True)
class _Benchmark:
    """What both benchmarks share, with the values both sources use.

    Attributes
    ----------
    dt : float          s, the source's ``T``
    redraw : bool       False: the same truth in every run
    truth_seed : int    numpy seed of a truth that is random but not redrawn
    p_survive : float   the source filter's probability that a target survives a step
    """

    dt: float = 1.0
    redraw: bool = False
    truth_seed: int = 0
    p_survive: float = 0.99


@dataclass(frozen=True)
class Williams15(_Benchmark):
    """The ``williams15`` benchmark (see the module docstring for the source).

    Attributes
    ----------
    world_size : (W, H)            m; the source's ``Area = [300 300]``
    steps : int                    the source's ``Nsteps`` (odd)
    dt : float                     s, the source's ``T``
    n_targets : int                the source's ``numtruth``
    mid_mean : (4,)                ``[x, y, vx, vy]`` mean at the midpoint: the area's centre
    mid_cov : float                the midpoint covariance ``Pmid = 0.1 I``
    q : float                      CWNA intensity of ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]``
                                   per axis (m^2/s^3)
    birth_step, death_step : (4,)  targets present from step 1; target 0 absent from 41
    redraw : bool                  False: the same trajectories in every run
    truth_seed : int               numpy seed of those trajectories (**choice**)

    The source's filter and sensor settings, recorded here for the presets that use them
    (not used by the truth): ``p_detect = 0.9``, ``p_survive = 0.99``, ``clutter = 10`` false
    alarms per scan uniform over the area, ``R = I`` (m^2, position measurements),
    ``gospa_c = 10`` m (GOSPA with p = 2, alpha = 2), birth intensity ``birth_weight =
    0.005`` per step with mean ``birth_mean`` and covariance ``diag(birth_std)^2``, and an
    initial Poisson intensity of ``initial_weight = 3`` with the same density.
    """

    world_size: tuple[float, float] = (300.0, 300.0)
    steps: int = 81
    n_targets: int = 4
    mid_mean: tuple[float, float, float, float] = (150.0, 150.0, 0.0, 0.0)
    mid_cov: float = 0.1
    q: float = 0.01
    birth_step: tuple[int, ...] = (1, 1, 1, 1)
    death_step: tuple[int, ...] = (41, -1, -1, -1)
    p_detect: float = 0.9
    clutter: float = 10.0
    measurement_var: float = 1.0
    gospa_c: float = 10.0
    birth_weight: float = 0.005
    birth_mean: tuple[float, float, float, float] = (100.0, 100.0, 0.0, 0.0)
    birth_std: tuple[float, float, float, float] = (150.0, 150.0, 1.0, 1.0)
    initial_weight: float = 3.0

    @property
    def midpoint(self) -> int:
        """The step at which the targets coalesce, ``(steps + 1) / 2`` = 41."""
        return (self.steps + 1) // 2


@dataclass(frozen=True)
class Vo12(_Benchmark):
    """The ``vo12`` benchmark (see the module docstring for the source).

    The ``source_*`` fields are the toolbox's values as written there (its coordinates and
    its state order ``[x, vx, y, vy]``); the properties turn them into this package's.

    Attributes
    ----------
    world_size : (W, H)           m; the source's region ``[-1000, 1000]^2``
    offset : (2,)                 m added to the source's positions
    steps : int                   the source's ``K``
    dt : float                    s, the source's ``T``
    source_xstart : (12, 4)       the source's ``xstart``: ``[x, vx, y, vy]`` before the
                                  birth step
    source_tbirth : (12,)         the source's ``tbirth``: first step present
    source_tdeath : (12,)         the source's ``tdeath``: last step present (``K + 1``:
                                  to the end)
    truth_sigma_v : float         m/s^2 of DWNA noise in the truth (0: the source's
                                  noiseless truth)
    redraw : bool                 False: the same truth in every run (deterministic)
    truth_seed : int              numpy seed of a noisy truth that is not redrawn

    The source's filter and sensor settings, recorded here for the presets that use them
    (not used by the truth): ``sigma_v = 5`` (DWNA filter model), ``p_survive = 0.99``,
    ``p_detect = 0.98``, ``R = 100 I`` (``measurement_var``, m^2), birth intensity: four
    Gaussian components of weight ``birth_weight = 0.03`` each at ``source_birth_sites``
    with zero velocity and covariance ``diag(birth_std)^2``. The clutter rate is not fixed
    here: the toolbox's GM-PHD demo uses 60 false alarms per scan, its CPHD demo 50.
    """

    world_size: tuple[float, float] = (2000.0, 2000.0)
    offset: tuple[float, float] = (1000.0, 1000.0)
    steps: int = 100
    source_xstart: tuple[tuple[float, float, float, float], ...] = (
        (0.0, 0.0, 0.0, -10.0),
        (400.0, -10.0, -600.0, 5.0),
        (-800.0, 20.0, -200.0, -5.0),
        (400.0, -7.0, -600.0, -4.0),
        (400.0, -2.5, -600.0, 10.0),
        (0.0, 7.5, 0.0, -5.0),
        (-800.0, 12.0, -200.0, 7.0),
        (-200.0, 15.0, 800.0, -10.0),
        (-800.0, 3.0, -200.0, 15.0),
        (-200.0, -3.0, 800.0, -15.0),
        (0.0, -20.0, 0.0, -15.0),
        (-200.0, 15.0, 800.0, -5.0),
    )
    source_tbirth: tuple[int, ...] = (1, 1, 1, 20, 20, 20, 40, 40, 60, 60, 80, 80)
    source_tdeath: tuple[int, ...] = (70, 101, 70, 101, 101, 101, 101, 101, 101, 101, 101,
                                      101)
    truth_sigma_v: float = 0.0
    sigma_v: float = 5.0
    p_detect: float = 0.98
    measurement_var: float = 100.0
    birth_weight: float = 0.03
    source_birth_sites: tuple[tuple[float, float], ...] = (
        (0.0, 0.0), (400.0, -600.0), (-800.0, -200.0), (-200.0, 800.0))
    birth_std: tuple[float, float, float, float] = (10.0, 10.0, 10.0, 10.0)

    @property
    def start(self) -> FloatArray:
        """``(12, 4)`` start states ``[x, y, vx, vy]`` on this package's map."""
        x = np.array(self.source_xstart)[:, [0, 2, 1, 3]]
        x[:, :2] += self.offset
        return x

    @property
    def birth_step(self) -> tuple[int, ...]:
        return self.source_tbirth

    @property
    def death_step(self) -> tuple[int, ...]:
        """First step absent (``tdeath + 1``), -1 for targets present to the end."""
        return tuple(-1 if d > self.steps else d + 1 for d in self.source_tdeath)

    @property
    def birth_sites(self) -> FloatArray:
        """``(4, 2)`` birth-site positions on this package's map."""
        return np.array(self.source_birth_sites) + self.offset


WILLIAMS15 = Williams15()
VO12 = Vo12()
#: The scripted benchmarks by name (a scenario's ``scripted`` key).
BENCHMARKS: dict[str, Williams15 | Vo12] = {"williams15": WILLIAMS15, "vo12": VO12}


def dwna_matrices(dt: float) -> tuple[FloatArray, FloatArray]:
    r"""Transition ``F (4, 4)`` and noise gain ``B (4, 2)`` of the discrete white-noise
    acceleration model, ``x' = F x + B a``, ``a ~ N(0, sigma_v^2 I_2)``, so that
    ``Q = sigma_v^2 B B^T`` with ``B = [[dt^2/2, 0], [0, dt^2/2], [dt, 0], [0, dt]]``."""
    F, _ = cv_matrices(dt, 0.0)
    B = np.array([[dt**2 / 2, 0.0], [0.0, dt**2 / 2], [dt, 0.0], [0.0, dt]])
    return F, B


def forward_trajectories(start: FloatArray, birth_step: IntArray, steps: int, dt: float,
                         sigma_v: float = 0.0, rng: np.random.Generator | None = None
                         ) -> FloatArray:
    """Trajectories ``(steps + 1, M, 4)`` started before each birth step and moved forward.

    Target ``j``'s state at step ``birth_step[j]`` is ``F start[j] + B a``, then ``F x + B a``
    each step (DWNA, :func:`dwna_matrices`; no noise when ``sigma_v = 0``, and ``rng`` is
    not used). Rows before a target's birth are NaN. Draws (``sigma_v > 0``): at each step
    from 1 on, one ``(2,)`` normal per target alive from then, in target order.
    """
    x0 = np.asarray(start, dtype=float)
    born = np.asarray(birth_step, dtype=np.int64)
    F, B = dwna_matrices(dt)
    out = np.full((steps + 1, len(x0), 4), np.nan)
    x = x0.copy()
    for t in range(1, steps + 1):
        moving = born <= t
        step = x[moving] @ F.T
        if sigma_v > 0.0:
            if rng is None:
                raise ValueError("a noisy truth needs a generator")
            step = step + sigma_v * rng.standard_normal((int(moving.sum()), 2)) @ B.T
        x[moving] = step
        out[t, moving] = step
    return out


def midpoint_trajectories(n: int, mean: FloatArray, cov: float, midpoint: int, steps: int,
                          dt: float, q: float, rng: np.random.Generator) -> FloatArray:
    """Trajectories ``(steps + 1, n, 4)`` drawn at ``midpoint`` and run both ways.

    The states at ``midpoint`` are ``N(mean, cov I)``; for ``s = 1 .. midpoint - 1`` the
    forward ones move ``x <- F x + w`` to step ``midpoint + s`` and the backward ones
    ``x <- F^{-1} (x + w)`` to ``midpoint - s``, ``w ~ N(0, Q)`` (CWNA with ``q``), one
    ``(n, 4)`` forward then one backward draw per ``s``. Row 0 (before the first scan) is
    NaN. ``steps`` must be ``2 midpoint - 1``.
    """
    if steps != 2 * midpoint - 1:
        raise ValueError(f"steps must be 2 midpoint - 1 = {2 * midpoint - 1}, got {steps}")
    F, Q = cv_matrices(dt, q)
    Finv, _ = cv_matrices(-dt, 0.0)
    L = np.linalg.cholesky(Q) if q > 0 else np.zeros((4, 4))
    out = np.full((steps + 1, n, 4), np.nan)
    x = np.asarray(mean, dtype=float) + np.sqrt(cov) * rng.standard_normal((n, 4))
    out[midpoint] = x
    xf, xb = x.copy(), x.copy()
    for s in range(1, midpoint):
        xf = xf @ F.T + rng.standard_normal((n, 4)) @ L.T
        xb = (xb + rng.standard_normal((n, 4)) @ L.T) @ Finv.T
        out[midpoint + s] = xf
        out[midpoint - s] = xb
    return out


class ScriptedTruth:
    """Replays scripted trajectories as a population (same attributes and :meth:`step` as
    :class:`~sensorplan.models.population.PopulationTruth`).

    Parameters
    ----------
    trajectories : (S + 1, M, 4)
        Each target's state at every step (rows outside its life are not used).
    birth_step : (M,) int, ascending   its slots follow the birth order
    death_step : (M,) int              first step absent, -1: alive to the end

    A slot exists from its birth step; a dead slot keeps its last live state. Stepping past
    step ``S`` raises ``ValueError``.
    """

    def __init__(self, trajectories: FloatArray, birth_step: IntArray | tuple[int, ...],
                 death_step: IntArray | tuple[int, ...]) -> None:
        traj = np.array(trajectories, dtype=float)
        born = np.asarray(birth_step, dtype=np.int64)
        dies = np.asarray(death_step, dtype=np.int64)
        S1, M = traj.shape[:2]
        if traj.shape != (S1, M, 4) or born.shape != (M,) or dies.shape != (M,):
            raise ValueError("trajectories (S + 1, M, 4), birth_step (M,) and death_step "
                             "(M,) must agree")
        if np.any(np.diff(born) < 0) or np.any(born < 0):
            raise ValueError("birth steps must be >= 0 and ascending (slots follow births)")
        if np.any((dies != -1) & (dies <= born)):
            raise ValueError("a target must die after its birth step")
        end = np.where(dies == -1, S1, np.minimum(dies, S1))
        # A dead target's rows from its death on repeat its last live state.
        for j in np.flatnonzero(end < S1):
            traj[end[j]:, j] = traj[end[j] - 1, j]
        self._traj = traj
        self._born = born
        self._dies = dies
        self.steps = S1 - 1
        self.step_index = -1
        self.step()

    def _at(self, t: int) -> tuple[FloatArray, BoolArray]:
        n = int(np.sum(self._born <= t))
        alive = (self._dies[:n] == -1) | (t < self._dies[:n])
        return self._traj[t, :n].copy(), alive

    def step(self) -> tuple[FloatArray, BoolArray]:
        """Advance one step; return ``states (M_t, 4)`` and ``alive (M_t,)`` for the
        ``M_t`` targets born so far."""
        t = self.step_index + 1
        if t > self.steps:
            raise ValueError(f"the scripted truth has {self.steps} steps")
        self.states, self.alive = self._at(t)
        n = len(self.alive)
        self.birth_step = self._born[:n].copy()
        self.death_step = np.where((self._dies[:n] != -1) & (self._dies[:n] <= t),
                                   self._dies[:n], -1)
        self.step_index = t
        return self.states, self.alive


def scripted_truth(name: str, rng: np.random.Generator | None = None) -> ScriptedTruth:
    """The scripted truth of benchmark ``name`` (:data:`BENCHMARKS`).

    ``rng`` (the run's truth generator) is used only by a benchmark whose truth is redrawn
    per run; neither built-in one is (``williams15`` draws from its fixed ``truth_seed``,
    ``vo12`` is noiseless).
    """
    bench = BENCHMARKS[name]
    if bench.redraw and rng is None:
        raise ValueError(f"{name} is redrawn per run: pass the run's truth generator")
    draw = rng if bench.redraw and rng is not None else np.random.default_rng(
        bench.truth_seed)
    if isinstance(bench, Williams15):
        traj = midpoint_trajectories(bench.n_targets, np.array(bench.mid_mean), bench.mid_cov,
                                     bench.midpoint, bench.steps, bench.dt, bench.q, draw)
    else:
        traj = forward_trajectories(bench.start, np.array(bench.birth_step), bench.steps,
                                    bench.dt, bench.truth_sigma_v, draw)
    return ScriptedTruth(traj, bench.birth_step, bench.death_step)
