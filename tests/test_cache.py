"""The cache of arrays derived from LUT files (evtms/luts/cache.py) and the cycle's use of it."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from evtms.luts.cache import CACHE_DIR_ENV, cached_arrays


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(CACHE_DIR_ENV, str(folder))
    return folder


def _entries(folder):
    """The cache's entries (not its build locks, kept in ``.locks``)."""
    return sorted(p.name for p in folder.iterdir() if p.name != ".locks") if folder.exists() else []


def test_second_call_reads_the_cache_memory_mapped(tmp_path):
    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    calls = []

    def build():
        calls.append(1)
        return {"x": np.arange(5.0)}, {"note": "built"}

    a, info_a = cached_arrays("thing", [src], {"v": 1}, build)
    b, info_b = cached_arrays("thing", [src], {"v": 1}, build)
    assert len(calls) == 1
    assert isinstance(b["x"], np.memmap) and not b["x"].flags.writeable
    assert np.array_equal(a["x"], b["x"]) and info_a == info_b == {"note": "built"}


def test_a_changed_source_or_recipe_rebuilds_and_drops_the_stale_entry(tmp_path, cache_dir):
    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    values = iter([1.0, 2.0, 3.0])

    def build():
        return {"x": np.array([next(values)])}, {}

    assert cached_arrays("thing", [src], {"v": 1}, build)[0]["x"][0] == 1.0
    time.sleep(0.01)
    src.write_bytes(b"two!")  # rewritten: new size and modification time
    assert cached_arrays("thing", [src], {"v": 1}, build)[0]["x"][0] == 2.0
    assert len(_entries(cache_dir)) == 1
    assert cached_arrays("thing", [src], {"v": 2}, build)[0]["x"][0] == 3.0
    assert len(_entries(cache_dir)) == 1
    assert len(list((cache_dir / ".locks").iterdir())) == 1  # the stale entries' locks went with them


def test_a_hard_link_finds_the_entry_and_a_copy_does_not(tmp_path, cache_dir):
    """A hard link is the same file (inode, size, time): its path reuses the entry. A copy with the
    same bytes and modification time is another file: it is built anew."""
    import os
    import shutil

    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    (tmp_path / "linked").mkdir()
    link = tmp_path / "linked" / "a.nc"
    os.link(src, link)
    copy = tmp_path / "copy.nc"
    shutil.copy2(src, copy)
    calls = []

    def build():
        calls.append(1)
        return {"x": np.array([float(len(calls))])}, {}

    assert cached_arrays("thing", [src], {"v": 1}, build)[0]["x"][0] == 1.0
    assert cached_arrays("thing", [link], {"v": 1}, build)[0]["x"][0] == 1.0
    assert len(calls) == 1
    assert cached_arrays("thing", [copy], {"v": 1}, build)[0]["x"][0] == 2.0
    assert len(calls) == 2


def test_an_unwritable_cache_folder_builds_in_memory(tmp_path, monkeypatch):
    """Where the cache cannot be written (here its parent is a file; a read-only folder fails
    alike, also for root), the arrays are built and returned, nothing raised."""
    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    (tmp_path / "taken").write_text("a file")
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path / "taken" / "cache"))
    arrays, _ = cached_arrays("thing", [src], {}, lambda: ({"x": np.ones(3)}, {}))
    assert np.array_equal(arrays["x"], np.ones(3))


def test_disabled_cache_writes_nothing(tmp_path, monkeypatch, cache_dir):
    monkeypatch.setenv("EVTMS_NO_CACHE", "1")
    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    cached_arrays("thing", [src], {}, lambda: ({"x": np.ones(3)}, {}))
    assert not cache_dir.exists()


@pytest.mark.parametrize("through_links", [False, True])
def test_concurrent_builders_build_once_all_get_whole_arrays_and_one_entry_stays(tmp_path, cache_dir, through_links):
    """Six builders of one entry at once (through one path, or through hard links to one file, as
    the demo and the tests reach one LUT): the first builds, the others wait for its entry."""
    import os

    src = tmp_path / "a.nc"
    src.write_bytes(b"one")
    paths = [src] * 6
    if through_links:
        paths = [tmp_path / f"link{i}.nc" for i in range(6)]
        for p in paths:
            os.link(src, p)
    start = threading.Barrier(6)
    results, errors, builds = [], [], []

    def build():
        builds.append(1)
        time.sleep(0.05)
        return {"x": np.arange(100_000.0)}, {}

    def worker(path):
        try:
            start.wait()
            results.append(cached_arrays("thing", [path], {}, build)[0]["x"])
        except Exception as exc:  # noqa: BLE001 - the test reports any failure
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(p,)) for p in paths]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(results) == 6 and all(np.array_equal(r, np.arange(100_000.0)) for r in results)
    assert len(builds) == 1
    assert len(_entries(cache_dir)) == 1  # no temporary folder left behind


def test_cycle_on_cached_tables_is_identical_and_needs_no_coolprop(cycle_luts_dir, tmp_path, cache_dir):
    """A second LUT cycle run reads the cache: the same numbers, and CoolProp is never imported;
    the LUT folder is left as it was."""
    import shutil

    folder = tmp_path / "luts"
    folder.mkdir()
    for name in ("condenser", "evaporator", "compressor", "expansion_valve"):
        shutil.copy(cycle_luts_dir / f"{name}.nc", folder / f"{name}.nc")
    code = (
        "import sys, json; from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle;"
        f"r = run_cycle(OperatingPoints(speed=[0.4, 0.8]), load_cycle_luts({str(folder)!r}));"
        "print(json.dumps({'p_A': r['p_A'].tolist(), 'COP': r['COP'].tolist(),"
        " 'coolprop': 'CoolProp' in sys.modules}))"
    )
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True) for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in folder.iterdir()) == [
        "compressor.nc",
        "condenser.nc",
        "evaporator.nc",
        "expansion_valve.nc",
    ]
    assert _entries(cache_dir)
    import json

    first, second = (json.loads(r.stdout) for r in runs)
    assert first["coolprop"] is True  # the first run built the saturation curve and the valve area
    assert second["coolprop"] is False
    assert first["p_A"] == second["p_A"] and first["COP"] == second["COP"]


def test_tagged_values_come_back_with_their_types_shapes_and_bits():
    import json

    from evtms.luts.cache import tagged, untagged

    value = {
        "a": np.array([[0.1, np.nan], [-np.inf, 1e-300]]),
        "flags": np.array([0, 5, 7], np.int8),
        "s": np.float64(1 / 3),
        "i": np.int32(-4),
        "u": np.array(["x", "yz"]),
        "dtype": np.dtype("<f4"),
        "t": (1, "two", (3.5,)),
        7: [None, True, "text", 2**70],
    }
    back = untagged(json.loads(json.dumps(tagged(value))))
    assert list(back) == list(value)
    for k, v in value.items():
        if isinstance(v, np.ndarray):
            assert back[k].dtype == v.dtype and back[k].shape == v.shape
            assert back[k].tobytes() == v.tobytes()
        else:
            assert type(back[k]) is type(v) and back[k] == v, k
    with pytest.raises(TypeError):
        tagged({"x": object()})


def test_a_lut_header_is_checked_once_per_file_version(cycle_luts_dir, tmp_path, monkeypatch):
    """A second read of an unchanged LUT's header comes from the cache, equal to the first and
    without opening the file; a rewritten file is read and checked again, and a file that breaks
    a rule is refused every time (never cached)."""
    import dataclasses
    import shutil

    import evtms.luts.validate as validate

    path = tmp_path / "compressor.nc"
    shutil.copy2(cycle_luts_dir / "compressor.nc", path)
    first = validate.read_lut_metadata(path, "compressor")
    real = validate._netcdf

    def refused(*args, **kwargs):
        raise AssertionError("the file was opened")

    monkeypatch.setattr(validate, "_netcdf", refused)
    again = validate.read_lut_metadata(path, "compressor")
    for f in dataclasses.fields(first):
        a, b = getattr(first, f.name), getattr(again, f.name)
        if f.name == "axes":
            assert all(a[d].dtype == b[d].dtype and np.array_equal(a[d], b[d]) for d in a) and list(a) == list(b)
        elif f.name == "variables":
            assert list(a) == list(b)
            for v in a:
                assert list(a[v]) == list(b[v])
                assert all(np.array_equal(a[v][k], b[v][k]) and type(a[v][k]) is type(b[v][k]) for k in a[v])
        else:
            assert a == b, f.name
    monkeypatch.setattr(validate, "_netcdf", real)
    with pytest.raises(validate.LutFormatError, match="the evaporator LUT is needed"):
        validate.read_lut_metadata(path, "evaporator")  # another question about the file

    time.sleep(0.01)
    shutil.copy2(cycle_luts_dir / "condenser.nc", path)  # the same path, another file
    with pytest.raises(validate.LutFormatError, match="holds the condenser LUT"):
        validate.read_lut_metadata(path, "compressor")
    with pytest.raises(validate.LutFormatError, match="holds the condenser LUT"):
        validate.read_lut_metadata(path, "compressor")
