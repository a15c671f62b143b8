"""Climate control that behaves like a car's (spec v2 sections 2-3, 10.2-10.5): set points held without limit
cycles, no frost, a blower that never stops, forced modes inside their safety limits, external inputs.

The behaviour tests at 25 and 35 degC run on cycle maps built from the session's cycle LUTs (2-3 nodes per
map axis, as ``test_simulate_cli.py``); the rest on the synthetic maps of ``test_simulate.py``, whose
evaporator gives 6 kW at full speed whatever the air, so that nothing but the frost relay keeps it from
freezing the air.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import patch_small_maps
from test_simulate import refrigerant as synthetic  # noqa: F401 - the module fixture of synthetic maps

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system import refrigerant as refrigerant_module
from evtms.system.drive_cycles import DriveCycle, drive_cycle
from evtms.system.inputs import Trace
from evtms.system.params import system_params_from_dict
from evtms.system.simulate import _moving_mean, simulate

WLTC = drive_cycle("wltc3b")


def parked(seconds: float) -> DriveCycle:
    t = np.arange(0.0, seconds + 1.0)
    return DriveCycle("parked", t, np.zeros_like(t), np.zeros_like(t), "test")


def first(cycle: DriveCycle, seconds: float) -> DriveCycle:
    keep = cycle.time <= seconds
    return DriveCycle(cycle.name, cycle.time[keep], cycle.speed[keep], cycle.grade[keep], cycle.source)


@pytest.fixture(scope="module")
def cycle_maps(small_map_luts):
    """Cycle maps from the session's cycle LUTs on 2-3 nodes per axis (built once for this module)."""
    mp = pytest.MonkeyPatch()
    patch_small_maps(mp)
    try:
        yield refrigerant_module.load_refrigerant(small_map_luts)
    finally:
        mp.undo()


def mean60(r) -> np.ndarray:
    return _moving_mean(r.records["time"], r.records["T_cabin"], 60.0)


@pytest.mark.parametrize("T_amb_c", [25.0, 35.0])
def test_part_load_holds_the_set_point_without_a_limit_cycle(cycle_maps, T_amb_c):
    """WLTC's first 20 min, RH 0.4, sun 600 W/m2, soaked: pulled down within 12 min, then the 60-s mean within
    1 K, at most 4 mode changes per 30 min, no frost, the blower never stops, no electric heat."""
    T_set = 295.15
    r = simulate(first(WLTC, 1200.0), T_amb_c + 273.15, cycle_maps, dt=1.0, sun=600.0, RH_amb=0.4)
    s = r.summary
    assert s["t_pulldown_s"] is not None and s["t_pulldown_s"] <= 720.0
    m = mean60(r)
    after = r.records["time"] >= s["t_pulldown_s"]
    assert np.nanmax(np.abs(m[after] - T_set)) <= 1.0 + 1e-9
    assert s["mode_changes_after_pulldown"] * 1800.0 / (1200.0 - s["t_pulldown_s"]) <= 4.0
    assert s["T_evap_air_min_degC"] > 0.0 and s["T_supply_min_degC"] > 0.0
    assert np.all(r.records["blower"][1:] >= 0.4 - 1e-12)
    assert np.all(r.records["P_ptc"][1:] == 0.0)
    assert max(r.ledgers.values()) <= 1e-9


def test_v1_limit_cycle_case_no_longer_swings(cycle_maps):
    """v1 at 30 degC: the mode flipped every 61 s and the cabin swung 15.9-28.5 degC."""
    r = simulate(first(WLTC, 1200.0), 303.15, cycle_maps, dt=1.0, sun=600.0)
    T = r.records["T_cabin"][r.records["time"] >= 600.0] - 273.15
    assert T.max() - T.min() < 3.0
    assert r.summary["mode_changes"] <= 2


def test_the_frost_relay_overrides_every_floor(synthetic):  # noqa: F811
    """Forced cooling at 35 degC, RH 0.2, no sun (v1's -11.8 degC case), on maps that would freeze the air at
    any speed: evaporator and vent air never reach 0 degC at any step, and each frost trip stops the
    compressor at once."""
    inputs = {"SP_evap": 273.15, "blower": 0.4}  # a target at 0 degC: only the relay stands between air and ice
    for dt in (0.1, 1.0):
        r = simulate(parked(900.0), 308.15, synthetic, mode="cc", dt=dt, RH_amb=0.2, output_every=1.0, inputs=inputs)
        assert r.summary["T_evap_air_min_degC"] >= 0.0, dt
        assert r.summary["T_supply_min_degC"] >= 0.0, dt
        frost = (r.flags[1:] & L.F_FREEZE_CUTOFF) > 0
        assert frost.any()  # the relay did act
        assert np.all(r.records["compressor_on"][1:][frost] < 1.0)
        assert r.summary["compressor_starts"] >= 2


def test_the_blower_never_stops_in_auto_and_stops_when_off(synthetic):  # noqa: F811
    for T_amb in (263.15, 295.15, 313.15):
        r = simulate(first(WLTC, 600.0), T_amb, synthetic, sun=600.0)
        assert np.all(r.records["blower"][1:] >= 0.4 - 1e-12), T_amb
    r = simulate(first(WLTC, 600.0), 313.15, synthetic, mode="off")
    assert np.all(r.records["blower"][1:] == 0.0)


def test_cold_warm_up_reaches_the_set_point_within_20_min(synthetic):  # noqa: F811
    """Parked, -10 degC soaked, no sun, the default 6 kW air PTC: within 1 K of T_set by 20 min (spec v2 10.4)."""
    r = simulate(parked(1800.0), 263.15, synthetic, dt=1.0)
    assert r.summary["t_pulldown_s"] is not None and r.summary["t_pulldown_s"] <= 1200.0
    assert np.nanmax(r.records["P_ptc"]) <= 6000.0 + 1e-9
    assert np.nanmax(r.records["P_ptc"]) > 5000.0  # the heater's capability caps the blower, not the other way
    assert np.all(r.records["P_compressor"][1:] == 0.0)  # below ac_T_amb_min: no compressor to dehumidify


def test_forced_bh_keeps_its_safety_relays(synthetic):  # noqa: F811
    """Forced BH at 0 degC from a -5 degC battery with 1 kW into it: the coolant never passes its limit by more
    than 1 K, and the heater is off once the battery reaches bh_T_battery_max (Table 12 bh-4's 5 kW would take
    the battery itself past 45 degC in 30 min, whatever the heater does)."""
    T0 = 268.15
    p = system_params_from_dict({"battery": {"T_init": T0}, "coolant": {"T_init": T0}})
    r = simulate(parked(1800.0), 273.15, synthetic, p, mode="bh", inputs={"Q_battery_ext": 1000.0})
    assert np.nanmax(r.records["T_coolant"]) <= 318.15 + 1.0
    hot = r.records["T_battery"][:-1] >= 298.15
    assert hot.any()
    assert np.all(r.records["P_heater"][1:][hot] == 0.0)
    assert np.any((r.flags & L.F_SAFETY_RELAY) > 0)
    assert max(r.ledgers.values()) <= 1e-9


def test_forced_bc_stops_below_its_battery_limit(synthetic):  # noqa: F811
    p = system_params_from_dict({"battery": {"T_init": 290.15}, "coolant": {"T_init": 290.15}})
    r = simulate(parked(1800.0), 293.15, synthetic, p, mode="bc")
    assert np.nanmin(r.records["T_battery"]) >= 288.15 - 0.5
    cold = r.records["T_battery"][:-1] < 288.15
    assert np.all(r.records["compressor_speed"][1:][cold] == 0.0)


def test_evaporator_setpoint_fixed_inlet_and_blower_are_held(synthetic):  # noqa: F811
    """Table 12 cc-2 style: forced cc at 35 degC, inlet fixed at 15 degC RH 0.5, SP_evap 5 degC, blower 0.6."""
    inputs = {"hvac_inlet_T": 288.15, "hvac_inlet_rh": 0.5, "SP_evap": 278.15, "blower": 0.6}
    r = simulate(parked(1800.0), 308.15, synthetic, mode="cc", inputs=inputs)
    last = r.records["time"] >= 1200.0
    assert abs(np.nanmean(r.records["T_evap_air"][last]) - 278.15) <= 1.0
    assert np.allclose(r.records["blower"][1:], 0.6)
    assert np.all(r.records["recirculation"][1:] == 0.0)
    assert max(r.ledgers.values()) <= 1e-9


def test_coolant_heating_holds_the_heater_core_setpoint(synthetic):  # noqa: F811
    """Table 12 ch-2: 0 degC, inlet 0 degC, blower 0.2, SP_CoHX 35 degC, heating by the coolant PTC."""
    p = system_params_from_dict({"hvac": {"heating": "ptc_coolant"}})
    inputs = {"hvac_inlet_T": 273.15, "blower": 0.2, "SP_CoHX": 308.15}
    r = simulate(parked(1800.0), 273.15, synthetic, p, mode="ch", inputs=inputs)
    last = r.records["time"] >= 1200.0
    assert abs(np.nanmean(r.records["T_heater_loop"][last]) - 308.15) <= 1.0
    assert np.nanmax(r.records["Q_heater_core"]) > 500.0
    assert np.all(r.records["P_ptc"][1:] == 0.0)
    assert r.ledgers["heater_loop"] <= 1e-9 and max(r.ledgers.values()) <= 1e-9


def test_a_battery_heat_trace_is_integrated_exactly(synthetic):  # noqa: F811
    """Q_battery_ext as a trace: the battery's ledger carries it as a boundary term and closes."""
    trace = Trace(np.array([0.0, 600.0, 1200.0]), np.array([0.0, 4000.0, 0.0]))
    r = simulate(parked(1200.0), 293.15, synthetic, mode="off", inputs={"Q_battery_ext": trace})
    E = np.nansum(r.records["Q_battery_ext"][1:])  # 1 s records: their sum is the energy [J]
    assert E == pytest.approx(0.5 * 1200.0 * 4000.0, rel=1e-9)
    assert r.ledgers["battery_thermal"] <= 1e-9


def test_key_off_soaks_with_everything_off(synthetic):  # noqa: F811
    t = np.arange(0.0, 601.0)
    off = (t >= 200.0) & (t < 500.0)
    cycle = DriveCycle("soak", t, np.zeros_like(t), np.zeros_like(t), "test", off)
    r = simulate(cycle, 313.15, synthetic, sun=600.0, T_init=313.15)
    soak = (r.records["time"] > 200.0) & (r.records["time"] <= 500.0)
    # Only the refrigerant filter's tail (10 s time constant) outlives the key: every other load is off.
    assert np.all(r.records["P_hvac"][soak] == r.records["P_compressor"][soak])
    assert np.all(r.records["blower"][soak] == 0.0)
    assert np.all(r.records["P_compressor"][soak & (r.records["time"] > 320.0)] < 0.1)
    assert np.all((r.flags[soak] & L.F_KEY_OFF) > 0)
    assert np.any(r.records["P_hvac"][r.records["time"] > 510.0] > 0.0)  # the climate restarts at key-on
    assert max(r.ledgers.values()) <= 1e-9


def test_plate_conductance_follows_hausen():
    """Hausen's developing laminar flow at the MW plate (Incropera eq. 8.57), by hand at pump 1."""
    re, pr, d, length, n, k = 1327.84, 33.0, 0.009, 1.3, 12, 0.38
    gz = d / length * re * pr
    nu = 3.66 + 0.0668 * gz / (1.0 + 0.04 * gz ** (2.0 / 3.0))
    h_a = nu * k / d * n * math.pi * d * length
    expected = 1.0 / (1.0 / 1216.0 + 1.0 / h_a)
    got = L.plate_conductance(1.0, re, pr, d / length, k * n * math.pi * length, 1216.0)
    assert got == pytest.approx(expected, rel=1e-12)
    assert L.plate_conductance(0.3, re, pr, d / length, k * n * math.pi * length, 1216.0) < got
    assert L.plate_conductance(0.0, re, pr, d / length, k * n * math.pi * length, 1216.0) < 40.0


def test_crossflow_effectiveness_limits():
    """Incropera eq. 11.32-11.33: 1 - e^-NTU as C_r -> 0, continuous where the streams are equal."""
    assert L.crossflow_effectiveness(100.0, 1e12, 150.0) == pytest.approx(1.0 - math.exp(-1.5), rel=1e-9)
    below = L.crossflow_effectiveness(100.0, 100.0 * (1 + 1e-9), 120.0)
    above = L.crossflow_effectiveness(100.0 * (1 + 1e-9), 100.0, 120.0)
    assert below == pytest.approx(above, abs=1e-8)
    assert 0.0 < below < 1.0
    assert L.crossflow_effectiveness(0.0, 100.0, 50.0) == 0.0


def test_v1_parameter_names_name_their_successors():
    cases = {
        ("controls", "ptc_max_power"): r"\[controls\] ptc_max_power is \[hvac\] ptc_max_power in v2",
        ("cabin", "recirculation"): r"recirc_cool",
        ("battery", "g_coolant"): r"g_coolant_fixed",
        ("controls", "freeze_cutoff_low"): r"p_frost_off",
    }
    for (table, name), msg in cases.items():
        with pytest.raises(EvtmsInputError, match=msg):
            system_params_from_dict({table: {name: 1.0}})
    assert system_params_from_dict({"hvac": {"heating": "heat_pump"}}).hvac.heating == "heat_pump"
    with pytest.raises(
        EvtmsInputError, match=r'heating = "gas" is not allowed; allowed: ptc_air, ptc_coolant, heat_pump'
    ):
        system_params_from_dict({"hvac": {"heating": "gas"}})


def test_a_humid_cabin_is_dried_with_reheat_only_while_the_compressor_runs(synthetic):  # noqa: F811
    """18 degC, RH 0.95 outside, a damp cabin (RH 0.9): the RH request runs the compressor at the dew point less
    2 K with electric reheat to the vent target (flag reheat), and the cabin ends drier than without it."""
    p = system_params_from_dict({"cabin": {"rh_cabin": 0.9}})
    r = simulate(parked(1800.0), 291.15, synthetic, p, RH_amb=0.95)
    reheat = (r.flags[1:] & L.F_REHEAT) > 0
    assert reheat.any()
    assert np.all(r.records["compressor_on"][1:][reheat] > 0.0)
    never = simulate(parked(1800.0), 291.15, synthetic, system_params_from_dict({"cabin": {"rh_cabin": 0.9},
                     "climate": {"rh_dehum": 1.0}}), RH_amb=0.95)  # fmt: skip
    assert not np.any(never.flags & L.F_REHEAT)
    # Drier than without the request (whose fog-limited recirculation already keeps the 0.95 outside air out).
    assert r.records["RH_cabin"][-1] < never.records["RH_cabin"][-1] - 0.03
    heat_without_compressor = (r.records["P_ptc"][1:] > 0.0) & (r.records["compressor_on"][1:] == 0.0)
    assert np.all(~heat_without_compressor | np.isin(r.mode[1:], [L.CH, L.CH_BH, L.CH_BC]))
    assert max(r.ledgers.values()) <= 1e-9


def test_frost_retries_end_and_repeat_at_long_steps(synthetic):  # noqa: F811
    """dt 30 s against the filter's 10 s: most restarts would freeze the coil within the step, so the step runs
    again with the relay open; the run ends, no step's air reaches 0 degC, and a rerun gives the same."""
    inputs = {"SP_evap": 273.15, "blower": 0.4}
    runs = [simulate(parked(1800.0), 308.15, synthetic, mode="cc", dt=30.0, inputs=inputs) for _ in range(2)]
    assert runs[0].summary["T_evap_air_min_degC"] >= 0.0
    assert np.array_equal(runs[0].records["compressor_speed"], runs[1].records["compressor_speed"], equal_nan=True)
    assert max(runs[0].ledgers.values()) <= 1e-9


def test_the_power_cap_cuts_the_coolant_ptc_before_traction(synthetic):  # noqa: F811
    """A cell floor that caps the pack's power: the coolant PTC is cut first, and the heater loop's and the
    cabin's ledgers still close with what it got."""
    from evtms.system.battery import Battery

    v_min = round(float(Battery().emf(0.9)) / 96 - 0.01, 3)  # 10 mV per cell of headroom at the start
    p = system_params_from_dict({"hvac": {"heating": "ptc_coolant"}, "battery": {"cell_voltage_min": v_min}})
    r = simulate(parked(600.0), 263.15, synthetic, p)
    limited = (r.flags[1:] & L.F_POWER_LIMITED) > 0
    assert limited.any()
    assert np.nanmin(r.records["P_ptcw"][1:][limited]) < 6000.0 - 1.0
    assert max(r.ledgers.values()) <= 1e-9


def test_surrogates_refuse_coolant_heating(synthetic):  # noqa: F811
    p = system_params_from_dict({"hvac": {"heating": "ptc_coolant"}})
    with pytest.raises(EvtmsInputError, match="air PTC only"):
        simulate(first(WLTC, 60.0), 263.15, synthetic, p, model="surrogate", mode_models=object())


def test_fan_stages_switch_once_per_crossing_of_their_bands():
    """Three relays on the discharge pressure (spec v2 5.4) at 30 degC: on at 1.1 / 1.7 / 2.2 MPa, off at 0.8 /
    1.3 / 1.8 MPa; a pressure between the two keeps each stage as it was."""
    from types import SimpleNamespace

    from evtms.system.simulate import pack_parameters

    maps = SimpleNamespace(coolant_mdot_max=0.428, fan_flow_max=0.88, blower_flow_max=0.3)
    par = pack_parameters(system_params_from_dict({}), 303.15, 0.4, 0.0, -1, maps)
    up = np.linspace(0.5e6, 2.5e6, 401)
    pressures = np.concatenate([up, up[::-1]])
    stages = np.zeros((pressures.size, 3))
    s = (0.0, 0.0, 0.0)
    for i, p in enumerate(pressures):
        s = L._fan_stages(p, *s, par)
        stages[i] = s
    for k, (on, off) in enumerate(((1.1e6, 0.8e6), (1.7e6, 1.3e6), (2.2e6, 1.8e6))):
        switches = np.flatnonzero(np.diff(stages[:, k]))
        assert switches.size == 2, k  # once on the way up, once on the way down
        assert pressures[switches[0]] <= on < pressures[switches[0] + 1]
        assert pressures[switches[1]] >= off > pressures[switches[1] + 1]
    assert L._fan_stages(math.nan, 1.0, 0.0, 1.0, par) == (1.0, 0.0, 1.0)


def test_the_condenser_fan_is_staged_and_ram_air_adds_to_it(synthetic):  # noqa: F811
    """WLTC's first 20 min at 30 degC: the fan runs only with the compressor, in thirds, at least one stage
    while ram air is weak, its power the cube of its flow, the front-end air fan and ram in quadrature."""
    r = simulate(first(WLTC, 1200.0), 303.15, synthetic, dt=1.0, sun=600.0)
    rec = r.records
    fan, v_front, comp = rec["fan"][1:], rec["V_front"][1:], rec["compressor_speed"][1:]
    np.testing.assert_allclose(fan * 3.0, np.round(fan * 3.0), atol=1e-12)
    assert np.all(fan[comp == 0.0] == 0.0) and np.any(fan > 0.0) and np.any(fan < 1.0)
    np.testing.assert_allclose(rec["P_fan"][1:], 533.0 * (fan * 0.88 / 0.8) ** 3, rtol=1e-12)
    v_car = np.diff(rec["distance"]) / np.diff(rec["time"])
    np.testing.assert_allclose(v_front, np.maximum(np.hypot(fan * 0.88, 0.0289 * v_car), 0.05), rtol=1e-9)
    weak_ram = (comp > 0.0) & (0.0289 * v_car < 0.2)
    assert weak_ram.any() and np.all(fan[weak_ram] >= 1.0 / 3.0 - 1e-12)
    assert r.summary["hvac_energy_kWh"] > 0.0 and max(r.ledgers.values()) <= 1e-9
