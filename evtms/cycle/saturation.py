r"""The valve at its maximum opening: the superheat floats above its setpoint.

A thermostatic valve at its maximum opening (its stroke's end) can open no
further as the superheat rises: it no longer holds the superheat, which
floats. The valve's orifice law at the maximum flow area
:math:`S_{max} = S_{nom} Q_{max}/Q_{nom}` [m2] (capacities :math:`Q` [W]) then
closes the suction side in place of the setpoint:

.. math:: \dot m = S_{max} \sqrt{2 \rho_C (p_C - p_D)}

(mass flow [kg/s], liquid density at the valve inlet [kg/m3], pressures [Pa]),
the law the cycle uses for the opening it needs. The superheat
:math:`\Delta T_{sh}` [K] is the root of

.. math:: g(\Delta T_{sh}) = \ln\frac{S(\Delta T_{sh})}{S_{max}}

where :math:`S(\Delta T_{sh})` is the opening that passes the flow of the
cycle solved with the superheat held at :math:`\Delta T_{sh}`. :math:`g` falls
as the superheat rises (less flow at a lower suction pressure, through a
larger pressure drop) and is positive at the setpoint, so the root lies above
the setpoint: a saturated valve starves the evaporator, it never floods it.
:math:`g` is nearly linear, about -0.0125 per kelvin (-0.009 to -0.018 over
the envelope), and falls a little faster as the superheat rises, so that its
secant slope from the setpoint to the root grows with :math:`g_0 = g`
(setpoint): the first step goes 0.9 of the shift that slope
(``_SH_FIRST_SLOPE``) gives, short of the root in most points, the second the
secant estimate from the setpoint, which lands just beyond it; further secant
steps (overshot) follow where it does not. Once bracketed, inverse quadratic
interpolation through the three latest points (the chord where it leaves the
bracket) and then the regula falsi of the pressures
(:func:`~evtms.cycle.roots.bracketed_root`) find the root, to 1e-4 in
:math:`g` (about 0.01 K); a point stops at any step that lands within that.

Every evaluation is a whole cycle solve (:func:`~evtms.cycle.closure.solve_at`),
warm-started by extrapolating the suction and discharge pressures and the
evaporator's drop linearly from the point's two latest superheats (from the
setpoint alone, by their typical changes in :math:`g_0`), with a
suction-closure slope fit for floating superheats; where a trial superheat
leaves the models' envelope the point fails with that reason (prefixed "with
the valve at its maximum opening"). About four cycle solves per batch, most
points converging in three.

References
----------
ASHRAE (2018). ASHRAE Handbook - Refrigeration, ch. 11, Refrigerant-control
devices (thermostatic expansion valves: capacity, superheat, feed limits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evtms.cycle.compiled import solve_closure
from evtms.cycle.roots import bracketed_root
from evtms.cycle.state import Ops, SolveContext, WarmStart, take
from evtms.cycle.status import STATUS_CONVERGED, STATUS_NOT_CONVERGED, STATUS_OUTSIDE_ENVELOPE

#: The first step's estimates are linear in g0 = ln(opening needed at the setpoint over the maximum) [1],
#: fitted on the 271 saturated points of benchmarks/bench_cycle.py (within 5 % for half of them, 22 % for
#: all): the secant slope of ln(opening) from the setpoint to the floating superheat [1/K] (steeper the
#: larger g0: ln(opening) falls ever faster as the superheat rises), and per kelvin of superheat over that
#: shift the change of the suction saturation temperature [K/K], of ln(p_B) [1/K] and the relative change
#: of the evaporator's pressure drop [1/K] (the warm start of that cycle solve). They only steer the
#: search, not where it ends.
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
#: per kelvin of suction saturation than at the setpoint, closure.OUTER_SLOPE, so that its bracket holds
#: the root).
_SH_OUTER_SLOPE = -1.5
#: Inverse-quadratic steps once bracketed, before the regula falsi; largest bracketing step [K] and number
#: of steps, tolerances in superheat (relative) [1] and in ln(opening) [1].
_SH_QUAD_STEPS = 3
_SH_MAX_STEP = 25.0
_SH_BRACKET_STEPS = 4
_SH_XTOL = 1e-4
_SH_FTOL = 1e-4
#: A warm start's second trial goes this far [K] beyond the root its secant predicts (a fifth of the
#: tolerance in g at the typical slope), so that it brackets the root where it does not land on it.
_SH_WARM_BEYOND = 2e-3


@dataclass
class _FloatingCycles:
    """The cycle solves of one batch of saturated points, each at a trial superheat.

    ``store`` holds each point's latest cycle (its working arrays); ``seen``
    and ``known`` the two latest solved superheats [K] with their suction
    saturation temperature [K], discharge pressure [Pa] and evaporator drop
    [Pa] (row 0 the latest), to extrapolate the next solve's warm start;
    ``fail`` the status of a point's latest failed solve.
    """

    ctx: SolveContext
    ops: Ops
    key: str
    log_max: float
    g0: np.ndarray
    share: np.ndarray
    store: dict[str, np.ndarray]
    seen: np.ndarray
    known: dict[str, np.ndarray]
    fail: np.ndarray
    slopes: dict[str, np.ndarray]
    warm: bool = False
    split: np.ndarray | None = None
    dp_branch: dict[str, np.ndarray] | None = None

    def guess(self, sh: np.ndarray, i: np.ndarray) -> dict[str, np.ndarray]:
        """Warm start of the points ``i`` at superheat ``sh`` [K]: ``t`` [K], ``p_B`` and ``dp`` [Pa]."""
        known = self.known
        s1, s0 = self.seen[0, i], self.seen[1, i]
        two = np.isfinite(s0) & (np.abs(s1 - s0) > 1e-9)
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(two, (sh - s1) / (s1 - s0), 0.0)
        g = {k: np.where(two, v[0, i] + w * (v[0, i] - v[1, i]), v[0, i]) for k, v in known.items()}
        # From one solved superheat: the typical changes over the shift to the root.
        d, g0_i = (sh - s1) / self.share[i], self.g0[i]
        one = {
            "t": known["t"][0, i] + d * (_SH_FIRST_T[0] + _SH_FIRST_T[1] * g0_i),
            "p_B": known["p_B"][0, i] * np.exp(d * (_SH_FIRST_LN_PB[0] + _SH_FIRST_LN_PB[1] * g0_i)),
            "dp": known["dp"][0, i] * (1.0 + d * (_SH_FIRST_DP[0] + _SH_FIRST_DP[1] * g0_i)),
        }
        g = {k: np.where(two, v, one[k]) for k, v in g.items()}
        g["p_B"] = np.where(g["p_B"] > 0, g["p_B"], known["p_B"][0, i])
        g["dp"] = np.maximum(g["dp"], 0.0)
        return g

    def residual(self, sh: np.ndarray, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``g`` of the points ``i`` at superheat ``sh`` [K] (a cycle solve each) and the reasons of NaN."""
        ops_i = take(self.ops, i)
        ops_i["superheat"] = sh
        g = self.guess(sh, i)
        # A warm search's trials start from the closure's slope measured at its latest trial.
        outer = np.where(self.warm & (self.slopes["outer"][i] < 0), self.slopes["outer"][i], _SH_OUTER_SLOPE)
        if self.warm:  # the solve warm-started: so are its trial cycles, from the guesses
            drops = {c: v[i] for c, v in self.dp_branch.items()}
            start = WarmStart(g["t"], outer, g["p_B"], self.slopes["inner"][i], g["dp"], drops, self.split[i])
            r, state = solve_closure(self.ctx, ops_i, warm=start)
            ok = r["status"] == STATUS_CONVERGED
            self.split[i[ok]] = state.split[ok]
            for c, v in state.dp_branch.items():
                self.dp_branch.setdefault(c, np.full(self.split.size, np.nan))[i[ok]] = v[ok]
        else:
            r, state = solve_closure(
                self.ctx, ops_i, t_guess=g["t"], p_B_guess=g["p_B"], dp_guess=g["dp"], outer_slope=outer
            )
        for k, v in r.items():
            self.store[k][i] = v
        ok = r["status"] == STATUS_CONVERGED
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(ok, np.log(r[self.key]) - self.log_max, np.nan)
        k = i[ok]
        self.seen[1, k], self.seen[0, k] = self.seen[0, k], sh[ok]
        new = {"t": self.ctx.sat.temperature(r["p_A"]), "p_B": r["p_B"], "dp": r["p_D"] - r["p_A"]}
        for name, v in self.known.items():
            v[1, k], v[0, k] = v[0, k], new[name][ok]
        for name, v in (("outer", state.outer_slope), ("inner", state.slope)):
            self.slopes[name][k] = np.where(v[ok] < 0, v[ok], self.slopes[name][k])
        self.fail[i[~ok]] = r["status"][~ok]
        return f, np.where(ok, "", r["reason"])


@dataclass
class _Search:
    """The superheat search's brackets per point: ``lo`` [K] (``g`` > 0) and ``hi`` (``g`` <= 0 or
    NaN), the slope of ``g`` [1/K], the three latest trials (``px``, ``pf``; newest first) and
    ``state`` (1 found, 2 failed on a NaN, 3 searching) with ``why`` it failed."""

    lo: np.ndarray
    f_lo: np.ndarray
    hi: np.ndarray
    f_hi: np.ndarray
    why_hi: np.ndarray
    slope: np.ndarray
    state: np.ndarray
    why: np.ndarray
    px: np.ndarray
    pf: np.ndarray

    @classmethod
    def at_setpoint(cls, lo: np.ndarray, f_lo: np.ndarray, slope: np.ndarray) -> _Search:
        """The search from the setpoint ``lo`` [K], where ``g`` is ``f_lo`` (> 0) and its slope
        is estimated at ``slope`` [1/K]."""
        m = lo.size
        s = cls(
            lo=lo,
            f_lo=f_lo,
            hi=np.full(m, np.nan),
            f_hi=np.full(m, np.nan),
            why_hi=np.full(m, "", dtype=object),
            slope=slope,
            state=np.full(m, 3, np.int8),
            why=np.full(m, "", dtype=object),
            px=np.full((3, m), np.nan),
            pf=np.full((3, m), np.nan),
        )
        s.px[0], s.pf[0] = lo, f_lo
        return s

    def record(self, j: np.ndarray, x: np.ndarray, f: np.ndarray) -> None:
        """The trials ``x`` of the points ``j`` and their residuals ``f``, as the newest."""
        self.px[1:, j], self.pf[1:, j] = self.px[:-1, j], self.pf[:-1, j]
        self.px[0, j], self.pf[0, j] = x, f


def float_superheat(
    ctx: SolveContext,
    ops: Ops,
    res: dict,
    idx: np.ndarray,
    key: str = "valve_opening",
    share=None,
    warm: WarmStart | None = None,
) -> WarmStart:
    """Cycle of the points ``idx`` with the valve at its maximum opening; written into ``res``.

    ``res`` are the working arrays of the solve with the valve holding the
    setpoint (:func:`~evtms.cycle.closure.solve_at`). ``key`` is the result
    holding the saturated valve's opening (``valve_opening_chiller``: the
    chiller's valve of two parallel branches, whose branch floats while the
    other holds the setpoint; the superheat iterated on is then the suction
    mixture's, see :mod:`evtms.cycle.limits`), and ``share`` the saturated
    branch's share of the flow at the setpoint [1] (default 1): the mixture's
    superheat moves that share of the branch's, so the typical changes per
    kelvin of the first step are divided by it.

    ``warm`` (of the points ``idx``), a previous solve's solution at nearby
    points: where its ``superheat`` floated above this setpoint, the first
    step goes there, and the cycle solves extrapolate from the setpoint's
    solution towards its ``floating`` one (the root is the same, to within
    the search's tolerance). Returns the floating solution of the points
    ``idx`` with its ``superheat``, for the next solve to start from (NaN
    where a point failed).
    """
    log_max = np.log(ctx.max_opening)
    m = idx.size
    # ln(opening over the maximum) at the setpoint: positive where the valve saturates.
    f_set = np.log(res[key][idx]) - log_max
    cycles = _FloatingCycles(
        ctx=ctx,
        ops=take(ops, idx),
        key=key,
        log_max=log_max,
        g0=np.maximum(f_set, 0.0),
        share=np.ones(m) if share is None else np.clip(np.asarray(share, float), 0.05, 1.0),
        store={k: np.asarray(v)[idx].copy() for k, v in res.items()},
        seen=np.stack([ops["superheat"][idx], np.full(m, np.nan)]),
        known={
            k: np.stack([v, np.full(m, np.nan)])
            for k, v in (
                ("t", ctx.sat.temperature(res["p_A"][idx])),
                ("p_B", res["p_B"][idx]),
                ("dp", (res["p_D"] - res["p_A"])[idx]),
            )
        },
        fail=np.full(m, STATUS_OUTSIDE_ENVELOPE, np.int8),
        slopes={"outer": np.full(m, np.nan), "inner": np.full(m, np.nan)},
        warm=warm is not None,
        split=np.full(m, np.nan),
        dp_branch={},
    )
    slope = (_SH_FIRST_SLOPE[0] + _SH_FIRST_SLOPE[1] * cycles.g0) / cycles.share
    search = _Search.at_setpoint(ops["superheat"][idx].copy(), f_set, slope)
    first = _warm_first_step(cycles, search, warm)
    still = _warm_trials(cycles, search, first)
    cold = np.nonzero(~np.isfinite(first))[0]
    rising = _step_up(cycles, search, cold, still)
    _quadratic_steps(cycles, search)
    _regula_falsi(cycles, search)
    _write_back(ctx, cycles, search, rising, res, idx)
    return _floating_solution(ctx, cycles, search, res, idx)


def _warm_first_step(cycles: _FloatingCycles, s: _Search, warm: WarmStart | None) -> np.ndarray:
    """The first trial superheat [K] per point from a previous solve's floating solution (NaN where
    there is none above this setpoint): its superheat, shifted by the change of ``g`` at the
    setpoint over its slope there (the curve ``g`` moves about as a whole between nearby points).
    That solution becomes the older of the two known cycles the trials' warm starts extrapolate
    from, with its closures' slopes, and its slope of ``g`` the search's."""
    first = np.full(s.lo.size, np.nan)
    if warm is None or warm.floating is None:
        return first
    fl = warm.floating
    use = np.isfinite(fl.superheat) & (fl.superheat > s.lo + 0.02) & np.isfinite(fl.t_A) & np.isfinite(fl.p_B)
    slope = np.where(fl.opening_slope < 0, fl.opening_slope, s.slope)
    with np.errstate(invalid="ignore"):
        shift = np.nan_to_num((cycles.g0 - fl.opening_excess) / -slope)
    first[use] = np.clip(fl.superheat + shift, s.lo + 0.02, s.lo + _SH_MAX_STEP)[use]
    s.slope[use] = slope[use]
    cycles.seen[1, use] = fl.superheat[use]
    for name, v in (("t", fl.t_A), ("p_B", fl.p_B), ("dp", fl.dp)):
        cycles.known[name][1, use] = v[use]
    cycles.slopes["outer"][use] = fl.outer_slope[use]
    cycles.slopes["inner"][use] = fl.inner_slope[use]
    cycles.split[use] = fl.split[use]
    for c, v in fl.dp_branch.items():
        cycles.dp_branch.setdefault(c, np.full(use.size, np.nan))[use] = v[use]
    return first


def _warm_trials(cycles: _FloatingCycles, s: _Search, first: np.ndarray) -> np.ndarray:
    """The points with a warm first trial ``first`` [K]: that trial, then the secant step along the
    slope of ``g`` measured at the previous root, up or down, and :data:`_SH_WARM_BEYOND` further
    (``g`` is nearly linear over such a step: the second trial lands within the tolerance, or just
    beyond the root, in most points). Returns the points left rising (both trials below the
    root), for the steps up."""
    going = np.nonzero(np.isfinite(first))[0]
    x = first[going]
    for trial in range(2):
        if going.size == 0:
            break
        f, why = cycles.residual(x, going)
        s.record(going, x, f)
        done = np.isfinite(f) & (np.abs(f) < _SH_FTOL)
        s.state[going[done]] = 1
        up = np.isfinite(f) & (f > 0) & ~done
        down = ~(np.isfinite(f) & (f > 0)) & ~done
        s.lo[going[up]], s.f_lo[going[up]] = x[up], f[up]
        k = going[down]
        tighter = ~(s.hi[k] <= x[down])  # the tighter upper end (NaN: none yet)
        j = k[tighter]
        s.hi[j], s.f_hi[j], s.why_hi[j] = x[down][tighter], f[down][tighter], why[down][tighter]
        if trial == 1:
            return going[up & ~np.isfinite(s.hi[going])]
        keep = np.isfinite(f) & ~done
        going, f, x = going[keep], f[keep], x[keep]
        step = -f / s.slope[going] + np.sign(f) * _SH_WARM_BEYOND
        x = np.maximum(x + np.clip(step, -_SH_MAX_STEP, _SH_MAX_STEP), s.lo[going] + 0.01)
    return going[:0]


def _floating_solution(ctx: SolveContext, cycles: _FloatingCycles, s: _Search, res: dict, idx) -> WarmStart:
    """The floating cycles of the points ``idx`` as a warm start (NaN where a point failed)."""
    ok = s.state == 1
    p_A, p_B = np.where(ok, res["p_A"][idx], np.nan), np.where(ok, res["p_B"][idx], np.nan)
    # The slope of g near the root: the secant of the two latest trials, else the search's.
    with np.errstate(invalid="ignore", divide="ignore"):
        chord = (s.pf[0] - s.pf[1]) / (s.px[0] - s.px[1])
    slope = np.where(np.isfinite(chord) & (chord < 0), chord, s.slope)
    with np.errstate(invalid="ignore"):
        t_A = ctx.sat.temperature(p_A)
    return WarmStart(
        t_A=t_A,
        outer_slope=np.where(ok, cycles.slopes["outer"], np.nan),
        p_B=p_B,
        inner_slope=np.where(ok, cycles.slopes["inner"], np.nan),
        dp=np.where(ok, res["p_D"][idx] - res["p_A"][idx], np.nan),
        dp_branch={c: np.where(ok, v, np.nan) for c, v in cycles.dp_branch.items()},
        split=np.where(ok, cycles.split, np.nan),
        superheat=np.where(ok, cycles.seen[0], np.nan),
        opening_excess=np.where(ok, cycles.g0, np.nan),
        opening_slope=np.where(ok, slope, np.nan),
    )


def _step_up(cycles: _FloatingCycles, s: _Search, cold: np.ndarray, warm: np.ndarray) -> np.ndarray:
    """Bracket: secant steps up from the setpoint, plus 0.5 K, of the points ``cold`` and, from
    their third step on, of ``warm`` (their warm trials were the first two); returns the points
    still rising (``g`` > 0 after every step)."""
    going = cold
    for step in range(_SH_BRACKET_STEPS):
        if step == 2:
            going = np.union1d(going, warm)
        if going.size == 0:
            if step >= 2:
                break
            continue
        # The first step goes most of the way the estimate from g0 gives (a step far beyond
        # the root may leave the models' envelope, and such points cost many evaluations);
        # the second follows the secant slope measured, which overshoots a little; later
        # steps overshoot more.
        lo, f_lo, slope = s.lo[going], s.f_lo[going], s.slope[going]
        if step == 0:
            x = lo + np.clip(-_SH_FIRST_SHARE * f_lo / slope, 0.02, _SH_MAX_STEP)
        elif step == 1:
            x = lo + np.clip(-f_lo / slope + 0.02, 0.02, _SH_MAX_STEP)
        else:
            x = lo + np.clip(-_SH_OVERSHOOT * f_lo / slope + 0.5, 0.5, _SH_MAX_STEP)
        f, why_x = cycles.residual(x, going)
        s.record(going, x, f)
        # A step onto the root (within the tolerance) ends that point's search.
        done = np.isfinite(f) & (np.abs(f) < _SH_FTOL)
        s.state[going[done]] = 1
        up = np.isfinite(f) & (f > 0) & ~done
        with np.errstate(invalid="ignore", divide="ignore"):
            secant = (f - f_lo) / (x - lo)
        k = going[up]
        s.slope[k] = np.where(secant[up] < 0, secant[up], s.slope[k])
        s.lo[k], s.f_lo[k] = x[up], f[up]
        down = ~up & ~done
        k = going[down]
        s.hi[k], s.f_hi[k], s.why_hi[k] = x[down], f[down], why_x[down]
        going = going[up]
    return going


def _quadratic_steps(cycles: _FloatingCycles, s: _Search) -> None:
    """Before the regula falsi, where both ends are finite: inverse quadratic interpolation
    through the three latest points where it stays inside the bracket, else the chord
    (ln(opening) bends: a chord whose far end lies at the setpoint misses the root by up
    to a few 0.1 K, a parabola through three points near it by far less)."""
    for _ in range(_SH_QUAD_STEPS):
        q = np.nonzero((s.state == 3) & np.isfinite(s.hi) & np.isfinite(s.f_hi))[0]
        if q.size == 0:
            break
        (x0, x1, x2), (f0, f1, f2) = s.px[:, q], s.pf[:, q]
        a, b, fa, fb = s.lo[q], s.hi[q], s.f_lo[q], s.f_hi[q]
        with np.errstate(invalid="ignore", divide="ignore"):
            xq = (
                x0 * f1 * f2 / ((f0 - f1) * (f0 - f2))
                + x1 * f0 * f2 / ((f1 - f0) * (f1 - f2))
                + x2 * f0 * f1 / ((f2 - f0) * (f2 - f1))
            )
        x = np.where(np.isfinite(xq) & (xq > a) & (xq < b), xq, b - fb * (b - a) / (fb - fa))
        f, w = cycles.residual(x, q)
        s.record(q, x, f)
        nan = ~np.isfinite(f)
        # Converged as in bracketed_root: a residual within the tolerance or a bracket narrower than it.
        done = ~nan & ((np.abs(f) < _SH_FTOL) | (np.abs(b - a) < _SH_XTOL * np.abs(x)))
        s.state[q[done]] = 1
        # A NaN between two finite ends ends the search, as in bracketed_root.
        s.state[q[nan]], s.why[q[nan]] = 2, w[nan]
        pos, neg = ~nan & ~done & (f > 0), ~nan & ~done & (f <= 0)
        s.lo[q[pos]], s.f_lo[q[pos]] = x[pos], f[pos]
        s.hi[q[neg]], s.f_hi[q[neg]] = x[neg], f[neg]


def _regula_falsi(cycles: _FloatingCycles, s: _Search) -> None:
    """The points still searching with a bracket: the regula falsi of the pressures."""
    br = np.nonzero((s.state == 3) & np.isfinite(s.hi))[0]
    if br.size:
        _, s.state[br], s.why[br] = bracketed_root(
            cycles.residual, s.lo[br], s.hi[br], s.f_lo[br], s.f_hi[br], br, _SH_XTOL, _SH_FTOL, why_hi=s.why_hi[br]
        )


def _write_back(ctx: SolveContext, cycles: _FloatingCycles, s: _Search, rising, res: dict, idx) -> None:
    """Each point's latest cycle into ``res`` at ``idx``: a found superheat's, with the valve's
    opening at its maximum; a failed point NaN, with its status and reason."""
    store, state = cycles.store, s.state
    status, reason = store["status"], store["reason"]
    status[state == 2] = cycles.fail[state == 2]
    reason[state == 2] = [f"with the valve at its maximum opening, {w}" for w in s.why[state == 2]]
    status[state == 3] = STATUS_NOT_CONVERGED
    reason[state == 3] = "superheat iteration with the valve at its maximum opening did not converge"
    reason[rising] = [
        f"with the valve at its maximum opening the superheat rises above {x:.3g} K" for x in s.lo[rising]
    ]
    failed = state != 1
    for v in store.values():
        if v.dtype.kind == "f":
            v[failed] = np.nan
    store[cycles.key][~failed] = ctx.max_opening
    for k, v in store.items():
        res[k][idx] = v
