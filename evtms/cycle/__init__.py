"""Vapor-compression cycle on component LUTs, with a direct-physics reference.

``run_cycle`` solves operating points from LUT files (or the benches directly
with ``direct=True``); see :mod:`evtms.cycle.solver` for the closure.
"""

from evtms.cycle.api import cycle_dataset, energy_balance, load_cycle_luts, run_cycle
from evtms.cycle.solver import CYCLE_FLAGS, CycleSolver, OperatingPoints

__all__ = [
    "CYCLE_FLAGS",
    "CycleSolver",
    "OperatingPoints",
    "cycle_dataset",
    "energy_balance",
    "load_cycle_luts",
    "run_cycle",
]
