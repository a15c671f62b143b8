"""Concurrent and interrupted sweeps lose nothing (issue 12).

One sweep per output at a time (a lock naming the running one), evtms never
deletes or reuses a ``.partial`` it did not make, saved chunks are checked
on resume, Ctrl-C keeps the finished chunks, chunks are balanced, an
all-invalid grid writes nothing, a full disk is refused up front, and a
dask scheduler address is checked and bounded in time (loopback only here).
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from conftest import sigint_default
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.benches.chunked import ChunkPlan, SweepInterrupted, sweep_to_file
from evtms.benches.parameters import Parameters
from evtms.benches.partial import LOCK, MAGIC, MARKER, lock_partial
from evtms.cli import app
from evtms.errors import EvtmsInputError

CONDENSER = BENCHES["condenser"]
# 216 points; with 20 points per chunk: 18 slabs of 2 x 4 x 2 and 1 x 4 x 2 points.
GRID = {
    "mdot": np.array([0.004, 0.006, 0.008]),
    "fan": np.array([0.1, 0.55, 1.0]),
    "p_in": np.array([900000.0, 1050000.0, 1200000.0]),
    "T_in": np.array([330.0, 345.0, 360.0, 375.0]),
    "T_res": np.array([300.0, 310.0]),
}
CLI_AXES = [
    "-a",
    "mdot=0.004,0.006,0.008",
    "-a",
    "fan=0.1,0.55,1",
    "-a",
    "p_in=900000,1050000,1200000",
    "-a",
    "T_in=330,345,360,375",
    "-a",
    "T_res=300,310",
]  # the same values as GRID, exactly
CHUNK = 20
CHUNKS = 18


def read_lut(path: Path) -> dict[str, tuple[str, tuple[int, ...], bytes]]:
    """Every variable's dtype, shape and raw bytes (no masking or scaling)."""
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        return {name: (var.dtype.str, var.shape, np.asarray(var[...]).tobytes()) for name, var in nc.variables.items()}


def assert_bitwise_equal(a: Path, b: Path) -> None:
    x, y = read_lut(a), read_lut(b)
    assert list(x) == list(y)
    for name in x:
        assert x[name] == y[name], name


@pytest.fixture(scope="module")
def lone(tmp_path_factory) -> Path:
    """The LUT of GRID written by one sweep alone, in one chunk."""
    path = tmp_path_factory.mktemp("lone") / "lone.nc"
    sweep_to_file(CONDENSER, GRID, Parameters(), path)
    return path


def interrupted(out: Path, after: int) -> SweepInterrupted:
    """Sweep GRID to ``out`` and stop it with a KeyboardInterrupt after ``after`` chunks."""
    seen = []

    def progress(done: int, total: int) -> None:
        seen.append(done)
        if len(seen) > after:  # the first call reports the chunks of an earlier run
            raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, progress=progress)
    return info.value


# --- Balanced chunks ---------------------------------------------------------------------


def test_a_long_leading_axis_gets_few_balanced_chunks():
    plan = ChunkPlan.for_grid((200_000, 2, 2), 16384)
    assert plan.count == math.ceil(800_000 / 16384) == 49  # not 200,000 chunks of 4 points
    sizes = [plan.size(k) for k in range(plan.count)]
    assert sum(sizes) == 800_000 and max(sizes) <= 16384 and min(sizes) >= 16384 * 0.95
    assert plan.chunksizes == (plan.rows, 2, 2) and plan.slab_shape(0) == (plan.rows, 2, 2)


@pytest.mark.parametrize(
    ("shape", "chunk_points"),
    [((7, 5, 3), 4), ((7, 5, 3), 10), ((7, 5, 3), 16), ((7, 5, 3), 200), ((1, 9), 4), ((13,), 5), ((3, 1, 4, 2), 7)],
)
def test_chunks_are_contiguous_slabs_that_cover_the_grid(shape, chunk_points):
    plan = ChunkPlan.for_grid(shape, chunk_points)
    flat = np.arange(plan.points).reshape(shape)
    start = 0
    for k in range(plan.count):
        slab = flat[plan.slab(k)]
        assert slab.shape == plan.slab_shape(k) and plan.start(k) == start
        np.testing.assert_array_equal(slab.ravel(), np.arange(start, start + plan.size(k)))
        assert plan.size(k) <= chunk_points
        start += plan.size(k)
    assert start == plan.points
    # Balanced: the chunks hold more than half of chunk_points on average (or it is one chunk).
    assert plan.count == 1 or plan.points / plan.count > chunk_points / 2


def test_balanced_chunks_write_the_same_lut_with_matching_netcdf_chunks(tmp_path, lone):
    out = tmp_path / "c.nc"
    s = sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK)
    assert s.chunks == CHUNKS and s.computed == CHUNKS
    assert_bitwise_equal(out, lone)
    plan = ChunkPlan.for_grid(tuple(len(v) for v in GRID.values()), CHUNK)
    with netCDF4.Dataset(out) as nc:
        assert nc.variables["Q"].chunking() == list(plan.chunksizes) == [1, 1, 2, 4, 2]


# --- One sweep per output ----------------------------------------------------------------

GATED = """
import sys, time
from pathlib import Path
import numpy as np
from evtms.benches import BENCHES
from evtms.benches.chunked import sweep_to_file
from evtms.benches.parameters import Parameters

grid = {grid}
out, running, gate = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])

def progress(done, total):
    if done > 0 and not running.exists():
        running.touch()
        deadline = time.monotonic() + 120
        while not gate.exists() and time.monotonic() < deadline:
            time.sleep(0.01)

s = sweep_to_file(BENCHES["condenser"], grid, Parameters(), out, chunk_points={chunk}, progress=progress)
print(s.computed, s.chunks)
"""


def _wait_for(path: Path, proc: subprocess.Popen, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"{path} did not appear"
        time.sleep(0.02)


def test_a_second_sweep_to_the_same_output_refuses_naming_the_running_one(tmp_path, lone):
    out, running, gate = tmp_path / "same.nc", tmp_path / "running", tmp_path / "gate"
    grid = "{" + ", ".join(f"{k!r}: np.array({v.tolist()!r})" for k, v in GRID.items()) + "}"
    first = subprocess.Popen(
        [sys.executable, "-c", GATED.format(grid=grid, chunk=CHUNK), str(out), str(running), str(gate)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_for(running, first)  # it holds the lock and has saved a chunk; it waits at the gate
        # The second sweep from this process (another process than the first, as the lock sees it): a
        # process of its own would spend 2-3 s loading CoolProp before it reaches the lock.
        second = CliRunner().invoke(app, ["bench", "condenser", *CLI_AXES, "-q", "-o", str(out)])
        assert second.exit_code == 2, second.output
        line = second.stderr.strip()
        assert "\n" not in line and "another sweep" in line and "is running" in line
        assert f"pid {first.pid} " in line and f"on host {socket.gethostname()}" in line and "started " in line
        assert not out.exists()
    finally:
        gate.touch()
        stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert stdout.split() == [str(CHUNKS), str(CHUNKS)]  # undisturbed: every chunk computed once, by it
    assert not (tmp_path / "same.nc.partial").exists()
    assert_bitwise_equal(out, lone)


RACER = """
import json, sys, time
from pathlib import Path
from evtms.benches.partial import lock_partial
from evtms.errors import EvtmsInputError

partial, go, done, ready = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]), Path(sys.argv[4])
ready.touch()
while not go.exists():
    pass
try:
    lock, notes = lock_partial(partial, partial.with_suffix(""))
except EvtmsInputError as exc:
    print(json.dumps(["refused", str(exc)]), flush=True)
else:
    print(json.dumps(["locked", notes]), flush=True)
    while not done.exists():
        time.sleep(0.01)
    lock.release()
"""


@pytest.mark.parametrize("existing", [False, True])
def test_racing_sweeps_create_and_lock_the_partial_folder_exactly_once(tmp_path, existing):
    """Four processes start at the same instant: one gets the folder, the others name it."""
    for round_ in range(3):
        folder = tmp_path / f"r{round_}"
        folder.mkdir()
        partial, go, done = folder / "x.nc.partial", folder / "go", folder / "done"
        if existing:  # an interrupted sweep's folder, unlocked
            partial.mkdir()
            (partial / MARKER).write_text(json.dumps({"magic": MAGIC}))
        ready = [tmp_path / f"ready{round_}-{i}" for i in range(4)]  # outside the folder checked below
        procs = [
            subprocess.Popen(
                [sys.executable, "-c", RACER, str(partial), str(go), str(done), str(r)],
                stdout=subprocess.PIPE,
                text=True,
            )
            for r in ready
        ]
        # All four imported and spinning on the start signal (not a fixed wait, which a loaded machine can outlast).
        deadline = time.monotonic() + 120
        while not all(r.exists() for r in ready):
            assert all(p.poll() is None for p in procs) and time.monotonic() < deadline
            time.sleep(0.01)
        go.touch()
        results = []
        for proc in procs:
            results.append(json.loads(proc.stdout.readline()))
        done.touch()
        for proc in procs:
            proc.communicate(timeout=60)
        winners = [r for r in results if r[0] == "locked"]
        assert len(winners) == 1 and winners[0][1] == [], results
        locked_pid = procs[results.index(winners[0])].pid
        for verdict, message in results:
            if verdict == "refused":
                assert f"pid {locked_pid} " in message, message
        assert (partial / MARKER).exists() and not (partial / LOCK).exists()  # released at the end
        assert sorted(p.name for p in folder.iterdir()) == ["done", "go", "x.nc.partial"]  # no staging left


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _write_lock(partial: Path, pid: int, host: str, started: float) -> None:
    record = {"pid": pid, "host": host, "started": started, "started_at": "2020-01-01T00:00:00+00:00"}
    (partial / LOCK).write_text(json.dumps(record))


def test_a_stale_lock_is_taken_over_and_reported(tmp_path, lone):
    out = tmp_path / "c.nc"
    stop = interrupted(out, after=3)
    dead = _dead_pid()
    _write_lock(stop.partial, dead, socket.gethostname(), time.time() - 3600)
    s = sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, resume=True)
    assert s.reused == 3 and s.computed == CHUNKS - 3
    assert len(s.notes) == 1 and "took over the lock" in s.notes[0] and f"process {dead} is not running" in s.notes[0]
    assert not stop.partial.exists()
    assert_bitwise_equal(out, lone)


def test_a_lock_whose_pid_is_now_a_later_process_is_stale(tmp_path):
    out = tmp_path / "c.nc"
    stop = interrupted(out, after=1)
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        time.sleep(0.2)
        _write_lock(stop.partial, sleeper.pid, socket.gethostname(), time.time() - 3600)  # locked before it started
        lock, notes = lock_partial(stop.partial, out)
        lock.release()
    finally:
        sleeper.kill()
        sleeper.wait()
    assert len(notes) == 1 and "now a later process" in notes[0]


@pytest.mark.parametrize("where", ["another host", "a live process"])
def test_a_lock_that_may_be_live_is_never_taken_over(tmp_path, where):
    out = tmp_path / "c.nc"
    stop = interrupted(out, after=2)
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        time.sleep(0.2)
        if where == "another host":
            _write_lock(stop.partial, 12345, "some-other-host", time.time())
        else:  # alive, on this host, started before the lock: its flock may not work here (a network mount)
            _write_lock(stop.partial, sleeper.pid, socket.gethostname(), time.time() + 5)
        before = (stop.partial / LOCK).read_bytes()
        with pytest.raises(EvtmsInputError) as info:
            sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, resume=True)
    finally:
        sleeper.kill()
        sleeper.wait()
    message = str(info.value)
    assert "\n" not in message and "another sweep" in message and f"delete {str(stop.partial / LOCK)!r}" in message
    assert (stop.partial / LOCK).read_bytes() == before and len(list(stop.partial.glob("chunk_*.npy"))) == 2


# --- Ownership of the partial folder -----------------------------------------------------


def _foreign(kind: str, partial: Path, tmp_path: Path) -> None:
    if kind == "folder":
        partial.mkdir()
        (partial / "thesis.tex").write_text("my work")
        (partial / "manifest.json").write_text("{}")
    elif kind == "file":
        partial.write_text("my work")
    else:  # a symbolic link, even to an evtms partial folder
        target = tmp_path / "elsewhere"
        target.mkdir()
        (target / MARKER).write_text(json.dumps({"magic": MAGIC}))
        (target / "thesis.tex").write_text("my work")
        partial.symlink_to(target)


def _snapshot(tmp_path: Path) -> dict[str, bytes | str]:
    return {
        str(p.relative_to(tmp_path)): os.readlink(p) if p.is_symlink() else p.read_bytes() if p.is_file() else "dir"
        for p in sorted(tmp_path.rglob("*"))
    }


@pytest.mark.parametrize("resume", [False, True])
@pytest.mark.parametrize("kind", ["folder", "file", "symlink"])
def test_a_partial_that_evtms_did_not_make_is_never_deleted_nor_reused(tmp_path, kind, resume):
    out = tmp_path / "c.nc"
    partial = tmp_path / "c.nc.partial"
    _foreign(kind, partial, tmp_path)
    before = _snapshot(tmp_path)
    with pytest.raises(EvtmsInputError) as info:
        sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, resume=resume)
    message = str(info.value)
    assert "\n" not in message and str(partial) in message and "move it away" in message
    assert _snapshot(tmp_path) == before  # untouched, and no output


# --- Checksums and Ctrl-C ----------------------------------------------------------------


def test_ctrl_c_keeps_the_chunks_releases_the_lock_and_resumes(tmp_path, lone):
    out = tmp_path / "c.nc"
    stop = interrupted(out, after=4)
    assert (stop.kept, stop.total, stop.partial) == (4, CHUNKS, tmp_path / "c.nc.partial")
    assert "4 of 18 chunks" in str(stop)
    assert len(list(stop.partial.glob("chunk_*.npy"))) == 4 and len(list(stop.partial.glob("chunk_*.sha256"))) == 4
    assert not (stop.partial / LOCK).exists() and not (stop.partial / "lut.nc.tmp").exists() and not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.nc.partial"]
    s = sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, resume=True)
    assert (s.reused, s.computed, s.damaged, s.notes) == (4, CHUNKS - 4, 0, [])
    assert_bitwise_equal(out, lone)


def test_a_damaged_chunk_is_recomputed_on_resume(tmp_path, lone):
    out = tmp_path / "c.nc"
    stop = interrupted(out, after=5)
    chunks = sorted(stop.partial.glob("chunk_*.npy"))
    flipped = bytearray(chunks[1].read_bytes())
    flipped[-3] ^= 0x01  # one bit of one value: the file still loads with the right shape
    chunks[1].write_bytes(bytes(flipped))
    chunks[3].with_suffix(".sha256").unlink()  # a chunk without its checksum
    chunks[4].write_bytes(chunks[4].read_bytes()[:100])  # truncated
    s = sweep_to_file(CONDENSER, GRID, Parameters(), out, chunk_points=CHUNK, resume=True)
    assert (s.reused, s.damaged, s.computed) == (2, 3, CHUNKS - 2)
    assert any("3 saved chunk(s) failed their checksum" in note for note in s.notes)
    assert_bitwise_equal(out, lone)


def test_sigint_to_a_cli_sweep_leaves_a_resumable_state(tmp_path):
    out = tmp_path / "evap.nc"
    partial = tmp_path / "evap.nc.partial"
    axes = ["-a", "mdot=0.004:0.008:8", "-a", "blower=0.2:0.5:6", "-a", "p_in=0.1:0.25:5MPa"]
    axes += ["-a", "T_in=250:275:20", "-a", "T_res=280"]  # 4800 points, 48 chunks of 100
    args = ["bench", "evaporator", *axes, "--chunk-points", "100", "-q"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "evtms.cli", *args, "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=sigint_default,  # interruptible even where the test run ignores SIGINT
    )
    deadline = time.monotonic() + 120
    while not list(partial.glob("chunk_*.npy")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=60)
    assert proc.returncode != 0  # 130 once the CLI turns SweepInterrupted into its exit code
    saved = len(list(partial.glob("chunk_*.npy")))
    assert 1 <= saved < 48 and not out.exists()
    assert not (partial / LOCK).exists() and not (partial / "lut.nc.tmp").exists()
    runner = CliRunner()
    res = runner.invoke(app, [*args, "-o", str(out), "--resume"])
    assert res.exit_code == 0, res.output
    assert f"48 chunks ({48 - saved} computed, {saved} reused)" in res.stdout
    assert not partial.exists()
    fresh = tmp_path / "fresh.nc"
    assert runner.invoke(app, [*args, "-o", str(fresh)]).exit_code == 0
    assert_bitwise_equal(out, fresh)


# --- Inputs that cannot give a LUT -------------------------------------------------------


def test_a_sweep_of_only_invalid_points_writes_nothing(tmp_path):
    grid = {
        "mdot": np.array([0.004, 0.005, 0.006]),
        "fan": np.array([0.5]),
        "p_in": np.array([0.9e6, 1.0e6, 1.1e6]),
        "T_in": np.array([280.0, 290.0, 295.0]),  # colder than the 300 K air
        "T_res": np.array([300.0]),
    }
    out = tmp_path / "c.nc"
    with pytest.raises(EvtmsInputError) as info:
        sweep_to_file(CONDENSER, grid, Parameters(), out, chunk_points=4)
    assert str(info.value) == (
        "every one of the 27 points is invalid: 27 refrigerant_inlet_not_warmer_than_air; "
        "check the axis values and units"
    )
    assert list(tmp_path.iterdir()) == []  # no LUT, no partial folder


def test_a_sweep_that_would_not_fit_on_the_disk_is_refused(tmp_path, monkeypatch):
    import shutil

    from evtms.benches import chunked

    real = shutil.disk_usage

    def nearly_full(path):
        usage = real(path)
        return type(usage)(usage.total, usage.total - 10_000, 10_000)

    monkeypatch.setattr(chunked.shutil, "disk_usage", nearly_full)
    with pytest.raises(EvtmsInputError) as info:
        sweep_to_file(CONDENSER, GRID, Parameters(), tmp_path / "c.nc")
    message = str(info.value)
    variables = len([n for n in CONDENSER.outputs if n not in GRID])
    lut = 216 * (8 * (variables - 1) + 1)
    assert "\n" not in message and f"LUT {lut / 1000:.1f} kB" in message and "only 10.0 kB is free" in message
    assert list(tmp_path.iterdir()) == []


# --- dask: loopback only, and a scheduler that does not answer ---------------------------


@pytest.mark.parametrize(
    "address",
    ["10.0.0.5:8786", "tls://10.0.0.5:8786", "tcp://10.0.0.5", "tcp://10.0.0.5:99999", "tcp://host:80/x", "tcp:// h:1"],
)
def test_a_malformed_scheduler_address_is_refused(address):
    from evtms.benches.chunked import DaskRunner

    with pytest.raises(EvtmsInputError) as info:
        DaskRunner(scheduler=address)
    assert "\n" not in str(info.value) and repr(address) in str(info.value) and "tcp://host:port" in str(info.value)


@pytest.fixture
def silent_server():
    """A loopback TCP server that accepts connections and never says a word."""
    server = socket.create_server(("127.0.0.1", 0))
    accepted = []

    def serve() -> None:
        while True:
            try:
                accepted.append(server.accept()[0])
            except OSError:
                return

    threading.Thread(target=serve, daemon=True).start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    server.close()
    for conn in accepted:
        conn.close()


@pytest.fixture
def closed_port():
    """A loopback port with nothing listening."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"tcp://127.0.0.1:{port}"


@pytest.mark.parametrize("peer", ["closed_port", "silent_server"])
def test_an_unreachable_scheduler_fails_within_15_s(peer, request, monkeypatch):
    pytest.importorskip("distributed")
    from evtms.benches import chunked
    from evtms.benches.chunked import DaskRunner

    # The library waits CONNECT_SECONDS (10 s); here 2 s, so that both peers cost 4 s, not 20.
    assert chunked.CONNECT_SECONDS <= 15.0
    monkeypatch.setattr(chunked, "CONNECT_SECONDS", 2.0)
    address = request.getfixturevalue(peer)
    t0 = time.monotonic()
    with pytest.raises(EvtmsInputError) as info:
        DaskRunner(scheduler=address)
    assert time.monotonic() - t0 < 7.0  # the behaviour under test: it gives up after the connect timeout
    message = str(info.value)
    assert "\n" not in message and f"cannot reach the dask scheduler {address!r}" in message


def test_the_local_cluster_listens_on_loopback_only():
    pytest.importorskip("distributed")
    import psutil

    from evtms.benches.chunked import DaskRunner

    runner = DaskRunner(workers=1)
    try:
        info = runner.client.scheduler_info()
        assert runner.client.scheduler.address.startswith("tcp://127.0.0.1:")
        assert all(w.startswith("tcp://127.0.0.1:") for w in info["workers"])
        assert runner._cluster.dashboard_link.startswith("http://127.0.0.1:")
        pids = [os.getpid(), *runner.client.run(os.getpid).values()]
        pids += [psutil.Process(pid).ppid() for pid in pids[1:]]  # the nannies
        listening = {
            (pid, c.laddr.ip)
            for pid in set(pids)
            for c in psutil.Process(pid).net_connections(kind="inet")
            if c.status == psutil.CONN_LISTEN
        }
        assert {ip for _, ip in listening} == {"127.0.0.1"}, listening
        assert len({pid for pid, _ in listening}) >= 2  # the worker's own sockets were seen too
    finally:
        runner.close()


def test_closing_the_cluster_after_an_interrupt_logs_nothing(caplog):
    """What dask and tornado log while a cluster stops must not follow the one 'error:' line."""
    import logging

    from evtms.benches.chunked import DaskRunner

    class Noisy:
        def close(self):
            logging.getLogger("tornado.application").error("Exception in callback ... KeyboardInterrupt")
            logging.getLogger("distributed.scheduler").warning("Removing worker ... lost computed tasks")

    runner = object.__new__(DaskRunner)  # the close path alone: no cluster needed
    runner.client, runner._cluster = Noisy(), Noisy()
    with caplog.at_level(logging.DEBUG):
        runner.close()
        assert caplog.records == []
        logging.getLogger("evtms.test").warning("after")  # logging is back on once closed
    assert [r.getMessage() for r in caplog.records] == ["after"]


_ENSURE_LUTS_SCRIPT = """
import sys
from pathlib import Path

import evtms.workflows.demo as demo
from evtms.benches import BENCHES
from evtms.benches.parameters import Parameters

# A grid of 4,800 evaporator points outweighs the compressor's 36: ensure_luts sweeps it in
# chunks over two PoolRunner workers while one more process sweeps the compressor.
BENCHES["evaporator"].presets["big"] = {
    "mdot": tuple(0.004 + 0.0005 * i for i in range(8)),
    "blower": (0.2, 0.26, 0.32, 0.38, 0.44, 0.5),
    "p_in": (0.1e6, 0.14e6, 0.18e6, 0.22e6, 0.25e6),
    "T_in": tuple(250.0 + 1.25 * i for i in range(20)),
    "T_res": (280.0,),
}
BENCHES["compressor"].presets["big"] = BENCHES["compressor"].presets["thesis"]
demo._components = lambda: ["evaporator", "compressor"]
import evtms.benches.chunked as chunked
_sweep = chunked.sweep_to_file  # 48 chunks of 100 points: time to interrupt it
chunked.sweep_to_file = lambda *a, **k: _sweep(*a, **{**k, "chunk_points": 100})
try:
    demo.ensure_luts(Path(sys.argv[1]), "big", Parameters(), workers=2)
except KeyboardInterrupt:
    print("interrupted")
    sys.exit(130)
print("done")
"""


def test_sigint_to_ensure_luts_spreading_one_grid_stops_promptly(tmp_path):
    """Ctrl-C while ensure_luts spreads its largest grid over PoolRunner workers: KeyboardInterrupt
    soon (not after the other LUTs), the saved chunks kept for a resume, no lock left behind."""
    folder = tmp_path / "luts"
    partial = folder / "evaporator.nc.partial"
    proc = subprocess.Popen(
        [sys.executable, "-c", _ENSURE_LUTS_SCRIPT, str(folder)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=sigint_default,
    )
    deadline = time.monotonic() + 120
    while not list(partial.glob("chunk_*.npy")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, (out, err)
    assert b"interrupted" in out
    saved = len(list(partial.glob("chunk_*.npy")))
    assert 1 <= saved < 48 and not (folder / "evaporator.nc").exists()
    assert not (partial / LOCK).exists()
    # Uninterrupted, this path writes every cycle LUT the suite's LUT tests use (conftest's background job).
