"""The evtms LUT file format (``docs/lut-format.md``) as data.

The rules every LUT follows (global attributes, versions, unit spellings) live
here; what a component's LUT holds (its axes with units and ranges, its
outputs) is declared once by its bench (:mod:`evtms.benches`) and read from the
registry through :func:`component_specs` and the views :data:`AXES`,
:data:`COMPONENT_AXES`, ... built from it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

#: The version evtms writes.
FORMAT_VERSION = 2
#: The versions evtms reads (version 1 is presented in the version 2 shape, see ``docs/lut-format.md``).
READABLE_VERSIONS = (1, 2)
CONVENTIONS = "CF-1.10"


@dataclass(frozen=True)
class AxisSpec:
    """A LUT axis: its units, meaning and the values a bench accepts.

    Attributes
    ----------
    name : str
        Fixed axis name.
    units : str
        UDUNITS string (SI).
    long_name : str
        Human-readable meaning.
    lower, upper : float
        Allowed range of values.
    lower_open, upper_open : bool
        Whether the bound itself is excluded.
    cli_units : dict of str to (float, float)
        Unit suffixes accepted on the command line, as (factor, offset) to SI.
    """

    name: str
    units: str
    long_name: str
    lower: float = float("-inf")
    upper: float = float("inf")
    lower_open: bool = True
    upper_open: bool = True
    cli_units: tuple[tuple[str, float, float], ...] = ()

    def allowed(self) -> str:
        """The allowed range in words, e.g. ``0 < fan <= 1``."""
        unit = "" if self.units == "1" else f" {self.units}"
        has_lower, has_upper = self.lower != float("-inf"), self.upper != float("inf")
        lower_op = "<" if self.lower_open else "<="
        upper_op = "<" if self.upper_open else "<="
        if has_lower and has_upper:
            return f"{self.lower:g} {lower_op} {self.name} {upper_op} {self.upper:g}{unit}"
        if has_lower:
            return f"{self.name} {'>' if self.lower_open else '>='} {self.lower:g}{unit}"
        if has_upper:
            return f"{self.name} {upper_op} {self.upper:g}{unit}"
        return f"any finite {self.name}{unit}"


#: Unit suffixes the command line and the files accept, as (suffix, factor, offset) to SI.
PRESSURE_UNITS = (("Pa", 1.0, 0.0), ("kPa", 1e3, 0.0), ("MPa", 1e6, 0.0), ("bar", 1e5, 0.0))
TEMPERATURE_UNITS = (("K", 1.0, 0.0), ("degC", 1.0, 273.15), ("C", 1.0, 273.15))
FRACTION_UNITS = (("%", 0.01, 0.0),)
MASS_FLOW_UNITS = (("kg/s", 1.0, 0.0), ("g/s", 1e-3, 0.0))
ENTHALPY_UNITS = (("J/kg", 1.0, 0.0), ("kJ/kg", 1e3, 0.0))

#: The module holding the component registry: its ``component_specs()`` gives
#: every component's :class:`ComponentSpec`. The LUT layer knows no component
#: itself; each is declared once, in its bench module, and read from there.
COMPONENT_REGISTRY = "evtms.benches"


@dataclass(frozen=True)
class ComponentSpec:
    """What a LUT of one component holds, as its bench declares it.

    Attributes
    ----------
    name : str
        Component name (the file's ``component`` attribute).
    axes : tuple of str
        Standard axes in the format's order (``T_in`` may be given as ``h_in``).
    extra_axes : tuple of str
        Axes a grid may add after the standard ones.
    axis_specs : mapping of str to AxisSpec
        Every axis the component accepts (standard, alternate and extra).
    variables : mapping of str to (str, str)
        Units and long name of every output.
    required : tuple of str
        Outputs every file of the component holds (``status`` first).
    """

    name: str
    axes: tuple[str, ...]
    extra_axes: tuple[str, ...]
    axis_specs: Mapping[str, AxisSpec]
    variables: Mapping[str, tuple[str, str]]
    required: tuple[str, ...]


_SPECS: dict[str, ComponentSpec] = {}


def component_specs() -> dict[str, ComponentSpec]:
    """Every registered component, from :data:`COMPONENT_REGISTRY` (read once)."""
    if not _SPECS:
        specs = importlib.import_module(COMPONENT_REGISTRY).component_specs()
        axes: dict[str, AxisSpec] = {}
        for spec in specs.values():
            for name, axis in spec.axis_specs.items():
                if axes.setdefault(name, axis) != axis:
                    raise ValueError(f"axis {name!r} is declared twice with different meanings ({spec.name})")
        _SPECS.update(specs)
    return _SPECS


class _View(Mapping):
    """A read-only mapping computed from the registered components on first use."""

    def __init__(self, build: Callable[[dict[str, ComponentSpec]], dict]) -> None:
        self._build = build
        self._data: dict | None = None

    def _get(self) -> dict:
        if self._data is None:
            self._data = self._build(component_specs())
        return self._data

    def __getitem__(self, key: str) -> Any:
        return self._get()[key]

    def __iter__(self) -> Iterator:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())

    def __repr__(self) -> str:
        return repr(self._get())


def _all_axes(specs: dict[str, ComponentSpec]) -> dict[str, AxisSpec]:
    return {k: v for spec in specs.values() for k, v in spec.axis_specs.items()}


def _all_variables(specs: dict[str, ComponentSpec]) -> dict[str, tuple[str, str]]:
    out: dict[str, tuple[str, str]] = {}
    for spec in specs.values():
        for k, v in spec.variables.items():
            out.setdefault(k, v)
    return out


#: Axis name -> :class:`AxisSpec`, over every registered component.
AXES: Mapping[str, AxisSpec] = _View(_all_axes)
#: Variable name -> (units, long name), the first component's meaning where
#: components differ (``Q`` is to air in a coil, to coolant in the chiller):
#: per component, see :func:`variable_spec`.
VARIABLES: Mapping[str, tuple[str, str]] = _View(_all_variables)
#: Component -> its standard axes, in the format's order.
COMPONENT_AXES: Mapping[str, tuple[str, ...]] = _View(lambda s: {k: v.axes for k, v in s.items()})
#: Component -> the data variables every file of that component holds.
COMPONENT_VARIABLES: Mapping[str, tuple[str, ...]] = _View(lambda s: {k: v.required for k, v in s.items()})
#: Component -> axes a grid may add to its standard ones.
EXTRA_AXES: Mapping[str, tuple[str, ...]] = _View(lambda s: {k: v.extra_axes for k, v in s.items()})


def variable_spec(component: str | None, name: str) -> tuple[str, str] | None:
    """(units, long name) of variable ``name`` of ``component``, or None if unknown."""
    specs = component_specs()
    if component in specs and name in specs[component].variables:
        return specs[component].variables[name]
    return VARIABLES.get(name)


#: Inlet-state axes that may stand in for each other at the same position.
ALTERNATE_AXES = {"T_in": "h_in", "h_in": "T_in"}

#: Unit spellings a file may use (UDUNITS) -> the ``cli_units`` suffix with the same meaning.
#: ``C`` is not among them: in UDUNITS it is the coulomb.
UNIT_ALIASES = {
    "kg s-1": "kg/s",
    "kg/s": "kg/s",
    "g s-1": "g/s",
    "g/s": "g/s",
    "Pa": "Pa",
    "pascal": "Pa",
    "kPa": "kPa",
    "MPa": "MPa",
    "bar": "bar",
    "K": "K",
    "kelvin": "K",
    "degC": "degC",
    "degree_Celsius": "degC",
    "degrees_Celsius": "degC",
    "celsius": "degC",
    "Celsius": "degC",
    "J kg-1": "J/kg",
    "J/kg": "J/kg",
    "kJ kg-1": "kJ/kg",
    "kJ/kg": "kJ/kg",
    "%": "%",
    "percent": "%",
}


def unit_conversion(axis: str, units: object) -> tuple[float, float] | None:
    """(factor, offset) that turn values of ``axis`` in ``units`` into its SI units, or None.

    ``si = value * factor + offset``. Only exact conversions are known: the
    axis' own units, and the ``cli_units`` of :data:`AXES` under their UDUNITS
    spellings (``bar``, ``kPa``, ``degC``, ``degree_Celsius``, ``g s-1``, ...).
    """
    spec = AXES[axis]
    if not isinstance(units, str):
        return None
    units = units.strip()
    if units == spec.units:
        return 1.0, 0.0
    suffix = UNIT_ALIASES.get(units)
    for name, factor, offset in spec.cli_units:
        if name == suffix:
            return factor, offset
    return None


def accepted_units(axis: str) -> list[str]:
    """Every spelling of units :func:`unit_conversion` converts for ``axis``."""
    return [u for u in dict.fromkeys([AXES[axis].units, *UNIT_ALIASES]) if unit_conversion(axis, u) is not None]


REQUIRED_GLOBAL_ATTRS = (
    "Conventions",
    "title",
    "component",
    "fluid",
    "evtms_version",
    "coolprop_version",
    "grid",
    "parameters",
    "environment",
    "created",
    "history",
    "lut_format_version",
)

#: Global attributes holding JSON objects (``fixed_inputs`` only from version 2, and optional).
JSON_GLOBAL_ATTRS = ("parameters", "environment", "fixed_inputs")

#: Global attribute saying what a LUT tabulates, one of :data:`LUT_KINDS`. A file without it is a
#: component LUT (every bench LUT: their files carry no such attribute).
KIND_ATTR = "lut_kind"
#: ``component``: one bench's outputs over its inputs, NaN at invalid points (the rules above);
#: ``map``: a circuit's steady outputs over its commands and boundaries, complete (every node holds
#: numbers; invalid ones are filled from a donor and marked), written by
#: :func:`evtms.luts.io.write_map_lut` and read by :func:`evtms.luts.validate.read_map_lut`.
LUT_KINDS = ("component", "map")
#: Global attributes every map LUT carries (its own provenance comes besides them).
MAP_REQUIRED_GLOBAL_ATTRS = (
    "Conventions",
    "title",
    KIND_ATTR,
    "map_name",
    "evtms_version",
    "created",
    "history",
    "lut_format_version",
)
#: Global attribute of a map LUT listing (space-separated) its other global attributes that hold JSON.
MAP_JSON_ATTR = "json_attributes"
#: Data variables stored as int8 flags (no fill value): every LUT's ``status``, and a map's ``filled``
#: (1 where a node's values were copied from a donor node). Every other data variable is a float.
FLAG_VARIABLES = ("status", "filled")
