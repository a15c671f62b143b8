"""External inputs of a simulation: the thesis's Table 12 experiment inputs as numbers or traces.

Each input is a constant or a :class:`Trace` (values on the run's time,
linear between samples, held at the ends). The time loop reads them per step
as one array (:func:`per_step`, columns in :data:`INPUT_NAMES` order, NaN
where an input is not given, so the controller's own law applies):

- ``Q_battery_ext`` [W]: heat into the battery from outside (Table 12
  ``Qloss``), ``C_b dT_b/dt`` gains it; an external source in the system
  ledger;
- ``hvac_inlet_T`` [K], ``hvac_inlet_rh`` [1]: a fixed HVAC inlet air state
  (Table 12 ``Tin``) instead of the fresh/recirculated mix;
- ``SP_evap`` [K]: the evaporator outlet air setpoint (Table 12, thesis
  section 4.4);
- ``SP_CoHX`` [K]: the coolant temperature at the heater core's inlet
  (thesis ``SP_T_C_CoHX_in``, section 4.5);
- ``blower`` [1]: a fixed blower command in place of the blower law;
- ``SP_vent`` [K]: the vent (supply) air target in place of the cabin
  loop's feed-forward and PI: what a supervisory controller
  (:mod:`evtms.system.mpc`) or a trace of one sets; the requests, the
  evaporator and heater loops and every relay follow it as they follow
  the law's target, clipped to ``T_vent_min``..``T_vent_max``;
- ``BC_request`` [1]: the battery-cooling request (above 0.5: on) in place
  of its relay on the battery temperature; the critical relay and the
  chiller's safety relay stay;
- ``speed_deviation`` [m/s]: the driven speed's deviation from the trace,
  within the vehicle's ``delta_v_ref`` (:func:`evtms.system.vehicle.deviated_cycle`;
  it changes the drive, not the loop's controls).

Users give each input as a number (SI) or as ``"FILE.csv:column"``, a
trace: a CSV file with a ``time_s`` column and named columns in SI units
(``docs/scenario-format.md``). :func:`check_inputs` turns such raw values
into numbers and :class:`Trace` objects, refusing anything else with one
line (:class:`~evtms.errors.EvtmsInputError`) that names the value and what
is allowed; file sizes and sample counts are bounded before anything is
allocated.

References
----------
Thesis Table 12 (inputs of the mode experiments); the project's system spec
v2, section 4 (inputs, traces) and 2.3 (a fixed blower of 0 is refused while
the climate can run the cabin coil or a heater).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.paths import csv_rows, read_small_text

#: Inputs in the loop's column order.
INPUT_NAMES = (
    "Q_battery_ext",
    "hvac_inlet_T",
    "hvac_inlet_rh",
    "SP_evap",
    "SP_CoHX",
    "blower",
    "SP_vent",
    "BC_request",
    "speed_deviation",
)
#: Inputs that change the drive, not the loop's controls: applied to the trace before the run.
DRIVE_INPUTS = ("speed_deviation",)
#: The loop's inputs, in its column order (:data:`evtms.system.loop.N_X` of them).
LOOP_INPUTS = tuple(n for n in INPUT_NAMES if n not in DRIVE_INPUTS)
#: Allowed range per input (both ends included) and its units.
INPUT_RANGES: dict[str, tuple[float, float, str]] = {
    "Q_battery_ext": (-50e3, 50e3, "W"),
    "hvac_inlet_T": (233.15, 333.15, "K"),
    "hvac_inlet_rh": (0.0, 1.0, "1"),
    "SP_evap": (273.15, 298.15, "K"),
    "SP_CoHX": (288.15, 363.15, "K"),
    "blower": (0.0, 1.0, "1"),
    "SP_vent": (273.15, 343.15, "K"),
    "BC_request": (0.0, 1.0, "1"),
    "speed_deviation": (-10.0, 10.0, "m/s"),
}


@dataclass(frozen=True)
class Trace:
    """An input given over time.

    Attributes
    ----------
    time : numpy.ndarray
        Sample times [s] on the run's clock, strictly increasing.
    values : numpy.ndarray
        The input's values at the samples [its units].
    source : str
        Where it came from (``FILE.csv:column``).
    """

    time: np.ndarray
    values: np.ndarray
    source: str = ""

    def step_means(self, edges: np.ndarray) -> np.ndarray:
        """Mean over each step ``[edges[k], edges[k+1]]`` of the piecewise-linear trace, held at its ends."""
        t = np.concatenate(([min(edges[0], self.time[0]) - 1.0], self.time, [max(edges[-1], self.time[-1]) + 1.0]))
        v = np.concatenate((self.values[:1], self.values, self.values[-1:]))
        area = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
        # The integral is piecewise quadratic between samples; integrate exactly at the edges.
        k = np.clip(np.searchsorted(t, edges, side="right") - 1, 0, t.size - 2)
        tau = edges - t[k]
        slope = (v[k + 1] - v[k]) / (t[k + 1] - t[k])
        at = area[k] + v[k] * tau + 0.5 * slope * tau**2
        return np.diff(at) / np.diff(edges)


InputValue = float | Trace


def per_step(inputs: Mapping[str, InputValue] | None, edges: np.ndarray) -> np.ndarray:
    """The inputs as the loop reads them: (steps, len(LOOP_INPUTS)), NaN where not given.

    Parameters
    ----------
    inputs : mapping of str to float or Trace, optional
        Inputs by name (:data:`INPUT_NAMES`); values in SI units.
    edges : numpy.ndarray
        Step boundaries [s] on the run's clock (preconditioning included).

    Returns
    -------
    numpy.ndarray
        Per step the mean of each given input over the step.
    """
    out = np.full((edges.size - 1, len(LOOP_INPUTS)), np.nan)
    for name, value in (inputs or {}).items():
        if name in DRIVE_INPUTS:
            continue
        col = LOOP_INPUTS.index(name)
        out[:, col] = value.step_means(edges) if isinstance(value, Trace) else float(value)
    return out


#: Inputs given in K (shown in degC on the command line, as ``--t-amb``).
KELVIN_INPUTS = ("hvac_inlet_T", "SP_evap", "SP_CoHX", "SP_vent")
#: Each input named as a request's field (```blower```), as messages name the inputs a request gives.
FIELD_LABELS = {name: f"`{name}`" for name in INPUT_NAMES}
#: Modes that can run the cabin coil or a heater: a fixed blower of 0 is refused with them (spec 2.3).
BLOWER_MODES = ("auto", "cc", "ch", "ch+bh", "ch+bc", "cc+bc", "ch-hp")
#: Largest trace file read [bytes] and most samples (a week at 1 Hz), as drive cycles.
MAX_TRACE_BYTES = 50 * 1024 * 1024
MAX_TRACE_SAMPLES = 604_800
#: Largest magnitude of a trace time [s] (a year).
MAX_TRACE_TIME = 3.2e7


def _allowed(name: str, celsius: bool) -> str:
    lo, hi, units = INPUT_RANGES[name]
    if celsius and name in KELVIN_INPUTS:
        return f"{lo - 273.15:g} to {hi - 273.15:g} degC"
    return f"{lo:g} to {hi:g}" + ("" if units == "1" else f" {units}")


def _shown(name: str, value: float, celsius: bool) -> str:
    units = INPUT_RANGES[name][2]
    if celsius and name in KELVIN_INPUTS:
        return f"{value - 273.15:g} degC"
    return f"{value:g} {units}" if units != "1" else f"{value:g}"


def _named(label: str, shown: str) -> str:
    """```blower` 0`` for a request's field, ``input blower = 0`` otherwise."""
    return f"{label} {shown}" if label.startswith("`") else f"{label} = {shown}"


def split_trace_spec(text: str) -> tuple[str, str] | None:
    """``(file, column)`` of ``"FILE.csv:column"``, or None when ``text`` is not of that form.

    The split is at the last colon, so a path may hold colons (``C:\\data\\run.csv:T``).
    """
    file, sep, column = text.rpartition(":")
    if not sep or not file.lower().endswith(".csv") or not column.strip():
        return None
    return file, column.strip()


def read_trace(path: str | Path, column: str, name: str, label: str | None = None) -> Trace:
    """Read input ``name`` from ``column`` of the trace file ``path`` (SI units).

    Format: CSV, ``#`` comment lines and blank lines skipped, a header of
    unique column names holding ``time_s`` and ``column``, then rows of as
    many cells; ``time_s`` [s] strictly increasing (any start: the trace is
    held before its first and after its last sample) and the column's values
    finite and within :data:`INPUT_RANGES`; other columns are not read.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    column : str
        The column holding the input.
    name : str
        The input (:data:`INPUT_NAMES`), for its range and units.
    label : str, optional
        How the input is named in messages (default ``name``).

    Returns
    -------
    Trace

    Raises
    ------
    EvtmsInputError
        One line naming the file, the line and the rule broken: not a
        readable regular file, above :data:`MAX_TRACE_BYTES`, not UTF-8, no
        ``time_s`` or no such column, a repeated column, a row of the wrong
        length, a cell that is not a finite number, a time that does not
        increase, a value out of range, fewer than 2 or more than
        :data:`MAX_TRACE_SAMPLES` samples.
    """
    path = Path(path)
    where = str(path)
    label = label or name
    text = read_small_text(
        path,
        "trace file",
        MAX_TRACE_BYTES,
        f"a CSV trace for {label} (time_s,{column})",
        f"a CSV trace with a header time_s,{column}",
        encoding="utf-8-sig",
    )
    lo, hi, units = INPUT_RANGES[name]
    header: list[str] | None = None
    it = iv = 0
    times: list[float] = []
    values: list[float] = []
    for number, line, cells in csv_rows(text):
        here = f"{where}:{number}"
        if header is None:
            repeated = sorted({c for c in cells if cells.count(c) > 1})
            if repeated:
                raise EvtmsInputError(f"{here}: column {repeated[0]!r} appears twice")
            if "time_s" not in cells:
                raise EvtmsInputError(f"{here}: no 'time_s' column; a trace's header names time_s and its columns")
            if column not in cells or column == "time_s":
                others = ", ".join(c for c in cells if c != "time_s") or "none"
                raise EvtmsInputError(
                    f"{here}: no column {column!r} for {label}; the header holds {others} (besides time_s)"
                )
            header, it, iv = cells, cells.index("time_s"), cells.index(column)
            continue
        if len(cells) != len(header):
            raise EvtmsInputError(f"{here}: {len(cells)} values in {line[:80]!r}; expected {len(header)}")
        try:
            t, v = float(cells[it]), float(cells[iv])
        except ValueError:
            raise EvtmsInputError(f"{here}: time_s {cells[it]!r} or {column} {cells[iv]!r} is not a number") from None
        if not (math.isfinite(t) and abs(t) <= MAX_TRACE_TIME):
            raise EvtmsInputError(f"{here}: time_s {cells[it]} is not allowed; allowed: finite, |t| <= 3.2e7 s")
        if not math.isfinite(v):
            raise EvtmsInputError(f"{here}: {column} {cells[iv]} is not finite; allowed: {_allowed(name, False)}")
        if times and t <= times[-1]:
            raise EvtmsInputError(f"{here}: time_s {t:g} s does not increase (previous {times[-1]:g} s)")
        if not lo <= v <= hi:
            raise EvtmsInputError(
                f"{here}: {column} {_shown(name, v, False)} for {label} is not allowed; "
                f"allowed: {_allowed(name, False)} (SI)"
            )
        times.append(t)
        values.append(v)
        if len(times) > MAX_TRACE_SAMPLES:
            raise EvtmsInputError(f"{where}: more than {MAX_TRACE_SAMPLES:,} samples (a week at 1 Hz)")
    if header is None:
        raise EvtmsInputError(f"{where}: empty; a trace has a header time_s,{column} and samples")
    if len(times) < 2:
        raise EvtmsInputError(
            f"{where}: {len(times)} sample(s) of {column}; a trace needs at least 2 (or give a number)"
        )
    return Trace(np.array(times), np.array(values), f"{os.fspath(path)}:{column}")


def check_inputs(
    raw: Mapping[str, object] | None,
    *,
    mode: str | None = None,
    base: str | Path | None = None,
    celsius: bool = False,
    labels: Mapping[str, str] | None = None,
) -> dict[str, InputValue]:
    """Checked inputs from what a user gave: numbers and ``"FILE.csv:column"`` traces.

    Parameters
    ----------
    raw : mapping of str to object
        Input name (:data:`INPUT_NAMES`) -> a number [SI units, or degC for
        :data:`KELVIN_INPUTS` when ``celsius``], a ``"FILE.csv:column"``
        string (a trace in SI units, :func:`read_trace`) or a :class:`Trace`.
    mode : str, optional
        The run's mode: a fixed ``blower`` of 0 anywhere (a number, or any
        sample of a trace) with a mode of :data:`BLOWER_MODES` is refused
        (spec 2.3: the blower never stops while the climate can run the cabin
        coil or a heater).
    base : str or Path, optional
        Folder a relative trace path is read from (default: the working folder).
    celsius : bool
        Numbers of temperature inputs are in degC (the command line's
        convention); messages show degC too.
    labels : mapping of str to str, optional
        How each input is named in messages (default: ``input NAME``).

    Returns
    -------
    dict of str to float or Trace
        In :data:`INPUT_NAMES` order, SI units.

    Raises
    ------
    EvtmsInputError
        One line: an unknown name, a value that is neither a finite number
        nor ``FILE.csv:column``, a number out of :data:`INPUT_RANGES`, a trace
        file that breaks :func:`read_trace`'s rules, or a blower of 0 with a
        mode that can run the cabin coil or a heater.
    """
    raw = dict(raw or {})
    for name in raw:
        if name not in INPUT_NAMES:
            raise EvtmsInputError(f"input {name!r} is unknown; allowed: {', '.join(INPUT_NAMES)}")
    out: dict[str, InputValue] = {}
    for name in INPUT_NAMES:
        if name not in raw:
            continue
        value = raw[name]
        label = (labels or {}).get(name, f"input {name}")
        if isinstance(value, Trace):
            _check_trace_values(value, name, label)
            out[name] = value
        elif isinstance(value, str):
            spec = split_trace_spec(value)
            if spec is None:
                raise EvtmsInputError(
                    f"{_named(label, repr(value))} is neither a number nor FILE.csv:column; allowed: "
                    f"{_allowed(name, celsius)} or a trace FILE.csv:column (SI units)"
                )
            file = Path(spec[0]).expanduser()
            if base is not None and not file.is_absolute():
                file = Path(base) / file
            try:
                out[name] = read_trace(file, spec[1], name, label)
            except EvtmsInputError as exc:
                raise EvtmsInputError(f"{label} {value!r}: {exc}") from None
        elif isinstance(value, bool) or not isinstance(value, int | float):
            raise EvtmsInputError(
                f"{_named(label, repr(value))} is not a number; allowed: {_allowed(name, celsius)} or FILE.csv:column"
            )
        else:
            v = float(value)
            if celsius and name in KELVIN_INPUTS:
                v = float(f"{v + 273.15:.12g}")
            lo, hi, _ = INPUT_RANGES[name]
            if not (math.isfinite(v) and lo <= v <= hi):
                shown = f"{value}" if not math.isfinite(v) else _shown(name, v, celsius)
                raise EvtmsInputError(f"{_named(label, shown)} is not allowed; allowed: {_allowed(name, celsius)}")
            out[name] = v
    if mode is not None:
        check_blower(out, mode, labels)
    return out


def _check_trace_values(trace: Trace, name: str, label: str) -> None:
    lo, hi, units = INPUT_RANGES[name]
    t, v = np.asarray(trace.time, float), np.asarray(trace.values, float)
    if t.ndim != 1 or t.shape != v.shape or t.size < 2:
        raise EvtmsInputError(f"{label} trace {trace.source!r}: give at least 2 samples, times and values alike")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise EvtmsInputError(f"{label} trace {trace.source!r}: times must be finite and strictly increasing")
    bad = ~(np.isfinite(v) & (v >= lo) & (v <= hi))
    if bad.any():
        k = int(np.argmax(bad))
        raise EvtmsInputError(
            f"{label} trace {trace.source!r}: {_shown(name, float(v[k]), False)} at {t[k]:g} s is not allowed; "
            f"allowed: {_allowed(name, False)}"
        )


def check_blower(inputs: Mapping[str, InputValue], mode: str, labels: Mapping[str, str] | None = None) -> None:
    """Refuse a fixed blower of 0 anywhere with a mode that can run the cabin coil or a heater (spec 2.3).

    Raises
    ------
    EvtmsInputError
        ``blower`` is 0, or a trace of it has a sample at 0, and ``mode`` is
        one of :data:`BLOWER_MODES`.
    """
    value = inputs.get("blower")
    if value is None or mode not in BLOWER_MODES:
        return
    label = (labels or {}).get("blower", "input blower")
    why = (
        f"is not allowed with mode {mode}, which runs the cabin coil or a heater (the blower never stops while "
        "the climate is on, spec 2.3); allowed: a blower above 0, or mode off, bh or bc"
    )
    if isinstance(value, Trace):
        zero = np.asarray(value.values) <= 0.0
        if zero.any():
            at = float(np.asarray(value.time)[int(np.argmax(zero))])
            raise EvtmsInputError(f"{label} {value.source} (0 at {at:g} s) {why}")
    elif float(value) <= 0.0:
        raise EvtmsInputError(f"{_named(label, '0')} {why}")


def describe_inputs(inputs: Mapping[str, InputValue] | None) -> dict[str, float | str]:
    """The inputs as recorded in an output file: numbers [SI] and traces by their ``FILE.csv:column``."""
    return {k: (v.source if isinstance(v, Trace) else float(v)) for k, v in (inputs or {}).items()}
