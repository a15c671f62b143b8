"""Export LUTs for other tools: MATLAB/Simulink ``.mat`` and long-form CSV."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.luts.io import atomic_output

if TYPE_CHECKING:
    import xarray as xr

FORMATS = ("mat", "csv")

SIMULINK_NOTE = (
    "n-D Lookup Table block: Number of table dimensions = numel(lut.axes); "
    "Breakpoints k = lut.breakpoints.(lut.axes{k}); Table data = lut.tables.<variable>; "
    "input port k takes lut.axes{k} in the units lut.units.(lut.axes{k}). "
    "Invalid points are NaN (see lut.tables.status and lut.status_flags)."
)


def _dims(ds: xr.Dataset) -> list[str]:
    return list(ds["status"].dims)


def to_mat(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` as a MATLAB v5 ``.mat`` file holding one struct ``lut``.

    Fields: ``component``, ``fluid``, ``axes`` (cell array of axis names, table
    dimension order), ``breakpoints.<axis>`` (row vectors), ``tables.<var>``
    (N-D double arrays indexed in axis order; ``status`` as double),
    ``units.<name>``, ``long_names.<name>``, ``status_flags``,
    ``provenance.<attribute>`` and ``note`` (how to wire an n-D Lookup Table
    block). MATLAB drops trailing singleton dimensions of a table; the
    breakpoint vectors keep them.
    """
    from scipy.io import savemat

    dims = _dims(ds)
    flags = ds["status"].attrs
    lut = {
        "component": ds.attrs["component"],
        "fluid": ds.attrs["fluid"],
        "axes": np.array(dims, dtype=object),
        "breakpoints": {d: ds[d].values.astype(np.float64) for d in dims},
        "tables": {v: ds[v].transpose(*dims).values.astype(np.float64) for v in ds.data_vars},
        "units": {n: str(ds[n].attrs.get("units", "")) for n in [*dims, *ds.data_vars]},
        "long_names": {n: str(ds[n].attrs.get("long_name", "")) for n in [*dims, *ds.data_vars]},
        "status_flags": " ".join(
            f"{int(c)}={m}"
            for c, m in zip(np.atleast_1d(flags["flag_values"]), flags["flag_meanings"].split(), strict=True)
        ),
        "provenance": {k: str(v) for k, v in ds.attrs.items()},
        "note": SIMULINK_NOTE,
    }
    path = Path(path)
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        savemat(fh, {"lut": lut}, do_compression=True, oned_as="row")
    return path


def csv_columns(ds: xr.Dataset) -> list[tuple[str, str]]:
    """(name, units) of the CSV columns: the axes, then every data variable."""
    dims = _dims(ds)
    return [(n, str(ds[n].attrs.get("units", ""))) for n in [*dims, *ds.data_vars]]


def to_csv(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` in long form: one row per grid point (C order), one column per axis and variable.

    The header names each column with its units in brackets, e.g.
    ``mdot [kg s-1]``. Floats are written with 17 significant digits so the
    file reads back to the same doubles; invalid values are ``nan``.
    """
    dims = _dims(ds)
    mesh = np.meshgrid(*[ds[d].values for d in dims], indexing="ij")
    columns = [m.reshape(-1) for m in mesh] + [ds[v].transpose(*dims).values.reshape(-1) for v in ds.data_vars]
    header = ",".join(f"{n} [{u}]" for n, u in csv_columns(ds))
    fmt = ["%.17g"] * len(dims) + ["%d" if ds[v].dtype.kind == "i" else "%.17g" for v in ds.data_vars]
    path = Path(path)
    with atomic_output(path) as tmp:
        np.savetxt(tmp, np.column_stack(columns), delimiter=",", header=header, comments="", fmt=fmt)
    return path


def read_csv(path: str | Path) -> tuple[list[tuple[str, str]], np.ndarray]:
    """Read a long-form CSV back: (column names and units, data array)."""
    with open(path, encoding="utf-8") as fh:
        header = fh.readline().strip().split(",")
    names = []
    for col in header:
        name, _, unit = col.partition(" [")
        names.append((name, unit.rstrip("]")))
    return names, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
