"""The array type the case study's modules annotate with (one definition, imported by all).

Examples
--------
>>> import numpy as np
>>> FloatArray == NDArray[np.float64]
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["FloatArray"]

#: A numpy array of ``float64`` values: states, positions, rotations, ellipsoid centres and shapes.
FloatArray = NDArray[np.float64]
