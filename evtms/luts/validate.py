"""Read a LUT file's header, check it against the format rule by rule, load what is asked.

Three ways in, all closing the file before they return:

* :func:`read_lut_metadata` reads the header (attributes, axes) with plain
  netCDF4 and checks every metadata rule; the data stay in the file and are
  read slab by slab on demand (:meth:`LutMetadata.iter_slabs`). No xarray
  import, no data loaded: ``evtms lut info`` uses it.
* :func:`open_lut` does the same, then loads ``status`` and the variables
  asked for into an :class:`xarray.Dataset` and checks the data rules on them.
* :func:`validate_lut` checks an in-memory dataset.

A version 1 file is presented in the version 2 shape: its length-1 axes
become ``fixed_inputs``.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.luts.io import LutStorage, MapTable, fixed_inputs_json
from evtms.luts.schema import (
    ALTERNATE_AXES,
    AXES,
    COMPONENT_AXES,
    COMPONENT_VARIABLES,
    EXTRA_AXES,
    FLAG_VARIABLES,
    FORMAT_VERSION,
    KIND_ATTR,
    LUT_KINDS,
    MAP_JSON_ATTR,
    MAP_REQUIRED_GLOBAL_ATTRS,
    READABLE_VERSIONS,
    REQUIRED_GLOBAL_ATTRS,
    accepted_units,
    unit_conversion,
    variable_spec,
)

if TYPE_CHECKING:
    import xarray as xr

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_CLASSIC_SIGNATURE = b"CDF"
#: Largest grid (points) a file may declare; a file declaring more is refused before anything is read.
MAX_POINTS = 200_000_000
#: Share of the available memory that loading variables may take.
MEMORY_SHARE = 0.8
#: Points per slab when data are streamed (about 8 MB per float64 variable).
SLAB_POINTS = 1 << 20
#: HDF5 chunk cache per variable while reading.
CHUNK_CACHE_BYTES = 4 << 20


class LutFormatError(EvtmsInputError):
    """A file is not a valid evtms LUT; the message names the file and the first broken rule."""


def _fail(name: str, rule: str) -> NoReturn:
    raise LutFormatError(f"{name}: {rule}")


# ----------------------------------------------------------------------------
# Attributes
# ----------------------------------------------------------------------------
def _json_object(name: str, attr: str, text: Any) -> dict:
    """Global attribute ``attr`` parsed as a JSON object, else a one-line LutFormatError."""
    if not isinstance(text, str):
        _fail(name, f"global attribute {attr!r} must be a JSON object in text, not {type(text).__name__}")
    try:
        value = json.loads(text)
    except ValueError:
        _fail(name, f"global attribute {attr!r} is not valid JSON")
    if not isinstance(value, dict):
        _fail(name, f"global attribute {attr!r} must be a JSON object, not {type(value).__name__}")
    return value


def allowed_inputs(component: str) -> tuple[str, ...]:
    """Every input name (axis or fixed input) a LUT of ``component`` may have."""
    names = list(COMPONENT_AXES[component])
    names += [ALTERNATE_AXES[a] for a in COMPONENT_AXES[component] if a in ALTERNATE_AXES]
    return tuple(names) + EXTRA_AXES.get(component, ())


def parse_fixed_inputs(text: Any, component: str | None = None, name: str = "dataset") -> dict[str, float]:
    """The ``fixed_inputs`` attribute as name -> value in SI units.

    Each entry is ``{"value": number, "units": text}``; units other than the
    axis' SI units are converted where the conversion is exact.

    Raises
    ------
    LutFormatError
        Not a JSON object, an entry that is not a known input (of
        ``component``), a value that is not a finite number, or units that
        cannot be converted.
    """
    raw = _json_object(name, "fixed_inputs", text)
    allowed = allowed_inputs(component) if component in COMPONENT_AXES else tuple(AXES)
    out = {}
    for key, entry in raw.items():
        if key not in allowed:
            _fail(name, f"fixed input {key!r} is not an input of a {component or 'LUT'}; allowed: {', '.join(allowed)}")
        if not isinstance(entry, dict) or "value" not in entry or "units" not in entry:
            _fail(name, f'fixed input {key!r} must be {{"value": number, "units": text}}')
        value = entry["value"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            _fail(name, f"fixed input {key!r} has value {value!r}; expected a finite number")
        conversion = unit_conversion(key, entry["units"])
        if conversion is None:
            _fail(
                name,
                f"fixed input {key!r} has units {entry['units']!r}; expected {AXES[key].units!r} "
                f"(or one of {', '.join(accepted_units(key))})",
            )
        out[key] = float(value) * conversion[0] + conversion[1]
    return out


def fixed_inputs(ds_or_attrs: xr.Dataset | Mapping[str, Any]) -> dict[str, float]:
    """Fixed inputs (name -> SI value) of a LUT dataset or of its global attributes; {} if none."""
    attrs = getattr(ds_or_attrs, "attrs", ds_or_attrs)  # a Dataset is a Mapping too
    text = attrs.get("fixed_inputs")
    if text is None:
        return {}
    return parse_fixed_inputs(text, attrs.get("component"))


def _version(name: str, attrs: Mapping[str, Any]) -> int:
    version = attrs.get("lut_format_version")
    if version is None:
        _fail(name, "global attribute lut_format_version is missing (not an evtms LUT file)")
    try:
        number = np.asarray(version).reshape(-1)
        if number.size != 1 or number.dtype.kind not in "iu":
            raise ValueError
        value = int(number[0])
    except (ValueError, TypeError):
        _fail(name, f"global attribute lut_format_version is {version!r}; expected an integer")
    if value not in READABLE_VERSIONS:
        shown = " and ".join(str(v) for v in READABLE_VERSIONS)
        _fail(name, f"LUT format version {value} is not supported; this evtms reads versions {shown}")
    return value


# ----------------------------------------------------------------------------
# The metadata rules, on a neutral description of the file (netCDF4 or xarray)
# ----------------------------------------------------------------------------
@dataclass
class _Header:
    attrs: dict[str, Any]
    dims: list[str]  # every dimension, in order
    sizes: dict[str, int]
    coords: dict[str, tuple[np.ndarray, dict]]  # axis -> (values, attributes incl. _FillValue)
    variables: dict[str, tuple[tuple[str, ...], np.dtype, dict]]  # data variable -> (dims, dtype, attrs)


@dataclass
class _Checked:
    version: int
    component: str
    dims: list[str]  # axes, without those that became fixed inputs
    axes: dict[str, np.ndarray]  # SI values
    axis_attrs: dict[str, dict]
    fixed: dict[str, float]


def _check_size(name: str, dims: list[str], sizes: Mapping[str, int]) -> None:
    points = math.prod(int(sizes[d]) for d in dims)
    if points > MAX_POINTS:
        shown = " x ".join(f"{d} {sizes[d]}" for d in dims)
        _fail(name, f"the file declares {points:.3g} grid points ({shown}); evtms reads at most {MAX_POINTS:.3g}")


def _axis_conversion(name: str, axis: str, units: Any, convert_units: bool) -> tuple[float, float]:
    """(factor, offset) from an axis' ``units`` to SI; refused if unknown (or, without ``convert_units``, not SI)."""
    conversion = unit_conversion(axis, units)
    if conversion is None or (conversion != (1.0, 0.0) and not convert_units):
        also = f" (or one of {', '.join(accepted_units(axis)[1:])}, converted on reading)" if convert_units else ""
        _fail(name, f"axis {axis!r} has units {units!r}; expected {AXES[axis].units!r}{also}")
    return conversion


def _check_header(name: str, h: _Header, convert_units: bool) -> _Checked:
    """Every metadata rule of the format, in order; the first broken one raises."""
    version = _version(name, h.attrs)
    kind = h.attrs.get(KIND_ATTR, "component")
    if kind != "component":
        shown = kind if kind in LUT_KINDS else repr(kind)
        _fail(name, f"holds a {shown} LUT (lut_kind {kind!r}); a component LUT is needed here")
    for attr in REQUIRED_GLOBAL_ATTRS:
        if attr not in h.attrs:
            _fail(name, f"global attribute {attr!r} is missing")
    _json_object(name, "parameters", h.attrs["parameters"])
    _json_object(name, "environment", h.attrs["environment"])
    component = h.attrs["component"]
    if component not in COMPONENT_AXES:
        _fail(name, f"component {component!r} is unknown; allowed: {', '.join(COMPONENT_AXES)}")
    fixed = parse_fixed_inputs(h.attrs["fixed_inputs"], component, name) if "fixed_inputs" in h.attrs else {}
    data_dims = list(h.variables["status"][0]) if "status" in h.variables else list(h.dims)
    _check_size(name, data_dims, h.sizes)
    # Length-1 axes: fixed inputs in the version 2 shape.
    dims = []
    for d in data_dims:
        if d in fixed:
            _fail(name, f"{d!r} is both an axis and a fixed input")
        if h.sizes[d] == 1:
            if version >= 2:
                _fail(name, f"axis {d!r} has a single value; format version 2 stores it in fixed_inputs")
            if d not in h.coords:
                _fail(name, f"axis {d!r} has no coordinate variable")
            value = float(np.asarray(h.coords[d][0]).reshape(-1)[0])
            factor, offset = _axis_conversion(name, d, h.coords[d][1].get("units"), convert_units)
            fixed[d] = value * factor + offset
            continue
        dims.append(d)
    # The component's standard axes, in order (T_in may be h_in), each an axis or a fixed input.
    present = set(dims) | set(fixed)
    standard = []
    for s in COMPONENT_AXES[component]:
        alt = ALTERNATE_AXES.get(s)
        both = [a for a in (s, alt) if a is not None and a in present]
        if not both:
            given = f" or {alt!r}" if alt else ""
            _fail(name, f"axis {s!r}{given} is neither an axis nor a fixed input")
        if len(both) == 2:
            _fail(name, f"{s!r} and {alt!r} are both given; the inlet state is one of them")
        if both[0] in dims:
            standard.append(both[0])
    if dims[: len(standard)] != standard:
        _fail(name, f"axes are {', '.join(dims)}; expected {', '.join(standard)} in that order, then extra axes")
    extras = EXTRA_AXES.get(component, ())
    for extra in dims[len(standard) :]:
        if extra not in extras:
            _fail(name, f"axis {extra!r} is not allowed for {component}")
    for extra in fixed:
        if extra not in allowed_inputs(component):
            _fail(name, f"fixed input {extra!r} is not allowed for {component}")
    # Coordinates.
    axes, axis_attrs = {}, {}
    for d in dims:
        if d not in h.coords:
            _fail(name, f"axis {d!r} has no coordinate variable")
        values, attrs = h.coords[d]
        values = np.asarray(values)
        if values.ndim != 1 or values.dtype != np.float64:
            _fail(name, f"axis {d!r} must be a 1-D float64 coordinate")
        if not np.all(np.isfinite(values)):
            _fail(name, f"axis {d!r} has non-finite values")
        if not np.all(np.diff(values) > 0):
            _fail(name, f"axis {d!r} is not strictly increasing")
        if version >= 2 and "_FillValue" in attrs:
            _fail(name, f"axis {d!r} has a _FillValue; coordinates carry none")
        if "long_name" not in attrs:
            _fail(name, f"axis {d!r} has no long_name")
        conversion = _axis_conversion(name, d, attrs.get("units"), convert_units)
        if conversion != (1.0, 0.0):
            values = values * conversion[0] + conversion[1]
            if not np.all(np.diff(values) > 0):
                _fail(name, f"axis {d!r} is not strictly increasing in {AXES[d].units}")
        axes[d] = values
        axis_attrs[d] = {k: v for k, v in attrs.items() if k != "_FillValue"} | {"units": AXES[d].units}
    # Variables.
    for var in COMPONENT_VARIABLES[component]:
        if var in dims or var in fixed:
            continue
        if var not in h.variables:
            _fail(name, f"required variable {var!r} is missing")
    if "status" not in h.variables:
        _fail(name, "required variable 'status' is missing")
    for var, (vdims, dtype, attrs) in h.variables.items():
        if list(vdims) != data_dims:
            _fail(name, f"variable {var!r} has dimensions {', '.join(vdims)}; expected {', '.join(data_dims)}")
        units = attrs.get("units")
        known = variable_spec(component, var)
        if known is not None and units != known[0]:
            _fail(name, f"variable {var!r} has units {units!r}; expected {known[0]!r}")
        if units is None or "long_name" not in attrs:
            _fail(name, f"variable {var!r} needs units and long_name")
        if "scale_factor" in attrs or "add_offset" in attrs:
            _fail(name, f"variable {var!r} is packed (scale_factor/add_offset); LUT values are stored unpacked")
        if var == "status":
            continue
        if dtype.kind != "f":
            _fail(name, f"variable {var!r} is {dtype}; expected float64 (or float32 storage)")
        for fill_attr in ("_FillValue", "missing_value"):
            fill = attrs.get(fill_attr)
            if fill is not None and not np.all(np.isnan(np.asarray(fill, np.float64))):
                _fail(name, f"variable {var!r} has {fill_attr} {fill!r}; invalid points hold NaN")
        if "evtms_storage" in attrs:
            try:
                LutStorage.parse(attrs["evtms_storage"])
            except EvtmsInputError as exc:
                _fail(name, f"variable {var!r}: {exc}")
        if "actual_range" in attrs:
            rng = np.asarray(attrs["actual_range"]).reshape(-1)
            if rng.size != 2 or rng.dtype.kind != "f" or not np.all(np.isfinite(rng)) or rng[0] > rng[1]:
                _fail(name, f"variable {var!r} has actual_range {attrs['actual_range']!r}; expected [min, max]")
    status_dtype, status_attrs = h.variables["status"][1], h.variables["status"][2]
    if status_dtype != np.int8:
        _fail(name, f"status must be int8, not {status_dtype}")
    flags = status_attrs.get("flag_values")
    meanings = status_attrs.get("flag_meanings")
    if flags is None or meanings is None:
        _fail(name, "status needs flag_values and flag_meanings")
    flags = np.atleast_1d(flags)
    if len(flags) != len(str(meanings).split()) or 0 not in flags:
        _fail(name, "status flag_values and flag_meanings must pair up and include 0 = valid")
    return _Checked(version, component, dims, axes, axis_attrs, fixed)


def _check_status(name: str, status: np.ndarray, flags: np.ndarray) -> None:
    unknown = np.setdiff1d(np.unique(status), flags)
    if unknown.size:
        _fail(name, f"status holds code {int(unknown[0])} that flag_values does not define")


def _check_values(name: str, var: str, values: np.ndarray, valid: np.ndarray) -> None:
    if not np.all(np.isfinite(values[valid])):
        _fail(name, f"variable {var!r} is not finite at a point whose status is valid")
    if not np.all(np.isnan(values[~valid])):
        _fail(name, f"variable {var!r} holds a number at a point whose status is invalid")


# ----------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------
def _attr_dict(obj) -> dict[str, Any]:
    return {k: obj.getncattr(k) for k in obj.ncattrs()}


def _signature(path: Path, name: str) -> os.stat_result:
    if not path.is_file():
        _fail(name, "no such file")
    stat = path.stat()
    if stat.st_size == 0:
        _fail(name, "the file is empty")
    with open(path, "rb") as fh:
        head = fh.read(8)
    if not (head.startswith(_HDF5_SIGNATURE) or head.startswith(_CLASSIC_SIGNATURE)):
        _fail(name, "not a netCDF file")
    return stat


def _identity(stat: os.stat_result) -> tuple:
    return (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)


@contextlib.contextmanager
def _netcdf(path: Path, name: str) -> Iterator[Any]:
    """The file opened read-only with netCDF4, raw values (no masking or scaling), closed on exit."""
    import netCDF4

    # Reads go slab by slab, each chunk once: a small chunk cache per variable (netCDF's
    # default, tens of MB per variable, would hold most of a file's data in memory).
    previous = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(size=CHUNK_CACHE_BYTES, nelems=1009, preemption=0.75)
    try:
        nc = netCDF4.Dataset(path, "r")
    except Exception as exc:  # HDF5 raises OSError or RuntimeError with multi-line text
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        _fail(name, f"the file is truncated or corrupt ({first})")
    finally:
        netCDF4.set_chunk_cache(*previous)
    try:
        nc.set_auto_maskandscale(False)
        yield nc
    finally:
        nc.close()


def _read(name: str, nc_var, index: tuple = ()) -> np.ndarray:
    try:
        return np.asarray(nc_var[index] if index else nc_var[...])
    except Exception as exc:  # a damaged chunk: HDF error
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        _fail(name, f"variable {nc_var.name!r} cannot be read; the file is truncated or corrupt ({first})")


@dataclass
class LutMetadata:
    """A LUT file's validated header; data are read from the file on demand.

    Attributes
    ----------
    path : Path
        The file.
    attrs : dict
        Global attributes as in the file, but ``fixed_inputs`` rewritten in SI
        units (and including a version 1 file's length-1 axes).
    component : str
        Component name.
    version : int
        ``lut_format_version`` of the file.
    dims : tuple of str
        Axes in table order (without fixed inputs).
    axes : dict of str to numpy.ndarray
        Axis values in SI units.
    axis_attrs : dict of str to dict
        Axis attributes (``units`` in SI).
    variables : dict of str to dict
        Data variable -> attributes (``_FillValue`` left out).
    dtypes : dict of str to numpy.dtype
        Data variable -> stored type.
    fixed : dict of str to float
        Fixed inputs in SI units.
    """

    path: Path
    attrs: dict[str, Any]
    component: str
    version: int
    dims: tuple[str, ...]
    axes: dict[str, np.ndarray]
    axis_attrs: dict[str, dict]
    variables: dict[str, dict]
    dtypes: dict[str, np.dtype]
    fixed: dict[str, float]
    _file_dims: tuple[str, ...] = field(default=(), repr=False)
    _identity: tuple = field(default=(), repr=False)

    @property
    def name(self) -> str:
        return str(self.path)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(self.axes[d]) for d in self.dims)

    @property
    def points(self) -> int:
        return math.prod(self.shape)

    def storage(self, var: str) -> LutStorage:
        """How float variable ``var`` is stored (a file without ``evtms_storage`` is lossless)."""
        return LutStorage.parse(self.variables[var].get("evtms_storage", "lossless"))

    def valid_flags(self) -> np.ndarray:
        """Status codes that mark valid points (``valid_flag_values``, else just 0)."""
        return np.atleast_1d(self.variables["status"].get("valid_flag_values", [0]))

    @contextlib.contextmanager
    def opened(self) -> Iterator[Any]:
        """The file opened for reading data (closed on exit), refused if it changed since the header was read."""
        try:
            same = _identity(self.path.stat()) == self._identity
        except OSError:
            same = False
        if not same:
            _fail(self.name, "the file changed or vanished since it was opened; open it again")
        with _netcdf(self.path, self.name) as nc:
            yield nc

    def _file_index(self, index: tuple) -> tuple:
        """An index over :attr:`dims` as an index over the file's dimensions (length-1 ones at 0)."""
        out, it = [], iter(index)
        for d in self._file_dims:
            out.append(next(it, slice(None)) if d in self.dims else 0)
        return tuple(out)

    def read(self, var: str, index: tuple = (), nc=None) -> np.ndarray:
        """Values of ``var`` at ``index`` (over :attr:`dims`; default all), as stored (float32 stays float32)."""
        if var not in self.variables:
            allowed = ", ".join(self.variables)
            raise EvtmsInputError(f"variable {var!r} is not in {self.name}; allowed: {allowed}")
        if nc is None:
            with self.opened() as nc:
                return self.read(var, index, nc)
        return _read(self.name, nc.variables[var], self._file_index(index))

    def slabs(self, max_points: int = SLAB_POINTS) -> list[tuple]:
        """Indices of slabs over the leading axes that cover the grid, each at most ``max_points`` (or one row)."""
        shape = self.shape
        lead = len(shape)
        for k in range(len(shape) + 1):
            if math.prod(shape[k:]) <= max_points:
                lead = k
                break
        lead = min(lead, max(len(shape) - 1, 0))
        return [tuple(int(i) for i in idx) for idx in np.ndindex(*shape[:lead])]

    def iter_slabs(self, variables: list[str], max_points: int = SLAB_POINTS) -> Iterator[dict[str, np.ndarray]]:
        """Flat arrays of ``variables`` slab by slab (bounded memory), the file opened once."""
        with self.opened() as nc:
            for index in self.slabs(max_points):
                yield {v: self.read(v, index, nc).reshape(-1) for v in variables}


def read_lut_metadata(path: str | Path, component: str | None = None) -> LutMetadata:
    """Read and check a LUT file's header without loading its data.

    Every metadata rule of ``docs/lut-format.md`` is checked (attributes and
    their JSON, axes, units, variables and their attributes, declared size);
    axis units other than SI are converted where exact. The file is closed
    again before this returns.

    Parameters
    ----------
    path : str or Path
        A netCDF-4 file written by evtms (or by anyone following the format).
    component : str, optional
        The component the caller needs; another one is refused.

    Returns
    -------
    LutMetadata
        The header, with on-demand access to the data.

    Raises
    ------
    LutFormatError
        The file is missing, empty, not netCDF, truncated, of another
        component, declares more than :data:`MAX_POINTS` grid points, or breaks
        a metadata rule; the one-line message names the file and the rule.
    """
    path = Path(path)
    name = str(path)
    if component is not None and component not in COMPONENT_AXES:
        raise EvtmsInputError(f"component {component!r} is unknown; allowed: {', '.join(COMPONENT_AXES)}")
    stat = _signature(path, name)
    if _HEADERS is None:
        return _known_header(path, name, component, stat)
    key = (name, component)
    known = _HEADERS.get(key)
    if known is not None and known._identity == _identity(stat):
        return copy.deepcopy(known)  # a copy: a caller may change its header, never the next caller's
    meta = _known_header(path, name, component, stat)
    _HEADERS[key] = copy.deepcopy(meta)
    return meta


#: Bump when a header's fields or their checks change: the user cache's copies are read again.
_HEADER_RECORD = 1


def _known_header(path: Path, name: str, component: str | None, stat: os.stat_result) -> LutMetadata:
    """The file's checked header, from the user cache where this file (the same device, inode,
    size and mtime_ns) was read and checked before (:func:`evtms.luts.cache.cached_arrays`): a
    command that finds its LUT folder opens no file (0.03 s of ``evtms cycle run``'s 0.37 s).
    A header that breaks a rule is never cached: it raises every time."""
    from evtms.luts.cache import cached_arrays, tagged, untagged

    def build() -> tuple[dict, dict]:
        meta = _read_header(path, name, component, stat)
        return {}, tagged({f.name: getattr(meta, f.name) for f in fields(meta) if f.name != "path"})

    try:
        _, info = cached_arrays("header", [path], {"record": _HEADER_RECORD, "component": component}, build)
    except OSError:  # the file went away since it was checked: its own error
        return _read_header(path, name, component, stat)
    try:
        record = untagged(info)
        if record.get("_identity") == _identity(stat):
            return LutMetadata(path=path, **record)
    except (TypeError, ValueError, KeyError, AttributeError):
        pass  # a damaged record: the file itself
    return _read_header(path, name, component, stat)


#: Inside :func:`headers_read_once`: the headers read so far, by (path, component).
_HEADERS: dict[tuple[str, str | None], LutMetadata] | None = None


@contextlib.contextmanager
def headers_read_once() -> Iterator[None]:
    """Within this block :func:`read_lut_metadata` reads and checks each LUT's header once.

    One job asks for a LUT's header several times (finding the LUT folder,
    loading the cycle LUTs, keying the maps); in this block a later call gets
    a copy of the first one's header, unless the file's identity (device,
    inode, size, mtime_ns) changed since. Outside it every call reads the
    file, however fast it is rewritten.
    """
    global _HEADERS
    outer = _HEADERS
    _HEADERS = {} if outer is None else outer
    try:
        yield
    finally:
        _HEADERS = outer


def _read_header(path: Path, name: str, component: str | None, stat: os.stat_result) -> LutMetadata:
    """:func:`read_lut_metadata`'s work: the file's header read and checked."""
    with _netcdf(path, name) as nc:
        attrs = _attr_dict(nc)
        if component is not None and "component" in attrs and attrs["component"] != component:
            _fail(name, f"holds the {attrs['component']} LUT; the {component} LUT is needed here")
        sizes = {d: len(dim) for d, dim in nc.dimensions.items()}
        variables = {}
        for v, var in nc.variables.items():
            if v in nc.dimensions and var.dimensions == (v,):
                continue
            variables[v] = (var.dimensions, var.dtype, _attr_dict(var))
        data_dims = list(variables["status"][0]) if "status" in variables else list(nc.dimensions)
        missing = [d for d in data_dims if d not in sizes]
        if missing:
            _fail(name, f"dimension {missing[0]!r} is not defined")
        _check_size(name, data_dims, sizes)
        coords = {}
        for d in data_dims:
            if d in nc.variables and nc.variables[d].dimensions == (d,):
                var = nc.variables[d]
                coords[d] = (_read(name, var), _attr_dict(var))
    header = _Header(attrs, list(sizes), sizes, coords, variables)
    checked = _check_header(name, header, convert_units=True)
    attrs["fixed_inputs"] = fixed_inputs_json(checked.fixed)
    return LutMetadata(
        path=path,
        attrs=attrs,
        component=checked.component,
        version=checked.version,
        dims=tuple(checked.dims),
        axes=checked.axes,
        axis_attrs=checked.axis_attrs,
        variables={v: {k: a for k, a in va.items() if k != "_FillValue"} for v, (_, _, va) in variables.items()},
        dtypes={v: np.dtype(dt) for v, (_, dt, _) in variables.items()},
        fixed=checked.fixed,
        _file_dims=tuple(data_dims),
        _identity=_identity(stat),
    )


def available_memory() -> int | None:
    """Bytes of memory available to this process now (Linux ``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _size(n: float) -> str:
    """Bytes in words: ``61 kB``, ``1.2 GB``."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.0f} B"


def open_lut(
    path: str | Path, component: str | None = None, variables: list[str] | tuple[str, ...] | None = None
) -> xr.Dataset:
    """Open a LUT file, check it against ``docs/lut-format.md`` and load it (or part of it) into memory.

    Parameters
    ----------
    path : str or Path
        A netCDF-4 file written by evtms (or by anyone following the format),
        version 1 or 2. A version 1 file comes in the version 2 shape (its
        length-1 axes as ``fixed_inputs``); axes in non-SI units that convert
        exactly (bar, kPa, degC, g s-1, ...) come in SI units.
    component : str, optional
        The component the caller needs; a file of another one is refused.
    variables : list of str, optional
        Data variables to load (``status`` always comes along); default all.
        Variables not loaded are not in the dataset.

    Returns
    -------
    xarray.Dataset
        Axes, fixed inputs (global attribute ``fixed_inputs``, JSON in SI
        units), ``status`` and the variables asked for, as float64 whatever
        their storage; the file is closed again.

    Raises
    ------
    LutFormatError
        As :func:`read_lut_metadata`, or a data rule is broken by a loaded
        variable (a status code without a meaning, a non-finite value at a
        valid point, a number at an invalid point).
    EvtmsInputError
        A variable asked for is not in the file, or loading would take more
        than 80 % of the available memory.
    """
    import xarray as xr

    meta = read_lut_metadata(path, component)
    name = meta.name
    names = list(meta.variables) if variables is None else list(dict.fromkeys(["status", *variables]))
    for v in names:
        if v not in meta.variables:
            raise EvtmsInputError(f"variable {v!r} is not in {name}; allowed: {', '.join(meta.variables)}")
    need = sum(meta.points * (1 if meta.dtypes[v] == np.int8 else 8) for v in names)
    available = available_memory()
    if available is not None and need > MEMORY_SHARE * available:
        raise EvtmsInputError(
            f"{name}: loading {len(names)} variables of {meta.points:,} points needs {_size(need)}; "
            f"{MEMORY_SHARE * 100:.0f} % of the available memory is {_size(MEMORY_SHARE * available)}; "
            "load fewer variables"
        )
    flags = np.atleast_1d(meta.variables["status"]["flag_values"])
    data = {}
    with meta.opened() as nc:
        status = meta.read("status", (), nc)
        _check_status(name, status, flags)
        valid = np.isin(status, meta.valid_flags())
        data["status"] = status
        for v in names:
            if v == "status":
                continue
            values = meta.read(v, (), nc)
            if values.dtype.kind == "f":
                values = values.astype(np.float64, copy=False)
                _check_values(name, v, values, valid)
            data[v] = values
    dims = meta.dims
    coords = {d: xr.Variable(d, meta.axes[d], meta.axis_attrs[d]) for d in dims}
    data_vars = {v: xr.Variable(dims, data[v], meta.variables[v]) for v in names}
    ds = xr.Dataset(data_vars, coords=coords, attrs=meta.attrs)
    ds.encoding["source"] = name
    return ds


def validate_lut(ds: xr.Dataset, name: str = "dataset") -> None:
    """Raise :class:`LutFormatError` at the first rule of the LUT format an in-memory ``ds`` breaks.

    Axes must be in SI units here (:func:`open_lut` converts a file's).
    """
    coords = {d: (ds[d].values, dict(ds[d].attrs) | _fill_attr(ds[d])) for d in ds.dims if d in ds.coords}
    variables = {v: (tuple(da.dims), da.dtype, dict(da.attrs) | _fill_attr(da)) for v, da in ds.data_vars.items()}
    dims = list(ds["status"].dims) if "status" in ds.data_vars else list(ds.dims)
    header = _Header(dict(ds.attrs), dims, dict(ds.sizes), coords, variables)
    _check_header(name, header, convert_units=False)
    status = ds["status"].values
    _check_status(name, status, np.atleast_1d(ds["status"].attrs["flag_values"]))
    valid = np.isin(status, valid_flags(ds))
    for var, da in ds.data_vars.items():
        if var != "status" and da.dtype.kind == "f":
            _check_values(name, var, da.transpose(*dims).values, valid)


def _fill_attr(da) -> dict:
    fill = da.encoding.get("_FillValue")
    return {} if fill is None else {"_FillValue": fill}


def status_flags(status_attrs: Mapping) -> dict[int, str]:
    """A LUT's status codes and their meanings, in the file's order (the ``status`` variable's
    ``flag_values`` and ``flag_meanings``, as :func:`evtms.luts.io.variable_attributes` writes them)."""
    codes = np.atleast_1d(status_attrs["flag_values"])
    return {int(c): m for c, m in zip(codes, str(status_attrs["flag_meanings"]).split(), strict=True)}


def valid_flags(ds: xr.Dataset | LutMetadata) -> np.ndarray:
    """Status codes that mark valid points (``valid_flag_values``, else just 0)."""
    if isinstance(ds, LutMetadata):
        return ds.valid_flags()
    return np.atleast_1d(ds["status"].attrs.get("valid_flag_values", [0]))


# ----------------------------------------------------------------------------
# Map LUTs
# ----------------------------------------------------------------------------
def _check_map_axis(name: str, d: str, coords: Mapping[str, tuple[np.ndarray, dict]]) -> np.ndarray:
    if d not in coords:
        _fail(name, f"axis {d!r} has no coordinate variable")
    values, attrs = coords[d]
    values = np.asarray(values)
    if values.ndim != 1 or values.dtype != np.float64:
        _fail(name, f"axis {d!r} must be a 1-D float64 coordinate")
    if not np.all(np.isfinite(values)) or not np.all(np.diff(values) > 0):
        _fail(name, f"axis {d!r} must be finite and strictly increasing")
    if "_FillValue" in attrs:
        _fail(name, f"axis {d!r} has a _FillValue; coordinates carry none")
    if "units" not in attrs or "long_name" not in attrs:
        _fail(name, f"axis {d!r} needs units and long_name")
    return values


def read_map_lut(path: str | Path, expect: Mapping[str, Any] | None = None) -> MapTable:
    """Read and check a map LUT (:func:`evtms.luts.io.write_map_lut`), the file closed again on return.

    The rules: a netCDF file of a readable format version with ``lut_kind``
    ``map`` and :data:`~evtms.luts.schema.MAP_REQUIRED_GLOBAL_ATTRS`; every
    data variable on the same axes, each axis a 1-D float64 coordinate,
    finite and strictly increasing, without ``_FillValue``; every axis and
    variable with ``units`` and ``long_name``; floats finite at every node
    (a map is complete); flags int8, ``status`` with ``flag_values`` and
    ``flag_meanings`` that pair up and define every code it holds.

    Parameters
    ----------
    path : str or Path
        The file.
    expect : mapping, optional
        Global attributes the file must carry with these values (e.g. its
        cache key), checked before any data is read.

    Returns
    -------
    MapTable
        Axes, variables (floats as float64) and attributes as stored (without
        ``_FillValue``); the global attributes named in ``json_attributes``
        decoded.

    Raises
    ------
    LutFormatError
        The file is missing, not netCDF, truncated, another kind of LUT, an
        expected attribute differs, or a rule is broken; one line naming the
        file and the rule.
    """
    path = Path(path)
    name = str(path)
    _signature(path, name)
    with _netcdf(path, name) as nc:
        attrs = _attr_dict(nc)
        _version(name, attrs)
        kind = attrs.get(KIND_ATTR, "component")
        if kind != "map":
            shown = kind if kind in LUT_KINDS else repr(kind)
            _fail(name, f"holds a {shown} LUT (lut_kind {kind!r}); a map LUT is needed here")
        for attr in MAP_REQUIRED_GLOBAL_ATTRS:
            if attr not in attrs:
                _fail(name, f"global attribute {attr!r} is missing")
        for key, value in (expect or {}).items():
            if attrs.get(key) != value:
                _fail(name, f"global attribute {key} is {attrs.get(key)!r}; expected {value!r}")
        coord_names = {v for v, var in nc.variables.items() if v in nc.dimensions and var.dimensions == (v,)}
        data = [v for v in nc.variables if v not in coord_names]
        if not data:
            _fail(name, "the file holds no data variable")
        dims = list(nc.variables[data[0]].dimensions)
        sizes = {d: len(nc.dimensions[d]) for d in dims}
        _check_size(name, dims, sizes)
        coords = {d: (_read(name, nc.variables[d]), _attr_dict(nc.variables[d])) for d in dims if d in coord_names}
        axes = {d: _check_map_axis(name, d, coords) for d in dims}
        attributes = {d: coords[d][1] for d in dims}
        variables = {}
        for v in data:
            var = nc.variables[v]
            vattrs = {k: a for k, a in _attr_dict(var).items() if k != "_FillValue"}
            if list(var.dimensions) != dims:
                _fail(name, f"variable {v!r} has dimensions {', '.join(var.dimensions)}; expected {', '.join(dims)}")
            if "units" not in vattrs or "long_name" not in vattrs:
                _fail(name, f"variable {v!r} needs units and long_name")
            values = _read(name, var)
            if v in FLAG_VARIABLES:
                if values.dtype != np.int8:
                    _fail(name, f"{v} must be int8, not {values.dtype}")
            elif values.dtype.kind != "f":
                _fail(name, f"variable {v!r} is {values.dtype}; expected float64")
            else:
                values = values.astype(np.float64, copy=False)
                if not np.all(np.isfinite(values)):
                    _fail(name, f"variable {v!r} is not finite at every node; a map is complete")
            variables[v] = values
            attributes[v] = vattrs
    if "status" in variables:
        flags, meanings = attributes["status"].get("flag_values"), attributes["status"].get("flag_meanings")
        if flags is None or meanings is None:
            _fail(name, "status needs flag_values and flag_meanings")
        flags = np.atleast_1d(flags)
        if len(flags) != len(str(meanings).split()) or 0 not in flags:
            _fail(name, "status flag_values and flag_meanings must pair up and include 0 = valid")
        _check_status(name, variables["status"], flags)
    for k in str(attrs.get(MAP_JSON_ATTR, "")).split():
        attrs[k] = _json_object(name, k, attrs.get(k))
    attrs.pop(MAP_JSON_ATTR, None)
    if int(np.asarray(attrs["lut_format_version"]).reshape(-1)[0]) != FORMAT_VERSION:
        _fail(name, f"map LUTs are written in format version {FORMAT_VERSION} only")
    try:
        return MapTable(axes, variables, attributes, attrs)
    except ValueError as exc:
        _fail(name, str(exc))
