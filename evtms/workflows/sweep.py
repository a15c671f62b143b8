"""A study of the vehicle's thermal system: ambients x drive cycles x parameter sets (``evtms sweep``).

:func:`run_sweep` takes a :class:`SweepRequest`, checks it in full (the
number of scenarios first, before anything is read or allocated, then every
ambient, cycle, parameter file, option and output path), loads the cycle maps
once per distinct coolant setting, runs every scenario as ``evtms simulate``
would run it alone (:mod:`evtms.system.sweep`: in this process, on local dask
workers or on a cluster) and writes one summary table, a row per scenario
(:mod:`evtms.system.sweep_table`, ``docs/sweep-format.md``), and, when asked,
each run's time series into a folder.

Scenario order: parameter sets (outermost), drive cycles, humidities, sun,
ambient temperatures (innermost), each in the order given.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError, EvtmsInterrupted
from evtms.paths import creating_parents, input_file, output_file, output_folder
from evtms.workflows.common import Notify, Progress, as_text, quiet

__all__ = ["MAX_SCENARIOS", "SweepRequest", "SweepResult", "run_sweep"]

#: Default and largest ``max_scenarios``.
DEFAULT_MAX_SCENARIOS = 10_000
MAX_SCENARIOS = 1_000_000
#: Models a sweep runs (the physics model reuses its solves across runs: a row would depend on its worker).
SWEEP_MODELS = ("lut", "surrogate")
#: Allowed solar irradiance [W/m2] (that of a scenario file).
SUN_RANGE = (0.0, 1500.0)


@dataclass
class SweepRequest:
    """One ``evtms sweep``: the scenario grid, the simulator's options, the runner and the outputs.

    Attributes
    ----------
    output : Path
        Summary table, ``.nc`` (netCDF-4) or ``.csv`` (docs/sweep-format.md).
    cycle : str or sequence of str
        Drive cycles: built-in names, ``parked:SECONDS`` or CSV files; text may list several, comma-separated.
    t_amb : str, float or sequence of float
        Ambients [degC]: ``v1,v2,...``, ``start:stop:count`` or numbers.
    rh_amb : str, float or sequence of float, optional
        Ambient relative humidities [0-1], as ``t_amb`` (default 0.4, as ``evtms simulate``).
    sun : str, float or sequence of float, optional
        Solar irradiance [W/m2], as ``t_amb`` (default 0).
    params : sequence of Path
        Parameter sets: system TOML files, or folders whose ``*.toml`` files each are one (none: the defaults).
    mode, luts, dt, output_every, soak_cabin, precondition, model, surrogates
        As :class:`evtms.workflows.simulate.SimulationRequest` (``model``: ``lut`` or ``surrogate``).
    runs : Path, optional
        Folder for each run's own netCDF file (docs/simulation-format.md); none: not written.
    workers : int, optional
        Local dask worker processes (default: in this process).
    scheduler : str, optional
        A dask.distributed scheduler, ``tcp://host:port``.
    batch : int, optional
        Scenarios per task (default: by the number of scenarios and workers, at most 64).
    max_scenarios : int
        Most scenarios allowed (1 to :data:`MAX_SCENARIOS`).
    """

    output: Path
    cycle: str | Sequence[str] = "wltc3b"
    t_amb: str | float | Sequence[float] = "25"
    rh_amb: str | float | Sequence[float] | None = None
    sun: str | float | Sequence[float] | None = None
    params: Sequence[Path] = ()
    mode: str | None = None
    luts: Path = Path("luts")
    dt: float = 1.0
    output_every: float | None = None
    soak_cabin: float | None = None
    precondition: float = 0.0
    model: str = "lut"
    surrogates: Path = Path("models")
    runs: Path | None = None
    workers: int | None = None
    scheduler: str | None = None
    batch: int | None = None
    max_scenarios: int = DEFAULT_MAX_SCENARIOS


@dataclass
class SweepResult:
    """What :func:`run_sweep` ran and wrote.

    Attributes
    ----------
    table : SweepTable
        The rows (:class:`evtms.system.sweep_table.SweepTable`), as written.
    path : Path
        The summary table written.
    runs : Path or None
        The folder of the runs' files.
    scenarios : int
        Rows.
    failed : int
        Rows whose status is ``error``.
    runner : str
        ``in-process`` or ``dask``; ``workers`` how many computed.
    wall_time_s : float
        Time of the request [s], maps and workers' start included.
    run_time_s : float
        Time of the runs alone [s] (from the first batch sent to the last row back).
    """

    table: Any
    path: Path
    runs: Path | None
    scenarios: int
    failed: int
    runner: str
    workers: int
    wall_time_s: float
    run_time_s: float
    notes: list[str] = field(default_factory=list)

    @property
    def per_run_s(self) -> float:
        """Wall time of the runs per scenario [s]."""
        return self.run_time_s / max(self.scenarios, 1)

    def to_dict(self) -> dict:
        """Plain values for ``--json``: the figures and every row."""
        keys = ("scenarios", "failed", "runner", "workers", "wall_time_s", "run_time_s")
        return {
            "path": str(self.path),
            "runs": None if self.runs is None else str(self.runs),
            **{k: getattr(self, k) for k in keys},
            "per_run_s": self.per_run_s,
            "rows": self.table.rows,
        }


@dataclass
class _Grid:
    """The checked scenario grid: values and labels, before any map work."""

    ambients: list[float]  # [K]
    humidities: list[float | None]
    suns: list[float | None]
    cycles: list[str]  # as given
    params: list[Path | None]

    @property
    def size(self) -> int:
        return len(self.ambients) * len(self.humidities) * len(self.suns) * len(self.cycles) * len(self.params)


def _items(value: str | Sequence[str]) -> list[str]:
    """Text items: a comma-separated list (a path that exists is one item, commas and all)."""
    values = [value] if isinstance(value, str) else list(value)
    out: list[str] = []
    for v in values:
        v = str(v)
        out.extend([v] if Path(v).exists() else [p.strip() for p in v.split(",") if p.strip()])
    return out


def _param_files(params: Sequence[Path]) -> list[Path | None]:
    """The parameter sets: files as given, folders as their ``*.toml`` files in name order (none: the defaults)."""
    out: list[Path | None] = []
    for p in params:
        p = Path(p)
        if p.is_dir():
            found = sorted(p.glob("*.toml"))
            if not found:
                raise EvtmsInputError(f"`params` folder {str(p)!r} holds no .toml file; allowed: TOML files or folders")
            out.extend(found)
        else:
            out.append(input_file(p, "params file"))
    return out or [None]


def _values(name: str, value, label: str, default: float | None) -> list[float | None]:
    """One axis of the grid from text or numbers (``T_amb`` in degC becomes K); ``[default]`` when not given."""
    from evtms.cycle.topology import parse_values

    if value is None:
        return [default]
    if name == "sun":
        return _sun_values(as_text(value), label)
    return parse_values(name, as_text(value), 1000, label)


def _sun_values(text: str, label: str) -> list[float]:
    try:
        parts = [float(v) for v in text.split(":" if ":" in text else ",")]
    except ValueError:
        raise EvtmsInputError(f"{label} {text!r} is not a number, v1,v2,... or start:stop:count") from None
    if ":" in text:
        if len(parts) != 3 or not parts[2].is_integer() or not 1 <= parts[2] <= 1000:
            raise EvtmsInputError(f"{label} {text!r} is not start:stop:count with a count of 1 to 1000")
        step = (parts[1] - parts[0]) / max(parts[2] - 1, 1)
        parts = [float(f"{parts[0] + i * step:.12g}") for i in range(int(parts[2]))]
    lo, hi = SUN_RANGE
    for v in parts:
        if not (math.isfinite(v) and lo <= v <= hi):
            raise EvtmsInputError(f"{label} {v:g} is not allowed; allowed: {lo:g} to {hi:g} W/m2")
    return parts


def _grid(r: SweepRequest) -> _Grid:
    """The grid's axes, its size checked before any file is read or a scenario made."""
    if not 1 <= r.max_scenarios <= MAX_SCENARIOS:
        raise EvtmsInputError(f"`max_scenarios` {r.max_scenarios} is not allowed; allowed: 1 to {MAX_SCENARIOS:,}")
    cycles = _items(r.cycle)
    if not cycles:
        raise EvtmsInputError("`cycle`: no drive cycle given; give NAME, parked:SECONDS or FILE.csv (comma-separated)")
    twice = sorted({c for c in cycles if cycles.count(c) > 1})
    if twice:
        raise EvtmsInputError(f"`cycle` {twice[0]!r} is given twice")
    grid = _Grid(
        ambients=_values("T_amb", r.t_amb, "`t_amb`", None),
        humidities=_values("RH_amb", r.rh_amb, "`rh_amb`", None),
        suns=_values("sun", r.sun, "`sun`", None),
        cycles=cycles,
        params=[None] * max(len(r.params), 1),
    )
    if grid.size > r.max_scenarios:
        raise EvtmsInputError(
            f"{grid.size:,} scenarios ({_shape(grid)}) are more than `max_scenarios` {r.max_scenarios:,}; "
            "give fewer values or raise the limit"
        )
    grid.params = _param_files(r.params)
    if grid.size > r.max_scenarios:  # a folder of parameter files counts each file
        raise EvtmsInputError(
            f"{grid.size:,} scenarios ({_shape(grid)}) are more than `max_scenarios` {r.max_scenarios:,}; "
            "give fewer values or raise the limit"
        )
    return grid


def _shape(g: _Grid) -> str:
    parts = [
        (len(g.params), "parameter sets"),
        (len(g.cycles), "cycles"),
        (len(g.humidities), "humidities"),
        (len(g.suns), "sun values"),
        (len(g.ambients), "ambients"),
    ]
    return " x ".join(f"{n} {what}" for n, what in parts if n > 1) or "1"


def _check_options(r: SweepRequest) -> None:
    from evtms.system.scenarios import SCENARIO_MODES, check_choice
    from evtms.system.sweep import check_runner
    from evtms.workflows.simulate import check_soak

    if r.model not in SWEEP_MODELS:
        why = " (its solves are reused from run to run, so a row would depend on the worker)"
        raise EvtmsInputError(
            f"`model` {r.model!r} is not allowed in a sweep{why if r.model == 'physics' else ''}; "
            f"allowed: {', '.join(SWEEP_MODELS)}"
        )
    if r.mode is not None:
        check_choice("`mode`", r.mode, SCENARIO_MODES)
    check_soak(r.soak_cabin)
    check_runner(r.workers, r.scheduler)
    if r.batch is not None and r.batch < 1:
        raise EvtmsInputError(f"`batch` {r.batch} is not allowed; allowed: 1 or more")


def _setups(r: SweepRequest, grid: _Grid):
    """(setups by (params, cycle), parameter trees, files read): every cycle and parameter file read and checked."""
    import dataclasses

    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.params import load_parameter_tree
    from evtms.system.scenarios import Scenario
    from evtms.system.simulate import check_run_options

    read = {}
    inputs: list[Path] = [p for p in grid.params if p is not None]
    for c in grid.cycles:
        try:
            read[c] = drive_cycle(c)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"`cycle`: {exc}") from None
        if Path(read[c].source).is_file():
            inputs.append(Path(read[c].source))
    trees = [load_parameter_tree(p) for p in grid.params]
    setups = []
    for tree in trees:
        for c in grid.cycles:
            setup = Scenario(name="", cycle=c).setup(tree.system, mode=r.mode)
            setup = dataclasses.replace(setup, cycle=read[c])  # one copy of each trace
            if r.model == "surrogate" and setup.params.hvac.heating != "ptc_air":
                raise EvtmsInputError(
                    f"`model` surrogate: the mode models know the air PTC only, not hvac.heating = "
                    f"{setup.params.hvac.heating!r} ({tree.path}); use `model` lut"
                )
            setups.append(setup)
    for c in grid.cycles:
        check_run_options(read[c], r.dt, r.mode or "auto", r.output_every, r.precondition)
    return setups, trees, inputs


def _refrigerants(r: SweepRequest, trees, lut_folder, notify: Notify, progress: Progress | None):
    """(cycle maps, one per distinct coolant setting; each parameter set's index into them).

    Every parameter file's component tables are checked against the LUTs, also where its maps are
    another set's (loaded once).
    """
    from evtms.cycle import load_cycle_luts
    from evtms.system.refrigerant import map_settings
    from evtms.workflows.common import check_lut_components
    from evtms.workflows.simulate import cycle_luts, system_refrigerant

    maps, settings, which = [], [], []
    folder = lut_folder
    for tree in trees:
        s = map_settings(tree.system)
        if s in settings:
            if tree.given_components():
                check_lut_components(load_cycle_luts(folder, "cabin+chiller"), tree, tree.path, folder)
            which.append(settings.index(s))
            continue
        maps.append(system_refrigerant(r.luts, folder, tree, notify, progress))
        settings.append(s)
        which.append(len(maps) - 1)
        folder = folder or cycle_luts(r.luts)[0]  # built by the first: found now
    return maps, which


def _runs(grid: _Grid, which: list[int]) -> list:
    from evtms.system.sweep import Run

    runs = []
    for p in range(len(grid.params)):
        for c in range(len(grid.cycles)):
            for rh in grid.humidities:
                for sun in grid.suns:
                    for T in grid.ambients:
                        runs.append(Run(p * len(grid.cycles) + c, T, rh, sun, refrigerant=which[p]))
    return runs


def _input_row(index: int, run, setup, label: Path | None, model: str) -> dict:
    return {
        "scenario": index,
        "cycle": setup.scenario.cycle,
        "params": "" if label is None else str(label),
        "T_amb_degC": float(run.T_amb - 273.15),
        "RH_amb": float(setup.RH_amb if run.RH_amb is None else run.RH_amb),
        "sun": float(setup.sun if run.sun is None else run.sun),
        "mode": setup.mode,
        "model": model,
    }


def run_sweep(request: SweepRequest, *, notify: Notify | None = None, progress: Progress | None = None) -> SweepResult:
    """Run every scenario of the request and write its summary table (and the runs' files when asked).

    Parameters
    ----------
    request : SweepRequest
        Checked in full (size first, then ambients, cycles, parameter files, options, LUT folder, mode
        models, output paths) before any map work or simulation; nothing is written on a bad request.
    notify : callable, optional
        ``notify(message)`` for notes (maps being built, runs that failed).
    progress : callable, optional
        ``progress(done, total, label)``: a cycle map's name while maps are built, then ``scenarios``.

    Returns
    -------
    SweepResult

    Raises
    ------
    EvtmsInputError
        Anything the request asks that is not allowed (the message names the request field).
    EvtmsInterrupted
        Ctrl-C: nothing is written (the runs' files written so far are kept).
    """
    from evtms.system.simulate import check_model
    from evtms.system.sweep import make_runner
    from evtms.workflows.simulate import cycle_luts, surrogate_models

    t0 = time.perf_counter()
    notify = notify or quiet
    r = request
    grid = _grid(r)
    _check_options(r)
    setups, trees, inputs = _setups(r, grid)
    lut_folder, lut_files = cycle_luts(r.luts)
    inputs += lut_files
    mode_models = None
    if r.model == "surrogate":
        mode_models, surrogate_file = surrogate_models(r.surrogates)
        inputs.append(surrogate_file)
    output_file(r.output, inputs, (".nc", ".csv"))
    if r.runs is not None:
        output_folder(r.runs, inputs + [r.output])
    maps, which = _refrigerants(r, trees, lut_folder, notify, progress)
    for m in maps:
        check_model(r.model, r.mode or "auto", mode_models, m)
    context = _context(r, grid, setups, maps, which, mode_models)
    runner = make_runner(r.workers, r.scheduler)
    try:
        table, run_time = _execute(r, grid, context, runner, progress)
    except KeyboardInterrupt:
        raise EvtmsInterrupted(f"interrupted: no summary table written to {str(r.output)!r}") from None
    finally:
        runner.close()
    rows = table.rows
    failed = sum(1 for row in rows if row["status"] == "error")
    if failed:
        first = next(row for row in rows if row["status"] == "error")
        notify(f"{failed} of {len(rows)} scenarios failed (status error); the first: {first['message']}")
    return SweepResult(
        table, Path(r.output), r.runs, len(rows), failed, runner.name, runner.workers,
        time.perf_counter() - t0, run_time,
    )  # fmt: skip


def _context(r: SweepRequest, grid: _Grid, setups, maps, which, mode_models):
    """The engine's context: the setups, maps and runs of the grid, a row per run (and its file in ``runs``)."""
    from evtms.system.sweep import SweepContext
    from evtms.system.sweep_table import SweepRows, failed_figures

    runs = _runs(grid, which)
    options = dict(dt=r.dt, output_every=r.output_every, precondition=r.precondition, model=r.model)
    if r.soak_cabin is not None:
        options["soak_cabin"] = r.soak_cabin + 273.15
    context = SweepContext(setups, maps, runs, None, options, mode_models, failed_figures)
    context.reduce = SweepRows(len(runs), None if r.runs is None else str(r.runs), context.token)
    return context


def _execute(r: SweepRequest, grid: _Grid, context, runner, progress: Progress | None):
    """(the table written, the runs' time [s]): every run on ``runner``, then the table, atomically."""
    from evtms.system.sweep import run_batches
    from evtms.system.sweep_table import RUNS_MARKER, SweepTable, write_table

    with creating_parents(r.output), _run_folder(r.runs, context.token, RUNS_MARKER):
        if progress is not None:
            progress(0, len(context.runs), "scenarios")
        t0 = time.perf_counter()
        figures = run_batches(context, runner, size=r.batch, progress=None if progress is None else _label(progress))
        run_time = time.perf_counter() - t0
        table = SweepTable(_rows(context, grid, figures, r), _attrs(r, runner, run_time))
        write_table(table, r.output)
    return table, run_time


def _label(progress: Progress):
    return lambda done, total: progress(done, total, "scenarios")


def _rows(context, grid: _Grid, figures: list[dict], r: SweepRequest) -> list[dict]:
    """The table's rows: each scenario's inputs and its figures (run files that came back written)."""
    from evtms.system.sweep_table import write_run_bytes

    rows = []
    for i, (run, fig) in enumerate(zip(context.runs, figures, strict=True)):
        data = fig.pop("run_bytes", None)
        if data is not None:
            write_run_bytes(r.runs, fig["run_file"], data)
        label = grid.params[run.setup // len(grid.cycles)]
        rows.append(_input_row(i, run, context.setups[run.setup], label, r.model) | fig)
    return rows


def _attrs(r: SweepRequest, runner, run_time: float) -> dict:
    return {
        "luts": str(r.luts),
        "dt": float(r.dt),
        "output_every": float(r.output_every) if r.output_every is not None else float(max(1.0, r.dt)),
        "precondition": float(r.precondition),
        "soak_cabin_degC": float(r.soak_cabin) if r.soak_cabin is not None else math.nan,
        "runner": runner.name,
        "workers": int(runner.workers),
        "run_time_s": float(run_time),
    }


@contextlib.contextmanager
def _run_folder(folder: Path | None, token: str, marker: str) -> Iterator[None]:
    """The run folder (created if missing) holding the sweep's marker file for the block; none: nothing."""
    if folder is None:
        yield
        return
    with creating_parents(folder, folder=True):
        (Path(folder) / marker).write_text(token)
        try:
            yield
        finally:
            (Path(folder) / marker).unlink(missing_ok=True)
