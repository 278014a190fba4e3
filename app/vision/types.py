"""Array aliases used across the engine.

They name what an array holds for the reader. The dtype is left open
(``NDArray[Any]``) because OpenCV's stubs type every result as "integer or
floating", which a precise ``uint8`` would fight at each call.
"""

from typing import Any

import numpy.typing as npt

Image = npt.NDArray[Any]
"""A frame: H x W x 3 BGR or H x W grey, 8 bits."""
GrayImage = npt.NDArray[Any]
"""H x W, 8 bits."""
Mask = npt.NDArray[Any]
"""H x W, 8 bits: 0 = still, 255 = motion."""
FloatImage = npt.NDArray[Any]
"""H x W, float32 (background models)."""
AnyArray = npt.NDArray[Any]
