"""Compiled per-point twin of the whole counter-flow evaporator solve (:mod:`evtms.hx.counterflow`).

:func:`solve_point` does for one point what
:func:`evtms.hx.counterflow.solve_counterflow_evaporator` does over arrays:
the heat-rate search (Bell et al. 2015, as that module explains), the pinch
fill of the zone fractions, the area needed to evaporate to saturated vapour,
the capacity ratio and the continued outlet enthalpy, with a tabulated
secondary enthalpy-temperature relation (a coolant's table, interpolated as
``np.interp`` does, :func:`table_interp`). The refrigerant is
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

import numpy as np

from evtms._jit import jit
from evtms.hx._kernels import counterflow_secants, divide
from evtms.hx.counterflow import _CONTINUATION_STEP, _PINCH_STEP, BISECTION_STEPS, CAPACITY_RATIO_MAX


def bucket_table(xp: np.ndarray, fp: np.ndarray) -> tuple:
    """``(xp, fp, start, x0, scale)``: a table for :func:`table_interp` (finite, ``xp`` strictly rising).

    ``start[b]`` is the interval (``xp[j] <= x < xp[j + 1]``) of the start of bucket ``b`` of
    ``xp.size`` equal buckets from ``xp[0]`` to ``xp[-1]`` (``b = (x - x0) * scale``)."""
    xp, fp = np.ascontiguousarray(xp, float), np.ascontiguousarray(fp, float)
    if not (np.isfinite(xp).all() and np.isfinite(fp).all() and (np.diff(xp) > 0).all()):
        raise ValueError("a bucket table needs finite values and strictly rising abscissae")
    scale = xp.size / (xp[-1] - xp[0])
    starts = xp[0] + np.arange(xp.size) / scale
    start = np.clip(np.searchsorted(xp, starts, side="right") - 1, 0, xp.size - 2).astype(np.int64)
    return xp, fp, start, float(xp[0]), float(scale)


@jit(counted=False)
def table_interp(x, table):
    """``np.interp(x, xp, fp, left=nan, right=nan)`` for one ``x`` on a :func:`bucket_table`.

    The interval (``xp[j] <= x < xp[j + 1]``) is found from its bucket's start in a step or
    two instead of a bisection over the table; the arithmetic is NumPy's (its ``x == xp[j]``
    case included: ``slope * 0 + fp[j]`` is ``fp[j]`` on a finite table). One return and no
    early exits, so that LLVM inlines it into the zone fractions (with them it did not, and the
    call cost more than the interpolation)."""
    xp, fp, start, x0, scale = table
    n = xp.size
    first, last = xp[0], xp[n - 1]
    inside = first <= x < last
    xc = x if inside else first
    lo = start[min(max(int((xc - x0) * scale), 0), start.size - 1)]
    while xp[lo + 1] <= xc:
        lo += 1
    while xp[lo] > xc:  # the bucket's start rounded past x
        lo -= 1
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    y = slope * (xc - xp[lo]) + fp[lo]
    if not inside:
        y = fp[n - 1] if x == last else math.nan
    return y


@jit(counted=False)
def _refrigerant_temperature(h, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v):
    """:func:`evtms.hx._kernels.counterflow_refrigerant_temperature` with the point's slopes given."""
    if h < h_l:
        T = T_in + (h - h_in) * slope_l
    elif h <= h_v:
        T = T_sat
    else:
        T = T0_v + (h - h0_v) * slope_v
    return T


@jit(counted=False)
def _log_mean(a, b):
    """:func:`evtms.hx._kernels.log_mean` (positive ``a`` and ``b``), with one return."""
    r = b / a
    e = r - 1.0
    if abs(e) < 1e-6:
        lm = a * (1.0 + e / 2.0 - e * e / 12.0)
    else:
        lm = (b - a) / math.log(r)  # |r - 1| >= 1e-6 here: the logarithm is not 0
    return lm


@jit(counted=False)
def _zone(Q_z, R, dT_a, dT_b):
    """A zone's fraction [1] from its heat load, resistance and end differences (inf: infeasible)."""
    f = 0.0
    if Q_z > 0:
        f = Q_z * R / _log_mean(dT_a, dT_b) if (dT_a > 0 and dT_b > 0) else math.inf
    return f


@jit(counted=False)
def prepare(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R):
    """A point's constants for :func:`fractions_of`: the inputs, each zone's resistance with the
    secondary's, the refrigerant's secant slopes (``counterflow._refrigerant_temperature``) and the
    flow ratio, worked out once for every trial heat rate."""
    slope_l, h0_v, T0_v, slope_v = counterflow_secants(h_in, T_in, T_sat, h_l, h_v, h_at_s, s_T_in)
    R0s, R1s, R2s = R0 + s_R, R1 + s_R, R2 + s_R
    return (mdot, h_in, T_in, T_sat, h_l, h_v, R0s, R1s, R2s, s_mdot, s_T_in, s_h_in, slope_l, h0_v, T0_v, slope_v)


@jit(counted=False)
def fractions_of(Q, point, table):
    """The three zone fractions [1] of :func:`evtms.hx.counterflow._fractions` at trial heat rate
    ``Q`` [W] (liquid, two-phase, vapour; inf where infeasible) of a :func:`prepare`-d point, with
    its arithmetic: the secondary temperature at each zone boundary from the balance
    ``h_s = h_s,out + mdot (h - h_in) / mdot_s``, the refrigerant's linear (secant) in each zone."""
    mdot, h_in, T_in, T_sat, h_l, h_v, R0s, R1s, R2s, s_mdot, s_T_in, s_h_in, slope_l, h0_v, T0_v, slope_v = point
    h_out = h_in + Q / mdot
    h_s_out = s_h_in - Q / s_mdot
    ratio = mdot / s_mdot
    b1 = min(max(h_l, h_in), h_out)
    b2 = min(max(h_v, h_in), h_out)
    Q0, Q1, Q2 = mdot * (b1 - h_in), mdot * (b2 - b1), mdot * (h_out - b2)
    f0 = f1 = f2 = 0.0
    if Q1 > 0 or Q2 > 0:
        T_s2 = table_interp(h_s_out + ratio * (b2 - h_in), table)
        dT2 = T_s2 - _refrigerant_temperature(b2, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
        if Q2 > 0:
            T_r3 = _refrigerant_temperature(h_out, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
            f2 = _zone(Q2, R2s, dT2, s_T_in - T_r3)
        if Q1 > 0 or Q0 > 0:
            T_s1 = table_interp(h_s_out + ratio * (b1 - h_in), table)
            dT1 = T_s1 - _refrigerant_temperature(b1, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
            f1 = _zone(Q1, R1s, dT1, dT2)
            if Q0 > 0:
                T_s0 = table_interp(h_s_out + ratio * (h_in - h_in), table)
                dT0 = T_s0 - _refrigerant_temperature(h_in, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
                f0 = _zone(Q0, R0s, dT0, dT1)
    elif Q0 > 0:
        T_s1 = table_interp(h_s_out + ratio * (b1 - h_in), table)
        dT1 = T_s1 - _refrigerant_temperature(b1, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
        T_s0 = table_interp(h_s_out + ratio * (h_in - h_in), table)
        dT0 = T_s0 - _refrigerant_temperature(h_in, h_in, T_in, T_sat, h_l, h_v, slope_l, h0_v, T0_v, slope_v)
        f0 = _zone(Q0, R0s, dT0, dT1)
    return f0, f1, f2


@jit(counted=False)
def fractions(Q, mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, table):
    """:func:`fractions_of` of one point given by its inputs (see the module notes)."""
    point = prepare(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R)
    return fractions_of(Q, point, table)


@jit(counted=False)
def _total(Q, point, table):
    f0, f1, f2 = fractions_of(Q, point, table)
    return f0 + f1 + f2


#: Regula-falsi steps (Illinois) that narrow the bracket before the bisection is replayed.
_BRACKET_STEPS = 16
#: Relative step [1] from a guessed heat rate to the other end of its first bracket (the chiller's
#: second coolant pass changes its heat rate by a few per cent at most).
_WARM_STEP = 0.03


@jit(counted=False)
def heat_rate(hi, point, table, guess):
    """The largest heat rate [W] in ``[0, hi]`` whose zones fit the exchanger: exactly the
    :data:`~evtms.hx.counterflow.BISECTION_STEPS`-step bisection of
    :func:`evtms.hx.counterflow._largest_fitting_heat_rate`, with fewer evaluations.

    The total fraction rises with the heat rate, so once a bracket ``a < b`` is known (fitting
    at ``a``, not at ``b``) every bisection midpoint outside it is decided without evaluating it.
    The bracket is narrowed first by the Illinois variant of regula falsi (Dowell and Jarratt
    1971) in ``s = ln(hi / (hi - Q))``, halving instead where the fraction is infinite (beyond a
    pinch); the bisection is
    then replayed, evaluating only the midpoints inside the bracket: a few of the 40 instead of
    all of them, for the same result. A ``guess`` inside ``(0, hi)`` (the heat rate of a
    nearby solve) starts the bracket at it and :data:`_WARM_STEP` away; 0 starts from
    ``[0, hi]``."""
    a, g_a = 0.0, -1.0  # no heat needs no area
    b, g_b = hi, math.nan
    if 0.0 < guess < hi:  # a bracket about the guess, if it holds the root
        g = _total(guess, point, table) - 1.0
        if g < 0.0:
            a, g_a = guess, g
            c = min(guess * (1.0 + _WARM_STEP), hi)
        else:
            b, g_b = guess, g
            c = guess * (1.0 - _WARM_STEP)
        g_c = _total(c, point, table) - 1.0
        if g_c < 0.0:
            if c > a:
                a, g_a = c, g_c
        elif c <= b:
            b, g_b = c, g_c
    if g_b != g_b:  # the bound itself: taken as not fitting (the replay never decides by it)
        g_b = math.inf
    # Regula falsi in s = ln(hi / (hi - Q)): the fraction grows about linearly in Q far from the
    # bound and in s near it (where the refrigerant pinches at the secondary inlet temperature the
    # area diverges logarithmically), so the secant fits both; towards the bound s doubles.
    s_a = -math.log1p(-a / hi)
    s_b = -math.log1p(-b / hi) if b < hi else math.inf
    tol = hi * 2.0 ** -(BISECTION_STEPS - 2)
    side = 0
    for _ in range(_BRACKET_STEPS):
        if not (b - a > tol) or not g_b >= 0.0:
            break
        if s_b == math.inf:
            r = max(2.0 * s_a, 1.0)
        elif math.isfinite(g_b):
            r = s_a - g_a * (s_b - s_a) / (g_b - g_a)
            if not s_a < r < s_b:
                r = 0.5 * (s_a + s_b)
        else:
            r = 0.5 * (s_a + s_b)
        c = -hi * math.expm1(-r)
        if not a < c < b:
            c = 0.5 * (a + b)
            r = -math.log1p(-c / hi)
        g_c = _total(c, point, table) - 1.0
        if g_c < 0.0:
            a, g_a, s_a = c, g_c, r
            if side == -1 and math.isfinite(g_b):
                g_b *= 0.5
            side = -1
        else:
            b, g_b, s_b = c, g_c, r
            if side == 1:
                g_a *= 0.5
            side = 1
    lo, up = 0.0, hi
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + up)
        if mid <= a:
            fits = True
        elif mid >= b and g_b >= 0.0:
            fits = False
        else:
            fits = _total(mid, point, table) < 1.0
        if fits:
            lo = mid
        else:
            up = mid
    return lo


@jit(counted=False)
def _growth(f: float, g: float) -> float:
    """A zone's growth towards a pinch, as :func:`evtms.hx.counterflow._fill_pinch` counts it."""
    d = f - g
    return max(d, 0.0) if math.isfinite(d) else 0.0


@jit(counted=False)
def _bracket(mdot, h_in, T_in, h_at_s, R0, R1, R2, s_T_in, s_h_in, s_R):
    """``(bad_direction, ok, hi)`` of :func:`evtms.hx.counterflow.solve_counterflow_evaporator`:
    a secondary inlet not warmer, finite inputs, and the heat rate [W] that brings the
    refrigerant to the secondary inlet temperature (0 where not ``ok``)."""
    bad_direction = not (s_T_in - T_in > 0)
    ok = (not bad_direction) and math.isfinite(h_at_s + (R0 + R1 + R2) + s_R + s_h_in)
    hi = mdot * (h_at_s - h_in) if ok else 0.0
    ok = ok and hi > 0
    return bad_direction, ok, hi if ok else 0.0


@jit(counted=False)
def heat_rate_point(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, table):
    """The heat rate [W] of :func:`solve_point` and ``T_secondary_out`` [K] alone (the search, no more)."""
    point = prepare(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R)
    _, ok, hi = _bracket(mdot, h_in, T_in, h_at_s, R0, R1, R2, s_T_in, s_h_in, s_R)
    Q = heat_rate(hi, point, table, 0.0) if ok else 0.0
    return Q, table_interp(s_h_in - Q / s_mdot, table)


@jit(counted=False)
def solve_point(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R, table, guess):
    """One point of :func:`evtms.hx.counterflow.solve_counterflow_evaporator` (``guess``: see
    :func:`heat_rate`).

    Returns
    -------
    tuple
        ``Q`` [W], the fractions ``f0, f1, f2`` [1], ``h_out``, ``h_secondary_out`` [J/kg],
        ``T_secondary_out`` [K], ``f_needed``, ``capacity_ratio`` [1], ``h_out_continued``
        [J/kg] and ``bad_direction`` (a float, 1.0 or 0.0), as the array solve's fields.
    """
    point = prepare(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_s, R0, R1, R2, s_mdot, s_T_in, s_h_in, s_R)
    bad_direction, ok, hi = _bracket(mdot, h_in, T_in, h_at_s, R0, R1, R2, s_T_in, s_h_in, s_R)
    Q = 0.0
    if ok:  # the largest heat rate found to fit (the bound itself may not)
        Q = heat_rate(hi, point, table, guess)
    f0, f1, f2 = fractions_of(Q, point, table)
    missing = 1.0 - (f0 + f1 + f2)
    if Q > 0 and missing > 0 and math.isfinite(missing):  # the area a pinch leaves over
        g0, g1, g2 = fractions_of(Q * (1.0 - _PINCH_STEP), point, table)
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
        n0, n1, n2 = fractions_of(Q_v, point, table)
        f_needed = n0 + n1 + n2
    if ok and h_in >= h_v:
        f_needed = 0.0
    capacity_ratio = 1.0 / max(f_needed, 1e-300) if f_needed > 1.0 / CAPACITY_RATIO_MAX else CAPACITY_RATIO_MAX
    h_continued = h_out
    if reachable and math.isfinite(f_needed) and f_needed > 1.0:
        dQ = mdot * _CONTINUATION_STEP
        p0, p1, p2 = fractions_of(Q_v + dQ, point, table)
        rate = divide(dQ, (p0 + p1 + p2) - f_needed)
        if not (math.isfinite(rate) and rate > 0):
            rate = (s_T_in - T_sat) / (R2 + s_R)
        h_continued = h_v + (1.0 - f_needed) * rate / mdot
    T_s_out = table_interp(h_s_out, table)
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
