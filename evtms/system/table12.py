"""The thesis's Table 12 mode experiments: scenarios run by each modelling approach, with the thesis's columns.

:func:`run_table12` runs every scenario (the built-in ``t12-*`` rows, or any
others) with every approach (``model=`` ``lut``, ``physics``, ``surrogate`` of
:func:`evtms.system.simulate.simulate`) and reduces each run to a
:class:`Table12Row`: the row's mode and inputs (T_amb, Tbatt, Qloss, Tin,
SP_evap, blower, SP_CoHX), the time per simulation, the error against the
reference approach, the electrical power the thesis reports per mode
(:data:`P_EL_TERMS`) and whether the setpoints were held
(:func:`capacity_check`). Library code: nothing is printed; progress goes to
a callback ``progress(done, total, message)``; the tables are written by
:mod:`evtms.reports.table12`.

Timing as :func:`evtms.workflows.compare.run_compare`: lut and surrogate run
``repeat`` times per scenario and report the median; physics runs once (its
solves are memoised on the ``refrigerant`` object).

References
----------
Thesis Table 12 and sections 4.2-4.5 (P_el per mode); the project's system
spec v2, sections 4 (P_el and ``capacity_limited`` per row) and 10 item 6
(the means of T_ev and T_H over the last 10 min within 1 K of SP_evap and
SP_CoHX, else ``capacity_limited``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.system.inputs import InputValue, Trace
from evtms.system.scenarios import Scenario, ScenarioSetup, run_scenario

#: Approaches in table order (``model=`` of ``simulate``); the first run of :data:`REFERENCE_ORDER` is the reference.
APPROACHES = ("physics", "lut", "surrogate")
REFERENCE_ORDER = ("physics", "lut")
#: The thesis's P_el per forced mode (T sections 4.2-4.5): record variables summed. Other modes: P_hvac.
P_EL_TERMS: dict[str, tuple[str, ...]] = {
    "bh": ("P_heater", "P_pump"),
    "bc": ("P_compressor", "P_fan", "P_pump"),
    "cc": ("P_compressor", "P_fan", "P_blower"),
    "ch": ("P_ptcw", "P_pump_h", "P_blower"),
}
P_EL_OTHER = ("P_hvac",)
#: The error of a row is the RMSE of this record against the reference's (default ``T_cabin``).
ERROR_VARIABLE = {"bh": "T_battery", "bc": "T_battery"}
#: Setpoint input -> the record it holds (spec 10 item 6: evaporator outlet air, heater-loop coolant).
CAPACITY_CHECKS = (("SP_evap", "T_evap_air"), ("SP_CoHX", "T_heater_loop"))
#: The window at the end of a run over which setpoints are judged [s], and the tolerance [K].
CAPACITY_WINDOW_S = 600.0
CAPACITY_TOLERANCE_K = 1.0

Progress = Callable[[int, int, str], None]


@dataclass(frozen=True)
class CapacityCheck:
    """Whether a run held its setpoints over the last :data:`CAPACITY_WINDOW_S`.

    Attributes
    ----------
    limited : bool or None
        True: a setpoint's mean was missed by more than :data:`CAPACITY_TOLERANCE_K`;
        False: every given setpoint held (or none was given); None: a record
        needed for the check is missing.
    means : dict of str to float
        Mean of each checked record over the window [K].
    setpoints : dict of str to float
        Mean of each setpoint over the window [K].
    note : str
        What was not checked, and why.
    """

    limited: bool | None
    means: dict[str, float] = field(default_factory=dict)
    setpoints: dict[str, float] = field(default_factory=dict)
    note: str = ""


@dataclass
class Table12Row:
    """One approach on one scenario: the thesis's Table 12 columns and more (SI units, names carry them).

    Inputs are numbers [SI] or a trace's ``FILE.csv:column``, None where the
    scenario does not give them. ``rmse_K`` is the RMSE of
    ``error_variable`` against the ``reference`` approach's run (None
    without a reference, 0 for the reference itself); ``d_P_el_pct`` the
    deviation of the run's mean P_el from the reference's. ``P_el_W`` is the
    mean over the run, ``P_el_last_W`` over the last
    :data:`CAPACITY_WINDOW_S`, both None when a term of ``P_el_terms`` is not
    recorded (named in ``P_el_missing``). ``capacity_setpoints`` names the
    setpoints :func:`capacity_check` judged (empty: none given, and
    ``capacity_limited`` is False).
    """

    scenario: str
    approach: str
    mode: str
    heating: str
    T_amb_K: float
    T_battery0_K: float | None
    Q_loss_W: float | str | None
    T_in_K: float | str | None
    SP_evap_K: float | str | None
    blower: float | str | None
    SP_CoHX_K: float | str | None
    wall_time_s: float
    loop_time_s: float
    reference: str | None
    error_variable: str
    rmse_K: float | None
    d_P_el_pct: float | None
    P_el_terms: str
    P_el_missing: str
    P_el_W: float | None
    P_el_last_W: float | None
    capacity_setpoints: str
    capacity_limited: bool | None
    T_evap_air_last_K: float | None
    T_heater_loop_last_K: float | None
    capacity_note: str
    soc_end: float
    T_battery_end_K: float
    T_cabin_end_K: float
    termination: str


@dataclass
class Table12Result:
    """Everything :func:`run_table12` found.

    Attributes
    ----------
    rows : list of Table12Row
        By scenario, then approach in :data:`APPROACHES` order.
    approaches : tuple of str
        Approaches run.
    reference : str or None
        The reference approach (physics if run, else lut).
    dt : float
        Time step [s].
    repeat : int
        Runs of lut and surrogate per scenario (median times).
    skipped : dict of str to str
        Approaches left out, and why (filled by the caller that chose them).
    """

    rows: list[Table12Row]
    approaches: tuple[str, ...]
    reference: str | None
    dt: float
    repeat: int
    skipped: dict[str, str] = field(default_factory=dict)


def window_mean(time: np.ndarray, values: np.ndarray, start: float, end: float) -> float:
    """Mean [values' units] of a record over ``[start, end]`` [s]; NaN where nothing falls in it.

    A record whose first value is NaN is an interval mean (record ``k`` is
    the mean over ``(t[k-1], t[k]]``): the intervals within the window are
    averaged, weighted by their length. Otherwise it is a state sampled at
    ``t[k]``: the trapezoid mean of the samples, interpolated at ``start``.
    """
    t, v = np.asarray(time, float), np.asarray(values, float)
    if t.size < 2:
        return math.nan
    tol = 1e-9 * max(1.0, abs(end))
    if not math.isfinite(v[0]):
        inside = (t[:-1] >= start - tol) & (t[1:] <= end + tol)
        span = np.diff(t)[inside]
        vals = v[1:][inside]
        return float(np.sum(vals * span) / np.sum(span)) if span.size and np.sum(span) > 0 else math.nan
    keep = (t > start + tol) & (t <= end + tol)
    ts = np.concatenate(([start], t[keep]))
    vs = np.concatenate(([np.interp(start, t, v)], v[keep]))
    if ts[-1] - ts[0] <= 0:
        return float(vs[-1])
    return float(np.sum(0.5 * (vs[1:] + vs[:-1]) * np.diff(ts)) / (ts[-1] - ts[0]))


def _input_mean(value: InputValue, start: float, end: float) -> float:
    if isinstance(value, Trace):
        return float(value.step_means(np.array([start, end]))[0])
    return float(value)


def p_el(records: Mapping[str, np.ndarray], mode: str) -> tuple[np.ndarray | None, tuple[str, ...], list[str]]:
    """The thesis's P_el [W] per record (an interval mean), its terms and the terms not recorded.

    Forced modes ``bh``, ``bc``, ``cc``, ``ch`` sum :data:`P_EL_TERMS`; any
    other mode takes ``P_hvac`` (all electricity of the thermal system).
    Returns None for the power when a term is missing.
    """
    terms = P_EL_TERMS.get(mode, P_EL_OTHER)
    missing = [t for t in terms if t not in records]
    if missing:
        return None, terms, missing
    return np.sum([np.asarray(records[t], float) for t in terms], axis=0), terms, []


def capacity_check(
    records: Mapping[str, np.ndarray], inputs: Mapping[str, InputValue], window: float = CAPACITY_WINDOW_S
) -> CapacityCheck:
    """Whether the run held each given setpoint over its last ``window`` [s] (spec v2 section 10 item 6).

    For ``SP_evap`` the mean of ``T_evap_air``, for ``SP_CoHX`` that of
    ``T_heater_loop``, each within :data:`CAPACITY_TOLERANCE_K` of the
    setpoint's mean over the window; else the run is capacity limited.
    """
    t = np.asarray(records["time"], float)
    end = float(t[-1])
    start = max(float(t[0]), end - window)
    means, setpoints, notes = {}, {}, []
    limited = False
    unknown = False
    for sp, name in CAPACITY_CHECKS:
        if sp not in inputs:
            continue
        setpoints[sp] = _input_mean(inputs[sp], start, end)
        if name not in records:
            unknown = True
            notes.append(f"no {name} record to hold {sp} against")
            continue
        means[name] = window_mean(t, records[name], start, end)
        if not (abs(means[name] - setpoints[sp]) <= CAPACITY_TOLERANCE_K):
            limited = True
    if not setpoints:
        notes.append("no setpoint given")
    return CapacityCheck(True if limited else (None if unknown else False), means, setpoints, "; ".join(notes))


def _rmse(ref: Mapping[str, np.ndarray], run: Mapping[str, np.ndarray], name: str) -> float | None:
    if name not in ref or name not in run:
        return None
    t_ref, v_ref = np.asarray(ref["time"], float), np.asarray(ref[name], float)
    t, v = np.asarray(run["time"], float), np.asarray(run[name], float)
    ok = np.isfinite(v_ref) & (t_ref >= t[0]) & (t_ref <= t[-1])
    good = np.isfinite(v)
    if not ok.any() or not good.any():
        return None
    at = np.interp(t_ref[ok], t[good], v[good])
    return float(np.sqrt(np.mean((at - v_ref[ok]) ** 2)))


def _input_cell(inputs: Mapping[str, InputValue], name: str) -> float | str | None:
    value = inputs.get(name)
    if value is None:
        return None
    return value.source if isinstance(value, Trace) else float(value)


def _row(setup: ScenarioSetup, approach: str, result, T_amb: float, reference: str | None, ref_result) -> Table12Row:
    rec, s = result.records, result.summary
    inputs = setup.inputs
    power, terms, missing = p_el(rec, setup.mode)
    t = np.asarray(rec["time"], float)
    end = float(t[-1])
    start_last = max(float(t[0]), end - CAPACITY_WINDOW_S)
    P_el = P_last = None
    if power is not None:
        P_el = window_mean(t, power, float(t[0]), end)
        P_last = window_mean(t, power, start_last, end)
    cap = capacity_check(rec, inputs)
    variable = ERROR_VARIABLE.get(setup.mode, "T_cabin")
    rmse = d_p = None
    if ref_result is not None:
        rmse = _rmse(ref_result.records, rec, variable)
        ref_power, _, _ = p_el(ref_result.records, setup.mode)
        if power is not None and ref_power is not None:
            ref_mean = window_mean(np.asarray(ref_result.records["time"], float), ref_power, float(t[0]), end)
            if math.isfinite(ref_mean) and abs(ref_mean) > 0:
                d_p = 100.0 * (P_el - ref_mean) / abs(ref_mean)
    T_b0 = setup.params.battery.T_init
    return Table12Row(
        scenario=setup.scenario.name,
        approach=approach,
        mode=setup.mode,
        heating=setup.heating,
        T_amb_K=float(T_amb),
        T_battery0_K=float(T_b0) if T_b0 is not None else float(T_amb),
        Q_loss_W=_input_cell(inputs, "Q_battery_ext"),
        T_in_K=_input_cell(inputs, "hvac_inlet_T"),
        SP_evap_K=_input_cell(inputs, "SP_evap"),
        blower=_input_cell(inputs, "blower"),
        SP_CoHX_K=_input_cell(inputs, "SP_CoHX"),
        wall_time_s=float(s.get("wall_time_s", math.nan)),
        loop_time_s=float(s.get("loop_time_s", math.nan)),
        reference=reference,
        error_variable=variable,
        rmse_K=rmse,
        d_P_el_pct=d_p,
        P_el_terms="+".join(terms),
        P_el_missing=",".join(missing),
        P_el_W=P_el,
        P_el_last_W=P_last,
        capacity_setpoints=",".join(cap.setpoints),
        capacity_limited=cap.limited,
        T_evap_air_last_K=cap.means.get("T_evap_air"),
        T_heater_loop_last_K=cap.means.get("T_heater_loop"),
        capacity_note=cap.note,
        soc_end=float(s.get("soc_end", math.nan)),
        T_battery_end_K=float(s.get("T_battery_end_degC", math.nan)) + 273.15,
        T_cabin_end_K=float(s.get("T_cabin_end_degC", math.nan)) + 273.15,
        termination=str(s.get("termination", "")),
    )


def run_table12(
    scenarios: Sequence[Scenario],
    refrigerant,
    *,
    params=None,
    approaches: Sequence[str] = ("lut",),
    mode_models=None,
    dt: float = 1.0,
    repeat: int = 3,
    progress: Progress | None = None,
    simulator: Callable[..., Any] | None = None,
) -> Table12Result:
    """Run every scenario with every approach and reduce each run to a :class:`Table12Row`.

    Parameters
    ----------
    scenarios : sequence of Scenario
        Scenarios (each with an ambient of its own), e.g. the built-in ``t12-*`` rows.
    refrigerant : Refrigerant
        Cycle maps and saturation curve (the physics approach memoises its solves on it).
    params : SystemParams, optional
        Parameters the scenarios' own apply over (default: the defaults).
    approaches : sequence of str
        Among :data:`APPROACHES`; run in that order so the reference runs first.
    mode_models : ModeModels, optional
        The surrogate's mode models (required with ``surrogate``).
    dt : float
        Time step [s].
    repeat : int
        Runs of lut and surrogate per scenario (the median times are reported), 1 to 20.
    progress : callable, optional
        ``progress(done, total, message)`` before each simulation.
    simulator : callable, optional
        Replaces :func:`evtms.system.scenarios.run_scenario` (tests); called as
        ``simulator(setup, refrigerant, dt=, model=, mode_models=)``.

    Returns
    -------
    Table12Result

    Raises
    ------
    EvtmsInputError
        No scenario, an unknown or repeated approach, a bad step or repeat, a
        scenario without an ambient or that cannot be set up; the failure of a
        run, naming approach and scenario. Everything is checked before the
        first run.
    """
    asked = list(approaches)
    for a in asked:
        if a not in APPROACHES:
            raise EvtmsInputError(f"approach {a!r} is unknown; allowed: {', '.join(APPROACHES)}")
    if len(set(asked)) != len(asked):
        raise EvtmsInputError(f"approaches {','.join(asked)} name one twice")
    approaches = tuple(a for a in APPROACHES if a in asked)
    if not scenarios:
        raise EvtmsInputError("no scenario to run; give at least one (e.g. t12)")
    if not approaches:
        raise EvtmsInputError(f"no approach to run; allowed: {', '.join(APPROACHES)}")
    if "surrogate" in approaches and mode_models is None:
        raise EvtmsInputError("the surrogate approach needs mode models (`surrogates` FILE)")
    if not (isinstance(dt, int | float) and math.isfinite(dt) and 1e-3 <= dt <= 60.0):
        raise EvtmsInputError(f"step {dt!r} s is not allowed; allowed: 0.001 to 60 s")
    if isinstance(repeat, bool) or not isinstance(repeat, int) or not 1 <= repeat <= 20:
        raise EvtmsInputError(f"repeat {repeat!r} is not allowed; allowed: 1 to 20")
    setups = [sc.setup(params) for sc in scenarios]
    for st in setups:
        if st.T_amb is None:
            raise EvtmsInputError(f"scenario {st.scenario.name!r} has no ambient of its own (T_amb); give one")
    reference = next((a for a in REFERENCE_ORDER if a in approaches), None)
    sim = simulator or run_scenario
    plan = [(st, a, 1 if a == "physics" else repeat) for st in setups for a in approaches]
    total = sum(n for *_, n in plan)
    done = 0
    rows: list[Table12Row] = []
    results: dict[tuple[str, str], Any] = {}
    for st, a, n in plan:
        runs = []
        for _ in range(n):
            if progress is not None:
                progress(done, total, f"{a} on {st.scenario.name}")
            done += 1
            try:
                runs.append(sim(st, refrigerant, dt=float(dt), model=a, mode_models=mode_models))
            except (EvtmsInputError, NotImplementedError) as exc:
                raise EvtmsInputError(f"{a} on scenario {st.scenario.name!r}: {exc}") from exc
        result = runs[0]
        for key in ("wall_time_s", "loop_time_s"):
            result.summary[key] = float(np.median([float(r.summary[key]) for r in runs]))
        results[(st.scenario.name, a)] = result
        ref = results.get((st.scenario.name, reference)) if reference is not None else None
        rows.append(_row(st, a, result, st.T_amb, reference, ref))
    if progress is not None:
        progress(total, total, "done")
    return Table12Result(rows, approaches, reference, float(dt), repeat)
