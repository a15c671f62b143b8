"""evtms sweep: ambients x drive cycles x parameter sets, one summary row per scenario."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, _ProgressBar, note, print_json
from evtms.cli.simulate import SoakCabin, _Dt, _Luts, _Mode, _OutputEvery, _Precondition, _Surrogates

_Output = Annotated[
    Path, typer.Option("--output", "-o", help="Summary table: .nc (netCDF) or .csv, one row per scenario.")
]
_Cycles = Annotated[
    list[str],
    typer.Option(
        "--cycle",
        help="Drive cycles: wltc3b, nedc, udds, hwfet, parked:SECONDS or CSV files; comma-separated or repeated.",
    ),
]
_TAmb = Annotated[str, typer.Option("--t-amb", help="Ambients [degC]: v1,v2,... or start:stop:count.")]
_RhAmb = Annotated[str | None, typer.Option("--rh-amb", help="Ambient humidities [0-1], as --t-amb (default 0.4).")]
_Sun = Annotated[str | None, typer.Option("--sun", help="Solar irradiance [W/m2], as --t-amb (default 0).")]
_ParamSets = Annotated[
    list[Path] | None,
    typer.Option("--params", help="Parameter sets: system TOML files or folders of them; repeated (default: one, "
                 "the defaults)."),
]  # fmt: skip
_Model = Annotated[str, typer.Option("--model", help="lut (cycle maps) or surrogate (mode models).")]
_Runs = Annotated[Path | None, typer.Option("--runs", help="Folder for each run's own netCDF file (run-NNNN.nc).")]
_Workers = Annotated[int | None, typer.Option("--workers", help="Run the scenarios in N local dask worker processes.")]
_Scheduler = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Send the scenarios to a dask.distributed scheduler, tcp://host:port (it runs the code sent to it: "
        "use only a cluster you trust).",
    ),
]
_Batch = Annotated[int | None, typer.Option("--batch", help="Scenarios per task (default: by scenarios and workers).")]
_MaxScenarios = Annotated[int, typer.Option("--max-scenarios", help="Refuse sweeps above this many scenarios.")]


def sweep(
    output: _Output,
    cycle: _Cycles = ["wltc3b"],  # noqa: B006 - typer's default of a repeated option
    t_amb: _TAmb = "25",
    rh_amb: _RhAmb = None,
    sun: _Sun = None,
    params: _ParamSets = None,
    mode: _Mode = None,
    luts: _Luts = Path("luts"),
    dt: _Dt = 1.0,
    output_every: _OutputEvery = None,
    soak_cabin: SoakCabin = None,
    precondition: _Precondition = 0.0,
    model: _Model = "lut",
    surrogates: _Surrogates = Path("models"),
    runs: _Runs = None,
    workers: _Workers = None,
    scheduler: _Scheduler = None,
    batch: _Batch = None,
    max_scenarios: _MaxScenarios = 10_000,
    json_out: JsonOut = False,
) -> None:
    """Simulate every scenario of ambients x drive cycles x parameter sets (each as 'evtms simulate' runs it)
    and write one summary table: energies, Wh/km, range, cabin comfort, battery temperatures, status.

    Example: evtms sweep --t-amb -10:40:6 --cycle wltc3b,udds --params variants/ --workers 2 -o study.nc
    """
    options = dict(locals())  # every option by name: the request's fields
    del options["json_out"]
    from evtms.workflows.sweep import SweepRequest, run_sweep

    request = SweepRequest(**{**options, "params": options["params"] or ()})
    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        result = run_sweep(request, notify=note, progress=bar.by_label())
    if json_out:
        print_json(result.to_dict())
        return
    for row in result.table.rows[:_SHOWN]:
        typer.echo(_row_line(row))
    if result.scenarios > _SHOWN:
        typer.echo(f"... {result.scenarios - _SHOWN} more rows in {result.path}")
    typer.echo(
        f"wrote {result.path}: {result.scenarios} scenarios ({result.failed} failed), {result.runner} "
        f"x{result.workers}, {result.per_run_s * 1e3:.1f} ms per run, {result.wall_time_s:.2f} s in all"
    )


#: Rows printed as text (all are in the table).
_SHOWN = 20


def _row_line(row: dict) -> str:
    """One scenario's inputs and main figures as a line."""
    where = f"{row['scenario']:4d} {row['cycle']:<8} {row['T_amb_degC']:6.1f} degC"
    if row["params"]:
        where += f" {Path(row['params']).name}"
    if row["status"] == "error":
        return f"{where}  error: {row['message']}"
    per_km = row["battery_Wh_per_km"]
    return (
        f"{where}  battery {row['battery_energy_kWh']:.3f} kWh (HVAC {row['hvac_energy_kWh']:.3f})  "
        f"{'n/a' if math.isnan(per_km) else f'{per_km:.1f}'} Wh/km  cabin {row['T_cabin_end_degC']:.1f} degC  "
        f"battery {row['T_battery_min_degC']:.1f}..{row['T_battery_max_degC']:.1f} degC  {row['status']}"
    )
