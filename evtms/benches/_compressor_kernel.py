"""Compiled per-point twin of the compressor bench (:func:`evtms.benches.compressor.compressor_power`).

:func:`compress_points` runs, point by point in machine code, what the bench
does over arrays: the suction state, the clearance-volume volumetric
efficiency and the mass flow (Stoecker and Jones 1982, ch. 11), the
isentropic discharge ``h(p_out, s_in)`` and the outlet state from the
isentropic efficiency (Dincer and Kanoglu 2010, ch. 4), and the status of
each point before :func:`evtms.benches.base.finish_status`. The equations and
their order are those of :mod:`evtms.benches.compressor`; only the properties
come from elsewhere, the tables of :mod:`evtms.fluid_tables` (single phase in
``(p, T)`` with the entropy column, ``(p, h) -> T``, ``(p, s) -> h``).

So the bench's NumPy path fed with :class:`evtms.fluid_tables.TabulatedFluid`
is this kernel's reference to round-off (``tests/test_compressor_kernel.py``
holds them to 1e-9 relative). Each point's result depends on its own inputs
only. A point whose states leave the tables (suction or discharge pressure,
temperature beyond them) is marked ``fallback`` for the caller to solve with
CoolProp.

numba keys its cache on a function's own file: after editing one of the
kernels this module calls, touch this file (or clear
``evtms/benches/__pycache__/*.nb*``).

References
----------
Stoecker, W. F., Jones, J. W. (1982). Refrigeration and Air Conditioning,
2nd ed., McGraw-Hill, ch. 11 (clearance volumetric efficiency).
Dincer, I., Kanoglu, M. (2010). Refrigeration Systems and Applications, 2nd
ed., Wiley, ch. 4 (isentropic and mechanical efficiencies).
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.fluid_tables import (
    PHASE_COLUMNS,
    SAT_COLUMNS,
    ph_temperature,
    pressure_stencil,
    ps_enthalpy,
    pt_state,
    sat_column,
)

#: The kernel's outputs per point, in the order of its output columns (``code``: the bench's
#: status before ``finish_status``; ``fallback``: 1.0 where CoolProp must decide the point).
COLUMNS = ("W", "mdot", "h_in", "h_out", "T_out", "eta_vol", "code", "fallback")
#: The compressor constants :func:`compress_points` reads, in this order.
CONSTANTS = (
    "displacement",
    "speed_max",
    "eta_isentropic",
    "eta_vol_nominal",
    "pr_nominal",
    "polytropic_exponent",
    "eta_mechanical",
    "p_crit",
)
_DISP, _NMAX, _ETA_IS, _ETA_V0, _PR0, _N_POLY, _ETA_M, _P_CRIT = range(len(CONSTANTS))
_H, _RHO, _S = PHASE_COLUMNS.index("h"), PHASE_COLUMNS.index("rho"), PHASE_COLUMNS.index("s")
_HL, _HV = SAT_COLUMNS.index("h_l"), SAT_COLUMNS.index("h_v")
# The bench's status codes (evtms.benches.base, evtms.benches.compressor).
_OUTSIDE, _LIQUID_SUCTION, _NO_FLOW = 1, 3, 4


@jit
def compress_point(speed, pr, p_in, x_in, by_enthalpy, c, meta, sat, vap, liq, out) -> None:
    """One point into ``out`` (:data:`COLUMNS`): suction ``(p_in, T_in)`` or, with
    ``by_enthalpy``, ``(p_in, h_in)`` with ``x_in`` the temperature [K] or enthalpy [J/kg];
    ``c`` the :data:`CONSTANTS` (:func:`compress_in` with its work row made here)."""
    compress_in(speed, pr, p_in, x_in, by_enthalpy, c, meta, sat, vap, liq, out, np.empty(len(PHASE_COLUMNS)))


# Allocates nothing (its work row comes from its caller), so it runs without reference counting
# (evtms._jit.uncounted).
@jit(counted=False)
def compress_in(speed, pr, p_in, x_in, by_enthalpy, c, meta, sat, vap, liq, out, row) -> None:
    """:func:`compress_point`; ``row`` holds the suction's single-phase state (work)."""
    if by_enthalpy:
        h_in = x_in
        pt_state(meta, sat, vap, liq, p_in, ph_temperature(meta, sat, vap, liq, p_in, h_in), row)
    else:
        pt_state(meta, sat, vap, liq, p_in, x_in, row)
        h_in = row[_H]
    rho, s_in = row[_RHO], row[_S]
    st = pressure_stencil(meta, p_in)
    h_l, h_v = sat_column(sat, st, _HL), sat_column(sat, st, _HV)
    n = c[_N_POLY]
    C = (1.0 - c[_ETA_V0]) / (c[_PR0] ** (1.0 / n) - 1.0)
    eta_vol = 1.0 + C - C * pr ** (1.0 / n)
    for j in range(out.size):
        out[j] = math.nan
    out[5] = eta_vol
    out[7] = 0.0
    if not math.isfinite(h_in + rho + s_in + h_v):  # beyond the tables: CoolProp decides
        out[6] = _OUTSIDE
        out[7] = 1.0
        return
    # Vapour strictly above saturation, as the bench: (p, T) exactly at saturation is wet.
    if not ((h_in - h_l) / (h_v - h_l) > 1.0):
        out[6] = _LIQUID_SUCTION
    elif not (eta_vol > 0.0):
        out[6] = _NO_FLOW
    else:
        out[6] = 0.0
    mdot = eta_vol * rho * c[_DISP] * speed * c[_NMAX] / 60.0
    out[1], out[2] = mdot, h_in
    if out[6] != 0.0:
        return
    p_out = pr * p_in
    h_out = h_in + (ps_enthalpy(meta, sat, vap, liq, p_out, s_in) - h_in) / c[_ETA_IS]
    T_out = ph_temperature(meta, sat, vap, liq, p_out, h_out)
    if not math.isfinite(h_out + T_out):  # a discharge beyond the tables (above 450 K, say)
        out[7] = 1.0
        return
    out[0] = mdot * (h_out - h_in) / c[_ETA_M]
    out[3], out[4] = h_out, T_out


@jit
def compress_points(speed, pr, p_in, x_in, by_enthalpy, c, tables):
    """:func:`compress_point` over arrays of points: an ``(n, len(COLUMNS))`` array;
    ``tables`` is :attr:`evtms.fluid_tables.PropertyTables.arrays`."""
    meta, sat, vap, liq = tables
    out = np.empty((p_in.size, len(COLUMNS)))
    row = np.empty(len(COLUMNS))
    state = np.empty(len(PHASE_COLUMNS))
    for k in range(p_in.size):
        compress_in(speed[k], pr[k], p_in[k], x_in[k], by_enthalpy, c, meta, sat, vap, liq, row, state)
        out[k, :] = row
    return out
