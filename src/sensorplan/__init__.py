"""sensorplan: non-myopic planning of mobile sensor networks for multi-target tracking.

Importing the package is cheap: numpy, the compiled kernels (numba), the plotting stack and
the table libraries load when first used, so the names below other than ``ConfigError`` and
``__version__`` are imported on first access.
"""

from __future__ import annotations

from .errors import ConfigError

# Not typing's: ``python -m sensorplan`` imports this package before the command line can
# catch a Ctrl-C, so it imports nothing it can do without (typing costs ~10-20 ms).
TYPE_CHECKING = False
if TYPE_CHECKING:  # pragma: no cover
    from typing import Any

    from .memory import keep_freed_memory
    from .models.sensors import SensorParams
    from .planners.information import potential
    from .planners.problem import MapRect, Plan, PlanningProblem

__version__ = "0.1.0"

__all__ = ["ConfigError", "MapRect", "Plan", "PlanningProblem", "SensorParams",
           "keep_freed_memory", "potential", "__version__"]


def __getattr__(name: str) -> Any:
    if name in ("MapRect", "Plan", "PlanningProblem"):
        from .planners import problem as module
    elif name == "SensorParams":
        from .models import sensors as module  # type: ignore[no-redef]
    elif name == "potential":
        from .planners import information as module  # type: ignore[no-redef]
    elif name == "keep_freed_memory":
        from . import memory as module  # type: ignore[no-redef]
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value
