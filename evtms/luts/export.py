"""Export LUTs for other tools: MATLAB/Simulink ``.mat`` and long-form CSV."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.luts.io import atomic_output, squeeze_fixed_inputs
from evtms.luts.schema import AXES
from evtms.luts.validate import fixed_inputs, status_flags

if TYPE_CHECKING:
    import xarray as xr

FORMATS = ("mat", "csv")

SIMULINK_NOTE = (
    "n-D Lookup Table block: Number of table dimensions = numel(lut.axes); "
    "Breakpoints k = lut.breakpoints.(lut.axes{k}); Table data = lut.tables.<variable>; "
    "input port k takes lut.axes{k} in the units lut.units.(lut.axes{k}). "
    "Every axis has two or more breakpoints (no singleton dimension); an input the LUT was "
    "made at one value of is not an axis but lut.fixed_inputs.<name>.value in lut.fixed_inputs.<name>.units. "
    "Invalid points are NaN (see lut.tables.status and lut.status_flags)."
)


def _dims(ds: xr.Dataset) -> list[str]:
    return list(ds["status"].dims)


def _fixed_struct(ds: xr.Dataset) -> dict[str, dict]:
    return {k: {"value": v, "units": AXES[k].units} for k, v in fixed_inputs(ds).items()}


def to_mat(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` as a MATLAB v5 ``.mat`` file holding one struct ``lut``.

    Fields: ``component``, ``fluid``, ``axes`` (cell array of axis names, table
    dimension order), ``breakpoints.<axis>`` (row vectors), ``tables.<var>``
    (N-D double arrays indexed in axis order; ``status`` as double),
    ``fixed_inputs.<name>.value`` and ``.units`` (inputs of one value: not
    axes), ``units.<name>``, ``long_names.<name>``, ``status_flags``,
    ``provenance.<attribute>`` and ``note`` (how to wire an n-D Lookup Table
    block). A length-1 axis of ``ds`` is dropped from the tables and recorded
    in ``fixed_inputs``, so no table has a singleton dimension (MATLAB would
    drop a trailing one, and an n-D Lookup Table needs two breakpoints per
    dimension).
    """
    from scipy.io import savemat

    ds = squeeze_fixed_inputs(ds)
    dims = _dims(ds)
    lut = {
        "component": ds.attrs["component"],
        "fluid": ds.attrs["fluid"],
        "axes": np.array(dims, dtype=object),
        "breakpoints": {d: ds[d].values.astype(np.float64) for d in dims},
        "tables": {v: ds[v].transpose(*dims).values.astype(np.float64) for v in ds.data_vars},
        "fixed_inputs": _fixed_struct(ds),
        "units": {n: str(ds[n].attrs.get("units", "")) for n in [*dims, *ds.data_vars]},
        "long_names": {n: str(ds[n].attrs.get("long_name", "")) for n in [*dims, *ds.data_vars]},
        "status_flags": " ".join(f"{c}={m}" for c, m in status_flags(ds["status"].attrs).items()),
        "provenance": {k: str(v) for k, v in ds.attrs.items()},
        "note": SIMULINK_NOTE,
    }
    path = Path(path)
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        savemat(fh, {"lut": lut}, do_compression=True, oned_as="row")
    return path


def csv_columns(ds: xr.Dataset) -> list[tuple[str, str]]:
    """(name, units) of the CSV columns: the axes, the fixed inputs, then every data variable."""
    dims = _dims(ds)
    fixed = [(k, AXES[k].units) for k in fixed_inputs(ds)]
    return (
        [(n, str(ds[n].attrs.get("units", ""))) for n in dims]
        + fixed
        + [(n, str(ds[n].attrs.get("units", ""))) for n in ds.data_vars]
    )


def to_csv(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` in long form: one row per grid point (C order), one column per input and variable.

    The columns are the axes, the fixed inputs (one value repeated: every row
    is a whole operating point) and the data variables. The header names each
    column with its units in brackets, e.g. ``mdot [kg s-1]``. Floats are
    written with 17 significant digits so the file reads back to the same
    doubles; invalid values are ``nan``.
    """
    ds = squeeze_fixed_inputs(ds)
    dims = _dims(ds)
    fixed = fixed_inputs(ds)
    mesh = np.meshgrid(*[ds[d].values for d in dims], indexing="ij")
    points = int(np.prod([ds.sizes[d] for d in dims]))
    columns = (
        [m.reshape(-1) for m in mesh]
        + [np.full(points, v) for v in fixed.values()]
        + [ds[v].transpose(*dims).values.reshape(-1) for v in ds.data_vars]
    )
    header = ",".join(f"{n} [{u}]" for n, u in csv_columns(ds))
    fmt = ["%.17g"] * (len(dims) + len(fixed)) + ["%d" if ds[v].dtype.kind == "i" else "%.17g" for v in ds.data_vars]
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
