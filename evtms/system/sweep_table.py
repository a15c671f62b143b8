"""The summary table of a simulation sweep: one row per scenario, as netCDF or CSV (``docs/sweep-format.md``).

A row holds the scenario's inputs (drive cycle, parameter set, ambient, mode,
model) and the figures of its run, taken from the run's summary (the
``evtms simulate --json`` object, same names and units: energies in kWh,
temperatures in degC) and from its records (the battery's coldest and
warmest temperature). :func:`run_figures` computes a run's figures,
:func:`write_table` writes the table atomically (a temporary file renamed
over the output: a concurrent reader or a second sweep to the same file
never sees a partial one) and :func:`read_table` reads either format back.
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms.errors import EvtmsInputError


@dataclass(frozen=True)
class Column:
    """One column: name, kind (``str``, ``int`` or ``float``), units and meaning."""

    name: str
    kind: str
    units: str
    long_name: str


def _f(name: str, units: str, long_name: str) -> Column:
    return Column(name, "float", units, long_name)


#: The scenario's inputs.
INPUT_COLUMNS = (
    Column("scenario", "int", "1", "scenario number, 0 first (the order of docs/sweep-format.md)"),
    Column("cycle", "str", "", "drive cycle as given: a built-in name, parked:SECONDS or a CSV file"),
    Column("params", "str", "", "system TOML file of the parameter set (empty: the defaults)"),
    _f("T_amb_degC", "degC", "ambient temperature"),
    _f("RH_amb", "1", "ambient relative humidity"),
    _f("sun", "W m-2", "solar irradiance"),
    Column("mode", "str", "", "mode requested: auto or a forced mode"),
    Column("model", "str", "", "refrigerant-loop model: lut or surrogate"),
)
#: Figures of the run (NaN where the run has none: a parked run's Wh/km, a pull-down never reached, a failed run).
FIGURE_COLUMNS = (
    Column("status", "str", "", "end of cycle, soc_min (the battery reached its floor first) or error"),
    Column("message", "str", "", "why the run failed (empty otherwise)"),
    _f("distance_km", "km", "distance driven"),
    _f("duration_s", "s", "duration of the cycle"),
    _f("battery_energy_kWh", "kWh", "energy at the battery terminals (> 0 discharged)"),
    _f("hvac_energy_kWh", "kWh", "electrical energy of the thermal system while driving"),
    _f("hvac_cabin_kWh", "kWh", "part of it for the cabin"),
    _f("battery_thermal_kWh", "kWh", "part of it for the battery"),
    _f("traction_energy_kWh", "kWh", "positive energy at the wheels"),
    _f("aux_energy_kWh", "kWh", "energy of the auxiliaries"),
    _f("battery_loss_kWh", "kWh", "heat generated in the battery"),
    _f("battery_Wh_per_km", "Wh km-1", "battery terminal energy per km"),
    _f("hvac_Wh_per_km", "Wh km-1", "thermal system energy per km"),
    _f("consumption_kWh_per_100km", "kWh (100 km)-1", "battery chemical energy per 100 km"),
    _f("range_km", "km", "range on the usable energy at this consumption (the cycle repeated)"),
    _f("soc_end", "1", "state of charge at the end"),
    _f("T_cabin_end_degC", "degC", "cabin air temperature at the end"),
    _f("t_pulldown_s", "s", "first time the cabin air's 60-s mean is within 1 K of its setpoint"),
    _f("cabin_dev_max_K", "K", "largest deviation of that mean from the setpoint after the pull-down"),
    _f("T_supply_min_degC", "degC", "coldest vent air (step mean)"),
    _f("T_battery_min_degC", "degC", "coldest battery temperature of the records"),
    _f("T_battery_max_degC", "degC", "warmest battery temperature of the records"),
    _f("T_battery_end_degC", "degC", "battery temperature at the end"),
    _f("compressor_starts", "1", "compressor starts"),
    _f("mode_changes", "1", "mode changes"),
    _f("ledger_worst", "1", "worst relative residual of the energy ledgers"),
    _f("loop_time_s", "s", "time of the simulator's loop"),
    Column("run_file", "str", "", "the run's own netCDF file (empty: not written)"),
)
COLUMNS = INPUT_COLUMNS + FIGURE_COLUMNS
_BY_NAME = {c.name: c for c in COLUMNS}
#: Summary keys copied as they are (the others are computed by :func:`run_figures`).
_FROM_SUMMARY = (
    "distance_km",
    "duration_s",
    "battery_energy_kWh",
    "hvac_energy_kWh",
    "hvac_cabin_kWh",
    "battery_thermal_kWh",
    "traction_energy_kWh",
    "aux_energy_kWh",
    "battery_loss_kWh",
    "consumption_kWh_per_100km",
    "range_km",
    "soc_end",
    "T_cabin_end_degC",
    "t_pulldown_s",
    "cabin_dev_max_K",
    "T_supply_min_degC",
    "T_battery_end_degC",
    "compressor_starts",
    "mode_changes",
    "ledger_worst",
    "loop_time_s",
)
TITLE = "evtms simulation sweep"


def _number(value) -> float:
    return math.nan if value is None else float(value)


def run_figures(result) -> dict:
    """The figure columns of a finished run (:class:`evtms.system.simulate.SimulationResult`)."""
    s = result.summary
    row = {k: _number(s.get(k)) for k in _FROM_SUMMARY}
    km = row["distance_km"]
    per_km = km > 0
    row["battery_Wh_per_km"] = row["battery_energy_kWh"] * 1e3 / km if per_km else math.nan
    row["hvac_Wh_per_km"] = row["hvac_energy_kWh"] * 1e3 / km if per_km else math.nan
    T = np.asarray(result.records["T_battery"], float)
    finite = T[np.isfinite(T)]
    row["T_battery_min_degC"] = float(finite.min() - 273.15) if finite.size else math.nan
    row["T_battery_max_degC"] = float(finite.max() - 273.15) if finite.size else math.nan
    row["status"] = s["termination"]
    row["message"] = ""
    row["run_file"] = ""
    return row


def failed_figures(index: int, run, message: str) -> dict:
    """The figure columns of run ``index`` that failed (``failed`` of a sweep's context): status ``error``, the
    message, NaN figures."""
    row = {c.name: (math.nan if c.kind == "float" else "") for c in FIGURE_COLUMNS}
    row.update(status="error", message=" ".join(message.split()))
    return row


@dataclass
class SweepTable:
    """The rows of a sweep (one dict per scenario, keys :data:`COLUMNS`) and the table's attributes.

    Attributes
    ----------
    rows : list of dict
        Column name -> value (str, int or float) per scenario, in scenario order.
    attrs : dict
        Global attributes (strings and numbers): the sweep's options and timing.
    """

    rows: list[dict]
    attrs: dict = field(default_factory=dict)

    def column(self, name: str) -> list:
        """One column's values, in scenario order."""
        return [r[name] for r in self.rows]


def _global_attrs(table: SweepTable) -> dict:
    created = dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    return {"Conventions": "CF-1.10", "title": TITLE, "evtms_version": __version__, "created": created, **table.attrs}


def write_table(table: SweepTable, path: str | Path) -> Path:
    """Write ``table`` to ``path`` (``.nc``: netCDF-4, ``.csv``: CSV), atomically.

    The file appears whole or not at all: it is written to a temporary file
    beside ``path`` and renamed over it (:func:`evtms.luts.io.atomic_output`).
    """
    from evtms.luts.io import atomic_output

    path = Path(path)
    with atomic_output(path) as tmp:
        if path.suffix.lower() == ".csv":
            _write_csv(table, tmp)
        else:
            _write_netcdf(table, tmp)
    return path


def _write_netcdf(table: SweepTable, tmp: Path) -> None:
    """netCDF-4 through netCDF4 itself (xarray would import dask for a table of a few thousand rows)."""
    import netCDF4

    with netCDF4.Dataset(tmp, "w", format="NETCDF4") as ds:
        ds.createDimension("scenario", len(table.rows))
        for key, value in _global_attrs(table).items():
            ds.setncattr(key, value)
        for c in COLUMNS:
            values = table.column(c.name)
            if c.kind == "str":
                var = ds.createVariable(c.name, str, ("scenario",))
                var[:] = np.array(values, dtype=object)
            else:
                dtype = np.int64 if c.kind == "int" else np.float64
                var = ds.createVariable(c.name, dtype, ("scenario",), zlib=True, complevel=1)
                var[:] = np.array(values, dtype=dtype)
            var.long_name = c.long_name
            if c.units:
                var.units = c.units


def _text(value, kind: str) -> str:
    if kind == "float":
        return "" if not math.isfinite(value) else repr(float(value))
    return str(value)


def _write_csv(table: SweepTable, tmp: Path) -> None:
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        for key, value in _global_attrs(table).items():
            f.write(f"# {key}: {json.dumps(value)}\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow([c.name for c in COLUMNS])
        w.writerow([c.units for c in COLUMNS])
        for row in table.rows:
            w.writerow([_text(row[c.name], c.kind) for c in COLUMNS])


def _parse(text: str, kind: str):
    if kind == "str":
        return text
    if kind == "int":
        return int(text)
    return math.nan if text == "" else float(text)


def read_table(path: str | Path) -> SweepTable:
    """A summary table written by :func:`write_table` (netCDF or CSV, by suffix).

    Raises
    ------
    EvtmsInputError
        Not a sweep table (another title, a column missing).
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return _read_csv(path)
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        ds.set_auto_mask(False)
        if getattr(ds, "title", None) != TITLE:
            raise EvtmsInputError(f"{str(path)!r} is not an evtms sweep table (title {getattr(ds, 'title', None)!r})")
        missing = [c.name for c in COLUMNS if c.name not in ds.variables]
        if missing:
            raise EvtmsInputError(f"sweep table {str(path)!r} has no column {missing[0]!r}")
        columns = {c.name: _column(ds.variables[c.name][:], c.kind) for c in COLUMNS}
        attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in ds.__dict__.items()}
    n = len(columns["scenario"])
    return SweepTable([{name: columns[name][i] for name in columns} for i in range(n)], attrs)


def _column(values: np.ndarray, kind: str) -> list:
    if kind == "str":
        return ["" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v) for v in values]
    return [int(v) for v in values] if kind == "int" else [float(v) for v in values]


def _read_csv(path: Path) -> SweepTable:
    attrs = {}
    with open(path, newline="", encoding="utf-8") as f:
        lines = [line for line in f]
    body = []
    for line in lines:
        if line.startswith("# ") and not body:
            key, _, value = line[2:].rstrip("\n").partition(": ")
            attrs[key] = json.loads(value)
        else:
            body.append(line)
    if attrs.get("title") != TITLE:
        raise EvtmsInputError(f"{str(path)!r} is not an evtms sweep table (title {attrs.get('title')!r})")
    reader = csv.reader(body)
    header = next(reader)
    next(reader)  # the units
    missing = [c.name for c in COLUMNS if c.name not in header]
    if missing:
        raise EvtmsInputError(f"sweep table {str(path)!r} has no column {missing[0]!r}")
    at = {name: i for i, name in enumerate(header)}
    rows = [{c.name: _parse(r[at[c.name]], c.kind) for c in COLUMNS} for r in reader]
    return SweepTable(rows, attrs)


def column(name: str) -> Column:
    """The column ``name`` (:data:`COLUMNS`)."""
    return _BY_NAME[name]


#: The marker file a sweep's run folder holds while the sweep runs: a worker that reads the same token in it
#: writes its runs there itself; elsewhere (a cluster without the folder) the file's bytes come back.
RUNS_MARKER = ".evtms-sweep-token"


def run_file_name(index: int, n: int) -> str:
    """The file name of run ``index`` of ``n`` in the run folder: ``run-0042.nc`` (digits enough for ``n``)."""
    return f"run-{index:0{max(len(str(n - 1)), 4)}d}.nc"


class SweepRows:
    """The ``reduce`` of a sweep (:class:`evtms.system.sweep.SweepContext`): a run's figure columns.

    With ``runs`` (a folder) each run's time series is written there too
    (:func:`evtms.system.output.write_simulation`, atomically): by the worker
    itself when it sees the folder (its :data:`RUNS_MARKER` holds ``token``),
    else its bytes travel back and the main process writes them
    (:func:`write_run_bytes`).
    """

    def __init__(self, n: int, runs: str | None = None, token: str | None = None) -> None:
        self.n, self.runs, self.token = n, runs, token

    def __call__(self, index: int, run, result) -> dict:
        row = run_figures(result)
        if self.runs is None:
            return row
        name = run_file_name(index, self.n)
        row["run_file"] = name
        if _sees(self.runs, self.token):
            from evtms.system.output import write_simulation

            write_simulation([result], Path(self.runs) / name)
        else:
            row["run_bytes"] = _netcdf_bytes(result)
        return row


def _sees(folder: str, token: str | None) -> bool:
    try:
        return token is not None and (Path(folder) / RUNS_MARKER).read_text() == token
    except OSError:
        return False


def _netcdf_bytes(result) -> bytes:
    import tempfile

    from evtms.system.output import write_simulation

    with tempfile.TemporaryDirectory(prefix="evtms-run-") as tmp:
        path = write_simulation([result], Path(tmp) / "run.nc")
        return path.read_bytes()


def write_run_bytes(folder: Path, name: str, data: bytes) -> None:
    """Write a run file that came back as bytes into ``folder``, atomically."""
    from evtms.luts.io import atomic_output

    with atomic_output(Path(folder) / name) as tmp:
        tmp.write_bytes(data)
