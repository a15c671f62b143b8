"""The Python API (evtms.workflows, re-exported by evtms): the same checks and results as the CLI.

A cycle point on the session's cycle LUTs and a WLTC simulation on the small-axis cycle maps
(conftest) run through the API and through the command line with the same inputs: the physics
holds (the cycle's first law, the simulation's energy ledgers) and both give the same numbers.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import xarray as xr
from conftest import one_error_line
from typer.testing import CliRunner

import evtms
from evtms.cli import _json_safe, app
from evtms.errors import EvtmsInputError
from evtms.workflows import (
    BenchRequest,
    CompareRequest,
    CycleRequest,
    SimulationRequest,
    run_bench,
    run_comparison,
    run_cycle,
    run_simulation,
)

runner = CliRunner()


def cli(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_import_stays_cheap_and_the_names_resolve():
    code = (
        "import sys, evtms; assert not [m for m in sys.modules if m.startswith('evtms.')], sys.modules;"
        "import evtms.workflows.cycle as c; assert evtms.run_cycle is c.run_cycle; print('ok')"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == "ok"
    assert evtms.CycleRequest is CycleRequest
    with pytest.raises(AttributeError):
        evtms.no_such_workflow  # noqa: B018


@pytest.mark.parametrize(
    ("call", "message", "argv", "shown"),
    [
        (
            lambda tmp: run_simulation(SimulationRequest(cycle="wltc3b", t_amb=30, soak_cabin=100.0)),
            "`soak_cabin` 100 is not allowed; allowed: -40 to 90 degC",
            ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--soak-cabin", "100", "-o", "x.nc"],
            "--soak-cabin 100 is not allowed; allowed: -40 to 90 degC",
        ),
        (
            lambda tmp: run_comparison(CompareRequest(cycle="wltc3b", t_amb=30, output=tmp, repeat=0)),
            "`repeat` 0 is not allowed; allowed: 1 to 20",
            ["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "-o", "c", "--repeat", "0"],
            "--repeat 0 is not allowed; allowed: 1 to 20",
        ),
        (
            lambda tmp: run_comparison(CompareRequest(cycle="wltc3b", t_amb=30, output=tmp, fmt="jpg")),
            "`fmt` 'jpg' is unknown; allowed: png, svg",
            ["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "-o", "c", "--format", "jpg"],
            "--format 'jpg' is unknown; allowed: png, svg",
        ),
        (
            lambda tmp: run_bench(BenchRequest(["condenser"], workers=2, scheduler="tcp://localhost:1")),
            "give `workers` or `scheduler`, not both",
            ["bench", "condenser", "--workers", "2", "--scheduler", "tcp://localhost:1"],
            "give --workers or --scheduler, not both",
        ),
    ],
)
def test_a_python_caller_gets_the_checks_of_the_command_line(tmp_path, monkeypatch, call, message, argv, shown):
    """The request is refused before any work, naming the field; the CLI names the option instead."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(EvtmsInputError) as exc:
        call(tmp_path / "out")
    assert str(exc.value) == message
    assert one_error_line(cli(*argv), shown) == f"error: {shown}"
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written


POINT = {"speed": 0.6, "fan": 0.5, "blower": 0.4, "T_amb": 30, "T_cabin": 27}


def test_a_cycle_point_closes_its_energy_balance_and_is_what_the_cli_prints(cycle_luts_dir):
    p = run_cycle(CycleRequest(inputs=POINT, luts=cycle_luts_dir))
    v = p.values
    assert p.status_meaning == "converged" and p.models == str(cycle_luts_dir)
    assert p.inputs["T_amb"] == pytest.approx(303.15) and p.inputs["speed"] == 0.6
    # First law over the circuit, each term from its own LUT: Q_cond + Q_evap - W_fluid (Q_evap < 0).
    residual = v["Q_cond"] + v["Q_evap"] - v["W_fluid"]
    assert residual == pytest.approx(v["balance_residual"], abs=1e-9)
    assert abs(v["balance_relative"]) < 0.005
    assert v["Q_cond"] > -v["Q_evap"] > 0 and v["COP"] == pytest.approx(-v["Q_evap"] / v["W"], rel=1e-9)
    assert v["h_D"] == pytest.approx(v["h_C"], abs=1e-6)  # the valve is isenthalpic
    assert v["p_B"] > v["p_A"] and v["T_B"] > v["T_C"]
    # The command line with the same inputs prints the same numbers.
    r = cli("cycle", "run", "--luts", cycle_luts_dir, "--speed", "0.6", "--fan", "0.5", "--blower", "0.4",
            "--t-amb", "30", "--t-cabin", "27", "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    shown = json.loads(r.stdout)
    assert shown["inputs"] == p.inputs and shown["status"] == p.status
    assert {s: shown["states"][s]["h"] for s in "ABCD"} == {s: v[f"h_{s}"] for s in "ABCD"}
    for key in ("mdot", "Q_evap", "Q_cond", "W", "COP", "balance_residual"):
        assert shown[key] == v[key], key


def test_a_simulation_closes_its_ledgers_and_is_what_the_cli_writes(small_map_luts, small_maps, tmp_path):
    out = tmp_path / "api.nc"
    run = run_simulation(SimulationRequest(output=out, cycle="wltc3b", t_amb=35.0, luts=small_map_luts))
    (result,) = run.results
    s = result.summary
    assert run.path == out and s["wall_time_s"] == run.wall_time_s
    assert s["steps"] == 1800 and s["distance_km"] == pytest.approx(23.27, abs=0.005)
    assert s["ledger_worst"] <= 1e-9  # every energy ledger of the loop closes
    assert 0.0 < s["hvac_energy_kWh"] < s["battery_energy_kWh"] < s["battery_chemical_kWh"]
    assert s["T_cabin_end_degC"] < 35.0  # the cabin was cooled below the ambient
    with xr.open_dataset(out) as written:
        xr.testing.assert_identical(written["T_cabin"].load(), run.dataset()["T_cabin"])
    # The command line with the same inputs writes the same run.
    r = cli("simulate", "--cycle", "wltc3b", "--t-amb", "35", "--luts", small_map_luts, "-o", tmp_path / "cli.nc",
            "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    shown = json.loads(r.stdout)
    timing = {k for k in s if k.endswith("_time_s")}
    assert {k: v for k, v in shown.items() if k not in timing} == _json_safe(
        {k: v for k, v in s.items() if k not in timing}
    )
    with xr.open_dataset(out) as a, xr.open_dataset(tmp_path / "cli.nc") as b:
        for name in ("T_cabin", "T_battery", "SOC", "P_hvac", "mode"):
            xr.testing.assert_equal(a[name], b[name])
