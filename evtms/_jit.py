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

Where the cache goes: numba writes it to ``__pycache__`` beside each module
when that folder can be written, else to a per-user folder
(``~/.cache/numba`` or ``$XDG_CACHE_HOME/numba``, keyed by the module's path);
``NUMBA_CACHE_DIR`` overrides both. So an install into a read-only
site-packages still compiles once per user, not once per run.

Processes that start together (a sweep's workers, a test run's) would each
compile a kernel the cache does not hold yet: for seconds per bench kernel,
about 16 s for the simulator's loop. :func:`jit` therefore compiles under a
lock file beside the function's cache: the first process compiles and saves,
the others wait and load its machine code (numba reads the cache before it
compiles). A lock held past :data:`COMPILE_WAIT` (a stopped process releases
its locks) is not waited on further.

A process pays numba's start-up once: its import, then, on the first call of
any compiled function, the set-up of its compiler (most of it even when the
machine code comes from the cache). numba imports SciPy's BLAS (for ``np.dot``
and ``np.linalg`` in compiled code) and cffi during that set-up, which costs
more than the rest; evtms's kernels use neither, so a program of its own (the
command line, through :func:`evtms.workflows.common.own_process`) calls
:func:`lean_numba` first and numba is set up without them.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from evtms._locks import file_lock

#: Modules numba binds only for features no evtms kernel uses: SciPy (``np.dot``, ``np.linalg``
#: in compiled code call its BLAS and LAPACK) and cffi (calls into cffi libraries).
_UNUSED_BY_KERNELS = ("scipy", "cffi")
_lean = False

#: The longest a process waits for another one compiling the same kernel [s] before compiling it too.
COMPILE_WAIT = 300.0


def lean_numba() -> None:
    """Set numba up, when it is first imported, without its SciPy and cffi bindings.

    For a process that runs only evtms (``evtms`` on the command line): numba
    then supports neither ``np.dot``/``np.linalg`` nor cffi calls in code it
    compiles in this process, which no evtms kernel needs. SciPy and cffi stay
    importable as usual. No effect once numba is imported.
    """
    global _lean
    _lean = True


def load_numba():
    """The numba module, imported (lean after :func:`lean_numba`); ImportError if numba is missing."""
    if not _lean or "numba" in sys.modules:
        import numba

        return numba
    # Both are optional to numba (it runs where neither is installed): hidden, an import of either
    # fails and numba leaves that binding out, as it would without them.
    hidden = [m for m in _UNUSED_BY_KERNELS if m not in sys.modules]
    for m in hidden:
        sys.modules[m] = None
    try:
        import numba
        import numba.core.typing.cffi_utils  # noqa: F401 - decides cffi support now, cffi hidden
        import numba.np.arraymath  # noqa: F401 - decides BLAS support now, SciPy hidden
    finally:
        for m in hidden:
            if sys.modules.get(m, 0) is None:
                del sys.modules[m]
    return numba


def numba_enabled() -> bool:
    """Whether kernels are compiled (numba importable and ``EVTMS_NO_NUMBA`` unset)."""
    if os.environ.get("EVTMS_NO_NUMBA", "") not in ("", "0"):
        return False
    try:
        load_numba()
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    return True


def jit(fn=None, *, counted: bool = True):
    """``fn`` compiled by numba (no Python objects, cached, one process at a time), or ``fn`` itself.

    ``counted=False``: compiled without reference counting (:func:`uncounted`), for a kernel that
    allocates no array. Use as ``@jit`` or ``@jit(counted=False)``.
    """
    if fn is None:
        return lambda f: jit(f, counted=counted)
    if not numba_enabled():
        return fn
    dispatcher = load_numba().njit(cache=True, nogil=True, **({} if counted else uncounted()))(fn)
    compile_one_at_a_time(dispatcher)
    return dispatcher


def uncounted() -> dict[str, bool]:
    """numba's options that compile a function without reference counting.

    numba's runtime counts the references to every array a compiled function
    takes as an argument, unpacks from a tuple or slices: an atomic increment
    on entry and a decrement on exit, where its pruning pass cannot pair them
    away (across loops and branches). A kernel that passes tuples of arrays
    down a chain of small functions, as the closure's kernels pass their
    LUTs, spends most of its time there: 75 % of a two-branch closure point
    (650 against 165 us a point). A function compiled with these options
    keeps no count: it must allocate no array (numba refuses to compile one
    that does), call nothing that does (numba compiles its callees with its
    options; ``tests/test_uncounted_kernels.py`` reads the calls) and return
    none, the arrays staying alive in its caller; it computes the same
    numbers. Empty where numba lacks the option (the same code, counted).
    """
    load_numba()
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # pragma: no cover - numba's layout since 0.54
        return {}
    return {"_nrt": False} if hasattr(CPUTargetOptions, "_nrt") else {}


def compile_one_at_a_time(dispatcher) -> None:
    """Make ``dispatcher`` compile a new signature under its lock file (module docstring).

    numba compiles, in one process, under its own compiler lock; it is taken first here, so that
    within a process only the thread holding it waits on lock files, and nested compilations (a
    kernel calling another) take theirs in call order in every process.
    """
    from numba.core.compiler_lock import global_compiler_lock

    compile_signature = dispatcher.compile
    try:  # numba's cache internals: a numba without them compiles as it always did, unlocked
        cache = dispatcher._cache
        lock_path = os.path.join(cache._cache_path, cache._cache_file._index_name + ".lock")
    except AttributeError:
        return

    def compile_locked(sig):
        with global_compiler_lock, file_lock(lock_path, COMPILE_WAIT):
            return compile_signature(sig)

    dispatcher.compile = compile_locked


def kernel_array(a, dtype=np.float64) -> np.ndarray:
    """``a`` as a compiled kernel reads a table: a plain, C-ordered, read-only array of ``dtype``
    (a view where ``a`` already is one, else a copy).

    numba compiles a function once per argument type, and a read-only array (a memory-mapped
    file, a view made read-only) is another type than a writable one: the same kernel would be
    compiled again, for seconds, when its table came from a cache file instead of memory. Every
    table handed to a kernel goes through here, so that each kernel has one type per argument.
    """
    view = np.ascontiguousarray(a, dtype=dtype).view(np.ndarray)
    view.flags.writeable = False
    return view
