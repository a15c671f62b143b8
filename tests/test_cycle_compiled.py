"""The compiled cycle closure: the same roots, statuses and figures as the Python path."""

import math
from unittest import mock

import numpy as np
import pytest

import evtms.cycle.closure as closure_module
import evtms.cycle.solver as solver_module
from evtms.cycle import CycleSolver, OperatingPoints, load_cycle_luts
from evtms.cycle._closure_kernel import DONE, FAILED, PHASE, STATE_SIZE, root_begin, root_next
from evtms.cycle.closure import solve_at
from evtms.cycle.compiled import compiled_roots, solve_closure
from evtms.cycle.models import LutModels
from evtms.cycle.state import (
    BOTH_HOLD,
    FIRST_CLOSED,
    FIRST_FLOATS,
    SECOND_CLOSED,
    SECOND_FLOATS,
    SolveContext,
)
from evtms.cycle.topology import topology
from evtms.fluid import Fluid, SaturationCurve

N = 120

#: Random operating points of each served circuit, inside its LUTs' usual envelope [SI, K].
RANGES = {
    "cabin": {"fan": (0.2, 1.0), "blower": (0.2, 1.0), "T_amb": (288.15, 318.15), "T_cabin": (293.15, 313.15)},
    "chiller": {
        "fan": (0.2, 1.0),
        "T_amb": (288.15, 318.15),
        "mdot_coolant": (0.05, 0.3),
        "T_coolant_in": (288.15, 313.15),
    },
    "cabin+chiller": {
        "fan": (0.2, 1.0),
        "blower": (0.2, 1.0),
        "T_amb": (288.15, 318.15),
        "T_cabin": (293.15, 313.15),
        "mdot_coolant": (0.05, 0.3),
        "T_coolant_in": (288.15, 313.15),
    },
    "hp": {
        "mdot_coolant_h": (0.1, 0.3),
        "T_coolant_h_in": (293.15, 323.15),
        "mdot_coolant": (0.05, 0.3),
        "T_coolant_in": (273.15, 303.15),
    },
}


def points(name: str, n: int = N, seed: int = 3) -> OperatingPoints:
    rng = np.random.default_rng(seed)
    values = {k: rng.uniform(lo, hi, n) for k, (lo, hi) in RANGES[name].items()}
    return OperatingPoints(speed=rng.uniform(0.2, 1.0, n), **values)


@pytest.fixture(scope="module")
def solvers(cycle_luts_dir):
    sat = SaturationCurve(Fluid())
    out = {}
    for name in RANGES:
        circuit = topology(name)
        luts = load_cycle_luts(cycle_luts_dir, name)
        out[name] = CycleSolver(LutModels(luts, circuit.components), sat, circuit)
    return out


def python_path(solver: CycleSolver) -> CycleSolver:
    """The same solver with every closure on the vectorised Python path."""
    return CycleSolver(solver.models, solver.sat, solver.circuit, closure="python")


def parallel_ops(ops: dict, mode: int) -> dict:
    """``ops`` of a two-branch circuit in branch mode ``mode`` (:mod:`evtms.cycle.state`): a valve
    at its maximum opening floats its superheat 0-8 K above the setpoint."""
    n = ops["speed"].size
    ops = dict(ops, branch_mode=np.full(n, mode, np.int8), setpoint=ops["superheat"].copy())
    if mode in (FIRST_FLOATS, SECOND_FLOATS):
        ops["superheat"] = ops["superheat"] + np.random.default_rng(mode).uniform(0.0, 8.0, n)
    return ops


def python_roots(ctx: SolveContext, ops: dict) -> tuple[dict, object, dict]:
    """:func:`solve_at`'s result and state, and its search's roots before the final evaluation
    (which blanks a root where a component fails there, e.g. a split clamped at a least flow)."""
    seen = {}
    final = closure_module.final_states

    def capture(ctx_, state, ops_, p_A, status, reason):
        seen["p_A"], seen["p_B"] = p_A.copy(), state.p_B.copy()
        return final(ctx_, state, ops_, p_A, status, reason)

    with mock.patch.object(closure_module, "final_states", capture):
        res, state = solve_at(ctx, ops)
    return res, state, seen


def assert_kernel_is_python(ctx: SolveContext, ops: dict, served: int) -> None:
    """The kernel solves exactly the points whose Python search converges (at least ``served``),
    with its roots and state to round-off, and the closure through the kernel ends every point
    with the Python path's status and reason."""
    roots = compiled_roots(ctx, ops)
    res, state, seen = python_roots(ctx, ops)
    # Most points are served (else the comparison below would prove little).
    assert roots.solved.mean() > 0.8
    # Served where the search converges, also where the final evaluation then fails (its word on both paths).
    k = np.isfinite(seen["p_A"])
    np.testing.assert_array_equal(roots.solved, k)
    assert k.sum() >= served
    np.testing.assert_allclose(roots.p_A[k], seen["p_A"][k], rtol=1e-12)
    np.testing.assert_allclose(roots.p_B[k], seen["p_B"][k], rtol=1e-12)
    # The same state at the roots: the drops, the split, and the two closures' slopes a warm start reads.
    pairs = [(roots.dp, state.dp), (roots.outer_slope, state.outer_slope), (roots.inner_slope, state.slope)]
    pairs += [(roots.dp_branch[c], state.dp_branch[c]) for c in roots.dp_branch]
    if roots.split is not None:
        pairs.append((roots.split, state.split))
        np.testing.assert_array_equal(roots.clamped[k], state.clamped[k])
    for mine, theirs in pairs:
        np.testing.assert_allclose(mine[k], theirs[k], rtol=1e-9, atol=1e-9)
    fast, _ = solve_closure(ctx, ops)
    np.testing.assert_array_equal(fast["status"], res["status"])
    np.testing.assert_array_equal(fast["reason"], res["reason"])


@pytest.mark.parametrize("name", list(RANGES))
def test_compiled_roots_are_the_python_roots(solvers, name):
    solver = solvers[name]
    ctx = SolveContext(solver.models, solver.sat, solver.circuit)
    ops = points(name).subset(np.arange(N))
    if ctx.parallel:
        ops = parallel_ops(ops, BOTH_HOLD)
    assert_kernel_is_python(ctx, ops, served=int(0.8 * N))


@pytest.mark.parametrize("mode", [FIRST_FLOATS, SECOND_FLOATS, FIRST_CLOSED, SECOND_CLOSED])
def test_compiled_parallel_roots_in_every_branch_mode(solvers, mode):
    """A valve at its maximum opening (the other branch holds the setpoint, the suction superheat
    floats) or closed (one branch takes all the flow): the kernel's roots are the Python path's."""
    solver = solvers["cabin+chiller"]
    ctx = SolveContext(solver.models, solver.sat, solver.circuit)
    ops = parallel_ops(points("cabin+chiller", n=60, seed=11).subset(np.arange(60)), mode)
    # Many floating points fail at the root (a branch at its least flow): the final evaluation's word.
    assert_kernel_is_python(ctx, ops, served=6 if mode in (FIRST_FLOATS, SECOND_FLOATS) else 48)


@pytest.mark.parametrize("name", list(RANGES))
def test_solver_figures_match_the_python_path(solvers, name):
    pts = points(name, seed=5)
    fast = solvers[name].solve(pts)
    slow = python_path(solvers[name]).solve(pts)
    np.testing.assert_array_equal(fast["status"], slow["status"])
    np.testing.assert_array_equal(fast["reason"], slow["reason"])
    ok = np.isfinite(slow["COP"])
    assert ok.mean() > 0.8
    for key in ("p_A", "p_B", "mdot", "Q_evap", "Q_chiller", "Q_cond", "W", "COP", "superheat_actual"):
        np.testing.assert_allclose(fast[key][ok], slow[key][ok], rtol=1e-12, atol=1e-9, err_msg=key)


def test_points_the_kernel_hands_back_keep_the_python_reasons(solvers):
    pts = points("cabin", n=6, seed=7)
    pts.subcooling[:2] = 3.0  # a subcooled target: the Python path's
    pts.T_amb[2] = 333.15  # beyond the condenser LUT's air axis
    pts.T_cabin[3] = 253.15  # below the evaporator LUT's air axis
    solver = solvers["cabin"]
    ctx = SolveContext(solver.models, solver.sat, solver.circuit)
    roots = compiled_roots(ctx, pts.subset(np.arange(6)))
    assert not roots.solved[:4].any()
    fast = solver.solve(pts)
    slow = python_path(solver).solve(pts)
    np.testing.assert_array_equal(fast["status"], slow["status"])
    np.testing.assert_array_equal(fast["reason"], slow["reason"])
    assert (fast["reason"][2:4] != "").all()


def test_the_solver_takes_the_kernel_for_small_batches_only(solvers, monkeypatch):
    import evtms.cycle.compiled as compiled

    asked = []
    real = compiled.compiled_roots

    def spy(ctx, ops, **guesses):
        asked.append(ops["speed"].size)
        return real(ctx, ops, **guesses)

    monkeypatch.setattr(compiled, "compiled_roots", spy)
    monkeypatch.setattr(solver_module, "KERNEL_BATCH_MAX", 10)
    solvers["cabin"].solve(points("cabin", n=10))
    assert asked and asked[0] == 10
    asked.clear()
    solvers["cabin"].solve(points("cabin", n=11))
    python_path(solvers["cabin"]).solve(points("cabin", n=3))
    assert asked == []
    with pytest.raises(ValueError, match="closure 'fast' is unknown"):
        CycleSolver(solvers["cabin"].models, solvers["cabin"].sat, "cabin", closure="fast")


def test_a_point_solved_alone_equals_its_batch(solvers):
    n = 40  # more points than the kernel runs side by side: its slots take new points
    pts = points("cabin", n=n, seed=9)
    batch = solvers["cabin"].solve(pts)
    columns = pts.subset(np.arange(n))
    for i in range(n):
        alone = solvers["cabin"].solve(OperatingPoints(**{k: v[i : i + 1] for k, v in columns.items()}))
        for key in ("p_A", "p_B", "COP", "status"):
            assert np.array_equal(alone[key], batch[key][i : i + 1], equal_nan=True), (i, key)


def search(fun, t_lo, t_hi, t_guess, slope=-1.0, ftol=1e-10, warm=0.0):
    """A whole search of the kernel's root finder; (root or NaN, evaluations)."""
    s = np.empty(STATE_SIZE)
    t = root_begin(s, t_lo, t_hi, t_guess, slope, warm)
    count = 0
    while s[PHASE] < DONE:
        count += 1
        t = root_next(s, t, fun(t), 10.0, 1.5, 1e-12, ftol)
    return (t if s[PHASE] == DONE else math.nan), count


def test_root_finder_solves_falling_residuals():
    root, count = search(lambda t: 3.0 - t, 0.0, 10.0, 5.0)
    assert root == pytest.approx(3.0, abs=1e-9)
    assert count <= 4  # guess, secant, one regula falsi step
    root, _ = search(lambda t: math.exp(-t) - 0.2, 0.0, 10.0, 0.5)
    assert root == pytest.approx(-math.log(0.2), abs=1e-9)
    root, _ = search(lambda t: 1.0 - t**3, -5.0, 5.0, math.nan)  # no guess: the range's ends
    assert root == pytest.approx(1.0, abs=1e-9)


def test_a_warm_root_finder_stops_at_a_trial_within_the_tolerance():
    """Warm: a guess within ``ftol`` of the root is the root (one evaluation; a cold search goes on
    to bracket it); a second trial short on the guess's side takes a third secant step before the
    range's ends."""
    root, count = search(lambda t: 3.0 - t, 0.0, 10.0, 3.0 + 1e-12, warm=1.0)
    assert (root, count) == (3.0 + 1e-12, 1)
    assert search(lambda t: 3.0 - t, 0.0, 10.0, 3.0 + 1e-12)[1] > 1
    # A slope ten times too steep: the first step falls short, the third trial brackets the root.
    seen = []
    root, count = search(lambda t: seen.append(t) or 3.0 - t, 0.0, 10.0, 5.0, slope=-10.0, ftol=1e-9, warm=1.0)
    assert root == pytest.approx(3.0, abs=1e-9)
    assert 0.0 not in seen and 10.0 not in seen  # the range's ends were not needed


def test_root_finder_goes_round_nan_ends_and_fails_without_a_root():
    # The model leaves its envelope above 6: the NaN end is bisected towards the root at 4.
    root, _ = search(lambda t: 4.0 - t if t < 6.0 else math.nan, 0.0, 10.0, math.nan)
    assert root == pytest.approx(4.0, abs=1e-9)
    # One sign over the range, NaN at both ends, the root beyond the envelope: no root.
    assert math.isnan(search(lambda t: -1.0 - t, 0.0, 10.0, 5.0)[0])
    assert math.isnan(search(lambda t: math.nan, 0.0, 10.0, 5.0)[0])
    assert math.isnan(search(lambda t: 8.0 - t if t < 6.0 else math.nan, 0.0, 10.0, 2.0)[0])
    s = np.empty(STATE_SIZE)
    root_begin(s, 0.0, 1.0, 0.5, -1.0, 0.0)
    root_next(s, 0.5, math.nan, 10.0, 1.5, 1e-12, 1e-10)
    assert s[PHASE] not in (DONE, FAILED)  # a NaN guess only sends the search to the range's ends


def test_one_compiled_closure_whatever_the_tables_came_as(cycle_luts_dir, monkeypatch):
    """The kernel reads the LUT tables and the saturation curve from the cache files (read-only, memory
    mapped) or built in memory (writable): numba compiles once per argument type, so both must reach it
    as one type, or a user whose tables moved into the cache pays a second compile of seconds."""
    from evtms._jit import numba_enabled
    from evtms.cycle import _closure_kernel as kernel
    from evtms.cycle import _parallel_kernel as parallel
    from evtms.cycle.api import run_cycle

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set)")
    for no_cache in ("1", "0"):
        monkeypatch.setenv("EVTMS_NO_CACHE", no_cache)
        luts = load_cycle_luts(cycle_luts_dir, "cabin")
        res = run_cycle(points("cabin", 4), luts, circuit="cabin", closure="compiled")
        assert np.isfinite(res["W"]).any()
        luts = load_cycle_luts(cycle_luts_dir, "cabin+chiller")
        res = run_cycle(points("cabin+chiller", 4), luts, circuit="cabin+chiller", compiled=True, closure="compiled")
        assert np.isfinite(res["W"]).any()
    assert len(kernel.solve_points.signatures) == 1, kernel.solve_points.signatures
    assert len(parallel.solve_parallel.signatures) == 1, parallel.solve_parallel.signatures


@pytest.fixture(scope="module")
def direct_solver():
    from evtms.benches.parameters import Parameters
    from evtms.cycle.models import DirectModels

    fluid = Fluid()
    return CycleSolver(DirectModels(Parameters(), fluid), SaturationCurve(fluid), topology("cabin"))


def on_circuit(solver: CycleSolver, name: str) -> CycleSolver:
    return CycleSolver(solver.models, solver.sat, topology(name))


@pytest.mark.parametrize("name", ["cabin", "chiller", "hp"])
def test_compiled_roots_on_the_bench_physics_are_the_python_roots(direct_solver, monkeypatch, name):
    """The direct-physics kernel: the Python path's roots, state, statuses and reasons; the states
    beyond its property tables (a discharge search's end near the critical pressure) are the
    bench's, asked of the caller, and the point goes on."""
    import evtms.cycle.compiled as compiled

    asked = []
    real = compiled._bench_answer
    monkeypatch.setattr(compiled, "_bench_answer", lambda *a: asked.append(a[2]) or real(*a))
    solver = on_circuit(direct_solver, name)
    ctx = SolveContext(solver.models, solver.sat, solver.circuit)
    ops = points(name, n=24, seed=13).subset(np.arange(24))
    assert_kernel_is_python(ctx, ops, served=20)
    assert {0, 1} <= set(asked)


@pytest.mark.parametrize("name", ["cabin", "chiller", "hp"])
def test_direct_solver_figures_match_the_python_path(direct_solver, name):
    solver = on_circuit(direct_solver, name)
    pts = points(name, n=12, seed=17)
    fast = solver.solve(pts)
    slow = python_path(solver).solve(pts)
    np.testing.assert_array_equal(fast["status"], slow["status"])
    np.testing.assert_array_equal(fast["reason"], slow["reason"])
    ok = np.isfinite(slow["COP"])
    assert ok.mean() > 0.8
    for key in ("p_A", "p_B", "mdot", "Q_evap", "Q_cond", "W", "COP", "superheat_actual"):
        np.testing.assert_allclose(fast[key][ok], slow[key][ok], rtol=1e-12, atol=1e-12, err_msg=key)


@pytest.mark.parametrize("name", ["cabin+wcc", "cabin+chiller"])
def test_the_direct_kernel_serves_its_circuits_only(direct_solver, name):
    """Other circuits on the bench physics (two condensing components, two branches) stay on the
    Python path."""
    ctx = SolveContext(direct_solver.models, direct_solver.sat, topology(name))
    assert compiled_roots(ctx, OperatingPoints(speed=[0.5, 0.6]).subset(np.arange(2))) is None


@pytest.mark.parametrize("models", ["direct", "lut"])
def test_warm_solves_through_the_kernel_are_the_python_warm_solves(direct_solver, solvers, models):
    """A drive's consecutive points, each warm-started from the previous solution (the
    physics-in-the-loop model's solves): the compiled searches take the Python path's warm steps
    (trials within the tolerance taken as roots, the extrapolated discharge guess, a third secant
    step), so they end on its roots, holding the setpoint or floating the superheat."""
    from test_cycle_warm import _SPEED, _point

    base = direct_solver if models == "direct" else solvers["cabin"]
    runs = {}
    for closure in ("python", "compiled"):
        solver = CycleSolver(base.models, base.sat, "cabin", closure=closure)
        warm, runs[closure] = None, []
        for j in range(len(_SPEED)):
            runs[closure].append(solver.solve(_point(j), warm=warm))
            warm = solver.warm_start
    statuses = set()
    for slow, fast in zip(runs["python"], runs["compiled"], strict=True):
        assert fast.status.tolist() == slow.status.tolist()
        statuses.add(int(slow.status[0]))
        for key in ("p_A", "p_B", "mdot", "superheat_actual", "COP"):
            np.testing.assert_allclose(fast[key], slow[key], rtol=1e-9, err_msg=key)
    assert len(statuses) == 2  # holding the setpoint and floating


def test_a_search_that_stays_beyond_the_tables_goes_to_the_python_path(direct_solver, monkeypatch):
    """A condenser that cannot condense below the critical pressure (a fan nearly stopped on a hot
    day): the kernel asks the bench at most BENCH_ASKS_MAX times, then hands the point back, and
    the Python path says why it fails."""
    import evtms.cycle.compiled as compiled

    asked = []
    real = compiled._bench_answer
    monkeypatch.setattr(compiled, "_bench_answer", lambda *a: asked.append(a[2]) or real(*a))
    point = OperatingPoints(speed=1.0, T_amb=323.15, fan=0.05)
    ctx = SolveContext(direct_solver.models, direct_solver.sat, direct_solver.circuit)
    roots = compiled_roots(ctx, point.subset(np.arange(1)))
    assert not roots.solved[0]
    assert len(asked) == compiled.BENCH_ASKS_MAX
    fast, slow = direct_solver.solve(point), python_path(direct_solver).solve(point)
    assert fast["reason"][0] == slow["reason"][0] != ""
