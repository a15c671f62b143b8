"""Compiled per-point twin of the whole counter-flow evaporator solve (:mod:`evtms.hx.counterflow`).

:func:`solve_point` does for one point what
:func:`evtms.hx.counterflow.solve_counterflow_evaporator` does over arrays:
the heat-rate search (Bell et al. 2015, as that module explains), the pinch
fill of the zone fractions, the area needed to evaporate to saturated vapour,
the capacity ratio and the continued outlet enthalpy, with a tabulated
secondary enthalpy-temperature relation (a coolant's table, interpolated as
``np.interp`` does, :func:`evtms.hx._kernels.interp`). The refrigerant is
given by scalars in the order of :class:`evtms.hx.counterflow.RefrigerantPath`
(``mdot, h_in, T_in, T_sat, h_l, h_v, h_at_secondary`` and the three zone
resistances), the secondary stream by ``mdot, T_in, h_in, R``. The compiled
chiller (:mod:`evtms.benches._chiller_kernel`) calls it; ``tests/test_hx.py``
holds it to the array solve to round-off.

numba keys its cache on a function's own file: after editing
:mod:`evtms.hx._kernels` alone, touch this file too (or clear
``evtms/hx/__pycache__/*.nb*``).
"""

from __future__ import annotations

import math

from evtms._jit import jit
from evtms.hx._kernels import counterflow_refrigerant_temperature, divide, interp, log_mean
from evtms.hx.counterflow import _CONTINUATION_STEP, _PINCH_STEP, BISECTION_STEPS, CAPACITY_RATIO_MAX


@jit
def zone_fraction(z, Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R_z, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T):
    """Column ``z`` (0 liquid, 1 two-phase, 2 vapour) of :func:`evtms.hx.counterflow._fractions` at
    trial heat rate ``Q`` [W]: the zone's area fraction [1], inf where infeasible."""
    h_out = h_in + Q / mdot
    h_s_out = s_h_in - Q / s_mdot
    ratio = mdot / s_mdot
    if z == 0:
        a, b = h_in, min(max(h_l, h_in), h_out)
    elif z == 1:
        a, b = min(max(h_l, h_in), h_out), min(max(h_v, h_in), h_out)
    else:
        a, b = min(max(h_v, h_in), h_out), h_out
    Q_z = mdot * (b - a)
    if not Q_z > 0:
        return 0.0
    T_s_a = interp(h_s_out + ratio * (a - h_in), tab_h, tab_T)
    T_s_b = s_T_in if z == 2 else interp(h_s_out + ratio * (b - h_in), tab_h, tab_T)
    dT_a = T_s_a - counterflow_refrigerant_temperature(a, h_in, T_in, T_sat, h_l, h_v, h_at_s, s_T_in)
    dT_b = T_s_b - counterflow_refrigerant_temperature(b, h_in, T_in, T_sat, h_l, h_v, h_at_s, s_T_in)
    if dT_a > 0 and dT_b > 0:
        return Q_z * (R_z + s_R) / log_mean(dT_a, dT_b)
    return math.inf


@jit
def fractions(Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T):
    """The three zone fractions [1] of :func:`evtms.hx.counterflow._fractions` at ``Q`` [W]."""
    f0 = zone_fraction(0, Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T)
    f1 = zone_fraction(1, Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R1, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T)
    f2 = zone_fraction(2, Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R2, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T)
    return f0, f1, f2


@jit
def _growth(f: float, g: float) -> float:
    """A zone's growth towards a pinch, as :func:`evtms.hx.counterflow._fill_pinch` counts it."""
    d = f - g
    return max(d, 0.0) if math.isfinite(d) else 0.0


@jit
def solve_point(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T):
    """One point of :func:`evtms.hx.counterflow.solve_counterflow_evaporator`.

    Returns
    -------
    tuple
        ``Q`` [W], the fractions ``f0, f1, f2`` [1], ``h_out``, ``h_secondary_out`` [J/kg],
        ``T_secondary_out`` [K], ``f_needed``, ``capacity_ratio`` [1], ``h_out_continued``
        [J/kg] and ``bad_direction`` (a float, 1.0 or 0.0), as the array solve's fields.
    """
    args = (mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, tab_h, tab_T)
    bad_direction = not (s_T_in - T_in > 0)
    ok = (not bad_direction) and math.isfinite(h_at_s + (R0 + R1 + R2) + s_R + s_h_in)
    hi = mdot * (h_at_s - h_in) if ok else 0.0
    ok = ok and hi > 0
    Q = 0.0
    if ok:  # the largest heat rate found to fit (the bound itself may not)
        lo, up = 0.0, hi
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (lo + up)
            f0, f1, f2 = fractions(mid, *args)
            if f0 + f1 + f2 < 1.0:
                lo = mid
            else:
                up = mid
        Q = lo
    f0, f1, f2 = fractions(Q, *args)
    missing = 1.0 - (f0 + f1 + f2)
    if Q > 0 and missing > 0 and math.isfinite(missing):  # the area a pinch leaves over
        g0, g1, g2 = fractions(Q * (1.0 - _PINCH_STEP), *args)
        d0, d1, d2 = _growth(f0, g0), _growth(f1, g1), _growth(f2, g2)
        total = d0 + d1 + d2
        if total > 0:
            f0, f1, f2 = f0 + missing * (d0 / total), f1 + missing * (d1 / total), f2 + missing * (d2 / total)
    h_out = h_in + Q / mdot
    h_s_out = s_h_in - Q / s_mdot

    reachable = ok and s_T_in > T_sat
    Q_v = mdot * max(h_v - h_in, 0.0)
    f_needed = math.inf
    if reachable:
        n0, n1, n2 = fractions(Q_v, *args)
        f_needed = n0 + n1 + n2
    if ok and h_in >= h_v:
        f_needed = 0.0
    capacity_ratio = 1.0 / max(f_needed, 1e-300) if f_needed > 1.0 / CAPACITY_RATIO_MAX else CAPACITY_RATIO_MAX
    h_continued = h_out
    if reachable and math.isfinite(f_needed) and f_needed > 1.0:
        dQ = mdot * _CONTINUATION_STEP
        p0, p1, p2 = fractions(Q_v + dQ, *args)
        rate = divide(dQ, (p0 + p1 + p2) - f_needed)
        if not (math.isfinite(rate) and rate > 0):
            rate = (s_T_in - T_sat) / (R2 + s_R)
        h_continued = h_v + (1.0 - f_needed) * rate / mdot
    T_s_out = interp(h_s_out, tab_h, tab_T)
    return (
        Q,
        f0,
        f1,
        f2,
        h_out,
        h_s_out,
        T_s_out,
        f_needed,
        capacity_ratio,
        h_continued,
        1.0 if bad_direction else 0.0,
    )
