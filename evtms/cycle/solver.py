"""Steady-state vapor-compression cycle: closure on two pressures, vectorised.

States: A evaporator outlet = compressor suction, B compressor discharge =
condenser inlet, C condenser outlet = valve inlet, D valve outlet =
evaporator inlet. The evaporating side is one branch (the cabin evaporator or
the battery chiller) or both in parallel (:mod:`evtms.cycle.topology`; with two
branches, A is the mixed suction state and D the first branch's valve outlet,
the flow split is solved at each suction iterate, :mod:`evtms.cycle.split`;
a valve at its maximum opening or closed, :mod:`evtms.cycle.limits`).
"Cabin air" below stands for the branch's secondary inlet (the coldest of the
two with parallel branches). The circuit has a receiver after the condenser, so the
condenser ends in saturated liquid (or at a given subcooling), and a
thermostatic valve that holds the evaporator-outlet superheat at its
setpoint. The two unknowns are the suction pressure ``p_A`` and the discharge
pressure ``p_B``:

- inner loop, for a given ``p_A``: the compressor at ``(speed, T_A, p_A,
  p_B/p_A)`` with ``T_A = T_sat(p_A) + superheat`` gives ``mdot`` and
  ``h_B``; the condenser at ``(mdot, fan, p_B, h_B, ambient air)`` gives its
  outlet; ``p_B`` is the root of ``1 - capacity_ratio`` for a saturated-liquid
  outlet, or of the outlet quality (from ``h_out_continued``) minus its
  target for a subcooled one (a higher discharge pressure raises the
  saturation temperature and so condenses and subcools more: the residual
  falls monotonically);
- outer loop: the valve is isenthalpic (``h_D = h_C``), the evaporator inlet
  pressure is ``p_A`` plus the evaporator's own pressure drop (fixed point,
  one pass per iterate from the previous iterate's drop), and ``p_A`` is the
  root of the outlet enthalpy (``h_out_continued``) minus the suction
  enthalpy at the superheat setpoint (a higher suction pressure means less
  temperature difference to the air and more mass flow, so less superheat).
  ``h_out_continued`` equals ``h_out`` where the outlets lie in the coils'
  last zone and has no kink where they change phase (see
  ``evtms.benches.coil.solve_coil``).

Both roots are found by regula falsi with the Anderson-Bjorck modification
(the Illinois halving where that fails), vectorised over all operating points
at once, in saturation temperature. Each search starts from a first guess
(the inner root at the previous suction iterate, or a physics guess: condensing
13 K above the ambient, evaporating 23 K below the cabin air) and one secant
step from it, which brackets the root in most points after two evaluations;
the other points fall back to the whole range from physics (saturation just
above the ambient for the condenser, just below the cabin air for the
evaporator) clipped to the models' ranges. A point whose residual does not
change sign on that range, or whose models return NaN, gets a status and the
reason.

The valve's limit. The opening that passes the cycle's flow follows from the
valve's orifice law, ``mdot = S sqrt(2 rho_C (p_C - p_D))``, with the flow
area ``S`` [m2] over the nominal area of its parameters. A thermostatic valve
opens no further than its maximum (``capacity_max / capacity_nominal`` times
the nominal area); where holding the setpoint would need more, the valve
sits at its maximum and stops holding the superheat, which floats above the
setpoint: the orifice law at the maximum area closes the suction side
instead, and the cycle is solved again with the superheat as the unknown
(:mod:`evtms.cycle.saturation`). Such a point is valid, with status 5
``converged_valve_saturated_superheat_floating`` and ``superheat_actual``
the superheat reached. This is the undersized (or, at a low condensing
pressure, under-driven) valve starving its evaporator: less flow at a lower
suction pressure and a higher superheat. A saturated valve never floods the
evaporator. A flooded evaporator, whose outlet stays two-phase however low
the suction pressure (here down to evaporating 45 K below the cabin air or
coolant, or at -30 degC where that is lower),
has no steady state the models describe: the compressor would draw liquid
(slugging), which its model, on superheated suction states, does not cover
and an automotive circuit with a receiver (no suction accumulator) must
avoid. Such a point is invalid, status 8 ``evaporator_outlet_wet``, its
states NaN.

Frost. Where the evaporator's coldest surface lies below 0 degC under
condensate (its bench status ``valid_frost_risk_surface_below_0C``) at the
solved point, the point is valid and flagged, status 6
``converged_frost_risk`` (7 with a saturated valve as well): ice would
build up on the fins and the steady state would not last. The direct models
take the flag from the evaporator bench at the solved point; the LUTs hold no
surface temperature, so the LUT cycle interpolates the indicator of that
status over the evaporator LUT's nodes (1 at a frost-risk node, 0 at another
valid one) and flags a point from 0.5, i.e. where most of the interpolation
weight lies on frost-risk nodes.

Where each step lives: :mod:`evtms.cycle.roots` (bracketing and regula
falsi), :mod:`evtms.cycle.closure` (the two pressure roots, the final states
and the figures), :mod:`evtms.cycle.branches` and :mod:`evtms.cycle.split`
(one evaporating branch, two in parallel), :mod:`evtms.cycle.saturation`
(the valve at its maximum opening), :mod:`evtms.cycle.limits` (parallel
valves closed or saturated), :mod:`evtms.cycle.state` (the inputs, the
context and the warm starts of a solve), :mod:`evtms.cycle.status` and
:mod:`evtms.cycle.results` (status codes, typed results). This module
orchestrates them (:class:`CycleSolver`) and flags the solved points.

References
----------
Dowell, M., Jarratt, P. (1971). A modified regula falsi method for computing
the root of an equation. BIT 11, 168-174 (the Illinois algorithm).
Anderson, N., Bjorck, A. (1973). A new high order method of regula falsi type
for computing a root of an equation. BIT 13, 253-264.
Stoecker, W. F., Jones, J. W. (1982). Refrigeration and Air Conditioning,
2nd ed., ch. 15 (system simulation by balancing components).
ASHRAE (2018). ASHRAE Handbook - Refrigeration, ch. 11, Refrigerant-control
devices (thermostatic expansion valves: capacity, superheat, feed limits).
"""

from __future__ import annotations

import numpy as np

from evtms.cycle.compiled import solve_closure
from evtms.cycle.limits import ValveLimits, parallel_limits
from evtms.cycle.results import BranchResult, CycleResult, mark_invalid
from evtms.cycle.roots import bracketed_root
from evtms.cycle.saturation import float_superheat
from evtms.cycle.state import (
    FIRST_CLOSED,
    FIRST_FLOATS,
    INPUTS,
    MIX_TOL,
    SECOND_CLOSED,
    OperatingPoints,
    Ops,
    SolveContext,
    WarmStart,
)
from evtms.cycle.status import (
    CYCLE_FLAGS,
    FROST_RISK_FLAGS,
    STATUS_BRANCH_CLOSED,
    STATUS_BRANCH_VALVE_SATURATED,
    STATUS_CONDENSER_NO_ROOT,
    STATUS_CONVERGED,
    STATUS_EVAPORATOR_NO_ROOT,
    STATUS_EVAPORATOR_WET,
    STATUS_FROST_RISK,
    STATUS_NOT_CONVERGED,
    STATUS_OUTSIDE_ENVELOPE,
    STATUS_VALVE_SATURATED,
    STATUS_VALVE_SATURATED_FROST_RISK,
    VALID_CYCLE_FLAGS,
    VALVE_SATURATED_FLAGS,
    CycleStatus,
)
from evtms.cycle.topology import Topology, topology
from evtms.fluid import SaturationCurve

__all__ = [
    "CYCLE_FLAGS",
    "FROST_RISK_FLAGS",
    "INPUTS",
    "STATUS_BRANCH_CLOSED",
    "STATUS_BRANCH_VALVE_SATURATED",
    "STATUS_CONDENSER_NO_ROOT",
    "STATUS_CONVERGED",
    "STATUS_EVAPORATOR_NO_ROOT",
    "STATUS_EVAPORATOR_WET",
    "STATUS_FROST_RISK",
    "STATUS_NOT_CONVERGED",
    "STATUS_OUTSIDE_ENVELOPE",
    "STATUS_VALVE_SATURATED",
    "STATUS_VALVE_SATURATED_FROST_RISK",
    "VALID_CYCLE_FLAGS",
    "VALVE_SATURATED_FLAGS",
    "BranchResult",
    "CycleResult",
    "CycleSolver",
    "CycleStatus",
    "OperatingPoints",
    "bracketed_root",
]

#: The closure's two paths (:class:`CycleSolver`'s ``closure``).
CLOSURES = ("auto", "compiled", "python")
#: ``auto`` finds the roots in the compiled kernel for batches up to this size: it solves a point
#: in about 0.1 ms where the Python path's per-call work takes 10 ms. In large batches the kernel
#: wins where few points are handed back (cabin map 65 against 71 us a node, random cabin points
#: 71 against 96) and loses where many are, each solved again on the Python path (hp map 139
#: against 80), so ``auto`` leaves large batches to the Python path (the maps name theirs).
KERNEL_BATCH_MAX = 1000

#: Largest difference [J/kg] between the suction state and the branches' mixture at a solved
#: parallel point (:data:`evtms.cycle.state.MIX_TOL`, under the name the tests know).
_MIX_TOL = MIX_TOL


class CycleSolver:
    """Solve the cycle for many operating points with a set of component models.

    Parameters
    ----------
    models : LutModels or DirectModels
        Where the component responses come from.
    saturation : SaturationCurve
        Tabulated saturation properties of the refrigerant.
    circuit : Topology or str
        The circuit (:data:`evtms.cycle.topology.TOPOLOGIES`), default ``cabin``.
    closure : {"auto", "compiled", "python"}
        Where the pressure roots are found: the compiled kernel (:mod:`evtms.cycle.compiled`, on
        compiled LUTs of a one-branch circuit; the points it cannot solve go to the Python path),
        or the vectorised Python path (:mod:`evtms.cycle.closure`); ``auto``: the kernel for
        batches of at most :data:`KERNEL_BATCH_MAX` points. The two agree to round-off, so a
        job that must give the same bits however it is split into batches (the simulator's
        maps) fixes it.
    """

    #: Maximum over nominal opening of the valve (its maximum over nominal capacity), set by solve.
    max_opening = np.nan

    def __init__(
        self, models, saturation: SaturationCurve, circuit: Topology | str = "cabin", closure: str = "auto"
    ) -> None:
        if closure not in CLOSURES:
            raise ValueError(f"closure {closure!r} is unknown; allowed: {', '.join(CLOSURES)}")
        self.models = models
        self.sat = saturation
        self.circuit = topology(circuit)
        self.closure = closure

    #: The solution of the last solve, per point (:class:`~evtms.cycle.state.WarmStart`), set by solve.
    warm_start: WarmStart | None = None

    def solve(self, points: OperatingPoints, warm: WarmStart | None = None) -> CycleResult:
        """Solve every operating point.

        ``warm``, the :attr:`warm_start` a solve of nearby points left (as many
        points, in the same order), starts the closures from that solution:
        a time step whose inputs moved little needs few iterates. The roots
        are the same as without it to within the closures' tolerances (the
        suction closure's step :data:`~evtms.cycle.state.XTOL` or residual
        :data:`~evtms.cycle.state.OUTER_FTOL`, the condenser's
        :data:`~evtms.cycle.state.INNER_FTOL`; a floating superheat's, about
        0.01 K); a point whose warm bracket holds no root is searched over its
        whole range, as without a warm start.

        First with the valve holding the superheat setpoint; where that needs
        more than the valve's maximum opening, the valve stays at its maximum
        opening and the superheat floats (:mod:`evtms.cycle.saturation`; two
        parallel valves at their limits: :mod:`evtms.cycle.limits`). Valid
        points are then flagged where the valve is saturated or closed or the
        evaporator surface risks frost.

        Returns
        -------
        CycleResult
            Readable as a mapping of the result variables: ``p_A, T_A, h_A``
            ... ``p_D, T_D, h_D`` [Pa, K, J/kg], ``mdot`` [kg/s], ``Q_evap``
            (< 0), ``Q_latent``, ``Q_cond``, ``W`` (shaft), ``W_fluid``
            (``mdot (h_B - h_A)``) [W], ``COP`` (cooling, |Q_evap|/W) [1],
            ``dp_valve`` [Pa], ``valve_opening`` (relative to the nominal
            opening; ``capacity_max / capacity_nominal`` where the valve is
            saturated) [1], ``superheat_actual`` (evaporator-outlet superheat:
            the setpoint, or the floating superheat where the valve is
            saturated) [K], ``frost_risk`` [1] (1 where the evaporator's
            coldest surface is below 0 degC, else 0; on LUTs the share of the
            interpolation weight on such nodes, flagged from 0.5), ``status``
            (int8, :data:`CYCLE_FLAGS`) and ``reason`` (why a point failed, or
            what its flags mean; empty when converged without a flag); each
            branch's own figures also as its :class:`BranchResult`.
        """
        if warm is not None and len(warm) != len(points):
            raise ValueError(f"a warm start of {len(warm)} points for {len(points)} points")
        kernel = self.closure == "compiled" or (self.closure == "auto" and len(points) <= KERNEL_BATCH_MAX)
        ctx = SolveContext(self.models, self.sat, self.circuit, kernel)
        ops = points.subset(np.arange(len(points)))
        if ctx.parallel:
            ops["branch_mode"] = np.zeros(len(points), np.int8)
            ops["setpoint"] = ops["superheat"].copy()
        # Operating inputs beyond a LUT's axes (a cabin at -20 degC against an evaporator LUT from
        # 10 degC): no refrigerant state helps; said up front, not as whichever bound the search met.
        outside = _outside_axes(ctx, ops)
        res, first = solve_closure(ctx, ops, warm=warm)
        self.warm_start = WarmStart.of(ctx.sat, res, first)
        self.max_opening = ctx.max_opening
        if ctx.parallel:
            limits = parallel_limits(ctx, ops, res, first, warm, self.warm_start)
        else:
            limits = _single_valve_limit(ctx, ops, res, self.warm_start, warm)
        _check_suction_closure(ctx, res, limits.saturated)
        _flag(ctx, res, ops, limits)
        off = outside != ""
        mark_invalid(res, off, STATUS_OUTSIDE_ENVELOPE, outside[off])
        return CycleResult.from_arrays(res, ctx.circuit)


def _single_valve_limit(
    ctx: SolveContext, ops: Ops, res: dict, solution: WarmStart, warm: WarmStart | None
) -> ValveLimits:
    """A single branch's valve beyond its maximum opening: its superheat floats (``res`` in place),
    from the floating superheat of the previous solve ``warm`` where it had one; the floating
    solution goes into ``solution``."""
    saturated = (res["status"] == STATUS_CONVERGED) & (res["valve_opening"] > ctx.max_opening)
    idx = np.nonzero(saturated)[0]
    if idx.size:
        floating = float_superheat(ctx, ops, res, idx, warm=None if warm is None else warm.take(idx))
        solution.superheat[idx] = floating.superheat
        if solution.floating is None:
            solution.floating = WarmStart.blank(len(solution))
        solution.floating.put(idx, floating)
    return ValveLimits.none(saturated)


def _outside_axes(ctx: SolveContext, ops: Ops) -> np.ndarray:
    """Per point, the first operating input outside a component model's axes (its reason), else ''.

    Of parallel branches none is checked: the search may close a branch whose model cannot
    take its stream (coolant below the chiller LUT, colder than the cabin's evaporation)."""
    branches = [] if ctx.parallel else list(ctx.names)
    components = ["compressor", *(c.component for c in ctx.circuit.chain), *branches]
    reasons = np.full(ops["speed"].size, "", dtype=object)
    for component in components:
        why = ctx.models.outside_axes(component, ops)
        reasons = np.where(reasons == "", why, reasons)
    return reasons


def _check_suction_closure(ctx: SolveContext, res: dict, saturated: np.ndarray) -> None:
    """Not converged where the suction state is not the evaporating branches' outlet (mixture).

    The energy balance closes on it. The closure can stop off it on a jump of the mixture (the
    split changing branch between two suction iterates), or on a jump of a branch's outlet
    with the suction pressure (the chiller on coolant below -5 degC, dropping 30-45 % of its
    inlet pressure: up to kilojoules per kilogram off, balances 6 % off before this check).
    ``res`` and ``saturated`` in place.
    """
    with np.errstate(invalid="ignore"):
        off = (res["status"] == STATUS_CONVERGED) & (np.abs(res["h_A_evap"] - res["h_A"]) > MIX_TOL)
    what = "the branches' mixture" if ctx.parallel else "the evaporating branch's outlet"
    mark_invalid(
        res,
        off,
        STATUS_NOT_CONVERGED,
        [
            f"the suction closure stopped {abs(x):.3g} J/kg off {what} (not converged)"
            for x in (res["h_A_evap"] - res["h_A"])[off]
        ],
    )
    saturated &= ~off


def _flag(ctx: SolveContext, res: dict, ops: Ops, limits: ValveLimits) -> None:
    """Flag the converged points where a valve is saturated or closed or frost may form (in place).

    Frost: the evaporator bench's status ``valid_frost_risk_surface_below_0C``
    (its coldest surface below 0 degC, under condensate) at the solved
    evaporator point; on LUTs, interpolated as the share of frost-risk
    nodes in the weight, flagged from 0.5.
    """
    status, reason = res["status"], res["reason"]
    ok = status == STATUS_CONVERGED
    sat = ok & limits.saturated
    frost = ok & (np.nan_to_num(res["frost_risk"]) >= 0.5)
    mode = ops.get("branch_mode", np.zeros(status.size, np.int8))
    closed = ok & ((mode == FIRST_CLOSED) | (mode == SECOND_CLOSED))
    status[closed] = STATUS_BRANCH_CLOSED
    status[sat] = STATUS_VALVE_SATURATED
    status[frost] = STATUS_FROST_RISK
    status[sat & frost] = STATUS_VALVE_SATURATED_FROST_RISK
    for i in np.nonzero(sat | frost | closed)[0]:
        notes = []
        if closed[i]:
            notes.append(_closed_note(ctx, limits, 0 if mode[i] == FIRST_CLOSED else 1, i))
        if sat[i]:
            notes.append(_saturated_note(ctx, res, ops, mode[i], i))
        if frost[i]:
            notes.append("an evaporator surface is below 0 degC under condensate: frost risk")
        reason[i] = "; ".join(notes)


def _closed_note(ctx: SolveContext, limits: ValveLimits, b: int, i: int) -> str:
    """Why branch ``b``'s valve of point ``i`` is closed."""
    least = ctx.models.flow_range(ctx.names[b])[0]
    cause = limits.closed_cause[i] or (
        f"that branch would need less than the least flow its model covers ({least * 1e3:.3g} g/s) to hold the setpoint"
    )
    return f"the {ctx.labels[b]} valve is closed (no flow, no heat): {cause}" + limits.closed_notes[i]


def _saturated_note(ctx: SolveContext, res: dict, ops: Ops, mode: int, i: int) -> str:
    """Which valve of point ``i`` is at its maximum opening, and where its superheat floats."""
    if not ctx.parallel:
        return (
            f"the valve is at its maximum opening ({ctx.max_opening:.3g} x nominal): the superheat floats "
            f"at {res['superheat_actual'][i]:.3g} K, above its setpoint {ops['superheat'][i]:.3g} K"
        )
    b = 0 if mode in (FIRST_FLOATS, SECOND_CLOSED) else 1
    key = "superheat_actual" if b == 0 else "superheat_chiller"
    return (
        f"the {ctx.labels[b]} valve is at its maximum opening ({ctx.max_opening:.3g} x nominal): its "
        f"superheat floats at {res[key][i]:.3g} K, above its setpoint {ops['setpoint'][i]:.3g} K"
    )
