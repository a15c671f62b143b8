"""A LUT's contents in brief: axes, variables with ranges, invalid points, provenance."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms.luts.validate import valid_flags

if TYPE_CHECKING:
    import xarray as xr


def lut_summary(ds: xr.Dataset) -> dict[str, Any]:
    """Facts about a LUT for ``evtms lut info`` and reports.

    Returns
    -------
    dict
        ``component``, ``fluid``, ``grid``, ``format``; ``axes`` (name, size,
        min, max, units, long_name); ``variables`` (name, units, min, max over
        valid points, long_name); ``points``, ``valid``; ``status`` (code,
        meaning, count); ``provenance`` (versions, created, history);
        ``parameters`` and ``environment`` (parsed JSON).
    """
    dims = list(ds["status"].dims)
    status = ds["status"].values
    ok = np.isin(status, valid_flags(ds))
    axes = [
        {
            "name": d,
            "size": int(ds.sizes[d]),
            "min": float(ds[d].values[0]),
            "max": float(ds[d].values[-1]),
            "units": ds[d].attrs.get("units", ""),
            "long_name": ds[d].attrs.get("long_name", ""),
        }
        for d in dims
    ]
    variables = []
    for v, da in ds.data_vars.items():
        if v == "status":
            continue
        vals = da.values[ok]
        variables.append(
            {
                "name": v,
                "units": da.attrs.get("units", ""),
                "min": float(vals.min()) if vals.size else float("nan"),
                "max": float(vals.max()) if vals.size else float("nan"),
                "long_name": da.attrs.get("long_name", ""),
            }
        )
    codes = np.atleast_1d(ds["status"].attrs["flag_values"])
    meanings = ds["status"].attrs["flag_meanings"].split()
    counts = [
        {"code": int(c), "meaning": m, "count": int((status == c).sum())} for c, m in zip(codes, meanings, strict=True)
    ]
    return {
        "component": ds.attrs.get("component"),
        "fluid": ds.attrs.get("fluid"),
        "grid": ds.attrs.get("grid"),
        "format": int(ds.attrs.get("lut_format_version", 0)),
        "axes": axes,
        "variables": variables,
        "points": int(status.size),
        "valid": int(ok.sum()),
        "status": counts,
        "provenance": {
            k: ds.attrs.get(k) for k in ("evtms_version", "coolprop_version", "created", "history", "title")
        },
        "parameters": json.loads(ds.attrs.get("parameters", "{}")),
        "environment": json.loads(ds.attrs.get("environment", "{}")),
    }
