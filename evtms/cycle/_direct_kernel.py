"""The cycle's two pressure closures compiled (numba) on the bench physics itself, point by point.

The closure of :mod:`evtms.cycle._closure_kernel` (the suction and discharge
roots and the branch's drop, the same searches, guesses and tolerances, the
same steps from one evaluation to the next) for a circuit of one condensing
component and one branch (``cabin``, ``chiller``, ``hp``: compressor,
air-cooled condenser or WCC, evaporator or plate chiller) on the direct models
of :class:`evtms.cycle.models.DirectModels` instead of the LUTs: each component
is the bench's compiled per-point twin on the refrigerant tables,
:func:`evtms.benches._compressor_kernel.compress_point`,
:func:`evtms.hx._coil_kernels.march_point`,
:func:`evtms.benches._wcc_kernel.solve_point_wcc` and
:func:`evtms.benches._chiller_kernel.solve_point_chiller`. The coils' air sides
(entering air, capacity rate, air-side resistance) are fixed per point and
computed before, as :func:`evtms.benches.coil.solve_coil` computes them.

Each evaluation gives its bench's status (:func:`evtms.benches.condenser.
coil_bench_outputs` and the other benches' functions, before
:func:`evtms.benches.base.finish_status` names the valid points' flags): a
refrigerant on the wrong side of its secondary stream (:data:`WRONG_SIDE`)
gives no heat flow; a non-finite inlet, a pressure drop past the inlet
pressure, a failed property or any non-finite output gives NaN. An evaluation
at a state the tables do not hold (the bench solves it with CoolProp: a
discharge search's upper end near the critical pressure, say) is asked of the
caller, and the closure goes on with its answer. A point whose search ends
without a root is handed back: the Python path solves it and says why it
fails. The roots equal the Python path's on the same models to round-off.
:func:`compressor_rows` and :func:`exchanger_rows` give the same evaluations
to the Python path's iterations (``DirectModels`` with ``detailed(False)``).

numba keys a cache on the function's own file: after editing a kernel this
module compiles in (:mod:`evtms.cycle._closure_kernel`'s steps, the benches'
twins), touch this file (or clear ``evtms/cycle/__pycache__/*.nb*``).
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import compile_one_at_a_time, load_numba
from evtms.benches import chiller, condenser, evaporator, wcc
from evtms.benches._chiller_kernel import COLUMNS as PLATE_COLUMNS
from evtms.benches._chiller_kernel import solve_point_chiller
from evtms.benches._compressor_kernel import COLUMNS as COMPRESSOR_COLUMNS
from evtms.benches._compressor_kernel import compress_point
from evtms.benches._wcc_kernel import COLUMNS as WCC_COLUMNS
from evtms.benches._wcc_kernel import solve_point_wcc
from evtms.benches.base import STATUS_OUTSIDE_FLUID_RANGE, STATUS_PROPERTY_FAILED
from evtms.cycle._closure_kernel import _NV, _SIZE, _W_COMP, _W_COND, _begin, _take_result
from evtms.cycle.tables import wrong_side_flags
from evtms.hx._coil_kernels import COLUMNS as COIL_COLUMNS
from evtms.hx._coil_kernels import POINTS as COIL_POINTS
from evtms.hx._coil_kernels import TUBE, march_point

numba = load_numba()
_njit = numba.njit(cache=True, nogil=True, error_model="numpy")
_inline = numba.extending.register_jitable

# An evaluation's answer is its bench's status code (before the valid points' own flags: 0 where
# valid), or one of these: a state beyond the tables (the bench decides it with CoolProp), or a coil
# asked at a flow or pressure that is not finite (NaN; the bench's NumPy march names the status).
ASK, NAN_INPUT = -1, -2
# The one status the coil, chiller and WCC benches give a refrigerant on the wrong side of their
# secondary stream (no heat flows the way the circuit needs).
_WRONG = {c for m in (condenser, evaporator, chiller, wcc) for c in wrong_side_flags(m.FLAGS)}
assert len(_WRONG) == 1, _WRONG
WRONG_SIDE = _WRONG.pop()
_OUTSIDE, _FAILED = STATUS_OUTSIDE_FLUID_RANGE, STATUS_PROPERTY_FAILED
_DP_CODE, _FLOW_CODE, _FREEZE_CODE = (
    condenser.STATUS_DP_EXCEEDS_INLET,
    chiller.STATUS_FLOW_NOT_POSITIVE,
    chiller.STATUS_COOLANT_FREEZES,
)
# The benches share these codes (each names its own); the kernel reads one of each.
assert {m.STATUS_DP_EXCEEDS_INLET for m in (condenser, evaporator, chiller, wcc)} == {_DP_CODE}
assert (wcc.STATUS_FLOW_NOT_POSITIVE, wcc.STATUS_COOLANT_FREEZES) == (_FLOW_CODE, _FREEZE_CODE)
_SUBCOOLED_CODE, _SUPERCRITICAL_CODE = wcc.STATUS_INLET_SUBCOOLED, wcc.STATUS_SUPERCRITICAL
# The compressor's columns read, and those a valid bench point holds finite (its outputs).
_C_MDOT, _C_HIN, _C_HOUT, _C_CODE, _C_FALLBACK = (
    COMPRESSOR_COLUMNS.index(k) for k in ("mdot", "h_in", "h_out", "code", "fallback")
)
_C_FINITE = np.array([COMPRESSOR_COLUMNS.index(k) for k in ("W", "mdot", "h_in", "h_out", "T_out", "eta_vol")])
# The coil's columns read; those a valid bench point holds finite (its outputs, the latent heat).
_COIL_READ = ("capacity_ratio", "h_out_continued", "p_out", "bad_direction", "bad_props", "fallback")
_M_CR, _M_HOC, _M_POUT, _M_DIR, _M_PROPS, _M_FALLBACK = (COIL_COLUMNS.index(k) for k in _COIL_READ)
_COIL_FINITE = ("Q", "dp", "h_out", "h_out_continued", "capacity_ratio", "latent", "cond_enthalpy", "p_out", "x_out")
_M_FINITE = np.array([COIL_COLUMNS.index(k) for k in (*_COIL_FINITE, "T_out")], np.int64)
_P_TRIPLE = TUBE.index("p_triple")
# The plates' columns read, and those a valid bench point holds finite (its outputs).
_K_HOC, _K_POUT = PLATE_COLUMNS.index("h_out_continued"), PLATE_COLUMNS.index("p_out")
_K_FINITE = np.array([PLATE_COLUMNS.index(k) for k in chiller.OUTPUTS if k not in ("status", "h_in")], np.int64)
_W_CR, _W_POUT = WCC_COLUMNS.index("capacity_ratio"), WCC_COLUMNS.index("p_out")
_W_FINITE = np.array([WCC_COLUMNS.index(k) for k in wcc.OUTPUTS if k not in ("status", "h_in")], np.int64)


def _order(columns: tuple[str, ...], masks: tuple[tuple[str, int], ...]) -> np.ndarray:
    """A plate's statuses in its bench's order (its ``first_code`` list), after the states beyond the
    tables: rows ``(mask column, code)``."""
    return np.array([(columns.index(k), code) for k, code in (("outside_tables", ASK), *masks)], np.int64)


_K_ORDER = _order(
    PLATE_COLUMNS,
    (
        ("coolant_outside", _OUTSIDE),
        ("bad_flow", _FLOW_CODE),
        ("coolant_freezes", _FREEZE_CODE),
        ("bad_direction", WRONG_SIDE),
        ("bad_dp", _DP_CODE),
        ("bad_props", _FAILED),
    ),
)
_W_ORDER = _order(
    WCC_COLUMNS,
    (
        ("bad_flow", _FLOW_CODE),
        ("coolant_freezes", _FREEZE_CODE),
        ("inlet_subcooled", _SUBCOOLED_CODE),
        ("not_below_inlet", WRONG_SIDE),
        ("coolant_outside", _OUTSIDE),
        ("bad_dp", _DP_CODE),
        ("bad_props", _FAILED),
    ),
)
# The rows _take_result reads of an answer: the compressor's flow, suction and discharge enthalpy;
# the condensing coil's capacity ratio and outlet pressure; the evaporator's continued outlet
# enthalpy and outlet pressure (the first four rows are the LUT kernel's, unused here).
_ROWS = np.array([0, 0, 0, 3, 0, 1, 2], np.int64)


@_inline
def _finite(row, columns):
    """Whether every column ``columns`` of ``row`` is finite."""
    total = 0.0
    for k in columns:
        total += row[k]
    return math.isfinite(total)


@_inline
def _plate_status(row, order, finite):
    """A plate's bench status from its kernel's ``row``: the code of the first mask of ``order`` set,
    else :data:`STATUS_PROPERTY_FAILED` where an output of ``finite`` is not finite, else 0."""
    for j in range(order.shape[0]):
        if row[order[j, 0]] > 0:
            return order[j, 1]
    return 0 if _finite(row, finite) else _FAILED


@_inline
def _compressor(dyn, speed, c, tables, row, r):
    """The compressor at the slot's suction ``(p_in, T_in)`` and pressure ratio: its bench's status
    (:func:`evtms.benches.compressor.compressor_power`), and ``r`` ``(mdot, h_in, h_out)`` where
    valid (else NaN); ``row`` holds its kernel's columns."""
    meta, sat, vap, liq = tables
    compress_point(speed, dyn[4], dyn[1], dyn[3], False, c, meta, sat, vap, liq, row)
    r[0], r[1], r[2] = np.nan, np.nan, np.nan
    if row[_C_FALLBACK] > 0:
        return ASK
    code = int(row[_C_CODE])
    if code != 0:
        return code
    if not _finite(row, _C_FINITE):
        return _FAILED
    r[0], r[1], r[2] = row[_C_MDOT], row[_C_HIN], row[_C_HOUT]
    return 0


@_inline
def _coil(dyn, air, coil, tables, pt, row, r, first):
    """A coil at the slot's ``(mdot, p_in, h_in)``: its bench's status (:func:`evtms.benches.
    condenser.coil_bench_outputs`), and ``r`` ``(column first, p_out)`` where valid (else NaN);
    ``row`` holds the march's columns."""
    tube, is_condenser, moist, sat_T, sat_h, sat_w = coil
    meta, sat, vap, liq = tables
    r[0], r[1] = np.nan, np.nan
    mdot, p_in, h_in = dyn[0], dyn[1], dyn[2]
    if not (math.isfinite(mdot) and math.isfinite(p_in)):
        return NAN_INPUT
    if not math.isfinite(h_in):
        return _OUTSIDE
    pt[0], pt[1], pt[2] = p_in, h_in, mdot
    for k in range(air.size):
        pt[3 + k] = air[k]
    march_point(pt, tube, is_condenser, moist, meta, sat, vap, liq, sat_T, sat_h, sat_w, row)
    if row[_M_FALLBACK] > 0:
        return ASK
    if row[_M_DIR] > 0:
        return WRONG_SIDE
    if not (row[_M_POUT] > tube[_P_TRIPLE]):
        return _DP_CODE
    if row[_M_PROPS] > 0 or not _finite(row, _M_FINITE):
        return _FAILED
    r[0], r[1] = row[first], row[_M_POUT]
    return 0


def memory() -> tuple:
    """A new :func:`solve_points` memory: the closure's scalars, its two searches, the model's
    arguments, what the point waits for, the point in progress and ``(next point, waiting)``."""
    return (
        np.empty((1, _NV)),
        np.empty((1, _SIZE)),
        np.empty((1, _SIZE)),
        np.empty((1, 5)),
        np.zeros(1, np.int64),
        np.full(1, -1, np.int64),
        np.zeros(2, np.int64),
    )


@_inline
def _plate(dyn, coolant, plate, tables, row, r):
    """The plate chiller at the slot's ``(mdot, p_in, h_in)`` and the point's ``coolant`` (flow
    [kg/s], inlet temperature [K]): ``r`` is ``(h_out_continued, p_out)``, NaN where the bench's
    point is not valid (:func:`evtms.benches.chiller.chiller_heat_rate`: an inlet outside the
    fluid's range or the coolant's tables, no flow, a freezing coolant, a drop past the inlet
    pressure, a failed property); no heat flow where its refrigerant is not colder than the coolant."""
    geo, cool, T_freeze, T_max, p_triple, curve_p_min, gauss, p_crit = plate
    r[0], r[1] = np.nan, np.nan
    mdot, p_in, h_in = dyn[0], dyn[1], dyn[2]
    if not (math.isfinite(h_in) and p_in > p_triple and p_in < p_crit):
        return _OUTSIDE
    solve_point_chiller(
        p_in, h_in, mdot, coolant[0], coolant[1], geo, cool, T_freeze, T_max, p_triple, curve_p_min, tables, gauss, row
    )
    code = _plate_status(row, _K_ORDER, _K_FINITE)
    if code == 0:
        r[0], r[1] = row[_K_HOC], row[_K_POUT]
    return code


@_inline
def _wcc(dyn, coolant, wcc, tables, row, r):
    """The water-cooled condenser at the slot's ``(mdot, p_in, h_in)`` and the point's heating-loop
    ``coolant`` (flow [kg/s], inlet temperature [K]): ``r`` is ``(capacity_ratio, p_out)``, NaN
    where the bench's point is not valid (:func:`evtms.benches.wcc.wcc_heat_rate`: a supercritical
    or out-of-range inlet, no flow, a freezing coolant, a subcooled inlet, a coolant outside its
    tables, a drop past the inlet pressure, a failed property); no heat flow where the coolant is
    not colder than the refrigerant entering."""
    geo, cool, mirrored, T_freeze, T_max, p_triple, p_crit, curve_p_min, g_range, gauss = wcc
    r[0], r[1] = np.nan, np.nan
    mdot, p_in, h_in = dyn[0], dyn[1], dyn[2]
    if p_in >= p_crit:
        return _SUPERCRITICAL_CODE
    if not (math.isfinite(h_in) and p_in > p_triple):
        return _OUTSIDE
    solve_point_wcc(
        p_in, h_in, mdot, coolant[0], coolant[1], geo, cool, mirrored, T_freeze, T_max, p_triple, p_crit,
        curve_p_min, g_range, tables, gauss, row,
    )  # fmt: skip
    code = _plate_status(row, _W_ORDER, _W_FINITE)
    if code == 0:
        r[0], r[1] = row[_W_CR], row[_W_POUT]
    return code


#: The length of a coil's constants (``tube, condenser, moist, sat_T, sat_h, sat_w``) and a plate
#: chiller's (``geo, cool, T_freeze, T_max, p_triple, curve_p_min, gauss, p_crit``); the WCC's are
#: :func:`evtms.benches.wcc.kernel_constants` but the refrigerant tables.
_COIL_CONSTANTS, _CHILLER_CONSTANTS = 6, 8


def _exchanger(dyn, inputs, constants, tables, pt, row_m, row_k, row_w, r, first):
    """A heat exchanger: the coil, the chiller or the WCC, by its constants' tuple (compiled for the
    one it is); a coil's ``r`` starts with its column ``first``."""


@numba.extending.overload(_exchanger)
def _exchanger_for(dyn, inputs, constants, tables, pt, row_m, row_k, row_w, r, first):
    if len(constants.types) == _COIL_CONSTANTS:

        def coil(dyn, inputs, constants, tables, pt, row_m, row_k, row_w, r, first):
            return _coil(dyn, inputs, constants, tables, pt, row_m, r, first)

        return coil
    if len(constants.types) == _CHILLER_CONSTANTS:

        def plate(dyn, inputs, constants, tables, pt, row_m, row_k, row_w, r, first):
            return _plate(dyn, inputs, constants, tables, row_k, r)

        return plate

    def wcc(dyn, inputs, constants, tables, pt, row_m, row_k, row_w, r, first):
        return _wcc(dyn, inputs, constants, tables, row_w, r)

    return wcc


@_njit
def solve_points(speed, comp, cond_in, cond, branch_in, branch, tables, ops, sat, tol, out, mem, answer):
    """The closure at every point on the bench physics: suction and discharge roots and the
    branch's drop, as :func:`evtms.cycle._closure_kernel.solve_points` on the LUTs.

    An evaluation whose states the tables do not hold is the caller's: the kernel returns the
    component it waits for (0 the compressor, 1 the condensing coil, 2 the branch), its arguments
    in ``mem[3][0]`` (``mdot, p_in, h_in, T_in, pr``) and the point in ``mem[5][0]``. The caller
    evaluates it with the bench and calls again with the same ``mem`` and the answer; the kernel
    goes on from there. It returns -1 when every point is done.

    Parameters
    ----------
    speed : (n,) float64
        The compressor speed per point [1].
    comp : (8,) float64
        The compressor constants (:func:`evtms.benches.compressor.kernel_constants`).
    cond_in, cond
        The condensing component per point and its constants: the air-cooled condenser's air
        ``(n, 7)`` (the march's ``POINTS`` after ``mdot``, :func:`evtms.benches.coil.march_inputs`)
        and ``(tube, condenser, moist, sat_T, sat_h, sat_w)`` (the march's tube array, its mode
        and the saturated-air curve); or the WCC's heating-loop coolant flow [kg/s] and inlet
        temperature [K] ``(n, 2)`` and its :func:`evtms.benches.wcc.kernel_constants` but the
        refrigerant tables.
    branch_in, branch
        The evaporating branch per point and its constants: an evaporator coil's air
        ``(n, 7)`` and constants as the condenser's; or the plate chiller's coolant flow [kg/s]
        and inlet temperature [K] ``(n, 2)`` and ``(geo, cool, T_freeze, T_max, p_triple,
        curve_p_min, gauss, p_crit)`` (:func:`evtms.benches.chiller.kernel_constants`).
    tables : tuple
        The refrigerant tables (:attr:`evtms.fluid_tables.PropertyTables.arrays`).
    ops, sat, tol, out
        As :func:`evtms.cycle._closure_kernel.solve_points` takes them.
    mem : tuple
        The kernel's memory between calls (:func:`memory`, new for each batch).
    answer : (4,) float64
        The caller's evaluation, where the kernel asked for one: the three values it reads (as
        ``_ROWS`` orders them) and 1 where no heat flows (-1: the point is handed back).
    """
    v, so, si, dyn, wait, point, at = mem
    n = ops.shape[1]
    r = np.empty(3)
    row_c = np.empty(len(COMPRESSOR_COLUMNS))
    row_m = np.empty(len(COIL_COLUMNS))
    row_k = np.empty(len(PLATE_COLUMNS))
    row_w = np.empty(len(WCC_COLUMNS))
    pt = np.empty(len(COIL_POINTS))
    if at[1] > 0:  # the caller's answer to the evaluation asked for
        at[1] = 0
        if answer[3] < 0:  # the caller hands the point back
            out[:, point[0]] = np.nan
            out[5, point[0]] = 0.0
            point[0] = -1
        else:
            r[0], r[1], r[2] = answer[0], answer[1], answer[2]
            _take_result(r, answer[3] > 0, _ROWS, v, so, si, dyn, wait, point, 0, ops, sat, tol, out)
    while True:
        while point[0] < 0:  # the next point (a point not served leaves the slot free)
            if at[0] >= n:
                return -1
            _begin(v, so, si, dyn, wait, point, 0, at[0], ops, sat, tol, out)
            at[0] += 1
        i = point[0]
        what = wait[0]
        if what == _W_COMP:
            got = _compressor(dyn[0], speed[i], comp, tables, row_c, r)
        elif what == _W_COND:
            got = _exchanger(dyn[0], cond_in[i], cond, tables, pt, row_m, row_k, row_w, r, _M_CR)
        else:
            got = _exchanger(dyn[0], branch_in[i], branch, tables, pt, row_m, row_k, row_w, r, _M_HOC)
        if got == ASK:
            at[1] = 1
            return min(what, 2)
        none = what != _W_COMP and got == WRONG_SIDE
        _take_result(r, none, _ROWS, v, so, si, dyn, wait, point, 0, ops, sat, tol, out)


@_njit
def compressor_rows(speed, T_in, p_in, pr, c, tables):
    """The compressor bench's compiled twin at each point, as :func:`solve_points` reads it: its
    kernel's columns (``evtms.benches._compressor_kernel.COLUMNS``) and the bench's status per point
    (:data:`ASK` where its states leave the tables)."""
    n = p_in.size
    rows = np.empty((n, len(COMPRESSOR_COLUMNS)))
    codes = np.empty(n, np.int64)
    dyn, r = np.empty(5), np.empty(3)
    for i in range(n):
        dyn[1], dyn[3], dyn[4] = p_in[i], T_in[i], pr[i]
        codes[i] = _compressor(dyn, speed[i], c, tables, rows[i], r)
    return rows, codes


@_njit
def exchanger_rows(mdot, p_in, h_in, inputs, constants, tables):
    """A coil, the WCC or the chiller at each point, as :func:`solve_points` reads it: its kernel's
    columns (the coil march's, the WCC's or the chiller's ``COLUMNS``) and the bench's status per
    point (:data:`ASK`: states beyond the tables; :data:`NAN_INPUT`: a coil at a flow or pressure
    that is not finite). ``inputs`` and ``constants`` as :func:`solve_points` takes them."""
    n = p_in.size
    width = max(len(COIL_COLUMNS), len(PLATE_COLUMNS), len(WCC_COLUMNS))
    rows = np.full((n, width), np.nan)
    codes = np.empty(n, np.int64)
    dyn, r, pt = np.empty(5), np.empty(3), np.empty(len(COIL_POINTS))
    row_m, row_k, row_w = np.empty(len(COIL_COLUMNS)), np.empty(len(PLATE_COLUMNS)), np.empty(len(WCC_COLUMNS))
    for i in range(n):
        dyn[0], dyn[1], dyn[2] = mdot[i], p_in[i], h_in[i]
        row_m[:], row_k[:], row_w[:] = np.nan, np.nan, np.nan
        codes[i] = _exchanger(dyn, inputs[i], constants, tables, pt, row_m, row_k, row_w, r, _M_CR)
        _keep(rows[i], row_m, row_k, row_w, len(constants))
    return rows, codes


@_inline
def _keep(out, row_m, row_k, row_w, n_constants):
    """The row of the exchanger the constants name (a coil's six, the chiller's eight, the WCC's ten)."""
    src = row_m if n_constants == _COIL_CONSTANTS else (row_k if n_constants == _CHILLER_CONSTANTS else row_w)
    for k in range(src.size):
        out[k] = src[k]


def twin_columns(component: str) -> tuple[str, ...]:
    """The columns of ``component``'s rows in :func:`compressor_rows` and :func:`exchanger_rows`."""
    return {"compressor": COMPRESSOR_COLUMNS, "chiller": PLATE_COLUMNS, "wcc": WCC_COLUMNS}.get(component, COIL_COLUMNS)


compile_one_at_a_time(solve_points)
compile_one_at_a_time(compressor_rows)
compile_one_at_a_time(exchanger_rows)
