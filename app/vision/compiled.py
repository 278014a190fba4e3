"""How the engine compiles its per-pixel loops (Numba), and when.

A kernel is compiled (or loaded from Numba's on-disk cache) on its first
call, and Numba itself is imported then: a process that never detects (the
web server, a CLI command) does without it (about 65 MB and 0.3 s to import;
one that runs the kernels carries about 130 MB more than before Numba).
The cache sits beside the source, or in the user's cache folder where that
is read-only, so only the first run on a machine compiles (a second or
two); where neither is writable, each process compiles afresh, with a
warning. Functions that kernels call (``compiled_helper``) are compiled with
the first kernel that reaches them, into its cached code; they may live in
other modules than the kernel (a mechanism's row functions in the
mechanism's module), whose sources then count as the kernel's: Numba's
cache checks a kernel's own file only, so a kernel is compiled again when
any of them changes (``_forget_if_sources_changed``).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import threading
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

log = logging.getLogger("vigil.vision")

Kernel = TypeVar("Kernel", bound=Callable[..., Any])


HELPER = "__vigil_helper__"
"""Marks a function that compiled kernels call (``compiled_helper``)."""

_helpers_compiling = threading.Lock()


def compiled_helper(helper: Kernel) -> Kernel:
    """``helper``, a function that compiled kernels call, compiled as a function of its
    own (not inlined: a loop vectorises best apart from its caller's code, and inlining
    costs seconds of compiling). It is compiled with the first kernel that reaches it
    (by the names of the kernel's module, and of each helper's module in turn), in place
    of those modules' names for it; called from Python, it runs as plain Python before
    that, compiled after."""
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


_compiled_helpers: dict[types.FunctionType, Callable[..., Any]] = {}
"""Each helper's compiled function, shared by every module that names it."""


def _compile(kernel: Callable[..., Any]) -> Callable[..., Any]:
    from numba import njit  # Here: only processes that run a kernel load it.

    with _helpers_compiling:
        sources = _compile_helpers(kernel.__globals__, njit)
    sources.discard(kernel.__code__.co_filename)
    try:
        dispatcher = njit(cache=True, nogil=True)(kernel)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available".
        # A read-only install with no writable home: compile in each process instead.
        log.warning("%s; compiling in each process (set NUMBA_CACHE_DIR to keep it)", exc)
        return njit(nogil=True)(kernel)
    _forget_if_sources_changed(dispatcher, kernel, sources)
    return dispatcher


def _compile_helpers(names: dict[str, Any], njit: Callable[..., Any]) -> set[str]:
    """Compile, in place, the helpers that ``names`` (a kernel's module's) holds, and
    those that their own modules hold, and so on; return the source files of them all."""
    sources: set[str] = set()
    pending, visited = [names], set()
    while pending:
        module_names = pending.pop()
        if id(module_names) in visited:
            continue
        visited.add(id(module_names))
        for name, value in list(module_names.items()):
            helper = getattr(value, "py_func", value)  # A compiled one: its function.
            if not (isinstance(helper, types.FunctionType) and getattr(helper, HELPER, False)):
                continue
            if helper not in _compiled_helpers:
                _compiled_helpers[helper] = njit(helper)
            module_names[name] = _compiled_helpers[helper]
            sources.add(helper.__code__.co_filename)
            pending.append(helper.__globals__)
    return sources


def _forget_if_sources_changed(
    dispatcher: Any, kernel: Callable[..., Any], sources: set[str]
) -> None:
    """Empty the kernel's disk cache where its helpers' other source files changed since it
    was filled (a stamp of their contents beside it says), so that it is compiled again."""
    digest = hashlib.sha256()
    for source in sorted(sources):
        digest.update(Path(source).read_bytes())
    cache = dispatcher._cache
    stamp = Path(cache.cache_path) / f"{kernel.__module__}.{kernel.__qualname__}.sources"
    try:
        if not stamp.exists() or stamp.read_text() != digest.hexdigest():
            cache.flush()
            stamp.write_text(digest.hexdigest())
    except OSError as exc:  # Unsure what the cache holds: leave it alone.
        log.warning("%s's cache cannot be checked (%s); compiling it afresh", kernel.__name__, exc)
        cache.disable()
