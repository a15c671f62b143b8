"""Scenarios and the Table 12 inputs: the file format, every refusal, the built-in rows, traces, the commands.

Library tests need no maps; the command-line runs use the small cycle maps of
``test_simulate_cli`` (its fixtures, imported): a parked 1800 s run at dt 1 s
takes well under a second of loop.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import test_simulate_cli as simulate_cli
import xarray as xr
from conftest import one_error_line

from evtms.errors import EvtmsInputError
from evtms.system import inputs as inputs_module
from evtms.system.drive_cycles import drive_cycle
from evtms.system.inputs import FIELD_LABELS, Trace, check_inputs, per_step, read_trace
from evtms.system.params import SystemParams, system_params_from_dict
from evtms.system.scenarios import (
    SCENARIOS,
    Scenario,
    apply_heating,
    read_scenario_file,
    scenario_from_dict,
    scenarios_to_toml,
    select_scenarios,
)
from evtms.system.table12 import capacity_check, p_el, run_table12, window_mean

#: The small cycle maps of test_simulate_cli: its fixtures (the LUT folder, the map axes patched) and runner.
luts, _small_maps, run = simulate_cli.luts, simulate_cli._small_maps, simulate_cli.run


def refused(fn, *args, **kwargs) -> str:
    """The one-line message of the EvtmsInputError ``fn(*args)`` raises."""
    with pytest.raises(EvtmsInputError) as info:
        fn(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message and message.strip() == message and message
    return message


def K(celsius: float) -> float:
    return celsius + 273.15


# --------------------------------------------------------------------------------------------- built-in rows

#: Spec v2 section 4's table, typed in again: name, mode, T_amb, Tbatt (None: = T_amb), Qloss, Tin, SP_evap,
#: blower, SP_CoHX (degC, W, 1; None: empty).
SPEC_TABLE_12 = [
    ("t12-bh-1", "bh", 25, -20, 4000, None, None, None, None),
    ("t12-bh-2", "bh", 30, -10, 8000, None, None, None, None),
    ("t12-bh-3", "bh", -15, 20, 2000, None, None, None, None),
    ("t12-bh-4", "bh", 0, -5, 5000, None, None, None, None),
    ("t12-bc-1", "bc", 20, 30, 8000, None, None, None, None),
    ("t12-bc-2", "bc", 30, 15.5, 4000, None, None, None, None),
    ("t12-bc-3", "bc", 40, 15.5, 6000, None, None, None, None),
    ("t12-bc-4", "bc", 15, 40.5, 0, None, None, None, None),
    ("t12-cc-1", "cc", 20, None, 0, 40, 15, None, None),
    ("t12-cc-2", "cc", 35, None, 0, 15, 5, None, None),
    ("t12-cc-3", "cc", 45, None, 0, 45, 5, None, None),
    ("t12-cc-4", "cc", 30, None, 0, 20, 10, None, None),
    ("t12-ch-1", "ch", 0, 0, 0, 0, None, 1.0, 45),
    ("t12-ch-2", "ch", 0, 0, 0, 0, None, 0.2, 35),
    ("t12-ch-3", "ch", 0, 0, 0, 0, None, 0.6, 85),
    ("t12-ch-4", "ch", 0, 0, 0, 0, None, 0.8, 55),
]


@pytest.mark.parametrize("name, mode, t_amb, t_batt, q_loss, t_in, sp_evap, blower, sp_cohx", SPEC_TABLE_12)
def test_every_table12_row_is_the_spec_s(name, mode, t_amb, t_batt, q_loss, t_in, sp_evap, blower, sp_cohx):
    sc = SCENARIOS[name]
    approx = pytest.approx
    assert sc.cycle == "parked:1800" and sc.mode == mode
    assert sc.heating == ("ptc_coolant" if mode == "ch" else "ptc_air")
    assert sc.T_amb == approx(K(t_amb), abs=1e-9) and sc.rh_amb == 0.5 and sc.sun == 0.0
    T_b = K(t_amb if t_batt is None else t_batt)
    assert sc.initial.T_battery == approx(T_b, abs=1e-9) and sc.initial.T_coolant == approx(T_b, abs=1e-9)
    assert sc.initial.T_cabin == approx(K(t_amb), abs=1e-9) and sc.initial.soc == 0.9
    expected = {"Q_battery_ext": q_loss}
    if t_in is not None:
        expected.update(hvac_inlet_T=K(t_in), hvac_inlet_rh=0.5)
    if sp_evap is not None:
        expected["SP_evap"] = K(sp_evap)
    if blower is not None:
        expected["blower"] = blower
    if sp_cohx is not None:
        expected["SP_CoHX"] = K(sp_cohx)
    assert sc.inputs == approx(expected, abs=1e-9)
    # The row's parameters carry the initial state (the loop reads the tables' T_init fields).
    setup = sc.setup()
    b, k, c = setup.params.battery, setup.params.coolant, setup.params.cabin
    assert (b.T_init, k.T_init, c.T_init, b.soc_init) == approx((T_b, T_b, K(t_amb), 0.9), abs=1e-9)
    assert c.T_set == 295.15 and setup.cycle.duration == 1800.0 and setup.mode == mode


def test_the_t12_group_is_the_16_rows_in_table_order():
    assert [sc.name for sc in select_scenarios("t12", SCENARIOS)] == [row[0] for row in SPEC_TABLE_12]
    assert [sc.name for sc in select_scenarios("t12-cc", SCENARIOS)] == [f"t12-cc-{i}" for i in range(1, 5)]
    assert [sc.name for sc in select_scenarios("t12-bh-1, cold", SCENARIOS)] == ["t12-bh-1", "cold"]
    assert "'t13' is unknown" in refused(select_scenarios, "t13", SCENARIOS)
    assert "named twice" in refused(select_scenarios, "t12,t12-bh-1", SCENARIOS)


def test_v1_scenarios_kept_and_hot_sun_added():
    cold, cooldown, hot = SCENARIOS["cold"], SCENARIOS["cooldown"], SCENARIOS["hot-sun"]
    assert (cold.cycle, cold.T_amb, cold.rh_amb, cold.sun) == ("hwfet", 268.15, 0.65, 300.0)
    assert cold.initial.T_battery == cold.initial.T_cabin == 268.15 and cold.mode == "auto"
    assert (cooldown.cycle, cooldown.T_amb, cooldown.sun, cooldown.initial.T_coolant) == ("udds", 313.15, 600.0, 313.15)
    assert SCENARIOS["hot-drive"].initial.T_battery is None and SCENARIOS["wltc"].T_amb is None
    assert SCENARIOS["nedc"].cycle == "nedc"
    assert (hot.cycle, hot.T_amb, hot.rh_amb, hot.sun) == ("wltc3b", 308.15, 0.4, 850.0)
    assert hot.initial.T_battery == hot.initial.T_coolant == hot.initial.T_cabin == 308.15


# --------------------------------------------------------------------------------------------- the file format

SPEC_EXAMPLE = """
[t12-cc-2]                       # one table per scenario; name [a-z0-9-]
cycle = "parked:1800"            # parked:SECONDS | wltc3b | nedc | udds | hwfet | FILE.csv
mode = "cc"                      # auto | off | bh | bc | cc | ch | ch-hp (all but auto are forced)
heating = "ptc_air"              # ptc_air | ptc_coolant | heat_pump
T_amb = 308.15
rh_amb = 0.5
sun = 0.0
initial = { T_battery = 308.15, T_coolant = 308.15, T_cabin = 308.15, soc = 0.9 }
inputs = { hvac_inlet_T = 288.15, hvac_inlet_rh = 0.5, SP_evap = 278.15 }
params = { cabin = { T_set = 295.15 } }    # any --params table
"""


def test_the_spec_s_example_reads_as_the_built_in_row(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(SPEC_EXAMPLE)
    sc = read_scenario_file(f)["t12-cc-2"]
    builtin = SCENARIOS["t12-cc-2"]
    assert sc.inputs == {k: v for k, v in builtin.inputs.items() if k != "Q_battery_ext"}
    assert dataclasses.replace(sc, inputs={}, source="") == dataclasses.replace(builtin, inputs={}, source="")


def test_round_trip_of_every_built_in_and_a_file_scenario(tmp_path):
    (tmp_path / "in.csv").write_text("time_s,T_in,rh\n0,300.15,0.4\n600,295.15,0.5\n")
    (tmp_path / "trip.csv").write_text("time_s,speed_kmh\n0,0\n10,30\n60,0\n")
    own = scenario_from_dict(
        "my-trip",
        {
            "cycle": "trip.csv",
            "mode": "cc",
            "T_amb": 305.0,
            "rh_amb": 0.3,
            "sun": 100.0,
            "initial": {"T_cabin": 320.0},
            "inputs": {"hvac_inlet_T": "in.csv:T_in", "hvac_inlet_rh": "in.csv:rh", "blower": 0.5},
            "params": {"cabin": {"T_set": 294.0}, "battery": {"g_ambient": 20.0}},
        },
        base=tmp_path,
    )
    assert own.cycle == str(tmp_path / "trip.csv") and own.inputs["hvac_inlet_T"] == f"{tmp_path / 'in.csv'}:T_in"
    originals = [*SCENARIOS.values(), own]
    f = tmp_path / "sub" / "all.toml"
    f.parent.mkdir()
    f.write_text(scenarios_to_toml(originals))
    back = read_scenario_file(f)
    assert list(back) == [sc.name for sc in originals]
    for sc in originals:
        assert dataclasses.replace(back[sc.name], source="") == dataclasses.replace(sc, source=""), sc.name
    # The traces of the read-back scenario are the file's.
    setup = back["my-trip"].setup()
    assert isinstance(setup.inputs["hvac_inlet_T"], Trace) and setup.inputs["hvac_inlet_T"].values[-1] == 295.15
    assert setup.params.cabin.T_init == 320.0 and setup.params.battery.g_ambient == 20.0


#: (case id, file text, fragments of the one-line message). Files and traces sit in the test's folder.
BAD_FILES = [
    ("not-toml", "[a\ncycle = 1", ["not valid TOML"]),
    ("empty", "", ["is empty"]),
    ("bad-name", '[Bad_Name]\ncycle = "udds"\n', ["scenario name 'Bad_Name' is not allowed", "a-z, 0-9 and -"]),
    ("not-a-table", "x = 3\n", ["[x] must be a table"]),
    ("unknown-key", '[a]\ncycle = "udds"\nspeed = 3\n', ["[a] key 'speed' is unknown", "allowed: cycle, mode"]),
    ("no-cycle", "[a]\nmode = 'cc'\n", ["[a] has no cycle"]),
    ("cycle-number", "[a]\ncycle = 3\n", ["cycle = 3 is not a string"]),
    ("cycle-parked-0", '[a]\ncycle = "parked:0"\n', ["parked:0", "1 to 604,800 s"]),
    ("cycle-missing-file", '[a]\ncycle = "nosuch.csv"\n', ["[a] cycle", "nosuch.csv", "cannot read"]),
    ("mode-unknown", '[a]\ncycle = "udds"\nmode = "heat"\n', ["mode 'heat' is unknown", "auto, off, bh"]),
    ("heating-unknown", '[a]\ncycle = "udds"\nheating = "gas"\n', ["heating 'gas' is unknown"]),
    ("T_amb-degC", '[a]\ncycle = "udds"\nT_amb = 35\n', ["T_amb = 35 is not allowed", "233.15 to 333.15 K"]),
    ("T_amb-text", '[a]\ncycle = "udds"\nT_amb = "hot"\n', ["T_amb = 'hot' is not a finite number"]),
    ("rh", '[a]\ncycle = "udds"\nrh_amb = 1.5\n', ["rh_amb = 1.5 is not allowed", "0 to 1"]),
    ("sun", '[a]\ncycle = "udds"\nsun = -1\n', ["sun = -1 is not allowed", "0 to 1500 W/m2"]),
    ("nan", '[a]\ncycle = "udds"\nsun = nan\n', ["sun = nan is not a finite number"]),
    ("initial-value", '[a]\ncycle = "udds"\ninitial = 3\n', ["initial must be a table"]),
    ("initial-key", '[a]\ncycle = "udds"\ninitial = { T_motor = 300.0 }\n', ["initial.T_motor is unknown",
                                                                           "T_battery, T_coolant, T_cabin, soc"]),
    ("initial-degC", '[a]\ncycle = "udds"\ninitial = { T_battery = 20 }\n', ["initial.T_battery = 20 is not allowed"]),
    ("initial-soc", '[a]\ncycle = "udds"\ninitial = { soc = 2 }\n', ["initial.soc = 2 is not allowed"]),
    ("initial-soc-min", '[a]\ncycle = "udds"\ninitial = { soc = 0.05 }\n', ["initial.soc", "soc_min < soc_init"]),
    ("initial-and-params",
     '[a]\ncycle = "udds"\ninitial = { T_cabin = 300.0 }\nparams = { cabin = { T_init = 300.0 } }\n',
     ["initial.T_cabin and params.cabin.T_init", "give one"]),
    ("inputs-value", '[a]\ncycle = "udds"\ninputs = 3\n', ["inputs must be a table"]),
    ("input-unknown", '[a]\ncycle = "udds"\ninputs = { Qloss = 3.0 }\n', ["input 'Qloss' is unknown",
                                                                        "allowed: Q_battery_ext, hvac_inlet_T"]),
    ("input-text", '[a]\ncycle = "udds"\ninputs = { blower = "fast" }\n', ["input blower = 'fast' is neither"]),
    ("input-bool", '[a]\ncycle = "udds"\ninputs = { blower = true }\n', ["input blower = True is not a number"]),
    ("input-range", '[a]\ncycle = "udds"\ninputs = { SP_evap = 5.0 }\n', ["input SP_evap = 5 K is not allowed",
                                                                        "273.15 to 298.15 K"]),
    ("blower-0-auto", '[a]\ncycle = "udds"\ninputs = { blower = 0.0 }\n', ["blower = 0 is not allowed with mode auto"]),
    ("blower-0-ch", '[a]\ncycle = "udds"\nmode = "ch"\ninputs = { blower = 0 }\n', ["with mode ch"]),
    ("params-value", '[a]\ncycle = "udds"\nparams = 3\n', ["params must be a table"]),
    ("params-table", '[a]\ncycle = "udds"\nparams = { hvac2 = { x = 1 } }\n', ["params: table [hvac2] is unknown"]),
    ("params-range", '[a]\ncycle = "udds"\nparams = { cabin = { volume = -1 } }\n', ["[cabin] volume = -1"]),
    ("trace-missing", '[a]\ncycle = "udds"\ninputs = { SP_evap = "no.csv:T" }\n', ["no.csv", "cannot read"]),
    ("trace-column", '[a]\ncycle = "udds"\ninputs = { SP_evap = "tr.csv:T_x" }\n', ["no column 'T_x'", "T, rh"]),
    ("trace-time", '[a]\ncycle = "udds"\ninputs = { SP_evap = "back.csv:T" }\n', ["back.csv:4", "does not increase"]),
    ("trace-nan", '[a]\ncycle = "udds"\ninputs = { SP_evap = "nan.csv:T" }\n', ["nan.csv:3", "T nan is not finite"]),
    ("trace-range", '[a]\ncycle = "udds"\ninputs = { hvac_inlet_rh = "tr.csv:T" }\n', ["tr.csv:2", "is not allowed",
                                                                                    "0 to 1"]),
    ("trace-degC", '[a]\ncycle = "udds"\ninputs = { SP_evap = "c.csv:T" }\n', ["c.csv:3", "5 K", "(SI)"]),
    ("trace-one", '[a]\ncycle = "udds"\ninputs = { SP_evap = "one.csv:T" }\n', ["1 sample(s)", "at least 2"]),
    ("trace-cells", '[a]\ncycle = "udds"\ninputs = { SP_evap = "short.csv:T" }\n', ["short.csv:3", "expected 3"]),
    ("trace-text", '[a]\ncycle = "udds"\ninputs = { SP_evap = "txt.csv:T" }\n', ["txt.csv:2", "is not a number"]),
    ("trace-no-time", '[a]\ncycle = "udds"\ninputs = { SP_evap = "notime.csv:T" }\n', ["no 'time_s' column"]),
    ("trace-twice", '[a]\ncycle = "udds"\ninputs = { SP_evap = "twice.csv:T" }\n', ["column 'T' appears twice"]),
    ("trace-blower-0", '[a]\ncycle = "udds"\nmode = "cc"\ninputs = { blower = "bl.csv:u" }\n',
     ["bl.csv:u (0 at 60 s) is not allowed with mode cc"]),
]  # fmt: skip

TRACES = {
    "tr.csv": "time_s,T,rh\n0,280.15,0.5\n600,285.15,0.5\n",
    "back.csv": "time_s,T\n0,280.15\n10,281.15\n5,282.15\n",
    "nan.csv": "time_s,T\n0,280.15\n10,nan\n",
    "c.csv": "# SP_evap in degC by mistake\ntime_s,T\n0,5\n10,5\n",
    "one.csv": "time_s,T\n0,280.15\n",
    "short.csv": "time_s,T,x\n0,280.15,1\n10,281.15\n",
    "txt.csv": "time_s,T\n0,cold\n",
    "notime.csv": "t,T\n0,280.15\n",
    "twice.csv": "time_s,T,T\n0,280.15,280.15\n",
    "bl.csv": "time_s,u\n0,0.5\n60,0\n120,0.5\n",
}


@pytest.mark.parametrize("case, text, fragments", BAD_FILES, ids=[c[0] for c in BAD_FILES])
def test_a_bad_scenario_file_is_one_line(tmp_path, case, text, fragments):
    for name, content in TRACES.items():
        (tmp_path / name).write_text(content)
    f = tmp_path / "bad.toml"
    f.write_text(text)
    message = refused(read_scenario_file, f)
    assert "scenario file" in message and "bad.toml" in message, message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_a_trace_file_is_bounded_before_it_is_read(tmp_path, monkeypatch):
    f = tmp_path / "big.csv"
    f.write_text("time_s,T\n" + "".join(f"{t},280.15\n" for t in range(200)))
    monkeypatch.setattr(inputs_module, "MAX_TRACE_BYTES", 1000)
    assert "above the limit of 1,000" in refused(read_trace, f, "T", "SP_evap")
    monkeypatch.setattr(inputs_module, "MAX_TRACE_BYTES", 10**6)
    monkeypatch.setattr(inputs_module, "MAX_TRACE_SAMPLES", 100)
    assert "more than 100 samples" in refused(read_trace, f, "T", "SP_evap")
    assert "not a regular file" in refused(read_trace, tmp_path, "T", "SP_evap")


def test_check_inputs_numbers_units_and_refusals():
    got = check_inputs({"SP_evap": 5, "blower": 0.6, "Q_battery_ext": 5000}, celsius=True)
    assert got == {"Q_battery_ext": 5000.0, "SP_evap": 278.15, "blower": 0.6}
    assert list(got) == ["Q_battery_ext", "SP_evap", "blower"]  # the loop's column order
    assert "input 'Qloss' is unknown" in refused(check_inputs, {"Qloss": 1.0})
    assert "input blower = [1] is not a number" in refused(check_inputs, {"blower": [1]})
    msg = refused(check_inputs, {"SP_CoHX": 100.0}, celsius=True, labels=FIELD_LABELS)
    assert msg == "`SP_CoHX` 100 degC is not allowed; allowed: 15 to 90 degC"
    assert "inf is not allowed" in refused(check_inputs, {"Q_battery_ext": math.inf})
    bad = Trace(np.array([0.0, 1.0]), np.array([0.5, 1.5]), "x.csv:u")
    assert "1.5 at 1 s is not allowed" in refused(check_inputs, {"blower": bad})
    back = Trace(np.array([1.0, 0.0]), np.array([0.5, 0.5]), "x.csv:u")
    assert "strictly increasing" in refused(check_inputs, {"blower": back})


@pytest.mark.parametrize("mode", ["auto", "cc", "ch", "cc+bc", "ch+bh"])
def test_a_blower_of_0_is_refused_with_a_mode_that_runs_the_cabin_coil_or_a_heater(mode):
    assert f"mode {mode}" in refused(check_inputs, {"blower": 0.0}, mode=mode)
    zero_once = Trace(np.array([0.0, 10.0, 20.0]), np.array([0.5, 0.0, 0.5]), "b.csv:u")
    assert "0 at 10 s" in refused(check_inputs, {"blower": zero_once}, mode=mode)


@pytest.mark.parametrize("mode", ["off", "bh", "bc"])
def test_a_blower_of_0_is_allowed_where_the_climate_stays_off(mode):
    assert check_inputs({"blower": 0.0}, mode=mode) == {"blower": 0.0}


def test_a_trace_s_step_means_are_its_exact_integral(tmp_path):
    f = tmp_path / "q.csv"
    f.write_text("# battery heat\ntime_s,other,Q\n0,1,1000\n10,2,3000\n30,3,-1000\n")
    trace = check_inputs({"Q_battery_ext": f"{f}:Q"})["Q_battery_ext"]
    assert trace.source == f"{f}:Q"

    def F(t: float) -> float:
        """Antiderivative of the trace, held at 1000 W before 0 s and at -1000 W after 30 s."""
        if t <= 0:
            return 1000.0 * t
        if t <= 10:
            return 1000.0 * t + 100.0 * t * t
        if t <= 30:
            u = t - 10.0
            return 20000.0 + 3000.0 * u - 100.0 * u * u
        return 40000.0 - 1000.0 * (t - 30.0)

    edges = np.concatenate((np.arange(-5.0, 40.0, 0.7), [40.0]))
    means = per_step({"Q_battery_ext": trace}, edges)[:, 0]
    exact = np.array([(F(b) - F(a)) / (b - a) for a, b in zip(edges[:-1], edges[1:], strict=True)])
    np.testing.assert_allclose(means, exact, rtol=0, atol=1e-9)
    assert np.isnan(per_step({"Q_battery_ext": trace}, edges)[:, 1]).all()  # an input not given


def test_parked_cycles():
    c = drive_cycle("parked:1800")
    assert c.duration == 1800.0 and c.distance == 0.0 and np.all(c.speed == 0) and c.name == "parked:1800"
    assert "parked:SECONDS" in refused(drive_cycle, "parked:soon")
    assert "1 to 604,800 s" in refused(drive_cycle, "parked:1e9")


def test_setup_overrides_and_the_heating_option():
    sc = SCENARIOS["t12-cc-1"]
    setup = sc.setup(mode="cc", inputs={"SP_evap": 280.0})
    assert setup.inputs["SP_evap"] == 280.0 and setup.inputs["hvac_inlet_T"] == K(40)
    assert "`blower` 0 is not allowed with mode cc" in refused(sc.setup, inputs={"blower": 0.0})
    assert "scenario 't12-cc-1': input blower = 0" in refused(dataclasses.replace(sc, inputs={"blower": 0.0}).setup)
    assert sc.setup(mode="bc", inputs={"blower": 0.0}).mode == "bc"
    ch = SCENARIOS["t12-ch-1"].setup()
    assert ch.heating == "ptc_coolant" and ch.params.hvac.heating == "ptc_coolant"
    assert apply_heating(SystemParams(), "ptc_coolant").hvac.heating == "ptc_coolant"
    assert Scenario("", "udds").setup().mode == "auto"
    # ch-hp forces cabin heating on the heat pump: the mode ch with heating heat_pump.
    hp = SCENARIOS["t12-ch-1"].setup(mode="ch-hp")
    assert hp.mode == "ch" and hp.heating == "heat_pump" and hp.params.hvac.heating == "heat_pump"
    assert Scenario("", "udds", heating="heat_pump").setup().params.hvac.heating == "heat_pump"
    # A scenario that names no heating keeps the parameters' (a --params file's [hvac] heating).
    own = Scenario("", "udds").setup(system_params_from_dict({"hvac": {"heating": "ptc_coolant"}}))
    assert own.heating == "ptc_coolant" and own.params.hvac.heating == "ptc_coolant"


# --------------------------------------------------------------------------------------------- Table 12 columns


def _records(t_end: float = 1800.0, **columns):
    t = np.arange(0.0, t_end + 1.0, 1.0)
    rec = {"time": t}
    for name, value in columns.items():
        v = np.broadcast_to(np.asarray(value, float), t.shape).copy() if np.ndim(value) == 0 else np.asarray(value)
        if name.startswith("P_"):
            v[0] = np.nan  # interval means
        rec[name] = v
    return rec


def test_window_means_of_interval_means_and_of_states():
    t = np.arange(0.0, 11.0)
    power = np.concatenate(([np.nan], np.arange(1.0, 11.0)))  # record k: the mean over (k-1, k]
    assert window_mean(t, power, 6.0, 10.0) == pytest.approx(np.mean([7, 8, 9, 10]))
    state = 2.0 * t
    assert window_mean(t, state, 4.5, 10.0) == pytest.approx((9.0 + 20.0) / 2)


def test_p_el_per_mode_and_missing_terms():
    rec = _records(P_heater=3000.0, P_pump=50.0, P_compressor=900.0, P_fan=200.0, P_blower=40.0, P_hvac=1500.0)
    for mode, total in (("bh", 3050.0), ("bc", 1150.0), ("cc", 1140.0), ("auto", 1500.0)):
        power, _, missing = p_el(rec, mode)
        assert not missing and window_mean(rec["time"], power, 0.0, 1800.0) == pytest.approx(total)
    power, terms, missing = p_el(rec, "ch")
    assert power is None and terms == ("P_ptcw", "P_pump_h", "P_blower") and missing == ["P_ptcw", "P_pump_h"]


def test_capacity_over_the_last_10_minutes():
    sp = {"SP_evap": 278.15}
    held = _records(T_evap_air=np.where(np.arange(1801) < 1200, 290.0, 278.15 + 0.9))
    assert capacity_check(held, sp).limited is False
    missed = _records(T_evap_air=278.15 + 1.5)
    check = capacity_check(missed, sp)
    assert check.limited is True and check.means["T_evap_air"] == pytest.approx(279.65)
    # A trace setpoint is compared with its own mean over the window.
    ramp = Trace(np.array([0.0, 1800.0]), np.array([278.15, 288.15]), "sp.csv:T")
    rising = _records(T_evap_air=np.linspace(278.15, 288.15, 1801))
    assert capacity_check(rising, {"SP_evap": ramp}).limited is False
    assert capacity_check(rising, {"SP_evap": 278.15}).limited is True
    unknown = capacity_check(_records(), {"SP_CoHX": 318.15})
    assert unknown.limited is None and "no T_heater_loop record" in unknown.note
    assert capacity_check(_records(), {}).limited is False


class _Fake:
    def __init__(self, records, summary):
        self.records, self.summary = records, summary


def test_run_table12_references_and_errors_with_a_stand_in_simulator():
    calls = []

    def sim(setup, refrigerant, *, dt, model, mode_models):
        calls.append((setup.scenario.name, model))
        offset = {"physics": 0.0, "lut": 0.3}[model]
        rec = _records(T_battery=300.0 + offset, T_cabin=295.0, P_compressor=1000.0 + 100 * offset, P_fan=100.0,
                       P_pump=50.0, P_blower=10.0)  # fmt: skip
        summary = {"wall_time_s": {"physics": 50.0, "lut": 0.01 + len(calls) * 1e-3}[model], "loop_time_s": 0.01,
                   "soc_end": 0.89, "T_battery_end_degC": 27.0, "T_cabin_end_degC": 22.0,
                   "termination": "end of cycle"}  # fmt: skip
        return _Fake(rec, summary)

    chosen = select_scenarios("t12-bc-1,t12-cc-2", SCENARIOS)
    result = run_table12(chosen, None, approaches=["lut", "physics"], dt=1.0, repeat=3, simulator=sim)
    assert calls[0] == ("t12-bc-1", "physics") and len(calls) == 2 * (1 + 3)
    assert result.reference == "physics" and result.approaches == ("physics", "lut")
    by = {(r.scenario, r.approach): r for r in result.rows}
    bc_lut = by[("t12-bc-1", "lut")]
    assert bc_lut.error_variable == "T_battery" and bc_lut.rmse_K == pytest.approx(0.3)
    assert by[("t12-bc-1", "physics")].rmse_K == 0.0
    assert bc_lut.P_el_W == pytest.approx(1030.0 + 100.0 + 50.0) and bc_lut.d_P_el_pct == pytest.approx(100 * 30 / 1150)
    assert bc_lut.wall_time_s == pytest.approx(np.median([0.012, 0.013, 0.014]))
    assert (bc_lut.T_amb_K, bc_lut.T_battery0_K, bc_lut.Q_loss_W) == (293.15, 303.15, 8000.0)
    cc = by[("t12-cc-2", "lut")]
    assert cc.error_variable == "T_cabin" and cc.rmse_K == 0.0 and cc.SP_evap_K == 278.15 and cc.T_in_K == 288.15
    assert cc.P_el_W == pytest.approx(1030.0 + 100.0 + 10.0)
    assert cc.capacity_setpoints == "SP_evap" and bc_lut.capacity_setpoints == ""
    assert cc.capacity_limited is None and "T_evap_air" in cc.capacity_note  # the stand-in records no T_evap_air
    assert bc_lut.capacity_limited is False and bc_lut.capacity_note == "no setpoint given"
    assert "repeat 0" in refused(run_table12, chosen, None, repeat=0, simulator=sim)
    assert "'neural' is unknown" in refused(run_table12, chosen, None, approaches=["neural"], simulator=sim)
    assert "no ambient" in refused(run_table12, [SCENARIOS["wltc"]], None, simulator=sim)


# --------------------------------------------------------------------------------------------- the commands


def test_simulate_a_table12_row_on_small_maps(luts, tmp_path):
    out = tmp_path / "bc1.nc"
    r = run("simulate", "--scenario", "t12-bc-1", "--luts", luts, "-o", out, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["scenario"] == "t12-bc-1" and s["mode_request"] == "bc" and s["inputs"] == {"Q_battery_ext": 8000.0}
    assert s["duration_s"] == 1800.0 and s["distance_km"] == 0.0 and s["termination"] == "end of cycle"
    assert s["ledger_worst"] <= 1e-9
    with xr.open_dataset(out) as ds:
        assert ds["T_battery"].values[0] == pytest.approx(303.15) and ds["T_coolant"].values[0] == pytest.approx(303.15)
        assert ds["T_cabin"].values[0] == pytest.approx(293.15) and ds["SOC"].values[0] == pytest.approx(0.9)
        assert ds.attrs["scenario"] == "t12-bc-1" and ds.attrs["mode_request"] == "bc"
        assert json.loads(ds.attrs["inputs"]) == {"Q_battery_ext": 8000.0} and ds.attrs["heating"] == "ptc_air"
        assert (ds["mode"].values[1:] == 2).any()  # forced BC ran (code 2) while the battery was warm


def test_simulate_with_input_options_and_a_scenario_file(luts, tmp_path):
    (tmp_path / "sp.csv").write_text("time_s,T\n0,283.15\n900,278.15\n")
    f = tmp_path / "mine.toml"
    f.write_text('[warm-cc]\ncycle = "parked:300"\nmode = "cc"\nT_amb = 303.15\ninputs = { SP_evap = "sp.csv:T" }\n')
    out = tmp_path / "w.nc"
    r = run("simulate", "--scenario-file", f, "--blower", "0.7", "--hvac-inlet-t", "25", "--luts", luts, "-o", out,
            "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["scenario"] == "warm-cc" and s["duration_s"] == 300.0
    assert s["inputs"] == {"hvac_inlet_T": 298.15, "SP_evap": f"{tmp_path / 'sp.csv'}:T", "blower": 0.7}


@pytest.mark.parametrize(
    "args, message",
    [
        (["--cycle", "parked:600", "--t-amb", "30", "--mode", "cc", "--blower", "0"],
         "--blower 0 is not allowed with mode cc"),
        (["--scenario", "t12-cc-1", "--blower", "0"], "--blower 0 is not allowed with mode cc"),
        (["--cycle", "parked:600", "--t-amb", "30", "--sp-evap", "40"],
         "--sp-evap 40 degC is not allowed; allowed: 0 to 25 degC"),
        (["--cycle", "parked:600", "--t-amb", "30", "--blower", "no.csv:u"], "--blower 'no.csv:u'"),
        (["--cycle", "parked:600", "--t-amb", "30", "--q-battery", "lots"], "--q-battery 'lots' is neither"),
        (["--cycle", "parked:600", "--t-amb", "30", "--heating", "gas"], "--heating 'gas' is unknown"),
        (["--cycle", "parked:600", "--t-amb", "30", "--heating", "ptc_air,ptc_air"], "--heating 'ptc_air,ptc_air'"),
        (["--scenario", "t12-bh-9"], "--scenario 't12-bh-9' is unknown"),
        (["--scenario-file", "nosuch.toml"], "scenario file 'nosuch.toml': no such file"),
        (["--scenario", "t12-bh-1", "--cycle", "udds"], "one of them"),
    ],
)  # fmt: skip
def test_bad_scenario_or_input_options_are_one_line_and_no_file(luts, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "bad.nc"
    r = run("simulate", *args, "--luts", luts, "-o", out)
    one_error_line(r, message)
    assert not out.exists()


def test_a_heat_pump_scenario_file_sets_the_heating(tmp_path):
    from evtms.system.scenarios import read_scenario_file

    f = tmp_path / "hp.toml"
    f.write_text('[hp]\ncycle = "wltc3b"\nT_amb = 263.15\nheating = "heat_pump"\n')
    setup = read_scenario_file(f)["hp"].setup()
    assert setup.heating == "heat_pump" and setup.params.hvac.heating == "heat_pump"


def test_report_compare_prints_the_table12_columns(luts, tmp_path):
    r = run("report", "compare", "--scenarios", "t12-bc-1,t12-cc-2", "--approaches", "lut", "--repeat", "1",
            "--luts", luts, "--json", "-o", tmp_path / "t12")  # fmt: skip
    assert r.exit_code == 0, r.output
    result = json.loads(r.stdout)
    rows = {row["scenario"]: row for row in result["rows"]}
    assert list(rows) == ["t12-bc-1", "t12-cc-2"] and result["reference"] == "lut"
    bc, cc = rows["t12-bc-1"], rows["t12-cc-2"]
    assert bc["mode"] == "bc" and bc["Q_loss_W"] == 8000.0 and bc["T_battery0_K"] == pytest.approx(303.15)
    assert cc["T_in_K"] == 288.15 and cc["SP_evap_K"] == 278.15 and cc["blower"] is None
    assert bc["rmse_K"] == 0.0 and bc["wall_time_s"] > 0.0 and bc["P_el_terms"] == "P_compressor+P_fan+P_pump"
    # P_el is the thesis's sum over the run, as the simulation file holds it.
    r = run("simulate", "--scenario", "t12-bc-1", "--luts", luts, "-o", tmp_path / "bc.nc")
    assert r.exit_code == 0, r.output
    with xr.open_dataset(tmp_path / "bc.nc") as ds:
        total = sum(ds[v].values[1:] for v in ("P_compressor", "P_fan", "P_pump"))
    assert bc["P_el_W"] == pytest.approx(float(np.mean(total)), rel=1e-12)
    assert (tmp_path / "t12" / "table12.csv").is_file() and (tmp_path / "t12" / "table12.html").is_file()
    r = run("report", "compare", "--scenarios", "t12-bh", "--approaches", "lut", "--repeat", "1", "--luts", luts)
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0].split()[:4] == ["scenario", "approach", "mode", "T_amb"]
    assert lines[1].split()[:6] == ["bh-1", "lut", "bh", "25.0", "-20.0", "4000"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--scenarios", "t13"], "scenario 't13' is unknown"),
        (["--scenarios", "t12", "--cycle", "udds"], "leave out --cycle, --t-amb, --measured"),
        (["--scenarios", "t12", "--sun", "600"], "leave out --sun, --soak-cabin, --physics-dts"),
        (["--scenarios", "wltc", "--approaches", "lut"], "has no ambient of its own"),
        (["--scenarios", "t12-cc-1", "--approaches", "lut,neural"], "--approaches 'neural' is unknown"),
        (["--cycle", "udds", "--t-amb", "30"], "give --output FOLDER"),
    ],
)  # fmt: skip
def test_bad_report_compare_scenarios_are_one_line(luts, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    r = run("report", "compare", *args, "--luts", luts)
    one_error_line(r, message)
