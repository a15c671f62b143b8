"""Command-line interface: parses, calls library code, prints.

Heavy libraries (CoolProp, xarray, matplotlib) are imported inside the
commands that need them, so ``evtms --help`` answers at once.
"""

from __future__ import annotations

import json
import math
import shlex
import sys
import time
from pathlib import Path
from typing import Annotated, NoReturn

import typer
from typer.core import TyperGroup

try:  # typer >= 0.20 carries its own copy of click
    from typer._click.exceptions import UsageError
except ImportError:  # pragma: no cover - older typer on click
    from click.exceptions import UsageError

from evtms import __version__
from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file, output_folder, staged_folder


class _EvtmsGroup(TyperGroup):
    """The root command: every error leaves as one ``error: ...`` line.

    Usage errors (a missing option, an unknown command) are one line, exit 2,
    instead of click's usage block; an :class:`EvtmsInputError` or an OS error
    (a read-only folder, a full disk, a name too long) that escapes a command
    is one line naming the path and the reason, exit 2, never a traceback.
    """

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        _ARGV[:] = list(sys.argv[1:] if args is None else args)
        code = 0
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            code = rv if isinstance(rv, int) else 0
        except UsageError as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # 'evtms lut' alone: the help, as click shows it
                exc.show()
                code = exc.exit_code
            else:
                code = _error(_usage_message(exc))
        except typer.Abort:
            code = _error("aborted", 130)
        except EvtmsInputError as exc:
            code = _error(str(exc))
        except OSError as exc:
            code = _error(_os_message(exc))
        except MemoryError:
            code = _error("out of memory; use a coarser grid or a smaller --chunk-points")
        if standalone_mode:
            sys.exit(code)
        return code


#: The arguments of this call (for the exact resume command after Ctrl-C).
_ARGV: list[str] = []


def _error(message: str, code: int = 2) -> int:
    typer.echo(f"error: {' '.join(str(message).split())}", err=True)
    return code


def _usage_message(exc: UsageError) -> str:
    message = exc.format_message()
    ctx = exc.ctx
    if message.startswith("No such command") and ctx is not None:
        names = [n for n in ctx.command.list_commands(ctx) if not ctx.command.get_command(ctx, n).hidden]
        message = f"{message.rstrip('.')} (allowed: {', '.join(names)})"
    where = ctx.command_path if ctx is not None else "evtms"
    return f"{message} (see '{where} --help')"


def _os_message(exc: OSError) -> str:
    path = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or type(exc).__name__
    return f"{str(path)!r}: {reason}" if path else reason


app = typer.Typer(
    cls=_EvtmsGroup,
    name="evtms",
    help="R134a refrigerant-circuit benches, N-D lookup tables and cycle models for EV thermal management.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def fail(message: str) -> NoReturn:
    """Print a one-line error and exit with code 2 (bad input)."""
    raise typer.Exit(_error(message))


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


def _json_safe(value):
    """``value`` with NaN and infinities as null (strict JSON), numpy scalars as Python numbers."""
    import math

    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def print_json(obj) -> None:
    """One JSON object on stdout, nothing else."""
    typer.echo(json.dumps(_json_safe(obj), allow_nan=False, sort_keys=False))


_JSON = typer.Option("--json", help="Print one JSON object on stdout (SI units) instead of the text summary.")


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


bench_app = typer.Typer(
    help=(
        "Sweep a component bench over a grid and write its LUT (netCDF). "
        "'evtms bench COMPONENT --help' lists that bench's axes, units, ranges and presets.\n\n"
        "Example: evtms bench condenser --grid thesis -o luts/condenser.nc"
    ),
    no_args_is_help=True,
)
app.add_typer(bench_app, name="bench")


def _bench_help(name: str) -> str:
    """A bench command's help, from its registry entry: axes with units and ranges, presets."""
    from evtms.benches import BENCHES
    from evtms.benches.grid import allowed_axes
    from evtms.luts.schema import AXES

    bench = BENCHES[name]
    cli = name.replace("_", "-")
    lines = [
        f"{bench.title}: sweep it over a grid and write its LUT (netCDF).",
        "",
        "\b",
        "Axes (--axis name=start:stop:count[unit] or name=v1,v2,...[unit]):",
    ]
    for a in allowed_axes(bench):
        spec = AXES[a]
        suffixes = ", ".join(u for u, _, _ in spec.cli_units) or "SI only"
        extra = " (optional extra axis)" if a in bench.extra_axes else ""
        lines.append(f"  {a} [{spec.units}]: {spec.long_name}{extra}; allowed {spec.allowed()}; units: {suffixes}")
    for preset, axes in bench.presets.items():
        lines += ["", "\b", f"Preset --grid {preset}:"]
        for a, values in axes.items():
            v = [float(x) for x in values]
            shown = f"{v[0]:g}" if len(v) == 1 else f"{len(v)} values {v[0]:g} .. {v[-1]:g}"
            lines.append(f"  {a} [{AXES[a].units}]: {shown}" + (" (fixed input)" if len(v) == 1 else ""))
    lines += ["", f"Example: evtms bench {cli} --grid {next(iter(bench.presets), 'thesis')} -o luts/{name}.nc"]
    return "\n".join(lines)


def _bench_command(names: list[str]):
    """The command that sweeps ``names`` (one bench, or all for 'bench all')."""

    def command(
        grid: Annotated[str, typer.Option("--grid", "-g", help="Grid preset: thesis, cycle, or custom.")] = "thesis",
        axis: Annotated[
            list[str] | None,
            typer.Option(
                "--axis",
                "-a",
                help="Override or add an axis: name=start:stop:count[unit] or name=v1,v2,...[unit]. Repeatable.",
            ),
        ] = None,
        params: Annotated[
            Path | None, typer.Option("--params", help="TOML file overriding component parameters.")
        ] = None,
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
            str | None,
            typer.Option(
                "--scheduler",
                help="Send the sweep to a dask.distributed scheduler, tcp://host:port (it runs the code sent to it: "
                "use only a cluster you trust).",
            ),
        ] = None,
        resume: Annotated[
            bool, typer.Option("--resume", help="Reuse the finished chunks of an interrupted sweep to the same output.")
        ] = False,
        chunk_points: Annotated[int, typer.Option("--chunk-points", help="Points per chunk (bounds memory).")] = 16384,
        max_points: Annotated[
            int | None,
            typer.Option("--max-points", help="Refuse grids above this many points (default 200,000,000)."),
        ] = None,
        float32: Annotated[
            bool, typer.Option("--float32", help="Store the variables as float32 (lossy, about half the size).")
        ] = False,
        significant_digits: Annotated[
            int | None,
            typer.Option("--significant-digits", help="Keep N significant digits (1-15; lossy, compresses better)."),
        ] = None,
        json_out: Annotated[bool, _JSON] = False,
    ) -> None:
        _run_benches(**{**locals(), "names": names})  # every option of this command, by name

    return command


def _register_benches() -> None:
    from evtms.benches import BENCHES

    for name in BENCHES:
        cli_name = name.replace("_", "-")
        bench_app.command(cli_name, help=_bench_help(name))(_bench_command([name]))
        if cli_name != name:  # the registry's spelling works too
            bench_app.command(name, help=_bench_help(name), hidden=True)(_bench_command([name]))
    bench_app.command(
        "all",
        help=(
            f"Sweep every bench ({', '.join(BENCHES)}) on one grid preset and write <folder>/<name>.nc.\n\n"
            "Example: evtms bench all --grid cycle -o luts/"
        ),
    )(_bench_command(list(BENCHES)))


def _run_benches(
    *,
    names: list[str],
    grid: str,
    axis: list[str] | None,
    params: Path | None,
    output: Path | None,
    backend: str | None,
    quiet: bool,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    chunk_points: int,
    max_points: int | None,
    float32: bool,
    significant_digits: int | None,
    json_out: bool,
) -> None:
    import dataclasses

    from evtms.benches import BENCHES
    from evtms.benches.chunked import InProcessRunner, SweepInterrupted, sweep_to_file
    from evtms.benches.grid import DEFAULT_MAX_POINTS, build_grid, parse_axes
    from evtms.benches.parameters import load_parameters
    from evtms.luts.io import LutStorage
    from evtms.params import check_backend

    max_points = DEFAULT_MAX_POINTS if max_points is None else max_points
    if max_points < 1:
        fail(f"--max-points {max_points} is not allowed; allowed: 1 or more")
    if workers is not None and workers < 1:
        fail(f"--workers {workers} is not allowed; allowed: 1 or more")
    if workers is not None and scheduler is not None:
        fail("give --workers or --scheduler, not both")
    if chunk_points < 1:
        fail(f"--chunk-points {chunk_points} is not allowed; allowed: 1 or more")
    storage = LutStorage(float32=float32, significant_digits=significant_digits)
    several = len(names) > 1
    if several and axis:
        fail("--axis applies to one bench; run the benches one by one for custom axes")
    inputs = [params] if params is not None else []
    if params is not None:
        input_file(params, "params file")
    if several:
        folder = output_folder(output or Path("luts"), inputs)
        targets = {name: output_file(folder / f"{name}.nc", inputs) for name in names}
    else:
        targets = {names[0]: output_file(output or Path("luts") / f"{names[0]}.nc", inputs, (".nc",))}
    parameters = load_parameters(params)
    if backend is not None:
        parameters = dataclasses.replace(parameters, backend=check_backend(backend))
    jobs = []
    for name in names:
        bench = BENCHES[name]
        overrides = parse_axes(axis or [], bench, max_points)
        values = build_grid(bench, grid if grid != "custom" else None, overrides, max_points)
        jobs.append((name, bench, values, grid if not overrides else "custom"))
    try:
        from evtms.fluid import Fluid

        Fluid(parameters.fluid, parameters.backend)
    except ValueError as exc:
        fail(f"fluid {parameters.fluid!r} with backend {parameters.backend!r} cannot be loaded ({exc})")
    if workers is None and scheduler is None:
        runner = InProcessRunner()  # plain NumPy in this process: dask is not imported
    else:
        from evtms.benches.chunked import DaskRunner

        runner = DaskRunner(workers=workers, scheduler=scheduler)
    summaries = []
    try:
        with _ProgressBar(quiet or json_out or not sys.stderr.isatty()) as bar:
            for name, bench, values, grid_name in jobs:
                total = math.prod(len(v) for v in values.values())
                with creating_parents(targets[name]):
                    s = sweep_to_file(
                        bench,
                        values,
                        parameters,
                        targets[name],
                        grid_name=grid_name,
                        runner=runner,
                        chunk_points=chunk_points,
                        resume=resume,
                        progress=bar.task(name, total),
                        storage=storage,
                    )
                for note in getattr(s, "notes", ()):
                    typer.echo(f"note: {note}", err=True)
                summaries.append((name, s))
                if not json_out:
                    chunks = f"{s.chunks} chunks ({s.computed} computed, {s.reused} reused), " if s.chunks > 1 else ""
                    typer.echo(
                        f"{name}: {s.points} points, {s.invalid} invalid, {chunks}{s.seconds:.2f} s "
                        f"({runner.name}), wrote {s.path}"
                    )
    except SweepInterrupted as exc:
        if exc.kept == 0:
            raise typer.Exit(_error("interrupted before the first chunk was saved; nothing to resume", 130)) from None
        command = shlex.join(["evtms", *[a for a in _ARGV if a != "--resume"], "--resume"])
        message = f"interrupted: {exc.kept} of {exc.total} chunks kept in {str(exc.partial)!r}; resume with: {command}"
        raise typer.Exit(_error(message, 130)) from None
    finally:
        runner.close()
    if json_out:
        print_json(
            {
                "benches": [
                    {
                        "component": name,
                        "path": str(s.path),
                        "points": s.points,
                        "invalid": s.invalid,
                        "chunks": s.chunks,
                        "computed": s.computed,
                        "reused": s.reused,
                        "seconds": s.seconds,
                        "runner": s.runner,
                        "notes": list(getattr(s, "notes", ())),
                    }
                    for name, s in summaries
                ]
            }
        )


_register_benches()


lut_app = typer.Typer(help="Read, check, query, export and compare LUT files.", no_args_is_help=True)
app.add_typer(lut_app, name="lut")


def _open(path: Path, **kwargs):
    """A validated LUT (see :func:`evtms.luts.open_lut`); a bad file is one line, exit 2."""
    from evtms.luts import open_lut

    return open_lut(input_file(path, "LUT file"), **kwargs)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


@lut_app.command("info")
def lut_info(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Show a LUT's component, axes, variables, invalid points and provenance.

    Reads the metadata and streams the data once for the ranges, so it stays
    fast and small on large LUTs.

    Example: evtms lut info luts/condenser.nc
    """
    from evtms.luts.summary import lut_summary

    s = lut_summary(input_file(file, "LUT file"))
    if json_out:
        print_json({"file": str(file), **s})
        return
    typer.echo(f"{file}: {s['component']} LUT, fluid {s['fluid']}, grid {s['grid']}, format v{s['format']}")
    typer.echo("axes:")
    for a in s["axes"]:
        typer.echo(
            f"  {a['name']:<8} {a['size']:>4} values  {_fmt(a['min']):>10} .. {_fmt(a['max']):<10} "
            f"[{a['units']}]  {a['long_name']}"
        )
    for name, fixed in s.get("fixed_inputs", {}).items():
        typer.echo(f"  {name:<8} fixed at {_fmt(fixed['value'])} [{fixed['units']}] (not an axis)")
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


def _parse_point(text: str, names: tuple[str, ...], partial: bool = False, fixed: dict | None = None) -> dict:
    """``name=value[unit],...`` -> SI values (units as for --axis).

    A fixed input of the LUT (``fixed``: name -> value) may be given too; it
    must then equal the LUT's value, as the LUT holds no other.
    """
    from evtms.benches.grid import parse_value

    fixed = fixed or {}
    point: dict[str, float] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise EvtmsInputError(f"--at item {item!r} is not name=value")
        if name not in names and name not in fixed:
            raise EvtmsInputError(f"unknown axis {name!r} in --at; allowed: {', '.join((*names, *fixed))}")
        if name in point:
            raise EvtmsInputError(f"axis {name!r} is given twice in --at")
        x = parse_value(name, value)
        if name in fixed:
            if not math.isclose(x, fixed[name], rel_tol=1e-9, abs_tol=1e-12):
                raise EvtmsInputError(
                    f"{name} = {x:g} in --at: the LUT holds {name} fixed at {fixed[name]:g} only (not an axis)"
                )
            continue
        point[name] = x
    missing = [n for n in names if n not in point]
    if missing and not partial:
        raise EvtmsInputError(f"--at has no value for axis {missing[0]!r}; give all of {', '.join(names)}")
    return point


_MAX_QUERY_POINTS = 100_000


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
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Interpolate LUT variables at points (N-D multilinear).

    Example: evtms lut query luts/condenser.nc --at mdot=0.005,fan=0.2,p_in=1e6,T_in=340,T_res=300 --var Q
    """
    from evtms.luts import Interpolator
    from evtms.luts.validate import fixed_inputs

    if len(at) > _MAX_QUERY_POINTS:
        fail(f"{len(at)} --at points is above the limit of {_MAX_QUERY_POINTS:,}")
    if out_of_range not in ("error", "clip", "nan"):
        fail(f"--out-of-range {out_of_range!r} is not allowed; allowed: error, clip, nan")
    variables = [v.strip() for item in (var or []) for v in item.split(",") if v.strip()] or None
    if variables is not None and len(set(variables)) != len(variables):
        fail(f"--var names a variable twice: {', '.join(variables)}")
    ds = _open(file, variables=variables)
    names = tuple(ds["status"].dims)
    fixed = fixed_inputs(ds)
    itp = Interpolator.from_dataset(ds, variables, out_of_range)
    points = [_parse_point(text, names, fixed=fixed) for text in at]
    query = {n: [p[n] for p in points] for n in names}
    result = itp(query)
    if json_out:
        print_json(
            {
                "file": str(file),
                "axes": list(names),
                "fixed_inputs": fixed,
                "variables": list(itp.variables),
                "units": {n: ds[n].attrs["units"] for n in (*names, *itp.variables)},
                "points": [
                    {**{n: p[n] for n in names}, **{v: float(result[v][i]) for v in itp.variables}}
                    for i, p in enumerate(points)
                ],
            }
        )
        return
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

    Length-1 axes are dropped from the .mat tables (Simulink's n-D Lookup
    Table rejects them) and recorded in lut.fixed_inputs.

    Example: evtms lut export luts/condenser.nc --format mat -o condenser.mat
    """
    from evtms.luts.export import FORMATS, to_csv, to_mat

    if fmt not in FORMATS:
        fail(f"export format {fmt!r} is not allowed; allowed: {', '.join(FORMATS)}")
    output_file(output, [file])
    ds = _open(file)
    with creating_parents(output):
        path = (to_mat if fmt == "mat" else to_csv)(ds, output)
    typer.echo(f"wrote {path}")


@lut_app.command("diff")
def lut_diff_cmd(
    a: Annotated[Path, typer.Argument(help="First LUT file.")],
    b: Annotated[Path, typer.Argument(help="Second LUT file.")],
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Compare two LUTs: per-variable max and RMS differences, parameter and version changes.

    Example: evtms lut diff luts/condenser.nc luts/condenser_44.nc
    """
    import dataclasses

    from evtms.luts.diff import lut_diff

    d = lut_diff(_open(a), _open(b))
    if json_out:
        summary = dataclasses.asdict(d)
        changed = {**summary.pop("attributes"), **summary.pop("parameters")}
        print_json({**summary, "changes": {k: {"from": x, "to": y} for k, (x, y) in changed.items()}})
        return
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

#: Operating points one 'cycle sweep' solves at most unless --max-points says otherwise.
DEFAULT_MAX_CYCLE_POINTS = 2_000_000


def _texts(*values: str | None) -> dict[str, str | None]:
    """The cycle commands' input options by input name (their order: ``evtms.cycle.topology.INPUTS``)."""
    from evtms.cycle.topology import INPUTS

    return dict(zip(INPUTS, values, strict=True))


def _cycle_inputs(topology: str, texts: dict[str, str | None], max_points: int = DEFAULT_MAX_CYCLE_POINTS):
    """(circuit, grid of its inputs) from the command line's texts; the library checks every value."""
    from evtms.cycle.topology import parse_inputs
    from evtms.cycle.topology import topology as circuit_named

    circuit = circuit_named(topology)
    return circuit, parse_inputs(texts, circuit, max_points)


def _cycle_models(luts: Path | None, direct: bool, params: Path | None, circuit):
    """(LUT tables or None, parameters) for a cycle command; a --params that the LUTs contradict is refused."""
    from evtms.benches.parameters import load_parameters
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.api import parameter_conflicts

    if direct and luts is not None:
        fail("give --direct (bench physics) or --luts (LUT folder), not both")
    if params is not None:
        input_file(params, "params file")
    parameters = load_parameters(params)
    if direct:
        return None, parameters
    folder = luts or Path("luts")
    tables = load_cycle_luts(folder, circuit)
    if params is not None:
        conflicts = parameter_conflicts(tables, parameters)
        if conflicts:
            shown = ", ".join(conflicts[:6]) + (f" and {len(conflicts) - 6} more" if len(conflicts) > 6 else "")
            fail(
                f"--params {str(params)!r} differs from the parameters the LUTs in {str(folder)!r} were made with "
                f"({shown}); rebuild the LUTs with these parameters or use --direct"
            )
    return tables, parameters


def _lut_folder(tables: dict) -> Path:
    """The folder the cycle LUTs were found in (one folder for all of them)."""
    return next(iter(tables.values())).path.parent


_SPEED = typer.Option("--speed", help="Compressor speed fraction (0-1].")
_FAN = typer.Option("--fan", help="Condenser fan fraction (0-1].")
_BLOWER = typer.Option("--blower", help="Evaporator blower fraction (0-1].")
_TAMB = typer.Option("--t-amb", help="Ambient air temperature [degC], -40 to 60.")
_RHAMB = typer.Option("--rh-amb", help="Ambient relative humidity [0-1].")
_TCAB = typer.Option("--t-cabin", help="Air temperature entering the evaporator [degC], -20 to 50.")
_RHCAB = typer.Option("--rh-cabin", help="Relative humidity entering the evaporator [0-1].")
_TCOOL = typer.Option("--t-coolant", help="Coolant temperature entering the chiller [degC], -20 to 60.")
_MCOOL = typer.Option("--coolant-flow", help="Coolant (50 % ethylene glycol) mass flow through the chiller [kg/s].")
_TOPOLOGY = typer.Option(
    "--topology",
    help="Circuit: cabin (evaporator), chiller (battery coolant, blower off) or cabin+chiller (both in parallel).",
)
_SH = typer.Option("--superheat", help="Thermostatic-valve superheat setpoint [K], 0-50.")
_SC = typer.Option("--subcooling", help="Condenser-outlet subcooling [K], 0-30; 0 = saturated liquid (receiver).")
_LUTS = typer.Option(
    "--luts",
    help="Folder with the cycle LUTs (evtms bench all --grid cycle -o DIR), or the luts/ or output folder of "
    "evtms demo. Default: luts/",
)
_DIRECT = typer.Option("--direct", help="Use the bench physics directly instead of LUTs (reference, slower).")
_PARAMS = typer.Option(
    "--params", help="TOML parameters: direct mode; with LUTs it must agree with the LUTs' own parameters."
)

_STATES = {"A": "A evaporator outlet", "B": "B compressor outlet", "C": "C condenser outlet", "D": "D valve outlet"}
_PERFORMANCE = (
    ("mdot", "mass flow", 1e3, "g/s", "kg s-1"),
    ("mdot_evap", "  through the evaporator", 1e3, "g/s", "kg s-1"),
    ("mdot_chiller", "  through the chiller", 1e3, "g/s", "kg s-1"),
    ("Q_evap", "cabin cooling |Q_evap|", -1.0, "W", "W"),
    ("Q_latent", "  of which latent", -1.0, "W", "W"),
    ("Q_chiller", "battery cooling |Q_chiller|", -1.0, "W", "W"),
    ("Q_cond", "Q_cond", 1.0, "W", "W"),
    ("W", "compressor shaft power W", 1.0, "W", "W"),
    ("COP", "cooling COP", 1.0, "-", "1"),
    ("dp_valve", "valve pressure drop", 1e-3, "kPa", "Pa"),
    ("valve_opening", "valve opening / nominal", 1.0, "-", "1"),
    ("valve_opening_chiller", "chiller valve opening / nom.", 1.0, "-", "1"),
    ("superheat_actual", "evaporator-outlet superheat", 1.0, "K", "K"),
    ("balance_residual", "energy balance residual", 1.0, "W", "W"),
    ("balance_relative", "  relative to W_fluid", 100.0, "%", "1"),
)
#: Rows only a circuit with that component shows (the split only with two branches).
_PERFORMANCE_NEEDS = {
    "mdot_evap": ("evaporator", "chiller"),
    "mdot_chiller": ("evaporator", "chiller"),
    "Q_evap": ("evaporator",),
    "Q_latent": ("evaporator",),
    "Q_chiller": ("chiller",),
    "valve_opening_chiller": ("evaporator", "chiller"),
}


def _performance(circuit) -> list[tuple]:
    """The performance rows that apply to ``circuit``."""
    have = set(circuit.components)
    return [row for row in _PERFORMANCE if set(_PERFORMANCE_NEEDS.get(row[0], ())) <= have]


@cycle_app.command("run")
def cycle_run(
    topology: Annotated[str, _TOPOLOGY] = "cabin",
    speed: Annotated[str | None, _SPEED] = None,
    fan: Annotated[str | None, _FAN] = None,
    blower: Annotated[str | None, _BLOWER] = None,
    t_amb: Annotated[str | None, _TAMB] = None,
    rh_amb: Annotated[str | None, _RHAMB] = None,
    t_cabin: Annotated[str | None, _TCAB] = None,
    rh_cabin: Annotated[str | None, _RHCAB] = None,
    coolant_flow: Annotated[str | None, _MCOOL] = None,
    t_coolant: Annotated[str | None, _TCOOL] = None,
    superheat: Annotated[str | None, _SH] = None,
    subcooling: Annotated[str | None, _SC] = None,
    luts: Annotated[Path | None, _LUTS] = None,
    direct: Annotated[bool, _DIRECT] = False,
    params: Annotated[Path | None, _PARAMS] = None,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Solve one operating point and print its states and performance.

    Example: evtms cycle run --luts luts/ --speed 0.6 --fan 0.5 --blower 0.4 --t-amb 30 --t-cabin 27
    """
    from evtms.cycle.api import solve_grid
    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS
    from evtms.cycle.topology import INPUTS

    circuit, grid = _cycle_inputs(
        topology,
        _texts(speed, fan, blower, t_amb, rh_amb, t_cabin, rh_cabin, coolant_flow, t_coolant, superheat, subcooling),
    )
    several = [f"{INPUTS[k].option} ({len(v)} values)" for k, v in grid.items() if len(v) != 1]
    if several:
        fail(f"{', '.join(several)}: cycle run takes one value per input; use 'evtms cycle sweep' for several")
    tables, parameters = _cycle_models(luts, direct, params, circuit)
    _, r = solve_grid(grid, tables, parameters, circuit)
    status = int(r["status"][0])
    if status not in VALID_CYCLE_FLAGS:
        fail(f"operating point not solved: {r['reason'][0]}")
    if json_out:
        print_json(
            {
                "topology": circuit.name,
                "inputs": {k: v[0] for k, v in grid.items()},
                "models": "direct" if tables is None else str(_lut_folder(tables)),
                "status": status,
                "status_meaning": CYCLE_FLAGS[status],
                "note": str(r["reason"][0]),
                "states": {s: {q: float(r[f"{q}_{s}"][0]) for q in ("p", "T", "h")} for s in _STATES},
                **{key: float(r[key][0]) for key, *_ in _performance(circuit)},
                "units": {"p": "Pa", "T": "K", "h": "J kg-1", **{key: si for key, *_, si in _performance(circuit)}},
            }
        )
        return
    typer.echo(f"{'state':<26} {'p [MPa]':>9} {'T [degC]':>9} {'h [kJ/kg]':>10}")
    for s, label in _STATES.items():
        typer.echo(
            f"{label:<26} {r['p_' + s][0] / 1e6:9.4f} {r['T_' + s][0] - 273.15:9.2f} {r['h_' + s][0] / 1e3:10.2f}"
        )
    for key, label, scale, unit, _ in _performance(circuit):
        typer.echo(f"{label:<26} {scale * r[key][0]:10.4g} {unit}")
    if r["reason"][0]:
        typer.echo(f"note: {r['reason'][0]}")


@cycle_app.command("sweep")
def cycle_sweep(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    topology: Annotated[str, _TOPOLOGY] = "cabin",
    speed: Annotated[str | None, _SPEED] = None,
    fan: Annotated[str | None, _FAN] = None,
    blower: Annotated[str | None, _BLOWER] = None,
    t_amb: Annotated[str | None, _TAMB] = None,
    rh_amb: Annotated[str | None, _RHAMB] = None,
    t_cabin: Annotated[str | None, _TCAB] = None,
    rh_cabin: Annotated[str | None, _RHCAB] = None,
    coolant_flow: Annotated[str | None, _MCOOL] = None,
    t_coolant: Annotated[str | None, _TCOOL] = None,
    superheat: Annotated[str | None, _SH] = None,
    subcooling: Annotated[str | None, _SC] = None,
    luts: Annotated[Path | None, _LUTS] = None,
    direct: Annotated[bool, _DIRECT] = False,
    params: Annotated[Path | None, _PARAMS] = None,
    max_points: Annotated[
        int, typer.Option("--max-points", help="Refuse sweeps above this many operating points.")
    ] = DEFAULT_MAX_CYCLE_POINTS,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Solve a grid of operating points (any input as v1,v2,... or start:stop:count) and write netCDF.

    Example: evtms cycle sweep --luts luts/ --speed 0.2:1:9 --t-amb 25,35,45 -o cycle.nc
    """
    import numpy as np

    from evtms.cycle import cycle_dataset
    from evtms.cycle.api import cycle_encoding, solve_grid
    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS
    from evtms.luts.io import atomic_output

    if max_points < 1:
        fail(f"--max-points {max_points} is not allowed; allowed: 1 or more")
    circuit, grid = _cycle_inputs(
        topology,
        _texts(speed, fan, blower, t_amb, rh_amb, t_cabin, rh_cabin, coolant_flow, t_coolant, superheat, subcooling),
        max_points,
    )
    tables, parameters = _cycle_models(luts, direct, params, circuit)
    # The LUT files found (headers read, data not yet): the output may not be one of them.
    inputs = [params] + ([] if tables is None else [t.path for t in tables.values()])
    output_file(output, inputs, (".nc",))
    t0 = time.perf_counter()
    points, r = solve_grid(grid, tables, parameters, circuit)
    wall = time.perf_counter() - t0
    ds = cycle_dataset(grid, r, "direct" if tables is None else f"LUTs in {_lut_folder(tables)}", circuit)
    with creating_parents(output), atomic_output(output) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", encoding=cycle_encoding(ds))
    status = np.asarray(r["status"])
    ok = int(np.isin(status, VALID_CYCLE_FLAGS).sum())
    if json_out:
        print_json(
            {
                "path": str(output),
                "points": len(points),
                "solved": ok,
                "seconds": wall,
                "status": {CYCLE_FLAGS[c]: int((status == c).sum()) for c in sorted(CYCLE_FLAGS)},
            }
        )
        return
    typer.echo(f"cycle: {len(points)} operating points, {ok} solved, {wall:.2f} s, wrote {output}")


report_app = typer.Typer(
    help="Figures and reports from LUT files, cycle sweeps and system simulations.", no_args_is_help=True
)
app.add_typer(report_app, name="report")


def _load_netcdf(path: Path, what: str):
    """The netCDF file ``path`` loaded into memory; missing, not netCDF or truncated: one line, exit 2."""
    import xarray as xr

    input_file(path, what)
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            return ds.load()
    except Exception as exc:  # not netCDF, truncated: one line, not an HDF5 traceback
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        fail(f"{path}: not a readable {what} ({first})")


def _open_cycle(path: Path):
    """A cycle sweep file, loaded; anything else is one line, exit 2."""

    ds = _load_netcdf(path, "cycle sweep file")
    if "status" not in ds or "p_A" not in ds or "reason" not in ds:
        fail(f"{path}: not an evtms cycle sweep (write one with 'evtms cycle sweep')")
    return ds


def _parse_index(ds, text: str | None):
    if text is None:
        return None
    index = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        name = name.strip()
        if name not in ds["status"].dims:
            fail(f"unknown input {name!r} in --point; allowed: {', '.join(ds['status'].dims)}")
        if name in index:
            fail(f"input {name!r} is given twice in --point")
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

    output_file(output, [sweep], (".png", ".svg"))
    ds = _open_cycle(sweep)
    try:
        states = diagram_data(ds, _parse_index(ds, point))
    except ValueError as exc:
        fail(str(exc))
    with creating_parents(output):
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

    output_file(output, [sweep], (".png", ".svg"))
    output_file(output.with_suffix(".csv"), [sweep])
    ds = _open_cycle(sweep)
    if x is None:
        varied = [d for d in ds["status"].dims if ds.sizes[d] > 1]
        if len(varied) != 1:
            fail(f"the sweep varies {len(varied)} inputs ({', '.join(varied) or 'none'}); an energy balance takes one")
        x = varied[0]
    try:
        with creating_parents(output):
            energy_balance_figure(ds, x, output)
    except ValueError as exc:
        fail(str(exc))
    typer.echo(f"wrote {output} and {output.with_suffix('.csv')}")


@report_app.command("bench")
def report_bench(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc) of any bench.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder (created if missing).")],
    at: Annotated[
        str | None, typer.Option("--at", help="Base point name=value,... (nearest grid value); default: first values.")
    ] = None,
    surface: Annotated[
        str | None, typer.Option("--surface", help="Two different axes for the 3-D map, e.g. p_in,T_in (default).")
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="Figure format: png or svg.")] = "png",
) -> None:
    """Bench figures and an HTML report from a LUT: response per axis, 3-D map, provenance.

    Nothing appears in the output folder unless every figure and the page
    are written.

    Example: evtms report bench luts/condenser.nc -o reports/condenser/
    """
    from evtms.luts.validate import fixed_inputs
    from evtms.reports.bench_plots import base_point, bench_report_figures, surface_data
    from evtms.reports.html import bench_report_page

    if fmt not in ("png", "svg"):
        fail(f"figure format {fmt!r} is not allowed; allowed: png, svg")
    output_folder(output, [file])
    ds = _open(file)
    dims = tuple(ds["status"].dims)
    base = base_point(ds, _parse_point(at, dims, partial=True, fixed=fixed_inputs(ds)) if at else None)
    pair = None
    if surface:
        parts = tuple(p.strip() for p in surface.split(","))
        if len(parts) != 2:
            fail(f"--surface {surface!r} must name two axes, e.g. p_in,T_in")
        if parts[0] == parts[1]:
            fail(f"--surface {surface!r} names the axis {parts[0]!r} twice; give two different axes")
        surface_data(ds, parts, base)  # checks the axes before anything is drawn
        pair = parts
    with staged_folder(output) as stage:
        figures = bench_report_figures(ds, stage, base, pair, fmt)
        bench_report_page(ds, figures, stage / "index.html", str(file))
    typer.echo(f"wrote {len(figures)} figures and {output / 'index.html'}")


def _open_simulation(path: Path, variables: tuple[str, ...] = ()):
    """A simulation output file (evtms simulate), loaded and checked; anything else is one line, exit 2."""

    from evtms.reports.system_plots import check_simulation

    ds = _load_netcdf(path, "simulation file")
    try:
        check_simulation(ds, variables)
    except EvtmsInputError as exc:
        fail(f"{path}: {exc}")
    return ds


@report_app.command("simulation")
def report_simulation(
    run: Annotated[Path, typer.Argument(help="Simulation file (evtms simulate), one run or an ambient sweep.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Figure file, .png or .svg.")],
    t_amb: Annotated[
        float | None,
        typer.Option("--t-amb", help="Ambient [degC] of the run to draw from a sweep; default: the first."),
    ] = None,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Time series of one run: speed, temperatures, powers, heat flows, SOC and the modes.

    Example: evtms simulate --cycle wltc3b --t-amb 35 -o run.nc && evtms report simulation run.nc -o run.png
    """
    from evtms.reports.system_plots import SIMULATION_VARIABLES, simulation_figure

    output_file(output, [run], (".png", ".svg"))
    ds = _open_simulation(run, SIMULATION_VARIABLES)
    try:
        with creating_parents(output):
            simulation_figure(ds, output, None if t_amb is None else t_amb + 273.15)
    except EvtmsInputError as exc:
        fail(f"{run}: {exc}")
    if json_out:
        print_json({"path": str(output)})
        return
    typer.echo(f"wrote {output}")


@report_app.command("range")
def report_range(
    sweep: Annotated[
        Path,
        typer.Argument(help="Simulation sweep over the ambient (evtms simulate --t-amb a:b:n), or range tests."),
    ],
    output: Annotated[Path, typer.Option("--output", "-o", help="Figure file, .png or .svg.")],
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Range against the ambient temperature.

    A range test's file (evtms simulate --range mct|ccp): the test's range (combined for mct, depletion for
    ccp) and the steady consumption EC_ss, the v1 single-trip range dashed, the 10-30 degC band (Geotab), the
    change against 23.9 degC with the AAA 2019 points; --json adds the figures per ambient and the Geotab shape
    checks (with a breakdown where one fails). A single-trip sweep: consumption per 100 km split by use, and
    the extrapolated range.

    Example: evtms simulate --range mct --t-amb -10:40:11 -o mct.nc && evtms report range mct.nc -o range.png
    """
    from evtms.reports.system_plots import depletion_report, range_figure, range_test

    output_file(output, [sweep], (".png", ".svg"))
    ds = _open_simulation(sweep)
    try:
        with creating_parents(output):
            range_figure(ds, output)
        report = depletion_report(ds) if range_test(ds) != "single" else {}
    except EvtmsInputError as exc:
        fail(f"{sweep}: {exc}")
    if json_out:
        print_json({"path": str(output), **report})
        return
    typer.echo(f"wrote {output}")


surrogate_app = typer.Typer(
    help="Data-driven mode models: train them on the simulator (evtms simulate --model surrogate runs them).",
    no_args_is_help=True,
)
app.add_typer(surrogate_app, name="surrogate")


@surrogate_app.command("train")
def surrogate_train(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder; the file is mode_models.npz.")],
    mode: Annotated[
        str,
        typer.Option(
            "--mode", help="Modes, comma-separated: off, bh, bc, cc, ch, ch+bh, ch+bc, cc+bc, or all (every one)."
        ),
    ] = "all",
    luts: Annotated[
        Path,
        typer.Option(
            "--luts", help="Cycle LUT folder, or evtms demo's luts/ or output folder; built if missing or empty."
        ),
    ] = Path("luts"),
    params: Annotated[Path | None, typer.Option("--params", help="System TOML, as evtms simulate.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the scenario design and of every fit.")] = 0,
    runs_per_mode: Annotated[int, typer.Option("--runs-per-mode", help="Training simulations per mode.")] = 24,
    quick: Annotated[
        bool, typer.Option("--quick", help="Small design and tiny networks (tests; errors not representative).")
    ] = False,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Train the mode models: simulate a designed set of scenarios on the cycle maps (dt 1 s), fit per mode a
    power and a dynamics network (scikit-learn, pip install 'evtms[surrogate]'), check them on held-out cycles
    and ambients (WLTC, NEDC), and write OUTPUT/mode_models.npz. Modes already in that file and not retrained
    are kept.

    Example: evtms surrogate train --mode all -o models/ && evtms simulate --cycle wltc3b --t-amb 30 --model
    surrogate --surrogates models/ -o run.nc
    """
    from evtms.surrogates.train import check_modes, train_surrogates
    from evtms.system.params import load_system_params

    if not 1 <= runs_per_mode <= 500:
        fail(f"--runs-per-mode {runs_per_mode} is not allowed; allowed: 1 to 500")
    if not 0 <= seed < 2**32:
        fail(f"--seed {seed} is not allowed; allowed: 0 to 2**32 - 1")
    modes = [m.strip() for m in mode.split(",") if m.strip()]
    check_modes(modes)  # before any LUT or map work
    inputs = [input_file(params, "params file")] if params is not None else []
    system = load_system_params(params)
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    output_folder(output, inputs)
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)
    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        task = None

        def progress(done: int, total: int, text: str) -> None:
            nonlocal task
            if task is None:
                task = bar.task("training", total)
            task(done, total)

        report = train_surrogates(
            refrigerant, modes, output, params=system, progress=progress, seed=seed, quick=quick,
            runs_per_mode=runs_per_mode,
        )  # fmt: skip
    if json_out:
        print_json(report.to_dict())
        return
    for name, m in report.modes.items():
        line = f"{name}: {m.n_train} steps, fit {m.fit_power.time_s + m.fit_dynamics.time_s:.0f} s"
        if m.rollout:
            line += ", held-out RMSE " + ", ".join(
                f"{v} {m.rollout[v]['rmse']:.3g}" for v in ("T_battery", "T_cabin", "T_coolant") if v in m.rollout
            )
        typer.echo(line)
    if report.auto:
        typer.echo(
            "auto (held out): RMSE "
            + ", ".join(f"{v} {report.auto[v]['rmse']:.3g}" for v in ("T_battery", "T_cabin") if v in report.auto)
        )
    for name, why in report.skipped.items():
        typer.echo(f"{name}: skipped ({why})")
    typer.echo(f"wrote {report.path} ({report.total_time_s:.0f} s)")


def _float_list(option: str, text: str, most: int = 20) -> list[float]:
    """Comma-separated numbers of an option; anything else is one line, exit 2."""
    items = [t.strip() for t in text.split(",")]
    if not items or len(items) > most:
        fail(f"{option} {text!r}: give 1 to {most} comma-separated numbers")
    try:
        values = [float(t) for t in items]
    except ValueError:
        fail(f"{option} {text!r}: not comma-separated numbers")
    if not all(math.isfinite(v) for v in values):
        fail(f"{option} {text!r}: numbers must be finite")
    return values


@report_app.command("compare")
def report_compare(
    cycle: Annotated[
        str | None, typer.Option("--cycle", help="Drive cycles, comma-separated: built-in names or CSV files.")
    ] = None,
    t_amb: Annotated[str | None, typer.Option("--t-amb", help="Ambient temperatures [degC], comma-separated.")] = None,
    output: Annotated[
        Path | None,
        typer.Option("--output", "-o", help="Output folder (created if missing); optional with --scenarios."),
    ] = None,
    scenarios: Annotated[
        str | None,
        typer.Option(
            "--scenarios",
            help="Scenarios instead of --cycle/--t-amb, comma-separated names or groups: t12 (the 16 Table 12 "
            "rows), t12-cc, t12-bh-1, ...; prints the thesis's Table 12 columns per row.",
        ),
    ] = None,
    scenario_file: Annotated[
        Path | None,
        typer.Option("--scenario-file", help="TOML scenario file whose scenarios --scenarios may name (else: all)."),
    ] = None,
    approaches: Annotated[
        str | None,
        typer.Option(
            "--approaches",
            help="Approaches to compare, comma-separated: physics, lut, surrogate (default: all three; with "
            "--scenarios lut and those available).",
        ),
    ] = None,
    surrogates: Annotated[
        Path, typer.Option("--surrogates", help="Mode-model file or folder (evtms surrogate train -o).")
    ] = Path("models"),
    luts: Annotated[
        Path,
        typer.Option(
            "--luts", help="Cycle LUT folder (evtms bench all --grid cycle), or evtms demo's luts/ or output folder."
        ),
    ] = Path("luts"),
    params: Annotated[Path | None, typer.Option("--params", help="System TOML, as evtms simulate.")] = None,
    dt: Annotated[float, typer.Option("--dt", help="Step of the comparison table and trajectories [s].")] = 1.0,
    dts: Annotated[str, typer.Option("--dts", help="Steps of the step-size study [s].")] = "0.01,0.1,1,10",
    physics_dts: Annotated[
        str | None,
        typer.Option("--physics-dts", help="Steps at which physics joins the study [s] (slow); default: --dts >= 1 s."),
    ] = None,
    no_steps: Annotated[bool, typer.Option("--no-steps", help="Skip the step-size study.")] = False,
    measured: Annotated[
        Path | None,
        typer.Option(
            "--measured",
            help="CSV of measured time,T_cabin,T_battery,SOC,P_hvac (any subset; s, K, 1, W): the reference where "
            "given; needs one cycle and one ambient.",
        ),
    ] = None,
    repeat: Annotated[int, typer.Option("--repeat", help="Runs of lut and surrogate per scenario, median time.")] = 3,
    sun: Annotated[float, typer.Option("--sun", help="Solar irradiance [W/m2].")] = 0.0,
    soak_cabin: Annotated[
        float | None, typer.Option("--soak-cabin", help="Initial cabin air, walls and interior [degC].")
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="Figure format: png or svg.")] = "png",
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Physics, LUT and surrogate models side by side: time per simulation, error, trajectories, step size.

    Example: evtms report compare --cycle wltc3b,nedc --t-amb -10,30,40 -o compare/
    Table 12: evtms report compare --scenarios t12 --approaches lut
    """
    if scenarios is not None or scenario_file is not None:
        if cycle is not None or t_amb is not None or measured is not None:
            fail("--scenarios runs scenarios with their own cycle and ambient; leave out --cycle, --t-amb, --measured")
        if sun != 0.0 or soak_cabin is not None or physics_dts is not None:
            fail("--scenarios set their own sun and initial state and run no step-size study; "
                 "leave out --sun, --soak-cabin, --physics-dts")  # fmt: skip
        _compare_scenarios(scenarios, scenario_file, approaches, surrogates, luts, params, dt, repeat, output, json_out)
        return
    if cycle is None or t_amb is None:
        fail("give --cycle NAMES and --t-amb DEGC (or --scenarios NAMES)")
    if output is None:
        fail("give --output FOLDER for the comparison's tables and figures")
    approaches = "physics,lut,surrogate" if approaches is None else approaches
    from evtms.cycle.topology import parse_values
    from evtms.reports.compare import (
        APPROACHES,
        check_request,
        compare_summary,
        read_measured,
        run_compare,
        write_compare,
    )
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.params import load_system_params

    chosen = [a.strip() for a in approaches.split(",")]
    for a in chosen:
        if a not in APPROACHES:
            fail(f"--approaches {a!r} is unknown; allowed: {', '.join(APPROACHES)}")
    if fmt not in ("png", "svg"):
        fail(f"--format {fmt!r} is unknown; allowed: png, svg")
    if not 1 <= repeat <= 20:
        fail(f"--repeat {repeat} is not allowed; allowed: 1 to 20")
    if not (math.isfinite(sun) and 0.0 <= sun <= 1500.0):
        fail(f"--sun {sun:g} is not allowed; allowed: 0 to 1500 W/m2")
    _check_soak(soak_cabin)
    ambients = parse_values("T_amb", t_amb, 20)
    step_list = _float_list("--dts", dts)
    physics_steps = _float_list("--physics-dts", physics_dts) if physics_dts is not None else None
    names = [c.strip() for c in cycle.split(",")]
    if len(names) > 20:
        fail(f"--cycle: {len(names)} cycles; at most 20")
    cycles = [drive_cycle(c) for c in names]
    inputs = [Path(c.source) for c in cycles if Path(c.source).is_file()]
    if params is not None:
        inputs.append(input_file(params, "params file"))
    system = load_system_params(params)
    reference = None
    if measured is not None:
        reference = read_measured(input_file(measured, "measured file"))
        inputs.append(measured)
    mode_models = None
    if "surrogate" in chosen:
        mode_models, surrogate_file = _mode_models(surrogates)
        inputs.append(surrogate_file)
    check_request(
        cycles, ambients, chosen, mode_models, step_list, physics_steps, dt, reference, repeat
    )  # before the maps are built
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    output_folder(output, inputs)
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)

    def progress(done: int, total: int, message: str) -> None:
        if not json_out:
            typer.echo(f"[{done}/{total}] {message}", err=True)

    result = run_compare(
        cycles,
        ambients,
        refrigerant,
        params=system,
        approaches=tuple(chosen),
        mode_models=mode_models,
        dts=tuple(step_list),
        physics_dts=None if physics_steps is None else tuple(physics_steps),
        dt=dt,
        measured=reference,
        measured_source=str(measured) if measured is not None else "",
        repeat=repeat,
        step_study=not no_steps,
        simulate_options={"sun": sun, "soak_cabin": None if soak_cabin is None else soak_cabin + 273.15},
        progress=progress,
    )
    files = write_compare(result, output, fmt)
    if json_out:
        print_json({**compare_summary(result), "files": [str(f) for f in files]})
        return
    typer.echo(f"wrote {len(files)} files and {output / 'index.html'}")


def _compare_scenarios(
    names: str | None,
    scenario_file: Path | None,
    approaches: str | None,
    surrogates: Path,
    luts: Path,
    params: Path | None,
    dt: float,
    repeat: int,
    output: Path | None,
    json_out: bool,
) -> None:
    """``report compare --scenarios``: the scenarios run by each approach, the Table 12 columns printed."""
    from evtms.reports.table12 import table12_summary, table12_text, write_table12
    from evtms.system.params import load_system_params
    from evtms.system.scenarios import SCENARIOS, read_scenario_file, select_scenarios
    from evtms.system.simulate import check_model
    from evtms.system.table12 import APPROACHES, run_table12

    if not 1 <= repeat <= 20:
        fail(f"--repeat {repeat} is not allowed; allowed: 1 to 20")
    inputs: list[Path] = []
    from_file = {}
    if scenario_file is not None:
        from_file = read_scenario_file(input_file(scenario_file, "scenario file"))
        inputs.append(scenario_file)
    chosen = select_scenarios(names, {**SCENARIOS, **from_file}) if names is not None else list(from_file.values())
    if params is not None:
        inputs.append(input_file(params, "params file"))
    system = load_system_params(params)
    setups = [sc.setup(system) for sc in chosen]
    for st in setups:
        if st.T_amb is None:
            fail(f"scenario {st.scenario.name!r} has no ambient of its own; give scenarios with T_amb")
        if Path(st.cycle.source).is_file():
            inputs.append(Path(st.cycle.source))
        inputs += _trace_files(st.inputs)
    asked = None if approaches is None else [a.strip() for a in approaches.split(",")]
    for a in asked or ():
        if a not in APPROACHES:
            fail(f"--approaches {a!r} is unknown; allowed: {', '.join(APPROACHES)}")
    skipped: dict[str, str] = {}
    mode_models = None
    if asked is None or "surrogate" in asked:
        from evtms.surrogates.io import MODEL_FILE

        file = surrogates / MODEL_FILE if surrogates.is_dir() else surrogates
        if asked is None and not file.is_file():
            skipped["surrogate"] = f"no mode-model file at {surrogates} (evtms surrogate train)"
        else:
            mode_models, surrogate_file = _mode_models(surrogates)
            inputs.append(surrogate_file)
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    if output is not None:
        output_folder(output, inputs)
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)
    chosen_approaches = []
    for a in APPROACHES:
        if (asked is None and a in skipped) or (asked is not None and a not in asked):
            continue
        try:
            for st in setups:
                check_model(a, st.mode, mode_models, refrigerant)
        except EvtmsInputError as exc:
            if asked is not None:
                raise
            skipped[a] = str(exc)
            continue
        chosen_approaches.append(a)

    def progress(done: int, total: int, message: str) -> None:
        if not json_out:
            typer.echo(f"[{done}/{total}] {message}", err=True)

    result = run_table12(
        chosen,
        refrigerant,
        params=system,
        approaches=chosen_approaches,
        mode_models=mode_models,
        dt=dt,
        repeat=repeat,
        progress=progress,
    )
    result.skipped = skipped
    files = write_table12(result, output) if output is not None else []
    if json_out:
        print_json({**table12_summary(result), "files": [str(f) for f in files]})
        return
    typer.echo(table12_text(result))
    if files:
        typer.echo(f"wrote {', '.join(str(f) for f in files)}")


@app.command()
def demo(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder (created if missing).")] = Path("out"),
    force: Annotated[bool, typer.Option("--force", help="Recompute LUTs even if they are up to date.")] = False,
    workers: Annotated[int, typer.Option("--workers", help="Processes for the bench sweeps.")] = 2,
    params: Annotated[Path | None, typer.Option("--params", help="TOML parameter overrides.")] = None,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """The whole job: benches on the thesis and cycle grids, LUTs, a cycle sweep, figures, index.html.

    Example: evtms demo -o out/   (a second run reuses up-to-date LUTs; --force recomputes)
    """
    from evtms.benches.parameters import load_parameters
    from evtms.demo import run_demo

    if workers < 1:
        fail(f"--workers {workers} is not allowed; allowed: 1 or more")
    if params is not None:
        input_file(params, "params file")
    parameters = load_parameters(params)
    folder = output_folder(output, [params] if params is not None else [])
    t0 = time.perf_counter()

    def notify(message: str) -> None:
        typer.echo(f"[{time.perf_counter() - t0:6.1f} s] {message}", err=True)

    with creating_parents(folder, folder=True):
        result = run_demo(folder, parameters, force=force, workers=workers, notify=notify)
    if json_out:
        print_json(
            {
                "index": result.index.resolve(),
                "computed": result.computed,
                "reused": result.reused,
                "timings": result.timings,
                "seconds": time.perf_counter() - t0,
            }
        )
        return
    typer.echo(
        f"demo: {len(result.computed)} LUTs computed, {len(result.reused)} reused, "
        f"{time.perf_counter() - t0:.1f} s; open {result.index.resolve()}"
    )


_SIM_TAMB = typer.Option(
    "--t-amb", help="Ambient [degC]: one value, v1,v2,... or start:stop:count (several run side by side)."
)


_INPUT_HELP = {
    "q_battery": ("--q-battery", "Heat into the battery [W] (Table 12 Qloss), or FILE.csv:column [W]."),
    "hvac_inlet_t": ("--hvac-inlet-t", "Fixed HVAC inlet air [degC] (Table 12 Tin), or FILE.csv:column [K]."),
    "hvac_inlet_rh": ("--hvac-inlet-rh", "Fixed HVAC inlet relative humidity [0-1], or FILE.csv:column."),
    "sp_evap": ("--sp-evap", "Evaporator outlet air setpoint [degC], or FILE.csv:column [K]."),
    "sp_cohx": ("--sp-cohx", "Heater-core coolant inlet setpoint [degC] (ptc_coolant), or FILE.csv:column [K]."),
    "blower": ("--blower", "Fixed blower command [0-1] (not 0 with auto, cc or ch), or FILE.csv:column."),
}
#: Option parameter -> input name (evtms.system.inputs.INPUT_NAMES).
_INPUT_OF = {
    "q_battery": "Q_battery_ext",
    "hvac_inlet_t": "hvac_inlet_T",
    "hvac_inlet_rh": "hvac_inlet_rh",
    "sp_evap": "SP_evap",
    "sp_cohx": "SP_CoHX",
    "blower": "blower",
}


def _input_option(key: str):
    option, text = _INPUT_HELP[key]
    return typer.Option(option, help=text)


def _option_inputs(texts: dict[str, str | None]) -> dict:
    """The input options given (numbers in degC for temperatures, or FILE.csv:column), checked, SI."""
    from evtms.system.inputs import CLI_OPTIONS, check_inputs

    raw: dict[str, object] = {}
    for key, text in texts.items():
        if text is None:
            continue
        try:
            raw[_INPUT_OF[key]] = float(text)
        except ValueError:
            raw[_INPUT_OF[key]] = text
    return check_inputs(raw, celsius=True, labels=CLI_OPTIONS)


def _trace_files(inputs: dict) -> list[Path]:
    from evtms.system.inputs import Trace

    return [Path(v.source.rpartition(":")[0]) for v in inputs.values() if isinstance(v, Trace)]


def _scenario_choice(name: str | None, file: Path | None):
    """The scenario of --scenario NAME (built in, or in --scenario-file) or the only one of --scenario-file."""
    from evtms.system.scenarios import SCENARIOS, read_scenario_file

    from_file = read_scenario_file(input_file(file, "scenario file")) if file is not None else {}
    if name is None:
        if len(from_file) != 1:
            fail(f"--scenario-file {str(file)!r} holds {len(from_file)} scenarios ({', '.join(from_file)}); "
                 "give --scenario NAME")  # fmt: skip
        return next(iter(from_file.values()))
    available = {**SCENARIOS, **from_file}
    if name not in available:
        where = f"allowed: {', '.join(from_file)} (in {file}) or the built-in " if from_file else "allowed: "
        fail(f"--scenario {name!r} is unknown; {where}{', '.join(SCENARIOS)}")
    return available[name]


@app.command()
def simulate(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    cycle: Annotated[
        str | None,
        typer.Option("--cycle", help="Drive cycle: wltc3b, nedc, udds, hwfet, parked:SECONDS or a CSV file."),
    ] = None,
    scenario: Annotated[
        str | None,
        typer.Option(
            "--scenario",
            help="Named scenario: built in (hot-drive, cooldown, cold, wltc, nedc, hot-sun, t12-bh-1 ... t12-ch-4) "
            "or from --scenario-file.",
        ),
    ] = None,
    scenario_file: Annotated[
        Path | None, typer.Option("--scenario-file", help="TOML scenario file (docs/scenario-format.md).")
    ] = None,
    t_amb: Annotated[str | None, _SIM_TAMB] = None,
    mode: Annotated[
        str | None,
        typer.Option("--mode", help="auto, or force one mode: off, bh, bc, cc, ch (default: the scenario's, or auto)."),
    ] = None,
    params: Annotated[Path | None, typer.Option("--params", help="TOML: [vehicle] [battery] [cabin] ...")] = None,
    luts: Annotated[
        Path,
        typer.Option(
            "--luts",
            help="Cycle LUT folder (evtms bench all --grid cycle -o DIR), or evtms demo's luts/ or output folder; "
            "built there if missing or empty.",
        ),
    ] = Path("luts"),
    dt: Annotated[float, typer.Option("--dt", help="Time step [s], 0.001 to 60.")] = 1.0,
    output_every: Annotated[
        float | None, typer.Option("--output-every", help="Record spacing [s], a multiple of --dt (max(1, dt)).")
    ] = None,
    soak_cabin: Annotated[
        float | None, typer.Option("--soak-cabin", help="Initial cabin air, walls and interior [degC].")
    ] = None,
    precondition: Annotated[
        float, typer.Option("--precondition", help="Seconds of HVAC parked and plugged in before the cycle.")
    ] = 0.0,
    model: Annotated[
        str,
        typer.Option(
            "--model",
            help="lut (cycle maps), physics (bench physics solved in the loop: the slow reference) or surrogate "
            "(mode models of 'evtms surrogate train').",
        ),
    ] = "lut",
    surrogates: Annotated[
        Path,
        typer.Option(
            "--surrogates", help="Mode-model file or folder (evtms surrogate train -o), for --model surrogate."
        ),
    ] = Path("models"),
    range_test: Annotated[
        str,
        typer.Option(
            "--range",
            help="single (the cycle once; range_km extrapolates it), mct (SAE J1634 multi-cycle test: UDDS, HWFET "
            "and 65 mph phases to break-off) or ccp (UN GTR 15: WLTC 3b back to back to break-off). mct and ccp "
            "start fully charged and drive their own cycles: leave out --cycle (ccp accepts --cycle wltc3b); a "
            "--scenario gives its conditions, not its cycle.",
        ),
    ] = "single",
    q_battery: Annotated[str | None, _input_option("q_battery")] = None,
    hvac_inlet_t: Annotated[str | None, _input_option("hvac_inlet_t")] = None,
    hvac_inlet_rh: Annotated[str | None, _input_option("hvac_inlet_rh")] = None,
    sp_evap: Annotated[str | None, _input_option("sp_evap")] = None,
    sp_cohx: Annotated[str | None, _input_option("sp_cohx")] = None,
    blower: Annotated[str | None, _input_option("blower")] = None,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Simulate the vehicle's thermal system over a drive cycle (or a range test) and write the time series.

    Example: evtms simulate --cycle wltc3b --t-amb 30 -o run.nc --json
    """
    t0 = time.perf_counter()
    from evtms.cycle.topology import parse_values
    from evtms.system.params import load_system_params
    from evtms.system.range_test import RANGE_TESTS
    from evtms.system.scenarios import SCENARIO_MODES, Scenario, check_choice
    from evtms.system.simulate import MODELS, check_run_options

    if range_test not in RANGE_TESTS:
        fail(f"--range {range_test!r} is unknown; allowed: {', '.join(RANGE_TESTS)}")
    depletion = range_test != "single"

    named = scenario is not None or scenario_file is not None
    if depletion:
        if cycle is not None and not (range_test == "ccp" and cycle == "wltc3b"):
            own = "UDDS, HWFET and 65 mph phases" if range_test == "mct" else "WLTC 3b back to back"
            fail(f"--range {range_test} drives its own cycles ({own}); leave out --cycle {cycle}")
        if cycle is not None and named:
            fail("give --cycle NAME|FILE.csv or --scenario NAME / --scenario-file FILE.toml (one of them)")
    elif (cycle is None) == (not named):
        fail("give --cycle NAME|FILE.csv or --scenario NAME / --scenario-file FILE.toml (one of them)")
    if model not in MODELS:
        fail(f"--model {model!r} is unknown; allowed: {', '.join(MODELS)}")
    if mode is not None:
        check_choice("--mode", mode, SCENARIO_MODES)
    _check_soak(soak_cabin)
    sc = _scenario_choice(scenario, scenario_file) if named else Scenario(name="", cycle=cycle or "wltc3b")
    if t_amb is None and sc.T_amb is None:
        fail("give --t-amb DEGC (this cycle or scenario has no ambient of its own)")
    ambients = parse_values("T_amb", t_amb, 1000) if t_amb is not None else [sc.T_amb]
    inputs = [params] if params is not None else []
    if params is not None:
        input_file(params, "params file")
    if scenario_file is not None:
        inputs.append(scenario_file)
    system = load_system_params(params)
    extra = _option_inputs(
        {"q_battery": q_battery, "hvac_inlet_t": hvac_inlet_t, "hvac_inlet_rh": hvac_inlet_rh, "sp_evap": sp_evap,
         "sp_cohx": sp_cohx, "blower": blower}
    )  # fmt: skip
    setup = sc.setup(system, mode=mode, inputs=extra)
    if depletion:
        from evtms.system.range_test import ccp_sequence, mct_sequence

        trace = mct_sequence(0.0, 1).cycle if range_test == "mct" else ccp_sequence(1).cycle  # the options' checks
    else:
        trace = setup.cycle
    check_run_options(trace, dt, setup.mode, output_every, precondition)
    if not depletion and Path(trace.source).is_file():
        inputs.append(Path(trace.source))
    inputs += _trace_files(setup.inputs)
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    mode_models = None
    if model == "surrogate":
        mode_models, surrogate_file = _mode_models(surrogates)
        inputs.append(surrogate_file)
    output_file(output, inputs, (".nc",))
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)
    from evtms.system.output import write_simulation
    from evtms.system.scenarios import run_scenario
    from evtms.system.simulate import check_model

    check_model(model, setup.mode, mode_models, refrigerant)
    options = dict(
        dt=dt,
        soak_cabin=None if soak_cabin is None else soak_cabin + 273.15,
        output_every=output_every,
        precondition=precondition,
        model=model,
        mode_models=mode_models,
    )
    if depletion:
        from evtms.system.range_test import run_range_test

        if named:
            typer.echo(
                f"note: --range {range_test} keeps the scenario's conditions, not its cycle {sc.cycle}", err=True
            )
        results = [
            run_range_test(
                range_test, T, refrigerant, setup.params, mode=setup.mode, RH_amb=setup.RH_amb, sun=setup.sun,
                scenario=sc.name, inputs=setup.inputs, **options,
            )[0]
            for T in ambients
        ]  # fmt: skip
    else:
        results = [run_scenario(setup, refrigerant, T, **options) for T in ambients]
    with creating_parents(output):
        write_simulation(results, output)
    wall = time.perf_counter() - t0
    for r in results:
        r.summary["wall_time_s"] = wall
    if json_out:
        print_json(results[0].summary if len(results) == 1 else {"runs": [r.summary for r in results]})
        return
    for r in results:
        s = r.summary
        if "range" in s:
            typer.echo(_range_line(s))
            continue
        typer.echo(
            f"{s['T_amb_degC']:6.1f} degC  {s['distance_km']:.2f} km  battery {s['battery_energy_kWh']:.3f} kWh "
            f"(HVAC {s['hvac_energy_kWh']:.3f})  SOC {s['soc_end']:.4f}  cabin {s['T_cabin_end_degC']:.1f} degC  "
            f"battery {s['T_battery_end_degC']:.1f} degC  loop {s['loop_time_s'] * 1e3:.0f} ms"
        )
    typer.echo(f"wrote {output} ({wall:.2f} s)")


def _range_line(s: dict) -> str:
    """One line of a depletion test's figures (evtms simulate --range mct|ccp)."""
    f = s["range"]

    def km(key: str) -> str:
        return "n/a" if f.get(key) is None else f"{f[key]:.1f} km"

    ec = f.get("EC_ss_combined_Wh_per_km")
    main = (
        f"combined {km('range_combined_km')} (city {km('range_city_km')}, highway {km('range_hwy_km')})"
        if f["test"] == "mct"
        else f"depletion {km('range_depletion_km')}"
    )
    return (
        f"{s['T_amb_degC']:6.1f} degC  {f['test']}: UBE {f['ube_kWh']:.2f} kWh, {main}, "
        f"EC_ss {'n/a' if ec is None else f'{ec:.1f}'} Wh/km, range_ss {km('range_ss_km')}, "
        f"break-off {f['break_off']} at {f['break_off_s'] / 3600.0:.2f} h  loop {s['loop_time_s'] * 1e3:.0f} ms"
    )


def _check_soak(soak_cabin: float | None) -> None:
    """--soak-cabin [degC], when given, within -40 to 90 degC."""
    if soak_cabin is not None and not (math.isfinite(soak_cabin) and -40.0 <= soak_cabin <= 90.0):
        fail(f"--soak-cabin {soak_cabin:g} is not allowed; allowed: -40 to 90 degC")


def _cycle_luts(luts: Path) -> tuple[Path | None, list[Path]]:
    """(folder holding the cycle LUTs of ``luts``, or None to build them in ``luts``; the LUTs and maps
    there: inputs an output may not overwrite).

    ``luts`` may be the folder of the cycle LUTs or the luts/ or output folder of ``evtms demo``
    (:func:`evtms.cycle.api.cycle_luts_folder`). A file, or a folder holding LUTs but no complete set
    of cycle LUTs, is one line, exit 2: nothing is built over LUTs already there.
    """
    from evtms.cycle.api import cycle_luts_folder

    if luts.exists() and not luts.is_dir():
        fail(f"--luts {str(luts)!r} is not a folder; allowed: a folder of cycle LUTs (or one to build them in)")
    try:
        folder = cycle_luts_folder(luts, "cabin+chiller")
    except EvtmsInputError as exc:
        fail(f"--luts: {exc}")
    if folder is None:
        return None, []
    return folder, sorted(folder.glob("*.nc")) + sorted((folder / "maps").glob("*.nc"))


def _mode_models(path: Path):
    """Mode models from a file or a folder holding the trainer's file; anything else is one line, exit 2."""
    from evtms.surrogates.io import MODEL_FILE, load_mode_models

    file = path / MODEL_FILE if path.is_dir() else path
    if not file.is_file():
        fail(
            f"--surrogates {str(path)!r}: no mode-model file; "
            f"train one with 'evtms surrogate train --mode all -o {path}'"
        )
    return load_mode_models(file), file


def _system_refrigerant(luts: Path, folder: Path | None, system, quiet: bool):
    """The cycle maps of the cycle LUTs in ``folder`` (from :func:`_cycle_luts`) for the simulator.

    With ``folder`` None (``luts`` missing or holding no LUTs) the cycle LUTs are built in ``luts``
    first; maps are built where missing (with a bar).
    """
    from evtms.benches.parameters import Parameters
    from evtms.demo import ensure_luts
    from evtms.system.refrigerant import load_refrigerant

    if folder is None:
        typer.echo(f"note: no cycle LUTs in {luts}/; building them (evtms bench all --grid cycle, 1-2 min)", err=True)
        with creating_parents(luts, folder=True):
            ensure_luts(luts, "cycle", Parameters(), notify=lambda m: typer.echo(f"  {m}", err=True))
        folder = luts
    with _ProgressBar(quiet or not sys.stderr.isatty()) as bar:
        tasks = {}

        def progress(done: int, total: int, text: str) -> None:
            if text not in tasks:
                typer.echo(f"note: building cycle map {text} in {folder}/maps/ (once)", err=True)
                tasks[text] = bar.task(text, total)
            tasks[text](done, total)

        return load_refrigerant(folder, system, progress)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
