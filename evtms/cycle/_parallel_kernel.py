"""The closure of two evaporating branches in parallel compiled (numba), point by point, on the LUTs.

The same closure as :func:`evtms.cycle.closure.solve_at` for a circuit of one
condensing component and two parallel branches (``cabin+chiller``) with a
saturated-liquid condenser outlet, started cold: the suction and discharge
roots of :mod:`evtms.cycle._closure_kernel` (the same searches, guesses and
tolerances), and at each suction iterate the branches of
:func:`evtms.cycle.split.parallel` in the order its vectorised path takes them:

- the flow split ``s`` (the second branch's share [1]) within the flows both
  branch models cover, the root of the residual of the point's branch mode
  (both outlets equal; or, with one valve at its maximum opening, the other
  branch's outlet at the setpoint's enthalpy), bracketed 0.03 either side of
  the previous iterate's split where that holds the root, else over the whole
  range, and closed by the modified regula falsi of
  :func:`evtms.cycle.roots.bracketed_root`; where the residual has one sign
  over the range, the split at the bound it points to (one branch at its
  least flow, ``CLAMP_*``);
- each branch's pressure drop at that split, and the split again at the new
  drops, until the drops stop moving (``DP_TOL``, at most ``DP_PASSES``);
- the outlets mixed, and the suction superheat residual from the mixture.

A branch whose valve is closed (modes 3, 4) takes no flow and leaves its inlet
state. Points run one after another; a point's result does not depend on the
others'. A point whose suction or discharge search ends without a root is
handed back, and the Python path says why it fails. The roots agree with the
Python path's to round-off.

References
----------
Anderson, N., Bjorck, A. (1973). A new high order method of regula falsi type
for computing a root of an equation. BIT 13, 253-264.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import compile_one_at_a_time, load_numba, uncounted
from evtms.cycle._closure_kernel import (
    _CP_SCALE,
    _DP_PASSES,
    _DP_TOL,
    _FLOOR_ABOVE,
    _GUESS_ABOVE,
    _INNER_FTOL,
    _INNER_SLOPE,
    _INNER_STEP,
    _MAXITER,
    _NSLOPE,
    _OUTER_FTOL,
    _OUTER_STEP,
    _OVERSHOOT,
    _PR_HI,
    _PR_LO,
    _R_OSLOPE,
    _R_PB,
    _R_PDHI,
    _R_PDLO,
    _R_SH,
    _R_TCOND,
    _R_TGUESS,
    _R_THI,
    _R_TLO,
    _SECANT,
    _SIZE,
    _SLOPE_SPAN,
    _XTOL,
    DONE,
    OPS_ROWS,
    PHASE,
    TOLERANCES,
    _at_p,
    _p_sat,
    _t_sat,
    _work,
    root_begin,
    root_next,
)
from evtms.cycle._component_kernel import evaluate_in
from evtms.cycle.state import (
    CLAMP_FIRST_LEAST,
    CLAMP_OTHER,
    CLAMP_SECOND_LEAST,
    FIRST_CLOSED,
    FIRST_FLOATS,
    SECOND_CLOSED,
    SECOND_FLOATS,
    SPLIT_HALF_WIDTH,
)
from evtms.luts._kernels import NAN_POLICY, interpolate_in

numba = load_numba()
_njit = numba.njit(cache=True, nogil=True, error_model="numpy")
# The helpers are compiled into the kernel that calls them (numba.extending.register_jitable), not as
# functions of their own: each of those took its own CPython wrapper and machine code, and the
# kernel's first compile 18 s instead of 13.
_inline = numba.extending.register_jitable

#: The rows of the kernel's per-point ``ops``: the single closure's, then the branch mode and the
#: superheat setpoint [K] (``ops["superheat"]`` is the suction's, floating where a valve is saturated).
PARALLEL_ROWS = (*OPS_ROWS, "branch_mode", "setpoint")
#: The kernel's constants (:data:`evtms.cycle._closure_kernel.TOLERANCES`, the same array).
PARALLEL_TOLERANCES = TOLERANCES
_R_MODE, _R_SET = len(OPS_ROWS), len(OPS_ROWS) + 1
#: The kernel's results per point, in the rows of its ``out``.
RESULTS = ("p_A", "p_B", "dp_first", "dp_second", "split", "clamped", "outer_slope", "inner_slope", "solved")
_O_PA, _O_PB, _O_DP1, _O_DP2, _O_SPLIT, _O_CLAMPED, _O_OSLOPE, _O_ISLOPE, _O_SOLVED = range(len(RESULTS))

# A point's carried scalars: the discharge pressure and its closure's slope, the split and both
# drops, why the split was clamped; the suction iterate's compressor flow and suction enthalpy,
# the valve-inlet enthalpy and the setpoint's enthalpy.
_PB, _ISLOPE, _SPLIT, _DP1, _DP2, _CLAMPED, _MDOT, _HA, _HD, _HSET = range(10)
_NC = 10
# The last pair of branch evaluations: the split and both inlets it was asked at, the outlets.
_K_S, _K_IN1, _K_IN2, _K_H1, _K_P1, _K_H2, _K_P2, _K_ON = range(8)


@_inline
def _eval(L, dyn, i, sh_min):
    """LUT bundle ``L`` at the closure variables ``dyn`` (mdot, p_in, h_in, T_in, pr) of point ``i``;
    its row of results in ``L[3][:, 0]`` (NaN outside an axis). Returns True where the cell says
    no heat flows (the refrigerant on the wrong side of its secondary stream)."""
    c, work, pts, res, first, outside, ts, share, vapour, dh = L
    lo, hi, floats, ints, values, rows, src, base, tsec, nh_floats, nh_ints, nh_values, nh_on = c
    for j in range(lo.size):
        pts[j, 0] = dyn[src[j]] if src[j] >= 0 else base[j, i]
    ts[0] = tsec[i]
    evaluate_in(
        pts,
        lo,
        hi,
        floats,
        ints,
        values,
        res,
        first,
        rows[0],
        rows[1],
        rows[2],
        ts,
        vapour,
        dh,
        sh_min,
        (outside, work[0], work[1], work[2]),
    )
    if first[0] >= 0:
        res[:, 0] = np.nan
        return False
    if nh_on and not math.isfinite(res[rows[0], 0]):
        interpolate_in(pts, NAN_POLICY, outside[:0], nh_floats, nh_ints, nh_values, share, *work[3])
        return share[0, 0] > 0
    return False


@_inline
def _out(L, k):
    """Result ``k`` of the bundle's last evaluation (``k`` an index into its ``rows``)."""
    return L[3][L[0][5][k], 0]


@_inline
def _branch(L, dyn, i, open_, mdot, p_in, h_in, sh_min):
    """One branch's outlet ``(h, p)`` [J/kg, Pa] (branches.branch): a closed branch, or one whose
    inlet is not colder than its stream, leaves its inlet state."""
    if not open_:
        return h_in, p_in
    dyn[0], dyn[1], dyn[2], dyn[3], dyn[4] = mdot, p_in, h_in, np.nan, np.nan
    none = _eval(L, dyn, i, sh_min)
    if none and math.isfinite(h_in):
        return h_in, p_in
    return _out(L, 4), _out(L, 5)


@_inline
def _pair(E1, E2, dyn, i, c, kc, share, in1, in2, mode, sh_min):
    """Both branches at the second's ``share`` of the flow and inlets ``in1``, ``in2`` [Pa] into
    ``kc``; the last pair is kept (asked again at the same split and inlets, it is not evaluated)."""
    if kc[_K_ON] > 0 and kc[_K_S] == share and kc[_K_IN1] == in1 and kc[_K_IN2] == in2:
        return
    m, h_D = c[_MDOT], c[_HD]
    kc[_K_H1], kc[_K_P1] = _branch(E1, dyn, i, mode != FIRST_CLOSED, m * (1.0 - share), in1, h_D, sh_min)
    kc[_K_H2], kc[_K_P2] = _branch(E2, dyn, i, mode != SECOND_CLOSED, m * share, in2, h_D, sh_min)
    kc[_K_S], kc[_K_IN1], kc[_K_IN2], kc[_K_ON] = share, in1, in2, 1.0


@_inline
def _split_residual(E1, E2, dyn, i, c, kc, share, in1, in2, mode, cp_scale, sh_min):
    """The split's residual [about K] (split._Split.residual), rising with ``share``."""
    _pair(E1, E2, dyn, i, c, kc, share, in1, in2, mode, sh_min)
    h1, h2 = kc[_K_H1], kc[_K_H2]
    if mode == FIRST_FLOATS:
        f = h2 - c[_HSET]
    elif mode == SECOND_FLOATS:
        f = c[_HSET] - h1
    else:
        f = h2 - h1
    return f / cp_scale


@_inline
def _falsi(E1, E2, dyn, i, c, kc, a, b, fa, fb, in1, in2, mode, tol, sh_min):
    """The split's root on ``[a, b]`` (residual ``fa`` > 0 or NaN at ``a``, ``fb`` <= 0 or NaN at
    ``b``) by regula falsi with the Anderson-Bjorck scaling, as roots.bracketed_root; NaN where it
    fails (a NaN it cannot go round, no convergence)."""
    xtol, ftol, cp = tol[_XTOL], tol[_INNER_FTOL], tol[_CP_SCALE]
    kept = 0
    for _ in range(_MAXITER):
        xs = b - fb * (b - a) / (fb - fa)
        xn = xs if (math.isfinite(xs) and xs > min(a, b) and xs < max(a, b)) else 0.5 * (a + b)
        f = _split_residual(E1, E2, dyn, i, c, kc, xn, in1, in2, mode, cp, sh_min)
        small = abs(b - a) < xtol * abs(xn)
        finite_ends = math.isfinite(fa) and math.isfinite(fb)
        if not math.isfinite(f):
            if small or finite_ends:
                return np.nan
            if not math.isfinite(fb):
                b = xn
            else:
                a = xn
            continue
        if abs(f) < ftol or (small and finite_ends):
            return xn
        if small:
            return np.nan
        if f > 0:
            m = 1.0 - f / fa
            a, fa = xn, f
            if kept == 1:
                fb *= m if m > 0 else 0.5
            kept = 1
        else:
            m = 1.0 - f / fb
            b, fb = xn, f
            if kept == -1:
                fa *= m if m > 0 else 0.5
            kept = -1
    return np.nan


@_inline
def _solve_split(E1, E2, dyn, i, c, kc, prev, s_lo, s_hi, in1, in2, mode, flows, tol, sh_min):
    """The split at the present inlets (split._solve_split), from the previous split ``prev``
    (NaN: none); returns ``(share, clamped)``, NaN where no split is found."""
    cp = tol[_CP_SCALE]
    lo, hi, f_lo, f_hi = s_lo, s_hi, np.nan, np.nan
    warm = math.isfinite(prev)
    if warm:
        a, b = max(prev - SPLIT_HALF_WIDTH, lo), min(prev + SPLIT_HALF_WIDTH, hi)
        fa = _split_residual(E1, E2, dyn, i, c, kc, a, in1, in2, mode, cp, sh_min)
        fb = _split_residual(E1, E2, dyn, i, c, kc, b, in1, in2, mode, cp, sh_min)
        if math.isfinite(fa) and math.isfinite(fb) and fa > 0 and fb <= 0:
            lo, hi, f_lo, f_hi = a, b, fa, fb
        else:
            warm = False
    if not warm:
        f_lo = _split_residual(E1, E2, dyn, i, c, kc, lo, in1, in2, mode, cp, sh_min)
        f_hi = _split_residual(E1, E2, dyn, i, c, kc, hi, in1, in2, mode, cp, sh_min)
    fin_lo, fin_hi = math.isfinite(f_lo), math.isfinite(f_hi)
    no_root = not (f_lo > 0 or not fin_lo) or not (f_hi <= 0 or not fin_hi) or not (fin_lo or fin_hi)
    if no_root:  # one sign over the range: the bound it points to (split._clamp_to_least_flow)
        if fin_lo and fin_hi and f_hi > 0:
            return hi, (CLAMP_FIRST_LEAST if _first_least(c, flows) else CLAMP_OTHER)
        if fin_lo and fin_hi and f_lo <= 0:
            return lo, (CLAMP_SECOND_LEAST if _second_least(c, flows) else CLAMP_OTHER)
        return np.nan, 0
    return _falsi(E1, E2, dyn, i, c, kc, lo, hi, f_lo, f_hi, in1, in2, mode, tol, sh_min), 0


@_inline
def _first_least(c, flows):
    """The first branch at its least flow binds the split's upper bound."""
    m = c[_MDOT]
    return 1.0 - flows[0] / m <= flows[3] / m


@_inline
def _second_least(c, flows):
    """The second branch at its least flow binds the split's lower bound."""
    m = c[_MDOT]
    return flows[2] / m >= 1.0 - flows[1] / m


@_inline
def _parallel_side(E1, E2, dyn, i, c, kc, p_A, mode, flows, tol, sh_min):
    """The branches from the valves to the suction at ``p_A`` [Pa] (split.parallel, not final):
    the split and drops solved and kept in ``c``; returns the outlets' mixed enthalpy [J/kg]."""
    m, h_D = c[_MDOT], c[_HD]
    lo1, hi1, lo2, hi2 = flows[0], flows[1], flows[2], flows[3]
    s_lo = max(lo2 / m, 1.0 - hi1 / m) * (1 + 1e-9)
    s_hi = min(1.0 - lo1 / m, hi2 / m) * (1 - 1e-9)
    split_mode = mode <= SECOND_FLOATS
    if split_mode:
        fits = s_lo < s_hi
    elif mode == FIRST_CLOSED:
        fits = m >= lo2 and m <= hi2
    else:
        fits = m >= lo1 and m <= hi1
    in1, in2 = p_A + c[_DP1], p_A + c[_DP2]
    c[_CLAMPED] = 0.0
    share = np.nan
    if math.isfinite(m) and math.isfinite(p_A) and math.isfinite(h_D) and fits:
        share = 1.0 if mode == FIRST_CLOSED else (0.0 if mode == SECOND_CLOSED else c[_SPLIT])
        kc[_K_ON] = 0.0  # a new suction iterate: the last pair was at another flow
        for _ in range(int(tol[_DP_PASSES])):
            if split_mode:
                share, c[_CLAMPED] = _solve_split(
                    E1, E2, dyn, i, c, kc, share, s_lo, s_hi, in1, in2, mode, flows, tol, sh_min
                )
            if not math.isfinite(share):
                break
            _pair(E1, E2, dyn, i, c, kc, share, in1, in2, mode, sh_min)
            old1, old2 = in1 - p_A, in2 - p_A
            new1 = in1 - kc[_K_P1] if math.isfinite(kc[_K_P1]) else old1
            new2 = in2 - kc[_K_P2] if math.isfinite(kc[_K_P2]) else old2
            moving = abs(new1 - old1) > tol[_DP_TOL] or abs(new2 - old2) > tol[_DP_TOL]
            in1, in2 = p_A + new1, p_A + new2
            if not moving:
                break
    for k, p_in in ((_DP1, in1), (_DP2, in2)):
        drop = p_in - p_A
        if math.isfinite(drop):
            c[k] = drop
    if not math.isfinite(share):
        return np.nan
    c[_SPLIT] = share
    _pair(E1, E2, dyn, i, c, kc, share, in1, in2, mode, sh_min)
    return (m * (1.0 - share) * kc[_K_H1] + m * share * kc[_K_H2]) / m


@_inline
def _discharge(C, K, dyn, i, c, s, p_A, t_suc, ops, sat, tol, sh_min):
    """The discharge root at suction ``p_A`` [Pa] (closure.solve_discharge): the compressor's flow
    and suction enthalpy, the discharge pressure and the valve-inlet enthalpy into ``c``; False
    where the search ends without a root."""
    log_p, T = sat[0], sat[1]
    lo_B = max(_p_sat(ops[_R_TCOND, i] + tol[_FLOOR_ABOVE], log_p, T), tol[_PR_LO] * p_A, ops[_R_PDLO, i])
    hi_B = min(ops[_R_PDHI, i], tol[_PR_HI] * p_A)
    known = math.isfinite(c[_PB])
    t_guess = _t_sat(c[_PB], log_p, T) if known else ops[_R_TCOND, i] + tol[_GUESS_ABOVE]
    slope = c[_ISLOPE] if (known and c[_ISLOPE] < 0) else tol[_INNER_SLOPE]
    t_B = root_begin(s, _t_sat(lo_B, log_p, T), _t_sat(hi_B, log_p, T), t_guess, slope, 0.0)
    while True:
        p_B = _p_sat(t_B, log_p, T)
        dyn[0], dyn[1], dyn[2], dyn[3], dyn[4] = np.nan, p_A, np.nan, t_suc, p_B / p_A
        _eval(C, dyn, i, sh_min)
        mdot, h_A = _out(C, 4), _out(C, 5)
        dyn[0], dyn[1], dyn[2], dyn[3], dyn[4] = mdot, p_B, _out(C, 6), np.nan, np.nan
        none = _eval(K, dyn, i, sh_min)
        # Condensing nothing: far above the target (closure.discharge_side).
        f = 1.0 if (none and math.isfinite(mdot)) else 1.0 - _out(K, 4)
        phase = s[PHASE]
        t_B = root_next(s, t_B, f, tol[_INNER_STEP], tol[_OVERSHOOT], tol[_XTOL], tol[_INNER_FTOL])
        if phase == _SECANT and s[_NSLOPE] < 0:
            c[_ISLOPE] = s[_NSLOPE]
        if s[PHASE] == DONE:
            c[_PB] = _p_sat(t_B, log_p, T)
            c[_MDOT], c[_HA], c[_HD] = mdot, h_A, _at_p(_out(K, 5), log_p, sat[2])
            return True
        if s[PHASE] > DONE:
            return False


@_inline
def _suction_residual(L, dyn, i, c, kc, so, si, t_A, ops, sat, flows, tol, sh_min):
    """The superheat residual [about K] at the suction iterate ``t_A`` [K] (closure.suction_side)."""
    C, K, E1, E2 = L
    log_p, T = sat[0], sat[1]
    p_A = _p_sat(t_A, log_p, T)
    t_suc = _t_sat(p_A, log_p, T) + ops[_R_SH, i]
    mode = int(ops[_R_MODE, i])
    if not _discharge(C, K, dyn, i, c, si, p_A, t_suc, ops, sat, tol, sh_min):
        c[_MDOT] = np.nan  # no flow to split: the drops stay as they are (the split too)
        _parallel_side(E1, E2, dyn, i, c, kc, p_A, mode, flows, tol, sh_min)
        return np.nan
    h_A = c[_HA]
    c[_HSET] = np.nan
    if mode == FIRST_FLOATS or mode == SECOND_FLOATS:  # the setpoint's enthalpy (split.setpoint_enthalpy)
        dyn[0], dyn[1], dyn[2] = np.nan, p_A, np.nan
        dyn[3], dyn[4] = _t_sat(p_A, log_p, T) + ops[_R_SET, i], c[_PB] / p_A
        _eval(C, dyn, i, sh_min)
        c[_HSET] = _out(C, 5)
    h_mix = _parallel_side(E1, E2, dyn, i, c, kc, p_A, mode, flows, tol, sh_min)
    return (h_mix - h_A) / tol[_CP_SCALE]


@_inline
def _solve_point(L, dyn, i, c, kc, so, si, ops, sat, flows, tol, sh_min, out):
    """Point ``i``'s closure into ``out[:, i]`` (solved 0 where it is handed back)."""
    out[:, i] = np.nan
    out[_O_SOLVED, i] = 0.0
    if not (ops[_R_TLO, i] < ops[_R_THI, i]):  # not served, or an empty range
        return
    c[:] = np.nan
    c[_PB], c[_DP1], c[_DP2], c[_CLAMPED] = ops[_R_PB, i], 0.0, 0.0, 0.0
    kc[_K_ON] = 0.0
    lat_t, lat_f, oslope = np.nan, np.nan, np.nan
    log_p, T = sat[0], sat[1]
    t_A = root_begin(so, ops[_R_TLO, i], ops[_R_THI, i], ops[_R_TGUESS, i], ops[_R_OSLOPE, i], 0.0)
    while True:
        f = _suction_residual(L, dyn, i, c, kc, so, si, t_A, ops, sat, flows, tol, sh_min)
        if math.isfinite(f):  # the local slope, for a warm start from this solution
            t = _t_sat(_p_sat(t_A, log_p, T), log_p, T)
            chord = (f - lat_f) / (t - lat_t)
            if math.isfinite(chord) and chord < 0 and abs(t - lat_t) > tol[_SLOPE_SPAN]:
                oslope = chord
            lat_t, lat_f = t, f
        t_A = root_next(so, t_A, f, tol[_OUTER_STEP], tol[_OVERSHOOT], tol[_XTOL], tol[_OUTER_FTOL])
        if so[PHASE] >= DONE:
            break
    if so[PHASE] != DONE:
        return
    out[_O_PA, i], out[_O_PB, i] = _p_sat(t_A, log_p, T), c[_PB]
    out[_O_DP1, i], out[_O_DP2, i], out[_O_SPLIT, i] = c[_DP1], c[_DP2], c[_SPLIT]
    out[_O_CLAMPED, i], out[_O_OSLOPE, i], out[_O_ISLOPE, i] = c[_CLAMPED], oslope, c[_ISLOPE]
    out[_O_SOLVED, i] = 1.0


@_inline
def _bundle(c, vapour, dh):
    """A LUT's bundle for :func:`_eval`: its packed table, work arrays and one point's buffers."""
    pts, res = np.empty((c[0].size, 1)), np.empty((c[5][3], 1))
    first, outside = np.empty(1, np.int64), np.empty(1, np.bool_)
    return (c, _work(c), pts, res, first, outside, np.empty(1), np.empty((1, 1)), vapour, dh)


@_njit
def solve_parallel(comp, cond, evap1, evap2, vap1, vap2, ops, sat, flows, tol, sh_min, out):
    """The closure of two parallel branches at every point: both roots, the split and the drops.

    Parameters
    ----------
    comp, cond, evap1, evap2 : tuple
        The compressor's, the condensing component's and the two branches' LUTs as
        :func:`evtms.cycle.compiled.packed` gives them.
    vap1, vap2 : tuple
        Each branch's approach transform, ``(vapour, dh)`` (:func:`evtms.cycle._component_kernel.evaluate`).
    ops : (12, n) float64
        Per point, the rows :data:`PARALLEL_ROWS` names (the single closure's
        :data:`~evtms.cycle._closure_kernel.OPS_ROWS`, the branch mode and the setpoint [K]).
    sat : tuple
        ``(ln p, T, h_l)`` of the saturation table.
    flows : (4,) float64
        Each branch model's least and largest flow [kg/s]: first, then second.
    tol : float64 array
        The constants :data:`~evtms.cycle._closure_kernel.TOLERANCES` names.
    sh_min : float
        The least superheat of the approach transform [K].
    out : (9, n) float64
        Written, by the rows :data:`RESULTS` names: ``p_A``, ``p_B`` [Pa], both drops [Pa], the
        split [1], why it was clamped, the two closures' slopes [1/K], and 1 where solved.
    """
    L = (
        _bundle(comp, vap1[0], vap1[1]),
        _bundle(cond, vap1[0], vap1[1]),
        _bundle(evap1, vap1[0], vap1[1]),
        _bundle(evap2, vap2[0], vap2[1]),
    )
    dyn = np.empty(5)
    c, kc = np.empty(_NC), np.zeros(8)
    so, si = np.empty(_SIZE), np.empty(_SIZE)
    _solve_each(L, dyn, c, kc, so, si, ops, sat, flows, tol, sh_min, out)


# The points' loop allocates nothing (its arrays are made above), so it runs without reference
# counting (evtms._jit.uncounted): the LUT bundles it hands down its chain of helpers at every
# evaluation otherwise cost three quarters of a point's time in counts.
@numba.njit(cache=True, nogil=True, error_model="numpy", **uncounted())
def _solve_each(L, dyn, c, kc, so, si, ops, sat, flows, tol, sh_min, out):
    """:func:`solve_parallel`'s loop over the points, with its work arrays."""
    for i in range(ops.shape[1]):
        _solve_point(L, dyn, i, c, kc, so, si, ops, sat, flows, tol, sh_min, out)


# Processes that start together (a test run's workers) compile it one at a time: the first one
# compiles and saves, the others load its machine code (evtms._jit; 12-18 s each otherwise).
compile_one_at_a_time(solve_parallel)
