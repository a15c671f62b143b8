"""The simulation output file (netCDF-4) and the ``--json`` summary.

Format (``docs/simulation-format.md``): dimension ``time`` (records at
``t_k = k dt_out``; states at the instant, powers the mean over
``(t_k-1, t_k]``, NaN at k = 0), float64 variables with ``units`` and
``long_name``, ``mode`` (int8, CF ``flag_values``/``flag_meanings``),
``flags`` (uint16 bit field, CF ``flag_masks``/``flag_meanings``). Several
ambient temperatures in one call add a leading dimension ``T_amb``; a run
that stopped early (SOC at its floor) is padded with NaN (``mode`` -1).
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms.system.loop import FLAG_NAMES, MODE_NAMES
from evtms.system.simulate import RECORD_VARIABLES, SimulationResult


def to_dataset(results: list[SimulationResult]):
    """The runs as one xarray Dataset (a ``T_amb`` dimension when there are several)."""
    import xarray as xr

    several = len(results) > 1
    n = max(r.records["time"].size for r in results)
    longest = max(results, key=lambda r: r.records["time"].size)
    time = longest.records["time"]

    def stack(values: list[np.ndarray], fill) -> np.ndarray:
        out = np.full((len(values), n), fill, dtype=np.asarray(values[0]).dtype)
        for i, v in enumerate(values):
            out[i, : v.size] = v
        return out if several else out[0]

    dims = ("T_amb", "time") if several else ("time",)
    data = {}
    for name, (units, long_name) in RECORD_VARIABLES.items():
        data[name] = xr.Variable(
            dims, stack([r.records[name] for r in results], np.nan), {"units": units, "long_name": long_name}
        )
    data["mode"] = xr.Variable(
        dims,
        stack([r.mode for r in results], -1).astype(np.int8),
        {
            "long_name": "operating mode",
            "flag_values": np.arange(len(MODE_NAMES), dtype=np.int8),
            "flag_meanings": " ".join(m.replace("+", "_plus_") for m in MODE_NAMES),
        },
    )
    data["flags"] = xr.Variable(
        dims,
        stack([r.flags for r in results], 0).astype(np.uint16),
        {
            "long_name": "events during the record's interval",
            "flag_masks": np.array([1 << i for i in range(len(FLAG_NAMES))], np.uint16),
            "flag_meanings": " ".join(FLAG_NAMES),
        },
    )
    coords = {"time": xr.Variable("time", time, {"units": "s", "long_name": "time since the start of the cycle"})}
    if several:
        coords["T_amb"] = xr.Variable(
            "T_amb", np.array([r.attrs["T_amb"] for r in results]), {"units": "K", "long_name": "ambient temperature"}
        )
    created = dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    first = results[0].attrs
    attrs = {
        "Conventions": "CF-1.10",
        "title": "evtms system simulation",
        "evtms_version": __version__,
        "created": created,
        **{k: v for k, v in first.items() if k not in ("T_amb", "termination", "ledgers", "range")},
        "termination": json.dumps([r.attrs["termination"] for r in results]) if several else first["termination"],
        "ledgers": json.dumps([r.ledgers for r in results]) if several else first["ledgers"],
        "summary": json.dumps([r.summary for r in results] if several else results[0].summary),
    }
    if "range" in first:  # a depletion test's figures (evtms.system.range_test), per run
        attrs["range"] = json.dumps([json.loads(r.attrs["range"]) for r in results]) if several else first["range"]
    if not several:
        attrs["T_amb"] = first["T_amb"]
    return xr.Dataset(data, coords=coords, attrs=attrs)


def write_simulation(results: list[SimulationResult], path: str | Path) -> Path:
    """Write the runs to ``path`` atomically (a concurrent run never sees a partial file)."""
    from evtms.luts.io import atomic_output

    ds = to_dataset(results)
    encoding = {k: {"zlib": True, "complevel": 1} for k in ds.data_vars}
    with atomic_output(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=encoding)
    return Path(path)
