"""LUT files per docs/lut-format.md (format version 2), read back with plain netCDF4."""

from __future__ import annotations

import json

import netCDF4
import numpy as np
import pytest

from evtms.benches import BENCHES
from evtms.benches.sweep import run_sweep
from evtms.luts.io import write_lut
from evtms.luts.schema import AXES, COMPONENT_VARIABLES, REQUIRED_GLOBAL_ATTRS, VARIABLES


@pytest.fixture(scope="module")
def written(small_condenser_grid, tmp_path_factory, params, fluid):
    bench = BENCHES["condenser"]
    paths = []
    for i in range(2):
        ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)
        paths.append(write_lut(ds, tmp_path_factory.mktemp(f"run{i}") / "condenser.nc"))
    return paths


def test_plain_netcdf4_reads_axes_units_and_order(written):
    axes = ("mdot", "fan", "T_in")  # p_in and T_res take one value: fixed inputs, not dimensions
    with netCDF4.Dataset(written[0]) as nc:
        assert nc.data_model == "NETCDF4"
        assert nc.lut_format_version == 2
        assert tuple(nc.dimensions) == axes
        assert json.loads(nc.fixed_inputs) == {
            "p_in": {"value": 1.0e6, "units": "Pa"},
            "T_res": {"value": 300.0, "units": "K"},
        }
        for name in axes:
            var = nc.variables[name]
            assert var.dtype == np.float64 and var.dimensions == (name,)
            assert var.units == AXES[name].units and var.long_name
            assert "_FillValue" not in var.ncattrs()
            assert np.all(np.diff(var[:]) > 0)
        for name in COMPONENT_VARIABLES["condenser"]:
            var = nc.variables[name]
            assert var.dimensions == axes
            assert var.units == VARIABLES[name][0] and var.long_name
            assert var.dtype == (np.int8 if name == "status" else np.float64)
            filters = var.filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == 4
            if name != "status":
                assert var.evtms_storage == "lossless"
                values = var[:].filled(np.nan) if np.ma.isMaskedArray(var[:]) else var[:]
                assert list(var.actual_range) == [np.nanmin(values), np.nanmax(values)]


def test_status_flags_and_global_attributes(written, params):
    with netCDF4.Dataset(written[0]) as nc:
        status = nc.variables["status"]
        assert list(status.flag_values) == [0, 1, 2, 3, 4, 11]  # 11: valid, air correlation outside its range
        assert list(status.valid_flag_values) == [0, 11]
        assert status.flag_meanings.split()[0] == "valid"
        assert len(status.flag_meanings.split()) == len(status.flag_values)
        for attr in REQUIRED_GLOBAL_ATTRS:
            assert attr in nc.ncattrs(), attr
        assert nc.Conventions == "CF-1.10"
        assert nc.component == "condenser" and nc.fluid == "R134a" and nc.grid == "custom"
        used = json.loads(nc.parameters)
        assert used["condenser"]["n_tubes"] == params.condenser.n_tubes
        assert json.loads(nc.environment)["RH"] == pytest.approx(0.4)
        assert nc.created.endswith("Z")


def test_two_runs_give_identical_data(written):
    with netCDF4.Dataset(written[0]) as a, netCDF4.Dataset(written[1]) as b:
        for name in a.variables:
            np.testing.assert_array_equal(a.variables[name][:], b.variables[name][:])


def test_atomic_write_leaves_no_file_on_failure(small_condenser_grid, tmp_path, params, fluid, monkeypatch):
    from evtms.luts.writer import LutFileWriter

    bench = BENCHES["condenser"]
    ds = run_sweep(bench, small_condenser_grid, params, fluid=fluid)

    def boom(self, index, arrays):
        assert self.tmp.stat().st_size > 0  # the file is partly written
        raise KeyboardInterrupt

    monkeypatch.setattr(LutFileWriter, "write", boom)
    with pytest.raises(KeyboardInterrupt):
        write_lut(ds, tmp_path / "c.nc")
    assert list(tmp_path.iterdir()) == []
