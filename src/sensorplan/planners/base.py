"""The planner protocol, the result value and the registry (SPEC 4)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from .._kernels import warm_up
from .._types import FloatArray
from ..errors import ConfigError
from ..information import Context, evaluate, prepare
from ..problem import Plan, PlanningProblem
from . import anytime

RngLike = np.random.Generator | int | None


@dataclass(frozen=True)
class PlanResult:
    """What every planner returns.

    Attributes
    ----------
    plan : Plan
    potential : float              Phi(plan) in nats, recomputed by :func:`potential`'s code
    information : (M,)             per-target terms of Phi
    headings : (N, K)              planned headings
    measurements : (N, K) int      looks that count in Phi
    converged : bool or None       ``pg``/``pg-refine`` only
    sweeps : int or None           outer sweeps (``pg``/``pg-refine`` only)
    seconds : float                the planner's own time
    trace : tuple of float         Phi after each sweep (diagnostics)
    budget_exhausted : bool        the time budget stopped the planner before it finished
                                   (the plan is then the best complete one it had found)
    """

    planner: str
    plan: Plan
    potential: float
    information: FloatArray
    headings: FloatArray
    measurements: np.ndarray
    converged: bool | None = None
    sweeps: int | None = None
    seconds: float = 0.0
    trace: tuple[float, ...] = field(default=())
    budget_exhausted: bool = False


class Planner(Protocol):
    """``plan(problem, rng) -> PlanResult``; ``rng`` overrides the planner's own seed."""

    name: ClassVar[str]

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult: ...


def start_clock(engine: bool = False) -> float:
    """Warm the compiled kernels (and the planning engine's, if ``engine``), then read the
    clock: ``seconds`` is the planner's own time."""
    warm_up()
    if engine:
        _warm_engine()
    return anytime.clock()


_ENGINE_WARM = False


def _warm_engine() -> None:
    """Compile (or load from numba's cache) the engine's kernels once, on a tiny decision."""
    global _ENGINE_WARM
    if _ENGINE_WARM:
        return
    _ENGINE_WARM = True
    from ..problem import PlanningProblem
    from ..sensors import SensorParams
    from .engine import GameState
    from .potential_game import jsfp_epoch

    problem = PlanningProblem(np.array([[300.0, 300.0, 1.0, 0.0]]),
                              np.diag([400.0, 400.0, 4.0, 4.0])[None], np.array([[0.0, 300.0]]),
                              np.array([0.0]), (SensorParams(),), horizon=2)
    state = GameState(prepare(problem))
    for _ in jsfp_epoch(state, 2, np.random.default_rng(0), 0.3, 0.95, 2):
        pass
    pos, tgt = state.player_actions(0, 1)
    state.chain_gains(0, 1, pos[:, None], tgt[:, None], with_base=True)


def make_rng(rng: RngLike, seed: int | None) -> np.random.Generator:
    """The planner's generator: ``rng`` when given, else one seeded with ``seed``."""
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(seed if rng is None else rng)


def finish(name: str, ctx: Context, plan: Plan, start: float, converged: bool | None = None,
           sweeps: int | None = None, trace: tuple[float, ...] = (),
           budget_exhausted: bool = False) -> PlanResult:
    """Evaluate ``plan`` with the one definition of Phi and wrap it in a :class:`PlanResult`."""
    ev = evaluate(ctx, plan)
    return PlanResult(name, plan, ev.potential, ev.information, ev.headings, ev.measurements,
                      converged, sweeps, anytime.clock() - start, trace, budget_exhausted)


PLANNERS: dict[str, Callable[..., Planner]] = {}


def register(cls: Any) -> Any:
    """Class decorator adding a planner to :data:`PLANNERS` under ``cls.name``."""
    PLANNERS[cls.name] = cls
    return cls


def make_planner(name: str, **params: Any) -> Planner:
    """Instantiate a registered planner; unknown names or settings raise ConfigError."""
    if name not in PLANNERS:
        raise ConfigError("planner.name", f"unknown planner {name!r}; choose from "
                          f"{sorted(PLANNERS)}")
    try:
        return PLANNERS[name](**params)
    except TypeError as exc:
        raise ConfigError("planner", str(exc)) from None


__all__ = ["PLANNERS", "PlanResult", "Planner", "finish", "make_planner", "make_rng",
           "prepare", "register", "start_clock"]
