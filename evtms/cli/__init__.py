"""Command-line interface: parses, calls library code, prints.

One module per command group (:mod:`~evtms.cli.bench`, :mod:`~evtms.cli.lut`,
:mod:`~evtms.cli.cycle`, :mod:`~evtms.cli.report`, :mod:`~evtms.cli.surrogate`,
:mod:`~evtms.cli.simulate`, :mod:`~evtms.cli.sweep`, :mod:`~evtms.cli.demo`) and :mod:`~evtms.cli.common`
for the error boundary, JSON printing and progress. Heavy libraries (CoolProp,
xarray, matplotlib) are imported inside the commands that need them, so
``evtms --help`` answers at once.
"""

from __future__ import annotations

from typing import Annotated

import typer

from evtms import __version__
from evtms.cli import bench, cycle, demo, lut, report, simulate, surrogate, sweep
from evtms.cli.common import _EvtmsGroup, _json_safe, print_json

__all__ = ["_json_safe", "app", "main", "print_json"]

app = typer.Typer(
    cls=_EvtmsGroup,
    name="evtms",
    help="R134a refrigerant-circuit benches, N-D lookup tables and cycle models for EV thermal management.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


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


app.add_typer(bench.bench_app, name="bench")
app.add_typer(lut.lut_app, name="lut")
app.add_typer(cycle.cycle_app, name="cycle")
app.add_typer(report.report_app, name="report")
app.add_typer(surrogate.surrogate_app, name="surrogate")
app.command()(demo.demo)
app.command()(simulate.simulate)
app.command()(sweep.sweep)


def main() -> None:
    """Console-script entry point."""
    from evtms.workflows.common import own_process

    own_process()  # a process of its own: numba set up without what no evtms kernel uses (SciPy's BLAS, cffi)
    app()
