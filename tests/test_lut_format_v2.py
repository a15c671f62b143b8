"""LUT format version 2 (docs/lut-format.md): storage, fixed inputs, units, hostile files, lazy reading."""

from __future__ import annotations

import json
import shutil
import subprocess

import netCDF4
import numpy as np
import pytest
import xarray as xr
from scipy.io import loadmat
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.benches.chunked import sweep_to_file
from evtms.benches.sweep import run_sweep
from evtms.cli import app
from evtms.errors import EvtmsInputError
from evtms.luts import Interpolator, LutFormatError, open_lut
from evtms.luts.diff import lut_diff
from evtms.luts.export import to_csv, to_mat
from evtms.luts.io import LutStorage, axis_attributes, write_lut
from evtms.luts.schema import COMPONENT_AXES
from evtms.luts.summary import lut_summary
from evtms.luts.validate import read_lut_metadata

runner = CliRunner()


def _bits(a: np.ndarray) -> np.ndarray:
    """Float values as their bit patterns: equal arrays of these are equal bit for bit (NaN included)."""
    a = np.ascontiguousarray(a)
    if a.dtype.kind != "f":
        return a
    return a.view(np.uint64 if a.dtype == np.float64 else np.uint32)


def _float_vars(ds: xr.Dataset) -> list[str]:
    return [v for v in ds.data_vars if v != "status"]


@pytest.fixture(scope="module")
def thesis_cond(thesis):
    return thesis("condenser")


@pytest.fixture(scope="module")
def cond_file(tmp_path_factory, thesis_cond):
    return write_lut(thesis_cond, tmp_path_factory.mktemp("v2") / "condenser.nc")


def _edited(tmp_path, src, edit, name="edited.nc"):
    """A copy of ``src`` changed by ``edit(netCDF4.Dataset)``."""
    dst = tmp_path / name
    dst.write_bytes(src.read_bytes())
    with netCDF4.Dataset(dst, "a") as nc:
        edit(nc)
    return dst


# --- storage --------------------------------------------------------------------------------


def test_lossless_round_trip_is_bit_for_bit_and_compressed(tmp_path, thesis_cond, cond_file):
    back = open_lut(cond_file)
    for v in thesis_cond.data_vars:
        a, b = thesis_cond[v].values, back[v].values
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(_bits(a), _bits(b))
    with netCDF4.Dataset(cond_file) as nc:
        for v in thesis_cond.data_vars:
            filters = nc[v].filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == 4, v
        assert nc["Q"].evtms_storage == "lossless"
        assert "_FillValue" not in nc["mdot"].ncattrs() and nc["mdot"].dtype == np.float64


def test_both_writers_store_the_same_bits(small_condenser_grid, tmp_path, params, fluid):
    """sweep_to_file (chunk by chunk) and write_lut (one slab) write through one writer: the same bits."""
    bench = BENCHES["condenser"]
    grid = small_condenser_grid
    ds = run_sweep(bench, grid, params, fluid=fluid)
    for storage in (LutStorage(), LutStorage(float32=True, significant_digits=4)):
        streamed = sweep_to_file(bench, grid, params, tmp_path / "s.nc", chunk_points=2, storage=storage).path
        written = write_lut(ds, tmp_path / "w.nc", storage)
        with netCDF4.Dataset(streamed) as a, netCDF4.Dataset(written) as b:
            assert list(a.dimensions) == list(b.dimensions) == ["mdot", "fan", "T_in"]
            assert json.loads(a.fixed_inputs) == json.loads(b.fixed_inputs)
            for v in ds.data_vars:
                a.set_auto_mask(False)
                b.set_auto_mask(False)
                assert a[v].dtype == b[v].dtype and a[v].filters() == b[v].filters()
                np.testing.assert_array_equal(_bits(a[v][:]), _bits(b[v][:]))
                if v != "status":
                    assert a[v].evtms_storage == b[v].evtms_storage == storage.label
                    np.testing.assert_array_equal(a[v].actual_range, b[v].actual_range)


@pytest.mark.parametrize(
    "storage",
    [LutStorage(float32=True), LutStorage(significant_digits=3), LutStorage(float32=True, significant_digits=5)],
    ids=lambda s: s.label,
)
def test_lossy_storage_keeps_its_promise_and_says_so(tmp_path, thesis_cond, cond_file, storage):
    path = write_lut(thesis_cond, tmp_path / "lossy.nc", storage)
    back = open_lut(path)
    changed = 0
    for v in _float_vars(thesis_cond):
        exact, stored = thesis_cond[v].values, back[v].values
        assert stored.dtype == np.float64  # read back as float64 whatever the storage
        np.testing.assert_array_equal(np.isnan(stored), np.isnan(exact))  # NaN fill survives
        ok = np.isfinite(exact) & (exact != 0)
        rel = np.abs(stored[ok] - exact[ok]) / np.abs(exact[ok])
        assert rel.max() <= storage.relative_error, v
        changed += int((stored[ok] != exact[ok]).sum())
        assert back[v].attrs["evtms_storage"] == storage.label
        assert read_lut_metadata(path).storage(v) == storage
        lo, hi = back[v].attrs["actual_range"]
        assert lo == np.nanmin(stored) and hi == np.nanmax(stored)
    assert changed > 0  # it is lossy
    np.testing.assert_array_equal(back["status"].values, thesis_cond["status"].values)  # status never is
    with netCDF4.Dataset(path) as nc:
        assert nc["Q"].dtype == (np.float32 if storage.float32 else np.float64)
    assert path.stat().st_size < cond_file.stat().st_size


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"significant_digits": 0}, "significant digits 0 is not allowed; allowed: 1 to 15"),
        ({"significant_digits": 16}, "allowed: 1 to 15 with float64"),
        ({"significant_digits": 7, "float32": True}, "allowed: 1 to 6 with float32"),
        ({"significant_digits": 2.5}, "significant digits 2.5 is not allowed"),
        ({"significant_digits": True}, "significant digits True is not allowed"),
    ],
)
def test_bad_storage_is_one_line(kwargs, message):
    with pytest.raises(EvtmsInputError, match=message) as err:
        LutStorage(**kwargs)
    assert "\n" not in str(err.value)


def test_unknown_storage_attribute_is_refused(tmp_path, cond_file):
    path = _edited(tmp_path, cond_file, lambda nc: nc["Q"].setncattr("evtms_storage", "jpeg quality=90"))
    with pytest.raises(LutFormatError, match="variable 'Q': evtms_storage 'jpeg quality=90' is not allowed"):
        read_lut_metadata(path)


# --- versions --------------------------------------------------------------------------------


def _as_version_1(ds: xr.Dataset, path) -> None:
    """Write condenser ``ds`` as evtms 0.1 did (format version 1): every input a dimension, uncompressed."""
    fixed = json.loads(ds.attrs["fixed_inputs"])
    grid = {n: ds[n].values if n in ds.dims else np.array([fixed[n]["value"]]) for n in COMPONENT_AXES["condenser"]}
    shape = tuple(len(v) for v in grid.values())
    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc:
        for name, values in grid.items():
            nc.createDimension(name, len(values))
            var = nc.createVariable(name, "f8", (name,))
            var[:] = values
            var.setncatts(axis_attributes(name))
        for name, da in ds.data_vars.items():
            status = name == "status"
            var = nc.createVariable(name, "i1" if status else "f8", tuple(grid), fill_value=None if status else np.nan)
            var.setncatts(dict(da.attrs))
            var[:] = da.values.reshape(shape)
        nc.setncatts({k: v for k, v in ds.attrs.items() if k != "fixed_inputs"} | {"lut_format_version": np.int32(1)})


def test_version_1_file_reads_in_the_version_2_shape(small_condenser_grid, tmp_path, params, fluid):
    bench = BENCHES["condenser"]
    ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)
    old = tmp_path / "v1.nc"
    _as_version_1(ds, old)
    with netCDF4.Dataset(old) as nc:
        assert tuple(nc.dimensions) == ("mdot", "fan", "p_in", "T_in", "T_res") and nc.lut_format_version == 1
    back = open_lut(old)
    assert list(back["status"].dims) == ["mdot", "fan", "T_in"]
    assert back.attrs["lut_format_version"] == 1
    assert json.loads(back.attrs["fixed_inputs"]) == {
        "p_in": {"value": 1.0e6, "units": "Pa"},
        "T_res": {"value": 300.0, "units": "K"},
    }
    for v in ds.data_vars:
        np.testing.assert_array_equal(back[v].values, ds[v].values)
    # The header-only summary streams a version 1 file's data for the ranges.
    s = lut_summary(old)
    assert s["format"] == 1 and s["fixed_inputs"]["T_res"]["value"] == 300.0
    assert [a["name"] for a in s["axes"]] == ["mdot", "fan", "T_in"]
    assert {v["name"]: (v["min"], v["max"]) for v in s["variables"]} == {
        v["name"]: (v["min"], v["max"]) for v in lut_summary(ds)["variables"]
    }
    # Rewritten, it is a version 2 file with the same data.
    rewritten = write_lut(back, tmp_path / "v2.nc")
    assert read_lut_metadata(rewritten).version == 2 and lut_diff(back, open_lut(rewritten)).status_changed == 0


def test_version_1_length_one_axis_in_celsius_becomes_a_fixed_input_in_kelvin(
    small_condenser_grid, tmp_path, params, fluid
):
    bench = BENCHES["condenser"]
    ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)
    _as_version_1(ds, tmp_path / "v1.nc")
    path = _edited(tmp_path, tmp_path / "v1.nc", lambda nc: _in_units(nc, "T_res", "degC", 1.0, 273.15))
    with netCDF4.Dataset(path) as nc:
        assert nc["T_res"].units == "degC" and nc["T_res"][0] == pytest.approx(26.85)
    assert read_lut_metadata(path).fixed["T_res"] == pytest.approx(300.0, abs=1e-12)
    bad = _edited(tmp_path, tmp_path / "v1.nc", lambda nc: nc["T_res"].setncattr("units", "F"), "bad.nc")
    with pytest.raises(LutFormatError, match="axis 'T_res' has units 'F'; expected 'K'"):
        read_lut_metadata(bad)


@pytest.mark.parametrize("version", [0, 3, 99])
def test_other_versions_are_refused(tmp_path, cond_file, version):
    path = _edited(tmp_path, cond_file, lambda nc: nc.setncattr("lut_format_version", np.int32(version)))
    with pytest.raises(LutFormatError, match=f"version {version} is not supported; this evtms reads versions 1 and 2"):
        open_lut(path)
    res = runner.invoke(app, ["lut", "info", str(path)])
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1


# --- fixed inputs ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_file(small_condenser_grid, tmp_path_factory, params):
    bench = BENCHES["condenser"]
    grid = small_condenser_grid
    folder = tmp_path_factory.mktemp("small")
    return sweep_to_file(bench, grid, params, folder / "condenser.nc", chunk_points=4).path


def test_length_one_axis_is_a_fixed_input_not_a_dimension(small_condenser_grid, small_file, params, fluid):
    with netCDF4.Dataset(small_file) as nc:
        assert list(nc.dimensions) == ["mdot", "fan", "T_in"]
        assert "p_in" not in nc.variables and "T_res" not in nc.variables
        assert json.loads(nc.fixed_inputs) == {
            "p_in": {"value": 1.0e6, "units": "Pa"},
            "T_res": {"value": 300.0, "units": "K"},
        }
    # The bench did evaluate at the fixed values: the file equals an in-memory sweep.
    bench = BENCHES["condenser"]
    ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)
    back = open_lut(small_file)
    np.testing.assert_array_equal(back["Q"].values, ds["Q"].values)
    assert read_lut_metadata(small_file).fixed == {"p_in": 1.0e6, "T_res": 300.0}


def test_interpolator_takes_fixed_inputs_by_policy(small_file):
    ds = open_lut(small_file)
    itp = Interpolator.from_dataset(ds, ["Q"])
    assert itp.names == ("mdot", "fan", "T_in") and itp.fixed == {"p_in": 1.0e6, "T_res": 300.0}
    at = {"mdot": 0.006, "fan": 0.3, "T_in": 350.0}
    q = itp(at)["Q"][0]
    assert itp(at | {"p_in": 1.0e6, "T_res": 300.0})["Q"][0] == q
    with pytest.raises(EvtmsInputError, match="T_res = 310 differs from the LUT's fixed input T_res = 300"):
        itp(at | {"T_res": 310.0})
    assert np.isnan(itp(at | {"T_res": [300.0, 310.0]}, out_of_range="nan")["Q"]).tolist() == [False, True]
    assert itp(at | {"T_res": 310.0}, out_of_range="clip")["Q"][0] == q


def test_a_standard_axis_must_be_an_axis_or_a_fixed_input(tmp_path, small_file):
    no_fixed = _edited(tmp_path, small_file, lambda nc: nc.setncattr("fixed_inputs", "{}"))
    with pytest.raises(LutFormatError, match="axis 'p_in' is neither an axis nor a fixed input"):
        open_lut(no_fixed)
    unknown = _edited(
        tmp_path,
        small_file,
        lambda nc: nc.setncattr("fixed_inputs", nc.fixed_inputs[:-1] + ', "blower": {"value": 1, "units": "1"}}'),
        "unknown.nc",
    )
    with pytest.raises(LutFormatError, match="fixed input 'blower' is not an input of a condenser"):
        open_lut(unknown)


def test_a_version_2_file_with_a_length_one_dimension_is_refused(small_condenser_grid, tmp_path, params, fluid):
    bench = BENCHES["condenser"]
    ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)
    ds = ds.expand_dims({"T_res": [300.0]}, axis=3)
    ds["T_res"].attrs = {"units": "K", "long_name": "outlet reservoir temperature"}
    ds.attrs["fixed_inputs"] = json.dumps({"p_in": {"value": 1.0e6, "units": "Pa"}})
    path = tmp_path / "bad.nc"
    ds.to_netcdf(path, encoding={"T_res": {"_FillValue": None}} | {n: {"_FillValue": None} for n in ds.coords})
    message = "axis 'T_res' has a single value; format version 2 stores it in fixed_inputs"
    with pytest.raises(LutFormatError, match=message):
        open_lut(path)


# --- units and attributes --------------------------------------------------------------------


def _in_units(nc, axis, units, factor, offset=0.0):
    nc[axis][:] = (nc[axis][:] - offset) / factor
    nc[axis].setncattr("units", units)


@pytest.mark.parametrize(
    ("axis", "units", "factor", "offset"),
    [
        ("p_in", "bar", 1e5, 0.0),
        ("p_in", "kPa", 1e3, 0.0),
        ("p_in", "MPa", 1e6, 0.0),
        ("T_in", "degC", 1.0, 273.15),
        ("T_in", "degree_Celsius", 1.0, 273.15),
        ("T_res", "celsius", 1.0, 273.15),
        ("mdot", "g s-1", 1e-3, 0.0),
    ],
)
def test_axis_units_are_converted_exactly(tmp_path, cond_file, axis, units, factor, offset):
    path = _edited(tmp_path, cond_file, lambda nc: _in_units(nc, axis, units, factor, offset))
    with netCDF4.Dataset(path) as nc:
        assert nc[axis].units == units and nc[axis][0] != open_lut(cond_file)[axis].values[0]
    ref, conv = open_lut(cond_file), open_lut(path)
    np.testing.assert_allclose(conv[axis].values, ref[axis].values, rtol=1e-13)
    assert conv[axis].attrs["units"] == ref[axis].attrs["units"]
    rng = np.random.default_rng(3)
    query = {d: rng.uniform(ref[d].values[0], ref[d].values[-1], 50) for d in ref["status"].dims}
    query[axis] = np.clip(query[axis], conv[axis].values[0], conv[axis].values[-1])
    a = Interpolator.from_dataset(ref, ["Q", "h_out"], out_of_range="clip")(query)
    b = Interpolator.from_dataset(conv, ["Q", "h_out"], out_of_range="clip")(query)
    for v in a:
        np.testing.assert_allclose(b[v], a[v], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize(
    ("axis", "units"), [("p_in", "psi"), ("T_in", "C"), ("mdot", "lb s-1"), ("fan", "rpm"), ("T_res", "")]
)
def test_unknown_axis_units_are_refused(tmp_path, cond_file, axis, units):
    path = _edited(tmp_path, cond_file, lambda nc: nc[axis].setncattr("units", units))
    with pytest.raises(LutFormatError) as err:
        open_lut(path)
    message = str(err.value)
    assert f"axis {axis!r} has units {units!r}; expected" in message and "\n" not in message


@pytest.mark.parametrize(
    ("attr", "text", "message"),
    [
        ("parameters", "{not json", "global attribute 'parameters' is not valid JSON"),
        ("environment", "[1, 2]", "global attribute 'environment' must be a JSON object, not list"),
        ("fixed_inputs", '"T_res"', "global attribute 'fixed_inputs' must be a JSON object, not str"),
        ("fixed_inputs", '{"T_res": 300}', 'fixed input \'T_res\' must be {"value": number, "units": text}'),
        ("fixed_inputs", '{"T_res": {"value": "hot", "units": "K"}}', "fixed input 'T_res' has value 'hot'"),
        ("fixed_inputs", '{"T_res": {"value": 27, "units": "F"}}', "fixed input 'T_res' has units 'F'"),
    ],
)
def test_garbage_evtms_attributes_are_refused_in_one_line(tmp_path, cond_file, attr, text, message):
    path = _edited(tmp_path, cond_file, lambda nc: nc.setncattr(attr, text))
    with pytest.raises(LutFormatError) as err:
        read_lut_metadata(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


def test_fixed_input_in_celsius_is_converted(tmp_path, small_file):
    text = json.dumps({"p_in": {"value": 10.0, "units": "bar"}, "T_res": {"value": 26.85, "units": "degC"}})
    path = _edited(tmp_path, small_file, lambda nc: nc.setncattr("fixed_inputs", text))
    fixed = read_lut_metadata(path).fixed
    assert fixed["p_in"] == 1.0e6 and fixed["T_res"] == pytest.approx(300.0, abs=1e-12)


def test_expected_component(cond_file):
    assert open_lut(cond_file, component="condenser").attrs["component"] == "condenser"
    with pytest.raises(LutFormatError, match="holds the condenser LUT; the evaporator LUT is needed here"):
        open_lut(cond_file, component="evaporator")
    with pytest.raises(EvtmsInputError, match="component 'heater' is unknown"):
        open_lut(cond_file, component="heater")


# --- hostile files ---------------------------------------------------------------------------


def test_huge_declared_dimensions_are_refused_from_the_header(tmp_path, cond_file):
    path = tmp_path / "huge.nc"
    with netCDF4.Dataset(cond_file) as src, netCDF4.Dataset(path, "w") as nc:
        nc.setncatts({k: src.getncattr(k) for k in src.ncattrs()})
        for d in ("mdot", "fan"):
            nc.createDimension(d, 100_000)
            nc.createVariable(d, "f8", (d,))
        nc.createVariable("status", "i1", ("mdot", "fan"))  # declared, never written: nothing allocated
    assert path.stat().st_size < 1_000_000
    for read in (read_lut_metadata, open_lut, lut_summary):
        with pytest.raises(LutFormatError, match=r"declares 1e\+10 grid points \(mdot 100000 x fan 100000\)"):
            read(path)


def test_loading_more_than_the_available_memory_is_refused(cond_file, monkeypatch):
    import evtms.luts.validate as validate

    monkeypatch.setattr(validate, "available_memory", lambda: 10_000)
    message = "loading 11 variables of 768 points needs 62.2 kB; 80 % of the available memory is 8 kB"
    with pytest.raises(EvtmsInputError, match=message):
        open_lut(cond_file)
    assert read_lut_metadata(cond_file).points == 768  # the header alone still reads


def _hdf5_from_another_program(path) -> bool:
    """A plain HDF5 file (not netCDF) written by h5import or Octave, if either is installed."""
    if shutil.which("h5import"):
        raw = path.with_suffix(".txt")
        raw.write_text("1 2 3 4\n")
        cfg = path.with_suffix(".cfg")
        cfg.write_text("PATH data\nINPUT-CLASS TEXTFP\nRANK 1\nDIMENSION-SIZES 4\nOUTPUT-CLASS FP\nOUTPUT-SIZE 64\n")
        subprocess.run(["h5import", str(raw), "-c", str(cfg), "-o", str(path)], check=True, capture_output=True)
        return True
    if shutil.which("octave"):
        script = f"x = [1 2 3 4]; save('-hdf5', '{path}', 'x');"
        subprocess.run(["octave", "--no-gui", "--quiet", "--eval", script], check=True, capture_output=True)
        return True
    return False


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p, src: p.write_bytes(b"x,y\n1,2\n") or True, "not a netCDF file"),
        (lambda p, src: p.write_bytes(src.read_bytes()[:5000]) or True, "truncated or corrupt"),
        (lambda p, src: p.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(200)) or True, "truncated or corrupt"),
        (lambda p, src: _hdf5_from_another_program(p), "lut_format_version is missing (not an evtms LUT file)"),
    ],
    ids=["text", "truncated", "hdf5 signature only", "hdf5 from another program"],
)
def test_hostile_files_are_refused_in_one_line(tmp_path, cond_file, make, message):
    path = tmp_path / "hostile.nc"
    if not make(path, cond_file):
        pytest.skip("neither h5import (hdf5-tools) nor Octave is installed to write a plain HDF5 file")
    for read in (read_lut_metadata, open_lut):
        with pytest.raises(LutFormatError) as err:
            read(path)
        assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)
    res = runner.invoke(app, ["lut", "info", str(path)])
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.output


# --- reading without loading -----------------------------------------------------------------


def test_metadata_reads_no_data_and_leaves_no_handle(tmp_path, cond_file, thesis_cond):
    meta = read_lut_metadata(cond_file)
    assert meta.dims == ("mdot", "fan", "p_in", "T_in", "T_res") and meta.points == 768
    # The file is closed: it can be replaced by an atomic rename, and is then refused, not mixed.
    other = write_lut(thesis_cond.isel(p_in=slice(0, 2)), tmp_path / "other.nc")
    copy = tmp_path / "copy.nc"
    copy.write_bytes(cond_file.read_bytes())
    meta = read_lut_metadata(copy)
    other.replace(copy)
    with pytest.raises(LutFormatError, match="changed or vanished since it was opened"):
        meta.read("Q")
    # Slabs cover the grid exactly once.
    meta = read_lut_metadata(cond_file)
    total = sum(slab["Q"].size for slab in meta.iter_slabs(["Q"], max_points=50))
    assert total == meta.points


def test_open_only_some_variables(cond_file):
    ds = open_lut(cond_file, variables=["Q"])
    assert sorted(ds.data_vars) == ["Q", "status"]
    with pytest.raises(EvtmsInputError, match="variable 'nope' is not in .*; allowed: status, Q"):
        open_lut(cond_file, variables=["nope"])


def test_summary_from_the_file_equals_the_summary_of_the_loaded_dataset(cond_file):
    from_file, loaded = lut_summary(cond_file), lut_summary(open_lut(cond_file))
    assert from_file == loaded
    assert all(v["storage"] == "lossless" for v in from_file["variables"])


# --- exports ---------------------------------------------------------------------------------


def test_mat_export_has_no_length_one_dimensions(tmp_path, small_file):
    ds = open_lut(small_file)
    out = to_mat(ds, tmp_path / "c.mat")
    lut = loadmat(out, squeeze_me=False, struct_as_record=False)["lut"][0, 0]
    axes = [str(a[0]) for a in lut.axes[0]]
    assert axes == ["mdot", "fan", "T_in"]
    q = lut.tables[0, 0].Q
    assert q.shape == (2, 2, 2) and 1 not in q.shape
    for k, a in enumerate(axes):
        bp = getattr(lut.breakpoints[0, 0], a)
        assert bp.shape == (1, q.shape[k])  # row vectors
    fixed = lut.fixed_inputs[0, 0]
    assert fixed.T_res[0, 0].value[0, 0] == 300.0 and str(fixed.T_res[0, 0].units[0]) == "K"
    assert fixed.p_in[0, 0].value[0, 0] == 1.0e6
    assert "lut.fixed_inputs" in str(lut.note[0])
    # An in-memory dataset with a length-1 dimension is squeezed on export too.
    padded = ds.expand_dims({"T_res": [300.0]}, axis=3)
    padded.attrs["fixed_inputs"] = json.dumps({"p_in": {"value": 1.0e6, "units": "Pa"}})
    lut = loadmat(to_mat(padded, tmp_path / "p.mat"), squeeze_me=True, struct_as_record=False)["lut"]
    assert lut.tables.Q.shape == (2, 2, 2) and lut.fixed_inputs.T_res.value == 300.0


def test_csv_export_carries_fixed_inputs_as_columns(tmp_path, small_file):
    from evtms.luts.export import read_csv

    columns, data = read_csv(to_csv(open_lut(small_file), tmp_path / "c.csv"))
    names = [c[0] for c in columns]
    assert names[:5] == ["mdot", "fan", "T_in", "p_in", "T_res"] and ("T_res", "K") in columns
    assert np.all(data[:, 3] == 1.0e6) and np.all(data[:, 4] == 300.0)


def test_octave_interpn_matches_the_interpolator(tmp_path, cond_file):
    """The exported .mat in Octave: interpn on the tables gives the LUT's values."""
    octave = shutil.which("octave")
    if octave is None:
        pytest.skip("Octave is not installed")
    ds = open_lut(cond_file)
    mat = to_mat(ds, tmp_path / "c.mat")
    rng = np.random.default_rng(11)
    dims = list(ds["status"].dims)
    pts = {d: rng.uniform(ds[d].values[0], ds[d].values[-1], 6) for d in dims}
    pts["mdot"][:3] = ds["mdot"].values[[0, 1, 2]]  # some on nodes
    expect = Interpolator.from_dataset(ds, ["Q", "h_out"])(pts)
    q = ";".join(" ".join(repr(float(pts[d][i])) for d in dims) for i in range(6))
    # interpn(x1..xn, V, y1..yn): breakpoints, table, then the query columns.
    script = (
        f"load('{mat}'); p = [{q}]; n = numel(lut.axes); bp = {{}}; qs = {{}};"
        "for k = 1:n, bp{k} = lut.breakpoints.(lut.axes{k}); qs{k} = p(:, k); end;"
        "for v = {'Q', 'h_out'}, printf('%.17g\\n', interpn(bp{:}, lut.tables.(v{1}), qs{:}, 'linear')); end"
    )
    res = subprocess.run([octave, "--no-gui", "--quiet", "--eval", script], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    got = np.array([float(x) for x in res.stdout.split()]).reshape(2, 6)
    np.testing.assert_allclose(got[0], expect["Q"], rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(got[1], expect["h_out"], rtol=1e-12, equal_nan=True)
