"""Compiled per-point twins of the exchanger cores' inner searches (numba, :func:`evtms._jit.jit`).

The cores search a heat rate (counter flow) or a zone's coil fraction (cross
flow) by 40 bisection steps over arrays of points. On the few points a cycle
solver passes per call, NumPy's per-call overhead dominates those steps; these
kernels run the same arithmetic per point in machine code. Each function here
is the scalar twin of an array function named in its docstring, and the tests
(``tests/test_hx.py``) hold the two to round-off. Divisions go through
:func:`divide`, which gives NumPy's inf and NaN where plain Python (and numba's
default error model) would raise.

Importing this module imports numba (about 0.2 s): the cores import it where
they first search per point, not at start-up, so a bench command or a dask
worker that never does pays nothing.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit

#: Enthalpy of liquid water per kelvin above the triple point [J/(kg K)]
#: (:func:`evtms.fluid.water_liquid_enthalpy`).
_WATER_CP = 4186.0
_WATER_T0 = 273.16


@jit(counted=False)
def divide(a: float, b: float) -> float:
    """``a / b`` as NumPy divides floats: inf or NaN for ``b == 0``."""
    if b != 0.0:
        return a / b
    if a != a or a == 0.0:
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


@jit(counted=False)
def nan_max(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@jit(counted=False)
def nan_min(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


@jit(counted=False)
def interp(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """``np.interp(x, xp, fp, left=nan, right=nan)`` for one ``x``, with NumPy's arithmetic."""
    n = xp.size
    if not (xp[0] <= x <= xp[n - 1]):  # also NaN
        return math.nan
    if x == xp[n - 1]:
        return fp[n - 1]
    lo, hi = 0, n - 1  # xp[lo] <= x < xp[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    if x == xp[lo]:
        return fp[lo]
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    y = slope * (x - xp[lo]) + fp[lo]
    if y != y:
        y = slope * (x - xp[lo + 1]) + fp[lo + 1]
        if y != y and fp[lo] == fp[lo + 1]:
            y = fp[lo]
    return y


@jit(counted=False)
def log_mean(a: float, b: float) -> float:
    """One point of :func:`evtms.hx.counterflow._log_mean` (positive ``a`` and ``b``)."""
    r = b / a
    e = r - 1.0
    if abs(e) < 1e-6:
        return a * (1.0 + e / 2.0 - e * e / 12.0)
    return divide(b - a, math.log(r))


def columns(n: int, *arrays: np.ndarray) -> np.ndarray:
    """The per-point arrays (or scalars) side by side: a C-ordered float array of ``n`` rows."""
    return np.column_stack([np.broadcast_to(np.asarray(a, float), (n,)) for a in arrays])


@jit(counted=False)
def crossflow_effectiveness(ntu: float, cr: float) -> float:
    """One point of :func:`evtms.hx.effectiveness.crossflow_effectiveness`."""
    ntu = nan_max(ntu, 0.0)
    cr = nan_min(nan_max(cr, 0.0), 1.0)
    if cr < 1e-9:
        return -math.expm1(-ntu)
    return 1.0 - math.exp(ntu**0.22 / cr * math.expm1(-cr * ntu**0.78))


@jit(counted=False)
def dry_rate(f: float, C_ref: float, R_tot: float, C_air: float, dT: float) -> float:
    """One point of :meth:`evtms.hx.crossflow.ZoneHeatRate.dry`: a zone's heat rate [W] at coil fraction ``f``."""
    C_af = f * C_air
    C_min = nan_min(C_af, C_ref)
    C_max = nan_max(C_af, C_ref)
    ntu = f / R_tot / C_min if C_min > 0 else 0.0
    cr = C_min / C_max if (math.isfinite(C_max) and C_max > 0) else 0.0
    return crossflow_effectiveness(ntu, cr) * C_min * dT


@jit(counted=False)
def condensate_enthalpy(f, q_air, air_h, air_w, m_air, decay, wet_h, wets, sat_T, sat_h, sat_w):
    """One point of :meth:`evtms.hx.sides.Moisture.condensate`'s third result: the enthalpy
    flow [W] of the condensate a zone of fraction ``f`` drains, its air losing ``q_air`` [W]."""
    h_a_out = air_h - divide(q_air, f * m_air if f > 0 else 1.0)
    h_s_eff = wet_h - divide(wet_h - h_a_out, 1.0 - decay)
    T_s_eff = interp(h_s_eff, sat_h, sat_T)
    w_s_eff = interp(T_s_eff, sat_T, sat_w)
    w_out = w_s_eff + (air_w - w_s_eff) * decay
    m_w = f * m_air * nan_max(air_w - w_out, 0.0) if (f > 0 and wets > 0) else 0.0
    return m_w * (_WATER_CP * (T_s_eff - _WATER_T0)) if m_w > 0 else 0.0


@jit(counted=False)
def air_rate(f, dry, wet) -> float:
    """One point of :meth:`evtms.hx.crossflow.ZoneHeatRate.air_rate` (``dry``, ``wet``: as :func:`zone_rate`'s)."""
    q = dry_rate(f, dry[0], dry[1], dry[2], dry[3])
    if wet[0] == wet[0]:
        x = wet[4]
        if x == x:
            q = dry_rate(f, dry[0], divide(dry[1], x), dry[2], dry[3])
            q = q + dry_rate(f, wet[0], divide(wet[1], 1.0 - x), wet[2], wet[3])
        else:
            q = nan_max(q, dry_rate(f, wet[0], wet[1], wet[2], wet[3]))
    return q


@jit(counted=False)
def zone_rate(f, dry, wet, moist, sat_T, sat_h, sat_w):
    """One point of :meth:`evtms.hx.crossflow.ZoneHeatRate.rate`.

    ``dry`` is ``(C_ref, R_tot, C_air, dT)`` of the zone's dry model, ``wet``
    the same of its enthalpy-potential model and the zone's dry depth
    (``wet[0]`` NaN: no wet model; ``wet[4]`` NaN: the larger rate counts);
    ``moist`` is ``(air_h, air_w, m_air, decay, wet_h, wets)`` (``moist[0]``
    NaN: no moisture).
    """
    q = air_rate(f, dry, wet)
    if moist[0] == moist[0]:
        H_w = condensate_enthalpy(f, q, moist[0], moist[1], moist[2], moist[3], moist[4], moist[5], sat_T, sat_h, sat_w)
        q = q - (H_w if math.isfinite(H_w) else 0.0)
    return q


@jit
def bisect_zone_fraction(target, hi, dry, wet, moist, sat_T, sat_h, sat_w, steps):
    """Per point of :func:`evtms.hx.crossflow.bisect` on :meth:`~evtms.hx.crossflow.ZoneHeatRate.rate`:
    the coil fraction in ``[0, hi]`` at which the zone's heat rate is ``target`` [W]
    (``steps`` halvings, the bracket's midpoint). ``dry``, ``wet``, ``moist``: one row per
    point of :func:`zone_rate`'s tuples."""
    out = np.empty(target.size)
    for i in range(target.size):
        lo, up = 0.0, hi[i]
        for _ in range(steps):
            mid = 0.5 * (lo + up)
            if zone_rate(mid, dry[i], wet[i], moist[i], sat_T, sat_h, sat_w) < target[i]:
                lo = mid
            else:
                up = mid
        out[i] = 0.5 * (lo + up)
    return out


@jit(counted=False)
def counterflow_secants(h_in, T_in, T_sat, h_l, h_v, h_at_secondary, T_sec_in):
    """The secant lines of :func:`evtms.hx.counterflow._refrigerant_temperature` for one point:
    ``(slope_l, h0_v, T0_v, slope_v)``, the liquid zone's slope [K kg/J] and the vapour zone's
    start enthalpy [J/kg], start temperature [K] and slope [K kg/J]."""
    reachable = T_sec_in > T_sat
    h_end_l = h_l if reachable else h_at_secondary
    T_end_l = T_sat if reachable else T_sec_in
    slope_l = divide(T_end_l - T_in, h_end_l - h_in) if h_in < h_l else 0.0
    vapour_in = h_in >= h_v
    h0_v = h_in if vapour_in else h_v
    T0_v = T_in if vapour_in else T_sat
    slope_v = divide(T_sec_in - T0_v, h_at_secondary - h0_v)
    return slope_l, h0_v, T0_v, slope_v


@jit(counted=False)
def counterflow_refrigerant_temperature(h, h_in, T_in, T_sat, h_l, h_v, h_at_secondary, T_sec_in):
    """One point of :func:`evtms.hx.counterflow._refrigerant_temperature` at enthalpy ``h``."""
    slope_l, h0_v, T0_v, slope_v = counterflow_secants(h_in, T_in, T_sat, h_l, h_v, h_at_secondary, T_sec_in)
    if h < h_l:
        return T_in + (h - h_in) * slope_l
    if h <= h_v:
        return T_sat
    return T0_v + (h - h0_v) * slope_v


@jit(counted=False)
def counterflow_fraction_total(
    Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_secondary, R, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T
):
    """One point of ``evtms.hx.counterflow._fractions(...).sum(axis=1)``: the area fraction a trial
    heat rate ``Q`` [W] needs [1]."""
    h_out = h_in + Q / mdot
    h_s_out = s_h_in - Q / s_mdot
    ratio = mdot / s_mdot
    bounds = (h_in, min(max(h_l, h_in), h_out), min(max(h_v, h_in), h_out), h_out)
    total = 0.0
    for z in range(3):
        a, b = bounds[z], bounds[z + 1]
        Q_z = mdot * (b - a)
        f_z = 0.0
        if Q_z > 0:
            T_s_a = interp(h_s_out + ratio * (a - h_in), tab_h, tab_T)
            T_s_b = s_T_in if z == 2 else interp(h_s_out + ratio * (b - h_in), tab_h, tab_T)
            dT_a = T_s_a - counterflow_refrigerant_temperature(a, h_in, T_in, T_sat, h_l, h_v, h_at_secondary, s_T_in)
            dT_b = T_s_b - counterflow_refrigerant_temperature(b, h_in, T_in, T_sat, h_l, h_v, h_at_secondary, s_T_in)
            f_z = Q_z * (R[z] + s_R) / log_mean(dT_a, dT_b) if dT_a > 0 and dT_b > 0 else math.inf
        total += f_z
    return total


@jit
def bisect_counterflow_heat_rate(steps, hi, ref, sec, tab_h, tab_T):
    """The largest heat rate [W] in ``[0, hi]`` whose zones fit the exchanger, per point: ``steps``
    halvings of the bracket, as :func:`evtms.hx.counterflow.solve_counterflow_evaporator`'s array
    loop does (``hi = 0`` gives 0). ``ref``: per point ``mdot, h_in, T_in, T_sat, h_l, h_v,
    h_at_secondary, R_liquid, R_two_phase, R_vapour``; ``sec``: ``mdot, T_in, h_in, R``."""
    out = np.zeros(hi.size)
    for i in range(hi.size):
        lo, up = 0.0, hi[i]
        r, s = ref[i], sec[i]
        if up > 0:
            for _ in range(steps):
                mid = 0.5 * (lo + up)
                total = counterflow_fraction_total(
                    mid, r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7:10], s[0], s[1], s[2], s[3], tab_h, tab_T
                )
                if total < 1.0:
                    lo = mid
                else:
                    up = mid
        out[i] = lo
    return out
