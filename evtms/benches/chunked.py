"""Sweeps that scale: chunked, written as chunks finish, resumable, parallel with dask.

A grid is cut into balanced chunks of about ``chunk_points`` points each: a
chunk spans whole trailing axes and a range of indices along the innermost of
the other ("leading") axes, so it is both a contiguous range of the flat grid
and a rectangular slab of the LUT (and the file's netCDF chunks are those
slabs). Each finished chunk is saved at once (atomically, with its SHA-256
beside it, checked on resume) in a
``<output>.partial`` folder beside the output, with a manifest of the sweep's
inputs, by the process that computed it when that process sees the folder
(local workers, a cluster on a shared file system), else by the main process;
``resume=True`` reuses the chunks of an interrupted sweep with the same
manifest and computes only the missing ones. The main process writes each
chunk into the netCDF file as it finishes (a temporary file in the partial
folder, renamed over the output when the last chunk is in), so writing
overlaps computing and memory is bounded by the chunk size and the number of
chunks in flight, not by the grid.

Runners compute chunks: :class:`InProcessRunner` (plain NumPy, no dask
import) and :class:`DaskRunner` (a ``dask.distributed`` client: local worker
processes or an existing cluster). Every mode evaluates the same points with
the same code, so the files are identical but for their creation time. A
dask worker that dies mid-chunk loses nothing: the scheduler reruns its task
elsewhere (and ``retries`` reruns tasks that raised).

The partial folder is evtms's own: it holds an ownership marker
(``evtms-partial.json``), and a folder of that name without it (or a file, or
a symbolic link) is never deleted nor reused. A sweep holds an exclusive lock
on it (``lock.json``: pid, host and start time, created atomically, plus an
``flock``), so a second sweep to the same output refuses while the first
runs; a lock whose process is gone is taken over (and reported in
:attr:`SweepSummary.notes`). Ctrl-C keeps the saved chunks and raises
:class:`SweepInterrupted`.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import io
import json
import logging
import math
import os
import re
import shutil
import socket
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: the lock file and the pid check alone
    fcntl = None

import numpy as np

from evtms import __version__
from evtms.benches.base import Bench
from evtms.errors import EvtmsInputError
from evtms.luts.io import LutStorage
from evtms.params import Parameters

Progress = Callable[[int, int], None]
DEFAULT_CHUNK_POINTS = 16384
#: Chunks in flight per dask worker: enough to keep each busy while results come back.
WINDOW = 3


@dataclass(frozen=True)
class ChunkPlan:
    """How a grid of ``shape`` is cut into balanced chunks, each a contiguous slab.

    The last ``len(shape) - lead`` axes ("trailing") are whole in every chunk;
    a chunk spans ``rows`` indices (fewer in the last piece) along axis
    ``lead - 1``, the innermost leading axis, and one index along the axes
    before it. So a chunk is a contiguous range of the flat grid (C order)
    and a rectangular slab of the LUT, and a grid with a long leading axis
    and short trailing ones still gets chunks of about ``chunk_points``.

    Attributes
    ----------
    shape : tuple of int
        Grid shape.
    lead : int
        Number of leading axes (0: the whole grid is one chunk).
    rows : int
        Indices of axis ``lead - 1`` per chunk (1 when ``lead`` is 0).
    """

    shape: tuple[int, ...]
    lead: int
    rows: int = 1

    @classmethod
    def for_grid(cls, shape: tuple[int, ...], chunk_points: int) -> ChunkPlan:
        """Balanced chunks of at most ``chunk_points`` points (at least one point).

        Parameters
        ----------
        shape : tuple of int
            Grid shape (every axis at least one long).
        chunk_points : int
            Most points per chunk; values below 1 count as 1.

        Returns
        -------
        ChunkPlan
            The fewest trailing axes that fit whole, cut along the next axis
            into pieces of equal length (the last one may be shorter).
        """
        shape = tuple(int(n) for n in shape)
        target = max(int(chunk_points), 1)
        lead = next(i for i in range(len(shape) + 1) if math.prod(shape[i:]) <= target)
        if lead == 0:
            return cls(shape, 0, 1)
        span = shape[lead - 1]
        rows = max(min(span, target // math.prod(shape[lead:])), 1)
        pieces = -(-span // rows)
        return cls(shape, lead, -(-span // pieces))  # the same pieces, as even as they go

    @property
    def trailing(self) -> tuple[int, ...]:
        """Shape of the axes that are whole in every chunk."""
        return self.shape[self.lead :]

    @property
    def pieces(self) -> int:
        """Chunks along axis ``lead - 1`` (1 when ``lead`` is 0)."""
        return -(-self.shape[self.lead - 1] // self.rows) if self.lead else 1

    @property
    def block(self) -> int:
        """Points of a full chunk (the largest)."""
        return self.rows * math.prod(self.trailing) if self.lead else self.points

    @property
    def count(self) -> int:
        return math.prod(self.shape[: self.lead - 1]) * self.pieces if self.lead else 1

    @property
    def points(self) -> int:
        return math.prod(self.shape)

    @property
    def chunksizes(self) -> tuple[int, ...]:
        """netCDF chunk shape of the LUT's variables: one chunk's slab."""
        return (1,) * (self.lead - 1) + (self.rows,) + self.trailing if self.lead else self.shape

    def _rows(self, k: int) -> tuple[int, int, int]:
        """(outer flat index, first row, end row) of chunk ``k``."""
        if not 0 <= k < self.count:
            raise IndexError(f"chunk {k} is not in 0..{self.count - 1}")
        outer, piece = divmod(k, self.pieces)
        first = piece * self.rows
        return outer, first, min(first + self.rows, self.shape[self.lead - 1]) if self.lead else 1

    def index(self, k: int) -> tuple[int | slice, ...]:
        """Leading index of chunk ``k``: ints, then a slice of axis ``lead - 1`` (its slab is ``index + (...,)``)."""
        if not self.lead:
            self._rows(k)
            return ()
        outer, first, end = self._rows(k)
        head = tuple(int(i) for i in np.unravel_index(outer, self.shape[: self.lead - 1])) if self.lead > 1 else ()
        return head + (slice(first, end),)

    def slab(self, k: int) -> tuple[int | slice, ...]:
        """Full index of chunk ``k`` in an array of ``shape``."""
        return self.index(k) + (slice(None),) * len(self.trailing)

    def slab_shape(self, k: int) -> tuple[int, ...]:
        """Shape of chunk ``k``'s slab (its flat points reshape to it)."""
        if not self.lead:
            return self.shape
        _, first, end = self._rows(k)
        return (end - first,) + self.trailing

    def start(self, k: int) -> int:
        """Flat index (C order) of chunk ``k``'s first point."""
        if not self.lead:
            self._rows(k)
            return 0
        outer, first, _ = self._rows(k)
        return (outer * self.shape[self.lead - 1] + first) * math.prod(self.trailing)

    def size(self, k: int) -> int:
        """Points in chunk ``k``."""
        return math.prod(self.slab_shape(k))


def _fluid_for(params: Parameters):
    """One Fluid per process and backend (building it imports CoolProp, about 2 s)."""
    from evtms.fluid import Fluid

    key = (params.fluid, params.backend)
    cache = _fluid_for.__dict__.setdefault("cache", {})
    if key not in cache:
        cache[key] = Fluid(*key)
    return cache[key]


def compute_chunk(
    bench_name: str, grid: dict[str, np.ndarray], params: Parameters, plan: ChunkPlan, k: int
) -> dict[str, np.ndarray]:
    """Evaluate chunk ``k`` of a sweep: flat output arrays of ``plan.size(k)`` points."""
    from evtms.benches import BENCHES
    from evtms.benches.sweep import grid_points

    bench = BENCHES[bench_name]
    start = plan.start(k)
    inputs = grid_points(grid, start, start + plan.size(k))
    out = bench.evaluate(inputs, params, _fluid_for(params))
    return {name: out[name] for name in bench.outputs if name not in grid}


def _warm_up() -> None:
    """Build the default fluid in this worker process (imports CoolProp)."""
    _fluid_for(Parameters())


class InProcessRunner:
    """Compute chunks one after the other in this process."""

    name = "in-process"
    workers = 1

    def run(self, job: Callable[[int], dict], chunks: Iterable[int]) -> Iterator[tuple[int, dict]]:
        for k in chunks:
            yield k, job(k)

    def close(self) -> None:
        pass


class DaskRunner:
    """Compute chunks on a ``dask.distributed`` cluster, at most ``window`` in flight.

    Parameters
    ----------
    workers : int, optional
        Start a local cluster of that many single-threaded worker processes.
    scheduler : str, optional
        Address of an existing scheduler, ``tcp://host:port``, e.g. ``tcp://10.0.0.5:8786``.
        It must answer within :data:`CONNECT_SECONDS`. A local cluster
        listens on 127.0.0.1 only (scheduler, workers and dashboards).

    Raises
    ------
    EvtmsInputError
        dask is not installed, the address is not ``tcp://host:port``, or no
        dask scheduler answers there in time.
    """

    name = "dask"

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
        if scheduler is not None:
            check_scheduler_address(scheduler)
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise EvtmsInputError("parallel sweeps need dask: pip install 'evtms[dask]'") from None
        import dask.config

        self._cluster = None
        # Worker processes of a local cluster (also those a nanny restarts after a
        # crash, hence set for the process, not just around the start):
        # - glibc trims the malloc heap of the thread a task runs in (not the main
        #   thread) as soon as its top is free, so the benches' many chunk-sized
        #   temporaries fault their pages in again for every array: about 15 % slower
        #   than in the main thread. A 64 MiB trim threshold and 16 MiB top pad keep
        #   them (dask's own 64 KiB trim threshold made it 1.7x slower).
        # - dask's statistical profiler samples every task thread's stack every
        #   10 ms, for the dashboard: off.
        # - Ctrl-C is the main process's business (it keeps the saved chunks and says how
        #   to resume): the workers' own logging stays at errors, so that stopping them
        #   does not bury that line under their warnings.
        environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
        environ.update(
            MALLOC_TRIM_THRESHOLD_=str(64 << 20), MALLOC_TOP_PAD_=str(16 << 20), DASK_LOGGING__DISTRIBUTED="error"
        )
        dask.config.set({"distributed.nanny.pre-spawn-environ": environ, "distributed.worker.profile.enabled": False})
        if scheduler is not None:
            # distributed's own connect waits forever for the handshake of a peer that
            # accepts the connection but never speaks: a bounded probe first.
            problem = _probe_scheduler(scheduler, CONNECT_SECONDS)
            if problem is None:
                try:
                    self.client = Client(scheduler, timeout=f"{CONNECT_SECONDS:g}s")
                except (OSError, TimeoutError, ValueError) as exc:
                    problem = _one_line(exc)
            if problem is not None:
                raise EvtmsInputError(
                    f"cannot reach the dask scheduler {scheduler!r} within {CONNECT_SECONDS:g} s ({problem}); "
                    "check the address and that the scheduler runs"
                )
        else:
            # Loopback only: the scheduler, the workers and their dashboards. The workers
            # ignore SIGINT (evtms.benches.dask_worker), so a Ctrl-C sent to the whole
            # process group interrupts only this process, which then closes the cluster.
            preload = list(dask.config.get("distributed.worker.preload", []))
            with dask.config.set({"distributed.worker.preload": [*preload, "evtms.benches.dask_worker"]}):
                self._cluster = LocalCluster(
                    n_workers=workers or 1,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address="127.0.0.1:0",
                    worker_dashboard_address="127.0.0.1:0",
                    silence_logs=logging.ERROR,
                )
            self.client = Client(self._cluster)
        self.workers = max(len(self.client.scheduler_info().get("workers", {})), 1)
        # Import CoolProp (about 2 s) on every worker now, not inside its first chunk.
        self.client.run(_warm_up)

    def run(self, job: Callable[[int], dict], chunks: Iterable[int]) -> Iterator[tuple[int, dict]]:
        from distributed import as_completed

        pending = list(chunks)
        window = WINDOW * self.workers
        futures = {}
        queue = as_completed()
        while pending and len(futures) < window:
            k = pending.pop(0)
            fut = self.client.submit(job, k, key=f"evtms-chunk-{k}-{time.monotonic_ns()}", retries=3, pure=False)
            futures[fut] = k
            queue.add(fut)
        for fut in queue:
            k = futures.pop(fut)
            result = fut.result()
            fut.release()
            if pending:
                nk = pending.pop(0)
                nf = self.client.submit(job, nk, key=f"evtms-chunk-{nk}-{time.monotonic_ns()}", retries=3, pure=False)
                futures[nf] = nk
                queue.add(nf)
            yield k, result

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


#: Seconds a ``--scheduler`` address has to answer (connection and handshake).
CONNECT_SECONDS = 10.0
_SCHEDULER_ADDRESS = re.compile(
    r"^tcp://(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]{0,251}[A-Za-z0-9])?):(?P<port>[0-9]{1,5})$"
)


def check_scheduler_address(address: str) -> str:
    """Return ``address`` if it is ``tcp://host:port``.

    Parameters
    ----------
    address : str
        A dask scheduler address, e.g. ``tcp://10.0.0.5:8786``.

    Returns
    -------
    str
        The address, unchanged.

    Raises
    ------
    EvtmsInputError
        Another form (another protocol, no port, a path, spaces, a port above 65535).
    """
    m = _SCHEDULER_ADDRESS.match(address)
    if m is None or not 1 <= int(m["port"]) <= 65535:
        raise EvtmsInputError(
            f"scheduler address {address!r} is not allowed; allowed: tcp://host:port with a port 1-65535, "
            "e.g. tcp://10.0.0.5:8786"
        )
    return address


def _one_line(exc: BaseException) -> str:
    """An exception as one short line (its type when it has no message)."""
    text = " ".join(str(exc).split())
    return text[:200] if text else type(exc).__name__


def _probe_scheduler(address: str, seconds: float) -> str | None:
    """Connect to ``address``, handshake and ask its identity, all within ``seconds``.

    Runs in a thread of its own with a fresh event loop, so it is bounded
    even if the peer accepts the connection but never answers.

    Returns
    -------
    str or None
        What went wrong, or None when a dask scheduler answered.
    """

    async def identity() -> object:
        from distributed.comm import connect

        comm = await connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    async def bounded() -> object:
        import asyncio

        return await asyncio.wait_for(identity(), seconds)

    outcome: dict[str, object] = {}

    def run() -> None:
        import asyncio

        try:
            outcome["reply"] = asyncio.run(bounded())
        except BaseException as exc:  # reported to the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=run, name="evtms-scheduler-probe", daemon=True)
    thread.start()
    thread.join(seconds + 2.0)
    if thread.is_alive() or isinstance(outcome.get("error"), TimeoutError):
        return f"no answer within {seconds:g} s"
    if "error" in outcome:
        return _one_line(outcome["error"])
    reply = outcome.get("reply")
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        return "the server there is not a dask scheduler"
    return None


class _Job:
    """A picklable chunk job: the bench, its grid, the parameters and the plan.

    With ``partial`` and ``token``, a process that sees the partial folder
    (its ``token`` file holds ``token``: a local worker, or a cluster on a
    shared file system) saves the chunk there itself and returns None, so the
    chunk's arrays never travel back to the main process; elsewhere it
    returns the arrays.
    """

    def __init__(
        self,
        bench_name: str,
        grid: dict,
        params: Parameters,
        plan: ChunkPlan,
        partial: str | None = None,
        token: str | None = None,
    ) -> None:
        self.bench_name, self.grid, self.params, self.plan = bench_name, grid, params, plan
        self.partial, self.token = partial, token

    def __call__(self, k: int) -> dict[str, np.ndarray] | None:
        arrays = compute_chunk(self.bench_name, self.grid, self.params, self.plan, k)
        if self.partial is not None and _sees_folder(self.partial, self.token):
            _save_chunk(Path(self.partial), k, arrays)
            return None
        return arrays


def _sees_folder(folder: str, token: str | None) -> bool:
    """True if this process sees ``folder`` as the main process does (its token file matches).

    Checked again before every save (one small read): a task that outlives
    its sweep (a dask task cannot be stopped mid-run) must not write into the
    folder once a later sweep has taken it over with a token of its own. A
    folder not seen is remembered as such.
    """
    unseen = _sees_folder.__dict__.setdefault("unseen", set())
    key = (folder, token)
    if token is None or key in unseen:
        return False
    try:
        seen = (Path(folder) / _TOKEN).read_text() == token
    except OSError:
        seen = False
    if not seen:
        unseen.add(key)
    return seen


_TOKEN = "token"


@dataclass
class SweepSummary:
    """What a chunked sweep did.

    Attributes
    ----------
    path : Path
        The LUT written.
    points, chunks : int
        Grid points and chunks.
    computed, reused : int
        Chunks computed now, and reused from an interrupted sweep (``resume``).
    invalid : int
        Points whose status is not valid.
    seconds : float
        Wall time.
    runner : str
        ``in-process`` or ``dask``.
    damaged : int
        Saved chunks of an interrupted sweep that failed their checksum (or
        were incomplete) and were computed again.
    notes : list of str
        One-line remarks for the user (a stale lock taken over, damaged chunks).
    """

    path: Path
    points: int
    chunks: int
    computed: int
    reused: int
    invalid: int
    seconds: float
    runner: str
    damaged: int = 0
    notes: list[str] = field(default_factory=list)


class SweepInterrupted(Exception):  # noqa: N818 (not an error: the user stopped the sweep)
    """A sweep stopped by Ctrl-C (KeyboardInterrupt); its saved chunks are kept for ``resume``.

    Attributes
    ----------
    kept : int
        Chunks saved in the partial folder.
    total : int
        Chunks of the sweep.
    partial : Path
        The partial folder that holds them.
    """

    def __init__(self, kept: int, total: int, partial: Path) -> None:
        self.kept, self.total, self.partial = kept, total, Path(partial)
        super().__init__(f"sweep interrupted: {kept} of {total} chunks kept in {str(partial)!r}")


def _manifest(bench: Bench, grid: dict, params: Parameters, grid_name: str, plan: ChunkPlan) -> dict:
    from evtms.fluid import coolprop_version

    manifest = {
        "bench": bench.name,
        "grid_name": grid_name,
        "axes": {k: [float(x) for x in v] for k, v in grid.items()},
        "parameters": json.loads(params.component_json(bench.name)),
        "environment": json.loads(params.environment_json()),
        "evtms_version": __version__,
        "coolprop_version": coolprop_version(),
        "chunks": {"lead": plan.lead, "rows": plan.rows, "checksum": "sha256"},
    }
    return json.loads(json.dumps(manifest))  # as it reads back from disk (tuples become lists)


def _chunk_file(folder: Path, k: int) -> Path:
    return folder / f"chunk_{k:06d}.npy"


def _checksum_file(folder: Path, k: int) -> Path:
    return folder / f"chunk_{k:06d}.sha256"


def _write_atomically(path: Path, data: bytes | memoryview) -> None:
    """Write ``data`` to ``path`` through a temporary file of this process, renamed over it."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _save_chunk(folder: Path, k: int, arrays: dict[str, np.ndarray]) -> None:
    """Save chunk ``k`` atomically as one (variables, points) float64 array, in ``arrays``' order.

    One plain ``.npy`` per chunk: loading it parses one header (an ``.npz`` parses
    a zip directory and a header per variable, which the main process would pay
    for every chunk). The int8 status is exact in float64. The SHA-256 of the
    file's bytes goes beside it first (``chunk_k.sha256``), so a chunk file
    always has the checksum ``resume`` checks it against.
    """
    stacked = np.stack([np.asarray(a, np.float64) for a in arrays.values()])
    buffer = io.BytesIO()
    np.save(buffer, stacked)
    data = buffer.getbuffer()
    _write_atomically(_checksum_file(folder, k), hashlib.sha256(data).hexdigest().encode())
    _write_atomically(_chunk_file(folder, k), data)


def _done_chunks(folder: Path, plan: ChunkPlan, names: list[str]) -> tuple[set[int], int]:
    """Chunks of an interrupted sweep that are whole, and how many saved ones are not.

    A chunk is whole when its bytes match its saved SHA-256 and it holds
    ``names`` over the chunk's points; any other saved chunk (flipped bits, a
    truncated file, a missing checksum) is counted as damaged and recomputed.
    """
    done, damaged = set(), 0
    for f in folder.glob("chunk_*.npy"):
        try:
            k = int(f.stem.split("_")[1])
        except (IndexError, ValueError):
            continue
        if not 0 <= k < plan.count:
            continue
        try:
            data = f.read_bytes()
            expected = _checksum_file(folder, k).read_text().strip()
            whole = hashlib.sha256(data).hexdigest() == expected
            whole = whole and np.load(io.BytesIO(data), mmap_mode=None).shape == (len(names), plan.size(k))
        except (OSError, ValueError, UnicodeDecodeError):
            whole = False
        if whole:
            done.add(k)
        else:
            damaged += 1
    return done, damaged


def _saved_chunks(folder: Path) -> int:
    """Chunk files in ``folder`` (0 if it is gone)."""
    try:
        return sum(1 for _ in folder.glob("chunk_*.npy"))
    except OSError:
        return 0


# --- The partial folder: ownership marker and exclusive lock -------------------------------

_MARKER = "evtms-partial.json"
_MAGIC = "evtms chunked sweep state (a partial LUT): evtms may delete this folder"
_LOCK = "lock.json"
#: Own entries of a partial folder that a fresh (not resumed) sweep clears.
_STATE = ("manifest.json", _TOKEN, "lut.nc.tmp", "chunk_*.npy", "chunk_*.sha256", ".chunk_*")
#: Seconds to sort out a lock that is changing hands before giving up.
LOCK_SETTLE_SECONDS = 5.0


def _lock_record() -> dict:
    now = time.time()
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": now,
        "started_at": datetime.datetime.fromtimestamp(now).astimezone().isoformat(timespec="seconds"),
    }


def _describe(record: dict | None) -> str:
    if not record:
        return "pid unknown (its lock file is unreadable)"
    return f"pid {record.get('pid')} on host {record.get('host')}, started {record.get('started_at')}"


def _read_record(path: Path) -> dict | None:
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return record if isinstance(record, dict) else None


def _flock(fd: int) -> bool | None:
    """Try an exclusive ``flock`` on ``fd``: True taken, False held elsewhere, None unsupported here."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # a file system without flock (some network mounts)
        return None
    return True


def _same_file(fd: int, path: Path) -> bool:
    try:
        st = os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    own = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)


def _pid_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    except (OSError, OverflowError):
        return False
    return True


def _process_started(pid: int) -> float | None:
    """Start time (epoch seconds) of process ``pid`` from /proc, or None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        ticks = int(stat[stat.rindex(")") + 2 :].split()[19])
        boot = next(
            float(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines() if line.startswith("btime")
        )
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def _stale(record: dict | None) -> str | None:
    """Why the lock of ``record`` (whose flock nobody holds) is stale, or None if its sweep may run."""
    if record is None:
        return "its lock file is unreadable"
    if record.get("host") != socket.gethostname():
        return None  # no way to check a process on another machine
    pid, started = record.get("pid"), record.get("started")
    if not isinstance(pid, int) or not isinstance(started, (int, float)):
        return "its lock file is unreadable"
    if pid == os.getpid():
        return "this process left it behind"
    if not _pid_running(pid):
        return f"process {pid} is not running"
    began = _process_started(pid)
    if began is not None and began > started + 2.0:
        return f"process {pid} is not running (that pid is now a later process)"
    return None


class _Lock:
    """An exclusive lock on a partial folder: ``lock.json`` (our record) held with ``flock``."""

    def __init__(self, fd: int, path: Path) -> None:
        self.fd, self.path = fd, path

    def release(self) -> None:
        """Remove the lock file (if it is still ours) and drop the flock; idempotent."""
        if self.fd < 0:
            return
        if _same_file(self.fd, self.path):
            self.path.unlink(missing_ok=True)
        os.close(self.fd)
        self.fd = -1


def _new_lock(path: Path, replace: bool = False) -> _Lock | None:
    """Create lock file ``path`` with our record, already flocked; None if it exists (and not ``replace``).

    The record is written to a temporary file that is then linked (or, to take
    over, renamed) to ``path``: the lock file appears whole and held, never
    empty.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    try:
        _flock(fd)  # a new inode nobody else knows: always ours
        os.write(fd, json.dumps(_lock_record()).encode())
        os.fsync(fd)
        if replace:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                os.close(fd)
                return None
    except BaseException:
        with contextlib.suppress(OSError):
            os.close(fd)
        raise
    finally:
        tmp.unlink(missing_ok=True)
    return _Lock(fd, path)


def _check_owned(partial: Path) -> None:
    """Raise unless ``partial`` is a real folder with evtms's ownership marker."""
    hint = "move it away (evtms never deletes nor reuses it)"
    if partial.is_symlink():
        raise EvtmsInputError(f"{str(partial)!r} is a symbolic link, not a partial sweep of evtms; {hint}")
    if not partial.is_dir():
        raise EvtmsInputError(f"{str(partial)!r} is a file, not a partial sweep of evtms; {hint}")
    marker = _read_record(partial / _MARKER)
    if marker is None or marker.get("magic") != _MAGIC or (partial / _MARKER).is_symlink():
        raise EvtmsInputError(f"{str(partial)!r} exists but is not a partial sweep of evtms (no {_MARKER}); {hint}")


def _create_partial(partial: Path) -> _Lock | None:
    """Create ``partial`` with its marker and our lock in one rename; None if it appeared meanwhile."""
    staging = partial.with_name(f".{partial.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.new")
    staging.mkdir()
    lock = None
    try:
        marker = {"magic": _MAGIC, "created": _lock_record()}
        (staging / _MARKER).write_text(json.dumps(marker))
        lock = _new_lock(staging / _LOCK)
        if lock is None or os.path.lexists(partial):
            raise FileExistsError(partial)
        # Atomic: the folder appears with its marker and held lock, or not at
        # all (a non-empty folder of that name makes the rename fail).
        os.rename(staging, partial)
        lock.path = partial / _LOCK
        return lock
    except (FileExistsError, OSError) as exc:
        if lock is not None:
            os.close(lock.fd)
        shutil.rmtree(staging, ignore_errors=True)
        if isinstance(exc, FileExistsError) or os.path.lexists(partial):
            return None
        raise
    except BaseException:
        if lock is not None:
            os.close(lock.fd)
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _lock_partial(partial: Path, output: Path) -> tuple[_Lock, list[str]]:
    """Take the exclusive lock on ``partial``, creating it (race-free) when missing.

    Returns
    -------
    lock : _Lock
        Held; release it (or remove the folder) on every exit path.
    notes : list of str
        A line if a stale lock was taken over.

    Raises
    ------
    EvtmsInputError
        ``partial`` is not evtms's, or another sweep to ``output`` runs.
    """
    running = f"another sweep to {str(output)!r} is running"
    deadline = time.monotonic() + LOCK_SETTLE_SECONDS
    while True:
        if not os.path.lexists(partial):
            lock = _create_partial(partial)
            if lock is not None:
                return lock, []
            continue  # another sweep created it first: lock it like any existing one
        _check_owned(partial)
        path = partial / _LOCK
        try:
            lock = _new_lock(path)
        except FileNotFoundError:  # the folder went away (a sweep finished)
            continue
        if lock is not None:
            return lock, []
        try:
            fd = os.open(path, os.O_RDWR | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:  # released meanwhile
            continue
        except OSError as exc:
            raise EvtmsInputError(
                f"{str(path)!r} cannot be opened as a lock ({_one_line(exc)}); move it away"
            ) from None
        settling = time.monotonic() < deadline
        held = _flock(fd)
        if not _same_file(fd, path):  # replaced or removed while we opened it
            os.close(fd)
            continue
        record = _read_record(path)
        reason = _stale(record)
        if held is False:
            os.close(fd)
            # A dead owner's record, yet the flock is held: another sweep is taking it over right now.
            if reason is not None and settling and (record or {}).get("pid") != os.getpid():
                time.sleep(0.05)
                continue
            raise EvtmsInputError(f"{running} ({_describe(record)}); wait for it to end or choose another output")
        if reason is None:
            os.close(fd)
            raise EvtmsInputError(f"{running} ({_describe(record)}); if it is not, delete {str(path)!r} and run again")
        try:
            lock = _new_lock(path, replace=True)  # a whole new record while we hold the old flock
        finally:
            os.close(fd)
        return lock, [f"took over the lock of an earlier sweep to {str(output)!r} ({_describe(record)}): {reason}"]


def _remove_partial(partial: Path, lock: _Lock) -> None:
    """Delete the locked partial folder: renamed away first (still locked), then removed."""
    trash = partial.with_name(f".{partial.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.done")
    try:
        os.rename(partial, trash)
    except OSError:
        lock.release()
        return
    lock.path = trash / _LOCK
    shutil.rmtree(trash, ignore_errors=True)
    lock.release()


def _clear_state(partial: Path) -> None:
    """Delete a fresh sweep's leftovers of an earlier one (our files only; marker and lock stay)."""
    for pattern in _STATE:
        for f in partial.glob(pattern):
            if f.is_file() or f.is_symlink():
                f.unlink(missing_ok=True)


def _size(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} TB"


def _check_disk(path: Path, plan: ChunkPlan, names: list[str], saved_bytes: int) -> None:
    """Refuse a sweep whose files would not fit in the free space of the output's folder.

    The uncompressed LUT (8 bytes per point per float variable, 1 for the
    status) and the chunk files (8 bytes per point per variable), which are
    all on disk at once just before the LUT is renamed into place, less the
    chunks an interrupted sweep already saved.
    """
    floats = sum(1 for n in names if n != "status")
    lut = plan.points * (8 * floats + (1 if "status" in names else 0))
    chunks = max(plan.points * 8 * len(names) - saved_bytes, 0)
    folder = path.parent
    while not folder.exists() and folder != folder.parent:  # to be created: its nearest existing parent
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    if lut + chunks > free:
        raise EvtmsInputError(
            f"the sweep needs up to {_size(lut + chunks)} in {str(folder)!r} (LUT {_size(lut)}, "
            f"chunks {_size(chunks)}) but only {_size(free)} is free; free space or choose another output folder"
        )


def _all_invalid(bench: Bench, counts: dict[int, int], points: int) -> str:
    reasons = ", ".join(
        f"{n} {bench.flags.get(code, f'status {code}')}" for code, n in sorted(counts.items(), key=lambda c: -c[1])
    )
    return f"every one of the {points} points is invalid: {reasons}; check the axis values and units"


def sweep_to_file(
    bench: Bench,
    grid: dict[str, np.ndarray],
    params: Parameters,
    path: str | Path,
    *,
    grid_name: str = "custom",
    runner: InProcessRunner | DaskRunner | None = None,
    chunk_points: int = DEFAULT_CHUNK_POINTS,
    resume: bool = False,
    progress: Progress | None = None,
    storage: LutStorage | None = None,
) -> SweepSummary:
    """Sweep ``bench`` over ``grid`` chunk by chunk and write the LUT to ``path``.

    The sweep's state lives in ``<path>.partial`` (evtms's own folder, locked
    while the sweep runs) and the LUT is renamed to ``path`` only when whole.

    Parameters
    ----------
    bench : Bench
        The bench to sweep.
    grid : dict of str to array
        Axis name -> values (SI), in the LUT's axis order.
    params : Parameters
        Component parameters and fluid.
    path : str or Path
        The LUT file to write.
    grid_name : str, optional
        The grid preset's name, recorded in the file.
    runner : InProcessRunner or DaskRunner, optional
        Where chunks are computed (default: in this process).
    chunk_points : int, optional
        Most points per chunk (bounds memory).
    resume : bool, optional
        Reuse the checked chunks of an interrupted sweep with the same inputs.
    progress : callable, optional
        ``progress(points_done, points_total)``, after each chunk.
    storage : LutStorage, optional
        How the LUT's variables are stored (see :mod:`evtms.luts.io`).

    Returns
    -------
    SweepSummary
        What it did; print its ``notes`` to the user.

    Raises
    ------
    EvtmsInputError
        An axis is out of range; ``resume`` finds a partial sweep made with
        other inputs; another sweep to ``path`` is running; ``<path>.partial``
        is not evtms's folder; the files would not fit on the disk; or every
        point of the grid is invalid (then no file is written).
    SweepInterrupted
        On KeyboardInterrupt (Ctrl-C): the saved chunks are kept for ``resume``.
    """
    from evtms.benches.grid import check_axis

    t0 = time.perf_counter()
    runner = runner or InProcessRunner()
    path = Path(path)
    fluid = _fluid_for(params)
    for name, values in grid.items():
        check_axis(name, np.asarray(values, float), fluid)
    grid = {k: np.asarray(v, float) for k, v in grid.items()}
    plan = ChunkPlan.for_grid(tuple(len(v) for v in grid.values()), chunk_points)
    names = [n for n in bench.outputs if n not in grid]
    partial = path.with_name(path.name + ".partial")
    manifest = _manifest(bench, grid, params, grid_name, plan)
    saved_bytes = 0
    if resume and partial.is_dir() and not partial.is_symlink():
        saved_bytes = sum(f.stat().st_size for f in partial.glob("chunk_*.npy"))
    _check_disk(path, plan, names, saved_bytes)
    lock, notes = _lock_partial(partial, path)
    remove = False  # the partial folder goes on success and when nothing is worth keeping
    try:
        done: set[int] = set()
        damaged = 0
        old = _read_record(partial / "manifest.json")
        if resume and old is not None and old != manifest:
            raise EvtmsInputError(
                f"--resume: the partial sweep in {str(partial)!r} was made with other inputs; "
                "remove it or run without --resume"
            )
        if resume and old == manifest:
            done, damaged = _done_chunks(partial, plan, names)
            if damaged:
                notes.append(f"{damaged} saved chunk(s) failed their checksum and were computed again")
        else:
            _clear_state(partial)
        _write_atomically(partial / "manifest.json", json.dumps(manifest).encode())
        todo = [k for k in range(plan.count) if k not in done]
        finished = sum(plan.size(k) for k in done)
        if progress is not None:
            progress(finished, plan.points)
        token = uuid.uuid4().hex
        (partial / _TOKEN).write_text(token)
        job = _Job(bench.name, grid, params, plan, str(partial), token)
        status_row = names.index("status")
        statuses: dict[int, int] = {}
        with _LutWriter(bench, grid, params, grid_name, plan, path, names, partial, storage=storage) as writer:
            # Chunks go into the file as they finish (those of an earlier run first),
            # so that writing overlaps the computing.
            for k in sorted(done):
                writer.add(partial, k)
                _count_statuses(partial, k, status_row, statuses)
            for k, arrays in runner.run(job, todo):
                if arrays is not None:  # computed where the partial folder is not visible
                    _save_chunk(partial, k, arrays)
                writer.add(partial, k)
                _count_statuses(partial, k, status_row, statuses)
                finished += plan.size(k)
                if progress is not None:
                    progress(finished, plan.points)
            if not any(n for code, n in statuses.items() if code in bench.valid_flags):
                remove = True  # the same inputs give the same points: nothing to resume
                raise EvtmsInputError(_all_invalid(bench, statuses, plan.points))
        remove = True
    except KeyboardInterrupt:
        raise SweepInterrupted(_saved_chunks(partial), plan.count, partial) from None
    finally:
        if remove or not _saved_chunks(partial):
            _remove_partial(partial, lock)
        else:
            lock.release()
    return SweepSummary(
        path,
        plan.points,
        plan.count,
        len(todo),
        len(done),
        writer.invalid,
        time.perf_counter() - t0,
        runner.name,
        damaged=damaged,
        notes=notes,
    )


def _count_statuses(partial: Path, k: int, row: int, counts: dict[int, int]) -> None:
    """Add the status codes of saved chunk ``k`` (row ``row`` of its array) to ``counts``."""
    status = np.asarray(np.load(_chunk_file(partial, k), mmap_mode="r")[row]).astype(np.int64)
    codes, n = np.unique(status, return_counts=True)
    for code, m in zip(codes.tolist(), n.tolist(), strict=True):
        counts[code] = counts.get(code, 0) + m


class _LutWriter:
    """The LUT file, filled chunk by chunk as they finish.

    It is written as ``lut.nc.tmp`` inside the partial folder (which holds all
    of an unfinished sweep's state and is removed at the end) and renamed to
    ``path`` only when every chunk is in it: an interrupted sweep never
    leaves a partial file at ``path``.

    Format version 2: an input with one value in the grid is evaluated by the
    bench but written as a fixed input (global attribute ``fixed_inputs``),
    not as a dimension, so every slab is written squeezed. Variables are
    stored as :func:`evtms.luts.io.variable_storage` and
    :func:`evtms.luts.io.store_values` decide (compressed; lossy only if
    ``storage`` says so), with the ``actual_range`` of the stored values.
    """

    def __init__(self, bench, grid, params, grid_name, plan, path, names, partial: Path, storage=None) -> None:
        from evtms.luts.io import fixed_axes

        self.bench, self.grid, self.plan, self.path, self.names = bench, grid, plan, path, names
        self.params, self.grid_name = params, grid_name
        self.storage = storage or LutStorage()
        self.axes, self.fixed = fixed_axes(grid)
        self.keep = [i for i, n in enumerate(plan.shape) if n > 1]  # grid dimensions that are file dimensions
        self.tmp = partial / "lut.nc.tmp"
        self.invalid = 0
        self.written: set[int] = set()
        self.ranges: dict[str, list] = {}
        self.nc = None

    def _slab(self, k: int) -> tuple[tuple, tuple[int, ...]]:
        """(index into the file's variables, shape of the squeezed slab) of chunk ``k``."""
        index = tuple(self.plan.index(k))
        index += (slice(None),) * (len(self.plan.shape) - len(index))
        file_index = tuple(index[i] for i in self.keep)
        shape = tuple(len(range(self.plan.shape[i])[index[i]]) for i in self.keep if isinstance(index[i], slice))
        return file_index, shape

    def __enter__(self) -> _LutWriter:
        import netCDF4

        from evtms.benches.sweep import bench_attributes
        from evtms.luts.io import (
            axis_attributes,
            axis_storage,
            global_attributes,
            storage_attributes,
            variable_attributes,
            variable_storage,
        )

        # Each chunk is written once, so HDF5's per-variable chunk cache (netCDF's default
        # is tens of MB per variable) buys nothing and would grow memory with the grid.
        self._previous_cache = netCDF4.get_chunk_cache()
        netCDF4.set_chunk_cache(size=1 << 20, nelems=61, preemption=1.0)
        try:
            nc = self.nc = netCDF4.Dataset(self.tmp, "w", format="NETCDF4")
            for name, values in self.axes.items():
                nc.createDimension(name, len(values))
                var = nc.createVariable(name, dimensions=(name,), **axis_storage())
                var[:] = values
                var.setncatts(axis_attributes(name))
            dims = tuple(self.axes)
            # The file's chunks are the sweep's chunks (squeezed), so each is compressed once.
            first = tuple(self.plan.index(0)) + (slice(None),) * len(self.plan.shape)
            chunksizes = tuple(
                len(range(self.plan.shape[i])[first[i]]) if isinstance(first[i], slice) else 1 for i in self.keep
            )
            self.variables = {}
            for name in self.names:
                kwargs = variable_storage(name, self.storage, len(dims))
                if dims:
                    kwargs["chunksizes"] = chunksizes
                var = nc.createVariable(name, dimensions=dims, **kwargs)
                attrs = variable_attributes(name, self.bench.flags, self.bench.valid_flags)
                var.setncatts(attrs | storage_attributes(name, None, self.storage))
                self.variables[name] = var
            attrs = bench_attributes(self.bench, self.params, self.grid_name)
            nc.setncatts(global_attributes(**attrs, fixed_inputs=self.fixed))
            nc.set_auto_maskandscale(False)  # plain arrays go in; NaN already is the fill value
        except BaseException:
            self._discard()
            raise
        return self

    def add(self, partial: Path, k: int) -> None:
        """Write saved chunk ``k`` into its (squeezed) slab of the file."""
        from evtms.luts.io import finite_range, store_values

        stacked = np.load(_chunk_file(partial, k))
        index, shape = self._slab(k)
        for name, values in zip(self.names, stacked, strict=True):
            if name == "status":
                values = values.astype(np.int8)
                self.invalid += int((~np.isin(values, self.bench.valid_flags)).sum())
            else:
                values = store_values(name, values, self.storage)
                lo, hi = finite_range(values)
                if lo is not None:
                    old = self.ranges.setdefault(name, [lo, hi])
                    old[:] = [min(old[0], lo), max(old[1], hi)]
            if index:
                self.variables[name][index] = values.reshape(shape)
            else:  # every input fixed: scalar variables
                self.variables[name].assignValue(values.reshape(()))
        self.written.add(k)

    def _discard(self) -> None:
        import netCDF4

        if self.nc is not None and self.nc.isopen():
            self.nc.close()
        self.tmp.unlink(missing_ok=True)
        netCDF4.set_chunk_cache(*self._previous_cache)

    def __exit__(self, exc_type, exc, tb) -> bool:
        import netCDF4

        if exc_type is not None:
            self._discard()
            return False
        for name, (lo, hi) in self.ranges.items():
            self.variables[name].setncattr("actual_range", np.array([lo, hi], dtype=self.storage.dtype))
        self.nc.close()
        netCDF4.set_chunk_cache(*self._previous_cache)
        if len(self.written) != self.plan.count:  # a runner that skipped chunks: a bug
            self.tmp.unlink(missing_ok=True)
            missing = sorted(set(range(self.plan.count)) - self.written)[:3]
            raise RuntimeError(f"the sweep ended with chunks {missing} not written")
        os.replace(self.tmp, self.path)
        return False
