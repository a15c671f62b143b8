"""Command-line interface: parses, calls library code, prints.

Heavy libraries (CoolProp, xarray, matplotlib) are imported inside the
commands that need them, so ``evtms --help`` answers at once.
"""

from __future__ import annotations

import json
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


lut_app = typer.Typer(help="Read, check, query, export and compare LUT files.", no_args_is_help=True)
app.add_typer(lut_app, name="lut")


def _open(path: Path):
    from evtms.luts import open_lut

    try:
        return open_lut(path)
    except EvtmsInputError as exc:
        fail(str(exc))


def _fmt(x: float) -> str:
    return f"{x:.6g}"


@lut_app.command("info")
def lut_info(file: Annotated[Path, typer.Argument(help="LUT file (.nc).")]) -> None:
    """Show a LUT's component, axes, variables, invalid points and provenance.

    Example: evtms lut info luts/condenser.nc
    """
    from evtms.luts.summary import lut_summary

    s = lut_summary(_open(file))
    typer.echo(f"{file}: {s['component']} LUT, fluid {s['fluid']}, grid {s['grid']}, format v{s['format']}")
    typer.echo("axes:")
    for a in s["axes"]:
        typer.echo(
            f"  {a['name']:<8} {a['size']:>4} values  {_fmt(a['min']):>10} .. {_fmt(a['max']):<10} "
            f"[{a['units']}]  {a['long_name']}"
        )
    typer.echo("variables (range over valid points):")
    for v in s["variables"]:
        typer.echo(f"  {v['name']:<10} {_fmt(v['min']):>12} .. {_fmt(v['max']):<12} [{v['units']}]  {v['long_name']}")
    typer.echo(f"points: {s['points']}, valid: {s['valid']}, invalid: {s['points'] - s['valid']}")
    for c in s["status"]:
        typer.echo(f"  status {c['code']:>3} {c['meaning']:<40} {c['count']}")
    p = s["provenance"]
    typer.echo(f"provenance: evtms {p['evtms_version']}, CoolProp {p['coolprop_version']}, created {p['created']}")
    typer.echo(f"history: {p['history']}")
    typer.echo(f"environment: {json.dumps(s['environment'], sort_keys=True)}")
    typer.echo(f"parameters: {json.dumps(s['parameters'], sort_keys=True)}")


def _parse_point(text: str, names: tuple[str, ...]) -> dict[str, float]:
    """``name=value[unit],...`` -> SI values (units as for --axis)."""
    from evtms.benches.grid import parse_value

    point = {}
    for item in text.split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise EvtmsInputError(f"--at item {item!r} is not name=value")
        if name not in names:
            raise EvtmsInputError(f"unknown axis {name!r} in --at; allowed: {', '.join(names)}")
        point[name] = parse_value(name, value)
    missing = [n for n in names if n not in point]
    if missing:
        raise EvtmsInputError(f"--at has no value for axis {missing[0]!r}; give all of {', '.join(names)}")
    return point


@lut_app.command("query")
def lut_query(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    at: Annotated[
        list[str], typer.Option("--at", help="Point as name=value,... (SI, or with a unit suffix). Repeatable.")
    ],
    var: Annotated[list[str] | None, typer.Option("--var", help="Variable(s) to report; default all.")] = None,
    out_of_range: Annotated[
        str, typer.Option("--out-of-range", help="Policy outside the grid: error, clip or nan.")
    ] = "error",
) -> None:
    """Interpolate LUT variables at points (N-D multilinear).

    Example: evtms lut query luts/condenser.nc --at mdot=0.005,fan=0.2,p_in=1e6,T_in=340,T_res=300 --var Q
    """
    from evtms.luts import Interpolator

    ds = _open(file)
    try:
        names = tuple(ds["status"].dims)
        variables = [v for item in (var or []) for v in item.split(",") if v] or None
        itp = Interpolator.from_dataset(ds, variables, out_of_range)
        points = [_parse_point(text, names) for text in at]
        query = {n: [p[n] for p in points] for n in names}
        result = itp(query)
    except EvtmsInputError as exc:
        fail(str(exc))
    header = [f"{n} [{ds[n].attrs['units']}]" for n in names] + [f"{v} [{ds[v].attrs['units']}]" for v in itp.variables]
    typer.echo("  ".join(header))
    for i, p in enumerate(points):
        row = [_fmt(p[n]) for n in names] + [_fmt(float(result[v][i])) for v in itp.variables]
        typer.echo("  ".join(row))


@lut_app.command("export")
def lut_export(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    fmt: Annotated[str, typer.Option("--format", "-f", help="mat (MATLAB/Simulink) or csv (long form).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Output file.")],
) -> None:
    """Export a LUT to .mat for MATLAB/Simulink or to long-form .csv.

    Example: evtms lut export luts/condenser.nc --format mat -o condenser.mat
    """
    from evtms.luts.export import FORMATS, to_csv, to_mat

    if fmt not in FORMATS:
        fail(f"export format {fmt!r} is not allowed; allowed: {', '.join(FORMATS)}")
    check_output_file(output)
    ds = _open(file)
    path = (to_mat if fmt == "mat" else to_csv)(ds, output)
    typer.echo(f"wrote {path}")


@lut_app.command("diff")
def lut_diff_cmd(
    a: Annotated[Path, typer.Argument(help="First LUT file.")],
    b: Annotated[Path, typer.Argument(help="Second LUT file.")],
) -> None:
    """Compare two LUTs: per-variable max and RMS differences, parameter and version changes.

    Example: evtms lut diff old/condenser.nc luts/condenser.nc
    """
    from evtms.luts.diff import lut_diff

    da, db = _open(a), _open(b)
    try:
        d = lut_diff(da, db)
    except EvtmsInputError as exc:
        fail(str(exc))
    typer.echo(
        f"common grid: {' x '.join(str(n) for n in d.common_shape)} points; status differs at {d.status_changed}"
    )
    typer.echo(f"  {'variable':<10} {'max |diff|':>12} {'RMS diff':>12} {'max rel':>10}  units")
    for v in d.variables:
        typer.echo(f"  {v.name:<10} {_fmt(v.max_abs):>12} {_fmt(v.rms):>12} {_fmt(v.max_rel):>10}  {v.units}")
    if not d.parameters and not d.attributes:
        typer.echo("parameters and versions: identical")
    for key, (x, y) in {**d.attributes, **d.parameters}.items():
        typer.echo(f"  {key}: {x} -> {y}")


def _isin(values, allowed):
    import numpy as np

    return np.isin(values, allowed)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
