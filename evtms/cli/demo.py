"""evtms demo: the whole job into one folder."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, print_json


def demo(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder (created if missing).")] = Path("out"),
    force: Annotated[bool, typer.Option("--force", help="Recompute LUTs even if they are up to date.")] = False,
    workers: Annotated[int, typer.Option("--workers", help="Processes for the bench sweeps.")] = 2,
    params: Annotated[Path | None, typer.Option("--params", help="TOML parameter overrides.")] = None,
    json_out: JsonOut = False,
) -> None:
    """The whole job: benches on the thesis and cycle grids, LUTs, a cycle sweep, figures, index.html.

    Example: evtms demo -o out/   (a second run reuses up-to-date LUTs; --force recomputes)
    """
    from evtms.workflows.demo import run_demo

    t0 = time.perf_counter()

    def notify(message: str) -> None:
        typer.echo(f"[{time.perf_counter() - t0:6.1f} s] {message}", err=True)

    result = run_demo(output, params, force=force, workers=workers, notify=notify)
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
