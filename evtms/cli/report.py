"""evtms report ...: figures and reports from LUT files, cycle sweeps and system simulations."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, _ProgressBar, cli_message, note, print_json
from evtms.cli.simulate import ControlStep, Horizon, SoakCabin, SystemToml

report_app = typer.Typer(
    help="Figures and reports from LUT files, cycle sweeps and system simulations.", no_args_is_help=True
)


def _diagram(kind: str, sweep: Path, output: Path, point: str | None) -> None:
    from evtms.workflows.report import cycle_diagram

    typer.echo(f"wrote {cycle_diagram(kind, sweep, output, point)}")


_Format = Annotated[str, typer.Option("--format", help="Figure format: png or svg.")]
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
    from evtms.workflows.report import energy_balance_report

    figure, table = energy_balance_report(sweep, output, x)
    typer.echo(f"wrote {figure} and {table}")


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
    fmt: _Format = "png",
) -> None:
    """Bench figures and an HTML report from a LUT: response per axis, 3-D map, provenance.

    Nothing appears in the output folder unless every figure and the page
    are written.

    Example: evtms report bench luts/condenser.nc -o reports/condenser/
    """
    from evtms.workflows.report import bench_report

    count, page = bench_report(file, output, at, surface, fmt)
    typer.echo(f"wrote {count} figures and {page}")


@report_app.command("simulation")
def report_simulation(
    run: Annotated[Path, typer.Argument(help="Simulation file (evtms simulate), one run or an ambient sweep.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Figure file, .png or .svg.")],
    t_amb: Annotated[
        float | None,
        typer.Option("--t-amb", help="Ambient [degC] of the run to draw from a sweep; default: the first."),
    ] = None,
    json_out: JsonOut = False,
) -> None:
    """Time series of one run: speed, temperatures, powers, heat flows, SOC and the modes.

    Example: evtms simulate --cycle wltc3b --t-amb 35 -o run.nc && evtms report simulation run.nc -o run.png
    """
    from evtms.workflows.report import simulation_report

    simulation_report(run, output, t_amb)
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
    heating: Annotated[
        str | None,
        typer.Option(
            "--heating",
            help="A range test's heating options to draw, comma-separated (ptc_air, ptc_coolant, heat_pump; "
            "default: every one in the file). With heat_pump and a resistive one: the gain per ambient.",
        ),
    ] = None,
    json_out: JsonOut = False,
) -> None:
    """Range against the ambient temperature.

    A range test's file (evtms simulate --range mct|ccp): the test's range (combined for mct, depletion for
    ccp) and the steady consumption EC_ss, the v1 single-trip range dashed, the 10-30 degC band (Geotab), the
    change against 23.9 degC with the AAA 2019 points; --json adds the figures per ambient and the Geotab shape
    checks (with a breakdown where one fails). A single-trip sweep: consumption per 100 km split by use, and
    the extrapolated range.

    Example: evtms simulate --range mct --t-amb -10:40:11 -o mct.nc && evtms report range mct.nc -o range.png
    """
    from evtms.workflows.report import range_report

    report = range_report(sweep, output, heating)
    if json_out:
        print_json({"path": str(output), **report})
        return
    for g in report.get("heat_pump_gain", []):
        typer.echo(_gain_line(g))
    typer.echo(f"wrote {output}")


def _gain_line(g: dict) -> str:
    """One line of the heat pump's range gain at one ambient, and where it comes from."""

    def num(key: str, fmt: str) -> str:
        return "n/a" if g.get(key) is None else format(g[key], fmt)

    return (
        f"{g['T_amb_degC']:6.1f} degC  heat_pump {num('range_km', '.0f')} km vs {g['base']} "
        f"{num('base_range_km', '.0f')} km: {num('gain_pct', '+.1f')} %  (HVAC share {g['hvac_share']:.0%} vs "
        f"{g['base_hvac_share']:.0%}, COP_sys {num('cop_sys_mean', '.2f')}, backup share "
        f"{num('backup_share', '.0%')}, waste heat {num('waste_heat_kWh', '.2f')} kWh, ambient heat "
        f"{num('ambient_heat_kWh', '.2f')} kWh)"
    )


_Cycles = Annotated[
    str | None, typer.Option("--cycle", help="Drive cycles, comma-separated: built-in names or CSV files.")
]
_Ambients = Annotated[str | None, typer.Option("--t-amb", help="Ambient temperatures [degC], comma-separated.")]
_Folder = Annotated[
    Path | None, typer.Option("--output", "-o", help="Output folder (created if missing); optional with --scenarios.")
]
_Scenarios = Annotated[
    str | None,
    typer.Option(
        "--scenarios",
        help="Scenarios instead of --cycle/--t-amb, comma-separated names or groups: t12 (the 16 Table 12 "
        "rows), t12-cc, t12-bh-1, ...; prints the thesis's Table 12 columns per row.",
    ),
]
_ScenarioFile = Annotated[
    Path | None,
    typer.Option("--scenario-file", help="TOML scenario file whose scenarios --scenarios may name (else: all)."),
]
_Approaches = Annotated[
    str | None,
    typer.Option(
        "--approaches",
        help="Approaches to compare, comma-separated: physics, lut, surrogate (default: all three; with "
        "--scenarios lut and those available).",
    ),
]
_Surrogates = Annotated[
    Path, typer.Option("--surrogates", help="Mode-model file or folder (evtms surrogate train -o).")
]
_Luts = Annotated[
    Path,
    typer.Option(
        "--luts", help="Cycle LUT folder (evtms bench all --grid cycle), or evtms demo's luts/ or output folder."
    ),
]
_Dt = Annotated[float, typer.Option("--dt", help="Step of the comparison table and trajectories [s].")]
_Dts = Annotated[str, typer.Option("--dts", help="Steps of the step-size study [s].")]
_PhysicsDts = Annotated[
    str | None,
    typer.Option("--physics-dts", help="Steps at which physics joins the study [s] (slow); default: --dts >= 1 s."),
]
_NoSteps = Annotated[bool, typer.Option("--no-steps", help="Skip the step-size study.")]
_Measured = Annotated[
    Path | None,
    typer.Option(
        "--measured",
        help="CSV of measured time,T_cabin,T_battery,SOC,P_hvac (any subset; s, K, 1, W): the reference where "
        "given; needs one cycle and one ambient.",
    ),
]
_Repeat = Annotated[int, typer.Option("--repeat", help="Runs of lut and surrogate per scenario, median time.")]
_Sun = Annotated[
    float | None,
    typer.Option(
        "--sun", help="Solar irradiance [W/m2]; default 0, with --controllers 600 above the setpoint and 0 below."
    ),
]
_Controllers = Annotated[
    str | None,
    typer.Option(
        "--controllers",
        help="Compare climate controllers instead of models, comma-separated: rules, mpc (the extra 'mpc'); "
        "over --cycle (default wltc3b,udds) and --t-amb (default -10,30,40) on the LUT model.",
    ),
]
_Previews = Annotated[
    str,
    typer.Option("--preview", help="With --controllers: the MPC's previews, comma-separated: perfect, none, noisy."),
]


@report_app.command("compare")
def report_compare(
    cycle: _Cycles = None,
    t_amb: _Ambients = None,
    output: _Folder = None,
    scenarios: _Scenarios = None,
    scenario_file: _ScenarioFile = None,
    approaches: _Approaches = None,
    surrogates: _Surrogates = Path("models"),
    luts: _Luts = Path("luts"),
    params: SystemToml = None,
    dt: _Dt = 1.0,
    dts: _Dts = "0.01,0.1,1,10",
    physics_dts: _PhysicsDts = None,
    no_steps: _NoSteps = False,
    measured: _Measured = None,
    repeat: _Repeat = 3,
    sun: _Sun = None,
    soak_cabin: SoakCabin = None,
    fmt: _Format = "png",
    controllers: _Controllers = None,
    preview: _Previews = "perfect,none",
    horizon: Horizon = 180.0,
    control_step: ControlStep = 10.0,
    json_out: JsonOut = False,
) -> None:
    """Physics, LUT and surrogate models side by side: time per simulation, error, trajectories, step size.

    Example: evtms report compare --cycle wltc3b,nedc --t-amb -10,30,40 -o compare/
    Table 12: evtms report compare --scenarios t12 --approaches lut
    Controllers: evtms report compare --controllers rules,mpc -o controllers/
    """
    options = dict(locals())  # every option by name: the request's fields
    if controllers is not None:
        _compare_controllers(options, json_out)
    else:
        _compare_models(options, json_out)


def _compare_models(options: dict, json_out: bool) -> None:
    """``report compare`` of models (physics, LUT, surrogates) or of Table 12's scenarios."""
    from evtms.reports.compare import compare_summary
    from evtms.reports.table12 import table12_summary, table12_text
    from evtms.workflows.compare import CompareRequest, run_comparison

    for key in ("controllers", "preview", "horizon", "control_step", "json_out"):
        del options[key]
    options["sun"] = 0.0 if options["sun"] is None else options["sun"]

    def on_run(done: int, total: int, message: str) -> None:
        if not json_out:
            typer.echo(f"[{done}/{total}] {message}", err=True)

    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        c = run_comparison(CompareRequest(**options), notify=note, progress=bar.by_label(), on_run=on_run)
    files = [str(f) for f in c.files]
    if json_out:
        print_json({**(table12_summary if c.table12 else compare_summary)(c.result), "files": files})
    elif not c.table12:
        typer.echo(f"wrote {len(files)} files and {options['output'] / 'index.html'}")
    else:
        typer.echo(cli_message(table12_text(c.result)))  # a skip reason's `field` as its option
        if files:
            typer.echo(f"wrote {', '.join(files)}")


def _compare_controllers(options: dict, json_out: bool) -> None:
    """``report compare --controllers``: the controllers' table, printed, and its files."""
    import inspect
    from dataclasses import asdict

    from evtms.errors import EvtmsInputError
    from evtms.workflows.controllers import ControllerRequest, compare_controllers, controller_table

    own = ("cycle", "t_amb", "controllers", "preview", "luts", "params", "sun", "horizon", "control_step", "output")
    defaults = {k: p.default for k, p in inspect.signature(report_compare).parameters.items()}
    unused = [
        f"--{k.replace('_', '-')}" for k in defaults if k not in (*own, "fmt", "json_out") and options[k] != defaults[k]
    ]
    if unused:
        raise EvtmsInputError(f"{', '.join(unused)}: for comparing models; not allowed with --controllers")
    request = ControllerRequest(
        cycle=options["cycle"] or "wltc3b,udds",
        t_amb=options["t_amb"] or "-10,30,40",
        controllers=options["controllers"],
        previews=options["preview"],
        luts=options["luts"],
        params=options["params"],
        sun=options["sun"],
        horizon=options["horizon"],
        control_step=options["control_step"],
        output=options["output"],
        fmt=options["fmt"],
    )

    def on_run(done: int, total: int, message: str) -> None:
        if not json_out:
            typer.echo(f"[{done}/{total}] {message}", err=True)

    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        rows, files = compare_controllers(request, notify=note, progress=bar.by_label(), on_run=on_run)
    if json_out:
        print_json({"rows": [asdict(r) for r in rows], "files": [str(f) for f in files]})
        return
    typer.echo(controller_table(rows))
    if files:
        typer.echo(f"wrote {', '.join(str(f) for f in files)}")
