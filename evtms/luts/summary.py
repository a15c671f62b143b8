"""A LUT's contents in brief: axes, fixed inputs, variables with ranges, invalid points, provenance."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms.luts.schema import AXES
from evtms.luts.validate import (
    LutFormatError,
    LutMetadata,
    fixed_inputs,
    read_lut_metadata,
    status_flags,
    valid_flags,
)

if TYPE_CHECKING:
    import xarray as xr


def lut_summary(source: xr.Dataset | LutMetadata | str | Path) -> dict[str, Any]:
    """Facts about a LUT for ``evtms lut info`` and reports.

    Parameters
    ----------
    source : xarray.Dataset, LutMetadata, str or Path
        A loaded dataset, or a file (its path, or the header from
        :func:`evtms.luts.validate.read_lut_metadata`). A file is read
        without loading it: status slab by slab, and each variable's range
        from its ``actual_range`` attribute (format version 2), else streamed
        slab by slab; memory stays bounded whatever the file's size.

    Returns
    -------
    dict
        ``component``, ``fluid``, ``grid``, ``format``; ``axes`` (name, size,
        min, max, units, long_name); ``fixed_inputs`` (name -> value, units,
        long_name: inputs that are not axes); ``variables`` (name, units, min, max over valid points,
        long_name, storage); ``points``, ``valid``; ``status`` (code, meaning,
        count); ``provenance`` (versions, created, history);
        ``parameters`` and ``environment`` (parsed JSON).

    Raises
    ------
    LutFormatError
        A file breaks a rule of the format (among them a status code that
        ``flag_values`` does not define).
    """
    if isinstance(source, (str, Path)):
        source = read_lut_metadata(source)
    if isinstance(source, LutMetadata):
        return _file_summary(source)
    return _dataset_summary(source)


def _axis(name: str, values: np.ndarray, attrs: dict) -> dict[str, Any]:
    return {
        "name": name,
        "size": int(values.size),
        "min": float(values[0]),
        "max": float(values[-1]),
        "units": attrs.get("units", ""),
        "long_name": attrs.get("long_name", ""),
    }


def _fixed(values: dict[str, float]) -> dict[str, dict[str, Any]]:
    return {k: {"value": v, "units": AXES[k].units, "long_name": AXES[k].long_name} for k, v in values.items()}


def _variable(name: str, attrs: dict, lo: float, hi: float) -> dict[str, Any]:
    return {
        "name": name,
        "units": attrs.get("units", ""),
        "min": lo,
        "max": hi,
        "long_name": attrs.get("long_name", ""),
        "storage": str(attrs.get("evtms_storage", "lossless")),
    }


def _status_counts(status_attrs: dict, counts: dict[int, int]) -> list[dict[str, Any]]:
    return [{"code": c, "meaning": m, "count": counts.get(c, 0)} for c, m in status_flags(status_attrs).items()]


def _common(attrs: dict) -> dict[str, Any]:
    return {
        "component": attrs.get("component"),
        "fluid": attrs.get("fluid"),
        "grid": attrs.get("grid"),
        "format": int(np.asarray(attrs.get("lut_format_version", 0)).reshape(-1)[0]),
        "provenance": {k: attrs.get(k) for k in ("evtms_version", "coolprop_version", "created", "history", "title")},
        "parameters": json.loads(attrs.get("parameters", "{}")),
        "environment": json.loads(attrs.get("environment", "{}")),
    }


def _file_summary(meta: LutMetadata) -> dict[str, Any]:
    floats = [v for v in meta.variables if v != "status" and meta.dtypes[v].kind == "f"]
    stored = {v: meta.variables[v].get("actual_range") for v in floats}
    stream = [v for v in floats if stored[v] is None]
    ranges = {v: [np.inf, -np.inf] for v in stream}
    counts: dict[int, int] = {}
    flags = np.atleast_1d(meta.variables["status"]["flag_values"])
    valid_codes = meta.valid_flags()
    for slab in meta.iter_slabs(["status"]):
        n = np.bincount(slab["status"].view(np.uint8), minlength=256)  # int8 codes by their bit pattern
        for c in np.nonzero(n)[0].tolist():
            code = c - 256 if c > 127 else c
            counts[code] = counts.get(code, 0) + int(n[c])
    for v in stream:  # one variable at a time (with the status again): memory of two slabs
        r = ranges[v]
        for slab in meta.iter_slabs(["status", v]):
            ok = np.isin(slab["status"], valid_codes)
            if not np.all(np.isnan(slab[v][~ok])):
                raise LutFormatError(f"{meta.name}: variable {v!r} holds a number at a point whose status is invalid")
            vals = slab[v][ok]
            if not np.all(np.isfinite(vals)):
                raise LutFormatError(f"{meta.name}: variable {v!r} is not finite at a point whose status is valid")
            if vals.size:
                r[0], r[1] = min(r[0], float(vals.min())), max(r[1], float(vals.max()))
    unknown = sorted(set(counts) - {int(c) for c in flags})
    if unknown:
        raise LutFormatError(f"{meta.name}: status holds code {unknown[0]} that flag_values does not define")
    variables = []
    for v in floats:
        if stored[v] is not None:
            lo, hi = (float(x) for x in np.asarray(stored[v]).reshape(-1))
        else:
            lo, hi = ranges[v] if np.isfinite(ranges[v][0]) else (float("nan"), float("nan"))
        variables.append(_variable(v, meta.variables[v], lo, hi))
    valid = sum(counts.get(int(c), 0) for c in valid_codes)
    return {
        **_common(meta.attrs),
        "axes": [_axis(d, meta.axes[d], meta.axis_attrs[d]) for d in meta.dims],
        "fixed_inputs": _fixed(meta.fixed),
        "variables": variables,
        "points": meta.points,
        "valid": valid,
        "status": _status_counts(meta.variables["status"], counts),
    }


def _dataset_summary(ds: xr.Dataset) -> dict[str, Any]:
    dims = list(ds["status"].dims)
    status = ds["status"].values
    ok = np.isin(status, valid_flags(ds))
    variables = []
    for v, da in ds.data_vars.items():
        if v == "status":
            continue
        vals = da.transpose(*dims).values[ok]
        lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (float("nan"), float("nan"))
        variables.append(_variable(v, da.attrs, lo, hi))
    codes, n = np.unique(status, return_counts=True)
    return {
        **_common(ds.attrs),
        "axes": [_axis(d, ds[d].values, ds[d].attrs) for d in dims],
        "fixed_inputs": _fixed(fixed_inputs(ds)),
        "variables": variables,
        "points": int(status.size),
        "valid": int(ok.sum()),
        "status": _status_counts(ds["status"].attrs, dict(zip(codes.tolist(), n.tolist(), strict=True))),
    }
