"""Interchangeable planners behind one protocol, chosen by name.

Everything a planner needs, including one written outside this package (docs/planning.md,
"Writing a planner"):

- the protocol and the result: :class:`Planner`, :class:`PlanResult`;
- the registry: :func:`register` (class decorator), :data:`PLANNERS` (every known name),
  :func:`make_planner`, :func:`planner_class`; installed distributions add planners through
  the entry-point group ``sensorplan.planners`` (:data:`ENTRY_POINT_GROUP`), and
  ``"package.module:Class"`` is accepted wherever a name is;
- the helpers of a ``plan`` method: :func:`start_clock`, :func:`make_rng`, :func:`prepare`,
  :func:`finish`; for search looks :func:`plans_search` (whether a planner declares it
  plans them) and :func:`refuse_search` (the refusal of one that does not);
- the problem and the plan: :class:`PlanningProblem`, :class:`Plan`, :func:`move_vectors`
  (a sensor's moves), :func:`check_plan` (feasibility), :func:`potential` (Phi),
  :data:`TIE_TOL`;
- the contract: :func:`check_planner` runs the named checks every planner must pass
  (:data:`CHECKS`) and returns a :class:`CheckReport`; :func:`checked_plan` plans one
  decision and refuses (:class:`PlanRejected`) a result that cannot be executed.

Importing this package loads only the registry (no numpy, no kernels, no planner); every
other name is imported on first use.
"""

from typing import TYPE_CHECKING, Any

from .registry import (ENTRY_POINT_GROUP, PLANNERS, make_planner, planner_class, planner_names,
                       register)

if TYPE_CHECKING:  # pragma: no cover
    from .base import (PlanResult, Planner, RngLike, finish, make_rng, plans_search, prepare,
                       refuse_search, start_clock)
    from .checks import (CHECKS, CheckReport, PlannerCheckError, PlanRejected, check_planner,
                         checked_plan)
    from .information import potential
    from .problem import TIE_TOL, Plan, PlanningProblem, check_plan, move_vectors


def __getattr__(name: str) -> Any:
    # Everything but the registry is imported on first use: the registry is what the
    # command line's help and the settings need, and it must not load numpy or the kernels.
    if name in ("TIE_TOL", "Plan", "PlanningProblem", "check_plan", "move_vectors"):
        from . import problem as module
    elif name in ("PlanResult", "Planner", "RngLike", "finish", "make_rng", "plans_search",
                  "prepare", "refuse_search", "start_clock"):
        from . import base as module  # type: ignore[no-redef]
    elif name in ("CHECKS", "CheckReport", "PlannerCheckError", "PlanRejected",
                  "check_planner", "checked_plan"):
        from . import checks as module  # type: ignore[no-redef]
    elif name == "potential":
        from . import information as module  # type: ignore[no-redef]
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value


__all__ = ["CHECKS", "ENTRY_POINT_GROUP", "PLANNERS", "TIE_TOL", "CheckReport", "Plan",
           "PlanRejected", "PlanResult", "Planner", "PlannerCheckError", "PlanningProblem",
           "RngLike", "check_plan", "check_planner", "checked_plan", "finish", "make_planner",
           "make_rng", "move_vectors", "planner_class", "planner_names", "plans_search",
           "potential", "prepare", "refuse_search", "register", "start_clock"]
