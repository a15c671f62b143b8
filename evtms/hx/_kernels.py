"""Compiled per-point twins of the exchanger cores' inner searches (numba, :func:`evtms._jit.jit`).

The cores search a heat rate (counter flow) or a zone's coil fraction (cross
flow) by 60 bisection steps over arrays of points. On the few points a cycle
solver passes per call, NumPy's per-call overhead dominates those steps; these
kernels run the same arithmetic per point in machine code. Each function here
is the scalar twin of an array function named in its docstring, and the tests
(``tests/test_hx.py``) hold the two to round-off. Divisions go through
:func:`divide`, which gives NumPy's inf and NaN where plain Python (and numba's
default error model) would raise.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Iterator

import numpy as np

from evtms._jit import jit

#: Whether the cross-flow core searches per point in machine code (:func:`per_point_searches`).
_PER_POINT = contextvars.ContextVar("evtms_hx_per_point", default=False)


@contextlib.contextmanager
def per_point_searches() -> Iterator[None]:
    """Within this block the cross-flow core's zone searches run per point, compiled.

    That is 2-3x faster on the few points of a cycle solver's call (a one-point
    evaporator call 6.3 -> 2.8 ms), and about 15 % slower on a sweep's thousands,
    where NumPy's vectorised exp and pow win. A sweep's values must not depend on
    its batch, so the caller chooses (the cycle's direct models do), not the batch
    size. The counter-flow core's compiled search is faster at every size and
    always on.
    """
    token = _PER_POINT.set(True)
    try:
        yield
    finally:
        _PER_POINT.reset(token)


def per_point() -> bool:
    """Whether :func:`per_point_searches` is in force."""
    return _PER_POINT.get()


#: Enthalpy of liquid water per kelvin above the triple point [J/(kg K)]
#: (:func:`evtms.fluid.water_liquid_enthalpy`).
_WATER_CP = 4186.0
_WATER_T0 = 273.16


@jit
def divide(a: float, b: float) -> float:
    """``a / b`` as NumPy divides floats: inf or NaN for ``b == 0``."""
    if b != 0.0:
        return a / b
    if a != a or a == 0.0:
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


@jit
def nan_max(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@jit
def nan_min(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


@jit
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


@jit
def crossflow_effectiveness(ntu: float, cr: float) -> float:
    """One point of :func:`evtms.hx.effectiveness.crossflow_effectiveness`."""
    ntu = nan_max(ntu, 0.0)
    cr = nan_min(nan_max(cr, 0.0), 1.0)
    if cr < 1e-9:
        return -math.expm1(-ntu)
    return 1.0 - math.exp(ntu**0.22 / cr * math.expm1(-cr * ntu**0.78))


@jit
def dry_rate(f: float, C_ref: float, R_tot: float, C_air: float, dT: float) -> float:
    """One point of :meth:`evtms.hx.crossflow.ZoneHeatRate.dry`: a zone's heat rate [W] at coil fraction ``f``."""
    C_af = f * C_air
    C_min = nan_min(C_af, C_ref)
    C_max = nan_max(C_af, C_ref)
    ntu = f / R_tot / C_min if C_min > 0 else 0.0
    cr = C_min / C_max if (math.isfinite(C_max) and C_max > 0) else 0.0
    return crossflow_effectiveness(ntu, cr) * C_min * dT


@jit
def condensate_enthalpy(f, q_air, air_h, air_w, m_air, decay, sat_T, sat_h, sat_w):
    """One point of :meth:`evtms.hx.sides.Moisture.condensate`'s third result: the enthalpy
    flow [W] of the condensate a zone of fraction ``f`` drains, its air losing ``q_air`` [W]."""
    h_a_out = air_h - divide(q_air, f * m_air if f > 0 else 1.0)
    h_s_eff = air_h - divide(air_h - h_a_out, 1.0 - decay)
    T_s_eff = interp(h_s_eff, sat_h, sat_T)
    w_s_eff = interp(T_s_eff, sat_T, sat_w)
    w_out = w_s_eff + (air_w - w_s_eff) * decay
    m_w = f * m_air * nan_max(air_w - w_out, 0.0) if f > 0 else 0.0
    return m_w * (_WATER_CP * (T_s_eff - _WATER_T0)) if m_w > 0 else 0.0


@jit
def zone_rate(f, dry, wet, moist, sat_T, sat_h, sat_w):
    """One point of :meth:`evtms.hx.crossflow.ZoneHeatRate.rate`.

    ``dry`` and ``wet`` are ``(C_ref, R_tot, C_air, dT)`` of the zone's dry and
    enthalpy-potential models (``wet[0]`` NaN: no wet model); ``moist`` is
    ``(air_h, air_w, m_air, decay)`` (``moist[0]`` NaN: no moisture).
    """
    q = dry_rate(f, dry[0], dry[1], dry[2], dry[3])
    if wet[0] == wet[0]:
        q = nan_max(q, dry_rate(f, wet[0], wet[1], wet[2], wet[3]))
    if moist[0] == moist[0]:
        H_w = condensate_enthalpy(f, q, moist[0], moist[1], moist[2], moist[3], sat_T, sat_h, sat_w)
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
