"""Comparison of the modelling approaches (physics, lut, surrogate): accuracy, speed and step size.

:func:`run_compare` runs every approach of :func:`evtms.system.simulate.simulate`
(``model=`` ``physics``, ``lut``, ``surrogate``) on every scenario (drive
cycle x ambient) and collects:

- the **comparison table** (:class:`~evtms.reports.compare.CompareRow`, one
  per approach and scenario at the comparison step ``dt``): wall time per
  simulation, loop time, speed-up over physics, battery and HVAC energy and
  their deviation from physics, and the RMSE and largest absolute error of
  ``T_cabin``, ``T_battery``, ``SOC`` and ``P_hvac`` against the reference on
  aligned record times (:func:`trajectory_errors`). The reference is the
  physics run, or, for the variables a measured file holds
  (:func:`read_measured`), the measurement;
- the **trajectories** of those four variables per scenario, one line per
  approach (drawn by :func:`evtms.reports.compare.trajectory_figure`);
- the **step-size study** (:class:`~evtms.reports.compare.StepRow`): every
  approach at every step of ``dts`` (physics only at ``physics_dts``, by
  default the steps of 1 s and more: a physics run takes minutes); for each
  run whether it stayed finite and within physical bounds and how far its
  summary figures moved from the approach's finest sound step
  (:func:`assess_steps`), and the largest stable step per approach
  (:func:`largest_stable`), as the source thesis's tables 5-6 and 12.

:func:`evtms.reports.compare.write_compare` writes the result. Library code:
nothing is printed; progress goes to a callback ``progress(done, total, message)``.
:func:`run_comparison` is ``evtms report compare``: a :class:`CompareRequest`
checked in full, then the comparison or the Table 12 scenarios written.

Timing: the fast approaches (lut, surrogate) run ``repeat`` times per
scenario and their times are the medians (the first call of a session
includes numba's compilation); physics runs once, because its solves are
memoised on the ``refrigerant`` object and a repeat would time the memo. Its
wall time therefore depends on what earlier runs (other scenarios, earlier
steps) already solved; the table reports ``physics_solves`` beside it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.paths import csv_rows, input_file, output_folder, read_small_text
from evtms.reports.compare import (
    APPROACHES,
    COMPARED,
    INTERVAL_MEANS,
    CompareResult,
    CompareRow,
    Run,
    StepRow,
    StepTolerance,
    scenario_label,
)
from evtms.system import loop as L  # noqa: N812 - flag bits L.F_*
from evtms.system.drive_cycles import DriveCycle

#: Columns a measured CSV may hold (``time`` required, the others any non-empty subset).
MEASURED_VARIABLES = ("time", *COMPARED)
#: Summary figures the step-size study follows.
STEP_FIGURES = ("battery_energy_kWh", "hvac_energy_kWh", "soc_end", "T_cabin_end_degC", "T_battery_end_degC")
#: Default steps of the study [s].
DEFAULT_DTS = (0.01, 0.1, 1.0, 10.0)
#: Largest measured file read [bytes] and most rows.
MAX_MEASURED_BYTES = 200 * 1024 * 1024
MAX_MEASURED_ROWS = 2_000_000
#: Plausible range of a measured temperature [K] (a value in degC is refused) and of the SOC [1].
MEASURED_T_RANGE = (150.0, 450.0)
#: Two record times closer than this are the same time [s].
TIME_TOL = 1e-6
_FIGURE_NAMES = {
    "d_battery_energy_pct": "battery energy",
    "d_hvac_energy_pct": "HVAC energy",
    "d_soc_end_pct": "SOC end",
    "d_T_cabin_end_K": "cabin end temperature",
    "d_T_battery_end_K": "battery end temperature",
}
_FLAG_OOR = getattr(L, "F_SURROGATE_OOR", 4)
_FLAG_FALLBACK = getattr(L, "F_PHYSICS_FALLBACK", 64)

Progress = Callable[[int, int, str], None]
Simulator = Callable[..., Any]


# ---------------------------------------------------------------------------------------------- measured data


def _fail(where: str, rule: str) -> EvtmsInputError:
    return EvtmsInputError(f"{where}: {rule}")


def read_measured(path: str | Path) -> dict[str, np.ndarray]:
    """Read and check a measured trajectory (the reference of :func:`run_compare` where given).

    Format: CSV, ``#`` comment lines and blank lines skipped, a header of
    column names among :data:`MEASURED_VARIABLES` (the simulation file's
    variable names, each at most once, ``time`` and at least one other), then
    one row of numbers per sample in the simulation file's units: ``time``
    [s] starting at 0 and strictly increasing, ``T_cabin`` and ``T_battery``
    [K] (within 150-450 K, so a column in degC is refused), ``SOC`` [1]
    within 0-1, ``P_hvac`` [W]; every value finite.

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    dict of str to numpy.ndarray
        Column name -> values (float64), ``time`` included.

    Raises
    ------
    EvtmsInputError
        One line naming the file, the line and the rule broken: not a readable
        regular file, too large, not UTF-8, an unknown or repeated column, no
        ``time`` or no variable, a row of the wrong length or not numbers, a
        value that is not finite, a time that does not start at 0 or does not
        increase, a temperature or SOC out of range, no rows.
    """
    path = Path(path)
    where = str(path)
    text = read_small_text(
        path,
        "measured file",
        MAX_MEASURED_BYTES,
        "a CSV file of measured values",
        "a CSV file with a header such as time,T_cabin,SOC",
        encoding="utf-8-sig",
    )
    allowed = ", ".join(MEASURED_VARIABLES)
    header: list[str] | None = None
    rows: list[list[float]] = []
    for number, line, cells in csv_rows(text):
        here = f"{where}:{number}"
        if header is None:
            unknown = [c for c in cells if c not in MEASURED_VARIABLES]
            if unknown:
                raise _fail(here, f"column {unknown[0]!r} is not allowed; allowed: {allowed} (units s, K, K, 1, W)")
            repeated = sorted({c for c in cells if cells.count(c) > 1})
            if repeated:
                raise _fail(here, f"column {repeated[0]!r} appears twice")
            if "time" not in cells:
                raise _fail(here, f"no 'time' column; the header names time [s] and any of {allowed[6:]}")
            if len(cells) < 2:
                raise _fail(here, f"only 'time'; name at least one of {allowed[6:]}")
            header = cells
            continue
        if len(cells) != len(header):
            raise _fail(here, f"{len(cells)} values in {line[:80]!r}; expected {len(header)} ({','.join(header)})")
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise _fail(here, f"{line[:80]!r} is not {len(header)} numbers") from None
        for name, v in zip(header, values, strict=True):
            if not math.isfinite(v):
                raise _fail(here, f"{name} {v} is not finite; every value must be a finite number")
            if name in ("T_cabin", "T_battery") and not MEASURED_T_RANGE[0] <= v <= MEASURED_T_RANGE[1]:
                lo, hi = MEASURED_T_RANGE
                raise _fail(here, f"{name} {v:g} K is not allowed; allowed: {lo:g} to {hi:g} K (temperatures in K)")
            if name == "SOC" and not 0.0 <= v <= 1.0:
                raise _fail(here, f"SOC {v:g} is not allowed; allowed: 0 to 1 (a fraction, not %)")
        t = values[header.index("time")]
        if not rows and t != 0.0:
            raise _fail(here, f"the first time is {t:g} s; measured times start at 0")
        if rows and t <= rows[-1][header.index("time")]:
            raise _fail(here, f"time {t:g} s does not increase (previous {rows[-1][header.index('time')]:g} s)")
        rows.append(values)
        if len(rows) > MAX_MEASURED_ROWS:
            raise _fail(here, f"more than {MAX_MEASURED_ROWS:,} rows")
    if header is None:
        raise _fail(where, f"empty; a measured file has a header ({allowed}) and rows")
    if not rows:
        raise _fail(where, "a header and no rows; give at least one sample")
    data = np.array(rows, dtype=float)
    return {name: np.ascontiguousarray(data[:, i]) for i, name in enumerate(header)}


# ---------------------------------------------------------------------------------------------- errors


def align(
    ref_time: np.ndarray, ref_values: np.ndarray, time: np.ndarray, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A trajectory on the reference's record times.

    Reference records that are not finite (the first record of an interval
    mean) or lie outside the candidate's time span are left out; the
    candidate's leading non-finite records are no data (an interval mean's
    first record) and shorten its span. Where a reference time is a candidate
    record time (within :data:`TIME_TOL`) its value is taken as it is, else it
    is interpolated linearly between the two neighbouring records; a NaN the
    candidate holds later (a run that blew up) stays NaN.

    Parameters
    ----------
    ref_time, ref_values : numpy.ndarray
        Reference record times [s] (increasing) and values.
    time, values : numpy.ndarray
        Candidate record times [s] (increasing) and values.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Aligned times [s], reference values, candidate values.
    """
    ref_time, ref_values = np.asarray(ref_time, float), np.asarray(ref_values, float)
    time, values = np.asarray(time, float), np.asarray(values, float)
    finite = np.isfinite(values)
    if not finite.any():
        start = time.size  # nothing finite: compare against NaN over the whole span
        ct, cv = time, values
    else:
        start = int(np.argmax(finite))
        ct, cv = time[start:], values[start:]
    empty = np.zeros(0)
    if ct.size == 0:
        return empty, empty, empty
    inside = np.isfinite(ref_values) & (ref_time >= ct[0] - TIME_TOL) & (ref_time <= ct[-1] + TIME_TOL)
    t, r = ref_time[inside], ref_values[inside]
    j = np.clip(np.searchsorted(ct, t, side="right") - 1, 0, ct.size - 1)
    j1 = np.minimum(j + 1, ct.size - 1)
    at_j = np.abs(ct[j] - t) <= TIME_TOL
    at_j1 = np.abs(ct[j1] - t) <= TIME_TOL
    span = np.where(j1 > j, ct[j1] - ct[j], 1.0)
    w = np.clip((t - ct[j]) / span, 0.0, 1.0)
    with np.errstate(invalid="ignore"):
        c = np.where(at_j, cv[j], np.where(at_j1, cv[j1], cv[j] * (1.0 - w) + cv[j1] * w))
    if start == time.size:
        c = np.full_like(t, np.nan)
    return t, r, c


@dataclass(frozen=True)
class ErrorStat:
    """Error of one variable against its reference on aligned records.

    Attributes
    ----------
    rmse, max_abs : float
        Root mean square and largest absolute difference [variable units];
        NaN when the candidate is not finite somewhere or nothing aligns.
    n : int
        Records compared.
    """

    rmse: float
    max_abs: float
    n: int


def trajectory_errors(
    reference: Mapping[str, np.ndarray], candidate: Mapping[str, np.ndarray], variables: Sequence[str] = tuple(COMPARED)
) -> dict[str, ErrorStat]:
    """RMSE and largest error of each variable of ``candidate`` against ``reference`` (:func:`align`).

    Parameters
    ----------
    reference, candidate : mapping of str to numpy.ndarray
        Records with ``time`` [s]; a variable missing from either is skipped.
    variables : sequence of str
        Variables to compare.

    Returns
    -------
    dict of str to ErrorStat
    """
    out = {}
    for name in variables:
        if name not in reference or name not in candidate:
            continue
        _, r, c = align(reference["time"], reference[name], candidate["time"], candidate[name])
        if r.size == 0:
            out[name] = ErrorStat(math.nan, math.nan, 0)
            continue
        d = c - r
        if not np.all(np.isfinite(d)):
            out[name] = ErrorStat(math.nan, math.nan, int(r.size))
            continue
        out[name] = ErrorStat(float(np.sqrt(np.mean(d * d))), float(np.max(np.abs(d))), int(r.size))
    return out


# ---------------------------------------------------------------------------------------------- runs


def _default_simulator(
    cycle: DriveCycle, T_amb: float, refrigerant, params, *, dt: float, model: str, mode_models=None, **options
):
    """:func:`evtms.system.simulate.simulate` with the approach as ``model``."""
    from evtms.system.simulate import simulate

    return simulate(cycle, T_amb, refrigerant, params, dt=dt, model=model, mode_models=mode_models, **options)


def _reduce(approach: str, cycle: str, T_amb: float, dt: float, results: list) -> Run:
    """A :class:`Run` from one or more results of the same simulation (times: the medians)."""
    first = results[0]
    records = {"time": np.asarray(first.records["time"], float)}
    for name in COMPARED:
        if name in first.records:
            records[name] = np.asarray(first.records[name], float)
    summary = dict(first.summary)
    for key in ("wall_time_s", "loop_time_s"):
        values = [float(r.summary[key]) for r in results if r.summary.get(key) is not None]
        if values:
            summary[key] = float(np.median(values))
    flags = np.asarray(first.flags)[1:].astype(np.int64)
    oor = float(np.mean((flags & _FLAG_OOR) != 0)) if flags.size else 0.0
    fallback = float(np.mean((flags & _FLAG_FALLBACK) != 0)) if flags.size else 0.0
    return Run(approach, cycle, T_amb, dt, records, summary, oor, fallback)


def _label_error(approach: str, cycle: str, T_amb: float, dt: float, exc: Exception) -> EvtmsInputError:
    where = f"{approach} on {scenario_label(cycle, T_amb)} at dt {dt:g} s"
    if isinstance(exc, NotImplementedError):
        return EvtmsInputError(f"approach {approach!r} is not available ({where}: {exc}); leave it out of `approaches`")
    return EvtmsInputError(f"{where}: {exc}")


def run_compare(
    cycles: Sequence[DriveCycle],
    t_ambs_K: Sequence[float],
    refrigerant,
    *,
    params=None,
    approaches: Sequence[str] = APPROACHES,
    mode_models=None,
    dts: Sequence[float] = DEFAULT_DTS,
    physics_dts: Sequence[float] | None = None,
    dt: float = 1.0,
    measured: Mapping[str, np.ndarray] | None = None,
    measured_source: str = "",
    tolerance: StepTolerance | None = None,
    repeat: int = 3,
    step_study: bool = True,
    simulate_options: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
    simulator: Simulator | None = None,
) -> CompareResult:
    """Run every approach on every scenario, then the step-size study.

    Parameters
    ----------
    cycles : sequence of DriveCycle
        Drive cycles.
    t_ambs_K : sequence of float
        Ambient temperatures [K]; the scenarios are every cycle at every ambient.
    refrigerant : Refrigerant
        Cycle maps and saturation curve (the physics approach memoises its solves on it).
    params : SystemParams, optional
        System parameters (default: the spec's).
    approaches : sequence of str
        Approaches among :data:`APPROACHES`, in table order; one that is
        requested and not available is an error, never skipped.
    mode_models : ModeModels, optional
        The surrogate's mode models (required when ``surrogate`` is compared).
    dts : sequence of float
        Steps of the study [s] (0.001-60 s).
    physics_dts : sequence of float, optional
        Steps at which physics joins the study [s] (default: those of ``dts``
        of 1 s and more, or the largest of ``dts`` when none is; a physics run
        takes minutes, and its finest step is its study's reference).
    dt : float
        Step of the comparison table and trajectories [s].
    measured : mapping of str to numpy.ndarray, optional
        Measured reference (:func:`read_measured`) for the one scenario
        compared: its variables are compared against it instead of physics.
    measured_source : str
        Where ``measured`` came from (for the report).
    tolerance : StepTolerance, optional
        Criteria of the study.
    repeat : int
        Runs of lut and surrogate per scenario for their times (medians).
    step_study : bool
        False: the comparison table only.
    simulate_options : mapping, optional
        More keyword arguments of ``simulate`` (``sun``, ``RH_amb``, ``soak_cabin``, ``mode``...).
    progress : callable, optional
        ``progress(done, total, message)`` before each simulation.
    simulator : callable, optional
        Replaces :func:`evtms.system.simulate.simulate` (tests, benchmarks);
        called as ``simulator(cycle, T_amb, refrigerant, params, dt=, model=, mode_models=, **simulate_options)``.

    Returns
    -------
    CompareResult

    Raises
    ------
    EvtmsInputError
        An unknown or repeated approach, surrogate without mode models, no
        cycle or ambient, a bad step, ``measured`` with more than one
        scenario or times beyond the cycle, or an approach that fails with an
        input error or is not available (the message names approach, scenario
        and step).
    """
    approaches = tuple(approaches)
    tolerance = tolerance or StepTolerance()
    check_request(cycles, t_ambs_K, approaches, mode_models, dts, physics_dts, dt, measured, repeat)
    dts = tuple(sorted({float(d) for d in dts}))
    if physics_dts is None:
        physics_dts = tuple(d for d in dts if d >= 1.0) or (max(dts),)
    physics_dts = tuple(sorted({float(d) for d in physics_dts}))
    scenarios = [(c, float(T)) for c in cycles for T in t_ambs_K]
    if measured is not None:
        duration = scenarios[0][0].duration
        if float(measured["time"][-1]) > duration + TIME_TOL:
            raise EvtmsInputError(
                f"measured times reach {float(measured['time'][-1]):g} s, beyond the {duration:g} s of "
                f"{scenarios[0][0].name}; give the measurement of that cycle"
            )
    sim = simulator or _default_simulator
    options = dict(simulate_options or {})
    cache: dict[tuple[str, str, float, float], Run] = {}

    plan: list[tuple[str, DriveCycle, float, float, int]] = []
    for cycle, T in scenarios:
        for a in approaches:
            plan.append((a, cycle, T, float(dt), 1 if a == "physics" else max(1, repeat)))
    if step_study:
        for cycle, T in scenarios:
            for a in approaches:
                for d in physics_dts if a == "physics" else dts:
                    if d != float(dt):
                        plan.append((a, cycle, T, d, 1))
    total = sum(n for *_, n in plan)
    done = 0
    for a, cycle, T, d, n in plan:
        results = []
        failure = None
        for _ in range(n):
            if progress is not None:
                progress(done, total, f"{a} on {scenario_label(cycle.name, T)} at dt {d:g} s")
            done += 1
            try:
                results.append(sim(cycle, T, refrigerant, params, dt=d, model=a, mode_models=mode_models, **options))
            except (EvtmsInputError, NotImplementedError) as exc:
                raise _label_error(a, cycle.name, T, d, exc) from exc
            except ArithmeticError as exc:  # a numerical blow-up: recorded, not fatal, in the step study
                if d == float(dt):
                    raise
                failure = f"{type(exc).__name__}: {exc}"
                done += n - len(results) - 1
                break
        if failure is not None:
            cache[(a, cycle.name, T, d)] = Run(a, cycle.name, T, d, error=failure)
        else:
            cache[(a, cycle.name, T, d)] = _reduce(a, cycle.name, T, d, results)
    if progress is not None:
        progress(total, total, "done")

    runs = {(a, c.name, T): cache[(a, c.name, T, float(dt))] for c, T in scenarios for a in approaches}
    rows = [_compare_row(runs, a, c.name, T, measured) for c, T in scenarios for a in approaches]
    steps: list[StepRow] = []
    stable: dict[str, dict[str, float | None]] = {a: {} for a in approaches}
    if step_study:
        for c, T in scenarios:
            for a in approaches:
                by_dt = {d: cache[(a, c.name, T, d)] for d in (physics_dts if a == "physics" else dts)}
                rows_a = assess_steps(by_dt, tolerance)
                steps.extend(rows_a)
                stable[a][scenario_label(c.name, T)] = largest_stable(rows_a)
        for a in approaches:
            values = list(stable[a].values())
            stable[a]["all"] = None if any(v is None for v in values) or not values else min(values)
    return CompareResult(
        scenarios=[(c.name, T) for c, T in scenarios],
        approaches=approaches,
        dt=float(dt),
        dts=dts,
        physics_dts=physics_dts if "physics" in approaches else (),
        rows=rows,
        steps=steps,
        stable_dt=stable,
        runs=runs,
        measured=dict(measured) if measured is not None else None,
        measured_source=measured_source,
        tolerance=tolerance,
    )


def check_request(cycles, t_ambs_K, approaches, mode_models, dts, physics_dts, dt, measured, repeat) -> None:
    """Refuse a comparison that cannot run (one line each), before any map or simulation work."""
    allowed = ", ".join(APPROACHES)
    if not approaches:
        raise EvtmsInputError(f"no approach to compare; allowed: {allowed}")
    for a in approaches:
        if a not in APPROACHES:
            raise EvtmsInputError(f"approach {a!r} is unknown; allowed: {allowed}")
    if len(set(approaches)) != len(approaches):
        raise EvtmsInputError(f"approaches {','.join(approaches)} name one twice")
    if "surrogate" in approaches and mode_models is None:
        raise EvtmsInputError(
            "the surrogate approach needs mode models (the mode_models argument, from 'evtms surrogate train')"
        )
    if not cycles or not t_ambs_K:
        raise EvtmsInputError("nothing to compare: give at least one drive cycle and one ambient")
    names = [c.name for c in cycles]
    if len(set(names)) != len(names):
        raise EvtmsInputError(f"drive cycles {','.join(names)} name one twice")
    if len({round(float(T), 6) for T in t_ambs_K}) != len(t_ambs_K):
        raise EvtmsInputError("the ambients name one temperature twice")
    steps = [*dts, *(physics_dts or ()), dt]
    for d in steps:
        if not (isinstance(d, int | float) and math.isfinite(d) and 1e-3 <= d <= 60.0):
            raise EvtmsInputError(f"step {d!r} s is not allowed; allowed: 0.001 to 60 s")
    if not dts:
        raise EvtmsInputError("the step-size study needs at least one step")
    if physics_dts is not None and not physics_dts and "physics" in approaches:
        raise EvtmsInputError("physics needs at least one step in the study")
    if not isinstance(repeat, int) or repeat < 1:
        raise EvtmsInputError(f"repeat {repeat!r} is not allowed; allowed: an integer >= 1")
    if measured is not None:
        if len(cycles) * len(t_ambs_K) != 1:
            raise EvtmsInputError(
                f"a measured reference is one run: give one drive cycle and one ambient "
                f"(got {len(cycles)} cycle(s) x {len(t_ambs_K)} ambient(s))"
            )
        if "time" not in measured or not set(measured) - {"time"} <= set(COMPARED) or len(measured) < 2:
            raise EvtmsInputError(f"a measured reference holds 'time' and any of {', '.join(COMPARED)}")


def _pct(value: float, reference: float, floor: float = 0.0) -> float:
    den = max(abs(reference), floor)
    return 100.0 * (value - reference) / den if den > 0 else (0.0 if value == reference else math.nan)


def _num(value) -> float:
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


def _compare_row(runs: dict, approach: str, cycle: str, T: float, measured) -> CompareRow:
    run = runs[(approach, cycle, T)]
    physics = runs.get(("physics", cycle, T))
    s = run.summary
    refs: dict[str, tuple[str, Mapping[str, np.ndarray]]] = {}
    for name in COMPARED:
        if measured is not None and name in measured:
            refs[name] = ("measured", measured)
        elif physics is not None and name in physics.records:
            refs[name] = ("physics", physics.records)
    stats: dict[str, ErrorStat] = {}
    for name, (_, ref) in refs.items():
        stats.update(trajectory_errors({"time": ref["time"], name: ref[name]}, run.records, (name,)))
    kinds = {k for k, _ in refs.values()}
    if kinds == {"measured"} or kinds == {"physics"}:
        reference = kinds.pop()
    elif kinds:
        on_measured = [n for n, (k, _) in refs.items() if k == "measured"]
        reference = f"measured ({', '.join(on_measured)}), physics (others)"
    else:
        reference = "none"

    def err(name: str, what: str) -> float | None:
        st = stats.get(name)
        return None if st is None else getattr(st, what)

    speedup = None
    if physics is not None:
        speedup = 1.0 if approach == "physics" else _num(physics.summary.get("wall_time_s")) / _num(s["wall_time_s"])
    d_bat = d_hvac = None
    if physics is not None:
        d_bat = _pct(_num(s.get("battery_energy_kWh")), _num(physics.summary.get("battery_energy_kWh")))
        d_hvac = _pct(_num(s.get("hvac_energy_kWh")), _num(physics.summary.get("hvac_energy_kWh")))
    solves = s.get("physics_solves")
    return CompareRow(
        approach=approach,
        cycle=cycle,
        T_amb_degC=round(T - 273.15, 9),
        dt_s=run.dt,
        wall_time_s=_num(s.get("wall_time_s")),
        loop_time_s=_num(s.get("loop_time_s")),
        speedup=speedup,
        battery_energy_kWh=_num(s.get("battery_energy_kWh")),
        hvac_energy_kWh=_num(s.get("hvac_energy_kWh")),
        d_battery_energy_pct=d_bat,
        d_hvac_energy_pct=d_hvac,
        soc_end=_num(s.get("soc_end")),
        T_cabin_end_degC=_num(s.get("T_cabin_end_degC")),
        T_battery_end_degC=_num(s.get("T_battery_end_degC")),
        reference=reference,
        compared_records=max((st.n for st in stats.values()), default=0),
        rmse_T_cabin_K=err("T_cabin", "rmse"),
        max_T_cabin_K=err("T_cabin", "max_abs"),
        rmse_T_battery_K=err("T_battery", "rmse"),
        max_T_battery_K=err("T_battery", "max_abs"),
        rmse_SOC=err("SOC", "rmse"),
        max_SOC=err("SOC", "max_abs"),
        rmse_P_hvac_W=err("P_hvac", "rmse"),
        max_P_hvac_W=err("P_hvac", "max_abs"),
        out_of_range_fraction=run.out_of_range_fraction,
        physics_fallback_fraction=run.fallback_fraction,
        physics_solves=int(solves) if solves is not None else None,
        termination=str(s.get("termination", "")),
    )


# ---------------------------------------------------------------------------------------------- step study


def run_problem(run: Run, tolerance: StepTolerance) -> tuple[bool, bool, str]:
    """Whether a run stayed finite and bounded: ``(finite, bounded, reason)``.

    Finite: every compared record (an interval mean's first record excepted)
    and every summary figure of :data:`STEP_FIGURES` is a finite number, and
    the run did not fail. Bounded: temperatures within ``T_min``-``T_max``
    and the SOC within 0-1.
    """
    if run.error is not None:
        return False, False, f"run failed: {run.error}"
    for name in COMPARED:
        if name not in run.records:
            continue
        v = run.records[name][1:] if name in INTERVAL_MEANS else run.records[name]
        if not np.all(np.isfinite(v)):
            k = int(np.argmax(~np.isfinite(v))) + (1 if name in INTERVAL_MEANS else 0)
            t = float(run.records["time"][k])
            return False, False, f"{name} not finite from t = {t:g} s"
    for key in STEP_FIGURES:
        if not math.isfinite(_num(run.summary.get(key))):
            return False, False, f"{key} not finite"
    for name in ("T_cabin", "T_battery"):
        if name in run.records:
            v = run.records[name]
            lo, hi = float(np.min(v)), float(np.max(v))
            if lo < tolerance.T_min or hi > tolerance.T_max:
                bad = lo if lo < tolerance.T_min else hi
                return True, False, f"{name} {bad:.1f} K outside {tolerance.T_min:g}-{tolerance.T_max:g} K"
    if "SOC" in run.records:
        v = run.records["SOC"]
        if float(np.min(v)) < -1e-9 or float(np.max(v)) > 1.0 + 1e-9:
            return True, False, "SOC outside 0-1"
    return True, True, ""


def assess_steps(runs: Mapping[float, Run], tolerance: StepTolerance | None = None) -> list[StepRow]:
    """The step-size rows of one approach on one scenario.

    Parameters
    ----------
    runs : mapping of float to Run
        The approach's runs by step [s].
    tolerance : StepTolerance, optional
        The criteria (default :class:`StepTolerance`).

    Returns
    -------
    list of StepRow
        By increasing step. The reference is the finest step whose run is
        finite and bounded; changes are relative to it (energies relative to
        max(|reference|, ``energy_floor_kWh``)); without a sound run no step
        is stable.
    """
    tolerance = tolerance or StepTolerance()
    order = sorted(runs)
    health = {d: run_problem(runs[d], tolerance) for d in order}
    sound = [d for d in order if health[d][0] and health[d][1]]
    ref_dt = sound[0] if sound else None
    ref = runs[ref_dt].summary if ref_dt is not None else None
    rows = []
    for d in order:
        run = runs[d]
        finite, bounded, reason = health[d]
        s = run.summary
        changes: dict[str, float | None] = dict.fromkeys(
            ("d_battery_energy_pct", "d_hvac_energy_pct", "d_soc_end_pct", "d_T_cabin_end_K", "d_T_battery_end_K")
        )
        within = False
        if ref is not None and run.error is None:
            floor = tolerance.energy_floor_kWh
            changes["d_battery_energy_pct"] = _pct(
                _num(s.get("battery_energy_kWh")), _num(ref.get("battery_energy_kWh")), floor
            )
            changes["d_hvac_energy_pct"] = _pct(_num(s.get("hvac_energy_kWh")), _num(ref.get("hvac_energy_kWh")), floor)
            changes["d_soc_end_pct"] = _pct(_num(s.get("soc_end")), _num(ref.get("soc_end")))
            changes["d_T_cabin_end_K"] = _num(s.get("T_cabin_end_degC")) - _num(ref.get("T_cabin_end_degC"))
            changes["d_T_battery_end_K"] = _num(s.get("T_battery_end_degC")) - _num(ref.get("T_battery_end_degC"))
            limits = {
                "d_battery_energy_pct": 100.0 * tolerance.energy_rel,
                "d_hvac_energy_pct": 100.0 * tolerance.energy_rel,
                "d_soc_end_pct": 100.0 * tolerance.soc_rel,
                "d_T_cabin_end_K": tolerance.temperature_K,
                "d_T_battery_end_K": tolerance.temperature_K,
            }
            over = [k for k, lim in limits.items() if not abs(_num(changes[k])) <= lim]
            within = not over
            if over and finite and bounded:
                k = over[0]
                unit = " %" if k.endswith("pct") else " K"
                what = _FIGURE_NAMES[k]
                reason = f"{what} moved {changes[k]:+.3g}{unit} from dt {ref_dt:g} s (allowed {limits[k]:g}{unit})"
        elif ref is None and finite and bounded:
            reason = "no reference"
        rows.append(
            StepRow(
                approach=run.approach,
                cycle=run.cycle,
                T_amb_degC=round(run.T_amb - 273.15, 9),
                dt_s=d,
                reference_dt_s=ref_dt,
                finite=finite,
                bounded=bounded,
                within_tolerance=within,
                stable=finite and bounded and within,
                wall_time_s=_num(s.get("wall_time_s")) if s else None,
                out_of_range_fraction=run.out_of_range_fraction if run.error is None else None,
                reason=reason,
                **changes,
            )
        )
    return rows


def largest_stable(rows: Sequence[StepRow]) -> float | None:
    """Largest step [s] such that the run at it and at every finer step of ``rows`` is stable (None: none)."""
    best = None
    for row in sorted(rows, key=lambda r: r.dt_s):
        if not row.stable:
            break
        best = row.dt_s
    return best


# ---------------------------------------------------------------------------------------------- the request


@dataclass
class CompareRequest:
    """One ``evtms report compare``: drive cycles x ambients, or named scenarios (Table 12).

    Attributes
    ----------
    cycle : str or sequence of str, optional
        Drive cycles (built-in names or CSV files); text is comma-separated.
    t_amb : str, float or sequence of float, optional
        Ambient temperatures [degC]; text is comma-separated.
    output : Path, optional
        Output folder (required for cycles; optional with scenarios).
    scenarios : str, optional
        Scenarios instead of cycles and ambients, comma-separated names or groups (``t12``, ``t12-cc`` ...).
    scenario_file : Path, optional
        TOML scenario file whose scenarios ``scenarios`` may name (else: all of them).
    approaches : str or sequence of str, optional
        Among physics, lut, surrogate (default: all three; with scenarios lut and those available).
    surrogates : Path
        Mode-model file or folder (``evtms surrogate train -o``).
    luts : Path
        Cycle LUT folder (or ``evtms demo``'s luts/ or output folder); built there if missing or empty.
    params : Path, optional
        System TOML, as for a simulation.
    dt : float
        Step of the comparison table and trajectories [s].
    dts, physics_dts : str or sequence of float
        Steps of the step-size study [s], and those at which physics joins it (default: ``dts`` >= 1 s).
    no_steps : bool
        Skip the step-size study.
    measured : Path, optional
        CSV of measured values (:func:`read_measured`): the reference where given (one cycle, one ambient).
    repeat : int
        Runs of lut and surrogate per scenario, median time (1 to 20).
    sun : float
        Solar irradiance [W/m2], 0 to 1500.
    soak_cabin : float, optional
        Initial cabin air, walls and interior [degC].
    fmt : str
        Figure format, png or svg.
    """

    cycle: str | Sequence[str] | None = None
    t_amb: str | float | Sequence[float] | None = None
    output: Path | None = None
    scenarios: str | None = None
    scenario_file: Path | None = None
    approaches: str | Sequence[str] | None = None
    surrogates: Path = Path("models")
    luts: Path = Path("luts")
    params: Path | None = None
    dt: float = 1.0
    dts: str | Sequence[float] = "0.01,0.1,1,10"
    physics_dts: str | Sequence[float] | None = None
    no_steps: bool = False
    measured: Path | None = None
    repeat: int = 3
    sun: float = 0.0
    soak_cabin: float | None = None
    fmt: str = "png"


@dataclass
class Comparison:
    """What :func:`run_comparison` ran and wrote.

    Attributes
    ----------
    result : CompareResult or Table12Result
        The comparison (:class:`~evtms.reports.compare.CompareResult`), or with scenarios the Table 12
        rows (:class:`~evtms.system.table12.Table12Result`).
    files : list of Path
        The files written.
    table12 : bool
        The request named scenarios.
    """

    result: Any
    files: list[Path]
    table12: bool


def _names(value: str | Sequence[str]) -> list[str]:
    """Comma-separated names (or a sequence of them), stripped."""
    return [v.strip() for v in (value.split(",") if isinstance(value, str) else value)]


def _float_list(field_name: str, value: str | Sequence[float], most: int = 20) -> list[float]:
    """Comma-separated numbers of a request field (or a sequence of them)."""
    from evtms.workflows.common import as_text

    text = as_text(value)
    items = [t.strip() for t in text.split(",")]
    if not items or len(items) > most:
        raise EvtmsInputError(f"`{field_name}` {text!r}: give 1 to {most} comma-separated numbers")
    try:
        values = [float(t) for t in items]
    except ValueError:
        raise EvtmsInputError(f"`{field_name}` {text!r}: not comma-separated numbers") from None
    if not all(math.isfinite(v) for v in values):
        raise EvtmsInputError(f"`{field_name}` {text!r}: numbers must be finite")
    return values


def _check_repeat(repeat: int) -> None:
    if not 1 <= repeat <= 20:
        raise EvtmsInputError(f"`repeat` {repeat} is not allowed; allowed: 1 to 20")


def run_comparison(
    request: CompareRequest,
    *,
    notify: Callable[[str], None] | None = None,
    progress: Progress | None = None,
    on_run: Progress | None = None,
) -> Comparison:
    """Compare the approaches on cycles x ambients (or on named scenarios) and write the report.

    Parameters
    ----------
    request : CompareRequest
        Checked in full before any LUT, map or simulation work.
    notify : callable, optional
        ``notify(message)`` for notes (LUTs or maps being built).
    progress : callable, optional
        ``progress(done, total, map_name)`` while cycle maps are built.
    on_run : callable, optional
        ``on_run(done, total, message)`` before each simulation.

    Returns
    -------
    Comparison
        The comparison and the files :func:`evtms.reports.compare.write_compare` wrote, or with scenarios
        the Table 12 rows and the files of :func:`evtms.reports.table12.write_table12`.

    Raises
    ------
    EvtmsInputError
        Anything the request asks that is not allowed (the message names the request field).
    """
    r = request
    if r.scenarios is not None or r.scenario_file is not None:
        if r.cycle is not None or r.t_amb is not None or r.measured is not None:
            raise EvtmsInputError(
                "`scenarios` runs scenarios with their own cycle and ambient; leave out `cycle`, `t_amb`, `measured`"
            )
        if r.sun != 0.0 or r.soak_cabin is not None or r.physics_dts is not None:
            raise EvtmsInputError(
                "`scenarios` set their own sun and initial state and run no step-size study; "
                "leave out `sun`, `soak_cabin`, `physics_dts`"
            )
        return _compare_scenarios(r, notify, progress, on_run)
    if r.cycle is None or r.t_amb is None:
        raise EvtmsInputError("give `cycle` NAMES and `t_amb` DEGC (or `scenarios` NAMES)")
    if r.output is None:
        raise EvtmsInputError("give `output` FOLDER for the comparison's tables and figures")
    return _compare_cycles(r, notify, progress, on_run)


def _cycles_plan(r: CompareRequest) -> dict:
    """The arguments of :func:`run_compare` and the files read, from a request of cycles x ambients."""
    from evtms.cycle.topology import parse_values
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.params import load_parameter_tree
    from evtms.workflows.common import as_text
    from evtms.workflows.simulate import check_soak, surrogate_models

    chosen = _names("physics,lut,surrogate" if r.approaches is None else r.approaches)
    for a in chosen:
        if a not in APPROACHES:
            raise EvtmsInputError(f"`approaches` {a!r} is unknown; allowed: {', '.join(APPROACHES)}")
    if r.fmt not in ("png", "svg"):
        raise EvtmsInputError(f"`fmt` {r.fmt!r} is unknown; allowed: png, svg")
    _check_repeat(r.repeat)
    if not (math.isfinite(r.sun) and 0.0 <= r.sun <= 1500.0):
        raise EvtmsInputError(f"`sun` {r.sun:g} is not allowed; allowed: 0 to 1500 W/m2")
    check_soak(r.soak_cabin)
    ambients = parse_values("T_amb", as_text(r.t_amb), 20, "`t_amb`")
    step_list = _float_list("dts", r.dts)
    physics_steps = _float_list("physics_dts", r.physics_dts) if r.physics_dts is not None else None
    names = _names(r.cycle)
    if len(names) > 20:
        raise EvtmsInputError(f"`cycle`: {len(names)} cycles; at most 20")
    cycles = [drive_cycle(c) for c in names]
    inputs = [Path(c.source) for c in cycles if Path(c.source).is_file()]
    if r.params is not None:
        inputs.append(input_file(r.params, "params file"))
    tree = load_parameter_tree(r.params)
    reference = None
    if r.measured is not None:
        reference = read_measured(input_file(r.measured, "measured file"))
        inputs.append(r.measured)
    mode_models = None
    if "surrogate" in chosen:
        mode_models, surrogate_file = surrogate_models(r.surrogates)
        inputs.append(surrogate_file)
    check_request(cycles, ambients, chosen, mode_models, step_list, physics_steps, r.dt, reference, r.repeat)
    return {
        "inputs": inputs,
        "cycles": cycles,
        "t_ambs_K": ambients,
        "tree": tree,
        "params": tree.system,
        "approaches": tuple(chosen),
        "mode_models": mode_models,
        "dts": tuple(step_list),
        "physics_dts": None if physics_steps is None else tuple(physics_steps),
        "measured": reference,
    }


def _compare_cycles(r: CompareRequest, notify, progress, on_run) -> Comparison:
    """``run_comparison`` of cycles x ambients: :func:`run_compare`, then the report written."""
    from evtms.reports.compare import write_compare
    from evtms.workflows.simulate import cycle_luts, system_refrigerant

    plan = _cycles_plan(r)  # before the maps are built
    inputs = plan.pop("inputs")
    lut_folder, lut_files = cycle_luts(r.luts)
    output_folder(r.output, inputs + lut_files)
    refrigerant = system_refrigerant(r.luts, lut_folder, plan.pop("tree"), notify, progress)
    result = run_compare(
        plan.pop("cycles"),
        plan.pop("t_ambs_K"),
        refrigerant,
        **plan,
        dt=r.dt,
        measured_source=str(r.measured) if r.measured is not None else "",
        repeat=r.repeat,
        step_study=not r.no_steps,
        simulate_options={"sun": r.sun, "soak_cabin": None if r.soak_cabin is None else r.soak_cabin + 273.15},
        progress=on_run,
    )
    return Comparison(result, write_compare(result, r.output, r.fmt), table12=False)


def _scenarios_plan(r: CompareRequest):
    """(scenarios, their setups, parameter tree, files read) of a request of named scenarios."""
    from evtms.system.params import load_parameter_tree
    from evtms.system.scenarios import SCENARIOS, read_scenario_file, select_scenarios
    from evtms.workflows.simulate import trace_files

    _check_repeat(r.repeat)
    inputs: list[Path] = []
    from_file = {}
    if r.scenario_file is not None:
        from_file = read_scenario_file(input_file(r.scenario_file, "scenario file"))
        inputs.append(r.scenario_file)
    available = {**SCENARIOS, **from_file}
    chosen = select_scenarios(r.scenarios, available) if r.scenarios is not None else list(from_file.values())
    if r.params is not None:
        inputs.append(input_file(r.params, "params file"))
    tree = load_parameter_tree(r.params)
    setups = [sc.setup(tree.system) for sc in chosen]
    for st in setups:
        if st.T_amb is None:
            raise EvtmsInputError(f"scenario {st.scenario.name!r} has no ambient of its own; give scenarios with T_amb")
        if Path(st.cycle.source).is_file():
            inputs.append(Path(st.cycle.source))
        inputs += trace_files(st.inputs)
    return chosen, setups, tree, inputs


def _available(asked: list[str] | None, skipped: dict[str, str], setups, mode_models, refrigerant) -> list[str]:
    """The approaches to run: those asked, or (none asked) those that can run every scenario."""
    from evtms.system.simulate import check_model
    from evtms.system.table12 import APPROACHES as TABLE12_APPROACHES

    chosen = []
    for a in TABLE12_APPROACHES:
        if (asked is None and a in skipped) or (asked is not None and a not in asked):
            continue
        try:
            for st in setups:
                check_model(a, st.mode, mode_models, refrigerant)
        except EvtmsInputError as exc:
            if asked is not None:
                raise
            skipped[a] = str(exc)
            continue
        chosen.append(a)
    return chosen


def _compare_scenarios(r: CompareRequest, notify, progress, on_run) -> Comparison:
    """``run_comparison`` of named scenarios: each approach on each scenario, the Table 12 rows written."""
    from evtms.reports.table12 import write_table12
    from evtms.system.table12 import APPROACHES as TABLE12_APPROACHES
    from evtms.system.table12 import run_table12
    from evtms.workflows.simulate import cycle_luts, surrogate_models, system_refrigerant

    chosen, setups, tree, inputs = _scenarios_plan(r)
    system = tree.system
    asked = None if r.approaches is None else _names(r.approaches)
    for a in asked or ():
        if a not in TABLE12_APPROACHES:
            raise EvtmsInputError(f"`approaches` {a!r} is unknown; allowed: {', '.join(TABLE12_APPROACHES)}")
    skipped: dict[str, str] = {}
    mode_models = None
    if asked is None or "surrogate" in asked:
        from evtms.surrogates.io import MODEL_FILE

        surrogates = Path(r.surrogates)
        file = surrogates / MODEL_FILE if surrogates.is_dir() else surrogates
        if asked is None and not file.is_file():
            skipped["surrogate"] = f"no mode-model file at {surrogates} (evtms surrogate train)"
        else:
            mode_models, surrogate_file = surrogate_models(surrogates)
            inputs.append(surrogate_file)
    lut_folder, lut_files = cycle_luts(r.luts)
    if r.output is not None:
        output_folder(r.output, inputs + lut_files)
    refrigerant = system_refrigerant(r.luts, lut_folder, tree, notify, progress)
    approaches = _available(asked, skipped, setups, mode_models, refrigerant)
    result = run_table12(
        chosen, refrigerant, params=system, approaches=approaches, mode_models=mode_models, dt=r.dt,
        repeat=r.repeat, progress=on_run,
    )  # fmt: skip
    result.skipped = skipped
    return Comparison(result, write_table12(result, r.output) if r.output is not None else [], table12=True)
