"""evtms simulate: the vehicle's thermal system over a drive cycle or a range test."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, _ProgressBar, note, print_json, with_options

_SIM_TAMB = typer.Option(
    "--t-amb", help="Ambient [degC]: one value, v1,v2,... or start:stop:count (several run side by side)."
)
#: Options 'report compare' and 'surrogate train' share with this command.
SoakCabin = Annotated[float | None, typer.Option("--soak-cabin", help="Initial cabin air, walls and interior [degC].")]
SystemToml = Annotated[Path | None, typer.Option("--params", help="System TOML, as evtms simulate.")]

_INPUT_HELP = {
    "q_battery": ("--q-battery", "Heat into the battery [W] (Table 12 Qloss), or FILE.csv:column [W]."),
    "hvac_inlet_t": ("--hvac-inlet-t", "Fixed HVAC inlet air [degC] (Table 12 Tin), or FILE.csv:column [K]."),
    "hvac_inlet_rh": ("--hvac-inlet-rh", "Fixed HVAC inlet relative humidity [0-1], or FILE.csv:column."),
    "sp_evap": ("--sp-evap", "Evaporator outlet air setpoint [degC], or FILE.csv:column [K]."),
    "sp_cohx": ("--sp-cohx", "Heater-core coolant inlet setpoint [degC] (ptc_coolant), or FILE.csv:column [K]."),
    "blower": ("--blower", "Fixed blower command [0-1] (not 0 with auto, cc or ch), or FILE.csv:column."),
    "sp_vent": ("--sp-vent", "Vent air target [degC] in place of the cabin loop's, or FILE.csv:column [K]."),
    "bc_request": (
        "--bc-request",
        "Battery-cooling request [0-1, on above 0.5] in place of its relay, or FILE.csv:column.",
    ),
    "speed_deviation": (
        "--speed-deviation",
        "Driven speed less the trace's [m/s], within [vehicle] delta_v_ref (0: off), or FILE.csv:column.",
    ),
}
#: Option parameter -> input name (evtms.system.inputs.INPUT_NAMES).
_INPUT_OF = {
    "q_battery": "Q_battery_ext",
    "hvac_inlet_t": "hvac_inlet_T",
    "hvac_inlet_rh": "hvac_inlet_rh",
    "sp_evap": "SP_evap",
    "sp_cohx": "SP_CoHX",
    "blower": "blower",
    "sp_vent": "SP_vent",
    "bc_request": "BC_request",
    "speed_deviation": "speed_deviation",
}


def _input_option(key: str):
    option, text = _INPUT_HELP[key]
    return typer.Option(option, help=text)


def _input_options(
    q_battery: Annotated[str | None, _input_option("q_battery")] = None,
    hvac_inlet_t: Annotated[str | None, _input_option("hvac_inlet_t")] = None,
    hvac_inlet_rh: Annotated[str | None, _input_option("hvac_inlet_rh")] = None,
    sp_evap: Annotated[str | None, _input_option("sp_evap")] = None,
    sp_cohx: Annotated[str | None, _input_option("sp_cohx")] = None,
    blower: Annotated[str | None, _input_option("blower")] = None,
    sp_vent: Annotated[str | None, _input_option("sp_vent")] = None,
    bc_request: Annotated[str | None, _input_option("bc_request")] = None,
    speed_deviation: Annotated[str | None, _input_option("speed_deviation")] = None,
) -> None:
    """The external-input options of 'evtms simulate' (see :func:`with_options`)."""


_Cycle = Annotated[
    str | None, typer.Option("--cycle", help="Drive cycle: wltc3b, nedc, udds, hwfet, parked:SECONDS or a CSV file.")
]
_Scenario = Annotated[
    str | None,
    typer.Option(
        "--scenario",
        help="Named scenario: built in (hot-drive, cooldown, cold, wltc, nedc, hot-sun, t12-bh-1 ... t12-ch-4) "
        "or from --scenario-file.",
    ),
]
_ScenarioFile = Annotated[
    Path | None, typer.Option("--scenario-file", help="TOML scenario file (docs/scenario-format.md).")
]
_Mode = Annotated[
    str | None,
    typer.Option(
        "--mode",
        help="auto, or force one mode: off, bh, bc, cc, ch, ch-hp (ch on the heat pump); default: the scenario's, "
        "or auto.",
    ),
]
_Params = Annotated[Path | None, typer.Option("--params", help="TOML: [vehicle] [battery] [cabin] ...")]
_Luts = Annotated[
    Path,
    typer.Option(
        "--luts",
        help="Cycle LUT folder (evtms bench all --grid cycle -o DIR), or evtms demo's luts/ or output folder; "
        "built there if missing or empty.",
    ),
]
_Dt = Annotated[float, typer.Option("--dt", help="Time step [s], 0.001 to 60.")]
_OutputEvery = Annotated[
    float | None, typer.Option("--output-every", help="Record spacing [s], a multiple of --dt (max(1, dt)).")
]
_Precondition = Annotated[
    float, typer.Option("--precondition", help="Seconds of HVAC parked and plugged in before the cycle.")
]
_Model = Annotated[
    str,
    typer.Option(
        "--model",
        help="lut (cycle maps), physics (bench physics solved in the loop: the slow reference) or surrogate "
        "(mode models of 'evtms surrogate train').",
    ),
]
_Surrogates = Annotated[
    Path,
    typer.Option("--surrogates", help="Mode-model file or folder (evtms surrogate train -o), for --model surrogate."),
]
_RangeTest = Annotated[
    str,
    typer.Option(
        "--range",
        help="single (the cycle once; range_km extrapolates it), mct (SAE J1634 multi-cycle test: UDDS, HWFET "
        "and 65 mph phases to break-off) or ccp (UN GTR 15: WLTC 3b back to back to break-off). mct and ccp "
        "start fully charged and drive their own cycles: leave out --cycle (ccp accepts --cycle wltc3b); a "
        "--scenario gives its conditions, not its cycle.",
    ),
]


_Heating = Annotated[
    str | None,
    typer.Option(
        "--heating",
        help="Cabin heating: ptc_air, ptc_coolant or heat_pump, or several comma-separated (each runs at every "
        "ambient, side by side; evtms report range draws one curve each). Default: --params' [hvac] heating.",
    ),
]


Controller = Annotated[
    str,
    typer.Option(
        "--controller",
        help="Who sets the cabin's vent air and blower: rules (the climate control) or mpc (a predictive "
        "controller above the same local loops and safety relays; needs the extra 'mpc').",
    ),
]
Horizon = Annotated[float, typer.Option("--horizon", help="MPC horizon [s], 30 to 1800.")]
ControlStep = Annotated[float, typer.Option("--control-step", help="MPC step [s], 1 to 60.")]
Preview = Annotated[str, typer.Option("--preview", help="MPC preview of the speed trace: perfect, none or noisy.")]


@with_options(_input_options, at=15)
def simulate(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    cycle: _Cycle = None,
    scenario: _Scenario = None,
    scenario_file: _ScenarioFile = None,
    t_amb: Annotated[str | None, _SIM_TAMB] = None,
    mode: _Mode = None,
    params: _Params = None,
    luts: _Luts = Path("luts"),
    dt: _Dt = 1.0,
    output_every: _OutputEvery = None,
    soak_cabin: SoakCabin = None,
    precondition: _Precondition = 0.0,
    model: _Model = "lut",
    surrogates: _Surrogates = Path("models"),
    range_test: _RangeTest = "single",
    heating: _Heating = None,
    controller: Controller = "rules",
    horizon: Horizon = 180.0,
    control_step: ControlStep = 10.0,
    preview: Preview = "perfect",
    json_out: JsonOut = False,
    **inputs: str | None,
) -> None:
    """Simulate the vehicle's thermal system over a drive cycle (or a range test) and write the time series.

    Example: evtms simulate --cycle wltc3b --t-amb 30 -o run.nc --json
    """
    options = dict(locals())  # every option by name: the request's fields
    del options["json_out"], options["inputs"]
    from evtms.workflows.simulate import SimulationRequest, run_simulation

    request = SimulationRequest(**options, inputs={_INPUT_OF[k]: v for k, v in inputs.items()})
    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        run = run_simulation(request, notify=note, progress=bar.by_label())
    results = run.results
    if json_out:
        print_json(results[0].summary if len(results) == 1 else {"runs": [r.summary for r in results]})
        return
    for r in results:
        typer.echo(_range_line(r.summary) if "range" in r.summary else _run_line(r.summary))
    typer.echo(f"wrote {output} ({run.wall_time_s:.2f} s)")


def _run_line(s: dict) -> str:
    """One line of a run's figures."""
    return (
        f"{s['T_amb_degC']:6.1f} degC  {s['distance_km']:.2f} km  battery {s['battery_energy_kWh']:.3f} kWh "
        f"(HVAC {s['hvac_energy_kWh']:.3f})  SOC {s['soc_end']:.4f}  cabin {s['T_cabin_end_degC']:.1f} degC  "
        f"battery {s['T_battery_end_degC']:.1f} degC  loop {s['loop_time_s'] * 1e3:.0f} ms"
        + ("" if s["termination"] == "end of cycle" else f"  ended: {s['termination']} at {s['duration_s']:.0f} s")
        + _controller_text(s)
    )


def _range_line(s: dict) -> str:
    """One line of a depletion test's figures (evtms simulate --range mct|ccp)."""
    f = s["range"]

    def km(key: str) -> str:
        return "n/a" if f.get(key) is None else f"{f[key]:.1f} km"

    ec = f.get("EC_ss_combined_Wh_per_km")
    main = (
        f"combined {km('range_combined_km')} (city {km('range_city_km')}, highway {km('range_hwy_km')})"
        if f["test"] == "mct"
        else f"depletion {km('range_depletion_km')}"
    )
    return (
        f"{s['T_amb_degC']:6.1f} degC  {f['test']}: UBE {f['ube_kWh']:.2f} kWh, {main}, "
        f"EC_ss {'n/a' if ec is None else f'{ec:.1f}'} Wh/km, range_ss {km('range_ss_km')}, "
        f"break-off {f['break_off']} at {f['break_off_s'] / 3600.0:.2f} h  loop {s['loop_time_s'] * 1e3:.0f} ms"
    )


def _controller_text(s: dict) -> str:
    """The MPC's solve times and fallbacks for the summary line (nothing for the rules)."""
    if s.get("controller_solve_mean_s") is None:
        return ""
    return (
        f"  {s['controller']} {s['controller_solve_mean_s'] * 1e3:.1f} ms per decision (worst "
        f"{s['controller_solve_max_s'] * 1e3:.0f}), {s['controller_fallbacks']} fallbacks"
    )
