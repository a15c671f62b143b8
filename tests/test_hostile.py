"""Hostile input: every bad input is one ``error: ...`` line, exit 2, no output, inputs untouched.

One table, ``CASES``, a row per hostile case: extend it with a row. Each row
runs in a fresh folder holding a few good inputs (a small condenser LUT, a
params file, the cycle LUTs, a cycle sweep); the test checks the exit code,
that stderr is exactly one line starting with ``error:`` and holding the
row's fragment, that no file or folder appeared, and that no input changed.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.cli import app

runner = CliRunner()
#: A simulate call whose other arguments are good.
SIM = ["simulate", "--cycle", "wltc3b", "--t-amb", "30"]
CMP = ["report", "compare", "--cycle", "wltc3b", "--approaches", "lut"]
SMALL = ["--axis", "mdot=4,6g/s", "--axis", "fan=0.2,0.5", "--axis", "p_in=1,1.1MPa", "--axis", "T_in=340,350"]


@pytest.fixture(scope="module")
def originals(tmp_path_factory, cycle_luts_dir):
    """Good inputs, made once: a small condenser LUT, a params file, a cycle sweep."""
    root = tmp_path_factory.mktemp("hostile_inputs")
    res = runner.invoke(app, ["bench", "condenser", *SMALL, "--axis", "T_res=300,310", "-o", str(root / "c.nc")])
    assert res.exit_code == 0, res.output
    (root / "p.toml").write_text("[condenser]\nn_tubes = 44\n")
    res = runner.invoke(
        app, ["cycle", "sweep", "--luts", str(cycle_luts_dir), "--speed", "0.4,0.8", "-o", str(root / "s.nc")]
    )
    assert res.exit_code == 0, res.output
    return root


@pytest.fixture()
def ws(tmp_path, originals, cycle_luts_dir):
    """A fresh folder with c.nc, p.toml, s.nc and luts/ (a copy of the cycle LUTs)."""
    for name in ("c.nc", "p.toml", "s.nc"):
        shutil.copy(originals / name, tmp_path / name)
    (tmp_path / "luts").mkdir()
    for f in cycle_luts_dir.glob("*.nc"):
        os.link(f, tmp_path / "luts" / f.name) if _same_device(f, tmp_path) else shutil.copy(f, tmp_path / "luts")
    return tmp_path


def _same_device(a: Path, b: Path) -> bool:
    return os.stat(a).st_dev == os.stat(b).st_dev


#: Files from this size on are fingerprinted by their inode's stat, not hashed [bytes].
_HASH_BELOW = 1 << 20


def _snapshot(root: Path) -> dict[str, str]:
    """Every file and folder below ``root`` with a fingerprint of its contents (folders: '').

    Small files are hashed. The workspace's copies of the cycle LUTs (some 200 MB) would
    take 0.4 s per snapshot to hash, most of this module's time: a big file's fingerprint
    is its size, inode, mtime and ctime instead. Any write or truncation moves ctime,
    which no process can set back (``os.utime`` restores mtime only), and a replaced
    file has another inode.
    """
    out = {}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        if p.is_symlink() or not (p.is_file() or p.is_dir()):
            out[rel] = "special"
        elif p.is_dir():
            out[rel] = ""
        else:
            st = p.stat()
            if st.st_size >= _HASH_BELOW:
                out[rel] = f"stat {st.st_size} {st.st_ino} {st.st_mtime_ns} {st.st_ctime_ns}"
            else:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


# --- helpers that make hostile inputs in the workspace -------------------------------------


def write(name: str, data: bytes | str) -> Callable[[Path], None]:
    def make(ws: Path) -> None:
        (ws / name).unlink(missing_ok=True)  # never write through a hard link to the shared LUTs
        (ws / name).write_bytes(data.encode() if isinstance(data, str) else data)

    return make


def fifo(name: str) -> Callable[[Path], None]:
    return lambda ws: os.mkfifo(ws / name)


def edit_nc(name: str, edit: Callable[[netCDF4.Dataset], None], src: str = "c.nc") -> Callable[[Path], None]:
    """A copy of LUT ``src`` as ``name``, edited in place with netCDF4."""

    def make(ws: Path) -> None:
        shutil.copy(ws / src, ws / name)
        with netCDF4.Dataset(ws / name, "a") as nc:
            edit(nc)

    return make


def truncated(name: str) -> Callable[[Path], None]:
    def make(ws: Path) -> None:
        data = (ws / "c.nc").read_bytes()
        (ws / name).write_bytes(data[: len(data) // 2])

    return make


def foreign_netcdf(name: str) -> Callable[[Path], None]:
    """A valid netCDF file another program wrote: no evtms attributes."""

    def make(ws: Path) -> None:
        with netCDF4.Dataset(ws / name, "w") as nc:
            nc.createDimension("x", 3)
            nc.createVariable("x", "f8", ("x",))[:] = [1.0, 2.0, 3.0]
            nc.createVariable("temp", "f4", ("x",))[:] = [280.0, 290.0, 300.0]
            nc.title = "some other program's data"

    return make


def huge_dims(name: str) -> Callable[[Path], None]:
    """An evtms-looking LUT whose status declares 10^12 points (never filled, so the file is tiny)."""

    def make(ws: Path) -> None:
        with netCDF4.Dataset(ws / "c.nc") as src, netCDF4.Dataset(ws / name, "w") as nc:
            nc.setncatts({k: src.getncattr(k) for k in src.ncattrs()})
            dims = list(src["status"].dimensions)
            for d in dims:
                nc.createDimension(d, 1_000_000 if d in ("mdot", "fan") else len(src.dimensions[d]))
                v = nc.createVariable(d, "f8", (d,))
                v.setncatts({k: src[d].getncattr(k) for k in src[d].ncattrs() if k != "_FillValue"})
            for var in ("status", "Q"):
                s = src[var]
                v = nc.createVariable(var, s.dtype, tuple(dims), fill_value=False)
                v.setncatts({k: s.getncattr(k) for k in s.ncattrs() if k != "_FillValue"})

    return make


def link_as(target: str, name: str) -> Callable[[Path], None]:
    """``luts/<name>`` replaced by a copy of ``luts/<target>`` (the wrong component at that name)."""

    def make(ws: Path) -> None:
        (ws / "luts" / name).unlink()
        shutil.copy(ws / "luts" / target, ws / "luts" / name)

    return make


def mkdir(name: str) -> Callable[[Path], None]:
    return lambda ws: (ws / name).mkdir()


def _set(attr: str, value) -> Callable[[netCDF4.Dataset], None]:
    return lambda nc: nc.setncattr(attr, value)


def _del(attr: str) -> Callable[[netCDF4.Dataset], None]:
    return lambda nc: nc.delncattr(attr)


def _axis_units(axis: str, units: str) -> Callable[[netCDF4.Dataset], None]:
    return lambda nc: nc[axis].setncattr("units", units)


@dataclass
class Case:
    """One hostile call: ``args`` run in the workspace after ``setup``; stderr must hold ``message``."""

    id: str
    args: list[str]
    message: str
    setup: list[Callable[[Path], None]] = field(default_factory=list)
    code: int = 2


def bad_params(
    id: str, toml: bytes | str, message: str, command: tuple[str, ...] = ("bench", "condenser", *SMALL)
) -> Case:
    """A run of ``command`` (a bench by default) whose --params file n.toml holds ``toml``."""
    return Case(id, [*command, "--params", "n.toml", "-o", "o.nc"], message, [write("n.toml", toml)])


LUT_INPUT_CASES = [
    # (id suffix, setup making bad.nc, expected fragment)
    ("text", [write("bad.nc", "mdot,Q\n1,2\n")], "not a netCDF file"),
    ("empty", [write("bad.nc", b"")], "empty"),
    ("truncated", [truncated("bad.nc")], "truncated or corrupt"),
    ("foreign-netcdf", [foreign_netcdf("bad.nc")], "not an evtms LUT"),
    ("no-version", [edit_nc("bad.nc", _del("lut_format_version"))], "lut_format_version"),
    ("future-version", [edit_nc("bad.nc", _set("lut_format_version", np.int32(9)))], "version 9"),
    ("garbage-parameters", [edit_nc("bad.nc", _set("parameters", "{not json"))], "parameters"),
    ("parameters-not-object", [edit_nc("bad.nc", _set("parameters", "[1, 2]"))], "parameters"),
    ("garbage-environment", [edit_nc("bad.nc", _set("environment", "nope{"))], "environment"),
    ("unknown-component", [edit_nc("bad.nc", _set("component", "flux_capacitor"))], "flux_capacitor"),
    ("axis-unknown-units", [edit_nc("bad.nc", _axis_units("p_in", "furlongs"))], "furlongs"),
    ("huge-dims", [huge_dims("bad.nc")], "points"),
    ("fifo", [fifo("bad.nc")], "not a regular file"),
    ("folder", [mkdir("bad.nc")], "is a folder"),
    ("missing", [], "no such file"),
]

CASES: list[Case] = [
    # Every command that reads a LUT refuses a bad one with one line.
    *[Case(f"lut-info-{i}", ["lut", "info", "bad.nc"], m, s) for i, s, m in LUT_INPUT_CASES],
    *[
        Case(
            f"lut-query-{i}", ["lut", "query", "bad.nc", "--at", "mdot=5g/s,fan=0.3,p_in=1MPa,T_in=345,T_res=300"], m, s
        )
        for i, s, m in LUT_INPUT_CASES
    ],
    *[
        Case(f"lut-export-{i}", ["lut", "export", "bad.nc", "--format", "csv", "-o", "x.csv"], m, s)
        for i, s, m in LUT_INPUT_CASES
    ],
    *[Case(f"lut-diff-{i}", ["lut", "diff", "c.nc", "bad.nc"], m, s) for i, s, m in LUT_INPUT_CASES],
    *[Case(f"report-bench-{i}", ["report", "bench", "bad.nc", "-o", "rep"], m, s) for i, s, m in LUT_INPUT_CASES[:6]],
    Case(
        "cycle-wrong-component",
        ["cycle", "run", "--luts", "luts"],
        "holds the condenser LUT; the evaporator LUT is needed",
        [link_as("condenser.nc", "evaporator.nc")],
    ),
    Case(
        "cycle-garbage-lut", ["cycle", "run", "--luts", "luts"], "not a netCDF file", [write("luts/compressor.nc", "x")]
    ),
    Case("cycle-missing-lut-folder", ["cycle", "run", "--luts", "nowhere"], "does not exist"),
    # Outputs that are inputs, however spelled: refused before anything is written.
    Case("export-over-input", ["lut", "export", "c.nc", "--format", "mat", "-o", "c.nc"], "is the input"),
    Case(
        "export-over-input-dotdot", ["lut", "export", "c.nc", "--format", "csv", "-o", "./luts/../c.nc"], "is the input"
    ),
    Case("cycle-sweep-over-lut", ["cycle", "sweep", "--luts", "luts", "-o", "luts/condenser.nc"], "is the input"),
    Case("bench-over-params", ["bench", "condenser", *SMALL, "--params", "p.toml", "-o", "p.toml"], "must end in .nc"),
    Case("bench-over-params-nc", ["bench", "condenser", *SMALL, "--params", "c.nc", "-o", "c.nc"], "is the input"),
    Case(
        "report-eb-table-over-input",
        ["report", "energy-balance", "s.csv", "-o", "s.png", "--x", "speed"],
        "is the input",
        [lambda ws: shutil.copy(ws / "s.nc", ws / "s.csv")],
    ),
    # OS errors: one line naming the path.
    Case("output-is-folder", ["bench", "condenser", *SMALL, "-o", "luts"], "is a folder"),
    Case("csv-into-folder", ["lut", "export", "c.nc", "--format", "csv", "-o", "luts"], "is a folder"),
    Case("output-under-a-file", ["bench", "condenser", *SMALL, "-o", "c.nc/x.nc"], "is a file"),
    Case("output-name-too-long", ["bench", "condenser", *SMALL, "-o", "x" * 300 + ".nc"], "at most 191"),
    Case("output-in-proc", ["lut", "export", "c.nc", "--format", "csv", "-o", "/proc/evtms-test.csv"], "/proc"),
    Case("output-device", ["lut", "export", "c.nc", "--format", "csv", "-o", "/dev/null"], "not a regular file"),
    Case(
        "partial-is-a-file",
        ["bench", "condenser", *SMALL, "-o", "out.nc"],
        "partial",
        [write("out.nc.partial", "mine")],
    ),
    Case(
        "foreign-partial-folder", ["bench", "condenser", *SMALL, "-o", "out.nc"], "partial", [mkdir("out.nc.partial")]
    ),
    # Parameters.
    Case(
        "params-fifo",
        ["bench", "condenser", *SMALL, "--params", "f.toml", "-o", "o.nc"],
        "not a regular file",
        [fifo("f.toml")],
    ),
    bad_params("params-nan", "[condenser]\nn_tubes = nan\n", "n_tubes"),
    bad_params("params-inf", "[condenser]\ncore_length = inf\n", "core_length"),
    bad_params("params-negative", "[condenser]\ntube_depth = -0.01\n", "tube_depth"),
    bad_params("params-zero", "[condenser]\narea_ref = 0\n", "area_ref"),
    bad_params("params-string", '[condenser]\nn_tubes = "40"\n', "n_tubes"),
    bad_params("params-not-utf8", b"[condenser]\n# \xff\xfe\n", "n.toml"),
    bad_params("params-empty", b"", "empty"),
    bad_params("params-binary", bytes(range(256)), "n.toml"),
    bad_params("params-unknown-table", "[condensor]\nn_tubes = 4\n", "condensor"),
    Case("params-folder", ["bench", "condenser", *SMALL, "--params", "luts", "-o", "o.nc"], "is a folder"),
    # Axes.
    Case(
        "axis-unitless-pressure", ["bench", "condenser", *SMALL, "--axis", "p_in=1:2:3", "-o", "o.nc"], "did you mean"
    ),
    Case("axis-huge-count", ["bench", "condenser", "--axis", "mdot=1:2:1000000000", "-o", "o.nc"], "1,000,000,000"),
    Case(
        "axis-grid-too-large",
        ["bench", "condenser", "--axis", "mdot=1:5:200g/s", "--max-points", "1000", "-o", "o.nc"],
        "1,000",
    ),
    Case("axis-T-and-h", ["bench", "condenser", *SMALL, "--axis", "h_in=420,430kJ/kg", "-o", "o.nc"], "h_in"),
    Case("axis-twice", ["bench", "condenser", *SMALL, "--axis", "mdot=5,7g/s", "-o", "o.nc"], "mdot"),
    Case("axis-nan", ["bench", "condenser", *SMALL[:-2], "--axis", "T_in=nan", "-o", "o.nc"], "T_in"),
    Case("axis-count-zero", ["bench", "condenser", *SMALL[:-2], "--axis", "T_in=330:340:0", "-o", "o.nc"], "count"),
    Case("all-points-invalid", ["bench", "condenser", *SMALL[:-2], "--axis", "T_in=200,210", "-o", "o.nc"], "invalid"),
    Case("bad-scheduler", ["bench", "condenser", *SMALL, "--scheduler", "nonsense", "-o", "o.nc"], "scheduler"),
    Case(
        "float-digits-range", ["bench", "condenser", *SMALL, "--significant-digits", "0", "-o", "o.nc"], "significant"
    ),
    # Cycle inputs.
    Case("cycle-direct-and-luts", ["cycle", "run", "--direct", "--luts", "luts"], "not both"),
    Case("cycle-params-contradict-luts", ["cycle", "run", "--luts", "luts", "--params", "p.toml"], "condenser.n_tubes"),
    Case("cycle-sweep-count-zero", ["cycle", "sweep", "--luts", "luts", "--speed", "0.2:1:0", "-o", "o.nc"], "count"),
    Case(
        "cycle-sweep-too-many",
        ["cycle", "sweep", "--luts", "luts", "--speed", "0.1:1:3000", "--fan", "0.1:1:3000", "-o", "o.nc"],
        "limit",
    ),
    Case("cycle-speed-nan", ["cycle", "run", "--luts", "luts", "--speed", "nan"], "speed"),
    Case("cycle-t-amb-words", ["cycle", "run", "--luts", "luts", "--t-amb", "hot"], "--t-amb"),
    Case("cycle-superheat-zero", ["cycle", "run", "--luts", "luts", "--superheat", "0"], "0.1"),
    # Reports: nothing half-written, no empty folder.
    Case("report-surface-twice", ["report", "bench", "c.nc", "-o", "rep", "--surface", "p_in,p_in"], "twice"),
    Case("report-surface-unknown", ["report", "bench", "c.nc", "-o", "rep", "--surface", "p_in,zzz"], "zzz"),
    Case("report-bad-at", ["report", "bench", "c.nc", "-o", "rep", "--at", "mdot=abc"], "mdot"),
    Case("report-eb-not-a-sweep", ["report", "energy-balance", "c.nc", "-o", "eb.png"], "cycle sweep"),
    Case("report-ph-bad-suffix", ["report", "ph-diagram", "s.nc", "-o", "ph.pdf"], ".png or .svg"),
    Case("report-ph-bad-point", ["report", "ph-diagram", "s.nc", "-o", "ph.png", "--point", "speed=9"], "speed"),
    # Usage errors are one line too.
    Case("unknown-command", ["bnch"], "No such command"),
    Case("unknown-bench", ["bench", "heater"], "allowed"),
    Case("missing-option", ["lut", "export", "c.nc", "--format", "csv"], "--output"),
    Case("query-unknown-axis", ["lut", "query", "c.nc", "--at", "mdot=5g/s,zzz=1"], "zzz"),
    Case(
        "query-fixed-input-other-value",
        [
            "lut",
            "query",
            "luts/condenser.nc",
            "--at",
            "mdot=10g/s,fan=0.5,p_in=1.5MPa,h_in=430kJ/kg,T_air_in=30degC,T_res=305",
        ],
        "fixed at 300",
    ),
    # evtms simulate: a bad trace, parameter file, option or LUT folder is refused before any work.
    *[
        Case(
            f"simulate-trace-{i}",
            ["simulate", "--cycle", "t.csv", "--t-amb", "30", "-o", "o.nc"],
            m,
            [write("t.csv", t)],
        )
        for i, t, m in (
            ("words", "time_s,speed_kmh\n0,0\n1,fast\n", "fast"),
            ("negative", "time_s,speed_kmh\n0,0\n1,-5\n", "-5"),
            ("backwards", "time_s,speed_kmh\n0,0\n2,5\n1,5\n", "time"),
            ("empty", "", "empty"),
            ("no-header", "0,0\n1,5\n", "header"),
            ("binary", b"\x00\x01\x02", "t.csv"),
        )
    ],
    Case(
        "simulate-trace-fifo", ["simulate", "--cycle", "t.csv", "--t-amb", "30", "-o", "o.nc"], "t.csv", [fifo("t.csv")]
    ),
    bad_params("simulate-params-unknown-table", "[boiler]\nx = 1\n", "unknown table or key 'boiler'", tuple(SIM)),
    bad_params(
        "simulate-params-shared-with-a-bench",
        "[cabin]\nblower_flow_max = 0.4\n",
        "[evaporator] fan_flow_max",
        tuple(SIM),
    ),
    bad_params("simulate-params-v1-name", "[controls]\nptc_max_power = 3000\n", "is [hvac] ptc_max_power", tuple(SIM)),
    bad_params("simulate-params-heating", "[hvac]\nheating = 'gas'\n", "allowed: ptc_air, ptc_coolant", tuple(SIM)),
    bad_params("simulate-params-frost-order", "[climate]\nT_frost_on = 274\n", "T_frost_off < T_frost_on", tuple(SIM)),
    bad_params("simulate-params-string", "[cabin]\nvolume = 'big'\n", '[cabin] volume = "big"', tuple(SIM)),
    bad_params("simulate-params-order", "[battery]\nsoc_min = 0.95\n", "soc_min < soc_init", tuple(SIM)),
    bad_params("simulate-params-empty", b"", "is empty; give at least one [table]", tuple(SIM)),
    Case("simulate-dt-nan", [*SIM, "--dt", "nan", "-o", "o.nc"], "--dt"),
    Case(
        "simulate-too-many-steps",
        [*SIM, "--dt", "0.001", "--precondition", "86400", "-o", "o.nc"],
        "steps",
    ),
    Case(
        "simulate-output-every",
        [*SIM, "--dt", "2", "--output-every", "3", "-o", "o.nc"],
        "--output-every",
    ),
    Case(
        "simulate-precondition-fraction",
        [*SIM, "--precondition", "0.5", "-o", "o.nc"],
        "--precondition 0.5",
    ),
    Case(
        "simulate-soak-nan",
        [*SIM, "--soak-cabin", "nan", "-o", "o.nc"],
        "soak",
    ),
    Case("simulate-t-amb-words", ["simulate", "--cycle", "wltc3b", "--t-amb", "hot", "-o", "o.nc"], "--t-amb"),
    Case(
        "simulate-over-lut",
        [*SIM, "-o", "luts/condenser.nc"],
        "is the input",
    ),
    Case("simulate-not-nc", [*SIM, "-o", "o.csv"], ".nc"),
    Case(
        "simulate-luts-is-a-file",
        [*SIM, "--luts", "c.nc", "-o", "o.nc"],
        "not a folder",
    ),
    Case(
        "simulate-wrong-lut",
        [*SIM, "--luts", "luts", "-o", "o.nc"],
        "the compressor LUT is needed",
        [link_as("condenser.nc", "compressor.nc")],
    ),
    Case(
        "report-simulation-not-a-run",
        ["report", "simulation", "c.nc", "-o", "r.png"],
        "c.nc",
    ),
    Case("report-range-not-a-sweep", ["report", "range", "s.nc", "-o", "r.png"], "s.nc"),
    Case(
        "simulate-surrogates-garbage",
        [*SIM, "--model", "surrogate", "--surrogates", "m.npz", "-o", "o.nc"],
        "m.npz",
        [write("m.npz", b"PK\x03\x04 not a zip")],
    ),
    Case(
        "simulate-surrogates-not-models",
        [*SIM, "--model", "surrogate", "--surrogates", "m.npz", "-o", "o.nc"],
        "m.npz",
        [write("m.npz", b"")],
    ),
    Case("surrogate-train-over-a-file", ["surrogate", "train", "--mode", "bc", "-o", "c.nc"], "c.nc"),
    Case("surrogate-train-unknown-mode", ["surrogate", "train", "--mode", "bc,heat", "-o", "m"], "heat"),
    Case(
        "compare-measured-celsius",
        [*CMP, "--t-amb", "30", "--measured", "m.csv", "-o", "cmp"],
        "m.csv",
        [write("m.csv", "time,T_cabin\n0,25.0\n1,25.1\n")],
    ),
    Case(
        "compare-measured-two-scenarios",
        [*CMP, "--t-amb", "30,35", "--measured", "m.csv", "-o", "cmp"],
        "one",
        [write("m.csv", "time,T_cabin\n0,300.0\n1,300.1\n")],
    ),
    Case(
        "compare-t-amb-words",
        [*CMP, "--t-amb", "hot", "-o", "cmp"],
        "--t-amb",
    ),
    Case("compare-output-is-a-file", [*CMP, "--t-amb", "30", "-o", "c.nc"], "is a file"),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_input_is_one_line_exit_2_and_changes_nothing(case, ws, monkeypatch):
    monkeypatch.chdir(ws)
    for make in case.setup:
        make(ws)
    before = _snapshot(ws)
    res = runner.invoke(app, case.args)
    after = _snapshot(ws)
    lines = res.stderr.splitlines()
    assert res.exit_code == case.code, (res.exit_code, res.stdout, res.stderr)
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert "Traceback" not in res.output
    assert case.message in lines[0], lines[0]
    assert res.stdout == ""
    assert after == before, f"files changed: {set(after.items()) ^ set(before.items())}"


def test_a_full_disk_is_one_line_and_leaves_no_file(ws, monkeypatch):
    """ENOSPC in the middle of writing an export: one line naming the path, nothing left behind."""
    import evtms.luts.export as export

    def no_space(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(ws / "x.csv"))

    monkeypatch.chdir(ws)
    monkeypatch.setattr(export.np, "savetxt", no_space)
    before = _snapshot(ws)
    res = runner.invoke(app, ["lut", "export", "c.nc", "--format", "csv", "-o", "sub/x.csv"])
    assert res.exit_code == 2 and res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    assert "No space left on device" in res.stderr
    assert _snapshot(ws) == before  # no x.csv, no temporary file, no 'sub' folder


def test_documented_boundary_values_are_accepted_exactly(ws, monkeypatch):
    """-40 degC is the lower end of T_air_in and of --t-amb: accepted, stored as 233.15 K."""
    monkeypatch.chdir(ws)
    res = runner.invoke(
        app,
        [
            "bench",
            "condenser",
            *SMALL[:2],
            *SMALL[4:],
            "--axis",
            "T_air_in=-40,-30degC",
            "--axis",
            "fan=0.1:0.3:3",
            "-o",
            "o.nc",
        ],
    )
    assert res.exit_code == 0, res.output
    with netCDF4.Dataset(ws / "o.nc") as nc:
        assert nc["T_air_in"][0] == 233.15
        assert list(nc["fan"][:]) == [0.1, 0.2, 0.3]  # not 0.30000000000000004
        assert "_FillValue" not in nc["fan"].ncattrs()


def test_json_outputs_are_one_object(ws, monkeypatch):
    monkeypatch.chdir(ws)
    calls = {
        "lut info": ["lut", "info", "c.nc", "--json"],
        "lut query": ["lut", "query", "c.nc", "--at", "mdot=5g/s,fan=0.3,p_in=1.05MPa,T_in=345,T_res=300", "--json"],
        "bench": ["bench", "condenser", *SMALL, "-o", "j.nc", "--json"],
        "cycle run": ["cycle", "run", "--luts", "luts", "--json"],
        "cycle sweep": ["cycle", "sweep", "--luts", "luts", "--speed", "0.5,0.7", "-o", "js.nc", "--json"],
        "lut diff": ["lut", "diff", "c.nc", "j.nc", "--json"],
    }
    out = {}
    for name, args in calls.items():
        res = runner.invoke(app, args)
        assert res.exit_code == 0, (name, res.output)
        out[name] = json.loads(res.stdout)  # the whole of stdout is one JSON object
        assert isinstance(out[name], dict)
    assert out["lut info"]["component"] == "condenser" and out["lut info"]["points"] == 32
    q = out["lut query"]["points"][0]
    assert q["mdot"] == pytest.approx(0.005) and q["Q"] > 0
    assert out["bench"]["benches"][0]["points"] == 48  # 2 x 2 x 2 x 2 and the thesis preset's 3 T_res
    run = out["cycle run"]
    assert run["states"]["B"]["p"] > run["states"]["A"]["p"] and run["COP"] > 1
    assert run["Q_cond"] == pytest.approx(-run["Q_evap"] + run["W"], rel=0.05)
    assert out["cycle sweep"]["points"] == 2 and out["cycle sweep"]["solved"] == 2
    diff = out["lut diff"]  # c.nc has T_res 300, 310; j.nc the thesis preset's 300, 315, 330: 300 in common
    assert diff["common_shape"] == [2, 2, 2, 2, 1] and {v["name"] for v in diff["variables"]} >= {"Q", "h_out"}
    assert all(v["max_abs"] == 0 for v in diff["variables"]), diff  # same physics at the common points


def test_cycle_accepts_params_that_agree_with_the_luts(ws, monkeypatch):
    monkeypatch.chdir(ws)
    (ws / "same.toml").write_text("[condenser]\nn_tubes = 40\n")  # the default the LUTs were made with
    res = runner.invoke(app, ["cycle", "run", "--luts", "luts", "--params", "same.toml"])
    assert res.exit_code == 0, res.output


def test_bench_help_lists_axes_units_ranges_and_presets():
    res = runner.invoke(app, ["bench", "evaporator", "--help"])
    assert res.exit_code == 0
    for text in ("blower [1]", "0 < blower <= 1", "RH_air_in", "Preset --grid cycle", "T_res [K]: 280 (fixed input)"):
        assert text in res.stdout, text
