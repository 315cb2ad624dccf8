"""The array type the modules name in their signatures (one definition for all of them)."""

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]  # float64 values of any shape: poses (N, 3), points (N, 2), grids
