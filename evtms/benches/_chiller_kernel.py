"""Compiled per-point twin of the plate chiller's solve (:func:`evtms.benches.chiller.solve_chiller`).

:func:`solve_points` runs, point by point in machine code, what
``solve_chiller`` does over arrays: the refrigerant states, Martin's (1996)
single-phase and Yan and Lin's (1999) evaporation coefficients
(:mod:`evtms.hx._plate_kernels`), the fixed point of the mean heat flux, the
two passes of the coolant's mean temperature, the counter-flow
moving-boundary solve (:mod:`evtms.hx._counterflow_kernels`), the pressure
drop over the zone lengths and the ports, the outlet state and the masks
behind the bench's statuses. The equations, their sources and the order of
the steps are those of :mod:`evtms.benches.chiller`; this module only
changes where the properties come from:

- refrigerant: the tables of :mod:`evtms.fluid_tables` (saturation against
  pressure, single phase in (p, T), (p, h) -> T) and the two-phase density
  of :mod:`evtms.fluid_tables_dome`;
- coolant: the :class:`evtms.fluid.Coolant` tables, interpolated linearly as
  ``np.interp`` does (the NumPy path reads the same tables).

So ``solve_chiller`` fed with :class:`evtms.fluid_tables_dome.DomeTabulatedFluid`
is this kernel's reference to round-off (``tests/test_chiller.py`` holds them
to 1e-9 relative), and against CoolProp it is within the tables' tolerance
(Q, h_out and dp within 1e-4 relative on the bench grids, the same test).
Each point's result depends on its own inputs only, so a sweep gives the same
numbers whatever its chunks. A point whose refrigerant states leave the
tables (``outside_tables``) is for the caller to solve with CoolProp.

numba keys its cache on a function's own file: after editing one of the
kernels this module calls, touch this file (or clear
``evtms/benches/__pycache__/*.nb*``).
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.fluid_tables import SAT_COLUMNS, ph_temperature, pt_state, saturation
from evtms.fluid_tables_dome import ph_density_in
from evtms.hx._counterflow_kernels import heat_rate_point, solve_point, table_interp
from evtms.hx._kernels import nan_max, nan_min
from evtms.hx._plate_kernels import (
    equivalent_mass_flux,
    martin_friction_factor,
    martin_nusselt,
    martin_outside_range,
    yan_lin_friction_factor,
    yan_lin_outside_range,
)

#: The kernel's outputs per point, in the order of its output columns (masks are 0.0 or 1.0).
COLUMNS = (
    "Q",
    "h_out",
    "p_out",
    "dp",
    "T_out",
    "x_out",
    "T_coolant_out",
    "h_coolant_in",
    "h_coolant_out",
    "UA",
    "f_liquid",
    "f_two_phase",
    "f_vapour",
    "capacity_ratio",
    "h_out_continued",
    "Re_coolant",
    "Re_eq",
    "outside_range",
    "bad_direction",
    "bad_dp",
    "bad_flow",
    "coolant_freezes",
    "coolant_outside",
    "bad_props",
    "outside_tables",
)
#: The geometry and parameters the kernel reads, in the order of its ``geo`` argument.
GEOMETRY = (
    "area",
    "D_h",
    "flow_ref",
    "flow_coolant",
    "port_area",
    "R_wall",
    "fouling_ref",
    "fouling_coolant",
    "plate_length",
    "chevron_angle",
    "port_velocity_heads",
    "flux_steps",
)
#: The coolant tables of the kernel's ``cool`` argument, (x, y) columns of :meth:`evtms.fluid.Coolant.tables`
#: each as an :func:`evtms.hx._counterflow_kernels.bucket_table`.
COOLANT_TABLES = (("T", "h"), ("T", "CP"), ("T", "D"), ("T", "MU"), ("T", "K"), ("h", "T"))

_T, _HL, _HV, _RHO_L, _RHO_V, _CP_L, _CP_V, _MU_L, _MU_V, _K_L, _K_V = range(len(SAT_COLUMNS))
_A, _DH, _FLOW_REF, _FLOW_C, _PORT, _R_WALL, _FOUL_REF, _FOUL_C, _LENGTH, _ANGLE, _HEADS, _FLUX = range(len(GEOMETRY))


@jit(counted=False)
def _martin_htc(G, D_h, rho, cp, mu, k, angle):
    """Single-phase coefficient [W/(m2 K)] and Reynolds number [1] of a plate channel (Martin 1996),
    as :func:`evtms.benches.chiller.martin_htc`."""
    Re = G * D_h / mu
    Pr = cp * mu / k
    return martin_nusselt(Re, Pr, angle) * k / D_h, Re


@jit(counted=False)
def _phase_props(meta, sat, vap, liq, p, T, s, vapour, row):
    """Density, heat capacity, viscosity and conductivity at ``(p, T)``, each falling back to the
    saturated phase's (``s``) where the tables give none (:func:`evtms.benches.chiller.refrigerant_props`);
    ``row``: work (the single phase's state)."""
    pt_state(meta, sat, vap, liq, p, T, row)
    fall = (s[_RHO_V], s[_CP_V], s[_MU_V], s[_K_V]) if vapour else (s[_RHO_L], s[_CP_L], s[_MU_L], s[_K_L])
    rho = row[1] if math.isfinite(row[1]) else fall[0]
    cp = row[2] if math.isfinite(row[2]) else fall[1]
    mu = row[3] if math.isfinite(row[3]) else fall[2]
    k = row[4] if math.isfinite(row[4]) else fall[3]
    return rho, cp, mu, k


@jit(counted=False)
def _yan_lin_factor(G, D_h, s, nodes, weights):
    """Yan and Lin's coefficient averaged over quality 0..1 (Gauss-Legendre) per ``q^0.3``
    [W/(m2 K) (W/m2)^-0.3], and Re_eq at x = 1/2, as :func:`evtms.benches.chiller._yan_lin_mean`.

    The coefficient goes as ``Bo_eq^0.3 = q^0.3 (G_eq h_lv)^-0.3`` (Yan and Lin 1999): the mean
    at flux ``q`` is this factor times ``q^0.3``, so the flux's fixed point needs one power a
    step, not one average over the nodes."""
    Pr_l = s[_CP_L] * s[_MU_L] / s[_K_L]
    h_lv = s[_HV] - s[_HL]
    mu_l, rho_l, rho_v = s[_MU_L], s[_RHO_L], s[_RHO_V]
    Re = G * D_h / mu_l
    factor = 0.0
    for j in range(nodes.size):
        G_eq = equivalent_mass_flux(G, nodes[j], rho_l, rho_v)
        factor += G_eq * D_h / mu_l * (G_eq * h_lv) ** -0.3 * weights[j]
    factor *= 1.926 * (s[_K_L] / D_h) * Pr_l ** (1.0 / 3.0) * Re**-0.5
    Re_eq = equivalent_mass_flux(G, 0.5, rho_l, rho_v) * D_h / mu_l
    return factor, Re_eq


@jit(counted=False)
def _two_phase_gradient(G, D_h, s, x0, x1, nodes, weights):
    """Mean two-phase frictional gradient [Pa/m] over quality x0..x1 (Yan and Lin 1999),
    as :func:`evtms.benches.chiller._two_phase_gradient`."""
    grad = 0.0
    for j in range(nodes.size):
        x = x0 + (x1 - x0) * nodes[j]
        Re_eq = equivalent_mass_flux(G, x, s[_RHO_L], s[_RHO_V]) * D_h / s[_MU_L]
        Re = G * D_h / s[_MU_L]
        rho_m = 1.0 / (x / s[_RHO_V] + (1.0 - x) / s[_RHO_L])
        grad += 2.0 * yan_lin_friction_factor(Re_eq, Re) * G**2 / (rho_m * D_h) * weights[j]
    return grad


@jit(counted=False)
def _clip01(x: float) -> float:
    """``np.clip(x, 0, 1)`` (NaN stays NaN)."""
    return nan_min(nan_max(x, 0.0), 1.0)


@jit(counted=False)
def _resistances(T_c_mean, ref, geo, cool, s, gauss):
    """One pass of :func:`evtms.benches.chiller.solve_chiller`'s coolant loop up to the solve: the
    coolant side at ``T_c_mean`` [K], the mean two-phase coefficient at the fixed-point heat flux
    and the zone resistances.

    Returns the coolant resistance [K/W] and Reynolds number, Re_eq and the three zone
    resistances [K/W] (liquid, two-phase, vapour)."""
    mdot, h_in, T_in, T_sat, h_l, h_v, h_at_c, h_liq, h_vap, R_fixed, G, G_c, m_c, T_c_in, h_c_in = ref
    nodes, weights = gauss
    A, D_h, angle = geo[_A], geo[_DH], geo[_ANGLE]
    cp_c = table_interp(T_c_mean, cool[1])
    rho_c, mu_c = table_interp(T_c_mean, cool[2]), table_interp(T_c_mean, cool[3])
    k_c = table_interp(T_c_mean, cool[4])
    h_c, Re_c = _martin_htc(G_c, D_h, rho_c, cp_c, mu_c, k_c, angle)
    R_c = 1.0 / (h_c * A) + geo[_FOUL_C] / A
    C_c = m_c * cp_c
    q = 5000.0  # mean heat flux of an all-two-phase exchanger, by fixed point (Yan and Lin's h ~ q^0.3)
    factor, Re_eq = _yan_lin_factor(G, D_h, s, nodes, weights)
    h_tp = math.nan
    for _ in range(int(geo[_FLUX])):
        h_tp = factor * q**0.3
        UA = 1.0 / (R_c + R_fixed + 1.0 / (h_tp * A))
        q = nan_max(C_c * -math.expm1(-UA / C_c) * abs(T_c_in - T_sat) / A, 1.0)
    R0, R1, R2 = R_fixed + 1.0 / (h_liq * A), R_fixed + 1.0 / (h_tp * A), R_fixed + 1.0 / (h_vap * A)
    return R_c, Re_c, Re_eq, R0, R1, R2


@jit(counted=False)
def plate_outlet_point(tables, s, geo, p_in, h_out, h_l, h_lv, mdot, rho_in, dp_channels, p_triple, row):
    """One point of :func:`evtms.benches.chiller.plate_outlet`: the ports' loss (1.4 velocity heads each
    at the inlet's and the outlet's density, Shah and Focke 1988) added to the channels' drop, and the
    outlet state at the outlet pressure (``s`` is overwritten with its saturation row; ``row`` is work).

    Returns ``dp`` [Pa], ``p_out`` [Pa], ``bad_dp``, ``x_out`` [1], ``T_out`` [K] and the outlet's
    density at the inlet pressure [kg/m3] (NaN where the outlet is not a state)."""
    meta, sat, vap, liq = tables
    x_hx = (h_out - h_l) / h_lv
    if x_hx >= 0.0 and x_hx <= 1.0:
        rho_out = 1.0 / (x_hx / s[_RHO_V] + (1.0 - x_hx) / s[_RHO_L])
    elif math.isfinite(h_out):
        rho_out = ph_density_in(meta, sat, vap, liq, p_in, h_out, row)
    else:
        rho_out = math.nan
    G_port = mdot / geo[_PORT]
    dp = dp_channels + geo[_HEADS] * G_port**2 / 2.0 * (1.0 / rho_in + 1.0 / rho_out)
    p_out = p_in - dp
    bad_dp = not (p_out > p_triple)
    p_ok = math.nan if bad_dp else p_out
    saturation(meta, sat, p_ok, s)
    x_out = (h_out - s[_HL]) / (s[_HV] - s[_HL])
    T_out = s[_T]
    if not (x_out >= 0.0 and x_out <= 1.0):
        T_out = ph_temperature(meta, sat, vap, liq, p_ok, h_out)
    return dp, p_out, bad_dp, x_out, T_out, rho_out


@jit
def solve_point_chiller(
    p_in, h_in, mdot, m_c, T_c_in, geo, cool, T_freeze, T_max_c, p_triple, curve_p_min, tables, gauss, out
):
    """One point of :func:`evtms.benches.chiller.solve_chiller` into ``out`` (:data:`COLUMNS`):
    :func:`chiller_in` with its work arrays made here."""
    work = (np.empty(len(SAT_COLUMNS)), np.empty(5))
    chiller_in(
        p_in, h_in, mdot, m_c, T_c_in, geo, cool, T_freeze, T_max_c, p_triple, curve_p_min, tables, gauss, out, work
    )


# The point allocates nothing (its work arrays come from its caller), so it runs without reference
# counting (evtms._jit.uncounted).
@jit(counted=False)
def chiller_in(
    p_in, h_in, mdot, m_c, T_c_in, geo, cool, T_freeze, T_max_c, p_triple, curve_p_min, tables, gauss, out, work
):
    """One point of :func:`evtms.benches.chiller.solve_chiller` into ``out`` (:data:`COLUMNS`).

    ``geo``: :data:`GEOMETRY`; ``cool``: the coolant's tables (:data:`COOLANT_TABLES`);
    ``T_freeze``, ``T_max_c``: the coolant's freezing point and table top [K]; ``p_triple``
    [Pa]; ``curve_p_min``: the lowest pressure of the CoolProp path's saturation curve [Pa]
    (below it that path has no outlet state either); ``tables``: ``(meta, sat, vapour,
    liquid)`` of :mod:`evtms.fluid_tables`; ``gauss``: Gauss-Legendre nodes and weights on [0, 1];
    ``work``: the saturation state's and a single phase's rows (written).
    """
    meta, sat, vap, liq = tables
    nodes, weights = gauss
    A, D_h, angle = geo[_A], geo[_DH], geo[_ANGLE]
    bad_flow = not (mdot > 0 and m_c > 0)
    if bad_flow:
        mdot, m_c = math.nan, math.nan
    coolant_freezes = T_c_in < T_freeze
    coolant_outside = (not coolant_freezes) and not (T_c_in <= T_max_c)
    if coolant_freezes or coolant_outside:
        T_c_in = math.nan

    # --- refrigerant states ---------------------------------------------------------
    s, row = work
    saturation(meta, sat, p_in, s)
    T_sat, h_l, h_v = s[_T], s[_HL], s[_HV]
    T_in = ph_temperature(meta, sat, vap, liq, p_in, h_in)
    rho_in = ph_density_in(meta, sat, vap, liq, p_in, h_in, row)
    pt_state(meta, sat, vap, liq, p_in, T_c_in, row)
    h_at_c = row[0]
    G = mdot / geo[_FLOW_REF]
    G_c = m_c / geo[_FLOW_C]
    bad_props = not math.isfinite(T_in + T_sat + h_at_c)

    reachable = T_c_in > T_sat
    T_end_l = T_sat if reachable else T_c_in
    rho_lq, cp_lq, mu_lq, k_lq = _phase_props(
        meta, sat, vap, liq, p_in, 0.5 * (nan_min(T_in, T_sat) + T_end_l), s, False, row
    )
    h_liq, Re_liq = _martin_htc(G, D_h, rho_lq, cp_lq, mu_lq, k_lq, angle)
    T0_v = T_in if h_in >= h_v else T_sat
    rho_vp, cp_vp, mu_vp, k_vp = _phase_props(meta, sat, vap, liq, p_in, 0.5 * (T0_v + T_c_in), s, True, row)
    h_vap, Re_vap = _martin_htc(G, D_h, rho_vp, cp_vp, mu_vp, k_vp, angle)
    R_fixed = geo[_R_WALL] + geo[_FOUL_REF] / A
    h_c_in = table_interp(T_c_in, cool[0])

    # --- coolant properties at the inlet, then at the mean temperature ---------------
    ref = (mdot, h_in, T_in, T_sat, h_l, h_v, h_at_c, h_liq, h_vap, R_fixed, G, G_c, m_c, T_c_in, h_c_in)
    # The first pass needs the coolant's outlet temperature only.
    R_c, _, _, R0, R1, R2 = _resistances(T_c_in, ref, geo, cool, s, gauss)
    args = (mdot, h_in, T_in, T_sat, h_l, h_v, h_at_c, R0, R1, R2, m_c, T_c_in, h_c_in, R_c, cool[5])
    Q_first, T_c_out = heat_rate_point(*args)
    T_c_mean = 0.5 * (T_c_in + T_c_out) if math.isfinite(T_c_out) else T_c_in
    R_c, Re_c, Re_eq, R0, R1, R2 = _resistances(T_c_mean, ref, geo, cool, s, gauss)
    res = solve_point(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_c, R0, R1, R2, m_c, T_c_in, h_c_in, R_c, cool[5], Q_first)
    Q, f0, f1, f2, h_out, h_c_out, T_c_out, _, capacity_ratio, h_continued, bad_direction = res

    # --- pressure drop over the zone lengths, plus the ports -------------------------
    L = geo[_LENGTH]
    grad_l = martin_friction_factor(Re_liq, angle) * G**2 / (2.0 * rho_lq * D_h)
    grad_v = martin_friction_factor(Re_vap, angle) * G**2 / (2.0 * rho_vp * D_h)
    h_lv = h_v - h_l
    x0 = _clip01((nan_max(h_in, h_l) - h_l) / h_lv)
    x1 = _clip01((nan_min(h_out, h_v) - h_l) / h_lv)
    grad_tp = _two_phase_gradient(G, D_h, s, x0, x1, nodes, weights)
    dp_channels = grad_l * (f0 * L) + grad_tp * (f1 * L) + grad_v * (f2 * L)
    dp, p_out, bad_dp, x_out, T_out, rho_out = plate_outlet_point(
        tables, s, geo, p_in, h_out, h_l, h_lv, mdot, rho_in, dp_channels, p_triple, row
    )
    p_ok = math.nan if bad_dp else p_out
    coolant_freezes = coolant_freezes or T_c_out < T_freeze

    outside = martin_outside_range(Re_c, angle)
    outside = outside or (f0 > 0 and martin_outside_range(Re_liq, angle))
    outside = outside or (f2 > 0 and martin_outside_range(Re_vap, angle))
    outside = outside or (f1 > 0 and yan_lin_outside_range(Re_eq))
    UA_total = f0 / (R0 + R_c) + f1 / (R1 + R_c) + f2 / (R2 + R_c)
    bad_props = bad_props or not math.isfinite(T_out + x_out + T_c_out + dp)

    # States the tables do not hold but CoolProp may: the caller solves those points with it.
    inputs_ok = math.isfinite(h_in + mdot + m_c + T_c_in)
    missing = not math.isfinite(T_sat + T_in + h_at_c + rho_in)
    missing = missing or (math.isfinite(h_out) and not math.isfinite(rho_out))
    missing = missing or (p_ok >= curve_p_min and not math.isfinite(x_out + T_out))
    values = (
        -Q,
        h_out,
        p_out,
        dp,
        T_out,
        x_out,
        T_c_out,
        h_c_in,
        h_c_out,
        UA_total,
        f0,
        f1,
        f2,
        capacity_ratio,
        h_continued,
        Re_c,
        Re_eq,
        1.0 if outside else 0.0,
        bad_direction,
        1.0 if bad_dp else 0.0,
        1.0 if bad_flow else 0.0,
        1.0 if coolant_freezes else 0.0,
        1.0 if coolant_outside else 0.0,
        1.0 if bad_props else 0.0,
        1.0 if (inputs_ok and missing) else 0.0,
    )
    for j in range(len(values)):
        out[j] = values[j]


@jit
def solve_points(p_in, h_in, mdot, m_c, T_c_in, geo, cool, T_freeze, T_max_c, p_triple, curve_p_min, tables, gauss):
    """:func:`solve_point_chiller` over arrays of points: an ``(n, len(COLUMNS))`` array."""
    out = np.empty((p_in.size, len(COLUMNS)))
    work = (np.empty(len(SAT_COLUMNS)), np.empty(5))
    for i in range(p_in.size):
        chiller_in(
            p_in[i],
            h_in[i],
            mdot[i],
            m_c[i],
            T_c_in[i],
            geo,
            cool,
            T_freeze,
            T_max_c,
            p_triple,
            curve_p_min,
            tables,
            gauss,
            out[i],
            work,
        )
    return out
