"""How the engine compiles its per-pixel loops (Numba), and when.

A kernel is compiled (or loaded from Numba's on-disk cache) on its first
call, and Numba itself is imported then: a process that never detects (the
web server, a CLI command) does without it (about 65 MB and 0.3 s to import;
one that runs the kernels carries about 130 MB more than before Numba).
The cache sits beside the source, or in the user's cache folder where that
is read-only, so only the first run on a machine compiles (a second or
two); where neither is writable, each process compiles afresh, with a
warning. Functions that kernels call (``compiled_helper``) are compiled with
the first kernel of their module that runs, into its cached code.
"""

from __future__ import annotations

import functools
import logging
import threading
import types
from collections.abc import Callable
from typing import Any, TypeVar, cast

log = logging.getLogger("vigil.vision")

Kernel = TypeVar("Kernel", bound=Callable[..., Any])


HELPER = "__vigil_helper__"
"""Marks a function that compiled kernels call (``compiled_helper``)."""

_helpers_compiling = threading.Lock()


def compiled_helper(helper: Kernel) -> Kernel:
    """``helper``, a function that compiled kernels call, compiled as a function of its
    own (not inlined: a loop vectorises best apart from its caller's code, and inlining
    costs seconds of compiling). It must live in the module of the kernels that call it:
    Numba's cache knows a kernel's source file only, so a helper elsewhere could change
    without the cached kernel noticing. It is compiled with the first kernel of that
    module that runs, in place of the module's name for it; called from Python, it runs
    as plain Python before that, compiled after."""
    setattr(helper, HELPER, True)
    return helper


def compiled(kernel: Kernel) -> Kernel:
    """``kernel`` compiled on first call, without the GIL, cached on disk."""
    compiling = threading.Lock()
    ready: list[Callable[..., Any]] = []

    @functools.wraps(kernel)
    def run(*args: Any) -> Any:
        if not ready:
            with compiling:
                if not ready:
                    ready.append(_compile(kernel))
        return ready[0](*args)

    return cast(Kernel, run)


def _compile(kernel: Callable[..., Any]) -> Callable[..., Any]:
    from numba import njit  # Here: only processes that run a kernel load it.

    with _helpers_compiling:
        names = kernel.__globals__
        for name, value in list(names.items()):
            # A compiled one keeps the mark (Numba copies the function's attributes).
            if isinstance(value, types.FunctionType) and getattr(value, HELPER, False):
                names[name] = njit(value)
    try:
        return njit(cache=True, nogil=True)(kernel)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available".
        # A read-only install with no writable home: compile in each process instead.
        log.warning("%s; compiling in each process (set NUMBA_CACHE_DIR to keep it)", exc)
        return njit(nogil=True)(kernel)
