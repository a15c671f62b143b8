"""LUT toolkit: interpolation, validation of malformed files, exports, diff, CLI."""

from __future__ import annotations

import json

import netCDF4
import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator
from scipy.io import loadmat
from typer.testing import CliRunner

from evtms.cli import app
from evtms.errors import EvtmsInputError
from evtms.luts import Interpolator, LutFormatError, open_lut
from evtms.luts.diff import lut_diff
from evtms.luts.export import read_csv, to_csv, to_mat
from evtms.luts.io import write_lut

runner = CliRunner()
RNG = np.random.default_rng(7)


def multilinear(x0, x1, x2):
    """A function multilinear interpolation must reproduce exactly."""
    return 1.5 + 2 * x0 - 3 * x1 + 0.5 * x2 + 4 * x0 * x1 - x1 * x2 + 0.7 * x0 * x1 * x2


@pytest.fixture(scope="module")
def grid3():
    axes = [("a", np.array([0.0, 0.3, 1.0, 1.7])), ("b", np.array([-1.0, 0.5, 2.0])), ("c", np.linspace(0, 5, 6))]
    mesh = np.meshgrid(*[v for _, v in axes], indexing="ij")
    return axes, {"f": multilinear(*mesh), "g": np.sin(mesh[0]) + mesh[1] * mesh[2]}


def test_exact_at_nodes_and_for_multilinear_functions(grid3):
    axes, tables = grid3
    itp = Interpolator(axes, tables)
    mesh = np.meshgrid(*[v for _, v in axes], indexing="ij")
    nodes = {n: m.ravel() for (n, _), m in zip(axes, mesh, strict=True)}
    np.testing.assert_array_equal(itp(nodes)["g"], tables["g"].ravel())
    q = {n: RNG.uniform(v[0], v[-1], 5000) for n, v in axes}
    np.testing.assert_allclose(itp(q)["f"], multilinear(q["a"], q["b"], q["c"]), rtol=1e-13, atol=1e-13)


def test_agrees_with_scipy_on_random_queries(grid3):
    axes, tables = grid3
    itp = Interpolator(axes, tables)
    ref = RegularGridInterpolator([v for _, v in axes], tables["g"])
    pts = np.column_stack([RNG.uniform(v[0], v[-1], 20000) for _, v in axes])
    np.testing.assert_allclose(itp(pts)["g"], ref(pts), rtol=1e-12, atol=1e-12)
    # The scalar path agrees with the batched one.
    for row in pts[:50]:
        assert itp.point(*row.tolist()) == pytest.approx((itp(row)["f"][0], itp(row)["g"][0]), rel=1e-12)


def test_five_d_uniform_and_nonuniform_axes_agree_with_scipy():
    axes = [
        (f"x{i}", np.sort(RNG.uniform(0, 1, n)) if i % 2 else np.linspace(0, 2, n))
        for i, n in enumerate((4, 5, 3, 6, 2))
    ]
    table = RNG.normal(size=(4, 5, 3, 6, 2))
    itp = Interpolator(axes, {"v": table})
    pts = np.column_stack([RNG.uniform(v[0], v[-1], 30000) for _, v in axes])
    ref = RegularGridInterpolator([v for _, v in axes], table)(pts)
    np.testing.assert_allclose(itp(pts)["v"], ref, rtol=1e-12, atol=1e-12)


def test_nan_corners_give_nan_but_not_at_weightless_corners():
    axes = [("a", np.array([0.0, 1.0, 2.0])), ("b", np.array([0.0, 1.0]))]
    table = np.array([[1.0, 2.0], [3.0, np.nan], [5.0, 6.0]])
    itp = Interpolator(axes, {"v": table})
    out = itp({"a": [0.5, 1.5, 1.0, 0.0, 2.0, 1.0], "b": [0.5, 0.5, 0.0, 1.0, 1.0, 0.3]})["v"]
    assert np.isnan(out[0]) and np.isnan(out[1]) and np.isnan(out[5])  # the NaN corner carries weight
    assert out[2] == 3.0 and out[3] == 2.0 and out[4] == 6.0  # on nodes next to the NaN
    assert np.isnan(itp.point(0.5, 0.5)[0]) and itp.point(1.0, 0.0)[0] == 3.0


def test_out_of_range_policies(grid3):
    axes, tables = grid3
    itp = Interpolator(axes, tables)
    q = {"a": [0.5, 2.0], "b": [0.0, 0.0], "c": [1.0, 1.0]}
    with pytest.raises(EvtmsInputError, match=r"a = 2 is outside the LUT range \[0, 1.7\]"):
        itp(q)
    nan = itp(q, out_of_range="nan")["f"]
    assert np.isfinite(nan[0]) and np.isnan(nan[1])
    clip = itp(q, out_of_range="clip")["f"]
    assert clip[1] == pytest.approx(multilinear(1.7, 0.0, 1.0))
    assert np.isnan(itp.point(2.0, 0.0, 1.0, out_of_range="nan")[0])
    assert itp.point(2.0, 0.0, 1.0, out_of_range="clip")[0] == pytest.approx(multilinear(1.7, 0.0, 1.0))
    with pytest.raises(EvtmsInputError, match="outside the LUT range"):
        itp.point(2.0, 0.0, 1.0)
    with pytest.raises(EvtmsInputError, match="allowed: error, clip, nan"):
        itp(q, out_of_range="extrapolate")


def test_length_one_axes():
    axes = [("a", np.array([1.0, 2.0])), ("b", np.array([5.0]))]
    itp = Interpolator(axes, {"v": np.array([[10.0], [20.0]])})
    assert itp({"a": [1.5], "b": [5.0]})["v"][0] == 15.0
    assert itp.point(1.5, 5.0) == (15.0,)
    with pytest.raises(EvtmsInputError, match="b = 6"):
        itp({"a": [1.5], "b": [6.0]})
    assert itp({"a": [1.5], "b": [6.0]}, out_of_range="clip")["v"][0] == 15.0


# --- files -------------------------------------------------------------------


@pytest.fixture(scope="module")
def cond_file(tmp_path_factory, thesis):
    return write_lut(thesis("condenser"), tmp_path_factory.mktemp("lut") / "condenser.nc")


@pytest.fixture(scope="module")
def valve_file(tmp_path_factory, thesis):
    return write_lut(thesis("expansion_valve"), tmp_path_factory.mktemp("lut") / "valve.nc")


def _broken(tmp_path, src, edit):
    """A copy of ``src`` changed by ``edit(netCDF4.Dataset)``."""
    dst = tmp_path / "broken.nc"
    dst.write_bytes(src.read_bytes())
    with netCDF4.Dataset(dst, "a") as nc:
        edit(nc)
    return dst


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


def _del_attr(name):
    return lambda nc: nc.delncattr(name)


MALFORMED = [
    ("empty", lambda t, s: _write(t / "e.nc", b""), "the file is empty"),
    ("text", lambda t, s: _write(t / "t.nc", b"mdot,Q\n1,2\n"), "not a netCDF file"),
    ("truncated", lambda t, s: _write(t / "tr.nc", s.read_bytes()[:3000]), "truncated or corrupt"),
    ("missing", lambda t, s: t / "nope.nc", "no such file"),
    ("no version", lambda t, s: _broken(t, s, _del_attr("lut_format_version")), "lut_format_version is missing"),
    (
        "version 3",
        lambda t, s: _broken(t, s, lambda nc: nc.setncattr("lut_format_version", 3)),
        "version 3 is not supported; this evtms reads versions 1 and 2",
    ),
    ("no fluid", lambda t, s: _broken(t, s, _del_attr("fluid")), "'fluid' is missing"),
    (
        "bad component",
        lambda t, s: _broken(t, s, lambda nc: nc.setncattr("component", "heater")),
        "'heater' is unknown",
    ),
    (
        "axis units",
        lambda t, s: _broken(t, s, lambda nc: nc.variables["p_in"].setncattr("units", "psi")),
        "axis 'p_in' has units 'psi'; expected 'Pa'",
    ),
    (
        "not increasing",
        lambda t, s: _broken(t, s, lambda nc: nc.variables["fan"].__setitem__(slice(None), [0.5, 0.4, 0.3, 0.2])),
        "axis 'fan' is not strictly increasing",
    ),
    (
        "nan at valid point",
        lambda t, s: _broken(t, s, lambda nc: nc.variables["Q"].__setitem__((0, 0, 0, 0, 0), np.nan)),
        "'Q' is not finite at a point whose status is valid",
    ),
    (
        "undefined status",
        lambda t, s: _broken(t, s, lambda nc: nc.variables["status"].__setitem__((0, 0, 0, 0, 0), 42)),
        "status holds code 42",
    ),
]


@pytest.mark.parametrize(("kind", "make", "message"), MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_files_one_line_error_exit_2(tmp_path, cond_file, kind, make, message):
    path = make(tmp_path, cond_file)
    with pytest.raises(LutFormatError, match=message):
        open_lut(path)
    # 'lut info' reads the header and the status only (the ranges are stored); the
    # data rules of the other variables are checked where they are loaded.
    if kind == "nan at valid point":
        command = ["lut", "export", str(path), "-f", "csv", "-o", str(tmp_path / "x.csv")]
    else:
        command = ["lut", "info", str(path)]
    res = runner.invoke(app, command)
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(path) in lines[0] and message in lines[0]
    assert "Traceback" not in res.output


def test_missing_variable_is_named(tmp_path, thesis):
    ds = thesis("condenser").drop_vars("T_air_out")
    path = write_lut(ds, tmp_path / "c.nc")
    with pytest.raises(LutFormatError, match="required variable 'T_air_out' is missing"):
        open_lut(path)


def test_mat_export_round_trip(tmp_path, cond_file):
    ds = open_lut(cond_file)
    out = to_mat(ds, tmp_path / "c.mat")
    lut = loadmat(out, squeeze_me=True, struct_as_record=False)["lut"]
    dims = list(ds["status"].dims)
    assert list(lut.axes) == dims and lut.component == "condenser"
    for d in dims:
        np.testing.assert_array_equal(getattr(lut.breakpoints, d), ds[d].values)
        assert getattr(lut.units, d) == ds[d].attrs["units"]
    for v in ds.data_vars:
        np.testing.assert_array_equal(getattr(lut.tables, v), ds[v].values.astype(float))
        assert getattr(lut.units, v) == ds[v].attrs["units"]
    assert "n-D Lookup Table" in lut.note and "0=valid" in lut.status_flags


def test_csv_export_round_trip_with_nan(tmp_path, valve_file):
    ds = open_lut(valve_file)
    out = to_csv(ds, tmp_path / "v.csv")
    columns, data = read_csv(out)
    dims = list(ds["status"].dims)
    assert [c[0] for c in columns] == dims + list(ds.data_vars)
    assert columns[0] == ("T_in", "K") and ("dp", "Pa") in columns
    assert data.shape == (ds["status"].size, len(columns))
    mesh = np.meshgrid(*[ds[d].values for d in dims], indexing="ij")
    for k in range(len(dims)):
        np.testing.assert_array_equal(data[:, k], mesh[k].ravel())
    for k, v in enumerate(ds.data_vars, start=len(dims)):
        np.testing.assert_array_equal(data[:, k], ds[v].values.ravel().astype(float))  # NaN == NaN here
    assert np.isnan(data[:, len(dims) + 1]).sum() == 18


def test_cli_query_and_export(tmp_path, cond_file):
    res = runner.invoke(
        app, ["lut", "query", str(cond_file), "--at", "mdot=0.005,fan=0.2,p_in=1MPa,T_in=340,T_res=300", "--var", "Q"]
    )
    assert res.exit_code == 0, res.output
    itp = Interpolator.from_dataset(open_lut(cond_file), ["Q"])
    expect = itp.point(0.005, 0.2, 1e6, 340.0, 300.0)[0]
    assert f"{expect:.6g}" in res.stdout and "Q [W]" in res.stdout
    res = runner.invoke(app, ["lut", "query", str(cond_file), "--at", "mdot=0.02,fan=0.2,p_in=1e6,T_in=340,T_res=300"])
    assert res.exit_code == 2 and "mdot = 0.02 is outside the LUT range" in res.stderr
    res = runner.invoke(
        app,
        [
            "lut",
            "query",
            str(cond_file),
            "--at",
            "mdot=0.02,fan=0.2,p_in=1e6,T_in=340,T_res=300",
            "--out-of-range",
            "nan",
        ],
    )
    assert res.exit_code == 0 and "nan" in res.stdout
    res = runner.invoke(app, ["lut", "query", str(cond_file), "--at", "mdot=0.005,fan=0.2"])
    assert res.exit_code == 2 and "no value for axis 'p_in'" in res.stderr
    res = runner.invoke(app, ["lut", "export", str(cond_file), "--format", "mat", "-o", str(tmp_path / "c.mat")])
    assert res.exit_code == 0 and (tmp_path / "c.mat").exists()
    res = runner.invoke(app, ["lut", "export", str(cond_file), "--format", "xlsx", "-o", str(tmp_path / "c.x")])
    assert res.exit_code == 2 and "allowed: mat, csv" in res.stderr and not (tmp_path / "c.x").exists()


def test_diff_reports_changes(tmp_path, cond_file, thesis):
    same = runner.invoke(app, ["lut", "diff", str(cond_file), str(cond_file)])
    assert same.exit_code == 0 and "identical" in same.stdout
    ds = thesis("condenser").copy(deep=True)
    ds["Q"] = ds["Q"] * 1.01
    params = json.loads(ds.attrs["parameters"])
    params["condenser"]["n_tubes"] = 44
    ds.attrs["parameters"] = json.dumps(params)
    ds.attrs["coolprop_version"] = "9.9.9"
    other = write_lut(ds.sel(mdot=[0.0062, 0.0077]), tmp_path / "other.nc")
    d = lut_diff(open_lut(cond_file), open_lut(other))
    assert d.common_shape == (2, 4, 4, 4, 3)
    q = next(v for v in d.variables if v.name == "Q")
    assert q.max_rel == pytest.approx(0.01 / 1.01, rel=1e-9) and q.rms > 0
    assert d.parameters == {"condenser.n_tubes": (40, 44)}
    assert d.attributes["coolprop_version"][1] == "9.9.9"
    res = runner.invoke(app, ["lut", "diff", str(cond_file), str(other)])
    assert res.exit_code == 0 and "condenser.n_tubes: 40 -> 44" in res.stdout


def _second_difference_whole(table, axis, j):
    """The 3-point second difference over the whole table at once (the formula, written plainly)."""
    f = np.moveaxis(np.asarray(table, float), j, 0)
    h = np.diff(axis)
    shape = (-1,) + (1,) * (f.ndim - 1)
    h0, h1 = h[:-1].reshape(shape), h[1:].reshape(shape)
    d2 = 2.0 * ((f[2:] - f[1:-1]) / h1 - (f[1:-1] - f[:-2]) / h0) / (h0 + h1)
    return np.moveaxis(np.concatenate([d2[:1], d2, d2[-1:]]), 0, j)


def test_table_rows_in_slabs_equal_the_whole_table_bit_for_bit(tmp_path, monkeypatch):
    """The interpolation table computed a slab of the first axis at a time (as the cache writes it)
    holds the bits of the table computed whole, NaN nodes included; its .npy file reads back equal."""
    from evtms.luts import interp

    rng = np.random.default_rng(5)
    axes = [np.cumsum(rng.uniform(0.1, 2.0, n)) for n in (7, 4, 5)]
    f = rng.normal(size=(7, 4, 5))
    g = np.sin(np.add.outer(np.add.outer(axes[0], axes[1]), axes[2]))
    g[3, 1, 2] = np.nan
    named = [(f"x{j}", a) for j, a in enumerate(axes)]
    expected = np.column_stack(
        [f.ravel(), g.ravel()] + [_second_difference_whole(t, axes[j], j).ravel() for j in range(3) for t in (f, g)]
    )
    monkeypatch.setattr(interp, "_TABLE_BLOCK_ROWS", 1)  # one node of the first axis per slab
    arrays, info = Interpolator.table_arrays(named, {"f": f, "g": g}, "nan", True)
    table = arrays["values"]
    assert table.shape == expected.shape and len(list(table.blocks())) == 7
    np.testing.assert_array_equal(table.materialize(), expected)
    table.write_npy(tmp_path / "values.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "values.npy"), expected)
    # The interpolator described by these arrays is the one built in memory, value for value.
    built = Interpolator(named, {"f": f, "g": g}, "nan", True)
    lazy = Interpolator.from_arrays(arrays, info)
    q = {f"x{j}": rng.uniform(a[0], a[-1], 50) for j, a in enumerate(axes)}
    for v in ("f", "g"):
        np.testing.assert_array_equal(lazy(q)[v], built(q)[v])
