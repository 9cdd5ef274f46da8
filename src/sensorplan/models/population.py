r"""Targets that are born and die: a population of slots over the truth model.

A target gets a **slot** when it is born: the next free index, never reused. The population
keeps ``(M_max, 4)`` states, an ``alive (M_max,)`` mask and each slot's ``birth_step`` and
``death_step``; ``M_max`` grows with every birth. At step ``t`` a slot is alive iff
``birth_step <= t`` and it has not died (``death_step`` is ``-1`` until it dies, then the
first step at which it is gone). A dead slot keeps its last live state. Initial targets are
born at step 0.

One step ``t`` (:meth:`PopulationTruth.step`), in this order:

1. **Deaths by survival**: each live target survives with probability
   ``survival_probability`` (one uniform per live target, in slot order; none are drawn when
   it is 1). The dead do not move.
2. **Motion**: the survivors move as in :class:`~sensorplan.models.truth.TruthModel` (``cv`` or
   ``dubins``, buildings reflect).
3. **Deaths at the walls** (``edges`` only): a target whose position left the map
   ``[0, W] x [0, H]`` dies (a point on a wall is inside). With ``none`` and ``uniform`` the
   walls mirror targets back inside, as they always did, so the count of ``uniform`` births
   is kept finite by survival alone.
4. **Births**: a Poisson number of targets with mean ``birth_rate``, at their birth states
   (they move from the next step on):

   - ``edges``: uniform over the map's perimeter (by length), heading uniform over the
     inward half-plane (the inward normal plus a uniform angle in (-pi/2, pi/2)), speed
     uniform in ``speed_range`` (as initial targets draw theirs);
   - ``uniform``: uniform over the map, redrawn while strictly inside a building, speed
     uniform in ``speed_range``, heading uniform in (-pi, pi] (as initial targets).

**Kinds of born targets**: the scenario's targets are templates, cycled: slot ``s`` moves as
template ``s mod T`` (its kind, ``turn_hold`` and ``max_turn_rate``). With the paper's five
templates (3 ``cv``, 2 ``dubins``) and 3 initial targets, births go ``dubins, dubins, cv,
cv, cv, dubins, ...``: the templates' 3 : 2 mix.

**Randomness**: the initial targets' motion streams are spawned from the truth generator
exactly as :class:`~sensorplan.models.truth.TruthModel` spawns them, so with ``births =
"none"`` and ``survival_probability = 1`` the truth is the known-target truth bit for bit.
Everything about births and deaths comes from a generator of its own, ``births_rng``, drawn
at each step in this order: the survival uniforms, the Poisson count, then per birth batch
the positions (``edges``: one perimeter coordinate each; ``uniform``: ``(x, y)`` pairs, then
redraws), the speeds and the headings; each newborn's motion stream is
``births_rng.spawn(n)`` (spawning does not consume draws).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..errors import ConfigError
from .angles import wrap_angle
from .truth import TruthModel, inside_buildings

#: Where targets are born: nowhere (the known targets only), at the map's edges, anywhere.
BIRTHS = ("none", "edges", "uniform")
#: Most redraws of a ``uniform`` birth that fell inside a building.
MAX_BIRTH_REDRAWS = 1000


class Population(Protocol):
    """A truth whose targets are born and die (:class:`PopulationTruth`, and the scripted
    benchmarks of :mod:`sensorplan.models.scripted`).

    Attributes
    ----------
    states : (M_max, 4)        true ``[x, y, vx, vy]`` of every slot (a dead slot: its last
                               live state)
    alive : (M_max,) bool
    birth_step, death_step : (M_max,) int64   ``death_step`` is -1 while alive
    step_index : int           the step the states are at (0 at the start)
    """

    states: FloatArray
    alive: BoolArray
    birth_step: IntArray
    death_step: IntArray
    step_index: int

    def step(self) -> tuple[FloatArray, BoolArray]:
        """Advance one step; return the new ``states (M_max, 4)`` and ``alive (M_max,)``."""
        ...


def edge_births(n: int, rng: np.random.Generator, world_size: Sequence[float],
                speed_range: Sequence[float]) -> FloatArray:
    """``n`` birth states ``(n, 4)`` on the boundary of ``[0, W] x [0, H]``, heading inward.

    The position is uniform over the perimeter by length, walked counter-clockwise from the
    origin (bottom, right, top, left side); the heading is the side's inward normal plus a
    uniform angle in (-pi/2, pi/2); the speed is uniform in ``speed_range`` (m/s). Draws, in
    order: ``n`` perimeter coordinates, ``n`` speeds, ``n`` angles.
    """
    W, H = (float(v) for v in world_size)
    s = rng.uniform(0.0, 2.0 * (W + H), n)
    speed = rng.uniform(speed_range[0], speed_range[1], n)
    offset = rng.uniform(-0.5 * np.pi, 0.5 * np.pi, n)
    side = np.searchsorted(np.array([W, W + H, 2 * W + H]), s, side="right")
    u = s - np.array([0.0, W, W + H, 2 * W + H])[side]
    x = np.choose(side, [u, np.full(n, W), W - u, np.zeros(n)])
    y = np.choose(side, [np.zeros(n), u, np.full(n, H), H - u])
    normal = np.array([0.5 * np.pi, np.pi, -0.5 * np.pi, 0.0])[side]
    heading = wrap_angle(normal + offset)
    return np.column_stack([x, y, speed * np.cos(heading), speed * np.sin(heading)])


def uniform_births(n: int, rng: np.random.Generator, world_size: Sequence[float],
                   speed_range: Sequence[float], buildings: FloatArray | None = None
                   ) -> FloatArray:
    """``n`` birth states ``(n, 4)`` uniform over ``[0, W] x [0, H]`` outside the buildings.

    Positions strictly inside a building ``(B, 5)`` are redrawn (at most
    :data:`MAX_BIRTH_REDRAWS` times); speed uniform in ``speed_range``, heading uniform in
    (-pi, pi] (drawn as ``pi - U(0, 2 pi)``, as the initial targets'). Draws, in order: ``n``
    ``(x, y)`` pairs, the redraws, ``n`` speeds, ``n`` headings.

    Raises
    ------
    ConfigError
        Naming ``buildings`` when they leave (almost) no room for a birth.
    """
    size = np.array([float(v) for v in world_size])
    b = np.zeros((0, 5)) if buildings is None else np.asarray(buildings, float).reshape(-1, 5)
    pos = rng.uniform(0.0, size, (n, 2))
    for _ in range(MAX_BIRTH_REDRAWS):
        inside = np.flatnonzero(inside_buildings(pos, b))
        if inside.size == 0:
            break
        pos[inside] = rng.uniform(0.0, size, (inside.size, 2))
    else:
        raise ConfigError("buildings", "cover (almost) all of the map: no room for a birth")
    speed = rng.uniform(speed_range[0], speed_range[1], n)
    heading = np.pi - rng.uniform(0.0, 2 * np.pi, n)
    return np.column_stack([pos, speed * np.cos(heading), speed * np.sin(heading)])


def outside_map(xy: FloatArray, world_size: Sequence[float]) -> BoolArray:
    """Whether positions ``(..., 2)`` lie outside ``[0, W] x [0, H]`` (a wall is inside)."""
    W, H = (float(v) for v in world_size)
    return (xy[..., 0] < 0.0) | (xy[..., 0] > W) | (xy[..., 1] < 0.0) | (xy[..., 1] > H)


class PopulationTruth:
    """Targets that are born and die, each in a slot of its own (see the module docstring).

    Parameters
    ----------
    kinds : (T,) sequence of {"cv", "dubins"}
        Templates, cycled: slot ``s`` is of kind ``kinds[s % T]``.
    initial_states : (M0, 4)
        The targets alive at step 0 (slots ``0 .. M0-1``; ``M0`` may be 0).
    rng : numpy.random.Generator
        The truth generator: the initial targets' motion streams are spawned from it.
    births_rng : numpy.random.Generator
        Births and deaths (survival draws, birth counts and states, newborn streams).
    turn_hold, max_turn_rate : (T,) float
        The templates' dubins settings (s, rad/s).
    world_size : (2,) float       map width and height (m)
    dt : float                    step (s)
    process_noise : float         q (m^2/s^3) of ``cv`` targets
    births : {"none", "edges", "uniform"}
    birth_rate : float >= 0       expected births per step (Poisson)
    survival_probability : float in (0, 1]   per step; ``uniform`` births need it < 1
    speed_range : (lo, hi)        speeds of born targets (m/s)
    buildings : (B, 5), optional

    Attributes
    ----------
    states, alive, birth_step, death_step, step_index : see :class:`Population`
    kinds : (M_max,) str          each slot's kind
    """

    def __init__(self, kinds: Sequence[str], initial_states: FloatArray,
                 rng: np.random.Generator, births_rng: np.random.Generator, *,
                 turn_hold: Sequence[float] | FloatArray,
                 max_turn_rate: Sequence[float] | FloatArray,
                 world_size: Sequence[float] | FloatArray, dt: float, process_noise: float,
                 births: str = "none", birth_rate: float = 0.0,
                 survival_probability: float = 1.0,
                 speed_range: Sequence[float] = (3.0, 6.0),
                 buildings: FloatArray | None = None) -> None:
        self._kinds = np.asarray(kinds, dtype=str).reshape(-1)
        self._hold = np.asarray(turn_hold, dtype=float).reshape(-1)
        self._rate = np.asarray(max_turn_rate, dtype=float).reshape(-1)
        T = len(self._kinds)
        if T == 0 or self._hold.shape != (T,) or self._rate.shape != (T,):
            raise ValueError("kinds, turn_hold and max_turn_rate must be equally long and "
                             "not empty")
        if births not in BIRTHS:
            raise ValueError(f"births must be one of {BIRTHS}, got {births!r}")
        if not (np.isfinite(birth_rate) and birth_rate >= 0.0):
            raise ValueError(f"birth_rate must be a finite number >= 0, got {birth_rate!r}")
        if not 0.0 < survival_probability <= 1.0:
            raise ValueError(f"survival_probability must be in (0, 1], got "
                             f"{survival_probability!r}")
        if births == "uniform" and survival_probability == 1.0:
            raise ValueError("uniform births need survival_probability < 1 (else the number "
                             "of targets grows without bound)")
        x0 = np.array(initial_states, dtype=float).reshape(-1, 4)
        M0 = len(x0)
        slots = np.arange(M0) % T
        self.births = births
        self.birth_rate = float(birth_rate)
        self.survival_probability = float(survival_probability)
        self.world_size = tuple(float(v) for v in world_size)
        self.speed_range = (float(speed_range[0]), float(speed_range[1]))
        self.buildings = np.zeros((0, 5)) if buildings is None else np.asarray(
            buildings, dtype=float).reshape(-1, 5)
        self._births_rng = births_rng
        self._engine = TruthModel(self._kinds[slots], x0, rng, turn_hold=self._hold[slots],
                                  max_turn_rate=self._rate[slots], world_size=world_size,
                                  dt=dt, process_noise=process_noise,
                                  buildings=self.buildings,
                                  walls="open" if births == "edges" else "mirror")
        #: Slot of each of the engine's rows (the live targets), ascending.
        self._rows = np.arange(M0, dtype=np.int64)
        self.states = x0
        self.alive = np.ones(M0, dtype=bool)
        self.birth_step = np.zeros(M0, dtype=np.int64)
        self.death_step = np.full(M0, -1, dtype=np.int64)
        self.kinds = self._kinds[slots]
        self.step_index = 0

    @property
    def n_alive(self) -> int:
        return len(self._rows)

    def _kill(self, rows: IntArray, t: int) -> None:
        """Engine rows ``rows`` die at step ``t``."""
        if rows.size == 0:
            return
        slots = self._rows[rows]
        self.alive = self.alive.copy()
        self.alive[slots] = False
        self.death_step = self.death_step.copy()
        self.death_step[slots] = t
        self._engine.remove(rows)
        self._rows = np.delete(self._rows, rows)

    def _born(self, n: int) -> FloatArray:
        if self.births == "edges":
            return edge_births(n, self._births_rng, self.world_size, self.speed_range)
        return uniform_births(n, self._births_rng, self.world_size, self.speed_range,
                              self.buildings)

    def step(self) -> tuple[FloatArray, BoolArray]:
        """Advance one step (deaths, motion, exits, births); return ``states (M_max, 4)``
        and ``alive (M_max,)`` (new arrays, not changed afterwards)."""
        t = self.step_index + 1
        if self.survival_probability < 1.0 and self.n_alive:
            u = self._births_rng.random(self.n_alive)
            self._kill(np.flatnonzero(u >= self.survival_probability), t)
        moved = self._engine.step()
        if self.births == "edges":
            self._kill(np.flatnonzero(outside_map(moved[:, :2], self.world_size)), t)
        states = self.states.copy()
        states[self._rows] = self._engine.states
        if self.births != "none" and self.birth_rate > 0.0:
            n = int(self._births_rng.poisson(self.birth_rate))
            if n:
                states = self._add(states, self._born(n), t)
        self.states = states
        self.step_index = t
        return self.states, self.alive

    def _add(self, states: FloatArray, born: FloatArray, t: int) -> FloatArray:
        n = len(born)
        first = len(states)
        slots = np.arange(first, first + n, dtype=np.int64)
        template = slots % len(self._kinds)
        self._engine.add(self._kinds[template], born, self._births_rng.spawn(n),
                         turn_hold=self._hold[template], max_turn_rate=self._rate[template])
        self._rows = np.concatenate([self._rows, slots])
        self.alive = np.concatenate([self.alive, np.ones(n, dtype=bool)])
        self.birth_step = np.concatenate([self.birth_step, np.full(n, t, dtype=np.int64)])
        self.death_step = np.concatenate([self.death_step, np.full(n, -1, dtype=np.int64)])
        self.kinds = np.concatenate([self.kinds, self._kinds[template]])
        return np.concatenate([states, born])
