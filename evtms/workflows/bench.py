"""Bench sweeps: a request checked before any work, the runner, the LUT files written.

:func:`run_bench` is what ``evtms bench COMPONENT|all`` runs: it checks the
request (limits, the runner, the parameter file, every grid and the output
paths), probes CoolProp, then sweeps each bench in chunks to its LUT file
(:func:`evtms.benches.chunked.sweep_to_file`). :func:`bench_catalogue`
describes the registered benches (their axes and presets) for the help texts.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from evtms.benches.chunked import SweepInterrupted, SweepSummary
from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, output_file, output_folder
from evtms.workflows.common import Progress, params_input

__all__ = ["AxisInfo", "BenchInfo", "BenchRequest", "BenchResult", "SweepInterrupted", "bench_catalogue", "run_bench"]


@dataclass(frozen=True)
class AxisInfo:
    """One axis a bench's grid may use (for help texts).

    Attributes
    ----------
    name, units, long_name : str
        Axis name, SI units and meaning.
    allowed : str
        Allowed range.
    unit_suffixes : tuple of str
        Unit suffixes an axis value may carry besides SI.
    extra : bool
        An optional extra axis of the bench.
    """

    name: str
    units: str
    long_name: str
    allowed: str
    unit_suffixes: tuple[str, ...]
    extra: bool


@dataclass(frozen=True)
class BenchInfo:
    """A registered bench: its title, axes and grid presets.

    Attributes
    ----------
    name, title : str
        Registry name and title.
    axes : tuple of AxisInfo
        The axes a grid may use.
    presets : dict of str to dict of str to tuple of float
        Preset name -> axis -> values [SI].
    units : dict of str to str
        Axis -> SI units, for every axis of the presets.
    """

    name: str
    title: str
    axes: tuple[AxisInfo, ...]
    presets: dict[str, dict[str, tuple[float, ...]]]
    units: dict[str, str]


def bench_catalogue() -> dict[str, BenchInfo]:
    """Every registered bench by name (:data:`evtms.benches.BENCHES`), in registry order."""
    from evtms.benches import BENCHES
    from evtms.benches.grid import allowed_axes
    from evtms.luts.schema import AXES

    out = {}
    for name, bench in BENCHES.items():
        axes = tuple(
            AxisInfo(
                a,
                AXES[a].units,
                AXES[a].long_name,
                AXES[a].allowed(),
                tuple(u for u, _, _ in AXES[a].cli_units),
                a in bench.extra_axes,
            )
            for a in allowed_axes(bench)
        )
        presets = {p: {a: tuple(float(x) for x in v) for a, v in axes_.items()} for p, axes_ in bench.presets.items()}
        units = {a: AXES[a].units for axes_ in bench.presets.values() for a in axes_}
        out[name] = BenchInfo(name, bench.title, axes, presets, units)
    return out


@dataclass
class BenchRequest:
    """One bench sweep (``evtms bench``), or several benches on one grid preset (``evtms bench all``).

    Attributes
    ----------
    names : sequence of str
        Registered bench names (:data:`evtms.benches.BENCHES`).
    grid : str
        Grid preset (``thesis``, ``cycle``) or ``custom``.
    axis : sequence of str
        Axes overriding or adding to the preset, ``name=start:stop:count[unit]`` or ``name=v1,v2,...[unit]``
        (one bench only).
    params : Path, optional
        TOML file overriding component parameters.
    output : Path, optional
        Output ``.nc`` file (a folder for several benches); default ``luts/<name>.nc``.
    backend : str, optional
        CoolProp backend (``HEOS``, ``BICUBIC&HEOS``).
    workers : int, optional
        Local dask worker processes (default: in this process).
    scheduler : str, optional
        A dask.distributed scheduler address, ``tcp://host:port``.
    resume : bool
        Reuse the finished chunks of an interrupted sweep to the same output.
    chunk_points : int
        Points per chunk (bounds memory).
    max_points : int, optional
        Largest grid allowed (default :data:`evtms.benches.grid.DEFAULT_MAX_POINTS`).
    float32 : bool
        Store the variables as float32.
    significant_digits : int, optional
        Keep this many significant digits (1-15).
    """

    names: Sequence[str]
    grid: str = "thesis"
    axis: Sequence[str] = ()
    params: Path | None = None
    output: Path | None = None
    backend: str | None = None
    workers: int | None = None
    scheduler: str | None = None
    resume: bool = False
    chunk_points: int = 16384
    max_points: int | None = None
    float32: bool = False
    significant_digits: int | None = None


@dataclass
class BenchResult:
    """What :func:`run_bench` wrote: ``(bench name, sweep summary)`` per bench, in request order."""

    benches: list[tuple[str, SweepSummary]] = field(default_factory=list)


def _check(request: BenchRequest) -> int:
    """The request's limits and runner choice (``max_points`` completed), before any file is read."""
    max_points = request.max_points
    if max_points is None:
        from evtms.benches.grid import DEFAULT_MAX_POINTS

        max_points = DEFAULT_MAX_POINTS
    if max_points < 1:
        raise EvtmsInputError(f"`max_points` {max_points} is not allowed; allowed: 1 or more")
    if request.workers is not None and request.workers < 1:
        raise EvtmsInputError(f"`workers` {request.workers} is not allowed; allowed: 1 or more")
    if request.workers is not None and request.scheduler is not None:
        raise EvtmsInputError("give `workers` or `scheduler`, not both")
    if request.chunk_points < 1:
        raise EvtmsInputError(f"`chunk_points` {request.chunk_points} is not allowed; allowed: 1 or more")
    return max_points


def _targets(request: BenchRequest, inputs: list[Path]) -> dict[str, Path]:
    """The LUT file of each bench: ``output`` (or ``luts/<name>.nc``), or ``<output>/<name>.nc`` for several."""
    from evtms.luts.store import SUFFIX, LutStore

    names = list(request.names)
    if len(names) > 1:
        folder = output_folder(request.output or Path("luts"), inputs)
        return {name: output_file(path, inputs) for name, path in LutStore(folder).luts(names).items()}
    return {names[0]: output_file(request.output or LutStore(Path("luts")).lut(names[0]), inputs, (SUFFIX,))}


def _plan(request: BenchRequest):
    """(storage, parameters, LUT file per bench, jobs): every check of the request, before any sweep."""
    from evtms.benches import BENCHES
    from evtms.benches.grid import build_grid, parse_axes
    from evtms.luts.io import LutStorage
    from evtms.params import check_backend
    from evtms.system.params import load_parameter_tree

    max_points = _check(request)
    storage = LutStorage(float32=request.float32, significant_digits=request.significant_digits)
    if len(request.names) > 1 and request.axis:
        raise EvtmsInputError("`axis` applies to one bench; run the benches one by one for custom axes")
    targets = _targets(request, params_input(request.params))
    parameters = load_parameter_tree(request.params).components
    if request.backend is not None:
        parameters = dataclasses.replace(parameters, backend=check_backend(request.backend))
    jobs = []
    for name in request.names:
        bench = BENCHES[name]
        overrides = parse_axes(list(request.axis or []), bench, max_points)
        values = build_grid(bench, request.grid if request.grid != "custom" else None, overrides, max_points)
        jobs.append((name, bench, values, request.grid if not overrides else "custom"))
    try:
        from evtms.fluid import Fluid

        Fluid(parameters.fluid, parameters.backend)
    except ValueError as exc:
        raise EvtmsInputError(
            f"fluid {parameters.fluid!r} with backend {parameters.backend!r} cannot be loaded ({exc})"
        ) from None
    return storage, parameters, targets, jobs


def _runner(request: BenchRequest):
    if request.workers is None and request.scheduler is None:
        from evtms.benches.chunked import InProcessRunner

        return InProcessRunner()  # plain NumPy in this process: dask is not imported
    from evtms.benches.chunked import DaskRunner

    return DaskRunner(workers=request.workers, scheduler=request.scheduler)


def run_bench(
    request: BenchRequest,
    *,
    progress: Progress | None = None,
    done: Callable[[str, SweepSummary], None] | None = None,
) -> BenchResult:
    """Sweep the requested benches and write their LUTs.

    Parameters
    ----------
    request : BenchRequest
        What to sweep and where to write it; checked in full before any sweep.
    progress : callable, optional
        ``progress(points_done, points_total, bench_name)`` as chunks finish.
    done : callable, optional
        ``done(bench_name, summary)`` as each bench's LUT is written.

    Returns
    -------
    BenchResult

    Raises
    ------
    EvtmsInputError
        A limit out of range, workers with a scheduler, custom axes for several
        benches, a bad parameter file, grid or output path, or a fluid that
        CoolProp cannot load.
    SweepInterrupted
        Ctrl-C: the saved chunks are kept for ``resume``.
    """
    from evtms.benches.chunked import sweep_to_file

    storage, parameters, targets, jobs = _plan(request)
    runner = _runner(request)
    result = BenchResult()
    try:
        for name, bench, values, grid_name in jobs:
            total = math.prod(len(v) for v in values.values())
            if progress is not None:
                progress(0, total, name)
            with creating_parents(targets[name]):
                s = sweep_to_file(
                    bench,
                    values,
                    parameters,
                    targets[name],
                    grid_name=grid_name,
                    runner=runner,
                    chunk_points=request.chunk_points,
                    resume=request.resume,
                    progress=None if progress is None else (lambda d, t, name=name: progress(d, t, name)),
                    storage=storage,
                )
            result.benches.append((name, s))
            if done is not None:
                done(name, s)
    finally:
        runner.close()
    return result
