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
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError
from evtms.system.battery import BatteryParams
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
    ``Q_sun = 3 sun sun_shield`` [W]; ``blower_flow_max`` [m3/s] and ``blower_power_max`` [W] (x u^3);
    ``T_set`` [K] the cabin setpoint; ``rh_cabin`` [1] the initial relative
    humidity; ``T_init`` [K] the initial temperature (None: the ambient).
    """

    volume: float = 3.0
    glass_area: float = 3.0
    glass_thickness: float = 0.004
    glass_conductivity: float = 0.96
    glass_heat_capacity: float = 26.2e3
    doors_area: float = 4.0
    doors_thickness: float = 0.06
    doors_conductivity: float = 0.08
    doors_heat_capacity: float = 37.5e3
    roof_area: float = 2.0
    roof_thickness: float = 0.04
    roof_conductivity: float = 0.08
    roof_heat_capacity: float = 15.0e3
    wall_htc: float = 40.0
    interior_heat_capacity: float = 80.0e3
    interior_conductance: float = 300.0
    recirc_cool: float = 0.85
    recirc_heat: float = 0.8
    recirc_warmup: float = 0.8
    recirc_vent: float = 0.5
    n_occupants: int = 1
    rh_cabin: float = 0.5
    sun: float | None = None
    sun_shield: float = 0.5
    blower_flow_max: float = 0.3
    blower_power_max: float = 250.0
    T_set: float = 295.15
    T_init: float | None = None

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

    heat_capacity: float = 16.5e3
    density: float = 1070.0
    cp: float = 3300.0
    viscosity: float = 3.8e-3
    conductivity: float = 0.38
    flow_max: float = 4.0e-4
    pump_power_ref: float = 120.0
    pump_speed_max: float = 1200.0
    heater_max_power: float = 4000.0
    T_init: float | None = None


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
    the share of stages on, its flow that times ``fan_flow_max`` [m3/s] (the
    condenser bench's at fan 1), its power ``fan_power_nominal`` at
    ``fan_flow_nominal`` [m3/s] scaled with the flow cubed. Ram air
    ``ram_area`` [m2] times the vehicle speed adds to the fan's flow in
    quadrature (one quadratic resistance), never below ``front_flow_min``
    [m3/s] (natural draft).
    """

    chiller_kp: float = 1.0
    chiller_ki: float = 0.2
    chiller_p_suction: float = 0.3e6
    compressor_min_speed: float = 0.1
    fan_power_nominal: float = 533.0
    fan_flow_nominal: float = 0.8
    fan_flow_max: float = 0.88
    fan_p1: float = 0.8e6
    fan_p1_band: float = 0.3e6
    fan_band: float = 0.4e6
    ram_area: float = 0.0289
    ram_flow_floor: float = 0.2
    front_flow_min: float = 0.05
    compressor_drive_efficiency: float = 1.0
    tau_refrigerant: float = 10.0
    bc_on: float = 308.15
    bc_off: float = 303.15
    bc_critical_on: float = 313.15
    bc_critical_off: float = 308.15
    bh_on: float = 278.15
    bh_off: float = 288.15
    bh_ambient_max: float = 278.15
    pump_idle: float = 0.3
    pump_bc: float = 0.5
    pump_critical: float = 1.0
    mode_hold: float = 60.0


@dataclass(frozen=True)
class ClimateParams:
    """Cabin climate control: vent target, blower law, requests, evaporator and frost (spec v2 section 2).

    Gains: ``vent_kp`` [K/K] with integral time ``vent_Ti`` [s];
    ``evap_kp`` [1/K], ``evap_ki`` [1/(K s)] (compressor speed on the
    evaporator outlet air); ``blend_kp`` [1/K], ``blend_ki`` [1/(K s)] (air-mix
    door of the heater core). Temperatures [K], pressures [Pa], times [s],
    ``blower_rate`` [1/s], ``rh_dehum`` [1].
    """

    vent_kp: float = 2.0
    vent_Ti: float = 300.0
    T_vent_min: float = 276.15
    T_vent_max: float = 333.15
    blower_min: float = 0.4
    blower_dT0: float = 2.0
    blower_dT1: float = 15.0
    blower_rate: float = 0.08
    warmup_max: float = 150.0
    cabin_band: float = 0.5
    t_request_clear: float = 300.0
    tau_request: float = 60.0
    T_evap_min: float = 276.15
    T_evap_max: float = 288.15
    evap_kp: float = 0.1
    evap_ki: float = 0.01
    dT_cycle: float = 1.0
    t_on_min: float = 30.0
    t_off_min: float = 25.0
    T_frost_off: float = 274.65
    T_frost_on: float = 278.15
    p_frost_off: float = 0.15e6
    p_frost_on: float = 0.25e6
    ac_T_amb_min: float = 277.15
    rh_dehum: float = 0.6
    blend_kp: float = 0.02
    blend_ki: float = 0.002


#: Cabin heating options (``hvac.heating``); the heat pump is a later version's.
HEATING = ("ptc_air", "ptc_coolant")


@dataclass(frozen=True)
class HvacParams:
    """Cabin heaters, the heater-core loop and the battery's safety limits (spec v2 sections 2.5-3).

    ``heating``: ``ptc_air`` (an air PTC after the evaporator) or
    ``ptc_coolant`` (a coolant PTC ``ptcw`` in loop H with a heater core).
    PTC gains are per K and K s times the heater's maximum power.
    ``heater_core_ua`` [W/K] at ``heater_core_air_ref`` [kg/s] of air through
    the core, scaled with the air flow to the power 0.6; loop H holds
    ``C_H`` [J/K], its pump moves ``pump_h_flow`` [m3/s] at ``pump_h_power``
    [W]. Battery relays: the coolant heater is off above
    ``bh_T_coolant_max`` (on 5 K below) and at ``bh_T_battery_max`` (on 1 K
    below); battery cooling stops below ``bc_T_battery_min`` (restarts 1 K
    above).
    """

    heating: str = "ptc_air"
    ptc_max_power: float = 6000.0
    ptc_kp: float = 0.01
    ptc_ki: float = 0.001
    ptcw_max_power: float = 6000.0
    ptcw_kp: float = 0.1
    ptcw_ki: float = 0.002
    T_H_max: float = 363.15
    C_H: float = 6600.0
    pump_h_flow: float = 3.33e-4
    pump_h_power: float = 120.0
    heater_core_ua: float = 250.0
    heater_core_air_ref: float = 0.15
    bh_T_coolant_max: float = 318.15
    bh_T_battery_max: float = 298.15
    bc_T_battery_min: float = 288.15


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

    def to_json(self) -> str:
        """Every parameter, by table, as JSON (recorded in the output file)."""
        return json.dumps({k: dataclasses.asdict(getattr(self, k)) for k in SECTIONS}, sort_keys=True)


SECTIONS = ("vehicle", "battery", "cabin", "coolant", "controls", "climate", "hvac")

_T = (173.15, 373.15)  # any temperature parameter [K]
#: Allowed range per parameter (both ends included; ``None`` for an optional temperature too).
RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "vehicle": {
        "mass": (100.0, 1e5),
        "drag_coefficient": (0.0, 3.0),
        "frontal_area": (0.1, 50.0),
        "rolling_resistance": (0.0, 0.1),
        "wheel_radius": (0.05, 2.0),
        "wheel_inertia": (0.0, 100.0),
        "gear_ratio": (0.1, 50.0),
        "gear_efficiency": (0.1, 1.0),
        "regen_fraction": (0.0, 1.0),
        "loss_factor": (0.0, 10.0),
        "aux_power": (0.0, 1e5),
    },
    "battery": {
        "n_series": (1, 1000),
        "n_parallel": (1, 1000),
        "cell_capacity": (0.01, 1000.0),
        "cell_voltage_min": (0.5, 5.0),
        "r2": (0.0, 10.0),
        "c2": (0.0, 1e7),
        "soc_min": (0.0, 1.0),
        "soc_max": (0.0, 1.0),
        "soc_init": (0.0, 1.0),
        "heat_capacity": (1.0, 1e8),
        "g_cells_plate": (1.0, 1e6),
        "plate_channels": (1, 1000),
        "plate_channel_diameter": (1e-4, 0.1),
        "plate_channel_length": (0.01, 100.0),
        "g_coolant_fixed": (0.0, 1e5),
        "g_ambient": (0.0, 1e5),
        "T_init": _T,
    },
    "cabin": {
        **{
            f"{w}_{k}": r
            for w in WALLS
            for k, r in (
                ("area", (0.01, 100.0)),
                ("thickness", (1e-4, 1.0)),
                ("conductivity", (1e-3, 500.0)),
                ("heat_capacity", (1.0, 1e7)),
            )
        },
        "volume": (0.1, 100.0),
        "wall_htc": (0.1, 1000.0),
        "interior_heat_capacity": (0.0, 1e8),
        "interior_conductance": (0.0, 1e5),
        "recirc_cool": (0.0, 1.0),
        "recirc_heat": (0.0, 1.0),
        "recirc_warmup": (0.0, 1.0),
        "recirc_vent": (0.0, 1.0),
        "n_occupants": (0, 100),
        "rh_cabin": (0.0, 1.0),
        "sun": (0.0, 1500.0),
        "sun_shield": (0.0, 1.0),
        "blower_flow_max": (0.001, 10.0),
        "blower_power_max": (0.0, 1e4),
        "T_set": (283.15, 308.15),
        "T_init": _T,
    },
    "coolant": {
        "heat_capacity": (1.0, 1e8),
        "density": (100.0, 3000.0),
        "cp": (100.0, 1e4),
        "viscosity": (1e-5, 1.0),
        "conductivity": (0.01, 10.0),
        "flow_max": (1e-6, 0.1),
        "pump_power_ref": (0.0, 1e4),
        "pump_speed_max": (1.0, 1e5),
        "heater_max_power": (0.0, 1e5),
        "T_init": _T,
    },
    "controls": {
        "chiller_kp": (0.0, 1e3),
        "chiller_ki": (0.0, 1e3),
        "chiller_p_suction": (0.05e6, 1.0e6),
        "compressor_min_speed": (0.01, 1.0),
        "fan_power_nominal": (0.0, 1e4),
        "fan_flow_nominal": (0.01, 100.0),
        "fan_flow_max": (0.01, 100.0),
        "fan_p1": (0.1e6, 3.0e6),
        "fan_p1_band": (0.0, 2.0e6),
        "fan_band": (0.0, 2.0e6),
        "ram_area": (0.0, 1.0),
        "ram_flow_floor": (0.0, 10.0),
        "front_flow_min": (0.001, 1.0),
        "compressor_drive_efficiency": (0.1, 1.0),
        "tau_refrigerant": (0.1, 600.0),
        **{k: _T for k in ("bc_on", "bc_off", "bc_critical_on", "bc_critical_off", "bh_on", "bh_off")},
        "bh_ambient_max": _T,
        "pump_idle": (0.0, 1.0),
        "pump_bc": (0.0, 1.0),
        "pump_critical": (0.0, 1.0),
        "mode_hold": (0.0, 3600.0),
    },
    "climate": {
        "vent_kp": (0.0, 100.0),
        "vent_Ti": (1.0, 1e5),
        "T_vent_min": _T,
        "T_vent_max": _T,
        "blower_min": (0.05, 1.0),
        "blower_dT0": (0.0, 50.0),
        "blower_dT1": (0.1, 100.0),
        "blower_rate": (1e-3, 100.0),
        "warmup_max": (0.0, 3600.0),
        "cabin_band": (0.0, 10.0),
        "t_request_clear": (0.0, 3600.0),
        "tau_request": (0.1, 3600.0),
        "T_evap_min": _T,
        "T_evap_max": _T,
        "evap_kp": (0.0, 100.0),
        "evap_ki": (0.0, 100.0),
        "dT_cycle": (0.05, 20.0),
        "t_on_min": (0.0, 3600.0),
        "t_off_min": (0.0, 3600.0),
        "T_frost_off": (263.15, 283.15),
        "T_frost_on": (263.15, 293.15),
        "p_frost_off": (0.0, 1.0e6),
        "p_frost_on": (0.0, 1.0e6),
        "ac_T_amb_min": _T,
        "rh_dehum": (0.1, 1.0),
        "blend_kp": (0.0, 100.0),
        "blend_ki": (0.0, 100.0),
    },
    "hvac": {
        "ptc_max_power": (0.0, 1e5),
        "ptc_kp": (0.0, 100.0),
        "ptc_ki": (0.0, 100.0),
        "ptcw_max_power": (0.0, 1e5),
        "ptcw_kp": (0.0, 100.0),
        "ptcw_ki": (0.0, 100.0),
        "T_H_max": (313.15, 373.15),
        "C_H": (100.0, 1e7),
        "pump_h_flow": (1e-6, 0.1),
        "pump_h_power": (0.0, 1e4),
        "heater_core_ua": (1.0, 1e5),
        "heater_core_air_ref": (1e-3, 10.0),
        "bh_T_coolant_max": _T,
        "bh_T_battery_max": _T,
        "bc_T_battery_min": _T,
    },
}

#: Choices of the parameters that are names, not numbers.
CHOICES: dict[str, dict[str, tuple[str, ...]]] = {"hvac": {"heating": HEATING}}

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
    ("controls", "condenser_fan"): (
        "was dropped in v2: the fan is staged on the discharge pressure ([controls] fan_p1, fan_p1_band, fan_band) "
        "and ram air adds to it ([controls] ram_area)"
    ),
}

#: Pairs that must hold: (table, smaller, larger, strictly).
_ORDER = (
    ("battery", "soc_min", "soc_init", True),
    ("battery", "soc_init", "soc_max", False),
    ("controls", "bc_off", "bc_on", True),
    ("controls", "bc_critical_off", "bc_critical_on", True),
    ("controls", "bh_on", "bh_off", True),
    ("climate", "p_frost_off", "p_frost_on", True),
    ("climate", "T_frost_off", "T_frost_on", True),
    ("climate", "T_vent_min", "T_vent_max", True),
    ("climate", "T_evap_min", "T_evap_max", True),
)

_INTEGERS = {"n_series", "n_parallel", "n_occupants", "plate_channels"}


def _value(section: str, name: str, value: Any) -> float | int | str:
    choices = CHOICES.get(section, {}).get(name)
    if choices is not None:
        if value not in choices:
            raise EvtmsInputError(f"[{section}] {name} = {value!r} is not allowed; allowed: {', '.join(choices)}")
        return value
    lo, hi = RANGES[section][name]
    allowed = f"allowed: {lo:g} <= {name} <= {hi:g}"
    if name in _INTEGERS:
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise EvtmsInputError(f"[{section}] {name} = {value!r} is not allowed; {allowed} (whole number)")
        return int(value)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise EvtmsInputError(f"[{section}] {name} = {value!r} is not a finite number; {allowed}")
    if not lo <= value <= hi:
        raise EvtmsInputError(f"[{section}] {name} = {value!r} is not allowed; {allowed}")
    return float(value)


def system_params_from_dict(data: dict[str, Any], base: SystemParams | None = None) -> SystemParams:
    """``base`` (default: the defaults) with the tables of ``data`` applied, every value checked."""
    params = base or SystemParams()
    tables = {}
    for section, values in data.items():
        if section not in SECTIONS:
            raise EvtmsInputError(f"table [{section}] is unknown; allowed: {', '.join(f'[{s}]' for s in SECTIONS)}")
        if not isinstance(values, dict):
            raise EvtmsInputError(f"{section} must be a table [{section}], not a value")
        names = {**RANGES[section], **CHOICES.get(section, {})}
        for name in values:
            if (section, name) in MIGRATED:
                raise EvtmsInputError(f"[{section}] {name} {MIGRATED[section, name]}")
            if name not in names:
                raise EvtmsInputError(f"[{section}] {name} is unknown; allowed: {', '.join(sorted(names))}")
        checked = {name: _value(section, name, v) for name, v in values.items()}
        tables[section] = dataclasses.replace(getattr(params, section), **checked)
    params = dataclasses.replace(params, **tables)
    for section, small, large, strict in _ORDER:
        a, b = getattr(getattr(params, section), small), getattr(getattr(params, section), large)
        if a > b or (strict and a == b):
            rel = "<" if strict else "<="
            raise EvtmsInputError(f"[{section}] needs {small} {rel} {large}; got {small} = {a:g}, {large} = {b:g}")
    return params


def load_system_params(path: str | Path | None = None) -> SystemParams:
    """Default parameters, overridden by a TOML file's tables if ``path`` is given.

    Raises
    ------
    EvtmsInputError
        One line naming the file and the bad table, name or value and what
        is allowed, e.g. ``params file 'p.toml': [cabin] volume = -1 is not
        allowed; allowed: 0.1 <= volume <= 100``.
    """
    if path is None:
        return SystemParams()
    from evtms.params import read_params_toml

    name = repr(str(path))
    data = read_params_toml(path)
    try:
        return system_params_from_dict(data)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"params file {name}: {exc}") from None
