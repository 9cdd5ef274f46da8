"""The planner protocol, the result value and the helpers every planner uses.

A planner is a class with a class attribute ``name`` and a method
``plan(problem, rng=None) -> PlanResult`` (:class:`Planner`). Its body usually reads::

    start = start_clock()                  # warm the compiled kernels, then read the clock
    gen = make_rng(rng, self.seed)         # the caller's generator, else the planner's seed
    ...                                    # choose a feasible, complete Plan
    return finish(self.name, problem, plan, start)   # Phi of the plan by its one definition

The numeric modules are imported when a helper is first called, not with this module, so
that naming a planner (the registry, ``sensorplan --help``) does not load the kernels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from .._types import FloatArray
from .problem import Plan, PlanningProblem
from .registry import PLANNERS, make_planner, register

if TYPE_CHECKING:  # pragma: no cover
    from .information import Context
    from .search import SearchContext

RngLike = np.random.Generator | int | None


@dataclass(frozen=True)
class PlanResult:
    """What every planner returns.

    Attributes
    ----------
    planner : str                  the planner's ``name``
    plan : Plan                    positions (N, K, 2) m and targets (N, K)
    potential : float              Phi(plan) in nats, by the one definition of Phi
                                   (:func:`finish` computes it)
    information : (M,)             per-target terms of Phi (nats); they sum to ``potential``
                                   (with search on, ``potential`` adds the value of the
                                   targets the plan is expected to find)
    headings : (N, K)              planned headings (rad)
    measurements : (N, K) int      looks that count in Phi
    converged : bool or None       None for planners without a notion of convergence
    sweeps : int or None           outer sweeps (``pg``/``pg-refine``), else None
    seconds : float                the planner's own time (s)
    trace : tuple of float         Phi after each sweep (diagnostics)
    budget_exhausted : bool        the time budget stopped the planner before it finished
                                   (the plan is then the best complete one it had found)
    found : float or None          with search on: mu, the expected number of undetected
                                   targets the plan finds (None with search off)
    search_weight : float or None  with search on: w, nats per target found; Phi's search
                                   term is ``search_weight * found``
    holding : tuple of int         sensors with no action in any epoch on purpose (they hold
                                   station and look at nothing: a decentralized planner's
                                   lost agents); every other sensor acts in every epoch
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
    found: float | None = None
    search_weight: float | None = None
    holding: tuple[int, ...] = ()

    @property
    def search_term(self) -> float | None:
        """Phi's search term ``w mu`` (nats); None with search off."""
        if self.found is None or self.search_weight is None:
            return None
        return self.search_weight * self.found


class Planner(Protocol):
    """``plan(problem, rng) -> PlanResult``; ``rng`` overrides the planner's own seed.

    A planner that plans search looks (a problem whose ``search`` is on) says so with the
    class attribute ``plans_search = True`` (:func:`plans_search`); any other must refuse
    such a problem with a :class:`~sensorplan.errors.ConfigError` on ``search``
    (:func:`refuse_search`). ``check_planner`` holds both to it.
    """

    name: ClassVar[str]

    def plan(self, problem: PlanningProblem, rng: RngLike = None) -> PlanResult: ...


def start_clock(engine: bool = False) -> float:
    """Warm the compiled kernels (and the planning engine's, if ``engine``), then read the
    clock: ``seconds`` is the planner's own time. In a process that runs numba's kernels,
    every planning kernel is loaded first (:func:`sensorplan._compiled.prepare.warm_listed`,
    once per process): numba may have been loaded since the last decision (by a tracker),
    and its kernels load at their first call.

    Returns
    -------
    float   the clock (:data:`sensorplan.planners.anytime.clock`) after the warm-up; pass
            it to :func:`finish`.
    """
    from .._compiled.jit import is_active
    from . import anytime
    from ._chains_nb import warm_up

    warm_up()
    if engine:
        from .epoch_game import warm_engine

        warm_engine()
    if is_active():
        from .._compiled.prepare import warm_listed

        warm_listed()
    return anytime.clock()


def make_rng(rng: RngLike, seed: int | None) -> np.random.Generator:
    """The planner's generator: ``rng`` itself when it is a Generator, else
    ``np.random.default_rng(rng)`` when given, else ``default_rng(seed)``."""
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(seed if rng is None else rng)


def prepare(problem: PlanningProblem) -> Context:
    """Everything Phi needs that does not depend on the plan (lattices, predictions, noise
    tables): :func:`sensorplan.planners.information.prepare`. Prepare once per decision."""
    from .information import prepare as _prepare

    return _prepare(problem)


def plans_search(planner: Any) -> bool:
    """Whether a planner (class or object) declares that it plans search looks: its class
    attribute ``plans_search`` (False when it has none)."""
    return getattr(planner, "plans_search", False) is True


def search_planner_names() -> tuple[str, ...]:
    """The registered planners that plan search looks (:func:`plans_search`), by name."""
    from .registry import planner_class, planner_names

    return tuple(n for n in planner_names() if plans_search(planner_class(n)))


def refuse_search(name: str, problem: PlanningProblem) -> None:
    """Raise :class:`~sensorplan.errors.ConfigError` (field ``search``) when ``problem``'s
    search is on: planner ``name`` plans on tracks only."""
    if problem.searching:
        from ..errors import ConfigError

        raise ConfigError("search", f"planner {name!r} does not plan search looks yet; "
                          f"set search to 'off' or use one of {', '.join(search_planner_names())}")


def finish(name: str, ctx: Context | PlanningProblem | SearchContext, plan: Plan,
           start: float, converged: bool | None = None, sweeps: int | None = None,
           trace: tuple[float, ...] = (), budget_exhausted: bool = False) -> PlanResult:
    """Evaluate ``plan`` with the one definition of Phi and wrap it in a :class:`PlanResult`.

    Parameters
    ----------
    name : str               the planner's name
    ctx : Context, SearchContext or PlanningProblem
                             :func:`prepare`'s result (with search,
                             :func:`~sensorplan.planners.search.prepare`'s, whose memo may
                             already hold the plan's Phi), or the problem (prepared here)
    plan : Plan              feasible and complete
    start : float            :func:`start_clock`'s value; ``seconds`` runs until now
    converged, sweeps, trace, budget_exhausted : as in :class:`PlanResult`
    """
    from . import anytime
    from .information import Context, evaluate
    from .information import prepare as _prepare

    if isinstance(ctx, PlanningProblem | Context):
        problem = ctx if isinstance(ctx, PlanningProblem) else ctx.problem
    else:
        problem = ctx.ctx.problem
    if problem.searching:
        # Phi with search: the tracks' terms plus the value of the targets found.
        from . import search

        sctx = ctx if isinstance(ctx, search.SearchContext) else search.prepare(problem)
        sev = search.evaluate(sctx, plan)
        return PlanResult(name, plan, sev.potential, sev.information, sev.headings,
                          sev.measurements, converged, sweeps, anytime.clock() - start, trace,
                          budget_exhausted, sev.found, sev.weight)
    if not isinstance(ctx, Context):
        ctx = _prepare(problem)
    ev = evaluate(ctx, plan)
    return PlanResult(name, plan, ev.potential, ev.information, ev.headings, ev.measurements,
                      converged, sweeps, anytime.clock() - start, trace, budget_exhausted)


__all__ = ["PLANNERS", "PlanResult", "Planner", "RngLike", "finish", "make_planner",
           "make_rng", "plans_search", "prepare", "refuse_search", "register",
           "search_planner_names", "start_clock"]
