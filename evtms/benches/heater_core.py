"""Heater-core bench: the cabin's coolant-to-air heater core (CoHX) on the heating loop.

Hot MEG 50 % from the water-cooled condenser of the heat pump and the
high-voltage coolant heater flows through the core; the cabin air the blend
door sends through it (after the evaporator) crosses the fins. The model is
the liquid coil of :mod:`evtms.benches.liquid_coil` (cross-flow
effectiveness-NTU, coolant mixed, Hausen / Gnielinski inside, Chang and
Wang's louvred fin outside) on the cabin evaporator's core geometry
(:func:`evtms.benches.evaporator.evaporator_coil`: 20 tubes of 0.75 m with
12 channels each, 7.2 m2 of fins; the system spec takes the Simscape
example's evaporator dimensions for the heater core, as heater cores and
evaporators of one HVAC module are built alike), with Shah and London's
fully developed limit for its 1.23 x 1.8 mm channels. The air is heated
without condensing in the usual case (coolant warmer than the air); a core
run colder than the air's dew point is flagged as the radiator's is.
"""

from __future__ import annotations

import dataclasses
from functools import partial

from evtms.benches.coil import CoilParams
from evtms.benches.evaporator import evaporator_coil
from evtms.benches.liquid_coil import liquid_coil_bench, liquid_coil_heat_rate
from evtms.hx.tube import shah_london_nu_t


def _heater_core() -> CoilParams:
    """The heater core's default core: the cabin evaporator's geometry, its laminar limit for its channels."""
    core = evaporator_coil()
    width = (core.tube_depth - 2 * core.wall_thickness) / core.n_channels
    height = core.tube_thickness - 2 * core.wall_thickness
    return dataclasses.replace(core, nu_laminar=round(shah_london_nu_t(height / width), 3))


BENCH = liquid_coil_bench(
    "heater_core",
    "evtms heater-core bench: louvred-fin flat-tube core, MEG 50 % coolant to cabin air",
    _heater_core,
    presets={
        # Table 12's heating rows: coolant into the core at 40-80 degC, the blower's 0.03-0.3 m3/s,
        # cabin air (after the evaporator) from -10 to 25 degC.
        "thesis": {
            "mdot_coolant": (0.05, 0.1, 0.2, 0.33),
            "T_coolant_in": (313.15, 333.15, 353.15),
            "V_air": (0.03, 0.08, 0.15, 0.3),
            "T_air_in": (263.15, 283.15, 298.15),
            "RH_air_in": (0.4,),
        },
        # The heating loop's envelope: its pump at 0.15-1 of 0.36 kg/s, coolant 0-90 degC, the
        # blend door's share of the blower flow, inlet air -30 to 40 degC.
        "cycle": {
            "mdot_coolant": (0.05, 0.1, 0.15, 0.2, 0.27, 0.36),
            "T_coolant_in": tuple(273.15 + 5.0 * i for i in range(19)),
            "V_air": (0.01, 0.02, 0.04, 0.08, 0.12, 0.18, 0.24, 0.3),
            "T_air_in": tuple(243.15 + 5.0 * i for i in range(15)),
            "RH_air_in": (0.0, 0.3, 0.6, 0.9, 1.0),
        },
    },
    evaluate=partial(liquid_coil_heat_rate, component="heater_core"),
)
