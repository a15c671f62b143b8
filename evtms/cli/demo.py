"""evtms demo: the whole job into one folder."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, fail, print_json
from evtms.paths import creating_parents, input_file, output_folder


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
