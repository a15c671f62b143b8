"""The LUT store (evtms/luts/store.py) and map LUTs (write_map_lut, read_map_lut), without physics.

The store is the one place that knows where LUT and map files sit, when a
map is stale and where the cache is; these tests run it on tiny made-up maps
and a fake builder (the cycle maps themselves: tests/test_maps.py).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from evtms.luts.cache import CACHE_DIR_ENV
from evtms.luts.io import MapTable, write_map_lut
from evtms.luts.store import KEY_ATTR, LutStore, cache_root
from evtms.luts.validate import LutFormatError, read_lut_metadata, read_map_lut

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(CACHE_DIR_ENV, str(folder))
    return folder


def _table(scale: float = 1.0) -> MapTable:
    x = np.array([0.0, 0.5, 1.0])
    y = np.array([10.0, 20.0])
    values = scale * (x[:, None] + y[None, :])
    return MapTable(
        axes={"x": x, "y": y},
        variables={"v": values, "filled": np.array([[0, 1], [0, 0], [0, 0]]), "status": np.zeros((3, 2))},
        attributes={
            "x": {"units": "1", "long_name": "x"},
            "y": {"units": "K", "long_name": "y"},
            "v": {"units": "W", "long_name": "v"},
            "filled": {"units": "1", "long_name": "filled", "flag_values": np.array([0, 1], np.int8)},
            "status": {"units": "1", "long_name": "status", "flag_values": np.array([0, 1], np.int8)}
            | {"flag_meanings": "ok bad"},
        },
        attrs={"title": "a test map", "map_name": "m", "recipe": {"scale": scale}},
    )


# ---- the layout --------------------------------------------------------------------------------


def test_the_layout_of_a_folder(tmp_path, cache_dir):
    store = LutStore(tmp_path / "luts")
    assert store.lut("condenser") == tmp_path / "luts" / "condenser.nc"
    assert list(store.luts(["a", "b"]).values()) == [tmp_path / "luts" / "a.nc", tmp_path / "luts" / "b.nc"]
    assert store.map_file("ac") == tmp_path / "luts" / "maps" / "ac.nc"
    near, far = store.map_places("ac")
    assert near == store.map_file("ac") and far.parent.parent == cache_root() / "maps" and far.name == "ac.nc"
    assert LutStore.containing(store.lut("x")) == store
    assert LutStore.demo(tmp_path / "out", "cycle").folder == tmp_path / "out" / "luts" / "cycle"
    assert LutStore.places(tmp_path, "cycle") == (tmp_path, tmp_path / "cycle", tmp_path / "luts" / "cycle")
    store.maps_folder.mkdir(parents=True)
    for p in (store.lut("b"), store.lut("a"), store.map_file("m"), store.folder / "notes.txt"):
        p.write_text("x")
    assert store.files() == [store.lut("a"), store.lut("b"), store.map_file("m")]


def test_the_signature_and_key_follow_the_files(tmp_path):
    store = LutStore(tmp_path)
    store.lut("a").write_bytes(b"one")
    key, provenance = store.map_key({"format": 1}, ["a"])
    assert provenance == {"format": 1, "lut_files": store.signature(["a"])}
    assert provenance["lut_files"]["a"]["file"] == "a.nc" and provenance["lut_files"]["a"]["size"] == 3
    assert store.map_key({"format": 1}, ["a"])[0] == key
    assert store.map_key({"format": 2}, ["a"])[0] != key
    st = os.stat(store.lut("a"))
    os.utime(store.lut("a"), ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))  # touched: another key
    assert store.map_key({"format": 1}, ["a"])[0] != key
    with pytest.raises(OSError):
        store.signature(["missing"])


# ---- map LUTs ------------------------------------------------------------------------------------


def test_a_map_lut_round_trips_through_the_lut_writer_and_reader(tmp_path):
    import netCDF4

    table = _table()
    write_map_lut(table, tmp_path / "m.nc")
    with netCDF4.Dataset(tmp_path / "m.nc") as nc:
        assert nc.lut_kind == "map" and int(nc.lut_format_version) == 2 and nc.Conventions == "CF-1.10"
        assert nc["v"].evtms_storage == "lossless" and list(nc["v"].actual_range) == [10.0, 21.0]
        assert nc["filled"].dtype == np.int8 and nc["status"].dtype == np.int8 and nc["x"].dtype == np.float64
        assert nc["v"].filters()["zlib"] and "_FillValue" not in nc["x"].ncattrs()
    back = read_map_lut(tmp_path / "m.nc")
    assert back.name == "m" and back.attrs["recipe"] == {"scale": 1.0}
    assert list(back.axes) == ["x", "y"] and all(np.array_equal(back.axes[k], table.axes[k]) for k in table.axes)
    for k, v in table.variables.items():
        assert np.array_equal(back.variables[k], v) and back.variables[k].dtype == v.dtype
    assert back.attributes["v"]["units"] == "W"
    itp = back.interpolator()
    assert itp.variables == ("v",)
    np.testing.assert_allclose(itp([[0.25, 15.0]])["v"], [15.25], rtol=1e-15)


def test_map_luts_and_component_luts_refuse_each_other(tmp_path, small_condenser_grid, params, fluid):
    from evtms.benches import BENCHES
    from evtms.benches.sweep import run_sweep
    from evtms.luts.io import write_lut

    write_map_lut(_table(), tmp_path / "m.nc")
    with pytest.raises(LutFormatError, match=r"m.nc: holds a map LUT \(lut_kind 'map'\); a component LUT is needed"):
        read_lut_metadata(tmp_path / "m.nc")
    ds = run_sweep(BENCHES["condenser"], small_condenser_grid, params, grid_name="test", fluid=fluid)
    write_lut(ds, tmp_path / "condenser.nc")
    with pytest.raises(LutFormatError, match=r"holds a component LUT \(lut_kind 'component'\); a map LUT is needed"):
        read_map_lut(tmp_path / "condenser.nc")


def test_a_map_lut_breaking_a_rule_is_refused_in_one_line(tmp_path):
    import netCDF4

    path = write_map_lut(_table(), tmp_path / "m.nc")
    with pytest.raises(LutFormatError, match="global attribute map_key is None; expected 'k'"):
        read_map_lut(path, {KEY_ATTR: "k"})
    with netCDF4.Dataset(path, "a") as nc:
        nc["v"][0, 0] = np.nan
    with pytest.raises(LutFormatError, match="'v' is not finite at every node; a map is complete") as err:
        read_map_lut(path)
    assert "\n" not in str(err.value)
    (tmp_path / "x.nc").write_text("not netCDF")
    with pytest.raises(LutFormatError, match="not a netCDF file"):
        read_map_lut(tmp_path / "x.nc")
    with pytest.raises(ValueError, match="'v' needs units and long_name"):
        bad = _table()
        bad.attributes["v"].pop("units")
        write_map_lut(bad, tmp_path / "bad.nc")


# ---- the cache and building on demand ------------------------------------------------------------


def _builder(calls: list, scale: float = 1.0):
    def build(names):
        calls.append(list(names))
        return {n: _table(scale) for n in names}

    return build


def test_maps_are_built_once_and_read_back(tmp_path):
    store = LutStore(tmp_path)
    calls = []
    first = store.load_maps({"m": "k1", "n": "k1"}, _builder(calls))
    assert calls == [["m", "n"]] and list(first) == ["m", "n"]
    assert read_map_lut(store.map_file("m")).attrs[KEY_ATTR] == "k1"
    assert not list(store.maps_folder.glob(".*"))  # no temporary file left
    again = store.load_maps({"n": "k1", "m": "k1"}, _builder(calls))
    assert calls == [["m", "n"]] and list(again) == ["n", "m"]
    assert np.array_equal(again["m"].variables["v"], first["m"].variables["v"])
    # Another key (a LUT or the recipe changed): that map alone is rebuilt and replaces the file.
    store.load_maps({"m": "k2", "n": "k1"}, _builder(calls, 2.0))
    assert calls[-1] == ["m"] and read_map_lut(store.map_file("m")).attrs[KEY_ATTR] == "k2"
    # A damaged file, or a file of another format: rebuilt.
    store.map_file("n").write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    store.load_maps({"n": "k1"}, _builder(calls))
    assert calls[-1] == ["n"]
    # A file the caller cannot use (here: of scale 1): rebuilt.
    calls.clear()

    def scale_3_only(table):
        if table.attrs["recipe"]["scale"] != 3.0:
            raise ValueError("not usable")
        return table

    got = store.load_maps({"n": "k1"}, _builder(calls, 3.0), convert=scale_3_only)
    assert calls == [["n"]] and got["n"].attrs["recipe"] == {"scale": 3.0}


def test_an_unwritable_folder_falls_back_to_the_user_cache_and_no_cache_writes_nothing(
    tmp_path, monkeypatch, cache_dir
):
    store = LutStore(tmp_path / "luts")
    store.folder.mkdir()
    store.maps_folder.write_text("a file where the maps folder would be")
    calls = []
    store.load_maps({"m": "k"}, _builder(calls))
    assert store.map_fallback("m").is_file() and calls == [["m"]]
    store.load_maps({"m": "k"}, _builder(calls))
    assert calls == [["m"]]
    # Neither place can be written: the map is returned unsaved.
    (tmp_path / "taken").write_text("a file")
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path / "taken" / "cache"))
    assert np.array_equal(store.load_maps({"m": "k"}, _builder(calls))["m"].variables["v"], _table().variables["v"])
    monkeypatch.setenv(CACHE_DIR_ENV, str(cache_dir))
    monkeypatch.setenv("EVTMS_NO_CACHE", "1")
    other = LutStore(tmp_path / "other")
    other.folder.mkdir()
    other.load_maps({"m": "k"}, _builder(calls))
    assert not other.maps_folder.exists()


# ---- one layout ------------------------------------------------------------------------------------

#: How a LUT folder's layout is spelled: a file joined as ``<name>.nc`` to a folder, the maps folder,
#: the demo's luts folder, a listing of a folder's LUT files.
_LAYOUT = re.compile(r'/ f"\{[^}]+\}\.nc"|/ "maps"|"luts" /|/ "luts"|\("luts", |glob\("\*\.nc"\)')


def test_the_folder_layout_is_spelled_only_in_the_store():
    found = []
    for path in sorted((ROOT / "evtms").rglob("*.py")):
        if path == ROOT / "evtms" / "luts" / "store.py":
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if _LAYOUT.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
