"""The condensing chain ``cabin+wcc``: the WCC ahead of the front condenser, in series, on physics and on LUTs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.cli import app
from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
from evtms.cycle.solver import VALID_CYCLE_FLAGS
from evtms.cycle.topology import TOPOLOGIES

runner = CliRunner()

#: A cabin at 27 degC against a 35 degC ambient; the WCC's coolant at 0.05 / 0.2 / 0.36 kg/s and 28 degC,
#: then at 0.2 kg/s and 22 degC.
FLOWS = (0.05, 0.2, 0.36, 0.2)
T_COOLANT = (301.15, 301.15, 301.15, 295.15)


def _points(**over) -> OperatingPoints:
    n = len(FLOWS)
    values = {
        "speed": 0.6,
        "fan": 0.5,
        "blower": 0.4,
        "T_amb": 308.15,
        "RH_amb": 0.4,
        "T_cabin": 300.15,
        "RH_cabin": 0.5,
        "mdot_coolant_h": np.array(FLOWS),
        "T_coolant_h_in": np.array(T_COOLANT),
        "superheat": 10.0,
    } | over
    return OperatingPoints(**{k: np.broadcast_to(np.asarray(v, float), (n,)).copy() for k, v in values.items()})


@pytest.fixture(scope="module")
def chain():
    return run_cycle(_points(), circuit="cabin+wcc")


@pytest.fixture(scope="module")
def cabin_alone():
    pts = _points()
    inputs = {k: getattr(pts, k) for k in TOPOLOGIES["cabin"].inputs if k != "subcooling"}
    return run_cycle(OperatingPoints(**inputs), circuit="cabin")


def test_the_chain_is_declared_wcc_first():
    circuit = TOPOLOGIES["cabin+wcc"]
    assert [c.component for c in circuit.chain] == ["wcc", "condenser"]
    assert circuit.condensing.component == "condenser"  # the receiver holds the condenser's outlet
    assert circuit.components == ("wcc", "condenser", "evaporator", "expansion_valve", "compressor")
    assert {"fan", "T_amb", "mdot_coolant_h", "T_coolant_h_in", "blower", "T_cabin"} <= set(circuit.inputs)


def test_the_chain_closes_its_energy_balance_and_splits_the_heat(chain):
    assert np.isin(chain["status"], VALID_CYCLE_FLAGS).all(), chain["reason"]
    assert np.all(np.abs(chain["balance_relative"]) < 1e-5)
    q_in = -chain["Q_evap"] + chain["W_fluid"]
    np.testing.assert_allclose(chain["Q_cond"], q_in, rtol=1e-5)
    # Both condense: the WCC takes a share, the condenser the rest.
    assert np.all(chain["Q_wcc"] > 0) and np.all(chain["Q_wcc"] < chain["Q_cond"])
    # The WCC's share is mdot (h_B - h at its outlet): between the discharge and the liquid line.
    assert np.all(chain["Q_wcc"] < chain["mdot"] * (chain["h_B"] - chain["h_C"]))


def test_more_or_colder_coolant_takes_more_heat_and_lowers_the_discharge(chain):
    q, p_b = chain["Q_wcc"], chain["p_B"]
    assert q[0] < q[1] < q[2] and p_b[0] > p_b[1] > p_b[2]  # more coolant flow
    assert q[3] > q[1] and p_b[3] < p_b[1]  # colder coolant


def test_the_wcc_ahead_beats_the_condenser_alone(chain, cabin_alone):
    """A second heat sink colder than the condensing refrigerant lowers the discharge pressure, so the
    compressor works less and the cycle's COP rises (the same cabin load, about the same cooling)."""
    assert np.isin(cabin_alone["status"], VALID_CYCLE_FLAGS).all()
    assert np.all(chain["p_B"] < cabin_alone["p_B"])
    assert np.all(chain["W"] < cabin_alone["W"])
    assert np.all(chain["COP"] > cabin_alone["COP"])
    assert np.all(cabin_alone["Q_wcc"] == 0.0)


def test_a_coolant_warmer_than_the_condensing_refrigerant_only_desuperheats():
    """With its coolant at 45 and 60 degC against refrigerant condensing near 42-43 degC the WCC only
    desuperheats the discharge gas (less heat the warmer the coolant, the condenser condensing all
    of it below the coolant's temperature); at 85 degC, warmer than the 67 degC discharge, it takes
    nothing and the circuit is the condenser alone."""
    from evtms.fluid import Fluid

    warm = [run_cycle(_points(T_coolant_h_in=t, speed=0.2), circuit="cabin+wcc") for t in (318.15, 333.15, 358.15)]
    pts = _points(speed=0.2)
    alone = run_cycle(
        OperatingPoints(**{k: getattr(pts, k) for k in TOPOLOGIES["cabin"].inputs if k != "subcooling"}),
        circuit="cabin",
    )
    for res in (*warm, alone):
        assert np.isin(res["status"], VALID_CYCLE_FLAGS).all(), res["reason"]
    t_sat = [Fluid("R134a").saturation(res["p_B"])["T"] for res in warm[:2]]
    assert np.all(t_sat[0] < 318.15) and np.all(t_sat[1] < 333.15)
    assert np.all(warm[0]["Q_wcc"] > warm[1]["Q_wcc"]) and np.all(warm[1]["Q_wcc"] > 0)
    assert np.all(warm[0]["p_B"] < warm[1]["p_B"]) and np.all(warm[1]["p_B"] < alone["p_B"])
    assert np.all(warm[2]["T_B"] < 358.15) and np.all(warm[2]["Q_wcc"] == 0.0)
    for key in ("p_B", "p_A", "Q_cond", "COP"):
        np.testing.assert_allclose(warm[2][key], alone[key], rtol=1e-12, err_msg=key)


def test_the_chain_on_luts_follows_the_physics(cycle_luts_dir, chain):
    """On the cycle grid's LUTs (the condenser's two-phase inlets scaled, the WCC's heat rate
    interpolated) the chain lands within 0.1 % of the bench physics at these points."""
    lut = run_cycle(_points(), load_cycle_luts(cycle_luts_dir, "cabin+wcc"), circuit="cabin+wcc")
    assert (lut["status"] == chain["status"]).all(), lut["reason"]
    for name in ("p_A", "p_B", "Q_cond", "Q_wcc", "COP"):
        np.testing.assert_allclose(lut[name], chain[name], rtol=1e-3, err_msg=name)
    assert np.all(np.abs(lut["balance_relative"]) < 1e-6)


def test_the_chain_on_luts_follows_the_physics_at_its_edges(cycle_luts_dir):
    """Where the WCC's coolant is warmer than the condensing refrigerant (it only desuperheats, and
    the LUT cells straddle the coolant passing the saturation), and where the condenser behind it
    condenses a kelvin or two above the air (cells holding nodes on the air's wrong side), the LUT
    cycle still lands within 1 % of the physics (measured: 0.7 % worst, the COP at 45 degC)."""
    pts = _points(T_coolant_h_in=np.array([318.15, 333.15, 289.0, 291.0]), speed=0.2)
    pts.T_amb[2:] = (295.5, 296.5)
    pts.mdot_coolant_h[2:] = 0.2
    direct = run_cycle(pts, circuit="cabin+wcc")
    lut = run_cycle(pts, load_cycle_luts(cycle_luts_dir, "cabin+wcc"), circuit="cabin+wcc")
    assert np.isin(direct["status"], VALID_CYCLE_FLAGS).all(), direct["reason"]
    assert (lut["status"] == direct["status"]).all(), lut["reason"]
    for name in ("p_A", "p_B", "Q_cond", "COP"):
        np.testing.assert_allclose(lut[name], direct[name], rtol=1e-2, err_msg=name)
    np.testing.assert_allclose(lut["Q_wcc"], direct["Q_wcc"], rtol=0.0, atol=1e-2 * direct["Q_cond"].min())


def test_only_the_chain_reads_the_condensers_two_phase_inlets(cycle_luts_dir):
    """A lone condenser's discharge is superheated: its tables start at the first superheated node."""
    from evtms.benches.condenser import SUPERHEATED_INLETS, TWO_PHASE_INLETS
    from evtms.cycle.api import saturation_curve
    from evtms.cycle.models import LutModels

    luts = load_cycle_luts(cycle_luts_dir, "cabin+wcc")
    alone = LutModels(luts, TOPOLOGIES["cabin"].components)
    assert alone.luts["condenser"].ranges["h_in"][0] == SUPERHEATED_INLETS[0]
    chained = LutModels(luts, TOPOLOGIES["cabin+wcc"].components, saturation=saturation_curve(luts))
    assert chained.luts["condenser"].ranges["h_in"][0] == TWO_PHASE_INLETS[0]


def test_cli_runs_the_chain_on_the_physics_and_on_luts(cycle_luts_dir):
    args = ["cycle", "run", "--topology", "cabin+wcc", "--t-amb", "35", "--t-coolant-h", "28", "--json"]
    out = {}
    for source in (["--direct"], ["--luts", str(cycle_luts_dir)]):
        res = runner.invoke(app, [*args, *source])
        assert res.exit_code == 0, res.output
        out[source[0]] = json.loads(res.output)
        assert out[source[0]]["topology"] == "cabin+wcc" and 0 < out[source[0]]["Q_wcc"] < out[source[0]]["Q_cond"]
    assert out["--luts"]["states"]["B"]["p"] == pytest.approx(out["--direct"]["states"]["B"]["p"], rel=1e-3)


def test_a_subcooled_target_is_the_chains_outlet(chain):
    """With 3 K of subcooling asked the chain's outlet (the condenser's) leaves 3 K below its saturation,
    at a higher discharge pressure than with a saturated outlet (more area for the liquid)."""
    from evtms.fluid import Fluid

    sub = run_cycle(_points(subcooling=3.0), circuit="cabin+wcc")
    assert np.isin(sub["status"], VALID_CYCLE_FLAGS).all(), sub["reason"]
    T_sat = Fluid("R134a").saturation_curve().temperature(sub["p_C"])
    np.testing.assert_allclose(T_sat - sub["T_C"], 3.0, atol=0.05)
    assert np.all(sub["p_B"] > chain["p_B"]) and np.all(np.abs(sub["balance_relative"]) < 1e-5)
