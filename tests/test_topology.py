"""Circuit topologies: their declared inputs, parsing of command-line values, and the CLI around them."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from evtms.cli import app
from evtms.cycle.topology import INPUTS, TOPOLOGIES, parse_inputs, topology
from evtms.errors import EvtmsInputError

runner = CliRunner()


def test_each_topology_uses_its_branches_inputs_only():
    assert TOPOLOGIES["cabin"].inputs == (
        "speed",
        "fan",
        "blower",
        "T_amb",
        "RH_amb",
        "T_cabin",
        "RH_cabin",
        "superheat",
        "subcooling",
    )
    chiller = TOPOLOGIES["chiller"].inputs
    assert "blower" not in chiller and "T_cabin" not in chiller
    assert {"mdot_coolant", "T_coolant_in"} <= set(chiller)
    both = TOPOLOGIES["cabin+chiller"]
    assert set(both.inputs) == set(TOPOLOGIES["cabin"].inputs) | set(chiller)
    assert both.parallel and not TOPOLOGIES["chiller"].parallel
    assert both.components == ("condenser", "evaporator", "chiller", "expansion_valve", "compressor")


def test_parse_inputs_defaults_units_and_ranges():
    grid = parse_inputs({"T_coolant_in": "25,35", "speed": "0.2:1:5"}, topology("chiller"), 1000)
    assert grid["T_coolant_in"] == [298.15, 308.15]
    assert grid["speed"] == [0.2, 0.4, 0.6, 0.8, 1.0]
    assert grid["mdot_coolant"] == [INPUTS["mdot_coolant"].default]
    assert set(grid) == set(TOPOLOGIES["chiller"].inputs)


@pytest.mark.parametrize(
    ("texts", "circuit", "message"),
    [
        ({"T_coolant_in": "30"}, "cabin", "`T_coolant_in`: not an input of the cabin topology"),
        ({"blower": "0.5"}, "chiller", "`blower`: not an input of the chiller topology"),
        ({"mdot_coolant": "0"}, "chiller", "mdot_coolant = 0 is not allowed; allowed: 0 < mdot_coolant <= 2 kg s-1"),
        ({"T_coolant_in": "70"}, "chiller", "T_coolant_in = 70 degC is not allowed; allowed: -20 to 60 degC"),
        ({"speed": "0.5,0.4"}, "cabin", "speed values must be strictly increasing"),
        ({"speed": "0.1:1:1e9"}, "cabin", "is above the limit of 1,000"),
    ],
)
def test_parse_inputs_refuses_with_one_line(texts, circuit, message):
    with pytest.raises(EvtmsInputError) as err:
        parse_inputs(texts, topology(circuit), 1000)
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_unknown_topology_is_refused():
    with pytest.raises(EvtmsInputError, match="allowed: cabin, chiller, cabin\\+chiller"):
        topology("heat-pump")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--topology", "heat-pump"], "error: topology 'heat-pump' is unknown; allowed: cabin, chiller, cabin+chiller"),
        (["--t-coolant", "30"], "error: --t-coolant: not an input of the cabin topology"),
        (["--topology", "chiller", "--blower", "0.3"], "error: --blower: not an input of the chiller topology"),
        (["--topology", "chiller", "--coolant-flow", "-1"], "error: mdot_coolant = -1 is not allowed"),
    ],
)
def test_cli_refuses_inputs_of_another_topology(args, message, tmp_path):
    res = runner.invoke(app, ["cycle", "run", "--direct", *args])
    assert res.exit_code == 2
    assert res.stderr.strip().startswith(message), res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert res.stdout == ""


# -- physics of the circuits (direct bench physics) ------------------------------------
@pytest.fixture(scope="module")
def circuits():
    """Direct solutions of the same operating points in each circuit (coolant at 25 and 35 degC; the
    WCC's at its 0.2 kg/s default and 25 degC, colder than the cabin circuits condense)."""
    import numpy as np

    from evtms.cycle import OperatingPoints, run_cycle

    points = OperatingPoints(
        speed=[0.5, 0.5, 0.8],
        fan=0.6,
        blower=0.4,
        T_amb=303.15,
        T_cabin=300.15,
        mdot_coolant=[0.15, 0.15, 0.3],
        T_coolant_in=[298.15, 308.15, 303.15],
        T_coolant_h_in=298.15,
    )
    return points, {name: run_cycle(points, circuit=name) for name in TOPOLOGIES}, np


def test_every_circuit_closes_its_energy_balance(circuits):
    _, results, np = circuits
    for name, r in results.items():
        assert (r["status"] == 0).all(), (name, r["reason"])
        # Q_cond = |Q_evap| + |Q_chiller| + W_fluid, each term from its own component.
        assert np.abs(r["balance_relative"]).max() < 1e-4, name
        assert np.allclose(r["mdot_evap"] + r["mdot_chiller"], r["mdot"], rtol=1e-12), name


def test_branch_heat_flows_belong_to_their_branches(circuits):
    _, results, np = circuits
    assert (results["cabin"]["Q_chiller"] == 0).all() and (results["cabin"]["Q_evap"] < 0).all()
    assert (results["chiller"]["Q_evap"] == 0).all() and (results["chiller"]["Q_latent"] == 0).all()
    assert (results["chiller"]["Q_chiller"] < 0).all()
    both = results["cabin+chiller"]
    assert (both["Q_evap"] < 0).all() and (both["Q_chiller"] < 0).all()
    assert np.isnan(results["cabin"]["valve_opening_chiller"]).all()


def test_both_branches_leave_at_the_setpoint_superheat(circuits):
    """At the suction root each branch's outlet is the suction state (both valves hold 10 K)."""
    _, results, np = circuits
    both = results["cabin+chiller"]
    assert np.allclose(both["h_A_evap"], both["h_A"], atol=0.5)  # J/kg: the mix of the two outlets


def test_a_second_evaporating_branch_raises_suction_pressure_and_cooling(circuits):
    """More evaporator surface for one compressor: it evaporates warmer and pumps more."""
    _, results, np = circuits
    cabin, both = results["cabin"], results["cabin+chiller"]
    assert (both["p_A"] > cabin["p_A"]).all()
    assert (both["mdot"] > cabin["mdot"]).all()
    assert (-(both["Q_evap"] + both["Q_chiller"]) > -cabin["Q_evap"]).all()
    # The cabin branch alone gets less flow than the whole circuit had: less cabin cooling.
    assert (-both["Q_evap"] < -cabin["Q_evap"]).all()


def test_warmer_coolant_takes_more_of_the_flow_and_the_heat(circuits):
    _, results, np = circuits
    chiller, both = results["chiller"], results["cabin+chiller"]
    # Points 0 and 1: coolant 25 -> 35 degC at the same speed and coolant flow.
    assert chiller["p_A"][1] > chiller["p_A"][0]
    assert chiller["Q_chiller"][1] < chiller["Q_chiller"][0]  # more negative: more battery cooling
    share = both["mdot_chiller"] / both["mdot"]
    assert share[1] > share[0]
    assert both["Q_evap"][1] > both["Q_evap"][0]  # the cabin gets less


def test_cycle_format_doc_lists_every_input_variable_and_status():
    """docs/cycle-format.md is the contract of the sweep file: nothing the code writes is missing."""
    from pathlib import Path

    from evtms.cycle.api import RESULT_VARIABLES
    from evtms.cycle.solver import CYCLE_FLAGS

    doc = (Path(__file__).resolve().parents[1] / "docs" / "cycle-format.md").read_text(encoding="utf-8")
    for name in [*INPUTS, *RESULT_VARIABLES, "status", "reason"]:
        assert f"| `{name}` |" in doc, name
    for meaning in CYCLE_FLAGS.values():
        assert f"`{meaning}`" in doc, meaning
    for name in TOPOLOGIES:
        assert f"`{name}`" in doc, name


def test_lut_circuits_match_the_direct_physics(circuits, cycle_luts_dir):
    """The chiller circuits on the cycle LUTs against the bench physics (docs/guide/cycle.md: accuracy per topology)."""
    from evtms.cycle import load_cycle_luts, run_cycle

    points, results, np = circuits
    # Measured: every figure within 0.32 % (pressures, flow, work, COP; branch heat flows as a
    # share of the total cooling) at these three points; 0.57 % with the outlet enthalpy itself
    # interpolated instead of its approach to the coolant (evtms.cycle.approach).
    for name, tol in (("chiller", 0.005), ("cabin+chiller", 0.005)):
        lut = run_cycle(points, load_cycle_luts(cycle_luts_dir, name), circuit=name)
        direct = results[name]
        assert (lut["status"] == 0).all(), lut["reason"]
        for key in ("p_A", "p_B", "mdot", "W", "COP"):
            assert np.allclose(lut[key], direct[key], rtol=tol), (name, key, lut[key], direct[key])
        total = -(direct["Q_evap"] + direct["Q_chiller"])
        for key in ("Q_evap", "Q_chiller"):
            assert np.all(np.abs(lut[key] - direct[key]) <= tol * total), (name, key, lut[key], direct[key])
        assert np.abs(lut["balance_relative"]).max() < 1e-4
