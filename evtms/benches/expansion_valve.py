"""Expansion-valve bench: thermostatic valve held at its nominal opening.

The bench imposes the inlet state ``(T_in, p_in)`` (or ``h_in``) and the mass
flow ``mdot`` and reports the pressure drop that passes that flow. Throttling
is adiabatic and without work, so isenthalpic: ``h_out = h_in``.

Opening. A thermostatic valve opens with evaporator superheat above its
static superheat; the bench holds it at the opening of the nominal superheat,
which is the area that passes the nominal capacity at the nominal conditions
(Simscape's "Thermostatic Expansion Valve (2P)" parameterisation):

.. math:: \\dot m_{nom} = \\frac{Q_{nom}}{h(p_e, T_e + \\Delta T_{sh}) - h(p_c, T_c - \\Delta T_{sc})},\\quad
          S = \\frac{\\dot m_{nom}}{\\sqrt{2 \\rho_{in,nom} (p_c - p_e)}}

with ``p_c = p_sat(T_c)``, ``p_e = p_sat(T_e)``. With the default parameters
(4.5 kW nominal) S = 6.9e-7 m2, far below the 10 mm port's 7.9e-5 m2.

Flow law. For a liquid or two-phase inlet, the orifice law of an
incompressible fluid at the inlet (homogeneous) density,
``mdot = S sqrt(2 rho_in dp)``, so ``dp = (mdot / S)^2 / (2 rho_in)``. Flashing
downstream of the vena contracta is not modelled (the valve's discharge
coefficient is folded into S at the nominal point). For a vapour inlet the
flow is compressible: the isentropic nozzle relation of an ideal gas with the
inlet's ratio of specific heats gives the outlet pressure, and a mass flow
above the choked limit ``S sqrt(gamma rho p (2/(gamma+1))^((gamma+1)/(gamma-1)))``
cannot pass at any outlet pressure (status 4).

Differences from the thesis' report: it found dp rising with inlet pressure
and independent of inlet temperature. At fixed opening the orifice law gives
dp proportional to ``1 / rho_in``: liquid density barely moves with pressure
(dp nearly independent of ``p_in``) and falls with temperature (dp rises
slightly with ``T_in``), and a vapour inlet is some 25 times less dense, so
its dp is far larger or the flow is choked. evtms follows the physics.

References
----------
Idelchik, I. E. (2007). Handbook of Hydraulic Resistance, 4th ed., ch. 4.
Shapiro, A. H. (1953). The Dynamics and Thermodynamics of Compressible Fluid
Flow, vol. 1, ch. 4 (isentropic nozzle flow and choking).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from evtms.benches.base import (
    COMMON_FLAGS,
    STATUS_OUTSIDE_FLUID_RANGE,
    Bench,
    finish_status,
    first_code,
    pressure_nodes,
)
from evtms.benches.condenser import inlet_enthalpy
from evtms.fluid import Fluid, quality
from evtms.params import Relation, length, param, temperature

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters


@dataclass(frozen=True)
class ExpansionValveParams:
    """Thermostatic expansion valve, used at its nominal opening on the bench.

    The capacities set the valve's flow area: the nominal opening passes
    ``capacity_nominal`` at the nominal conditions below, the maximum opening
    ``capacity_max / capacity_nominal`` times that area (the cycle holds the
    superheat up to the maximum opening and lets it float beyond). Default
    sizing: the Simscape BEV example (``simscape/Optimize-BEV-Thermal-Management-with-Simscape``,
    block data of ``Models/BEV_Thermal_Management.slx``) feeds two valves from
    one compressor, the cabin evaporator's (2 kW nominal, 4 kW max) and the
    chiller's (4.5 kW nominal, 7 kW max); evtms's circuit passes the whole
    flow of the default 80 cm3 compressor through its one valve, so it takes
    the chiller valve's rating with the cabin valve's nominal conditions. With
    the cabin valve's rating 7 of the 9 points of ``evtms cycle sweep --speed
    0.2:1:9`` needed more than its maximum opening; with the chiller valve's,
    none does (the largest needs 90 % of it, at speed 1), and about 83 % of
    1000 random points over the cycle envelope (speed, fan and blower 0.1-1,
    ambient 15-45 degC, cabin air 15-35 degC) hold their superheat. The rest
    run with the valve saturated, mostly at high speed and a cool ambient (a
    quarter of the points below 25 degC ambient): a low condensing pressure
    leaves the valve a small pressure drop.

    Attributes
    ----------
    capacity_nominal : float
        Evaporator capacity at the nominal opening [W], (0, 1 MW].
    capacity_max : float
        Capacity at the maximum opening [W], (0, 1 MW], at least ``capacity_nominal``.
    T_cond_nominal : float
        Nominal condensing temperature [K], 150 K to 500 K, above ``T_evap_nominal``.
    T_evap_nominal : float
        Nominal evaporating temperature [K], 150 K to 500 K.
    subcooling_nominal : float
        Nominal liquid subcooling at the valve inlet [K], 0 K to 100 K.
    superheat_nominal : float
        Superheat at the nominal opening [K], (0, 100] K, above ``superheat_static``.
    superheat_static : float
        Superheat below which the valve is closed [K], 0 K to 100 K.
    port_diameter : float
        Port diameter [m], (0, 0.1]; the opening area cannot exceed the port area.
    """

    capacity_nominal: float = param(4500.0, 0.0, 1e6, "W", lo_open=True)
    capacity_max: float = param(7000.0, 0.0, 1e6, "W", lo_open=True)
    T_cond_nominal: float = temperature(313.15)
    T_evap_nominal: float = temperature(274.15)
    subcooling_nominal: float = param(5.0, 0.0, 100.0, "K")
    superheat_nominal: float = param(10.0, 0.0, 100.0, "K", lo_open=True)
    superheat_static: float = param(5.0, 0.0, 100.0, "K")
    port_diameter: float = length(0.010, 0.1)

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        Relation("capacity_max", ">=", lambda v: v.capacity_nominal, "capacity_nominal", ("capacity_nominal",)),
        Relation("T_cond_nominal", ">", lambda v: v.T_evap_nominal, "T_evap_nominal", ("T_evap_nominal",)),
        Relation("superheat_nominal", ">", lambda v: v.superheat_static, "superheat_static", ("superheat_static",)),
    )


STATUS_DP_EXCEEDS_INLET = 3
STATUS_CHOKED = 4

OUTPUTS = ("status", "dp", "h_in", "h_out", "T_out", "p_out", "x_out")


def nominal_opening(valve: ExpansionValveParams, fluid: Fluid) -> float:
    """Effective flow area [m2] of the valve at its nominal opening (see module notes)."""
    p_c = float(fluid.saturation_pressure(valve.T_cond_nominal))
    p_e = float(fluid.saturation_pressure(valve.T_evap_nominal))
    liquid = fluid.state("PT", p_c, valve.T_cond_nominal - valve.subcooling_nominal, ("H", "D"))
    h_evap_out = float(fluid.state("PT", p_e, valve.T_evap_nominal + valve.superheat_nominal, ("H",))["H"])
    mdot_nom = valve.capacity_nominal / (h_evap_out - float(liquid["H"]))
    area = mdot_nom / np.sqrt(2.0 * float(liquid["D"]) * (p_c - p_e))
    return float(min(area, np.pi / 4.0 * valve.port_diameter**2))


def _ideal_gas_mass_flux(r: np.ndarray, rho: np.ndarray, p: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Isentropic nozzle mass flux [kg/(m2 s)] of an ideal gas at pressure ratio r = p_out/p_in."""
    return np.sqrt(
        2.0 * rho * p * gamma / (gamma - 1.0) * np.maximum(r ** (2.0 / gamma) - r ** ((gamma + 1.0) / gamma), 0)
    )


def valve_pressure_drop(inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid) -> dict[str, np.ndarray]:
    """Pressure drop that passes ``mdot`` through the valve at its nominal opening.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``T_in`` [K] or ``h_in`` [J/kg], ``p_in`` [Pa], ``mdot`` [kg/s].
    params : Parameters
        Valve parameters (``params.expansion_valve``).
    fluid : Fluid
        Refrigerant properties.

    Returns
    -------
    dict of str to numpy.ndarray
        ``dp`` [Pa], ``h_in`` = ``h_out`` [J/kg], ``T_out`` [K], ``p_out``
        [Pa], ``x_out`` [1], ``status`` (int8, see :data:`FLAGS`).
    """
    p_in = np.asarray(inputs["p_in"], float)
    mdot = np.asarray(inputs["mdot"], float)
    h_in = inlet_enthalpy(inputs, fluid)
    area = nominal_opening(params.expansion_valve, fluid)
    st = fluid.state("PH", p_in, h_in, ("D",))
    sat_in = fluid.saturation(p_in)
    x_in = quality(h_in, sat_in["h_l"], sat_in["h_v"])
    vapour = (x_in >= 1.0) | (p_in >= fluid.p_crit)
    rho = st["D"]
    dp = (mdot / area) ** 2 / (2.0 * rho)  # liquid and two-phase inlets

    choked = np.zeros(p_in.shape, bool)
    if vapour.any():
        idx = np.nonzero(vapour)[0]
        heat = fluid.state("PH", p_in[idx], h_in[idx], ("CP", "CV"))
        g = heat["CP"] / heat["CV"]  # real-gas ratio of specific heats at the inlet
        r_crit = (2.0 / (g + 1.0)) ** (g / (g - 1.0))
        flux = mdot[idx] / area
        flux_max = _ideal_gas_mass_flux(r_crit, rho[idx], p_in[idx], g)
        choked[idx] = flux > flux_max
        lo, hi = r_crit.copy(), np.ones_like(r_crit)
        for _ in range(60):  # bisection: flux falls monotonically from r_crit to 1
            mid = 0.5 * (lo + hi)
            too_much = _ideal_gas_mass_flux(mid, rho[idx], p_in[idx], g) > flux
            lo = np.where(too_much, mid, lo)
            hi = np.where(too_much, hi, mid)
        dp[idx] = p_in[idx] * (1.0 - 0.5 * (lo + hi))

    p_out = p_in - dp
    too_large = ~choked & ~(p_out > fluid.p_triple)
    p_ok = np.where(too_large | choked, np.nan, p_out)
    out_state = fluid.state("PH", p_ok, h_in, ("T",))
    h_l = fluid.state("PQ", p_ok, 0.0, ("H",))["H"]
    h_v = fluid.state("PQ", p_ok, 1.0, ("H",))["H"]
    out = {
        "dp": dp,
        "h_in": h_in.copy(),
        "h_out": h_in.copy(),
        "T_out": out_state["T"],
        "p_out": p_out,
        "x_out": quality(h_in, h_l, h_v),
    }
    status = first_code(
        [
            (~np.isfinite(h_in + rho), STATUS_OUTSIDE_FLUID_RANGE),
            (choked, STATUS_CHOKED),
            (too_large, STATUS_DP_EXCEEDS_INLET),
        ],
        p_in.size,
    )
    finish_status(status, out, (0,))
    out["status"] = status
    return out


FLAGS = {
    **COMMON_FLAGS,
    STATUS_DP_EXCEEDS_INLET: "pressure_drop_exceeds_inlet_pressure",
    STATUS_CHOKED: "mass_flow_above_choked_limit",
}

BENCH = Bench(
    name="expansion_valve",
    title="evtms expansion-valve bench: thermostatic valve at nominal opening, isenthalpic",
    axes=("T_in", "p_in", "mdot"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=valve_pressure_drop,
    parameters=ExpansionValveParams,
    main_output=("dp", "mdot"),
    surface_axes=(("p_in", "T_in"), ("p_in", "h_in")),
    presets={
        "thesis": {
            "T_in": (300.0, 315.0, 330.0),
            "p_in": (0.9e6, 1.0e6, 1.1e6, 1.2e6),
            "mdot": (0.0045, 0.00625, 0.008),
        },
        # Condenser outlets of the cycle envelope (condensing -10-91 degC: liquid at 187-345
        # kJ/kg); dp goes with mdot^2, so two flows suffice.
        "cycle": {
            "h_in": tuple(np.linspace(175e3, 350e3, 8)),
            "p_in": pressure_nodes(np.arange(-10.0, 92.0, 5.0)),
            "mdot": (0.001, 0.005),
        },
    },
)
