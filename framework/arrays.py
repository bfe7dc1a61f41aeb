"""Array type aliases shared by the core and every plugin (one definition, imported everywhere).

They say the element type only; docstrings state the shapes (``(N, 2)`` points, ``(K,)`` ids).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
"""Float64 array: positions, scores, costs."""

Float32Array = NDArray[np.float32]
"""Float32 array: network inputs and outputs."""

IntArray = NDArray[np.int64]
"""Int64 array: ids and indices (``-1`` = no match, see ``trackfw.records.NO_MATCH``)."""

BoolArray = NDArray[np.bool_]
"""Boolean mask."""

UInt8Array = NDArray[np.uint8]
"""8-bit image or mask, ``(H, W, 3)`` BGR or ``(H, W)``."""

ImageArray = NDArray[Any]
"""An image as OpenCV returns it: ``(H, W, 3)`` BGR uint8 frames, float32 sprites."""

__all__ = ["BoolArray", "Float32Array", "FloatArray", "ImageArray", "IntArray", "UInt8Array"]
