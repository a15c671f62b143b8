"""Bench figures from a LUT: response lines per axis and 3-D maps over two axes.

As the thesis showed its benches: the main output (``Q``, ``dp`` or ``W``)
against each input with the others at a base point, one line per value of the
mass-flow (or speed) axis, and surfaces over two inputs, one per mass flow.
The data of every figure comes from a ``*_data`` function that returns exactly
what is drawn, so tests check the numbers, not pixels. Invalid points are NaN
and stay gaps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.benches import BENCHES
from evtms.errors import EvtmsInputError
from evtms.luts.schema import AXES
from evtms.luts.validate import fixed_inputs
from evtms.reports.cycle_plots import _figure, _save

if TYPE_CHECKING:
    import xarray as xr

#: Main output and the family axis (one line/surface per value) per component, as its bench declares.
MAIN = {name: bench.main_output for name, bench in BENCHES.items()}
#: Surface axes per component (the first pair the LUT has), as its bench declares.
SURFACE_AXES = {name: bench.surface_axes for name, bench in BENCHES.items()}
#: Display units: SI unit -> (label, factor to divide by).
_DISPLAY = {
    "Pa": ("MPa", 1e6),
    "kg s-1": ("kg/s", 1.0),
    "K": ("K", 1.0),
    "J kg-1": ("kJ/kg", 1e3),
    "1": ("-", 1.0),
}


def display_unit(ds: xr.Dataset, name: str) -> tuple[str, float]:
    """(label, divisor) to show variable, axis or fixed input ``name`` in engineering units."""
    if name not in ds.variables:  # a fixed input: units of its axis
        units = AXES[name].units if name in AXES else ""
        return _DISPLAY.get(units, (units, 1.0))
    units = ds[name].attrs.get("units", "")
    if units == "W":
        big = np.nanmax(np.abs(ds[name].values)) if ds[name].size else 0.0
        return ("kW", 1e3) if big >= 1e4 else ("W", 1.0)
    if units == "Pa" and name == "dp":
        return ("kPa", 1e3)
    return _DISPLAY.get(units, (units, 1.0))


def label(ds: xr.Dataset, name: str) -> str:
    """Axis label: long name, symbol and engineering unit."""
    unit, _ = display_unit(ds, name)
    return f"{ds[name].attrs.get('long_name', name)}, {name} [{unit}]"


def base_point(ds: xr.Dataset, at: dict[str, float] | None = None) -> dict[str, float]:
    """Base values of every axis: the first grid value (as the thesis did), or the
    nearest grid value to ``at``'s.

    ``at`` may name a fixed input of the LUT (not an axis) at its value only.
    """
    dims = list(ds["status"].dims)
    fixed = fixed_inputs(ds)
    at = at or {}
    for name, value in at.items():
        if name in fixed:
            if abs(value - fixed[name]) > 1e-9 * max(abs(fixed[name]), 1.0):
                unit = AXES[name].units
                raise EvtmsInputError(
                    f"{name} = {value:g} is not allowed in `at`; the LUT was made at {name} = {fixed[name]:g} {unit} "
                    "only (a fixed input, not an axis)"
                )
            continue
        if name not in dims:
            raise EvtmsInputError(f"unknown axis {name!r} in `at`; allowed: {', '.join(dims)}")
    base = {}
    for d in dims:
        values = ds[d].values
        base[d] = float(values[np.argmin(np.abs(values - at[d]))]) if d in at else float(values[0])
    return base


def _valid(ds: xr.Dataset, var: str) -> xr.DataArray:
    ok = np.isin(ds["status"], ds["status"].attrs.get("valid_flag_values", [0]))
    return ds[var].where(ok)


@dataclass
class LineData:
    """What a response-line figure draws: y per family value, against x."""

    axis: str
    x: np.ndarray
    family: str
    lines: dict[float, np.ndarray] = field(default_factory=dict)
    base: dict[str, float] = field(default_factory=dict)


def line_data(ds: xr.Dataset, axis: str, base: dict[str, float]) -> LineData:
    """Main output against ``axis``, other axes at ``base``, one line per family value."""
    component = ds.attrs["component"]
    var, family = MAIN[component]
    y = _valid(ds, var)
    fixed = {d: v for d, v in base.items() if d not in (axis, family)}
    sel = y.sel(fixed)
    data = LineData(axis=axis, x=ds[axis].values, family=family, base=base)
    if family not in ds["status"].dims:  # the family input is fixed: one line
        data.lines[float("nan")] = sel.transpose(axis).values
        return data
    if axis == family:
        data.lines[float("nan")] = sel.values if sel.ndim == 1 else sel.sel({family: ds[family]}).values
        return data
    for f in ds[family].values:
        data.lines[float(f)] = sel.sel({family: f}).transpose(axis).values
    return data


@dataclass
class SurfaceData:
    """What a surface figure draws: Z over (X, Y), one surface per family value."""

    axes: tuple[str, str]
    X: np.ndarray
    Y: np.ndarray
    family: str
    surfaces: dict[float, np.ndarray] = field(default_factory=dict)
    base: dict[str, float] = field(default_factory=dict)


def surface_data(ds: xr.Dataset, axes: tuple[str, str], base: dict[str, float]) -> SurfaceData:
    """Main output over two axes, other axes at ``base``, one surface per family value."""
    component = ds.attrs["component"]
    var, family = MAIN[component]
    a, b = axes
    for name in axes:
        if name not in ds["status"].dims or name == family:
            allowed = ", ".join(d for d in ds["status"].dims if d != family)
            raise EvtmsInputError(f"surface axis {name!r} is not allowed; allowed: {allowed}")
    fixed = {d: v for d, v in base.items() if d not in (a, b, family)}
    sel = _valid(ds, var).sel(fixed)
    X, Y = np.meshgrid(ds[a].values, ds[b].values, indexing="ij")
    data = SurfaceData(axes=(a, b), X=X, Y=Y, family=family, base=base)
    if family not in ds["status"].dims:  # the family input is fixed: one surface
        data.surfaces[float("nan")] = sel.transpose(a, b).values
        return data
    for f in ds[family].values:
        data.surfaces[float(f)] = sel.sel({family: f}).transpose(a, b).values
    return data


def default_surface_axes(ds: xr.Dataset) -> tuple[str, str] | None:
    """The component's usual surface axes, else the first two axes but the family; None if there are not two."""
    for pair in SURFACE_AXES[ds.attrs["component"]]:
        if all(p in ds["status"].dims for p in pair):
            return pair
    dims = [d for d in ds["status"].dims if d != MAIN[ds.attrs["component"]][1]]
    return (dims[0], dims[1]) if len(dims) >= 2 else None


def _base_text(ds: xr.Dataset, base: dict[str, float], skip: tuple[str, ...]) -> str:
    """The other axes' base values, then the LUT's fixed inputs, in engineering units."""
    parts = []
    for d, v in base.items():
        if d in skip:
            continue
        unit, div = display_unit(ds, d)
        parts.append(f"{d} = {v / div:.4g} {unit}")
    for d, v in fixed_inputs(ds).items():
        unit, div = display_unit(ds, d)
        parts.append(f"{d} = {v / div:.4g} {unit} (fixed)")
    return ", ".join(parts)


def draw_line(ds: xr.Dataset, data: LineData, path: str | Path) -> Path:
    var, _ = MAIN[ds.attrs["component"]]
    yu, ydiv = display_unit(ds, var)
    xu, xdiv = display_unit(ds, data.axis)
    fu, fdiv = display_unit(ds, data.family)
    fig = _figure()
    ax = fig.add_subplot()
    for f, y in data.lines.items():
        name = "" if np.isnan(f) else f"{data.family} = {f / fdiv:.4g} {fu}"
        ax.plot(data.x / xdiv, y / ydiv, "o-", label=name or None)
    ax.set_xlabel(label(ds, data.axis))
    ax.set_ylabel(label(ds, var))
    ax.set_title(_base_text(ds, data.base, (data.axis, data.family)), fontsize=8)
    if any(not np.isnan(f) for f in data.lines):
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def draw_surface(ds: xr.Dataset, data: SurfaceData, path: str | Path) -> Path:
    var, _ = MAIN[ds.attrs["component"]]
    a, b = data.axes
    (au, adiv), (bu, bdiv) = display_unit(ds, a), display_unit(ds, b)
    zu, zdiv = display_unit(ds, var)
    fu, fdiv = display_unit(ds, data.family)
    fig = _figure(figsize=(7.5, 6.0))
    ax = fig.add_subplot(projection="3d")
    for k, (f, Z) in enumerate(data.surfaces.items()):
        ax.plot_surface(data.X / adiv, data.Y / bdiv, Z / zdiv, color=f"C{k}", alpha=0.55, edgecolor=f"C{k}", lw=0.4)
        if not np.isnan(f):
            ax.plot([], [], color=f"C{k}", label=f"{data.family} = {f / fdiv:.4g} {fu}")
    ax.set_xlabel(f"{a} [{au}]")
    ax.set_ylabel(f"{b} [{bu}]")
    ax.set_zlabel(f"{var} [{zu}]")
    ax.set_title(_base_text(ds, data.base, (a, b, data.family)), fontsize=8)
    if any(not np.isnan(f) for f in data.surfaces):
        ax.legend(fontsize=7, loc="upper left")
    return _save(fig, path)


def bench_report_figures(
    ds: xr.Dataset,
    folder: str | Path,
    at: dict[str, float] | None = None,
    surface_axes: tuple[str, str] | None = None,
    fmt: str = "png",
) -> list[tuple[str, Path]]:
    """Write every response-line figure and the surface map of a bench LUT.

    Returns (caption, path) per figure, in order.
    """
    folder = Path(folder)
    component = ds.attrs["component"]
    base = base_point(ds, at)
    out = []
    for axis in ds["status"].dims:
        if ds.sizes[axis] < 2:
            continue
        data = line_data(ds, axis, base)
        path = draw_line(ds, data, folder / f"{component}_{MAIN[component][0]}_vs_{axis}.{fmt}")
        out.append((f"{MAIN[component][0]} against {axis}", path))
    pair = surface_axes or default_surface_axes(ds)
    if pair is None:  # fewer than two axes besides the family: no surface
        return out
    data = surface_data(ds, pair, base)
    path = draw_surface(ds, data, folder / f"{component}_{MAIN[component][0]}_map_{pair[0]}_{pair[1]}.{fmt}")
    out.append((f"{MAIN[component][0]} over {pair[0]} and {pair[1]}", path))
    return out
