"""evtms cycle run|sweep: the vapor-compression cycle on the component LUTs."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, fail, print_json
from evtms.paths import creating_parents, input_file, output_file

cycle_app = typer.Typer(help="Solve the vapor-compression cycle on the component LUTs.", no_args_is_help=True)


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
