"""Condenser bench: air-cooled flat-tube condenser between a refrigerant source and a reservoir.

The refrigerant enters at ``(p_in, T_in)`` (or ``h_in``) with mass flow
``mdot``; ambient air (the bench environment) is blown across the coil by the
fan at fraction ``fan`` of its maximum flow. The steady-state response comes
from the moving-boundary coil model of :mod:`evtms.benches.coil` (vapour,
two-phase and liquid zones, effectiveness-NTU per zone, dry air).

Correlations (see :mod:`evtms.hx.tube`, :mod:`evtms.hx.fins`): Gnielinski single phase
(laminar Nu below Re 2300), Cavallini-Zecchin condensation with Chato's film
condensation, Haaland friction and Mueller-Steinhagen-Heck two-phase pressure
drop; on the air side the louvred-fin Colburn factor of Chang and Wang (1997),
``j = Re_Lp^-0.49 (theta/90)^0.27 (F_p/L_p)^-0.14 ...``, with ``h = j rho V_c
c_p Pr^(-2/3)`` at the core velocity ``V_c``. Its data cover louver-pitch
Reynolds numbers 100 to 3000; the Simscape coil's air flows give Re_Lp of
about 7 (fan 0.05) to 140 (fan 1), so most points use it below its range:
they are valid with status 11 (``valid_air_correlation_outside_range``),
the correlation evaluated as published.

``T_res`` is the downstream reservoir of the thesis bench. In steady state a
reservoir downstream of a forward flow cannot change the coil's response, so
the axis is kept for parity with the thesis and has no effect.

Where this differs from the thesis' Simscape results: at fan fractions of
0.05-0.1 the air stream (about 50-100 W/K) cannot take the whole condensing
load of 0.6-1.6 kW within the 5-16 K between saturation and ambient (the
second law caps the two-phase zone at C_air (T_sat - T_air)), so the outlet
stays two-phase there, Q depends on fan speed and rises with pressure (a
higher saturation temperature). The thesis reported under 1 % fan effect.
From fan 0.33 up the coil condenses fully at every thesis point: Q is then
proportional to mass flow, changes by well under 1 % with fan speed, and
falls slightly with pressure, as the thesis found.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from evtms.benches.base import (
    COMMON_FLAGS,
    STATUS_OUTSIDE_FLUID_RANGE,
    STATUS_PROPERTY_FAILED,
    Bench,
    finish_status,
    first_code,
    pressure_nodes,
)
from evtms.benches.coil import CoilParams, solve_coil
from evtms.fluid import Fluid

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters

#: Two-phase inlet enthalpies of the cycle grid [J/kg]: the condenser behind a water-cooled
#: condenser (the ``cabin+wcc`` chain) takes its partly condensed outlet, from the saturated liquid
#: of the WCC's lowest condensing temperature (227 kJ/kg at 20 degC) to the saturated vapour at
#: -10 degC (393 kJ/kg).
TWO_PHASE_INLETS = tuple(np.arange(220e3, 381e3, 20e3))
#: Superheated inlet enthalpies of the cycle grid [J/kg], every compressor discharge's. The LUT
#: cycle of a circuit without a WCC ahead reads the grid from the first of them up
#: (:data:`evtms.cycle.models.DISCHARGE_WINDOW`).
SUPERHEATED_INLETS = (*np.linspace(400e3, 480e3, 9), 500e3, 520e3)

STATUS_NOT_WARMER_THAN_AIR = 3
STATUS_DP_EXCEEDS_INLET = 4
#: Valid point whose air-side Re_Lp lies outside the Chang and Wang (1997) range (both coil benches).
STATUS_AIR_CORRELATION_OUTSIDE_RANGE = 11

#: What the coil model gives both coil benches (``coil_bench_outputs``), in file order.
COIL_OUTPUTS = (
    "Q",
    "h_in",
    "h_out",
    "T_out",
    "p_out",
    "x_out",
    "T_air_out",
    "dp",
    "capacity_ratio",
    "h_out_continued",
)
OUTPUTS = ("status", *COIL_OUTPUTS)


def inlet_enthalpy(inputs: dict[str, np.ndarray], fluid: Fluid) -> np.ndarray:
    """Refrigerant inlet enthalpy [J/kg] from the ``h_in`` axis or from ``(p_in, T_in)``."""
    if "h_in" in inputs:
        return np.asarray(inputs["h_in"], float).copy()
    return fluid.state("PT", inputs["p_in"], inputs["T_in"], ("H",))["H"]


def coil_bench_outputs(
    inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid, component: str
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    """Run the coil model for a condenser or evaporator bench.

    Returns the outputs (without status), the status array with the shared
    coil codes (valid points whose air-side correlation runs outside its
    range get :data:`STATUS_AIR_CORRELATION_OUTSIDE_RANGE`), and the raw coil
    result.
    """
    mode = component
    air_axis = "fan" if component == "condenser" else "blower"
    p_in = np.asarray(inputs["p_in"], float)
    h_in = inlet_enthalpy(inputs, fluid)
    inlet_bad = ~np.isfinite(h_in)
    res = solve_coil(
        fluid,
        getattr(params, component),
        params.environment,
        p_in,
        np.where(inlet_bad, np.nan, h_in),
        inputs["mdot"],
        inputs[air_axis],
        mode,
        T_air=inputs.get("T_air_in"),
        RH_air=inputs.get("RH_air_in"),
    )
    status = first_code(
        [
            (inlet_bad, STATUS_OUTSIDE_FLUID_RANGE),
            (res["bad_direction"], STATUS_NOT_WARMER_THAN_AIR),
            (res["bad_dp"], STATUS_DP_EXCEEDS_INLET),
            (res["bad_props"], STATUS_PROPERTY_FAILED),
        ],
        p_in.size,
    )
    status[(status == 0) & res["air_outside_range"]] = STATUS_AIR_CORRELATION_OUTSIDE_RANGE
    out = {k: np.asarray(res[k], float).copy() for k in COIL_OUTPUTS if k != "h_in"}
    out["h_in"] = h_in
    return out, status, res


def condenser_heat_rate(inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid) -> dict[str, np.ndarray]:
    """Steady-state condenser response over arrays of bench inputs.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``mdot`` [kg/s], ``fan`` [1], ``p_in`` [Pa], ``T_in`` [K] or
        ``h_in`` [J/kg], ``T_res`` [K] (no effect, see the module notes);
        optionally ``T_air_in`` [K] and ``RH_air_in`` [1] (else the
        environment's air).
    params : Parameters
        Coil geometry (``params.condenser``) and ambient air.
    fluid : Fluid
        Refrigerant properties.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` [W] (> 0, refrigerant to air), ``h_in``, ``h_out`` [J/kg],
        ``T_out`` [K], ``p_out`` [Pa], ``x_out`` [1], ``T_air_out`` [K],
        ``dp`` [Pa], ``capacity_ratio`` [1] (coil length over the length
        needed to condense to saturated liquid: > 1 subcooled outlet, < 1
        two-phase outlet; a smooth function of the inputs where ``x_out`` has
        a kink, which the cycle solver uses), ``h_out_continued`` [J/kg]
        (``h_out`` for a subcooled outlet; otherwise the liquid zone's heat
        rate continued linearly to the negative length ``1 -
        1/capacity_ratio``, for the cycle's subcooling target) and ``status``
        (int8, see :data:`FLAGS`; 0 and 11 are valid).
    """
    out, status, _ = coil_bench_outputs(inputs, params, fluid, "condenser")
    finish_status(status, out, BENCH.valid_flags)
    out["status"] = status
    return out


FLAGS = {
    **COMMON_FLAGS,
    STATUS_NOT_WARMER_THAN_AIR: "refrigerant_inlet_not_warmer_than_air",
    STATUS_DP_EXCEEDS_INLET: "pressure_drop_exceeds_inlet_pressure",
    STATUS_AIR_CORRELATION_OUTSIDE_RANGE: "valid_air_correlation_outside_range",
}

BENCH = Bench(
    name="condenser",
    title="evtms condenser bench: air-cooled flat-tube R134a condenser",
    axes=("mdot", "fan", "p_in", "T_in", "T_res"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=condenser_heat_rate,
    parameters=CoilParams,
    extra_axes=("T_air_in", "RH_air_in"),
    optional_outputs=("capacity_ratio", "h_out_continued"),
    surface_axes=(("p_in", "T_in"), ("p_in", "h_in")),
    valid_flags=(0, STATUS_AIR_CORRELATION_OUTSIDE_RANGE),
    presets={
        "thesis": {
            "mdot": (0.004526, 0.0062, 0.00743, 0.0077),
            "fan": (0.05, 0.1, 0.33, 0.5),
            "p_in": (0.9e6, 1.0e6, 1.1e6, 1.2e6),
            "T_in": (330.0, 345.0, 360.0, 375.0),
            "T_res": (300.0, 315.0, 330.0),
        },
        # Cycle envelope (README): ambient -10-50 degC, fan 0.1-1, condensing -10-91 degC.
        # Saturation temperature and air temperature every 2 K over 15-91 and 15-45 degC: the
        # response hinges on their difference, which is small (a few kelvin) at a fully
        # condensing point. Beyond, for the system simulator (spec 2.5): air every 5 K from
        # -10 degC and at 50 degC, saturation every 4 K from -10 degC and at 13 degC (with fan 1
        # a -10 degC ambient condenses at -9 degC, a 50 degC one at full speed at 55-63 degC),
        # h_in up to 520 kJ/kg (a 50 degC ambient at full speed discharges at up to 495 kJ/kg;
        # the last cell is superheated vapour). Refrigerant flows 24 (not 16) and inlet enthalpies
        # every 10 kJ/kg (not 20): the LUT cycle's discharge pressure hinges on capacity_ratio = 1,
        # whose interpolation error at the physics' cycle states fell from 2.8 to 1.8 % (worst),
        # and the worst COP error of a 100-point chiller-cycle check from 1.36 to 0.88 %.
        # Two-phase inlets every 20 kJ/kg below (TWO_PHASE_INLETS) for the cabin+wcc chain.
        # 3,886,080 points, 18 s with two workers (compiled coil kernel).
        "cycle": {
            "mdot": tuple(np.geomspace(0.002, 0.15, 24)),
            "fan": tuple(np.geomspace(0.1, 1.0, 8)),
            "p_in": pressure_nodes(np.r_[-10.0, -6.0, -2.0, 2.0, 6.0, 10.0, 13.0, np.arange(15.0, 92.0, 2.0)]),
            "h_in": (*TWO_PHASE_INLETS, *SUPERHEATED_INLETS),
            "T_res": (300.0,),
            "T_air_in": tuple(np.r_[-10.0, -5.0, 0.0, 5.0, 10.0, np.arange(15.0, 45.1, 2.0), 50.0] + 273.15),
        },
    },
)
