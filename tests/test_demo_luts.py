"""``evtms demo`` writes the same LUTs bit for bit: twice over, and as ``evtms bench`` writes them.

The demo's LUT step (:func:`evtms.workflows.demo.ensure_luts`: one process per
LUT, or a grid that outweighs the others together in chunks over worker
processes) runs on two values of each axis of both of its presets (eight of
the evaporator's mass flow on the cycle preset: that grid is spread, as the
demo spreads the cycle evaporator's), in small chunks, twice into two folders;
the bench workflow (``evtms bench all``, in this process, on the same chunks)
writes the same grids into a third.
Every dimension, variable (its raw stored bytes: no masking or scaling, dtype,
chunking and filters) and attribute is the same in the three; of the global
attributes only the time stamp (``created``, and the ``history`` it begins)
differs.
"""

from __future__ import annotations

from pathlib import Path

import netCDF4
import numpy as np
import pytest

import evtms.benches.chunked as chunked
from evtms.benches import BENCHES
from evtms.benches.parameters import Parameters
from evtms.workflows import demo
from evtms.workflows.bench import BenchRequest, run_bench
from evtms.workflows.demo import GRIDS, ensure_luts

#: The demo's presets, each on two values of every axis (a fixed input keeps its one value).
TINY = {grid: f"tiny-{grid}" for grid in GRIDS}
#: Points per chunk of the sweeps here (several chunks per LUT; the chunks set the files' netCDF chunking).
CHUNK_POINTS = 16


@pytest.fixture()
def tiny_presets(monkeypatch):
    for name, bench in BENCHES.items():
        for grid, tiny in TINY.items():
            preset = {k: tuple(v)[:2] for k, v in bench.presets[grid].items()}
            if name == "evaporator" and grid == "cycle":
                preset["mdot"] = tuple(bench.presets[grid]["mdot"])[:8]
            monkeypatch.setitem(bench.presets, tiny, preset)
    spread = TINY["cycle"]
    points = {c: demo._grid_points(c, spread) for c in BENCHES}
    assert points["evaporator"] > sum(points.values()) - points["evaporator"]  # ensure_luts spreads it


def _raw(value):
    """An attribute as it is stored: text, or its dtype and bytes (a NaN equals itself)."""
    if isinstance(value, str):
        return value
    value = np.asarray(value)
    return value.dtype.str, value.shape, value.tobytes()


def _contents(path: Path) -> dict:
    """Everything the file holds, raw; the time stamp of the global attributes apart."""
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        created = attrs.pop("created")
        assert attrs["history"].startswith(created)
        attrs["history"] = attrs["history"].removeprefix(created)
        out = {
            "dimensions": [(d.name, d.size) for d in nc.dimensions.values()],
            "attributes": {k: _raw(v) for k, v in attrs.items()},
        }
        for name, var in nc.variables.items():
            out[name] = {
                "dtype": str(var.dtype),
                "dimensions": var.dimensions,
                "chunking": var.chunking(),
                "filters": var.filters(),
                "attributes": {k: _raw(var.getncattr(k)) for k in var.ncattrs()},
                "bytes": np.ascontiguousarray(var[:]).tobytes(),
            }
        return out


def test_the_demo_writes_the_same_luts_bit_for_bit(tmp_path, tiny_presets):
    params = Parameters()
    chunked._fluid_for(params)  # CoolProp loaded here once: the demo's forked processes start with it
    runs = {}
    sweep = chunked.sweep_to_file
    with pytest.MonkeyPatch.context() as m:  # forked into the demo's processes too
        m.setattr(chunked, "sweep_to_file", lambda *a, **k: sweep(*a, **{**k, "chunk_points": CHUNK_POINTS}))
        for name, force in (("first", False), ("again", True)):
            for grid, tiny in TINY.items():
                result = ensure_luts(tmp_path / name / grid, tiny, params, force=force, workers=2)
                assert sorted(result.computed) == sorted(f"{tiny}/{c}" for c in BENCHES) and not result.reused
            runs[name] = tmp_path / name
    for grid, tiny in TINY.items():
        run_bench(BenchRequest(list(BENCHES), tiny, output=tmp_path / "bench" / grid, chunk_points=CHUNK_POINTS))
    runs["bench"] = tmp_path / "bench"
    for grid in TINY:
        for component in BENCHES:
            first = _contents(runs["first"] / grid / f"{component}.nc")
            assert first["attributes"]["grid"] == TINY[grid] and len(first) > 2
            for name in ("again", "bench"):
                other = _contents(runs[name] / grid / f"{component}.nc")
                assert list(other) == list(first), (name, grid, component)
                for key in first:
                    assert other[key] == first[key], (name, grid, component, key)
