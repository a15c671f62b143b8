"""Coolant-to-air coil: a louvred-fin flat-tube core with water-glycol in the tubes.

Shared by the radiator and the heater-core benches. The core is the
geometry of the refrigerant coils (:class:`evtms.benches.coil.CoilParams`,
one row of flat multiport tubes, louvred fins, air in cross flow) with the
coolant, monoethylene glycol 50 % by mass in water (CoolProp's
incompressible ``MEG``, :class:`evtms.fluid.Coolant`), in all tubes in
parallel. Both streams stay single phase, so the whole core is one
effectiveness-NTU exchanger: cross flow with the coolant mixed (it is
stirred across the tube's width by the headers and the tube's aspect) and the
air unmixed (the fins keep it in channels), Incropera et al. (2007)
Table 11.3, :func:`evtms.hx.effectiveness.crossflow_one_mixed_effectiveness`.

Coolant side: Hausen's developing-laminar mean Nusselt number with the
fully developed limit of the coil's ``nu_laminar`` (Shah and London's
rectangular-duct value for the benches' channels,
:func:`evtms.hx.tube.hausen_nusselt`, :func:`evtms.hx.tube.shah_london_nu_t`),
Gnielinski above Re 2300, blended linearly up to Re 4000
(:func:`evtms.hx.tube.single_phase_nusselt`); Haaland friction for the
channels' pressure drop (headers and ports not included). Air side:
the louvred fin of Chang and Wang (1997) at the core velocity, as the
refrigerant coils (:func:`evtms.benches.coil.air_stream`); its data cover
louver-pitch Reynolds numbers 100 to 3000, and the points outside are valid
with status 11 (``valid_correlation_outside_range``). Coolant properties are
taken at the inlet, then once more at the mean of inlet and outlet.

Energy: ``Q = mdot_coolant (h_c,in - h_c,out) = C_air (T_air,out - T_air,in)``
to round-off (the coolant in its tabulated enthalpy, the air at its
entering heat capacity: the air is heated or cooled without condensing).
Second law: ``|Q| <= C_min |T_coolant_in - T_air_in|``, as ``epsilon <= 1``,
so neither stream leaves beyond the other's inlet temperature.

Moisture: the model is sensible only. Where the coldest tube surface (at the
coolant inlet, where the air enters; from the split of the temperature
difference between the air's and the coolant's thermal resistances) lies
below the air's dew point, moisture condenses and the latent heat the model
leaves out makes the true ``|Q|`` larger: such points are valid with status
12 (``valid_surface_below_dew_point_sensible_only``), and with status 13
(``valid_frost_risk_surface_below_0C``) where that surface is also below
0 degC: a radiator drawing heat from cold, humid ambient air (the heat
pump's source) frosts, and its steady state would not last.

References
----------
Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
Fundamentals of Heat and Mass Transfer, 6th ed., Wiley (Table 11.3; eq. 8.57).
Chang, Y.-J., Wang, C.-C. (1997). A generalized heat transfer correlation for
louver fin geometry. Int. J. Heat Mass Transfer 40(3), 533-544.
Shah, R. K., London, A. L. (1978). Laminar Flow Forced Convection in Ducts.
Academic Press.
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
)
from evtms.benches.coil import CoilParams, air_stream, coil_geometry
from evtms.fluid import Coolant, Fluid, coolant
from evtms.hx.effectiveness import crossflow_one_mixed_effectiveness
from evtms.hx.fins import chang_wang_outside_range
from evtms.hx.tube import haaland_friction_factor, hausen_nusselt, single_phase_nusselt
from evtms.luts.schema import AxisSpec

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters
    from evtms.params import Environment

STATUS_COOLANT_FREEZES = 5
STATUS_FLOW_NOT_POSITIVE = 6
STATUS_CORRELATION_OUTSIDE_RANGE = 11
STATUS_BELOW_DEW_POINT = 12
STATUS_FROST_RISK = 13

FLAGS = {
    **COMMON_FLAGS,
    STATUS_COOLANT_FREEZES: "coolant_below_freezing_point",
    STATUS_FLOW_NOT_POSITIVE: "mass_flow_not_positive",
    STATUS_CORRELATION_OUTSIDE_RANGE: "valid_correlation_outside_range",
    STATUS_BELOW_DEW_POINT: "valid_surface_below_dew_point_sensible_only",
    STATUS_FROST_RISK: "valid_frost_risk_surface_below_0C",
}
VALID_FLAGS = (0, STATUS_CORRELATION_OUTSIDE_RANGE, STATUS_BELOW_DEW_POINT, STATUS_FROST_RISK)

AXES = ("mdot_coolant", "T_coolant_in", "V_air", "T_air_in", "RH_air_in")
OUTPUTS = ("status", "Q", "UA", "effectiveness", "T_coolant_out", "T_air_out", "T_surface_min", "dp_coolant")

#: The liquid coils' own axis (the coolant's and the air's inlet axes are shared).
AXIS_SPECS = {
    "V_air": AxisSpec("V_air", "m3 s-1", "air volume flow through the core, at its entering state", 0.0, upper=100.0),
}

VARIABLES = {
    "Q": ("W", "heat flow from coolant to air"),
    "UA": ("W K-1", "overall conductance of the core"),
    "effectiveness": ("1", "Q over the largest heat flow the second law allows"),
    "T_coolant_out": ("K", "coolant temperature leaving the core"),
    "T_surface_min": ("K", "tube surface at the coolant inlet: the coldest where the coolant is the colder stream"),
    "dp_coolant": ("Pa", "coolant pressure drop in the tubes (headers not included)"),
}


def _coolant_resistance(
    coil: CoilParams, cool: Coolant, mdot: np.ndarray, T: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Coolant side at temperature ``T`` [K]: its thermal resistance with wall and fouling
    [K/W], heat capacity [J/(kg K)], channel Reynolds number [1] and friction pressure drop [Pa]."""
    geo = coil_geometry(coil)
    props = cool.properties(T)
    G = mdot / geo.flow_area
    Re = G * geo.D_h / props["MU"]
    Pr = props["CP"] * props["MU"] / props["K"]
    f = haaland_friction_factor(Re, coil.roughness / geo.D_h)
    nu_lam = hausen_nusselt(Re, Pr, geo.D_h, geo.tube_length, coil.nu_laminar)
    h = single_phase_nusselt(Re, Pr, f, nu_lam) * props["K"] / geo.D_h
    R = 1.0 / (h * coil.area_ref) + coil.fouling_ref / coil.area_ref + geo.R_wall
    dp = f * geo.tube_length / geo.D_h * G**2 / (2.0 * props["D"])
    return R, props["CP"], Re, dp


def solve_liquid_coil(
    coil: CoilParams,
    env: Environment,
    mdot_coolant: np.ndarray,
    T_coolant_in: np.ndarray,
    V_air: np.ndarray,
    T_air_in: np.ndarray,
    RH_air_in: np.ndarray,
    cool: Coolant | None = None,
) -> dict[str, np.ndarray]:
    """Steady-state response of a coolant-to-air core at arrays of inlet conditions.

    Parameters
    ----------
    coil : CoilParams
        Core geometry.
    env : Environment
        Air pressure (``env.p``) [Pa].
    mdot_coolant : numpy.ndarray
        Coolant mass flow [kg/s], > 0.
    T_coolant_in : numpy.ndarray
        Coolant inlet temperature [K].
    V_air : numpy.ndarray
        Air volume flow at its entering state [m3/s], > 0.
    T_air_in, RH_air_in : numpy.ndarray
        Entering air temperature [K] and relative humidity [1].
    cool : Coolant, optional
        The coolant; MEG 50 % by default.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` heat from coolant to air [W] (negative where the air is warmer),
        ``UA`` [W/K], ``effectiveness`` [1], ``T_coolant_out`` [K],
        ``T_air_out`` [K], ``T_surface_min`` [K], ``dp_coolant`` [Pa],
        ``T_dew_air_in`` [K], ``Re_Lp`` [1], ``Re_coolant`` [1].
    """
    cool = cool or coolant()
    mdot, T_c, V, T_a, RH = np.broadcast_arrays(
        *(np.asarray(a, float).reshape(-1) for a in (mdot_coolant, T_coolant_in, V_air, T_air_in, RH_air_in))
    )
    air, _, C_air, R_air, Re_Lp = air_stream(coil, env, V, T_a, RH)
    h_c_in = cool.enthalpy(T_c)
    T_props = T_c
    for _ in range(2):  # coolant properties at the inlet, then at the mean temperature
        R_c, cp, Re_c, dp = _coolant_resistance(coil, cool, mdot, T_props)
        UA = 1.0 / (R_c + R_air)
        C_c = mdot * cp
        C_min, C_max = np.minimum(C_c, C_air), np.maximum(C_c, C_air)
        eps = crossflow_one_mixed_effectiveness(UA / C_min, C_min / C_max, C_c <= C_air)
        Q = eps * C_min * (T_c - T_a)
        T_c_out = cool.temperature(h_c_in - Q / mdot)
        T_props = 0.5 * (T_c + T_c_out)
    T_surface = T_a - (T_a - T_c) * R_air / (R_air + R_c)
    return {
        "Q": Q,
        "UA": UA,
        "effectiveness": eps,
        "T_coolant_out": T_c_out,
        "T_air_out": T_a + Q / C_air,
        "T_surface_min": T_surface,
        "dp_coolant": dp,
        "T_dew_air_in": air["T_dew"],
        "Re_Lp": Re_Lp,
        "Re_coolant": Re_c,
    }


def liquid_coil_heat_rate(
    inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid, component: str
) -> dict[str, np.ndarray]:
    """A liquid coil bench's response over arrays of its inputs (:data:`AXES`).

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``mdot_coolant`` [kg/s], ``T_coolant_in`` [K], ``V_air`` [m3/s],
        ``T_air_in`` [K], ``RH_air_in`` [1].
    params : Parameters
        The core's geometry (``params.<component>``) and the air pressure.
    fluid : Fluid
        Unused (no refrigerant flows here); the benches' common signature.
    component : str
        ``"radiator"`` or ``"heater_core"``.

    Returns
    -------
    dict of str to numpy.ndarray
        :data:`OUTPUTS`, ``status`` as int8 (:data:`FLAGS`), NaN where invalid.
    """
    mdot, T_c, V, T_a, RH = (np.asarray(inputs[a], float).reshape(-1) for a in AXES)
    cool = coolant()
    in_table = (T_c >= cool.T_min) & (T_c <= cool.T_max)
    flowing = (mdot > 0) & (V > 0)
    ok = in_table & flowing
    safe = {  # a harmless stand-in where a point is refused, so nothing warns
        "mdot_coolant": np.where(ok, mdot, 1.0),
        "T_coolant_in": np.where(ok, T_c, 300.0),
        "V_air": np.where(ok, V, 1.0),
    }
    res = solve_liquid_coil(
        getattr(params, component),
        params.environment,
        safe["mdot_coolant"],
        safe["T_coolant_in"],
        safe["V_air"],
        T_a,
        RH,
        cool,
    )
    freezes = ok & ((T_c < cool.T_freeze) | ~(res["T_coolant_out"] >= cool.T_freeze))
    outside = chang_wang_outside_range(res["Re_Lp"])
    wet = res["T_surface_min"] < res["T_dew_air_in"]
    status = first_code(
        [
            (~in_table, STATUS_OUTSIDE_FLUID_RANGE),
            (~flowing, STATUS_FLOW_NOT_POSITIVE),
            (freezes, STATUS_COOLANT_FREEZES),
            (~np.isfinite(res["Q"]), STATUS_PROPERTY_FAILED),
            (wet & (res["T_surface_min"] < 273.15), STATUS_FROST_RISK),
            (wet, STATUS_BELOW_DEW_POINT),
            (outside, STATUS_CORRELATION_OUTSIDE_RANGE),
        ],
        mdot.size,
    )
    out = {k: np.asarray(res[k], float).copy() for k in OUTPUTS if k != "status"}
    finish_status(status, out, VALID_FLAGS)
    return {"status": status, **out}


def liquid_coil_bench(name: str, title: str, parameters, presets: dict, evaluate) -> Bench:
    """The :class:`Bench` of a liquid coil: the shared axes, outputs and flags, its own parameters and presets."""
    return Bench(
        name=name,
        title=title,
        axes=AXES,
        outputs=OUTPUTS,
        flags=FLAGS,
        evaluate=evaluate,
        parameters=parameters,
        presets=presets,
        valid_flags=VALID_FLAGS,
        axis_specs=AXIS_SPECS,
        variables=VARIABLES,
        surface_axes=(("V_air", "T_coolant_in"), ("T_air_in", "V_air")),
        main_output=("Q", "mdot_coolant"),
    )
