"""Two valves in parallel at the limits of their stroke: closed, or at their maximum opening.

Two thermostatic valves in parallel each act on their own branch's outlet
superheat; the compressor sets the common suction pressure. A valve that
reaches a limit of its stroke stops holding its setpoint while the other one
keeps holding its own. :func:`parallel_limits` solves such points again
(``ops["branch_mode"]``, :mod:`evtms.cycle.state`):

- closed: a branch whose secondary stream is barely warmer than the suction
  saturation plus the setpoint (coolant at 20 degC against evaporation at
  12 degC and a 10 K setpoint) cannot superheat its refrigerant by the
  setpoint at any flow, and the split finds the branch below the least flow
  its model covers (the chiller's ``mdot`` axis starts at 1 g/s, the
  evaporator's at 3 g/s). The valve's bulb then sees less than its static
  superheat and the valve closes: that branch carries no flow and no heat,
  and the circuit runs on the other branch alone (its valve holding the
  setpoint, or saturated as below), with status 10
  ``converged_branch_valve_closed`` (5-7 where those notes apply; the reason
  names the closed branch, ``mdot_evap`` or ``mdot_chiller`` is 0 and its
  valve opening 0). We chose the closed valve over pinning the branch at its
  model's least flow: at that flow its outlet would be below the setpoint
  (two-phase or nearly), which no TXV lets through in steady state, and the
  mixed suction state would be wrong; a real valve in that state modulates
  near its seat with a bleed below the least flow, whose duty (below that
  flow times the enthalpy rise, about 0.15 kW for the chiller, 0.45 kW for
  the evaporator) is dropped. At the solved point the closed branch is
  evaluated at its least flow: where it would leave above the setpoint
  superheat there (the suction pressure fell once it closed), its valve would
  open a little and the true flow lies between 0 and that least flow; the
  point stays valid and its reason says "nearly closed", with the bound of
  the duty left out. The same holds where, with the other valve saturated,
  the branch holding the setpoint would need less than its least flow: it
  closes and the saturated branch runs alone. And where, with both valves
  holding, the outlets are still above the setpoint at the top of the
  suction pressures searched (saturation 0.5 K below the colder secondary
  inlet, which no open branch may evaporate above), the suction would rise
  past that stream's temperature: the branch on it cannot evaporate, its
  valve closes, and the other branch alone sets the suction (coolant at
  22 degC against a 35 degC cabin at low speed evaporates at 24 degC with the
  chiller closed).
- saturated: a valve that would need more than its maximum opening sits at
  it, and its branch's superheat floats above the setpoint while the other
  branch holds the setpoint (the split is solved with the other outlet at the
  setpoint, :mod:`evtms.cycle.split`). The suction state is the outlets'
  mixture, with its own superheat, found as for a single branch
  (:mod:`evtms.cycle.saturation`) so that the saturated valve passes its
  branch's flow at its maximum opening. Status 5 (7 with frost risk);
  ``superheat_actual`` (the first branch) or ``superheat_chiller`` is the
  floating superheat. Where both valves would need more than their maximum
  (or the other one would, once the first floats), the point stays invalid
  (status 9).

Every valid point's suction state must be the branches' mixture to within
:data:`~evtms.cycle.state.MIX_TOL` (the energy balance closes on it); one
where the suction closure stopped on a jump of the mixture is status 4
(checked by :mod:`evtms.cycle.solver`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evtms.cycle.branches import branch, converged_drop
from evtms.cycle.compiled import solve_closure
from evtms.cycle.results import mark_invalid
from evtms.cycle.saturation import float_superheat
from evtms.cycle.state import (
    BOTH_HOLD,
    CLAMP_FIRST_LEAST,
    CLAMP_SECOND_LEAST,
    CP_SCALE,
    FIRST_CLOSED,
    FIRST_FLOATS,
    OUTER_FTOL,
    SECOND_CLOSED,
    SECOND_FLOATS,
    Ops,
    SolveContext,
    SolveState,
    WarmStart,
    take,
)
from evtms.cycle.status import (
    STATUS_BRANCH_VALVE_SATURATED,
    STATUS_CONVERGED,
    STATUS_NOT_CONVERGED,
    STATUS_OUTSIDE_ENVELOPE,
)

#: Outlet excess [J/kg, about 2 K] over its setpoint of a closed branch at its least flow beyond
#: which its valve would open: the closing is not a state of the circuit.
_STARVED_EXCESS = 2000.0
#: Each branch's valve opening in the working arrays, in the circuit's order.
_OPENINGS = ("valve_opening", "valve_opening_chiller")


@dataclass(frozen=True)
class ValveLimits:
    """What the limits found per point, for the flags and notes of the solved points.

    Attributes
    ----------
    saturated : numpy.ndarray
        A valve at its maximum opening, its superheat floating.
    closed_cause : numpy.ndarray
        Why a closed valve closed, where not for its branch's least flow ('' otherwise).
    closed_notes : numpy.ndarray
        A note on a closed valve that would open a little ('' otherwise).
    """

    saturated: np.ndarray
    closed_cause: np.ndarray
    closed_notes: np.ndarray

    @classmethod
    def none(cls, saturated: np.ndarray) -> ValveLimits:
        """A single branch: only its valve's saturation."""
        n = saturated.size
        return cls(saturated, np.full(n, "", dtype=object), np.full(n, "", dtype=object))


def parallel_limits(
    ctx: SolveContext,
    ops: Ops,
    res: dict,
    first: SolveState,
    warm: WarmStart | None = None,
    solution: WarmStart | None = None,
) -> ValveLimits:
    """Parallel branches at their valves' limits, solved again (``ops``, ``res`` in place).

    ``res`` are the working arrays of the first solve, with both valves
    holding their setpoint, and ``first`` its state after its last suction
    iterate (where its split stopped at a branch's least flow, and which
    points stayed above the setpoint up to the top of the search). A valve
    that floats starts from the floating solution of the previous solve
    ``warm`` where the same valve floated there; the floating solutions go
    into ``solution``.
    """
    closed_cause = np.full(ops["branch_mode"].size, "", dtype=object)
    _close_least_flow(ctx, ops, res, first.clamped.copy())
    _close_capped(ctx, ops, res, first.above_top.copy(), closed_cause)
    saturated = _float_saturated(ctx, ops, res, warm, solution)
    _close_beside_saturated(ctx, ops, res, saturated)
    _mark_second_saturation(ctx, ops, res)
    return ValveLimits(saturated, closed_cause, _closed_notes(ctx, ops, res))


def solve_again(ctx: SolveContext, ops: Ops, res: dict, idx: np.ndarray, modes: np.ndarray) -> None:
    """Solve the points ``idx`` again with their branch modes set to ``modes`` (``ops`` and ``res`` in place)."""
    ops["branch_mode"][idx] = modes
    r, _ = solve_closure(ctx, take(ops, idx))
    for k, v in r.items():
        res[k][idx] = v


def _close_least_flow(ctx: SolveContext, ops: Ops, res: dict, kind: np.ndarray) -> None:
    """Closed valves: a branch that would need less than its model's least flow (at the last
    suction iterate; where the suction search did not converge with the split at that bound, it
    went back and forth across the flow at which that branch would close)."""
    least = np.isin(kind, (CLAMP_FIRST_LEAST, CLAMP_SECOND_LEAST))
    idx = np.nonzero(np.isin(res["status"], (STATUS_OUTSIDE_ENVELOPE, STATUS_NOT_CONVERGED)) & least)[0]
    if idx.size:
        solve_again(ctx, ops, res, idx, np.where(kind[idx] == CLAMP_FIRST_LEAST, FIRST_CLOSED, SECOND_CLOSED))


def _close_capped(ctx: SolveContext, ops: Ops, res: dict, above_top: np.ndarray, closed_cause: np.ndarray) -> None:
    """The colder stream's branch at the top of the search: every open branch must evaporate below
    its secondary inlet, so the coldest one caps the suction pressure. Where both outlets are still
    above the setpoint there, the suction would rise past that cap: the branch on the colder stream
    can no longer evaporate, its bulb sees no superheat and its valve closes, and the other branch
    alone sets the suction (up to its own stream). Its cause goes into ``closed_cause``."""
    capped = np.nonzero(above_top & (ops["branch_mode"] == BOTH_HOLD))[0]
    if capped.size == 0:
        return
    temps = [np.asarray(ops[b.secondary_temperature], float)[capped] for b in ctx.circuit.branches]
    colder = np.where(temps[0] <= temps[1], 0, 1)
    for i, b, t in zip(capped, colder, np.minimum(*temps), strict=True):
        closed_cause[i] = (
            f"with both open, the suction would rise past the {ctx.labels[b]}'s secondary inlet "
            f"({t - 273.15:.3g} degC), where that branch cannot evaporate"
        )
    solve_again(ctx, ops, res, capped, np.where(colder == 0, FIRST_CLOSED, SECOND_CLOSED))


def _float_saturated(
    ctx: SolveContext, ops: Ops, res: dict, warm: WarmStart | None = None, solution: WarmStart | None = None
) -> np.ndarray:
    """Saturated valves: one floats, the other holds its setpoint (both beyond their maximum: not
    modelled, status 9), from ``warm``'s floating solution of the same valve. Returns the points
    floating; their floating solutions go into ``solution``."""
    mode, max_opening = ops["branch_mode"], ctx.max_opening
    ok = res["status"] == STATUS_CONVERGED
    over = [ok & (res[key] > max_opening) for key in _OPENINGS]
    both = over[0] & over[1]
    mark_invalid(
        res,
        both,
        STATUS_BRANCH_VALVE_SATURATED,
        [
            f"both valves would need more than their maximum {max_opening:.3g} x nominal "
            f"({a:.3g} and {b:.3g}): two saturated valves in parallel are not modelled"
            for a, b in zip(res["valve_opening"][both], res["valve_opening_chiller"][both], strict=True)
        ],
    )
    saturated = np.zeros(mode.size, bool)
    for b, key in enumerate(_OPENINGS):
        floating = over[b] & ~both
        mode[floating & (mode == BOTH_HOLD)] = FIRST_FLOATS if b == 0 else SECOND_FLOATS
        idx = np.nonzero(floating)[0]
        if idx.size:
            flow = res["mdot_evap" if b == 0 else "mdot_chiller"][idx]
            floats = FIRST_FLOATS if b == 0 else SECOND_FLOATS
            start = _same_float(warm, idx, floats)
            fl = float_superheat(ctx, ops, res, idx, key, share=flow / res["mdot"][idx], warm=start)
            if solution is not None:
                fl.mode[:] = np.where(np.isfinite(fl.superheat), floats, -1)
                solution.superheat[idx] = fl.superheat
                if solution.floating is None:
                    solution.floating = WarmStart.blank(len(solution))
                solution.floating.put(idx, fl)
        saturated |= floating
    return saturated


def _same_float(warm: WarmStart | None, idx: np.ndarray, floats: int) -> WarmStart | None:
    """``warm`` of the points ``idx``, its floating solution kept where the same valve floated."""
    if warm is None or warm.floating is None:
        return None
    start = warm.take(idx)
    other = start.floating.mode != floats
    start.floating.superheat[other] = np.nan
    return start


def _close_beside_saturated(ctx: SolveContext, ops: Ops, res: dict, saturated: np.ndarray) -> None:
    """With one valve at its maximum the suction pressure falls, and the branch holding the setpoint
    may then need less than its model's least flow (or the total flow no longer splits within the
    models' flows): that valve closes, and the saturated branch runs alone (``saturated`` revised
    in place)."""
    mode = ops["branch_mode"]
    why = res["reason"].astype(str)
    retry = (res["status"] == STATUS_OUTSIDE_ENVELOPE) & ((mode == FIRST_FLOATS) | (mode == SECOND_FLOATS))
    retry &= np.char.find(why, "split") >= 0
    idx = np.nonzero(retry)[0]
    if idx.size == 0:
        return
    solve_again(ctx, ops, res, idx, np.where(mode[idx] == FIRST_FLOATS, SECOND_CLOSED, FIRST_CLOSED))
    saturated[idx] = False
    for b, key in enumerate(_OPENINGS):
        alone = (SECOND_CLOSED, FIRST_CLOSED)[b]
        k = idx[(res["status"][idx] == STATUS_CONVERGED) & (mode[idx] == alone)]
        k = k[res[key][k] > ctx.max_opening]
        if k.size:
            float_superheat(ctx, ops, res, k, key)
            saturated[k] = True


def _mark_second_saturation(ctx: SolveContext, ops: Ops, res: dict) -> None:
    """The holding valve may then need more than its maximum in turn: two saturated valves, status 9."""
    mode, labels, max_opening = ops["branch_mode"], ctx.labels, ctx.max_opening
    for b, key in enumerate(("valve_opening_chiller", "valve_opening")):
        held = (res["status"] == STATUS_CONVERGED) & (mode == (FIRST_FLOATS, SECOND_FLOATS)[b])
        held &= res[key] > max_opening
        mark_invalid(
            res,
            held,
            STATUS_BRANCH_VALVE_SATURATED,
            [
                f"with the {labels[b]} valve at its maximum opening, the {labels[1 - b]} valve would need "
                f"{x:.3g} x its nominal opening, beyond its maximum {max_opening:.3g}: two saturated "
                "valves in parallel are not modelled"
                for x in res[key][held]
            ],
        )


def _closed_notes(ctx: SolveContext, ops: Ops, res: dict) -> np.ndarray:
    """A closed valve: where its branch at the least flow its model covers would leave above the
    setpoint superheat at the solved point, the valve would open a little: the branch's flow lies
    between 0 and that least flow (the valve modulating near its seat) and its duty, below the
    least flow's, is left out; the note says so, with that bound. Kelvins above: not converged."""
    mode = ops["branch_mode"]
    notes = np.full(mode.size, "", dtype=object)
    idx = np.nonzero((res["status"] == STATUS_CONVERGED) & ((mode == FIRST_CLOSED) | (mode == SECOND_CLOSED)))[0]
    if idx.size == 0:
        return notes
    excess, duty = closed_branch_at_least_flow(ctx, ops, res, idx, mode[idx] == FIRST_CLOSED)
    # A closed branch whose outlet at its least flow lies kelvins above its setpoint needs
    # more flow, so its valve would open: the search starved it (e.g. the other valve, at
    # its maximum, taking the compressor's flow at a low suction iterate), its bulb did not
    # close it. Not a state of the circuit: not converged, said so.
    starved = excess > _STARVED_EXCESS
    mark_invalid(
        res,
        idx[starved],
        STATUS_NOT_CONVERGED,
        [
            f"the search closed the {ctx.labels[int(mode[i] != FIRST_CLOSED)]} valve, but at the least flow "
            f"its model covers that branch leaves {x / CP_SCALE:.3g} K above its setpoint: its valve "
            "would open (not converged)"
            for i, x in zip(idx[starved], excess[starved], strict=True)
        ],
    )
    opens = (excess > OUTER_FTOL * CP_SCALE) & ~starved
    for i, d in zip(idx[opens], duty[opens], strict=True):
        notes[i] = (
            f"; nearly closed: its flow lies between 0 and that least flow, its duty below {d / 1e3:.2g} kW is left out"
        )
    return notes


def closed_branch_at_least_flow(
    ctx: SolveContext, ops: Ops, res: dict, idx: np.ndarray, first_closed: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The closed branch of points ``idx`` run at the least flow its model covers, at the solved
    suction: its outlet's excess [J/kg] over the setpoint state, and its duty [W] there."""
    names = ctx.names
    sub = take(ops, idx)
    p_A, h_C = res["p_A"][idx], res["h_C"][idx]
    with np.errstate(invalid="ignore", divide="ignore"):
        h_set = ctx.models.compressor(
            sub["speed"], ctx.sat.temperature(p_A) + sub["setpoint"], p_A, res["p_B"][idx] / p_A
        )["h_in"]
    excess, duty = np.full(idx.size, np.nan), np.full(idx.size, np.nan)
    for b in (0, 1):
        k = np.nonzero(first_closed == (b == 0))[0]
        if k.size == 0:
            continue
        o = take(sub, k)
        least = np.full(k.size, ctx.models.flow_range(names[b])[0] * (1 + 1e-6))
        drop = converged_drop(ctx, names[b], o, least, p_A[k], h_C[k], np.zeros(k.size))
        h_out = branch(ctx, names[b], o, least, p_A[k] + drop, h_C[k])["h_out_continued"]
        excess[k], duty[k] = h_out - h_set[k], least * (h_out - h_C[k])
    return excess, duty
