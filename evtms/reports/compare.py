"""The comparison of the modelling approaches (physics, lut, surrogate): its tables, figures and pages.

:func:`evtms.workflows.compare.run_compare` runs the approaches and fills a
:class:`CompareResult`: the **comparison table** (:class:`CompareRow`, one per
approach and scenario at the comparison step), the **trajectories** of
``T_cabin``, ``T_battery``, ``SOC`` and ``P_hvac`` (:class:`Run` records) and
the **step-size study** (:class:`StepRow`, judged by :class:`StepTolerance`).
This module draws and writes it: :func:`trajectory_data` and
:func:`trajectory_figure` (one line per approach), :func:`compare_summary`
(the JSON summary) and :func:`write_compare`, which writes the tables (CSV
and HTML), the figures, the JSON summary and an ``index.html`` linking them
into a folder, staged so that a failed run leaves the folder as it was.
"""

from __future__ import annotations

import csv
import html
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from evtms.errors import EvtmsInputError

#: Modelling approaches, in table order (``model=`` of :func:`evtms.system.simulate.simulate`).
APPROACHES = ("physics", "lut", "surrogate")
#: Record variables compared against the reference, with their units (those of the simulation file).
COMPARED: dict[str, str] = {"T_cabin": "K", "T_battery": "K", "SOC": "1", "P_hvac": "W"}
#: Interval means among :data:`COMPARED` (NaN at the first record by construction).
INTERVAL_MEANS = ("P_hvac",)
_COLOURS = {"physics": "k", "lut": "tab:blue", "surrogate": "tab:orange"}


@dataclass(frozen=True)
class StepTolerance:
    """What the step-size study calls stable.

    A run is **stable** when (a) every compared record and every followed
    summary figure is finite (the first record of an interval mean excepted),
    (b) temperatures stay within ``T_min``-``T_max`` and the SOC within 0-1,
    and (c) its summary figures are within these tolerances of the same
    approach's run at its finest sound step (finite and bounded). The defaults
    let a coarse step lose some accuracy (the LUT model at 10 s moves energies
    by about 1.5 % on WLTC) and catch what is no longer the same solution.

    Attributes
    ----------
    energy_rel : float
        Largest relative change of battery and of HVAC energy [1].
    energy_floor_kWh : float
        Energies are compared relative to max(|reference|, this) [kWh], so a
        run with almost no HVAC energy is not judged on noise.
    soc_rel : float
        Largest relative change of the SOC at the end [1].
    temperature_K : float
        Largest change of the cabin and of the battery temperature at the end [K].
    T_min, T_max : float
        Physical bounds of every recorded temperature [K].
    """

    energy_rel: float = 0.05
    energy_floor_kWh: float = 0.01
    soc_rel: float = 0.005
    temperature_K: float = 2.0
    T_min: float = 200.0
    T_max: float = 400.0


@dataclass
class Run:
    """One simulation of the comparison, reduced to what the report needs.

    Attributes
    ----------
    approach, cycle : str
        Modelling approach and drive-cycle name.
    T_amb : float
        Ambient temperature [K].
    dt : float
        Time step [s].
    records : dict of str to numpy.ndarray
        ``time`` [s] and the :data:`COMPARED` variables (K, 1, W) on the record times.
    summary : dict
        The run's summary (:attr:`evtms.system.simulate.SimulationResult.summary`);
        ``wall_time_s`` and ``loop_time_s`` are the medians over the repeats.
    out_of_range_fraction, fallback_fraction : float
        Share of records (after the first) flagged ``surrogate_out_of_range`` /
        ``physics_fallback`` [1].
    error : str or None
        Why the run produced no result (a numerical failure), else None.
    """

    approach: str
    cycle: str
    T_amb: float
    dt: float
    records: dict[str, np.ndarray] = field(default_factory=dict)
    summary: dict = field(default_factory=dict)
    out_of_range_fraction: float = 0.0
    fallback_fraction: float = 0.0
    error: str | None = None


@dataclass
class CompareRow:
    """One approach on one scenario at the comparison step (a row of ``compare.csv``).

    Units are in the names: temperatures and their errors [K] or [degC] as
    named, energies [kWh], powers [W], deviations from physics [%]; ``None``
    where a figure does not apply (no physics run, no reference for a variable).
    """

    approach: str
    cycle: str
    T_amb_degC: float
    dt_s: float
    wall_time_s: float
    loop_time_s: float
    speedup: float | None
    battery_energy_kWh: float
    hvac_energy_kWh: float
    d_battery_energy_pct: float | None
    d_hvac_energy_pct: float | None
    soc_end: float
    T_cabin_end_degC: float
    T_battery_end_degC: float
    reference: str
    compared_records: int
    rmse_T_cabin_K: float | None
    max_T_cabin_K: float | None
    rmse_T_battery_K: float | None
    max_T_battery_K: float | None
    rmse_SOC: float | None
    max_SOC: float | None
    rmse_P_hvac_W: float | None
    max_P_hvac_W: float | None
    out_of_range_fraction: float
    physics_fallback_fraction: float
    physics_solves: int | None
    termination: str


@dataclass
class StepRow:
    """One approach on one scenario at one step of the study (a row of ``steps.csv``).

    ``d_*_pct`` are relative changes [%] and ``d_*_K`` changes [K] of the
    summary figures from the run at ``reference_dt_s``, the approach's finest
    step that stayed finite and bounded; ``stable`` is ``finite and bounded
    and within_tolerance`` (:class:`StepTolerance`); ``reason`` says why not.
    """

    approach: str
    cycle: str
    T_amb_degC: float
    dt_s: float
    reference_dt_s: float | None
    finite: bool
    bounded: bool
    within_tolerance: bool
    stable: bool
    d_battery_energy_pct: float | None
    d_hvac_energy_pct: float | None
    d_soc_end_pct: float | None
    d_T_cabin_end_K: float | None
    d_T_battery_end_K: float | None
    wall_time_s: float | None
    out_of_range_fraction: float | None
    reason: str


@dataclass
class CompareResult:
    """Everything :func:`run_compare` found.

    Attributes
    ----------
    scenarios : list of (str, float)
        ``(cycle name, T_amb [K])`` in run order.
    approaches : tuple of str
        Approaches compared.
    dt : float
        Step of the comparison table [s].
    dts, physics_dts : tuple of float
        Steps of the study [s] (physics at ``physics_dts`` only).
    rows : list of CompareRow
        The comparison table.
    steps : list of StepRow
        The step-size table.
    stable_dt : dict of str to dict of str to float or None
        Largest stable step [s] per approach, by scenario label and ``all``
        (the smallest over the scenarios); None: no stable step.
    runs : dict
        The runs at ``dt`` by ``(approach, cycle, T_amb)`` (the trajectories).
    measured : dict of str to numpy.ndarray or None
        The measured reference (:func:`read_measured`), if any.
    measured_source : str
        Where it came from.
    tolerance : StepTolerance
        The study's criteria.
    """

    scenarios: list[tuple[str, float]]
    approaches: tuple[str, ...]
    dt: float
    dts: tuple[float, ...]
    physics_dts: tuple[float, ...]
    rows: list[CompareRow]
    steps: list[StepRow]
    stable_dt: dict[str, dict[str, float | None]]
    runs: dict[tuple[str, str, float], Run]
    measured: dict[str, np.ndarray] | None = None
    measured_source: str = ""
    tolerance: StepTolerance = field(default_factory=StepTolerance)


def scenario_label(cycle: str, T_amb: float) -> str:
    """``'wltc3b at -10 degC'`` for a cycle name and an ambient [K]."""
    return f"{cycle} at {T_amb - 273.15:g} degC"


# ---------------------------------------------------------------------------------------------- output


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else format(value, ".6g")
    return str(value)


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value


def compare_summary(result: CompareResult) -> dict:
    """The JSON summary (``--json``; NaN as null).

    Returns
    -------
    dict
        ``reference`` (``physics``, ``measured`` or ``none``), ``measured``
        (source or null), ``approaches``, ``scenarios`` (``cycle``,
        ``T_amb_degC``), ``dt_s``, ``dts_s``, ``physics_dts_s``, ``table``
        (the :class:`CompareRow` fields per row), ``steps`` (the
        :class:`StepRow` fields), ``largest_stable_dt_s`` (approach ->
        scenario label or ``all`` -> step [s] or null) and ``tolerance``.
    """
    if result.measured is not None:
        reference = "measured"
    elif "physics" in result.approaches:
        reference = "physics"
    else:
        reference = "none"
    return _jsonable(
        {
            "reference": reference,
            "measured": result.measured_source or (None if result.measured is None else "measured"),
            "approaches": list(result.approaches),
            "scenarios": [{"cycle": c, "T_amb_degC": round(T - 273.15, 9)} for c, T in result.scenarios],
            "dt_s": result.dt,
            "dts_s": list(result.dts),
            "physics_dts_s": list(result.physics_dts),
            "table": [asdict(r) for r in result.rows],
            "steps": [asdict(r) for r in result.steps],
            "largest_stable_dt_s": result.stable_dt,
            "tolerance": asdict(result.tolerance),
        }
    )


def trajectory_data(result: CompareResult, cycle: str, T_amb: float) -> dict:
    """What :func:`trajectory_figure` draws for one scenario, in display units.

    Returns
    -------
    dict
        ``lines``: approach -> {``time_min`` [min], ``T_cabin``, ``T_battery``
        [degC], ``SOC`` [1], ``P_hvac`` [kW]}; ``measured``: the same for the
        measured variables (or None); ``title`` (str).
    """

    def convert(rec: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = {"time_min": np.asarray(rec["time"], float) / 60.0}
        for name in COMPARED:
            if name in rec:
                v = np.asarray(rec[name], float)
                out[name] = v - 273.15 if COMPARED[name] == "K" else (v / 1e3 if name == "P_hvac" else v)
        return out

    lines = {a: convert(result.runs[(a, cycle, T_amb)].records) for a in result.approaches}
    measured = convert(result.measured) if result.measured is not None else None
    return {"lines": lines, "measured": measured, "title": f"{scenario_label(cycle, T_amb)}, dt {result.dt:g} s"}


def trajectory_figure(result: CompareResult, cycle: str, T_amb: float, path: str | Path) -> Path:
    """Overlay the approaches' T_cabin, T_battery, SOC and P_hvac against time for one scenario.

    Parameters
    ----------
    result : CompareResult
        The comparison.
    cycle : str
        Drive-cycle name.
    T_amb : float
        Ambient [K], as in ``result.scenarios``.
    path : str or Path
        Figure file, ``.png`` or ``.svg`` (written atomically).

    Returns
    -------
    Path
        ``path``.
    """
    from evtms.reports.cycle_plots import _figure, _save

    d = trajectory_data(result, cycle, T_amb)
    fig = _figure(figsize=(10.0, 10.0))
    axes = fig.subplots(4, 1, sharex=True)
    labels = {
        "T_cabin": "cabin air T_cabin [degC]",
        "T_battery": "battery T_battery [degC]",
        "SOC": "SOC [1]",
        "P_hvac": "thermal system\nel. power P_hvac [kW]",
    }
    for ax, name in zip(axes, COMPARED, strict=True):
        for a, line in d["lines"].items():
            if name in line:
                style = {"drawstyle": "steps-pre"} if name in INTERVAL_MEANS else {}
                lw = 2.2 if a == "physics" else 1.0  # the reference underneath, visible where others overlay it
                ax.plot(line["time_min"], line[name], color=_COLOURS.get(a), lw=lw, label=a, **style)
        m = d["measured"]
        if m is not None and name in m:
            ax.plot(m["time_min"], m[name], ".", color="tab:red", ms=2.5, label="measured")
        ax.set_ylabel(labels[name])
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize="small", ncols=4)
    axes[-1].set_xlabel("time [min]")
    fig.suptitle(d["title"], fontsize="medium")
    return _save(fig, path)


def _write_csv(path: Path, rows: Sequence[object], cls) -> None:
    names = [f.name for f in fields(cls)]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for r in rows:
            w.writerow([_cell(getattr(r, n)) for n in names])


def _html_table(rows: Sequence[object], cls) -> str:
    from evtms.reports.html import _table

    names = [f.name for f in fields(cls)]
    return _table([[_cell(getattr(r, n)) for n in names] for r in rows], names)


def write_compare(result: CompareResult, out_dir: str | Path, fmt: str = "png") -> list[Path]:
    """Write the comparison into ``out_dir``: tables, figures, JSON summary and ``index.html``.

    Files: ``compare.csv`` and ``compare.html`` (the comparison table),
    ``steps.csv`` and ``steps.html`` (the step-size study and the largest
    stable steps; absent when the study was not run),
    ``trajectories_<cycle>_<T>degC.<fmt>`` per scenario, ``summary.json``
    (:func:`compare_summary`) and ``index.html``. Everything is drawn into a
    staging folder beside ``out_dir`` and moved in only when all is written
    (:func:`evtms.paths.staged_folder`): a failed run leaves ``out_dir`` as
    it was.

    Parameters
    ----------
    result : CompareResult
        The comparison.
    out_dir : str or Path
        Output folder (created if missing; files of the same names replaced).
    fmt : str
        Figure format, ``png`` or ``svg``.

    Returns
    -------
    list of Path
        The files written, in ``out_dir``.
    """
    from evtms.paths import file_slug, staged_folder
    from evtms.reports.html import _page

    if fmt not in ("png", "svg"):
        raise EvtmsInputError(f"figure format {fmt!r} is not allowed; allowed: png, svg")
    out_dir = Path(out_dir)
    summary = compare_summary(result)
    names: list[str] = []
    with staged_folder(out_dir) as stage:
        _write_csv(stage / "compare.csv", result.rows, CompareRow)
        ref = summary["reference"]
        source = f" ({html.escape(result.measured_source)})" if result.measured_source else ""
        intro = (
            f"<p>Every approach on every scenario at dt {result.dt:g} s. Errors (RMSE and largest absolute) of "
            f"T_cabin [K], T_battery [K], SOC [1] and P_hvac [W] against the reference <b>{html.escape(ref)}</b>"
            f"{source} on its record times (P_hvac: means over each record's interval, the first record left "
            "out). Speed-up: physics wall time over the approach's; wall and loop times are medians of repeated "
            "runs for lut and surrogate, one run for physics (its solves are memoised across runs: see "
            "physics_solves). d_*_pct: deviation of the energy from physics.</p>"
        )
        (stage / "compare.html").write_text(
            _page("evtms approach comparison", intro + _html_table(result.rows, CompareRow)), encoding="utf-8"
        )
        names += ["compare.csv", "compare.html"]
        if result.steps:
            _write_csv(stage / "steps.csv", result.steps, StepRow)
            tol = result.tolerance
            body = (
                f"<p>Steps {', '.join(f'{d:g}' for d in result.dts)} s"
                + (f" (physics: {', '.join(f'{d:g}' for d in result.physics_dts)} s)" if result.physics_dts else "")
                + ". Each run against the same approach's finest step that stayed finite and bounded "
                "(reference_dt_s). Stable: finite (records and summary), temperatures within "
                f"{tol.T_min:g}-{tol.T_max:g} K and SOC within 0-1, battery and HVAC energy within "
                f"{100 * tol.energy_rel:g} % (relative to at least {tol.energy_floor_kWh:g} kWh), SOC end within "
                f"{100 * tol.soc_rel:g} %, cabin and battery end temperatures within {tol.temperature_K:g} K. "
                "The largest stable step is the largest step at which this and every finer step are stable.</p>"
            )
            scen = list(next(iter(result.stable_dt.values())).keys()) if result.stable_dt else []
            stable_rows = [[a, *(_cell(result.stable_dt[a].get(s)) or "none" for s in scen)] for a in result.approaches]
            body += "<h2>Largest stable step [s]</h2>" + _table_plain(stable_rows, ["approach", *scen])
            body += "<h2>Runs</h2>" + _html_table(result.steps, StepRow)
            (stage / "steps.html").write_text(_page("evtms step-size study", body), encoding="utf-8")
            names += ["steps.csv", "steps.html"]
        figures = []
        for cycle, T in result.scenarios:
            name = f"trajectories_{file_slug(cycle)}_{T - 273.15:g}degC.{fmt}"
            trajectory_figure(result, cycle, T, stage / name)
            figures.append((scenario_label(cycle, T), name))
            names.append(name)
        (stage / "summary.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
        names.append("summary.json")
        links = "".join(
            f'<li><a href="{n}">{html.escape(n)}</a></li>'
            for n in ("compare.html", "compare.csv", "steps.html", "steps.csv", "summary.json")
            if n in names
        )
        figs = "".join(
            f'<figure><a href="{n}"><img src="{n}" alt="{html.escape(c)}"></a>'
            f"<figcaption>{html.escape(c)}</figcaption></figure>"
            for c, n in figures
        )
        scen_list = ", ".join(scenario_label(c, T) for c, T in result.scenarios)
        body = (
            f"<p>Approaches {', '.join(result.approaches)} on {html.escape(scen_list)}; reference: "
            f"{html.escape(ref)}{source}.</p><ul>{links}</ul><h2>Trajectories</h2>{figs}"
        )
        (stage / "index.html").write_text(_page("evtms approach comparison", body), encoding="utf-8")
        names.append("index.html")
    return [out_dir / n for n in names]


def _table_plain(rows: Sequence[Sequence[object]], header: Sequence[str]) -> str:
    from evtms.reports.html import _table

    return _table(rows, header)
