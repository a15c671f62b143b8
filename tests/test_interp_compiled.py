"""The compiled (numba) interpolation path gives the NumPy path's numbers and errors.

The NumPy path (``Interpolator._call_numpy``) is the reference; the compiled one
must agree with it to 1e-12 relative (in practice to the bit) everywhere: on
uniform and non-uniform axes, with and without curvature, with NaN table entries
(a NaN corner with weight makes NaN, one without weight does not), at nodes and
cell faces, under each out-of-range policy, with fixed inputs and length-1 axes.
"""

from __future__ import annotations

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.luts import Interpolator
from evtms.luts.interp import compiled_kernel

pytestmark = pytest.mark.skipif(compiled_kernel() is None, reason="numba is not importable (or EVTMS_NO_NUMBA is set)")

RNG = np.random.default_rng(20261130)


def grid(uniform: bool, sizes=(5, 7, 1, 4)) -> list[tuple[str, np.ndarray]]:
    """Axes named x0, x1, ...: uniform, or non-uniform with cells from 1x to ~30x apart."""
    axes = []
    for j, k in enumerate(sizes):
        if k == 1:
            a = np.array([0.3 * j + 0.1])
        elif uniform:
            a = np.linspace(-1.0 + j, 2.0 + 2 * j, k)
        else:
            a = np.cumsum(np.r_[-1.0 + j, RNG.uniform(0.05, 1.5, k - 1)])
        axes.append((f"x{j}", a))
    return axes


def tables(axes, nan_fraction: float = 0.0) -> dict[str, np.ndarray]:
    shape = tuple(len(a) for _, a in axes)
    mesh = np.meshgrid(*[a for _, a in axes], indexing="ij")
    smooth = np.exp(0.3 * mesh[0]) * np.sin(mesh[1]) + mesh[-1] ** 2  # curves along several axes
    out = {"smooth": smooth, "noise": RNG.normal(size=shape), "flat": np.full(shape, 2.5)}
    if nan_fraction:
        for v in ("smooth", "noise"):
            out[v] = out[v].copy()
            out[v][RNG.uniform(size=shape) < nan_fraction] = np.nan
    return out


def inside(axes, n: int) -> dict[str, np.ndarray]:
    return {name: RNG.uniform(a[0], a[-1], n) for name, a in axes}


def on_nodes_and_faces(axes, n: int) -> dict[str, np.ndarray]:
    """Every point on a cell face along some axes (a node), inside a cell along the others."""
    q = inside(axes, n)
    for name, a in axes:
        nodes = RNG.choice(a, n)
        q[name] = np.where(RNG.uniform(size=n) < 0.6, nodes, q[name])
    return q


def both(itp: Interpolator, query, policy: str | None = None):
    """(compiled, NumPy) results of one query."""
    assert itp.compiled
    policy = itp.out_of_range if policy is None else policy
    return itp(query, policy), itp._call_numpy(query, policy)


def assert_same(got: dict, ref: dict) -> None:
    assert list(got) == list(ref)
    for v in ref:
        assert got[v].shape == ref[v].shape, v
        np.testing.assert_array_equal(np.isnan(got[v]), np.isnan(ref[v]), err_msg=v)
        np.testing.assert_allclose(got[v], ref[v], rtol=1e-12, atol=0.0, err_msg=v)


def error_of(fn) -> str:
    with pytest.raises(EvtmsInputError) as info:
        fn()
    return str(info.value)


@pytest.mark.parametrize("uniform", [True, False], ids=["uniform", "non-uniform"])
@pytest.mark.parametrize("curvature", [False, True, ("smooth",)], ids=["linear", "curved", "curved-one"])
@pytest.mark.parametrize("nan_fraction", [0.0, 0.15], ids=["finite", "nan-entries"])
def test_matches_numpy_path(uniform, curvature, nan_fraction):
    axes = grid(uniform)
    itp = Interpolator(axes, tables(axes, nan_fraction), curvature=curvature)
    for query in (inside(axes, 2000), on_nodes_and_faces(axes, 2000)):
        assert_same(*both(itp, query))
    # Exactly on every node: a NaN neighbour with zero weight must not leak in.
    mesh = np.meshgrid(*[a for _, a in axes], indexing="ij")
    assert_same(*both(itp, {name: m.ravel() for (name, _), m in zip(axes, mesh, strict=True)}))


def test_nan_corner_rules():
    axes = [("a", np.array([0.0, 1.0, 2.0])), ("b", np.array([0.0, 1.0]))]
    table = np.array([[1.0, 2.0], [np.nan, 4.0], [5.0, 6.0]])
    itp = Interpolator(axes, {"v": table})
    query = {"a": [0.0, 0.5, 1.0, 1.5, 2.0, 1.0, 1.5], "b": [0.0, 0.0, 1.0, 0.5, 0.0, 0.5, 1.0]}
    got, ref = both(itp, query)
    assert_same(got, ref)
    # Weight on the NaN node -> NaN; on its neighbours' faces only -> a number.
    assert np.isnan(got["v"][[1, 3, 5]]).all()
    np.testing.assert_array_equal(got["v"][[0, 2, 4, 6]], [1.0, 4.0, 5.0, 5.0])


@pytest.mark.parametrize("uniform", [True, False], ids=["uniform", "non-uniform"])
@pytest.mark.parametrize("policy", ["clip", "nan"])
def test_out_of_range_policies(uniform, policy):
    axes = grid(uniform)
    itp = Interpolator(axes, tables(axes, 0.1), out_of_range="error", curvature=True)
    q = inside(axes, 3000)
    for name, a in axes:  # a quarter of each axis' values outside its range, some NaN or infinite
        span = max(a[-1] - a[0], 1.0)
        wild = RNG.uniform(a[0] - span, a[-1] + span, 3000)
        wild[RNG.uniform(size=3000) < 0.05] = np.nan
        wild[RNG.uniform(size=3000) < 0.02] = np.inf
        wild[RNG.uniform(size=3000) < 0.02] = -np.inf
        q[name] = np.where(RNG.uniform(size=3000) < 0.25, wild, q[name])
    got, ref = both(itp, q, policy)
    assert_same(got, ref)
    if policy == "nan":
        assert np.isnan(got["flat"]).any() and not np.isnan(got["flat"]).all()
    else:
        assert not np.isnan(got["flat"]).any()


def test_error_policy_message_unchanged():
    axes = grid(False)
    itp = Interpolator(axes, tables(axes), out_of_range="error", curvature=True)
    q = inside(axes, 50)
    q["x3"][[7, 30]] = [99.0, -99.0]  # later axis: not the one reported
    q["x1"][[12, 40]] = [np.nan, 1e9]  # first axis with a bad point: its first bad point is reported
    message = error_of(lambda: itp(q))
    assert message == error_of(lambda: itp._call_numpy(q, "error"))
    a = dict(axes)["x1"]
    assert message == (
        f"x1 = nan is outside the LUT range [{a[0]:g}, {a[-1]:g}]; "
        "the out-of-range policy is 'error' (use 'clip' or 'nan' to allow it)"
    )
    # The array form and a length-1 axis off its node.
    rows = np.column_stack([inside(axes, 5)[name] for name, _ in axes])
    rows[3, 2] = 0.0
    assert error_of(lambda: itp(rows)) == error_of(lambda: itp._call_numpy(rows, "error"))
    assert error_of(lambda: itp(rows)).startswith("x2 = 0 is outside the LUT range [0.7, 0.7]")


def test_length_one_axes():
    axes = [("a", np.array([1.0])), ("b", np.linspace(0.0, 1.0, 4)), ("c", np.array([2.0]))]
    itp = Interpolator(axes, {"v": RNG.normal(size=(1, 4, 1)), "w": RNG.normal(size=(1, 4, 1))}, curvature=True)
    q = {"a": 1.0, "b": RNG.uniform(0, 1, 100), "c": [2.0]}
    assert_same(*both(itp, q))
    off = {"a": np.r_[1.0, 1.5, np.nan, 1.0], "b": [0.2, 0.4, 0.6, 0.8], "c": 2.0}
    for policy in ("clip", "nan"):
        assert_same(*both(itp, off, policy))
    assert error_of(lambda: itp(off)) == error_of(lambda: itp._call_numpy(off, "error"))
    # Only length-1 axes: one node, every query gets its value.
    single = Interpolator([("a", np.array([1.0]))], {"v": np.array([3.0])})
    assert_same(*both(single, {"a": [1.0, 1.0]}))
    assert_same(*both(single, {"a": [1.0, 2.0]}, "nan"))


def test_fixed_inputs():
    axes = grid(True, (4, 3))
    itp = Interpolator(axes, tables(axes), out_of_range="nan", curvature=True, fixed={"p": 2.0, "q": -1.0})
    q = inside(axes, 200)
    assert_same(*both(itp, q))
    assert_same(*both(itp, {**q, "p": 2.0}))
    off = {**q, "p": np.where(np.arange(200) % 3 == 0, 2.5, 2.0), "q": -1.0}
    for policy in ("clip", "nan"):
        got, ref = both(itp, off, policy)
        assert_same(got, ref)
    assert np.isnan(got["flat"][::3]).all() and not np.isnan(got["flat"][1::3]).any()
    assert error_of(lambda: itp(off, "error")) == error_of(lambda: itp._call_numpy(off, "error"))
    # Every input fixed: one point per query value, or one point if none is given.
    none = Interpolator([], {"v": np.array(4.0)}, fixed={"p": 1.0})
    assert_same(*both(none, {}))
    assert_same(*both(none, {"p": [1.0, 1.0, 3.0]}, "nan"))


def test_query_forms_and_batch_sizes():
    axes = grid(False, (6, 5, 4, 3, 5))
    itp = Interpolator(axes, tables(axes, 0.05), out_of_range="clip", curvature=("smooth",))
    big = inside(axes, 100_000)
    assert_same(*both(itp, big))
    one = {name: v[:1] for name, v in big.items()}
    assert_same(*both(itp, one))
    scalars = {name: float(v[0]) for name, v in big.items()}
    assert_same(*both(itp, scalars))
    rows = np.column_stack([big[name][:300] for name, _ in axes])
    assert_same(*both(itp, rows))
    assert_same(*both(itp, rows[0]))  # one point as a 1-D row
    broadcast = {**{name: v[:50] for name, v in big.items()}, "x1": 0.5}
    assert_same(*both(itp, broadcast))
    empty = {name: v[:0] for name, v in big.items()}
    got, _ = both(itp, empty)
    assert all(r.shape == (0,) for r in got.values())
    # Shape errors and unknown or missing names are worded by the same checks.
    with pytest.raises(ValueError):
        itp({**one, "x1": [0.1, 0.2], "x2": [0.1, 0.2, 0.3]})
    assert error_of(lambda: itp({**one, "zz": 1.0})) == error_of(lambda: itp._call_numpy({**one, "zz": 1.0}, "clip"))
    missing = {k: v for k, v in one.items() if k != "x2"}
    assert error_of(lambda: itp(missing)) == error_of(lambda: itp._call_numpy(missing, "clip"))
    assert error_of(lambda: itp(rows[:, :3])) == error_of(lambda: itp._call_numpy(rows[:, :3], "clip"))


def test_point_with_curvature_uses_the_same_numbers():
    axes = grid(True)
    itp = Interpolator(axes, tables(axes), curvature=True)
    q = inside(axes, 1)
    ref = itp._call_numpy(q, "error")
    got = itp.point(*[float(q[name][0]) for name, _ in axes])
    np.testing.assert_allclose(got, [ref[v][0] for v in itp.variables], rtol=1e-12, atol=0.0)


def test_env_var_forces_numpy_path(monkeypatch):
    axes = grid(True)
    monkeypatch.setenv("EVTMS_NO_NUMBA", "1")
    itp = Interpolator(axes, tables(axes))
    assert not itp.compiled
    assert compiled_kernel() is None
    q = inside(axes, 10)
    assert_same(itp(q), itp._call_numpy(q, "error"))
