"""One evaporating branch of the circuit (the cabin evaporator or the battery chiller), evaluated.

A branch is a coil behind its own thermostatic valve: refrigerant enters at
the valve-outlet state ``(p_in, h_in)`` and leaves at the suction pressure
after the coil's own pressure drop, taking heat from its secondary stream (the
cabin air or the battery coolant). These functions give the branch's model
result, with the conventions the closures need: no heat where the inlet is
not colder than the stream, a closed branch leaving its inlet state, and the
inlet pressure that ends at a given outlet pressure (a fixed point of the
drop).
"""

from __future__ import annotations

import numpy as np

from evtms.cycle.state import DP_PASSES, DP_TOL, FIRST_CLOSED, SECOND_CLOSED, Ops, SolveContext, take


def no_heat_flow(result: dict) -> np.ndarray:
    """Points where a heat exchanger's refrigerant inlet is not on the side of the secondary
    stream that lets heat flow the required way (its bench status; LUTs hold NaN there)."""
    return np.asarray(result.get("no_heat_flow", False), bool)


def branch(ctx: SolveContext, component: str, ops: Ops, mdot, p_in, h_in) -> dict:
    """One evaporating branch's model at refrigerant flow ``mdot`` [kg/s], inlet ``(p_in, h_in)`` [Pa, J/kg]."""
    if component == "evaporator":
        r = ctx.models.evaporator(mdot, ops["blower"], p_in, h_in, ops["T_cabin"], ops["RH_cabin"])
    else:
        r = ctx.models.chiller(mdot, p_in, h_in, ops["mdot_coolant"], ops["T_coolant_in"])
    if ctx.parallel and "no_heat_flow" in r:
        # A branch whose inlet is not colder than its stream takes no heat: its outlet is its inlet.
        none = r["no_heat_flow"] & np.isfinite(np.asarray(h_in, float))
        r["h_out_continued"] = np.where(none, h_in, r["h_out_continued"])
        r["p_out"] = np.where(none, p_in, r["p_out"])
        r["reason"] = np.where(none, "", r["reason"])
    return r


def run_branch(ctx: SolveContext, component: str, ops: Ops, mdot, p_in, h_in, open_: np.ndarray) -> dict:
    """:func:`branch` where ``open_``; a closed branch (no flow) leaves its inlet state, no heat."""
    if open_.all():
        return branch(ctx, component, ops, mdot, p_in, h_in)
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
        r = branch(ctx, component, take(ops, k), mdot[k], p_in[k], h_in[k])
        for key, v in r.items():
            v = np.asarray(v)
            if key not in out:
                out[key] = np.full(n, "", dtype=object) if v.dtype == object else np.full(n, np.nan)
            out[key][k] = v
    return out


def converged_drop(ctx: SolveContext, component: str, ops: Ops, mdot, p_out, h_in, drop: np.ndarray) -> np.ndarray:
    """A branch's pressure drop [Pa] at outlet pressure ``p_out`` [Pa]: the fixed point of
    ``drop = p_in - p_out(p_in)`` from ``drop``, to :data:`~evtms.cycle.state.DP_TOL` in at most
    :data:`~evtms.cycle.state.DP_PASSES` passes (each on the points still moving; where the model
    returns NaN the drop is kept)."""
    drop = np.asarray(drop, float).copy()
    todo = np.arange(drop.size)
    for _ in range(DP_PASSES):
        p_in = p_out[todo] + drop[todo]
        out = branch(ctx, component, take(ops, todo), mdot[todo], p_in, h_in[todo])["p_out"]
        new = np.where(np.isfinite(out), p_in - out, drop[todo])
        moving = np.abs(new - drop[todo]) > DP_TOL
        drop[todo] = new
        todo = todo[moving]
        if todo.size == 0:
            break
    return drop


def secondary_temperature(ctx: SolveContext, ops: Ops) -> np.ndarray:
    """The coldest secondary inlet of the open branches: every open branch must evaporate below it [K]."""
    temps = [np.asarray(ops[b.secondary_temperature], float) for b in ctx.circuit.branches]
    coldest = np.minimum.reduce(temps)
    if ctx.parallel and "branch_mode" in ops:
        mode = ops["branch_mode"]
        coldest = np.where(mode == FIRST_CLOSED, temps[1], np.where(mode == SECOND_CLOSED, temps[0], coldest))
    return coldest
