"""Axes and outputs several components share, declared once.

A bench module declares its own axes and outputs (``Bench.axis_specs``,
``Bench.variables``); those it shares with others (refrigerant mass flow,
inlet pressure and state, ...) are here, so that ``mdot`` means the same in
every LUT.
"""

from __future__ import annotations

from evtms.luts.schema import (
    ENTHALPY_UNITS,
    FRACTION_UNITS,
    MASS_FLOW_UNITS,
    PRESSURE_UNITS,
    TEMPERATURE_UNITS,
    AxisSpec,
)

#: Shared axis name -> its specification.
AXES: dict[str, AxisSpec] = {
    a.name: a
    for a in (
        AxisSpec("mdot", "kg s-1", "refrigerant mass flow rate", 0.0, cli_units=MASS_FLOW_UNITS),
        AxisSpec(
            "fan",
            "1",
            "condenser fan speed, fraction of maximum",
            0.0,
            1.0,
            upper_open=False,
            cli_units=FRACTION_UNITS,
        ),
        AxisSpec(
            "blower",
            "1",
            "evaporator blower air flow, fraction of maximum",
            0.0,
            1.0,
            upper_open=False,
            cli_units=FRACTION_UNITS,
        ),
        AxisSpec(
            "speed", "1", "compressor speed, fraction of maximum", 0.0, 1.0, upper_open=False, cli_units=FRACTION_UNITS
        ),
        AxisSpec("p_in", "Pa", "refrigerant inlet pressure", 0.0, cli_units=PRESSURE_UNITS),
        AxisSpec("T_in", "K", "refrigerant inlet temperature", 0.0, cli_units=TEMPERATURE_UNITS),
        AxisSpec("h_in", "J kg-1", "refrigerant inlet specific enthalpy", cli_units=ENTHALPY_UNITS),
        AxisSpec("T_res", "K", "outlet reservoir temperature", 0.0, cli_units=TEMPERATURE_UNITS),
        AxisSpec("pr", "1", "compressor pressure ratio p_out/p_in", 1.0),
        AxisSpec(
            "T_air_in",
            "K",
            "air temperature entering the coil",
            233.15,
            353.15,
            lower_open=False,
            upper_open=False,
            cli_units=TEMPERATURE_UNITS,
        ),
        AxisSpec("mdot_coolant", "kg s-1", "coolant (MEG 50 %) mass flow rate", 0.0, cli_units=MASS_FLOW_UNITS),
        AxisSpec(
            "T_coolant_in",
            "K",
            "coolant temperature entering the exchanger",
            238.15,
            373.15,
            lower_open=False,
            upper_open=False,
            cli_units=TEMPERATURE_UNITS,
        ),
        AxisSpec(
            "RH_air_in",
            "1",
            "relative humidity of the air entering the coil",
            0.0,
            1.0,
            lower_open=False,
            upper_open=False,
            cli_units=FRACTION_UNITS,
        ),
    )
}

#: Outputs several components share: name -> (units, long name).
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
