"""Radiator bench: the e-drive coolant loop's coolant-to-air radiator at the front end.

MEG 50 % from the motor, inverter and DC-DC jackets flows through the flat
tubes; front-end air (fan plus ram air, behind the condenser when stacked)
crosses the louvred fins. The model is the liquid coil of
:mod:`evtms.benches.liquid_coil`: one effectiveness-NTU cross-flow exchanger,
coolant mixed and air unmixed, the coolant side on Hausen's developing
laminar flow (the tubes run at Re of about 400-900) with Shah and London's
fully developed limit for the tube's 1:11.4 channel, the air side on Chang
and Wang's louvred fin. Heat flows either way: ``Q > 0`` cools the coolant
(the e-drive's waste heat to ambient), ``Q < 0`` warms it from the air (the
heat pump's ambient source, where frost and condensate are flagged).

Geometry (the Simscape BEV example's radiator, MathWorks 2024, as the
system spec reads it): 25 flat tubes of 600 x 15 x 1.5 mm with one
14.8 x 1.3 mm channel (hydraulic diameter 2.39 mm, 0.1 mm aluminium wall),
6.8 mm between tubes, fins every 2 mm; 0.437 m2 primary and 1.46 m2 fin area
on the air side, fin efficiency 0.7, 0.0975 m2 free-flow area, fouling
0.1 m2K/kW each side. The system spec gave the air side as a tube-bank
correlation (Zukauskas' ``Nu = 0.27 Re^0.63 Pr^0.36``) on the fin channel's
hydraulic diameter; that correlation is for flow across tube banks, outside
its range (Re >= 1000) at the front end's 0.2-1.4 m3/s, and this core has
louvred fins, so the bench takes the louvred-fin correlation the coils use
(louvers of 1 mm pitch and 6 mm length at 27 deg, the coils' louver
geometry). At 50 km/h on ram air (0.4 m3/s) and the pump at full flow
(0.36 kg/s) it gives UA = 163 W/K, near the upper end of the spec's
100-160 W/K estimate.

References
----------
MathWorks (2024). Electric Vehicle Thermal Management (Simscape example,
``BEV_Thermal_Management``), radiator block parameters.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from evtms.benches.coil import CoilParams
from evtms.benches.liquid_coil import liquid_coil_bench, liquid_coil_heat_rate
from evtms.hx.tube import shah_london_nu_t

#: One channel per tube, 14.8 x 1.3 mm inside a 15 x 1.5 mm tube with 0.1 mm walls.
_CHANNEL_ASPECT = (1.5e-3 - 2 * 0.1e-3) / (15e-3 - 2 * 0.1e-3)


def _radiator_core() -> CoilParams:
    """The radiator's default core: :class:`CoilParams` at the Simscape example's radiator size."""
    return CoilParams(
        n_tubes=25,
        core_length=0.6,
        core_height=25 * (1.5e-3 + 6.8e-3),
        tube_depth=0.015,
        tube_thickness=1.5e-3,
        n_channels=1,
        fin_spacing=2e-3,
        area_air_free=0.0975,
        area_air_primary=0.437,
        area_air_fin=1.46,
        area_ref=round(25 * 2 * (14.8e-3 + 1.3e-3) * 0.6, 6),
        fan_flow_max=0.88,
        fin_efficiency=0.7,
        louver_length=6.0e-3,
        nu_laminar=round(shah_london_nu_t(_CHANNEL_ASPECT), 3),
    )


BENCH = liquid_coil_bench(
    "radiator",
    "evtms radiator bench: louvred-fin flat-tube core, MEG 50 % coolant to front-end air",
    _radiator_core,
    presets={
        # About the e-drive loop's working range: the pump at 0.3-1 of its 0.36 kg/s, coolant
        # 30-90 degC, front-end air from natural draft to the fan and ram air at speed.
        "thesis": {
            "mdot_coolant": (0.1, 0.2, 0.36),
            "T_coolant_in": (303.15, 323.15, 343.15, 363.15),
            "V_air": (0.2, 0.5, 1.0, 1.4),
            "T_air_in": (263.15, 283.15, 303.15, 313.15),
            "RH_air_in": (0.5,),
        },
        # The system's envelope: pump fractions 0.15-1, coolant -25 to 100 degC (below ambient when
        # the heat pump draws on the radiator), air 0.05-1.4 m3/s (natural draft to 130 km/h with
        # the fan at 1), ambient -30 to 50 degC, dry to saturated.
        "cycle": {
            "mdot_coolant": (0.05, 0.1, 0.15, 0.2, 0.27, 0.36),
            "T_coolant_in": tuple(248.15 + 5.0 * np.arange(26)),
            "V_air": (0.05, 0.1, 0.2, 0.4, 0.6, 0.9, 1.4),
            "T_air_in": tuple(243.15 + 5.0 * np.arange(17)),
            "RH_air_in": (0.0, 0.3, 0.6, 0.9, 1.0),
        },
    },
    evaluate=partial(liquid_coil_heat_rate, component="radiator"),
)
