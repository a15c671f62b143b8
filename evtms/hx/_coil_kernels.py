"""The cross-flow coil march per point in machine code (numba), on tabulated refrigerant properties.

:func:`march_points` does for each point what :func:`evtms.hx.crossflow.march_crossflow`
does for arrays of them with the dry air side (:class:`evtms.hx.sides.AirSide`,
the condenser) or the moist one (:class:`evtms.hx.sides.MoistAirSide`, the
evaporator: partly wet two-phase zone, larger-rate rule for the single-phase
zones, condensate), then the outlet state of
:func:`evtms.benches.coil.solve_coil` (outlet pressure, quality, temperature).
The refrigerant properties come from :mod:`evtms.fluid_tables`; the
correlations are the scalar forms of :mod:`evtms.hx.tube` (same equations,
same references) and the zone heat rates those of :mod:`evtms.hx._kernels`.
Fed with the same tables (:class:`evtms.fluid_tables.TabulatedFluid`), the
NumPy march gives the same numbers to round-off (``tests/test_coil_kernels.py``).

A point is computed alone, so its value does not depend on the batch it
comes in. Where a table lookup falls outside the tables (or an input is not
finite, or a flow is not positive) the point is marked in the last output
column for the caller to solve with CoolProp instead.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.fluid_tables import ph_temperature, pt_state, saturation
from evtms.hx._kernels import air_rate, divide, interp, nan_max, nan_min, zone_rate
from evtms.hx.crossflow import _BISECTION_STEPS, _F_SEARCH_MAX, _F_SLOPE, CAPACITY_RATIO_MAX
from evtms.hx.tube import GAUSS_NODES, GAUSS_WEIGHTS, RE_LAMINAR, RE_TURBULENT

#: Output columns of :func:`march_points`, in order.
COLUMNS = (
    "Q",
    "dp",
    "h_out",
    "h_out_continued",
    "capacity_ratio",
    "T_surface_min",
    "bad_direction",
    "bad_props",
    "m_cond",
    "cond_enthalpy",
    "latent",
    "T_surface_eff",
    "p_out",
    "x_out",
    "T_out",
    "fallback",
)
#: Tube-side parameters, in the order of :func:`march_points`' ``tube`` array.
TUBE = ("D_h", "flow_area", "length", "area", "roughness", "nu_laminar", "R_wall", "p_triple")
#: Per-point inputs, in the order of the columns of :func:`march_points`' ``points`` array.
POINTS = ("p_in", "h_in", "mdot", "T_air", "C_air", "R_air", "air_h", "air_w", "m_da", "air_cp")

_G = 9.80665
_GN = np.ascontiguousarray(GAUSS_NODES)
_GW = np.ascontiguousarray(GAUSS_WEIGHTS)
# Saturation columns of evtms.fluid_tables.SAT_COLUMNS.
_T, _HL, _HV, _RHOL, _RHOV, _CPL, _CPV, _MUL, _MUV, _KL, _KV = range(11)


# --- the correlations of evtms.hx.tube, one point ----------------------------------------------


@jit(counted=False)
def _clip(x: float, lo: float, hi: float) -> float:
    return nan_min(nan_max(x, lo), hi)


@jit(counted=False)
def _turbulent_weight(Re: float) -> float:
    return _clip((Re - RE_LAMINAR) / (RE_TURBULENT - RE_LAMINAR), 0.0, 1.0)


@jit(counted=False)
def haaland_friction_factor(Re: float, rr: float) -> float:
    """:func:`evtms.hx.tube.haaland_friction_factor` (Haaland 1983, laminar 64/Re, linear blend)."""
    Re = nan_max(Re, 1e-12)
    laminar = 64.0 / Re
    Re_t = nan_max(Re, RE_TURBULENT)
    turbulent = (-1.8 * math.log10((rr / 3.7) ** 1.11 + 6.9 / Re_t)) ** -2
    w = _turbulent_weight(Re)
    return (1.0 - w) * laminar + w * turbulent


@jit(counted=False)
def single_phase_htc(G, D, rr, nu_lam, mu, cp, k) -> float:
    """:meth:`evtms.hx.crossflow.TubeSide.single_phase_htc` (Gnielinski 1976, laminar floor)."""
    Re = G * D / mu
    Pr = cp * mu / k
    f8 = haaland_friction_factor(Re, rr) / 8.0
    Re_t = nan_max(Re, RE_TURBULENT)
    turbulent = f8 * (Re_t - 1000.0) * Pr / (1.0 + 12.7 * math.sqrt(f8) * (Pr ** (2.0 / 3.0) - 1.0))
    turbulent = nan_max(turbulent, nu_lam)
    w = _turbulent_weight(Re)
    return ((1.0 - w) * nu_lam + w * turbulent) * k / D


@jit(counted=False)
def _gauss_sum(v: np.ndarray) -> float:
    # NumPy's pairwise order for eight terms (np.sum), so the mean rounds as gauss_mean's does.
    return ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]))


@jit(counted=False)
def condensation_shear(G, D, nu_lam, sat, v) -> float:
    """The shear-driven part of :meth:`evtms.hx.crossflow.TubeSide.condensation_htc` [W/(m2 K)]:
    Cavallini and Zecchin (1974) averaged over quality (it does not depend on the heat flux);
    ``v`` holds the eight Gauss terms (work, written)."""
    mu_l, mu_v, rho_l, rho_v, k_l = sat[_MUL], sat[_MUV], sat[_RHOL], sat[_RHOV], sat[_KL]
    Pr_l = sat[_CPL] * mu_l / k_l
    for n in range(8):
        x = _GN[n]
        Re_eq = (G * x * D / mu_v) * (mu_v / mu_l) * math.sqrt(rho_l / rho_v) + G * (1.0 - x) * D / mu_l
        v[n] = nan_max(0.05 * Re_eq**0.8 * Pr_l**0.33, nu_lam) * _GW[n]
    return _gauss_sum(v) * k_l / D


@jit(counted=False)
def condensation_htc(shear, D, sat, q) -> float:
    """:meth:`evtms.hx.crossflow.TubeSide.condensation_htc`: the larger of the shear-driven
    coefficient (:func:`condensation_shear`) and Chato's (1962) film coefficient at heat flux ``q``."""
    rho_l, rho_v, k_l, mu_l, cp_l = sat[_RHOL], sat[_RHOV], sat[_KL], sat[_MUL], sat[_CPL]
    q = nan_max(q, 1e-6)
    base = _G * rho_l * (rho_l - rho_v) * k_l**3 / (mu_l * D)
    h_fg = sat[_HV] - sat[_HL]
    h = (0.555**4 * base * h_fg / q) ** (1.0 / 3.0)
    film = (0.555**4 * base * (h_fg + 0.375 * cp_l * (q / h)) / q) ** (1.0 / 3.0)
    return nan_max(shear, film)


@jit(counted=False)
def boiling_terms(G, D, nu_lam, sat, h_l, quality_term) -> None:
    """The heat-flux-free parts of Gungor and Winterton's (1987) coefficient at the quality nodes:
    the liquid-only coefficient ``h_l`` and ``1.12 (x/(1-x))^0.75 (rho_l/rho_v)^0.41``."""
    mu_l, rho_l, rho_v, k_l = sat[_MUL], sat[_RHOL], sat[_RHOV], sat[_KL]
    Pr_l = sat[_CPL] * mu_l / k_l
    for n in range(8):
        x = _clip(_GN[n], 0.0, 0.999)
        Re_l = G * (1.0 - x) * D / mu_l
        h_l[n] = nan_max(0.023 * Re_l**0.8 * Pr_l**0.4, nu_lam) * k_l / D
        quality_term[n] = 1.12 * (x / (1.0 - x)) ** 0.75 * (rho_l / rho_v) ** 0.41


@jit(counted=False)
def boiling_htc(G, sat, q, h_l, quality_term, v) -> float:
    """:meth:`evtms.hx.crossflow.TubeSide.boiling_htc` (Gungor and Winterton 1987) at heat flux
    ``q``, averaged over quality, from :func:`boiling_terms` (``v``: the Gauss terms, work)."""
    Bo = nan_max(q, 0.0) / (G * (sat[_HV] - sat[_HL]))
    nucleate = 3000.0 * Bo**0.86
    for n in range(8):
        v[n] = (1.0 + nucleate + quality_term[n]) * h_l[n] * _GW[n]
    return _gauss_sum(v)


@jit(counted=False)
def single_phase_gradient(G, D, rr, mu, rho) -> float:
    """:func:`evtms.hx.tube.single_phase_gradient` (Darcy-Weisbach)."""
    return haaland_friction_factor(G * D / mu, rr) * G**2 / (2.0 * rho * D)


@jit(counted=False)
def two_phase_gradient(G, D, rr, sat, x0, x1, v) -> float:
    """:meth:`evtms.hx.crossflow.TubeSide.two_phase_gradient` (Mueller-Steinhagen and Heck 1986);
    ``v``: the Gauss terms (work)."""
    A = single_phase_gradient(G, D, rr, sat[_MUL], sat[_RHOL])
    B = single_phase_gradient(G, D, rr, sat[_MUV], sat[_RHOV])
    for n in range(8):
        x = _clip(x0 + (x1 - x0) * _GN[n], 0.0, 1.0)
        lam = A + 2.0 * (B - A) * x
        v[n] = (lam * (1.0 - x) ** (1.0 / 3.0) + B * x**3) * _GW[n]
    return _gauss_sum(v)


# --- the zone models of evtms.hx.sides, one point ----------------------------------------------


@jit(counted=False)
def _dew_point(w, sat_T, sat_w) -> float:
    """:meth:`evtms.fluid.SaturatedAir.dew_point`: -inf below the table, NaN above."""
    if w < sat_w[0]:
        return -math.inf
    return interp(w, sat_w, sat_T)


@jit(counted=False)
def moist_zone(pt, C_ref, R_ref, Tr0, dry, wet, moist, sat_T, sat_h, sat_w) -> None:
    """:meth:`evtms.hx.sides.MoistAirSide.zone_model` for one point (Braun et al. 1989; the partly
    wet coil of Elmahdy and Mitalas 1977 and Braun 1988): fills ``wet`` and ``moist`` as
    :func:`evtms.hx._kernels.zone_rate` reads them; ``dry`` holds the dry model."""
    Ta, R, C_a = pt[3], pt[5], pt[4]
    h_a, w_a, m_da, cp_a = pt[6], pt[7], pt[8], pt[9]
    R_tot, dT = dry[1], dry[3]
    ntu_air = divide(1.0, R * C_a)
    h_s_r = interp(Tr0, sat_T, sat_h)
    partly = math.isinf(C_ref)
    T_dew = _dew_point(w_a, sat_T, sat_w)
    T_top = nan_max(T_dew, Tr0 + 0.05) if partly else Ta
    c_s = (interp(T_top, sat_T, sat_h) - h_s_r) / nan_max(T_top - Tr0, 1e-9)
    at_dew = divide((T_dew - Tr0) * R_tot, R_ref)
    if at_dew <= 0.0:
        depth = 1.0
    elif at_dew >= dT:
        depth = 0.0
    elif at_dew == at_dew and dT == dT:
        depth = nan_min(math.log(dT / at_dew) * R_tot * C_a, 1.0)
    else:
        depth = math.nan
    if not partly:
        depth = math.nan
    dry_part = 1.0 - math.exp(-divide(depth, R_tot * C_a)) if partly else 0.0
    wet_h = h_a - divide(C_a, m_da) * dT * dry_part
    wet[0] = C_ref / c_s
    wet[1] = cp_a * R + c_s * R_ref
    wet[2] = m_da
    wet[3] = nan_max(wet_h - h_s_r, 0.0)
    wet[4] = depth
    wets = (not partly) or depth < 1.0 - 1e-9
    after_dry = partly and wets
    moist[0] = h_a
    moist[1] = w_a
    moist[2] = m_da
    moist[3] = math.exp(-ntu_air * ((1.0 - depth) if after_dry else 1.0))
    moist[4] = wet_h if after_dry else h_a
    moist[5] = 1.0 if wets else 0.0


@jit(counted=False)
def _condensate(f, q_air, moist, sat_T, sat_h, sat_w) -> tuple[float, float, float]:
    """:meth:`evtms.hx.sides.Moisture.condensate`: condensate [kg/s], effective surface
    temperature [K] and the condensate's enthalpy flow [W] (Braun et al. 1989, eqs. 25-28)."""
    air_h, air_w, m_air, decay, wet_h, wets = moist[0], moist[1], moist[2], moist[3], moist[4], moist[5]
    h_a_out = air_h - divide(q_air, f * m_air if f > 0 else 1.0)
    h_s_eff = wet_h - divide(wet_h - h_a_out, 1.0 - decay)
    T_s_eff = interp(h_s_eff, sat_h, sat_T)
    w_s_eff = interp(T_s_eff, sat_T, sat_w)
    w_out = w_s_eff + (air_w - w_s_eff) * decay
    m_w = f * m_air * nan_max(air_w - w_out, 0.0) if (f > 0 and wets > 0) else 0.0
    H_w = m_w * (4186.0 * (T_s_eff - 273.16)) if m_w > 0 else 0.0
    return m_w, T_s_eff, H_w


@jit(counted=False)
def _bisect(target, hi, rate_hi, dry, wet, moist, sat_T, sat_h, sat_w) -> float:
    """:func:`evtms.hx.crossflow.bisect` on the zone's rate for one point, from its root.

    The bisection's result is the midpoint of the 2^-40 cell of ``[0, hi]`` its comparisons
    ``rate(mid) < target`` lead to. The root is bracketed first by the Illinois method
    (regula falsi with halving of a stale end; Dowell and Jarratt 1971) to below a sixteenth of
    that cell, from ``rate(0) = 0`` and ``rate(hi) = rate_hi`` [W]; the bisection then
    replays its steps, a comparison being known without evaluating the rate wherever the
    midpoint lies outside the bracket (the rate rises with the fraction). The same result
    as the 40 evaluations, from about five.

    A secant that lands on an end of the bracket (the residual there zero or too small to
    move it: a step that hit the root, as the first step does where the rate is linear in the
    fraction, a dry two-phase zone) is moved half the final width inside it, which closes
    the bracket at once where that end is the root. The midpoint there, as Illinois has it,
    bisected the whole bracket down to its final width: some 40 evaluations, 23 on average
    over the evaporator's cycle grid.
    """
    a, fa = 0.0, -target  # rate(a) - target < 0
    b, fb = hi, rate_hi - target  # rate(b) - target >= 0 (else the bisection ends at hi)
    if not (fb >= 0.0 and fa < 0.0):
        return _bisect_plain(target, hi, dry, wet, moist, sat_T, sat_h, sat_w)
    width = hi * 2.0**-_BISECTION_STEPS / 16.0
    side = 0
    for _ in range(60):
        if b - a <= width:
            break
        c = b - fb * (b - a) / (fb - fa)
        if c >= b:
            c = b - 0.5 * width
        elif c <= a:
            c = a + 0.5 * width
        if not (a < c < b):
            c = 0.5 * (a + b)
        fc = zone_rate(c, dry, wet, moist, sat_T, sat_h, sat_w) - target
        if fc < 0.0:
            a, fa = c, fc
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb = c, fc
            if side == 1:
                fa *= 0.5
            side = 1
    lo, up = 0.0, hi
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + up)
        if mid <= a:
            below = True
        elif mid >= b:
            below = False
        else:
            below = zone_rate(mid, dry, wet, moist, sat_T, sat_h, sat_w) < target
        if below:
            lo = mid
        else:
            up = mid
    return 0.5 * (lo + up)


@jit(counted=False)
def _bisect_plain(target, hi, dry, wet, moist, sat_T, sat_h, sat_w) -> float:
    """:func:`evtms.hx.crossflow.bisect` on the zone's rate, one point, step by step."""
    lo, up = 0.0, hi
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + up)
        if zone_rate(mid, dry, wet, moist, sat_T, sat_h, sat_w) < target:
            lo = mid
        else:
            up = mid
    return 0.5 * (lo + up)


@jit(counted=False)
def _fraction_needed(Q_needed, two_phase, dry, wet, moist, sat_T, sat_h, sat_w) -> float:
    """:meth:`evtms.hx.crossflow.ZoneHeatRate.fraction_needed`, one point."""
    if not math.isfinite(Q_needed):
        return math.inf
    if two_phase:
        per_unit = zone_rate(1.0, dry, wet, moist, sat_T, sat_h, sat_w)
        return Q_needed / per_unit if per_unit > 0 else math.inf
    rate_max = zone_rate(_F_SEARCH_MAX, dry, wet, moist, sat_T, sat_h, sat_w)
    if not (rate_max >= Q_needed):
        return math.inf
    return _bisect(Q_needed, _F_SEARCH_MAX, rate_max, dry, wet, moist, sat_T, sat_h, sat_w)


# --- the march ----------------------------------------------------------------------------------


@jit
def march_work():
    """The work arrays of :func:`march_in`: the saturation state, the refrigerant's state at the
    air's inlet temperature, the boiling terms at the quality nodes, the zone models' states and
    the Gauss terms."""
    return (np.empty(11), np.empty(5), np.empty(8), np.empty(8), np.empty(4), np.empty(5), np.empty(6), np.empty(8))


@jit
def march_point(pt, tube, condenser, moist_air, meta, sat, vap, liq, sat_T, sat_h, sat_w, out) -> None:
    """One point of :func:`march_points` into the row ``out`` (:data:`COLUMNS`)."""
    march_in(pt, tube, condenser, moist_air, meta, sat, vap, liq, sat_T, sat_h, sat_w, out, march_work())


# The march allocates nothing (its work arrays come from march_work), so it runs without reference
# counting (evtms._jit.uncounted): the counts were about 40 % of a point's time.
@jit(counted=False)
def march_in(pt, tube, condenser, moist_air, meta, sat, vap, liq, sat_T, sat_h, sat_w, out, work) -> None:
    """:func:`march_point` with its work arrays (:func:`march_work`)."""
    s, props, h_liq, quality_term, dry, wet, moist, v8 = work
    p_in, h_in, mdot, T_air, C_air, R_air = pt[0], pt[1], pt[2], pt[3], pt[4], pt[5]
    D_h, flow_area, length, area, rr, nu_lam, R_wall = tube[0], tube[1], tube[2], tube[3], tube[4], tube[5], tube[6]
    for c in range(out.size):
        out[c] = 0.0
    sign = -1.0 if condenser else 1.0
    saturation(meta, sat, p_in, s)
    T_sat, h_l, h_v = s[_T], s[_HL], s[_HV]
    T_in = ph_temperature(meta, sat, vap, liq, p_in, h_in)
    pt_state(meta, sat, vap, liq, p_in, T_air, props)
    h_air_T = props[0]
    G = mdot / flow_area
    if not (math.isfinite(T_in + T_sat + h_air_T) and mdot > 0 and C_air > 0 and math.isfinite(R_air)):
        out[15] = 1.0  # outside the tables, or degenerate: CoolProp's path decides
        return
    if condenser:
        start = 2 if h_in > h_v else (1 if h_in > h_l else 0)
        start_pos = 2 - start
    else:
        start = 0 if h_in < h_l else (1 if h_in < h_v else 2)
        start_pos = start
    bad_direction = not (sign * (T_air - T_in) > 0)

    q = 1000.0
    h_tp = math.nan
    shear = condensation_shear(G, D_h, nu_lam, s, v8) if condenser else 0.0
    if not condenser:
        boiling_terms(G, D_h, nu_lam, s, h_liq, quality_term)
    for _ in range(5):
        h_tp = condensation_htc(shear, D_h, s, q) if condenser else boiling_htc(G, s, q, h_liq, quality_term, v8)
        UA = 1.0 / (R_air + R_wall + 1.0 / (h_tp * area))
        q = nan_max(C_air * -math.expm1(-UA / C_air) * abs(T_air - T_sat) / area, 1.0)

    f_rem = 1.0
    done = bad_direction
    Q = 0.0
    dp = 0.0
    T_surface_min = math.inf
    T_surface_eff = math.inf
    m_cond = 0.0
    cond_enthalpy = 0.0
    latent = 0.0
    f_needed = 0.0
    last_zone_slope = math.nan
    wet[:] = math.nan
    moist[:] = math.nan
    for pos in range(3):
        zone = 2 - pos if condenser else pos
        is_last = pos == 2
        live = start_pos <= pos and not done and f_rem > 0
        ok = start_pos <= pos and not bad_direction
        if not (live or (ok and not is_last) or (ok and is_last and done and math.isfinite(f_needed))):
            continue
        at_start = start == zone
        Tr0 = T_in if at_start else T_sat
        if at_start:
            hr0 = h_in
        elif zone == 1:
            hr0 = h_v if condenser else h_l
        elif zone == 0 and condenser:
            hr0 = h_l
        elif zone == 2 and not condenser:
            hr0 = h_v
        else:
            hr0 = h_in
        two_phase = zone == 1
        reachable = False if is_last else sign * (T_air - T_sat) > 0
        boundary_h = h_l if (zone == 0 or (two_phase and condenser)) else h_v
        T_end = T_sat if reachable else T_air
        h_end = boundary_h if reachable else h_air_T
        Q_needed = mdot * abs(boundary_h - hr0) if reachable else math.inf
        mu = rho = 0.0
        if two_phase:
            h_ref = h_tp
            C_ref = math.inf
        else:
            pt_state(meta, sat, vap, liq, p_in, 0.5 * (Tr0 + T_end), props)
            vapour = zone == 2
            rho = props[1] if math.isfinite(props[1]) else s[_RHOV if vapour else _RHOL]
            cp = props[2] if math.isfinite(props[2]) else s[_CPV if vapour else _CPL]
            mu = props[3] if math.isfinite(props[3]) else s[_MUV if vapour else _MUL]
            k = props[4] if math.isfinite(props[4]) else s[_KV if vapour else _KL]
            h_ref = single_phase_htc(G, D_h, rr, nu_lam, mu, cp, k)
            span = T_end - Tr0
            cp_eff = (h_end - hr0) / span if abs(span) > 1e-9 else cp
            C_ref = mdot * cp_eff
        R_ref = R_wall + 1.0 / (h_ref * area)
        dry[0] = C_ref
        dry[1] = R_air + R_ref
        dry[2] = C_air
        dry[3] = abs(T_air - Tr0)
        if moist_air:
            moist_zone(pt, C_ref, R_ref, Tr0, dry, wet, moist, sat_T, sat_h, sat_w)
        if not is_last:
            f_needed += _fraction_needed(Q_needed, two_phase, dry, wet, moist, sat_T, sat_h, sat_w)
        elif not live:
            last_zone_slope = zone_rate(_F_SLOPE, dry, wet, moist, sat_T, sat_h, sat_w) / _F_SLOPE
        if not live:
            continue

        fr = f_rem
        Q_full = zone_rate(fr, dry, wet, moist, sat_T, sat_h, sat_w)
        take_all = Q_full <= Q_needed
        f_z = fr if take_all else _bisect(Q_needed, fr, Q_full, dry, wet, moist, sat_T, sat_h, sat_w)
        Q_z = Q_full if take_all else Q_needed

        T_wall = Tr0 + (T_air - Tr0) * R_ref / dry[1]
        if f_z > 0:
            T_surface_min = nan_min(T_surface_min, T_wall)
        if moist_air:
            m_w, T_s_eff, H_w = _condensate(f_z, air_rate(f_z, dry, wet), moist, sat_T, sat_h, sat_w)
            m_cond += m_w
            cond_enthalpy += H_w
            if m_w > 0:
                latent += m_w * (2.501e6 - 2369.0 * (T_s_eff - 273.15))
            T_surface_eff = nan_min(T_surface_eff, T_s_eff if f_z > 0 else math.inf)

        L = f_z * length
        if two_phase:
            h_z_end = hr0 + sign * Q_z / mdot
            x0 = (hr0 - h_l) / (h_v - h_l)
            x1 = (h_z_end - h_l) / (h_v - h_l)
            grad = two_phase_gradient(G, D_h, rr, s, x0, x1, v8)
        else:
            grad = single_phase_gradient(G, D_h, rr, mu, rho)
        dp += grad * L
        Q += Q_z
        f_rem = 0.0 if take_all else fr - f_z
        done = done or take_all

    h_out = h_in + sign * Q / mdot
    h_continued = h_out
    if math.isfinite(last_zone_slope) and math.isfinite(f_needed):
        h_continued = (h_l if condenser else h_v) + sign * (1.0 - f_needed) * last_zone_slope / mdot
    if f_needed > 1.0 / CAPACITY_RATIO_MAX:
        capacity_ratio = 1.0 / nan_max(f_needed, 1e-300)
    else:
        capacity_ratio = CAPACITY_RATIO_MAX

    # Outlet state at the outlet pressure (evtms.benches.coil.solve_coil).
    p_out = p_in - dp
    x_out = T_out = math.nan
    if p_out > tube[7]:
        saturation(meta, sat, p_out, s)
        x_out = (h_out - s[_HL]) / (s[_HV] - s[_HL])
        T_out = s[_T] if 0.0 <= x_out <= 1.0 else ph_temperature(meta, sat, vap, liq, p_out, h_out)
        if not math.isfinite(T_out + x_out):
            out[15] = 1.0
    out[0] = Q
    out[1] = dp
    out[2] = h_out
    out[3] = h_continued
    out[4] = capacity_ratio
    out[5] = T_surface_min
    out[6] = 1.0 if bad_direction else 0.0
    out[7] = 0.0
    out[8] = m_cond
    out[9] = cond_enthalpy
    out[10] = latent
    out[11] = T_surface_eff
    out[12] = p_out
    out[13] = x_out
    out[14] = T_out


@jit
def march_points(points, tube, condenser, moist_air, meta, sat, vap, liq, sat_T, sat_h, sat_w) -> np.ndarray:
    """The coil march and outlet state per point: one row of :data:`COLUMNS` per row of ``points``
    (:data:`POINTS`); ``tube`` holds :data:`TUBE`; ``meta, sat, vap, liq`` the refrigerant
    tables (:attr:`evtms.fluid_tables.PropertyTables.arrays`); ``sat_T, sat_h, sat_w`` the
    saturated-air curve (moist air only)."""
    n = points.shape[0]
    out = np.empty((n, len(COLUMNS)))
    row = np.empty(len(COLUMNS))
    work = march_work()
    for i in range(n):
        march_in(points[i], tube, condenser, moist_air, meta, sat, vap, liq, sat_T, sat_h, sat_w, row, work)
        out[i, :] = row
    return out
