"""Compiled per-point twin of the water-cooled condenser's solve (:func:`evtms.benches.wcc.solve_wcc`).

:func:`solve_points` runs, point by point in machine code, what ``solve_wcc``
does over arrays: the refrigerant states, Martin's (1996) single-phase and
Yan, Lio and Lin's (1999) condensation coefficients, the two passes over the
coolant's mean temperature and the condensing zone's quality range, the
counter-flow moving-boundary solve reflected in enthalpy and temperature
(:func:`evtms.hx.counterflow.solve_counterflow_condenser`, here
:func:`evtms.hx._counterflow_kernels.solve_point` on the reflected point),
the pressure drop over the zone lengths and the ports, the outlet state and
the masks behind the bench's statuses. The equations, their sources and the
order of the steps are those of :mod:`evtms.benches.wcc`; only the property
source changes, as in :mod:`evtms.benches._chiller_kernel`: the refrigerant
tables of :mod:`evtms.fluid_tables` (and the two-phase density of
:mod:`evtms.fluid_tables_dome`), the coolant's own tables interpolated as
``np.interp`` does.

So ``solve_wcc`` fed with :class:`evtms.fluid_tables_dome.DomeTabulatedFluid`
is this kernel's reference to round-off and CoolProp is within the tables'
tolerance (``tests/test_wcc.py``). A point whose refrigerant states leave the
tables (``outside_tables``) is for the caller to solve with CoolProp.

numba keys its cache on a function's own file: after editing a kernel this
module calls, touch this file (or clear ``evtms/benches/__pycache__/*.nb*``).
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.benches._chiller_kernel import (
    _A,
    _ANGLE,
    _CP_L,
    _DH,
    _FLOW_C,
    _FLOW_REF,
    _FOUL_C,
    _FOUL_REF,
    _HL,
    _HV,
    _K_L,
    _LENGTH,
    _MU_L,
    _R_WALL,
    _RHO_L,
    _RHO_V,
    _T,
    _martin_htc,
    _phase_props,
    plate_outlet_point,
)
from evtms.benches.wcc import _COOLANT_TOP_MARGIN, _PASSES
from evtms.fluid_tables import SAT_COLUMNS, ph_temperature, pt_state, saturation
from evtms.fluid_tables_dome import ph_density_in
from evtms.hx._counterflow_kernels import solve_point, table_interp
from evtms.hx._kernels import nan_max, nan_min
from evtms.hx._plate_kernels import equivalent_mass_flux, martin_friction_factor, martin_outside_range

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
    "outside_range",
    "inlet_subcooled",
    "supercritical",
    "not_below_inlet",
    "bad_dp",
    "bad_flow",
    "coolant_freezes",
    "coolant_outside",
    "bad_props",
    "outside_tables",
)


@jit(counted=False)
def _condensing_zone(G, D_h, s, x_hi, x_lo, angle, nodes, weights):
    """Mean condensing coefficient [W/(m2 K)] and frictional gradient [Pa/m] over quality
    ``x_lo..x_hi``, as :func:`evtms.benches.wcc._condensing_zone` (Yan, Lio and Lin 1999;
    Martin's friction factor on the equivalent liquid flux)."""
    mu_l, rho_l, rho_v, k_l = s[_MU_L], s[_RHO_L], s[_RHO_V], s[_K_L]
    Pr_l = s[_CP_L] * mu_l / k_l
    h_sum, grad_sum = 0.0, 0.0
    for j in range(nodes.size):
        x = x_lo + (x_hi - x_lo) * nodes[j]
        G_eq = equivalent_mass_flux(G, x, rho_l, rho_v)
        Re_eq = G_eq * D_h / mu_l
        h = 4.118 * Re_eq**0.4 * Pr_l ** (1.0 / 3.0) * k_l / D_h
        grad = martin_friction_factor(Re_eq, angle) * G_eq**2 / (2.0 * rho_l * D_h)
        h_sum += h * weights[j]
        grad_sum += grad * weights[j]
    return h_sum, grad_sum


@jit(counted=False)
def _clip(x, lo, hi):
    """``np.clip(x, lo, hi)`` (NaN stays NaN)."""
    return nan_min(nan_max(x, lo), hi)


@jit
def solve_point_wcc(
    p_in, h_in, mdot, m_c, T_c_in, geo, cool, mirrored, T_freeze, T_max_c, p_triple, p_crit, curve_p_min, g_range,
    tables, gauss, out,
):  # fmt: skip
    """One point of :func:`evtms.benches.wcc.solve_wcc` into ``out`` (:data:`COLUMNS`): :func:`wcc_in`
    with its work arrays made here."""
    work = (np.empty(len(SAT_COLUMNS)), np.empty(5))
    wcc_in(
        p_in, h_in, mdot, m_c, T_c_in, geo, cool, mirrored, T_freeze, T_max_c, p_triple, p_crit, curve_p_min, g_range,
        tables, gauss, out, work,
    )  # fmt: skip


# The point allocates nothing (its work arrays come from its caller), so it runs without reference
# counting (evtms._jit.uncounted).
@jit(counted=False)
def wcc_in(
    p_in,
    h_in,
    mdot,
    m_c,
    T_c_in,
    geo,
    cool,
    mirrored,
    T_freeze,
    T_max_c,
    p_triple,
    p_crit,
    curve_p_min,
    g_range,
    tables,
    gauss,
    out,
    work,
):
    """One point of :func:`evtms.benches.wcc.solve_wcc` into ``out`` (:data:`COLUMNS`).

    ``geo``: :data:`evtms.benches._chiller_kernel.GEOMETRY`; ``cool``: the coolant's tables
    (:data:`evtms.benches._chiller_kernel.COOLANT_TABLES`); ``mirrored``: its (h, T)
    table reflected (``-h`` rising, ``-T``) for the condensing solve; ``T_freeze``,
    ``T_max_c``: the coolant's freezing point and table top [K]; ``p_triple``, ``p_crit``
    [Pa]; ``curve_p_min``: the lowest pressure of the CoolProp path's saturation curve [Pa];
    ``g_range``: Yan, Lio and Lin's mass-flux range [kg/(m2 s)]; ``tables``: ``(meta, sat,
    vapour, liquid)`` of :mod:`evtms.fluid_tables`; ``gauss``: Gauss-Legendre nodes and weights
    on [0, 1]; ``work``: the saturation state's and a single phase's rows (written).
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
    supercritical = p_in >= p_crit
    s, row = work
    saturation(meta, sat, p_in, s)
    T_sat, h_l, h_v = s[_T], s[_HL], s[_HV]
    inlet_subcooled = h_in < h_l
    h_in_ok = math.nan if inlet_subcooled else h_in
    T_in = ph_temperature(meta, sat, vap, liq, p_in, h_in_ok)
    rho_in = ph_density_in(meta, sat, vap, liq, p_in, h_in_ok, row)
    not_below_inlet = (not (T_c_in < T_in)) and math.isfinite(T_c_in + T_in)
    T_c_ok = math.nan if not_below_inlet else T_c_in
    pt_state(meta, sat, vap, liq, p_in, T_c_ok, row)
    h_at_c = row[0]
    if T_c_ok >= T_sat and not (h_at_c > h_v):  # vapour at the coolant's temperature, h_v as it tends to T_sat
        h_at_c = h_v
    G = mdot / geo[_FLOW_REF]
    G_c = m_c / geo[_FLOW_C]
    bad_props = (not math.isfinite(T_in + T_sat + h_at_c)) and not inlet_subcooled and not not_below_inlet

    # Single-phase coefficients at each zone's mean temperature (Martin 1996); the vapour zone
    # ends at the saturation or the coolant's inlet temperature, whichever is warmer.
    superheated = h_in_ok > h_v
    T_vap = 0.5 * (T_in + (T_c_ok if T_c_ok > T_sat else T_sat)) if superheated else math.nan
    rho_vp, cp_vp, mu_vp, k_vp = _phase_props(meta, sat, vap, liq, p_in, T_vap, s, True, row)
    h_vap, Re_vap = _martin_htc(G, D_h, rho_vp, cp_vp, mu_vp, k_vp, angle)
    T_liq = 0.5 * (T_sat + (T_c_ok if T_c_ok < T_sat else T_sat))
    rho_lq, cp_lq, mu_lq, k_lq = _phase_props(meta, sat, vap, liq, p_in, T_liq, s, False, row)
    h_liq, Re_liq = _martin_htc(G, D_h, rho_lq, cp_lq, mu_lq, k_lq, angle)
    R_fixed = geo[_R_WALL] + geo[_FOUL_REF] / A
    h_lv = h_v - h_l
    x_hi = _clip((nan_min(h_in_ok, h_v) - h_l) / h_lv, 0.0, 1.0)
    x_lo = 0.0
    h_c_in = table_interp(T_c_ok, cool[0])
    R_liq, R_vap = R_fixed + 1.0 / (h_liq * A), R_fixed + 1.0 / (h_vap * A)

    T_c_mean = T_c_ok
    res = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    R_c, Re_c, R_tp, grad_tp = math.nan, math.nan, math.nan, math.nan
    for _ in range(_PASSES):  # coolant at its inlet, then its mean; quality range to 0, then to the outlet's
        cp_c = table_interp(T_c_mean, cool[1])
        rho_c, mu_c = table_interp(T_c_mean, cool[2]), table_interp(T_c_mean, cool[3])
        k_c = table_interp(T_c_mean, cool[4])
        h_c, Re_c = _martin_htc(G_c, D_h, rho_c, cp_c, mu_c, k_c, angle)
        R_c = 1.0 / (h_c * A) + geo[_FOUL_C] / A
        h_tp, grad_tp = _condensing_zone(G, D_h, s, x_hi, x_lo, angle, nodes, weights)
        R_tp = R_fixed + 1.0 / (h_tp * A)
        # The condenser is the evaporator reflected in h and T (zones in reverse order).
        res = solve_point(
            mdot,
            -h_in_ok,
            -T_in,
            -T_sat,
            -h_v,
            -h_l,
            -h_at_c,
            R_vap,
            R_tp,
            R_liq,
            m_c,
            -T_c_ok,
            -h_c_in,
            R_c,
            mirrored,
            0.0,
        )
        T_c_out = -res[6]
        h_out = -res[4]
        T_c_mean = 0.5 * (T_c_ok + T_c_out) if math.isfinite(T_c_out) else T_c_ok
        x_lo = _clip((h_out - h_l) / h_lv, 0.0, x_hi) if math.isfinite(h_out) else 0.0
    Q, g0, g1, g2, h_out_m, h_c_out_m, T_c_out_m, _, capacity_ratio, h_continued_m, _ = res
    f0, f1, f2 = g2, g1, g0  # liquid, two-phase, vapour
    h_out, h_c_out, T_c_out, h_continued = -h_out_m, -h_c_out_m, -T_c_out_m, -h_continued_m

    # --- pressure drop over the zone lengths, plus the ports -------------------------
    L = geo[_LENGTH]
    grad_l = martin_friction_factor(Re_liq, angle) * G**2 / (2.0 * rho_lq * D_h)
    grad_v = martin_friction_factor(Re_vap, angle) * G**2 / (2.0 * rho_vp * D_h)
    dp_channels = grad_l * (f0 * L) + grad_tp * (f1 * L) + grad_v * (f2 * L)
    dp, p_out, bad_dp, x_out, T_out, rho_out = plate_outlet_point(
        tables, s, geo, p_in, h_out, h_l, h_lv, mdot, rho_in, dp_channels, p_triple, row
    )
    p_ok = math.nan if bad_dp else p_out
    coolant_outside = coolant_outside or (math.isfinite(T_c_ok) and not (T_c_out < T_max_c - _COOLANT_TOP_MARGIN))

    outside = martin_outside_range(Re_c, angle)
    outside = outside or (f0 > 0 and martin_outside_range(Re_liq, angle))
    outside = outside or (f2 > 0 and martin_outside_range(Re_vap, angle))
    outside = outside or (f1 > 0 and (G < g_range[0] or G > g_range[1]))
    UA_total = f0 / (R_liq + R_c) + f1 / (R_tp + R_c) + f2 / (R_vap + R_c)
    bad_props = bad_props or not math.isfinite(T_out + x_out + T_c_out + dp)

    # States the tables do not hold but CoolProp may: the caller solves those points with it.
    inputs_ok = math.isfinite(h_in + mdot + m_c + T_c_in) and not supercritical
    missing = not math.isfinite(T_sat + h_l + h_v)
    missing = missing or (not inlet_subcooled and not not_below_inlet and not math.isfinite(T_in + rho_in))
    missing = missing or (math.isfinite(T_c_ok) and not math.isfinite(h_at_c))
    missing = missing or (math.isfinite(h_out) and not math.isfinite(rho_out))
    missing = missing or (p_ok >= curve_p_min and math.isfinite(h_out) and not math.isfinite(x_out + T_out))
    values = (
        Q,
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
        1.0 if outside else 0.0,
        1.0 if inlet_subcooled else 0.0,
        1.0 if supercritical else 0.0,
        1.0 if not_below_inlet else 0.0,
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
def solve_points(
    p_in, h_in, mdot, m_c, T_c_in, geo, cool, mirrored, T_freeze, T_max_c, p_triple, p_crit, curve_p_min, g_range,
    tables, gauss,
):  # fmt: skip
    """:func:`solve_point_wcc` over arrays of points: an ``(n, len(COLUMNS))`` array."""
    out = np.empty((p_in.size, len(COLUMNS)))
    work = (np.empty(len(SAT_COLUMNS)), np.empty(5))
    for i in range(p_in.size):
        wcc_in(
            p_in[i], h_in[i], mdot[i], m_c[i], T_c_in[i], geo, cool, mirrored, T_freeze, T_max_c, p_triple, p_crit,
            curve_p_min, g_range, tables, gauss, out[i], work,
        )  # fmt: skip
    return out
