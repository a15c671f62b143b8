"""Build and write LUT datasets per ``docs/lut-format.md`` (format version 2).

How a variable is stored (type, compression, fill value, lossy rounding and
the attributes that record it) is decided here once, by
:func:`variable_storage`, :func:`store_values` and :func:`storage_attributes`;
the one file writer, :class:`evtms.luts.writer.LutFileWriter`, applies them
for :func:`write_lut` (a dataset, in one slab) and for
:func:`evtms.benches.chunked.sweep_to_file` (slab by slab).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms import __version__
from evtms.errors import EvtmsInputError
from evtms.luts.schema import (
    AXES,
    CONVENTIONS,
    FLAG_VARIABLES,
    FORMAT_VERSION,
    KIND_ATTR,
    MAP_JSON_ATTR,
    MAP_REQUIRED_GLOBAL_ATTRS,
    variable_spec,
)

if TYPE_CHECKING:  # xarray is imported lazily: it costs ~0.5 s
    import xarray as xr

    from evtms.luts.interp import Interpolator

#: zlib level of every data variable: level 4 gives nearly all of level 9's size at a third of its time.
COMPRESSION_LEVEL = 4
#: Most significant decimal digits a lossy float32 variable may keep (float32 holds about 7).
FLOAT32_MAX_DIGITS = 6
_STORAGE_ATTR = "evtms_storage"


@dataclass(frozen=True)
class LutStorage:
    """How the float data variables of a LUT are stored; the default is lossless.

    Parameters
    ----------
    float32 : bool
        Store floats as float32 (relative error at most 2**-24, about 6e-8).
    significant_digits : int, optional
        Round each float to ``significant_digits`` decimal digits (1..15;
        1..6 with ``float32``): its binary mantissa keeps enough bits that
        the relative error is at most ``0.5 * 10**-significant_digits``
        (float32 rounding included). The zeroed low bits compress well.

    Raises
    ------
    EvtmsInputError
        ``significant_digits`` is not a whole number in the allowed range.
    """

    float32: bool = False
    significant_digits: int | None = None

    def __post_init__(self) -> None:
        d = self.significant_digits
        if d is None:
            return
        top = FLOAT32_MAX_DIGITS if self.float32 else 15
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or not 1 <= d <= top:
            kind = "float32" if self.float32 else "float64"
            raise EvtmsInputError(f"significant digits {d!r} is not allowed; allowed: 1 to {top} with {kind} storage")

    @property
    def lossless(self) -> bool:
        """True if floats are stored exactly (float64, no rounding)."""
        return not self.float32 and self.significant_digits is None

    @property
    def label(self) -> str:
        """The ``evtms_storage`` attribute: ``lossless``, ``float32``, ``significant_digits=5`` or both."""
        parts = (["float32"] if self.float32 else []) + (
            [f"significant_digits={self.significant_digits}"] if self.significant_digits is not None else []
        )
        return " ".join(parts) or "lossless"

    @property
    def relative_error(self) -> float:
        """Largest relative error of a stored value (0 when lossless)."""
        if self.significant_digits is not None:
            return 0.5 * 10.0**-self.significant_digits
        return 2.0**-24 if self.float32 else 0.0

    @property
    def dtype(self) -> np.dtype:
        """The stored type of float variables."""
        return np.dtype(np.float32 if self.float32 else np.float64)

    @classmethod
    def parse(cls, label: str) -> LutStorage:
        """The storage an ``evtms_storage`` attribute describes.

        Raises
        ------
        EvtmsInputError
            ``label`` is not one of the forms :attr:`label` writes.
        """
        float32, digits = False, None
        words = str(label).split()
        for word in words:
            if word == "float32" and not float32:
                float32 = True
            elif word.startswith("significant_digits=") and digits is None:
                text = word.partition("=")[2]
                if not text.isdigit():
                    raise EvtmsInputError(f"{_STORAGE_ATTR} {label!r}: significant_digits must be a whole number")
                digits = int(text)
            elif word != "lossless" or len(words) != 1:
                raise EvtmsInputError(
                    f"{_STORAGE_ATTR} {label!r} is not allowed; allowed: lossless, float32, "
                    "significant_digits=N, float32 significant_digits=N"
                )
        return cls(float32, digits)

    def mantissa_bits(self) -> int | None:
        """Fraction bits kept by the rounding (None: no rounding).

        ``ceil(d log2 10) + 1`` bits bound the rounding error by
        ``0.25 * 10**-d``, which leaves room for float32's own rounding.
        """
        if self.significant_digits is None:
            return None
        return math.ceil(self.significant_digits * math.log2(10.0)) + 1


def _round_mantissa(values: np.ndarray, bits: int) -> np.ndarray:
    """Round finite floats to ``bits`` fraction bits (ties away from zero); NaN and inf stay."""
    info = np.finfo(values.dtype)
    drop = info.nmant - bits
    if drop <= 0:
        return values
    uint = np.uint32 if values.dtype == np.float32 else np.uint64
    raw = values.view(uint)
    mask = uint(~((1 << drop) - 1) & ((1 << (8 * values.dtype.itemsize)) - 1))
    # Adding half a unit of the last kept bit to the sign-magnitude pattern rounds the
    # magnitude; a carry into the exponent is the correct rounding up to the next power of 2.
    rounded = (raw + uint(1 << (drop - 1))) & mask
    out = rounded.view(values.dtype)
    finite = np.isfinite(values)
    overflow = finite & ~np.isfinite(out)
    if overflow.any():  # the largest floats: truncate instead of rounding to infinity
        out = np.where(overflow, (raw & mask).view(values.dtype), out)
    return np.where(finite, out, values)


def store_values(name: str, values: np.ndarray, storage: LutStorage | None = None) -> np.ndarray:
    """``values`` of variable ``name`` as they are stored: int8 flags (:data:`~evtms.luts.schema.FLAG_VARIABLES`),
    floats cast and rounded per ``storage``.

    Raises
    ------
    EvtmsInputError
        A finite value does not fit float32 (with ``storage.float32``).
    """
    storage = storage or LutStorage()
    if name in FLAG_VARIABLES:
        return np.asarray(values, np.int8)
    values = np.asarray(values)
    if values.dtype.kind != "f":
        return values
    with np.errstate(over="ignore"):
        out = np.asarray(values, storage.dtype)
    if storage.float32 and bool(np.any(np.isinf(out) & np.isfinite(values))):
        raise EvtmsInputError(f"variable {name!r} has values beyond the float32 range; store it as float64")
    bits = storage.mantissa_bits()
    if bits is not None:
        out = _round_mantissa(out, bits)
    return out


def variable_storage(name: str, storage: LutStorage | None = None, ndim: int = 1) -> dict[str, Any]:
    """``netCDF4.Dataset.createVariable`` keyword arguments of LUT data variable ``name``.

    ``status`` (and a map's ``filled``: :data:`~evtms.luts.schema.FLAG_VARIABLES`)
    is int8 without fill value, floats are in ``storage``'s type with a NaN
    fill value; all zlib-compressed (level :data:`COMPRESSION_LEVEL`) with the
    shuffle filter, except scalars (``ndim`` 0), which HDF5 cannot compress.
    Axes take :func:`axis_storage`.
    """
    storage = storage or LutStorage()
    if name in FLAG_VARIABLES:
        kwargs: dict[str, Any] = {"datatype": "i1", "fill_value": None}
    else:
        kwargs = {"datatype": storage.dtype.str[1:], "fill_value": storage.dtype.type(np.nan)}
    if ndim > 0:
        kwargs.update(zlib=True, complevel=COMPRESSION_LEVEL, shuffle=True)
    return kwargs


def axis_storage() -> dict[str, Any]:
    """``createVariable`` keyword arguments of an axis: float64, no ``_FillValue`` (CF), uncompressed."""
    return {"datatype": "f8", "fill_value": None}


def storage_attributes(name: str, stored: np.ndarray | None, storage: LutStorage | None = None) -> dict[str, Any]:
    """Attributes a float data variable gets from its storage and its stored values.

    ``evtms_storage`` (``storage.label``) and ``actual_range`` (smallest and
    largest finite stored value, in the stored type; omitted when there is
    none, or when ``stored`` is None). Flags (``status``) get none.
    """
    storage = storage or LutStorage()
    if name in FLAG_VARIABLES:
        return {}
    attrs: dict[str, Any] = {_STORAGE_ATTR: storage.label}
    if stored is not None:
        lo, hi = finite_range(stored)
        if lo is not None:
            attrs["actual_range"] = np.array([lo, hi], dtype=stored.dtype)
    return attrs


def finite_range(values: np.ndarray) -> tuple[float | None, float | None]:
    """(min, max) of the finite values, or (None, None)."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return None, None
    return finite.min(), finite.max()


def variable_attributes(
    name: str, flags: dict[int, str], valid_flags: tuple[int, ...], component: str | None = None
) -> dict:
    """CF attributes of a LUT data variable of ``component`` (``status`` gets its flags)."""
    units, long_name = variable_spec(component, name)
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


def fixed_inputs_json(values: Mapping[str, float]) -> str:
    """The ``fixed_inputs`` attribute: JSON object name -> ``{"value": v, "units": u}`` (SI)."""
    return json.dumps({name: {"value": float(v), "units": AXES[name].units} for name, v in values.items()})


def fixed_axes(grid: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """Split a grid into its axes (two values or more) and its fixed inputs (one value).

    A bench evaluates every input of the grid; the file holds only the
    inputs that vary as dimensions, the others in ``fixed_inputs``.
    """
    axes = {k: np.asarray(v, np.float64) for k, v in grid.items() if np.size(v) > 1}
    fixed = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in grid.items() if np.size(v) == 1}
    return axes, fixed


def _utc_now() -> str:
    """The current UTC time to the second, ISO 8601 with ``Z`` (``created`` attributes)."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


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
    fixed_inputs: Mapping[str, float] | None = None,
) -> dict:
    """The LUT format's global attributes, stamped with the current UTC time.

    ``fixed_inputs`` maps the inputs that take one value (not axes) to that
    value in SI units.
    """
    created = _utc_now()
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
        "fixed_inputs": fixed_inputs_json(fixed_inputs or {}),
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
        Axis name -> strictly increasing values, in dimension order. An axis
        of one value becomes a fixed input (global attribute ``fixed_inputs``),
        not a dimension.
    outputs : dict of str to numpy.ndarray
        Variable name -> flat array of ``prod(len(axis))`` values in C order
        of the grid (``status`` as int8).
    flags : dict of int to str
        Status codes and their meanings (CF ``flag_values``/``flag_meanings``).
    **attrs
        Keyword arguments of :func:`global_attributes` (but ``fixed_inputs``).
    """
    import xarray as xr

    axes, fixed = fixed_axes(grid)
    dims = tuple(axes)
    shape = tuple(len(v) for v in axes.values())
    coords = {name: xr.Variable(name, values, axis_attributes(name)) for name, values in axes.items()}
    data_vars = {}
    for name, flat in outputs.items():
        dtype = np.int8 if name == "status" else np.float64
        data_vars[name] = xr.Variable(
            dims,
            np.asarray(flat, dtype).reshape(shape),
            variable_attributes(name, flags, valid_flags, attrs.get("component")),
        )
    return xr.Dataset(data_vars, coords=coords, attrs=global_attributes(**attrs, fixed_inputs=fixed))


def squeeze_fixed_inputs(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` without length-1 dimensions: each becomes an entry of the ``fixed_inputs`` attribute.

    A dataset without length-1 dimensions comes back unchanged (but for a
    ``fixed_inputs`` attribute added if it had none).
    """
    from evtms.luts.validate import fixed_inputs

    fixed = fixed_inputs(ds)
    dims = list(ds["status"].dims) if "status" in ds else list(ds.dims)
    single = [d for d in dims if ds.sizes[d] == 1]
    for d in single:
        if d in fixed:
            raise EvtmsInputError(f"{d!r} is both a length-1 axis and a fixed input of the dataset")
        fixed[d] = float(ds[d].values[0])
    out = ds.isel({d: 0 for d in single}, drop=True) if single else ds.copy(deep=False)
    out.attrs = dict(ds.attrs)
    out.attrs["fixed_inputs"] = fixed_inputs_json(fixed)
    return out


def write_lut(ds: xr.Dataset, path: str | Path, storage: LutStorage | None = None) -> Path:
    """Write ``ds`` as a format-version-2 netCDF-4 LUT to ``path`` atomically.

    Length-1 dimensions become ``fixed_inputs``; data variables are compressed
    (zlib, shuffle) and stored as :class:`LutStorage` says (lossless by
    default), each float variable with ``evtms_storage`` and ``actual_range``
    attributes. The file is written to a temporary file in the target folder
    and renamed over the target, so an interrupted write never leaves a
    partial file at ``path``.

    Parameters
    ----------
    ds : xarray.Dataset
        A LUT dataset (from :func:`build_dataset` or :func:`evtms.luts.open_lut`).
    path : str or Path
        Target file.
    storage : LutStorage, optional
        Lossy storage of the floats (float32 and/or significant digits).

    Returns
    -------
    Path
        ``path``.
    """
    from evtms.luts.writer import LutFileWriter

    storage = storage or LutStorage()
    path = Path(path)
    ds = squeeze_fixed_inputs(ds)
    dims = list(ds["status"].dims) if "status" in ds else list(ds.dims)
    # Attributes of the plain variables: nothing of the encoding of a file ds was read from comes along.
    axes = {name: np.asarray(ds[name].values, np.float64) for name in dims}
    attributes = {name: {k: v for k, v in ds[name].attrs.items() if k != "_FillValue"} for name in dims}
    arrays = {}
    for name, da in ds.data_vars.items():
        arrays[name] = values = da.transpose(*dims).values
        attrs = {k: v for k, v in da.attrs.items() if k not in ("actual_range", _STORAGE_ATTR, "_FillValue")}
        if name != "status" and values.dtype.kind == "f":
            attrs.update(storage_attributes(name, None, storage))
        attributes[name] = attrs
    attrs = dict(ds.attrs)
    attrs["lut_format_version"] = np.int32(FORMAT_VERSION)
    with atomic_output(path) as tmp, LutFileWriter(tmp, axes, list(arrays), attributes, attrs, storage=storage) as w:
        w.write((), arrays)  # one slab: the whole dataset
        w.finish()
    return path


@dataclass(frozen=True, eq=False)
class MapTable:
    """A map LUT in memory: complete tables of variables on a rectilinear grid, with their provenance.

    A map is a LUT of a circuit rather than a component (global attribute
    ``lut_kind`` ``map``): every node holds numbers, a node that was invalid
    holding a donor node's values (``filled`` 1); ``status`` keeps each node's
    status as computed. The layer knows nothing of what the variables mean:
    the caller gives their units and long names.

    Attributes
    ----------
    axes : dict of str to numpy.ndarray
        Axis name -> nodes [SI], float64, finite and strictly increasing, in table order.
    variables : dict of str to numpy.ndarray
        Data variable -> values shaped as the grid: float64, finite; ``status``
        and ``filled`` (:data:`~evtms.luts.schema.FLAG_VARIABLES`) int8.
    attributes : dict of str to dict
        Axis or variable name -> its attributes (``units`` and ``long_name``
        each; a flag's ``flag_values`` and ``flag_meanings``).
    attrs : dict
        Global attributes (:data:`~evtms.luts.schema.MAP_REQUIRED_GLOBAL_ATTRS`
        at least, when written); a dict value is stored as JSON and comes back as a dict.
    """

    axes: dict[str, np.ndarray]
    variables: dict[str, np.ndarray]
    attributes: dict[str, dict]
    attrs: dict[str, Any]

    def __post_init__(self) -> None:
        axes = {k: np.ascontiguousarray(v, np.float64).reshape(-1) for k, v in self.axes.items()}
        shape = tuple(a.size for a in axes.values())
        variables = {}
        for k, v in self.variables.items():
            v = np.ascontiguousarray(v, np.int8 if k in FLAG_VARIABLES else np.float64)
            if v.shape != shape:
                raise ValueError(f"map variable {k!r} has shape {v.shape}; the grid is {shape}")
            variables[k] = v
        for k, a in axes.items():
            if a.size == 0 or not np.all(np.isfinite(a)) or np.any(np.diff(a) <= 0):
                raise ValueError(f"map axis {k!r} must be finite and strictly increasing")
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "variables", variables)

    @property
    def name(self) -> str:
        """The map's name (global attribute ``map_name``)."""
        return str(self.attrs.get("map_name", ""))

    @property
    def shape(self) -> tuple[int, ...]:
        """Node counts per axis."""
        return tuple(a.size for a in self.axes.values())

    def interpolator(self, variables: Sequence[str] | None = None, out_of_range: str = "clip") -> Interpolator:
        """A multilinear :class:`~evtms.luts.interp.Interpolator` of ``variables`` (default: every float variable).

        Parameters
        ----------
        variables : sequence of str, optional
            Float variables to interpolate, in the order of the results.
        out_of_range : {"clip", "nan", "error"}
            Policy for points outside the axes (default: clipped to them).

        Returns
        -------
        Interpolator
        """
        from evtms.luts.interp import Interpolator

        names = [k for k in self.variables if k not in FLAG_VARIABLES] if variables is None else list(variables)
        return Interpolator(list(self.axes.items()), {k: self.variables[k] for k in names}, out_of_range)


def write_map_lut(table: MapTable, path: str | Path) -> Path:
    """Write a map LUT with the one LUT writer (:class:`~evtms.luts.writer.LutFileWriter`), atomically.

    Stored as every LUT is (lossless: axes float64 uncompressed, floats with
    NaN fill value, ``evtms_storage`` and ``actual_range``, flags int8, zlib
    level :data:`COMPRESSION_LEVEL` with shuffle), with the format's version,
    ``lut_kind`` ``map``, CF ``Conventions`` and the table's global
    attributes; dict attributes as JSON text, named in ``json_attributes``.

    Parameters
    ----------
    table : MapTable
        The map; its ``attrs`` hold :data:`~evtms.luts.schema.MAP_REQUIRED_GLOBAL_ATTRS`
        (``Conventions``, ``lut_kind`` and ``lut_format_version`` are set; ``evtms_version``, ``created``
        and ``history`` added where missing).
    path : str or Path
        The file (its folder must exist).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        A required global attribute is missing, or an axis or variable has no units or long_name.
    """
    from evtms.luts.writer import LutFileWriter

    path = Path(path)
    attrs: dict[str, Any] = {"Conventions": CONVENTIONS, **table.attrs}
    attrs[KIND_ATTR] = "map"
    attrs["lut_format_version"] = np.int32(FORMAT_VERSION)
    attrs.setdefault("evtms_version", __version__)
    attrs.setdefault("created", _utc_now())
    attrs.setdefault("history", f"{attrs['created']} written by evtms {__version__}")
    missing = [k for k in MAP_REQUIRED_GLOBAL_ATTRS if k not in attrs]
    if missing:
        raise ValueError(f"map LUT {table.name!r}: global attribute {missing[0]!r} is missing")
    json_names = [k for k, v in attrs.items() if isinstance(v, dict)]
    for k in json_names:
        attrs[k] = json.dumps(attrs[k], sort_keys=True)
    if json_names:
        attrs[MAP_JSON_ATTR] = " ".join(json_names)
    attributes = {}
    for k in (*table.axes, *table.variables):
        given = dict(table.attributes.get(k, {}))
        if "units" not in given or "long_name" not in given:
            raise ValueError(f"map LUT {table.name!r}: {k!r} needs units and long_name")
        if k in table.variables and k not in FLAG_VARIABLES:
            given = {a: v for a, v in given.items() if a not in ("actual_range", _STORAGE_ATTR)}
            given.update(storage_attributes(k, None))
        attributes[k] = given
    with atomic_output(path) as tmp, LutFileWriter(tmp, table.axes, list(table.variables), attributes, attrs) as w:
        w.write((), table.variables)
        w.finish()
    return path


@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` on success.

    On any exception (including KeyboardInterrupt) the temporary file is
    removed and ``path`` is left as it was. An OS error (a full disk, a
    read-only folder) names ``path``, not the temporary file the user never
    asked for; so does an HDF5 error of a netCDF writer, which reports a full
    disk as ``RuntimeError: NetCDF: HDF error``.
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    os.close(fd)
    # mkstemp makes the file private (0600); outputs are ordinary files, so apply the umask.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.errno is not None and exc.filename in (None, tmp):
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        if isinstance(exc, RuntimeError) and "HDF error" in str(exc):
            free = shutil.disk_usage(path.parent).free
            reason = f"the netCDF library could not write it ({exc}; {free:,} bytes free)"
            raise OSError(errno.EIO, reason, str(path)) from None
        raise
