"""Hostile input that needs its own set-up: deep nesting, wrong provenance, huge sizes.

Each case runs the CLI in a child process (as a user would: a RecursionError,
a traceback or a kill by the out-of-memory killer show there as they would in
a terminal) and checks the one ``error: ...`` line, exit code 2, an empty
stdout and that no file appeared or changed. None needs the cycle LUTs of the
session: what is refused is refused before any LUT is interpolated.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import netCDF4
import numpy as np
import pytest

CLI = "import sys; from evtms.cli import main; sys.argv[0] = 'evtms'; main()"


def run_cli(cwd: Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)


def snapshot(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        for p in sorted(root.rglob("*"))
    }


def refused(cwd: Path, *args: str, message: str) -> str:
    """Run ``evtms args`` in ``cwd``: one error line holding ``message``, exit 2, nothing written."""
    before = snapshot(cwd)
    res = run_cli(cwd, *args)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr[-2000:])
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr[-2000:]
    assert "Traceback" not in res.stderr and res.stdout == ""
    assert message in lines[0], lines[0]
    assert snapshot(cwd) == before
    return lines[0]


# --- Runs whose time steps and records would not fit in memory ----------------------------------


def test_a_simulation_recorded_every_millisecond_is_refused_before_any_work(tmp_path):
    """1.8 million steps and as many records (2 GB of arrays): refused before the LUTs are looked for."""
    line = refused(
        tmp_path,
        *["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--dt", "0.001", "--output-every", "0.001", "-o", "o.nc"],
        message="--dt 0.001 s with --output-every 0.001 s gives 1,800,000 steps and 1,800,001 records",
    )
    assert "allowed: at most 1,750 MB" in line


def test_every_run_the_step_limit_and_the_range_test_allow_fits_the_array_bound():
    from evtms.system.drive_cycles import MAX_SAMPLES
    from evtms.system.simulate import MAX_STEPS, check_run_size

    day = 86400.0
    assert check_run_size(MAX_SAMPLES + day, 1.0, 1.0) == MAX_SAMPLES + day  # a week's range test, preconditioned
    assert check_run_size(MAX_SAMPLES + day, 0.5, 1.0) == 2 * (MAX_SAMPLES + day)
    assert check_run_size(MAX_STEPS * 1e-3, 1e-3, 1.0) == MAX_STEPS  # the step limit, records every second
    assert check_run_size(1800.0, 1e-3, 1.0) == 1_800_000  # a WLTC at 1 ms


# --- TOML files nested deeper than the parser's recursion ----------------------------------------

DEEP = {
    "array": "x = " + "[" * 5000 + "]" * 5000 + "\n",
    "inline-table": "x = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n",
    "parsed-but-deep": "x = " + "[" * 100 + "]" * 100 + "\n",  # tomllib parses it; the checks after it would not
}


@pytest.mark.parametrize("kind", DEEP)
@pytest.mark.parametrize(
    "args",
    [
        ["bench", "condenser", "--params", "deep.toml", "-o", "o.nc"],
        ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--params", "deep.toml", "-o", "o.nc"],
        ["simulate", "--scenario-file", "deep.toml", "-o", "o.nc"],
    ],
    ids=["bench-params", "simulate-params", "scenario-file"],
)
def test_a_deeply_nested_toml_file_is_one_line(tmp_path, kind, args):
    (tmp_path / "deep.toml").write_text(DEEP[kind])
    refused(tmp_path, *args, message="'deep.toml' nests tables or arrays more than 32 levels deep")


def test_toml_nested_as_deep_as_a_scenario_file_is_read(tmp_path):
    from evtms.params import read_params_toml

    (tmp_path / "s.toml").write_text("[a.b.c]\nx = [[1.0, 2.0], [3.0, 4.0]]\n")  # 5 levels
    assert read_params_toml(tmp_path / "s.toml")["a"]["b"]["c"]["x"][1] == [3.0, 4.0]


# --- Fluids CoolProp does not know, and LUTs that do not belong to their component --------------


@pytest.mark.parametrize("fluid", ["R999x", "R134a&R32"])  # unknown; a mixture without fractions
def test_a_direct_cycle_of_a_fluid_coolprop_cannot_load_is_one_line(tmp_path, fluid):
    (tmp_path / "bad.toml").write_text(f'fluid = "{fluid}"\n')
    refused(tmp_path, "cycle", "run", "--direct", "--params", "bad.toml", message=f"fluid {fluid!r}")


@pytest.fixture(scope="module")
def tiny_luts(tmp_path_factory):
    """The five cycle LUTs on two nodes per axis (valid files, too coarse to solve on)."""
    from evtms.benches import BENCHES
    from evtms.benches.grid import build_grid
    from evtms.benches.parameters import Parameters
    from evtms.benches.sweep import run_sweep
    from evtms.luts.io import write_lut

    folder = tmp_path_factory.mktemp("tiny_luts")
    for c in ("condenser", "evaporator", "expansion_valve", "compressor", "chiller"):
        bench = BENCHES[c]
        axes = {k: np.asarray(v[:2], float) for k, v in bench.presets["cycle"].items()}
        write_lut(run_sweep(bench, build_grid(bench, None, axes), Parameters(), grid_name="custom"), folder / f"{c}.nc")
    return folder


def _condenser_parameters(nc, params: dict, component: str) -> dict:
    with netCDF4.Dataset(Path(nc.filepath()).parent / "condenser.nc") as cond:
        return json.loads(cond.getncattr("parameters"))


def _set(**values):
    def edit(nc, params: dict, component: str) -> dict:
        params[component].update(values)
        return params

    return edit


def _backend(nc, params: dict, component: str) -> dict:
    return {**params, "backend": "XYZ"}


def _fluid_attribute(nc, params: dict, component: str) -> dict:
    nc.setncattr("fluid", "R999x")
    return params


PROVENANCE = {
    # id: (file, edit(nc, parsed parameters, component) -> parameters to write, message)
    "valve-holds-condenser-parameters": ("expansion_valve", _condenser_parameters, "unknown table or key 'condenser'"),
    "compressor-holds-condenser-parameters": ("compressor", _condenser_parameters, "unknown table or key 'condenser'"),
    "valve-parameter-out-of-range": ("expansion_valve", _set(port_diameter=-1), "port_diameter = -1 is not allowed"),
    "valve-unknown-parameter": ("expansion_valve", _set(n_tubes=40), "unknown parameter 'n_tubes'"),
    "unknown-backend": ("expansion_valve", _backend, 'backend = "XYZ" is not allowed'),
    "fluid-attribute-unlike-parameters": ("compressor", _fluid_attribute, "'fluid' is 'R999x'"),
}


@pytest.mark.parametrize("case", PROVENANCE)
def test_cycle_luts_whose_parameters_do_not_belong_are_one_line(tmp_path, tiny_luts, case):
    component, edit, message = PROVENANCE[case]
    luts = tmp_path / "luts"
    shutil.copytree(tiny_luts, luts)
    with netCDF4.Dataset(luts / f"{component}.nc", "a") as nc:
        params = edit(nc, json.loads(nc.getncattr("parameters")), component)
        nc.setncattr("parameters", json.dumps(params))
    line = refused(tmp_path, "cycle", "run", "--luts", "luts", message=message)
    assert f"{component}.nc" in line


def test_cycle_luts_of_two_fluids_are_one_line(tmp_path, tiny_luts):
    luts = tmp_path / "luts"
    shutil.copytree(tiny_luts, luts)
    with netCDF4.Dataset(luts / "compressor.nc", "a") as nc:
        params = json.loads(nc.getncattr("parameters"))
        nc.setncattr("parameters", json.dumps({**params, "fluid": "R1234yf"}))
        nc.setncattr("fluid", "R1234yf")
    refused(tmp_path, "cycle", "run", "--luts", "luts", message="'R1234yf' (compressor); allowed: one fluid")


# --- Model files whose arrays would inflate beyond what the reader allows -------------------------


def _zip_member(path: Path, name: str, header: dict, data_bytes: int) -> Path:
    """A zip holding one deflated ``.npy`` member: ``header`` and ``data_bytes`` zero bytes."""
    import zipfile

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open(name, "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(f, header)
            block = bytes(1 << 20)
            for start in range(0, data_bytes, len(block)):
                f.write(block[: min(len(block), data_bytes - start)])
    return path


def test_a_model_file_whose_array_inflates_past_the_limit_is_refused_unread(tmp_path):
    from evtms.surrogates.io import MAX_ARRAY_BYTES

    n = MAX_ARRAY_BYTES + (56 << 20)  # 256 MiB of zeros: a file of about 1 MB
    _zip_member(tmp_path / "m.npz", "format.npy", {"descr": "|u1", "fortran_order": False, "shape": (n,)}, n)
    args = ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--model", "surrogate", "--surrogates", "m.npz"]
    refused(tmp_path, *args, "-o", "o.nc", message=f"'format.npy' inflates to {n + 128:,} bytes")


def _load_error(path: Path) -> str:
    from evtms.errors import EvtmsInputError
    from evtms.surrogates.io import load_mode_models

    with pytest.raises(EvtmsInputError) as exc:
        load_mode_models(path)
    return str(exc.value)


def test_a_model_array_whose_header_claims_more_than_its_member_is_refused(tmp_path):
    path = _zip_member(tmp_path / "m.npz", "W0.npy", {"descr": "<f8", "fortran_order": False, "shape": (10**12,)}, 8)
    assert "declares shape (1000000000000,) of float64 (8,000,000,000,000 bytes)" in _load_error(path)


def test_model_arrays_of_python_objects_or_other_members_are_refused(tmp_path):
    import zipfile

    path = _zip_member(tmp_path / "o.npz", "attrs.npy", {"descr": "|O", "fortran_order": False, "shape": (1,)}, 8)
    assert "holds Python objects" in _load_error(path)
    with zipfile.ZipFile(tmp_path / "t.npz", "w") as zf:
        zf.writestr("readme.txt", "hello")
    assert "'readme.txt' is not a .npy array" in _load_error(tmp_path / "t.npz")


def test_a_model_file_evtms_wrote_reads_back_exactly(tmp_path):
    from evtms.surrogates.io import load_mode_models, save_mode_models
    from evtms.system import mode_model as mm

    rng = np.random.default_rng(1)

    def network(n_in: int, n_out: int) -> mm.Network:
        return mm.Network(
            "tanh",
            [rng.normal(size=(n_in, 4)), rng.normal(size=(4, n_out))],
            [rng.normal(size=4), rng.normal(size=n_out)],
            x_mean=rng.normal(size=n_in),
            x_scale=np.ones(n_in),
            y_mean=rng.normal(size=n_out),
            y_scale=np.ones(n_out),
            x_min=-np.ones(n_in),
            x_max=np.ones(n_in),
        )

    code = mm.MODE_CODES["bc"]
    models = mm.ModeModels(
        power={code: network(len(mm.POWER_FEATURES), 1)},
        dynamics={code: network(len(mm.DYNAMICS_FEATURES), len(mm.DYNAMICS_TARGETS))},
        attrs={"scenarios": {}, "metrics": {}},
    )
    back = load_mode_models(save_mode_models(models, tmp_path / "m.npz"))
    for a, b in zip(models.packed(), back.packed(), strict=True):
        assert np.array_equal(a, b) and a.dtype == b.dtype


# --- Ctrl-C while the cycle maps build ------------------------------------------------------------

_SLOW_MAPS = """
import os
import sys
import time
from pathlib import Path

import numpy as np

import evtms.system.maps as maps

# A slow solver (the workers are forked: they run it too) on chunks of 500 of the maps' 100,000
# nodes: 200 chunks of 30 s each, an hour on two workers if the build ran to its end. Each process
# that solves leaves a mark in the working folder as it starts its first chunk.
def slow(folder, topology, inputs):
    Path(f"solving-{os.getpid()}").touch()
    time.sleep(30.0)
    return {k: np.zeros(next(iter(inputs.values())).size) for k in maps._RESULT_KEYS}

maps._solve_in_worker = slow
maps.CHUNK_POINTS = 500
"""

_LOAD_MAPS = (
    _SLOW_MAPS
    + """
from evtms.errors import EvtmsInterrupted

print("building", flush=True)
try:
    maps.load_maps(sys.argv[1], workers=2)
except EvtmsInterrupted as exc:
    print(f"{type(exc).__name__}: {exc}; KeyboardInterrupt: {isinstance(exc, KeyboardInterrupt)}", flush=True)
    sys.exit(130)
"""
)

_CLI_MAPS = (
    _SLOW_MAPS
    + """
from evtms.cli import main

sys.argv[0] = "evtms"
main()
"""
)


def _interrupt_map_build(
    cwd: Path, script: str, *args: str, started: bytes, workers: int
) -> tuple[int, float, str, str]:
    """Run ``script args`` in its own process group, SIGINT the group (a terminal's Ctrl-C) once
    ``started`` appears in its output and ``workers`` processes are solving a chunk; (exit code,
    seconds from SIGINT to exit, stdout, stderr). Checks that none of its processes (the map
    workers) outlive it."""
    import os
    import signal
    import time

    from conftest import sigint_default

    out, err = cwd / "stdout.txt", cwd / "stderr.txt"
    with out.open("wb") as stdout, err.open("wb") as stderr:
        proc = subprocess.Popen(
            [sys.executable, "-c", script, *args],
            cwd=cwd,
            stdout=stdout,
            stderr=stderr,
            start_new_session=True,
            preexec_fn=sigint_default,
        )
        try:
            deadline = time.monotonic() + 120
            while started not in out.read_bytes() + err.read_bytes() or len(list(cwd.glob("solving-*"))) < workers:
                assert proc.poll() is None and time.monotonic() < deadline, err.read_text()
                time.sleep(0.05)
            time.sleep(0.2)  # the workers in the middle of a chunk (30 s each)
            sent = time.monotonic()
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=60)
            stopped = time.monotonic() - sent
            time.sleep(0.5)
            with pytest.raises(ProcessLookupError):  # no worker left in the group
                os.killpg(proc.pid, 0)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, stopped, out.read_text(), err.read_text()


def test_ctrl_c_while_the_cycle_maps_build_stops_at_once(tmp_path, tiny_luts):
    """Two workers build the maps when Ctrl-C comes: they are ended at once (a chunk saves nothing),
    no other chunk starts, and the build raises EvtmsInterrupted (a KeyboardInterrupt) saying what
    stopped."""
    shutil.copytree(tiny_luts, tmp_path / "luts")
    code, stopped, out, err = _interrupt_map_build(tmp_path, _LOAD_MAPS, "luts", started=b"building", workers=2)
    assert code == 130, (out, err)
    assert stopped < 10, stopped  # not the running chunks' 30 s, nor the 200 queued ones
    assert "EvtmsInterrupted: interrupted while building the cycle maps ac, chiller, ac+chiller of 'luts'" in out
    assert "KeyboardInterrupt: True" in out and "Traceback" not in err
    assert not list((tmp_path / "luts").glob("maps/*.nc"))


def test_ctrl_c_while_simulate_builds_the_maps_exits_130_at_once(tmp_path, tiny_luts):
    shutil.copytree(tiny_luts, tmp_path / "luts")
    args = ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", "luts", "-o", "o.nc"]
    code, stopped, out, err = _interrupt_map_build(
        tmp_path, _CLI_MAPS, *args, started=b"building cycle map", workers=min(2, os.cpu_count() or 1)
    )
    assert code == 130 and stopped < 10, (code, stopped, err)
    assert "Traceback" not in err and out == ""
    assert err.splitlines()[-1].startswith("error: interrupted while building the cycle maps"), err
    assert not (tmp_path / "o.nc").exists() and not list((tmp_path / "luts").glob("maps/*.nc"))
