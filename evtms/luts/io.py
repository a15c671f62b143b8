"""Build, write and read LUT datasets per ``shared/spec/lut-format.md``."""

from __future__ import annotations

import contextlib
import datetime as _dt
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms import __version__
from evtms.luts.schema import AXES, CONVENTIONS, FORMAT_VERSION, VARIABLES

if TYPE_CHECKING:  # xarray is imported lazily: it costs ~0.5 s
    import xarray as xr


def variable_attributes(name: str, flags: dict[int, str], valid_flags: tuple[int, ...]) -> dict:
    """CF attributes of a LUT data variable (``status`` gets its flags)."""
    units, long_name = VARIABLES[name]
    attrs: dict = {"units": units, "long_name": long_name}
    if name == "status":
        codes = sorted(flags)
        attrs["flag_values"] = np.array(codes, np.int8)
        attrs["flag_meanings"] = " ".join(flags[c] for c in codes)
        attrs["valid_flag_values"] = np.array(valid_flags, np.int8)
    return attrs


def axis_attributes(name: str) -> dict:
    """CF attributes of a LUT axis (coordinate variable)."""
    spec = AXES[name]
    return {"units": spec.units, "long_name": spec.long_name}


def global_attributes(
    *,
    component: str,
    title: str,
    parameters_json: str,
    environment_json: str,
    grid_name: str,
    fluid: str,
    coolprop_version: str,
    history: str = "",
) -> dict:
    """The LUT format's global attributes, stamped with the current UTC time."""
    created = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "component": component,
        "fluid": fluid,
        "evtms_version": __version__,
        "coolprop_version": coolprop_version,
        "grid": grid_name,
        "parameters": parameters_json,
        "environment": environment_json,
        "created": created,
        "history": f"{created} {history}".strip(),
        "lut_format_version": np.int32(FORMAT_VERSION),
    }


def build_dataset(
    *,
    grid: dict[str, np.ndarray],
    outputs: dict[str, np.ndarray],
    flags: dict[int, str],
    valid_flags: tuple[int, ...],
    **attrs: str,
) -> xr.Dataset:
    """Assemble a LUT dataset from flat bench outputs on a grid.

    Parameters
    ----------
    grid : dict of str to numpy.ndarray
        Axis name -> strictly increasing values, in dimension order.
    outputs : dict of str to numpy.ndarray
        Variable name -> flat array of ``prod(len(axis))`` values in C order
        of the grid (``status`` as int8).
    flags : dict of int to str
        Status codes and their meanings (CF ``flag_values``/``flag_meanings``).
    **attrs
        Keyword arguments of :func:`global_attributes`.
    """
    import xarray as xr

    dims = tuple(grid)
    shape = tuple(len(v) for v in grid.values())
    coords = {
        name: xr.Variable(name, np.asarray(values, np.float64), axis_attributes(name)) for name, values in grid.items()
    }
    data_vars = {}
    for name, flat in outputs.items():
        dtype = np.int8 if name == "status" else np.float64
        data_vars[name] = xr.Variable(
            dims, np.asarray(flat, dtype).reshape(shape), variable_attributes(name, flags, valid_flags)
        )
    return xr.Dataset(data_vars, coords=coords, attrs=global_attributes(**attrs))


def write_lut(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` as netCDF-4 to ``path`` atomically.

    The file is written to a temporary file in the target folder and renamed
    over the target, so an interrupted write never leaves a partial file at
    ``path``.
    """
    path = Path(path)
    encoding = {}
    for name in ds.variables:
        if name == "status" or name in ds.dims:
            encoding[name] = {"_FillValue": None}
        else:
            encoding[name] = {"_FillValue": np.nan}
    with atomic_output(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=encoding)
    return path


@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` on success.

    On any exception (including KeyboardInterrupt) the temporary file is
    removed and ``path`` is left as it was.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    # mkstemp makes the file private (0600); outputs are ordinary files, so apply the umask.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
