"""Sweeps that scale: chunked, written as chunks finish, resumable, parallel with dask.

A grid is cut into chunks of whole trailing blocks: chunk ``k`` holds every
point whose leading indices (the first ``lead`` axes, in C order) flatten to
``k``, so it is both a contiguous range of the flat grid and a rectangular
slab of the LUT. Each finished chunk is saved at once (atomically) in a
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
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

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
    """How a grid of ``shape`` is cut: chunks of ``block`` points over the last axes.

    Attributes
    ----------
    shape : tuple of int
        Grid shape.
    lead : int
        Number of leading axes that number the chunks.
    """

    shape: tuple[int, ...]
    lead: int

    @classmethod
    def for_grid(cls, shape: tuple[int, ...], chunk_points: int) -> ChunkPlan:
        """The fewest chunks with at most ``chunk_points`` points (at least one row of the last axis)."""
        for lead in range(len(shape)):
            if math.prod(shape[lead:]) <= chunk_points:
                return cls(tuple(shape), lead)
        return cls(tuple(shape), max(len(shape) - 1, 0))

    @property
    def block(self) -> int:
        return math.prod(self.shape[self.lead :])

    @property
    def count(self) -> int:
        return math.prod(self.shape[: self.lead])

    @property
    def points(self) -> int:
        return math.prod(self.shape)

    def index(self, k: int) -> tuple[int, ...]:
        """Leading indices of chunk ``k`` (its slab is ``var[index + (...,)]``)."""
        return tuple(int(i) for i in np.unravel_index(k, self.shape[: self.lead])) if self.lead else ()


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
    """Evaluate chunk ``k`` of a sweep: flat output arrays of ``plan.block`` points."""
    from evtms.benches import BENCHES
    from evtms.benches.sweep import grid_points

    bench = BENCHES[bench_name]
    start = k * plan.block
    inputs = grid_points(grid, start, start + plan.block)
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
        Address of an existing scheduler, e.g. ``tcp://10.0.0.5:8786``.
    """

    name = "dask"

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
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
        environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
        environ.update(MALLOC_TRIM_THRESHOLD_=str(64 << 20), MALLOC_TOP_PAD_=str(16 << 20))
        dask.config.set({"distributed.nanny.pre-spawn-environ": environ, "distributed.worker.profile.enabled": False})
        if scheduler is not None:
            try:
                self.client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise EvtmsInputError(f"cannot reach the dask scheduler {scheduler!r}: {exc}") from None
        else:
            self._cluster = LocalCluster(
                n_workers=workers or 1,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                worker_dashboard_address=":0",
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
    """True if this process sees ``folder`` as the main process does (its token file matches)."""
    cache = _sees_folder.__dict__.setdefault("cache", {})
    key = (folder, token)
    if key not in cache:
        try:
            cache[key] = token is not None and (Path(folder) / _TOKEN).read_text() == token
        except OSError:
            cache[key] = False
    return cache[key]


_TOKEN = "token"


@dataclass
class SweepSummary:
    """What a chunked sweep did."""

    path: Path
    points: int
    chunks: int
    computed: int
    reused: int
    invalid: int
    seconds: float
    runner: str


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
        "lead": plan.lead,
    }
    return json.loads(json.dumps(manifest))  # as it reads back from disk (tuples become lists)


def _chunk_file(folder: Path, k: int) -> Path:
    return folder / f"chunk_{k:06d}.npy"


def _save_chunk(folder: Path, k: int, arrays: dict[str, np.ndarray]) -> None:
    """Save chunk ``k`` atomically as one (variables, points) float64 array, in ``arrays``' order.

    One plain ``.npy`` per chunk: loading it parses one header (an ``.npz`` parses
    a zip directory and a header per variable, which the main process would pay
    for every chunk). The int8 status is exact in float64.
    """
    stacked = np.stack([np.asarray(a, np.float64) for a in arrays.values()])
    tmp = folder / f".chunk_{k:06d}.tmp.npy"
    with open(tmp, "wb") as fh:
        np.save(fh, stacked)
    os.replace(tmp, _chunk_file(folder, k))


def _done_chunks(folder: Path, plan: ChunkPlan, names: list[str]) -> set[int]:
    done = set()
    for f in folder.glob("chunk_*.npy"):
        try:
            k = int(f.stem.split("_")[1])
            # Memory-mapped: reads the header only; a truncated file fails to map.
            if k < plan.count and np.load(f, mmap_mode="r").shape == (len(names), plan.block):
                done.add(k)
        except (OSError, ValueError):
            continue  # a damaged chunk is recomputed
    return done


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

    Raises
    ------
    EvtmsInputError
        An axis is out of range, or ``resume`` finds a partial sweep made with
        other inputs.
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
    done: set[int] = set()
    if partial.exists():
        old = None
        try:
            old = json.loads((partial / "manifest.json").read_text())
        except (OSError, ValueError):
            pass
        if resume and old is not None and old != manifest:
            raise EvtmsInputError(
                f"--resume: the partial sweep in {str(partial)!r} was made with other inputs; "
                "remove it or run without --resume"
            )
        if resume and old == manifest:
            done = _done_chunks(partial, plan, names)
        else:
            shutil.rmtree(partial)
    partial.mkdir(exist_ok=True)
    (partial / "manifest.json").write_text(json.dumps(manifest))
    todo = [k for k in range(plan.count) if k not in done]
    finished = len(done) * plan.block
    if progress is not None:
        progress(finished, plan.points)
    token = uuid.uuid4().hex
    (partial / _TOKEN).write_text(token)
    job = _Job(bench.name, grid, params, plan, str(partial), token)
    with _LutWriter(bench, grid, params, grid_name, plan, path, names, partial, storage=storage) as writer:
        # Chunks go into the file as they finish (those of an earlier run first),
        # so that writing overlaps the computing.
        for k in sorted(done):
            writer.add(partial, k)
        for k, arrays in runner.run(job, todo):
            if arrays is not None:  # computed where the partial folder is not visible
                _save_chunk(partial, k, arrays)
            writer.add(partial, k)
            finished += plan.block
            if progress is not None:
                progress(finished, plan.points)
    shutil.rmtree(partial)
    return SweepSummary(
        path, plan.points, plan.count, len(todo), len(done), writer.invalid, time.perf_counter() - t0, runner.name
    )


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
