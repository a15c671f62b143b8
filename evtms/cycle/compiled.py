"""The closure on the two pressures, compiled where the circuit and the models allow it.

:func:`solve_closure` is what the solver calls in place of
:func:`evtms.cycle.closure.solve_at`. On LUTs whose interpolation is compiled,
for a circuit of one condensing component and one evaporating branch
(``cabin``, ``chiller``, ``hp``), it finds each point's roots in one compiled
loop (:mod:`evtms.cycle._closure_kernel`), and with two branches in parallel
(``cabin+chiller``) the roots, the flow split and both branches' drops in
another (:mod:`evtms.cycle._parallel_kernel`), then evaluates the components at
the roots with every output variable as the Python path does
(:func:`evtms.cycle.closure.final_states`). A warm start of one branch (a
previous solve's solution) starts the kernel's searches from its roots. On the
bench physics itself (:class:`~evtms.cycle.models.DirectModels`), for a circuit
of one condensing component and one branch (``cabin``, ``chiller``, ``hp``), a
third kernel runs the same closure on the benches' compiled twins
(:mod:`evtms.cycle._direct_kernel`) and asks the bench for the few states
beyond their property tables. The points a kernel hands back (a model's
envelope met on the way, no root in the range, a subcooled condenser target),
a warm start of two parallel branches, and every other circuit or model go through
:func:`~evtms.cycle.closure.solve_at`, which says why a point fails.

The roots agree with the Python path's to within the closures' tolerances
(:data:`~evtms.cycle.state.OUTER_FTOL` on the superheat residual,
:data:`~evtms.cycle.state.INNER_FTOL` on the capacity ratio); a point's
result does not depend on the other points of its batch.
"""

from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass

import numpy as np

from evtms._jit import kernel_array, numba_enabled
from evtms.cycle.approach import APPROACH, OUTLET, SUPERHEAT_MIN
from evtms.cycle.branches import branch, no_heat_flow, secondary_temperature
from evtms.cycle.closure import (
    COLD_OVERSHOOT,
    DISCHARGE_FLOOR_ABOVE,
    DISCHARGE_GUESS_ABOVE,
    INNER_MAX_STEP,
    INNER_SLOPE,
    OUTER_MAX_STEP,
    OUTER_SLOPE,
    SUCTION_GUESS_BELOW,
    _suction_range,
    condensing,
    condensing_secondary,
    final_states,
    solve_at,
    suction_guess,
)
from evtms.cycle.models import MODEL_AXES
from evtms.cycle.state import (
    CP_SCALE,
    DP_PASSES,
    DP_TOL,
    INNER_FTOL,
    OUTER_FTOL,
    SLOPE_SPAN,
    WARM_OVERSHOOT,
    XTOL,
    Ops,
    SolveContext,
    SolveState,
    WarmStart,
    take,
)
from evtms.cycle.status import STATUS_CONVERGED

#: The closure's own variables, in the kernel's order (its ``dyn`` slots); a model's other
#: arguments are operating inputs, fixed per point.
CLOSURE_VARIABLES = ("mdot", "p_in", "h_in", "T_in", "pr")

#: The variables the kernel reads of each role's component, in its order.
_WANTED = {
    "compressor": ("mdot", "h_in", "h_out"),
    "condensing": ("capacity_ratio", "p_out"),
    "evaporating": (OUTLET, "p_out"),
}


def _eligible(ctx: SolveContext) -> bool:
    """A circuit and models the kernels serve: LUTs, one condensing component, one branch or two
    in parallel."""
    return getattr(ctx.models, "name", "") == "lut" and len(ctx.circuit.chain) == 1 and len(ctx.names) <= 2


def packed(ctx: SolveContext, component: str, inputs: tuple[str, ...], ops: Ops, role: str):
    """Component ``component``'s LUT as the kernel takes it, and the points whose operating inputs
    the LUT holds fixed at another value (handed back); None where its interpolation is not compiled.

    ``inputs`` are the operating inputs of its model's arguments that are not closure variables, in
    the model's order (:data:`evtms.cycle.models.MODEL_AXES`): ``Branch.inputs``, ``Condensing.inputs``,
    or ``("speed",)`` for the compressor.
    """
    lut = ctx.models.luts[component]
    known = _PACKED.setdefault(lut, {})
    key = (component, inputs, role)
    if key not in known:
        known[key] = _fixed_part(lut, component, inputs, role)
    part = known[key]
    if part is None:
        return None
    table, source, no_heat = part
    n = ops["speed"].size
    base = np.empty((len(lut.dims), n))
    for j, d in enumerate(lut.dims):
        if d in source:
            base[j] = ops[source[d]]
        elif d == "T_res":  # no effect in steady state; any grid value will do
            base[j] = lut._lo[j]
    fixed = {a: ops[source[a]] for a in lut._fixed_axes if a in source}
    off = np.zeros(n, bool)
    for mask, _ in lut._fixed_off(fixed, n):
        off |= mask
    tsec = ops[source[lut.secondary]].copy() if lut.secondary else np.zeros(n)
    return (*table, base, tsec, *no_heat), off


#: What :func:`packed` takes from a LUT whatever the points (:func:`_fixed_part`), per LUT and
#: (component, inputs, role); an entry goes with its LUT.
_PACKED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _fixed_part(lut, component: str, inputs: tuple[str, ...], role: str) -> tuple | None:
    """The part of :func:`packed` that does not depend on the points: the LUT's tables, the closure
    variable each axis reads (``src``), the rows the kernel reads, the operating input of each
    other axis and the no-heat table; None where its interpolation is not compiled."""
    itp = lut.fast
    if lut._kernel_for(itp) is None:
        return None
    operating = [a for a in MODEL_AXES[component] if a not in CLOSURE_VARIABLES]
    source = dict(zip(operating, inputs, strict=True))
    if any(a in CLOSURE_VARIABLES and a not in lut.dims for a in MODEL_AXES[component]):
        return None
    src = np.array([CLOSURE_VARIABLES.index(d) if d in CLOSURE_VARIABLES else -1 for d in lut.dims], np.int64)
    names = [APPROACH if (v == OUTLET and lut.secondary) else v for v in _WANTED[role]]
    variables = itp.variables
    approach = (variables.index(APPROACH), variables.index("p_out")) if lut.secondary else (-1, -1)
    check = approach[0] if lut.secondary else 0
    rows = np.array([check, *approach, len(variables), *(variables.index(v) for v in names)], np.int64)
    table = (lut._lo, lut._hi, itp._floats, itp._ints, itp._kernel_values, rows, src)
    return table, source, _no_heat(lut)


def _no_heat(lut) -> tuple:
    """The share of a cell's weight on nodes where no heat flows (the refrigerant on the wrong side
    of its secondary stream), as the kernel reads it: ``(floats, ints, values, on)``; ``on`` 0
    where the LUT has no such nodes (the arrays then unused)."""
    itp = lut.no_heat_indicator()
    if itp is None or not itp.compiled:
        return _NO_TABLE
    return itp._floats, itp._ints, itp._kernel_values, 1


#: No no-heat table (the kernel does not read its arrays).
_NO_TABLE = (np.zeros(8), np.zeros(8, np.int64), kernel_array(np.zeros((1, 1))), 0)


@dataclass(frozen=True)
class CompiledRoots:
    """The compiled closure's roots per point (NaN where handed back).

    Attributes
    ----------
    p_A, p_B : numpy.ndarray
        Suction and discharge pressures [Pa].
    dp : numpy.ndarray
        The branch's pressure drop [Pa].
    outer_slope, inner_slope : numpy.ndarray
        The suction and discharge closures' slopes in saturation temperature [1/K].
    solved : numpy.ndarray
        False where the point is handed back to the Python path.
    dp_branch : dict of str to numpy.ndarray
        Two parallel branches: each one's drop [Pa] (empty for one branch).
    split, clamped : numpy.ndarray or None
        Two parallel branches: the second one's share of the flow [1] and why the split was
        clamped (``CLAMP_*``; 0 where it found a root); None for one branch.
    """

    p_A: np.ndarray
    p_B: np.ndarray
    dp: np.ndarray
    outer_slope: np.ndarray
    inner_slope: np.ndarray
    solved: np.ndarray
    dp_branch: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    split: np.ndarray | None = None
    clamped: np.ndarray | None = None


def compiled_roots(
    ctx: SolveContext,
    ops: Ops,
    t_guess: np.ndarray | None = None,
    p_B_guess: np.ndarray | None = None,
    dp_guess: np.ndarray | None = None,
    outer_slope: np.ndarray | float = OUTER_SLOPE,
    warm: WarmStart | None = None,
) -> CompiledRoots | None:
    """The roots of :func:`~evtms.cycle.closure.solve_at` (the same guesses) from the compiled
    kernel; None where the circuit or models are not served (see the module's text).

    ``warm``, a previous solve's solution (one branch only), replaces the guesses where it has
    one, as in :func:`~evtms.cycle.closure.solve_at`: the searches start from its roots, its
    suction closure's slope and its branch's drop."""
    if warm is not None and ctx.parallel:
        return None
    direct = _direct_eligible(ctx)
    parts = _direct_parts(ctx, ops) if direct else (_parts(ctx, ops) if _eligible(ctx) else None)
    if parts is None:
        return None
    n, limits = ops["speed"].size, ctx.models.limits()
    state = SolveState.start(n, limits, ctx.names, p_B_guess, dp_guess, warm)
    if warm is not None:
        given = np.full(n, np.nan) if t_guess is None else t_guess
        t_guess, outer_slope = suction_guess(given, outer_slope, warm, n)
    guesses = {"t_guess": t_guess, "outer_slope": outer_slope}
    if direct:
        return _direct_roots(ctx, ops, limits, state, parts, guesses)
    if ctx.parallel:
        return _parallel_roots(ctx, ops, limits, state, parts, guesses)
    from evtms.cycle import _closure_kernel as kernel

    rows = _kernel_inputs(ctx, ops, limits, state, parts, guesses, kernel.OPS_ROWS)
    vapour, dh = ctx.models.luts[ctx.names[0]]._vapour_args
    sat = (ctx.sat._log_p, ctx.sat.T, ctx.sat.h_l)
    out = np.empty((6, n))
    tol = _tolerances(state, kernel.TOLERANCES)
    kernel.solve_points(*(p[0] for p in parts), rows, sat, vapour, dh, SUPERHEAT_MIN, tol, out)
    return CompiledRoots(*out[:5], solved=out[5] == 1.0)


#: The circuits the direct-physics kernel serves: the condensing component and the branches.
DIRECT_CIRCUITS = (("condenser", ("evaporator",)), ("condenser", ("chiller",)), ("wcc", ("chiller",)))


def _direct_eligible(ctx: SolveContext) -> bool:
    """The bench physics itself (:class:`~evtms.cycle.models.DirectModels`) with its compiled
    twins, on a circuit of :data:`DIRECT_CIRCUITS`."""
    circuit = ctx.circuit
    return (
        getattr(ctx.models, "name", "") == "direct"
        and len(circuit.chain) == 1
        and (circuit.condensing.component, tuple(ctx.names)) in DIRECT_CIRCUITS
        and numba_enabled()
    )


def _direct_parts(ctx: SolveContext, ops: Ops) -> list:
    """The direct-physics kernel's components as it takes them (:mod:`evtms.cycle._direct_kernel`):
    the compressor's speed per point and constants, then the condensing component's and the
    branch's per-point inputs and constants (:meth:`~evtms.cycle.models.DirectModels.twin_inputs`,
    :meth:`~evtms.cycle.models.DirectModels.twin_constants`); each with no point held back (the
    mask :func:`packed` gives)."""
    models = ctx.models
    n = ops["speed"].size
    kept = np.zeros(n, bool)
    speed = np.ascontiguousarray(np.broadcast_to(np.asarray(ops["speed"], float), (n,)))
    parts = [((speed, models.twin_constants("compressor")), kept)]
    for role in (ctx.circuit.condensing, *ctx.circuit.branches):
        per_point = models.twin_inputs(role.component, *(ops[k] for k in role.inputs), n=n)
        parts.append(((per_point, models.twin_constants(role.component)), kept))
    return parts


def _direct_roots(ctx: SolveContext, ops: Ops, limits: dict, state: SolveState, parts: list, guesses: dict):
    """:func:`compiled_roots` on the bench physics (:mod:`evtms.cycle._direct_kernel`)."""
    from evtms.cycle import _closure_kernel, _direct_kernel
    from evtms.fluid_tables import tables_for

    n = ops["speed"].size
    rows = _kernel_inputs(ctx, ops, limits, state, parts, guesses, _closure_kernel.OPS_ROWS)
    (speed, comp), (cond_in, cond), (branch_in, branch) = (p[0] for p in parts)
    sat = (ctx.sat._log_p, ctx.sat.T, ctx.sat.h_l)
    out = np.empty((6, n))
    tol = _tolerances(state, _closure_kernel.TOLERANCES)
    tables = tables_for(ctx.models.fluid).arrays
    mem, answer = _direct_kernel.memory(), np.zeros(4)
    args = (speed, comp, cond_in, cond, branch_in, branch, tables, rows, sat, tol, out, mem, answer)
    asks = np.zeros(n, np.int64)
    while (ask := _direct_kernel.solve_points(*args)) >= 0:
        i = mem[5][0]
        asks[i] += 1
        if asks[i] > BENCH_ASKS_MAX:  # a search that stays beyond the tables: the Python path's
            answer[:] = (np.nan, np.nan, np.nan, -1.0)
            continue
        answer[:] = _bench_answer(ctx, take(ops, mem[5][:1]), ask, mem[3][0])
    return CompiledRoots(*out[:5], solved=out[5] == 1.0)


#: The bench evaluations one point of the direct-physics kernel may ask of Python before it is handed
#: back to the Python path. A usual point asks two to eight (its discharge search's upper end); one
#: whose condenser cannot condense below the critical pressure (a fan nearly stopped on a hot day)
#: asked some 190 and then had no root, so that the Python path solved it again after them.
BENCH_ASKS_MAX = 24


def _bench_answer(ctx: SolveContext, ops: Ops, ask: int, at: np.ndarray) -> list[float]:
    """What the direct-physics kernel asks of the bench where its tables end: the compressor
    (``ask`` 0), the condensing side (1) or the branch (2) of one point (``ops``) at the closure's
    variables ``at`` (``mdot, p_in, h_in, T_in, pr``), as the Python path evaluates them; the
    three values the kernel reads and 1 where no heat flows."""
    mdot, p_in, h_in, T_in, pr = (np.array([x]) for x in at)
    if ask == 0:
        r = ctx.models.compressor(ops["speed"], T_in, p_in, pr)
        return [r["mdot"][0], r["h_in"][0], r["h_out"][0], 0.0]
    if ask == 1:
        r = condensing(ctx, ops, mdot, p_in, h_in)
        first = r["capacity_ratio"]
    else:
        r = branch(ctx, ctx.names[0], ops, mdot, p_in, h_in)
        first = r["h_out_continued"]
    return [first[0], r["p_out"][0], np.nan, float(no_heat_flow(r)[0])]


def _parallel_roots(ctx: SolveContext, ops: Ops, limits: dict, state: SolveState, parts: list, guesses: dict):
    """:func:`compiled_roots` of a circuit with two parallel branches (:mod:`evtms.cycle._parallel_kernel`)."""
    from evtms.cycle import _parallel_kernel as kernel

    n = ops["speed"].size
    rows = _kernel_inputs(ctx, ops, limits, state, parts, guesses, kernel.PARALLEL_ROWS)
    flows = np.array([x for c in ctx.names for x in ctx.models.flow_range(c)], float)
    vap = [ctx.models.luts[c]._vapour_args for c in ctx.names]
    sat = (ctx.sat._log_p, ctx.sat.T, ctx.sat.h_l)
    out = np.empty((len(kernel.RESULTS), n))
    tol = _tolerances(state, kernel.PARALLEL_TOLERANCES)
    kernel.solve_parallel(*(p[0] for p in parts), *vap, rows, sat, flows, tol, SUPERHEAT_MIN, out)
    r = dict(zip(kernel.RESULTS, out, strict=True))
    return CompiledRoots(
        r["p_A"],
        r["p_B"],
        state.dp,  # a single branch's drop: the guess, untouched by a parallel solve (as solve_at leaves it)
        r["outer_slope"],
        r["inner_slope"],
        solved=r["solved"] == 1.0,
        dp_branch={ctx.names[0]: r["dp_first"], ctx.names[1]: r["dp_second"]},
        split=r["split"],
        clamped=np.nan_to_num(r["clamped"]).astype(np.int8),
    )


def solve_closure(
    ctx: SolveContext,
    ops: Ops,
    t_guess: np.ndarray | None = None,
    p_B_guess: np.ndarray | None = None,
    dp_guess: np.ndarray | None = None,
    outer_slope: np.ndarray | float = OUTER_SLOPE,
    warm: WarmStart | None = None,
) -> tuple[dict, SolveState]:
    """:func:`~evtms.cycle.closure.solve_at` (the same arguments, results and state), through the
    compiled kernel where the solve asks for it (``ctx.closure_kernel``) and the circuit and models
    allow it; the points it hands back, and a warm start of two parallel branches, through the Python
    path."""
    guesses = {"t_guess": t_guess, "p_B_guess": p_B_guess, "dp_guess": dp_guess, "outer_slope": outer_slope}
    roots = compiled_roots(ctx, ops, **guesses, warm=warm) if ctx.closure_kernel else None
    if roots is None:
        return solve_at(ctx, ops, warm=warm, **guesses)
    n = ops["speed"].size
    limits = ctx.models.limits()
    k = np.nonzero(roots.solved)[0]
    rest = np.nonzero(~roots.solved)[0]
    served = _served_state(roots, k, limits, ctx)
    if rest.size == 0:  # the usual batch: every point served
        return _final(ctx, ops, roots.p_A[k], served), served
    state = SolveState.start(n, limits, ctx.names, p_B_guess, dp_guess)
    res = None
    if k.size:
        res = _scatter(None, n, k, _final(ctx, take(ops, k), roots.p_A[k], served))
        _put_state(state, k, served)
    if rest.size:
        part = {
            name: v if v is None or np.ndim(v) == 0 else np.broadcast_to(np.asarray(v, float), (n,))[rest]
            for name, v in guesses.items()
        }
        r, sub = solve_at(ctx, take(ops, rest), warm=None if warm is None else warm.take(rest), **part)
        res = _scatter(res, n, rest, r)
        _put_state(state, rest, sub)
    return res, state


def _served_state(roots: CompiledRoots, k: np.ndarray, limits: dict, ctx: SolveContext) -> SolveState:
    """The solve's state at the served points ``k``, as the Python path leaves it at its roots."""
    state = SolveState.start(k.size, limits, ctx.names)
    state.p_B[:], state.dp[:] = roots.p_B[k], roots.dp[k]
    state.outer_slope[:], state.slope[:] = roots.outer_slope[k], roots.inner_slope[k]
    for c, dp in roots.dp_branch.items():
        state.dp_branch[c][:] = dp[k]
    if roots.split is not None:
        state.split[:], state.clamped[:] = roots.split[k], roots.clamped[k]
    return state


def _final(ctx: SolveContext, ops: Ops, p_A: np.ndarray, state: SolveState) -> dict:
    """The components at the served points' suction roots ``p_A`` [Pa] and their ``state``, with
    every output (``ops`` of those points)."""
    ctx.models.subcooled_targets(False)
    status = np.full(p_A.size, STATUS_CONVERGED, np.int8)
    return final_states(ctx, state, ops, p_A, status, _reasons(p_A.size))


def _parts(ctx: SolveContext, ops: Ops) -> list | None:
    """The compressor's, condensing component's and branch's packed LUTs, or None where one is
    not compiled."""
    circuit = ctx.circuit
    parts = [
        packed(ctx, "compressor", ("speed",), ops, "compressor"),
        packed(ctx, circuit.condensing.component, circuit.condensing.inputs, ops, "condensing"),
        *(packed(ctx, b.component, b.inputs, ops, "evaporating") for b in circuit.branches),
    ]
    return None if any(p is None for p in parts) else parts


def _kernel_inputs(ctx: SolveContext, ops: Ops, limits: dict, state: SolveState, parts: list, guesses: dict, names):
    """The kernel's per-point rows, by their ``names`` (:data:`evtms.cycle._closure_kernel.OPS_ROWS`)."""
    sat = ctx.sat
    T_sec = secondary_temperature(ctx, ops)
    lo, _, hi, _ = _suction_range(ctx, ops, limits, T_sec)
    # Subcooled targets, and inputs a LUT holds fixed at another value: the Python path.
    served = ops["subcooling"] <= 0
    for _, off in parts:
        served &= ~off
    cold = T_sec - SUCTION_GUESS_BELOW
    given = guesses["t_guess"]
    rows = {
        "t_lo": np.where(served, sat.temperature(lo), np.nan),
        "t_hi": sat.temperature(hi),
        "t_guess": cold if given is None else np.where(np.isfinite(given), given, cold),
        "outer_slope": np.asarray(guesses["outer_slope"], float),
        "T_cond_sec": condensing_secondary(ctx, ops),
        "superheat": ops["superheat"],
        "p_B": state.p_B,
        "dp": state.dp,
        "p_dis_lo": state.p_discharge[0],
        "p_dis_hi": state.p_discharge[1],
        "inner_slope": state.slope,
        "branch_mode": ops.get("branch_mode", np.zeros(served.size)),
        "setpoint": ops.get("setpoint", ops["superheat"]),
    }
    return np.stack(np.broadcast_arrays(*(rows[k] for k in names))).astype(float)


def _tolerances(state: SolveState, names) -> np.ndarray:
    """The kernel's constants, by their ``names`` (:data:`evtms.cycle._closure_kernel.TOLERANCES`)."""
    values = {
        "outer_ftol": OUTER_FTOL,
        "inner_ftol": INNER_FTOL,
        "xtol": XTOL,
        "cp_scale": CP_SCALE,
        "dp_tol": DP_TOL,
        "dp_passes": DP_PASSES,
        "pr_lo": state.pr[0],
        "pr_hi": state.pr[1],
        "inner_slope": INNER_SLOPE,
        "discharge_floor_above": DISCHARGE_FLOOR_ABOVE,
        "discharge_guess_above": DISCHARGE_GUESS_ABOVE,
        "inner_max_step": INNER_MAX_STEP,
        "outer_max_step": OUTER_MAX_STEP,
        "overshoot": WARM_OVERSHOOT if state.warm else COLD_OVERSHOOT,
        "slope_span": SLOPE_SPAN,
        "warm": float(state.warm),
    }
    return np.array([values[k] for k in names], float)


def _reasons(n: int) -> np.ndarray:
    return np.full(n, "", dtype=object)


def _scatter(res: dict | None, n: int, idx: np.ndarray, part: dict) -> dict:
    """``part``'s arrays (of the points ``idx``) into ``res``, made for ``n`` points where None."""
    if res is None:
        res = {k: _blank(v, n) for k, v in part.items()}
    for k, v in part.items():
        res[k][idx] = v
    return res


def _blank(v: np.ndarray, n: int) -> np.ndarray:
    """An array of ``n`` points like ``v``: '' for text, NaN for floats, 0 for codes."""
    if v.dtype == object:
        return np.full(n, "", dtype=object)
    return np.full(n, np.nan) if v.dtype.kind == "f" else np.zeros(n, v.dtype)


def _put_state(state: SolveState, idx: np.ndarray, part: SolveState) -> None:
    """The per-point arrays of ``part`` (of the points ``idx``) into ``state``."""
    for f in dataclasses.fields(state):
        v = getattr(part, f.name)
        if isinstance(v, np.ndarray):
            getattr(state, f.name)[..., idx] = v
    for c, a in part.dp_branch.items():
        state.dp_branch[c][idx] = a
