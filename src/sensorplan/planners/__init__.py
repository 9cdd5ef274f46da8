"""Interchangeable planners behind one protocol, registered by name (SPEC 4)."""

from . import greedy, potential_game, random_plan  # noqa: F401  (registers)
from .base import PLANNERS, Planner, PlanResult, make_planner

__all__ = ["PLANNERS", "PlanResult", "Planner", "make_planner"]
