"""System-simulation figures: the time series of one run, consumption and range over the ambient.

The range figure of a depletion test (``evtms simulate --range mct|ccp``,
:mod:`evtms.system.range_test`) draws the test's range and the steady
consumption over the ambient against the Geotab and AAA 2019 field figures
(:func:`depletion_figure`); a single-trip sweep keeps the consumption split.

Reads the files of ``evtms simulate`` (:mod:`evtms.system.output`): one run
(dimension ``time``) or several ambients side by side (dimensions ``T_amb``,
``time``), with the run figures in the global attribute ``summary`` (JSON: an
object, or a list of objects along ``T_amb``). As in the other report
modules, the numbers of every figure come from a ``*_data`` function that
returns exactly what is drawn (so tests check numbers, not pixels), and the
figure is drawn with matplotlib's object API (no global state, the Agg
backend), written as PNG or SVG by the file suffix.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.reports.cycle_plots import _figure, _save

if TYPE_CHECKING:
    import xarray as xr

#: Variables the time-series figure draws.
SIMULATION_VARIABLES = (
    "speed",
    "T_cabin",
    "T_battery",
    "T_coolant",
    "P_motor_el",
    "P_hvac",
    "P_compressor",
    "P_ptc",
    "P_heater",
    "P_blower",
    "P_fan",
    "P_pump",
    "Q_evaporator",
    "Q_chiller",
    "SOC",
    "mode",
)
#: Consumption split of the range figure: label -> summary key [kWh]; together they are battery_chemical_kWh.
CONSUMPTION_PARTS = {
    "traction (motor)": "motor_energy_kWh",
    "cabin HVAC": "hvac_cabin_kWh",
    "battery thermal": "battery_thermal_kWh",
    "auxiliaries": "aux_energy_kWh",
    "battery losses": "battery_loss_kWh",
}
#: Summary keys the range figure reads.
RANGE_KEYS = (*CONSUMPTION_PARTS.values(), "battery_chemical_kWh", "distance_km", "consumption_kWh_per_100km")
#: Colour of each mode code (as ``evtms.system.loop.MODE_NAMES``: off BH BC CC CH CH+BH CH+BC CC+BC).
MODE_COLOURS = (
    "0.85",
    "tab:orange",
    "lightskyblue",
    "tab:blue",
    "tab:red",
    "darkred",
    "tab:purple",
    "tab:cyan",
)
#: Cabin setpoint [K] when the file records none (the simulator's default ``T_set``).
DEFAULT_SETPOINT = 298.15
_SWEEP_HINT = "use 'evtms simulate --t-amb a:b:n' for a sweep over the ambient"


def summaries(ds: xr.Dataset) -> list[dict]:
    """The ``summary`` attribute as a list of run summaries (one per ambient).

    Parameters
    ----------
    ds : xarray.Dataset
        A simulation output file.

    Returns
    -------
    list of dict
        One summary per run, in the order of ``T_amb`` (energies in kWh,
        distance in km, temperatures in degC).

    Raises
    ------
    EvtmsInputError
        When ``ds`` is not a simulation output (no readable ``summary``, or
        one summary count different from the number of ambients).
    """
    text = ds.attrs.get("summary")
    if not isinstance(text, str):
        raise EvtmsInputError("not an evtms simulation output (no 'summary' attribute; write one with evtms simulate)")
    try:
        data = json.loads(text)
    except ValueError:
        raise EvtmsInputError("not an evtms simulation output (its 'summary' attribute is not JSON)") from None
    runs = data if isinstance(data, list) else [data]
    if not runs or not all(isinstance(r, dict) for r in runs):
        raise EvtmsInputError("not an evtms simulation output (its 'summary' attribute is not a run summary)")
    expected = ds.sizes["T_amb"] if "T_amb" in ds.dims else 1
    if len(runs) != expected or (("T_amb" in ds.dims) != isinstance(data, list)):
        raise EvtmsInputError(f"the 'summary' attribute holds {len(runs)} runs, the file {expected} ambients")
    return runs


def check_simulation(ds: xr.Dataset, variables: tuple[str, ...] = SIMULATION_VARIABLES) -> None:
    """Refuse a dataset that is not a simulation output with ``variables``.

    Parameters
    ----------
    ds : xarray.Dataset
        Candidate simulation output.
    variables : tuple of str
        Variables the caller draws.

    Raises
    ------
    EvtmsInputError
        One line naming what is missing.
    """
    if "time" not in ds.dims:
        raise EvtmsInputError("not an evtms simulation output (no 'time' dimension; write one with evtms simulate)")
    summaries(ds)
    missing = [v for v in variables if v not in ds.variables]
    if missing:
        raise EvtmsInputError(f"not a complete evtms simulation output: missing variable(s) {', '.join(missing)}")
    for name in variables:
        if "time" not in ds[name].dims:
            raise EvtmsInputError(f"variable {name!r} has no 'time' dimension; not an evtms simulation output")


def ambients(ds: xr.Dataset) -> np.ndarray:
    """Ambient temperatures [K] of the runs in ``ds`` (one value for a single run)."""
    if "T_amb" in ds.dims:
        return np.asarray(ds["T_amb"].values, dtype=float)
    if "T_amb" in ds.attrs:
        return np.array([float(ds.attrs["T_amb"])])
    return np.array([float(summaries(ds)[0].get("T_amb_degC", np.nan)) + 273.15])


def _setpoint(ds: xr.Dataset) -> float:
    """Cabin setpoint [K] recorded in the file's ``parameters``, else the default."""
    try:
        value = json.loads(ds.attrs["parameters"])["cabin"]["T_set"]
        return float(value) if value is not None else DEFAULT_SETPOINT
    except (KeyError, TypeError, ValueError):
        return DEFAULT_SETPOINT


def _mode_names(ds: xr.Dataset) -> dict[int, str]:
    """Mode code -> name from the ``mode`` variable's CF ``flag_values``/``flag_meanings``."""
    attrs = ds["mode"].attrs
    meanings = str(attrs.get("flag_meanings", "")).split()
    values = np.atleast_1d(attrs.get("flag_values", np.arange(len(meanings))))
    if len(values) != len(meanings):
        raise EvtmsInputError("variable 'mode': flag_values and flag_meanings differ in length")
    return {int(v): m.replace("_plus_", "+") for v, m in zip(values, meanings, strict=True)}


def _title_cycle(ds: xr.Dataset) -> str:
    cycle = str(ds.attrs.get("cycle", "")) or "drive cycle"
    scenario = str(ds.attrs.get("scenario", ""))
    return f"{cycle} (scenario {scenario})" if scenario else cycle


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None or not np.isfinite(value) else format(value, spec)


def simulation_data(ds: xr.Dataset, t_amb: float | None = None) -> dict:
    """What :func:`simulation_figure` draws, in display units.

    Parameters
    ----------
    ds : xarray.Dataset
        A simulation output (one run, or a sweep with dimension ``T_amb``).
    t_amb : float, optional
        Ambient temperature [K] of the run to draw from a sweep (within
        1 mK of a value of ``T_amb``); default: the first. For a single run
        it must be the run's ambient when given.

    Returns
    -------
    dict
        ``time_min`` [min]; ``speed`` [km/h]; ``T_cabin``, ``T_battery``,
        ``T_coolant`` [degC]; ``T_amb``, ``T_set`` [degC] (scalars);
        ``P_motor_el``, ``P_hvac`` and the split ``hvac_parts`` (label ->
        array; compressor, PTC, heater, blower + fan + pump, summing to
        ``P_hvac``) [kW]; ``Q_evaporator``, ``Q_chiller`` [kW]; ``SOC`` [1];
        ``mode`` (int code per record, -1 where a run that stopped early
        has no record), ``mode_names`` (code -> name), ``summary`` (dict) and
        ``title`` (str). Powers are means over the interval ending at the
        record time (NaN at the first record).

    Raises
    ------
    EvtmsInputError
        Not a simulation output, a variable missing, or ``t_amb`` not in the file.
    """
    check_simulation(ds)
    runs = summaries(ds)
    temps = ambients(ds)
    index = 0
    if t_amb is not None:
        hits = np.flatnonzero(np.abs(temps - float(t_amb)) < 1e-3)
        if hits.size == 0:
            allowed = ", ".join(f"{t - 273.15:g}" for t in temps)
            raise EvtmsInputError(f"ambient {float(t_amb) - 273.15:g} degC is not in the file; allowed: {allowed} degC")
        index = int(hits[0])
    run = ds.isel(T_amb=index) if "T_amb" in ds.dims else ds

    def v(name: str, scale: float = 1.0, offset: float = 0.0) -> np.ndarray:
        return np.asarray(run[name].values, dtype=float) / scale + offset

    kw = 1e3
    summary = runs[index]
    T_amb = float(temps[index]) - 273.15
    hvac_parts = {
        "compressor": v("P_compressor", kw),
        "PTC air heater": v("P_ptc", kw),
        "coolant heater": v("P_heater", kw),
        "blower + fan + pump": v("P_blower", kw) + v("P_fan", kw) + v("P_pump", kw),
    }
    soc = v("SOC")
    title = (
        f"{_title_cycle(ds)} at {T_amb:g} degC: {_fmt(summary.get('distance_km'), '.1f')} km, "
        f"{_fmt(summary.get('consumption_kWh_per_100km'), '.1f')} kWh/100 km, "
        f"range {_fmt(summary.get('range_km'), '.0f')} km, HVAC {_fmt(summary.get('hvac_energy_kWh'), '.2f')} kWh, "
        f"SOC {_fmt(soc[0], '.3f')} -> {_fmt(summary.get('soc_end'), '.3f')}"
    )
    return {
        "time_min": np.asarray(run["time"].values, dtype=float) / 60.0,
        "speed": v("speed", 1.0 / 3.6),
        "T_cabin": v("T_cabin", offset=-273.15),
        "T_battery": v("T_battery", offset=-273.15),
        "T_coolant": v("T_coolant", offset=-273.15),
        "T_amb": T_amb,
        "T_set": _setpoint(ds) - 273.15,
        "P_motor_el": v("P_motor_el", kw),
        "P_hvac": v("P_hvac", kw),
        "hvac_parts": hvac_parts,
        "Q_evaporator": v("Q_evaporator", kw),
        "Q_chiller": v("Q_chiller", kw),
        "SOC": soc,
        "mode": np.asarray(run["mode"].values).astype(int),
        "mode_names": _mode_names(ds),
        "summary": summary,
        "title": title,
    }


def mode_spans(time: np.ndarray, mode: np.ndarray) -> list[tuple[int, float, float]]:
    """Runs of one mode as (code, start, end) in the units of ``time``.

    The mode of record k is the one of its interval ``(t_k-1, t_k]``; records
    with code -1 (no record: a run that stopped early) are left out.
    """
    if time.size < 2:
        return []
    codes = mode[1:]
    change = np.flatnonzero(np.diff(codes)) + 1
    starts = np.r_[0, change]
    ends = np.r_[change, codes.size]
    return [(int(codes[a]), float(time[a]), float(time[b])) for a, b in zip(starts, ends, strict=True) if codes[a] >= 0]


def simulation_figure(ds: xr.Dataset, path: str | Path, t_amb: float | None = None) -> Path:
    """Draw one run's time series: speed, temperatures, powers, heat flows, SOC and modes.

    Parameters
    ----------
    ds : xarray.Dataset
        A simulation output (one run, or a sweep with dimension ``T_amb``).
    path : str or Path
        Figure file, ``.png`` or ``.svg`` (written atomically).
    t_amb : float, optional
        Ambient temperature [K] of the run to draw from a sweep (default: the first).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    EvtmsInputError
        Not a simulation output, a variable missing, or ``t_amb`` not in the file.
    """
    from matplotlib.patches import Patch

    d = simulation_data(ds, t_amb)
    t = d["time_min"]
    fig = _figure(figsize=(10.0, 14.0))
    axes = fig.subplots(7, 1, sharex=True, height_ratios=(1.0, 1.4, 1.0, 1.2, 1.0, 0.8, 0.35))
    speed, temps, motor, hvac, heat, soc, modes = axes

    speed.plot(t, d["speed"], color="k", lw=1)
    speed.set_ylabel("speed [km/h]")

    temps.plot(t, d["T_cabin"], color="tab:blue", label="cabin air T_cabin")
    temps.plot(t, d["T_battery"], color="tab:red", label="battery T_battery")
    temps.plot(t, d["T_coolant"], color="tab:green", label="coolant T_coolant")
    temps.axhline(d["T_amb"], color="0.4", lw=1.2, label=f"ambient T_amb ({d['T_amb']:g} degC)")
    temps.axhline(d["T_set"], color="tab:blue", ls="--", lw=1, label=f"cabin setpoint ({d['T_set']:g} degC)")
    temps.set_ylabel("temperature [degC]")
    temps.legend(loc="best", fontsize="small", ncols=2)

    motor.plot(t, d["P_motor_el"], color="tab:purple", lw=0.8, drawstyle="steps-pre", label="motor P_motor_el")
    motor.axhline(0, color="0.5", lw=0.6)
    motor.set_ylabel("motor el. power [kW]")
    motor.legend(loc="upper left", fontsize="small")

    base = np.zeros_like(t)
    colours = ("tab:blue", "tab:red", "tab:orange", "tab:gray")
    for (name, part), colour in zip(d["hvac_parts"].items(), colours, strict=True):
        top = base + part
        hvac.fill_between(t, base, top, step="pre", color=colour, alpha=0.6, lw=0, label=name)
        base = top
    hvac.plot(t, d["P_hvac"], color="k", lw=0.8, drawstyle="steps-pre", label="total P_hvac")
    hvac.set_ylabel("thermal system\nel. power [kW]")
    hvac.legend(loc="upper left", fontsize="small", ncols=3)

    heat.plot(t, d["Q_evaporator"], color="tab:blue", lw=1, drawstyle="steps-pre", label="evaporator Q_evaporator")
    heat.plot(t, d["Q_chiller"], color="tab:cyan", lw=1, drawstyle="steps-pre", label="chiller Q_chiller")
    heat.axhline(0, color="0.5", lw=0.6)
    heat.set_ylabel("heat flow [kW]\n(> 0 cooling)")
    heat.legend(loc="upper left", fontsize="small")

    soc.plot(t, d["SOC"], color="k", lw=1)
    soc.set_ylabel("SOC [1]")

    seen: dict[int, str] = {}
    for code, a, b in mode_spans(t, d["mode"]):
        modes.axvspan(a, b, color=MODE_COLOURS[code % len(MODE_COLOURS)], lw=0)
        seen.setdefault(code, d["mode_names"].get(code, str(code)))
    modes.set_yticks([])
    modes.set_ylabel("mode")
    handles = [Patch(color=MODE_COLOURS[c % len(MODE_COLOURS)], label=seen[c]) for c in sorted(seen)]
    if handles:
        modes.legend(
            handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.9), ncols=len(handles), fontsize="small"
        )
    modes.set_xlabel("time [min]")
    if t.size > 1:
        modes.set_xlim(t[0], t[-1])

    for ax in axes[:-1]:
        ax.grid(alpha=0.3)
    fig.suptitle(d["title"], fontsize="medium")
    return _save(fig, path)


def range_data(ds: xr.Dataset) -> dict:
    """What :func:`range_figure` draws, from the runs' summaries.

    Parameters
    ----------
    ds : xarray.Dataset
        A simulation sweep over the ambient (dimension ``T_amb``).

    Returns
    -------
    dict
        ``T_amb`` [degC]; ``parts`` (label -> consumption [kWh/100 km] per
        ambient: traction, cabin HVAC, battery thermal, auxiliaries,
        battery losses, as :data:`CONSUMPTION_PARTS`); ``other``
        [kWh/100 km], the chemical energy the five do not hold (the energy
        left in the battery's RC branch; 0 without one), so that the parts and
        ``other`` sum to ``total``; ``total``, the summary's
        ``consumption_kWh_per_100km`` [kWh/100 km]; ``range_km`` [km] (NaN
        where the run drove no distance); ``closure``, the largest relative
        difference between the sum of the five parts and the chemical energy
        [1]; ``title`` (str).

    Raises
    ------
    EvtmsInputError
        A single run (no ``T_amb`` dimension), or a summary without the
        consumption split.
    """
    if "time" not in ds.dims:
        raise EvtmsInputError("not an evtms simulation output (no 'time' dimension; write one with evtms simulate)")
    if "T_amb" not in ds.dims:
        summaries(ds)  # a LUT or other file: 'not a simulation output' first
        raise EvtmsInputError(f"the file holds a single run; the range figure needs several ambients: {_SWEEP_HINT}")
    runs = summaries(ds)
    for key in RANGE_KEYS:
        if any(r.get(key) is None for r in runs):
            raise EvtmsInputError(f"the run summaries have no {key!r}; write the file again with evtms simulate")

    def column(key: str) -> np.ndarray:
        return np.array([float(r[key]) if r.get(key) is not None else np.nan for r in runs])

    distance = column("distance_km")
    chemical = column("battery_chemical_kWh")
    total = column("consumption_kWh_per_100km")
    per_100 = np.where(distance > 0, 100.0 / np.where(distance > 0, distance, 1.0), np.nan)
    parts = {label: column(key) * per_100 for label, key in CONSUMPTION_PARTS.items()}
    summed = sum(column(key) for key in CONSUMPTION_PARTS.values())
    with np.errstate(invalid="ignore", divide="ignore"):
        closure = np.abs(summed - chemical) / np.maximum(np.abs(chemical), 1e-300)
    other = total - sum(parts.values())
    return {
        "T_amb": ambients(ds) - 273.15,
        "parts": parts,
        "other": other,
        "total": total,
        "range_km": column("range_km"),
        "closure": float(np.nanmax(closure)) if np.isfinite(closure).any() else float("nan"),
        "title": f"Consumption and range over the ambient: {_title_cycle(ds)}",
    }


def range_figure(ds: xr.Dataset, path: str | Path, heating: Sequence[str] | None = None) -> Path:
    """Draw consumption per 100 km split by use (stacked bars) and the single-trip range against the ambient.

    Parameters
    ----------
    ds : xarray.Dataset
        A simulation sweep over the ambient (dimension ``T_amb``).
    path : str or Path
        Figure file, ``.png`` or ``.svg`` (written atomically).
    heating : sequence of str, optional
        A range test's heating options to draw (default: all).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    EvtmsInputError
        A single run, or a summary without the consumption split.

    Notes
    -----
    A depletion test's file (``evtms simulate --range mct|ccp``) gets :func:`depletion_figure` instead.
    """
    if "time" in ds.dims and range_test(ds) != "single":
        return depletion_figure(ds, path, heating)
    d = range_data(ds)
    x = d["T_amb"]
    step = float(np.min(np.diff(np.sort(x)))) if x.size > 1 else 5.0
    width = 0.8 * step if step > 0 else 4.0
    fig = _figure(figsize=(8.0, 7.0))
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    colours = ("tab:purple", "tab:blue", "tab:red", "tab:gray", "tab:orange")
    base = np.zeros_like(x)
    for (name, part), colour in zip(d["parts"].items(), colours, strict=True):
        top.bar(x, part, width, bottom=base, color=colour, label=name)
        base = base + part
    if np.nanmax(np.abs(d["other"]), initial=0.0) > 1e-9 * np.nanmax(np.abs(d["total"]), initial=0.0):
        top.bar(x, d["other"], width, bottom=base, color="0.8", label="other (RC branch)")
    top.plot(x, d["total"], "k_", ms=14, mew=2, ls="none", label="total consumption")
    top.set_ylabel("consumption [kWh/100 km]")
    top.legend(loc="best", fontsize="small", ncols=2)
    top.grid(axis="y", alpha=0.3)
    bottom.plot(x, d["range_km"], "o-", color="tab:green")
    bottom.set_ylabel("range [km]")
    bottom.set_xlabel("ambient temperature T_amb [degC]")
    bottom.grid(alpha=0.3)
    top.set_title(d["title"])
    return _save(fig, path)


#: AAA (2019), five BEVs on SAE J1634 against 75 degF (23.9 degC): range change [%] at 20 degF with the heat
#: on and at 95 degF with the A/C on. Ambient [degC] -> change [%].
AAA_2019 = {-6.7: -41.0, 35.0: -17.0}
#: The AAA baseline ambient [degC] (75 degF).
BASELINE_DEGC = 23.9
#: Geotab (4,200 EVs): at least 100 % of the rated range from 10 to about 30 degC, peak about 115 % at 21.5 degC.
GEOTAB_BAND_DEGC = (10.0, 30.0)
GEOTAB_PEAK_DEGC = 21.5
#: The range curve's expected shape (the project's spec v2 section 10 item 10, from Geotab): the peak within
#: 18-26 degC; at 20 degC at most 5 % below the peak; at 10 and at 30 degC 5-20 % below it.
PEAK_WINDOW_DEGC = (18.0, 26.0)
DROP_AT_20_MAX = 0.05
DROP_AT_10_30 = (0.05, 0.20)


def range_test(ds: xr.Dataset) -> str:
    """The file's range test: ``single`` (no ``range_test`` attribute: a v1 trip), ``mct`` or ``ccp``."""
    return str(ds.attrs.get("range_test", "single"))


def _range_runs(ds: xr.Dataset) -> list[dict]:
    """The ``range`` attribute as one figures object per run (the order of ``T_amb``)."""
    text = ds.attrs.get("range")
    try:
        data = json.loads(text) if isinstance(text, str) else None
    except ValueError:
        data = None
    runs = data if isinstance(data, list) else [data]
    if data is None or not all(isinstance(r, dict) for r in runs):
        raise EvtmsInputError(
            "the file's 'range' attribute is not a range test's figures; write it with evtms simulate"
        )
    if len(runs) != len(summaries(ds)):
        raise EvtmsInputError(f"the 'range' attribute holds {len(runs)} runs, the file {len(summaries(ds))}")
    return runs


def _heating(ds: xr.Dataset, n: int) -> list[str]:
    """Heating option per run: the ``heating`` attribute (one name, or a JSON list along ``T_amb``), else the
    runs' summaries' ``heating``; '' where the file names none (then all runs are one curve)."""
    value = ds.attrs.get("heating")
    if isinstance(value, str):
        try:
            parsed = json.loads(value)
        except ValueError:
            parsed = value
        if isinstance(parsed, list) and len(parsed) == n:
            return [str(v) for v in parsed]
        return [str(parsed)] * n
    return [str(s.get("heating", "") or "") for s in summaries(ds)]


def _at(x: np.ndarray, y: np.ndarray, x0: float) -> float | None:
    """y at x0, linear between the points (None outside them or where y is NaN there)."""
    ok = np.isfinite(y)
    if ok.sum() == 0 or not (x[ok].min() - 1e-9 <= x0 <= x[ok].max() + 1e-9):
        return None
    return float(np.interp(x0, x[ok], y[ok]))


def _checks(T: np.ndarray, r: np.ndarray) -> list[dict]:
    """The Geotab shape checks of one range curve (``T`` [degC] increasing, ``r`` [km])."""
    ok = np.isfinite(r)
    if not ok.any():
        return []
    peak_i = int(np.nanargmax(r))
    peak, T_peak = float(r[peak_i]), float(T[peak_i])
    lo, hi = PEAK_WINDOW_DEGC
    out = [
        {
            "check": "peak between 18 and 26 degC",
            "value_degC": T_peak,
            "ok": lo <= T_peak <= hi,
            "evaluated": True,
        }
    ]

    def drop(at: float, allowed: tuple[float, float], label: str) -> dict:
        value = _at(T, r, at)
        d = None if value is None or peak <= 0 else 1.0 - value / peak
        return {
            "check": label,
            "T_degC": at,
            "drop": d,
            "evaluated": d is not None,
            "interpolated": d is not None and not np.any(np.abs(T - at) < 1e-6),
            "ok": None if d is None else allowed[0] - 1e-12 <= d <= allowed[1] + 1e-12,
        }

    out.append(drop(20.0, (-np.inf, DROP_AT_20_MAX), "20 degC at most 5 % below the peak"))
    for at in (10.0, 30.0):
        out.append(drop(at, DROP_AT_10_30, f"{at:g} degC 5-20 % below the peak"))
    return out


def depletion_data(ds: xr.Dataset, heating: Sequence[str] | None = None) -> dict:
    """What :func:`depletion_figure` draws, and the report's JSON, from a depletion test's runs.

    Parameters
    ----------
    ds : xarray.Dataset
        An ``evtms simulate --range mct|ccp`` file (one ambient or a sweep).
    heating : sequence of str, optional
        The heating options to draw (default: every one in the file).

    Returns
    -------
    dict
        ``test`` (``mct`` or ``ccp``); ``range_key`` (``range_combined_km`` for mct,
        ``range_depletion_km`` for ccp); ``curves``: per heating option (``''`` when the file names none) a
        dict of arrays over the ambient, sorted: ``T_amb`` [degC], ``range_km`` (the test's range),
        ``range_ss_km``, ``single_trip_range_km`` [km], ``EC_ss_Wh_per_km`` (combined) [Wh/km],
        ``hvac_share`` [1], ``warmup_kWh`` [kWh], ``pct_vs_baseline`` [%] (against the curve's range at
        23.9 degC, linear between ambients; NaN without one), ``baseline_km`` (or None) and ``checks`` (the
        Geotab shape checks; ``breakdown``, per point the HVAC share and warm-up energy, when one fails);
        ``aaa_2019`` (ambient [degC] -> change [%]); ``geotab_band`` [degC]; ``title``.

    Raises
    ------
    EvtmsInputError
        Not a simulation output, not a depletion test's file, or a heating option the file has no run of.
    """
    if "time" not in ds.dims:
        raise EvtmsInputError("not an evtms simulation output (no 'time' dimension; write one with evtms simulate)")
    test = range_test(ds)
    if test not in ("mct", "ccp"):
        raise EvtmsInputError(
            f"range test {test!r} is not mct or ccp; write the file with 'evtms simulate --range mct' (or ccp)"
        )
    runs = _range_runs(ds)
    temps = np.round(ambients(ds) - 273.15, 9)  # K to degC without the subtraction's round-off
    heating_of_runs = _heating(ds, len(runs))
    key = "range_combined_km" if test == "mct" else "range_depletion_km"

    def num(value) -> float:
        return float(value) if value is not None else np.nan

    in_file = list(dict.fromkeys(heating_of_runs))
    missing = [h for h in (heating or ()) if h not in in_file]
    if missing:
        raise EvtmsInputError(f"`heating` {missing[0]!r}: the file has no run of it; it has {', '.join(in_file)}")
    curves = {}
    for option in heating or in_file:
        idx = [i for i, h in enumerate(heating_of_runs) if h == option]
        idx.sort(key=lambda i: temps[i])
        T = np.array([temps[i] for i in idx])
        col = {
            name: np.array([num(runs[i].get(name)) for i in idx])
            for name in (key, "range_ss_km", "single_trip_range_km", "EC_ss_combined_Wh_per_km", "hvac_share")
        }
        warm = np.array([num(runs[i].get("warmup_kWh")) for i in idx])
        base = _at(T, col[key], BASELINE_DEGC)
        pct = (col[key] / base - 1.0) * 100.0 if base else np.full(T.size, np.nan)
        checks = _checks(T, col[key])
        curve = {
            "T_amb": T,
            "range_km": col[key],
            "range_ss_km": col["range_ss_km"],
            "single_trip_range_km": col["single_trip_range_km"],
            "EC_ss_Wh_per_km": col["EC_ss_combined_Wh_per_km"],
            "hvac_share": col["hvac_share"],
            "warmup_kWh": warm,
            "pct_vs_baseline": pct,
            "baseline_km": base,
            "checks": checks,
            "runs": idx,
        }
        if any(c["ok"] is False for c in checks):
            curve["breakdown"] = [
                {
                    "T_amb_degC": float(T[j]),
                    "hvac_share": float(col["hvac_share"][j]),
                    "hvac_kWh": num(runs[idx[j]].get("hvac_kWh")),
                    "warmup_kWh": float(warm[j]),
                    "not_steady": runs[idx[j]].get("not_steady", []),
                }
                for j in range(T.size)
            ]
        curves[option] = curve
    name = "SAE J1634 multi-cycle test, combined 55/45" if test == "mct" else "UN GTR 15 consecutive WLTCs, depletion"
    return {
        "test": test,
        "range_key": key,
        "curves": curves,
        "heat_pump_gain": _heat_pump_gain(curves, summaries(ds)),
        "aaa_2019": dict(AAA_2019),
        "geotab_band": GEOTAB_BAND_DEGC,
        "title": f"Range over the ambient: {name}",
    }


#: The resistive heating a heat pump's gain is measured against, first found first.
GAIN_BASES = ("ptc_air", "ptc_coolant")
#: What a heat-pump run's summary says of where its range gain comes from (evtms.system.simulate.heat_pump_metrics).
GAIN_BREAKDOWN = ("cop_sys_mean", "cop_hp", "backup_share", "hp_heat_kWh", "waste_heat_kWh", "ambient_heat_kWh")


def _heat_pump_gain(curves: dict, runs: list[dict]) -> list[dict]:
    """The heat pump's range against the resistive heater's at each ambient both curves have, with its breakdown:
    the heating share of the energy of both, the heat pump's COPs, backup share and source heats."""
    base_name = next((b for b in GAIN_BASES if b in curves), None)
    if "heat_pump" not in curves or base_name is None:
        return []
    hp, base = curves["heat_pump"], curves[base_name]
    out = []
    for j, T in enumerate(hp["T_amb"]):
        k = np.flatnonzero(np.abs(base["T_amb"] - T) < 1e-6)
        if not k.size:
            continue
        k = int(k[0])
        r_hp, r_base = float(hp["range_km"][j]), float(base["range_km"][k])
        summary = runs[hp["runs"][j]]
        entry = {
            "T_amb_degC": float(T),
            "base": base_name,
            "range_km": r_hp if np.isfinite(r_hp) else None,
            "base_range_km": r_base if np.isfinite(r_base) else None,
            "gain_pct": (r_hp / r_base - 1.0) * 100.0 if np.isfinite(r_hp) and r_base > 0 else None,
            "hvac_share": float(hp["hvac_share"][j]),
            "base_hvac_share": float(base["hvac_share"][k]),
        }
        entry.update({name: summary.get(name) for name in GAIN_BREAKDOWN})
        out.append(entry)
    return out


def depletion_report(ds: xr.Dataset, heating: Sequence[str] | None = None) -> dict:
    """The ``evtms report range --json`` object of a depletion test: per curve the per-ambient figures, the
    Geotab shape checks and, where one fails, the per-point breakdown; the AAA 2019 comparison; the heat
    pump's gain per ambient with its breakdown (JSON-ready). ``heating``: the curves (default: all)."""
    d = depletion_data(ds, heating)

    def clean(x) -> float | None:
        return None if x is None or not np.isfinite(x) else float(x)

    curves = []
    for option, c in d["curves"].items():
        points = [
            {
                "T_amb_degC": float(c["T_amb"][j]),
                "range_km": clean(c["range_km"][j]),
                "range_ss_km": clean(c["range_ss_km"][j]),
                "single_trip_range_km": clean(c["single_trip_range_km"][j]),
                "EC_ss_Wh_per_km": clean(c["EC_ss_Wh_per_km"][j]),
                "pct_vs_23_9_degC": clean(c["pct_vs_baseline"][j]),
                "hvac_share": clean(c["hvac_share"][j]),
                "warmup_kWh": clean(c["warmup_kWh"][j]),
            }
            for j in range(c["T_amb"].size)
        ]
        aaa = {}
        for at, ref in d["aaa_2019"].items():
            value = _at(c["T_amb"], c["range_km"], at)
            base = c["baseline_km"]
            aaa[f"{at:g}"] = {
                "model_pct": None if value is None or not base else (value / base - 1) * 100,
                "aaa_pct": ref,
                "interpolated": value is not None and not np.any(np.abs(c["T_amb"] - at) < 1e-6),
            }
        entry = {"heating": option or None, "points": points, "checks": c["checks"], "aaa_2019": aaa}
        if "breakdown" in c:
            entry["breakdown"] = c["breakdown"]
        curves.append(entry)
    return {"test": d["test"], "range": d["range_key"], "curves": curves, "heat_pump_gain": d["heat_pump_gain"]}


def depletion_figure(ds: xr.Dataset, path: str | Path, heating: Sequence[str] | None = None) -> Path:
    """Draw a depletion test's range and steady consumption against the ambient.

    Top: the test's range (combined for mct, depletion for ccp) per heating option, ``range_ss`` dotted,
    the v1 single-trip range dashed, the 10-30 degC band shaded (Geotab), the change against 23.9 degC on
    the right axis with the AAA 2019 points. Bottom: the combined steady consumption EC_ss.

    Parameters
    ----------
    ds : xarray.Dataset
        An ``evtms simulate --range mct|ccp`` file.
    path : str or Path
        Figure file, ``.png`` or ``.svg`` (written atomically).
    heating : sequence of str, optional
        The heating options to draw (default: every one in the file).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    EvtmsInputError
        Not a depletion test's file.
    """
    d = depletion_data(ds, heating)
    fig = _figure(figsize=(8.5, 7.5))
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    lo, hi = d["geotab_band"]
    top.axvspan(
        lo, hi, color="tab:green", alpha=0.08, lw=0, label="Geotab: >= 100 % of rated range, peak ~115 % at 21.5 degC"
    )
    top.axvline(GEOTAB_PEAK_DEGC, color="tab:green", lw=0.8, alpha=0.5)
    colours = ("tab:blue", "tab:red", "tab:purple", "tab:orange")
    label_main = "combined range (55/45)" if d["test"] == "mct" else "depletion range"
    first = None
    for k, (option, c) in enumerate(d["curves"].items()):
        colour = colours[k % len(colours)]
        tag = f" ({option})" if option else ""
        x = c["T_amb"]
        top.plot(x, c["range_km"], "o-", color=colour, label=f"{label_main}{tag}")
        top.plot(x, c["range_ss_km"], ":", color=colour, label=f"steady range UBE/EC_ss{tag}")
        top.plot(
            x, c["single_trip_range_km"], "--", color=colour, alpha=0.6, label=f"v1 single trip, extrapolated{tag}"
        )
        bottom.plot(x, c["EC_ss_Wh_per_km"], "s-", color=colour, label=f"EC_ss{tag}")
        if first is None and c["baseline_km"]:
            first = c
    for g in d["heat_pump_gain"]:
        if g["gain_pct"] is not None:
            top.annotate(f"{g['gain_pct']:+.0f} %", (g["T_amb_degC"], g["range_km"]), textcoords="offset points",
                         xytext=(0, 7), ha="center", fontsize="x-small", color="tab:red")  # fmt: skip
    if d["heat_pump_gain"]:
        top.plot([], [], ls="none", label=f"heat pump's gain over {d['heat_pump_gain'][0]['base']} (red)")
    if first is not None:
        base = first["baseline_km"]
        right = top.secondary_yaxis(
            "right", functions=(lambda km: (km / base - 1.0) * 100.0, lambda pct: base * (1.0 + pct / 100.0))
        )
        right.set_ylabel(f"change against {BASELINE_DEGC:g} degC [%]")
        for at, pct in d["aaa_2019"].items():
            top.plot(at, base * (1.0 + pct / 100.0), "kD", ms=7, mfc="none", mew=1.5)
            left = at > float(np.mean(top.get_xlim()))
            top.annotate(f"AAA 2019: {pct:+g} %", (at, base * (1.0 + pct / 100.0)), textcoords="offset points",
                         xytext=(-8 if left else 8, -12), ha="right" if left else "left", fontsize="small")  # fmt: skip
        top.plot([], [], "kD", mfc="none", label="AAA 2019 (heat at -6.7, A/C at 35 degC)")
    top.set_ylabel("range [km]")
    top.legend(loc="best", fontsize="small")
    top.grid(alpha=0.3)
    top.set_title(d["title"], fontsize="medium")
    bottom.set_ylabel("steady consumption\nEC_ss [Wh/km]")
    bottom.set_xlabel("ambient temperature T_amb [degC]")
    bottom.grid(alpha=0.3)
    bottom.legend(loc="best", fontsize="small")
    return _save(fig, path)
