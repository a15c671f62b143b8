"""A drive-cycle simulation of the whole thermal system: set-up, the loop, records and ledgers.

:func:`simulate` prepares everything the compiled loop (:mod:`evtms.system.loop`)
needs as flat arrays: the drive cycle's motor power per time step (from the
per-segment e-drive model, :func:`evtms.system.vehicle.drive_segments`,
averaged exactly over each step, with and without regeneration), the packed
parameters, the battery cell tables, the refrigerant's saturation curve and
the cycle maps; it runs the loop, then turns the per-step values into the
output records (states at ``t_k = k dt_out``, powers the mean over
``(t_k-1, t_k]``) and closes the ledgers of every subsystem.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812 - the loop's index constants, read as L.P_*, L.S_*, L.O_*
from evtms.system.controllers import ControlContext, SupervisionLog, Supervisor, check_period, run_supervised
from evtms.system.drive_cycles import DriveCycle
from evtms.system.edrive import MOTOR_REQUIREMENT, core_table, jacket_slots
from evtms.system.inputs import INPUT_NAMES, InputValue, check_inputs, per_step
from evtms.system.mode_model import MODE_CODES, ModeModels
from evtms.system.params import FAN_STAGE_CURVES, SECTIONS, WALLS, SystemParams
from evtms.system.refrigerant import Refrigerant
from evtms.system.tables import battery_cell_tables
from evtms.system.vehicle import deviated_cycle, drive_segments

P_ATM = 101325.0  # [Pa]
#: Most time steps one simulation may take (23 days at 1 s; the loop's arrays take ~0.7 kB per step).
MAX_STEPS = 2_000_000
#: Most bytes of the step and record arrays of one simulation (:func:`run_bytes`): nearly twice those of the
#: longest run at the default 1 s (a week's cycle or range test after a day's preconditioning, 0.94 GB),
#: and more than :data:`MAX_STEPS` steps with sparse records take (1.65 GB). Temporaries add about a quarter.
MAX_RUN_BYTES = 1_750_000_000
#: ``--mode``: auto, or a forced mode by name (:data:`evtms.system.mode_model.MODE_CODES`).
MODES = {"auto": -1, **MODE_CODES}
#: How the refrigerant loop (and, for surrogates, the thermal plant) is computed.
MODELS = ("lut", "physics", "surrogate")


@dataclass
class SimulationResult:
    """One simulation's records, ledgers and summary.

    Attributes
    ----------
    records : dict of str to numpy.ndarray
        Output variables on the record times (see :data:`RECORD_VARIABLES`).
    mode, flags : numpy.ndarray
        Mode code (int8) and flag bits (uint16) per record.
    ledgers : dict of str to float
        Relative residual of every ledger (see :func:`ledgers`).
    summary : dict
        The ``--json`` figures of the run.
    attrs : dict
        Run description for the output file.
    """

    records: dict[str, np.ndarray]
    mode: np.ndarray
    flags: np.ndarray
    ledgers: dict[str, float]
    summary: dict
    attrs: dict = field(default_factory=dict)
    #: The loop's own arrays (``states``, ``out``, ``modes``, ``flags``, ``dts``, ``par``) when asked for.
    trace: dict | None = None


#: Output variable -> (units, long_name); states at the record time, powers the mean over its interval.
RECORD_VARIABLES: dict[str, tuple[str, str]] = {
    "speed": ("m s-1", "vehicle speed"),
    "distance": ("m", "distance driven"),
    "P_wheel": ("W", "power at the wheels (< 0 braking)"),
    "P_traction": ("W", "positive part of the power at the wheels"),
    "P_motor_el": ("W", "motor electrical power (< 0 regenerating)"),
    "P_battery": ("W", "battery terminal power (> 0 discharging)"),
    "P_hvac": ("W", "electrical power of the thermal system"),
    "P_compressor": ("W", "compressor electrical power"),
    "P_ptc": ("W", "PTC air heater power"),
    "P_heater": ("W", "coolant heater power"),
    "P_blower": ("W", "cabin blower power"),
    "P_fan": ("W", "condenser fan power"),
    "P_pump": ("W", "coolant pump power"),
    "P_pump_ed": ("W", "e-drive loop pump power (low-voltage side)"),
    "Q_edrive": ("W", "e-drive loss into the motor and inverter (0 with edrive.model ambient: to the ambient)"),
    "Q_dcdc": ("W", "DC-DC converter loss feeding the low-voltage loads"),
    "Q_radiator": ("W", "radiator heat flow from the e-drive coolant to the air (< 0 from the air)"),
    "T_air_radiator": ("K", "air entering the radiator (behind the condenser)"),
    "u_pump_ed": ("1", "e-drive loop pump command"),
    "radiator_in": ("1", "share of the interval the radiator was in the loop (not bypassed)"),
    "Q_wcc": ("W", "heat pump: water-cooled condenser heat into the heater-core loop"),
    "Q_chiller_ed": ("W", "heat pump: chiller heat drawn from the e-drive loop"),
    "hp_speed_ceiling": ("1", "heat pump: the suction limiter's speed ceiling (1: not limiting; NaN: off)"),
    "Q_evaporator": ("W", "evaporator heat flow from the cabin air, total (> 0 cooling)"),
    "Q_latent": ("W", "latent part of Q_evaporator (condensate)"),
    "Q_chiller": ("W", "chiller heat flow from the coolant (> 0 cooling)"),
    "Q_condenser": ("W", "condenser heat flow to the ambient air"),
    "Q_battery_gen": ("W", "heat generated in the battery"),
    "Q_battery_to_coolant": ("W", "heat flow battery to coolant"),
    "v_battery": ("V", "battery terminal voltage"),
    "i_battery": ("A", "battery current (> 0 discharging)"),
    "SOC": ("1", "battery state of charge"),
    "T_battery": ("K", "battery temperature"),
    "T_coolant": ("K", "coolant temperature"),
    "T_cabin": ("K", "cabin air temperature"),
    "T_glass": ("K", "glass temperature"),
    "T_doors": ("K", "doors temperature"),
    "T_roof": ("K", "roof temperature"),
    "T_interior": ("K", "cabin interior mass temperature"),
    "v_rc": ("V", "voltage of the battery's RC branch (0 when off)"),
    "RH_cabin": ("1", "cabin air relative humidity"),
    "T_supply": ("K", "vent air temperature: the cabin air node's inflow after evaporator and heaters"),
    "T_evap_air": ("K", "air temperature after the cabin evaporator"),
    "T_vent_target": ("K", "vent-air target of the climate control"),
    "T_evap_target": ("K", "evaporator-air target while the cabin coil is requested"),
    "recirculation": ("1", "recirculated share of the blower's air"),
    "T_heater_loop": ("K", "heater-core loop coolant temperature (heater-core inlet)"),
    "T_motor": ("K", "motor temperature"),
    "T_inverter": ("K", "inverter temperature"),
    "T_dcdc": ("K", "DC-DC converter temperature"),
    "T_coolant_ed": ("K", "e-drive loop coolant temperature"),
    "T_heater_target": ("K", "heater-core loop target while its PTC runs"),
    "Q_heater_core": ("W", "heat from the heater core to the cabin air"),
    "P_ptcw": ("W", "coolant PTC power (heater-core loop)"),
    "P_pump_h": ("W", "heater-core loop pump power"),
    "blend": ("1", "air-mix door: share of the air through the heater core"),
    "Q_battery_ext": ("W", "external heat into the battery (input)"),
    "compressor_on": ("1", "share of the interval the compressor ran"),
    "circuit": ("1", "refrigerant circuit: 0 none, 1 cabin, 2 chiller, 3 cabin+chiller (last step)"),
    "p_suction": ("Pa", "compressor suction pressure (filtered)"),
    "p_discharge": ("Pa", "compressor discharge pressure (filtered)"),
    "compressor_speed": ("1", "compressor speed command, fraction of maximum"),
    "blower": ("1", "blower command"),
    "u_pump": ("1", "coolant pump command"),
    "fan": ("1", "front-end fan command: the condenser's stages or the motor's requirement, the larger"),
    "V_front": ("m3 s-1", "air flow through the condenser, fan and ram air"),
}

#: The e-drive pump's and fan's motor-temperature requirement as the loop reads it: nodes [K], commands [1].
MOTOR_TABLE = tuple(np.asarray(MOTOR_REQUIREMENT[k], np.float64) for k in ("T_motor", "command"))

# Per-step output column -> record variable, for the interval means.
_MEANS = {
    "P_motor_el": L.O_P_MOTOR_EL,
    "P_battery": L.O_P_BATTERY,
    "P_hvac": L.O_P_HVAC,
    "P_compressor": L.O_P_COMPRESSOR,
    "P_ptc": L.O_P_PTC,
    "P_heater": L.O_P_HEATER,
    "P_blower": L.O_P_BLOWER,
    "P_fan": L.O_P_FAN,
    "P_pump": L.O_P_PUMP,
    "Q_evaporator": L.O_Q_EVAP,
    "Q_latent": L.O_Q_LATENT,
    "Q_chiller": L.O_Q_CHILLER,
    "Q_condenser": L.O_Q_COND,
    "Q_battery_gen": L.O_Q_GEN,
    "v_battery": L.O_V,
    "i_battery": L.O_I,
    "T_supply": L.O_T_SUPPLY,
    "T_evap_air": L.O_T_EVAP_AIR,
    "T_vent_target": L.O_T_VENT_TARGET,
    "T_evap_target": L.O_T_EVAP_TARGET,
    "recirculation": L.O_RECIRC,
    "T_heater_target": L.O_T_H_TARGET,
    "Q_heater_core": L.O_Q_HC,
    "P_ptcw": L.O_P_PTCW,
    "P_pump_h": L.O_P_PUMP_H,
    "blend": L.O_BLEND,
    "Q_battery_ext": L.O_Q_EXT,
    "compressor_on": L.O_COMP_ON,
    "p_suction": L.O_P_SUCTION,
    "p_discharge": L.O_P_DISCHARGE,
    "compressor_speed": L.O_SPEED_CMD,
    "blower": L.O_BLOWER,
    "u_pump": L.O_U_PUMP,
    "fan": L.O_FAN,
    "V_front": L.O_V_FRONT,
    "P_pump_ed": L.O_P_PUMP_E,
    "Q_edrive": L.O_Q_DRIVE,
    "Q_dcdc": L.O_Q_DCDC,
    "Q_radiator": L.O_Q_RAD,
    "T_air_radiator": L.O_T_AIR_RAD,
    "u_pump_ed": L.O_U_PUMP_E,
    "radiator_in": L.O_RAD_IN,
    "Q_wcc": L.O_Q_WCC,
    "Q_chiller_ed": L.O_Q_CH_E,
    "hp_speed_ceiling": L.O_HP_CEILING,
}
_STATES = {
    "SOC": L.S_SOC,
    "T_battery": L.S_TB,
    "T_coolant": L.S_TC,
    "T_cabin": L.S_TA,
    "T_glass": L.S_TGLASS,
    "T_doors": L.S_TDOORS,
    "T_roof": L.S_TROOF,
    "T_interior": L.S_TINT,
    "v_rc": L.S_VRC,
    "T_heater_loop": L.S_TH,
    "T_motor": L.S_TM,
    "T_inverter": L.S_TI,
    "T_dcdc": L.S_TD,
    "T_coolant_ed": L.S_TE,
}


def step_count(duration: float, dt: float) -> int:
    """Steps of ``dt`` [s] that cover ``duration`` [s]; more than :data:`MAX_STEPS` is an input error."""
    n = math.ceil(duration / dt - 1e-9)
    if n > MAX_STEPS:
        raise EvtmsInputError(
            f"`dt` {dt:g} s gives {n:,} steps over {duration:g} s; allowed: at most {MAX_STEPS:,} steps"
        )
    return n


#: Bytes per time step of the arrays :func:`simulate` allocates for the loop: states and outputs, the
#: step's motor power and external input columns, its edges, length and plug flag (float64), mode and flags.
STEP_BYTES = 8 * (L.N_S + L.N_O + 6 + len(INPUT_NAMES) + 3) + 1 + 2
#: Bytes per output record: every record variable and the time (float64), mode and flags.
RECORD_BYTES = 8 * (len(RECORD_VARIABLES) + 1) + 1 + 2


def run_bytes(steps: int, records: int) -> int:
    """Bytes of the step and record arrays of a run of ``steps`` steps and ``records`` records."""
    return steps * STEP_BYTES + records * RECORD_BYTES


def check_run_size(duration: float, dt: float, every: float) -> int:
    """Steps of a run of ``duration`` [s] at ``dt`` recorded every ``every`` [s], checked before any allocation.

    Raises
    ------
    EvtmsInputError
        More than :data:`MAX_STEPS` steps (:func:`step_count`), or step and
        record arrays of more than :data:`MAX_RUN_BYTES` bytes.
    """
    n = step_count(duration, dt)
    records = math.ceil(n / max(1, round(every / dt))) + 1
    size = run_bytes(n, records)
    if size > MAX_RUN_BYTES:
        raise EvtmsInputError(
            f"`dt` {dt:g} s with `output_every` {every:g} s gives {n:,} steps and {records:,} records over "
            f"{duration:g} s, {size / 1e6:,.0f} MB of arrays; allowed: at most {MAX_RUN_BYTES / 1e6:,.0f} MB "
            "(a larger `dt` or `output_every`)"
        )
    return n


def step_edges(duration: float, dt: float) -> np.ndarray:
    """Step boundaries [s] from 0 to ``duration`` every ``dt``; the last step is shortened."""
    n = step_count(duration, dt)
    edges = np.arange(n + 1) * dt
    edges[-1] = duration
    return edges


def _step_means(t_nodes: np.ndarray, power: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Exact mean over each step of a power constant per segment of ``t_nodes``."""
    energy = np.concatenate(([0.0], np.cumsum(power * np.diff(t_nodes))))
    return np.diff(np.interp(edges, t_nodes, energy)) / np.diff(edges)


def _distance(cycle: DriveCycle, t: np.ndarray) -> np.ndarray:
    """Distance [m] at times ``t``: the speed is linear between samples, so this is exact."""
    seg_len = 0.5 * (cycle.speed[:-1] + cycle.speed[1:]) * np.diff(cycle.time)
    at_nodes = np.concatenate(([0.0], np.cumsum(seg_len)))
    k = np.clip(np.searchsorted(cycle.time, t, side="right") - 1, 0, cycle.time.size - 2)
    tau = t - cycle.time[k]
    a = (cycle.speed[k + 1] - cycle.speed[k]) / (cycle.time[k + 1] - cycle.time[k])
    return at_nodes[k] + cycle.speed[k] * tau + 0.5 * a * tau**2


def declared_slots(params: SystemParams) -> dict[str, float]:
    """The loop's parameters read as declared (``slot`` of :func:`evtms.params.param`), by slot name.

    A choice is packed as its index among the field's choices.
    """
    slots: dict[str, float] = {}
    for section in SECTIONS:
        table = getattr(params, section)
        for f in dataclasses.fields(table):
            slot = f.metadata.get("slot")
            if slot is None:
                continue
            value = getattr(table, f.name)
            choices = f.metadata.get("choices")
            slots[slot] = float(choices.index(value) if choices else value)
    return slots


def derived_slots(
    params: SystemParams, T_amb: float, RH_amb: float, sun: float, forced_mode: int, refrigerant: Refrigerant
) -> dict[str, float]:
    """The loop's parameters computed from several declared ones, the run and the maps' components, by slot name."""
    b, c, k, hv = params.battery, params.cabin, params.coolant, params.hvac
    rho_amb = P_ATM / (L._R_AIR * T_amb)
    # Plate channels: Reynolds number at pump command 1, Prandtl number, D/L and k/D times the wetted area.
    area = b.plate_channels * math.pi * b.plate_channel_diameter**2 / 4.0
    velocity = k.flow_max / area
    curves = FAN_STAGE_CURVES
    slots = {
        "T_AMB": T_amb,
        "W_AMB": L.humidity_ratio(T_amb, RH_amb, P_ATM),
        "P_ATM": P_ATM,
        "FORCED_MODE": forced_mode,
        "R_SCALE": b.n_series / b.n_parallel,
        "CAP_AS": b.capacity_As,
        "G_BC_FIXED": -1.0 if b.g_coolant_fixed is None else b.g_coolant_fixed,
        "PLATE_RE1": k.density * velocity * b.plate_channel_diameter / k.viscosity,
        "PLATE_PR": k.cp * k.viscosity / k.conductivity,
        "PLATE_DL": b.plate_channel_diameter / b.plate_channel_length,
        "PLATE_KA": k.conductivity * b.plate_channels * math.pi * b.plate_channel_length,
        "C_AIR": rho_amb * c.volume * L._CP_AIR,
        "M_AIR": rho_amb * c.volume,
        "Q_OCC": 70.0 * c.n_occupants,
        "MOIST": 1.4e-5 * c.n_occupants,
        "Q_SUN": 3.0 * (sun if c.sun is None else c.sun) * c.sun_shield,
        "UA_SHELL": c.shell_conductance(),
        "BLOWER_FLOW": refrigerant.blower_flow_max,
        "FAN_VMAX": refrigerant.fan_flow_max,
        "FAN_P2": float(np.interp(T_amb, curves["T_amb"], curves["p_2"])),
        "FAN_P3": float(np.interp(T_amb, curves["T_amb"], curves["p_3"])),
        "COOLANT_MDOT_MAX": refrigerant.coolant_mdot_max,
        "MDOT_H": hv.pump_h_flow * k.density,
    }
    for w in WALLS:
        slots[f"G_{w.upper()}"] = c.wall_conductance(w)
    return slots | jacket_slots(params.edrive, k.density, k.cp, k.viscosity, k.conductivity)


def pack_parameters(
    params: SystemParams, T_amb: float, RH_amb: float, sun: float, forced_mode: int, refrigerant: Refrigerant
) -> np.ndarray:
    """The loop's parameter array (``evtms.system.loop.P_*`` indices), SI.

    Every slot is filled once: by a declared parameter (:func:`declared_slots`)
    or by a value derived from several (:func:`derived_slots`).
    """
    par = np.zeros(L.N_P)
    slots = declared_slots(params) | derived_slots(params, T_amb, RH_amb, sun, forced_mode, refrigerant)
    for name, value in slots.items():
        par[getattr(L, f"P_{name}")] = value
    return par


def initial_state(
    params: SystemParams, T_amb: float, T_init: float | None, soak_cabin: float | None, p_equalised: float
) -> np.ndarray:
    """Row 0 of the loop's states: SOC, temperatures, cabin humidity and the filter at rest."""
    b, c, k = params.battery, params.cabin, params.coolant
    base = T_amb if T_init is None else T_init
    s = np.zeros(L.N_S)
    s[L.S_SOC] = b.soc_init
    s[L.S_TB] = b.T_init if b.T_init is not None else base
    s[L.S_TC] = k.T_init if k.T_init is not None else base
    T_cab = soak_cabin if soak_cabin is not None else (c.T_init if c.T_init is not None else base)
    for i in (L.S_TA, L.S_TGLASS, L.S_TDOORS, L.S_TROOF, L.S_TINT):
        s[i] = T_cab
    s[L.S_W] = L.humidity_ratio(T_cab, c.rh_cabin, P_ATM)
    s[L.S_TH] = T_cab  # the heater-core loop sits in the dashboard, at the cabin's temperature
    s[L.S_YF + L.Y_PS] = s[L.S_YF + L.Y_PD] = p_equalised
    T_ed = params.edrive.T_init if params.edrive.T_init is not None else base
    for i in (L.S_TM, L.S_TI, L.S_TD, L.S_TE):
        s[i] = T_ed
    return s


def simulate(
    cycle: DriveCycle,
    T_amb: float,
    refrigerant: Refrigerant,
    params: SystemParams | None = None,
    *,
    dt: float = 1.0,
    mode: str = "auto",
    RH_amb: float = 0.4,
    sun: float = 0.0,
    T_init: float | None = None,
    soak_cabin: float | None = None,
    output_every: float | None = None,
    scenario: str = "",
    precondition: float = 0.0,
    model: str = "lut",
    mode_models: ModeModels | None = None,
    keep_trace: bool = False,
    inputs: Mapping[str, InputValue] | None = None,
    controller: Supervisor | None = None,
) -> SimulationResult:
    """Simulate the vehicle's thermal system over a drive cycle.

    Parameters
    ----------
    cycle : DriveCycle
        Speed trace.
    T_amb : float
        Ambient temperature [K].
    refrigerant : Refrigerant
        Cycle maps and saturation curve.
    params : SystemParams, optional
        Parameters (defaults: the spec's).
    dt : float
        Time step [s], 1e-3 to 60.
    mode : str
        ``auto`` or a forced mode: ``off``, ``bh``, ``bc``, ``cc``, ``ch``.
    RH_amb : float
        Ambient relative humidity [1].
    sun : float
        Solar irradiance [W/m2] (``Q_sun = 3 sun sun_shield``).
    T_init : float, optional
        Initial temperature of every node [K] (default: the ambient); the
        tables' ``T_init`` override it per subsystem.
    precondition : float
        Seconds of HVAC parked and plugged in before the cycle (a whole
        multiple of the record spacing): the grid feeds auxiliaries and HVAC;
        records of that phase have negative times.
    soak_cabin : float, optional
        Initial cabin air, wall and interior temperature [K].
    output_every : float, optional
        Record spacing [s], a whole multiple of ``dt`` (default max(1 s, dt)).
    scenario : str
        Name recorded in the output.
    model : str
        ``lut`` (the cycle maps), ``physics`` (the bench physics solved in the
        loop whenever a map input drifts beyond
        :data:`evtms.system.refrigerant.PHYSICS_TOLERANCE`; slow, the
        reference) or ``surrogate`` (``mode_models`` replace the refrigerant
        loop and the thermal network; heat-flow records are NaN).
    mode_models : ModeModels, optional
        The mode models of ``model='surrogate'``.
    keep_trace : bool
        Keep the loop's arrays in :attr:`SimulationResult.trace`.
    inputs : mapping of str to float or Trace, optional
        External inputs (:mod:`evtms.system.inputs`: battery heat, HVAC inlet
        air, evaporator and heater-core setpoints, a fixed blower), SI; traces
        on the cycle's clock (preconditioning shifts them with the cycle).
        Checked by :func:`evtms.system.inputs.check_inputs` (a blower of 0
        with a mode that runs the cabin coil or a heater is refused).
    controller : Supervisor, optional
        A supervisory controller (:mod:`evtms.system.controllers`, e.g.
        :class:`evtms.system.mpc.CabinMpc`) that sets the vent-air target
        and the blower every period in place of the rules' cabin loop;
        None: the rules alone.

    Returns
    -------
    SimulationResult
    """
    wall0 = time.perf_counter()
    params = params or SystemParams()
    every = check_run_options(cycle, dt, mode, output_every, precondition)
    if controller is not None:
        check_period(controller.period, dt)
    if model == "surrogate" and params.hvac.heating != "ptc_air":
        raise EvtmsInputError(
            f"`model` surrogate: the mode models know the air PTC only, not hvac.heating = {params.hvac.heating!r}; "
            "use `model` lut or physics"
        )
    check_model(model, mode, mode_models, refrigerant)
    check_heating(params, refrigerant)
    inputs = check_inputs(inputs, mode=mode)
    if "speed_deviation" in inputs:
        cycle = deviated_cycle(cycle, inputs["speed_deviation"], params.vehicle.delta_v_ref)
    m = round(every / dt)
    if precondition:
        cycle = _with_precondition(cycle, precondition)
    edges = step_edges(cycle.duration, dt)
    dts = np.diff(edges)
    seg = {regen: drive_segments(cycle, T_amb, params.vehicle, regen=regen) for regen in (True, False)}
    plugged = (edges[1:] <= precondition + 1e-9).astype(float)
    p_motor = np.column_stack(
        [
            *(_step_means(cycle.time, seg[r].P_motor_el, edges) for r in (True, False)),
            plugged,
            _key_off(cycle, edges),
            np.diff(_distance(cycle, edges)) / dts,  # mean vehicle speed (ram air at the condenser)
            *(_step_means(cycle.time, seg[r].P_loss, edges) for r in (True, False)),
        ]
    )
    ext = per_step(inputs, edges - precondition)
    tables = battery_cell_tables()
    par = pack_parameters(params, T_amb, RH_amb, sun, MODES[mode], refrigerant)
    p_eq = float(np.interp(T_amb if T_init is None else T_init, refrigerant.sat_T, refrigerant.sat_p))
    n = dts.size
    states = np.full((n + 1, L.N_S), np.nan)
    states[0] = initial_state(params, T_amb, T_init, soak_cabin, p_eq)
    out = np.full((n, L.N_O), np.nan)
    modes = np.zeros(n, np.int8)
    flags = np.zeros(n, np.uint16)
    ocv = np.ascontiguousarray(tables.ocv_V[:, 0])
    cores = (*core_table("radiator"), *core_table("heater_core"))
    args = (
        par, dts, p_motor, tables.soc, tables.temperature_K, ocv, np.ascontiguousarray(tables.r0_ohm),
        refrigerant.sat_T, refrigerant.sat_p, *refrigerant.packed(), *MOTOR_TABLE, *cores,
        states, out, modes, flags, ext,
    )  # fmt: skip
    loop0 = time.perf_counter()
    context = None
    if controller is not None:
        context = ControlContext(
            par, edges, p_motor[:, 4].copy(), p_motor[:, 0].copy(), p_motor[:, 3] > 0.0, refrigerant
        )
    done, solves, stop, control_log = _run_loop(args, model, refrigerant, mode_models, controller, context)
    loop_time = time.perf_counter() - loop0
    termination = L.STOP_NAMES[stop]
    edges, dts = edges[: done + 1], dts[:done]
    states, out, modes, flags = states[: done + 1], out[:done], modes[:done], flags[:done]
    regen = out[:, L.O_REGEN] > 0.5
    drive = _drive_means(cycle, seg, edges, regen)
    ledger = ledgers(par, states, out, dts, drive)
    if model == "surrogate":  # a mode model conserves no heat: only the electrical and vehicle ledgers apply
        ledger = {k: v for k, v in ledger.items() if k in ("vehicle", "battery_electrical", "system")}
    records, rec_mode, rec_flags, t_rec = _records(cycle, par, states, out, modes, flags, dts, drive, m)
    E = np.sum(out[:, L.O_EMF] * out[:, L.O_I] * dts)
    distance_km = float(_distance(cycle, edges[-1:])[0] / 1e3)
    summary = {
        "distance_km": distance_km,
        "duration_s": float(edges[-1] - precondition),
        "traction_energy_kWh": float(np.sum(drive["P_traction"] * dts) / 3.6e6),
        "battery_energy_kWh": float(np.sum(out[:, L.O_P_BATTERY] * dts) / 3.6e6),
        "battery_chemical_kWh": float(E / 3.6e6),
        "hvac_energy_kWh": float(np.sum(out[:, L.O_P_HVAC] * dts * (1.0 - p_motor[:done, 2])) / 3.6e6),
        "motor_energy_kWh": float(np.sum(out[:, L.O_P_MOTOR_EL] * dts) / 3.6e6),
        "aux_energy_kWh": float(np.sum(out[:, L.O_P_AUX] * dts * (1.0 - p_motor[:done, 2])) / 3.6e6),
        **_consumption_split(out, dts * (1.0 - p_motor[:done, 2])),
        "battery_loss_kWh": float(np.sum(out[:, L.O_Q_GEN] * dts) / 3.6e6),
        "edrive_cooling_kWh": float(np.sum(out[:, L.O_P_EDRIVE_AUX] * dts * (1.0 - p_motor[:done, 2])) / 3.6e6),
        "T_motor_max_degC": float(np.max(states[:, L.S_TM]) - 273.15),
        **heat_pump_metrics(par, states, out, flags, dts),
        "soc_end": float(states[-1, L.S_SOC]),
        # None for a parked run, as range_km: a floor on the distance would report 1e10 kWh/100 km.
        "consumption_kWh_per_100km": float(E / 3.6e6 / distance_km * 100.0) if distance_km > 0 else None,
        "range_km": float(usable_energy(params) / max(E, 1e-9) * distance_km) if distance_km > 0 else None,
        "T_cabin_end_degC": float(states[-1, L.S_TA] - 273.15),
        "T_battery_end_degC": float(states[-1, L.S_TB] - 273.15),
        "T_battery_min_degC": float(np.min(states[:, L.S_TB]) - 273.15),
        "T_battery_max_degC": float(np.max(states[:, L.S_TB]) - 273.15),
        "T_amb_degC": float(T_amb - 273.15),
        "termination": termination,
        "ledger_worst": float(max(ledger.values())),
        "wall_time_s": float(time.perf_counter() - wall0),
        "loop_time_s": float(loop_time),
        "steps": int(done),
        "precondition_s": float(precondition),
        "precondition_grid_kWh": float(np.sum(out[:, L.O_P_GRID] * dts) / 3.6e6),
        "model": model,
        "physics_solves": int(solves),
        "surrogate_out_of_range_fraction": float(np.mean((flags & L.F_SURROGATE_OOR) > 0)) if done else 0.0,
        "heating": params.hvac.heating,
        **climate_metrics(states, out, modes, dts, params.cabin.T_set, precondition),
        "controller": "rules" if controller is None else controller.name,
        **(control_log.summary() if control_log is not None else {}),
    }
    attrs = {
        "scenario": scenario,
        "cycle": cycle.name,
        "cycle_source": cycle.source,
        "dt": dt,
        "output_every": every,
        "T_amb": T_amb,
        "RH_amb": RH_amb,
        "sun": sun if params.cabin.sun is None else params.cabin.sun,
        "mode_request": mode,
        "model": model,
        "termination": termination,
        "parameters": params.to_json(),
        "lut_parameters": json.dumps(
            {
                "condenser.fan_flow_max": refrigerant.fan_flow_max,
                "evaporator.fan_flow_max": refrigerant.blower_flow_max,
            }
        ),
        "ledgers": json.dumps(ledger),
    }
    records["time"] = t_rec - precondition
    trace = None
    if keep_trace:
        trace = {"states": states, "out": out, "modes": modes, "flags": flags, "dts": dts, "par": par}
    return SimulationResult(records, rec_mode, rec_flags, ledger, summary, attrs, trace)


def _moving_mean(t: np.ndarray, values: np.ndarray, window: float) -> np.ndarray:
    """Trailing ``window`` [s] mean of a trace sampled at ``t`` (trapezoids), NaN before one window has passed."""
    integral = np.concatenate(([0.0], np.cumsum(0.5 * (values[1:] + values[:-1]) * np.diff(t))))
    mean = (integral - np.interp(t - window, t, integral)) / window
    return np.where(t - t[0] >= window - 1e-9, mean, np.nan)


def heat_pump_metrics(par: np.ndarray, states: np.ndarray, out: np.ndarray, flags: np.ndarray, dts: np.ndarray) -> dict:
    """What the heat pump did (spec v2 section 6), from the loop's per-step arrays; None where it never ran.

    - ``hp_heat_kWh``: the water-cooled condenser's heat into the heater-core loop;
    - ``cop_hp``: that heat over the compressor's shaft work;
    - ``cop_sys_mean``: the heater core's heat less the backup PTC's over the compressor's electrical power
      and the low-voltage power the heat pump adds at the pack (heater-core loop pump, the e-drive pump above
      the motor's own need, the front-end fan), over the steps the heat pump ran;
    - ``backup_kWh`` and ``backup_share``: the coolant PTC's heat while it backed the heat pump up, and its
      share of the heater core's heat over those steps;
    - ``source_heat_kWh`` (the chiller's draw on the e-drive loop), split into ``ambient_heat_kWh`` (what the
      radiator took from the air while it was the source) and ``waste_heat_kWh`` (the rest: the drive's);
    - ``frost_time_s``: time with the radiator as the source, its cold end below 0 degC and the ambient's
      frost point (no defrost is modelled).
    """
    hp = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    frost = float(np.sum(dts[(flags & L.F_FROST_OUTSIDE) > 0]))
    if not np.any(hp):
        keys = ("hp_heat_kWh", "cop_hp", "cop_sys_mean", "backup_kWh", "backup_share", "source_heat_kWh")
        return {**dict.fromkeys(keys), "ambient_heat_kWh": None, "waste_heat_kWh": None, "frost_time_s": frost}

    def kwh(values: np.ndarray, where: np.ndarray = hp) -> float:
        return float(np.sum(values[where] * dts[where]) / 3.6e6)

    eta = par[L.P_ETA_DC]
    need = np.interp(states[:-1, L.S_TM], *MOTOR_TABLE)
    own = par[L.P_PUMP_E_POWER] * np.clip(need, par[L.P_PUMP_E_MIN], 1.0) ** 3
    extra_pump = np.maximum(out[:, L.O_P_PUMP_E] - own, 0.0)
    electric = out[:, L.O_P_COMPRESSOR] + (out[:, L.O_P_PUMP_H] + extra_pump + out[:, L.O_P_FAN]) / eta
    heat = out[:, L.O_Q_HC] - out[:, L.O_P_PTCW]
    backup = hp & ((flags & L.F_HP_BACKUP) > 0)
    source = kwh(out[:, L.O_Q_CH_E])
    ambient = kwh(np.maximum(-out[:, L.O_Q_RAD], 0.0))
    q_hc = kwh(out[:, L.O_Q_HC])
    return {
        "hp_heat_kWh": kwh(out[:, L.O_Q_WCC]),
        "cop_hp": kwh(out[:, L.O_Q_WCC]) / max(kwh(out[:, L.O_W]), 1e-12),
        "cop_sys_mean": kwh(heat) / max(kwh(electric), 1e-12),
        "backup_kWh": kwh(out[:, L.O_P_PTCW], backup),
        "backup_share": kwh(out[:, L.O_P_PTCW], backup) / q_hc if q_hc > 0 else None,
        "source_heat_kWh": source,
        "ambient_heat_kWh": ambient,
        "waste_heat_kWh": source - ambient,
        "frost_time_s": frost,
    }


def climate_metrics(
    states: np.ndarray, out: np.ndarray, modes: np.ndarray, dts: np.ndarray, T_set: float, precondition: float
) -> dict:
    """How the climate control behaved (the spec v2's section 10.2 figures), from the loop's per-step arrays.

    - ``t_pulldown_s``: first time [s] (cycle clock) the cabin air's 60-s mean is within 1 K of ``T_set``
      (None: never);
    - ``cabin_dev_max_K``: largest deviation [K] of that mean from ``T_set`` after ``t_pulldown_s``;
    - ``mode_changes``, ``mode_changes_after_pulldown`` and their rate per 30 min after it;
    - ``compressor_starts`` (off-to-on steps, cycling included) and per 30 min after the pull-down;
    - ``cabin_rms_K``: RMS deviation [K] of the cabin air from ``T_set`` after ``t_pulldown_s``, and
      ``cabin_minutes_outside``: minutes after it with the 60-s mean more than 1 K off (the comfort figures the
      controllers are compared on);
    - ``T_evap_air_min_degC``, ``T_supply_min_degC``: the coldest step means of evaporator and vent air.
    """
    t = np.concatenate(([0.0], np.cumsum(dts))) - precondition
    mean60 = _moving_mean(t, states[:, L.S_TA], 60.0)
    near = np.flatnonzero(np.abs(mean60 - T_set) <= 1.0)
    t_pd = float(t[near[0]]) if near.size else None
    changes = np.flatnonzero(np.diff(modes.astype(int))) + 1  # step indices where the mode changed
    on = out[:, L.O_COMP_ON] > 0.5
    starts = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    res: dict = {"t_pulldown_s": t_pd, "mode_changes": int(changes.size), "compressor_starts": int(starts.size)}
    if t_pd is not None:
        after = t >= t_pd
        res["cabin_dev_max_K"] = float(np.nanmax(np.abs(mean60[after] - T_set)))
        late = after[:-1]  # steps starting at or after the pull-down, weighted by their length
        dev = 0.5 * (states[1:, L.S_TA] + states[:-1, L.S_TA]) - T_set
        span_s = float(np.sum(dts[late]))
        res["cabin_rms_K"] = float(np.sqrt(np.sum(dev[late] ** 2 * dts[late]) / span_s)) if span_s > 0 else 0.0
        outside = late & (np.abs(mean60[:-1] - T_set) > 1.0)
        res["cabin_minutes_outside"] = float(np.sum(dts[outside]) / 60.0)
        span = max(t[-1] - t_pd, 1e-9)
        n_modes = int(np.sum(t[changes] > t_pd))
        n_starts = int(np.sum(t[starts] > t_pd))
        res["mode_changes_after_pulldown"] = n_modes
        res["mode_changes_per_30min"] = float(n_modes * 1800.0 / span) if span >= 600.0 else None
        res["compressor_starts_per_30min"] = float(n_starts * 1800.0 / span) if span >= 600.0 else None
    else:
        res.update(cabin_dev_max_K=None, mode_changes_after_pulldown=None, mode_changes_per_30min=None)
        res.update(cabin_rms_K=None, cabin_minutes_outside=None)
        res["compressor_starts_per_30min"] = None

    def coldest(col: int) -> float | None:
        v = out[:, col]
        return float(np.nanmin(v) - 273.15) if np.any(np.isfinite(v)) else None

    res["T_evap_air_min_degC"] = coldest(L.O_T_EVAP_AIR)
    res["T_supply_min_degC"] = coldest(L.O_T_SUPPLY)
    return res


def _run_loop(
    args: tuple,
    model: str,
    refrigerant: Refrigerant,
    mode_models: ModeModels | None,
    supervisor: Supervisor | None = None,
    context: ControlContext | None = None,
) -> tuple[int, int, int, SupervisionLog | None]:
    """Run the compiled loop for ``model``; returns the steps done, the number of direct-physics solves, why
    the run stopped early (:data:`evtms.system.loop.STOP_NAMES` index; ``STOP_NONE``: it did not) and the
    supervisory controller's record (None: the rules alone).

    With ``physics`` the loop stops wherever the refrigerant's inputs left the
    tolerance of the point it holds; the cycle is solved there (or a nearby
    earlier solve reused) and the loop resumes at that step. With a
    ``supervisor`` the loop runs period by period
    (:func:`evtms.system.controllers.run_supervised`).
    """
    mem = np.zeros(L.N_M)
    held = np.full(L.N_H, np.nan)
    tol = refrigerant.tolerances()
    net, index = np.zeros(1), np.full((8, 2), -1, np.int64)
    source = {"lut": L.SRC_MAPS, "physics": L.SRC_HELD, "surrogate": L.SRC_SURROGATE}[model]
    if model == "surrogate":
        net, index = mode_models.packed()
    solves = 0

    def run_chunk(chunk_args: tuple, start: int) -> int:
        nonlocal solves
        while True:
            done = L.run_loop(*chunk_args, start, source, mem, held, tol, net, index)
            if done >= 0:
                return done
            start = -done - 1
            y, fallback, solved = refrigerant.solve_direct(int(held[L.H_MAP]), held[L.H_X : L.H_X + L.N_MAP_X])
            held[L.H_Y : L.H_Y + L.N_Y] = y
            held[L.H_FALLBACK] = float(fallback)
            solves += int(solved)

    if supervisor is None:
        return run_chunk(args, 0), solves, int(mem[L.M_STOP]), None
    done, log = run_supervised(args, supervisor, context, run_chunk)
    return done, solves, int(mem[L.M_STOP]), log


def check_heating(params: SystemParams, refrigerant: Refrigerant) -> None:
    """Refuse a heat pump without the loops it works on: the e-drive loop (its source) and its cycle map."""
    if params.hvac.heating != "heat_pump":
        return
    if params.edrive.model != "loop":
        raise EvtmsInputError(
            "hvac.heating = 'heat_pump' draws on the e-drive coolant loop; edrive.model 'ambient' has none "
            "(use edrive.model = 'loop')"
        )
    if "hp" not in refrigerant.maps:
        raise EvtmsInputError(
            "hvac.heating = 'heat_pump' needs the hp cycle map; load the refrigerant with these parameters "
            "(evtms.system.refrigerant.load_refrigerant(folder, params))"
        )


def check_model(model: str, mode: str, mode_models: ModeModels | None, refrigerant: Refrigerant) -> None:
    """Refuse a model that cannot run this simulation (one line, before any work)."""
    if model not in MODELS:
        raise EvtmsInputError(f"`model` {model!r} is unknown; allowed: {', '.join(MODELS)}")
    if model == "physics":
        refrigerant.check_physics()
    if model == "surrogate":
        if mode_models is None:
            raise EvtmsInputError(
                "the surrogate model needs mode models (`surrogates` FILE, from 'evtms surrogate train')"
            )
        needed = sorted(set(MODES.values()) - {-1}) if mode == "auto" else [MODES[mode]]
        missing = [L.MODE_NAMES[c] for c in needed if c not in mode_models.codes()]
        if missing:
            raise EvtmsInputError(
                f"the surrogate model's mode models lack mode(s) {', '.join(missing)} that mode {mode} can use; "
                "train them with 'evtms surrogate train --mode all'"
            )


def check_run_options(
    cycle: DriveCycle, dt: float, mode: str, output_every: float | None, precondition: float
) -> float:
    """Check the run's time options before any work; returns the record spacing [s].

    Raises
    ------
    EvtmsInputError
        ``dt`` outside 0.001-60 s, an unknown mode, a record spacing that is
        not a whole multiple of ``dt``, a preconditioning time that is not a
        multiple of the record spacing (or above a day), or preconditioning
        before a cycle that does not start at standstill; or more than
        :data:`MAX_STEPS` steps or :data:`MAX_RUN_BYTES` of arrays
        (:func:`check_run_size`).
    """
    if not (math.isfinite(dt) and 1e-3 <= dt <= 60.0):
        raise EvtmsInputError(f"`dt` {dt:g} is not allowed; allowed: 0.001 to 60 s")
    if mode not in MODES:
        raise EvtmsInputError(f"`mode` {mode!r} is unknown; allowed: {', '.join(MODES)}")
    every = max(1.0, dt) if output_every is None else output_every
    m = round(every / dt) if math.isfinite(every) else 0
    if not (math.isfinite(every) and m >= 1 and abs(m * dt - every) <= 1e-9 * every):
        raise EvtmsInputError(f"`output_every` {every:g} s is not allowed; allowed: a whole multiple of `dt` {dt:g} s")
    if precondition:
        k = round(precondition / every) if math.isfinite(precondition) else 0
        if not (0 < precondition <= 86400.0 and abs(k * every - precondition) <= 1e-9 * precondition):
            raise EvtmsInputError(
                f"`precondition` {precondition:g} s is not allowed; allowed: a multiple of the record spacing "
                f"{every:g} s, up to 86400 s"
            )
        if cycle.speed[0] != 0.0:
            raise EvtmsInputError(f"`precondition` needs a cycle that starts at standstill; {cycle.name} does not")
    check_run_size(cycle.duration + precondition, dt, every)  # bounds the arrays before anything is allocated
    return every


def _with_precondition(cycle: DriveCycle, seconds: float) -> DriveCycle:
    """``cycle`` after ``seconds`` parked."""
    t = np.concatenate(([0.0], seconds + cycle.time))
    key_off = None if cycle.key_off is None else np.concatenate(([False], cycle.key_off))
    return DriveCycle(
        cycle.name, t, np.concatenate(([0.0], cycle.speed)), np.concatenate(([0.0], cycle.grade)), cycle.source,
        key_off,
    )  # fmt: skip


def _key_off(cycle: DriveCycle, edges: np.ndarray) -> np.ndarray:
    """Per step 1 where the key is off for at least half of it (the cycle's key-off intervals), else 0."""
    if cycle.key_off is None:
        return np.zeros(edges.size - 1)
    return (_step_means(cycle.time, np.asarray(cycle.key_off[:-1], float), edges) >= 0.5).astype(float)


def usable_energy(params: SystemParams) -> float:
    """Chemical energy [J] between ``soc_max`` and ``soc_min``: the integral of the pack EMF over the charge."""
    b = params.battery
    tables = battery_cell_tables()
    soc = np.linspace(b.soc_min, b.soc_max, 2001)
    emf = b.n_series * np.interp(soc, tables.soc, tables.ocv_V[:, 0])
    return float(np.sum(0.5 * (emf[1:] + emf[:-1]) * np.diff(soc)) * b.capacity_As)


def _consumption_split(out: np.ndarray, dts: np.ndarray) -> dict[str, float]:
    """Electrical energy [kWh] by use: the compressor and fan shared by the heat each branch takes."""
    q_e, q_c = np.abs(out[:, L.O_Q_EVAP]), np.abs(out[:, L.O_Q_CHILLER])
    with np.errstate(invalid="ignore", divide="ignore"):
        chiller_share = np.where(q_e + q_c > 0, q_c / (q_e + q_c), 0.0)
    refrigerant = out[:, L.O_P_COMPRESSOR] + out[:, L.O_P_FAN]
    battery = out[:, L.O_P_HEATER] + out[:, L.O_P_PUMP] + chiller_share * refrigerant
    cabin = out[:, L.O_P_HVAC] - battery

    def kwh(p: np.ndarray) -> float:
        return float(np.sum(p * dts) / 3.6e6)

    return {"hvac_cabin_kWh": kwh(cabin), "battery_thermal_kWh": kwh(battery)}


def _drive_means(cycle: DriveCycle, seg: dict, edges: np.ndarray, regen: np.ndarray) -> dict[str, np.ndarray]:
    """Per-step means of the e-drive's powers, with regeneration where the loop allowed it."""
    names = ("P_wheel", "P_traction", "P_gear_loss", "P_loss", "P_friction")
    on = {k: _step_means(cycle.time, getattr(seg[True], k), edges) for k in names}
    off = {k: _step_means(cycle.time, getattr(seg[False], k), edges) for k in names}
    return {k: np.where(regen, on[k], off[k]) for k in names}


def ledgers(par: np.ndarray, states: np.ndarray, out: np.ndarray, dts: np.ndarray, drive: dict) -> dict[str, float]:
    """Relative residual of every ledger over the run (each divided by its throughput).

    - ``vehicle``: motor electrical = wheel + gear + motor losses + friction brakes;
    - ``battery_electrical``: chemical (E i) = terminal (v i) + heat + RC energy;
    - ``battery_thermal``, ``coolant``, ``heater_loop``, ``cabin``: change of stored heat = sum of flows
      (the battery's external heat and the fixed HVAC inlet's enthalpy are boundary terms);
    - ``refrigerant``: Q_condenser = Q_evaporator + Q_chiller + W_fluid;
    - ``system``: chemical = motor + auxiliaries + HVAC + battery heat + RC energy.
    """
    T_amb = par[L.P_T_AMB]
    s1 = states[1:]
    E_chem = out[:, L.O_EMF] * out[:, L.O_I] * dts
    Pb = out[:, L.O_P_BATTERY] * dts
    Qg = out[:, L.O_Q_GEN] * dts
    Erc = out[:, L.O_E_RC]

    def rel(residual: float, throughput: float) -> float:
        return float(abs(residual) / max(throughput, 1e-300))

    motor = out[:, L.O_P_MOTOR_EL]
    parts = drive["P_wheel"] + drive["P_gear_loss"] + drive["P_loss"] + drive["P_friction"]
    res = {"vehicle": rel(np.sum((motor - parts) * dts), np.sum(np.abs(motor) * dts))}
    res["battery_electrical"] = rel(np.sum(E_chem - Pb - Qg - Erc), np.sum(np.abs(E_chem)))
    Tb1, Tc1 = s1[:, L.S_TB], s1[:, L.S_TC]
    q_bc = out[:, L.O_G_BC] * (Tb1 - Tc1)
    q_ba = par[L.P_G_BA] * (Tb1 - T_amb)
    q_ext = out[:, L.O_Q_EXT]
    stored_b = par[L.P_C_BAT] * (states[-1, L.S_TB] - states[0, L.S_TB])
    flow_b = (out[:, L.O_Q_GEN] + q_ext - q_bc - q_ba) * dts
    through_b = (out[:, L.O_Q_GEN] + abs(q_ext) + abs(q_bc) + abs(q_ba)) * dts
    res["battery_thermal"] = rel(stored_b - np.sum(flow_b), np.sum(through_b))
    stored_c = par[L.P_C_COOL] * (states[-1, L.S_TC] - states[0, L.S_TC])
    flow_c = (q_bc + out[:, L.O_Q_HEATER] - out[:, L.O_Q_CHILLER]) * dts
    through_c = (abs(q_bc) + out[:, L.O_Q_HEATER] + abs(out[:, L.O_Q_CHILLER])) * dts
    res["coolant"] = rel(stored_c - np.sum(flow_c), np.sum(through_c))
    stored_h = par[L.P_C_H] * (states[-1, L.S_TH] - states[0, L.S_TH])
    flow_h = (out[:, L.O_P_PTCW] + out[:, L.O_Q_WCC] - out[:, L.O_Q_HC]) * dts
    res["heater_loop"] = rel(
        stored_h - np.sum(flow_h),
        np.sum((out[:, L.O_P_PTCW] + abs(out[:, L.O_Q_WCC]) + abs(out[:, L.O_Q_HC])) * dts) + 1.0,
    )
    caps = [par[L.P_C_AIR], par[L.P_C_GLASS], par[L.P_C_DOORS], par[L.P_C_ROOF], par[L.P_C_INT]]
    idx = [L.S_TA, L.S_TGLASS, L.S_TDOORS, L.S_TROOF, L.S_TINT]
    stored = sum(c * (states[-1, i] - states[0, i]) for c, i in zip(caps, idx, strict=True))
    walls = sum(par[L.P_G_GLASS + k] * (T_amb - s1[:, L.S_TGLASS + k]) for k in range(3))
    # Inflow from outside the cabin: fresh air, or the fixed HVAC inlet (a ledger boundary).
    inflow = out[:, L.O_G_IN] * (out[:, L.O_T_IN_SRC] - s1[:, L.S_TA])
    flows = (walls + inflow + out[:, L.O_Q_AIR_SOURCES] + out[:, L.O_Q_SUN_INT]) * dts
    walls_abs = sum(par[L.P_G_GLASS + k] * abs(T_amb - s1[:, L.S_TGLASS + k]) for k in range(3))
    through = walls_abs + abs(inflow) + abs(out[:, L.O_Q_AIR_SOURCES]) + out[:, L.O_Q_SUN_INT]
    res["cabin"] = rel(stored - np.sum(flows), np.sum(through * dts))
    ref = out[:, L.O_Q_COND] + out[:, L.O_Q_WCC] - out[:, L.O_Q_EVAP] - out[:, L.O_Q_CHILLER] - out[:, L.O_Q_CH_E]
    ref -= out[:, L.O_W_FLUID]
    res["refrigerant"] = rel(np.sum(ref * dts), np.sum(out[:, L.O_W_FLUID] * dts) + 1.0)
    res["edrive"] = _edrive_ledger(par, states, out, dts)
    uses = out[:, L.O_P_AUX] + out[:, L.O_P_HVAC] + out[:, L.O_P_EDRIVE_AUX] - out[:, L.O_P_GRID]
    uses = (motor + uses + out[:, L.O_Q_GEN]) * dts + Erc
    res["system"] = rel(np.sum(E_chem - uses), np.sum(np.abs(E_chem)))
    return res


def _edrive_ledger(par: np.ndarray, states: np.ndarray, out: np.ndarray, dts: np.ndarray) -> float:
    """Relative residual of the e-drive loop's heat (motor, inverter, DC-DC and coolant E): the change of
    their stored heat against the drive's and the DC-DC's losses, the motor's loss to the ambient and the
    radiator's heat."""
    caps = (par[L.P_C_M], par[L.P_C_I], par[L.P_C_D], par[L.P_C_E])
    idx = (L.S_TM, L.S_TI, L.S_TD, L.S_TE)
    stored = sum(c * (states[-1, i] - states[0, i]) for c, i in zip(caps, idx, strict=True))
    to_motor = par[L.P_K1_M] * (par[L.P_T_AMB] - states[1:, L.S_TM])
    if int(par[L.P_EDRIVE_MODEL]) != L.EDRIVE_LOOP:
        to_motor = np.zeros_like(to_motor)
    sources = out[:, L.O_Q_DRIVE] + out[:, L.O_Q_DCDC]
    flows = np.sum((sources + to_motor - out[:, L.O_Q_RAD] - out[:, L.O_Q_CH_E]) * dts)
    through = np.sum((sources + np.abs(to_motor) + np.abs(out[:, L.O_Q_RAD]) + np.abs(out[:, L.O_Q_CH_E])) * dts)
    return float(abs(stored - flows) / max(through, 1e-300))


def _records(cycle, par, states, out, modes, flags, dts, drive, m):
    """States every ``m`` steps and the means of powers over each record's interval."""
    n = dts.size
    starts = np.arange(0, n, m)
    ends = np.append(starts[1:], n)  # steps [start, end) form record k = 1, 2, ...
    t_edges = np.concatenate(([0.0], np.cumsum(dts)))
    t_rec = np.concatenate(([0.0], t_edges[ends]))
    span = np.diff(t_rec)

    def mean(values: np.ndarray) -> np.ndarray:
        sums = np.add.reduceat(values * dts, starts) if n else np.zeros(0)
        return np.concatenate(([np.nan], sums / span))

    rec = {name: mean(out[:, col]) for name, col in _MEANS.items()}
    for name in ("P_wheel", "P_traction"):
        rec[name] = mean(drive[name])
    rec["Q_battery_to_coolant"] = mean(out[:, L.O_G_BC] * (states[1:, L.S_TB] - states[1:, L.S_TC]))
    rows = np.concatenate(([0], ends))
    for name, col in _STATES.items():
        rec[name] = states[rows, col]
    rec["speed"] = np.interp(t_rec, cycle.time, cycle.speed)
    rec["distance"] = _distance(cycle, t_rec)
    rec["RH_cabin"] = L.relative_humidity(rec["T_cabin"], states[rows, L.S_W], P_ATM)
    rec["circuit"] = np.concatenate(([0.0], out[ends - 1, L.O_CIRCUIT])) if n else np.zeros(1)
    last = np.concatenate(([0], ends - 1)) if n else np.zeros(1, int)
    rec_mode = modes[last] if n else np.zeros(1, np.int8)
    rec_flags = np.zeros(t_rec.size, np.uint16)
    if n:
        rec_flags[1:] = np.bitwise_or.reduceat(flags, starts)
    return rec, rec_mode.astype(np.int8), rec_flags, t_rec
