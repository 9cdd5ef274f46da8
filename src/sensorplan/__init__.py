"""sensorplan: non-myopic planning of mobile sensor networks for multi-target tracking."""

from .errors import ConfigError
from .information import potential
from .problem import MapRect, Plan, PlanningProblem
from .sensors import SensorParams

__version__ = "0.1.0"

__all__ = ["ConfigError", "MapRect", "Plan", "PlanningProblem", "SensorParams", "potential",
           "__version__"]
