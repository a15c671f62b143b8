"""The cycle's two pressure closures compiled (numba), point by point, on the component LUTs.

The same closure as :func:`evtms.cycle.closure.solve_at` for a circuit of one
condensing component and one evaporating branch (``cabin``, ``chiller``,
``hp``) with a saturated-liquid condenser outlet: the suction pressure is the
root of the superheat residual, each suction iterate finds the discharge
pressure where the condensing component's capacity ratio is 1, and the
branch's pressure drop is the fixed point of its model. The searches are
those of :mod:`evtms.cycle.roots` (a first guess and one overshot secant step,
else the range's ends; modified regula falsi in saturation temperature, with
the Anderson-Bjorck scaling), the guesses and tolerances those of
:mod:`evtms.cycle.closure`, started cold or from a previous solution (a warm
start: a trial within the tolerance is the root, the discharge guess is
extrapolated from the last two suction iterates' roots), and each component is interpolated by the
kernel the Python path calls (:func:`evtms.cycle._component_kernel.evaluate`).

Each point's closure runs one evaluation after another, as the Python path
runs it; :data:`IN_FLIGHT` points run side by side and each round asks each
LUT once for all the points waiting for it, so that the memory reads of
different points overlap. A point's result does not depend on the others'.

A search meets NaN where a model leaves its envelope: at an end of its range
that end's sign is taken as known and the steps bisect, as in
:func:`evtms.cycle.roots.bracketed_root`. A LUT cell next to nodes where no
heat flows (the refrigerant on the wrong side of its secondary stream) gives
the residual the Python path gives there, from the same indicator table. A
point whose search ends without a root (one sign over the range, NaN at both
ends or inside a finite bracket, no convergence), a subcooled condenser
target, or an input a LUT holds fixed at another value, is handed back
unsolved: the Python path solves it and says why it fails. The roots equal
the Python path's to round-off (within 4e-15 relative on 2,000 envelope
points, 94 % of them to the bit).

References
----------
Anderson, N., Bjorck, A. (1973). A new high order method of regula falsi type
for computing a root of an equation. BIT 13, 253-264.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import compile_one_at_a_time, load_numba, uncounted
from evtms.cycle._component_kernel import evaluate_in
from evtms.hx._kernels import interp
from evtms.luts._kernels import NAN_POLICY, interpolate_in, scratch

numba = load_numba()
# error_model="numpy": a division by zero gives inf or NaN, as NumPy's, which the searches read as
# a failed step (a secant through two equal residuals), not an exception.
_njit = numba.njit(cache=True, nogil=True, error_model="numpy")
# The helpers are compiled into the kernel that calls them (numba.extending.register_jitable), not as
# functions of their own, which cost each its own CPython wrapper and machine code at the first compile.
_inline = numba.extending.register_jitable

# The root search's state vector (reverse communication: the caller evaluates, the search says
# where next), indices into a float64 array of _SIZE.
# A warm search (_WARM 1) takes a trial within the tolerance as the root and may take a third trial
# (_T2, _F2: its second).
(
    _A,
    _B,
    _FA,
    _FB,
    _KEPT,
    _PHASE,
    _TG,
    _FG,
    _SLOPE,
    _NEED_A,
    _NEED_B,
    _LO_END,
    _HI_END,
    _NSLOPE,
    _IT,
    _WARM,
    _T2,
    _F2,
) = range(18)
_SIZE = 18
#: A search's state: its size, and the entry holding its phase (:data:`DONE`, :data:`FAILED` at the end).
STATE_SIZE, PHASE = _SIZE, _PHASE
# Phases: the guess, the secant step from it, a warm search's third trial, the range's ends, regula
# falsi; then done or failed.
_GUESS, _SECANT, _THIRD, _END_A, _END_B, _FALSI, DONE, FAILED = range(8)
_MAXITER = 80


@_inline
def _t_sat(p, log_p, T):
    """Saturation temperature [K] at ``p`` [Pa], linear in ln p; NaN outside the table."""
    return _at_p(p, log_p, T)


@_inline
def _p_sat(t, log_p, T):
    """Saturation pressure [Pa] at ``t`` [K]; NaN outside the table."""
    if not (t >= T[0] and t <= T[-1]):
        return np.nan
    return math.exp(interp(t, T, log_p))


@_inline
def _at_p(p, log_p, table):
    """A saturation property at ``p`` [Pa], linear in ln p; NaN outside the table."""
    x = math.log(p) if p > 0 else np.nan
    if not (x >= log_p[0] and x <= log_p[-1]):
        return np.nan
    return interp(x, log_p, table)


@_inline
def _falsi_x(s):
    """The regula falsi trial of the bracket: the secant through its ends, or its midpoint."""
    a, b, fa, fb = s[_A], s[_B], s[_FA], s[_FB]
    xs = b - fb * (b - a) / (fb - fa)
    if math.isfinite(xs) and xs > min(a, b) and xs < max(a, b):
        return xs
    return 0.5 * (a + b)


@_inline
def _take(s, t, f):
    """A trial of the bracketing phase: it becomes the end of its sign where it narrows the range."""
    if f > 0 and t > s[_A]:
        s[_A], s[_FA], s[_NEED_A] = t, f, 0.0
    elif f <= 0 and t < s[_B]:
        s[_B], s[_FB], s[_NEED_B] = t, f, 0.0


@_inline
def _next_end(s):
    """The next range end to evaluate, or the first regula falsi trial once the bracket holds a root."""
    if s[_NEED_A] > 0:
        s[_PHASE] = _END_A
        return s[_A]
    if s[_NEED_B] > 0:
        s[_PHASE] = _END_B
        return s[_B]
    # One sign up to an end of the range, or NaN at both ends: no root the search can find.
    fa, fb = s[_FA], s[_FB]
    if (s[_LO_END] > 0 and fa <= 0) or (s[_HI_END] > 0 and fb >= 0) or not (math.isfinite(fa) or math.isfinite(fb)):
        s[_PHASE] = FAILED
        return np.nan
    s[_PHASE] = _FALSI
    return _falsi_x(s)


@_inline
def _secant_step(t, f, slope, overshoot, max_step, lo, hi):
    """The trial after ``t`` [K] with residual ``f``: a secant step along ``slope`` [1/K] overshot
    ``overshoot`` times and by 0.01 K, at most ``max_step`` [K], within ``[lo, hi]`` (NaN: no step)."""
    step = -overshoot * f / slope + math.copysign(0.01, f) if f != 0 else 0.0
    if math.isnan(step):
        step = 0.0
    return min(max(t + min(max(step, -max_step), max_step), lo), hi)


@_inline
def root_begin(s, t_lo, t_hi, t_guess, slope, warm):
    """Start a search for the root of a residual falling in ``t`` on ``[t_lo, t_hi]`` [K] from
    ``t_guess`` with the estimated ``slope`` [1/K]; returns the first ``t`` to evaluate. A ``warm``
    search (1.0; 0.0 cold) starts from a previous solution, as :func:`evtms.cycle.roots.bracket`
    with ``ftol``: a guess trial within the tolerance is the root, and a second trial that falls
    short on the guess's side is followed by a third secant step before the range's ends."""
    s[:] = np.nan
    s[_A], s[_B], s[_KEPT], s[_IT], s[_WARM] = t_lo, t_hi, 0.0, 0.0, warm
    s[_NEED_A] = s[_NEED_B] = 1.0
    s[_SLOPE] = slope
    if t_guess > t_lo and t_guess < t_hi:  # False for NaN
        s[_PHASE], s[_TG] = _GUESS, t_guess
        return t_guess
    s[_LO_END] = s[_HI_END] = 1.0
    return _next_end(s)


@_inline
def root_next(s, t, f, max_step, overshoot, xtol, ftol):
    """Take the residual ``f`` at ``t``, the trial :func:`root_begin` or this function asked for;
    returns the next ``t`` to evaluate. ``s[PHASE]`` is then :data:`DONE` (``t`` was the root) or
    :data:`FAILED` (no root the search can find, a NaN it cannot go round, no convergence) where
    the search ends.

    A NaN residual at an end of the range leaves that end's sign as known and the steps bisect
    until both ends are finite; a NaN inside the bracket replaces the NaN end (as
    :func:`evtms.cycle.roots.bracketed_root`).
    """
    phase = s[_PHASE]
    finite = math.isfinite(f)
    hit = s[_WARM] > 0 and finite and abs(f) < ftol  # a warm trial at the root
    if phase == _GUESS:  # one overshot secant step, as evtms.cycle.roots._guess_and_secant (NaN: no step)
        s[_FG] = f
        if hit:
            s[_PHASE] = DONE
            return t
        s[_PHASE] = _SECANT
        return _secant_step(t, f, s[_SLOPE], overshoot, max_step, s[_A], s[_B])
    if phase == _SECANT:
        s[_NSLOPE] = (f - s[_FG]) / (t - s[_TG])
        if hit:
            s[_PHASE] = DONE
            return t
        fg = s[_FG]
        if s[_WARM] > 0 and finite and math.isfinite(fg) and (f > 0) == (fg > 0) and f != 0 and t != s[_TG]:
            # A measured slope's step fell short: one more secant step through both trials (overshot
            # 1.5 times), as evtms.cycle.roots._guess_and_secant.
            chord = s[_NSLOPE]
            s[_T2], s[_F2], s[_PHASE] = t, f, _THIRD
            return _secant_step(t, f, chord if chord < 0 else s[_SLOPE], 1.5, max_step, s[_A], s[_B])
        _take(s, s[_TG], s[_FG])
        _take(s, t, f)
        s[_LO_END], s[_HI_END] = s[_NEED_A], s[_NEED_B]
        return _next_end(s)
    if phase == _THIRD:
        if hit:
            s[_PHASE] = DONE
            return t
        _take(s, s[_TG], s[_FG])
        _take(s, s[_T2], s[_F2])
        _take(s, t, f)
        s[_LO_END], s[_HI_END] = s[_NEED_A], s[_NEED_B]
        return _next_end(s)
    if phase == _END_A:
        s[_FA], s[_NEED_A] = f, 0.0
        return _next_end(s)
    if phase == _END_B:
        s[_FB], s[_NEED_B] = f, 0.0
        return _next_end(s)
    a, b = s[_A], s[_B]
    small = abs(b - a) < xtol * abs(t)
    finite_ends = math.isfinite(s[_FA]) and math.isfinite(s[_FB])
    if not finite:  # joins the NaN end; with both ends finite, or the bracket closed, the search ends
        if small or finite_ends:
            s[_PHASE] = FAILED
            return np.nan
        if not math.isfinite(s[_FB]):
            s[_B] = t
        else:
            s[_A] = t
    elif abs(f) < ftol or (small and finite_ends):
        s[_PHASE] = DONE
        return t
    elif small:  # closed onto a NaN end with the residual away from zero: the root lies beyond it
        s[_PHASE] = FAILED
        return np.nan
    elif f > 0:  # replaces the low end; a high end kept twice in a row is scaled down
        m = 1.0 - f / s[_FA]
        s[_A], s[_FA] = t, f
        if s[_KEPT] == 1:
            s[_FB] *= m if m > 0 else 0.5
        s[_KEPT] = 1
    else:
        m = 1.0 - f / s[_FB]
        s[_B], s[_FB] = t, f
        if s[_KEPT] == -1:
            s[_FA] *= m if m > 0 else 0.5
        s[_KEPT] = -1
    s[_IT] += 1
    if s[_IT] >= _MAXITER:
        s[_PHASE] = FAILED
        return np.nan
    return _falsi_x(s)


#: The kernel's constants, in the order of its ``tol`` array (built by these names).
TOLERANCES = (
    "outer_ftol",
    "inner_ftol",
    "xtol",
    "cp_scale",
    "dp_tol",
    "dp_passes",
    "pr_lo",
    "pr_hi",
    "inner_slope",
    "discharge_floor_above",
    "discharge_guess_above",
    "inner_max_step",
    "outer_max_step",
    "overshoot",
    "slope_span",
    "warm",
)
(
    _OUTER_FTOL,
    _INNER_FTOL,
    _XTOL,
    _CP_SCALE,
    _DP_TOL,
    _DP_PASSES,
    _PR_LO,
    _PR_HI,
    _INNER_SLOPE,
    _FLOOR_ABOVE,
    _GUESS_ABOVE,
    _INNER_STEP,
    _OUTER_STEP,
    _OVERSHOOT,
    _SLOPE_SPAN,
    _WARM_SOLVE,
) = range(len(TOLERANCES))
#: The rows of the kernel's per-point ``ops`` array, in order (built by these names).
OPS_ROWS = (
    "t_lo",
    "t_hi",
    "t_guess",
    "outer_slope",
    "T_cond_sec",
    "superheat",
    "p_B",
    "dp",
    "p_dis_lo",
    "p_dis_hi",
    "inner_slope",
)
_R_TLO, _R_THI, _R_TGUESS, _R_OSLOPE, _R_TCOND, _R_SH, _R_PB, _R_DP, _R_PDLO, _R_PDHI, _R_ISLOPE = range(len(OPS_ROWS))

# Each point in flight holds its closure's scalars in a row of these columns: the suction and
# discharge iterates [K], the suction pressure [Pa] and temperature [K], the compressor's flow and
# suction enthalpy, the discharge pressure [Pa], the condensing outlet pressure, the valve-outlet
# enthalpy, the latest finite suction residual and its iterate, the suction closure's slope, the
# drop's pass, and what it carries from one suction iterate to the next (the discharge pressure,
# the discharge closure's slope, the branch's drop); a warm solve's two latest discharge roots, as
# (suction, discharge) saturation temperatures [K] (the latest first).
(_TA, _TB, _PA, _TSUC, _MDOT, _HA, _PB_TRIAL, _PC, _HD, _LAT_T, _LAT_F, _OSLOPE, _PASS, _PB, _ISLOPE, _DP) = range(16)
_PAIR_A1, _PAIR_B1, _PAIR_A0, _PAIR_B0 = range(16, 20)
_NV = 20
# What a point waits for: the compressor, the condensing component, the branch for its drop, the
# branch for the superheat; and which LUT each asks.
_W_COMP, _W_COND, _W_DROP, _W_SH = range(4)
_ASKS = (0, 1, 2, 2)
# The three LUTs' numbers as _serve takes them: NumPy integers, not literals, as numba would
# compile _serve once for each literal it is called with.
_COMP, _COND, _EVAP = np.int64(0), np.int64(1), np.int64(2)
#: Points in flight at once: their LUT cells are fetched together, so that the memory reads of
#: different points overlap (one point's evaluations depend on each other's results).
IN_FLIGHT = 32


@_inline
def _ask(dyn, wait, g, what, mdot, p_in, h_in, T_in, pr):
    """Point slot ``g`` waits for ``what`` at the closure's variables (mdot, p_in, h_in, T_in, pr)."""
    dyn[g, 0], dyn[g, 1], dyn[g, 2], dyn[g, 3], dyn[g, 4] = mdot, p_in, h_in, T_in, pr
    wait[g] = what


@_inline
def _discharge_trial(v, dyn, wait, g, t_B, sat):
    """Ask the compressor at discharge saturation ``t_B`` [K] (the discharge search's next trial)."""
    v[g, _TB] = t_B
    p_B = _p_sat(t_B, sat[0], sat[1])
    v[g, _PB_TRIAL] = p_B
    p_A = v[g, _PA]
    _ask(dyn, wait, g, _W_COMP, np.nan, p_A, np.nan, v[g, _TSUC], p_B / p_A)


@_inline
def _suction_iterate(v, si, dyn, wait, g, i, ops, sat, tol):
    """Start the discharge search at the suction iterate ``v[g, _TA]``."""
    log_p, T = sat[0], sat[1]
    p_A = _p_sat(v[g, _TA], log_p, T)
    v[g, _PA] = p_A
    v[g, _TSUC] = _t_sat(p_A, log_p, T) + ops[_R_SH, i]
    lo_B = max(_p_sat(ops[_R_TCOND, i] + tol[_FLOOR_ABOVE], log_p, T), tol[_PR_LO] * p_A, ops[_R_PDLO, i])
    hi_B = min(ops[_R_PDHI, i], tol[_PR_HI] * p_A)
    known = math.isfinite(v[g, _PB])
    t_guess = _t_sat(v[g, _PB], log_p, T) if known else ops[_R_TCOND, i] + tol[_GUESS_ABOVE]
    slope = v[g, _ISLOPE] if (known and v[g, _ISLOPE] < 0) else tol[_INNER_SLOPE]
    if tol[_WARM_SOLVE] > 0:
        t_guess = _extrapolated_discharge(v[g], _t_sat(p_A, log_p, T), t_guess)
    t_B = root_begin(si[g], _t_sat(lo_B, log_p, T), _t_sat(hi_B, log_p, T), t_guess, slope, tol[_WARM_SOLVE])
    _discharge_trial(v, dyn, wait, g, t_B, sat)


@_inline
def _extrapolated_discharge(w, t_A, t_guess):
    """A warm solve's first guess of the discharge saturation temperature [K] at suction saturation
    ``t_A`` [K], from the slot's row ``w``: linear through its two latest discharge roots, by at
    most 2 K from the latest; ``t_guess`` where there are not two (closure._extrapolated_discharge)."""
    a1, b1, a0, b0 = w[_PAIR_A1], w[_PAIR_B1], w[_PAIR_A0], w[_PAIR_B0]
    shift = (b1 - b0) / (a1 - a0) * (t_A - a1)
    if math.isnan(shift) or not (math.isfinite(b1) and abs(a1 - a0) > 1e-9):
        return t_guess
    return b1 + min(max(shift, -2.0), 2.0)


@_inline
def _begin(v, so, si, dyn, wait, point, g, i, ops, sat, tol, out):
    """Put point ``i`` in slot ``g``; where it is not served (handed back at once) the slot stays free."""
    out[:, i] = np.nan
    out[5, i] = 0.0
    if not (ops[_R_TLO, i] < ops[_R_THI, i]):  # not served, or an empty range
        return
    point[g] = i
    v[g, :] = np.nan
    v[g, _PB], v[g, _DP], v[g, _ISLOPE] = ops[_R_PB, i], ops[_R_DP, i], ops[_R_ISLOPE, i]
    t_lo, t_hi = ops[_R_TLO, i], ops[_R_THI, i]
    v[g, _TA] = root_begin(so[g], t_lo, t_hi, ops[_R_TGUESS, i], ops[_R_OSLOPE, i], tol[_WARM_SOLVE])
    _suction_iterate(v, si, dyn, wait, g, i, ops, sat, tol)


@_inline
def _suction_residual(v, so, si, dyn, wait, point, g, f, ops, sat, tol, out):
    """The superheat residual ``f`` at the slot's suction iterate: the next iterate, or the end of
    its point (written to ``out``; the slot is then free, ``point[g]`` -1)."""
    i = point[g]
    t_A = v[g, _TA]
    if math.isfinite(f):  # the local slope, for a warm start from this solution (at T(p(t)), as the Python path)
        t = _t_sat(v[g, _PA], sat[0], sat[1])
        chord = (f - v[g, _LAT_F]) / (t - v[g, _LAT_T])
        if math.isfinite(chord) and chord < 0 and abs(t - v[g, _LAT_T]) > tol[_SLOPE_SPAN]:
            v[g, _OSLOPE] = chord
        v[g, _LAT_T], v[g, _LAT_F] = t, f
    t_A = root_next(so[g], t_A, f, tol[_OUTER_STEP], tol[_OVERSHOOT], tol[_XTOL], tol[_OUTER_FTOL])
    if so[g, _PHASE] < DONE:
        v[g, _TA] = t_A
        _suction_iterate(v, si, dyn, wait, g, i, ops, sat, tol)
        return
    if so[g, _PHASE] == DONE:
        out[0, i], out[1, i], out[2, i] = _p_sat(t_A, sat[0], sat[1]), v[g, _PB], v[g, _DP]
        out[3, i], out[4, i], out[5, i] = v[g, _OSLOPE], v[g, _ISLOPE], 1.0
    point[g] = -1


@_inline
def _take_result(r, none, rows, v, so, si, dyn, wait, point, g, ops, sat, tol, out):
    """The LUT's answer ``r`` to what slot ``g`` waited for, ``none`` where its cell says no heat
    flows (the refrigerant on the wrong side of the secondary stream): the slot's next step."""
    what = wait[g]
    if what == _W_COMP:
        v[g, _MDOT], v[g, _HA] = r[rows[4]], r[rows[5]]
        _ask(dyn, wait, g, _W_COND, r[rows[4]], v[g, _PB_TRIAL], r[rows[6]], np.nan, np.nan)
    elif what == _W_COND:
        v[g, _PC] = r[rows[5]]
        phase = si[g, _PHASE]
        # Condensing nothing: far above the target (closure.discharge_side).
        f = 1.0 if (none and math.isfinite(v[g, _MDOT])) else 1.0 - r[rows[4]]
        t_B = root_next(si[g], v[g, _TB], f, tol[_INNER_STEP], tol[_OVERSHOOT], tol[_XTOL], tol[_INNER_FTOL])
        if phase == _SECANT and si[g, _NSLOPE] < 0:
            v[g, _ISLOPE] = si[g, _NSLOPE]
        if si[g, _PHASE] < DONE:
            _discharge_trial(v, dyn, wait, g, t_B, sat)
        elif si[g, _PHASE] == DONE:  # the discharge root: the branch's drop from the last iterate's
            v[g, _PB] = _p_sat(t_B, sat[0], sat[1])
            # The two latest roots, for a warm solve's next first guess (at T(p), as the Python path).
            v[g, _PAIR_A0], v[g, _PAIR_B0] = v[g, _PAIR_A1], v[g, _PAIR_B1]
            v[g, _PAIR_A1], v[g, _PAIR_B1] = _t_sat(v[g, _PA], sat[0], sat[1]), _t_sat(v[g, _PB], sat[0], sat[1])
            v[g, _HD] = _at_p(v[g, _PC], sat[0], sat[2])
            v[g, _PASS] = 0.0
            _ask(dyn, wait, g, _W_DROP, v[g, _MDOT], v[g, _PA] + v[g, _DP], v[g, _HD], np.nan, np.nan)
        else:  # no discharge root: the superheat residual is NaN here
            _suction_residual(v, so, si, dyn, wait, point, g, np.nan, ops, sat, tol, out)
    elif what == _W_DROP:  # a pass of the drop's fixed point, then the superheat at it
        p_in, dp, p_out = dyn[g, 1], v[g, _DP], r[rows[5]]
        new = p_in - p_out if math.isfinite(p_out) else dp
        moving = abs(new - dp) > tol[_DP_TOL]
        v[g, _DP] = new
        v[g, _PASS] += 1.0
        step = _W_DROP if (moving and v[g, _PASS] < tol[_DP_PASSES]) else _W_SH
        _ask(dyn, wait, g, step, v[g, _MDOT], v[g, _PA] + new, v[g, _HD], np.nan, np.nan)
    else:  # an inlet not colder than the air evaporates nothing: the outlet stays at h_D (closure.suction_side)
        h_out = v[g, _HD] if (none and math.isfinite(v[g, _HD])) else r[rows[4]]
        f = (h_out - v[g, _HA]) / tol[_CP_SCALE]
        _suction_residual(v, so, si, dyn, wait, point, g, f, ops, sat, tol, out)


@_inline
def _serve(c, cid, v, so, si, dyn, wait, point, ops, sat, vapour, dh, sh_min, tol, out, work):
    """Evaluate LUT ``c`` (number ``cid``) for every slot waiting for it, in one call; hand each
    slot its answer. Returns how many were served. ``work``: the LUT's work arrays (:func:`_serve_work`)."""
    lo, hi, floats, ints, values, rows, src, base, tsec, nh_floats, nh_ints, nh_values, nh_on = c
    slots, pts_flat, ts_all, res_flat, first_all, outside_all, share, one = work[4:]
    G = point.size
    m = 0
    for g in range(G):
        if point[g] >= 0 and _ASKS[wait[g]] == cid:
            slots[m] = g
            m += 1
    if m == 0:
        return 0
    d = lo.size
    # The first m columns of the slots' buffers, C-ordered as a call of their own (views, no copy).
    pts = pts_flat[: d * m].reshape((d, m))
    ts = ts_all[:m]
    for k in range(m):
        g = slots[k]
        i = point[g]
        ts[k] = tsec[i]
        for j in range(d):
            pts[j, k] = dyn[g, src[j]] if src[j] >= 0 else base[j, i]
    res = res_flat[: rows[3] * m].reshape((rows[3], m))
    first = first_all[:m]
    outside = outside_all[:m]
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
    for k in range(m):
        none = False
        if first[k] >= 0:  # outside an axis: no value (an invalid cell leaves NaN where it weighs)
            res[:, k] = np.nan
        elif nh_on and not math.isfinite(res[rows[0], k]):
            # A NaN cell: no heat flows where any of its weight lies on such nodes (NaN: other invalid ones).
            for j in range(d):
                one[j, 0] = pts[j, k]
            interpolate_in(one, NAN_POLICY, outside[:0], nh_floats, nh_ints, nh_values, share, *work[3])
            none = share[0, 0] > 0
        _take_result(res[:, k], none, rows, v, so, si, dyn, wait, point, slots[k], ops, sat, tol, out)
    return m


@_inline
def _work(c):
    """A LUT's work arrays: its table's (:func:`evtms.luts._kernels.scratch`), then its no-heat
    table's as the fourth."""
    d = c[0].size
    corners, t, bows = scratch(c[3], c[4], d)
    return corners, t, bows, scratch(c[10], c[11], d)


@_inline
def _serve_work(c, G):
    """:func:`_work`, then what :func:`_serve` fills for up to ``G`` slots: the slots served, their
    points' coordinates and secondary inlets, the results, the first axis each lies outside and
    its flag, the no-heat share and one point's coordinates (C-ordered as every other call's)."""
    d = c[0].size
    corners, t, bows, nh = _work(c)
    return (
        corners,
        t,
        bows,
        nh,
        np.empty(G, np.int64),
        np.empty(d * G),
        np.empty(G),
        np.empty(c[5][3] * G),
        np.empty(G, np.int64),
        np.empty(G, np.bool_),
        np.empty((1, 1)),
        np.empty((d, 1)),
    )


@_njit
def solve_points(comp, cond, evap, ops, sat, vapour, dh, sh_min, tol, out):
    """The closure at every point: suction and discharge roots and the branch's drop.

    Each point's closure runs as in :func:`evtms.cycle.closure.solve_at`, one evaluation after
    another; :data:`IN_FLIGHT` points run side by side, and each round asks each LUT once for
    every point waiting for it. A point's result does not depend on the others'.

    Parameters
    ----------
    comp, cond, evap : tuple
        The compressor's, the condensing component's and the evaporating branch's LUTs:
        ``(lo, hi, floats, ints, values, rows, src, base, tsec)`` and their no-heat indicator
        ``(floats, ints, values, on)`` (see :func:`evtms.cycle.compiled.packed`).
    ops : (10, n) float64
        Per point, the rows :data:`OPS_ROWS` names: the suction search's ends [K] (NaN: not
        served), its first guess [K] and slope [1/K], the condensing side's secondary inlet
        [K], the superheat setpoint [K], the first guesses of the discharge pressure [Pa]
        (NaN: none) and of the branch's drop [Pa], and the condensing LUT's
        discharge-pressure range [Pa] (a hair inside its axis).
    sat : tuple
        ``(ln p, T, h_l)`` of the saturation table.
    vapour, dh, sh_min
        The evaporating branch's approach transform (:func:`evtms.cycle._component_kernel.evaluate`).
    tol : (15,) float64
        The constants :data:`TOLERANCES` names, in that order: the closures' tolerances
        (``OUTER_FTOL, INNER_FTOL, XTOL``), ``CP_SCALE``, the drop's ``DP_TOL`` and
        ``DP_PASSES``, the compressor's pressure-ratio range searched, the condensing
        closure's typical slope [1/K], the discharge search's floor and first guess above
        the secondary inlet [K], the two searches' largest first steps [K], the overshoot
        of their secant step [1], and the least span of the suction slope's chord [K].
    out : (6, n) float64
        Written: ``p_A, p_B`` [Pa], the branch's drop [Pa], the two closures' slopes [1/K] and
        1 where the point is solved, 0 where it is handed back.
    """
    n = ops.shape[1]
    G = max(1, min(n, IN_FLIGHT))
    v = np.empty((G, _NV))
    so, si = np.empty((G, _SIZE)), np.empty((G, _SIZE))
    dyn = np.empty((G, 5))
    wait = np.zeros(G, np.int64)
    point = np.full(G, -1, np.int64)
    works = (_serve_work(comp, G), _serve_work(cond, G))
    work_e = _serve_work(evap, G)
    _run_slots(comp, cond, evap, ops, sat, vapour, dh, sh_min, tol, out, v, so, si, dyn, wait, point, works, work_e)


# The slots' loop allocates nothing (its arrays are made above), so it runs without reference
# counting (evtms._jit.uncounted): the counts of the LUT tuples handed to every round were about
# 40 % of a point's time.
@numba.njit(cache=True, nogil=True, error_model="numpy", **uncounted())
def _run_slots(comp, cond, evap, ops, sat, vapour, dh, sh_min, tol, out, v, so, si, dyn, wait, point, works, work_e):
    """:func:`solve_points`' rounds: free slots take the next points, each LUT serves its slots."""
    n = ops.shape[1]
    G = point.size
    nxt = 0
    while True:
        for g in range(G):  # free slots take the next points
            while point[g] < 0 and nxt < n:
                _begin(v, so, si, dyn, wait, point, g, nxt, ops, sat, tol, out)
                nxt += 1
        busy = _serve(comp, _COMP, v, so, si, dyn, wait, point, ops, sat, vapour, dh, sh_min, tol, out, works[0])
        busy += _serve(cond, _COND, v, so, si, dyn, wait, point, ops, sat, vapour, dh, sh_min, tol, out, works[1])
        busy += _serve(evap, _EVAP, v, so, si, dyn, wait, point, ops, sat, vapour, dh, sh_min, tol, out, work_e)
        if busy == 0 and nxt >= n:
            break


# Processes that start together (a test run's workers) compile it one at a time: the first one
# compiles and saves, the others load its machine code (evtms._jit; 12-18 s each otherwise).
compile_one_at_a_time(solve_points)
