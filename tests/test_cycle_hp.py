"""The heat-pump circuit ``hp``: the WCC heating the heating loop, the chiller drawing on the e-drive loop."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import one_error_line
from typer.testing import CliRunner

from evtms.cli import app
from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
from evtms.cycle.solver import VALID_CYCLE_FLAGS
from evtms.cycle.topology import INPUTS, TOPOLOGIES, parse_inputs, topology
from evtms.errors import EvtmsInputError

runner = CliRunner()


def test_hp_declares_its_condensing_component_and_inputs():
    hp = TOPOLOGIES["hp"]
    assert hp.condensing.component == "wcc" and hp.condensing.secondary_temperature == "T_coolant_h_in"
    assert hp.components == ("wcc", "chiller", "expansion_valve", "compressor")
    assert hp.inputs == (
        "speed",
        "mdot_coolant_h",
        "T_coolant_h_in",
        "mdot_coolant",
        "T_coolant_in",
        "superheat",
        "subcooling",
    )
    # The other circuits keep the air-cooled condenser and its air inputs.
    for name in ("cabin", "chiller", "cabin+chiller"):
        circuit = TOPOLOGIES[name]
        assert circuit.components[0] == "condenser"
        assert {"fan", "T_amb", "RH_amb"} <= set(circuit.inputs)
        assert not {"mdot_coolant_h", "T_coolant_h_in"} & set(circuit.inputs)
    assert INPUTS["T_coolant_h_in"].celsius and INPUTS["mdot_coolant_h"].positive


def test_hp_inputs_parse_in_celsius_and_refuse_air_inputs():
    grid = parse_inputs({"T_coolant_h_in": "40,60", "mdot_coolant_h": None}, topology("hp"), 100)
    assert grid["T_coolant_h_in"] == [313.15, 333.15]
    assert grid["mdot_coolant_h"] == [0.2]
    with pytest.raises(EvtmsInputError, match="`fan`: not an input of the hp topology"):
        parse_inputs({"fan": "0.5"}, topology("hp"), 100)
    with pytest.raises(EvtmsInputError, match="T_coolant_h_in = 95 degC is not allowed; allowed: -20 to 90 degC"):
        parse_inputs({"T_coolant_h_in": "95"}, topology("hp"), 100)


# -- the circuit on the cycle LUTs ----------------------------------------------------------
#: Speed 0.3 / 0.6 / 1 at an e-drive loop at 10 degC, then the e-drive loop at 0 / 20 / 30 degC at speed 0.6;
#: the heating loop at 40 degC, 0.2 kg/s.
SPEEDS = (0.3, 0.6, 1.0, 0.6, 0.6, 0.6)
T_EDRIVE = (283.15, 283.15, 283.15, 273.15, 293.15, 303.15)


@pytest.fixture(scope="module")
def hp_points():
    return OperatingPoints(
        speed=SPEEDS, mdot_coolant_h=0.2, T_coolant_h_in=313.15, mdot_coolant=0.2, T_coolant_in=T_EDRIVE
    )


@pytest.fixture(scope="module")
def hp_lut(cycle_luts_dir, hp_points):
    return run_cycle(hp_points, load_cycle_luts(cycle_luts_dir, "hp"), circuit="hp")


def test_hp_closes_its_energy_balance_per_point(hp_lut):
    r = hp_lut
    assert (r["status"] == 0).all(), r["reason"]
    # The WCC's heat to the heating loop is the chiller's heat from the e-drive loop plus the compressor's work.
    assert np.allclose(r["Q_cond"], -r["Q_chiller"] + r["W_fluid"], rtol=1e-4, atol=0)
    assert np.abs(r["balance_relative"]).max() < 1e-4
    assert (r["Q_evap"] == 0).all() and (r["mdot_chiller"] == r["mdot"]).all()
    assert np.allclose(r["COP_heating"], r["Q_cond"] / r["W"])


def test_hp_heats_more_with_speed_and_more_efficiently_with_a_warmer_source(hp_lut):
    r = hp_lut
    q = r["Q_cond"][:3]
    assert np.all(np.diff(q) > 0), q
    cop = r["COP_heating"][[3, 1, 4, 5]]  # e-drive loop at 0, 10, 20, 30 degC
    assert np.all(cop > 1) and np.all(np.diff(cop) > 0), cop
    assert np.all(r["COP_heating"] > 1)
    # Condensing above the heating loop's coolant, evaporating below the e-drive loop's.
    T_sat_B, T_sat_A = r["T_C"], r["T_D"]  # saturated liquid at C; D is two-phase
    assert np.all(T_sat_B > 313.15) and np.all(T_sat_A < np.asarray(T_EDRIVE))


def test_hp_luts_match_the_direct_physics(hp_lut, hp_points):
    """LUTs against the WCC and chiller benches called directly (docs/guide/cycle.md: accuracy, hp)."""
    idx = np.array([0, 2, 4])
    points = OperatingPoints(**hp_points.subset(idx))
    direct = run_cycle(points, circuit="hp")
    assert (direct["status"] == 0).all(), direct["reason"]
    # Measured at these points: within 0.16 % (Q_chiller; the envelope's worst: docs/guide/cycle.md).
    for key in ("p_A", "p_B", "mdot", "Q_cond", "Q_chiller", "W", "COP_heating"):
        assert np.allclose(hp_lut[key][idx], direct[key], rtol=0.005), (key, hp_lut[key][idx], direct[key])
    assert np.abs(direct["balance_relative"]).max() < 1e-4


def test_hp_says_where_the_wcc_cannot_condense(cycle_luts_dir):
    """A heating loop too warm and too slow for the compressor's pressure ratio: a status and a reason, no crash."""
    points = OperatingPoints(
        speed=1.0, mdot_coolant_h=0.05, T_coolant_h_in=343.15, mdot_coolant=0.1, T_coolant_in=273.15
    )
    r = run_cycle(points, load_cycle_luts(cycle_luts_dir, "hp"), circuit="hp")
    assert r["status"][0] not in VALID_CYCLE_FLAGS
    assert "water-cooled condenser" in r["reason"][0]
    assert np.isnan(r["p_B"][0])


def test_hp_luts_need_the_wcc_not_the_condenser(cycle_luts_dir, tmp_path):
    import shutil

    for c in ("chiller", "compressor", "expansion_valve", "condenser"):
        shutil.copy2(cycle_luts_dir / f"{c}.nc", tmp_path / f"{c}.nc")
    with pytest.raises(EvtmsInputError, match="lacks wcc"):
        load_cycle_luts(tmp_path, "hp")
    shutil.copy2(cycle_luts_dir / "wcc.nc", tmp_path / "wcc.nc")
    assert set(load_cycle_luts(tmp_path, "hp")) == {"wcc", "chiller", "expansion_valve", "compressor"}


# -- command line ---------------------------------------------------------------------------
def test_cli_runs_the_heat_pump(cycle_luts_dir):
    res = runner.invoke(
        app,
        ["cycle", "run", "--luts", str(cycle_luts_dir), "--topology", "hp", "--speed", "0.6"]
        + ["--t-coolant-h", "40", "--coolant-flow-h", "0.2", "--t-coolant", "10"],
    )
    assert res.exit_code == 0, res.output
    assert "heating COP" in res.stdout and "heat from the e-drive loop" in res.stdout and "C WCC outlet" in res.stdout


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--fan", "0.5"], ("--fan: not an input of the hp topology", "--coolant-flow-h", "--t-coolant-h")),
        (["--t-amb", "0"], ("--t-amb: not an input of the hp topology",)),
        (["--t-coolant-h", "95"], ("T_coolant_h_in = 95 degC is not allowed", "-20 to 90 degC")),
        (["--coolant-flow-h", "0"], ("mdot_coolant_h = 0 is not allowed",)),
        (["--coolant-flow-h", "abc"], ("is not a number",)),
    ],
)
def test_cli_refuses_bad_heat_pump_inputs(args, fragments, tmp_path):
    res = runner.invoke(app, ["cycle", "run", "--luts", str(tmp_path), "--topology", "hp", *args])
    one_error_line(res, *fragments)


def test_cli_refuses_heating_loop_inputs_in_other_circuits(tmp_path):
    res = runner.invoke(app, ["cycle", "run", "--luts", str(tmp_path), "--t-coolant-h", "40"])
    one_error_line(res, "--t-coolant-h: not an input of the cabin topology")


@pytest.mark.parametrize(
    "meaning",
    ["coolant_inlet_not_colder_than_refrigerant_inlet", "coolant_inlet_not_colder_than_refrigerant_saturation"],
)
def test_wcc_nodes_without_heat_flow_take_their_limits(meaning):
    """A WCC LUT's nodes where no heat leaves the refrigerant (this bench's status 3, or the wider
    rule of LUTs written before it solved desuperheating-only states) read capacity ratio 0, the
    inlet pressure less the drop of the nearest colder-coolant node, and that node's heat rate."""
    import xarray as xr

    from evtms.cycle.tables import not_condensing_fill

    status = np.array([[0, 11, 3], [0, 3, 3]], np.int8)
    attrs = {"flag_values": np.array([0, 3, 11], np.int8), "flag_meanings": f"valid {meaning} valid_x"}
    dims = ("p_in", "T_coolant_in")
    nan = np.nan
    ds = xr.Dataset(
        {
            "status": (dims, status, attrs),
            "dp": (dims, [[1e3, 2e3, nan], [3e3, nan, nan]]),
        },
        coords={"p_in": [1.0e6, 1.2e6], "T_coolant_in": [290.0, 300.0, 310.0]},
    )
    tables = {
        "capacity_ratio": np.array([[2.0, 0.5, nan], [3.0, nan, nan]]),
        "p_out": np.array([[0.999e6, 0.998e6, nan], [1.197e6, nan, nan]]),
        "Q": np.array([[900.0, 400.0, nan], [1200.0, nan, nan]]),
    }
    out = not_condensing_fill(ds, "wcc", dims, tables)
    np.testing.assert_array_equal(out["capacity_ratio"], [[2.0, 0.5, 0.0], [3.0, 0.0, 0.0]])
    np.testing.assert_array_equal(out["p_out"], [[0.999e6, 0.998e6, 0.998e6], [1.197e6, 1.197e6, 1.197e6]])
    np.testing.assert_array_equal(out["Q"], [[900.0, 400.0, 400.0], [1200.0, 1200.0, 1200.0]])
