"""Array type aliases used in signatures (shapes are given in docstrings)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
#: Integers of any width (counts are stored as int16).
IntegerArray = npt.NDArray[np.integer]
BoolArray = npt.NDArray[np.bool_]
