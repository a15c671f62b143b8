"""Component benches: steady-state physics swept over N-D grids.

``BENCHES`` maps each component name to its :class:`~evtms.benches.base.Bench`,
declared once in the component's module (its axes, outputs, status flags,
presets and physics); the command line, the LUT schema and validation, the
sweeps and the reports derive everything from it. Adding a component is its
module plus one line in :data:`MODULES`.
"""

from __future__ import annotations

import importlib

from evtms.benches.base import Bench
from evtms.luts.schema import ComponentSpec

#: The registry: one line per component, the module (in this package) that declares its ``BENCH``.
MODULES = (
    "condenser",
    "evaporator",
    "expansion_valve",
    "compressor",
    "chiller",
    "radiator",
    "heater_core",
    "wcc",
)

BENCHES: dict[str, Bench] = {
    bench.name: bench for bench in (importlib.import_module(f"{__name__}.{m}").BENCH for m in MODULES)
}


def component_specs() -> dict[str, ComponentSpec]:
    """Every component's LUT contents, for :func:`evtms.luts.schema.component_specs`."""
    return {name: bench.lut_spec() for name, bench in BENCHES.items()}


__all__ = ["BENCHES", "Bench", "component_specs"]
