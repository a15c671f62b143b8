"""The e-drive coolant loop (loop E): motor, inverter and DC-DC on one pump, a radiator at the front end.

Per the project's system spec (v2 sections 5.1-5.5, 5.8):

- the e-drive loss ``P_loss`` (:mod:`evtms.system.vehicle`) heats the motor
  (``1 - f_inv``) and the inverter (``f_inv``); the low-voltage loads
  (blower, fan, pumps) draw ``P_LV / eta_dc`` from the pack through the DC-DC
  converter, whose loss ``P_LV (1 / eta_dc - 1)`` heats it;
- each of the three is a lumped mass on the loop's coolant through its
  jacket's convective conductance ``G = h A`` (the thesis's motor equation,
  section 3.2, with its constant coolant temperature rise replaced by a
  conductance, which conserves heat); the motor also loses ``K_1 (T_m -
  T_amb)`` to the air around it;
- the pump follows the motor temperature on the model's table (MWc ``Motor
  Pump``), never below ``pump_min`` while the car is on; its power scales
  with the cube of its command (affinity law; the thesis's pump polynomial
  with its cubic term only);
- the radiator, bypassed below ``radiator_off`` and back in above
  ``radiator_on`` (a relay on the loop's temperature, MWc ``Radiator
  Bypass``), is a steady cross-flow exchanger, coolant mixed and air
  unmixed, its conductance ``UA(mdot, T_coolant, V_air)`` tabulated from the
  radiator bench (:mod:`evtms.benches.radiator`, :func:`core_table`),
  its air the front end's fan and ram air after the condenser (stacked);
- the condenser fan also serves the motor: its command is the larger of the
  condenser's stages and the same motor-temperature table (MWc ``Fan
  Control``).

The loop itself (:func:`evtms.system.loop.run_loop`) advances the four nodes
by backward Euler with the motor, inverter and DC-DC eliminated onto the
loop's temperature in closed form and the radiator implicit in it.

References
----------
MathWorks (2024). Electric Vehicle Thermal Management (Simscape example,
``BEV_Thermal_Management``): motor, pump, radiator and fan blocks and the
controls' lookup tables.
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th
ed. Wiley: eq. 8.57 (Hausen), eq. 8.62 (Gnielinski), eqs. 11.33-11.34 (cross flow, one
fluid mixed).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from evtms._jit import kernel_array
from evtms.params import Relation, choice, ordered, param

if TYPE_CHECKING:
    from evtms.benches.coil import CoilParams

#: What the e-drive's losses heat: the coolant loop (motor, inverter and DC-DC nodes, pump, radiator), or the
#: ambient directly (the first system model: no loop, no DC-DC loss, the fan for the condenser only).
EDRIVE_MODELS = ("loop", "ambient")

#: The motor-temperature requirement [1] of the e-drive pump and of the front-end fan over the motor
#: temperature [K] (linear between the nodes, held at the ends; MWc ``Motor Pump`` and ``Fan Control``).
MOTOR_REQUIREMENT = {
    "T_motor": tuple(273.15 + c for c in (-50.0, 45.0, 48.0, 52.0, 58.0, 60.0, 75.0, 130.0)),
    "command": (0.0, 0.0, 0.1, 0.3, 0.5, 0.7, 1.0, 1.0),
}

#: Nodes of the coolant-to-air cores' conductance tables by bench: coolant mass flow [kg/s], coolant
#: temperature [K] and air volume flow [m3/s]. The radiator: the e-drive pump's 0-0.36 kg/s, the coolant over
#: its table (-35 to 100 degC), natural draft to 130 km/h; the heater core: the heating loop's pump, the blend
#: door's share of the blower's 0-0.3 m3/s.
CORE_NODES = {
    "radiator": {
        "mdot_coolant": (0.02, 0.05, 0.1, 0.15, 0.2, 0.27, 0.36, 0.45),
        "T_coolant_in": (238.15, *(243.15 + 10.0 * i for i in range(14))),
        "V_air": (0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.2, 1.45),
    },
    "heater_core": {
        "mdot_coolant": (0.02, 0.05, 0.1, 0.15, 0.2, 0.27, 0.36, 0.45),
        "T_coolant_in": (238.15, *(243.15 + 10.0 * i for i in range(14))),
        "V_air": (0.002, 0.005, 0.01, 0.02, 0.04, 0.07, 0.1, 0.15, 0.2, 0.3, 0.4),
    },
}
#: The air the cores' conductances are tabulated at [K], [1]: its properties move the air side by a few
#: per cent over the ambients of a drive (k and mu of air rise about 0.3 % per K); the coolant's viscosity,
#: which changes tenfold, is an axis.
CORE_AIR = (293.15, 0.4)


@dataclass(frozen=True)
class EdriveParams:
    """E-drive loop E: motor, inverter and DC-DC nodes, their jackets, pump and radiator bypass (spec v2 5).

    Heat capacities [J/K]; ``motor_ambient_conductance`` ``K_1`` [W/K];
    ``inverter_loss_fraction`` [1] of the e-drive loss heats the inverter,
    the rest the motor; ``dcdc_efficiency`` [1] of the converter feeding the
    low-voltage loads; ``flow_max`` [m3/s] of the pump at command 1 and
    ``pump_power_max`` [W] there (x u^3); ``pump_min`` [1] its least command
    while the car is on; the radiator is bypassed below ``radiator_off`` and
    back in above ``radiator_on`` [K]; the jackets are ``jacket_diameter``
    [m] channels, ``motor_jacket_channels`` in parallel of
    ``motor_jacket_length`` [m] in the motor and one of
    ``drive_jacket_length`` [m] in each of the inverter and the DC-DC, with
    the coolant properties of ``[coolant]``; ``T_init`` [K] of every node
    (None: the ambient).
    """

    model: str = choice(
        "loop",
        EDRIVE_MODELS,
        slot="EDRIVE_MODEL",
        source="spec v2 5 (`loop`); `ambient`: the first system model's losses straight to ambient",
    )
    motor_heat_capacity: float = param(
        19000.0, 1.0, 1e7, "J/K", slot="C_M", source="MW M `Motor` 10 kJ/K + `Housing` 10 kg x 900 J/(kg K)"
    )
    motor_ambient_conductance: float = param(
        1.2, 0.0, 1e4, "W/K", slot="K1_M", source="MW M: 5 W/(m2 K) on pi x 0.255 x 0.300 m2 (thesis 3.2's K_1)"
    )
    inverter_heat_capacity: float = param(5000.0, 1.0, 1e7, "J/K", slot="C_I", source="A (MW lumps it into `Motor`)")
    inverter_loss_fraction: float = param(
        0.3, 0.0, 1.0, "1", slot="F_INV", source="A (MW lumps the drive's losses into `Motor`)"
    )
    dcdc_heat_capacity: float = param(5800.0, 1.0, 1e7, "J/K", slot="C_D", source="MW M 4000 J/K + 2 kg x 900")
    dcdc_efficiency: float = param(
        0.92,
        0.5,
        1.0,
        "1",
        slot="ETA_DC",
        source='A (real units 0.90-0.95; MW P `DCDCEff` 0.8 is "a default value" there)',
    )
    coolant_heat_capacity: float = param(
        8040.0,
        1.0,
        1e8,
        "J/K",
        slot="C_E",
        source="MW P/M: tank 1.25 l, radiator tubes 0.34 l, jackets 0.12 l, 2 m of 19 mm pipe (A): 2.28 l MEG 50 %",
    )
    flow_max: float = param(3.33e-4, 1e-6, 0.1, "m3/s", source="MW M `Motor Pump` (20 l/min at 10 m)")
    pump_power_max: float = param(
        120.0, 0.0, 1e4, "W", slot="PUMP_E_POWER", source="MW M `Motor Pump`; thesis 3.2 polynomial, cubic term"
    )
    pump_min: float = param(0.3, 0.0, 1.0, "1", slot="PUMP_E_MIN", source="spec v2 5.3 (the MWc table, clipped)")
    radiator_on: float = param(308.15, 173.15, 423.15, "K", slot="RAD_ON", source="MWc `Radiator Bypass`")
    radiator_off: float = param(293.15, 173.15, 423.15, "K", slot="RAD_OFF", source="MWc `Radiator Bypass`")
    jacket_diameter: float = param(9.2e-3, 1e-4, 0.1, "m", source="MW P motor and drive jackets")
    motor_jacket_channels: int = param(4, 1, 100, "1", whole=True, source="MW P")
    motor_jacket_length: float = param(0.4, 1e-3, 10.0, "m", source="MW P")
    drive_jacket_length: float = param(0.2, 1e-3, 10.0, "m", source="MW P (inverter and DC-DC, one channel each)")
    T_init: float | None = param(None, 173.15, 423.15, "K", optional=True, source="A (unset: the ambient)")

    RELATIONS: ClassVar[tuple[Relation, ...]] = (ordered("radiator_off", "<", "radiator_on"),)


def jacket_slots(edrive: EdriveParams, density: float, cp: float, viscosity: float, conductivity: float) -> dict:
    """The loop's jacket constants (slot name -> value): per jacket the channel Reynolds number at pump
    command 1, ``D/L`` and ``k/D`` times the wetted area [W/K]; the coolant's Prandtl number and the
    pump's mass flow at command 1 [kg/s] (:func:`evtms.system.loop.jacket_conductance`)."""
    d = edrive.jacket_diameter
    area = math.pi * d * d / 4.0
    slots = {"JACKET_PR": cp * viscosity / conductivity, "MDOT_E_MAX": edrive.flow_max * density}
    for name, channels, length in (
        ("M", edrive.motor_jacket_channels, edrive.motor_jacket_length),
        ("D", 1, edrive.drive_jacket_length),
    ):
        velocity = edrive.flow_max / (channels * area)
        slots[f"JACKET_{name}_RE1"] = density * velocity * d / viscosity
        slots[f"JACKET_{name}_DL"] = d / length
        slots[f"JACKET_{name}_KA"] = conductivity / d * channels * math.pi * d * length
    return slots


def core_table(component: str, core: CoilParams | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A coolant-to-air core's conductance ``UA`` [W/K] over :data:`CORE_NODES`, packed for the loop.

    Computed by the core's bench (``radiator`` or ``heater_core``, both
    :func:`evtms.benches.liquid_coil.solve_liquid_coil`: Hausen / Gnielinski
    in the tubes, Chang and Wang's louvred fin outside) with the air at
    :data:`CORE_AIR`, once per core geometry: cached as arrays
    (:func:`evtms.luts.cache.cached_arrays`), so a run with the cache warm
    imports neither the bench nor CoolProp.

    Parameters
    ----------
    component : str
        ``radiator`` or ``heater_core``.
    core : CoilParams, optional
        The core (default: the bench's).

    Returns
    -------
    (knots, starts, table)
        As :meth:`evtms.system.maps.CycleMap.packed`: the nodes concatenated,
        each axis' offsets, and ``UA`` as a ``(n_nodes, 1)`` column.
    """
    from evtms.luts.cache import cached_arrays

    nodes = CORE_NODES[component]
    if core is None:
        from evtms.benches.parameters import Parameters

        core = getattr(Parameters(), component)
    recipe = {"core": dataclasses.asdict(core), "nodes": nodes, "air": CORE_AIR}

    def build() -> tuple[dict[str, np.ndarray], dict]:
        from evtms.benches.liquid_coil import solve_liquid_coil
        from evtms.params import Environment

        grids = np.meshgrid(*(np.asarray(v, float) for v in nodes.values()), indexing="ij")
        m, T, V = (g.reshape(-1) for g in grids)
        T_air, rh = (np.full(m.size, v) for v in CORE_AIR)
        ua = solve_liquid_coil(core, Environment(), m, T, V, T_air, rh)["UA"]
        return {"ua": ua.reshape(-1, 1)}, {}

    arrays, _ = cached_arrays(f"{component.replace('_', '-')}-ua", [], recipe, build)
    knots = np.concatenate([np.asarray(v, float) for v in nodes.values()])
    starts = np.zeros(len(nodes) + 1, np.int64)
    starts[1:] = np.cumsum([len(v) for v in nodes.values()])
    return kernel_array(knots), kernel_array(starts, np.int64), kernel_array(arrays["ua"])
