r"""Two evaporating branches in parallel: the flow split at a suction iterate.

Both valves see the condenser's liquid (enthalpy ``h_D``) and both branches
end at the suction pressure ``p_A``, each after its own pressure drop (a fixed
point per branch, as the single branch's). Each valve holds its branch's
outlet at the setpoint superheat; at a suction iterate the flow splits so that
both outlets leave at the same enthalpy,

.. math:: h_{out,1}((1 - s)\,\dot m) = h_{out,2}(s\,\dot m)

(``h_out_continued`` of each branch [J/kg], ``s`` the share of the flow
through the second branch [1]). More flow through a branch lowers its outlet
enthalpy, so the difference rises monotonically with ``s``: regula falsi
(:func:`~evtms.cycle.roots.bracketed_root`) on ``s`` within the flows the
branch models cover, warm-started from the previous suction iterate's split.
At the suction root both outlets are at the setpoint, and the outlets mix at
that state.

``ops["branch_mode"]`` (absent: all 0; see :mod:`evtms.cycle.state`) changes
a point's split (:mod:`evtms.cycle.limits` sets it): 1 (2), the first
(second) branch's valve at its maximum opening: the other branch alone holds
the setpoint, its outlet at ``h_set`` (the enthalpy at the setpoint superheat
at ``p_A`` [J/kg]), and the suction superheat (``ops["superheat"]``) is the
mixture's, found as a floating superheat (:mod:`evtms.cycle.saturation`); 3
(4), the first (second) branch's valve closed: all the flow goes through the
other branch, and the closed one leaves its inlet state with no flow and no
heat.

Where the difference has one sign over the whole range of flows the models
cover, one branch takes the least flow its model covers (its valve nearly
closed). The outlets then differ, and the mixture still tells the suction
closure which way to go; a root found so is not a state with both valves
holding their setpoint and fails in the final evaluation (the limits then
close that valve, where it is a branch at its least flow).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evtms.cycle.branches import run_branch
from evtms.cycle.roots import bracketed_root
from evtms.cycle.state import (
    CLAMP_FIRST_LEAST,
    CLAMP_OTHER,
    CLAMP_SECOND_LEAST,
    CP_SCALE,
    DP_PASSES,
    DP_TOL,
    FIRST_CLOSED,
    FIRST_FLOATS,
    INNER_FTOL,
    SECOND_CLOSED,
    SECOND_FLOATS,
    SPLIT_HALF_WIDTH,
    WARM_OVERSHOOT,
    XTOL,
    Ops,
    SolveContext,
    SolveState,
    take,
)


@dataclass(frozen=True)
class EvaporatingSide:
    """The evaporating side of a suction iterate, from the valves to the suction.

    Attributes
    ----------
    h_out, p_out : numpy.ndarray
        The suction-side outlet (the branches' mixture) [J/kg], [Pa].
    reason : numpy.ndarray
        Why a point's outlet is NaN (empty otherwise).
    p_D : numpy.ndarray
        The first branch's valve outlet = coil inlet pressure [Pa].
    no_heat_flow : numpy.ndarray
        A single branch whose inlet is not colder than its stream (False for parallel branches).
    branches : dict of str to dict
        Each branch's model result, by component.
    flows, inlets : dict of str to numpy.ndarray
        Each branch's refrigerant flow [kg/s] and inlet pressure [Pa], by component.
    h_set : numpy.ndarray or None
        The enthalpy at the setpoint superheat at ``p_A`` [J/kg] where a parallel valve floats.
    """

    h_out: np.ndarray
    p_out: np.ndarray
    reason: np.ndarray
    p_D: np.ndarray
    no_heat_flow: np.ndarray
    branches: dict[str, dict]
    flows: dict[str, np.ndarray]
    inlets: dict[str, np.ndarray]
    h_set: np.ndarray | None = None


@dataclass
class _Split:
    """One call's flow split: its points' inputs and bounds, and the split found so far.

    ``i`` in the methods are the points' positions in this call's arrays
    (``idx[i]`` in the whole batch).
    """

    ctx: SolveContext
    ops: Ops
    mdot: np.ndarray
    p_A: np.ndarray
    h_D: np.ndarray
    mode: np.ndarray
    h_set: np.ndarray
    inlets: dict[str, np.ndarray]
    least: tuple[float, float]  # each branch model's least flow [kg/s]
    s_lo: np.ndarray
    s_hi: np.ndarray
    first_least: np.ndarray  # which bound binds: the first (second) branch at its least flow
    second_least: np.ndarray
    ok: np.ndarray
    reason: np.ndarray
    share: np.ndarray
    clamped: np.ndarray
    state: SolveState | None = None
    idx: np.ndarray | None = None
    _last: tuple | None = None

    def evaluate(self, share: np.ndarray, i: np.ndarray) -> tuple[dict, dict]:
        """Both branches of the points ``i`` at the second branch's ``share`` of the flow.

        The latest evaluation is kept: the drops' pass at the split found asks again for the
        split search's last trial (same points, share and inlets), which it returns as it was."""
        names = self.ctx.names
        share = np.asarray(share, float)
        inlets = [self.inlets[c][i] for c in names]
        last = self._last
        if (
            last is not None
            and np.array_equal(last[0], i)
            and np.array_equal(last[1], share)
            and all(np.array_equal(a, b) for a, b in zip(last[2], inlets, strict=True))
        ):
            return last[3], last[4]
        o, m = take(self.ops, i), self.mdot[i]
        open1, open2 = self.mode[i] != FIRST_CLOSED, self.mode[i] != SECOND_CLOSED
        r1 = run_branch(self.ctx, names[0], o, m * (1.0 - share), inlets[0], self.h_D[i], open1)
        r2 = run_branch(self.ctx, names[1], o, m * share, inlets[1], self.h_D[i], open2)
        self._last = (np.array(i, copy=True), share.copy(), [a.copy() for a in inlets], r1, r2)
        return r1, r2

    def residual(self, share: np.ndarray, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The split's residual [about K], rising with ``share``, and the reasons of NaN."""
        r1, r2 = self.evaluate(share, i)
        h1, h2 = r1["h_out_continued"], r2["h_out_continued"]
        md, h_set = self.mode[i], self.h_set[i]
        # Both hold the setpoint: equal outlets; one valve saturated: the other one at the setpoint.
        f = np.where(md == FIRST_FLOATS, h2 - h_set, np.where(md == SECOND_FLOATS, h_set - h1, h2 - h1))
        why = np.where(r1["reason"] != "", r1["reason"], r2["reason"])
        return f / CP_SCALE, why


def parallel(
    ctx: SolveContext,
    state: SolveState,
    ops: Ops,
    mdot: np.ndarray,
    p_A: np.ndarray,
    h_D: np.ndarray,
    idx: np.ndarray,
    final: bool,
    h_set: np.ndarray | None = None,
) -> EvaporatingSide:
    """Two evaporating branches in parallel from the valves to the suction, at total flow ``mdot`` [kg/s].

    At suction pressure ``p_A`` [Pa], valve-inlet enthalpy ``h_D`` [J/kg];
    ``idx`` are the points' indices in the whole batch (for the warm starts in
    ``state``). Without ``final``, the split is solved at the branches'
    present pressure drops, then each drop at that split, until the drops stop
    moving, and the split and drops are kept for the next iterate; with
    ``final`` (at the suction root), the stored split and drops are used as
    they are (the last iterate's).
    """
    if not final and state.warm:
        _extrapolate(ctx, state, p_A, idx)
    sp = _setup(ctx, state, ops, mdot, p_A, h_D, idx, h_set)
    if not final:
        _iterate_drops(sp)
        for c in ctx.names:
            drop = sp.inlets[c] - p_A
            state.dp_branch[c][idx] = np.where(np.isfinite(drop), drop, state.dp_branch[c][idx])
        state.split[idx] = np.where(np.isfinite(sp.share), sp.share, state.split[idx])
        state.clamped[idx] = sp.clamped
        if state.warm:
            _remember(ctx, state, p_A, idx, np.isfinite(sp.share))
    else:
        sp.clamped = state.clamped[idx]
        _split_at_the_root(sp)
    return _mixed_outlet(sp, final)


def _extrapolate(ctx: SolveContext, state: SolveState, p_A: np.ndarray, idx: np.ndarray) -> None:
    """A warm closure's split and drops to start a suction iterate from (``state`` in place): linear
    in the suction saturation temperature through the two latest iterates' (``state.par_pairs``),
    where there are two; the split within [0, 1], the drops not below 0."""
    pairs = state.par_pairs[:, :, idx]
    t = ctx.sat.temperature(p_A)
    (t1, *y1), (t0, *y0) = pairs[0], pairs[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        w = (t - t1) / (t1 - t0)
    use = np.isfinite(w) & np.all(np.isfinite(pairs), axis=(0, 1)) & (np.abs(t1 - t0) > 1e-9)
    if not use.any():
        return
    k = idx[use]
    guess = [a[use] + w[use] * (a[use] - b[use]) for a, b in zip(y1, y0, strict=True)]
    state.split[k] = np.clip(guess[0], 0.0, 1.0)
    for c, g in zip(ctx.names, guess[1:], strict=True):
        state.dp_branch[c][k] = np.maximum(g, 0.0)


def _remember(ctx: SolveContext, state: SolveState, p_A: np.ndarray, idx: np.ndarray, ok: np.ndarray) -> None:
    """This suction iterate's split and drops as the latest of ``state.par_pairs`` (where ``ok``)."""
    k = idx[ok]
    state.par_pairs[1, :, k] = state.par_pairs[0, :, k]
    rows = [ctx.sat.temperature(p_A)[ok], state.split[k], *(state.dp_branch[c][k] for c in ctx.names)]
    state.par_pairs[0, :, k] = np.stack(rows, axis=-1)


def _setup(ctx: SolveContext, state: SolveState, ops: Ops, mdot, p_A, h_D, idx, h_set) -> _Split:
    """The split's bounds and starting point: the shares within the flows both branch models cover."""
    names = ctx.names
    n = p_A.size
    mode = np.asarray(ops.get("branch_mode", np.zeros(n)), int)
    (lo1, hi1), (lo2, hi2) = (ctx.models.flow_range(c) for c in names)
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
    share = np.where(ok, state.split[idx], np.nan)
    share[ok & first_closed] = 1.0
    share[ok & second_closed] = 0.0
    return _Split(
        ctx=ctx,
        ops=ops,
        mdot=mdot,
        p_A=p_A,
        h_D=h_D,
        mode=mode,
        h_set=np.full(n, np.nan) if h_set is None else h_set,
        inlets={c: p_A + state.dp_branch[c][idx] for c in names},
        least=(lo1, lo2),
        s_lo=s_lo,
        s_hi=s_hi,
        first_least=first_least,
        second_least=second_least,
        ok=ok,
        reason=reason,
        share=share,
        clamped=np.zeros(n, np.int8),
        state=state,
        idx=idx,
    )


def _iterate_drops(sp: _Split) -> None:
    """The split at the present drops, then each branch's drop at that split, until the drops
    stop moving (see :data:`~evtms.cycle.state.DP_TOL`): the outlets then meet at ``p_A``."""
    p_A = sp.p_A
    todo = np.nonzero(sp.ok)[0]
    for _ in range(DP_PASSES):
        split = todo[sp.mode[todo] <= SECOND_FLOATS]
        if split.size:
            _solve_split(sp, split)
        todo = todo[np.isfinite(sp.share[todo])]
        if todo.size == 0:
            break
        r1, r2 = sp.evaluate(sp.share[todo], todo)
        moving = np.zeros(todo.size, bool)
        for c, r in zip(sp.ctx.names, (r1, r2), strict=True):
            p_in = sp.inlets[c][todo]
            new = np.where(np.isfinite(r["p_out"]), p_in - r["p_out"], p_in - p_A[todo])
            moving |= np.abs(new - (p_in - p_A[todo])) > DP_TOL
            sp.inlets[c][todo] = p_A[todo] + new
        todo = todo[moving]
        if todo.size == 0:
            break


def _split_at_the_root(sp: _Split) -> None:
    """With a saturated valve the mixture depends on the split itself (not only on both outlets
    being equal): the split of the last suction iterate, which may be the root's neighbour, is
    solved again at the root (at the stored drops), so that the mixture closes there."""
    floats = (sp.mode == FIRST_FLOATS) | (sp.mode == SECOND_FLOATS)
    again = np.nonzero(sp.ok & (sp.clamped == 0) & floats)[0]
    if again.size:
        kept, why = sp.share[again].copy(), sp.reason[again].copy()
        _solve_split(sp, again)
        lost = ~np.isfinite(sp.share[again])
        sp.share[again[lost]], sp.reason[again[lost]] = kept[lost], why[lost]


def _solve_split(sp: _Split, todo: np.ndarray) -> None:
    """The split of the points ``todo`` at the present branch inlets, into ``sp.share``."""
    lo, hi, f_lo, f_hi, w_lo, w_hi, found = _bracket_split(sp, todo)
    no_root = ~((f_lo > 0) | ~np.isfinite(f_lo)) | ~((f_hi <= 0) | ~np.isfinite(f_hi))
    no_root |= ~np.isfinite(f_lo) & ~np.isfinite(f_hi)
    no_root &= ~found
    sp.share[todo] = np.nan
    _clamp_to_least_flow(sp, todo, no_root, lo, hi, f_lo, f_hi, w_lo, w_hi)
    sp.share[todo[found]] = lo[found]
    go = np.nonzero(~no_root & ~found)[0]
    if go.size:
        x, state, why = bracketed_root(
            sp.residual, lo[go], hi[go], f_lo[go], f_hi[go], todo[go], XTOL, INNER_FTOL, why_lo=w_lo[go]
        )
        fine = state == 1
        sp.share[todo[go[fine]]] = x[fine]
        failed = np.where(state[~fine] == 3, "flow-split iteration did not converge", why[~fine])
        sp.reason[todo[go[~fine]]] = failed


def _bracket_split(sp: _Split, todo: np.ndarray) -> tuple[np.ndarray, ...]:
    """Bracket of the split of the points ``todo``: a narrow one around the previous split where
    it holds the root (warm start), else the whole range of shares; ``(lo, hi, f_lo, f_hi, w_lo,
    w_hi, found)``, ``found`` where a trial is the root within the tolerance (``lo`` = ``hi``).
    A warm-started closure first tries the secant from the previous split along the slope its
    last bracket measured (:func:`_secant_bracket`)."""
    lo, hi = sp.s_lo[todo].copy(), sp.s_hi[todo].copy()
    f_lo, f_hi = np.full(todo.size, np.nan), np.full(todo.size, np.nan)
    w_lo, w_hi = np.full(todo.size, "", dtype=object), np.full(todo.size, "", dtype=object)
    found = np.zeros(todo.size, bool)
    prev = sp.share[todo]
    warm = np.isfinite(prev)
    if sp.state is not None and sp.state.warm:
        done = _secant_bracket(sp, todo, prev, warm, (lo, hi, f_lo, f_hi), found)
        warm &= ~done
    if warm.any():
        k = np.nonzero(warm)[0]
        a = np.maximum(prev[k] - SPLIT_HALF_WIDTH, lo[k])
        b = np.minimum(prev[k] + SPLIT_HALF_WIDTH, hi[k])
        fa, _ = sp.residual(a, todo[k])
        fb, _ = sp.residual(b, todo[k])
        good = np.isfinite(fa) & np.isfinite(fb) & (fa > 0) & (fb <= 0)
        g = k[good]
        lo[g], hi[g], f_lo[g], f_hi[g] = a[good], b[good], fa[good], fb[good]
        if sp.state is not None:
            with np.errstate(invalid="ignore", divide="ignore"):
                sp.state.split_slope[sp.idx[todo[g]]] = (fb[good] - fa[good]) / (b[good] - a[good])
        warm[k[~good]] = False
    cold = np.nonzero(~warm & ~found & ~np.isfinite(f_lo))[0]
    if cold.size:
        f_lo[cold], w_lo[cold] = sp.residual(lo[cold], todo[cold])
        f_hi[cold], w_hi[cold] = sp.residual(hi[cold], todo[cold])
    return lo, hi, f_lo, f_hi, w_lo, w_hi, found


def _secant_bracket(sp: _Split, todo: np.ndarray, prev: np.ndarray, warm: np.ndarray, ends: tuple, found) -> np.ndarray:
    """Warm bracket of the points ``todo`` with a previous split ``prev`` and a measured slope: the
    residual there, then the secant step along that slope overshot :data:`WARM_OVERSHOOT` times and
    by 1e-6; ``ends`` (lo, hi, f_lo, f_hi) and ``found`` in place. Returns the points done (found,
    or bracketed by the two trials)."""
    lo, hi, f_lo, f_hi = ends
    slope = sp.state.split_slope[sp.idx[todo]]
    done = np.zeros(todo.size, bool)
    k = np.nonzero(warm & (slope < 0))[0]
    if k.size == 0:
        return done
    x1 = np.clip(prev[k], lo[k], hi[k])
    f1, _ = sp.residual(x1, todo[k])
    hit = np.isfinite(f1) & (np.abs(f1) < INNER_FTOL)
    found[k[hit]], lo[k[hit]], hi[k[hit]], f_lo[k[hit]], f_hi[k[hit]] = True, x1[hit], x1[hit], f1[hit], f1[hit]
    done[k[hit]] = True
    go = np.isfinite(f1) & ~hit
    k, x1, f1 = k[go], x1[go], f1[go]
    if k.size == 0:
        return done
    x2 = np.clip(x1 - WARM_OVERSHOOT * f1 / slope[k] + np.sign(f1) * 1e-6, lo[k], hi[k])
    f2 = _secant_trial(sp, todo, k, x1, f1, x2, ends, found, done)
    # Where the measured slope fell short: one more step, along the chord of both trials, overshot.
    with np.errstate(invalid="ignore", divide="ignore"):
        chord = (f2 - f1) / (x2 - x1)
    ok = np.isfinite(chord) & (chord < 0)
    sp.state.split_slope[sp.idx[todo[k[ok]]]] = chord[ok]
    short = ok & ~done[k]
    if short.any():
        k, x2, f2, chord = k[short], x2[short], f2[short], chord[short]
        x3 = np.clip(x2 - 1.5 * f2 / chord + np.sign(f2) * 1e-6, lo[k], hi[k])
        _secant_trial(sp, todo, k, x2, f2, x3, ends, found, done)
    return done


def _secant_trial(sp: _Split, todo, k, x1, f1, x2, ends: tuple, found, done) -> np.ndarray:
    """The split's residual of the points ``todo[k]`` at ``x2``: found where within the tolerance,
    bracketed with the trial ``x1`` (residual ``f1``) where the sign changed (``ends``, ``found``,
    ``done`` in place); returns the residuals."""
    lo, hi, f_lo, f_hi = ends
    f2, _ = sp.residual(x2, todo[k])
    hit = np.isfinite(f2) & (np.abs(f2) < INNER_FTOL)
    found[k[hit]], lo[k[hit]], hi[k[hit]], f_lo[k[hit]], f_hi[k[hit]] = True, x2[hit], x2[hit], f2[hit], f2[hit]
    done[k[hit]] = True
    up = ~hit & np.isfinite(f2) & (f1 > 0) & (f2 <= 0) & (x1 < x2)  # root between x1 < x2
    down = ~hit & np.isfinite(f2) & (f1 <= 0) & (f2 > 0) & (x2 < x1)  # root between x2 < x1
    for m, a, b, fa, fb in ((up, x1, x2, f1, f2), (down, x2, x1, f2, f1)):
        j = k[m]
        lo[j], hi[j], f_lo[j], f_hi[j] = a[m], b[m], fa[m], fb[m]
        done[j] = True
    return f2


def _clamp_to_least_flow(sp: _Split, todo, no_root, lo, hi, f_lo, f_hi, w_lo, w_hi) -> None:
    """Points whose split residual has one sign over the whole range: the split at the bound it
    points to (one branch at its least flow, the kind in ``sp.clamped``), or NaN with the reason
    of a NaN end."""
    finite = np.isfinite(f_lo) & np.isfinite(f_hi)
    low = no_root & finite & (f_lo <= 0)
    high = no_root & finite & (f_hi > 0)
    sp.share[todo[low]], sp.share[todo[high]] = lo[low], hi[high]
    kind = np.zeros(todo.size, np.int8)
    kind[low] = np.where(sp.second_least[todo[low]], CLAMP_SECOND_LEAST, CLAMP_OTHER)
    kind[high] = np.where(sp.first_least[todo[high]], CLAMP_FIRST_LEAST, CLAMP_OTHER)
    sp.clamped[todo] = kind
    nan = no_root & ~low & ~high
    sp.reason[todo[nan]] = np.where(~np.isfinite(f_lo[nan]), w_lo[nan], w_hi[nan])


def _mixed_outlet(sp: _Split, final: bool) -> EvaporatingSide:
    """Both branches at the split found, and their outlets mixed; at the root (``final``) a split
    at a least flow has no mixture, and says which branch would need less."""
    names, labels = sp.ctx.names, sp.ctx.labels
    share, mdot, reason = sp.share, sp.mdot, sp.reason
    r1, r2 = sp.evaluate(share, np.arange(share.size))
    flows = {names[0]: mdot * (1.0 - share), names[1]: mdot * share}
    with np.errstate(invalid="ignore"):
        h_mix = (flows[names[0]] * r1["h_out_continued"] + flows[names[1]] * r2["h_out_continued"]) / mdot
    if final:
        clamped = sp.clamped
        h_mix[clamped > 0] = np.nan
        lows = {CLAMP_FIRST_LEAST: (labels[0], sp.least[0]), CLAMP_SECOND_LEAST: (labels[1], sp.least[1])}
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
    return EvaporatingSide(
        h_out=h_mix,
        p_out=sp.p_A.copy(),
        reason=reason,
        p_D=sp.inlets[names[0]],
        no_heat_flow=np.asarray(False),
        branches={names[0]: r1, names[1]: r2},
        flows=flows,
        inlets=sp.inlets,
        h_set=sp.h_set,
    )


def setpoint_enthalpy(ctx: SolveContext, ops: Ops, p_A: np.ndarray, p_B: np.ndarray) -> np.ndarray | None:
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
        T = ctx.sat.temperature(p_A[k]) + ops["setpoint"][k]
        out[k] = ctx.models.compressor(ops["speed"][k], T, p_A[k], p_B[k] / p_A[k])["h_in"]
    return out
