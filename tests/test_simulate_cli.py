"""`evtms simulate` end to end on cycle maps built from the session's cycle LUTs (small map axes).

The map axes are cut to 2-3 nodes each (``refrigerant.map_settings`` patched)
so that the maps build in seconds; the command, its output file, its JSON and
its errors are what a user gets.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import SMALL_MAP_AXES, one_error_line
from typer.testing import CliRunner

from evtms.cli import app

JSON_FIELDS = {
    "distance_km",
    "duration_s",
    "traction_energy_kWh",
    "battery_energy_kWh",
    "battery_chemical_kWh",
    "hvac_energy_kWh",
    "soc_end",
    "T_cabin_end_degC",
    "T_battery_end_degC",
    "wall_time_s",
    "loop_time_s",
    "steps",
}
runner = CliRunner()


@pytest.fixture()
def luts(small_map_luts):
    """The session's cycle LUTs, with the small-axis maps built once and shared (conftest)."""
    return small_map_luts


@pytest.fixture(autouse=True)
def _small_maps(small_maps):
    """Every test here builds its maps on the small axes (conftest's ``small_maps``)."""


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_wltc_at_30_degC_json_and_file(luts, tmp_path):
    out = tmp_path / "run.nc"
    r = run("simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", luts, "-o", out, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert JSON_FIELDS <= set(s)
    assert s["distance_km"] == pytest.approx(23.27, abs=0.005)
    assert s["steps"] == 1800 and s["termination"] == "end of cycle"
    assert s["ledger_worst"] <= 1e-9
    assert 0.0 < s["battery_energy_kWh"] < s["battery_chemical_kWh"]
    assert s["soc_end"] < 0.9
    with xr.open_dataset(out) as ds:
        assert ds["time"].size == 1801
        assert ds["T_cabin"].attrs["units"] == "K"
        assert ds["mode"].attrs["flag_meanings"].startswith("off BH BC CC")
        ledgers = json.loads(ds.attrs["ledgers"])
        assert max(ledgers.values()) <= 1e-9
        assert json.loads(ds.attrs["parameters"])["battery"]["n_series"] == 96
        assert np.nanmax(ds["Q_evaporator"].values) > 500.0  # the cabin was cooled on the maps


#: Libraries a simulation on cached maps has no use for (the output is written by netCDF4, numba
#: is set up without SciPy's BLAS, figures and the cycle physics are other commands').
_NOT_NEEDED = ("xarray", "scipy", "CoolProp", "matplotlib", "dask", "pandas", "rich")

#: The command line's entry point in a fresh process, the maps on the small axes as in this
#: module's tests; prints the exit code and the libraries above that got imported.
_ENTRY_POINT = """
import dataclasses, json, sys
from evtms.workflows.common import own_process
own_process()  # as evtms.cli.main does first: the patch below imports numba before main runs
from evtms.system import refrigerant
full, axes = refrigerant.map_settings, json.loads(sys.argv[1])
refrigerant.map_settings = lambda p: dataclasses.replace(full(p), axes=axes)
sys.argv = ["evtms", *sys.argv[2:]]
from evtms.cli import main
try:
    main()
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "imported": [m for m in %r if m in sys.modules]}))
"""


def test_a_run_on_cached_maps_imports_only_what_it_needs(luts, tmp_path):
    """evtms simulate on cached maps, as a user runs it: no xarray, SciPy, CoolProp, matplotlib, dask or rich."""
    args = ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", str(luts), "--json"]
    first = run(*args, "-o", tmp_path / "first.nc")  # builds the maps if no test did yet
    assert first.exit_code == 0, first.output
    code = _ENTRY_POINT % (list(_NOT_NEEDED),)
    res = subprocess.run(
        [sys.executable, "-c", code, json.dumps(SMALL_MAP_AXES), *args, "-o", str(tmp_path / "run.nc")],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr
    summary, report = (json.loads(line) for line in res.stdout.strip().splitlines())
    assert report == {"code": 0, "imported": []}
    assert set(summary) == set(json.loads(first.stdout))
    with xr.open_dataset(tmp_path / "first.nc") as a, xr.open_dataset(tmp_path / "run.nc") as b:
        for name in a.variables:
            assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def test_scenarios_and_a_sweep_of_ambients(luts, tmp_path):
    out = tmp_path / "sweep.nc"
    r = run("simulate", "--cycle", "nedc", "--t-amb", "-10,35", "--luts", luts, "-o", out, "--json")
    assert r.exit_code == 0, r.output
    runs = json.loads(r.stdout)["runs"]
    assert [x["T_amb_degC"] for x in runs] == pytest.approx([-10.0, 35.0])
    assert runs[0]["distance_km"] == pytest.approx(11.0132, abs=5e-4)
    with xr.open_dataset(out) as ds:
        assert ds["SOC"].dims == ("T_amb", "time")
    r = run("simulate", "--scenario", "cold", "--luts", luts, "-o", tmp_path / "cold.nc", "--json")
    assert r.exit_code == 0, r.output
    cold = json.loads(r.stdout)
    assert cold["T_amb_degC"] == pytest.approx(-5.0)
    assert cold["distance_km"] == pytest.approx(16.5068, abs=5e-4)
    assert cold["T_cabin_end_degC"] > 5.0  # heated from -5 degC


def test_a_user_trace(luts, tmp_path):
    trace = tmp_path / "trace.csv"
    trace.write_text("# constant 50 km/h\ntime_s,speed_kmh\n0,0\n10,50\n600,50\n610,0\n")
    r = run("simulate", "--cycle", trace, "--t-amb", "20", "--luts", luts, "-o", tmp_path / "u.nc", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["distance_km"] == pytest.approx((5 * 50 + 590 * 50 + 5 * 50) / 3600, rel=1e-12)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--cycle", "wltc3b", "--t-amb", "30", "--dt", "0"], "--dt 0 is not allowed"),
        (["--cycle", "wltc3b"], "give --t-amb"),
        (["--cycle", "wltc3b", "--scenario", "cold", "--t-amb", "3"], "one of them"),
        (["--scenario", "desert"], "--scenario 'desert' is unknown"),
        (["--cycle", "wltc3b", "--t-amb", "30", "--mode", "heat"], "--mode 'heat' is unknown"),
        (["--cycle", "wltc3b", "--t-amb", "30", "--model", "neural"], "--model 'neural' is unknown"),
        (
            ["--cycle", "wltc3b", "--t-amb", "30", "--model", "surrogate", "--surrogates", "nosuch"],
            "--surrogates 'nosuch': no mode-model file",
        ),
        (["--cycle", "wltc3b", "--t-amb", "90"], "T_amb = 90 degC is not allowed"),
        (["--cycle", "wltc3b", "--t-amb", "30", "--precondition", "-5"], "--precondition"),
        (["--cycle", "wltc3b", "--t-amb", "30", "--dt", "0.3", "--output-every", "1"], "--output-every"),
        (["--cycle", "nosuch", "--t-amb", "30"], "nosuch"),
    ],
)
def test_bad_input_is_one_line_and_no_file(luts, tmp_path, args, message):
    out = tmp_path / "bad.nc"
    r = run("simulate", *args, "--luts", luts, "-o", out)
    one_error_line(r, message)
    assert not out.exists()


def test_bad_params_file(luts, tmp_path):
    p = tmp_path / "p.toml"
    p.write_text("[cabin]\nvolume = -1\n")
    out = tmp_path / "bad.nc"
    r = run("simulate", "--cycle", "wltc3b", "--t-amb", "30", "--params", p, "--luts", luts, "-o", out)
    assert r.exit_code == 2
    assert "[cabin] volume = -1 is not allowed" in r.stderr and "p.toml" in r.stderr
    p.write_text("[cabin]\nvolume = 2.5\n[controls]\ntau_refrigerant = 20.0\n")
    r = run("simulate", "--cycle", "wltc3b", "--t-amb", "30", "--params", p, "--luts", luts, "-o", out, "--json")
    assert r.exit_code == 0, r.output
    with xr.open_dataset(out) as ds:
        used = json.loads(ds.attrs["parameters"])
    assert used["cabin"]["volume"] == 2.5 and used["controls"]["tau_refrigerant"] == 20.0


def _short_trace(tmp_path, seconds: int = 20):
    trace = tmp_path / "short.csv"
    rows = "".join(f"{t},{min(2.0 * t, 30.0)}\n" for t in range(seconds + 1))
    trace.write_text("time_s,speed_kmh\n" + rows)
    return trace


def test_physics_model_runs_the_bench_physics_in_the_loop(luts, tmp_path):
    trace = _short_trace(tmp_path, 8)
    out = {}
    for model in ("lut", "physics"):
        r = run("simulate", "--cycle", trace, "--t-amb", "35", "--luts", luts, "--model", model, "-o",
                tmp_path / f"{model}.nc", "--json")  # fmt: skip
        assert r.exit_code == 0, r.output
        out[model] = json.loads(r.stdout)
    assert out["lut"]["physics_solves"] == 0 and out["physics"]["model"] == "physics"
    # The cabin asks for cooling from the start: the cycle is solved by the bench physics, a few times.
    assert 1 <= out["physics"]["physics_solves"] <= 8
    # Both cool the cabin from 35 degC; they differ by the LUTs and these tests' coarse maps (2-3 nodes an axis).
    for model in out:
        assert out[model]["T_cabin_end_degC"] < 34.5
    assert out["physics"]["T_cabin_end_degC"] == pytest.approx(out["lut"]["T_cabin_end_degC"], abs=1.0)
    assert out["physics"]["hvac_energy_kWh"] == pytest.approx(out["lut"]["hvac_energy_kWh"], rel=0.25)
    with xr.open_dataset(tmp_path / "physics.nc") as ds:
        assert ds.attrs["model"] == "physics"


def test_train_surrogates_then_simulate_and_compare_with_them(luts, tmp_path):
    models = tmp_path / "models"
    r = run("surrogate", "train", "--quick", "--mode", "all", "--runs-per-mode", "3", "--luts", luts, "-o", models,
            "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    report = json.loads(r.stdout)
    assert (models / "mode_models.npz").is_file() and report["path"] == str(models / "mode_models.npz")
    trace = _short_trace(tmp_path, 120)
    r = run("simulate", "--cycle", trace, "--t-amb", "30", "--luts", luts, "--model", "surrogate", "--surrogates",
            models, "-o", tmp_path / "s.nc", "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout)
    assert summary["model"] == "surrogate" and 0.0 <= summary["surrogate_out_of_range_fraction"] <= 1.0
    assert math.isfinite(summary["T_cabin_end_degC"]) and math.isfinite(summary["soc_end"])
    r = run("report", "compare", "--cycle", trace, "--t-amb", "30", "--approaches", "lut,surrogate", "--surrogates",
            models, "--luts", luts, "--dts", "1,10", "--repeat", "1", "-o", tmp_path / "cmp", "--json")  # fmt: skip
    assert r.exit_code == 0, r.output
    result = json.loads(r.stdout)
    assert {row["approach"] for row in result["table"]} == {"lut", "surrogate"}
    assert (tmp_path / "cmp" / "index.html").is_file() and (tmp_path / "cmp" / "compare.csv").is_file()


def test_a_surrogate_that_runs_away_ends_the_run_without_a_traceback(luts, tmp_path):
    """Mode models whose cabin cools at 3 K/s: the command finishes (exit 0), the JSON and the file say the run
    ended when the cabin left the physical range, and the text line says so too."""
    pytest.importorskip("sklearn")
    from evtms.surrogates.io import FILE_NAME, save_mode_models
    from tests.test_surrogates import _constant_rate_models

    models = tmp_path / "models"
    models.mkdir()
    save_mode_models(_constant_rate_models({"T_cabin": -3.0}), models / FILE_NAME)
    trace = _short_trace(tmp_path, 120)
    cmd = ("simulate", "--cycle", trace, "--t-amb", "30", "--luts", luts, "--model", "surrogate", "--surrogates",
           models, "-o", tmp_path / "s.nc")  # fmt: skip
    r = run(*cmd, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["termination"] == "surrogate_out_of_bounds" and 40 <= s["steps"] < 120
    assert -100.0 <= s["T_cabin_end_degC"] < -96.0
    with xr.open_dataset(tmp_path / "s.nc") as ds:
        assert ds.attrs["termination"] == "surrogate_out_of_bounds"
    r = run(*cmd)
    assert r.exit_code == 0 and "Traceback" not in r.output
    assert f"ended: surrogate_out_of_bounds at {s['duration_s']:.0f} s" in r.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["surrogate", "train", "--mode", "cooling", "-o", "m"], "cooling"),
        (["surrogate", "train", "--runs-per-mode", "0", "-o", "m"], "--runs-per-mode 0 is not allowed"),
        (["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "--approaches", "lut,neural", "-o", "c"],
         "--approaches 'neural' is unknown"),
        (["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "--approaches", "lut", "--dts", "1,x", "-o", "c"],
         "--dts '1,x'"),
        (["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "--approaches", "surrogate", "--surrogates",
          "none", "-o", "c"], "--surrogates 'none': no mode-model file"),
        (["report", "compare", "--cycle", "wltc3b", "--t-amb", "30", "--approaches", "lut", "--measured", "no.csv",
          "-o", "c"], "no.csv"),
    ],
)  # fmt: skip
def test_bad_surrogate_and_compare_input_is_one_line(luts, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    r = run(*args, "--luts", luts)
    one_error_line(r, message)
    assert not (tmp_path / "m").exists() and not (tmp_path / "c").exists()
