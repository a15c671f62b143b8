"""Compare two LUT files of the same component on their common grid."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.luts.validate import fixed_inputs, valid_flags

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

    The common grid is, per input, the values both files share exactly; an
    input that is an axis in one file and a fixed input of the other
    contributes the fixed value (if the axis has it). Points valid in both
    files are compared; ``status_changed`` counts common points whose status
    differs.

    Raises
    ------
    EvtmsInputError
        Different components or inputs, or no common grid point (among them
        fixed inputs of different values).
    """
    if a.attrs["component"] != b.attrs["component"]:
        raise EvtmsInputError(f"cannot compare a {a.attrs['component']} LUT with a {b.attrs['component']} LUT")
    dims_a, dims_b = list(a["status"].dims), list(b["status"].dims)
    fixed_a, fixed_b = fixed_inputs(a), fixed_inputs(b)
    inputs_a, inputs_b = dims_a + list(fixed_a), dims_b + list(fixed_b)
    if set(inputs_a) != set(inputs_b):
        raise EvtmsInputError(f"inputs differ: {', '.join(inputs_a)} vs {', '.join(inputs_b)}")
    sel_a, sel_b = {}, {}
    for d in inputs_a:
        va = a[d].values if d in dims_a else np.array([fixed_a[d]])
        vb = b[d].values if d in dims_b else np.array([fixed_b[d]])
        common = np.intersect1d(va, vb)
        if common.size == 0:
            if d in fixed_a and d in fixed_b:
                raise EvtmsInputError(
                    f"fixed input {d} is {fixed_a[d]:g} in one file and {fixed_b[d]:g} in the other; "
                    "the files share no grid point"
                )
            raise EvtmsInputError(f"axis {d} has no value in common; the files share no grid point")
        if d in dims_a and d in dims_b:
            sel_a[d] = sel_b[d] = common
        elif d in dims_a:
            sel_a[d] = common[0]  # the other file's fixed value: this axis drops out
        elif d in dims_b:
            sel_b[d] = common[0]
    dims = [d for d in dims_a if d in dims_b]
    sa, sb = a.sel(sel_a), b.sel(sel_b)
    result = LutDiff(common_shape=tuple(len(sel_a[d]) for d in dims))
    status_a, status_b = sa["status"].transpose(*dims).values, sb["status"].transpose(*dims).values
    ok = np.isin(status_a, valid_flags(a)) & np.isin(status_b, valid_flags(b))
    result.status_changed = int((status_a != status_b).sum())
    for v in sa.data_vars:
        if v == "status" or v not in sb.data_vars or sa[v].dtype.kind != "f":
            continue
        x, y = sa[v].transpose(*dims).values[ok], sb[v].transpose(*dims).values[ok]
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
    for attr in ("evtms_version", "coolprop_version", "fluid", "grid", "environment", "lut_format_version"):
        if a.attrs.get(attr) != b.attrs.get(attr):
            result.attributes[attr] = (a.attrs.get(attr), b.attrs.get(attr))
    if fixed_a != fixed_b:
        result.attributes["fixed_inputs"] = (fixed_a, fixed_b)
    storage = {v: (a[v].attrs.get("evtms_storage"), b[v].attrs.get("evtms_storage")) for v in sa.data_vars if v in b}
    for v, (x, y) in storage.items():
        if x != y and v != "status":
            result.attributes[f"{v}.evtms_storage"] = (x or "lossless", y or "lossless")
    return result
