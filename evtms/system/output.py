"""The simulation output file (netCDF-4) and the ``--json`` summary.

Format (``docs/simulation-format.md``): dimension ``time`` (records at
``t_k = k dt_out``; states at the instant, powers the mean over
``(t_k-1, t_k]``, NaN at k = 0), float64 variables with ``units`` and
``long_name``, ``mode`` (int8, CF ``flag_values``/``flag_meanings``),
``flags`` (uint16 bit field, CF ``flag_masks``/``flag_meanings``). Several
ambient temperatures in one call add a leading dimension ``T_amb``; a run
that stopped early (SOC at its floor) is padded with NaN (``mode`` -1).

The file is described once (:func:`file_content`) and either written by
netCDF4 directly (:func:`write_simulation`, what ``evtms simulate`` runs:
importing xarray and building its dataset would cost a short run more than the
simulation) or turned into an xarray Dataset (:func:`to_dataset`, for figures
and notebooks). The writer makes the file xarray's ``to_netcdf`` made from
that Dataset: float variables carry ``_FillValue`` NaN, the data variables are
zlib-compressed (level 1, shuffled), the coordinates are stored contiguous.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms.system.loop import FLAG_NAMES, MODE_NAMES
from evtms.system.simulate import RECORD_VARIABLES, SimulationResult

#: zlib level of the data variables (level 1: most of the size saving, a fraction of the time of level 4).
COMPLEVEL = 1


@dataclass
class FileVariable:
    """One variable of the output file.

    Attributes
    ----------
    dims : tuple of str
        Its dimensions.
    data : numpy.ndarray
        Its values, in the type stored.
    attrs : dict
        Its attributes (``units``, ``long_name``, CF flags).
    coordinate : bool
        A coordinate (``time``, ``T_amb``): stored uncompressed.
    """

    dims: tuple[str, ...]
    data: np.ndarray
    attrs: dict
    coordinate: bool = False


@dataclass
class FileContent:
    """What the output file holds: variables in file order (data, then coordinates) and global attributes."""

    variables: dict[str, FileVariable]
    attrs: dict


def file_content(results: list[SimulationResult]) -> FileContent:
    """The runs as the output file holds them (a ``T_amb`` dimension when there are several)."""
    several = len(results) > 1
    n = max(r.records["time"].size for r in results)
    longest = max(results, key=lambda r: r.records["time"].size)

    def stack(values: list[np.ndarray], fill) -> np.ndarray:
        out = np.full((len(values), n), fill, dtype=np.asarray(values[0]).dtype)
        for i, v in enumerate(values):
            out[i, : v.size] = v
        return out if several else out[0]

    dims = ("T_amb", "time") if several else ("time",)
    variables = {
        name: FileVariable(dims, stack([r.records[name] for r in results], np.nan), {"units": units, "long_name": ln})
        for name, (units, ln) in RECORD_VARIABLES.items()
    }
    variables["mode"] = FileVariable(
        dims,
        stack([r.mode for r in results], -1).astype(np.int8),
        {
            "long_name": "operating mode",
            "flag_values": np.arange(len(MODE_NAMES), dtype=np.int8),
            "flag_meanings": " ".join(m.replace("+", "_plus_") for m in MODE_NAMES),
        },
    )
    variables["flags"] = FileVariable(
        dims,
        stack([r.flags for r in results], 0).astype(np.uint16),
        {
            "long_name": "events during the record's interval",
            "flag_masks": np.array([1 << i for i in range(len(FLAG_NAMES))], np.uint16),
            "flag_meanings": " ".join(FLAG_NAMES),
        },
    )
    time_attrs = {"units": "s", "long_name": "time since the start of the cycle"}
    variables["time"] = FileVariable(("time",), longest.records["time"], time_attrs, coordinate=True)
    if several:
        ambients = np.array([r.attrs["T_amb"] for r in results])
        T_attrs = {"units": "K", "long_name": "ambient temperature"}  # noqa: N806 - the variable's name
        variables["T_amb"] = FileVariable(("T_amb",), ambients, T_attrs, coordinate=True)
    return FileContent(variables, _global_attrs(results))


def _global_attrs(results: list[SimulationResult]) -> dict:
    """The file's global attributes: conventions, provenance, the run's description, ledgers and summary."""
    several = len(results) > 1
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
    # The cabin heating per run (`evtms simulate --heating a,b` runs each at every ambient): one name, or a
    # JSON list along T_amb where the runs differ; `parameters` is the first run's.
    heating = [r.summary.get("heating") for r in results]
    if len(set(heating)) > 1:
        attrs["heating"] = json.dumps(heating)
    elif heating[0] is not None:
        attrs["heating"] = str(heating[0])
    return attrs


def to_dataset(results: list[SimulationResult]):
    """The runs as one xarray Dataset (a ``T_amb`` dimension when there are several)."""
    import xarray as xr

    content = file_content(results)
    data, coords = {}, {}
    for name, v in content.variables.items():
        (coords if v.coordinate else data)[name] = xr.Variable(v.dims, v.data, v.attrs)
    return xr.Dataset(data, coords=coords, attrs=content.attrs)


def write_simulation(results: list[SimulationResult], path: str | Path) -> Path:
    """Write the runs to ``path`` atomically (a concurrent run never sees a partial file)."""
    from evtms.luts.io import atomic_output

    content = file_content(results)
    with atomic_output(path) as tmp:
        _write_netcdf4(content, tmp)
    return Path(path)


def _write_netcdf4(content: FileContent, path: Path) -> None:
    """``content`` as a netCDF-4 file, with the calls xarray's netCDF4 backend makes for the same Dataset."""
    import netCDF4

    with netCDF4.Dataset(path, "w", format="NETCDF4", clobber=True) as nc:
        for key, value in content.attrs.items():
            nc.setncattr(key, value)
        for v in content.variables.values():  # dimensions in the order the variables name them
            for d, size in zip(v.dims, v.data.shape, strict=True):
                if d not in nc.dimensions:
                    nc.createDimension(d, size)
        for name, v in content.variables.items():
            var = nc.createVariable(
                name,
                v.data.dtype,
                v.dims,
                zlib=not v.coordinate,
                complevel=COMPLEVEL if not v.coordinate else 4,
                shuffle=True,
                fletcher32=False,
                contiguous=False,
                chunksizes=None,
                endian="native",
                least_significant_digit=None,
                fill_value=np.nan if v.data.dtype.kind == "f" else None,
            )
            var.setncatts(v.attrs)
            var.set_auto_maskandscale(False)  # the values as they are: NaN stays NaN, no masking
            var[...] = v.data
