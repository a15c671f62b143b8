"""The compiled cycle closure: the same roots, statuses and figures as the Python path."""

import math

import numpy as np
import pytest

import evtms.cycle.solver as solver_module
from evtms.cycle import CycleSolver, OperatingPoints, load_cycle_luts
from evtms.cycle._closure_kernel import DONE, FAILED, PHASE, STATE_SIZE, root_begin, root_next
from evtms.cycle.closure import solve_at
from evtms.cycle.compiled import compiled_roots
from evtms.cycle.models import LutModels
from evtms.cycle.state import SolveContext
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


@pytest.mark.parametrize("name", list(RANGES))
def test_compiled_roots_are_the_python_roots(solvers, name):
    solver = solvers[name]
    ctx = SolveContext(solver.models, solver.sat, solver.circuit)
    ops = points(name).subset(np.arange(N))
    roots = compiled_roots(ctx, ops)
    res, _ = solve_at(ctx, ops)
    # Most points are served (else the comparison below would prove little).
    assert roots.solved.mean() > 0.8
    k = roots.solved
    # A point the kernel solves, the Python path solves too: the same roots, to round-off, and the
    # same state at them (the drop, and the two closures' slopes a warm start reads).
    assert (res["status"][k] == 0).all()
    for key in ("p_A", "p_B"):
        np.testing.assert_allclose(getattr(roots, key)[k], res[key][k], rtol=1e-12)
    _, state = solve_at(ctx, ops)
    pairs = ((roots.dp, state.dp), (roots.outer_slope, state.outer_slope), (roots.inner_slope, state.slope))
    for mine, theirs in pairs:
        np.testing.assert_allclose(mine[k], theirs[k], rtol=1e-9, atol=1e-9)


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


def search(fun, t_lo, t_hi, t_guess, slope=-1.0, ftol=1e-10):
    """A whole search of the kernel's root finder; (root or NaN, evaluations)."""
    s = np.empty(STATE_SIZE)
    t = root_begin(s, t_lo, t_hi, t_guess, slope)
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


def test_root_finder_goes_round_nan_ends_and_fails_without_a_root():
    # The model leaves its envelope above 6: the NaN end is bisected towards the root at 4.
    root, _ = search(lambda t: 4.0 - t if t < 6.0 else math.nan, 0.0, 10.0, math.nan)
    assert root == pytest.approx(4.0, abs=1e-9)
    # One sign over the range, NaN at both ends, the root beyond the envelope: no root.
    assert math.isnan(search(lambda t: -1.0 - t, 0.0, 10.0, 5.0)[0])
    assert math.isnan(search(lambda t: math.nan, 0.0, 10.0, 5.0)[0])
    assert math.isnan(search(lambda t: 8.0 - t if t < 6.0 else math.nan, 0.0, 10.0, 2.0)[0])
    s = np.empty(STATE_SIZE)
    root_begin(s, 0.0, 1.0, 0.5, -1.0)
    root_next(s, 0.5, math.nan, 10.0, 1.5, 1e-12, 1e-10)
    assert s[PHASE] not in (DONE, FAILED)  # a NaN guess only sends the search to the range's ends


def test_one_compiled_closure_whatever_the_tables_came_as(cycle_luts_dir, monkeypatch):
    """The kernel reads the LUT tables and the saturation curve from the cache files (read-only, memory
    mapped) or built in memory (writable): numba compiles once per argument type, so both must reach it
    as one type, or a user whose tables moved into the cache pays a second compile of seconds."""
    from evtms._jit import numba_enabled
    from evtms.cycle import _closure_kernel as kernel
    from evtms.cycle.api import run_cycle

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set)")
    for no_cache in ("1", "0"):
        monkeypatch.setenv("EVTMS_NO_CACHE", no_cache)
        luts = load_cycle_luts(cycle_luts_dir, "cabin")
        res = run_cycle(points("cabin", 4), luts, circuit="cabin", closure="compiled")
        assert np.isfinite(res["W"]).any()
    assert len(kernel.solve_points.signatures) == 1, kernel.solve_points.signatures
