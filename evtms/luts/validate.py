"""Open a LUT file and check it against the format spec, rule by rule."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.luts.schema import (
    ALTERNATE_AXES,
    AXES,
    COMPONENT_AXES,
    COMPONENT_VARIABLES,
    FORMAT_VERSION,
    REQUIRED_GLOBAL_ATTRS,
    VARIABLES,
)

if TYPE_CHECKING:
    import xarray as xr

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_CLASSIC_SIGNATURE = b"CDF"
#: Axes a grid may add to a component's standard ones.
EXTRA_AXES = {
    "compressor": ("p_in",),
    "condenser": ("T_air_in", "RH_air_in"),
    "evaporator": ("T_air_in", "RH_air_in"),
}


class LutFormatError(EvtmsInputError):
    """A file is not a valid evtms LUT; the message names the file and the first broken rule."""


def open_lut(path: str | Path) -> xr.Dataset:
    """Open a LUT file, check it against ``lut-format.md`` and return it in memory.

    Parameters
    ----------
    path : str or Path
        A netCDF-4 file written by evtms (or by anyone following the format).

    Returns
    -------
    xarray.Dataset
        The file's contents, loaded (the file is closed again).

    Raises
    ------
    LutFormatError
        The file is missing, empty, not netCDF, truncated, or breaks a rule of
        the format; the one-line message names the file and the first rule.
    """
    import xarray as xr

    path = Path(path)
    name = str(path)
    if not path.is_file():
        raise LutFormatError(f"{name}: no such file")
    size = path.stat().st_size
    if size == 0:
        raise LutFormatError(f"{name}: the file is empty")
    with open(path, "rb") as fh:
        head = fh.read(8)
    if not (head.startswith(_HDF5_SIGNATURE) or head.startswith(_CLASSIC_SIGNATURE)):
        raise LutFormatError(f"{name}: not a netCDF file")
    try:
        with xr.open_dataset(path, engine="netcdf4", mask_and_scale=True) as ds:
            ds = ds.load()
    except Exception as exc:  # HDF5 raises OSError or RuntimeError with multi-line text
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise LutFormatError(f"{name}: the file is truncated or corrupt ({first})") from None
    validate_lut(ds, name)
    return ds


def validate_lut(ds: xr.Dataset, name: str = "dataset") -> None:
    """Raise :class:`LutFormatError` at the first rule of the LUT format ``ds`` breaks."""

    def fail(rule: str) -> None:
        raise LutFormatError(f"{name}: {rule}")

    version = ds.attrs.get("lut_format_version")
    if version is None:
        fail("global attribute lut_format_version is missing (not an evtms LUT file)")
    if int(version) != FORMAT_VERSION:
        fail(f"LUT format version {int(version)} is not supported; this evtms reads version {FORMAT_VERSION}")
    for attr in REQUIRED_GLOBAL_ATTRS:
        if attr not in ds.attrs:
            fail(f"global attribute {attr!r} is missing")
    component = ds.attrs["component"]
    if component not in COMPONENT_AXES:
        fail(f"component {component!r} is unknown; allowed: {', '.join(COMPONENT_AXES)}")
    # Axes: the component's standard axes in order (T_in may be h_in), then allowed extras.
    dims = list(ds.dims)
    standard = COMPONENT_AXES[component]
    expected = [d if d in dims else ALTERNATE_AXES.get(d, d) for d in standard]
    if dims[: len(standard)] != expected:
        fail(f"axes are {', '.join(dims)}; expected {', '.join(expected)} in that order")
    for extra in dims[len(standard) :]:
        if extra not in EXTRA_AXES.get(component, ()):
            fail(f"axis {extra!r} is not allowed for {component}")
    for d in dims:
        if d not in ds.coords:
            fail(f"axis {d!r} has no coordinate variable")
        coord = ds[d]
        values = coord.values
        if coord.ndim != 1 or values.dtype != np.float64:
            fail(f"axis {d!r} must be a 1-D float64 coordinate")
        if values.size > 1 and not np.all(np.diff(values) > 0):
            fail(f"axis {d!r} is not strictly increasing")
        if not np.all(np.isfinite(values)):
            fail(f"axis {d!r} has non-finite values")
        units = coord.attrs.get("units")
        if units != AXES[d].units:
            fail(f"axis {d!r} has units {units!r}; expected {AXES[d].units!r}")
        if "long_name" not in coord.attrs:
            fail(f"axis {d!r} has no long_name")
    # Variables.
    for var in COMPONENT_VARIABLES[component]:
        if var == "p_in" or var in dims:
            continue
        if var not in ds.data_vars:
            fail(f"required variable {var!r} is missing")
    for var, da in ds.data_vars.items():
        if list(da.dims) != dims:
            fail(f"variable {var!r} has dimensions {', '.join(da.dims)}; expected {', '.join(dims)}")
        units = da.attrs.get("units")
        if var in VARIABLES and units != VARIABLES[var][0]:
            fail(f"variable {var!r} has units {units!r}; expected {VARIABLES[var][0]!r}")
        if units is None or "long_name" not in da.attrs:
            fail(f"variable {var!r} needs units and long_name")
    status = ds["status"]
    if status.dtype != np.int8:
        fail(f"status must be int8, not {status.dtype}")
    flags = status.attrs.get("flag_values")
    meanings = status.attrs.get("flag_meanings")
    if flags is None or meanings is None:
        fail("status needs flag_values and flag_meanings")
    flags = np.atleast_1d(flags)
    if len(flags) != len(str(meanings).split()) or 0 not in flags:
        fail("status flag_values and flag_meanings must pair up and include 0 = valid")
    unknown = np.setdiff1d(np.unique(status.values), flags)
    if unknown.size:
        fail(f"status holds code {int(unknown[0])} that flag_values does not define")
    valid = np.isin(status.values, valid_flags(ds))
    for var, da in ds.data_vars.items():
        if var == "status" or da.dtype.kind != "f":
            continue
        if not np.all(np.isfinite(da.values[valid])):
            fail(f"variable {var!r} is not finite at a point whose status is valid")
        if not np.all(np.isnan(da.values[~valid])):
            fail(f"variable {var!r} holds a number at a point whose status is invalid")


def valid_flags(ds: xr.Dataset) -> np.ndarray:
    """Status codes that mark valid points (``valid_flag_values``, else just 0)."""
    return np.atleast_1d(ds["status"].attrs.get("valid_flag_values", [0]))
