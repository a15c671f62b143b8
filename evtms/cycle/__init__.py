"""Vapor-compression cycle on component LUTs, with a direct-physics reference.

``run_cycle`` solves operating points of a circuit (:mod:`evtms.cycle.topology`:
``cabin``, ``chiller``, ``cabin+chiller``) from LUT files, or from the benches
directly when no LUTs are given; ``solve_grid`` does it on every combination of
input values; see :mod:`evtms.cycle.solver` for the closure.
"""

from evtms.cycle.api import cycle_dataset, energy_balance, load_cycle_luts, run_cycle, solve_grid
from evtms.cycle.results import BranchResult, CycleResult
from evtms.cycle.solver import CYCLE_FLAGS, CycleSolver, CycleStatus, OperatingPoints
from evtms.cycle.topology import INPUTS, TOPOLOGIES, Topology

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
