"""Compare two LUT files of the same component on their common grid."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.luts.validate import valid_flags

if TYPE_CHECKING:
    import xarray as xr


@dataclass
class VariableDiff:
    """Differences of one variable over the common valid points."""

    name: str
    units: str
    max_abs: float
    rms: float
    max_rel: float
    points: int


@dataclass
class LutDiff:
    """What differs between two LUTs."""

    common_shape: tuple[int, ...]
    variables: list[VariableDiff] = field(default_factory=list)
    status_changed: int = 0
    parameters: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    attributes: dict[str, tuple[Any, Any]] = field(default_factory=dict)


def _flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(obj, dict):
        out: dict[str, Any] = {}
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    return {prefix.rstrip("."): obj}


def lut_diff(a: xr.Dataset, b: xr.Dataset) -> LutDiff:
    """Per-variable max and RMS differences on the common grid, and provenance changes.

    The common grid is, per axis, the values both files share exactly. Points
    valid in both files are compared; ``status_changed`` counts common points
    whose status differs.

    Raises
    ------
    EvtmsInputError
        Different components or axes, or no common grid point.
    """
    if a.attrs["component"] != b.attrs["component"]:
        raise EvtmsInputError(f"cannot compare a {a.attrs['component']} LUT with a {b.attrs['component']} LUT")
    dims_a, dims_b = list(a["status"].dims), list(b["status"].dims)
    if dims_a != dims_b:
        raise EvtmsInputError(f"axes differ: {', '.join(dims_a)} vs {', '.join(dims_b)}")
    sel = {}
    for d in dims_a:
        common = np.intersect1d(a[d].values, b[d].values)
        if common.size == 0:
            raise EvtmsInputError(f"axis {d} has no value in common; the files share no grid point")
        sel[d] = common
    sa, sb = a.sel(sel), b.sel(sel)
    result = LutDiff(common_shape=tuple(len(v) for v in sel.values()))
    ok = np.isin(sa["status"].values, valid_flags(a)) & np.isin(sb["status"].values, valid_flags(b))
    result.status_changed = int((sa["status"].values != sb["status"].values).sum())
    for v in sa.data_vars:
        if v == "status" or v not in sb.data_vars or sa[v].dtype.kind != "f":
            continue
        x, y = sa[v].values[ok], sb[v].transpose(*dims_a).values[ok]
        d = np.abs(x - y)
        scale = np.maximum(np.abs(x), np.abs(y))
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.where(scale > 0, d / scale, 0.0)
        result.variables.append(
            VariableDiff(
                name=v,
                units=str(sa[v].attrs.get("units", "")),
                max_abs=float(d.max()) if d.size else float("nan"),
                rms=float(np.sqrt(np.mean(d**2))) if d.size else float("nan"),
                max_rel=float(rel.max()) if rel.size else float("nan"),
                points=int(d.size),
            )
        )
    pa = _flatten(json.loads(a.attrs.get("parameters", "{}")))
    pb = _flatten(json.loads(b.attrs.get("parameters", "{}")))
    for key in sorted(set(pa) | set(pb)):
        if pa.get(key) != pb.get(key):
            result.parameters[key] = (pa.get(key), pb.get(key))
    for attr in ("evtms_version", "coolprop_version", "fluid", "grid", "environment"):
        if a.attrs.get(attr) != b.attrs.get(attr):
            result.attributes[attr] = (a.attrs.get(attr), b.attrs.get(attr))
    return result
