"""Interchangeable planners behind one protocol, registered by name (SPEC 4)."""

from . import greedy, potential_game, random_plan, refine  # noqa: F401  (registers)
from . import brute_force  # noqa: F401
from .base import PLANNERS, Planner, PlanResult, make_planner

__all__ = ["PLANNERS", "PlanResult", "Planner", "make_planner"]
