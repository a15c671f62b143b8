"""Vectorised root finding for the cycle's closures: bracketing and modified regula falsi.

Both pressure roots of the cycle (the condenser-outlet condition in the
discharge pressure, the superheat setpoint in the suction pressure), the flow
split of parallel branches and the floating superheat of a saturated valve are
roots of residuals that fall monotonically in their unknown. They are found
for every operating point of a batch at once:

- :func:`bracket` evaluates a first guess and one overshot secant step from
  it, which brackets the root in most points after two evaluations; the
  other points fall back to the whole range, narrowed by what the evaluated
  points showed;
- :func:`bracketed_root` closes a bracket by regula falsi with the
  Anderson-Bjorck modification (the Illinois halving where that fails), and
  copes with residuals a model leaves NaN (its envelope's end);
- :func:`pressure_root` iterates in saturation temperature, in which both
  pressure closures are close to linear, and :func:`range_status` says why a
  residual of one sign over the whole range has no root there.

References
----------
Dowell, M., Jarratt, P. (1971). A modified regula falsi method for computing
the root of an equation. BIT 11, 168-174 (the Illinois algorithm).
Anderson, N., Bjorck, A. (1973). A new high order method of regula falsi type
for computing a root of an equation. BIT 13, 253-264.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from evtms.cycle.state import XTOL
from evtms.cycle.status import STATUS_CONVERGED, STATUS_NOT_CONVERGED, STATUS_OUTSIDE_ENVELOPE
from evtms.fluid import SaturationCurve

#: ``residual(x, idx)``: the residuals of the points ``idx`` at ``x`` and a reason per point
#: (non-empty where the residual is NaN).
Residual = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class _RegulaFalsi:
    """The brackets of :func:`bracketed_root`'s points while it iterates."""

    lo: np.ndarray
    hi: np.ndarray
    f_lo: np.ndarray
    f_hi: np.ndarray
    x: np.ndarray
    state: np.ndarray
    reason: np.ndarray
    kept: np.ndarray  # end kept by the last update: -1 lo, +1 hi
    why_lo: np.ndarray  # reasons of NaN ends
    why_hi: np.ndarray


def _empty_reasons(n: int) -> np.ndarray:
    return np.full(n, "", dtype=object)


def bracketed_root(
    fun: Residual,
    lo: np.ndarray,
    hi: np.ndarray,
    f_lo: np.ndarray,
    f_hi: np.ndarray,
    idx: np.ndarray,
    xtol: float,
    ftol: float,
    maxiter: int = 80,
    why_lo: np.ndarray | None = None,
    why_hi: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised root of a decreasing residual on [lo, hi], modified regula falsi.

    ``fun(x, idx)`` returns the residuals of points ``idx`` at ``x`` and a
    reason string per point (non-empty where the residual is NaN). The
    residual is positive at ``lo`` and negative at ``hi``; an end may be NaN
    (its model left its envelope there), in which case that end's sign is
    taken as known and the step is a bisection until both ends are finite. A
    NaN inside the bracket joins the end that is NaN; with both ends finite,
    it ends the point's search with its reason. A bracket that shrinks onto
    a NaN end with the residual still away from zero has no root inside the
    models' envelope: the point fails with that end's reason (``why_lo``,
    ``why_hi``: the reasons of NaN ends given, else the NaN met inside).

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
    n = lo.size
    s = _RegulaFalsi(
        lo=lo.copy(),
        hi=hi.copy(),
        f_lo=f_lo.copy(),
        f_hi=f_hi.copy(),
        x=0.5 * (lo + hi),
        state=np.zeros(n, np.int8),
        reason=_empty_reasons(n),
        kept=np.zeros(n, np.int8),
        why_lo=_empty_reasons(n) if why_lo is None else np.asarray(why_lo, dtype=object).copy(),
        why_hi=_empty_reasons(n) if why_hi is None else np.asarray(why_hi, dtype=object).copy(),
    )
    for _ in range(maxiter):
        act = np.nonzero(s.state == 0)[0]
        if act.size == 0:
            break
        _regula_falsi_step(s, fun, idx, act, xtol, ftol)
    s.state[s.state == 0] = 3
    s.reason[s.state == 1] = ""
    return s.x, s.state, s.reason


def _regula_falsi_step(s: _RegulaFalsi, fun: Residual, idx: np.ndarray, act: np.ndarray, xtol, ftol) -> None:
    """One step of the points ``act``: the secant (or the midpoint) evaluated, the brackets updated."""
    a, b, fa, fb = s.lo[act], s.hi[act], s.f_lo[act], s.f_hi[act]
    with np.errstate(invalid="ignore", divide="ignore"):
        xs = b - fb * (b - a) / (fb - fa)
    secant = np.isfinite(xs) & (xs > np.minimum(a, b)) & (xs < np.maximum(a, b))
    xn = np.where(secant, xs, 0.5 * (a + b))
    f, why = fun(xn, idx[act])
    s.x[act] = xn
    nan = ~np.isfinite(f)
    small = np.abs(b - a) < xtol * np.abs(xn)
    finite_ends = np.isfinite(fa) & np.isfinite(fb)
    conv = ~nan & ((np.abs(f) < ftol) | (small & finite_ends))
    s.state[act[conv]] = 1
    _nan_joins_its_end(s, act, xn, why, nan, small, fa, fb)
    # Shrunk onto a NaN end with the residual away from zero: the root lies beyond it.
    edge = ~nan & ~conv & small
    s.state[act[edge]] = 2
    at_hi = ~np.isfinite(fb)
    s.reason[act[edge]] = np.where(at_hi, s.why_hi[act], s.why_lo[act])[edge]
    s.reason[act[edge & (s.reason[act] == "")]] = "the root lies where the models return NaN"
    _replace_ends(s, act, xn, f, ~nan & ~conv & ~edge)


def _nan_joins_its_end(s: _RegulaFalsi, act, xn, why, nan, small, fa, fb) -> None:
    """A NaN trial replaces the NaN end of its bracket; with both ends finite (or the bracket
    within the tolerance) it ends the point's search with its reason."""
    to_hi = nan & ~np.isfinite(fb)
    to_lo = nan & ~to_hi & ~np.isfinite(fa)
    dead = nan & ((~to_hi & ~to_lo) | small)
    s.state[act[dead]] = 2
    s.reason[act[nan]] = why[nan]
    s.hi[act[to_hi & ~dead]] = xn[to_hi & ~dead]
    s.lo[act[to_lo & ~dead]] = xn[to_lo & ~dead]
    s.why_hi[act[to_hi]] = why[to_hi]
    s.why_lo[act[to_lo]] = why[to_lo]


def _replace_ends(s: _RegulaFalsi, act, xn, f, upd) -> None:
    """A finite residual replaces the end of its sign; an end kept twice in a row has its
    residual scaled down so that the next step moves it."""
    pos, neg = upd & (f > 0), upd & (f <= 0)
    i_pos, i_neg = act[pos], act[neg]
    # Anderson-Bjorck scaling of the kept end: 1 - f_new/f_replaced, or the
    # Illinois 1/2 where that is not positive (or the replaced end was NaN).
    with np.errstate(invalid="ignore", divide="ignore"):
        m_pos = 1.0 - f[pos] / s.f_lo[i_pos]
        m_neg = 1.0 - f[neg] / s.f_hi[i_neg]
    m_pos = np.where(m_pos > 0, m_pos, 0.5)
    m_neg = np.where(m_neg > 0, m_neg, 0.5)
    s.lo[i_pos], s.f_lo[i_pos] = xn[pos], f[pos]
    s.f_hi[i_pos] = np.where(s.kept[i_pos] == 1, m_pos * s.f_hi[i_pos], s.f_hi[i_pos])
    s.kept[i_pos] = 1
    s.hi[i_neg], s.f_hi[i_neg] = xn[neg], f[neg]
    s.f_lo[i_neg] = np.where(s.kept[i_neg] == -1, m_neg * s.f_lo[i_neg], s.f_lo[i_neg])
    s.kept[i_neg] = -1


@dataclass(frozen=True)
class Bracket:
    """Brackets of the roots of a residual that falls with the saturation temperature, per point.

    Attributes
    ----------
    lo, hi : numpy.ndarray
        The ends [K] (saturation temperatures).
    f_lo, f_hi : numpy.ndarray
        The residuals there (NaN where a model left its envelope).
    why_lo, why_hi : numpy.ndarray
        The reasons of NaN residuals.
    slope : numpy.ndarray
        Secant slope of the two guess points [1/K], NaN where not evaluated.
    lo_is_end, hi_is_end : numpy.ndarray
        True where that end is the range's own end (an end from a guess point
        always has the sign of its side, so a residual of the wrong sign there
        means that the range holds no root).
    found : numpy.ndarray
        True where a guess point's residual is already within the tolerance
        (``bracket``'s ``ftol``): the root is that point, ``lo = hi``, and its
        evaluation there was the point's last.
    """

    lo: np.ndarray
    hi: np.ndarray
    f_lo: np.ndarray
    f_hi: np.ndarray
    why_lo: np.ndarray
    why_hi: np.ndarray
    slope: np.ndarray
    lo_is_end: np.ndarray
    hi_is_end: np.ndarray
    found: np.ndarray | None = None


def bracket(
    sat: SaturationCurve,
    residual: Residual,
    t_lo: np.ndarray,
    t_hi: np.ndarray,
    t_guess: np.ndarray,
    slope: np.ndarray,
    max_step: float,
    overshoot: float = 1.5,
    ftol: float | None = None,
) -> Bracket:
    """Bracket the root of a residual that falls with the saturation temperature.

    ``residual(p, i)`` gives the residuals and reasons of the points ``i``
    at pressures ``p`` [Pa]. Where ``t_guess`` [K] lies inside ``(t_lo, t_hi)``
    the residual is evaluated there and after one secant step with the
    estimated ``slope`` [1/K] (< 0), overshot ``overshoot`` times (1.5 for a
    typical slope; less for a slope measured near the root) and by 0.01 K and
    at most ``max_step`` [K], so that it usually changes sign between the
    two: that pair is the bracket. Elsewhere, and where it does not change
    sign, the bracket is ``[t_lo, t_hi]`` narrowed by what the evaluated
    points showed, and its remaining ends are evaluated. With ``ftol``, a
    guess point whose residual is within it is the root (``found``; a point
    found at its guess is not evaluated again).
    """
    n = t_lo.size
    a, b = t_lo.copy(), t_hi.copy()
    fa, fb = np.full(n, np.nan), np.full(n, np.nan)
    wa, wb = _empty_reasons(n), _empty_reasons(n)
    need_a, need_b = np.ones(n, bool), np.ones(n, bool)
    new_slope = np.full(n, np.nan)
    found = np.zeros(n, bool)
    g = np.nonzero(np.isfinite(t_guess) & (t_guess > t_lo) & (t_guess < t_hi))[0]
    if g.size:
        trials = _guess_and_secant(sat, residual, g, t_guess[g], slope[g], max_step, t_lo[g], t_hi[g], overshoot, ftol)
        if ftol is not None:
            for t, f, _ in trials:
                hit = np.isfinite(f) & (np.abs(f) < ftol) & ~found[g]
                k = g[hit]
                found[k], a[k], b[k], fa[k], fb[k] = True, t[hit], t[hit], f[hit], f[hit]
                need_a[k] = need_b[k] = False
        for t, f, w in trials:
            above = np.isfinite(f) & (f > 0) & (t > a[g]) & ~found[g]  # the root lies above t
            k = g[above]
            a[k], fa[k], wa[k], need_a[k] = t[above], f[above], w[above], False
            below = np.isfinite(f) & (f <= 0) & (t < b[g]) & ~found[g]
            k = g[below]
            b[k], fb[k], wb[k], need_b[k] = t[below], f[below], w[below], False
        (t_g, f_g, _), (t_2, f_2, _) = trials[:2]
        with np.errstate(invalid="ignore", divide="ignore"):
            new_slope[g] = (f_2 - f_g) / (t_2 - t_g)
    lo_is_end, hi_is_end = need_a.copy(), need_b.copy()
    for t, f, w, need in ((a, fa, wa, need_a), (b, fb, wb, need_b)):
        k = np.arange(n)[need]
        if k.size:
            f[k], w[k] = residual(sat.pressure(t[k]), k)
    return Bracket(a, b, fa, fb, wa, wb, new_slope, lo_is_end, hi_is_end, found)


def _guess_and_secant(
    sat: SaturationCurve, residual: Residual, g, t_g, slope, max_step, t_lo, t_hi, overshoot=1.5, ftol=None
) -> list:
    """The residual of the points ``g`` at their guess ``t_g`` [K] and after one overshot secant
    step from it within ``[t_lo, t_hi]``: ``[(t, f, why)]`` of both (the second NaN where the
    guess is within ``ftol`` of the root: not evaluated)."""
    f_g, w_g = residual(sat.pressure(t_g), g)
    with np.errstate(invalid="ignore", divide="ignore"):
        step = -overshoot * f_g / slope + np.sign(f_g) * 0.01
    t_2 = np.clip(t_g + np.clip(np.nan_to_num(step), -max_step, max_step), t_lo, t_hi)
    if ftol is None:
        f_2, w_2 = residual(sat.pressure(t_2), g)
        return [(t_g, f_g, w_g), (t_2, f_2, w_2)]
    f_2, w_2 = np.full(g.size, np.nan), _empty_reasons(g.size)
    go = ~(np.isfinite(f_g) & (np.abs(f_g) < ftol))
    if go.any():
        f_2[go], w_2[go] = residual(sat.pressure(t_2[go]), g[go])
    trials = [(t_g, f_g, w_g), (t_2, f_2, w_2)]
    # The tighter step of a measured slope falls short where the slope changed: one more secant
    # step through both trials (overshot 1.5 times), before the whole range.
    short = go & np.isfinite(f_2) & (np.abs(f_2) >= ftol) & (np.sign(f_2) == np.sign(f_g)) & (t_2 != t_g)
    if short.any():
        with np.errstate(invalid="ignore", divide="ignore"):
            chord = (f_2 - f_g) / (t_2 - t_g)
            step = -1.5 * f_2 / np.where(chord < 0, chord, slope) + np.sign(f_2) * 0.01
        t_3 = np.clip(t_2 + np.clip(np.nan_to_num(step), -max_step, max_step), t_lo, t_hi)
        f_3, w_3 = np.full(g.size, np.nan), _empty_reasons(g.size)
        f_3[short], w_3[short] = residual(sat.pressure(t_3[short]), g[short])
        trials.append((t_3, f_3, w_3))
    return trials


def pressure_root(
    sat: SaturationCurve,
    residual: Residual,
    br: Bracket,
    idx: np.ndarray,
    ftol: float,
    status: np.ndarray,
    reason: np.ndarray,
    what: str,
    codes: dict[str, int] | None = None,
) -> np.ndarray:
    """Root in pressure [Pa] of ``residual(p, idx)`` for the points ``idx`` of a bracket.

    Iterates on the saturation temperature, in which both closures are close
    to linear, from the bracket ``br`` of :func:`bracket`. Marks
    points whose model left its envelope (with its reason; status 1, or the
    status ``codes`` gives for that reason) or that did not converge in
    ``status`` and ``reason`` (in place; ``what`` names the iteration).
    """

    def fun(t_sat, i):
        return residual(sat.pressure(t_sat), i)

    root, state, why = bracketed_root(
        fun,
        br.lo[idx],
        br.hi[idx],
        br.f_lo[idx],
        br.f_hi[idx],
        idx,
        XTOL,
        ftol,
        why_lo=br.why_lo[idx],
        why_hi=br.why_hi[idx],
    )
    codes = codes or {}
    status[idx[state == 2]] = [codes.get(w, STATUS_OUTSIDE_ENVELOPE) for w in why[state == 2]]
    status[idx[state == 3]] = STATUS_NOT_CONVERGED
    reason[idx] = np.where(state == 3, f"{what} iteration did not converge", why)
    return sat.pressure(root)


def tightest_bound(
    candidates: list[tuple[np.ndarray | float, str | None]], upper: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The tightest of several bounds per point, and the LUT axis it is (None: a physical bound)."""
    values = np.stack(np.broadcast_arrays(*[np.asarray(v, float) for v, _ in candidates]))
    which = np.argmin(values, axis=0) if upper else np.argmax(values, axis=0)
    names = np.array([name for _, name in candidates], dtype=object)[which]
    return np.take_along_axis(values, which[None, :], axis=0)[0], names


def range_status(br: Bracket, lo, lo_axis, hi, hi_axis, code: int, below: tuple, above: tuple):
    """Status and reason per point of a bracket ``br`` of :func:`bracket`.

    A residual of one sign up to an end of the range [``lo``, ``hi``] [Pa]
    means no root in it. Where that end is a LUT axis (``lo_axis``,
    ``hi_axis``; None for a physical bound) the point is outside the envelope
    (status 1, the axis named, text ``below[1]`` / ``above[1]`` and the
    pressure); elsewhere it gets ``code`` and ``below[0]`` / ``above[0]``.
    """
    status = np.full(lo.size, STATUS_CONVERGED, np.int8)
    reason = _empty_reasons(lo.size)
    f_lo, f_hi = br.f_lo, br.f_hi
    low = br.lo_is_end & np.isfinite(f_lo) & (f_lo <= 0)
    high = br.hi_is_end & ~low & np.isfinite(f_hi) & (f_hi >= 0)
    for where, axes, bound, (physical, beyond) in ((low, lo_axis, lo, below), (high, hi_axis, hi, above)):
        lut = where & np.array([a is not None for a in axes], dtype=bool)
        status[where] = code
        status[lut] = STATUS_OUTSIDE_ENVELOPE
        reason[where & ~lut] = physical
        reason[lut] = [f"{beyond} {b:.4g} Pa, the end of the {a}" for b, a in zip(bound[lut], axes[lut], strict=True)]
    return status, reason
