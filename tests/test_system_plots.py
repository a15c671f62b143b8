"""System-simulation figures: files written, the consumption stack closes, bad input is one line, exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from evtms.cli import app
from evtms.errors import EvtmsInputError
from evtms.reports.system_plots import (
    CONSUMPTION_PARTS,
    mode_spans,
    range_data,
    range_figure,
    simulation_data,
    simulation_figure,
)
from evtms.system.output import to_dataset
from evtms.system.simulate import RECORD_VARIABLES, SimulationResult

runner = CliRunner()


def _result(T_amb: float, n: int = 61, stop: int | None = None) -> SimulationResult:
    """A made-up run at ``T_amb`` [K]: n records 1 s apart; the energies of its summary close exactly."""
    rng = np.random.default_rng(int(T_amb))
    time = np.arange(float(stop or n))
    records = {name: 300.0 + rng.random(time.size) for name in RECORD_VARIABLES}
    records["time"] = time
    records["speed"] = 10.0 * np.sin(time / 20.0) ** 2
    records["SOC"] = 0.9 - 1e-4 * time
    for name in ("P_compressor", "P_ptc", "P_heater", "P_blower", "P_fan", "P_pump"):
        records[name] = 100.0 * rng.random(time.size)
    records["P_hvac"] = sum(records[k] for k in ("P_compressor", "P_ptc", "P_heater", "P_blower", "P_fan", "P_pump"))
    for name in records:
        if name.startswith(("P_", "Q_")):
            records[name][0] = np.nan
    mode = (np.arange(time.size) // 10 % 8).astype(np.int8)
    # Energies [kWh] with a cold-weather heating share; the chemical energy is their exact sum.
    parts = {
        "motor_energy_kWh": 2.0 + 0.01 * rng.random(),
        "hvac_cabin_kWh": 1.0 + abs(T_amb - 295.0) / 40.0,
        "battery_thermal_kWh": 0.5 * rng.random(),
        "aux_energy_kWh": 0.125,
        "battery_loss_kWh": 0.1 * rng.random(),
    }
    chemical = sum(parts.values())
    distance = 23.0 + rng.random()
    summary = {
        "distance_km": distance,
        "battery_chemical_kWh": chemical,
        "hvac_energy_kWh": parts["hvac_cabin_kWh"] + parts["battery_thermal_kWh"],
        **parts,
        "soc_end": float(records["SOC"][-1]),
        "consumption_kWh_per_100km": chemical / distance * 100.0,
        "range_km": 50.0 / chemical * distance,
        "T_amb_degC": T_amb - 273.15,
    }
    attrs = {
        "scenario": "",
        "cycle": "testcycle",
        "T_amb": T_amb,
        "termination": "end of cycle",
        "parameters": json.dumps({"cabin": {"T_set": 295.15}}),
        "ledgers": json.dumps({"cabin": 0.0}),
    }
    return SimulationResult(records, mode, np.zeros(time.size, np.uint16), {"cabin": 0.0}, summary, attrs)


AMBIENTS = (263.15, 278.15, 298.15, 313.15)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A single run, a sweep over four ambients (the last stopped early) and a LUT-like file, on disk."""
    folder = tmp_path_factory.mktemp("sim")
    single = to_dataset([_result(303.15)])
    sweep = to_dataset([_result(T, stop=40 if T == AMBIENTS[-1] else None) for T in AMBIENTS])
    paths = {"run": folder / "run.nc", "sweep": folder / "sweep.nc", "lut": folder / "lut.nc"}
    single.to_netcdf(paths["run"], engine="netcdf4")
    sweep.to_netcdf(paths["sweep"], engine="netcdf4")
    xr.Dataset({"Q": ("mdot", np.ones(3))}, coords={"mdot": [0.01, 0.02, 0.03]}).to_netcdf(paths["lut"])
    single.drop_vars("T_coolant").to_netcdf(folder / "missing.nc", engine="netcdf4")
    paths["missing"] = folder / "missing.nc"
    return paths, single, sweep


def _invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_figures_written(tmp_path, files, suffix):
    paths, single, sweep = files
    for path, made in (
        (tmp_path / f"run{suffix}", lambda p: simulation_figure(single, p)),
        (tmp_path / f"cold{suffix}", lambda p: simulation_figure(sweep, p, t_amb=263.15)),
        (tmp_path / f"range{suffix}", lambda p: range_figure(sweep, p)),
    ):
        assert made(path) == path
        assert path.stat().st_size > 1000
    res = _invoke("report", "simulation", paths["sweep"], "-o", tmp_path / "sub" / f"c{suffix}", "--t-amb", "5")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "sub" / f"c{suffix}").stat().st_size > 1000
    out = tmp_path / f"r{suffix}"
    res = _invoke("report", "range", paths["sweep"], "-o", out, "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout) == {"path": str(out)} and out.stat().st_size > 1000


def test_simulation_data_units_and_selection(files):
    _, single, sweep = files
    d = simulation_data(sweep, t_amb=298.15)
    assert d["T_amb"] == pytest.approx(25.0) and d["T_set"] == pytest.approx(22.0)
    assert d["summary"]["T_amb_degC"] == pytest.approx(25.0)
    run = sweep.isel(T_amb=2)
    np.testing.assert_allclose(d["speed"], run["speed"].values * 3.6)
    np.testing.assert_allclose(d["T_battery"], run["T_battery"].values - 273.15)
    np.testing.assert_allclose(d["time_min"], run["time"].values / 60.0)
    np.testing.assert_allclose(sum(d["hvac_parts"].values())[1:], d["P_hvac"][1:], rtol=1e-12)
    assert "testcycle at 25 degC" in d["title"]
    assert simulation_data(single)["T_amb"] == pytest.approx(30.0)
    # A run that stopped early: its padded records (mode -1) have no mode band.
    stopped = simulation_data(sweep, t_amb=313.15)
    spans = mode_spans(stopped["time_min"], stopped["mode"])
    assert spans[-1][2] == pytest.approx(39 / 60.0) and all(code >= 0 for code, _, _ in spans)


def test_mode_spans():
    t = np.arange(6.0)
    assert mode_spans(t, np.array([3, 3, 3, 1, 1, -1])) == [(3, 0.0, 2.0), (1, 2.0, 4.0)]


def test_range_stack_sums_to_total(files):
    _, _, sweep = files
    d = range_data(sweep)
    np.testing.assert_allclose(d["T_amb"], np.array(AMBIENTS) - 273.15)
    stack = sum(d["parts"].values())
    np.testing.assert_allclose(stack, d["total"], rtol=1e-9, atol=0)
    assert d["closure"] < 1e-9 and np.all(np.abs(d["other"]) <= 1e-9 * d["total"])
    assert list(d["parts"]) == list(CONSUMPTION_PARTS)
    # From the summaries themselves: the five uses make the chemical energy.
    for s in json.loads(sweep.attrs["summary"]):
        five = sum(s[k] for k in CONSUMPTION_PARTS.values())
        assert five == pytest.approx(s["battery_chemical_kWh"], rel=1e-9)
        assert five / s["distance_km"] * 100 == pytest.approx(s["consumption_kWh_per_100km"], rel=1e-9)


def test_library_errors(files, tmp_path):
    _, single, sweep = files
    with pytest.raises(EvtmsInputError, match="single run"):
        range_figure(single, tmp_path / "r.png")
    with pytest.raises(EvtmsInputError, match="not in the file"):
        simulation_figure(sweep, tmp_path / "s.png", t_amb=300.0)
    assert list(tmp_path.iterdir()) == []


CLI_ERRORS = [
    (("range", "run"), "evtms simulate --t-amb a:b:n"),
    (("simulation", "missing"), "T_coolant"),
    (("range", "lut"), "not an evtms simulation output"),
    (("simulation", "lut"), "not an evtms simulation output"),
    (("simulation", "sweep", "--t-amb", "12"), "allowed: -10, 5, 25, 40 degC"),
    (("simulation", "run", "--t-amb", "20"), "allowed: 30 degC"),
]


@pytest.mark.parametrize(("args", "message"), CLI_ERRORS)
def test_cli_errors_one_line_exit_2_no_file(tmp_path, files, args, message):
    paths, _, _ = files
    out = tmp_path / "new" / "fig.png"
    command, name, *rest = args
    res = _invoke("report", command, paths[name], "-o", out, *rest)
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], res.stderr
    assert "Traceback" not in res.output and res.stdout == ""
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_cli_not_netcdf_and_bad_suffix(tmp_path, files):
    paths, _, _ = files
    text = tmp_path / "notes.nc"
    text.write_text("not netCDF\n")
    res = _invoke("report", "simulation", text, "-o", tmp_path / "f.png")
    assert res.exit_code == 2 and res.stderr.startswith("error: ") and "not a readable simulation file" in res.stderr
    res = _invoke("report", "range", paths["sweep"], "-o", tmp_path / "f.pdf")
    assert res.exit_code == 2 and ".png or .svg" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.nc"]
