"""evtms bench COMPONENT|all: sweep a bench over a grid and write its LUT."""

from __future__ import annotations

import math
import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _ARGV, _JSON, _error, _ProgressBar, fail, print_json
from evtms.paths import creating_parents, input_file, output_file, output_folder

bench_app = typer.Typer(
    help=(
        "Sweep a component bench over a grid and write its LUT (netCDF). "
        "'evtms bench COMPONENT --help' lists that bench's axes, units, ranges and presets.\n\n"
        "Example: evtms bench condenser --grid thesis -o luts/condenser.nc"
    ),
    no_args_is_help=True,
)


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
