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
    workers: Annotated[
        int | None, typer.Option("--workers", help="Run the sweep in N local dask worker processes.")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Send the sweep to a dask.distributed scheduler, tcp://host:port.")
    ] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Reuse the finished chunks of an interrupted sweep to the same output.")
    ] = False,
    chunk_points: Annotated[int, typer.Option("--chunk-points", help="Points per chunk (bounds memory).")] = 16384,
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

    from evtms.benches.chunked import InProcessRunner, sweep_to_file

    if workers is not None and workers < 1:
        fail(f"--workers {workers} is not allowed; allowed: 1 or more")
    if workers is not None and scheduler is not None:
        fail("give --workers or --scheduler, not both")
    if chunk_points < 1:
        fail(f"--chunk-points {chunk_points} is not allowed; allowed: 1 or more")
    try:
        from evtms.fluid import Fluid

        Fluid(parameters.fluid, parameters.backend)
    except ValueError as exc:
        fail(f"fluid {parameters.fluid!r} with backend {parameters.backend!r} cannot be loaded ({exc})")
    try:
        if workers is None and scheduler is None:
            runner = InProcessRunner()  # plain NumPy in this process: dask is not imported
        else:
            from evtms.benches.chunked import DaskRunner

            runner = DaskRunner(workers=workers, scheduler=scheduler)
    except EvtmsInputError as exc:
        fail(str(exc))
    try:
        with _ProgressBar(quiet or not sys.stderr.isatty()) as bar:
            for name, bench_, values, grid_name in jobs:
                total = 1
                for v in values.values():
                    total *= len(v)
                try:
                    s = sweep_to_file(
                        bench_,
                        values,
                        parameters,
                        targets[name],
                        grid_name=grid_name,
                        runner=runner,
                        chunk_points=chunk_points,
                        resume=resume,
                        progress=bar.task(name, total),
                    )
                except EvtmsInputError as exc:
                    fail(str(exc))
                chunks = f"{s.chunks} chunks ({s.computed} computed, {s.reused} reused), " if s.chunks > 1 else ""
                typer.echo(
                    f"{name}: {s.points} points, {s.invalid} invalid, {chunks}{s.seconds:.2f} s "
                    f"({runner.name}), wrote {s.path}"
                )
    finally:
        runner.close()


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


def _parse_point(text: str, names: tuple[str, ...], partial: bool = False) -> dict[str, float]:
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
    if missing and not partial:
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


cycle_app = typer.Typer(help="Solve the vapor-compression cycle on the component LUTs.", no_args_is_help=True)
app.add_typer(cycle_app, name="cycle")

_CYCLE_RANGES = {
    "speed": (0.0, 1.0),
    "fan": (0.0, 1.0),
    "blower": (0.0, 1.0),
    "RH_amb": (0.0, 1.0),
    "RH_cabin": (0.0, 1.0),
    "superheat": (0.0, 50.0),
    "subcooling": (0.0, 30.0),
    "T_amb": (233.15, 333.15),
    "T_cabin": (253.15, 323.15),
}


def _cycle_values(name: str, text: str, celsius: bool) -> list[float]:
    """A cycle input: one value, v1,v2,... or start:stop:count; degC inputs to K."""
    import numpy as np

    try:
        if ":" in text:
            start, stop, count = text.split(":")
            values = np.linspace(float(start), float(stop), int(count)).tolist()
        else:
            values = [float(v) for v in text.split(",")]
    except ValueError:
        raise EvtmsInputError(
            f"--{name.replace('_', '-').lower()} {text!r} is not a number, v1,v2,... or start:stop:count"
        ) from None
    if celsius:
        values = [v + 273.15 for v in values]
    lo, hi = _CYCLE_RANGES[name]
    for v in values:
        if not lo <= v <= hi or (name in ("speed", "fan", "blower") and v == 0):
            shown = f"{v - 273.15:g} degC" if celsius else f"{v:g}"
            allowed = f"{lo - 273.15:g} to {hi - 273.15:g} degC" if celsius else f"{lo:g} to {hi:g}"
            raise EvtmsInputError(f"{name} = {shown} is not allowed; allowed: {allowed}")
    if any(b <= a for a, b in zip(values, values[1:], strict=False)):
        raise EvtmsInputError(f"{name} values must be strictly increasing")
    return values


def _cycle_inputs(
    speed, fan, blower, t_amb, rh_amb, t_cabin, rh_cabin, superheat, subcooling
) -> dict[str, list[float]]:
    raw = {
        "speed": (speed, False),
        "fan": (fan, False),
        "blower": (blower, False),
        "T_amb": (t_amb, True),
        "RH_amb": (rh_amb, False),
        "T_cabin": (t_cabin, True),
        "RH_cabin": (rh_cabin, False),
        "superheat": (superheat, False),
        "subcooling": (subcooling, False),
    }
    return {name: _cycle_values(name, text, c) for name, (text, c) in raw.items()}


def _solve(luts: Path | None, direct: bool, params: Path | None, grid: dict[str, list[float]]):
    import numpy as np

    from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
    from evtms.cycle.solver import INPUTS
    from evtms.params import load_parameters

    parameters = load_parameters(params)
    tables = None if direct else load_cycle_luts(luts or Path("luts"))
    mesh = np.meshgrid(*[np.asarray(grid[k]) for k in INPUTS], indexing="ij")
    points = OperatingPoints(**{k: m.ravel() for k, m in zip(INPUTS, mesh, strict=True)})
    return points, run_cycle(points, tables, parameters)


_SPEED = typer.Option("--speed", help="Compressor speed fraction (0-1].")
_FAN = typer.Option("--fan", help="Condenser fan fraction (0-1].")
_BLOWER = typer.Option("--blower", help="Evaporator blower fraction (0-1].")
_TAMB = typer.Option("--t-amb", help="Ambient air temperature [degC].")
_RHAMB = typer.Option("--rh-amb", help="Ambient relative humidity (0-1).")
_TCAB = typer.Option("--t-cabin", help="Air temperature entering the evaporator [degC].")
_RHCAB = typer.Option("--rh-cabin", help="Relative humidity entering the evaporator (0-1).")
_SH = typer.Option("--superheat", help="Thermostatic-valve superheat setpoint [K].")
_SC = typer.Option("--subcooling", help="Condenser-outlet subcooling [K]; 0 = saturated liquid (receiver).")
_LUTS = typer.Option("--luts", help="Folder with the cycle LUTs (evtms bench all --grid cycle). Default: luts/")
_DIRECT = typer.Option("--direct", help="Use the bench physics directly instead of LUTs (reference, slower).")
_PARAMS = typer.Option("--params", help="TOML parameter overrides (direct mode and valve limits).")


@cycle_app.command("run")
def cycle_run(
    speed: Annotated[str, _SPEED] = "0.6",
    fan: Annotated[str, _FAN] = "0.5",
    blower: Annotated[str, _BLOWER] = "0.4",
    t_amb: Annotated[str, _TAMB] = "30",
    rh_amb: Annotated[str, _RHAMB] = "0.4",
    t_cabin: Annotated[str, _TCAB] = "27",
    rh_cabin: Annotated[str, _RHCAB] = "0.5",
    superheat: Annotated[str, _SH] = "10",
    subcooling: Annotated[str, _SC] = "0",
    luts: Annotated[Path | None, _LUTS] = None,
    direct: Annotated[bool, _DIRECT] = False,
    params: Annotated[Path | None, _PARAMS] = None,
) -> None:
    """Solve one operating point and print its states and performance.

    Example: evtms cycle run --luts luts/ --speed 0.6 --fan 0.5 --blower 0.4 --t-amb 30 --t-cabin 27
    """
    try:
        grid = _cycle_inputs(speed, fan, blower, t_amb, rh_amb, t_cabin, rh_cabin, superheat, subcooling)
        if any(len(v) != 1 for v in grid.values()):
            raise EvtmsInputError("cycle run takes one value per input; use 'evtms cycle sweep' for several")
        _, r = _solve(luts, direct, params, grid)
    except EvtmsInputError as exc:
        fail(str(exc))
    from evtms.cycle.solver import VALID_CYCLE_FLAGS

    if int(r["status"][0]) not in VALID_CYCLE_FLAGS:
        fail(f"operating point not solved: {r['reason'][0]}")
    typer.echo(f"{'state':<26} {'p [MPa]':>9} {'T [degC]':>9} {'h [kJ/kg]':>10}")
    names = {"A": "A evaporator outlet", "B": "B compressor outlet", "C": "C condenser outlet", "D": "D valve outlet"}
    for s, label in names.items():
        typer.echo(
            f"{label:<26} {r['p_' + s][0] / 1e6:9.4f} {r['T_' + s][0] - 273.15:9.2f} {r['h_' + s][0] / 1e3:10.2f}"
        )
    rows = [
        ("mass flow", r["mdot"][0] * 1e3, "g/s"),
        ("cooling |Q_evap|", -r["Q_evap"][0], "W"),
        ("  of which latent", -r["Q_latent"][0], "W"),
        ("Q_cond", r["Q_cond"][0], "W"),
        ("compressor shaft power W", r["W"][0], "W"),
        ("cooling COP", r["COP"][0], "-"),
        ("valve pressure drop", r["dp_valve"][0] / 1e3, "kPa"),
        ("valve opening / nominal", r["valve_opening"][0], "-"),
        ("energy balance residual", r["balance_residual"][0], "W"),
        ("  relative to W_fluid", 100 * r["balance_relative"][0], "%"),
    ]
    for label, value, unit in rows:
        typer.echo(f"{label:<26} {value:10.4g} {unit}")
    if r["reason"][0]:
        typer.echo(f"note: {r['reason'][0]}")


@cycle_app.command("sweep")
def cycle_sweep(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    speed: Annotated[str, _SPEED] = "0.6",
    fan: Annotated[str, _FAN] = "0.5",
    blower: Annotated[str, _BLOWER] = "0.4",
    t_amb: Annotated[str, _TAMB] = "30",
    rh_amb: Annotated[str, _RHAMB] = "0.4",
    t_cabin: Annotated[str, _TCAB] = "27",
    rh_cabin: Annotated[str, _RHCAB] = "0.5",
    superheat: Annotated[str, _SH] = "10",
    subcooling: Annotated[str, _SC] = "0",
    luts: Annotated[Path | None, _LUTS] = None,
    direct: Annotated[bool, _DIRECT] = False,
    params: Annotated[Path | None, _PARAMS] = None,
) -> None:
    """Solve a grid of operating points (any input as v1,v2,... or start:stop:count) and write netCDF.

    Example: evtms cycle sweep --luts luts/ --speed 0.2:1:9 --t-amb 25,35,45 -o cycle.nc
    """
    check_output_file(output)
    try:
        grid = _cycle_inputs(speed, fan, blower, t_amb, rh_amb, t_cabin, rh_cabin, superheat, subcooling)
        t0 = time.perf_counter()
        points, r = _solve(luts, direct, params, grid)
        wall = time.perf_counter() - t0
    except EvtmsInputError as exc:
        fail(str(exc))
    from evtms.cycle import cycle_dataset
    from evtms.cycle.solver import VALID_CYCLE_FLAGS
    from evtms.luts.io import atomic_output

    ds = cycle_dataset(grid, r, "direct" if direct else f"LUTs in {luts or 'luts'}")
    with atomic_output(output) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4")
    ok = int(_isin(r["status"], VALID_CYCLE_FLAGS).sum())
    typer.echo(f"cycle: {len(points)} operating points, {ok} solved, {wall:.2f} s, wrote {output}")


report_app = typer.Typer(help="Figures and reports from LUT files and cycle sweeps.", no_args_is_help=True)
app.add_typer(report_app, name="report")


def _open_cycle(path: Path):
    import xarray as xr

    if not path.is_file():
        fail(f"{path}: no such file")
    try:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
    except Exception as exc:  # not netCDF, truncated: one line, not an HDF5 traceback
        fail(
            f"{path}: not a readable cycle sweep file ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
        )
    if "status" not in ds or "p_A" not in ds:
        fail(f"{path}: not an evtms cycle sweep (write one with 'evtms cycle sweep')")
    return ds


def _parse_index(ds, text: str | None):
    if text is None:
        return None
    index = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        if name not in ds["status"].dims:
            fail(f"unknown input {name!r} in --point; allowed: {', '.join(ds['status'].dims)}")
        try:
            index[name] = int(value)
        except ValueError:
            fail(f"--point {name}={value!r}: give a 0-based index along that input")
        if not 0 <= index[name] < ds.sizes[name]:
            fail(f"--point {name}={value}: allowed 0 to {ds.sizes[name] - 1}")
    return {d: index.get(d, 0) for d in ds["status"].dims}


def _diagram(kind: str, sweep: Path, output: Path, point: str | None) -> None:
    from evtms.fluid import Fluid
    from evtms.reports.cycle_plots import diagram_data, ph_diagram, pt_diagram

    if output.suffix.lower() not in (".png", ".svg"):
        fail(f"output {str(output)!r} must end in .png or .svg")
    check_output_file(output)
    ds = _open_cycle(sweep)
    try:
        states = diagram_data(ds, _parse_index(ds, point))
    except ValueError as exc:
        fail(str(exc))
    (ph_diagram if kind == "ph" else pt_diagram)(states, Fluid(), output)
    typer.echo(f"wrote {output}")


_POINT = typer.Option("--point", help="Operating point as input=index,... (0-based); default: the first solved.")


@report_app.command("ph-diagram")
def report_ph(
    sweep: Annotated[Path, typer.Argument(help="Cycle sweep file (evtms cycle sweep).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Figure file, .png or .svg.")],
    point: Annotated[str | None, _POINT] = None,
) -> None:
    """p-h diagram of an operating point: states A-D and the cycle on R134a's dome.

    Example: evtms report ph-diagram cycle.nc -o ph.svg --point speed=3
    """
    _diagram("ph", sweep, output, point)


@report_app.command("pt-diagram")
def report_pt(
    sweep: Annotated[Path, typer.Argument(help="Cycle sweep file (evtms cycle sweep).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Figure file, .png or .svg.")],
    point: Annotated[str | None, _POINT] = None,
) -> None:
    """p-T diagram of an operating point: states A-D and the cycle on R134a's saturation curve.

    Example: evtms report pt-diagram cycle.nc -o pt.png
    """
    _diagram("pt", sweep, output, point)


@report_app.command("energy-balance")
def report_energy_balance(
    sweep: Annotated[Path, typer.Argument(help="Cycle sweep varying one input (evtms cycle sweep).")],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Figure file, .png or .svg; a .csv table is written beside.")
    ],
    x: Annotated[str | None, typer.Option("--x", help="The swept input; default: the one with several values.")] = None,
) -> None:
    """Energy balance over a sweep: Q_cond, |Q_evap|, W_fluid (each from its LUT) and the residual.

    Example: evtms cycle sweep --speed 0.2:1:9 -o speed.nc && evtms report energy-balance speed.nc -o eb.png
    """
    from evtms.reports.cycle_plots import energy_balance_figure

    if output.suffix.lower() not in (".png", ".svg"):
        fail(f"output {str(output)!r} must end in .png or .svg")
    check_output_file(output)
    ds = _open_cycle(sweep)
    if x is None:
        varied = [d for d in ds["status"].dims if ds.sizes[d] > 1]
        if len(varied) != 1:
            fail(f"the sweep varies {len(varied)} inputs ({', '.join(varied) or 'none'}); an energy balance takes one")
        x = varied[0]
    try:
        energy_balance_figure(ds, x, output)
    except ValueError as exc:
        fail(str(exc))
    typer.echo(f"wrote {output} and {output.with_suffix('.csv')}")


@report_app.command("bench")
def report_bench(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc) of any bench.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder (created if its parent exists).")],
    at: Annotated[
        str | None, typer.Option("--at", help="Base point name=value,... (nearest grid value); default: first values.")
    ] = None,
    surface: Annotated[
        str | None, typer.Option("--surface", help="Two axes for the 3-D map, e.g. p_in,T_in (the default).")
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="Figure format: png or svg.")] = "png",
) -> None:
    """Bench figures and an HTML report from a LUT: response per axis, 3-D map, provenance.

    Example: evtms report bench luts/condenser.nc -o reports/condenser/
    """
    from evtms.reports.bench_plots import bench_report_figures
    from evtms.reports.html import bench_report_page

    if fmt not in ("png", "svg"):
        fail(f"figure format {fmt!r} is not allowed; allowed: png, svg")
    ds = _open(file)
    try:
        base = _parse_point(at, tuple(ds["status"].dims), partial=True) if at else None
        pair = None
        if surface:
            parts = tuple(p.strip() for p in surface.split(","))
            if len(parts) != 2:
                raise EvtmsInputError(f"--surface {surface!r} must name two axes, e.g. p_in,T_in")
            pair = parts
        folder = check_output_folder(output)
        figures = bench_report_figures(ds, folder, base, pair, fmt)
    except EvtmsInputError as exc:
        fail(str(exc))
    page = bench_report_page(ds, figures, folder / "index.html", str(file))
    typer.echo(f"wrote {len(figures)} figures and {page}")


@app.command()
def demo(
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Output folder (created if its parent exists).")
    ] = Path("out"),
    force: Annotated[bool, typer.Option("--force", help="Recompute LUTs even if they are up to date.")] = False,
    workers: Annotated[int, typer.Option("--workers", help="Processes for the bench sweeps.")] = 2,
    params: Annotated[Path | None, typer.Option("--params", help="TOML parameter overrides.")] = None,
) -> None:
    """The whole job: benches on the thesis and cycle grids, LUTs, a cycle sweep, figures, index.html.

    Example: evtms demo -o out/   (a second run reuses up-to-date LUTs; --force recomputes)
    """
    from evtms.demo import run_demo
    from evtms.params import load_parameters

    if workers < 1:
        fail(f"--workers {workers} is not allowed; allowed: 1 or more")
    try:
        parameters = load_parameters(params)
    except EvtmsInputError as exc:
        fail(str(exc))
    folder = check_output_folder(output)
    t0 = time.perf_counter()

    def notify(message: str) -> None:
        typer.echo(f"[{time.perf_counter() - t0:6.1f} s] {message}", err=True)

    result = run_demo(folder, parameters, force=force, workers=workers, notify=notify)
    typer.echo(
        f"demo: {len(result.computed)} LUTs computed, {len(result.reused)} reused, "
        f"{time.perf_counter() - t0:.1f} s; open {result.index.resolve()}"
    )


def _isin(values, allowed):
    import numpy as np

    return np.isin(values, allowed)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
