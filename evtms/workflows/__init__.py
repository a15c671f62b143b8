"""The application layer: what each command does, callable from Python.

Each workflow takes a request (a dataclass of the command's options, in the
command line's units), applies every check the command line applies, does the
work and returns a typed result; it never prints or exits. The CLI
(:mod:`evtms.cli`) parses options into a request, calls one workflow and
prints its result.

The modules are imported when a name is first used, so ``import evtms.workflows``
stays cheap.
"""

from __future__ import annotations

import importlib

#: Public name -> the module of this package that defines it.
_API = {
    "BenchRequest": "bench",
    "BenchResult": "bench",
    "run_bench": "bench",
}

__all__ = sorted(_API)


def __getattr__(name: str):
    if name in _API:
        return getattr(importlib.import_module(f"{__name__}.{_API[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})
