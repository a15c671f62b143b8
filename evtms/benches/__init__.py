"""Component benches: steady-state physics swept over N-D grids.

``BENCHES`` maps each component name to its :class:`~evtms.benches.base.Bench`.
"""

from __future__ import annotations

from evtms.benches.base import Bench
from evtms.benches.compressor import BENCH as _COMPRESSOR
from evtms.benches.condenser import BENCH as _CONDENSER
from evtms.benches.evaporator import BENCH as _EVAPORATOR
from evtms.benches.expansion_valve import BENCH as _VALVE

BENCHES: dict[str, Bench] = {b.name: b for b in (_CONDENSER, _EVAPORATOR, _VALVE, _COMPRESSOR)}

__all__ = ["BENCHES", "Bench"]
