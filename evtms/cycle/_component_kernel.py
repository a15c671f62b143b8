"""Compiled (numba) evaluation of a component LUT for the cycle solver: one call per model call.

The cycle solver asks a component model for a few points at a time, some
ninety times per operating point and solve; the nested closures of a valve at
its maximum opening or of two parallel branches ask several times more. Each
ask used to be three steps with Python between them (the axis checks, the
interpolation kernel of :mod:`evtms.luts._kernels`, the outlet's approach
transform of :mod:`evtms.cycle.approach`), and the Python cost some 60 us of
the 80 us an ask took. :func:`evaluate` does the three in one compiled call
with the same kernels, so the numbers are the same to the bit; the reasons of
the points it marks outside an axis are worded in Python afterwards, where
there are any.

Importing this module imports numba; :mod:`evtms.cycle.models` imports it only
where its interpolators are compiled.
"""

from __future__ import annotations

import numpy as np

from evtms._jit import load_numba, uncounted
from evtms.cycle.approach import compiled_outlet_kernel
from evtms.luts._kernels import NAN_POLICY, interpolate_in, scratch

numba = load_numba()

# The approach transform's compiled loop (the one :func:`evtms.cycle.approach.outlet_enthalpy` calls).
_outlet_points = compiled_outlet_kernel()


@numba.njit(cache=True, nogil=True, error_model="numpy")
def evaluate(
    pts, lo, hi, floats, ints, values, out, first_off, check_row, approach_row, p_out_row, t_sec, vapour, dh, sh_min
):
    """:func:`evaluate_in` with its work arrays made here."""
    work = (np.zeros(pts.shape[1], np.bool_), *scratch(ints, values, pts.shape[0]))
    return evaluate_in(
        pts,
        lo,
        hi,
        floats,
        ints,
        values,
        out,
        first_off,
        check_row,
        approach_row,
        p_out_row,
        t_sec,
        vapour,
        dh,
        sh_min,
        work,
    )


@numba.njit(cache=True, nogil=True, error_model="numpy", **uncounted())  # allocates nothing
def evaluate_in(
    pts,
    lo,
    hi,
    floats,
    ints,
    values,
    out,
    first_off,
    check_row,
    approach_row,
    p_out_row,
    t_sec,
    vapour,
    dh,
    sh_min,
    work,
):
    """Interpolate a component LUT at ``pts``, NaN outside its axes, the outlet from its approach.

    Parameters
    ----------
    pts : (d, n) float64
        Query points, one row per LUT axis.
    lo, hi : (d,) float64
        The axes' ends.
    floats, ints, values
        The interpolator's packed grid and table (:func:`evtms.luts._kernels.pack`).
    out : (nv, n) float64
        Results, one row per variable (written).
    first_off : (n,) int64
        Per point, the first axis its value lies outside (or NaN on), else -1 (written).
    check_row : int
        The row whose NaN at a point inside the axes marks an invalid cell (the outlet, or the first
        variable).
    approach_row, p_out_row : int
        Rows of ``out`` holding the outlet's ``approach_log`` and ``p_out``; -1: no transform.
        The approach row is replaced by the outlet enthalpy [J/kg].
    t_sec : (n,) float64
        The secondary inlet temperature [K] (unused without a transform).
    vapour : tuple
        The vapour table's ``log_p0, dlog_p, T, h_v, step``; ``dh``, its superheat rise, and ``sh_min`` [K]
        the least superheat of the transform (:func:`evtms.cycle.approach.outlet_enthalpy`).
    work : tuple
        Work arrays: ``(outside, corners, t, bows)``, a flag per point and the interpolation's
        (:func:`evtms.luts._kernels.scratch`); a caller asking one point at a time makes them once.

    Returns
    -------
    int
        Bit 0: some point lies outside an axis; bit 1: some point inside them has NaN in ``check_row``.
    """
    d, n = pts.shape
    outside, corners, t, bows = work
    any_off = False
    for p in range(n):
        first_off[p] = -1
        outside[p] = False
        for j in range(d):
            x = pts[j, p]
            if not (x >= lo[j] and x <= hi[j]):  # NaN counts as outside
                first_off[p] = j
                outside[p] = True
                any_off = True
                break
    interpolate_in(pts, NAN_POLICY, outside, floats, ints, values, out, corners, t, bows)
    if approach_row >= 0:
        log_p0, dlog_p, T, h_v, step = vapour
        row = out[approach_row]
        _outlet_points(row, out[p_out_row], t_sec, log_p0, dlog_p, T, h_v, step, dh, sh_min, row)
    flags = 1 if any_off else 0
    for p in range(n):
        if not outside[p] and not np.isfinite(out[check_row, p]):
            flags |= 2
            break
    return flags
