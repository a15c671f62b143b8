"""Parameters of the system simulator: the TOML tables vehicle, battery, cabin, coolant and controls.

Defaults and sources are the project's system spec, section 3 (the Simscape
BEV example "MW", FASTSim "FS", assumptions "A" to calibrate); they are
listed with units in ``docs/system-parameters.md``. Every value is SI
(temperatures in K). :func:`load_system_params` reads a TOML file: an unknown
table or name, a value that is not a number, or one outside its range is a
one-line :class:`~evtms.errors.EvtmsInputError`.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from evtms.errors import EvtmsInputError
from evtms.params import Relation, choice, ordered, override, param
from evtms.system.battery import BatteryParams
from evtms.system.edrive import EdriveParams
from evtms.system.vehicle import VehicleParams


@dataclass(frozen=True)
class CabinParams:
    """Cabin air, walls (glass, doors, roof), interior mass and blower (MW M cabin blocks).

    Walls: area [m2], thickness [m], conductivity [W/(m K)] and heat capacity
    [J/K] each; ``wall_htc`` [W/(m2 K)] on both sides. ``interior_heat_capacity``
    [J/K] 0 turns the interior node off (the sun then heats the air).
    ``recirc_cool``, ``recirc_heat``, ``recirc_warmup``, ``recirc_vent`` [1]
    are the recirculated shares of the blower's air while cooling, heating,
    warming up and with no request (the climate control chooses among them,
    fog-limited outside cooling, or sets its own share in fresh-air economy);
    ``sun`` [W/m2] (None: the scenario's) and ``sun_shield`` [1] give
    ``Q_sun = 3 sun sun_shield`` [W]; ``blower_power_max`` [W] (x u^3) at the
    blower's full flow, which is the evaporator bench's ``fan_flow_max`` the
    cycle LUTs were made with (the maps' ``blower`` axis is a share of it);
    ``T_set`` [K] the cabin setpoint; ``rh_cabin`` [1] the initial relative
    humidity; ``T_init`` [K] the initial temperature (None: the ambient).
    """

    volume: float = param(3.0, 0.1, 100.0, "m3", source="MW M")
    glass_area: float = param(3.0, 0.01, 100.0, "m2", source="MW M")
    glass_thickness: float = param(0.004, 1e-4, 1.0, "m", source="MW M")
    glass_conductivity: float = param(0.96, 1e-3, 500.0, "W/(m K)", source="MW P")
    glass_heat_capacity: float = param(26.2e3, 1.0, 1e7, "J/K", source="MW P", slot="C_GLASS")
    doors_area: float = param(4.0, 0.01, 100.0, "m2", source="MW M")
    doors_thickness: float = param(0.06, 1e-4, 1.0, "m", source="MW M")
    doors_conductivity: float = param(0.08, 1e-3, 500.0, "W/(m K)", source="MW P")
    doors_heat_capacity: float = param(37.5e3, 1.0, 1e7, "J/K", source="MW P", slot="C_DOORS")
    roof_area: float = param(2.0, 0.01, 100.0, "m2", source="MW M")
    roof_thickness: float = param(0.04, 1e-4, 1.0, "m", source="MW M")
    roof_conductivity: float = param(0.08, 1e-3, 500.0, "W/(m K)", source="MW P")
    roof_heat_capacity: float = param(15.0e3, 1.0, 1e7, "J/K", source="MW P", slot="C_ROOF")
    wall_htc: float = param(40.0, 0.1, 1000.0, "W/(m2 K)", source="MW M, both sides (UA to ambient 64.0 W/K)")
    interior_heat_capacity: float = param(
        80.0e3,
        0.0,
        1e8,
        "J/K",
        slot="C_INT",
        source="A (FS whole cabin 80.1 kJ/K, lumped in one node); 0 turns the node off",
    )
    interior_conductance: float = param(
        300.0,
        0.0,
        1e5,
        "W/K",
        slot="G_INT",
        source="A: about 25 m2 of seats, dashboard and trim at 12 W/(m2 K) under vent flow",
    )
    recirc_cool: float = param(
        0.85,
        0.0,
        1.0,
        slot="RC_COOL",
        source=(
            "G13: CO2 below 2000 ppm with more than 85 % recirculation; A (window fogging: outside cooling the "
            "share falls to 0 as the cabin RH rises from `rh_dehum` - 0.1 to `rh_dehum`)"
        ),
    )
    recirc_heat: float = param(0.8, 0.0, 1.0, slot="RC_HEAT", source="G13; A, fog-limited as `recirc_cool`")
    recirc_warmup: float = param(0.8, 0.0, 1.0, slot="RC_WARM", source="G13; A, fog-limited as `recirc_cool`")
    recirc_vent: float = param(
        0.5,
        0.0,
        1.0,
        slot="RC_VENT",
        source="A: with no request the fresh air holds a mild cabin (the spec's `recirc_heat`; fog-limited)",
    )
    n_occupants: int = param(1, 0, 100, whole=True, source="MW M (70 W and 1.4e-5 kg/s of water each)")
    rh_cabin: float = param(0.5, 0.0, 1.0, source="MW S, initial cabin humidity")
    sun: float | None = param(
        None, 0.0, 1500.0, "W/m2", optional=True, source="MW M (600 in summer scenarios); unset: the scenario's"
    )
    sun_shield: float = param(0.5, 0.0, 1.0, source="MW P `radiationReflectionShields`; `Q_sun = 3 sun sun_shield`")
    blower_power_max: float = param(
        250.0, 0.0, 1e4, "W", slot="BLOWER_POWER", source="A, times the blower command cubed"
    )
    T_set: float = param(295.15, 283.15, 308.15, "K", slot="T_SET", source="FS `te_set_cab_kelvin` (22 degC)")
    T_init: float | None = param(None, 173.15, 373.15, "K", optional=True, source="MW S (unset: the ambient)")

    def shell_conductance(self) -> float:
        """Air-to-ambient conductance [W/K] of the three walls in parallel, each film-half-half-film in series."""
        return sum(self.wall_conductance(w) / 2.0 for w in WALLS)

    def wall_conductance(self, wall: str) -> float:
        """Conductance [W/K] from the wall's mid-thickness mass to one side: film in series with half the wall."""
        area = getattr(self, f"{wall}_area")
        half = getattr(self, f"{wall}_thickness") / 2.0
        return 1.0 / (1.0 / (self.wall_htc * area) + half / (getattr(self, f"{wall}_conductivity") * area))


WALLS = ("glass", "doors", "roof")


@dataclass(frozen=True)
class CoolantParams:
    """Battery coolant loop: coolant, plate, heater and pump (MW P/M).

    ``heat_capacity`` [J/K] of the loop; ``density`` [kg/m3], ``cp``
    [J/(kg K)], ``viscosity`` [Pa s] and ``conductivity`` [W/(m K)] of the
    coolant (50 % ethylene glycol at 20 degC); ``flow_max`` [m3/s] at pump command 1;
    ``pump_power_ref`` [W] at 1000 rpm, ``pump_speed_max`` [rpm] (affinity
    law, power ~ speed^3); ``heater_max_power`` [W]; ``T_init`` [K] (None:
    the ambient).
    """

    heat_capacity: float = param(
        16.5e3,
        1.0,
        1e8,
        "J/K",
        slot="C_COOL",
        source="MW P/M battery loop: tank, heater, plate channels, plate, heater mass",
    )
    density: float = param(1070.0, 100.0, 3000.0, "kg/m3", source="A (50 % ethylene glycol at 20 degC)")
    cp: float = param(3300.0, 100.0, 1e4, "J/(kg K)", slot="CP_H", source="A (50 % ethylene glycol at 20 degC)")
    viscosity: float = param(3.8e-3, 1e-5, 1.0, "Pa s", source="A (50 % ethylene glycol at 20 degC)")
    conductivity: float = param(0.38, 0.01, 10.0, "W/(m K)", source="A (50 % ethylene glycol at 20 degC)")
    flow_max: float = param(4.0e-4, 1e-6, 0.1, "m3/s", source="MW P pump 0.02 l/rev x 1200 rpm")
    pump_power_ref: float = param(
        120.0, 0.0, 1e4, "W", slot="PUMP_REF", source="MW M, at 1000 rpm (affinity law, power ~ speed^3)"
    )
    pump_speed_max: float = param(1200.0, 1.0, 1e5, "rpm", slot="PUMP_NMAX", source="MW P")
    heater_max_power: float = param(4000.0, 0.0, 1e5, "W", slot="HEATER_MAX", source="MW P")
    T_init: float | None = param(None, 173.15, 373.15, "K", optional=True, source="MW S (unset: the ambient)")


#: The condenser fan's stage-2 and stage-3 switch-off pressures [Pa] over the ambient temperature [K]
#: (linear, held at the ends; the model's condenser-fan requirement, spec v2 5.4).
FAN_STAGE_CURVES = {
    "T_amb": (273.15, 293.15, 303.15, 313.15, 323.15),
    "p_2": (1.4e6, 1.4e6, 1.3e6, 1.2e6, 1.1e6),
    "p_3": (2.0e6, 2.0e6, 1.8e6, 1.5e6, 1.3e6),
}


@dataclass(frozen=True)
class ControlParams:
    """Battery relays, pumps, the chiller's compressor controller and refrigerant-loop settings (MW M; A).

    The chiller's suction PI (battery cooling) in parallel form per MPa and
    MPa s on ``p_suction - chiller_p_suction``. Pressures [Pa], temperatures
    [K], powers [W], times [s], commands [1].

    The condenser fan (spec v2 5.4) is staged while the compressor is
    commanded: three relays on the filtered discharge pressure, on at
    ``p_k + band_k`` and off at ``p_k`` (``fan_p1`` with ``fan_p1_band``;
    ``p_2``, ``p_3`` from the ambient-temperature curves of
    :data:`FAN_STAGE_CURVES` with ``fan_band``), at least one stage while
    ram air gives less than ``ram_flow_floor`` [m3/s]. The fan command is
    the share of stages on, its flow that times the condenser bench's
    ``fan_flow_max`` [m3/s] the cycle LUTs were made with (the maps' ``fan``
    axis is a share of it), its power ``fan_power_nominal`` at
    ``fan_flow_nominal`` [m3/s] scaled with the flow cubed. Ram air
    ``ram_area`` [m2] times the vehicle speed adds to the fan's flow in
    quadrature (one quadratic resistance), never below ``front_flow_min``
    [m3/s] (natural draft).
    """

    chiller_kp: float = param(
        1.0,
        0.0,
        1e3,
        "1/MPa",
        slot="CH_KP",
        source="MW M (P 1): the compressor's suction PI when the chiller runs alone, or a critical battery's",
    )
    chiller_ki: float = param(0.2, 0.0, 1e3, "1/(MPa s)", slot="CH_KI", source="MW M (I 1/5)")
    chiller_p_suction: float = param(0.3e6, 0.05e6, 1.0e6, "Pa", slot="CH_PS", source="MW M")
    compressor_min_speed: float = param(0.1, 0.01, 1.0, slot="SPEED_MIN", source="evtms cycle envelope")
    fan_power_nominal: float = param(
        533.0, 0.0, 1e4, "W", slot="FAN_PNOM", source="MW M fan 400 Pa at efficiency 0.6; power ~ flow^3"
    )
    fan_flow_nominal: float = param(0.8, 0.01, 100.0, "m3/s", slot="FAN_VNOM", source="MW M")
    fan_p1: float = param(
        0.8e6,
        0.1e6,
        3.0e6,
        "Pa",
        slot="FAN_P1",
        source="MWc `Condenser Requirement`: stage 1 off at 0.8 MPa, on at 1.1 MPa discharge",
    )
    fan_p1_band: float = param(0.3e6, 0.0, 2.0e6, "Pa", slot="FAN_D1", source="MWc (stage 1 on at 1.1 MPa)")
    fan_band: float = param(
        0.4e6, 0.0, 2.0e6, "Pa", slot="FAN_D23", source="MWc: stages 2 and 3 on 0.4 MPa above their switch-off"
    )
    ram_area: float = param(
        0.0289,
        0.0,
        1.0,
        "m2",
        slot="RAM_AREA",
        source="MW intake 500 Pa at 1 kg/s: ram flow = ram_area x speed, 1/sqrt(2 x 500 x 1.2)",
    )
    ram_flow_floor: float = param(
        0.2,
        0.0,
        10.0,
        "m3/s",
        slot="RAM_FLOOR",
        source="A: below this ram flow a running compressor keeps one fan stage (the maps' lowest air-flow node)",
    )
    front_flow_min: float = param(
        0.05, 0.001, 1.0, "m3/s", slot="V_FRONT_MIN", source="A: natural draft through the front end"
    )
    compressor_drive_efficiency: float = param(1.0, 0.1, 1.0, slot="DRIVE_EFF", source="A")
    tau_refrigerant: float = param(10.0, 0.1, 600.0, "s", slot="TAU", source="A")
    bc_on: float = param(308.15, 173.15, 373.15, "K", slot="BC_ON", source="MW M chiller relay on T_battery")
    bc_off: float = param(303.15, 173.15, 373.15, "K", slot="BC_OFF", source="MW M chiller relay on T_battery")
    bc_critical_on: float = param(313.15, 173.15, 373.15, "K", slot="CRIT_ON", source="MW M pump relay")
    bc_critical_off: float = param(308.15, 173.15, 373.15, "K", slot="CRIT_OFF", source="MW M pump relay")
    bh_on: float = param(278.15, 173.15, 373.15, "K", slot="BH_ON", source="MW M heater relay on T_coolant")
    bh_off: float = param(288.15, 173.15, 373.15, "K", slot="BH_OFF", source="MW M heater relay on T_coolant")
    bh_ambient_max: float = param(
        278.15, 173.15, 373.15, "K", slot="BH_AMB_MAX", source="MW M heater relay: only below this ambient"
    )
    pump_idle: float = param(0.3, 0.0, 1.0, slot="PUMP_IDLE", source="MW M pump logic")
    pump_bc: float = param(0.5, 0.0, 1.0, slot="PUMP_BC", source="MW M pump logic")
    pump_critical: float = param(1.0, 0.0, 1.0, slot="PUMP_CRIT", source="MW M pump logic")
    mode_hold: float = param(
        60.0,
        0.0,
        3600.0,
        "s",
        slot="HOLD",
        source="A: a cabin request holds at least this long once set (v1 held the mode)",
    )

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        ordered("bc_off", "<", "bc_on"),
        ordered("bc_critical_off", "<", "bc_critical_on"),
        ordered("bh_on", "<", "bh_off"),
    )


@dataclass(frozen=True)
class ClimateParams:
    """Cabin climate control: vent target, blower law, requests, evaporator and frost (spec v2 section 2).

    Gains: ``vent_kp`` [K/K] with integral time ``vent_Ti`` [s];
    ``evap_kp`` [1/K], ``evap_ki`` [1/(K s)] (compressor speed on the
    evaporator outlet air); ``blend_kp`` [1/K], ``blend_ki`` [1/(K s)] (air-mix
    door of the heater core). Temperatures [K], pressures [Pa], times [s],
    ``blower_rate`` [1/s], ``rh_dehum`` [1].
    """

    vent_kp: float = param(2.0, 0.0, 100.0, "K/K", slot="VENT_KP", source="A")
    vent_Ti: float = param(300.0, 1.0, 1e5, "s", slot="VENT_TI", source="A")
    T_vent_min: float = param(
        276.15, 173.15, 373.15, "K", slot="TV_MIN", source="SM-L lowest evaporator setting 3 degC"
    )
    T_vent_max: float = param(333.15, 173.15, 373.15, "K", slot="TV_MAX", source="A")
    blower_min: float = param(0.4, 0.05, 1.0, slot="BLOWER_MIN", source="SM-S minimum 5.5 V of about 13.5 V")
    blower_dT0: float = param(2.0, 0.0, 50.0, "K", slot="BL_DT0", source="A (speed from the vent-target gap)")
    blower_dT1: float = param(15.0, 0.1, 100.0, "K", slot="BL_DT1", source="A (speed from the vent-target gap)")
    blower_rate: float = param(0.08, 1e-3, 100.0, "1/s", slot="BL_RATE", source="SM-S about +1 V/s")
    warmup_max: float = param(
        150.0,
        0.0,
        3600.0,
        "s",
        slot="WARMUP_MAX",
        source="A: the blower held at its minimum at most this long while the heater warms",
    )
    cabin_band: float = param(0.5, 0.0, 10.0, "K", slot="BAND", source="FS `te_deadband_cab_kelvin`")
    t_request_clear: float = param(300.0, 0.0, 3600.0, "s", slot="T_CLEAR", source="A")
    tau_request: float = param(60.0, 0.1, 3600.0, "s", slot="TAU_REQ", source="A")
    T_evap_min: float = param(
        276.15,
        173.15,
        373.15,
        "K",
        slot="TEV_MIN",
        source="SM-L settings (on 4 / off 3 degC); thesis Table 12 SP_evap 5-15 degC",
    )
    T_evap_max: float = param(
        288.15,
        173.15,
        373.15,
        "K",
        slot="TEV_MAX",
        source="SM-L settings (on 11 / off 10 degC); thesis Table 12 SP_evap 5-15 degC",
    )
    evap_kp: float = param(0.1, 0.0, 100.0, "1/K", slot="EV_KP", source="A")
    evap_ki: float = param(0.01, 0.0, 100.0, "1/(K s)", slot="EV_KI", source="A")
    dT_cycle: float = param(1.0, 0.05, 20.0, "K", slot="DT_CYC", source="A (SM-L: 1 K between its on and off settings)")
    t_on_min: float = param(30.0, 0.0, 3600.0, "s", slot="T_ON_MIN", source="A")
    t_off_min: float = param(
        25.0,
        0.0,
        3600.0,
        "s",
        slot="T_OFF_MIN",
        source=(
            "A: with 30 s the off phases at 25 degC lift the cabin's 60-s mean 1.1 K above its band (the "
            "evaporator air, 10 s time constant, reaches the inlet within 20 s)"
        ),
    )
    T_frost_off: float = param(
        274.65,
        263.15,
        283.15,
        "K",
        slot="TFR_OFF",
        source="SM-N (off at or below 1.5 degC); SM-F (no clutch below 1.5 degC)",
    )
    T_frost_on: float = param(278.15, 263.15, 293.15, "K", slot="TFR_ON", source="SM-N (on at or above 5.0 degC)")
    p_frost_off: float = param(
        0.15e6,
        0.0,
        1.0e6,
        "Pa",
        slot="PF_OFF",
        source='MW M "Freezing Cutoff" low end, a relay on the suction pressure',
    )
    p_frost_on: float = param(
        0.25e6,
        0.0,
        1.0e6,
        "Pa",
        slot="PF_ON",
        source='MW M "Freezing Cutoff" high end, a relay on the suction pressure',
    )
    ac_T_amb_min: float = param(
        277.15, 173.15, 373.15, "K", slot="AC_TAMB_MIN", source="SM-F (Focus 2012: no A/C below about 4 degC)"
    )
    rh_dehum: float = param(0.6, 0.1, 1.0, slot="RH_DEHUM", source="A (cleared below 0.55)")
    blend_kp: float = param(0.02, 0.0, 100.0, "1/K", slot="BLEND_KP", source="A (air-mix door of the heater core)")
    blend_ki: float = param(0.002, 0.0, 100.0, "1/(K s)", slot="BLEND_KI", source="A (air-mix door of the heater core)")

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        ordered("p_frost_off", "<", "p_frost_on"),
        ordered("T_frost_off", "<", "T_frost_on"),
        ordered("T_vent_min", "<", "T_vent_max"),
        ordered("T_evap_min", "<", "T_evap_max"),
    )


#: Cabin heating options (``hvac.heating``): an air PTC, a coolant PTC in the heater-core loop, or the
#: indirect heat pump on that loop with the coolant PTC as its backup.
HEATING = ("ptc_air", "ptc_coolant", "heat_pump")


@dataclass(frozen=True)
class HvacParams:
    """Cabin heaters, the heater-core loop and the battery's safety limits (spec v2 sections 2.5-3).

    ``heating``: ``ptc_air`` (an air PTC after the evaporator),
    ``ptc_coolant`` (a coolant PTC ``ptcw`` in loop H with a heater core) or
    ``heat_pump`` (the indirect heat pump on loop H, ``ptcw`` its backup:
    :class:`HeatPumpParams`).
    PTC gains are per K and K s times the heater's maximum power.
    The heater core is the ``heater_core`` bench's core, its conductance
    tabulated over coolant flow, coolant temperature and air flow
    (:func:`evtms.system.edrive.core_table`); loop H holds
    ``C_H`` [J/K], its pump moves ``pump_h_flow`` [m3/s] at ``pump_h_power``
    [W]. Battery relays: the coolant heater is off above
    ``bh_T_coolant_max`` (on 5 K below) and at ``bh_T_battery_max`` (on 1 K
    below); battery cooling stops below ``bc_T_battery_min`` (restarts 1 K
    above).
    """

    heating: str = choice(
        "ptc_air",
        HEATING,
        slot="HEATING",
        source=(
            "MW (an air PTC after the evaporator); `ptc_coolant`: a coolant PTC in a heater-core loop "
            "(EFFEREST, thesis 4.5); `heat_pump`: the indirect heat pump on that loop, the coolant PTC its backup "
            "(spec v2 6)"
        ),
    )
    ptc_max_power: float = param(
        6000.0,
        0.0,
        1e5,
        "W",
        slot="PTC_MAX",
        source=(
            'HV PTC heaters "up to 7 kW", EVs need "5 kW or more"; Leaf 2011-12 about 5.5 kW peak (spec v2 PTC '
            "sources; MW P 2500 W warms the cabin only to 18 degC in 30 min at -10 degC)"
        ),
    )
    ptc_kp: float = param(
        0.01, 0.0, 100.0, "1/K", slot="PTC_KP", source="A: a trim on the feed-forward, times `ptc_max_power`"
    )
    ptc_ki: float = param(
        0.001, 0.0, 100.0, "1/(K s)", slot="PTC_KI", source="A: a trim on the feed-forward, times `ptc_max_power`"
    )
    ptcw_max_power: float = param(6000.0, 0.0, 1e5, "W", slot="PTCW_MAX", source="as `ptc_max_power`")
    ptcw_kp: float = param(
        0.1, 0.0, 100.0, "1/K", slot="PTCW_KP", source="A (`C_H / (kp P_max)` about 11 s), times `ptcw_max_power`"
    )
    ptcw_ki: float = param(0.002, 0.0, 100.0, "1/(K s)", slot="PTCW_KI", source="A, times `ptcw_max_power`")
    T_H_max: float = param(
        363.15, 313.15, 373.15, "K", slot="TH_MAX", source="A (combustion cars' heater cores run on about 90 degC)"
    )
    C_H: float = param(6600.0, 100.0, 1e7, "J/K", slot="C_H", source="A: 1.5 l of glycol plus 2 kg of core")
    pump_h_flow: float = param(3.33e-4, 1e-6, 0.1, "m3/s", source="MW M pump as template (20 l/min)")
    pump_h_power: float = param(120.0, 0.0, 1e4, "W", slot="PUMP_H_POWER", source="MW M pump as template")
    bh_T_coolant_max: float = param(
        318.15,
        173.15,
        373.15,
        "K",
        slot="BH_TC_MAX",
        source="A (MWc battery zone 5-35 degC): the coolant heater is off above 45 degC coolant (on 5 K below)",
    )
    bh_T_battery_max: float = param(
        298.15,
        173.15,
        373.15,
        "K",
        slot="BH_TB_MAX",
        source="A: the coolant heater is off at a 25 degC battery (on 1 K below), in every mode",
    )
    bc_T_battery_min: float = param(
        288.15,
        173.15,
        373.15,
        "K",
        slot="BC_TB_MIN",
        source="A: battery cooling stops below a 15 degC battery (restarts 1 K above) or 5 degC coolant",
    )


@dataclass(frozen=True)
class HeatPumpParams:
    """The indirect heat pump's controls (``hvac.heating = "heat_pump"``, spec v2 section 6).

    The compressor runs the ``hp`` circuit (the water-cooled condenser heats
    the heater-core loop, the chiller draws on the e-drive loop) on a PI of
    the heater-core loop's temperature (``hp_kp`` [1/K], ``hp_ki``
    [1/(K s)]), limited so that the filtered suction pressure stays above
    ``hp_p_suction_min`` [Pa] + 10 kPa (the speed's ceiling a PI on the
    suction's distance from it, ``hp_ps_kp`` [1/Pa], ``hp_ps_ki``
    [1/(Pa s)]); below ``T_hp_min`` [K] it does not
    run. A suction pressure below ``hp_p_suction_min`` for 30 s trips it; it
    restarts after ``hp_restart_delay`` [s], and after ``hp_trips_max`` trips
    within 10 min it stays off until the oldest is 10 min old. The coolant
    PTC backs it up once it has run flat out ``hp_backup_delay`` [s] with the
    loop 2 K below its target. The radiator joins the e-drive loop as the
    heat pump's ambient source while that loop is ``hp_rad_band`` [K] below
    the ambient and is bypassed above it by as much (it keeps the drive's
    waste heat).
    """

    T_hp_min: float = param(
        258.15, 173.15, 323.15, "K", slot="HP_T_MIN", source="A: the suction guard binds first (spec v2 6)"
    )
    hp_p_suction_min: float = param(
        0.10e6, 0.02e6, 1.0e6, "Pa", slot="HP_PS_MIN", source="A (R134a saturates at -26 degC at 0.10 MPa)"
    )
    hp_kp: float = param(0.05, 0.0, 10.0, "1/K", slot="HP_KP", source="A")
    hp_ps_kp: float = param(
        2e-5,
        0.0,
        1e-3,
        "1/Pa",
        slot="HP_PS_KP",
        source="A: 0.6 of speed for 30 kPa below the limit (70-150 kPa of suction per unit speed in the cold)",
    )
    hp_ps_ki: float = param(2e-6, 0.0, 1e-4, "1/(Pa s)", slot="HP_PS_KI", source="A: integral time 10 s")
    hp_ki: float = param(0.002, 0.0, 10.0, "1/(K s)", slot="HP_KI", source="A")
    hp_backup_delay: float = param(60.0, 0.0, 3600.0, "s", slot="HP_BACKUP_DELAY", source="A")
    hp_rad_band: float = param(1.0, 0.0, 20.0, "K", slot="HP_RAD_BAND", source="A")
    hp_restart_delay: float = param(120.0, 0.0, 3600.0, "s", slot="HP_RESTART", source="A")
    hp_trips_max: int = param(3, 1, 3, "1", whole=True, slot="HP_TRIPS_MAX", source="A (per 10 min)")


@dataclass(frozen=True)
class SystemParams:
    """All parameters of a system simulation."""

    vehicle: VehicleParams = field(default_factory=VehicleParams)
    battery: BatteryParams = field(default_factory=BatteryParams)
    cabin: CabinParams = field(default_factory=CabinParams)
    coolant: CoolantParams = field(default_factory=CoolantParams)
    controls: ControlParams = field(default_factory=ControlParams)
    climate: ClimateParams = field(default_factory=ClimateParams)
    hvac: HvacParams = field(default_factory=HvacParams)
    edrive: EdriveParams = field(default_factory=EdriveParams)
    heatpump: HeatPumpParams = field(default_factory=HeatPumpParams)

    def to_json(self) -> str:
        """Every parameter, by table, as JSON (recorded in the output file)."""
        return json.dumps({k: dataclasses.asdict(getattr(self, k)) for k in SECTIONS}, sort_keys=True)


SECTIONS = ("vehicle", "battery", "cabin", "coolant", "controls", "climate", "hvac", "edrive", "heatpump")

#: v1 names that moved or went: (table, name) -> what to say instead of applying them.
MIGRATED: dict[tuple[str, str], str] = {
    ("controls", "ptc_max_power"): "is [hvac] ptc_max_power in v2",
    ("controls", "ptc_kp"): "is [hvac] ptc_kp in v2 (a trim on the vent-air error)",
    ("controls", "ptc_ki"): "is [hvac] ptc_ki in v2 (a trim on the vent-air error)",
    ("controls", "ptc_T_out"): "was dropped in v2: the air PTC follows the vent-air target",
    ("controls", "blower_kp"): "was dropped in v2: the blower follows the vent-target law ([climate] blower_*)",
    ("controls", "blower_ki"): "was dropped in v2: the blower follows the vent-target law ([climate] blower_*)",
    ("controls", "blower_min"): "is [climate] blower_min in v2",
    ("controls", "compressor_kp"): "is [controls] chiller_kp in v2; the cabin compressor follows [climate] evap_kp",
    ("controls", "compressor_ki"): "is [controls] chiller_ki in v2; the cabin compressor follows [climate] evap_ki",
    ("controls", "p_suction_target"): "is [controls] chiller_p_suction in v2",
    ("controls", "freeze_cutoff_low"): "is [climate] p_frost_off in v2 (a relay, no ramp)",
    ("controls", "freeze_cutoff_high"): "is [climate] p_frost_on in v2 (a relay, no ramp)",
    ("controls", "cabin_deadband"): "is [climate] cabin_band in v2",
    ("cabin", "recirculation"): "is [cabin] recirc_cool, recirc_heat and recirc_warmup in v2",
    ("battery", "g_coolant"): "is [battery] g_coolant_fixed in v2 (unset: the conductance follows the pump flow)",
    ("cabin", "blower_flow_max"): (
        "is the evaporator bench's [evaporator] fan_flow_max, read from the cycle LUTs the maps are built on "
        "(the maps' blower axis is a share of it); build the LUTs with it"
    ),
    ("controls", "fan_flow_max"): (
        "is the condenser bench's [condenser] fan_flow_max, read from the cycle LUTs the maps are built on "
        "(the maps' fan axis is a share of it); build the LUTs with it"
    ),
    ("hvac", "heater_core_ua"): (
        "was dropped: the heater core is the heater_core bench's core ([heater_core] table), its conductance "
        "tabulated over coolant flow, coolant temperature and air flow"
    ),
    ("hvac", "heater_core_air_ref"): "was dropped with heater_core_ua: the heater core is the heater_core bench's core",
    ("controls", "condenser_fan"): (
        "was dropped in v2: the fan is staged on the discharge pressure ([controls] fan_p1, fan_p1_band, fan_band) "
        "and ram air adds to it ([controls] ram_area)"
    ),
}


def system_params_from_dict(data: dict[str, Any], base: SystemParams | None = None) -> SystemParams:
    """``base`` (default: the defaults) with the tables of ``data`` applied, every value checked.

    Each value is checked against its field's declaration (:func:`evtms.params.param`:
    range, whole number, choices) and each table against its ``RELATIONS``
    (:func:`evtms.params.override`); a name of the first version is refused
    with its successor (:data:`MIGRATED`).
    """
    params = base or SystemParams()
    tables = {}
    for section, values in data.items():
        if section not in SECTIONS:
            raise EvtmsInputError(f"table [{section}] is unknown; allowed: {', '.join(f'[{s}]' for s in SECTIONS)}")
        if not isinstance(values, dict):
            raise EvtmsInputError(f"{section} must be a table [{section}], not a value")
        for name in values:
            if (section, name) in MIGRATED:
                raise EvtmsInputError(f"[{section}] {name} {MIGRATED[section, name]}")
        tables[section] = override(getattr(params, section), values, f"[{section}]")
    return dataclasses.replace(params, **tables)


def parameter_fields(section: str) -> tuple[dataclasses.Field, ...]:
    """The declared parameters of table ``section`` (:data:`SECTIONS`), in declaration order."""
    return dataclasses.fields(SystemParams.__dataclass_fields__[section].default_factory)


@dataclass(frozen=True)
class ParameterTree:
    """Every parameter of a study, from one TOML file: the components' and the system's.

    Attributes
    ----------
    components : Parameters
        The fluid, the air boundary and one table per component
        (:class:`evtms.benches.parameters.Parameters`): what the benches and the
        LUTs are made with.
    system : SystemParams
        The system simulator's tables.
    given : frozenset of str
        The top-level tables and keys the file gave (``condenser``, ``cabin``, ``fluid``, ...).
    path : Path, optional
        The file they were read from.
    """

    components: Any
    system: SystemParams
    given: frozenset[str] = frozenset()
    path: Path | None = None

    def given_components(self) -> tuple[str, ...]:
        """The component-side names the file gave (``fluid``, ``backend``, ``environment`` or a component)."""
        from evtms.benches.parameters import SECTIONS as COMPONENT_SECTIONS

        names = ("fluid", "backend", *COMPONENT_SECTIONS)
        return tuple(n for n in names if n in self.given)


def parameter_tree_from_dict(data: dict[str, Any]) -> ParameterTree:
    """The defaults with the tables of ``data`` (parsed TOML) applied, each by the side that declares it.

    ``fluid``, ``backend``, ``[environment]`` and the component tables
    (``[condenser]``, ...) go to :func:`evtms.params.apply_tables`; the system's
    (:data:`SECTIONS`) to :func:`system_params_from_dict`; any other name is
    refused with both lists.
    """
    from evtms.benches.parameters import SECTIONS as COMPONENT_SECTIONS
    from evtms.benches.parameters import parameters_from_dict

    component_keys = ("fluid", "backend", *COMPONENT_SECTIONS)
    for key in data:
        if key not in component_keys and key not in SECTIONS:
            allowed = ", ".join(["fluid", "backend"] + [f"[{s}]" for s in (*COMPONENT_SECTIONS, *SECTIONS)])
            raise EvtmsInputError(f"unknown table or key {key!r}; allowed: {allowed}")
    components = parameters_from_dict({k: v for k, v in data.items() if k in component_keys})
    system = system_params_from_dict({k: v for k, v in data.items() if k in SECTIONS})
    return ParameterTree(components, system, frozenset(data))


def load_parameter_tree(path: str | Path | None = None) -> ParameterTree:
    """Default parameters, overridden by a TOML file's tables if ``path`` is given: the one parameter loader.

    One file may hold the components' tables (what the benches and LUTs are
    made with) and the system's; each command uses its side. The file is read
    by :func:`evtms.params.read_params_toml` (bounded, UTF-8, valid TOML).

    Raises
    ------
    EvtmsInputError
        One line naming the file and the bad table, name or value and what
        is allowed, e.g. ``params file 'p.toml': [cabin] volume = -1 is not
        allowed; allowed: 0.1 <= volume <= 100 m3``.
    """
    if path is None:
        from evtms.benches.parameters import Parameters

        return ParameterTree(Parameters(), SystemParams())
    from evtms.params import read_params_toml

    data = read_params_toml(path)
    try:
        return dataclasses.replace(parameter_tree_from_dict(data), path=Path(path))
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"params file {str(path)!r}: {exc}") from None


def load_system_params(path: str | Path | None = None) -> SystemParams:
    """The system side of :func:`load_parameter_tree` (the file may hold component tables too)."""
    return load_parameter_tree(path).system
