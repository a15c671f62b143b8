"""The vehicle's thermal system over a drive cycle, a scenario or a range test (``evtms simulate``).

:func:`run_simulation` takes a :class:`SimulationRequest` (the command's
options, in its units: degC for temperatures, the ambient as text or numbers),
checks it in full before any map or simulation work, builds the cycle LUTs
and maps where missing, runs the simulator at every ambient and writes the
time series. The helpers the other workflows share (:func:`cycle_luts`,
:func:`system_refrigerant`, :func:`surrogate_models`, :func:`trace_files`,
:func:`check_soak`) live here too.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file
from evtms.workflows.common import Notify, Progress, as_text, check_lut_components, params_input, quiet

__all__ = ["SimulationRequest", "SimulationRun", "run_simulation"]

#: A request's choice of cycle or scenario, when it gives neither or both.
_ONE_OF = "give `cycle` NAME|FILE.csv or `scenario` NAME / `scenario_file` FILE.toml (one of them)"


@dataclass
class SimulationRequest:
    """One ``evtms simulate`` run: a cycle or a scenario, the ambients, the model and its options.

    Attributes
    ----------
    output : Path, optional
        The netCDF file (docs/simulation-format.md); none: not written.
    cycle : str, optional
        Drive cycle: ``wltc3b``, ``nedc``, ``udds``, ``hwfet``, ``parked:SECONDS`` or a CSV file.
    scenario : str, optional
        Named scenario, built in or from ``scenario_file``.
    scenario_file : Path, optional
        TOML scenario file (docs/scenario-format.md).
    t_amb : str, float or sequence of float, optional
        Ambient [degC]: one value, several, or text ``v1,v2,...`` / ``start:stop:count`` (default: the
        scenario's).
    mode : str, optional
        ``auto`` or a forced mode (default: the scenario's, or auto).
    params : Path, optional
        System TOML ([vehicle] [battery] [cabin] ...).
    luts : Path
        Cycle LUT folder (or ``evtms demo``'s luts/ or output folder); built there if missing or empty.
    dt : float
        Time step [s], 0.001 to 60.
    output_every : float, optional
        Record spacing [s], a multiple of ``dt`` (default max(1, dt)).
    soak_cabin : float, optional
        Initial cabin air, walls and interior [degC].
    precondition : float
        Seconds of HVAC parked and plugged in before the cycle.
    model : str
        ``lut``, ``physics`` or ``surrogate``.
    surrogates : Path
        Mode-model file or folder (``evtms surrogate train -o``), for the surrogate model.
    range_test : str
        ``single``, ``mct`` (SAE J1634) or ``ccp`` (UN GTR 15).
    inputs : mapping of str to str or float
        External inputs by name (:data:`evtms.system.inputs.INPUT_NAMES`): numbers (degC for temperatures)
        or ``FILE.csv:column`` traces.
    heating : str or sequence of str, optional
        Cabin heating (``ptc_air``, ``ptc_coolant``, ``heat_pump``): one, several, or text ``a,b``; each
        runs at every ambient, side by side in the file (default: the parameters' or the scenario's).
    controller : str
        Who sets the cabin's vent-air target and blower: ``rules`` (the climate control's own loop) or ``mpc``
        (:class:`evtms.system.mpc.CabinMpc` above the same local loops and relays).
    horizon, control_step : float
        The MPC's horizon and step [s].
    preview : str
        The MPC's preview of the speed trace: ``perfect``, ``none`` or ``noisy``.
    """

    output: Path | None = None
    cycle: str | None = None
    scenario: str | None = None
    scenario_file: Path | None = None
    t_amb: str | float | Sequence[float] | None = None
    mode: str | None = None
    params: Path | None = None
    luts: Path = Path("luts")
    dt: float = 1.0
    output_every: float | None = None
    soak_cabin: float | None = None
    precondition: float = 0.0
    model: str = "lut"
    surrogates: Path = Path("models")
    range_test: str = "single"
    inputs: Mapping[str, str | float | None] = field(default_factory=dict)
    heating: str | Sequence[str] | None = None
    controller: str = "rules"
    horizon: float = 180.0
    control_step: float = 10.0
    preview: str = "perfect"


@dataclass
class SimulationRun:
    """What :func:`run_simulation` ran and wrote.

    Attributes
    ----------
    results : list of SimulationResult
        One run per heating option and ambient, ambients varying fastest
        (:class:`evtms.system.simulate.SimulationResult`); their summaries carry
        ``wall_time_s``, the time of the whole request.
    path : Path or None
        The file written.
    wall_time_s : float
        Time of the request [s], maps and LUTs included.
    """

    results: list[Any]
    path: Path | None
    wall_time_s: float

    def dataset(self):
        """The runs as the output file holds them (:func:`evtms.system.output.to_dataset`)."""
        from evtms.system.output import to_dataset

        return to_dataset(self.results)


def check_soak(soak_cabin: float | None) -> None:
    """``soak_cabin`` [degC], when given, within -40 to 90 degC."""
    if soak_cabin is not None and not (math.isfinite(soak_cabin) and -40.0 <= soak_cabin <= 90.0):
        raise EvtmsInputError(f"`soak_cabin` {soak_cabin:g} is not allowed; allowed: -40 to 90 degC")


def trace_files(inputs: dict) -> list[Path]:
    """The files the trace inputs among ``inputs`` read."""
    from evtms.system.inputs import Trace

    return [Path(v.source.rpartition(":")[0]) for v in inputs.values() if isinstance(v, Trace)]


def cycle_luts(luts: Path) -> tuple[Path | None, list[Path]]:
    """(folder holding the cycle LUTs of ``luts``, or None to build them in ``luts``; the LUTs and maps
    there: inputs an output may not overwrite).

    ``luts`` may be the folder of the cycle LUTs or the luts/ or output folder of ``evtms demo``
    (:func:`evtms.cycle.api.cycle_luts_folder`). A file, or a folder holding LUTs but no complete set
    of cycle LUTs, is refused: nothing is built over LUTs already there.
    """
    from evtms.cycle.api import cycle_luts_folder
    from evtms.luts.store import LutStore

    luts = Path(luts)
    if luts.exists() and not luts.is_dir():
        raise EvtmsInputError(
            f"`luts` {str(luts)!r} is not a folder; allowed: a folder of cycle LUTs (or one to build them in)"
        )
    try:
        folder = cycle_luts_folder(luts, "cabin+chiller")
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"`luts`: {exc}") from None
    if folder is None:
        return None, []
    return folder, LutStore(folder).files()


def surrogate_models(path: Path):
    """(mode models, their file) from a file or a folder holding the trainer's file."""
    from evtms.surrogates.io import MODEL_FILE, load_mode_models

    path = Path(path)
    file = path / MODEL_FILE if path.is_dir() else path
    if not file.is_file():
        raise EvtmsInputError(
            f"`surrogates` {str(path)!r}: no mode-model file; "
            f"train one with 'evtms surrogate train --mode all -o {path}'"
        )
    return load_mode_models(file), file


def system_refrigerant(
    luts: Path, folder: Path | None, tree, notify: Notify | None = None, progress: Progress | None = None
):
    """The cycle maps of the cycle LUTs in ``folder`` (from :func:`cycle_luts`) for the simulator.

    ``tree`` is the run's :class:`~evtms.system.params.ParameterTree`. With
    ``folder`` None (``luts`` missing or holding no LUTs) the cycle LUTs are
    built in ``luts`` first, with the tree's component parameters; LUTs found
    are refused if a component table the parameter file gives contradicts
    them. Maps are built where missing, each announced by ``notify`` and
    reported to ``progress`` under its name.
    """
    from evtms.cycle import load_cycle_luts
    from evtms.luts.store import LutStore
    from evtms.system.refrigerant import load_refrigerant
    from evtms.workflows.demo import ensure_luts

    notify = notify or quiet
    luts = Path(luts)
    if folder is None:
        notify(f"no cycle LUTs in {luts}/; building them as 'evtms bench all --grid cycle' does (1-2 min)")
        with creating_parents(luts, folder=True):
            ensure_luts(luts, "cycle", tree.components, notify=lambda m: notify(f"  {m}"))
        folder = luts
    elif tree.given_components():
        check_lut_components(load_cycle_luts(folder, "cabin+chiller"), tree, tree.path, folder)
    announced = set()

    def maps(done: int, total: int, name: str) -> None:
        if name not in announced:
            announced.add(name)
            notify(f"building cycle map {name} in {LutStore(folder).maps_folder}/ (once)")
        if progress is not None:
            progress(done, total, name)

    return load_refrigerant(folder, tree.system, maps)


def _option_inputs(values: Mapping[str, str | float | None]) -> dict:
    """The inputs given (numbers in degC for temperatures, or FILE.csv:column), checked, SI."""
    from evtms.system.inputs import FIELD_LABELS, check_inputs

    raw: dict[str, object] = {}
    for name, value in values.items():
        if value is None:
            continue
        try:
            raw[name] = float(value)
        except ValueError:
            raw[name] = value
    return check_inputs(raw, celsius=True, labels=FIELD_LABELS)


def _scenario_choice(name: str | None, file: Path | None):
    """The scenario ``name`` (built in, or in ``file``) or the only one of ``file``."""
    from evtms.system.scenarios import SCENARIOS, read_scenario_file

    from_file = read_scenario_file(input_file(file, "scenario file")) if file is not None else {}
    if name is None:
        if len(from_file) != 1:
            raise EvtmsInputError(
                f"`scenario_file` {str(file)!r} holds {len(from_file)} scenarios ({', '.join(from_file)}); "
                "give `scenario` NAME"
            )
        return next(iter(from_file.values()))
    available = {**SCENARIOS, **from_file}
    if name not in available:
        where = f"allowed: {', '.join(from_file)} (in {file}) or the built-in " if from_file else "allowed: "
        raise EvtmsInputError(f"`scenario` {name!r} is unknown; {where}{', '.join(SCENARIOS)}")
    return available[name]


def _check_choice(request: SimulationRequest) -> tuple[bool, bool]:
    """(a range test, a named scenario): the request's choice of run, model and mode checked."""
    from evtms.system.range_test import RANGE_TESTS
    from evtms.system.scenarios import SCENARIO_MODES, check_choice
    from evtms.system.simulate import MODELS

    test, cycle = request.range_test, request.cycle
    if test not in RANGE_TESTS:
        raise EvtmsInputError(f"`range_test` {test!r} is unknown; allowed: {', '.join(RANGE_TESTS)}")
    depletion = test != "single"
    named = request.scenario is not None or request.scenario_file is not None
    if depletion:
        if cycle is not None and not (test == "ccp" and cycle == "wltc3b"):
            own = "UDDS, HWFET and 65 mph phases" if test == "mct" else "WLTC 3b back to back"
            raise EvtmsInputError(f"`range_test` {test} drives its own cycles ({own}); leave out `cycle` {cycle}")
        if cycle is not None and named:
            raise EvtmsInputError(_ONE_OF)
    elif (cycle is None) == (not named):
        raise EvtmsInputError(_ONE_OF)
    if request.model not in MODELS:
        raise EvtmsInputError(f"`model` {request.model!r} is unknown; allowed: {', '.join(MODELS)}")
    if request.mode is not None:
        check_choice("`mode`", request.mode, SCENARIO_MODES)
    check_soak(request.soak_cabin)
    return depletion, named


def heating_options(heating: str | Sequence[str] | None) -> list[str] | None:
    """The heating options a request names (text ``a,b`` or a sequence), checked; None: none named."""
    from evtms.system.params import HEATING
    from evtms.system.scenarios import check_choice

    if heating is None:
        return None
    names = [h.strip() for h in heating.split(",")] if isinstance(heating, str) else [str(h) for h in heating]
    if not names or len(set(names)) != len(names):
        raise EvtmsInputError(
            f"`heating` {heating!r}: give one or more different options; allowed: {', '.join(HEATING)}"
        )
    for name in names:
        check_choice("`heating`", name, HEATING)
    return names


def _plan(request: SimulationRequest, depletion: bool, named: bool):
    """(scenario, its setup, system parameters, ambients [K], files read): checked before any map work."""
    from evtms.cycle.topology import parse_values
    from evtms.system.params import load_parameter_tree
    from evtms.system.scenarios import Scenario, apply_heating
    from evtms.system.simulate import check_run_options

    r = request
    sc = _scenario_choice(r.scenario, r.scenario_file) if named else Scenario(name="", cycle=r.cycle or "wltc3b")
    if r.t_amb is None and sc.T_amb is None:
        raise EvtmsInputError("give `t_amb` DEGC (this cycle or scenario has no ambient of its own)")
    ambients = parse_values("T_amb", as_text(r.t_amb), 1000, "`t_amb`") if r.t_amb is not None else [sc.T_amb]
    inputs = params_input(r.params)
    if r.scenario_file is not None:
        inputs.append(r.scenario_file)
    tree = load_parameter_tree(r.params)
    setup = sc.setup(tree.system, mode=r.mode, inputs=_option_inputs(r.inputs))
    heatings = heating_options(r.heating) or [setup.params.hvac.heating]
    if r.mode == "ch-hp" and heatings != ["heat_pump"]:
        raise EvtmsInputError(
            f"`heating` {r.heating!r}: the mode ch-hp heats with the heat pump; leave out `heating` or give heat_pump"
        )
    if depletion:
        from evtms.system.range_test import ccp_sequence, mct_sequence

        trace = mct_sequence(0.0, 1).cycle if r.range_test == "mct" else ccp_sequence(1).cycle  # the options' checks
    else:
        trace = setup.cycle
    check_run_options(trace, r.dt, setup.mode, r.output_every, r.precondition)
    if not depletion and Path(trace.source).is_file():
        inputs.append(Path(trace.source))
    setups = [dataclasses.replace(setup, params=apply_heating(setup.params, h), heating=h) for h in heatings]
    # The maps the runs need: the heat pump's only where one of them heats with it.
    maps_for = next((s.params for s in setups if s.params.hvac.heating == "heat_pump"), setup.params)
    tree = dataclasses.replace(tree, system=maps_for)
    return sc, setups, tree, ambients, inputs + trace_files(setup.inputs)


def run_simulation(
    request: SimulationRequest, *, notify: Notify | None = None, progress: Progress | None = None
) -> SimulationRun:
    """Simulate the request at each of its ambients and write the runs to ``request.output``.

    Parameters
    ----------
    request : SimulationRequest
        The run; checked in full (choice of cycle or scenario, model, mode, ambients, inputs, step
        options, LUT folder, mode models, output path) before any map or simulation work.
    notify : callable, optional
        ``notify(message)`` for notes (LUTs or maps being built; a range test that keeps only a
        scenario's conditions).
    progress : callable, optional
        ``progress(done, total, map_name)`` while cycle maps are built.

    Returns
    -------
    SimulationRun

    Raises
    ------
    EvtmsInputError
        Anything the request asks that is not allowed (the message names the request field).
    """
    from evtms.luts.validate import headers_read_once

    with headers_read_once():  # the LUTs' headers are asked for several times before any work
        return _run_simulation(request, notify or quiet, progress)


def _controller(request: SimulationRequest, depletion: bool):
    """The run's supervisory controller (None: the rules), checked before any work."""
    from evtms.system.controllers import check_period
    from evtms.system.mpc import MpcOptions, make_controller

    if request.controller == "rules":
        return make_controller("rules")
    if depletion:
        raise EvtmsInputError(
            f"controller {request.controller!r} runs single cycles; allowed with `range_test` mct or ccp: rules"
        )
    # The set points it writes, and the ones its model takes from the plant (the evaporator's and the heater
    # loop's targets follow its vent target; the inlet air is the recirculated mix).
    taken = ("SP_vent", "blower", "BC_request", "SP_evap", "SP_CoHX", "hvac_inlet_T", "hvac_inlet_rh")
    given = sorted(k for k in taken if request.inputs.get(k) is not None)
    if given:
        raise EvtmsInputError(
            f"input {', '.join(given)} with controller {request.controller!r}: the controller sets the cabin's "
            "targets and its model the inlet air; allowed: leave them out, or controller rules"
        )
    options = MpcOptions(horizon=request.horizon, step=request.control_step, preview=request.preview)
    check_period(options.step, request.dt)
    return make_controller(request.controller, options)


def _run_simulation(request: SimulationRequest, notify: Notify, progress: Progress | None) -> SimulationRun:
    t0 = time.perf_counter()
    from evtms.system.output import write_simulation
    from evtms.system.scenarios import run_scenario
    from evtms.system.simulate import check_model
    from evtms.system.vehicle import check_deviation

    depletion, named = _check_choice(request)
    controller = _controller(request, depletion)
    sc, setups, tree, ambients, inputs = _plan(request, depletion, named)
    for setup in setups:  # the drive's inputs against the vehicle's bound, before the maps are built
        if "speed_deviation" in setup.inputs:
            check_deviation(setup.inputs["speed_deviation"], setup.params.vehicle.delta_v_ref)
    lut_folder, lut_files = cycle_luts(request.luts)
    inputs += lut_files
    mode_models = None
    if request.model == "surrogate":
        mode_models, surrogate_file = surrogate_models(request.surrogates)
        inputs.append(surrogate_file)
    if request.output is not None:
        output_file(request.output, inputs, (".nc",))
    refrigerant = system_refrigerant(request.luts, lut_folder, tree, notify, progress)
    for setup in setups:
        check_model(request.model, setup.mode, mode_models, refrigerant)
    options = dict(
        dt=request.dt,
        soak_cabin=None if request.soak_cabin is None else request.soak_cabin + 273.15,
        output_every=request.output_every,
        precondition=request.precondition,
        model=request.model,
        mode_models=mode_models,
    )
    if controller is not None:
        options["controller"] = controller
    if depletion:
        from evtms.system.range_test import run_range_test

        test = request.range_test
        if named:
            notify(f"`range_test` {test} keeps the scenario's conditions, not its cycle {sc.cycle}")
        results = [
            run_range_test(
                test, T, refrigerant, setup.params, mode=setup.mode, RH_amb=setup.RH_amb, sun=setup.sun,
                scenario=sc.name, inputs=setup.inputs, **options,
            )[0]
            for setup in setups
            for T in ambients
        ]  # fmt: skip
    else:
        results = [run_scenario(setup, refrigerant, T, **options) for setup in setups for T in ambients]
    if request.output is not None:
        with creating_parents(request.output):
            write_simulation(results, request.output)
    wall = time.perf_counter() - t0
    for r in results:
        r.summary["wall_time_s"] = wall
    return SimulationRun(results, request.output, wall)
