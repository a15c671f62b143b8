"""The evtms LUT file format (``docs/lut-format.md``) as data.

Axis and variable names, units and meanings live here once; the benches, the
writer, the validator and the exporters all read them from this module.
"""

from __future__ import annotations

from dataclasses import dataclass

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


_PRESSURE_UNITS = (("Pa", 1.0, 0.0), ("kPa", 1e3, 0.0), ("MPa", 1e6, 0.0), ("bar", 1e5, 0.0))
_TEMPERATURE_UNITS = (("K", 1.0, 0.0), ("degC", 1.0, 273.15), ("C", 1.0, 273.15))
_FRACTION_UNITS = (("%", 0.01, 0.0),)

AXES: dict[str, AxisSpec] = {
    a.name: a
    for a in (
        AxisSpec(
            "mdot", "kg s-1", "refrigerant mass flow rate", 0.0, cli_units=(("kg/s", 1.0, 0.0), ("g/s", 1e-3, 0.0))
        ),
        AxisSpec(
            "fan",
            "1",
            "condenser fan speed, fraction of maximum",
            0.0,
            1.0,
            upper_open=False,
            cli_units=_FRACTION_UNITS,
        ),
        AxisSpec(
            "blower",
            "1",
            "evaporator blower air flow, fraction of maximum",
            0.0,
            1.0,
            upper_open=False,
            cli_units=_FRACTION_UNITS,
        ),
        AxisSpec(
            "speed", "1", "compressor speed, fraction of maximum", 0.0, 1.0, upper_open=False, cli_units=_FRACTION_UNITS
        ),
        AxisSpec("p_in", "Pa", "refrigerant inlet pressure", 0.0, cli_units=_PRESSURE_UNITS),
        AxisSpec("T_in", "K", "refrigerant inlet temperature", 0.0, cli_units=_TEMPERATURE_UNITS),
        AxisSpec(
            "h_in", "J kg-1", "refrigerant inlet specific enthalpy", cli_units=(("J/kg", 1.0, 0.0), ("kJ/kg", 1e3, 0.0))
        ),
        AxisSpec("T_res", "K", "outlet reservoir temperature", 0.0, cli_units=_TEMPERATURE_UNITS),
        AxisSpec("pr", "1", "compressor pressure ratio p_out/p_in", 1.0),
        AxisSpec(
            "T_air_in",
            "K",
            "air temperature entering the coil",
            233.15,
            353.15,
            lower_open=False,
            upper_open=False,
            cli_units=_TEMPERATURE_UNITS,
        ),
        AxisSpec(
            "RH_air_in",
            "1",
            "relative humidity of the air entering the coil",
            0.0,
            1.0,
            lower_open=False,
            upper_open=False,
            cli_units=_FRACTION_UNITS,
        ),
    )
}

#: Variable name -> (units, long_name).
VARIABLES: dict[str, tuple[str, str]] = {
    "status": ("1", "point status: 0 valid, other codes per flag_meanings"),
    "h_in": ("J kg-1", "refrigerant specific enthalpy at inlet"),
    "h_out": ("J kg-1", "refrigerant specific enthalpy at outlet"),
    "p_out": ("Pa", "refrigerant outlet pressure"),
    "T_out": ("K", "refrigerant outlet temperature"),
    "x_out": ("1", "outlet thermodynamic quality (h-h_l)/(h_v-h_l)"),
    "Q": ("W", "heat flow from refrigerant to air"),
    "T_air_out": ("K", "air temperature leaving the coil"),
    "Q_latent": ("W", "part of Q that condensed moisture out of the air"),
    "dp": ("Pa", "refrigerant pressure drop p_in - p_out"),
    "W": ("W", "compressor shaft power"),
    "mdot": ("kg s-1", "refrigerant mass flow delivered"),
    "p_in": ("Pa", "compressor suction pressure"),
    "eta_is": ("1", "isentropic efficiency"),
    "eta_vol": ("1", "volumetric efficiency"),
    # evtms extension (not required by the format): a smooth closure variable for cycles.
    "capacity_ratio": ("1", "coil length over the length needed to finish the phase change"),
    "h_out_continued": (
        "J kg-1",
        "outlet enthalpy continued smoothly past the phase boundary (h_out where the outlet is in the last zone)",
    ),
}

#: Component -> axes of the thesis order.
COMPONENT_AXES: dict[str, tuple[str, ...]] = {
    "condenser": ("mdot", "fan", "p_in", "T_in", "T_res"),
    "evaporator": ("mdot", "blower", "p_in", "T_in", "T_res"),
    "expansion_valve": ("T_in", "p_in", "mdot"),
    "compressor": ("speed", "T_in", "pr"),
}

#: Component -> data variables every file of that component holds.
COMPONENT_VARIABLES: dict[str, tuple[str, ...]] = {
    "condenser": ("status", "Q", "h_in", "h_out", "T_out", "p_out", "x_out", "T_air_out", "dp"),
    "evaporator": ("status", "Q", "Q_latent", "h_in", "h_out", "T_out", "p_out", "x_out", "T_air_out", "dp"),
    "expansion_valve": ("status", "dp", "h_in", "h_out", "T_out", "p_out", "x_out"),
    "compressor": ("status", "W", "mdot", "h_in", "h_out", "T_out", "p_out", "eta_is", "eta_vol"),
}

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
