"""Steady-state vapor-compression cycle: closure on two pressures, vectorised.

States: A evaporator outlet = compressor suction, B compressor discharge =
condenser inlet, C condenser outlet = valve inlet, D valve outlet =
evaporator inlet. The evaporating side is one branch (the cabin evaporator or
the battery chiller) or both in parallel (:mod:`evtms.cycle.topology`; with two
branches, A is the mixed suction state and D the first branch's valve outlet,
the flow split is solved at each suction iterate, :mod:`evtms.cycle.split`;
a valve at its maximum opening or closed, :meth:`CycleSolver._parallel_limits`).
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
(:meth:`CycleSolver._float_superheat`). Such a point is valid, with status 5
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

from evtms.cycle.branches import branch, converged_drop
from evtms.cycle.closure import solve_at
from evtms.cycle.roots import bracketed_root  # noqa: F401  (stays importable from here)
from evtms.cycle.state import (  # noqa: F401  (INPUTS, OperatingPoints stay importable from here)
    BOTH_HOLD,
    CLAMP_FIRST_LEAST,
    CLAMP_OTHER,
    CLAMP_SECOND_LEAST,
    CP_SCALE,
    DP_PASSES,
    DP_TOL,
    FIRST_CLOSED,
    FIRST_FLOATS,
    INNER_FTOL,
    INPUTS,
    MIX_TOL,
    OUTER_FTOL,
    SECOND_CLOSED,
    SECOND_FLOATS,
    XTOL,
    OperatingPoints,
    SolveContext,
    SolveState,
)
from evtms.cycle.status import (  # noqa: F401  (the status names stay importable from here)
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

#: Largest difference [J/kg] between the suction state and the branches' mixture at a solved parallel
#: point (evtms.cycle.state.MIX_TOL, under the name the tests know).
_MIX_TOL = MIX_TOL
#: Outlet excess [J/kg, about 2 K] over its setpoint of a closed branch at its least flow beyond
#: which its valve would open: the closing is not a state of the circuit.
_STARVED_EXCESS = 2000.0

#: Superheat search with the valve at its maximum opening (see CycleSolver._float_superheat). Its first
#: step's estimates are linear in g0 = ln(opening needed at the setpoint over the maximum) [1], fitted on the
#: 271 saturated points of benchmarks/bench_cycle.py (within 5 % for half of them, 22 % for all): the secant
#: slope of ln(opening) from the setpoint to the floating superheat [1/K] (steeper the larger g0: ln(opening)
#: falls ever faster as the superheat rises), and per kelvin of superheat over that shift the change of the
#: suction saturation temperature [K/K], of ln(p_B) [1/K] and the relative change of the evaporator's pressure
#: drop [1/K] (the warm start of that cycle solve). They only steer the search, not where it ends.
_SH_FIRST_SLOPE = (-0.0105, -0.0165)
_SH_FIRST_T = (-0.160, -0.476)
_SH_FIRST_LN_PB = (-0.00233, -0.00629)
_SH_FIRST_DP = (-0.0140, -0.0066)
#: The first step goes this share of the estimated shift [1], short of the root in most points; the second
#: the full secant estimate (the secant from the setpoint overshoots, ln(opening) bending down); later ones
#: overshoot by _SH_OVERSHOOT [1] and 0.5 K.
_SH_FIRST_SHARE = 0.9
_SH_OVERSHOOT = 1.3
#: Typical slope of the suction superheat closure [1/K] at a floating superheat (the superheat falls less
#: per kelvin of suction saturation than at the setpoint, closure.OUTER_SLOPE, so that its bracket holds the root).
_SH_OUTER_SLOPE = -1.5
#: Inverse-quadratic steps once bracketed, before the regula falsi; largest bracketing step [K] and number
#: of steps, tolerances in superheat (relative) [1] and in ln(opening) [1].
_SH_QUAD_STEPS = 3
_SH_MAX_STEP = 25.0
_SH_BRACKET_STEPS = 4
_SH_XTOL = 1e-4
_SH_FTOL = 1e-4


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
    """

    def __init__(self, models, saturation: SaturationCurve, circuit: Topology | str = "cabin") -> None:
        self.models = models
        self.sat = saturation
        self.circuit = topology(circuit)

    @property
    def _ctx(self) -> SolveContext:
        return SolveContext(self.models, self.sat, self.circuit)

    # -- public --------------------------------------------------------------
    def solve(self, points: OperatingPoints) -> dict[str, np.ndarray]:
        """Solve every operating point.

        First with the valve holding the superheat setpoint; where that needs
        more than the valve's maximum opening, the valve stays at its maximum
        opening and the superheat floats (:meth:`_float_superheat`). Valid
        points are then flagged where the valve is saturated or the evaporator
        surface risks frost (:meth:`_flag`).

        Returns
        -------
        dict of str to numpy.ndarray
            ``p_A, T_A, h_A`` ... ``p_D, T_D, h_D`` [Pa, K, J/kg], ``mdot``
            [kg/s], ``Q_evap`` (< 0), ``Q_latent``, ``Q_cond``, ``W`` (shaft),
            ``W_fluid`` (``mdot (h_B - h_A)``) [W], ``COP`` (cooling, |Q_evap|/W)
            [1], ``dp_valve`` [Pa], ``valve_opening`` (relative to the nominal
            opening; ``capacity_max / capacity_nominal`` where the valve is
            saturated) [1], ``superheat_actual`` (evaporator-outlet superheat:
            the setpoint, or the floating superheat where the valve is
            saturated) [K], ``frost_risk`` [1] (1 where the evaporator's coldest
            surface is below 0 degC, else 0; on LUTs the share of the
            interpolation weight on such nodes, flagged from 0.5), ``status``
            (int8, :data:`CYCLE_FLAGS`) and ``reason`` (why a point failed, or
            what its flags mean; empty when converged without a flag).
        """
        ops = points.subset(np.arange(len(points)))
        if self.circuit.parallel:
            ops["branch_mode"] = np.zeros(len(points), np.int8)
            ops["setpoint"] = ops["superheat"].copy()
        # Operating inputs beyond a LUT's axes (a cabin at -20 degC against an evaporator LUT from
        # 10 degC): no refrigerant state helps; said up front, not as whichever bound the search met.
        outside = self._outside_axes(ops)
        res, first = solve_at(self._ctx, ops)
        valve, _ = self.models.valve()
        self.max_opening = valve.capacity_max / valve.capacity_nominal
        if self.circuit.parallel:
            saturated = self._parallel_limits(ops, res, first)
        else:
            saturated = (res["status"] == STATUS_CONVERGED) & (res["valve_opening"] > self.max_opening)
            idx = np.nonzero(saturated)[0]
            if idx.size:
                self._float_superheat(ops, res, idx)
        self._check_suction_closure(res, saturated)
        self._flag(res, ops, saturated)
        off = outside != ""
        self._mark_invalid(res, off, STATUS_OUTSIDE_ENVELOPE, outside[off])
        return res

    def _parallel_limits(self, ops: dict, res: dict, first: SolveState) -> np.ndarray:
        """Parallel branches at their valves' limits, solved again (in place); the points floating.

        Two thermostatic valves in parallel each act on their own branch's
        outlet superheat; the compressor sets the common suction pressure.
        A valve that reaches a limit of its stroke stops holding its setpoint
        while the other one keeps holding its own:

        - closed: a branch whose secondary stream is barely warmer than the
          suction saturation plus the setpoint (coolant at 20 degC against
          evaporation at 12 degC and a 10 K setpoint) cannot superheat its
          refrigerant by the setpoint at any flow, and the split finds the
          branch below the least flow its model covers (the chiller's
          ``mdot`` axis starts at 1 g/s, the evaporator's at 3 g/s). The
          valve's bulb then sees less than its static superheat and the
          valve closes: that branch carries no flow and no heat, and the
          circuit runs on the other branch alone (its valve holding the
          setpoint, or saturated as below), with status 10
          ``converged_branch_valve_closed`` (5-7 where those notes apply;
          the reason names the closed branch, ``mdot_evap`` or
          ``mdot_chiller`` is 0 and its valve opening 0). We chose the
          closed valve over pinning the branch at its model's least flow:
          at that flow its outlet would be below the setpoint (two-phase or
          nearly), which no TXV lets through in steady state, and the mixed
          suction state would be wrong; a real valve in that state modulates
          near its seat with a bleed below the least flow, whose duty (below
          that flow times the enthalpy rise, about 0.15 kW for the chiller,
          0.45 kW for the evaporator) is dropped. At the solved point the
          closed branch is evaluated at its least flow: where it would leave
          above the setpoint superheat there (the suction pressure fell once
          it closed), its valve would open a little and the true flow lies
          between 0 and that least flow; the point stays valid and its
          reason says "nearly closed", with the bound of the duty left out.
          The same holds where, with the other valve saturated, the branch
          holding the setpoint would need less than its least flow: it
          closes and the saturated branch runs alone. And where, with both
          valves holding, the outlets are still above the setpoint at the top
          of the suction pressures searched (saturation 0.5 K below the colder
          secondary inlet, which no open branch may evaporate above), the
          suction would rise past that stream's temperature: the branch on it
          cannot evaporate, its valve closes, and the other branch alone sets
          the suction (coolant at 22 degC against a 35 degC cabin at low
          speed evaporates at 24 degC with the chiller closed).
        - saturated: a valve that would need more than its maximum opening
          sits at it, and its branch's superheat floats above the setpoint
          while the other branch holds the setpoint (the split is solved with
          the other outlet at the setpoint, :mod:`evtms.cycle.split`). The suction
          state is the outlets' mixture, with its own superheat, found as for
          a single branch (:meth:`_float_superheat`) so that the saturated
          valve passes its branch's flow at its maximum opening. Status 5
          (7 with frost risk); ``superheat_actual`` (the first branch) or
          ``superheat_chiller`` is the floating superheat. Where both valves
          would need more than their maximum (or the other one would, once
          the first floats), the point stays invalid (status 9).

        Every valid point's suction state must be the branches' mixture to
        within ``MIX_TOL`` (the energy balance closes on it); one where the
        suction closure stopped on a jump of the mixture is status 4.
        """
        labels = [b.label for b in self.circuit.branches]
        mode = ops["branch_mode"]
        above_top = first.above_top.copy()
        # Why a closed valve closed, where not for the least flow (the default note in _flag).
        self._closed_cause = np.full(mode.size, "", dtype=object)
        # Closed valves: a branch that would need less than its model's least flow (at the last
        # suction iterate; where the suction search did not converge with the split at that
        # bound, it went back and forth across the flow at which that branch would close).
        kind = first.clamped.copy()
        least = np.isin(kind, (CLAMP_FIRST_LEAST, CLAMP_SECOND_LEAST))
        idx = np.nonzero(np.isin(res["status"], (STATUS_OUTSIDE_ENVELOPE, STATUS_NOT_CONVERGED)) & least)[0]
        if idx.size:
            self._solve_again(ops, res, idx, np.where(kind[idx] == CLAMP_FIRST_LEAST, FIRST_CLOSED, SECOND_CLOSED))
        # The colder stream's branch at the top of the search: every open branch must evaporate below
        # its secondary inlet, so the coldest one caps the suction pressure. Where both outlets are
        # still above the setpoint there, the suction would rise past that cap: the branch on the
        # colder stream can no longer evaporate, its bulb sees no superheat and its valve closes,
        # and the other branch alone sets the suction (up to its own stream).
        capped = np.nonzero(above_top & (mode == BOTH_HOLD))[0]
        if capped.size:
            temps = [np.asarray(ops[b.secondary_temperature], float)[capped] for b in self.circuit.branches]
            colder = np.where(temps[0] <= temps[1], 0, 1)
            for i, b, t in zip(capped, colder, np.minimum(*temps), strict=True):
                self._closed_cause[i] = (
                    f"with both open, the suction would rise past the {labels[b]}'s secondary inlet "
                    f"({t - 273.15:.3g} degC), where that branch cannot evaporate"
                )
            self._solve_again(ops, res, capped, np.where(colder == 0, FIRST_CLOSED, SECOND_CLOSED))
        # Saturated valves: one floats, the other holds its setpoint.
        ok = res["status"] == STATUS_CONVERGED
        over = [ok & (res[key] > self.max_opening) for key in ("valve_opening", "valve_opening_chiller")]
        both = over[0] & over[1]
        self._mark_invalid(
            res,
            both,
            STATUS_BRANCH_VALVE_SATURATED,
            [
                f"both valves would need more than their maximum {self.max_opening:.3g} x nominal "
                f"({a:.3g} and {b:.3g}): two saturated valves in parallel are not modelled"
                for a, b in zip(res["valve_opening"][both], res["valve_opening_chiller"][both], strict=True)
            ],
        )
        saturated = np.zeros(mode.size, bool)
        for b, key in enumerate(("valve_opening", "valve_opening_chiller")):
            floating = over[b] & ~both
            mode[floating & (mode == BOTH_HOLD)] = FIRST_FLOATS if b == 0 else SECOND_FLOATS
            idx = np.nonzero(floating)[0]
            if idx.size:
                flow = res["mdot_evap" if b == 0 else "mdot_chiller"][idx]
                self._float_superheat(ops, res, idx, key, share=flow / res["mdot"][idx])
            saturated |= floating
        # With one valve at its maximum the suction pressure falls, and the branch holding the setpoint
        # may then need less than its model's least flow (or the total flow no longer splits within
        # the models' flows): that valve closes, and the saturated branch runs alone.
        why = res["reason"].astype(str)
        retry = (res["status"] == STATUS_OUTSIDE_ENVELOPE) & ((mode == FIRST_FLOATS) | (mode == SECOND_FLOATS))
        retry &= np.char.find(why, "split") >= 0
        idx = np.nonzero(retry)[0]
        if idx.size:
            self._solve_again(ops, res, idx, np.where(mode[idx] == FIRST_FLOATS, SECOND_CLOSED, FIRST_CLOSED))
            saturated[idx] = False
            for b, key in enumerate(("valve_opening", "valve_opening_chiller")):
                alone = (SECOND_CLOSED, FIRST_CLOSED)[b]
                k = idx[(res["status"][idx] == STATUS_CONVERGED) & (mode[idx] == alone)]
                k = k[res[key][k] > self.max_opening]
                if k.size:
                    self._float_superheat(ops, res, k, key)
                    saturated[k] = True
        # The holding valve may then need more than its maximum in turn.
        for b, key in enumerate(("valve_opening_chiller", "valve_opening")):
            held = (res["status"] == STATUS_CONVERGED) & (mode == (FIRST_FLOATS, SECOND_FLOATS)[b])
            held &= res[key] > self.max_opening
            self._mark_invalid(
                res,
                held,
                STATUS_BRANCH_VALVE_SATURATED,
                [
                    f"with the {labels[b]} valve at its maximum opening, the {labels[1 - b]} valve would need "
                    f"{x:.3g} x its nominal opening, beyond its maximum {self.max_opening:.3g}: two saturated "
                    "valves in parallel are not modelled"
                    for x in res[key][held]
                ],
            )
        # A closed valve: where its branch at the least flow its model covers would leave above the
        # setpoint superheat at the solved point, the valve would open a little: the branch's flow lies
        # between 0 and that least flow (the valve modulating near its seat) and its duty, below the
        # least flow's, is left out; the note says so, with that bound.
        self._closed_notes = np.full(mode.size, "", dtype=object)
        idx = np.nonzero((res["status"] == STATUS_CONVERGED) & ((mode == FIRST_CLOSED) | (mode == SECOND_CLOSED)))[0]
        if idx.size:
            excess, duty = self._closed_branch_at_least_flow(ops, res, idx, mode[idx] == FIRST_CLOSED)
            # A closed branch whose outlet at its least flow lies kelvins above its setpoint needs
            # more flow, so its valve would open: the search starved it (e.g. the other valve, at
            # its maximum, taking the compressor's flow at a low suction iterate), its bulb did not
            # close it. Not a state of the circuit: not converged, said so.
            starved = excess > _STARVED_EXCESS
            self._mark_invalid(
                res,
                idx[starved],
                STATUS_NOT_CONVERGED,
                [
                    f"the search closed the {labels[int(mode[i] != FIRST_CLOSED)]} valve, but at the least flow "
                    f"its model covers that branch leaves {x / CP_SCALE:.3g} K above its setpoint: its valve "
                    "would open (not converged)"
                    for i, x in zip(idx[starved], excess[starved], strict=True)
                ],
            )
            opens = (excess > OUTER_FTOL * CP_SCALE) & ~starved
            for i, d in zip(idx[opens], duty[opens], strict=True):
                self._closed_notes[i] = (
                    f"; nearly closed: its flow lies between 0 and that least flow, its duty below "
                    f"{d / 1e3:.2g} kW is left out"
                )
        return saturated

    def _outside_axes(self, ops: dict) -> np.ndarray:
        """Per point, the first operating input outside a component model's axes (its reason), else ''.

        Of parallel branches none is checked: the search may close a branch whose model cannot
        take its stream (coolant below the chiller LUT, colder than the cabin's evaporation)."""
        branches = [] if self.circuit.parallel else [b.component for b in self.circuit.branches]
        components = ["compressor", "condenser", *branches]
        reasons = np.full(ops["speed"].size, "", dtype=object)
        for component in components:
            why = self.models.outside_axes(component, ops)
            reasons = np.where(reasons == "", why, reasons)
        return reasons

    def _check_suction_closure(self, res: dict, saturated: np.ndarray) -> None:
        """Not converged where the suction state is not the evaporating branches' outlet (mixture).

        The energy balance closes on it. The closure can stop off it on a jump of the mixture (the
        split changing branch between two suction iterates), or on a jump of a branch's outlet
        with the suction pressure (the chiller on coolant below -5 degC, dropping 30-45 % of its
        inlet pressure: up to kilojoules per kilogram off, balances 6 % off before this check).
        """
        with np.errstate(invalid="ignore"):
            off = (res["status"] == STATUS_CONVERGED) & (np.abs(res["h_A_evap"] - res["h_A"]) > MIX_TOL)
        what = "the branches' mixture" if self.circuit.parallel else "the evaporating branch's outlet"
        self._mark_invalid(
            res,
            off,
            STATUS_NOT_CONVERGED,
            [
                f"the suction closure stopped {abs(x):.3g} J/kg off {what} (not converged)"
                for x in (res["h_A_evap"] - res["h_A"])[off]
            ],
        )
        saturated &= ~off

    def _closed_branch_at_least_flow(
        self, ops: dict, res: dict, idx: np.ndarray, first_closed: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The closed branch of points ``idx`` run at the least flow its model covers, at the solved
        suction: its outlet's excess [J/kg] over the setpoint state, and its duty [W] there."""
        names = [b.component for b in self.circuit.branches]
        sub = {k: v[idx] for k, v in ops.items()}
        p_A, h_C = res["p_A"][idx], res["h_C"][idx]
        with np.errstate(invalid="ignore", divide="ignore"):
            h_set = self.models.compressor(
                sub["speed"], self.sat.temperature(p_A) + sub["setpoint"], p_A, res["p_B"][idx] / p_A
            )["h_in"]
        excess, duty = np.full(idx.size, np.nan), np.full(idx.size, np.nan)
        for b in (0, 1):
            k = np.nonzero(first_closed == (b == 0))[0]
            if k.size == 0:
                continue
            o = {c: v[k] for c, v in sub.items()}
            least = np.full(k.size, self.models.flow_range(names[b])[0] * (1 + 1e-6))
            drop = converged_drop(self._ctx, names[b], o, least, p_A[k], h_C[k], np.zeros(k.size))
            h_out = branch(self._ctx, names[b], o, least, p_A[k] + drop, h_C[k])["h_out_continued"]
            excess[k], duty[k] = h_out - h_set[k], least * (h_out - h_C[k])
        return excess, duty

    def _solve_again(self, ops: dict, res: dict, idx: np.ndarray, modes: np.ndarray) -> None:
        """Solve the points ``idx`` again with their branch modes set to ``modes`` (``ops`` and ``res`` in place)."""
        ops["branch_mode"][idx] = modes
        r, _ = solve_at(self._ctx, {k: v[idx] for k, v in ops.items()})
        for k, v in r.items():
            res[k][idx] = v

    @staticmethod
    def _mark_invalid(res: dict, where: np.ndarray, status: int, reasons) -> None:
        """Mark the points ``where`` (mask or indices) ``status`` with their ``reasons``, their
        states NaN (in place)."""
        res["status"][where] = status
        res["reason"][where] = reasons
        for v in res.values():
            if v.dtype.kind == "f":
                v[where] = np.nan

    def _float_superheat(
        self, ops: dict, res: dict, idx: np.ndarray, key: str = "valve_opening", share: np.ndarray | None = None
    ) -> None:
        """Cycle of the points ``idx`` with the valve at its maximum opening; written into ``res``.

        A thermostatic valve at its maximum opening (its stroke's end) can
        open no further as the superheat rises: it no longer holds the
        superheat, which floats. The valve's orifice law at the maximum flow
        area :math:`S_{max} = S_{nom} Q_{max}/Q_{nom}` [m2] (capacities
        :math:`Q` [W]) then closes the suction side in place of the setpoint:

        .. math:: \\dot m = S_{max} \\sqrt{2 \\rho_C (p_C - p_D)}

        (mass flow [kg/s], liquid density at the valve inlet [kg/m3],
        pressures [Pa]), the law the cycle uses for the opening it needs. The
        superheat :math:`\\Delta T_{sh}` [K] is the root of

        .. math:: g(\\Delta T_{sh}) = \\ln\\frac{S(\\Delta T_{sh})}{S_{max}}

        where :math:`S(\\Delta T_{sh})` is the opening that passes the flow of
        the cycle solved with the superheat held at :math:`\\Delta T_{sh}`.
        :math:`g` falls as the superheat rises (less flow at a lower suction
        pressure, through a larger pressure drop) and is positive at the
        setpoint, so the root lies above the setpoint: a saturated valve
        starves the evaporator, it never floods it. :math:`g` is nearly
        linear, about -0.0125 per kelvin (-0.009 to -0.018 over the envelope),
        and falls a little faster as the superheat rises, so that its secant
        slope from the setpoint to the root grows with :math:`g_0 = g`
        (setpoint): the first step goes 0.9 of the shift that slope
        (``_SH_FIRST_SLOPE``) gives, short of the root in most points, the
        second the secant estimate from the setpoint, which lands just beyond
        it; further secant steps (overshot) follow where it does not. Once
        bracketed, inverse quadratic interpolation through the three latest
        points (the chord where it leaves the bracket) and then the regula
        falsi of the pressures (:func:`bracketed_root`) find the root, to
        1e-4 in :math:`g` (about 0.01 K); a point stops at any step that lands
        within that. Every evaluation is a whole cycle solve, warm-started by
        extrapolating the suction and discharge pressures and the
        evaporator's drop linearly from the point's two latest superheats
        (from the setpoint alone, by their typical changes in
        :math:`g_0`), with a suction-closure slope fit for floating
        superheats; where a trial superheat leaves the models' envelope the
        point fails with that reason (prefixed "with the valve at its maximum
        opening"). About four cycle solves per batch, most points converging
        in three.

        ``key`` is the result holding the saturated valve's opening
        (``valve_opening_chiller``: the chiller's valve of two parallel
        branches, whose branch floats while the other holds the setpoint;
        the superheat iterated on is then the suction mixture's, see
        :meth:`_parallel_limits`), and ``share`` the saturated branch's share
        of the flow at the setpoint (default 1): the mixture's superheat
        moves that share of the branch's, so the typical changes per kelvin
        above are divided by it.
        """
        log_max = np.log(self.max_opening)
        sub = {k: v[idx] for k, v in ops.items()}
        m = idx.size
        store = {k: np.asarray(v)[idx].copy() for k, v in res.items()}
        # Warm starts: the two latest solved superheats of each point, with their suction
        # saturation temperature, discharge pressure and evaporator pressure drop, to
        # extrapolate linearly to the next superheat (from one: their typical changes,
        # _SH_FIRST_T, _SH_FIRST_LN_PB, _SH_FIRST_DP).
        seen = np.stack([sub["superheat"], np.full(m, np.nan)])
        known = {
            "t": self.sat.temperature(res["p_A"][idx]),
            "p_B": res["p_B"][idx],
            "dp": (res["p_D"] - res["p_A"])[idx],
        }
        known = {k: np.stack([v, np.full(m, np.nan)]) for k, v in known.items()}
        fail = np.full(m, STATUS_OUTSIDE_ENVELOPE, np.int8)

        # ln(opening over the maximum) at the setpoint: positive where the valve saturates.
        g0 = np.maximum(np.log(res[key][idx]) - log_max, 0.0)
        share = np.ones(m) if share is None else np.clip(np.asarray(share, float), 0.05, 1.0)

        def guess(sh, i):
            s1, s0 = seen[0, i], seen[1, i]
            two = np.isfinite(s0) & (np.abs(s1 - s0) > 1e-9)
            with np.errstate(invalid="ignore", divide="ignore"):
                w = np.where(two, (sh - s1) / (s1 - s0), 0.0)
            g = {k: np.where(two, v[0, i] + w * (v[0, i] - v[1, i]), v[0, i]) for k, v in known.items()}
            # From one solved superheat: the typical changes over the shift to the root.
            d, g0_i = (sh - s1) / share[i], g0[i]
            one = {
                "t": known["t"][0, i] + d * (_SH_FIRST_T[0] + _SH_FIRST_T[1] * g0_i),
                "p_B": known["p_B"][0, i] * np.exp(d * (_SH_FIRST_LN_PB[0] + _SH_FIRST_LN_PB[1] * g0_i)),
                "dp": known["dp"][0, i] * (1.0 + d * (_SH_FIRST_DP[0] + _SH_FIRST_DP[1] * g0_i)),
            }
            g = {k: np.where(two, v, one[k]) for k, v in g.items()}
            g["p_B"] = np.where(g["p_B"] > 0, g["p_B"], known["p_B"][0, i])
            g["dp"] = np.maximum(g["dp"], 0.0)
            return g

        def fun(sh, i):
            ops_i = {k: v[i] for k, v in sub.items()}
            ops_i["superheat"] = sh
            g = guess(sh, i)
            r, _ = solve_at(
                self._ctx, ops_i, t_guess=g["t"], p_B_guess=g["p_B"], dp_guess=g["dp"], outer_slope=_SH_OUTER_SLOPE
            )
            for k, v in r.items():
                store[k][i] = v
            ok = r["status"] == STATUS_CONVERGED
            with np.errstate(invalid="ignore", divide="ignore"):
                f = np.where(ok, np.log(r[key]) - log_max, np.nan)
            k = i[ok]
            seen[1, k], seen[0, k] = seen[0, k], sh[ok]
            new = {"t": self.sat.temperature(r["p_A"]), "p_B": r["p_B"], "dp": r["p_D"] - r["p_A"]}
            for name, v in known.items():
                v[1, k], v[0, k] = v[0, k], new[name][ok]
            fail[i[~ok]] = r["status"][~ok]
            return f, np.where(ok, "", r["reason"])

        # Bracket: secant steps up from the setpoint, plus 0.5 K.
        lo = sub["superheat"].copy()
        f_lo = np.log(res[key][idx]) - log_max
        hi, f_hi = np.full(m, np.nan), np.full(m, np.nan)
        why_hi = np.full(m, "", dtype=object)
        slope = (_SH_FIRST_SLOPE[0] + _SH_FIRST_SLOPE[1] * g0) / share
        sh = np.full(m, np.nan)
        state = np.full(m, 3, np.int8)
        why = np.full(m, "", dtype=object)
        going = np.arange(m)
        # The three latest superheats evaluated and their residuals, newest first (for the quadratic step).
        px, pf = np.full((3, m), np.nan), np.full((3, m), np.nan)
        px[0], pf[0] = lo, f_lo
        for step in range(_SH_BRACKET_STEPS):
            if going.size == 0:
                break
            # The first step goes most of the way the estimate from g0 gives (a step far beyond
            # the root may leave the models' envelope, and such points cost many evaluations);
            # the second follows the secant slope measured, which overshoots a little; later
            # steps overshoot more.
            if step == 0:
                x = lo[going] + np.clip(-_SH_FIRST_SHARE * f_lo[going] / slope[going], 0.02, _SH_MAX_STEP)
            elif step == 1:
                x = lo[going] + np.clip(-f_lo[going] / slope[going] + 0.02, 0.02, _SH_MAX_STEP)
            else:
                x = lo[going] + np.clip(-_SH_OVERSHOOT * f_lo[going] / slope[going] + 0.5, 0.5, _SH_MAX_STEP)
            f, why_x = fun(x, going)
            px[1:, going], pf[1:, going] = px[:-1, going], pf[:-1, going]
            px[0, going], pf[0, going] = x, f
            # A step onto the root (within the tolerance) ends that point's search.
            done = np.isfinite(f) & (np.abs(f) < _SH_FTOL)
            sh[going[done]], state[going[done]] = x[done], 1
            up = np.isfinite(f) & (f > 0) & ~done
            with np.errstate(invalid="ignore", divide="ignore"):
                s = (f - f_lo[going]) / (x - lo[going])
            k = going[up]
            slope[k] = np.where(s[up] < 0, s[up], slope[k])
            lo[k], f_lo[k] = x[up], f[up]
            k = going[~up & ~done]
            hi[k], f_hi[k], why_hi[k] = x[~up & ~done], f[~up & ~done], why_x[~up & ~done]
            going = going[up]
        # Before the regula falsi, where both ends are finite: inverse quadratic interpolation
        # through the three latest points where it stays inside the bracket, else the chord
        # (ln(opening) bends: a chord whose far end lies at the setpoint misses the root by up
        # to a few 0.1 K, a parabola through three points near it by far less).
        for _ in range(_SH_QUAD_STEPS):
            q = np.nonzero((state == 3) & np.isfinite(hi) & np.isfinite(f_hi))[0]
            if q.size == 0:
                break
            (x0, x1, x2), (f0, f1, f2) = px[:, q], pf[:, q]
            a, b, fa, fb = lo[q], hi[q], f_lo[q], f_hi[q]
            with np.errstate(invalid="ignore", divide="ignore"):
                xq = (
                    x0 * f1 * f2 / ((f0 - f1) * (f0 - f2))
                    + x1 * f0 * f2 / ((f1 - f0) * (f1 - f2))
                    + x2 * f0 * f1 / ((f2 - f0) * (f2 - f1))
                )
            x = np.where(np.isfinite(xq) & (xq > a) & (xq < b), xq, b - fb * (b - a) / (fb - fa))
            f, w = fun(x, q)
            px[1:, q], pf[1:, q] = px[:-1, q], pf[:-1, q]
            px[0, q], pf[0, q] = x, f
            nan = ~np.isfinite(f)
            # Converged as in bracketed_root: a residual within the tolerance or a bracket narrower than it.
            done = ~nan & ((np.abs(f) < _SH_FTOL) | (np.abs(b - a) < _SH_XTOL * np.abs(x)))
            sh[q[done]], state[q[done]] = x[done], 1
            # A NaN between two finite ends ends the search, as in bracketed_root.
            state[q[nan]], why[q[nan]] = 2, w[nan]
            pos, neg = ~nan & ~done & (f > 0), ~nan & ~done & (f <= 0)
            lo[q[pos]], f_lo[q[pos]] = x[pos], f[pos]
            hi[q[neg]], f_hi[q[neg]] = x[neg], f[neg]
        br = np.nonzero((state == 3) & np.isfinite(hi))[0]
        if br.size:
            sh[br], state[br], why[br] = bracketed_root(
                fun, lo[br], hi[br], f_lo[br], f_hi[br], br, _SH_XTOL, _SH_FTOL, why_hi=why_hi[br]
            )
        sh[state != 1] = np.nan
        status, reason = store["status"], store["reason"]
        status[state == 2] = fail[state == 2]
        reason[state == 2] = [f"with the valve at its maximum opening, {w}" for w in why[state == 2]]
        status[state == 3] = STATUS_NOT_CONVERGED
        reason[state == 3] = "superheat iteration with the valve at its maximum opening did not converge"
        reason[going] = [
            f"with the valve at its maximum opening the superheat rises above {x:.3g} K" for x in lo[going]
        ]
        failed = state != 1
        for v in store.values():
            if v.dtype.kind == "f":
                v[failed] = np.nan
        store[key][~failed] = self.max_opening
        for k, v in store.items():
            res[k][idx] = v

    def _flag(self, res: dict, ops: dict, saturated: np.ndarray) -> None:
        """Flag the converged points where the valve is saturated or frost may form (in place).

        Frost: the evaporator bench's status ``valid_frost_risk_surface_below_0C``
        (its coldest surface below 0 degC, under condensate) at the solved
        evaporator point; on LUTs, interpolated as the share of frost-risk
        nodes in the weight, flagged from 0.5.
        """
        status, reason = res["status"], res["reason"]
        ok = status == STATUS_CONVERGED
        sat = ok & saturated
        frost = ok & (np.nan_to_num(res["frost_risk"]) >= 0.5)
        mode = ops.get("branch_mode", np.zeros(status.size, np.int8))
        closed = ok & ((mode == FIRST_CLOSED) | (mode == SECOND_CLOSED))
        status[closed] = STATUS_BRANCH_CLOSED
        status[sat] = STATUS_VALVE_SATURATED
        status[frost] = STATUS_FROST_RISK
        status[sat & frost] = STATUS_VALVE_SATURATED_FROST_RISK
        labels = [b.label for b in self.circuit.branches]
        for i in np.nonzero(sat | frost | closed)[0]:
            notes = []
            if closed[i]:
                b = 0 if mode[i] == FIRST_CLOSED else 1
                least = self.models.flow_range(self.circuit.branches[b].component)[0]
                cause = self._closed_cause[i] or (
                    f"that branch would need less than the least flow its model covers ({least * 1e3:.3g} g/s) "
                    "to hold the setpoint"
                )
                notes.append(f"the {labels[b]} valve is closed (no flow, no heat): {cause}" + self._closed_notes[i])
            if sat[i] and self.circuit.parallel:
                b = 0 if mode[i] in (FIRST_FLOATS, SECOND_CLOSED) else 1
                key = "superheat_actual" if b == 0 else "superheat_chiller"
                notes.append(
                    f"the {labels[b]} valve is at its maximum opening ({self.max_opening:.3g} x nominal): its "
                    f"superheat floats at {res[key][i]:.3g} K, above its setpoint {ops['setpoint'][i]:.3g} K"
                )
            elif sat[i]:
                notes.append(
                    f"the valve is at its maximum opening ({self.max_opening:.3g} x nominal): the superheat floats "
                    f"at {res['superheat_actual'][i]:.3g} K, above its setpoint {ops['superheat'][i]:.3g} K"
                )
            if frost[i]:
                notes.append("an evaporator surface is below 0 degC under condensate: frost risk")
            reason[i] = "; ".join(notes)

    #: Maximum over nominal opening of the valve (its maximum over nominal capacity), set by solve.
    max_opening = np.nan
