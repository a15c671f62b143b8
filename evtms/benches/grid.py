"""Grids: presets by name, axis specifications from the command line, validation."""

from __future__ import annotations

import re

import numpy as np

from evtms.benches.base import Bench
from evtms.errors import EvtmsInputError
from evtms.fluid import Fluid
from evtms.luts.schema import ALTERNATE_AXES, AXES

_SPEC = re.compile(r"^\s*(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*=\s*(?P<body>.+?)\s*$")
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_BODY = re.compile(rf"^(?P<values>{_NUMBER}(?:\s*[:,]\s*{_NUMBER})*)\s*(?P<unit>[A-Za-z/%]*)$")


def allowed_axes(bench: Bench) -> tuple[str, ...]:
    """Every axis name a grid of ``bench`` may use."""
    names = list(bench.axes)
    for a in bench.axes:
        if a in ALTERNATE_AXES:
            names.append(ALTERNATE_AXES[a])
    return tuple(names) + bench.extra_axes


def parse_axis(spec: str, bench: Bench) -> tuple[str, np.ndarray]:
    """Parse ``name=start:stop:count[unit]`` or ``name=v1,v2,...[unit]`` into SI values.

    Raises
    ------
    EvtmsInputError
        Unknown axis name, malformed values, an unknown unit, or values that
        are not strictly increasing.
    """
    m = _SPEC.match(spec)
    if not m:
        raise EvtmsInputError(f"axis {spec!r} is not of the form name=start:stop:count or name=v1,v2,...")
    name, body = m["name"], m["body"]
    if name not in allowed_axes(bench):
        raise EvtmsInputError(f"unknown axis {name!r} for {bench.name}; allowed: {', '.join(allowed_axes(bench))}")
    b = _BODY.match(body)
    if not b:
        raise EvtmsInputError(f"axis {name}: {body!r} is not start:stop:count or a comma-separated list of numbers")
    text, unit = b["values"], b["unit"]
    axis = AXES[name]
    factor, offset = 1.0, 0.0
    if unit:
        units = {u: (f, o) for u, f, o in axis.cli_units}
        if unit not in units:
            allowed = ", ".join(units) or "none (SI values)"
            raise EvtmsInputError(f"axis {name}: unit {unit!r} is not allowed; allowed: {allowed}")
        factor, offset = units[unit]
    if ":" in text:
        parts = [p.strip() for p in text.split(":")]
        if len(parts) != 3 or "," in text:
            raise EvtmsInputError(f"axis {name}: {text!r} must be start:stop:count")
        start, stop, count = float(parts[0]), float(parts[1]), float(parts[2])
        if count != int(count) or count < 1:
            raise EvtmsInputError(f"axis {name}: count {parts[2]!r} must be a whole number >= 1")
        values = np.linspace(start, stop, int(count))
    else:
        values = np.array([float(v) for v in text.split(",")])
    values = values * factor + offset
    check_axis(name, values)
    return name, values


def parse_value(name: str, text: str) -> float:
    """One value of axis ``name`` with an optional unit suffix, in SI."""
    b = _BODY.match(text.strip())
    if not b or ":" in b["values"] or "," in b["values"]:
        raise EvtmsInputError(f"{name}: {text!r} is not a number (with an optional unit)")
    unit = b["unit"]
    factor, offset = 1.0, 0.0
    if unit:
        units = {u: (f, o) for u, f, o in AXES[name].cli_units} if name in AXES else {}
        if unit not in units:
            raise EvtmsInputError(f"{name}: unit {unit!r} is not allowed; allowed: {', '.join(units) or 'none'}")
        factor, offset = units[unit]
    return float(b["values"]) * factor + offset


def check_axis(name: str, values: np.ndarray, fluid: Fluid | None = None) -> None:
    """Check that ``values`` are finite, strictly increasing and within the axis' range.

    With ``fluid``, refrigerant pressures must also lie below the critical
    pressure and refrigerant temperatures within the equation of state's range.
    """
    axis = AXES[name]
    if values.size == 0:
        raise EvtmsInputError(f"axis {name}: no values")
    if not np.all(np.isfinite(values)):
        raise EvtmsInputError(f"axis {name}: values must be finite")
    if np.any(np.diff(values) <= 0):
        shown = ", ".join(f"{v:g}" for v in values)
        raise EvtmsInputError(f"axis {name}: values must be strictly increasing, got {shown}")
    for v in (values[0], values[-1]):
        too_low = v <= axis.lower if axis.lower_open else v < axis.lower
        too_high = v >= axis.upper if axis.upper_open else v > axis.upper
        if too_low or too_high:
            raise EvtmsInputError(f"axis {name}: value {v:g} is not allowed; allowed: {axis.allowed()}")
    if fluid is None:
        return
    if name == "p_in" and values[-1] >= fluid.p_crit:
        raise EvtmsInputError(
            f"axis p_in: value {values[-1]:g} Pa is at or above the critical pressure of {fluid.name}; "
            f"allowed: 0 < p_in < {fluid.p_crit:g} Pa"
        )
    if name == "T_in":
        for v in (values[0], values[-1]):
            if not fluid.T_triple <= v <= fluid.T_max:
                raise EvtmsInputError(
                    f"axis T_in: value {v:g} K is outside the range of {fluid.name}'s equation of state; "
                    f"allowed: {fluid.T_triple:g} <= T_in <= {fluid.T_max:g} K"
                )


def build_grid(bench: Bench, preset: str | None, overrides: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Axis values of a grid, in the bench's order (extra axes last).

    ``preset`` supplies every standard axis; ``overrides`` replace or add
    axes (``h_in`` replaces ``T_in`` at its position).
    """
    if preset is not None and preset not in bench.presets:
        allowed = ", ".join(bench.presets) or "none"
        raise EvtmsInputError(f"unknown grid preset {preset!r} for {bench.name}; allowed: {allowed}")
    base = dict(bench.presets[preset]) if preset is not None else {}
    grid: dict[str, np.ndarray] = {}
    for name in bench.axes:
        alt = ALTERNATE_AXES.get(name)
        if alt is not None and alt in overrides:
            grid[alt] = np.asarray(overrides[alt], float)
        elif name in overrides:
            grid[name] = np.asarray(overrides[name], float)
        elif name in base:
            grid[name] = np.asarray(base[name], float)
        elif alt is not None and alt in base:
            grid[alt] = np.asarray(base[alt], float)
        else:
            raise EvtmsInputError(f"axis {name} of {bench.name} has no values; give it with --axis {name}=...")
    for name in bench.extra_axes:
        if name in overrides:
            grid[name] = np.asarray(overrides[name], float)
        elif name in base:
            grid[name] = np.asarray(base[name], float)
    return grid
