"""Command-line interface: parses, calls library code, prints.

Heavy libraries (CoolProp, xarray, matplotlib) are imported inside the
commands that need them, so ``evtms --help`` answers at once.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Annotated, NoReturn

import typer

from evtms import __version__
from evtms.errors import EvtmsInputError

app = typer.Typer(
    name="evtms",
    help="R134a refrigerant-circuit benches, N-D lookup tables and cycle models for EV thermal management.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)

COMPONENT_ALIASES = {
    "condenser": "condenser",
    "evaporator": "evaporator",
    "expansion-valve": "expansion_valve",
    "expansion_valve": "expansion_valve",
    "compressor": "compressor",
}


def fail(message: str) -> NoReturn:
    """Print a one-line error and exit with code 2 (bad input)."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(2)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"evtms {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version_callback, is_eager=True, help="Show the version and exit.")
    ] = False,
) -> None:
    """R134a refrigerant-circuit benches, N-D lookup tables and cycle models."""


def check_output_file(path: Path) -> Path:
    """Fail early if ``path`` cannot be written (missing or read-only folder)."""
    parent = path.parent if str(path.parent) else Path(".")
    if path.exists() and path.is_dir():
        fail(f"output {str(path)!r} is a folder; give a file path ending in .nc")
    if not parent.is_dir():
        fail(f"output folder {str(parent)!r} does not exist; create it or choose an existing folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        fail(f"output folder {str(parent)!r} is not writable")
    return path


def check_output_folder(path: Path) -> Path:
    """An output folder: created if its parent exists, else an error."""
    if path.exists() and not path.is_dir():
        fail(f"output {str(path)!r} is a file; give a folder for several outputs")
    if not path.exists():
        if not path.parent.is_dir():
            fail(f"output folder {str(path.parent)!r} does not exist; create it or choose an existing folder")
        try:
            path.mkdir()
        except OSError as exc:
            fail(f"output folder {str(path)!r} cannot be created: {exc.strerror}")
    if not os.access(path, os.W_OK | os.X_OK):
        fail(f"output folder {str(path)!r} is not writable")
    return path


class _ProgressBar:
    """A rich progress bar on stderr, one task per bench."""

    def __init__(self, quiet: bool) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        self._progress = Progress(
            TextColumn("{task.description:<16}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeRemainingColumn(),
            console=Console(stderr=True),
            disable=quiet,
            transient=False,
        )

    def __enter__(self) -> _ProgressBar:
        self._progress.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.__exit__(*exc)

    def task(self, name: str, total: int):
        task = self._progress.add_task(name, total=total, rate="")
        t0 = time.perf_counter()

        def update(done: int, total: int) -> None:
            rate = done / max(time.perf_counter() - t0, 1e-9)
            self._progress.update(task, completed=done, total=total, rate=f"{rate:,.0f} pt/s")

        return update


def _parse_grid(component: str, grid: str, axis: list[str] | None):
    from evtms.benches import BENCHES
    from evtms.benches.grid import build_grid, parse_axis

    bench = BENCHES[component]
    overrides = dict(parse_axis(spec, bench) for spec in axis or [])
    preset = grid if grid != "custom" else None
    values = build_grid(bench, preset, overrides)
    name = grid if not overrides else "custom"
    return bench, values, name


@app.command()
def bench(
    component: Annotated[
        str, typer.Argument(help="condenser, evaporator, expansion-valve, compressor, or all.", show_default=False)
    ],
    grid: Annotated[str, typer.Option("--grid", "-g", help="Grid preset: thesis, cycle, or custom.")] = "thesis",
    axis: Annotated[
        list[str] | None,
        typer.Option(
            "--axis",
            "-a",
            help="Override or add an axis: name=start:stop:count[unit] or name=v1,v2,...[unit]. Repeatable.",
        ),
    ] = None,
    params: Annotated[Path | None, typer.Option("--params", help="TOML file overriding component parameters.")] = None,
    output: Annotated[
        Path | None,
        typer.Option("--output", "-o", help="Output .nc file (a folder for 'all'). Default: luts/<name>.nc"),
    ] = None,
    backend: Annotated[
        str | None, typer.Option("--backend", help="CoolProp backend: HEOS (default) or BICUBIC&HEOS.")
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
) -> None:
    """Sweep a component bench over a grid and write its LUT (netCDF).

    Example: evtms bench condenser --grid thesis -o luts/condenser.nc

    Custom axes: evtms bench condenser --axis mdot=0.004:0.008:5 --axis p_in=0.9:1.2:4MPa -o c.nc
    """
    from evtms.params import load_parameters

    names = list(dict.fromkeys(COMPONENT_ALIASES.values())) if component == "all" else None
    if names is None:
        if component not in COMPONENT_ALIASES:
            fail(f"unknown bench {component!r}; allowed: {', '.join(COMPONENT_ALIASES)}, all")
        names = [COMPONENT_ALIASES[component]]
    if component == "all":
        if axis:
            fail("--axis applies to one bench; run the benches one by one for custom axes")
        folder = check_output_folder(output or Path("luts"))
        targets = {name: folder / f"{name}.nc" for name in names}
    elif output is None:
        targets = {names[0]: check_output_folder(Path("luts")) / f"{names[0]}.nc"}
    else:
        targets = {names[0]: check_output_file(output)}
    try:
        parameters = load_parameters(params)
        if backend is not None:
            import dataclasses

            parameters = dataclasses.replace(parameters, backend=backend)
        jobs = [(name, *_parse_grid(name, grid, axis)) for name in names]
    except EvtmsInputError as exc:
        fail(str(exc))

    from evtms.benches.sweep import run_sweep
    from evtms.fluid import Fluid
    from evtms.luts.io import write_lut

    try:
        fluid = Fluid(parameters.fluid, parameters.backend)
    except ValueError as exc:
        fail(f"fluid {parameters.fluid!r} with backend {parameters.backend!r} cannot be loaded ({exc})")
    with _ProgressBar(quiet or not sys.stderr.isatty()) as bar:
        for name, bench_, values, grid_name in jobs:
            total = 1
            for v in values.values():
                total *= len(v)
            t0 = time.perf_counter()
            try:
                ds = run_sweep(
                    bench_, values, parameters, grid_name=grid_name, progress=bar.task(name, total), fluid=fluid
                )
            except EvtmsInputError as exc:
                fail(str(exc))
            path = write_lut(ds, targets[name])
            wall = time.perf_counter() - t0
            status = ds["status"].values
            invalid = int((~_isin(status, ds["status"].attrs["valid_flag_values"])).sum())
            typer.echo(f"{name}: {total} points, {invalid} invalid, {wall:.2f} s, wrote {path}")


def _isin(values, allowed):
    import numpy as np

    return np.isin(values, allowed)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
