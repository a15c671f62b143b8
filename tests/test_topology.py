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
        ({"T_coolant_in": "30"}, "cabin", "--t-coolant: not an input of the cabin topology"),
        ({"blower": "0.5"}, "chiller", "--blower: not an input of the chiller topology"),
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
