"""Evaluate a bench over an N-D grid and return a LUT dataset."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from evtms.benches.base import Bench
from evtms.benches.grid import check_axis
from evtms.benches.parameters import Parameters
from evtms.fluid import Fluid, coolprop_version

if TYPE_CHECKING:
    import xarray as xr

Progress = Callable[[int, int], None]


def grid_points(grid: dict[str, np.ndarray], start: int, stop: int) -> dict[str, np.ndarray]:
    """Input arrays of grid points ``start:stop`` in C order, without building the full mesh."""
    shape = tuple(len(v) for v in grid.values())
    index = np.unravel_index(np.arange(start, stop), shape)
    return {name: values[i] for (name, values), i in zip(grid.items(), index, strict=True)}


def evaluate_grid(
    bench: Bench,
    grid: dict[str, np.ndarray],
    params: Parameters,
    fluid: Fluid,
    progress: Progress | None = None,
    chunk_size: int = 4096,
) -> dict[str, np.ndarray]:
    """Flat outputs of ``bench`` at every grid point, evaluated in chunks."""
    n = math.prod(len(v) for v in grid.values())
    out: dict[str, np.ndarray] = {}
    for start in range(0, n, chunk_size):
        stop = min(start + chunk_size, n)
        res = bench.evaluate(grid_points(grid, start, stop), params, fluid)
        for name in bench.outputs:
            if name in grid:  # an input given as an axis is not also a variable
                continue
            if name not in out:
                out[name] = np.empty(n, np.int8 if name == "status" else np.float64)
            out[name][start:stop] = res[name]
        if progress is not None:
            progress(stop, n)
    return out


def run_sweep(
    bench: Bench,
    grid: dict[str, np.ndarray],
    params: Parameters,
    *,
    grid_name: str = "custom",
    progress: Progress | None = None,
    chunk_size: int = 4096,
    fluid: Fluid | None = None,
) -> xr.Dataset:
    """Sweep ``bench`` over ``grid`` and return the LUT dataset.

    Parameters
    ----------
    bench : Bench
        The component bench.
    grid : dict of str to numpy.ndarray
        Axis values (SI), in dimension order (see :func:`evtms.benches.grid.build_grid`).
    params : Parameters
        Component parameters and environment.
    grid_name : str
        Preset name, or ``"custom"``; stored in the file.
    progress : callable, optional
        Called as ``progress(done, total)`` after each chunk.
    chunk_size : int
        Points evaluated per call of the bench (bounds the working memory).
    fluid : Fluid, optional
        Property source; built from ``params`` if not given.

    Raises
    ------
    EvtmsInputError
        An axis is out of range (e.g. ``p_in`` at or above the critical pressure).
    """
    from evtms.luts.io import build_dataset

    fluid = fluid or Fluid(params.fluid, params.backend)
    for name, values in grid.items():
        check_axis(name, np.asarray(values, float), fluid)
    outputs = evaluate_grid(bench, grid, params, fluid, progress, chunk_size)
    return build_dataset(
        grid=grid,
        outputs=outputs,
        flags=bench.flags,
        valid_flags=bench.valid_flags,
        **bench_attributes(bench, params, grid_name),
    )


def bench_attributes(bench: Bench, params: Parameters, grid_name: str) -> dict[str, str]:
    """Keyword arguments of :func:`evtms.luts.io.global_attributes` for a bench's LUT."""
    return {
        "component": bench.name,
        "title": bench.title,
        "parameters_json": params.component_json(bench.name),
        "environment_json": params.environment_json(),
        "grid_name": grid_name,
        "fluid": params.fluid,
        "coolprop_version": coolprop_version(),
        "history": f"evtms bench {bench.name} --grid {grid_name}",
    }
