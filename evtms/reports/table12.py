"""The Table 12 mode experiments as tables: plain text, JSON, CSV and HTML.

:func:`table12_text` lays out the thesis's columns per row (mode, inputs
T_amb, Tbatt, Qloss, Tin, SP_evap, blower, SP_CoHX in degC, W and 1, time per
simulation, error against the reference approach, P_el, capacity_limited);
:func:`table12_summary` is the same as JSON (SI units);
:func:`write_table12` writes ``table12.csv``, ``table12.html`` and
``table12.json`` into a folder, staged so that a failed write leaves it as it
was. The runs are :func:`evtms.system.table12.run_table12`'s.

References
----------
Thesis Table 12; the project's system spec v2, section 4.
"""

from __future__ import annotations

import csv
import html
import json
import math
from dataclasses import asdict, fields
from pathlib import Path

from evtms.system.table12 import CAPACITY_TOLERANCE_K, CAPACITY_WINDOW_S, Table12Result, Table12Row

#: Columns of the text table: header, width.
_COLUMNS = (
    ("scenario", 9),
    ("approach", 9),
    ("mode", 4),
    ("T_amb", 6),
    ("Tbatt", 6),
    ("Qloss", 6),
    ("Tin", 6),
    ("SP_evap", 7),
    ("blower", 6),
    ("SP_CoHX", 7),
    ("time_s", 7),
    ("err_K", 6),
    ("P_el_W", 7),
    ("capacity", 8),
)


def _degc(value) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return "trace"
    return f"{value - 273.15:.1f}"


def _plain(value, fmt: str = "{:g}") -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return "trace"
    return fmt.format(value)


def _num(value, fmt: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return fmt.format(value)


def _capacity(row: Table12Row) -> str:
    if not row.capacity_setpoints:
        return "-"
    if row.capacity_limited is None:
        return "n/a"
    return "limited" if row.capacity_limited else "held"


def _cells(row: Table12Row) -> list[str]:
    err = "ref" if row.reference == row.approach else _num(row.rmse_K, "{:.3f}")
    return [
        row.scenario.removeprefix("t12-"),
        row.approach,
        row.mode,
        _degc(row.T_amb_K),
        _degc(row.T_battery0_K),
        _plain(row.Q_loss_W, "{:.0f}"),
        _degc(row.T_in_K),
        _degc(row.SP_evap_K),
        _plain(row.blower, "{:.2f}"),
        _degc(row.SP_CoHX_K),
        _num(row.wall_time_s, "{:.3f}"),
        err,
        _num(row.P_el_W, "{:.0f}"),
        _capacity(row),
    ]


def table12_text(result: Table12Result) -> str:
    """The rows as a fixed-width text table with notes below it (temperatures in degC)."""
    lines = ["  ".join(h.rjust(w) if i > 2 else h.ljust(w) for i, (h, w) in enumerate(_COLUMNS))]
    widths = [w for _, w in _COLUMNS]
    for row in result.rows:
        cells = _cells(row)
        lines.append(
            "  ".join(c.rjust(w) if i > 2 else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths, strict=True)))
        )
    notes = [
        "T_amb, Tbatt, Tin, SP_evap, SP_CoHX [degC]; Qloss, P_el [W]; time per simulation [s]; "
        f"err_K: RMSE of T_battery (bh, bc) or T_cabin against {result.reference or 'no reference'}",
        f"P_el: the thesis's sum per mode, mean over the run; capacity: SP_evap and SP_CoHX held within "
        f"{CAPACITY_TOLERANCE_K:g} K over the last {CAPACITY_WINDOW_S / 60:g} min (- : no setpoint given)",
    ]
    missing = sorted({(r.mode, r.P_el_missing) for r in result.rows if r.P_el_missing})
    for mode, names in missing:
        notes.append(f"P_el n/a for {mode}: no record {names} in this build")
    unchecked = sorted({r.capacity_note for r in result.rows if r.capacity_limited is None and r.capacity_note})
    for note in unchecked:
        notes.append(f"capacity n/a: {note}")
    traces = sorted({r.scenario for r in result.rows for c in _cells(r) if c == "trace"})
    if traces:
        notes.append(f"trace inputs in {', '.join(traces)}: the JSON summary (table12.json) names their files")
    for approach, why in result.skipped.items():
        notes.append(f"{approach} not run: {why}")
    return "\n".join(lines + [""] + [f"note: {n}" for n in notes])


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def table12_summary(result: Table12Result) -> dict:
    """The rows and run settings as one JSON-ready dict (SI units)."""
    return {
        "approaches": list(result.approaches),
        "reference": result.reference,
        "dt_s": result.dt,
        "repeat": result.repeat,
        "capacity_window_s": CAPACITY_WINDOW_S,
        "capacity_tolerance_K": CAPACITY_TOLERANCE_K,
        "skipped": dict(result.skipped),
        "rows": [{k: _jsonable(v) for k, v in asdict(r).items()} for r in result.rows],
    }


def write_table12(result: Table12Result, out_dir: str | Path) -> list[Path]:
    """Write ``table12.csv``, ``table12.html`` and ``table12.json`` into ``out_dir`` (staged); the files written."""
    from evtms.paths import staged_folder
    from evtms.reports.html import _page, _table

    out_dir = Path(out_dir)
    names = [f.name for f in fields(Table12Row)]
    written = ["table12.csv", "table12.html", "table12.json"]
    with staged_folder(out_dir) as stage:
        with open(stage / "table12.csv", "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(names)
            for r in result.rows:
                w.writerow(["" if getattr(r, n) is None else getattr(r, n) for n in names])
        header = [h for h, _ in _COLUMNS]
        body = _table([_cells(r) for r in result.rows], header)
        text = table12_text(result).splitlines()
        notes = "".join(f"<p>{html.escape(line[6:])}</p>" for line in text if line.startswith("note:"))
        (stage / "table12.html").write_text(_page("Table 12 mode experiments", body + notes), encoding="utf-8")
        (stage / "table12.json").write_text(json.dumps(table12_summary(result), allow_nan=False), encoding="utf-8")
    return [out_dir / n for n in written]
