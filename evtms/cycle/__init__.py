"""Vapor-compression cycle on component LUTs, with a direct-physics reference.

``run_cycle`` solves operating points of a circuit (:mod:`evtms.cycle.topology`:
``cabin``, ``chiller``, ``cabin+chiller``) from LUT files, or from the benches
directly when no LUTs are given; ``solve_grid`` does it on every combination of
input values; see :mod:`evtms.cycle.solver` for the closure.

The names below are loaded when first used: a caller of one submodule (the
system simulator reads LUT folders and topologies, never the solver) does not
import the solver and its models.
"""

from __future__ import annotations

import importlib

#: Name -> the submodule that defines it.
_NAMES = {
    "cycle_dataset": "api",
    "energy_balance": "api",
    "load_cycle_luts": "api",
    "run_cycle": "api",
    "solve_grid": "api",
    "BranchResult": "results",
    "CycleResult": "results",
    "CYCLE_FLAGS": "solver",
    "CycleSolver": "solver",
    "CycleStatus": "solver",
    "OperatingPoints": "solver",
    "INPUTS": "topology",
    "TOPOLOGIES": "topology",
    "Topology": "topology",
}

__all__ = [
    "CYCLE_FLAGS",
    "INPUTS",
    "TOPOLOGIES",
    "BranchResult",
    "CycleResult",
    "CycleSolver",
    "CycleStatus",
    "Topology",
    "OperatingPoints",
    "cycle_dataset",
    "energy_balance",
    "load_cycle_luts",
    "run_cycle",
    "solve_grid",
]


def __getattr__(name: str):
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
