"""Sweeps that scale: chunked, written as chunks finish, resumable, parallel with dask.

A grid is cut into chunks of whole trailing blocks: chunk ``k`` holds every
point whose leading indices (the first ``lead`` axes, in C order) flatten to
``k``, so it is both a contiguous range of the flat grid and a rectangular
slab of the LUT. Each finished chunk is saved at once (atomically) in a
``<output>.partial`` folder beside the output, with a manifest of the sweep's
inputs; ``resume=True`` reuses the chunks of an interrupted sweep with the same
manifest and computes only the missing ones. At the end the chunks are streamed
into the netCDF file (written to a temporary file and renamed), so memory is
bounded by the chunk size and the number of chunks in flight, not by the grid.

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
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms.benches.base import Bench
from evtms.errors import EvtmsInputError
from evtms.params import Parameters

Progress = Callable[[int, int], None]
DEFAULT_CHUNK_POINTS = 16384


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
        # dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=64 KiB, which hands
        # every freed large array back to the OS; the benches allocate and free many
        # chunk-sized arrays, and run about 1.7x slower so. Keep glibc's default.
        environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
        environ.pop("MALLOC_TRIM_THRESHOLD_", None)
        dask.config.set({"distributed.nanny.pre-spawn-environ": environ})
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
        window = 3 * self.workers
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
    """A picklable chunk job: the bench, its grid, the parameters and the plan."""

    def __init__(self, bench_name: str, grid: dict, params: Parameters, plan: ChunkPlan) -> None:
        self.bench_name, self.grid, self.params, self.plan = bench_name, grid, params, plan

    def __call__(self, k: int) -> dict[str, np.ndarray]:
        return compute_chunk(self.bench_name, self.grid, self.params, self.plan, k)


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


def _save_chunk(folder: Path, k: int, arrays: dict[str, np.ndarray]) -> None:
    tmp = folder / f".chunk_{k:06d}.tmp.npz"
    with open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    os.replace(tmp, folder / f"chunk_{k:06d}.npz")


def _done_chunks(folder: Path, plan: ChunkPlan, names: list[str]) -> set[int]:
    done = set()
    for f in folder.glob("chunk_*.npz"):
        try:
            k = int(f.stem.split("_")[1])
            with np.load(f) as z:
                if k < plan.count and all(z[n].shape == (plan.block,) for n in names):
                    done.add(k)
        except (OSError, ValueError, KeyError):
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
    job = _Job(bench.name, grid, params, plan)
    for k, arrays in runner.run(job, todo):
        _save_chunk(partial, k, arrays)
        finished += plan.block
        if progress is not None:
            progress(finished, plan.points)
    invalid = _assemble(bench, grid, params, grid_name, plan, partial, path, names)
    shutil.rmtree(partial)
    return SweepSummary(
        path, plan.points, plan.count, len(todo), len(done), invalid, time.perf_counter() - t0, runner.name
    )


def _assemble(
    bench: Bench,
    grid: dict[str, np.ndarray],
    params: Parameters,
    grid_name: str,
    plan: ChunkPlan,
    partial: Path,
    path: Path,
    names: list[str],
) -> int:
    """Stream the chunk files into the LUT file (atomically); returns the invalid-point count."""
    import netCDF4

    from evtms.benches.sweep import bench_attributes
    from evtms.luts.io import global_attributes

    attrs = global_attributes(**bench_attributes(bench, params, grid_name))
    trailing = plan.shape[plan.lead :]
    # Each chunk is written once, so HDF5's per-variable chunk cache (netCDF's default
    # is tens of MB per variable) buys nothing and would grow memory with the grid.
    previous = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(size=1 << 20, nelems=61, preemption=1.0)
    try:
        _write_chunks(bench, grid, plan, partial, path, names, attrs, trailing)
    finally:
        netCDF4.set_chunk_cache(*previous)
    return _count_invalid(bench, plan, partial)


def _count_invalid(bench: Bench, plan: ChunkPlan, partial: Path) -> int:
    invalid = 0
    for k in range(plan.count):
        with np.load(partial / f"chunk_{k:06d}.npz") as z:
            invalid += int((~np.isin(z["status"], bench.valid_flags)).sum())
    return invalid


def _write_chunks(bench, grid, plan, partial, path, names, attrs, trailing) -> None:
    """Create the LUT file and stream every chunk into its slab (atomically)."""
    import netCDF4

    from evtms.luts.io import atomic_output, axis_attributes, variable_attributes

    dims = tuple(grid)
    with atomic_output(path) as tmp, netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
        for name, values in grid.items():
            nc.createDimension(name, len(values))
            var = nc.createVariable(name, "f8", (name,))
            var[:] = values
            var.setncatts(axis_attributes(name))
        chunksizes = tuple([1] * plan.lead) + tuple(trailing)
        variables = {}
        for name in names:
            is_status = name == "status"
            var = nc.createVariable(
                name,
                "i1" if is_status else "f8",
                dims,
                fill_value=None if is_status else np.nan,
                chunksizes=chunksizes,
            )
            var.setncatts(variable_attributes(name, bench.flags, bench.valid_flags))
            variables[name] = var
        nc.setncatts(attrs)
        for k in range(plan.count):
            with np.load(partial / f"chunk_{k:06d}.npz") as z:
                index = plan.index(k) + (slice(None),) * len(trailing)
                for name in names:
                    variables[name][index] = z[name].reshape(trailing)
