"""The array type of the numeric core, written once: every solver, method and export takes and
returns float64 numpy arrays, and says so with `FloatArray`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
