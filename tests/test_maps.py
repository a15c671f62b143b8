"""Steady cycle maps (spec 2.5): closure at nodes and between them, signs, interpolation, fill, cache.

Small maps (2-3 nodes per axis, inside the 'cycle' LUT grids) on the session's
cycle LUTs; the LUT folder is a private one whose large files are links to the
session's, so touching a LUT here never invalidates another test's tables.
"""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.luts.validate import read_map_lut
from evtms.system import maps as maps_module
from evtms.system.maps import (
    MAP_FORMAT,
    MAP_OUTPUTS,
    MAPS,
    CycleMap,
    MapSettings,
    _map_interp,
    build_map,
    fill_invalid,
    load_maps,
    map_interp,
)

RNG = np.random.default_rng(20261130)
SLOT = {k: i for i, k in enumerate(MAP_OUTPUTS)}

#: 2-3 nodes per axis, inside the evaporator (15-35 degC) and condenser (15-45 degC) 'cycle' grids.
SMALL = {
    "speed": [0.3, 0.6, 1.0],
    "fan": [0.4, 1.0],
    "blower": [0.4, 1.0],
    "T_amb": [298.15, 308.15],
    "T_air_in": [295.15, 303.15],
    "RH_air_in": [0.4, 0.6],
    "u_pump": [0.3, 1.0],
    "T_coolant_in": [293.15, 303.15],
}


def _luts_copy(src, dst):
    """A LUT folder: links to the large files, a real copy of the small ones (touched by the tests)."""
    dst.mkdir()
    for f in sorted(src.glob("*.nc")):
        if f.stat().st_size < 2_000_000:
            shutil.copy2(f, dst / f.name)
        else:
            os.symlink(f, dst / f.name)
    return dst


@pytest.fixture(scope="module")
def small():
    return MapSettings(axes=SMALL)


@pytest.fixture(scope="module")
def maps(cycle_luts_dir, small, tmp_path_factory):
    folder = _luts_copy(cycle_luts_dir, tmp_path_factory.mktemp("maps") / "luts")
    return load_maps(folder, small)


def _closure(values: np.ndarray) -> np.ndarray:
    v = values.reshape(-1, len(MAP_OUTPUTS))
    q_in = v[:, SLOT["Q_evaporator"]] + v[:, SLOT["Q_chiller"]] + v[:, SLOT["W_fluid"]]
    return np.abs(v[:, SLOT["Q_condenser"]] - q_in)


def test_maps_are_complete_and_close_at_every_node(maps):
    assert list(maps) == ["ac", "chiller", "ac+chiller"]
    for name, m in maps.items():
        assert m.axes == MAPS[name].axes
        assert m.values.shape == (*(len(SMALL[a]) for a in m.axes), 9)
        assert m.values.dtype == np.float64 and m.values.flags.c_contiguous
        assert np.all(np.isfinite(m.values))
        assert m.filled == int(m.filled_nodes.sum()) < m.values[..., 0].size
        w_fluid = m.values[..., SLOT["W_fluid"]].reshape(-1)
        assert np.all(_closure(m.values) <= 1e-6 * w_fluid), name
        knots, starts, table = m.packed()
        assert knots.dtype == np.float64 and starts.dtype == np.int64 and table.dtype == np.float64
        assert starts.tolist() == [0, *np.cumsum([len(SMALL[a]) for a in m.axes]).tolist()]
        assert table.shape == (m.values[..., 0].size, 9) and table.flags.c_contiguous


def test_signs_and_absent_branches(maps):
    ac, ch, both = (maps[n].values for n in ("ac", "chiller", "ac+chiller"))
    assert np.all(ac[..., SLOT["Q_evaporator"]] > 0) and np.all(ac[..., SLOT["Q_chiller"]] == 0)
    assert np.all(ac[..., SLOT["Q_latent"]] >= 0) and np.all(ac[..., SLOT["Q_latent"]] <= ac[..., SLOT["Q_evaporator"]])
    assert np.any(ac[..., SLOT["Q_latent"]] > 0)  # RH 0.6 at 30 degC condenses
    assert np.all(ch[..., SLOT["Q_chiller"]] > 0) and np.all(ch[..., SLOT["Q_evaporator"]] == 0)
    assert np.all(ch[..., SLOT["Q_latent"]] == 0)
    # Two branches: a branch whose valve is closed (cycle status 10) takes no heat, the other one does.
    q_both = both[..., SLOT["Q_chiller"]] + both[..., SLOT["Q_evaporator"]]
    assert np.all(both[..., SLOT["Q_chiller"]] >= 0) and np.all(both[..., SLOT["Q_evaporator"]] >= 0)
    assert (
        np.all(q_both > 0) and np.any(both[..., SLOT["Q_chiller"]] > 0) and np.any(both[..., SLOT["Q_evaporator"]] > 0)
    )
    for v in (ac, ch, both):
        assert np.all(v[..., SLOT["p_discharge"]] > v[..., SLOT["p_suction"]])
        assert np.all(v[..., SLOT["W"]] >= v[..., SLOT["W_fluid"]]) and np.all(v[..., SLOT["W_fluid"]] > 0)
        assert np.all(v[..., SLOT["mdot"]] > 0) and np.all(v[..., SLOT["Q_condenser"]] > 0)


def test_cooling_rises_with_compressor_speed(maps):
    m = maps["ac"]
    mid = (slice(None), 1, 1, 0, 1, 1)  # fan 1, blower 1, T_amb 25 degC, air 30 degC, RH 0.6
    assert not m.filled_nodes[mid].any()
    q = m.values[(*mid, SLOT["Q_evaporator"])]
    assert np.all(np.diff(q) > 0), q


def test_less_condenser_air_raises_the_discharge_pressure_and_the_work(maps):
    for name, m in maps.items():
        assert m.axes[1] == "fan"
        low, full = m.values[:, 0], m.values[:, -1]
        solved = ~(m.filled_nodes[:, 0] | m.filled_nodes[:, -1])
        assert solved.sum() >= 0.5 * solved.size, name
        assert np.all(low[solved][..., SLOT["p_discharge"]] > full[solved][..., SLOT["p_discharge"]]), name
        assert np.all(low[solved][..., SLOT["W"]] > full[solved][..., SLOT["W"]]), name


def _interp(m: CycleMap, x, fn=map_interp):
    knots, starts, table = m.packed()
    out = np.empty(9)
    flag = fn(knots, starts, table, np.asarray(x, np.float64), out)
    return out, flag


def test_interpolation_returns_nodes_and_is_linear_between_them(maps):
    for m in maps.values():
        shape = m.values.shape[:-1]
        for flat in RNG.choice(np.prod(shape), 8, replace=False):
            idx = np.unravel_index(flat, shape)
            x = [m.nodes[d][i] for d, i in enumerate(idx)]
            out, flag = _interp(m, x)
            assert flag == 0
            np.testing.assert_array_equal(out, m.values[idx])
            for d in range(len(shape)):  # midpoint towards the next node along each axis
                j = idx[d] + 1 if idx[d] + 1 < shape[d] else idx[d] - 1
                other = (*idx[:d], j, *idx[d + 1 :])
                xm = list(x)
                xm[d] = 0.5 * (m.nodes[d][idx[d]] + m.nodes[d][j])
                out, flag = _interp(m, xm)
                assert flag == 0
                np.testing.assert_allclose(out, 0.5 * (m.values[idx] + m.values[other]), rtol=1e-12)


def test_closure_between_nodes_and_clipping(maps):
    for m in maps.values():
        lo = np.array([n[0] for n in m.nodes])
        hi = np.array([n[-1] for n in m.nodes])
        for _ in range(50):
            x = lo + RNG.uniform(size=lo.size) * (hi - lo)
            out, flag = _interp(m, x)
            assert flag == 0
            assert _closure(out)[0] <= 1e-9 * out[SLOT["W_fluid"]]
            out_py, flag_py = _interp(m, x, _map_interp)  # the plain-Python kernel gives the same
            np.testing.assert_allclose(out_py, out, rtol=1e-13)
            assert flag_py == flag
        x = 0.5 * (lo + hi)
        for d in range(lo.size):
            for beyond, end in ((lo[d] - 1.0, lo[d]), (hi[d] + 1.0, hi[d])):
                xo, xe = x.copy(), x.copy()
                xo[d], xe[d] = beyond, end
                out, flag = _interp(m, xo)
                assert flag == 1
                np.testing.assert_array_equal(out, _interp(m, xe)[0])
                assert _interp(m, xe)[1] == 0
                assert _interp(m, xo, _map_interp)[1] == 1
        values, clipped = m.interp(hi + 1.0)  # the LUT layer's interpolator, clipped to the last node
        assert clipped and np.allclose(values, m.values[(-1,) * lo.size], rtol=1e-14, atol=0.0)
        assert m.interp(lo)[1] is False and np.all(np.isnan(m.interp(np.full(lo.size, np.nan))[0]))


def test_the_loop_kernel_is_the_twin_of_the_luts_interpolator(maps):
    """map_interp (the time loop's compiled kernel) and CycleMap.interp (evtms.luts.interp.Interpolator) give
    the same outputs on random points, inside the axes and beyond them (clipped), to rounding."""
    for m in maps.values():
        lo = np.array([n[0] for n in m.nodes])
        hi = np.array([n[-1] for n in m.nodes])
        # Relative to each value, or to the output's largest value where it passes near 0 (Q_latent).
        scale = np.max(np.abs(m.values.reshape(-1, len(MAP_OUTPUTS))), axis=0)
        for _ in range(300):
            x = lo + RNG.uniform(-0.2, 1.2, size=lo.size) * (hi - lo)
            luts, clipped = m.interp(x)
            twin, flag = _interp(m, x)
            assert np.all(np.abs(luts - twin) <= 1e-12 * np.maximum(np.abs(twin), scale)), (x, luts, twin)
            assert clipped == bool(flag)


def test_fill_rule_lower_speed_then_higher_then_ambient():
    # axes (speed, T_amb, blower); output 0 records the donor
    nodes = (np.array([0.1, 0.5, 1.0]), np.array([270.0, 280.0, 300.0]), np.array([0.2, 1.0]))
    values = np.zeros((3, 3, 2, 1))
    values[..., 0] = np.arange(18).reshape(3, 3, 2)
    valid = np.ones((3, 3, 2), bool)
    valid[1:, 0, 0] = False  # speeds 0.5, 1: from speed 0.1
    valid[0, 1, 0] = False  # lowest speed: from the next higher valid speed
    valid[:, 2, 1] = False  # whole speed line: nearest along T_amb (280 K, not 270 K)
    out, filled = fill_invalid(values, valid, nodes, ("speed", "T_amb", "blower"))
    assert filled.sum() == 6 and np.array_equal(filled, ~valid)
    assert out[1, 0, 0, 0] == values[0, 0, 0, 0] and out[2, 0, 0, 0] == values[0, 0, 0, 0]
    assert out[0, 1, 0, 0] == values[1, 1, 0, 0]
    for s in range(3):
        assert out[s, 2, 1, 0] == values[s, 1, 1, 0]
    valid2 = np.zeros((3, 3, 2), bool)
    valid2[0, 0, 1] = True  # one valid node: everything copies it, along blower last
    out2, filled2 = fill_invalid(values, valid2, nodes, ("speed", "T_amb", "blower"))
    assert filled2.sum() == 17 and np.all(out2[..., 0] == values[0, 0, 1, 0])


def test_a_map_without_a_valid_node_is_an_input_error(cycle_luts_dir, small, monkeypatch):
    real = maps_module.solve_nodes

    def failing(luts, topology, inputs):
        res = real(luts, topology, inputs)
        res["status"] = np.full(res["status"].size, 1, np.int8)
        return res

    monkeypatch.setattr(maps_module, "solve_nodes", failing)
    with pytest.raises(EvtmsInputError, match="none of its 48 operating points solved") as err:
        build_map("chiller", cycle_luts_dir, small, workers=1)
    assert "\n" not in str(err.value)


def test_settings_and_names_are_checked(cycle_luts_dir):
    for bad in ({"speeds": [0.5]}, {"speed": [0.5, 0.5]}, {"speed": [0.0, 1.0]}, {"ac.u_pump": [0.5]}):
        with pytest.raises(EvtmsInputError):
            MapSettings(axes=bad)
    with pytest.raises(EvtmsInputError):
        MapSettings(superheat=-1.0)
    with pytest.raises(EvtmsInputError, match="unknown"):
        load_maps(cycle_luts_dir, names=("boiler",))
    with pytest.raises(EvtmsInputError, match="u_H must be > 0"):
        MapSettings(axes={"u_H": [0.0, 1.0]})
    s = MapSettings(axes={"T_amb": [290.0, 300.0], "ac+chiller.T_amb": [295.0]})
    assert s.override("ac", "T_amb") == (290.0, 300.0) and s.override("ac+chiller", "T_amb") == (295.0,)


def test_cache_is_read_back_and_rebuilt_when_a_lut_or_the_settings_change(cycle_luts_dir, small, tmp_path):
    folder = _luts_copy(cycle_luts_dir, tmp_path / "luts")
    calls = []

    def progress(done, total, text):
        calls.append((done, total, text))

    first = load_maps(folder, small, names=("chiller",), progress=progress)["chiller"]
    assert calls[0] == (0, 48, "chiller") and calls[-1] == (48, 48, "chiller")
    path = folder / "maps" / "chiller.nc"
    assert path.is_file() and not list((folder / "maps").glob(".*"))  # no temporary file left
    # A map LUT, written by the LUT layer and read back by it.
    table = read_map_lut(path)
    assert table.attrs["lut_kind"] == "map" and table.attrs["map_format"] == MAP_FORMAT
    assert set(table.attrs["lut_files"]) == {"compressor", "condenser", "chiller", "expansion_valve"}
    assert table.attributes["Q_chiller"]["units"] == "W" and table.attributes["T_amb"]["units"] == "K"
    calls.clear()
    again = load_maps(folder, small, names=("chiller",), progress=progress)["chiller"]
    assert not calls  # read from disk, nothing solved
    assert np.array_equal(again.values, first.values) and again.filled == first.filled
    assert all(np.array_equal(a, b) for a, b in zip(again.nodes, first.nodes, strict=True))
    assert again.attrs["created"] == first.attrs["created"]

    st = os.stat(folder / "expansion_valve.nc")  # a LUT touched: rebuilt
    os.utime(folder / "expansion_valve.nc", ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    load_maps(folder, small, names=("chiller",), progress=progress)
    assert calls
    calls.clear()
    load_maps(folder, small, names=("chiller",), progress=progress)
    assert not calls

    other = load_maps(folder, MapSettings(axes=SMALL, superheat=8.0), names=("chiller",), progress=progress)
    assert calls and not np.array_equal(other["chiller"].values, first.values)  # settings differ: rebuilt
    calls.clear()
    load_maps(folder, MapSettings(axes=SMALL, superheat=8.0), names=("chiller",), progress=progress)
    assert not calls

    path.write_bytes(b"not netCDF")  # unreadable: rebuilt
    load_maps(folder, MapSettings(axes=SMALL, superheat=8.0), names=("chiller",), progress=progress)
    assert calls


def test_a_map_file_read_once_comes_back_from_the_user_cache_until_it_changes(
    cycle_luts_dir, small, tmp_path, monkeypatch
):
    """The second read of a map file takes its arrays from the user cache (no netCDF read), equal
    to the file's; a map file rewritten under the same key is read again, not served stale."""
    import evtms.luts.validate as validate
    from evtms.system.maps import read_map, write_map

    folder = _luts_copy(cycle_luts_dir, tmp_path / "luts")
    load_maps(folder, small, names=("chiller",))
    path = folder / "maps" / "chiller.nc"
    from_file = read_map(path)
    first = load_maps(folder, small, names=("chiller",))["chiller"]  # the file read, its arrays kept
    real = validate.read_map_lut

    def refused(*args, **kwargs):
        raise AssertionError("the map file was read again")

    monkeypatch.setattr(validate, "read_map_lut", refused)
    cached = load_maps(folder, small, names=("chiller",))["chiller"]
    assert isinstance(cached.values, np.memmap) or isinstance(cached.values.base, np.memmap)
    for m in (first, cached):
        assert np.array_equal(m.values, from_file.values) and m.filled == from_file.filled
        assert np.array_equal(m.filled_nodes, from_file.filled_nodes)
        assert np.array_equal(m.attrs["status"], from_file.attrs["status"])
        assert all(np.array_equal(a, b) for a, b in zip(m.nodes, from_file.nodes, strict=True))
        assert {k: v for k, v in m.attrs.items() if k != "status"} == {
            k: v for k, v in from_file.attrs.items() if k != "status"
        }
    monkeypatch.setattr(validate, "read_map_lut", real)
    changed = CycleMap(
        "chiller", from_file.axes, from_file.nodes, from_file.values * 2.0, from_file.filled,
        from_file.filled_nodes, from_file.attrs,
    )  # fmt: skip
    write_map(changed, path)
    again = load_maps(folder, small, names=("chiller",))["chiller"]
    assert np.array_equal(again.values, from_file.values * 2.0)


def test_a_map_cached_in_the_previous_format_is_rebuilt(cycle_luts_dir, small, tmp_path):
    """A format-2 file (xarray's netCDF, no lut_kind) carrying the current key is not taken: rebuilt."""
    import xarray as xr

    folder = _luts_copy(cycle_luts_dir, tmp_path / "luts")
    first = load_maps(folder, small, names=("chiller",))["chiller"]
    path = folder / "maps" / "chiller.nc"
    old = xr.Dataset(
        {k: (first.axes, first.output(k) + 1.0) for k in MAP_OUTPUTS} | {"filled": (first.axes, first.filled_nodes)},
        coords=dict(zip(first.axes, first.nodes, strict=True)),
        attrs={"map_key": first.attrs["map_key"], "map_name": "chiller", "filled": first.filled, "map_format": 2},
    )
    old.to_netcdf(path, engine="netcdf4")
    calls = []
    again = load_maps(folder, small, names=("chiller",), progress=lambda *a: calls.append(a))["chiller"]
    assert calls and np.array_equal(again.values, first.values)
    assert read_map_lut(path).attrs["lut_kind"] == "map"


def test_unwritable_lut_folder_falls_back_to_the_user_cache(cycle_luts_dir, small, tmp_path):
    from evtms.luts.cache import cache_root

    folder = _luts_copy(cycle_luts_dir, tmp_path / "luts")
    (folder / "maps").write_text("a file where the maps folder would be")
    calls = []
    load_maps(folder, small, names=("chiller",), progress=lambda *a: calls.append(a))
    assert calls and list((cache_root() / "maps").rglob("chiller.nc"))
    calls.clear()
    load_maps(folder, small, names=("chiller",), progress=lambda *a: calls.append(a))
    assert not calls


def test_worker_processes_give_the_serial_map(cycle_luts_dir, small, maps, monkeypatch, tmp_path):
    """Two workers, chunks of 10 nodes and an empty user cache: the workers first build the
    circuit's derived tables, one component each at a time, the largest LUT first; the map is
    the serial one."""
    from evtms.luts.cache import CACHE_DIR_ENV
    from evtms.luts.store import LutStore

    monkeypatch.setattr(maps_module, "POOL_FROM_POINTS", 0)
    monkeypatch.setattr(maps_module, "CHUNK_POINTS", 10)
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path / "cache"))
    plan = maps_module._plan("chiller", cycle_luts_dir, small)
    tasks = maps_module._table_tasks([plan, plan], cycle_luts_dir)
    assert sorted(c for _, c in tasks) == ["chiller", "compressor", "condenser"]
    sizes = [LutStore(cycle_luts_dir).lut(c).stat().st_size for _, c in tasks]
    assert sizes == sorted(sizes, reverse=True)
    par = build_map("chiller", cycle_luts_dir, small, workers=2)
    np.testing.assert_array_equal(par.values, maps["chiller"].values)
    made = {p.name.split("-")[0] for p in (tmp_path / "cache").iterdir() if "-itp-" in p.name}
    assert made == {"chiller", "compressor", "condenser"}
