"""evtms report ...: figures and reports from LUT files, cycle sweeps and system simulations."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, JsonOut, _ProgressBar, fail, note, print_json
from evtms.cli.lut import _open, _parse_point
from evtms.cli.simulate import SoakCabin, SystemToml
from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file, output_folder, staged_folder

report_app = typer.Typer(
    help="Figures and reports from LUT files, cycle sweeps and system simulations.", no_args_is_help=True
)


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
    fmt: _Format = "png",
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
_Sun = Annotated[float, typer.Option("--sun", help="Solar irradiance [W/m2].")]


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
    sun: _Sun = 0.0,
    soak_cabin: SoakCabin = None,
    fmt: _Format = "png",
    json_out: JsonOut = False,
) -> None:
    """Physics, LUT and surrogate models side by side: time per simulation, error, trajectories, step size.

    Example: evtms report compare --cycle wltc3b,nedc --t-amb -10,30,40 -o compare/
    Table 12: evtms report compare --scenarios t12 --approaches lut
    """
    options = dict(locals())  # every option by name: the request's fields
    del options["json_out"]
    from evtms.reports.compare import compare_summary
    from evtms.reports.table12 import table12_summary, table12_text
    from evtms.workflows.compare import CompareRequest, run_comparison

    def on_run(done: int, total: int, message: str) -> None:
        if not json_out:
            typer.echo(f"[{done}/{total}] {message}", err=True)

    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        c = run_comparison(CompareRequest(**options), notify=note, progress=bar.by_label(), on_run=on_run)
    files = [str(f) for f in c.files]
    if json_out:
        print_json({**(table12_summary if c.table12 else compare_summary)(c.result), "files": files})
    elif not c.table12:
        typer.echo(f"wrote {len(files)} files and {output / 'index.html'}")
    else:
        typer.echo(table12_text(c.result))
        if files:
            typer.echo(f"wrote {', '.join(files)}")
