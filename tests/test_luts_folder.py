"""`--luts` and :func:`evtms.cycle.api.cycle_luts_folder`: which folders hold the cycle LUTs.

A folder of cycle LUTs, the luts/ folder `evtms demo -o OUT` writes and OUT
itself are taken; a folder holding other LUTs (thesis grid, an incomplete
set, a file that is no LUT) is one error line saying what it holds, and
nothing is built over it; a missing or empty folder is where the LUTs are
built. The refusals run on tiny LUTs (a few points each, written here);
only the runs that solve need the session's cycle LUTs.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from conftest import one_error_line
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.benches.grid import build_grid
from evtms.benches.sweep import run_sweep
from evtms.cli import app
from evtms.cycle.api import cycle_luts_folder, load_cycle_luts
from evtms.errors import EvtmsInputError
from evtms.luts.io import write_lut

COMPONENTS = ("compressor", "condenser", "evaporator", "chiller", "expansion_valve")
EXPECTED = ("evtms bench all --grid cycle -o DIR", "evtms demo -o OUT")
TRACE = "time_s,speed_kmh\n0,0\n10,50\n60,50\n70,0\n"
runner = CliRunner()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, params, fluid):
    """``{grid: folder}``: every component's LUT on two values of each thesis axis, labelled thesis and cycle.

    Only their headers are read before a folder is refused; the labels are what tells them apart.
    """
    root = tmp_path_factory.mktemp("tiny_luts")
    (root / "thesis").mkdir()
    (root / "cycle").mkdir()
    for c in COMPONENTS:
        bench = BENCHES[c]
        small = {k: np.asarray(v, float)[:2] for k, v in bench.presets["thesis"].items()}
        ds = run_sweep(bench, build_grid(bench, None, small), params, grid_name="thesis", fluid=fluid)
        write_lut(ds, root / "thesis" / f"{c}.nc")
        ds.attrs["grid"] = "cycle"
        write_lut(ds, root / "cycle" / f"{c}.nc")
    return {"thesis": root / "thesis", "cycle": root / "cycle"}


def _links(source, folder, components=COMPONENTS):
    folder.mkdir(parents=True, exist_ok=True)
    for c in components:
        os.symlink(source / f"{c}.nc", folder / f"{c}.nc")
    return folder


def _files(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture()
def no_build(monkeypatch):
    """Building LUTs fails the test (the folders here must be taken or refused as they are)."""
    import evtms.workflows.demo

    def refuse(*args, **kwargs):
        raise AssertionError(f"ensure_luts{args[:2]} called: LUTs would be built")

    monkeypatch.setattr(evtms.workflows.demo, "ensure_luts", refuse)


# ---- the library ---------------------------------------------------------------------------------


def test_the_demo_layout_is_found_from_each_of_its_folders(tiny, tmp_path):
    out = tmp_path / "out"
    _links(tiny["thesis"], out / "luts" / "thesis")
    cycle = _links(tiny["cycle"], out / "luts" / "cycle")
    for given in (out, out / "luts", cycle):
        assert cycle_luts_folder(given) == cycle
        assert {lut.path.parent for lut in load_cycle_luts(given).values()} == {cycle}
    # 'evtms bench all --grid cycle -o DIR': the folder itself.
    flat = _links(tiny["cycle"], tmp_path / "flat")
    assert cycle_luts_folder(flat) == flat


def test_thesis_grid_luts_are_not_taken_for_cycle_luts(tiny, tmp_path):
    with pytest.raises(EvtmsInputError) as exc:
        cycle_luts_folder(tiny["thesis"])
    message = str(exc.value)
    assert "on the thesis grid" in message and all(e in message for e in EXPECTED), message
    assert "\n" not in message
    # The demo's output folder with its thesis LUTs only (no cycle/ yet): named where they are.
    out = tmp_path / "out"
    _links(tiny["thesis"], out / "luts" / "thesis")
    for given in (out, out / "luts"):
        with pytest.raises(EvtmsInputError, match=r"luts/thesis' holds .* on the thesis grid"):
            load_cycle_luts(given)


def test_an_incomplete_set_says_what_it_lacks(tiny, tmp_path):
    folder = _links(tiny["cycle"], tmp_path / "luts", ("compressor", "condenser", "evaporator"))
    with pytest.raises(EvtmsInputError, match=r"on the cycle grid, and lacks chiller, expansion_valve"):
        cycle_luts_folder(folder)
    # The circuit sets what is needed: the cabin cycle has no chiller.
    _links(tiny["cycle"], folder, ("expansion_valve",))
    assert cycle_luts_folder(folder, "cabin") == folder
    with pytest.raises(EvtmsInputError, match=r"lacks chiller"):
        cycle_luts_folder(folder, "cabin+chiller")


def test_a_file_that_is_no_lut_is_named_with_its_rule(tiny, tmp_path):
    folder = _links(tiny["cycle"], tmp_path / "luts", ("condenser", "evaporator", "chiller", "expansion_valve"))
    (folder / "compressor.nc").write_text("x")
    with pytest.raises(EvtmsInputError, match=r"compressor.nc, which is no valid LUT \(not a netCDF file\)"):
        load_cycle_luts(folder)


def test_a_missing_or_empty_folder_holds_no_luts(tmp_path):
    (tmp_path / "empty" / "maps").mkdir(parents=True)  # map caches alone are no LUTs
    assert cycle_luts_folder(tmp_path / "nowhere") is None
    assert cycle_luts_folder(tmp_path / "empty") is None
    with pytest.raises(EvtmsInputError, match="'.*nowhere' does not exist; give the folder of cycle-grid LUTs"):
        load_cycle_luts(tmp_path / "nowhere")
    with pytest.raises(EvtmsInputError, match="'.*empty' holds no LUTs"):
        load_cycle_luts(tmp_path / "empty")


# ---- the commands: refused or built, on tiny LUTs --------------------------------------------------


@pytest.mark.parametrize("given", ["out", "out/luts", "out/luts/thesis"])
def test_simulate_refuses_thesis_luts_in_one_line_and_writes_nothing(tiny, tmp_path, no_build, given):
    _links(tiny["thesis"], tmp_path / "out" / "luts" / "thesis")
    (tmp_path / "trace.csv").write_text(TRACE)
    before = _files(tmp_path)
    trace = tmp_path / "trace.csv"
    r = run("simulate", "--cycle", trace, "--t-amb", "30", "--luts", tmp_path / given, "-o", tmp_path / "run.nc")
    one_error_line(r, "error: --luts: no complete set of cycle LUTs", "on the thesis grid", *EXPECTED)
    assert _files(tmp_path) == before


def test_simulate_does_not_complete_an_incomplete_set(tiny, tmp_path, no_build):
    luts = _links(tiny["cycle"], tmp_path / "luts", ("condenser", "evaporator"))
    before = _files(tmp_path)
    r = run("simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", luts, "-o", tmp_path / "run.nc")
    one_error_line(r, "condenser, evaporator on the cycle grid, and lacks chiller, expansion_valve, compressor")
    assert _files(tmp_path) == before


@pytest.mark.parametrize("state", ["missing", "empty"])
def test_simulate_builds_in_a_missing_or_empty_folder_and_says_so(tmp_path, monkeypatch, state):
    import evtms.workflows.demo

    calls = []

    def record(folder, grid, *args, **kwargs):
        calls.append((folder, grid))
        raise EvtmsInputError("stopped before the build")  # the real build takes minutes

    monkeypatch.setattr(evtms.workflows.demo, "ensure_luts", record)
    luts = tmp_path / "luts"
    if state == "empty":
        luts.mkdir()
    r = run("simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", luts, "-o", tmp_path / "run.nc")
    assert f"note: no cycle LUTs in {luts}/; building them" in r.stderr, r.stderr
    assert calls == [(luts, "cycle")]
    assert "error: stopped before the build" in r.stderr


def test_cycle_commands_refuse_thesis_luts(tiny, tmp_path):
    out = tmp_path / "out"
    _links(tiny["thesis"], out / "luts" / "thesis")
    before = _files(tmp_path)
    one_error_line(run("cycle", "run", "--luts", out), "on the thesis grid", *EXPECTED)
    r = run("cycle", "sweep", "--luts", out / "luts", "--speed", "0.4,0.8", "-o", tmp_path / "s.nc")
    one_error_line(r, "on the thesis grid", *EXPECTED)
    assert _files(tmp_path) == before


# ---- the commands on the demo's layout, with the session's cycle LUTs --------------------------------


@pytest.fixture(scope="module")
def demo_out(cycle_luts_dir, tiny, tmp_path_factory):
    """A folder laid out as 'evtms demo -o OUT' writes its LUTs (links to the session's cycle LUTs)."""
    out = tmp_path_factory.mktemp("demo_layout") / "out"
    _links(tiny["thesis"], out / "luts" / "thesis")
    _links(cycle_luts_dir, out / "luts" / "cycle")
    return out


@pytest.mark.parametrize("given", ["luts", "."])
def test_simulate_takes_the_demo_folders_without_building(demo_out, tmp_path, no_build, small_maps, given):
    trace = tmp_path / "trace.csv"
    trace.write_text(TRACE)
    luts = demo_out / given
    r = run("simulate", "--cycle", trace, "--t-amb", "30", "--luts", luts, "-o", tmp_path / "run.nc", "--json")
    assert r.exit_code == 0, r.output
    assert "building them" not in r.stderr and (tmp_path / "run.nc").is_file()
    # The maps go beside the cycle LUTs, as the demo's own simulation caches them; nothing else is added.
    made = {str(p.relative_to(demo_out)) for p in demo_out.rglob("*.nc") if not p.is_symlink()}
    assert made == {f"luts/cycle/maps/{m}.nc" for m in ("ac", "chiller", "ac+chiller")}


def test_cycle_run_and_sweep_take_the_demo_folders(demo_out, tmp_path):
    r = run("cycle", "run", "--luts", demo_out, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["models"] == str(demo_out / "luts" / "cycle")
    r = run("cycle", "sweep", "--luts", demo_out / "luts", "--speed", "0.4,0.8", "-o", tmp_path / "s.nc")
    assert r.exit_code == 0, r.output
    # The output may not be one of the LUTs found, however the folder was given.
    r = run("cycle", "sweep", "--luts", demo_out, "-o", demo_out / "luts" / "cycle" / "condenser.nc")
    one_error_line(r, "is the input")
