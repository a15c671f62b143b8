"""Chunked, resumable, parallel sweeps: identical files, resume after a kill, bounded memory."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import netCDF4
import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.benches.partial import MAGIC, MARKER
from evtms.cli import app

runner = CliRunner()
GRID = [
    "-a",
    "mdot=0.004:0.008:4",
    "-a",
    "fan=0.1:1:3",
    "-a",
    "p_in=0.9:1.2:3MPa",
    "-a",
    "T_in=330:375:5",
    "-a",
    "T_res=300",
]  # 180 points
PER_RUN = ("created", "history")


def assert_same_lut(a, b):
    """Same variables, values and attributes, but for the creation time."""
    with netCDF4.Dataset(a) as x, netCDF4.Dataset(b) as y:
        assert list(x.variables) == list(y.variables)
        for name in x.variables:
            np.testing.assert_array_equal(x.variables[name][:].filled(np.nan), y.variables[name][:].filled(np.nan))
            assert x.variables[name].ncattrs() == y.variables[name].ncattrs()
        for attr in x.ncattrs():
            if attr not in PER_RUN:
                assert x.getncattr(attr) == y.getncattr(attr), attr


@pytest.fixture(scope="module")
def local_cluster():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        worker_dashboard_address="127.0.0.1:0",
    )
    yield cluster
    cluster.close()


def test_in_process_workers_and_cluster_give_identical_files(tmp_path, local_cluster):
    files = {}
    for mode, extra in (
        ("in", []),
        ("workers", ["--workers", "2"]),
        ("cluster", ["--scheduler", local_cluster.scheduler_address]),
    ):
        files[mode] = tmp_path / f"{mode}.nc"
        res = runner.invoke(app, ["bench", "condenser", *GRID, "--chunk-points", "30", "-o", str(files[mode]), *extra])
        assert res.exit_code == 0, res.output
        assert "8 chunks (8 computed, 0 reused)" in res.stdout  # balanced: 4 x 2 slabs of 30 and 15 points
        assert ("(dask)" in res.stdout) == (mode != "in")
    assert_same_lut(files["in"], files["workers"])
    assert_same_lut(files["in"], files["cluster"])
    # Chunking changes nothing either: one chunk against eight.
    one = tmp_path / "one.nc"
    assert runner.invoke(app, ["bench", "condenser", *GRID, "-o", str(one)]).exit_code == 0
    assert_same_lut(files["in"], one)


def test_process_pool_runner_gives_the_in_process_file(tmp_path):
    """PoolRunner (what 'evtms demo' spreads the cycle evaporator's chunks with): the same file as
    a sweep in this process, each chunk saved by the worker that computed it."""
    from evtms.benches import BENCHES
    from evtms.benches.chunked import PoolRunner, sweep_to_file
    from evtms.benches.grid import build_grid
    from evtms.benches.parameters import Parameters

    bench = BENCHES["evaporator"]
    grid = build_grid(bench, "thesis", {})
    here, pooled = tmp_path / "here.nc", tmp_path / "pooled.nc"
    sweep_to_file(bench, grid, Parameters(), here, chunk_points=100)
    runner = PoolRunner(2)
    try:
        summary = sweep_to_file(bench, grid, Parameters(), pooled, chunk_points=100, runner=runner)
    finally:
        runner.close()
    assert summary.computed == summary.chunks > 2
    assert_same_lut(here, pooled)


def test_in_process_sweep_does_not_import_dask(tmp_path):
    code = (
        "import sys; from typer.testing import CliRunner; from evtms.cli import app;"
        f"r = CliRunner().invoke(app, ['bench', 'compressor', '-o', r'{tmp_path / 'c.nc'}']);"
        "assert r.exit_code == 0, r.output; assert 'dask' not in sys.modules and 'distributed' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_killed_sweep_resumes_and_recomputes_only_missing_chunks(tmp_path):
    out = tmp_path / "evap.nc"
    partial = tmp_path / "evap.nc.partial"
    grid = [
        "-a",
        "mdot=0.004:0.008:8",
        "-a",
        "blower=0.2:0.5:6",
        "-a",
        "p_in=0.1:0.25:5MPa",
        "-a",
        "T_in=250:275:20",
        "-a",
        "T_res=280",
    ]  # 4800 points
    cmd = [sys.executable, "-m", "evtms.cli", "bench", "evaporator", *grid, "--chunk-points", "100", "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(partial.glob("chunk_*.npy"))) < 8:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    saved = len(list(partial.glob("chunk_*.npy")))
    assert 8 <= saved < 48 and not out.exists()  # killed part-way, and no half-written output
    res = runner.invoke(app, ["bench", "evaporator", *grid, "--chunk-points", "100", "-o", str(out), "--resume"])
    assert res.exit_code == 0, res.output
    assert f"48 chunks ({48 - saved} computed, {saved} reused)" in res.stdout
    assert not partial.exists()
    fresh = tmp_path / "fresh.nc"
    assert runner.invoke(app, ["bench", "evaporator", *grid, "--chunk-points", "100", "-o", str(fresh)]).exit_code == 0
    assert_same_lut(out, fresh)


def test_resume_refuses_a_partial_sweep_of_other_inputs(tmp_path):
    out = tmp_path / "c.nc"
    partial = tmp_path / "c.nc.partial"
    partial.mkdir()
    (partial / MARKER).write_text(json.dumps({"magic": MAGIC}))  # an evtms partial folder
    (partial / "manifest.json").write_text(json.dumps({"bench": "condenser", "axes": {}}))
    (partial / "chunk_000000.npy").write_bytes(b"another sweep's chunk")
    res = runner.invoke(app, ["bench", "condenser", "-o", str(out), "--resume"])
    assert res.exit_code == 2 and "was made with other inputs" in res.stderr and not out.exists()
    # Its chunks are kept (and unlocked) for the user to decide.
    assert (partial / "chunk_000000.npy").read_bytes() == b"another sweep's chunk"
    assert not (partial / "lock.json").exists()


def _peak_rss_mb(points_per_axis: int, tmp_path) -> float:
    code = f"""
import resource
import numpy as np
from evtms.benches import BENCHES
from evtms.benches.chunked import sweep_to_file
from evtms.benches.parameters import Parameters
n = {points_per_axis}
grid = {{"mdot": np.linspace(0.004, 0.008, n), "fan": np.linspace(0.1, 1, n), "p_in": np.linspace(0.9e6, 1.2e6, n),
        "T_in": np.linspace(330, 375, n), "T_res": np.linspace(300, 330, 5)}}
sweep_to_file(BENCHES["condenser"], grid, Parameters(), r"{tmp_path}/m{points_per_axis}.nc")
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(res.stdout.strip().splitlines()[-1])


def test_peak_memory_does_not_grow_with_the_grid(tmp_path):
    small = _peak_rss_mb(10, tmp_path)  # 50,000 points
    # 417,605 points: holding its outputs alone would take about 28 MB more (77 bytes a point).
    large = _peak_rss_mb(17, tmp_path)
    assert large - small < 15.0, (small, large)


def test_a_worker_killed_mid_sweep_loses_nothing(tmp_path):
    distributed = pytest.importorskip("distributed")
    from evtms.benches import BENCHES
    from evtms.benches.chunked import DaskRunner, InProcessRunner, sweep_to_file
    from evtms.benches.parameters import Parameters

    grid = {
        "mdot": np.linspace(0.004, 0.008, 6),
        "blower": np.linspace(0.2, 0.5, 6),
        "p_in": np.linspace(0.1e6, 0.25e6, 6),
        "T_in": np.linspace(250, 275, 10),  # 54 chunks of 40: the kill comes after 4
        "T_res": np.array([280.0]),
    }
    dask = DaskRunner(workers=2)
    try:
        pids = dask.client.run(os.getpid)
        victim = next(iter(pids.values()))
        done = []

        def progress(finished, total):
            done.append(finished)

        result = {}
        worker = threading.Thread(
            target=lambda: result.update(
                s=sweep_to_file(
                    BENCHES["evaporator"],
                    grid,
                    Parameters(),
                    tmp_path / "d.nc",
                    runner=dask,
                    chunk_points=40,
                    progress=progress,
                )
            )
        )
        worker.start()
        while len(done) < 4 and worker.is_alive():
            time.sleep(0.01)
        os.kill(victim, signal.SIGKILL)  # the nanny restarts it; its tasks are rescheduled
        worker.join(timeout=180)
        assert not worker.is_alive() and result["s"].computed == result["s"].chunks
    finally:
        dask.close()
    sweep_to_file(
        BENCHES["evaporator"], grid, Parameters(), tmp_path / "ref.nc", runner=InProcessRunner(), chunk_points=40
    )
    assert_same_lut(tmp_path / "d.nc", tmp_path / "ref.nc")
    assert distributed is not None


def test_a_worker_saves_its_chunk_only_where_it_sees_the_partial_folder(tmp_path):
    from evtms.benches.chunked import ChunkPlan, _Job
    from evtms.benches.parameters import Parameters
    from evtms.benches.partial import TOKEN, save_chunk

    grid = {
        "mdot": np.array([0.004, 0.006]),
        "fan": np.array([0.5]),
        "p_in": np.array([1e6]),
        "T_in": np.array([340.0, 350.0]),
        "T_res": np.array([300.0]),
    }
    plan = ChunkPlan.for_grid((2, 1, 1, 2, 1), 2)  # two chunks of two points
    (tmp_path / TOKEN).write_text("this-sweep")
    seen = _Job("condenser", grid, Parameters(), plan, str(tmp_path), "this-sweep")(1)
    assert seen is None and (tmp_path / "chunk_000001.npy").exists()
    # Another sweep's token (a worker on another machine with a folder of that name):
    # the arrays travel back to the main process, which saves them.
    elsewhere = _Job("condenser", grid, Parameters(), plan, str(tmp_path), "other-sweep")(0)
    assert set(elsewhere) >= {"status", "Q", "h_out"} and not (tmp_path / "chunk_000000.npy").exists()
    save_chunk(tmp_path, 0, elsewhere)
    a, b = np.load(tmp_path / "chunk_000000.npy"), np.load(tmp_path / "chunk_000001.npy")
    assert a.shape == b.shape == (len(elsewhere), 2)
    np.testing.assert_array_equal(a[list(elsewhere).index("Q")], elsewhere["Q"])
