"""Grids: presets by name, axis specifications from the command line, validation.

An axis is given as ``name=start:stop:count[unit]`` or ``name=v1,v2,...[unit]``.
:func:`parse_axes` parses the ``--axis`` options of one bench (refusing an
axis given twice, or ``T_in`` with ``h_in``), :func:`build_grid` completes them
from a preset, and :func:`check_grid_size` refuses a grid too large to
allocate before anything is allocated. Parsed values are rounded to 12
significant digits (:func:`round_sig`), so ``-40degC`` is exactly 233.15 K and
the third value of ``0.1:1:10`` exactly 0.3. Values that make no physical sense
in SI (a pressure of 1 Pa, a temperature of 25 K, a mass flow of 5 kg/s, a
fan fraction of 50) are refused with the unit the user likely meant.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from evtms.benches.base import Bench
from evtms.errors import EvtmsInputError
from evtms.fluid import Fluid
from evtms.luts.schema import ALTERNATE_AXES, AXES
from evtms.luts.validate import available_memory

_SPEC = re.compile(r"^\s*(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*=\s*(?P<body>.+?)\s*$")
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_NUMBER_UNIT = re.compile(rf"(?P<number>{_NUMBER})\s*(?P<unit>[A-Za-z/%]+)")
_NOT_FINITE = re.compile(r"[-+]?(?:nan|inf|infinity)", re.IGNORECASE)

#: Most points a grid may have unless the caller raises the limit (``--max-points``).
DEFAULT_MAX_POINTS = 200_000_000
#: Share of the available memory a grid's estimated working set may take.
MEMORY_SHARE = 0.8
#: Working bytes per grid point when the bench is not known: 16 float64 variables.
DEFAULT_BYTES_PER_POINT = 128
#: Significant digits parsed axis values are rounded to.
SIGNIFICANT_DIGITS = 12

#: R134a's triple-point pressure [Pa] (CoolProp HEOS), the floor of ``p_in`` when no fluid is given.
R134A_P_TRIPLE = 389.56
#: Lowest refrigerant pressure [Pa] taken as meant in Pa.
MIN_PRESSURE = 1e3
#: Lowest temperature [K] taken as meant in K.
MIN_TEMPERATURE = 150.0
#: Highest refrigerant mass flow [kg/s] of an EV circuit taken as meant in kg/s.
MAX_MASS_FLOW = 1.0

_TEMPERATURE_AXES = tuple(n for n, a in AXES.items() if a.units == "K")
_FRACTION_AXES = tuple(n for n, a in AXES.items() if any(u == "%" for u, _, _ in a.cli_units))


def allowed_axes(bench: Bench) -> tuple[str, ...]:
    """Every axis name a grid of ``bench`` may use."""
    names = list(bench.axes)
    for a in bench.axes:
        if a in ALTERNATE_AXES:
            names.append(ALTERNATE_AXES[a])
    return tuple(names) + bench.extra_axes


def round_sig(values: np.ndarray | Sequence[float] | float, digits: int = SIGNIFICANT_DIGITS) -> np.ndarray:
    """``values`` rounded to ``digits`` significant digits, as the nearest float to the decimal.

    Unit conversions and ``linspace`` leave binary noise in the last digits
    (``-40 + 273.15 = 233.14999999999998``, ``linspace(0.1, 1, 10)[2] =
    0.30000000000000004``); after rounding these are exactly ``233.15`` and
    ``0.3``, so closed bounds accept them and equal inputs give equal grids.

    Parameters
    ----------
    values : array_like
        Numbers [any units]; zeros and non-finite values are returned as they are.
    digits : int
        Significant digits, 1 to 15.

    Returns
    -------
    numpy.ndarray
        Rounded values (float64, at least 1-D shape of ``values``).
    """
    x = np.array(values, dtype=float, ndmin=1)
    out = x.copy()
    ok = np.isfinite(x) & (x != 0)
    if not ok.any():
        return out
    v = x[ok]
    k = digits - 1 - np.floor(np.log10(np.abs(v))).astype(int)
    # Scale by an exact power of ten so the rounded integer divided (or multiplied) by it is the
    # correctly rounded decimal: k >= 0 divides by 10**k, k < 0 multiplies by 10**-k.
    pos = k >= 0
    r = np.empty_like(v)
    with np.errstate(over="ignore", invalid="ignore"):
        scale = 10.0 ** k[pos]
        r[pos] = np.round(v[pos] * scale) / scale
        scale = 10.0 ** (-k[~pos])
        r[~pos] = np.round(v[~pos] / scale) * scale
    # Values so tiny that the scale overflows (below about 1e-290) stay as they are.
    out[ok] = np.where(np.isfinite(r), r, v)
    return out


def _fmt(v: float) -> str:
    return f"{v:.12g}"


def _gb(n: float) -> str:
    return f"{n / 1e9:.1f} GB"


def check_grid_size(
    shape: Mapping[str, int] | Sequence[int],
    max_points: int = DEFAULT_MAX_POINTS,
    *,
    bytes_per_point: int = DEFAULT_BYTES_PER_POINT,
    available_bytes: int | None = None,
) -> int:
    """Refuse a grid with too many points before any of it is allocated.

    Parameters
    ----------
    shape : mapping of str to int, or sequence of int
        Axis name -> number of values (or just the numbers), in grid order.
    max_points : int
        Most points allowed [1].
    bytes_per_point : int
        Estimated working memory per point [bytes] (the LUT's variables as float64).
    available_bytes : int, optional
        Memory available [bytes]; read from ``/proc/meminfo`` (``MemAvailable``)
        if not given. If it cannot be found, only ``max_points`` is checked.

    Returns
    -------
    int
        Number of points of the grid.

    Raises
    ------
    EvtmsInputError
        More than ``max_points`` points, or an estimated working set above
        80 % of the available memory, e.g. ``grid of 1,000,000,000 points
        (mdot 1000000000 x fan 4) is above the limit of 200,000,000 points;
        raise it with `max_points` or use a coarser grid``.
    """
    sizes = dict(shape) if isinstance(shape, Mapping) else {f"axis {i}": int(n) for i, n in enumerate(shape)}
    points = math.prod(int(n) for n in sizes.values())
    shown = " x ".join(f"{name} {n}" for name, n in sizes.items())
    if points > max_points:
        raise EvtmsInputError(
            f"grid of {points:,} points ({shown}) is above the limit of {max_points:,} points; "
            "raise it with `max_points` or use a coarser grid"
        )
    available = available_memory() if available_bytes is None else available_bytes
    needed = points * bytes_per_point
    if available is not None and needed > MEMORY_SHARE * available:
        raise EvtmsInputError(
            f"grid of {points:,} points ({shown}) needs about {_gb(needed)} of memory, above "
            f"{MEMORY_SHARE:.0%} of the {_gb(available)} available; use a coarser grid"
        )
    return points


def _bytes_per_point(bench: Bench) -> int:
    """Working bytes per point of ``bench``'s grid: its outputs and axes as float64."""
    return 8 * (len(bench.outputs) + len(bench.axes) + len(bench.extra_axes))


def _split_unit(name: str, text: str) -> tuple[list[str], str, str]:
    """``"1:2:3g/s"`` -> (["1", "2", "3"], ":", "g/s"); tokens are not yet checked as numbers."""
    if ":" in text and "," in text:
        raise EvtmsInputError(f"axis {name}: {text!r} mixes ':' and ','; give start:stop:count or v1,v2,...")
    sep = ":" if ":" in text else ","
    tokens = [t.strip() for t in text.split(sep)]
    unit = ""
    last = tokens[-1]
    m = _NUMBER_UNIT.fullmatch(last)
    if m and not _NOT_FINITE.fullmatch(last):
        tokens[-1], unit = m["number"], m["unit"]
    return tokens, sep, unit


def _number(name: str, token: str, text: str) -> float:
    """One number of an axis specification, finite."""
    if not token:
        raise EvtmsInputError(f"axis {name}: empty value in {text!r}; give numbers separated by ',' or ':'")
    if _NOT_FINITE.fullmatch(token):
        raise EvtmsInputError(f"axis {name}: {token!r} is not a finite number; allowed: {AXES[name].allowed()}")
    if not _NUMBER_RE.fullmatch(token):
        where = "" if token == text else f" in {text!r}"
        raise EvtmsInputError(
            f"axis {name}: {token!r}{where} is not a number; give start:stop:count or a comma-separated list"
        )
    value = float(token)
    if not math.isfinite(value):
        raise EvtmsInputError(f"axis {name}: {token!r} is too large to be a number; allowed: {AXES[name].allowed()}")
    return value


def _unit(name: str, unit: str) -> tuple[float, float]:
    """(factor, offset) to SI of ``unit`` on axis ``name``."""
    if not unit:
        return 1.0, 0.0
    units = {u: (f, o) for u, f, o in AXES[name].cli_units}
    if unit not in units:
        allowed = ", ".join(units) or "none (SI values)"
        raise EvtmsInputError(f"axis {name}: unit {unit!r} is not allowed; allowed: {allowed}")
    return units[unit]


def parse_axis(
    spec: str, bench: Bench, max_points: int = DEFAULT_MAX_POINTS, fluid: Fluid | None = None
) -> tuple[str, np.ndarray]:
    """Parse ``name=start:stop:count[unit]`` or ``name=v1,v2,...[unit]`` into SI values.

    Values are converted to SI, rounded to 12 significant digits
    (:func:`round_sig`) and checked with :func:`check_axis`.

    Parameters
    ----------
    spec : str
        The axis specification.
    bench : Bench
        The bench the axis belongs to (its allowed axis names).
    max_points : int
        Most values the axis may have [1]; a larger count is refused before
        any value is allocated.
    fluid : Fluid, optional
        Refrigerant, for its triple-point and critical pressures.

    Raises
    ------
    EvtmsInputError
        Unknown axis name, malformed values (``nan``, ``inf``, ``1e999``,
        empty items, a count that is not a whole number >= 1), an unknown
        unit, too many values, or values that :func:`check_axis` refuses.
    """
    m = _SPEC.match(spec)
    if not m:
        raise EvtmsInputError(f"axis {spec!r} is not of the form name=start:stop:count or name=v1,v2,...")
    name, body = m["name"], m["body"]
    if name not in allowed_axes(bench):
        raise EvtmsInputError(f"unknown axis {name!r} for {bench.name}; allowed: {', '.join(allowed_axes(bench))}")
    tokens, sep, unit = _split_unit(name, body)
    if sep == ":":
        if len(tokens) != 3:
            raise EvtmsInputError(f"axis {name}: {body!r} must be start:stop:count")
        start, stop = _number(name, tokens[0], body), _number(name, tokens[1], body)
        count_text = tokens[2]
        count = float(count_text) if _NUMBER_RE.fullmatch(count_text) else math.nan
        if not math.isfinite(count) or count != int(count) or count < 1:
            raise EvtmsInputError(f"axis {name}: count {count_text!r} must be a whole number >= 1")
        n = int(count)
        check_grid_size({name: n}, max_points, bytes_per_point=_bytes_per_point(bench))
        factor, offset = _unit(name, unit)
        values = np.linspace(start, stop, n)
    else:
        check_grid_size({name: len(tokens)}, max_points, bytes_per_point=_bytes_per_point(bench))
        numbers = [_number(name, t, body) for t in tokens]
        factor, offset = _unit(name, unit)
        values = np.array(numbers, float)
    values = round_sig(values * factor + offset)
    check_axis(name, values, fluid)
    return name, values


def parse_axes(
    specs: Iterable[str], bench: Bench, max_points: int = DEFAULT_MAX_POINTS, fluid: Fluid | None = None
) -> dict[str, np.ndarray]:
    """Parse every ``--axis`` of one bench into ``{name: SI values}``.

    Parameters
    ----------
    specs : iterable of str
        Axis specifications (see :func:`parse_axis`).
    bench : Bench
        The bench.
    max_points : int
        Most points the given axes may span together [1].
    fluid : Fluid, optional
        Refrigerant, for its triple-point and critical pressures.

    Raises
    ------
    EvtmsInputError
        An axis is given twice, ``T_in`` and ``h_in`` are both given, the
        axes span more than ``max_points`` points, or :func:`parse_axis`
        refuses one.
    """
    axes: dict[str, np.ndarray] = {}
    given: dict[str, str] = {}
    for spec in specs:
        name, values = parse_axis(spec, bench, max_points, fluid)
        if name in axes:
            raise EvtmsInputError(
                f"axis {name} is given twice ({given[name].strip()!r} and {spec.strip()!r}); give each axis once"
            )
        alt = ALTERNATE_AXES.get(name)
        if alt in axes:
            raise EvtmsInputError(
                f"axes {alt} and {name} both set the refrigerant inlet state ({given[alt].strip()!r} and "
                f"{spec.strip()!r}); give one of them"
            )
        axes[name], given[name] = values, spec
        check_grid_size({k: len(v) for k, v in axes.items()}, max_points, bytes_per_point=_bytes_per_point(bench))
    return axes


def parse_value(name: str, text: str) -> float:
    """One value of axis ``name`` with an optional unit suffix, in SI, rounded to 12 significant digits.

    Raises
    ------
    EvtmsInputError
        Not one finite number, or a unit the axis does not accept.
    """
    t = text.strip()
    m = _NUMBER_UNIT.fullmatch(t)
    number, unit = (m["number"], m["unit"]) if m and not _NOT_FINITE.fullmatch(t) else (t, "")
    if not _NUMBER_RE.fullmatch(number) or not math.isfinite(float(number)):
        raise EvtmsInputError(f"{name}: {text!r} is not a finite number (with an optional unit)")
    factor, offset = 1.0, 0.0
    if unit:
        units = {u: (f, o) for u, f, o in AXES[name].cli_units} if name in AXES else {}
        if unit not in units:
            raise EvtmsInputError(f"{name}: unit {unit!r} is not allowed; allowed: {', '.join(units) or 'none'}")
        factor, offset = units[unit]
    return float(round_sig(float(number) * factor + offset)[0])


def _pressure_unit(v: float) -> str:
    """The unit a pressure typed as ``v`` most likely meant: MPa, bar or kPa by magnitude."""
    if v <= 4:
        return "MPa"
    return "bar" if v <= 40 else "kPa"


def unit_hint(name: str, value: float) -> str:
    """``"; did you mean 25degC?"`` if ``value`` (SI) of axis ``name`` looks typed in another unit, else ``""``."""
    v = _fmt(value)
    if name == "p_in" and 0 < value < MIN_PRESSURE:
        return f"; did you mean {v}{_pressure_unit(value)}?"
    if name in _TEMPERATURE_AXES and -273.15 < value < MIN_TEMPERATURE:
        return f"; did you mean {v}degC?"
    if name == "mdot" and MAX_MASS_FLOW < value <= 1000:
        return f"; did you mean {v}g/s?"
    if name in _FRACTION_AXES and 1 < value <= 100:
        return f"; did you mean {v}%?"
    return ""


def _shown(values: np.ndarray, most: int = 8) -> str:
    """Up to ``most`` values for a message, with ``...`` for the rest."""
    if values.size <= most:
        return ", ".join(_fmt(v) for v in values)
    return ", ".join(_fmt(v) for v in values[: most - 1]) + f", ... ({values.size} values)"


def check_axis(name: str, values: np.ndarray, fluid: Fluid | None = None) -> None:
    """Check that ``values`` are finite, strictly increasing, within the axis' range and physically sensible.

    Values that make no sense in SI (``p_in`` below the fluid's triple-point
    pressure or 1 kPa, a temperature below 150 K, ``mdot`` above 1 kg/s, a
    fraction above 1) are refused with the unit they were likely meant in.
    With ``fluid``, refrigerant pressures must also lie below the critical
    pressure and refrigerant temperatures within the equation of state's
    range; without it, R134a's triple-point pressure is used.

    Raises
    ------
    EvtmsInputError
        One line naming the axis, the value and what is allowed.
    """
    axis = AXES[name]
    values = np.asarray(values, float)
    if values.size == 0:
        raise EvtmsInputError(f"axis {name}: no values")
    if not np.all(np.isfinite(values)):
        raise EvtmsInputError(f"axis {name}: values must be finite, got {_shown(values)}")
    if np.any(np.diff(values) <= 0):
        raise EvtmsInputError(f"axis {name}: values must be strictly increasing, got {_shown(values)}")
    ends = (float(values[0]), float(values[-1]))
    for v in ends:
        too_low = v <= axis.lower if axis.lower_open else v < axis.lower
        too_high = v >= axis.upper if axis.upper_open else v > axis.upper
        if too_low or too_high:
            raise EvtmsInputError(
                f"axis {name}: value {_fmt(v)} is not allowed; allowed: {axis.allowed()}{unit_hint(name, v)}"
            )
    lo, hi = ends
    if name == "p_in":
        p_triple = fluid.p_triple if fluid is not None else R134A_P_TRIPLE
        fluid_name = fluid.name if fluid is not None else "R134a"
        if lo < p_triple:
            raise EvtmsInputError(
                f"axis p_in: value {_fmt(lo)} Pa is below {fluid_name}'s triple-point pressure "
                f"{_fmt(round_sig(p_triple, 4)[0])} Pa{unit_hint(name, lo)}"
            )
        if lo < MIN_PRESSURE:
            raise EvtmsInputError(
                f"axis p_in: value {_fmt(lo)} Pa is below {MIN_PRESSURE / 1e3:g} kPa, lower than a refrigerant circuit "
                f"runs{unit_hint(name, lo)}"
            )
    if name in _TEMPERATURE_AXES and lo < MIN_TEMPERATURE:
        raise EvtmsInputError(
            f"axis {name}: value {_fmt(lo)} K is below {MIN_TEMPERATURE:g} K, colder than any state a bench "
            f"handles{unit_hint(name, lo)}"
        )
    if name == "mdot" and hi > MAX_MASS_FLOW:
        raise EvtmsInputError(
            f"axis mdot: value {_fmt(hi)} kg/s is above {MAX_MASS_FLOW:g} kg/s, more than an EV refrigerant "
            f"circuit carries{unit_hint(name, hi)}"
        )
    if fluid is None:
        return
    if name == "p_in" and hi >= fluid.p_crit:
        raise EvtmsInputError(
            f"axis p_in: value {_fmt(hi)} Pa is at or above the critical pressure of {fluid.name}; "
            f"allowed: 0 < p_in < {fluid.p_crit:g} Pa"
        )
    if name == "T_in":
        for v in ends:
            if not fluid.T_triple <= v <= fluid.T_max:
                raise EvtmsInputError(
                    f"axis T_in: value {_fmt(v)} K is outside the range of {fluid.name}'s equation of state; "
                    f"allowed: {fluid.T_triple:g} <= T_in <= {fluid.T_max:g} K"
                )


def build_grid(
    bench: Bench, preset: str | None, overrides: dict[str, np.ndarray], max_points: int = DEFAULT_MAX_POINTS
) -> dict[str, np.ndarray]:
    """Axis values of a grid, in the bench's order (extra axes last).

    Parameters
    ----------
    bench : Bench
        The bench.
    preset : str or None
        Grid preset that supplies every standard axis, or None.
    overrides : dict of str to array
        Axes that replace or add to the preset's (``h_in`` replaces ``T_in``
        at its position, and the other way round).
    max_points : int
        Most points the whole grid may have [1] (see :func:`check_grid_size`).

    Raises
    ------
    EvtmsInputError
        Unknown preset, ``overrides`` with both ``T_in`` and ``h_in``, an
        axis without values, or a grid too large.
    """
    if preset is not None and preset not in bench.presets:
        allowed = ", ".join(bench.presets) or "none"
        raise EvtmsInputError(f"unknown grid preset {preset!r} for {bench.name}; allowed: {allowed}")
    for name, alt in ALTERNATE_AXES.items():
        if name < alt and name in overrides and alt in overrides:
            raise EvtmsInputError(f"axes {name} and {alt} both set the refrigerant inlet state; give one of them")
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
            raise EvtmsInputError(f"axis {name} of {bench.name} has no values; give it with `axis` {name}=...")
    for name in bench.extra_axes:
        if name in overrides:
            grid[name] = np.asarray(overrides[name], float)
        elif name in base:
            grid[name] = np.asarray(base[name], float)
    check_grid_size({k: len(v) for k, v in grid.items()}, max_points, bytes_per_point=_bytes_per_point(bench))
    return grid
