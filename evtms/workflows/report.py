"""Figures and reports from files: cycle diagrams, energy balances, bench reports, simulations, range.

What ``evtms report ph-diagram|pt-diagram|energy-balance|bench|simulation|range``
run: each checks its input file (one :class:`~evtms.errors.EvtmsInputError`
line for a file that is missing, not netCDF or not of the right kind) and its
output path before anything is drawn, then draws with :mod:`evtms.reports`.
``evtms report compare`` is :func:`evtms.workflows.compare.run_comparison`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file, output_folder, staged_folder

__all__ = ["bench_report", "cycle_diagram", "energy_balance_report", "range_report", "simulation_report"]

_FIGURES = (".png", ".svg")


def _load_netcdf(path: Path, what: str):
    """The netCDF file ``path`` loaded into memory; missing, not netCDF or truncated: one line."""
    import xarray as xr

    input_file(path, what)
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            return ds.load()
    except Exception as exc:  # not netCDF, truncated: one line, not an HDF5 traceback
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise EvtmsInputError(f"{path}: not a readable {what} ({first})") from None


def _open_cycle(path: Path):
    """A cycle sweep file, loaded and checked."""
    ds = _load_netcdf(path, "cycle sweep file")
    if "status" not in ds or "p_A" not in ds or "reason" not in ds:
        raise EvtmsInputError(f"{path}: not an evtms cycle sweep (write one with 'evtms cycle sweep')")
    return ds


def _open_simulation(path: Path, variables: tuple[str, ...] = ()):
    """A simulation output file (evtms simulate), loaded and checked."""
    from evtms.reports.system_plots import check_simulation

    ds = _load_netcdf(path, "simulation file")
    try:
        check_simulation(ds, variables)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"{path}: {exc}") from None
    return ds


def _parse_index(ds, text: str | None):
    """The operating point ``input=index,...`` (0-based; the request field ``point``) of a sweep."""
    if text is None:
        return None
    index = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        name = name.strip()
        if name not in ds["status"].dims:
            raise EvtmsInputError(f"unknown input {name!r} in `point`; allowed: {', '.join(ds['status'].dims)}")
        if name in index:
            raise EvtmsInputError(f"input {name!r} is given twice in `point`")
        try:
            index[name] = int(value)
        except ValueError:
            raise EvtmsInputError(f"`point` {name}={value!r}: give a 0-based index along that input") from None
        if not 0 <= index[name] < ds.sizes[name]:
            raise EvtmsInputError(f"`point` {name}={value}: allowed 0 to {ds.sizes[name] - 1}")
    return {d: index.get(d, 0) for d in ds["status"].dims}


def cycle_diagram(kind: str, sweep: str | Path, output: str | Path, point: str | None = None) -> Path:
    """The p-h (``kind`` ``ph``) or p-T (``pt``) diagram of one operating point of a cycle sweep.

    ``point`` is ``input=index,...`` (0-based; default: the first solved point).
    Returns the figure written (``.png`` or ``.svg``).
    """
    from evtms.fluid import Fluid
    from evtms.reports.cycle_plots import diagram_data, ph_diagram, pt_diagram

    output = output_file(output, [sweep], _FIGURES)
    ds = _open_cycle(Path(sweep))
    try:
        states = diagram_data(ds, _parse_index(ds, point))
    except ValueError as exc:
        raise EvtmsInputError(str(exc)) from None
    with creating_parents(output):
        (ph_diagram if kind == "ph" else pt_diagram)(states, Fluid(), output)
    return output


def energy_balance_report(sweep: str | Path, output: str | Path, x: str | None = None) -> tuple[Path, Path]:
    """The energy balance over the swept input ``x`` (default: the one with several values) of a sweep.

    Returns the figure and the ``.csv`` table written beside it.
    """
    from evtms.reports.cycle_plots import energy_balance_figure

    output = output_file(output, [sweep], _FIGURES)
    output_file(output.with_suffix(".csv"), [sweep])
    ds = _open_cycle(Path(sweep))
    if x is None:
        varied = [d for d in ds["status"].dims if ds.sizes[d] > 1]
        if len(varied) != 1:
            raise EvtmsInputError(
                f"the sweep varies {len(varied)} inputs ({', '.join(varied) or 'none'}); an energy balance takes one"
            )
        x = varied[0]
    try:
        with creating_parents(output):
            energy_balance_figure(ds, x, output)
    except ValueError as exc:
        raise EvtmsInputError(str(exc)) from None
    return output, output.with_suffix(".csv")


def bench_report(
    file: str | Path, output: str | Path, at: str | None = None, surface: str | None = None, fmt: str = "png"
) -> tuple[int, Path]:
    """Bench figures and an HTML page from a LUT into the folder ``output`` (all or nothing).

    ``at`` is the base point ``name=value,...`` (nearest grid values; default: the first ones),
    ``surface`` two different axes for the 3-D map (``p_in,T_in``), ``fmt`` png or svg.
    Returns the number of figures and the page written.
    """
    from evtms.luts.validate import fixed_inputs
    from evtms.reports.bench_plots import base_point, bench_report_figures, surface_data
    from evtms.reports.html import bench_report_page
    from evtms.workflows.lut import open_lut_file, parse_point

    if fmt not in ("png", "svg"):
        raise EvtmsInputError(f"figure format {fmt!r} is not allowed; allowed: png, svg")
    output = output_folder(output, [file])
    ds = open_lut_file(file)
    dims = tuple(ds["status"].dims)
    base = base_point(ds, parse_point(at, dims, partial=True, fixed=fixed_inputs(ds)) if at else None)
    pair = None
    if surface:
        parts = tuple(p.strip() for p in surface.split(","))
        if len(parts) != 2:
            raise EvtmsInputError(f"`surface` {surface!r} must name two axes, e.g. p_in,T_in")
        if parts[0] == parts[1]:
            raise EvtmsInputError(f"`surface` {surface!r} names the axis {parts[0]!r} twice; give two different axes")
        surface_data(ds, parts, base)  # checks the axes before anything is drawn
        pair = parts
    with staged_folder(output) as stage:
        figures = bench_report_figures(ds, stage, base, pair, fmt)
        bench_report_page(ds, figures, stage / "index.html", str(file))
    return len(figures), output / "index.html"


def simulation_report(run: str | Path, output: str | Path, t_amb: float | None = None) -> Path:
    """The time series of one run of a simulation file (``t_amb`` [degC] picks one of a sweep)."""
    from evtms.reports.system_plots import SIMULATION_VARIABLES, simulation_figure

    output = output_file(output, [run], _FIGURES)
    ds = _open_simulation(Path(run), SIMULATION_VARIABLES)
    try:
        with creating_parents(output):
            simulation_figure(ds, output, None if t_amb is None else t_amb + 273.15)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"{run}: {exc}") from None
    return output


def range_report(sweep: str | Path, output: str | Path, heating: str | Sequence[str] | None = None) -> dict:
    """Range against the ambient of a simulation sweep or range-test file.

    ``heating`` (text ``a,b`` or names) picks the range test's curves to draw (default: every heating option
    in the file). Returns the depletion report of a range test
    (:func:`evtms.reports.system_plots.depletion_report`; empty for a single-trip sweep) once the figure is
    written.
    """
    from evtms.reports.system_plots import depletion_report, range_figure, range_test
    from evtms.workflows.simulate import heating_options

    options = heating_options(heating)
    output = output_file(output, [sweep], _FIGURES)
    ds = _open_simulation(Path(sweep))
    try:
        if options is not None and range_test(ds) == "single":
            raise EvtmsInputError("`heating` picks a range test's curves; this file is a single-trip sweep")
        with creating_parents(output):
            range_figure(ds, output, options)
        return depletion_report(ds, options) if range_test(ds) != "single" else {}
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"{sweep}: {exc}") from None
