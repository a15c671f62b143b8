"""evtms cycle run|sweep: the vapor-compression cycle on the component LUTs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, print_json, with_options
from evtms.workflows.cycle import DEFAULT_MAX_CYCLE_POINTS

cycle_app = typer.Typer(help="Solve the vapor-compression cycle on the component LUTs.", no_args_is_help=True)

_SPEED = typer.Option("--speed", help="Compressor speed fraction (0-1].")
_FAN = typer.Option("--fan", help="Condenser fan fraction (0-1].")
_BLOWER = typer.Option("--blower", help="Evaporator blower fraction (0-1].")
_TAMB = typer.Option("--t-amb", help="Ambient air temperature [degC], -40 to 60.")
_RHAMB = typer.Option("--rh-amb", help="Ambient relative humidity [0-1].")
_TCAB = typer.Option("--t-cabin", help="Air temperature entering the evaporator [degC], -20 to 50.")
_RHCAB = typer.Option("--rh-cabin", help="Relative humidity entering the evaporator [0-1].")
_TCOOL = typer.Option(
    "--t-coolant", help="Coolant temperature entering the chiller [degC], -20 to 60 (battery loop; e-drive loop in hp)."
)
_MCOOL = typer.Option(
    "--coolant-flow",
    help="Coolant (50 % ethylene glycol) mass flow through the chiller [kg/s] (battery loop; e-drive loop in hp).",
)
_TCOOLH = typer.Option(
    "--t-coolant-h", help="Heating-loop coolant temperature entering the water-cooled condenser [degC], -20 to 90 (hp)."
)
_MCOOLH = typer.Option(
    "--coolant-flow-h", help="Heating-loop coolant mass flow through the water-cooled condenser [kg/s] (hp)."
)
_TOPOLOGY = typer.Option(
    "--topology",
    help="Circuit: cabin (evaporator), chiller (battery coolant, blower off), cabin+chiller (both in parallel) "
    "or hp (heat pump: the water-cooled condenser heats the heating loop, the chiller draws on the e-drive loop).",
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
#: The heat pump's state labels (its evaporator is the chiller, its condenser the WCC).
_HP_STATES = {"A": "A chiller outlet", "B": "B compressor outlet", "C": "C WCC outlet", "D": "D valve outlet"}
_PERFORMANCE = (
    ("mdot", "mass flow", 1e3, "g/s", "kg s-1"),
    ("mdot_evap", "  through the evaporator", 1e3, "g/s", "kg s-1"),
    ("mdot_chiller", "  through the chiller", 1e3, "g/s", "kg s-1"),
    ("Q_evap", "cabin cooling |Q_evap|", -1.0, "W", "W"),
    ("Q_latent", "  of which latent", -1.0, "W", "W"),
    ("Q_chiller", "battery cooling |Q_chiller|", -1.0, "W", "W"),
    ("Q_cond", "Q_cond", 1.0, "W", "W"),
    ("Q_wcc", "  of which to the WCC", 1.0, "W", "W"),
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
    "Q_wcc": ("wcc", "condenser"),
}
#: The heat pump's rows (a circuit with the WCC): its heat flows named by the loops they serve.
_HP_PERFORMANCE = (
    ("mdot", "mass flow", 1e3, "g/s", "kg s-1"),
    ("Q_cond", "heat to the heating loop", 1.0, "W", "W"),
    ("Q_chiller", "heat from the e-drive loop", -1.0, "W", "W"),
    ("W", "compressor shaft power W", 1.0, "W", "W"),
    ("COP_heating", "heating COP Q_cond/W", 1.0, "-", "1"),
    ("COP", "source COP |Q_chiller|/W", 1.0, "-", "1"),
    ("dp_valve", "valve pressure drop", 1e-3, "kPa", "Pa"),
    ("valve_opening", "valve opening / nominal", 1.0, "-", "1"),
    ("superheat_actual", "chiller-outlet superheat", 1.0, "K", "K"),
    ("balance_residual", "energy balance residual", 1.0, "W", "W"),
    ("balance_relative", "  relative to W_fluid", 100.0, "%", "1"),
)


def _heat_pump(components: tuple[str, ...]) -> bool:
    """Whether a circuit of ``components`` is the heat pump: the WCC condenses alone."""
    return "wcc" in components and "condenser" not in components


def _performance(components: tuple[str, ...]) -> list[tuple]:
    """The performance rows that apply to a circuit of ``components``."""
    if _heat_pump(components):
        return list(_HP_PERFORMANCE)
    return [row for row in _PERFORMANCE if set(_PERFORMANCE_NEEDS.get(row[0], ())) <= set(components)]


#: Input options whose parameter is not the input's name (evtms.cycle.topology.INPUTS).
_INPUT_OF = {
    "t_amb": "T_amb",
    "rh_amb": "RH_amb",
    "t_cabin": "T_cabin",
    "rh_cabin": "RH_cabin",
    "coolant_flow": "mdot_coolant",
    "t_coolant": "T_coolant_in",
    "coolant_flow_h": "mdot_coolant_h",
    "t_coolant_h": "T_coolant_h_in",
}


def _circuit_options(
    topology: Annotated[str, _TOPOLOGY] = "cabin",
    speed: Annotated[str | None, _SPEED] = None,
    fan: Annotated[str | None, _FAN] = None,
    blower: Annotated[str | None, _BLOWER] = None,
    t_amb: Annotated[str | None, _TAMB] = None,
    rh_amb: Annotated[str | None, _RHAMB] = None,
    t_cabin: Annotated[str | None, _TCAB] = None,
    rh_cabin: Annotated[str | None, _RHCAB] = None,
    coolant_flow_h: Annotated[str | None, _MCOOLH] = None,
    t_coolant_h: Annotated[str | None, _TCOOLH] = None,
    coolant_flow: Annotated[str | None, _MCOOL] = None,
    t_coolant: Annotated[str | None, _TCOOL] = None,
    superheat: Annotated[str | None, _SH] = None,
    subcooling: Annotated[str | None, _SC] = None,
    luts: Annotated[Path | None, _LUTS] = None,
    direct: Annotated[bool, _DIRECT] = False,
    params: Annotated[Path | None, _PARAMS] = None,
) -> None:
    """The options 'cycle run' and 'cycle sweep' share (declared once, see :func:`with_options`)."""


def _request(topology: str, luts: Path | None, direct: bool, params: Path | None, **inputs: str | None):
    """The workflow's request from the shared options."""
    from evtms.workflows.cycle import CycleRequest

    return CycleRequest(topology, {_INPUT_OF.get(k, k): v for k, v in inputs.items()}, luts, direct, params)


@cycle_app.command("run")
@with_options(_circuit_options)
def cycle_run(json_out: JsonOut = False, **options) -> None:
    """Solve one operating point and print its states and performance.

    Example: evtms cycle run --luts luts/ --speed 0.6 --fan 0.5 --blower 0.4 --t-amb 30 --t-cabin 27

    Heat pump: evtms cycle run --luts luts/ --topology hp --speed 0.6 --t-coolant-h 40 --t-coolant 10
    """
    from evtms.workflows.cycle import run_cycle

    p = run_cycle(_request(**options))
    rows = _performance(p.components)
    if json_out:
        print_json(
            {
                "topology": p.topology,
                "inputs": p.inputs,
                "models": p.models,
                "status": p.status,
                "status_meaning": p.status_meaning,
                "note": p.note,
                "states": {s: {q: p.values[f"{q}_{s}"] for q in ("p", "T", "h")} for s in _STATES},
                **{key: p.values[key] for key, *_ in rows},
                "units": {"p": "Pa", "T": "K", "h": "J kg-1", **{key: si for key, *_, si in rows}},
            }
        )
        return
    v = p.values
    typer.echo(f"{'state':<26} {'p [MPa]':>9} {'T [degC]':>9} {'h [kJ/kg]':>10}")
    for s, label in (_HP_STATES if _heat_pump(p.components) else _STATES).items():
        typer.echo(f"{label:<26} {v['p_' + s] / 1e6:9.4f} {v['T_' + s] - 273.15:9.2f} {v['h_' + s] / 1e3:10.2f}")
    for key, label, scale, unit, _ in rows:
        typer.echo(f"{label:<26} {scale * v[key]:10.4g} {unit}")
    if p.note:
        typer.echo(f"note: {p.note}")


@cycle_app.command("sweep")
@with_options(_circuit_options, at=1)
def cycle_sweep(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    max_points: Annotated[
        int, typer.Option("--max-points", help="Refuse sweeps above this many operating points.")
    ] = DEFAULT_MAX_CYCLE_POINTS,
    json_out: JsonOut = False,
    **options,
) -> None:
    """Solve a grid of operating points (any input as v1,v2,... or start:stop:count) and write netCDF.

    Example: evtms cycle sweep --luts luts/ --speed 0.2:1:9 --t-amb 25,35,45 -o cycle.nc
    """
    import dataclasses

    from evtms.workflows.cycle import sweep_cycle

    s = sweep_cycle(dataclasses.replace(_request(**options), output=output, max_points=max_points))
    if json_out:
        print_json(
            {"path": str(output), "points": s.points, "solved": s.solved, "seconds": s.seconds, "status": s.status}
        )
        return
    typer.echo(f"cycle: {s.points} operating points, {s.solved} solved, {s.seconds:.2f} s, wrote {output}")
