"""Steady-state vapor-compression cycle: closure on two pressures, vectorised.

States: A evaporator outlet = compressor suction, B compressor discharge =
condenser inlet, C condenser outlet = valve inlet, D valve outlet =
evaporator inlet. The evaporating side is one branch (the cabin evaporator or
the battery chiller) or both in parallel (:mod:`evtms.cycle.topology`; with two
branches, A is the mixed suction state and D the first branch's valve outlet,
the flow split is solved at each suction iterate, :meth:`CycleSolver._parallel`;
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

from evtms.cycle.roots import (  # noqa: F401  (bracketed_root stays importable from here)
    bracket,
    bracketed_root,
    pressure_root,
    range_status,
    tightest_bound,
)
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

#: Figures every valid point has finite (a closed branch's are 0; its superheat and opening may be NaN).
_MUST_BE_FINITE = ("p_A", "p_B", "mdot", "Q_evap", "Q_latent", "Q_chiller", "Q_cond", "W", "COP")

#: Largest difference [J/kg] between the suction state and the branches' mixture at a solved parallel
#: point (evtms.cycle.state.MIX_TOL, under the name the tests know).
_MIX_TOL = MIX_TOL
#: Outlet excess [J/kg, about 2 K] over its setpoint of a closed branch at its least flow beyond
#: which its valve would open: the closing is not a state of the circuit.
_STARVED_EXCESS = 2000.0

#: The suction search's low end: evaporating this far [K] below the coldest open branch's
#: secondary inlet, or at _SUCTION_LOW_FLOOR [K] where that is lower.
_SUCTION_LOW_BELOW = 45.0
_SUCTION_LOW_FLOOR = 243.15

#: Typical slopes of the closures in saturation temperature [1/K]: condenser, suction superheat.
_INNER_SLOPE = -0.075
_OUTER_SLOPE = -4.0
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
#: per kelvin of suction saturation than at the setpoint, _OUTER_SLOPE, so that its bracket holds the root).
_SH_OUTER_SLOPE = -1.5
#: Inverse-quadratic steps once bracketed, before the regula falsi; largest bracketing step [K] and number
#: of steps, tolerances in superheat (relative) [1] and in ln(opening) [1].
_SH_QUAD_STEPS = 3
_SH_MAX_STEP = 25.0
_SH_BRACKET_STEPS = 4
_SH_XTOL = 1e-4
_SH_FTOL = 1e-4


def _no_heat_flow(result: dict) -> np.ndarray:
    """Points where a heat exchanger's refrigerant inlet is not on the side of the secondary
    stream that lets heat flow the required way (its bench status; LUTs hold NaN there)."""
    return np.asarray(result.get("no_heat_flow", False), bool)


class _Scattered:
    """The latest evaluation of every point, gathered from evaluations of subsets.

    Holds a (nested) dict of per-point arrays as returned by
    ``CycleSolver._discharge_side``; ``put(i, r)`` writes the results of the
    points ``i``.
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

        def blank(d: dict) -> None:
            for k, v in d.items():
                if isinstance(v, dict):
                    blank(v)
                elif k == "reason":
                    v[failed] = reason[failed]
                else:
                    v[failed] = np.nan

        blank(self.data)
        return self.data


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

    # -- the evaporating side ------------------------------------------------
    def _branch(self, component: str, ops: dict, mdot, p_in, h_in) -> dict:
        """One evaporating branch's model at refrigerant flow ``mdot``, inlet ``(p_in, h_in)``."""
        if component == "evaporator":
            r = self.models.evaporator(mdot, ops["blower"], p_in, h_in, ops["T_cabin"], ops["RH_cabin"])
        else:
            r = self.models.chiller(mdot, p_in, h_in, ops["mdot_coolant"], ops["T_coolant_in"])
        if self.circuit.parallel and "no_heat_flow" in r:
            # A branch whose inlet is not colder than its stream takes no heat: its outlet is its inlet.
            none = r["no_heat_flow"] & np.isfinite(np.asarray(h_in, float))
            r["h_out_continued"] = np.where(none, h_in, r["h_out_continued"])
            r["p_out"] = np.where(none, p_in, r["p_out"])
            r["reason"] = np.where(none, "", r["reason"])
        return r

    def _converged_drop(self, component: str, ops: dict, mdot, p_out, h_in, drop: np.ndarray) -> np.ndarray:
        """A branch's pressure drop [Pa] at outlet pressure ``p_out``: the fixed point of
        ``drop = p_in - p_out(p_in)`` from ``drop``, to :data:`DP_TOL` in at most
        :data:`DP_PASSES` passes (each on the points still moving; where the model
        returns NaN the drop is kept)."""
        drop = np.asarray(drop, float).copy()
        todo = np.arange(drop.size)
        for _ in range(DP_PASSES):
            p_in = p_out[todo] + drop[todo]
            sub = {k: v[todo] for k, v in ops.items()}
            out = self._branch(component, sub, mdot[todo], p_in, h_in[todo])["p_out"]
            new = np.where(np.isfinite(out), p_in - out, drop[todo])
            moving = np.abs(new - drop[todo]) > DP_TOL
            drop[todo] = new
            todo = todo[moving]
            if todo.size == 0:
                break
        return drop

    def _secondary_temperature(self, ops: dict) -> np.ndarray:
        """The coldest secondary inlet of the open branches: every open branch must evaporate below it [K]."""
        temps = [np.asarray(ops[b.secondary_temperature], float) for b in self.circuit.branches]
        coldest = np.minimum.reduce(temps)
        if self.circuit.parallel and "branch_mode" in ops:
            mode = ops["branch_mode"]
            coldest = np.where(mode == FIRST_CLOSED, temps[1], np.where(mode == SECOND_CLOSED, temps[0], coldest))
        return coldest

    def _run_branch(self, component: str, ops: dict, mdot, p_in, h_in, open_: np.ndarray) -> dict:
        """:meth:`_branch` where ``open_``; a closed branch (no flow) leaves its inlet state, no heat."""
        if open_.all():
            return self._branch(component, ops, mdot, p_in, h_in)
        n = open_.size
        out = {
            "h_out_continued": np.array(h_in, float, copy=True),
            "p_out": np.array(p_in, float, copy=True),
            "reason": np.full(n, "", dtype=object),
            "Q_latent": np.zeros(n),
            "frost_risk": np.zeros(n),
            "no_heat_flow": np.zeros(n, bool),
        }
        k = np.nonzero(open_)[0]
        if k.size:
            r = self._branch(component, {c: v[k] for c, v in ops.items()}, mdot[k], p_in[k], h_in[k])
            for key, v in r.items():
                v = np.asarray(v)
                if key not in out:
                    out[key] = np.full(n, "", dtype=object) if v.dtype == object else np.full(n, np.nan)
                out[key][k] = v
        return out

    def _parallel(
        self,
        ops: dict,
        mdot: np.ndarray,
        p_A: np.ndarray,
        h_D: np.ndarray,
        idx: np.ndarray,
        final: bool,
        h_set: np.ndarray | None = None,
    ):
        r"""Two evaporating branches in parallel from the valves to the suction, at total flow ``mdot``.

        Both valves see the condenser's liquid (enthalpy ``h_D``) and both
        branches end at the suction pressure ``p_A``, each after its own
        pressure drop (a fixed point per branch, one pass per suction iterate,
        as the single branch's). Each valve holds its branch's outlet at the
        setpoint superheat; at a suction iterate the flow splits so that both
        outlets leave at the same enthalpy,

        .. math:: h_{out,1}((1 - s)\,\dot m) = h_{out,2}(s\,\dot m)

        (``h_out_continued`` of each branch [J/kg], ``s`` the share of the
        flow through the second branch [1]). More flow through a branch
        lowers its outlet enthalpy, so the difference rises monotonically
        with ``s``: regula falsi (:func:`bracketed_root`) on ``s`` within the
        flows the branch models cover, warm-started from the previous suction
        iterate's split. At the suction root both outlets are at the setpoint,
        and the outlets mix at that state. ``idx`` are the points' indices in
        the whole batch; with ``final``, the stored split and drops are used
        as they are (the last iterate's).

        ``ops["branch_mode"]`` (absent: all 0) changes a point's split
        (:meth:`solve` sets it): 1 (2), the first (second) branch's valve at
        its maximum opening: the other branch alone holds the setpoint, its
        outlet at ``h_set`` (the enthalpy at the setpoint superheat at
        ``p_A`` [J/kg]), and the suction superheat (``ops["superheat"]``) is
        the mixture's, found by :meth:`_float_superheat`; 3 (4), the first
        (second) branch's valve closed: all the flow goes through the other
        branch, and the closed one leaves its inlet state with no flow and no
        heat.

        Returns the mixed outlet (``h_out_continued``, ``p_out`` = ``p_A``),
        ``reason``, ``p_D`` (the first branch's inlet), ``h_set``, and per
        branch ``branches`` (model results), ``flows`` [kg/s] and ``inlets`` [Pa].
        """
        names = [b.component for b in self.circuit.branches]
        labels = [b.label for b in self.circuit.branches]
        n = p_A.size
        mode = np.asarray(ops.get("branch_mode", np.zeros(n)), int)
        if h_set is None:
            h_set = np.full(n, np.nan)
        inlets = {c: p_A + self._dp_branch[c][idx] for c in names}
        (lo1, hi1), (lo2, hi2) = (self.models.flow_range(c) for c in names)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_lo = np.maximum(lo2 / mdot, 1.0 - hi1 / mdot) * (1 + 1e-9)
            s_hi = np.minimum(1.0 - lo1 / mdot, hi2 / mdot) * (1 - 1e-9)
            # Which bound binds: the second (first) branch at the least flow its model covers.
            second_least = lo2 / mdot >= 1.0 - hi1 / mdot
            first_least = 1.0 - lo1 / mdot <= hi2 / mdot
        split_mode = mode <= SECOND_FLOATS
        first_closed, second_closed = mode == FIRST_CLOSED, mode == SECOND_CLOSED
        with np.errstate(invalid="ignore"):
            fits = np.where(
                split_mode,
                s_lo < s_hi,
                np.where(first_closed, (mdot >= lo2) & (mdot <= hi2), (mdot >= lo1) & (mdot <= hi1)),
            )
        ok = np.isfinite(mdot) & np.isfinite(p_A) & np.isfinite(h_D) & fits
        reason = np.full(n, "", dtype=object)
        bad = ~ok & np.isfinite(mdot)
        reason[bad & split_mode] = "the flow cannot be split between the branches within their models' flows"
        reason[bad & ~split_mode] = "with one valve closed, the other branch's model does not cover the whole flow"
        open1, open2 = ~first_closed, ~second_closed

        # ``i``: the points' positions in this call's arrays (``idx[i]`` in the whole batch).
        def evaluate(share: np.ndarray, i: np.ndarray) -> tuple[dict, dict]:
            o = {k: v[i] for k, v in ops.items()}
            m = mdot[i]
            r1 = self._run_branch(names[0], o, m * (1.0 - share), inlets[names[0]][i], h_D[i], open1[i])
            r2 = self._run_branch(names[1], o, m * share, inlets[names[1]][i], h_D[i], open2[i])
            return r1, r2

        def residual(share: np.ndarray, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r1, r2 = evaluate(share, i)
            h1, h2 = r1["h_out_continued"], r2["h_out_continued"]
            md = mode[i]
            # Both hold the setpoint: equal outlets; one valve saturated: the other one at the setpoint.
            f = np.where(md == FIRST_FLOATS, h2 - h_set[i], np.where(md == SECOND_FLOATS, h_set[i] - h1, h2 - h1))
            why = np.where(r1["reason"] != "", r1["reason"], r2["reason"])
            return f / CP_SCALE, why

        share = np.where(ok, self._split[idx], np.nan)
        share[ok & first_closed] = 1.0
        share[ok & second_closed] = 0.0
        clamped = np.zeros(n, np.int8)

        def solve_split(todo: np.ndarray) -> None:
            """The split of the points ``todo`` at the present branch inlets, into ``share``."""
            lo, hi = s_lo[todo].copy(), s_hi[todo].copy()
            f_lo, f_hi = np.full(todo.size, np.nan), np.full(todo.size, np.nan)
            w_lo, w_hi = np.full(todo.size, "", dtype=object), np.full(todo.size, "", dtype=object)
            # Warm start: a narrow bracket around the previous split, where it holds the root.
            prev = share[todo]
            warm = np.isfinite(prev)
            if warm.any():
                k = np.nonzero(warm)[0]
                a = np.maximum(prev[k] - 0.03, lo[k])
                b = np.minimum(prev[k] + 0.03, hi[k])
                fa, _ = residual(a, todo[k])
                fb, _ = residual(b, todo[k])
                good = np.isfinite(fa) & np.isfinite(fb) & (fa > 0) & (fb <= 0)
                g = k[good]
                lo[g], hi[g], f_lo[g], f_hi[g] = a[good], b[good], fa[good], fb[good]
                warm[k[~good]] = False
            cold = np.nonzero(~warm)[0]
            if cold.size:
                f_lo[cold], w_lo[cold] = residual(lo[cold], todo[cold])
                f_hi[cold], w_hi[cold] = residual(hi[cold], todo[cold])
            no_root = ~((f_lo > 0) | ~np.isfinite(f_lo)) | ~((f_hi <= 0) | ~np.isfinite(f_hi))
            no_root |= ~np.isfinite(f_lo) & ~np.isfinite(f_hi)
            share[todo] = np.nan
            # One sign over the whole range of flows the models cover: one branch takes the least
            # flow its model covers (its valve nearly closed). The outlets then differ, and the
            # mixture still tells the suction closure which way to go; a root found so is not a
            # state with both valves holding their setpoint and fails in the final evaluation
            # (solve then closes that valve, where it is a branch at its least flow).
            finite = np.isfinite(f_lo) & np.isfinite(f_hi)
            low = no_root & finite & (f_lo <= 0)
            high = no_root & finite & (f_hi > 0)
            share[todo[low]], share[todo[high]] = lo[low], hi[high]
            kind = np.zeros(todo.size, np.int8)
            kind[low] = np.where(second_least[todo[low]], CLAMP_SECOND_LEAST, CLAMP_OTHER)
            kind[high] = np.where(first_least[todo[high]], CLAMP_FIRST_LEAST, CLAMP_OTHER)
            clamped[todo] = kind
            nan = no_root & ~low & ~high
            reason[todo[nan]] = np.where(~np.isfinite(f_lo[nan]), w_lo[nan], w_hi[nan])
            go = np.nonzero(~no_root)[0]
            if go.size:
                x, state, why = bracketed_root(
                    residual, lo[go], hi[go], f_lo[go], f_hi[go], todo[go], XTOL, INNER_FTOL, why_lo=w_lo[go]
                )
                fine = state == 1
                share[todo[go[fine]]] = x[fine]
                failed = np.where(state[~fine] == 3, "flow-split iteration did not converge", why[~fine])
                reason[todo[go[~fine]]] = failed

        if not final:
            # The split at the present drops, then each branch's drop at that split, until the
            # drops stop moving (see DP_TOL): the outlets then meet at p_A.
            todo = np.nonzero(ok)[0]
            for _ in range(DP_PASSES):
                split = todo[split_mode[todo]]
                if split.size:
                    solve_split(split)
                todo = todo[np.isfinite(share[todo])]
                if todo.size == 0:
                    break
                r1, r2 = evaluate(share[todo], todo)
                moving = np.zeros(todo.size, bool)
                for c, r in zip(names, (r1, r2), strict=True):
                    p_in = inlets[c][todo]
                    new = np.where(np.isfinite(r["p_out"]), p_in - r["p_out"], p_in - p_A[todo])
                    moving |= np.abs(new - (p_in - p_A[todo])) > DP_TOL
                    inlets[c][todo] = p_A[todo] + new
                todo = todo[moving]
                if todo.size == 0:
                    break
            for c in names:
                drop = inlets[c] - p_A
                self._dp_branch[c][idx] = np.where(np.isfinite(drop), drop, self._dp_branch[c][idx])
            self._split[idx] = np.where(np.isfinite(share), share, self._split[idx])
            self._clamped[idx] = clamped
        else:
            clamped = self._clamped[idx]
            # With a saturated valve the mixture depends on the split itself (not only on both outlets
            # being equal): the split of the last suction iterate, which may be the root's neighbour,
            # is solved again at the root (at the stored drops), so that the mixture closes there.
            again = np.nonzero(ok & (clamped == 0) & ((mode == FIRST_FLOATS) | (mode == SECOND_FLOATS)))[0]
            if again.size:
                kept, why = share[again].copy(), reason[again].copy()
                solve_split(again)
                lost = ~np.isfinite(share[again])
                share[again[lost]], reason[again[lost]] = kept[lost], why[lost]
        everyone = np.arange(n)
        r1, r2 = evaluate(share, everyone)
        flows = {names[0]: mdot * (1.0 - share), names[1]: mdot * share}
        branches = {names[0]: r1, names[1]: r2}
        with np.errstate(invalid="ignore"):
            h_mix = (flows[names[0]] * r1["h_out_continued"] + flows[names[1]] * r2["h_out_continued"]) / mdot
        if final:
            h_mix[clamped > 0] = np.nan
            lows = {CLAMP_FIRST_LEAST: (labels[0], lo1), CLAMP_SECOND_LEAST: (labels[1], lo2)}
            for kind, (label, least) in lows.items():
                reason[clamped == kind] = (
                    "no split of the flow brings both branch outlets to the setpoint within the flows "
                    f"their models cover (the {label} would need less than {least * 1e3:.3g} g/s)"
                )
            reason[clamped == CLAMP_OTHER] = (
                "no split of the flow brings both branch outlets to the setpoint within the flows "
                "their models cover (one branch would need more)"
            )
        for r in (r1, r2):
            reason = np.where(reason != "", reason, r["reason"])
        return {
            "h_out_continued": h_mix,
            "p_out": p_A.copy(),
            "reason": reason,
            "p_D": inlets[names[0]],
            "h_set": h_set,
            "branches": branches,
            "flows": flows,
            "inlets": inlets,
        }

    def _setpoint_enthalpy(self, ops: dict, p_A: np.ndarray, p_B: np.ndarray) -> np.ndarray | None:
        """Suction-side enthalpy at the setpoint superheat [J/kg] where one parallel valve is saturated
        (the other branch's outlet holds it; NaN elsewhere), from the compressor's inlet state; None
        where no point has a saturated parallel valve."""
        mode = ops.get("branch_mode")
        if mode is None:
            return None
        k = np.nonzero((mode == FIRST_FLOATS) | (mode == SECOND_FLOATS))[0]
        if k.size == 0:
            return None
        out = np.full(p_A.size, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            T = self.sat.temperature(p_A[k]) + ops["setpoint"][k]
            out[k] = self.models.compressor(ops["speed"][k], T, p_A[k], p_B[k] / p_A[k])["h_in"]
        return out

    # -- the two residuals ---------------------------------------------------
    def _discharge_side(self, ops: dict, p_A: np.ndarray, p_B: np.ndarray) -> dict:
        T_A = self.sat.temperature(p_A) + ops["superheat"]
        comp = self.models.compressor(ops["speed"], T_A, p_A, p_B / p_A)
        cond = self.models.condenser(comp["mdot"], ops["fan"], p_B, comp["h_out"], ops["T_amb"], ops["RH_amb"])
        # Target quality of a liquid subcooled by `subcooling` below saturation.
        p_C = cond["p_out"]
        h_l, h_v = self.sat.liquid_enthalpy(p_C), self.sat.vapour_enthalpy(p_C)
        x_target = -self.sat.liquid_cp(p_C) * ops["subcooling"] / (h_v - h_l)
        # Saturated-liquid outlet: the capacity ratio (coil over the coil needed to
        # condense fully) is smooth where x_out has its kink, exactly at this target.
        residual = 1.0 - cond["capacity_ratio"]
        if "h_out_continued" in cond:  # present whenever some point targets a subcooled outlet
            x_out = (cond["h_out_continued"] - h_l) / (h_v - h_l)
            residual = np.where(ops["subcooling"] > 0, x_out - x_target, residual)
        # Refrigerant not warmer than the air condenses nothing: far above the target.
        residual = np.where(_no_heat_flow(cond) & np.isfinite(comp["mdot"]), 1.0, residual)
        reason = np.where(comp["reason"] != "", comp["reason"], cond["reason"])
        return {"T_A": T_A, "comp": comp, "cond": cond, "residual": residual, "reason": reason}

    def _solve_discharge(self, ops: dict, p_A: np.ndarray, idx: np.ndarray) -> dict:
        """Discharge pressure p_B for each suction pressure: the condenser-outlet condition.

        ``idx`` are the points' indices in the whole batch. The first guess is
        the root at the previous suction iterate, with the slope found there;
        without one, condensing 13 K above the ambient air (the middle of the
        default circuit's envelope). Returns ``p_B``, ``status``, ``reason``
        and ``side``: the discharge side at the root (the solver's last
        evaluation, not a new one).
        """
        n = p_A.size
        (pr_lo, pr_hi), axes = self._pr, self._axes
        lo, lo_axis = tightest_bound(
            [
                (self.sat.pressure(ops["T_amb"] + 0.5), None),
                (pr_lo * p_A, axes["pr"][0]),
                (self._p_discharge[0], axes["p_discharge"][0]),
            ],
            upper=False,
        )
        hi, hi_axis = tightest_bound(
            [(self._p_discharge[1], axes["p_discharge"][1]), (pr_hi * p_A, axes["pr"][1])], upper=True
        )
        last = _Scattered(n)

        def residual(pb, i):
            r = self._discharge_side({k: v[i] for k, v in ops.items()}, p_A[i], pb)
            last.put(i, r)
            return r["residual"], r["reason"]

        known = np.isfinite(self._guess[idx])
        t_guess = np.where(known, self.sat.temperature(self._guess[idx]), ops["T_amb"] + 13.0)
        slope = np.where(known & (self._slope[idx] < 0), self._slope[idx], _INNER_SLOPE)
        br = bracket(self.sat, residual, self.sat.temperature(lo), self.sat.temperature(hi), t_guess, slope, 10.0)
        self._slope[idx] = np.where(br.slope < 0, br.slope, self._slope[idx])
        status, reason = range_status(
            br,
            lo,
            lo_axis,
            hi,
            hi_axis,
            STATUS_CONDENSER_NO_ROOT,
            (
                "the condenser outlet is below its target even at the lowest discharge pressure searched",
                "the condenser outlet condition lies below the discharge pressure",
            ),
            (
                "the condenser cannot reach its outlet condition up to the highest discharge pressure searched",
                "the condenser outlet condition lies above the discharge pressure",
            ),
        )
        bad_pa = ~np.isfinite(p_A)
        status[bad_pa] = STATUS_OUTSIDE_ENVELOPE
        p_B = np.full(n, np.nan)
        todo = np.nonzero(status == STATUS_CONVERGED)[0]
        if todo.size:
            p_B[todo] = pressure_root(self.sat, residual, br, todo, INNER_FTOL, status, reason, "discharge-pressure")
        failed = status != STATUS_CONVERGED
        p_B[failed] = np.nan
        if last.data is None:  # nothing evaluated (no valid suction pressure)
            side = self._discharge_side(ops, p_A, p_B)
        else:  # each converged point's last evaluation was at its root
            side = last.result(failed, reason)
        return {"p_B": p_B, "status": status, "reason": reason, "side": side}

    def _suction_side(self, ops: dict, p_A: np.ndarray, idx: np.ndarray, final: bool = False) -> dict:
        """Superheat residual at suction pressure p_A (with the inner discharge solve).

        ``idx`` are the points' indices in the whole batch, for the warm start
        of the discharge pressure from the previous suction iterate. With
        ``final``, p_A is each point's root, the suction iterate last
        evaluated: the components are evaluated once more (with every output
        variable) at that iterate's discharge and evaporator-inlet pressures,
        without solving again.
        """
        if final:
            p_B = self._guess[idx]
            side = self._discharge_side(ops, p_A, p_B)
            dis = {"p_B": p_B, "status": np.full(p_A.size, STATUS_CONVERGED, np.int8), "reason": side["reason"]}
            dis["status"][~np.isfinite(p_B)] = STATUS_OUTSIDE_ENVELOPE
        else:
            dis = self._solve_discharge(ops, p_A, idx)
            self._guess[idx] = np.where(np.isfinite(dis["p_B"]), dis["p_B"], self._guess[idx])
            side = dis["side"]
        comp, cond = side["comp"], side["cond"]
        saturated = ops["subcooling"] <= 0
        h_D = self.sat.liquid_enthalpy(cond["p_out"])
        if "h_out_continued" in cond:
            h_D = np.where(saturated, h_D, cond["h_out_continued"])
        # Evaporator inlet = outlet pressure + its own drop: a fixed point, warm-started
        # from the drop at the previous suction iterate (the drop changes slowly).
        if self.circuit.parallel:
            h_set = self._setpoint_enthalpy(ops, p_A, dis["p_B"])
            evap = self._parallel(ops, comp["mdot"], p_A, h_D, idx, final, h_set)
            p_D = evap["p_D"]
        else:
            branch = self.circuit.branches[0].component
            if not final:
                self._dp_guess[idx] = self._converged_drop(branch, ops, comp["mdot"], p_A, h_D, self._dp_guess[idx])
            p_D = p_A + self._dp_guess[idx]
            evap = self._branch(branch, ops, comp["mdot"], p_D, h_D)
        # The valve holds the outlet at the superheat setpoint, i.e. at the compressor's
        # suction state A. The residual compares enthalpies (scaled to about kelvin):
        # interpolated outlet enthalpy stays smooth where the LUT's outlet temperature
        # has its kink (outlet turning two-phase), and matching it keeps the cycle's
        # energy balance.
        sh = (evap["h_out_continued"] - comp["h_in"]) / CP_SCALE
        # An inlet not colder than the air evaporates nothing: the outlet stays at h_D.
        sh = np.where(_no_heat_flow(evap) & np.isfinite(h_D), (h_D - comp["h_in"]) / CP_SCALE, sh)
        status = dis["status"].copy()
        reason = dis["reason"].copy()
        bad = (status == STATUS_CONVERGED) & ~np.isfinite(sh)
        status[bad] = STATUS_OUTSIDE_ENVELOPE
        reason[bad] = np.where(side["reason"][bad] != "", side["reason"][bad], evap["reason"][bad])
        residual = np.where(status == STATUS_CONVERGED, sh, np.nan)
        out = {"residual": residual, "status": status, "reason": reason}
        # A two-phase outlet: below saturated vapour (h_out_continued has no kink there).
        out["outlet_wet"] = evap["h_out_continued"] < self.sat.vapour_enthalpy(evap["p_out"])
        if final:
            out.update(p_B=dis["p_B"], p_D=p_D, side=side, evap=evap)
        return out

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
        res = self._solve_at(ops)
        valve, _ = self.models.valve()
        self.max_opening = valve.capacity_max / valve.capacity_nominal
        if self.circuit.parallel:
            saturated = self._parallel_limits(ops, res)
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

    def _parallel_limits(self, ops: dict, res: dict) -> np.ndarray:
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
          the other outlet at the setpoint, :meth:`_parallel`). The suction
          state is the outlets' mixture, with its own superheat, found as for
          a single branch (:meth:`_float_superheat`) so that the saturated
          valve passes its branch's flow at its maximum opening. Status 5
          (7 with frost risk); ``superheat_actual`` (the first branch) or
          ``superheat_chiller`` is the floating superheat. Where both valves
          would need more than their maximum (or the other one would, once
          the first floats), the point stays invalid (status 9).

        Every valid point's suction state must be the branches' mixture to
        within ``_MIX_TOL`` (the energy balance closes on it); one where the
        suction closure stopped on a jump of the mixture is status 4.
        """
        labels = [b.label for b in self.circuit.branches]
        mode = ops["branch_mode"]
        above_top = self._above_top.copy()  # of the first solve (a re-solve below resets it)
        # Why a closed valve closed, where not for the least flow (the default note in _flag).
        self._closed_cause = np.full(mode.size, "", dtype=object)
        # Closed valves: a branch that would need less than its model's least flow (at the last
        # suction iterate; where the suction search did not converge with the split at that
        # bound, it went back and forth across the flow at which that branch would close).
        kind = self._clamped.copy()
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
            drop = self._converged_drop(names[b], o, least, p_A[k], h_C[k], np.zeros(k.size))
            h_out = self._branch(names[b], o, least, p_A[k] + drop, h_C[k])["h_out_continued"]
            excess[k], duty[k] = h_out - h_set[k], least * (h_out - h_C[k])
        return excess, duty

    def _solve_again(self, ops: dict, res: dict, idx: np.ndarray, modes: np.ndarray) -> None:
        """Solve the points ``idx`` again with their branch modes set to ``modes`` (``ops`` and ``res`` in place)."""
        ops["branch_mode"][idx] = modes
        r = self._solve_at({k: v[idx] for k, v in ops.items()})
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

    def _solve_at(
        self,
        ops: dict,
        t_guess: np.ndarray | None = None,
        p_B_guess: np.ndarray | None = None,
        dp_guess: np.ndarray | None = None,
        outer_slope: np.ndarray | float = _OUTER_SLOPE,
    ) -> dict[str, np.ndarray]:
        """The cycle with the evaporator-outlet superheat at ``ops["superheat"]`` (the valve not limited).

        ``t_guess`` [K] is the first guess of the suction saturation
        temperature (default 23 K below the cabin air), ``p_B_guess`` [Pa]
        that of the discharge pressure (default condensing 13 K above the
        ambient air) and ``dp_guess`` [Pa] that of the evaporator's pressure
        drop (default 0; its fixed point takes one pass per suction iterate,
        so a warm start whose root takes few iterates needs a good one).
        Returns the result of :meth:`solve` with the statuses 0-4 and 8 (no
        flags) and ``valve_opening`` the opening that passes the cycle's
        flow, whatever its maximum.
        """
        n = ops["speed"].size
        limits = self.models.limits()
        # A hair inside the pressure ranges: the saturation temperature <-> pressure
        # round trip must not step off a LUT's last node.
        self._p_discharge = (limits["p_discharge"][0] * (1 + 1e-9), limits["p_discharge"][1] * (1 - 1e-9))
        # A hair inside the compressor's pressure-ratio range, so that p_B/p_A stays on its grid.
        self._pr = (max(limits["pr"][0], 1.0) * (1 + 1e-9), limits["pr"][1] * (1 - 1e-9))
        self._axes = limits["axes"]
        # The low end: evaporating 45 K below the (coldest) secondary stream, which leaves a large
        # superheat, or at -30 degC where that is lower. Against hot coolant a starved branch runs
        # further below it (valve at its maximum, full speed, coolant at 45 degC: -1 degC at the
        # outlet, 46 K below), which a bound relative to the stream alone cut off.
        T_sec = self._secondary_temperature(ops)
        floor = np.minimum(T_sec - _SUCTION_LOW_BELOW, _SUCTION_LOW_FLOOR)
        # Not below the saturation table (its pressure would be NaN, and the search with it).
        floor = np.maximum(floor, self.sat.T[0] + 0.01)
        lows, highs = [(self.sat.pressure(floor), None)], [(self.sat.pressure(T_sec - 0.5), None)]
        for where, lim in self._suction_limits(ops, limits):
            (p_lo_lim, p_hi_lim), (lo_name, hi_name) = lim["p_suction"], lim["axes"]["p_suction"]
            lows.append((np.where(where, p_lo_lim * (1 + 1e-9), -np.inf), lo_name))
            highs.append((np.where(where, p_hi_lim * (1 - 1e-9), np.inf), hi_name))
        lo, lo_axis = tightest_bound(lows, upper=False)
        hi, hi_axis = tightest_bound(highs, upper=True)
        t_lo, t_hi = self.sat.temperature(lo), self.sat.temperature(hi)
        self._guess = np.full(n, np.nan) if p_B_guess is None else np.asarray(p_B_guess, float).copy()
        self._dp_guess = np.zeros(n) if dp_guess is None else np.nan_to_num(np.asarray(dp_guess, float))
        self._dp_branch = {b.component: np.zeros(n) for b in self.circuit.branches}
        self._split = np.full(n, np.nan)
        self._clamped = np.zeros(n, np.int8)
        self._slope = np.full(n, np.nan)
        self.models.subcooled_targets(bool(np.any(ops["subcooling"] > 0)))

        # The status each failure reason came with (the discharge side's own: a condenser that
        # cannot reach its outlet at any discharge pressure is not the end of a model's envelope).
        failure_status: dict[str, int] = {}

        def residual(pa, i):
            r = self._suction_side({k: v[i] for k, v in ops.items()}, pa, i)
            failed = (r["status"] != STATUS_CONVERGED) & (r["reason"] != "")
            failure_status.update(zip(r["reason"][failed], r["status"][failed].tolist(), strict=True))
            return r["residual"], r["reason"]

        # First guess: evaporating 23 K below the cabin air, the middle of the default
        # circuit's envelope; the superheat falls about 4 K per kelvin above it.
        if t_guess is None:
            t_guess = T_sec - 23.0
        t_guess = np.where(np.isfinite(t_guess), t_guess, T_sec - 23.0)
        br = bracket(
            self.sat, residual, t_lo, t_hi, t_guess, np.broadcast_to(np.asarray(outer_slope, float), (n,)), 15.0
        )
        status, reason = range_status(
            br,
            lo,
            lo_axis,
            hi,
            hi_axis,
            STATUS_EVAPORATOR_NO_ROOT,
            (
                "the superheat stays below its setpoint even at the lowest suction pressure searched",
                "the superheat setpoint lies below the suction pressure",
            ),
            (
                "the superheat stays above its setpoint up to saturation at the secondary inlet temperature",
                "the superheat setpoint lies above the suction pressure",
            ),
        )
        f_lo, f_hi = br.f_lo, br.f_hi
        # Superheat above its setpoint up to the physical top (saturation 0.5 K below the coldest
        # secondary inlet): with branches in parallel, the one on that stream caps the search.
        self._above_top = (status == STATUS_EVAPORATOR_NO_ROOT) & br.hi_is_end & np.isfinite(f_hi) & (f_hi >= 0)
        # Superheat below its setpoint down to the physical low end (evaporating 45 K below
        # the secondary, or at -30 degC): where the outlet is still two-phase there, it floods.
        low = np.nonzero((status == STATUS_EVAPORATOR_NO_ROOT) & br.lo_is_end & np.isfinite(f_lo) & (f_lo <= 0))[0]
        if low.size:
            wet = self._suction_side({k: v[low] for k, v in ops.items()}, lo[low], low)["outlet_wet"]
            status[low[wet]] = STATUS_EVAPORATOR_WET
            reason[low[wet]] = (
                "the evaporator outlet stays two-phase down to the lowest suction pressure searched "
                "(evaporating 45 K below the secondary inlet, or at -30 degC): the evaporator floods and "
                "the compressor would draw liquid"
            )
        # Both ends outside a model's envelope: nothing to go on.
        both = ~np.isfinite(f_lo) & ~np.isfinite(f_hi) & (status == STATUS_CONVERGED)
        reason[both] = np.where(br.why_lo[both] != "", br.why_lo[both], br.why_hi[both])
        status[both] = [failure_status.get(x, STATUS_OUTSIDE_ENVELOPE) for x in reason[both]]
        p_A = np.full(n, np.nan)
        idx = np.nonzero(status == STATUS_CONVERGED)[0]
        if idx.size:
            p_A[idx] = pressure_root(
                self.sat, residual, br, idx, OUTER_FTOL, status, reason, "suction-pressure", failure_status
            )
        p_A[status != STATUS_CONVERGED] = np.nan
        return self._final_states(ops, p_A, status, reason)

    def _suction_limits(self, ops: dict, limits: dict) -> list[tuple[np.ndarray, dict]]:
        """The models' suction-pressure ranges per group of points: a closed branch's model does not
        bound the suction (a hot cabin alone may evaporate above the chiller LUT's last pressure)."""
        n = ops["speed"].size
        mode = np.asarray(ops.get("branch_mode", np.zeros(n)), int)
        if not self.circuit.parallel or not np.isin(mode, (FIRST_CLOSED, SECOND_CLOSED)).any():
            return [(np.ones(n, bool), limits)]
        names = [b.component for b in self.circuit.branches]
        return [
            (~np.isin(mode, (FIRST_CLOSED, SECOND_CLOSED)), limits),
            (mode == FIRST_CLOSED, self.models.limits(exclude=(names[0],))),
            (mode == SECOND_CLOSED, self.models.limits(exclude=(names[1],))),
        ]

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
            r = self._solve_at(ops_i, t_guess=g["t"], p_B_guess=g["p_B"], dp_guess=g["dp"], outer_slope=_SH_OUTER_SLOPE)
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

    def _final_states(self, ops: dict, p_A: np.ndarray, status: np.ndarray, reason: np.ndarray) -> dict:
        self.models.detailed(True)
        try:
            fin = self._suction_side(ops, p_A, np.arange(p_A.size), final=True)
            return self._collect(ops, p_A, status, reason, fin)
        finally:
            self.models.detailed(False)

    def _collect(self, ops: dict, p_A: np.ndarray, status: np.ndarray, reason: np.ndarray, fin: dict) -> dict:
        late = (status == STATUS_CONVERGED) & (fin["status"] != STATUS_CONVERGED)
        status[late] = fin["status"][late]
        reason[late] = fin["reason"][late]
        side, evap = fin["side"], fin["evap"]
        comp, cond = side["comp"], side["cond"]
        mdot = comp["mdot"]
        # State C: with a saturated-liquid outlet it is that condition at the LUT's
        # outlet pressure (the LUT's own h_out has its kink exactly there); a subcooled
        # liquid is T_sat minus its enthalpy below saturation over the liquid's cp, as
        # its target was set.
        p_C = cond["p_out"]
        saturated = ops["subcooling"] <= 0
        h_l, T_sat = self.sat.liquid_enthalpy(p_C), self.sat.temperature(p_C)
        h_C = np.where(saturated, h_l, cond["h_out_continued"])
        T_C = np.where(saturated, T_sat, T_sat - (h_l - h_C) / self.sat.liquid_cp(p_C))
        # Each branch: its flow, valve-outlet pressure and outlet enthalpy.
        names = [b.component for b in self.circuit.branches]
        if self.circuit.parallel:
            branches, flows, inlets = evap["branches"], evap["flows"], evap["inlets"]
        else:
            branches, flows, inlets = {names[0]: evap}, {names[0]: mdot}, {names[0]: fin["p_D"]}
        zero = np.zeros(p_A.size)
        # The opening (over the nominal) that passes a branch's flow at its valve drop, by
        # the valve's orifice law for a liquid inlet, mdot = S sqrt(2 rho_in dp); a
        # subcooled liquid's density is the saturated liquid's at its temperature.
        _, area = self.models.valve()
        rho_C = self.sat.liquid_density(np.where(saturated, p_C, self.sat.pressure(T_C)))
        opening = {}
        with np.errstate(invalid="ignore", divide="ignore"):
            for c in names:
                opening[c] = flows[c] / (area * np.sqrt(2.0 * rho_C * (p_C - inlets[c])))
        # Heat flows as each branch's flow times its enthalpy change, the outlet from its own model.
        heat = {c: 0.0 - flows[c] * (branches[c]["h_out_continued"] - h_C) for c in names}
        h_B = comp["h_out"]
        superheat = self._branch_superheats(ops, p_A, fin["p_B"], comp, evap, branches)
        res = {
            "p_A": p_A,
            "T_A": side["T_A"],
            "h_A": comp["h_in"],
            "p_B": fin["p_B"],
            "T_B": comp["T_out"],
            "h_B": h_B,
            "p_C": p_C,
            "T_C": T_C,
            "h_C": h_C,
            "p_D": fin["p_D"],
            "T_D": self.sat.temperature(fin["p_D"]),
            "h_D": h_C.copy(),
            "mdot": mdot,
            "mdot_evap": flows.get("evaporator", zero),
            "mdot_chiller": flows.get("chiller", zero),
            "Q_evap": heat.get("evaporator", zero),
            "Q_latent": branches["evaporator"]["Q_latent"] if "evaporator" in branches else zero,
            "Q_chiller": heat.get("chiller", zero),
            "Q_cond": mdot * (h_B - h_C),
            "W": comp["W"],
            "W_fluid": mdot * (h_B - comp["h_in"]),
            "h_A_evap": evap["h_out_continued"],
            "dp_valve": p_C - fin["p_D"],
            "valve_opening": opening[names[0]],
            "valve_opening_chiller": opening.get("chiller", np.full(p_A.size, np.nan)),
            "superheat_actual": superheat[names[0]],
            "superheat_chiller": superheat.get("chiller", np.full(p_A.size, np.nan)),
            "frost_risk": branches["evaporator"].get("frost_risk", zero) if "evaporator" in branches else zero,
        }
        with np.errstate(invalid="ignore", divide="ignore"):
            res["COP"] = -(res["Q_evap"] + res["Q_chiller"]) / res["W"]
        # A valid point carries finite figures. A root can sit on a jump of its residual where a
        # component gives no heat (a LUT cell next to nodes with the refrigerant on the wrong side
        # of its secondary stream, or the bench's own edge): its figures are then not a state.
        no_heat = np.broadcast_to(_no_heat_flow(cond), p_A.shape).copy()
        for c in names:
            no_heat |= _no_heat_flow(branches[c]) & (np.asarray(flows[c]) > 0)
        finite = np.logical_and.reduce([np.isfinite(np.asarray(res[k], float)) for k in _MUST_BE_FINITE])
        broken = np.isin(status, VALID_CYCLE_FLAGS) & (no_heat | ~finite)
        status[broken] = STATUS_OUTSIDE_ENVELOPE
        reason[broken] = np.where(
            no_heat[broken],
            "the solution lies where a component takes no heat (its refrigerant inlet on the wrong side "
            "of its secondary stream, or a LUT cell next to such nodes)",
            "a component model gives NaN at the solved state",
        )
        invalid = ~np.isin(status, VALID_CYCLE_FLAGS)
        for k, v in res.items():
            v = np.array(v, float)
            v[invalid] = np.nan
            res[k] = v
        res["status"] = status
        res["reason"] = reason
        return res

    def _branch_superheats(self, ops: dict, p_A, p_B, comp: dict, evap: dict, branches: dict) -> dict:
        """Each branch's outlet superheat [K]: the setpoint, the suction superheat for a branch alone
        (or the only open one), NaN for a closed one; a floating parallel branch's from its outlet
        enthalpy at ``p_A``, by the secant method on the compressor's inlet enthalpy h(T) (within 1e-3 K)."""
        names = [b.component for b in self.circuit.branches]
        if not self.circuit.parallel:
            return {names[0]: ops["superheat"].copy()}
        mode, suction, setpoint = ops["branch_mode"], ops["superheat"], ops["setpoint"]
        out = {c: setpoint.copy() for c in names}
        for b, (closed, floats) in enumerate(((FIRST_CLOSED, FIRST_FLOATS), (SECOND_CLOSED, SECOND_FLOATS))):
            other = names[1 - b]
            out[names[b]][mode == closed] = np.nan
            out[other][mode == closed] = suction[mode == closed]
            k = np.nonzero(mode == floats)[0]
            if k.size == 0:
                continue
            target = branches[names[b]]["h_out_continued"][k]
            T_sat = self.sat.temperature(p_A[k])
            pr = p_B[k] / p_A[k]

            def h(sh, k=k, T_sat=T_sat, pr=pr):
                return self.models.compressor(ops["speed"][k], T_sat + sh, p_A[k], pr)["h_in"]

            x0, y0 = setpoint[k], evap["h_set"][k]
            x1, y1 = suction[k].copy(), comp["h_in"][k]
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
            out[names[b]][k] = x1
        return out

    #: Maximum over nominal opening of the valve (its maximum over nominal capacity), set by solve.
    max_opening = np.nan
