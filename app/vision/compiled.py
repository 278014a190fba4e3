"""How the engine compiles its per-pixel loops (Numba)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, TypeVar

from numba import njit
from numba.core.dispatcher import Dispatcher

log = logging.getLogger("vigil.vision")

Kernel = TypeVar("Kernel", bound=Callable[..., Any])


def compiled(kernel: Kernel) -> Dispatcher[Kernel]:
    """Compile without the GIL, cached on disk; where no cache folder is writable
    (read-only install, no home), compile afresh in each process instead of failing."""
    try:
        return njit(cache=True, nogil=True)(kernel)
    except RuntimeError as exc:  # Numba: "cannot cache function ...: no locator available".
        log.warning("%s; compiling in each process (set NUMBA_CACHE_DIR to keep it)", exc)
        return njit(nogil=True)(kernel)
