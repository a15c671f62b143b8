"""Numeric tables of the system simulator and their 2-D lookup.

The e-drive loss map and torque characteristic and the battery cell OCV and
R0 tables are numbers from the MathWorks example
``simscape/Optimize-BEV-Thermal-Management-with-Simscape`` (spec ``system.md``
"MW P"), shipped as package data in ``evtms/system/data/`` (``edrive.json``,
``battery_cell.json``; provenance, licence note and transformations in
``SOURCE_MW.md`` there). The loss map is stored WITHOUT the source's factor
1.1: the simulator applies it (spec 2.1).

The loaders return frozen dataclasses of read-only float arrays, read once
per process. :func:`bilinear_clamped` is the vectorised bilinear lookup the
spec prescribes for both tables (clamped to the axes, no extrapolation).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data"


@dataclass(frozen=True)
class EdriveTables:
    """E-drive loss map and torque characteristic (MW P ``Edrive``).

    Attributes
    ----------
    speed_rpm : numpy.ndarray
        Loss-map speed axis [rpm], shape (10,), 500 ... 10000.
    torque_Nm : numpy.ndarray
        Loss-map torque axis [N m], shape (10,), 10 ... 200.
    loss_W : numpy.ndarray
        Motor loss [W], shape (10, 10): ``loss_W[i, j]`` at ``speed_rpm[i]``,
        ``torque_Nm[j]``. Source values without the spec's factor 1.1; cells
        at shaft power >= 62.8 kW hold the source's placeholder (half the
        shaft power).
    curve_speed_rpm : numpy.ndarray
        Torque-characteristic speed axis [rpm], shape (200,), 1 ... 23875.
    curve_torque_Nm : numpy.ndarray
        Largest motor torque [N m] at ``curve_speed_rpm``: 200 N m up to the
        100 kW corner, then constant power.
    max_torque_Nm : float
        Torque limit [N m] (200).
    max_power_W : float
        Power limit [W] (100 kW).
    source : str
        Repository, commit, file and variables the numbers come from.
    """

    speed_rpm: np.ndarray
    torque_Nm: np.ndarray
    loss_W: np.ndarray
    curve_speed_rpm: np.ndarray
    curve_torque_Nm: np.ndarray
    max_torque_Nm: float
    max_power_W: float
    source: str


@dataclass(frozen=True)
class BatteryCellTables:
    """Battery cell OCV and ohmic resistance over SOC and temperature (MW P ``ModuleType1``).

    Attributes
    ----------
    soc : numpy.ndarray
        State-of-charge axis [1], shape (101,), 0 ... 1 in steps of 0.01.
    temperature_K : numpy.ndarray
        Temperature axis [K], shape (7,): -40, -30, -20, 0, 23, 45, 60 degC.
    ocv_V : numpy.ndarray
        Cell open-circuit voltage [V], shape (101, 7): ``ocv_V[i, j]`` at
        ``soc[i]``, ``temperature_K[j]`` (the source's columns are equal).
    r0_ohm : numpy.ndarray
        Cell ohmic resistance [ohm], same grid.
    source : str
        Repository, commit, file and variables the numbers come from.
    """

    soc: np.ndarray
    temperature_K: np.ndarray
    ocv_V: np.ndarray
    r0_ohm: np.ndarray
    source: str


def _array(values: object, name: str, ndim: int) -> np.ndarray:
    """Read-only float64 array of ``values``, checked for rank and finiteness."""
    arr = np.array(values, dtype=np.float64)
    if arr.ndim != ndim or not np.all(np.isfinite(arr)):
        raise ValueError(f"package table {name}: expected a finite {ndim}-D array")
    arr.setflags(write=False)
    return arr


def _source(doc: dict) -> str:
    """One-line provenance from a data file's ``source`` object."""
    src = doc["source"]
    names = ", ".join(src["variables"].values())
    return f"{src['repository']}@{src['commit'][:12]} {src['file']}: {names}"


def _load(name: str) -> dict:
    with open(DATA / name, encoding="utf-8") as fh:
        return json.load(fh)


@functools.cache
def edrive_tables() -> EdriveTables:
    """The e-drive loss map and torque characteristic (``data/edrive.json``).

    Returns
    -------
    EdriveTables
        Read-only arrays; the same object on every call.
    """
    doc = _load("edrive.json")
    loss = doc["loss_map"]
    curve = doc["torque_characteristic"]
    tables = EdriveTables(
        speed_rpm=_array(loss["speed_rpm"], "loss_map.speed_rpm", 1),
        torque_Nm=_array(loss["torque_Nm"], "loss_map.torque_Nm", 1),
        loss_W=_array(loss["loss_W"], "loss_map.loss_W", 2),
        curve_speed_rpm=_array(curve["speed_rpm"], "torque_characteristic.speed_rpm", 1),
        curve_torque_Nm=_array(curve["torque_max_Nm"], "torque_characteristic.torque_max_Nm", 1),
        max_torque_Nm=float(curve["max_torque_Nm"]),
        max_power_W=float(curve["max_power_W"]),
        source=_source(doc),
    )
    _check_grid(tables.speed_rpm, tables.torque_Nm, tables.loss_W)
    if tables.curve_speed_rpm.shape != tables.curve_torque_Nm.shape:
        raise ValueError("package table torque_characteristic: speed and torque differ in length")
    _check_axis(tables.curve_speed_rpm)
    return tables


@functools.cache
def battery_cell_tables() -> BatteryCellTables:
    """The battery cell OCV and R0 tables (``data/battery_cell.json``).

    Returns
    -------
    BatteryCellTables
        Read-only arrays; the same object on every call.
    """
    doc = _load("battery_cell.json")
    tables = BatteryCellTables(
        soc=_array(doc["soc"], "soc", 1),
        temperature_K=_array(doc["temperature_K"], "temperature_K", 1),
        ocv_V=_array(doc["ocv_V"], "ocv_V", 2),
        r0_ohm=_array(doc["r0_ohm"], "r0_ohm", 2),
        source=_source(doc),
    )
    _check_grid(tables.soc, tables.temperature_K, tables.ocv_V)
    _check_grid(tables.soc, tables.temperature_K, tables.r0_ohm)
    return tables


def _check_axis(axis: np.ndarray) -> None:
    if axis.ndim != 1 or axis.size < 2 or not np.all(np.diff(axis) > 0):
        raise ValueError("table axis must be 1-D, strictly increasing, with at least 2 points")


def _check_grid(x_axis: np.ndarray, y_axis: np.ndarray, table: np.ndarray) -> None:
    _check_axis(x_axis)
    _check_axis(y_axis)
    if table.shape != (x_axis.size, y_axis.size):
        raise ValueError(f"table shape {table.shape} does not match the axes ({x_axis.size}, {y_axis.size})")


def _cell(axis: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower node index and weight in [0, 1] of ``v`` clamped to ``axis``."""
    v = np.clip(v, axis[0], axis[-1])
    i = np.clip(np.searchsorted(axis, v, side="right") - 1, 0, axis.size - 2)
    w = (v - axis[i]) / (axis[i + 1] - axis[i])
    return i, w


def bilinear_clamped(
    x_axis: np.ndarray,
    y_axis: np.ndarray,
    table: np.ndarray,
    x: np.ndarray | float,
    y: np.ndarray | float,
) -> np.ndarray:
    """Bilinear interpolation in a 2-D table, clamped to the axes' ranges.

    Parameters
    ----------
    x_axis : numpy.ndarray
        First axis, shape (nx,), strictly increasing, nx >= 2, in the unit of
        ``x`` (e.g. speed [rpm] for the loss map, SOC [1] for the cell tables).
    y_axis : numpy.ndarray
        Second axis, shape (ny,), strictly increasing, ny >= 2, in the unit of
        ``y`` (e.g. torque [N m], temperature [K]).
    table : numpy.ndarray
        Values, shape (nx, ny), ``table[i, j]`` at ``(x_axis[i], y_axis[j])``,
        in any unit (e.g. loss [W], OCV [V], R0 [ohm]).
    x, y : array_like
        Query points in the axes' units; broadcast against each other.
        Values outside an axis are clamped to its end (no extrapolation);
        NaN gives NaN.

    Returns
    -------
    numpy.ndarray
        Interpolated values in the unit of ``table``, with the broadcast shape
        of ``x`` and ``y`` (a numpy float64 scalar when both are scalars).
        Exact at the nodes, linear along each axis between them.

    Raises
    ------
    ValueError
        An axis is not 1-D and strictly increasing with >= 2 points, or the
        table's shape is not ``(nx, ny)``.
    """
    x_axis = np.asarray(x_axis, dtype=np.float64)
    y_axis = np.asarray(y_axis, dtype=np.float64)
    table = np.asarray(table, dtype=np.float64)
    _check_grid(x_axis, y_axis, table)
    xq, yq = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    i, wx = _cell(x_axis, xq)
    j, wy = _cell(y_axis, yq)
    out = (1.0 - wx) * ((1.0 - wy) * table[i, j] + wy * table[i, j + 1]) + wx * (
        (1.0 - wy) * table[i + 1, j] + wy * table[i + 1, j + 1]
    )
    return out[()]
