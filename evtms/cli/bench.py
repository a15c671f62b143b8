"""evtms bench COMPONENT|all: sweep a bench over a grid and write its LUT."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from typer.core import TyperGroup

from evtms.cli.common import _ARGV, JsonOut, _error, _ProgressBar, note, print_json

if TYPE_CHECKING:
    from evtms.workflows.bench import BenchInfo


class _BenchGroup(TyperGroup):
    """'evtms bench': one command per registered bench, made when 'bench' itself is run.

    The commands' help comes from the bench registry, which imports NumPy and
    every bench module: made on first use, the other commands (and
    ``evtms --help``) need not import them.
    """

    def _load(self) -> None:
        if "all" in self.commands:
            return
        benches = typer.Typer(rich_markup_mode=self.rich_markup_mode)  # help shown as the group's
        _register_benches(benches)
        for name, command in typer.main.get_group(benches).commands.items():
            self.add_command(command, name)

    def list_commands(self, ctx):
        self._load()
        return super().list_commands(ctx)

    def get_command(self, ctx, cmd_name):
        self._load()
        return super().get_command(ctx, cmd_name)


bench_app = typer.Typer(
    cls=_BenchGroup,
    help=(
        "Sweep a component bench over a grid and write its LUT (netCDF). "
        "'evtms bench COMPONENT --help' lists that bench's axes, units, ranges and presets.\n\n"
        "Example: evtms bench condenser --grid thesis -o luts/condenser.nc"
    ),
    no_args_is_help=True,
)


def _bench_help(bench: BenchInfo) -> str:
    """A bench command's help, from its registry entry: axes with units and ranges, presets."""
    lines = [
        f"{bench.title}: sweep it over a grid and write its LUT (netCDF).",
        "",
        "\b",
        "Axes (--axis name=start:stop:count[unit] or name=v1,v2,...[unit]):",
    ]
    for a in bench.axes:
        suffixes = ", ".join(a.unit_suffixes) or "SI only"
        extra = " (optional extra axis)" if a.extra else ""
        lines.append(f"  {a.name} [{a.units}]: {a.long_name}{extra}; allowed {a.allowed}; units: {suffixes}")
    for preset, axes in bench.presets.items():
        lines += ["", "\b", f"Preset --grid {preset}:"]
        for a, v in axes.items():
            shown = f"{v[0]:g}" if len(v) == 1 else f"{len(v)} values {v[0]:g} .. {v[-1]:g}"
            lines.append(f"  {a} [{bench.units[a]}]: {shown}" + (" (fixed input)" if len(v) == 1 else ""))
    name, cli = bench.name, bench.name.replace("_", "-")
    lines += ["", f"Example: evtms bench {cli} --grid {next(iter(bench.presets), 'thesis')} -o luts/{name}.nc"]
    return "\n".join(lines)


_Grid = Annotated[str, typer.Option("--grid", "-g", help="Grid preset: thesis, cycle, or custom.")]
_Axis = Annotated[
    list[str] | None,
    typer.Option(
        "--axis",
        "-a",
        help="Override or add an axis: name=start:stop:count[unit] or name=v1,v2,...[unit]. Repeatable.",
    ),
]
_Params = Annotated[Path | None, typer.Option("--params", help="TOML file overriding component parameters.")]
_Output = Annotated[
    Path | None,
    typer.Option("--output", "-o", help="Output .nc file (a folder for 'all'). Default: luts/<name>.nc"),
]
_Backend = Annotated[str | None, typer.Option("--backend", help="CoolProp backend: HEOS (default) or BICUBIC&HEOS.")]
_Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]
_Workers = Annotated[int | None, typer.Option("--workers", help="Run the sweep in N local dask worker processes.")]
_Scheduler = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Send the sweep to a dask.distributed scheduler, tcp://host:port (it runs the code sent to it: "
        "use only a cluster you trust).",
    ),
]
_Resume = Annotated[
    bool, typer.Option("--resume", help="Reuse the finished chunks of an interrupted sweep to the same output.")
]
_ChunkPoints = Annotated[int, typer.Option("--chunk-points", help="Points per chunk (bounds memory).")]
_MaxPoints = Annotated[
    int | None, typer.Option("--max-points", help="Refuse grids above this many points (default 200,000,000).")
]
_Float32 = Annotated[
    bool, typer.Option("--float32", help="Store the variables as float32 (lossy, about half the size).")
]
_Digits = Annotated[
    int | None,
    typer.Option("--significant-digits", help="Keep N significant digits (1-15; lossy, compresses better)."),
]


def _bench_command(names: list[str]):
    """The command that sweeps ``names`` (one bench, or all for 'bench all')."""

    def command(
        grid: _Grid = "thesis",
        axis: _Axis = None,
        params: _Params = None,
        output: _Output = None,
        backend: _Backend = None,
        quiet: _Quiet = False,
        workers: _Workers = None,
        scheduler: _Scheduler = None,
        resume: _Resume = False,
        chunk_points: _ChunkPoints = 16384,
        max_points: _MaxPoints = None,
        float32: _Float32 = False,
        significant_digits: _Digits = None,
        json_out: JsonOut = False,
    ) -> None:
        _run_benches(**{**locals(), "names": names})  # every option of this command, by name

    return command


def _register_benches(app: typer.Typer) -> None:
    """One command per registered bench on ``app``, and 'all'."""
    from evtms.workflows.bench import bench_catalogue

    catalogue = bench_catalogue()
    for name, bench in catalogue.items():
        cli_name = name.replace("_", "-")
        app.command(cli_name, help=_bench_help(bench))(_bench_command([name]))
        if cli_name != name:  # the registry's spelling works too
            app.command(name, help=_bench_help(bench), hidden=True)(_bench_command([name]))
    app.command(
        "all",
        help=(
            f"Sweep every bench ({', '.join(catalogue)}) on one grid preset and write <folder>/<name>.nc.\n\n"
            "Example: evtms bench all --grid cycle -o luts/"
        ),
    )(_bench_command(list(catalogue)))


def _run_benches(*, quiet: bool, json_out: bool, **options) -> None:
    from evtms.workflows.bench import BenchRequest, SweepInterrupted, run_bench

    request = BenchRequest(**{**options, "axis": options["axis"] or ()})

    def done(name, s) -> None:
        for message in getattr(s, "notes", ()):
            note(message)  # as every workflow's note: a field it names shown as its option
        if not json_out:
            chunks = f"{s.chunks} chunks ({s.computed} computed, {s.reused} reused), " if s.chunks > 1 else ""
            timing = f"{s.seconds:.2f} s ({s.runner})"
            typer.echo(f"{name}: {s.points} points, {s.invalid} invalid, {chunks}{timing}, wrote {s.path}")

    try:
        with _ProgressBar(quiet or json_out or not sys.stderr.isatty()) as bar:
            result = run_bench(request, progress=bar.by_label(), done=done)
    except SweepInterrupted as exc:
        if exc.kept == 0:
            raise typer.Exit(_error("interrupted before the first chunk was saved; nothing to resume", 130)) from None
        command = shlex.join(["evtms", *[a for a in _ARGV if a != "--resume"], "--resume"])
        message = f"interrupted: {exc.kept} of {exc.total} chunks kept in {str(exc.partial)!r}; resume with: {command}"
        raise typer.Exit(_error(message, 130)) from None
    if json_out:
        keys = ("points", "invalid", "chunks", "computed", "reused", "seconds", "runner")
        print_json(
            {
                "benches": [
                    {"component": name, "path": str(s.path), **{k: getattr(s, k) for k in keys}, "notes": list(s.notes)}
                    for name, s in result.benches
                ]
            }
        )
