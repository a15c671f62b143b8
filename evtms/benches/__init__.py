"""Component benches: steady-state physics swept over N-D grids.

``BENCHES`` maps each component name to its :class:`~evtms.benches.base.Bench`.
"""

from __future__ import annotations

from evtms.benches.base import Bench
from evtms.benches.condenser import BENCH as _CONDENSER

BENCHES: dict[str, Bench] = {b.name: b for b in (_CONDENSER,)}

__all__ = ["BENCHES", "Bench"]
