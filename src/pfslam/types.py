"""The types the modules name in their signatures (one definition for all of them): the array
type, and the JSON value (run.json, a sweep's rows, a filter's diagnostics)."""

from collections.abc import Mapping, Sequence
from typing import Union

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]  # float64 values of any shape: poses (N, 3), points (N, 2), grids

# A value ``json.dumps`` writes: None, a bool, a number, a string, or a list or mapping of such
# values (read-only containers, so a ``dict[str, float]`` is one; ``json.loads`` gives lists and dicts).
JSON = Union[None, bool, int, float, str, Sequence["JSON"], Mapping[str, "JSON"]]
JSONObject = dict[str, JSON]  # a JSON object: a row of a sweep's table, a filter's diagnostics
