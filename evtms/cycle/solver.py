"""Steady-state vapor-compression cycle: closure on two pressures, vectorised.

States: A evaporator outlet = compressor suction, B compressor discharge =
condenser inlet, C condenser outlet = valve inlet, D valve outlet =
evaporator inlet. The circuit has a receiver after the condenser, so the
condenser ends in saturated liquid (or at a given subcooling), and a
thermostatic valve that holds the evaporator-outlet superheat at its
setpoint. The two unknowns are the suction pressure ``p_A`` and the discharge
pressure ``p_B``:

- inner loop, for a given ``p_A``: the compressor at ``(speed, T_A, p_A,
  p_B/p_A)`` with ``T_A = T_sat(p_A) + superheat`` gives ``mdot`` and
  ``h_B``; the condenser at ``(mdot, fan, p_B, h_B, ambient air)`` gives its
  outlet quality; ``p_B`` is the root of ``x_out - x_target`` (a higher
  discharge pressure raises the saturation temperature and so condenses and
  subcools more: the residual falls monotonically);
- outer loop: the valve is isenthalpic (``h_D = h_C``), the evaporator inlet
  pressure is ``p_A`` plus the evaporator's own pressure drop (fixed point,
  three passes), and ``p_A`` is the root of the outlet superheat minus its
  setpoint (a higher suction pressure means less temperature difference to the
  air and more mass flow, so less superheat).

Both roots are found by the Illinois variant of regula falsi on brackets
from physics (saturation just above the ambient for the condenser, just below
the cabin air for the evaporator) clipped to the models' ranges, vectorised
over all operating points at once. A point whose residual does not change
sign on its bracket, or whose models return NaN, gets a status and the reason.

References
----------
Dowell, M., Jarratt, P. (1971). A modified regula falsi method for computing
the root of an equation. BIT 11, 168-174 (the Illinois algorithm).
Stoecker, W. F., Jones, J. W. (1982). Refrigeration and Air Conditioning,
2nd ed., ch. 15 (system simulation by balancing components).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from evtms.fluid import SaturationCurve

STATUS_CONVERGED = 0
STATUS_OUTSIDE_ENVELOPE = 1
STATUS_CONDENSER_NO_ROOT = 2
STATUS_EVAPORATOR_NO_ROOT = 3
STATUS_NOT_CONVERGED = 4
STATUS_VALVE_BEYOND_MAX = 5

CYCLE_FLAGS = {
    STATUS_CONVERGED: "converged",
    STATUS_OUTSIDE_ENVELOPE: "outside_model_envelope",
    STATUS_CONDENSER_NO_ROOT: "condenser_outlet_condition_not_reachable",
    STATUS_EVAPORATOR_NO_ROOT: "superheat_setpoint_not_reachable",
    STATUS_NOT_CONVERGED: "not_converged",
    STATUS_VALVE_BEYOND_MAX: "converged_valve_beyond_max_opening",
}
VALID_CYCLE_FLAGS = (STATUS_CONVERGED, STATUS_VALVE_BEYOND_MAX)

#: Scale [J/(kg K)] that turns the suction enthalpy residual into about kelvin of superheat.
_CP_SCALE = 1000.0

INPUTS = ("speed", "fan", "blower", "T_amb", "RH_amb", "T_cabin", "RH_cabin", "superheat", "subcooling")


@dataclass
class OperatingPoints:
    """Operating points of the circuit, as equally long arrays (scalars broadcast).

    Attributes
    ----------
    speed : array_like
        Compressor speed, fraction of maximum [1].
    fan, blower : array_like
        Condenser fan and evaporator blower fractions [1].
    T_amb, RH_amb : array_like
        Ambient air at the condenser [K], [1].
    T_cabin, RH_cabin : array_like
        Air entering the evaporator [K], [1].
    superheat : array_like
        Thermostatic-valve superheat setpoint at the evaporator outlet [K].
    subcooling : array_like
        Condenser-outlet subcooling [K]; 0 = saturated liquid (receiver).
    """

    speed: np.ndarray
    fan: np.ndarray
    blower: np.ndarray
    T_amb: np.ndarray
    RH_amb: np.ndarray = field(default=0.4)
    T_cabin: np.ndarray = field(default=300.15)
    RH_cabin: np.ndarray = field(default=0.5)
    superheat: np.ndarray = field(default=10.0)
    subcooling: np.ndarray = field(default=0.0)

    def __post_init__(self) -> None:
        arrays = np.broadcast_arrays(*[np.atleast_1d(np.asarray(getattr(self, k), float)) for k in INPUTS])
        for k, a in zip(INPUTS, arrays, strict=True):
            setattr(self, k, np.ascontiguousarray(a).reshape(-1))

    def __len__(self) -> int:
        return self.speed.size

    def subset(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {k: getattr(self, k)[idx] for k in INPUTS}


def _says(reasons: np.ndarray, words: str) -> np.ndarray:
    """Mask of reason strings that contain ``words``."""
    return np.array([words in r for r in reasons], dtype=bool)


def bracketed_root(
    fun: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    lo: np.ndarray,
    hi: np.ndarray,
    f_lo: np.ndarray,
    f_hi: np.ndarray,
    idx: np.ndarray,
    xtol: float,
    ftol: float,
    maxiter: int = 80,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised root of a decreasing residual on [lo, hi], Illinois regula falsi.

    ``fun(x, idx)`` returns the residuals of points ``idx`` at ``x`` and a
    reason string per point (non-empty where the residual is NaN). The
    residual is positive at ``lo`` and negative at ``hi``; an end may be NaN
    (its model left its envelope there), in which case that end's sign is
    taken as known and the step is a bisection until both ends are finite. A
    NaN inside the bracket joins the end that is NaN; with both ends finite,
    it ends the point's search with its reason.

    Returns
    -------
    x : numpy.ndarray
        The roots.
    state : numpy.ndarray
        1 converged (relative step < ``xtol`` or |residual| < ``ftol``),
        2 failed on a NaN (see ``reason``), 3 not converged in ``maxiter``.
    reason : numpy.ndarray
        Why a point failed.
    """
    lo, hi, f_lo, f_hi = lo.copy(), hi.copy(), f_lo.copy(), f_hi.copy()
    n = lo.size
    x = 0.5 * (lo + hi)
    state = np.zeros(n, np.int8)
    reason = np.full(n, "", dtype=object)
    kept = np.zeros(n, np.int8)  # end kept by the last update: -1 lo, +1 hi
    for _ in range(maxiter):
        act = np.nonzero(state == 0)[0]
        if act.size == 0:
            break
        a, b, fa, fb = lo[act], hi[act], f_lo[act], f_hi[act]
        with np.errstate(invalid="ignore", divide="ignore"):
            xs = b - fb * (b - a) / (fb - fa)
        secant = np.isfinite(xs) & (xs > np.minimum(a, b)) & (xs < np.maximum(a, b))
        xn = np.where(secant, xs, 0.5 * (a + b))
        f, why = fun(xn, idx[act])
        x[act] = xn
        nan = ~np.isfinite(f)
        small = np.abs(b - a) < xtol * np.abs(xn)
        conv = ~nan & ((np.abs(f) < ftol) | small)
        state[act[conv]] = 1
        to_hi = nan & ~np.isfinite(fb)
        to_lo = nan & ~to_hi & ~np.isfinite(fa)
        dead = nan & ((~to_hi & ~to_lo) | small)
        state[act[dead]] = 2
        reason[act[nan]] = why[nan]
        hi[act[to_hi & ~dead]] = xn[to_hi & ~dead]
        lo[act[to_lo & ~dead]] = xn[to_lo & ~dead]
        # Finite residual: it replaces the end of its sign; an end kept twice in a
        # row has its residual halved (the Illinois modification).
        upd = ~nan & ~conv
        pos, neg = upd & (f > 0), upd & (f <= 0)
        i_pos, i_neg = act[pos], act[neg]
        lo[i_pos], f_lo[i_pos] = xn[pos], f[pos]
        f_hi[i_pos] = np.where(kept[i_pos] == 1, 0.5 * f_hi[i_pos], f_hi[i_pos])
        kept[i_pos] = 1
        hi[i_neg], f_hi[i_neg] = xn[neg], f[neg]
        f_lo[i_neg] = np.where(kept[i_neg] == -1, 0.5 * f_lo[i_neg], f_lo[i_neg])
        kept[i_neg] = -1
    state[state == 0] = 3
    reason[state == 1] = ""
    return x, state, reason


class CycleSolver:
    """Solve the cycle for many operating points with a set of component models.

    Parameters
    ----------
    models : LutModels or DirectModels
        Where the component responses come from.
    saturation : SaturationCurve
        Tabulated saturation properties of the refrigerant.
    """

    def __init__(self, models, saturation: SaturationCurve) -> None:
        self.models = models
        self.sat = saturation

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
        if "x_out" in cond:  # present whenever some point targets a subcooled outlet
            residual = np.where(ops["subcooling"] > 0, cond["x_out"] - x_target, residual)
        # Refrigerant not warmer than the air condenses nothing: far above the target.
        residual = np.where(_says(cond["reason"], "not_warmer_than_air") & np.isfinite(comp["mdot"]), 1.0, residual)
        reason = np.where(comp["reason"] != "", comp["reason"], cond["reason"])
        return {"T_A": T_A, "comp": comp, "cond": cond, "residual": residual, "reason": reason}

    def _pressure_root(self, residual, lo, hi, f_lo, f_hi, idx, ftol, status, reason, what) -> np.ndarray:
        """Root in pressure of ``residual(p, idx)`` for the points ``idx`` of a bracket.

        Iterates on the saturation temperature, in which both closures are close
        to linear; marks points whose model left its envelope (with its reason)
        or that did not converge in ``status`` and ``reason``.
        """

        def fun(t_sat, i):
            return residual(self.sat.pressure(t_sat), i)

        t_lo, t_hi = self.sat.temperature(lo[idx]), self.sat.temperature(hi[idx])
        root, state, why = bracketed_root(fun, t_lo, t_hi, f_lo[idx], f_hi[idx], idx, 1e-8, ftol)
        status[idx[state == 2]] = STATUS_OUTSIDE_ENVELOPE
        status[idx[state == 3]] = STATUS_NOT_CONVERGED
        reason[idx] = np.where(state == 3, f"{what} iteration did not converge", why)
        return self.sat.pressure(root)

    def _solve_discharge(self, ops: dict, p_A: np.ndarray, guess: np.ndarray | None = None) -> dict:
        """Discharge pressure p_B for each suction pressure: the condenser-outlet condition.

        ``guess`` (NaN where unknown), the root at a nearby suction pressure,
        narrows the bracket to +-2 % where the residual changes sign there.
        """
        n = p_A.size
        pr_lo, pr_hi = self._pr
        lo = np.maximum(self.sat.pressure(ops["T_amb"] + 0.5), pr_lo * p_A)
        lo = np.maximum(lo, self._p_discharge[0])
        hi = np.minimum(np.full(n, self._p_discharge[1]), pr_hi * p_A)
        f_lo, f_hi = np.full(n, np.nan), np.full(n, np.nan)
        r_lo, r_hi = np.full(n, "", dtype=object), np.full(n, "", dtype=object)
        narrow = np.zeros(n, bool)
        if guess is not None and np.isfinite(guess).any():
            g = np.nonzero(np.isfinite(guess) & (guess > lo) & (guess < hi))[0]
            sub = {k: v[g] for k, v in ops.items()}
            a, b = np.maximum(lo[g], guess[g] / 1.05), np.minimum(hi[g], guess[g] * 1.05)
            ea, eb = self._discharge_side(sub, p_A[g], a), self._discharge_side(sub, p_A[g], b)
            ok = (ea["residual"] > 0) & (eb["residual"] < 0)
            k = g[ok]
            lo[k], hi[k], f_lo[k], f_hi[k] = a[ok], b[ok], ea["residual"][ok], eb["residual"][ok]
            narrow[k] = True
        wide = np.nonzero(~narrow)[0]
        if wide.size:
            sub = {k: v[wide] for k, v in ops.items()}
            e_lo = self._discharge_side(sub, p_A[wide], lo[wide])
            e_hi = self._discharge_side(sub, p_A[wide], hi[wide])
            f_lo[wide], f_hi[wide] = e_lo["residual"], e_hi["residual"]
            r_lo[wide], r_hi[wide] = e_lo["reason"], e_hi["reason"]
        status = np.full(n, STATUS_CONVERGED, np.int8)
        reason = np.full(n, "", dtype=object)
        cold = np.isfinite(f_lo) & (f_lo <= 0)
        hot = ~cold & np.isfinite(f_hi) & (f_hi >= 0)
        status[cold | hot] = STATUS_CONDENSER_NO_ROOT
        reason[cold] = "the condenser outlet is below its target even at the lowest discharge pressure searched"
        reason[hot] = [
            f"the condenser cannot reach its outlet condition up to the highest discharge pressure {h:.4g} Pa"
            for h in hi[hot]
        ]
        bad_pa = ~np.isfinite(p_A)
        status[bad_pa] = STATUS_OUTSIDE_ENVELOPE
        p_B = np.full(n, np.nan)
        idx = np.nonzero(status == STATUS_CONVERGED)[0]
        if idx.size:

            def residual(pb, i):
                r = self._discharge_side({k: v[i] for k, v in ops.items()}, p_A[i], pb)
                return r["residual"], r["reason"]

            p_B[idx] = self._pressure_root(
                residual, lo, hi, f_lo, f_hi, idx, 1e-7, status, reason, "discharge-pressure"
            )
        p_B[status != STATUS_CONVERGED] = np.nan
        return {"p_B": p_B, "status": status, "reason": reason}

    def _suction_side(self, ops: dict, p_A: np.ndarray, idx: np.ndarray, full: bool = False) -> dict:
        """Superheat residual at suction pressure p_A (with the inner discharge solve).

        ``idx`` are the points' indices in the whole batch, for the warm start
        of the discharge pressure from the previous suction iterate.
        """
        dis = self._solve_discharge(ops, p_A, self._guess[idx])
        self._guess[idx] = np.where(np.isfinite(dis["p_B"]), dis["p_B"], self._guess[idx])
        side = self._discharge_side(ops, p_A, dis["p_B"])
        comp, cond = side["comp"], side["cond"]
        saturated = ops["subcooling"] <= 0
        h_D = self.sat.liquid_enthalpy(cond["p_out"])
        if "h_out" in cond:
            h_D = np.where(saturated, h_D, cond["h_out"])
        # Evaporator inlet = outlet pressure + its own drop: a fixed point, warm-started
        # from the drop at the previous suction iterate (the drop changes slowly).
        p_D = p_A + self._dp_guess[idx]
        for _ in range(2):
            evap = self.models.evaporator(comp["mdot"], ops["blower"], p_D, h_D, ops["T_cabin"], ops["RH_cabin"])
            drop = np.where(np.isfinite(evap["p_out"]), p_D - evap["p_out"], self._dp_guess[idx])
            p_D = p_A + drop
        self._dp_guess[idx] = drop
        evap = self.models.evaporator(comp["mdot"], ops["blower"], p_D, h_D, ops["T_cabin"], ops["RH_cabin"])
        # The valve holds the outlet at the superheat setpoint, i.e. at the compressor's
        # suction state A. The residual compares enthalpies (scaled to about kelvin):
        # interpolated outlet enthalpy stays smooth where the LUT's outlet temperature
        # has its kink (outlet turning two-phase), and matching it keeps the cycle's
        # energy balance.
        sh = (evap["h_out"] - comp["h_in"]) / _CP_SCALE
        # An inlet not colder than the air evaporates nothing: the outlet stays at h_D.
        sh = np.where(
            _says(evap["reason"], "not_colder_than_air") & np.isfinite(h_D), (h_D - comp["h_in"]) / _CP_SCALE, sh
        )
        status = dis["status"].copy()
        reason = dis["reason"].copy()
        bad = (status == STATUS_CONVERGED) & ~np.isfinite(sh)
        status[bad] = STATUS_OUTSIDE_ENVELOPE
        reason[bad] = np.where(side["reason"][bad] != "", side["reason"][bad], evap["reason"][bad])
        residual = np.where(status == STATUS_CONVERGED, sh, np.nan)
        out = {"residual": residual, "status": status, "reason": reason}
        if full:
            out.update(p_B=dis["p_B"], p_D=p_D, side=side, evap=evap)
        return out

    # -- public --------------------------------------------------------------
    def solve(self, points: OperatingPoints) -> dict[str, np.ndarray]:
        """Solve every operating point.

        Returns
        -------
        dict of str to numpy.ndarray
            ``p_A, T_A, h_A`` ... ``p_D, T_D, h_D`` [Pa, K, J/kg], ``mdot``
            [kg/s], ``Q_evap`` (< 0), ``Q_latent``, ``Q_cond``, ``W`` (shaft),
            ``W_fluid`` (``mdot (h_B - h_A)``) [W], ``COP`` (cooling, |Q_evap|/W)
            [1], ``dp_valve`` [Pa], ``valve_opening`` (relative to the nominal
            opening) [1], ``status`` (int8, :data:`CYCLE_FLAGS`) and
            ``reason`` (text, empty when converged).
        """
        ops = points.subset(np.arange(len(points)))
        n = len(points)
        limits = self.models.limits()
        self._p_discharge = limits["p_discharge"]
        # A hair inside the compressor's pressure-ratio range, so that p_B/p_A stays on its grid.
        self._pr = (max(limits["pr"][0], 1.0) * (1 + 1e-9), limits["pr"][1] * (1 - 1e-9))
        p_lo_lim, p_hi_lim = limits["p_suction"]
        # Evaporating 45 K below the cabin air leaves a large superheat: the low end of the bracket.
        lo = np.maximum(self.sat.pressure(ops["T_cabin"] - 45.0), p_lo_lim)
        hi = np.minimum(self.sat.pressure(ops["T_cabin"] - 0.5), p_hi_lim)
        self._guess = np.full(n, np.nan)
        self._dp_guess = np.zeros(n)
        self.models.subcooled_targets(bool(np.any(ops["subcooling"] > 0)))
        everyone = np.arange(n)
        e_lo = self._suction_side(ops, lo, everyone)
        e_hi = self._suction_side(ops, hi, everyone)
        f_lo, f_hi = e_lo["residual"], e_hi["residual"]
        status = np.full(n, STATUS_CONVERGED, np.int8)
        reason = np.full(n, "", dtype=object)
        low = np.isfinite(f_lo) & (f_lo <= 0)
        high = ~low & np.isfinite(f_hi) & (f_hi >= 0)
        status[low | high] = STATUS_EVAPORATOR_NO_ROOT
        reason[low] = "the superheat stays below its setpoint even at the lowest suction pressure searched"
        reason[high] = "the superheat stays above its setpoint up to saturation at the cabin air temperature"
        # Both ends outside a model's envelope: nothing to go on.
        both = ~np.isfinite(f_lo) & ~np.isfinite(f_hi) & (status == STATUS_CONVERGED)
        status[both] = STATUS_OUTSIDE_ENVELOPE
        reason[both] = np.where(e_lo["reason"][both] != "", e_lo["reason"][both], e_hi["reason"][both])
        p_A = np.full(n, np.nan)
        idx = np.nonzero(status == STATUS_CONVERGED)[0]
        if idx.size:

            def residual(pa, i):
                r = self._suction_side({k: v[i] for k, v in ops.items()}, pa, i)
                return r["residual"], r["reason"]

            p_A[idx] = self._pressure_root(residual, lo, hi, f_lo, f_hi, idx, 1e-4, status, reason, "suction-pressure")
        p_A[status != STATUS_CONVERGED] = np.nan
        return self._final_states(ops, p_A, status, reason)

    def _final_states(self, ops: dict, p_A: np.ndarray, status: np.ndarray, reason: np.ndarray) -> dict:
        self.models.detailed(True)
        try:
            fin = self._suction_side(ops, p_A, np.arange(p_A.size), full=True)
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
        # outlet pressure (the LUT's own h_out has its kink exactly there).
        p_C = cond["p_out"]
        saturated = ops["subcooling"] <= 0
        h_C = np.where(saturated, self.sat.liquid_enthalpy(p_C), cond["h_out"])
        T_C = np.where(saturated, self.sat.temperature(p_C), cond["T_out"])
        # The valve's orifice law makes dp go with mdot^2 at a given inlet state, so the
        # opening that passes mdot at the cycle's dp follows from the nominal-opening dp
        # at a small reference flow (valid on every valve grid).
        m_ref = self.models.valve_reference_flow()
        valve = self.models.valve(h_C, p_C, np.full(mdot.shape, m_ref))
        dp_valve = p_C - fin["p_D"]
        with np.errstate(invalid="ignore", divide="ignore"):
            opening = mdot / m_ref * np.sqrt(valve["dp"] / dp_valve)
        # Heat flows as mdot times each component's enthalpy change, the outlet from its own model.
        h_B = comp["h_out"]
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
            "Q_evap": -mdot * (evap["h_out"] - h_C),
            "Q_latent": evap["Q_latent"],
            "Q_cond": mdot * (h_B - h_C),
            "W": comp["W"],
            "W_fluid": mdot * (h_B - comp["h_in"]),
            "h_A_evap": evap["h_out"],
            "dp_valve": dp_valve,
            "valve_opening": opening,
        }
        with np.errstate(invalid="ignore", divide="ignore"):
            res["COP"] = -res["Q_evap"] / res["W"]
        ok = status == STATUS_CONVERGED
        bad_valve = ok & (valve["reason"] == "") & (opening > self.max_opening)
        status[bad_valve] = STATUS_VALVE_BEYOND_MAX
        reason[bad_valve] = "the valve would need more than its maximum opening to hold the superheat"
        invalid = ~np.isin(status, VALID_CYCLE_FLAGS)
        for k, v in res.items():
            v = np.asarray(v, float)
            v[invalid] = np.nan
            res[k] = v
        res["status"] = status
        res["reason"] = reason
        return res

    #: Maximum over nominal opening of the thermostatic valve (capacity 4000 W / 2000 W).
    max_opening = 2.0
