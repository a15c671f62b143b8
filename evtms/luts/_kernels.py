"""Compiled (numba) kernel of :class:`evtms.luts.interp.Interpolator`.

The cycle solver calls the interpolator about ninety times per operating point
per solve, mostly on batches of 1-50 points, where NumPy's per-call overhead
(dozens of small temporaries, ``clip``, ``take``, ``where`` per axis) costs far
more than the arithmetic. This kernel does the same work point by point in one
compiled loop, with the NumPy path's arithmetic in the same order, so that both
give the same numbers (to the bit, as long as the compiler does not contract
multiply-adds into FMAs, which numba does not do without ``fastmath``).

Importing this module imports numba (about 0.2 s), so :mod:`evtms.luts.interp`
imports it only when the first interpolator is built. ``cache=True`` stores the
compiled machine code in ``__pycache__`` next to this file (numba falls back to
a per-user cache folder when that is read-only): only the first call on a
machine compiles; later processes load the machine code.

Numba unboxes every argument on every call (about 0.1 us per array), so the
interpolator's grid description travels as two packed arrays, built once by
:func:`pack`: ``floats`` and ``ints``, laid out as below.
"""

from __future__ import annotations

import numpy as np

from evtms._jit import load_numba, uncounted

numba = load_numba()  # lean in the command line's process (evtms._jit.lean_numba)

# Out-of-range policies as the kernel's integer codes.
ERROR, CLIP, NAN = 0, 1, 2
#: ``NAN`` as compiled callers pass it: a NumPy integer, not a literal (numba compiles a callee
#: once per literal argument, and once more for a variable one).
NAN_POLICY = np.int64(NAN)
POLICY_CODES = {"error": ERROR, "clip": CLIP, "nan": NAN}

# floats: per axis N_F values (F_* below), then every axis' nodes one after the other.
F_LO, F_HI, F_START, F_STEP, F_BUCKET_START, F_BUCKET_WIDTH = range(6)
N_F = 6
# ints: [nc, number of corners], per axis N_I values (I_* below), the corners' row
# offsets from the cell's base row, the curved variables' indices, the bucket tables.
I_SIZE, I_STRIDE, I_UNIFORM, I_NODES, I_BUCKETS, I_BUCKET_COUNT, I_CURVED = range(7)
N_I = 7
HEADER = 2


def pack(axes, strides, uniform, buckets, curved_axes, curved_vars):
    """The interpolator's grid as the kernel's ``floats`` and ``ints`` arrays.

    Parameters
    ----------
    axes : list of numpy.ndarray
        Axis nodes, in table dimension order.
    strides : list of int
        Row stride of each axis in the flattened table.
    uniform : list of (float, float) or None
        Per axis, (start, step) when the nodes are uniform.
    buckets : list of (float, float, numpy.ndarray) or None
        Per non-uniform axis, (start, width, first cell index per bucket).
    curved_axes : list of int
        Axes with curvature columns, in the order of their column blocks.
    curved_vars : list of int
        Indices of the curved variables (empty: no correction).

    Returns
    -------
    floats : numpy.ndarray of float64
    ints : numpy.ndarray of int64
    """
    d = len(axes)
    # Corner k has bit b set for the b-th axis with more than one node (the NumPy path's order).
    offsets = [0]
    for j, a in enumerate(axes):
        if len(a) > 1:
            offsets = offsets + [o + strides[j] for o in offsets]
    curved = list(curved_vars) if curved_axes else []
    floats = np.zeros(N_F * d + sum(len(a) for a in axes))
    ints = [len(curved), len(offsets)] + [0] * (N_I * d) + offsets + curved
    tables = [np.asarray(ints, np.int64)]
    end = len(ints)  # where the next bucket table goes
    node = N_F * d
    for j, a in enumerate(axes):
        f, i = N_F * j, HEADER + N_I * j
        floats[f + F_LO], floats[f + F_HI] = a[0], a[-1]
        floats[node : node + len(a)] = a
        ints[i + I_SIZE], ints[i + I_STRIDE], ints[i + I_NODES] = len(a), strides[j], node
        node += len(a)
        if uniform[j] is not None:
            ints[i + I_UNIFORM] = 1
            floats[f + F_START], floats[f + F_STEP] = uniform[j]
        elif buckets[j] is not None:
            start, width, first = buckets[j]
            floats[f + F_BUCKET_START], floats[f + F_BUCKET_WIDTH] = start, width
            ints[i + I_BUCKETS], ints[i + I_BUCKET_COUNT] = end, len(first)
            tables.append(np.asarray(first, np.int64))
            end += len(first)
        ints[i + I_CURVED] = curved_axes.index(j) if j in curved_axes else -1
    tables[0] = np.asarray(ints, np.int64)
    return floats, np.concatenate(tables)


# error_model="numpy": a division never checks for zero (axes are strictly increasing)
# and gives what NumPy's would.
@numba.njit(cache=True, nogil=True, error_model="numpy")
def interpolate(pts, policy, outside, floats, ints, values, out):
    """Multilinear interpolation with the optional curvature correction, all points in one loop
    (:func:`interpolate_in` with its work arrays made here)."""
    d = pts.shape[0]
    return interpolate_in(pts, policy, outside, floats, ints, values, out, *scratch(ints, values, d))


@numba.njit(cache=True, nogil=True)
def scratch(ints, values, d):
    """The work arrays of :func:`interpolate_in` for a table and ``d`` axes: the cell's corners
    (each corner's columns in a row), the cell coordinates and the curvature weights."""
    return np.empty(ints[1] * values.shape[1]), np.empty(d), np.zeros(d)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _on_edge(c0, c1, tk):
    """``(c1 - c0) tk + c0`` on a cell's edge (``tk`` 0 or 1), where a NaN corner of zero weight does
    not poison the result (``r != r``: ``r`` is NaN)."""
    r = (c1 - c0) * tk + c0
    if tk == 0.0 and r != r:
        r = c0
    if tk == 1.0 and r != r:
        r = c1
    return r


# Allocates nothing: compiled without reference counting (evtms._jit.uncounted), as the callers
# that pass it their tables point by point need.
@numba.njit(cache=True, nogil=True, error_model="numpy", **uncounted())
def interpolate_in(pts, policy, outside, floats, ints, values, out, corners, t, bows):
    """Multilinear interpolation with the optional curvature correction, all points in one loop.

    Parameters
    ----------
    pts : (d, n) float64
        Query points, one row per axis (the query's columns, contiguous).
    policy : int
        ``ERROR``, ``CLIP`` or ``NAN``.
    outside : (n,) or (0,) bool
        Points already out of range (a fixed input off its value under the 'nan'
        policy); empty when there are none.
    floats, ints : numpy.ndarray
        The grid, from :func:`pack`.
    values : (rows, columns) float64
        The flattened table: the variables, then per curved axis one second-derivative
        column per curved variable.
    out : (nv, n) float64
        Results, one row per variable (written).
    corners, t, bows : numpy.ndarray
        Work arrays (:func:`scratch`): a caller that interpolates one point at a time
        makes them once.

    Returns
    -------
    int
        -1, or under the 'error' policy the first out-of-range point of the first
        axis that has one, as ``axis * n + point`` (nothing is computed then).
    """
    d, n = pts.shape
    nv = out.shape[0]
    ncols = values.shape[1]
    nc = ints[0]
    ncorners = ints[1]
    offsets = HEADER + N_I * d  # where the corner offsets start in ints
    curved_vars = offsets + ncorners
    m = 0  # axes with more than one node: they span the cell
    for j in range(d):
        if ints[HEADER + N_I * j + I_SIZE] > 1:
            m += 1
    # 'error' reports the first axis with any bad point, then that axis' first bad
    # point (as the NumPy path does): check axis by axis before computing anything.
    if policy == ERROR:
        for j in range(d):
            lo = floats[N_F * j + F_LO]
            hi = floats[N_F * j + F_HI]
            for p in range(n):
                x = pts[j, p]
                if not (x >= lo and x <= hi):  # NaN counts as outside
                    return j * n + p
    flagged = outside.shape[0] > 0
    for p in range(n):
        skip = flagged and outside[p]
        base = 0
        k = 0  # index among the axes with more than one node
        for j in range(d):
            if skip:
                break
            f = N_F * j
            a = HEADER + N_I * j
            lo = floats[f + F_LO]
            hi = floats[f + F_HI]
            x = pts[j, p]
            if not (x >= lo and x <= hi):
                if policy == NAN:
                    skip = True
                    break
                x = lo if np.isnan(x) else min(max(x, lo), hi)
            size = ints[a + I_SIZE]
            if size == 1:
                continue  # a single node: no cell, no weight to spread
            nodes = ints[a + I_NODES]
            if ints[a + I_UNIFORM]:
                i = int(np.floor((x - floats[f + F_START]) / floats[f + F_STEP]))
                i = min(max(i, 0), size - 2)
            else:
                # Buckets narrower than the smallest cell hold at most one node: the
                # bucket's first cell, moved on by one where x lies past that node.
                b = int((x - floats[f + F_BUCKET_START]) / floats[f + F_BUCKET_WIDTH])
                b = min(max(b, 0), ints[a + I_BUCKET_COUNT] - 1)
                i = ints[ints[a + I_BUCKETS] + b]
                if x >= floats[nodes + i + 1]:
                    i += 1
                i = min(max(i, 0), size - 2)
            node = floats[nodes + i]
            width = floats[nodes + i + 1] - node
            tk = (x - node) / width
            t[k] = tk
            k += 1
            if ints[a + I_CURVED] >= 0:
                bows[j] = 0.5 * tk * (tk - 1.0) * width * width
            base += i * ints[a + I_STRIDE]
        if skip:
            for v in range(nv):
                out[v, p] = np.nan
            continue
        # Halve along the last spanning axis first, as the NumPy path does. The first halving
        # reads its two corners straight from the table (corner c and c + half differ in that
        # axis alone): the same numbers, without first copying every corner (a sixth less time).
        if m == 0:
            for col in range(ncols):
                corners[col] = values[base, col]
        else:
            half = ncorners >> 1
            tk = t[m - 1]
            plain = tk != 0.0 and tk != 1.0
            for c in range(half):
                row0 = base + ints[offsets + c]
                row1 = base + ints[offsets + c + half]
                for col in range(ncols):
                    c0 = values[row0, col]
                    c1 = values[row1, col]
                    corners[c * ncols + col] = (c1 - c0) * tk + c0 if plain else _on_edge(c0, c1, tk)
        for k in range(m - 2, -1, -1):
            half = 1 << k
            tk = t[k]
            width = half * ncols
            if tk != 0.0 and tk != 1.0:  # the usual step: one loop the compiler vectorises
                for e in range(width):
                    c0 = corners[e]
                    corners[e] = (corners[e + width] - c0) * tk + c0
                continue
            for e in range(width):
                corners[e] = _on_edge(corners[e], corners[e + width], tk)
        for v in range(nv):
            out[v, p] = corners[v]
        if nc == 0:
            continue
        # Quadratic correction: per curved axis, the interpolated second derivative
        # times (x - x_i)(x - x_i+1)/2; none where it is unknown (NaN).
        for j in range(d):
            q = ints[HEADER + N_I * j + I_CURVED]
            if q < 0:
                continue
            bow = bows[j]
            for s in range(nc):
                d2 = corners[nv + nc * q + s]
                inc = d2 * bow if np.isfinite(d2) else 0.0
                out[ints[curved_vars + s], p] += inc
    return -1
