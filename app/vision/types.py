"""Array aliases used across the engine (documentation for readers and mypy)."""

from typing import Any

import numpy as np
import numpy.typing as npt

Image = npt.NDArray[np.uint8]
"""A frame: H x W x 3 BGR or H x W grey, 8 bits."""
GrayImage = npt.NDArray[np.uint8]
"""H x W, 8 bits."""
Mask = npt.NDArray[np.uint8]
"""H x W, 0 = still, 255 = motion."""
FloatImage = npt.NDArray[np.float32]
AnyArray = npt.NDArray[Any]
