"""evtms simulate: the vehicle's thermal system over a drive cycle or a range test."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, _ProgressBar, fail, print_json
from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file

_SIM_TAMB = typer.Option(
    "--t-amb", help="Ambient [degC]: one value, v1,v2,... or start:stop:count (several run side by side)."
)


_INPUT_HELP = {
    "q_battery": ("--q-battery", "Heat into the battery [W] (Table 12 Qloss), or FILE.csv:column [W]."),
    "hvac_inlet_t": ("--hvac-inlet-t", "Fixed HVAC inlet air [degC] (Table 12 Tin), or FILE.csv:column [K]."),
    "hvac_inlet_rh": ("--hvac-inlet-rh", "Fixed HVAC inlet relative humidity [0-1], or FILE.csv:column."),
    "sp_evap": ("--sp-evap", "Evaporator outlet air setpoint [degC], or FILE.csv:column [K]."),
    "sp_cohx": ("--sp-cohx", "Heater-core coolant inlet setpoint [degC] (ptc_coolant), or FILE.csv:column [K]."),
    "blower": ("--blower", "Fixed blower command [0-1] (not 0 with auto, cc or ch), or FILE.csv:column."),
}
#: Option parameter -> input name (evtms.system.inputs.INPUT_NAMES).
_INPUT_OF = {
    "q_battery": "Q_battery_ext",
    "hvac_inlet_t": "hvac_inlet_T",
    "hvac_inlet_rh": "hvac_inlet_rh",
    "sp_evap": "SP_evap",
    "sp_cohx": "SP_CoHX",
    "blower": "blower",
}


def _input_option(key: str):
    option, text = _INPUT_HELP[key]
    return typer.Option(option, help=text)


def _option_inputs(texts: dict[str, str | None]) -> dict:
    """The input options given (numbers in degC for temperatures, or FILE.csv:column), checked, SI."""
    from evtms.system.inputs import CLI_OPTIONS, check_inputs

    raw: dict[str, object] = {}
    for key, text in texts.items():
        if text is None:
            continue
        try:
            raw[_INPUT_OF[key]] = float(text)
        except ValueError:
            raw[_INPUT_OF[key]] = text
    return check_inputs(raw, celsius=True, labels=CLI_OPTIONS)


def _trace_files(inputs: dict) -> list[Path]:
    from evtms.system.inputs import Trace

    return [Path(v.source.rpartition(":")[0]) for v in inputs.values() if isinstance(v, Trace)]


def _scenario_choice(name: str | None, file: Path | None):
    """The scenario of --scenario NAME (built in, or in --scenario-file) or the only one of --scenario-file."""
    from evtms.system.scenarios import SCENARIOS, read_scenario_file

    from_file = read_scenario_file(input_file(file, "scenario file")) if file is not None else {}
    if name is None:
        if len(from_file) != 1:
            fail(f"--scenario-file {str(file)!r} holds {len(from_file)} scenarios ({', '.join(from_file)}); "
                 "give --scenario NAME")  # fmt: skip
        return next(iter(from_file.values()))
    available = {**SCENARIOS, **from_file}
    if name not in available:
        where = f"allowed: {', '.join(from_file)} (in {file}) or the built-in " if from_file else "allowed: "
        fail(f"--scenario {name!r} is unknown; {where}{', '.join(SCENARIOS)}")
    return available[name]


def simulate(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output netCDF file.")],
    cycle: Annotated[
        str | None,
        typer.Option("--cycle", help="Drive cycle: wltc3b, nedc, udds, hwfet, parked:SECONDS or a CSV file."),
    ] = None,
    scenario: Annotated[
        str | None,
        typer.Option(
            "--scenario",
            help="Named scenario: built in (hot-drive, cooldown, cold, wltc, nedc, hot-sun, t12-bh-1 ... t12-ch-4) "
            "or from --scenario-file.",
        ),
    ] = None,
    scenario_file: Annotated[
        Path | None, typer.Option("--scenario-file", help="TOML scenario file (docs/scenario-format.md).")
    ] = None,
    t_amb: Annotated[str | None, _SIM_TAMB] = None,
    mode: Annotated[
        str | None,
        typer.Option("--mode", help="auto, or force one mode: off, bh, bc, cc, ch (default: the scenario's, or auto)."),
    ] = None,
    params: Annotated[Path | None, typer.Option("--params", help="TOML: [vehicle] [battery] [cabin] ...")] = None,
    luts: Annotated[
        Path,
        typer.Option(
            "--luts",
            help="Cycle LUT folder (evtms bench all --grid cycle -o DIR), or evtms demo's luts/ or output folder; "
            "built there if missing or empty.",
        ),
    ] = Path("luts"),
    dt: Annotated[float, typer.Option("--dt", help="Time step [s], 0.001 to 60.")] = 1.0,
    output_every: Annotated[
        float | None, typer.Option("--output-every", help="Record spacing [s], a multiple of --dt (max(1, dt)).")
    ] = None,
    soak_cabin: Annotated[
        float | None, typer.Option("--soak-cabin", help="Initial cabin air, walls and interior [degC].")
    ] = None,
    precondition: Annotated[
        float, typer.Option("--precondition", help="Seconds of HVAC parked and plugged in before the cycle.")
    ] = 0.0,
    model: Annotated[
        str,
        typer.Option(
            "--model",
            help="lut (cycle maps), physics (bench physics solved in the loop: the slow reference) or surrogate "
            "(mode models of 'evtms surrogate train').",
        ),
    ] = "lut",
    surrogates: Annotated[
        Path,
        typer.Option(
            "--surrogates", help="Mode-model file or folder (evtms surrogate train -o), for --model surrogate."
        ),
    ] = Path("models"),
    range_test: Annotated[
        str,
        typer.Option(
            "--range",
            help="single (the cycle once; range_km extrapolates it), mct (SAE J1634 multi-cycle test: UDDS, HWFET "
            "and 65 mph phases to break-off) or ccp (UN GTR 15: WLTC 3b back to back to break-off). mct and ccp "
            "start fully charged and drive their own cycles: leave out --cycle (ccp accepts --cycle wltc3b); a "
            "--scenario gives its conditions, not its cycle.",
        ),
    ] = "single",
    q_battery: Annotated[str | None, _input_option("q_battery")] = None,
    hvac_inlet_t: Annotated[str | None, _input_option("hvac_inlet_t")] = None,
    hvac_inlet_rh: Annotated[str | None, _input_option("hvac_inlet_rh")] = None,
    sp_evap: Annotated[str | None, _input_option("sp_evap")] = None,
    sp_cohx: Annotated[str | None, _input_option("sp_cohx")] = None,
    blower: Annotated[str | None, _input_option("blower")] = None,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Simulate the vehicle's thermal system over a drive cycle (or a range test) and write the time series.

    Example: evtms simulate --cycle wltc3b --t-amb 30 -o run.nc --json
    """
    t0 = time.perf_counter()
    from evtms.cycle.topology import parse_values
    from evtms.system.params import load_system_params
    from evtms.system.range_test import RANGE_TESTS
    from evtms.system.scenarios import SCENARIO_MODES, Scenario, check_choice
    from evtms.system.simulate import MODELS, check_run_options

    if range_test not in RANGE_TESTS:
        fail(f"--range {range_test!r} is unknown; allowed: {', '.join(RANGE_TESTS)}")
    depletion = range_test != "single"

    named = scenario is not None or scenario_file is not None
    if depletion:
        if cycle is not None and not (range_test == "ccp" and cycle == "wltc3b"):
            own = "UDDS, HWFET and 65 mph phases" if range_test == "mct" else "WLTC 3b back to back"
            fail(f"--range {range_test} drives its own cycles ({own}); leave out --cycle {cycle}")
        if cycle is not None and named:
            fail("give --cycle NAME|FILE.csv or --scenario NAME / --scenario-file FILE.toml (one of them)")
    elif (cycle is None) == (not named):
        fail("give --cycle NAME|FILE.csv or --scenario NAME / --scenario-file FILE.toml (one of them)")
    if model not in MODELS:
        fail(f"--model {model!r} is unknown; allowed: {', '.join(MODELS)}")
    if mode is not None:
        check_choice("--mode", mode, SCENARIO_MODES)
    _check_soak(soak_cabin)
    sc = _scenario_choice(scenario, scenario_file) if named else Scenario(name="", cycle=cycle or "wltc3b")
    if t_amb is None and sc.T_amb is None:
        fail("give --t-amb DEGC (this cycle or scenario has no ambient of its own)")
    ambients = parse_values("T_amb", t_amb, 1000) if t_amb is not None else [sc.T_amb]
    inputs = [params] if params is not None else []
    if params is not None:
        input_file(params, "params file")
    if scenario_file is not None:
        inputs.append(scenario_file)
    system = load_system_params(params)
    extra = _option_inputs(
        {"q_battery": q_battery, "hvac_inlet_t": hvac_inlet_t, "hvac_inlet_rh": hvac_inlet_rh, "sp_evap": sp_evap,
         "sp_cohx": sp_cohx, "blower": blower}
    )  # fmt: skip
    setup = sc.setup(system, mode=mode, inputs=extra)
    if depletion:
        from evtms.system.range_test import ccp_sequence, mct_sequence

        trace = mct_sequence(0.0, 1).cycle if range_test == "mct" else ccp_sequence(1).cycle  # the options' checks
    else:
        trace = setup.cycle
    check_run_options(trace, dt, setup.mode, output_every, precondition)
    if not depletion and Path(trace.source).is_file():
        inputs.append(Path(trace.source))
    inputs += _trace_files(setup.inputs)
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    mode_models = None
    if model == "surrogate":
        mode_models, surrogate_file = _mode_models(surrogates)
        inputs.append(surrogate_file)
    output_file(output, inputs, (".nc",))
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)
    from evtms.system.output import write_simulation
    from evtms.system.scenarios import run_scenario
    from evtms.system.simulate import check_model

    check_model(model, setup.mode, mode_models, refrigerant)
    options = dict(
        dt=dt,
        soak_cabin=None if soak_cabin is None else soak_cabin + 273.15,
        output_every=output_every,
        precondition=precondition,
        model=model,
        mode_models=mode_models,
    )
    if depletion:
        from evtms.system.range_test import run_range_test

        if named:
            typer.echo(
                f"note: --range {range_test} keeps the scenario's conditions, not its cycle {sc.cycle}", err=True
            )
        results = [
            run_range_test(
                range_test, T, refrigerant, setup.params, mode=setup.mode, RH_amb=setup.RH_amb, sun=setup.sun,
                scenario=sc.name, inputs=setup.inputs, **options,
            )[0]
            for T in ambients
        ]  # fmt: skip
    else:
        results = [run_scenario(setup, refrigerant, T, **options) for T in ambients]
    with creating_parents(output):
        write_simulation(results, output)
    wall = time.perf_counter() - t0
    for r in results:
        r.summary["wall_time_s"] = wall
    if json_out:
        print_json(results[0].summary if len(results) == 1 else {"runs": [r.summary for r in results]})
        return
    for r in results:
        s = r.summary
        if "range" in s:
            typer.echo(_range_line(s))
            continue
        typer.echo(
            f"{s['T_amb_degC']:6.1f} degC  {s['distance_km']:.2f} km  battery {s['battery_energy_kWh']:.3f} kWh "
            f"(HVAC {s['hvac_energy_kWh']:.3f})  SOC {s['soc_end']:.4f}  cabin {s['T_cabin_end_degC']:.1f} degC  "
            f"battery {s['T_battery_end_degC']:.1f} degC  loop {s['loop_time_s'] * 1e3:.0f} ms"
        )
    typer.echo(f"wrote {output} ({wall:.2f} s)")


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


def _check_soak(soak_cabin: float | None) -> None:
    """--soak-cabin [degC], when given, within -40 to 90 degC."""
    if soak_cabin is not None and not (math.isfinite(soak_cabin) and -40.0 <= soak_cabin <= 90.0):
        fail(f"--soak-cabin {soak_cabin:g} is not allowed; allowed: -40 to 90 degC")


def _cycle_luts(luts: Path) -> tuple[Path | None, list[Path]]:
    """(folder holding the cycle LUTs of ``luts``, or None to build them in ``luts``; the LUTs and maps
    there: inputs an output may not overwrite).

    ``luts`` may be the folder of the cycle LUTs or the luts/ or output folder of ``evtms demo``
    (:func:`evtms.cycle.api.cycle_luts_folder`). A file, or a folder holding LUTs but no complete set
    of cycle LUTs, is one line, exit 2: nothing is built over LUTs already there.
    """
    from evtms.cycle.api import cycle_luts_folder

    if luts.exists() and not luts.is_dir():
        fail(f"--luts {str(luts)!r} is not a folder; allowed: a folder of cycle LUTs (or one to build them in)")
    try:
        folder = cycle_luts_folder(luts, "cabin+chiller")
    except EvtmsInputError as exc:
        fail(f"--luts: {exc}")
    if folder is None:
        return None, []
    return folder, sorted(folder.glob("*.nc")) + sorted((folder / "maps").glob("*.nc"))


def _mode_models(path: Path):
    """Mode models from a file or a folder holding the trainer's file; anything else is one line, exit 2."""
    from evtms.surrogates.io import MODEL_FILE, load_mode_models

    file = path / MODEL_FILE if path.is_dir() else path
    if not file.is_file():
        fail(
            f"--surrogates {str(path)!r}: no mode-model file; "
            f"train one with 'evtms surrogate train --mode all -o {path}'"
        )
    return load_mode_models(file), file


def _system_refrigerant(luts: Path, folder: Path | None, system, quiet: bool):
    """The cycle maps of the cycle LUTs in ``folder`` (from :func:`_cycle_luts`) for the simulator.

    With ``folder`` None (``luts`` missing or holding no LUTs) the cycle LUTs are built in ``luts``
    first; maps are built where missing (with a bar).
    """
    from evtms.benches.parameters import Parameters
    from evtms.system.refrigerant import load_refrigerant
    from evtms.workflows.demo import ensure_luts

    if folder is None:
        typer.echo(f"note: no cycle LUTs in {luts}/; building them (evtms bench all --grid cycle, 1-2 min)", err=True)
        with creating_parents(luts, folder=True):
            ensure_luts(luts, "cycle", Parameters(), notify=lambda m: typer.echo(f"  {m}", err=True))
        folder = luts
    with _ProgressBar(quiet or not sys.stderr.isatty()) as bar:
        tasks = {}

        def progress(done: int, total: int, text: str) -> None:
            if text not in tasks:
                typer.echo(f"note: building cycle map {text} in {folder}/maps/ (once)", err=True)
                tasks[text] = bar.task(text, total)
            tasks[text](done, total)

        return load_refrigerant(folder, system, progress)
