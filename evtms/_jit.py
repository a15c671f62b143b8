"""Compile evtms's scalar kernels with numba where it is available.

The system simulator's time loop and lookups (:mod:`evtms.system.loop`,
:mod:`evtms.system.maps`) and the counter-flow exchanger's heat-rate search
(:mod:`evtms.hx.counterflow`) are written in the subset of Python that numba
compiles (scalars, NumPy arrays, no objects). :func:`jit` compiles them with
``numba.njit(cache=True)`` (machine code cached next to the module, so only a
machine's first run compiles); with ``EVTMS_NO_NUMBA=1`` set, or without
numba, the same functions run as plain Python: slower, same numbers.

numba keys a function's cache on its own source file only: the loop
(``loop.py``) inlines the map kernel of ``maps.py``, so after editing that
kernel alone, touch ``loop.py`` (or delete ``evtms/system/__pycache__/*.nb*``)
or the loop keeps the old machine code. An installed release replaces both
files together.
"""

from __future__ import annotations

import os


def numba_enabled() -> bool:
    """Whether kernels are compiled (numba importable and ``EVTMS_NO_NUMBA`` unset)."""
    if os.environ.get("EVTMS_NO_NUMBA", "") not in ("", "0"):
        return False
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    return True


def jit(fn):
    """``fn`` compiled by numba (no Python objects, cached), or ``fn`` itself."""
    if not numba_enabled():
        return fn
    import numba

    return numba.njit(cache=True, nogil=True)(fn)
