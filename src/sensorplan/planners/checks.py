"""The planner contract: named checks every planner must pass (:func:`check_planner`).

In the style of scikit-learn's ``check_estimator``: each check runs the planner on a fixed
set of problems (:func:`~sensorplan.planners.contract_problems.contract_problems`: both visibility
modes and both objectives, tiny problems and paper-size ones) and raises
:class:`PlannerCheckError` naming the check, the planner and the problem on the first
failure. A planner that declares it plans search looks (``plans_search``) is also run on
the searching problems
(:func:`~sensorplan.planners.contract_problems.search_contract_problems`), its Phi
recomputed with search (:func:`sensorplan.planners.search.potential`); any other planner
must refuse each of them with a :class:`~sensorplan.errors.ConfigError` on ``search``
(check ``search_declared``). The project's own contract suite
(``tests/planners/test_planner_contract.py``) runs exactly these checks for every registered
planner.

A planner may decline a problem that is too large for it by raising a
:class:`~sensorplan.errors.ConfigError` on one of its settings (``planner.max_plans``, as
``brute-force`` does); the checks skip such a problem, but declining a tiny one fails.

The same rules guard every decision that is executed: :func:`checked_plan` calls a planner
and refuses its result (:class:`PlanRejected`) unless it is well formed, complete and
feasible, so a planner that breaks its contract stops a run before anything of its plan
is carried out.
"""

from __future__ import annotations

import contextvars
import dataclasses
import math
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import numpy as np

from ..errors import ConfigError
from .base import PlanResult, plans_search
from .contract_problems import ContractProblem, contract_problems, search_contract_problems
from .information import potential
from .problem import TIE_TOL, Plan, PlanError, PlanningProblem, check_plan
from .registry import make_planner, planner_class, planner_label

#: The seed passed as ``rng`` to every ``plan`` call of the checks.
SEED = 3


class PlannerCheckError(AssertionError):
    """A planner failed a check of the contract.

    Attributes
    ----------
    check : str       the check's name (a key of :data:`CHECKS`)
    planner : str     the planner's name
    problem : str     label of the problem it failed on ('' if none)
    detail : str      what went wrong
    """

    def __init__(self, check: str, planner: str, problem: str, detail: str) -> None:
        self.check, self.planner, self.problem, self.detail = check, planner, problem, detail
        where = f" on {problem}" if problem else ""
        super().__init__(f"planner {planner!r} fails check {check!r}{where}: {detail}")


class _Failure(Exception):
    """Raised inside a check; :func:`check_planner` adds the check's and planner's names."""

    def __init__(self, problem: str, detail: str) -> None:
        super().__init__(detail)
        self.problem, self.detail = problem, detail


#: While :func:`check_planner` runs: each contract problem planned -> whether it was declined.
_SEEN: contextvars.ContextVar[dict[str, bool] | None] = contextvars.ContextVar(
    "sensorplan_checks_seen", default=None)


def _plan(planner: Any, case: ContractProblem) -> PlanResult | None:
    """``planner.plan(problem, rng=SEED)``; None if the planner declines a large problem."""
    seen = _SEEN.get()
    try:
        result = planner.plan(case.problem, rng=SEED)
    except ConfigError as exc:
        if case.tiny or not exc.field.startswith("planner."):
            raise _Failure(case.label, f"plan raised ConfigError({exc})") from exc
        if seen is not None:
            seen[case.label] = seen.get(case.label, True)
        return None
    except Exception as exc:  # noqa: BLE001 - any error of the planner fails the check
        raise _Failure(case.label, f"plan raised {type(exc).__name__}: {exc}") from exc
    if seen is not None:
        seen[case.label] = False
    return result


def _cases(planner: Any) -> tuple[ContractProblem, ...]:
    """The contract problems of ``planner``: the searching ones too when it plans search
    looks."""
    return contract_problems() + (search_contract_problems() if plans_search(planner) else ())


def _results(planner: Any, tiny_only: bool = False
             ) -> Iterator[tuple[ContractProblem, PlanResult]]:
    for case in _cases(planner):
        if tiny_only and not case.tiny:
            continue
        result = _plan(planner, case)
        if result is not None:
            yield case, result


def _close(a: Any, b: Any) -> bool:
    return bool(np.allclose(a, b, rtol=1e-9, atol=1e-12))


# -------------------------------------------------------------------------- checks


def check_result_well_formed(planner: Any) -> None:
    """``plan`` returns a :class:`PlanResult` carrying the planner's name, a plan of shapes
    (N, K, 2) and (N, K), a finite Phi >= 0, one information term per target, headings and
    measurements of shape (N, K) and a finite ``seconds`` >= 0."""
    for case, res in _results(planner):
        problem = _result_problem(planner, case.problem, res)
        if problem:
            raise _Failure(case.label, problem)


def _result_problem(planner: Any, p: PlanningProblem, res: Any,
                    named: bool = True) -> str:
    """What is wrong with result ``res`` of ``planner`` on ``p`` ('' if nothing); with
    ``named`` False, the result's name is not compared with a planner that has none."""
    N, K, M = p.n_sensors, p.horizon, p.n_targets
    if not isinstance(res, PlanResult):
        return f"plan returned {type(res).__name__}, not a PlanResult"
    if (named or hasattr(planner, "name")) and res.planner != planner.name:
        return f"result.planner is {res.planner!r}, not the planner's name {planner.name!r}"
    if not isinstance(res.plan, Plan):
        return f"result.plan is {type(res.plan).__name__}, not a Plan"
    shapes = {"plan.positions": (np.shape(res.plan.positions), (N, K, 2)),
              "plan.targets": (np.shape(res.plan.targets), (N, K)),
              "information": (np.shape(res.information), (M,)),
              "headings": (np.shape(res.headings), (N, K)),
              "measurements": (np.shape(res.measurements), (N, K))}
    for what, (got, want) in shapes.items():
        if got != want:
            return f"result.{what} has shape {got}, expected {want}"
    if not (isinstance(res.potential, (float, np.floating)) and math.isfinite(res.potential)
            and res.potential >= 0.0):
        return f"result.potential must be a finite float >= 0, got {res.potential!r}"
    if not (isinstance(res.seconds, (float, int)) and math.isfinite(res.seconds)
            and res.seconds >= 0.0):
        return f"result.seconds must be finite and >= 0, got {res.seconds!r}"
    return ""


def check_feasible_complete_plan(planner: Any) -> None:
    """Every player is assigned and the plan is feasible: each position lies in the map and
    in its reachable set, one move from the previous one, and every target exists. A
    result's ``holding`` excuses no one here: nothing is lost on a contract problem."""
    for case, res in _results(planner):
        try:
            check_plan(case.problem, res.plan, complete=True)
        except ValueError as exc:
            raise _Failure(case.label, str(exc)) from None


def check_potential_matches_recomputation(planner: Any) -> None:
    """The reported Phi and its per-target terms equal an independent recomputation with
    :func:`sensorplan.planners.information.potential` (rtol 1e-9), and the terms sum to Phi.
    With search on, the recomputation is :func:`sensorplan.planners.search.potential`: the
    terms plus the search term ``w mu`` sum to Phi, and a reported ``found`` is mu."""
    for case, res in _results(planner):
        found: float | None = None
        if case.problem.searching:
            from .search import potential as search_potential

            phi, info, found = search_potential(case.problem, res.plan)
            term = phi - float(np.sum(info))               # w mu
        else:
            phi, info = potential(case.problem, res.plan)
            term = 0.0
        if not _close(res.potential, phi):
            raise _Failure(case.label, f"reported potential {res.potential!r} but the plan's "
                           f"Phi is {phi!r}")
        if not _close(res.information, info):
            raise _Failure(case.label, f"reported information {np.asarray(res.information)} "
                           f"but the plan's per-target terms are {info}")
        if not _close(np.sum(res.information) + term, res.potential):
            raise _Failure(case.label, "the information terms do not sum to the potential"
                           + (" with the search term" if found is not None else ""))
        reported = getattr(res, "found", None)
        if found is not None and reported is not None and not _close(reported, found):
            raise _Failure(case.label, f"reported found {reported!r} but the plan's mu is "
                           f"{found!r}")


def _same_plan(a: Plan, b: Plan) -> bool:
    return (np.array_equal(a.targets, b.targets)
            and np.array_equal(np.asarray(a.sectors), np.asarray(b.sectors))
            and np.array_equal(a.positions, b.positions, equal_nan=True))


def check_same_seed_same_plan(planner: Any) -> None:
    """Two calls with the same seed give the same plan and the same Phi."""
    for case, res in _results(planner):
        again = _plan(planner, case)
        if again is None or not _same_plan(res.plan, again.plan) or \
                again.potential != res.potential:
            raise _Failure(case.label, f"two calls with rng={SEED} gave different plans")


def _snapshot(problem: PlanningProblem) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in dataclasses.fields(problem):
        v = getattr(problem, f.name)
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            # The undetected intensity: each of its fields.
            out.update({f"{f.name}.{k}": x for k, x in _snapshot_of(v).items()})
        else:
            out[f.name] = np.array(v, copy=True) if isinstance(v, np.ndarray) else v
    return out


def _snapshot_of(value: Any) -> dict[str, Any]:
    return {f.name: (np.array(v, copy=True) if isinstance(v, np.ndarray) else v)
            for f in dataclasses.fields(value) for v in [getattr(value, f.name)]}


def _changed(before: dict[str, Any], problem: PlanningProblem) -> list[str]:
    out = []
    for name, old in before.items():
        new: Any = problem
        for part in name.split("."):
            new = getattr(new, part)
        same = (np.array_equal(old, new, equal_nan=True) if isinstance(old, np.ndarray)
                else old == new)
        if not same:
            out.append(name)
    return out


def check_input_not_mutated(planner: Any) -> None:
    """``plan`` leaves every field of the problem as it was."""
    for case in _cases(planner):
        before = _snapshot(case.problem)
        _plan(planner, case)
        changed = _changed(before, case.problem)
        if changed:
            contract_problems.cache_clear()        # do not hand the damage to other checks
            search_contract_problems.cache_clear()
            raise _Failure(case.label, f"plan changed problem.{', problem.'.join(changed)}")


#: id(problem) -> (problem, Phi of its brute-force optimum); holding the problem keeps the id.
_OPTIMA: dict[int, tuple[PlanningProblem, float]] = {}


def _optimum(problem: PlanningProblem) -> float:
    """Phi of the brute-force optimum of a contract problem (computed once per process)."""
    if id(problem) not in _OPTIMA:
        best = planner_class("brute-force")().plan(problem).potential
        _OPTIMA[id(problem)] = (problem, best)
    return _OPTIMA[id(problem)][1]


def check_never_above_brute_force(planner: Any) -> None:
    """On the tiny problems, Phi is at most the brute-force optimum (within the tie
    tolerance :data:`~sensorplan.planners.problem.TIE_TOL`): nobody beats exhaustive search."""
    for case, res in _results(planner, tiny_only=True):
        best = _optimum(case.problem)
        if res.potential > best + TIE_TOL * max(1.0, abs(best)):
            raise _Failure(case.label, f"potential {res.potential!r} is above the optimum "
                           f"{best!r}")


def check_search_declared(planner: Any) -> None:
    """A planner that does not declare ``plans_search`` refuses every searching problem
    with a :class:`~sensorplan.errors.ConfigError` on ``search`` (not a plan that ignores
    the search looks, not another error); one that declares it plans them (the other
    checks hold its plans to the contract)."""
    if plans_search(planner):
        return
    for case in search_contract_problems():
        try:
            planner.plan(case.problem, rng=SEED)
        except ConfigError as exc:
            if exc.field != "search":
                raise _Failure(case.label, f"refused a searching problem with ConfigError on "
                               f"{exc.field!r}, not on 'search'") from exc
            continue
        except Exception as exc:  # noqa: BLE001 - any other error fails the check
            raise _Failure(case.label, f"plan raised {type(exc).__name__}: {exc} instead of "
                           "refusing the searching problem (ConfigError on 'search')") from exc
        raise _Failure(case.label, "planned a problem whose search is on without declaring "
                       "plans_search = True: declare it, or refuse such a problem "
                       "(sensorplan.planners.refuse_search)")


#: The checks, by name, in the order :func:`check_planner` runs them.
CHECKS: dict[str, Callable[[Any], None]] = {
    "result_well_formed": check_result_well_formed,
    "feasible_complete_plan": check_feasible_complete_plan,
    "potential_matches_recomputation": check_potential_matches_recomputation,
    "same_seed_same_plan": check_same_seed_same_plan,
    "input_not_mutated": check_input_not_mutated,
    "never_above_brute_force": check_never_above_brute_force,
    "search_declared": check_search_declared,
}


@dataclasses.dataclass(frozen=True)
class CheckReport:
    """What :func:`check_planner` ran on a planner that passed every check.

    Attributes
    ----------
    planner : str                the planner's name
    checks : tuple of str        the checks run, in order (keys of :data:`CHECKS`)
    problems : tuple of str      the contract problems it planned (labels such as
                                 ``tiny[0] (probabilistic, terminal)``)
    declined : tuple of str      those of ``problems`` it declined as too large (allowed
                                 for problems that are not tiny; no check ran on them)
    """

    planner: str
    checks: tuple[str, ...]
    problems: tuple[str, ...]
    declined: tuple[str, ...] = ()

    def __str__(self) -> str:
        text = (f"planner {self.planner!r} passed {len(self.checks)} check(s) "
                f"({', '.join(self.checks)}) on {len(self.problems)} problem(s)")
        if self.declined:
            text += f", declining {len(self.declined)} as too large ({', '.join(self.declined)})"
        return text


def check_planner(planner: Any, checks: Iterable[str] | None = None) -> CheckReport:
    """Run the contract's named checks on ``planner``; raise on the first failure.

    Parameters
    ----------
    planner : Planner or str
        A planner object (``name`` and ``plan(problem, rng)``), or a name for
        :func:`~sensorplan.planners.make_planner` (default settings).
    checks : iterable of str, optional
        Names of :data:`CHECKS` to run (default: all, in order).

    Returns
    -------
    CheckReport
        The checks run and the problems planned (``print`` it for one line).

    Raises
    ------
    PlannerCheckError
        Naming the check, the planner and the problem that failed.
    ValueError
        An unknown check name.

    Examples
    --------
    >>> from sensorplan.planners import check_planner
    >>> report = check_planner("sequential-greedy", checks=["feasible_complete_plan"])
    >>> report.checks
    ('feasible_complete_plan',)
    """
    if isinstance(planner, str):
        planner = make_planner(planner)
    names = list(CHECKS) if checks is None else list(checks)
    unknown = [n for n in names if n not in CHECKS]
    if unknown:
        raise ValueError(f"unknown check {unknown[0]!r}; choose from {', '.join(CHECKS)}")
    label = str(getattr(planner, "name", type(planner).__name__))
    seen: dict[str, bool] = {}
    token = _SEEN.set(seen)
    try:
        for name in names:
            try:
                CHECKS[name](planner)
            except _Failure as exc:
                raise PlannerCheckError(name, label, exc.problem, exc.detail) from exc.__cause__
            except Exception as exc:  # noqa: BLE001 - e.g. a result of the wrong shape
                raise PlannerCheckError(name, label, "", f"{type(exc).__name__}: {exc}") from exc
    finally:
        _SEEN.reset(token)
    return CheckReport(label, tuple(names), tuple(seen),
                       tuple(p for p, declined in seen.items() if declined))


# ------------------------------------------------------------- every executed decision


class PlanRejected(ConfigError):
    """A planner's result cannot be executed: nothing of it was.

    The field is ``planner``; the message names the planner, the decision (when known), the
    sensor and the epoch, and what is wrong.

    Attributes
    ----------
    planner : str            the planner's label (:func:`.registry.planner_label`)
    detail : str             what is wrong
    sensor, epoch : int or None
                             the first sensor and epoch (1..K) whose action is wrong; None
                             when the result as a whole is (a wrong shape, a bad Phi)
    decision : int or None   the decision's index in its run (0 = the first)
    """

    def __init__(self, planner: str, detail: str, sensor: int | None = None,
                 epoch: int | None = None, decision: int | None = None) -> None:
        self.planner, self.detail = planner, detail
        self.sensor, self.epoch, self.decision = sensor, epoch, decision
        where = [] if decision is None else [f"decision {decision}"]
        if sensor is not None:
            where.append(f"sensor {sensor} epoch {epoch}")
        at = f" ({', '.join(where)})" if where else ""
        super().__init__("planner", f"{planner} broke the planner contract{at}: {detail}; "
                                    "nothing of its plan was executed")

    def __reduce__(self) -> tuple[type, tuple[Any, ...]]:  # type: ignore[override]
        return (type(self), (self.planner, self.detail, self.sensor, self.epoch,
                             self.decision))


def check_result(planner: Any, problem: PlanningProblem, result: Any,
                 decision: int | None = None) -> None:
    """Refuse ``result`` of ``planner`` on ``problem`` unless it can be executed.

    The rules are the contract's (``result_well_formed`` and ``feasible_complete_plan``):
    a :class:`PlanResult` with the planner's name, the right shapes and a finite Phi >= 0,
    whose plan assigns every sensor in every epoch a target that exists and a position in
    the map one move from the last; a sensor the result declares ``holding`` has no action
    in any epoch instead. Phi is not recomputed here (``check_planner`` does).

    Raises
    ------
    PlanRejected
        Naming the planner, ``decision``, the first wrong sensor and epoch, and the rule.
    """
    label = planner_label(planner)
    # A wrapper without a name of its own (one that records or times another planner)
    # passes the inner planner's result on: its plan is what is checked.
    problem_text = _result_problem(planner, problem, result, named=False)
    if problem_text:
        raise PlanRejected(label, problem_text, decision=decision)
    try:
        check_plan(problem, result.plan, complete=True,
                   holding=tuple(int(i) for i in result.holding))
    except PlanError as exc:
        raise PlanRejected(label, exc.detail, exc.sensor, exc.epoch, decision) from None


def checked_plan(planner: Any, problem: PlanningProblem, rng: Any = None,
                 decision: int | None = None) -> PlanResult:
    """``planner.plan(problem, rng=rng)``, refused unless its result can be executed.

    Every place that carries out a plan (``sensorplan plan``, the closed loop of
    ``simulate``, studies and agents, the Stone Soup manager) plans through this function,
    so a planner of any origin is held to the same rules (:func:`check_result`).

    Parameters
    ----------
    planner : Planner
    problem : PlanningProblem
    rng : Generator, int or None     passed on to ``planner.plan``
    decision : int, optional         the decision's index in its run, for the error

    Raises
    ------
    PlanRejected
        The result breaks the contract (see :func:`check_result`).
    """
    result = planner.plan(problem, rng=rng)
    check_result(planner, problem, result, decision)
    return result


__all__ = ["CHECKS", "SEED", "CheckReport", "PlanRejected", "PlannerCheckError",
           "check_feasible_complete_plan", "check_result", "checked_plan",
           "check_input_not_mutated", "check_never_above_brute_force", "check_planner",
           "check_potential_matches_recomputation", "check_result_well_formed",
           "check_same_seed_same_plan", "check_search_declared"]
