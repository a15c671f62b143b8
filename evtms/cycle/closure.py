"""The cycle closed on its two pressures, with the valve holding the superheat setpoint.

For a suction pressure ``p_A``, the inner closure
(:func:`solve_discharge`) finds the discharge pressure ``p_B`` at which the
condensing component (the air-cooled condenser or the WCC, the circuit's
:class:`~evtms.cycle.topology.Condensing`) reaches its outlet condition; the evaporating side from the valve
(isenthalpic, ``h_D = h_C``) to the suction then gives the outlet enthalpy,
and :func:`suction_side` its difference to the suction state at the
superheat setpoint. :func:`solve_at` finds the suction pressure where that
difference vanishes, evaluates the components once more at the root with
every output variable (:func:`final_states`) and gathers the figures of the
cycle (:func:`collect`), one flat array per result variable (the working
arrays the limits and flags of :mod:`evtms.cycle.solver` then revise).

Every solve keeps its warm starts in a :class:`~evtms.cycle.state.SolveState`
of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evtms.cycle.branches import branch, converged_drop, no_heat_flow, secondary_temperature
from evtms.cycle.roots import Bracket, bracket, pressure_root, range_status, tightest_bound
from evtms.cycle.split import EvaporatingSide, parallel, setpoint_enthalpy
from evtms.cycle.state import (
    CP_SCALE,
    FIRST_CLOSED,
    FIRST_FLOATS,
    INNER_FTOL,
    OUTER_FTOL,
    SECOND_CLOSED,
    SECOND_FLOATS,
    SLOPE_SPAN,
    WARM_OVERSHOOT,
    Ops,
    SolveContext,
    SolveState,
    WarmStart,
    take,
)
from evtms.cycle.status import (
    STATUS_CONDENSER_NO_ROOT,
    STATUS_CONVERGED,
    STATUS_EVAPORATOR_NO_ROOT,
    STATUS_EVAPORATOR_WET,
    STATUS_OUTSIDE_ENVELOPE,
    valid_status,
)
from evtms.hx.counterflow import CAPACITY_RATIO_MAX

#: Figures every valid point has finite (a closed branch's are 0; its superheat and opening may be NaN).
_MUST_BE_FINITE = ("p_A", "p_B", "mdot", "Q_evap", "Q_latent", "Q_chiller", "Q_cond", "W", "COP")

#: The suction search's low end: evaporating this far [K] below the coldest open branch's
#: secondary inlet, or at _SUCTION_LOW_FLOOR [K] where that is lower.
_SUCTION_LOW_BELOW = 45.0
_SUCTION_LOW_FLOOR = 243.15

#: Typical slopes of the closures in saturation temperature [1/K]: condenser, suction superheat.
INNER_SLOPE = -0.075
OUTER_SLOPE = -4.0
#: First guesses without a previous solution [K]: condensing this far above the condensing side's
#: secondary inlet, evaporating this far below the branch's (the middle of the default envelope).
DISCHARGE_GUESS_ABOVE = 13.0
SUCTION_GUESS_BELOW = 23.0
#: The discharge search's low end: condensing this far [K] above the condensing side's secondary inlet.
DISCHARGE_FLOOR_ABOVE = 0.5
#: Largest first secant step of each search [K], and how far a cold search overshoots it [1].
INNER_MAX_STEP = 10.0
OUTER_MAX_STEP = 15.0
COLD_OVERSHOOT = 1.5

#: Why a closure has no root in its range: (physical bound, LUT axis) texts at its low and high end,
#: the condensing side's by its component.
_CONDENSER_LOW = {
    "condenser": (
        "the condenser outlet is below its target even at the lowest discharge pressure searched",
        "the condenser outlet condition lies below the discharge pressure",
    ),
    "wcc": (
        "the water-cooled condenser outlet is below its target even at the lowest discharge pressure searched",
        "the water-cooled condenser outlet condition lies below the discharge pressure",
    ),
}
_CONDENSER_HIGH = {
    "condenser": (
        "the condenser cannot reach its outlet condition up to the highest discharge pressure searched",
        "the condenser outlet condition lies above the discharge pressure",
    ),
    # The heating loop's coolant enters too warm, or flows too little to take the heat: the refrigerant
    # would have to condense above what the compressor (pressure ratio) or the LUT (discharge pressure) reach.
    "wcc": (
        "the water-cooled condenser cannot condense the refrigerant up to the highest discharge pressure "
        "searched (the heating-loop coolant too warm, or its flow too small, to take the heat)",
        "the water-cooled condenser outlet condition (heating-loop coolant too warm or too little) lies above "
        "the discharge pressure",
    ),
}
_SUPERHEAT_LOW = (
    "the superheat stays below its setpoint even at the lowest suction pressure searched",
    "the superheat setpoint lies below the suction pressure",
)
_SUPERHEAT_HIGH = (
    "the superheat stays above its setpoint up to saturation at the secondary inlet temperature",
    "the superheat setpoint lies above the suction pressure",
)


class Scattered:
    """The latest evaluation of every point, gathered from evaluations of subsets.

    Holds a (nested) dict of per-point arrays as returned by
    :func:`discharge_side`; ``put(i, r)`` writes the results of the points ``i``.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.data: dict | None = None

    def _empty(self, r: dict) -> dict:
        out = {}
        for k, v in r.items():
            if isinstance(v, dict):
                out[k] = self._empty(v)
            elif v.dtype == object:
                out[k] = np.full(self.n, "", dtype=object)
            else:
                out[k] = np.full(self.n, np.nan)
        return out

    def _put(self, dst: dict, i: np.ndarray, r: dict) -> None:
        for k, v in r.items():
            if isinstance(v, dict):
                self._put(dst[k], i, v)
            else:
                dst[k][i] = v

    def put(self, i: np.ndarray, r: dict) -> None:
        if self.data is None:
            self.data = self._empty(r)
        self._put(self.data, i, r)

    def result(self, failed: np.ndarray, reason: np.ndarray) -> dict:
        """The gathered dict; points that ``failed`` get NaN and their ``reason``."""
        _blank(self.data, failed, reason)
        return self.data


def _blank(d: dict, failed: np.ndarray, reason: np.ndarray) -> None:
    for k, v in d.items():
        if isinstance(v, dict):
            _blank(v, failed, reason)
        elif k == "reason":
            v[failed] = reason[failed]
        else:
            v[failed] = np.nan


@dataclass(frozen=True)
class DischargeRoot:
    """The inner closure at a suction iterate: ``p_B`` [Pa], ``status``, ``reason`` per point, and
    ``side``, the discharge side (:func:`discharge_side`) at the root."""

    p_B: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    side: dict


@dataclass(frozen=True)
class SuctionEval:
    """The suction side at a suction pressure.

    Attributes
    ----------
    residual : numpy.ndarray
        Outlet enthalpy minus the suction enthalpy at the setpoint [about K], NaN where failed.
    status, reason : numpy.ndarray
        Per point.
    outlet_wet : numpy.ndarray
        The evaporating side's outlet is two-phase.
    p_B, p_D : numpy.ndarray
        Discharge pressure and the first branch's valve-outlet pressure [Pa].
    side : dict
        The discharge side (:func:`discharge_side`).
    evap : EvaporatingSide
        The evaporating side.
    """

    residual: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    outlet_wet: np.ndarray
    p_B: np.ndarray
    p_D: np.ndarray
    side: dict
    evap: EvaporatingSide


def _condensing_stage(ctx: SolveContext, ops: Ops, component: str, mdot, p_in, h_in) -> dict:
    """One condensing component at refrigerant flow ``mdot`` [kg/s], inlet ``(p_in, h_in)`` [Pa, J/kg]:
    the air-cooled condenser against the ambient air, or the WCC against its coolant loop."""
    if component == "wcc":
        return ctx.models.wcc(mdot, p_in, h_in, ops["mdot_coolant_h"], ops["T_coolant_h_in"])
    return ctx.models.condenser(mdot, ops["fan"], p_in, h_in, ops["T_amb"], ops["RH_amb"])


def condensing(ctx: SolveContext, ops: Ops, mdot, p_in, h_in) -> dict:
    """The circuit's condensing chain at refrigerant flow ``mdot`` [kg/s], inlet ``(p_in, h_in)`` [Pa, J/kg].

    One component: its result. Two in series (the WCC ahead of the condenser): the second's
    result at the first's outlet, with ``Q_first`` [W], the heat the first takes. Where the
    first condenses the refrigerant to liquid on its own (its capacity ratio 1 or more), the
    chain holds more area than it needs whatever the second does: its ``capacity_ratio`` is
    then the largest the models give (:data:`evtms.hx.counterflow.CAPACITY_RATIO_MAX`, a liquid
    inlet's), so that the closure's residual keeps falling with the discharge pressure. A
    first component on a coolant warmer than the saturation only desuperheats (its capacity
    ratio 0); one on a coolant not colder than the refrigerant entering takes no heat (its
    bench's wrong-side status) and passes the refrigerant on as it came, as a closed branch
    does (:func:`evtms.cycle.branches.branch`).
    """
    chain = ctx.circuit.chain
    first = _condensing_stage(ctx, ops, chain[0].component, mdot, p_in, h_in)
    if len(chain) == 1:
        return first
    idle = no_heat_flow(first) & np.isfinite(np.asarray(h_in, float))
    if idle.any():
        first = dict(first)
        for key, through in (("p_out", p_in), ("h_out", h_in), ("capacity_ratio", 0.0), ("reason", "")):
            first[key] = np.where(idle, through, first[key])
    # The first's outlet is the second's inlet; a liquid outlet gives the second a liquid inlet.
    second = _condensing_stage(ctx, ops, chain[1].component, mdot, first["p_out"], first["h_out"])
    out = dict(second)
    done = first["capacity_ratio"] >= 1.0
    out["capacity_ratio"] = np.where(done, CAPACITY_RATIO_MAX, second["capacity_ratio"])
    # The condenser may refuse a liquid inlet colder than its air: there the WCC's outlet is the chain's.
    for key in ("p_out", "h_out_continued"):
        if key in second:
            out[key] = np.where(done & ~np.isfinite(second[key]), first[key], second[key])
    out["no_heat_flow"] = ~done & np.asarray(second.get("no_heat_flow", False))
    out["Q_first"] = mdot * (h_in - first["h_out"])
    out["reason"] = np.where(first["reason"] != "", first["reason"], np.where(done, "", second["reason"]))
    return out


def condensing_secondary(ctx: SolveContext, ops: Ops) -> np.ndarray:
    """The secondary inlet temperature [K] the refrigerant must condense above (ambient air, a
    coolant loop): that of the chain's last component, whose outlet the receiver holds. A
    component ahead of it may meet a warmer secondary and then only desuperheat (a WCC on an
    e-drive loop warmer than the air)."""
    return ops[ctx.circuit.condensing.secondary_temperature]


def discharge_side(ctx: SolveContext, ops: Ops, p_A: np.ndarray, p_B: np.ndarray) -> dict:
    """Compressor and condensing component at ``(p_A, p_B)`` [Pa], and its closure's residual [1].

    Returns ``T_A`` [K], ``comp`` and ``cond`` (the models' results), ``residual`` (falls as
    ``p_B`` rises) and ``reason``.
    """
    sat = ctx.sat
    T_A = sat.temperature(p_A) + ops["superheat"]
    comp = ctx.models.compressor(ops["speed"], T_A, p_A, p_B / p_A)
    cond = condensing(ctx, ops, comp["mdot"], p_B, comp["h_out"])
    # Target quality of a liquid subcooled by `subcooling` below saturation.
    p_C = cond["p_out"]
    h_l, h_v = sat.liquid_enthalpy(p_C), sat.vapour_enthalpy(p_C)
    x_target = -sat.liquid_cp(p_C) * ops["subcooling"] / (h_v - h_l)
    # Saturated-liquid outlet: the capacity ratio (coil over the coil needed to
    # condense fully) is smooth where x_out has its kink, exactly at this target.
    residual = 1.0 - cond["capacity_ratio"]
    if "h_out_continued" in cond:  # present whenever some point targets a subcooled outlet
        x_out = (cond["h_out_continued"] - h_l) / (h_v - h_l)
        residual = np.where(ops["subcooling"] > 0, x_out - x_target, residual)
    # Refrigerant not warmer than the air (a saturation not above the WCC's coolant) condenses
    # nothing: far above the target.
    residual = np.where(no_heat_flow(cond) & np.isfinite(comp["mdot"]), 1.0, residual)
    reason = np.where(comp["reason"] != "", comp["reason"], cond["reason"])
    return {"T_A": T_A, "comp": comp, "cond": cond, "residual": residual, "reason": reason}


def solve_discharge(ctx: SolveContext, state: SolveState, ops: Ops, p_A: np.ndarray, idx: np.ndarray) -> DischargeRoot:
    """Discharge pressure p_B [Pa] for each suction pressure ``p_A`` [Pa]: the condenser-outlet condition.

    ``idx`` are the points' indices in the whole batch. The first guess is
    the root at the previous suction iterate, with the slope found there
    (``state``); without one, condensing 13 K above the condensing side's
    secondary inlet (the ambient air, the heating loop's coolant; the middle
    of the default circuit's envelope). The side returned is the
    solver's last evaluation at the root, not a new one.
    """
    sat = ctx.sat
    n = p_A.size
    lo, lo_axis, hi, hi_axis = _discharge_range(ctx, state, ops, p_A)
    last = Scattered(n)

    def residual(pb, i):
        r = discharge_side(ctx, take(ops, i), p_A[i], pb)
        last.put(i, r)
        return r["residual"], r["reason"]

    known = np.isfinite(state.p_B[idx])
    t_guess = np.where(known, sat.temperature(state.p_B[idx]), condensing_secondary(ctx, ops) + DISCHARGE_GUESS_ABOVE)
    slope = np.where(known & (state.slope[idx] < 0), state.slope[idx], INNER_SLOPE)
    if state.warm:
        t_guess = _extrapolated_discharge(state, sat.temperature(p_A), idx, t_guess)
    br = bracket(
        sat,
        residual,
        sat.temperature(lo),
        sat.temperature(hi),
        t_guess,
        slope,
        INNER_MAX_STEP,
        WARM_OVERSHOOT if state.warm else COLD_OVERSHOOT,
        INNER_FTOL if state.warm else None,
    )
    state.slope[idx] = np.where(br.slope < 0, br.slope, state.slope[idx])
    component = ctx.circuit.condensing.component
    status, reason = range_status(
        br, lo, lo_axis, hi, hi_axis, STATUS_CONDENSER_NO_ROOT, _CONDENSER_LOW[component], _CONDENSER_HIGH[component]
    )
    status[~np.isfinite(p_A)] = STATUS_OUTSIDE_ENVELOPE
    p_B = np.full(n, np.nan)
    todo = _found_at_a_guess(sat, br, status, p_B)
    if todo.size:
        p_B[todo] = pressure_root(sat, residual, br, todo, INNER_FTOL, status, reason, "discharge-pressure")
    failed = status != STATUS_CONVERGED
    p_B[failed] = np.nan
    if state.warm:
        ok = idx[~failed]
        state.t_pairs[1, :, ok] = state.t_pairs[0, :, ok]
        state.t_pairs[0, 0, ok], state.t_pairs[0, 1, ok] = sat.temperature(p_A[~failed]), sat.temperature(p_B[~failed])
    if last.data is None:  # nothing evaluated (no valid suction pressure)
        side = discharge_side(ctx, ops, p_A, p_B)
    else:  # each converged point's last evaluation was at its root
        side = last.result(failed, reason)
    return DischargeRoot(p_B, status, reason, side)


def _found_at_a_guess(sat, br: Bracket, status: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The roots [Pa] a bracket's guess points hit within the tolerance, into ``p``; returns the
    converged points left to search."""
    todo = np.nonzero(status == STATUS_CONVERGED)[0]
    if br.found is None or not br.found[todo].any():
        return todo
    hit = todo[br.found[todo]]
    p[hit] = sat.pressure(br.lo[hit])
    return todo[~br.found[todo]]


def _extrapolated_discharge(state: SolveState, t_A: np.ndarray, idx: np.ndarray, t_guess: np.ndarray) -> np.ndarray:
    """First guess of the discharge saturation temperature [K] at suction saturation ``t_A`` [K]:
    linear in ``t_A`` through the two latest suction iterates' roots (``state.t_pairs``), by at
    most 2 K from the latest; ``t_guess`` where there are not two."""
    (a1, b1), (a0, b0) = state.t_pairs[0][:, idx], state.t_pairs[1][:, idx]
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (b1 - b0) / (a1 - a0)
        t = b1 + np.clip(slope * (t_A - a1), -2.0, 2.0)
    use = np.isfinite(t) & (np.abs(a1 - a0) > 1e-9)
    return np.where(use, t, t_guess)


def _discharge_range(ctx: SolveContext, state: SolveState, ops: Ops, p_A: np.ndarray) -> tuple:
    """The discharge pressures searched [Pa]: from saturation just above the condensing side's secondary
    inlet (ambient air, heating-loop coolant) and the models' lower ends to their upper ends;
    ``(lo, lo_axis, hi, hi_axis)`` (the axes as :func:`tightest_bound`)."""
    (pr_lo, pr_hi), axes = state.pr, state.axes
    lo, lo_axis = tightest_bound(
        [
            (ctx.sat.pressure(condensing_secondary(ctx, ops) + DISCHARGE_FLOOR_ABOVE), None),
            (pr_lo * p_A, axes["pr"][0]),
            (state.p_discharge[0], axes["p_discharge"][0]),
        ],
        upper=False,
    )
    hi, hi_axis = tightest_bound(
        [(state.p_discharge[1], axes["p_discharge"][1]), (pr_hi * p_A, axes["pr"][1])], upper=True
    )
    return lo, lo_axis, hi, hi_axis


def suction_side(
    ctx: SolveContext, state: SolveState, ops: Ops, p_A: np.ndarray, idx: np.ndarray, final: bool = False
) -> SuctionEval:
    """Superheat residual at suction pressure ``p_A`` [Pa] (with the inner discharge solve).

    ``idx`` are the points' indices in the whole batch, for the warm start
    of the discharge pressure from the previous suction iterate. With
    ``final``, p_A is each point's root, the suction iterate last
    evaluated: the components are evaluated once more (with every output
    variable) at that iterate's discharge and evaporator-inlet pressures,
    without solving again.
    """
    if final:
        p_B = state.p_B[idx]
        side = discharge_side(ctx, ops, p_A, p_B)
        dis_status = np.full(p_A.size, STATUS_CONVERGED, np.int8)
        dis_status[~np.isfinite(p_B)] = STATUS_OUTSIDE_ENVELOPE
        dis_reason = side["reason"]
    else:
        dis = solve_discharge(ctx, state, ops, p_A, idx)
        state.p_B[idx] = np.where(np.isfinite(dis.p_B), dis.p_B, state.p_B[idx])
        p_B, side, dis_status, dis_reason = dis.p_B, dis.side, dis.status, dis.reason
    comp, cond = side["comp"], side["cond"]
    h_D = ctx.sat.liquid_enthalpy(cond["p_out"])
    if "h_out_continued" in cond:
        h_D = np.where(ops["subcooling"] <= 0, h_D, cond["h_out_continued"])
    evap = _evaporating_side(ctx, state, ops, comp["mdot"], p_A, p_B, h_D, idx, final)
    # The valve holds the outlet at the superheat setpoint, i.e. at the compressor's
    # suction state A. The residual compares enthalpies (scaled to about kelvin):
    # interpolated outlet enthalpy stays smooth where the LUT's outlet temperature
    # has its kink (outlet turning two-phase), and matching it keeps the cycle's
    # energy balance.
    sh = (evap.h_out - comp["h_in"]) / CP_SCALE
    # An inlet not colder than the air evaporates nothing: the outlet stays at h_D.
    sh = np.where(evap.no_heat_flow & np.isfinite(h_D), (h_D - comp["h_in"]) / CP_SCALE, sh)
    status = dis_status.copy()
    reason = dis_reason.copy()
    bad = (status == STATUS_CONVERGED) & ~np.isfinite(sh)
    status[bad] = STATUS_OUTSIDE_ENVELOPE
    reason[bad] = np.where(side["reason"][bad] != "", side["reason"][bad], evap.reason[bad])
    residual = np.where(status == STATUS_CONVERGED, sh, np.nan)
    # A two-phase outlet: below saturated vapour (h_out_continued has no kink there).
    outlet_wet = evap.h_out < ctx.sat.vapour_enthalpy(evap.p_out)
    return SuctionEval(residual, status, reason, outlet_wet, p_B, evap.p_D, side, evap)


def _evaporating_side(
    ctx: SolveContext, state: SolveState, ops: Ops, mdot, p_A, p_B, h_D, idx, final
) -> EvaporatingSide:
    """The branches from the valve at ``h_D`` [J/kg] to the suction at ``p_A`` [Pa], at flow ``mdot``.

    A branch's inlet is the outlet pressure plus its own drop: a fixed point,
    warm-started from the drop at the previous suction iterate (the drop
    changes slowly), solved again unless ``final``.
    """
    if ctx.parallel:
        h_set = setpoint_enthalpy(ctx, ops, p_A, p_B)
        return parallel(ctx, state, ops, mdot, p_A, h_D, idx, final, h_set)
    c = ctx.names[0]
    if not final:
        state.dp[idx] = converged_drop(ctx, c, ops, mdot, p_A, h_D, state.dp[idx])
    p_D = p_A + state.dp[idx]
    r = branch(ctx, c, ops, mdot, p_D, h_D)
    return EvaporatingSide(
        h_out=r["h_out_continued"],
        p_out=r["p_out"],
        reason=r["reason"],
        p_D=p_D,
        no_heat_flow=no_heat_flow(r),
        branches={c: r},
        flows={c: mdot},
        inlets={c: p_D},
    )


def suction_limits(ctx: SolveContext, ops: Ops, limits: dict) -> list[tuple[np.ndarray, dict]]:
    """The models' suction-pressure ranges per group of points: a closed branch's model does not
    bound the suction (a hot cabin alone may evaporate above the chiller LUT's last pressure)."""
    n = ops["speed"].size
    mode = np.asarray(ops.get("branch_mode", np.zeros(n)), int)
    if not ctx.parallel or not np.isin(mode, (FIRST_CLOSED, SECOND_CLOSED)).any():
        return [(np.ones(n, bool), limits)]
    names = ctx.names
    return [
        (~np.isin(mode, (FIRST_CLOSED, SECOND_CLOSED)), limits),
        (mode == FIRST_CLOSED, ctx.models.limits(exclude=(names[0],))),
        (mode == SECOND_CLOSED, ctx.models.limits(exclude=(names[1],))),
    ]


def _suction_range(ctx: SolveContext, ops: Ops, limits: dict, T_sec: np.ndarray) -> tuple:
    """The suction pressures searched [Pa], ``(lo, lo_axis, hi, hi_axis)``: up to saturation 0.5 K
    below the coldest open branch's secondary inlet ``T_sec`` [K], within the models' ranges.

    The low end: evaporating 45 K below the (coldest) secondary stream, which leaves a large
    superheat, or at -30 degC where that is lower. Against hot coolant a starved branch runs
    further below it (valve at its maximum, full speed, coolant at 45 degC: -1 degC at the
    outlet, 46 K below), which a bound relative to the stream alone cut off.
    """
    sat = ctx.sat
    floor = np.minimum(T_sec - _SUCTION_LOW_BELOW, _SUCTION_LOW_FLOOR)
    # Not below the saturation table (its pressure would be NaN, and the search with it).
    floor = np.maximum(floor, sat.T[0] + 0.01)
    lows, highs = [(sat.pressure(floor), None)], [(sat.pressure(T_sec - 0.5), None)]
    for where, lim in suction_limits(ctx, ops, limits):
        (p_lo_lim, p_hi_lim), (lo_name, hi_name) = lim["p_suction"], lim["axes"]["p_suction"]
        lows.append((np.where(where, p_lo_lim * (1 + 1e-9), -np.inf), lo_name))
        highs.append((np.where(where, p_hi_lim * (1 - 1e-9), np.inf), hi_name))
    lo, lo_axis = tightest_bound(lows, upper=False)
    hi, hi_axis = tightest_bound(highs, upper=True)
    return lo, lo_axis, hi, hi_axis


def suction_guess(
    t_guess: np.ndarray, outer_slope: np.ndarray | float, warm: WarmStart | None, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """The suction search's first guess [K] and slope [1/K] of ``n`` points: ``warm``'s root and the
    closure's local slope there where it has them (a previous solve's solution), else the given ones."""
    slopes = np.broadcast_to(np.asarray(outer_slope, float), (n,))
    if warm is not None:
        t_guess = np.where(np.isfinite(warm.t_A), warm.t_A, t_guess)
        slopes = np.where(warm.outer_slope < 0, warm.outer_slope, slopes)
    return t_guess, slopes


def solve_at(
    ctx: SolveContext,
    ops: Ops,
    t_guess: np.ndarray | None = None,
    p_B_guess: np.ndarray | None = None,
    dp_guess: np.ndarray | None = None,
    outer_slope: np.ndarray | float = OUTER_SLOPE,
    warm: WarmStart | None = None,
) -> tuple[dict[str, np.ndarray], SolveState]:
    """The cycle with the evaporator-outlet superheat at ``ops["superheat"]`` (the valve not limited).

    ``t_guess`` [K] is the first guess of the suction saturation
    temperature (default 23 K below the cabin air), ``p_B_guess`` [Pa]
    that of the discharge pressure (default condensing 13 K above the
    ambient air) and ``dp_guess`` [Pa] that of the evaporator's pressure
    drop (default 0; its fixed point takes one pass per suction iterate,
    so a warm start whose root takes few iterates needs a good one).
    ``warm``, a previous solve's solution at nearby points, replaces
    these guesses where it has one (and gives the closures' slopes and a
    parallel split to start from); the roots are the same to within the
    closures' tolerances, only found in fewer iterates.
    Returns the working arrays of :func:`collect` (statuses 0-4 and 8, no
    flags; ``valve_opening`` the opening that passes the cycle's flow,
    whatever its maximum) and the solve's state after its last iterate.
    """
    n = ops["speed"].size
    limits = ctx.models.limits()
    T_sec = secondary_temperature(ctx, ops)
    lo, lo_axis, hi, hi_axis = _suction_range(ctx, ops, limits, T_sec)
    state = SolveState.start(n, limits, ctx.names, p_B_guess, dp_guess, warm)
    ctx.models.subcooled_targets(bool(np.any(ops["subcooling"] > 0)))
    ctx.models.detailed(False)  # the iterations' variables; final_states asks for every one
    # The status each failure reason came with (the discharge side's own: a condenser that
    # cannot reach its outlet at any discharge pressure is not the end of a model's envelope).
    failure_status: dict[str, int] = {}

    # Each point's latest suction iterate, for the closure's local slope (state.outer_slope).
    latest_t, latest_f = np.full(n, np.nan), np.full(n, np.nan)

    def residual(pa, i):
        r = suction_side(ctx, state, take(ops, i), pa, i)
        failed = (r.status != STATUS_CONVERGED) & (r.reason != "")
        failure_status.update(zip(r.reason[failed], r.status[failed].tolist(), strict=True))
        t = ctx.sat.temperature(pa)
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = (r.residual - latest_f[i]) / (t - latest_t[i])
        moved = np.isfinite(slope) & (slope < 0) & (np.abs(t - latest_t[i]) > SLOPE_SPAN)
        state.outer_slope[i[moved]] = slope[moved]
        seen = np.isfinite(r.residual)
        latest_t[i[seen]], latest_f[i[seen]] = t[seen], r.residual[seen]
        return r.residual, r.reason

    # First guess: evaporating 23 K below the cabin air, the middle of the default
    # circuit's envelope; the superheat falls about 4 K per kelvin above it.
    cold = T_sec - SUCTION_GUESS_BELOW
    t_guess = cold if t_guess is None else np.where(np.isfinite(t_guess), t_guess, cold)
    t_guess, slopes = suction_guess(t_guess, outer_slope, warm, n)
    br = bracket(
        ctx.sat,
        residual,
        ctx.sat.temperature(lo),
        ctx.sat.temperature(hi),
        t_guess,
        slopes,
        OUTER_MAX_STEP,
        WARM_OVERSHOOT if state.warm else COLD_OVERSHOOT,
        OUTER_FTOL if state.warm else None,
    )
    status, reason = range_status(
        br, lo, lo_axis, hi, hi_axis, STATUS_EVAPORATOR_NO_ROOT, _SUPERHEAT_LOW, _SUPERHEAT_HIGH
    )
    _tell_no_root_apart(ctx, state, ops, br, lo, status, reason, failure_status)
    p_A = np.full(n, np.nan)
    idx = _found_at_a_guess(ctx.sat, br, status, p_A)
    if idx.size:
        p_A[idx] = pressure_root(
            ctx.sat, residual, br, idx, OUTER_FTOL, status, reason, "suction-pressure", failure_status
        )
    p_A[status != STATUS_CONVERGED] = np.nan
    return final_states(ctx, state, ops, p_A, status, reason), state


def _tell_no_root_apart(
    ctx: SolveContext, state: SolveState, ops: Ops, br: Bracket, lo, status, reason, failure_status: dict
) -> None:
    """Points whose suction bracket ``br`` holds no root, told apart (``status``, ``reason`` in place).

    Superheat above its setpoint up to the physical top (saturation 0.5 K below the coldest
    secondary inlet): with branches in parallel, the one on that stream caps the search
    (``state.above_top``). Superheat below its setpoint down to the physical low end ``lo`` [Pa]
    (evaporating 45 K below the secondary, or at -30 degC): where the outlet is still two-phase
    there, the evaporator floods (status 8). Both ends outside a model's envelope: nothing to go
    on (the status its reason came with, ``failure_status``).
    """
    no_root = status == STATUS_EVAPORATOR_NO_ROOT
    state.above_top = no_root & br.hi_is_end & np.isfinite(br.f_hi) & (br.f_hi >= 0)
    low = np.nonzero(no_root & br.lo_is_end & np.isfinite(br.f_lo) & (br.f_lo <= 0))[0]
    if low.size:
        wet = suction_side(ctx, state, take(ops, low), lo[low], low).outlet_wet
        status[low[wet]] = STATUS_EVAPORATOR_WET
        reason[low[wet]] = (
            "the evaporator outlet stays two-phase down to the lowest suction pressure searched "
            "(evaporating 45 K below the secondary inlet, or at -30 degC): the evaporator floods and "
            "the compressor would draw liquid"
        )
    both = ~np.isfinite(br.f_lo) & ~np.isfinite(br.f_hi) & (status == STATUS_CONVERGED)
    reason[both] = np.where(br.why_lo[both] != "", br.why_lo[both], br.why_hi[both])
    status[both] = [failure_status.get(x, STATUS_OUTSIDE_ENVELOPE) for x in reason[both]]


def final_states(ctx: SolveContext, state: SolveState, ops: Ops, p_A, status, reason) -> dict[str, np.ndarray]:
    """The components at the suction roots ``p_A`` [Pa] with every output variable, gathered."""
    ctx.models.detailed(True)
    try:
        fin = suction_side(ctx, state, ops, p_A, np.arange(p_A.size), final=True)
        return collect(ctx, ops, p_A, status, reason, fin)
    finally:
        ctx.models.detailed(False)


def collect(ctx: SolveContext, ops: Ops, p_A, status: np.ndarray, reason: np.ndarray, fin: SuctionEval) -> dict:
    """The cycle's figures at the final evaluation ``fin``, one float array per result variable in
    :data:`evtms.cycle.results.RESULT_KEYS` order (NaN where a point is not solved), and
    ``status``, ``reason`` (revised in place where the final evaluation failed)."""
    late = (status == STATUS_CONVERGED) & (fin.status != STATUS_CONVERGED)
    status[late] = fin.status[late]
    reason[late] = fin.reason[late]
    cond, evap = fin.side["cond"], fin.evap
    p_C, T_C, h_C = _liquid_line(ctx, ops, cond)
    res = _figures(ctx, ops, p_A, fin, p_C, T_C, h_C)
    # A valid point carries finite figures. A root can sit on a jump of its residual where a
    # component gives no heat (a LUT cell next to nodes with the refrigerant on the wrong side
    # of its secondary stream, or the bench's own edge): its figures are then not a state.
    no_heat = np.broadcast_to(no_heat_flow(cond), p_A.shape).copy()
    for c in ctx.names:
        no_heat |= no_heat_flow(evap.branches[c]) & (np.asarray(evap.flows[c]) > 0)
    finite = np.logical_and.reduce([np.isfinite(np.asarray(res[k], float)) for k in _MUST_BE_FINITE])
    broken = valid_status(status) & (no_heat | ~finite)
    status[broken] = STATUS_OUTSIDE_ENVELOPE
    reason[broken] = np.where(
        no_heat[broken],
        "the solution lies where a component takes no heat (its refrigerant inlet on the wrong side "
        "of its secondary stream, or a LUT cell next to such nodes)",
        "a component model gives NaN at the solved state",
    )
    invalid = ~valid_status(status)
    for k, v in res.items():
        v = np.array(v, float)
        v[invalid] = np.nan
        res[k] = v
    res["status"] = status
    res["reason"] = reason
    return res


def _liquid_line(ctx: SolveContext, ops: Ops, cond: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State C, the condenser outlet: ``(p_C, T_C, h_C)`` [Pa, K, J/kg].

    With a saturated-liquid outlet it is that condition at the LUT's outlet
    pressure (the LUT's own h_out has its kink exactly there); a subcooled
    liquid is T_sat minus its enthalpy below saturation over the liquid's cp,
    as its target was set.
    """
    sat = ctx.sat
    p_C = cond["p_out"]
    saturated = ops["subcooling"] <= 0
    h_l, T_sat = sat.liquid_enthalpy(p_C), sat.temperature(p_C)
    h_C = np.where(saturated, h_l, cond["h_out_continued"])
    T_C = np.where(saturated, T_sat, T_sat - (h_l - h_C) / sat.liquid_cp(p_C))
    return p_C, T_C, h_C


def _figures(ctx: SolveContext, ops: Ops, p_A, fin: SuctionEval, p_C, T_C, h_C) -> dict:
    """The result variables (:data:`evtms.cycle.results.RESULT_KEYS` but ``status``, ``reason``)
    at the final evaluation ``fin``, before the invalid points are blanked."""
    sat, names = ctx.sat, ctx.names
    comp, evap = fin.side["comp"], fin.evap
    branches, flows, inlets = evap.branches, evap.flows, evap.inlets
    mdot = comp["mdot"]
    zero = np.zeros(p_A.size)
    # The opening (over the nominal) that passes a branch's flow at its valve drop, by
    # the valve's orifice law for a liquid inlet, mdot = S sqrt(2 rho_in dp); a
    # subcooled liquid's density is the saturated liquid's at its temperature.
    _, area = ctx.models.valve()
    rho_C = sat.liquid_density(np.where(ops["subcooling"] <= 0, p_C, sat.pressure(T_C)))
    opening = {}
    with np.errstate(invalid="ignore", divide="ignore"):
        for c in names:
            opening[c] = flows[c] / (area * np.sqrt(2.0 * rho_C * (p_C - inlets[c])))
    # Heat flows as each branch's flow times its enthalpy change, the outlet from its own model.
    heat = {c: 0.0 - flows[c] * (branches[c]["h_out_continued"] - h_C) for c in names}
    h_B = comp["h_out"]
    superheat = branch_superheats(ctx, ops, p_A, fin.p_B, comp, evap)
    evaporator = branches.get("evaporator", {})
    res = {
        "p_A": p_A,
        "T_A": fin.side["T_A"],
        "h_A": comp["h_in"],
        "p_B": fin.p_B,
        "T_B": comp["T_out"],
        "h_B": h_B,
        "p_C": p_C,
        "T_C": T_C,
        "h_C": h_C,
        "p_D": fin.p_D,
        "T_D": sat.temperature(fin.p_D),
        "h_D": h_C.copy(),
        "mdot": mdot,
        "mdot_evap": flows.get("evaporator", zero),
        "mdot_chiller": flows.get("chiller", zero),
        "Q_evap": heat.get("evaporator", zero),
        "Q_latent": evaporator["Q_latent"] if "evaporator" in branches else zero,
        "Q_chiller": heat.get("chiller", zero),
        "Q_cond": mdot * (h_B - h_C),
        "Q_wcc": _wcc_heat(ctx, fin.side["cond"], mdot * (h_B - h_C), zero),
        "W": comp["W"],
        "W_fluid": mdot * (h_B - comp["h_in"]),
        "h_A_evap": evap.h_out,
        "dp_valve": p_C - fin.p_D,
        "valve_opening": opening[names[0]],
        "valve_opening_chiller": opening.get("chiller", np.full(p_A.size, np.nan)),
        "superheat_actual": superheat[names[0]],
        "superheat_chiller": superheat.get("chiller", np.full(p_A.size, np.nan)),
        "frost_risk": evaporator.get("frost_risk", zero) if "evaporator" in branches else zero,
    }
    with np.errstate(invalid="ignore", divide="ignore"):
        res["COP"] = -(res["Q_evap"] + res["Q_chiller"]) / res["W"]
        res["COP_heating"] = res["Q_cond"] / res["W"]
    return res


def _wcc_heat(ctx: SolveContext, cond: dict, Q_cond: np.ndarray, zero: np.ndarray) -> np.ndarray:
    """The heat the WCC gives its coolant [W]: all of ``Q_cond`` where it condenses alone (hp), its
    share ahead of the condenser (cabin+wcc), 0 in a circuit without it."""
    chain = [c.component for c in ctx.circuit.chain]
    if "wcc" not in chain:
        return zero
    return Q_cond if len(chain) == 1 else cond["Q_first"]


def branch_superheats(ctx: SolveContext, ops: Ops, p_A, p_B, comp: dict, evap: EvaporatingSide) -> dict:
    """Each branch's outlet superheat [K]: the setpoint, the suction superheat for a branch alone
    (or the only open one), NaN for a closed one, and a floating parallel branch's from its outlet
    enthalpy (:func:`_superheat_of_enthalpy`)."""
    names = ctx.names
    if not ctx.parallel:
        return {names[0]: ops["superheat"].copy()}
    mode, suction, setpoint = ops["branch_mode"], ops["superheat"], ops["setpoint"]
    out = {c: setpoint.copy() for c in names}
    for b, (closed, floats) in enumerate(((FIRST_CLOSED, FIRST_FLOATS), (SECOND_CLOSED, SECOND_FLOATS))):
        other = names[1 - b]
        out[names[b]][mode == closed] = np.nan
        out[other][mode == closed] = suction[mode == closed]
        k = np.nonzero(mode == floats)[0]
        if k.size:
            target = evap.branches[names[b]]["h_out_continued"][k]
            out[names[b]][k] = _superheat_of_enthalpy(ctx, ops, k, p_A, p_B, target, comp, evap)
    return out


def _superheat_of_enthalpy(ctx: SolveContext, ops: Ops, k, p_A, p_B, target, comp: dict, evap) -> np.ndarray:
    """The superheat [K] at ``p_A`` whose enthalpy is ``target`` [J/kg] (a floating branch's outlet)
    for the points ``k``: the secant method on the compressor's inlet enthalpy h(T), from the
    setpoint and the suction superheat, within 1e-3 K."""
    T_sat = ctx.sat.temperature(p_A[k])
    pr = p_B[k] / p_A[k]

    def h(sh):
        return ctx.models.compressor(ops["speed"][k], T_sat + sh, p_A[k], pr)["h_in"]

    x0, y0 = ops["setpoint"][k], evap.h_set[k]
    x1, y1 = ops["superheat"][k].copy(), comp["h_in"][k]
    near = np.abs(x1 - x0) < 1e-6
    if near.any():  # one point only: about 1 kJ/(kg K)
        x1 = np.where(near, x0 + (target - y0) / CP_SCALE, x1)
        y1 = np.where(near, h(x1), y1)
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(4):
            x2 = x1 + (target - y1) * (x1 - x0) / (y1 - y0)
            x2 = np.where(np.isfinite(x2), x2, x1)
            if np.all(~np.isfinite(x2) | (np.abs(x2 - x1) < 1e-3)):
                x1 = x2
                break
            x0, y0, x1, y1 = x1, y1, x2, h(x2)
    return x1
