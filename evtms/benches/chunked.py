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
import), :class:`PoolRunner` (local worker processes, no dask either) and
:class:`DaskRunner` (a ``dask.distributed`` client: local worker processes or
an existing cluster). Every mode evaluates the same points with
the same code, so the files are identical but for their creation time. A
dask worker that dies mid-chunk loses nothing: the scheduler reruns its task
elsewhere (and ``retries`` reruns tasks that raised).

The partial folder (:mod:`evtms.benches.partial`) is evtms's own: an
ownership marker says so, and a sweep holds an exclusive lock on it, so a
second sweep to the same output refuses while the first runs; a lock whose
process is gone is taken over (and reported in :attr:`SweepSummary.notes`).
The file is written by :class:`evtms.luts.writer.LutFileWriter`. Ctrl-C keeps
the saved chunks and raises :class:`SweepInterrupted`.
"""

from __future__ import annotations

import json
import logging
import math
import re
import shutil
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.benches.base import Bench
from evtms.benches.parameters import Parameters
from evtms.benches.partial import (
    TOKEN,
    chunk_file,
    clear_state,
    done_chunks,
    lock_partial,
    one_line,
    read_record,
    remove_partial,
    save_chunk,
    saved_chunks,
    sees_folder,
    sweep_manifest,
    write_atomically,
)
from evtms.errors import EvtmsInputError
from evtms.luts.io import LutStorage

if TYPE_CHECKING:
    from evtms.luts.writer import LutFileWriter

Progress = Callable[[int, int], None]
DEFAULT_CHUNK_POINTS = 16384
#: Chunks in flight per worker (dask or :class:`PoolRunner`): enough to keep each busy while results come back.
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


def _ignore_sigint() -> None:
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


class InProcessRunner:
    """Compute chunks one after the other in this process."""

    name = "in-process"
    workers = 1

    def run(self, job: Callable[[int], dict], chunks: Iterable[int]) -> Iterator[tuple[int, dict]]:
        for k in chunks:
            yield k, job(k)

    def close(self) -> None:
        pass


class PoolRunner:
    """Compute chunks in local worker processes (``concurrent.futures``; no dask import).

    What ``evtms demo`` and the tests use to spread one large grid over the
    cores: the jobs are the same picklable :class:`_Job` as with dask, each
    worker saves its chunks in the partial folder itself, and at most
    :data:`WINDOW` chunks per worker are in flight.

    The workers start from a fork server (not forked from this process, which may
    run threads, e.g. another pool's) and ignore SIGINT, as dask's local workers
    do: Ctrl-C is the main process's business. On Ctrl-C (or any error) in
    :meth:`run` the chunks not started are cancelled and :meth:`close` waits
    for the running ones only, so the job stops within one chunk's time. A
    worker that dies fails the sweep (its saved chunks are kept for
    ``resume``); dask would rerun the chunk. Any other job of picklable chunks
    runs the same way (the cycle maps' build, :mod:`evtms.system.maps`, whose
    chunks save nothing: it ends its workers at once, ``close(kill=True)``).

    Parameters
    ----------
    workers : int
        Worker processes.
    start_method : str
        How the workers start (:mod:`multiprocessing`): ``forkserver``, or
        ``fork`` where a job must not import the caller's main script again.
    """

    name = "processes"

    def __init__(self, workers: int, start_method: str = "forkserver") -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.workers = max(1, int(workers))
        self._pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context(start_method),
            initializer=_ignore_sigint,
        )

    def run(self, job: Callable[[int], dict], chunks: Iterable[int]) -> Iterator[tuple[int, dict]]:
        from concurrent.futures import FIRST_COMPLETED, wait

        pending = list(chunks)
        futures: dict = {}
        try:
            while pending or futures:
                while pending and len(futures) < WINDOW * self.workers:
                    k = pending.pop(0)
                    futures[self._pool.submit(job, k)] = k
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield futures.pop(fut), fut.result()
        finally:  # stopped early (an error, Ctrl-C): the chunks not started are not started
            for fut in futures:
                fut.cancel()

    def close(self, kill: bool = False) -> None:
        """Shut the pool down: the chunks not started are dropped and the running ones finish;
        with ``kill`` the workers are ended at once (a job whose chunks save nothing, which
        would otherwise keep a stopped command waiting for its longest chunk)."""
        if kill:  # concurrent.futures has no public way to end busy workers before Python 3.14
            for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
                proc.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)


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
    warm_up : callable, optional
        Run on every worker once connected (default: build the default fluid,
        which imports CoolProp, about 2 s, not inside the first chunk); None:
        nothing (the system simulations do not use CoolProp).

    Raises
    ------
    EvtmsInputError
        dask is not installed, the address is not ``tcp://host:port``, or no
        dask scheduler answers there in time.
    """

    name = "dask"

    def __init__(
        self, workers: int | None = None, scheduler: str | None = None, warm_up: Callable[[], None] | None = _warm_up
    ) -> None:
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
                    problem = one_line(exc)
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
        if warm_up is not None:
            self.client.run(warm_up)

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
        # The caller reports how the sweep ended (the file written, or one line on an
        # interrupt with the chunks kept). What dask and tornado log in this process while
        # the cluster stops (tasks cancelled by Ctrl-C, comms closed, a callback cut short)
        # would only follow that line: logging is off until the cluster is closed.
        logging.disable(logging.CRITICAL)
        try:
            self.client.close()
            if self._cluster is not None:
                self._cluster.close()
        finally:
            logging.disable(logging.NOTSET)


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
        return one_line(outcome["error"])
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
        if self.partial is not None and sees_folder(self.partial, self.token):
            save_chunk(Path(self.partial), k, arrays)
            return None
        return arrays


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
        ``in-process``, ``processes`` (:class:`PoolRunner`) or ``dask``.
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
    runner: InProcessRunner | PoolRunner | DaskRunner | None = None,
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
    runner : InProcessRunner, PoolRunner or DaskRunner, optional
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
    manifest = sweep_manifest(bench, grid, params, grid_name, plan)
    saved_bytes = 0
    if resume and partial.is_dir() and not partial.is_symlink():
        saved_bytes = sum(f.stat().st_size for f in partial.glob("chunk_*.npy"))
    _check_disk(path, plan, names, saved_bytes)
    lock, notes = lock_partial(partial, path)
    remove = False  # the partial folder goes on success and when nothing is worth keeping
    try:
        done: set[int] = set()
        damaged = 0
        old = read_record(partial / "manifest.json")
        if resume and old is not None and old != manifest:
            raise EvtmsInputError(
                f"`resume`: the partial sweep in {str(partial)!r} was made with other inputs; "
                "remove it or run without `resume`"
            )
        if resume and old == manifest:
            done, damaged = done_chunks(partial, plan, names)
            if damaged:
                notes.append(f"{damaged} saved chunk(s) failed their checksum and were computed again")
        else:
            clear_state(partial)
        write_atomically(partial / "manifest.json", json.dumps(manifest).encode())
        todo = [k for k in range(plan.count) if k not in done]
        finished = sum(plan.size(k) for k in done)
        if progress is not None:
            progress(finished, plan.points)
        token = uuid.uuid4().hex
        (partial / TOKEN).write_text(token)
        job = _Job(bench.name, grid, params, plan, str(partial), token)
        statuses: dict[int, int] = {}
        written: set[int] = set()
        with _lut_writer(bench, grid, params, grid_name, plan, names, partial / "lut.nc.tmp", storage) as writer:
            # Chunks go into the file as they finish (those of an earlier run first),
            # so that writing overlaps the computing.
            for k in sorted(done):
                _add_chunk(writer, plan, partial, k, names, statuses)
                written.add(k)
            for k, arrays in runner.run(job, todo):
                if arrays is not None:  # computed where the partial folder is not visible
                    save_chunk(partial, k, arrays)
                _add_chunk(writer, plan, partial, k, names, statuses)
                written.add(k)
                finished += plan.size(k)
                if progress is not None:
                    progress(finished, plan.points)
            if not any(n for code, n in statuses.items() if code in bench.valid_flags):
                remove = True  # the same inputs give the same points: nothing to resume
                raise EvtmsInputError(_all_invalid(bench, statuses, plan.points))
            if len(written) != plan.count:  # a runner that skipped chunks: a bug
                missing = sorted(set(range(plan.count)) - written)[:3]
                raise RuntimeError(f"the sweep ended with chunks {missing} not written")
            writer.finish(path)
        remove = True
    except KeyboardInterrupt:
        raise SweepInterrupted(saved_chunks(partial), plan.count, partial) from None
    finally:
        if remove or not saved_chunks(partial):
            remove_partial(partial, lock)
        else:
            lock.release()
    return SweepSummary(
        path,
        plan.points,
        plan.count,
        len(todo),
        len(done),
        sum(n for code, n in statuses.items() if code not in bench.valid_flags),
        time.perf_counter() - t0,
        runner.name,
        damaged=damaged,
        notes=notes,
    )


def _lut_writer(
    bench: Bench,
    grid: dict[str, np.ndarray],
    params: Parameters,
    grid_name: str,
    plan: ChunkPlan,
    names: list[str],
    tmp: Path,
    storage: LutStorage | None,
) -> LutFileWriter:
    """The LUT file of a sweep, written at ``tmp`` (in the partial folder) chunk by chunk.

    Format version 2: an input with one value in the grid is evaluated by the
    bench but written as a fixed input (global attribute ``fixed_inputs``),
    not as a dimension, so every slab is written squeezed. The file's netCDF
    chunks are the sweep's chunks (squeezed), so each is compressed once.
    """
    from evtms.benches.sweep import bench_attributes
    from evtms.luts.io import axis_attributes, fixed_axes, global_attributes, storage_attributes, variable_attributes
    from evtms.luts.writer import LutFileWriter

    storage = storage or LutStorage()
    axes, fixed = fixed_axes(grid)
    keep = _file_dimensions(plan)
    first = tuple(plan.index(0)) + (slice(None),) * len(plan.shape)
    chunksizes = tuple(len(range(plan.shape[i])[first[i]]) if isinstance(first[i], slice) else 1 for i in keep)
    attributes = {name: axis_attributes(name) for name in axes}
    for name in names:
        attributes[name] = variable_attributes(name, bench.flags, bench.valid_flags, bench.name) | storage_attributes(
            name, None, storage
        )
    attrs = global_attributes(**bench_attributes(bench, params, grid_name), fixed_inputs=fixed)
    return LutFileWriter(tmp, axes, names, attributes, attrs, storage=storage, chunksizes=chunksizes)


def _file_dimensions(plan: ChunkPlan) -> list[int]:
    """The grid dimensions that are file dimensions (more than one value)."""
    return [i for i, n in enumerate(plan.shape) if n > 1]


def _add_chunk(
    writer: LutFileWriter, plan: ChunkPlan, partial: Path, k: int, names: list[str], statuses: dict[int, int]
) -> None:
    """Write saved chunk ``k`` into its (squeezed) slab of the file and add its status codes to ``statuses``."""
    stacked = np.load(chunk_file(partial, k))
    keep = _file_dimensions(plan)
    index = tuple(plan.index(k))
    index += (slice(None),) * (len(plan.shape) - len(index))
    file_index = tuple(index[i] for i in keep)
    shape = tuple(len(range(plan.shape[i])[index[i]]) for i in keep if isinstance(index[i], slice))
    writer.write(file_index, {name: values.reshape(shape) for name, values in zip(names, stacked, strict=True)})
    status = stacked[names.index("status")].astype(np.int64)
    codes, n = np.unique(status, return_counts=True)
    for code, m in zip(codes.tolist(), n.tolist(), strict=True):
        statuses[code] = statuses.get(code, 0) + m
