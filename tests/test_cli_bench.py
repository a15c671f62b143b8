"""The bench CLI: happy path, summary line and every kind of bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.cli import app

runner = CliRunner()


def run(*args: str):
    return runner.invoke(app, list(args))


def test_condenser_thesis_writes_file_and_summary(tmp_path):
    out = tmp_path / "c.nc"
    res = run("bench", "condenser", "--grid", "thesis", "-o", str(out))
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 0
    assert "condenser: 768 points, 0 invalid" in res.stdout and str(out) in res.stdout


def test_custom_axes_with_units(tmp_path):
    out = tmp_path / "c.nc"
    res = run(
        "bench",
        "condenser",
        "-a",
        "mdot=4:8:3g/s",
        "-a",
        "p_in=0.9:1.2:2MPa",
        "-a",
        "fan=10,50%",
        "-a",
        "T_in=70degC",
        "-a",
        "T_res=300",
        "-o",
        str(out),
    )
    assert res.exit_code == 0, res.output
    import xarray as xr

    with xr.open_dataset(out) as ds:
        assert ds.attrs["grid"] == "custom"
        assert list(ds["mdot"].values) == pytest.approx([0.004, 0.006, 0.008])
        assert list(ds["p_in"].values) == pytest.approx([0.9e6, 1.2e6])
        assert list(ds["fan"].values) == pytest.approx([0.1, 0.5])
        # One value is a fixed input, recorded as an attribute, not a length-1 axis (format v2).
        assert "T_in" not in ds.dims
        assert json.loads(ds.attrs["fixed_inputs"])["T_in"]["value"] == pytest.approx(343.15)


BAD = [
    (["-a", "mdot=-0.001,0.005"], "mdot", "mdot > 0"),
    (["-a", "mdot=0,0.005"], "mdot", "mdot > 0"),
    (["-a", "fan=0.1,1.2"], "fan", "0 < fan <= 1"),
    (["-a", "p_in=4.1MPa"], "p_in", "critical pressure"),
    (["-a", "fan=0.5,0.1"], "fan", "strictly increasing"),
    (["-a", "mdto=0.005"], "mdto", "allowed: mdot, fan"),
    (["-a", "p_in=1:2:3psi"], "psi", "allowed: Pa, kPa, MPa, bar"),
    (["-a", "fan=abc"], "abc", "start:stop:count"),
    (["--grid", "nosuch"], "nosuch", "allowed: thesis"),
    (["-a", "fan=50"], "fan", "did you mean 50%?"),
    (["-a", "p_in=1"], "p_in", "did you mean 1MPa?"),
    (["-a", "mdot=1:2:1000000000"], "1,000,000,000 points", "--max-points"),
    (["-a", "T_in=340", "-a", "h_in=420kJ/kg"], "T_in and h_in", "give one of them"),
]


@pytest.mark.parametrize(("args", "names", "allowed"), BAD)
def test_bad_axis_values_exit_2_one_line_no_file(tmp_path, args, names, allowed):
    out = tmp_path / "c.nc"
    res = run("bench", "condenser", *args, "-o", str(out))
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert names in lines[0] and allowed in lines[0]
    assert "Traceback" not in res.output
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_unknown_bench(tmp_path):
    res = run("bench", "pump", "-o", str(tmp_path / "h.nc"))
    assert res.exit_code == 2
    assert res.stderr.strip() == (
        "error: No such command 'pump' (allowed: condenser, evaporator, expansion-valve, compressor, chiller, "
        "radiator, heater-core, wcc, all) (see 'evtms bench --help')"
    )


def test_missing_and_malformed_params_file(tmp_path):
    out = tmp_path / "c.nc"
    res = run("bench", "condenser", "--params", str(tmp_path / "none.toml"), "-o", str(out))
    assert res.exit_code == 2 and "none.toml" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert "cannot be read" in res.stderr or "no such file" in res.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text("[condenser\nn_tubes = 3\n")
    res = run("bench", "condenser", "--params", str(bad), "-o", str(out))
    assert res.exit_code == 2 and "not valid TOML" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    typo = tmp_path / "typo.toml"
    typo.write_text("[condenser]\nn_tube = 3\n")
    res = run("bench", "condenser", "--params", str(typo), "-o", str(out))
    assert res.exit_code == 2 and "'n_tube'" in res.stderr and "n_tubes" in res.stderr
    wrong = tmp_path / "wrong.toml"
    wrong.write_text("[condenser]\nn_tubes = 'many'\n")
    res = run("bench", "condenser", "--params", str(wrong), "-o", str(out))
    assert res.exit_code == 2 and "n_tubes" in res.stderr
    assert not out.exists()


def test_params_file_changes_the_physics(tmp_path):
    small = tmp_path / "small.toml"
    small.write_text("[condenser]\nfan_flow_max = 0.3\n")
    a, b = tmp_path / "a.nc", tmp_path / "b.nc"
    assert run("bench", "condenser", "-o", str(a), "-q").exit_code == 0
    assert run("bench", "condenser", "--params", str(small), "-o", str(b), "-q").exit_code == 0
    import json

    import xarray as xr

    with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
        assert json.loads(db.attrs["parameters"])["condenser"]["fan_flow_max"] == 0.3
        # Less air can never reject more heat.
        assert (db["Q"] <= da["Q"] + 1e-9).all() and (db["Q"] < da["Q"] - 1).any()


def test_output_folder_created_or_refused(tmp_path):
    """A missing output folder is made (as the documented commands need); a file in the way is refused."""
    plain = tmp_path / "file"
    plain.write_text("x")
    res = run("bench", "condenser", "-o", str(plain / "c.nc"))
    assert res.exit_code == 2 and "is a file" in res.stderr
    res = run("bench", "condenser", "-o", str(tmp_path))
    assert res.exit_code == 2 and "is a folder" in res.stderr
    res = run("bench", "condenser", "-a", "T_in=100,110", "-o", str(tmp_path / "new" / "deeper" / "c.nc"))
    assert res.exit_code == 2, res.output  # bad input: the folders it would have made are not left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
    res = run("bench", "condenser", "-o", str(tmp_path / "new" / "deeper" / "c.nc"))
    assert res.exit_code == 0, res.output
    assert (tmp_path / "new" / "deeper" / "c.nc").is_file()


def test_help_and_version_are_lazy():
    """``--help`` imports none of the heavy libraries (its time is the benchmarks', not a test's)."""
    code = (
        "import sys;"
        "from typer.testing import CliRunner; from evtms.cli import app;"
        "r=CliRunner().invoke(app, ['--help']); assert r.exit_code == 0;"
        "print(sorted(m for m in ('CoolProp', 'xarray', 'matplotlib', 'numba', 'scipy') if m in sys.modules))"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == "[]"
    v = run("--version")
    assert v.exit_code == 0 and v.stdout.startswith("evtms ")
    h = run("bench", "--help")
    assert "evtms bench condenser --grid thesis" in h.stdout


def test_bench_all_writes_one_file_per_registered_bench(tmp_path):
    out = tmp_path / "luts"
    res = run("bench", "all", "--grid", "thesis", "-o", str(out))
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out.iterdir()) == sorted(f"{name}.nc" for name in BENCHES)
    assert {"chiller.nc", "radiator.nc", "heater_core.nc", "wcc.nc"} <= {p.name for p in out.iterdir()}
    assert "expansion_valve: 36 points, 18 invalid" in res.stdout
    assert "compressor: 36 points, 0 invalid" in res.stdout


@pytest.mark.parametrize("name", ["expansion-valve", "expansion_valve"])
def test_valve_alias(tmp_path, name):
    out = tmp_path / "v.nc"
    res = run("bench", name, "-o", str(out))
    assert res.exit_code == 0 and out.exists()


BAD_PER_BENCH = [
    ("evaporator", ["-a", "blower=0,0.5"], "0 < blower <= 1"),
    ("evaporator", ["-a", "fan=0.5"], "unknown axis 'fan' for evaporator"),
    ("expansion-valve", ["-a", "mdot=-1g/s"], "mdot > 0"),
    ("expansion-valve", ["-a", "p_in=50bar"], "critical pressure"),
    ("compressor", ["-a", "pr=0.5,2"], "pr > 1"),
    ("compressor", ["-a", "speed=0:1:3"], "0 < speed <= 1"),
    ("compressor", ["-a", "T_in=100"], "T_in"),
]


@pytest.mark.parametrize(("bench", "args", "message"), BAD_PER_BENCH)
def test_bad_input_per_bench(tmp_path, bench, args, message):
    out = tmp_path / "x.nc"
    res = run("bench", bench, *args, "-o", str(out))
    assert res.exit_code == 2, res.output
    assert len(res.stderr.strip().splitlines()) == 1 and message in res.stderr
    assert list(tmp_path.iterdir()) == []
