"""Bench reports, HTML pages and the demo: files exist, data equal the LUT, browser opens them."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
from conftest import patch_small_maps
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.cli import app
from evtms.luts import open_lut
from evtms.reports.bench_plots import MAIN, base_point, line_data, surface_data
from evtms.reports.html import referenced_files

runner = CliRunner()


def test_demo_produces_every_artefact(demo_run):
    out, result, _ = demo_run
    # The cycle LUTs were in place (the session's fixture wrote them): the demo reuses them.
    assert sorted(result.computed) == sorted(f"thesis/{c}" for c in BENCHES)
    assert sorted(result.reused) == sorted(f"cycle/{c}" for c in BENCHES)
    for grid in ("thesis", "cycle"):
        for c in BENCHES:
            assert open_lut(out / "luts" / grid / f"{c}.nc").attrs["grid"] == grid
    for c in BENCHES:
        figures = list((out / "reports" / c).glob("*.png"))
        assert len(figures) >= 4 and all(f.stat().st_size > 5000 for f in figures)
        assert (out / "reports" / c / "index.html").exists()
    for name in (
        "energy_balance.png",
        "energy_balance.svg",
        "energy_balance.csv",
        "ph_diagram.png",
        "ph_diagram.svg",
        "pt_diagram.png",
        "pt_diagram.svg",
    ):
        assert (out / "reports" / "cycle" / name).stat().st_size > 500
    assert (out / "cycle" / "speed_sweep.nc").exists()
    # The system simulation: its file, figure and a link from the index.
    import json

    import xarray as xr

    with xr.open_dataset(out / "simulation" / "wltc_40C.nc") as ds:
        summary = json.loads(ds.attrs["summary"])
    assert summary["distance_km"] == pytest.approx(23.2663, abs=5e-5) and summary["ledger_worst"] <= 1e-9
    assert summary["T_cabin_end_degC"] < 40.0 - 5.0  # pulled down from the soak
    assert (out / "reports" / "simulation" / "wltc_40C.png").stat().st_size > 20_000
    assert "reports/simulation/wltc_40C.png" in (out / "index.html").read_text()


def test_html_pages_reference_only_existing_files(demo_run):
    out = demo_run[0]
    pages = [out / "index.html"] + [out / "reports" / c / "index.html" for c in BENCHES]
    for page in pages:
        refs = referenced_files(page)
        assert refs, page
        missing = [r for r in refs if not r.exists()]
        assert not missing, (page, missing)
    top = (out / "index.html").read_text()
    assert "cycle/speed_sweep.nc" in top and "reports/condenser/index.html" in top


def test_second_demo_run_skips_the_benches(demo_run, tmp_path, monkeypatch):

    out = demo_run[0]
    patch_small_maps(monkeypatch)  # the demo fixture's maps have the small axes: reused, not rebuilt
    maps = {p: p.stat().st_mtime_ns for p in (out / "luts" / "cycle" / "maps").glob("*.nc")}
    res = runner.invoke(app, ["demo", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert f"0 LUTs computed, {2 * len(BENCHES)} reused" in res.stdout
    assert len(maps) == 3 and {p: p.stat().st_mtime_ns for p in maps} == maps


def test_plotted_data_equal_the_lut(thesis):
    for component in ("condenser", "compressor", "expansion_valve"):
        ds = thesis(component)
        var, family = MAIN[component]
        base = base_point(ds)
        for axis in ds["status"].dims:
            if axis == family:
                continue
            data = line_data(ds, axis, base)
            for f, y in data.lines.items():
                sel = {d: v for d, v in base.items() if d not in (axis, family)} | {family: f}
                expected = ds[var].sel(sel).transpose(axis).values
                ok = np.isin(ds["status"].sel(sel).transpose(axis).values, ds["status"].attrs["valid_flag_values"])
                np.testing.assert_array_equal(y[ok], expected[ok])
                assert np.isnan(y[~ok]).all()  # invalid points are gaps
    ds = thesis("condenser")
    base = base_point(ds, {"fan": 0.5, "T_res": 315.0})
    surf = surface_data(ds, ("p_in", "T_in"), base)
    z = surf.surfaces[0.0077]
    assert z.shape == (4, 4)
    assert z[2, 3] == float(ds["Q"].sel(mdot=0.0077, fan=0.5, T_res=315.0, p_in=1.1e6, T_in=375.0))


def test_valve_gaps_stay_gaps(thesis):
    ds = thesis("expansion_valve")
    data = surface_data(ds, ("p_in", "T_in"), base_point(ds))
    z = data.surfaces[float(ds["mdot"][0])]
    assert np.isnan(z).sum() == 6 and np.isfinite(z).sum() == 6  # vapour inlets choke at 330 K and 315 K


def test_report_bench_cli(tmp_path, thesis):
    from evtms.luts.io import write_lut

    lut = write_lut(thesis("compressor"), tmp_path / "compressor.nc")
    out = tmp_path / "rep"
    res = runner.invoke(app, ["report", "bench", str(lut), "-o", str(out), "--at", "T_in=265", "--format", "svg"])
    assert res.exit_code == 0, res.output
    assert len(list(out.glob("*.svg"))) == 4 and (out / "index.html").exists()
    res = runner.invoke(app, ["report", "bench", str(lut), "-o", str(out), "--at", "p_in=3"])
    assert res.exit_code == 2 and "unknown axis 'p_in'" in res.stderr
    res = runner.invoke(app, ["report", "bench", str(lut), "-o", str(out), "--surface", "speed,pr"])
    assert res.exit_code == 2 and "surface axis 'speed' is not allowed" in res.stderr


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_html_opens_in_headless_browser_without_console_errors(demo_run, tmp_path):
    browser = _chromium()
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs Debian's chromium; it could not here)")
    out = demo_run[0]
    shot = tmp_path / "index.png"
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
    ]
    page = (out / "index.html").resolve().as_uri()
    res = subprocess.run(
        [browser, *flags, "--enable-logging=stderr", "--v=0", f"--screenshot={shot}", "--window-size=1200,1600", page],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert shot.exists() and shot.stat().st_size > 10000, res.stderr[-2000:]
    console = [line for line in res.stderr.splitlines() if "CONSOLE" in line and "ERROR" in line.upper()]
    assert not console, console
    dom = subprocess.run([browser, *flags, "--dump-dom", page], capture_output=True, text=True, timeout=120)
    assert "evtms: R134a circuit benches" in dom.stdout and "<img" in dom.stdout


def test_a_lut_from_another_grid_or_bench_version_is_not_reused(thesis, params, tmp_path):
    from evtms.luts.io import write_lut
    from evtms.workflows.demo import lut_is_current

    ds = thesis("condenser")
    write_lut(ds, tmp_path / "same.nc")
    assert lut_is_current(tmp_path / "same.nc", "condenser", "thesis", params)
    # One variable the bench now writes is missing (an older build of the same version).
    write_lut(ds.drop_vars("capacity_ratio"), tmp_path / "older.nc")
    assert not lut_is_current(tmp_path / "older.nc", "condenser", "thesis", params)
    # Same preset name, other axis values.
    write_lut(ds.isel(p_in=slice(0, 2)), tmp_path / "other.nc")
    assert not lut_is_current(tmp_path / "other.nc", "condenser", "thesis", params)
