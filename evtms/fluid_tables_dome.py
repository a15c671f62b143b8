r"""Two-phase (p, h) states on the tabulated refrigerant properties (:mod:`evtms.fluid_tables`).

:mod:`evtms.fluid_tables` answers single-phase states; an evaporator's inlet
is usually inside the dome, where CoolProp's density is that of the
homogeneous mixture at the quality ``x = (h - h_l) / (h_v - h_l)``,

.. math:: \frac{1}{\rho} = \frac{x}{\rho_v} + \frac{1 - x}{\rho_l}

(the specific volumes of the saturated phases weighted by mass; Bell et al.
2014, CoolProp's two-phase state). :func:`ph_density` gives it from the
tabulated saturation columns, and the single-phase density of
:func:`evtms.fluid_tables.pt_state` at :func:`evtms.fluid_tables.ph_temperature`
outside the dome; :class:`DomeTabulatedFluid` is
:class:`evtms.fluid_tables.TabulatedFluid` with that density for the pair
``"PH"``. Its tolerance against CoolProp is that of the saturation columns
(about 1e-6 relative in the densities).

References
----------
Bell, I. H., Wronski, J., Quoilin, S., Lemort, V. (2014). Pure and pseudo-pure
fluid thermophysical property evaluation and the open-source thermophysical
property library CoolProp. Ind. Eng. Chem. Res. 53(6), 2498-2508.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.fluid_tables import (
    PHASE_COLUMNS,
    SAT_COLUMNS,
    TabulatedFluid,
    ph_temperature,
    pressure_stencil,
    pt_state,
    sat_column,
)

_HL, _HV = SAT_COLUMNS.index("h_l"), SAT_COLUMNS.index("h_v")
_RHO_L, _RHO_V = SAT_COLUMNS.index("rho_l"), SAT_COLUMNS.index("rho_v")
_RHO = PHASE_COLUMNS.index("rho")


@jit
def ph_density(meta, sat, vapour, liquid, p: float, h: float) -> float:
    """Density [kg/m3] at ``(p [Pa], h [J/kg])``: the homogeneous mixture's inside the dome
    (``h_l <= h <= h_v``), else the single phase's at :func:`~evtms.fluid_tables.ph_temperature`;
    NaN outside the tables (:func:`ph_density_in` with its work array made here)."""
    return ph_density_in(meta, sat, vapour, liquid, p, h, np.empty(len(PHASE_COLUMNS)))


@jit(counted=False)
def ph_density_in(meta, sat, vapour, liquid, p: float, h: float, row) -> float:
    """:func:`ph_density`; ``row`` (at least two long) holds the single phase's state (work)."""
    st = pressure_stencil(meta, p)
    if st[0] < 0 or h != h:
        return math.nan
    h_l = sat_column(sat, st, _HL)
    h_v = sat_column(sat, st, _HV)
    if h_l <= h <= h_v:
        x = (h - h_l) / (h_v - h_l)
        return 1.0 / (x / sat_column(sat, st, _RHO_V) + (1.0 - x) / sat_column(sat, st, _RHO_L))
    pt_state(meta, sat, vapour, liquid, p, ph_temperature(meta, sat, vapour, liquid, p, h), row)
    return row[_RHO]


@jit
def _ph_density_many(meta, sat, vapour, liquid, p, h, out):
    row = np.empty(len(PHASE_COLUMNS))
    for n in range(p.size):
        out[n] = ph_density_in(meta, sat, vapour, liquid, p[n], h[n], row)


class DomeTabulatedFluid(TabulatedFluid):
    """:class:`evtms.fluid_tables.TabulatedFluid` whose ``"PH"`` density is CoolProp's inside the dome too.

    The NumPy reference of the compiled chiller (:mod:`evtms.benches._chiller_kernel`): its inlet
    is usually two-phase, and the port pressure drop reads the inlet density.
    """

    def __repr__(self) -> str:
        return f"DomeTabulatedFluid({self.name!r}, backend={self.backend!r})"

    def state(
        self, pair: str, a: np.ndarray | float, b: np.ndarray | float, outputs: tuple[str, ...] = ("T", "H", "D")
    ) -> dict[str, np.ndarray]:
        """:meth:`evtms.fluid_tables.TabulatedFluid.state`, with :func:`ph_density` for ``("PH", "D")``."""
        out = super().state(pair, a, b, outputs)
        if pair == "PH" and "D" in outputs:
            p, h = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
            flat = np.empty(p.size)
            _ph_density_many(
                *self.tables.arrays, np.ascontiguousarray(p.reshape(-1)), np.ascontiguousarray(h.reshape(-1)), flat
            )
            out["D"] = flat.reshape(p.shape)
        return out
