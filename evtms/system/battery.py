"""Battery pack: equivalent circuit after Gao et al. (2002), the electrical side.

A pack of ``Ns`` cells in series and ``Np`` in parallel: EMF ``E = Ns
OCV(SOC)`` [V] (the Simscape example's OCV has no temperature dependence),
ohmic resistance ``R1 = R0(SOC, T_battery) Ns / Np`` [ohm] (bilinear and
clamped in the cell table, :func:`evtms.system.tables.battery_cell_tables`),
and an optional RC branch (``v_rc`` [V]; off by default, no source gives its
values). For a terminal power ``P`` [W] (> 0 discharging) the current is the
smaller root of ``R1 i^2 - (E - v_rc) i + P = 0``:

.. math:: i = \\frac{(E - v_{rc}) - \\sqrt{(E - v_{rc})^2 - 4 R_1 P}}{2 R_1}

so that ``v i = P`` exactly with ``v = E - v_rc - R1 i``. The terminal voltage
binds first: the power is capped at the one that brings ``v`` to ``Ns
v_min``, ``P_cap = Ns v_min (E - v_rc - Ns v_min) / R1``; a point above it
gets the cap and is flagged. Heat ``Q_gen = R1 i^2`` (+ ``v_rc^2 / R2`` with
the RC branch), so ``E i = v i + Q_gen`` (+ the RC branch's stored energy) to
round-off. SOC falls as ``dSOC/dt = -i / (3600 Q_Ah)`` with ``Q_Ah = Np
Q_cell``.

References
----------
Gao, L., Liu, S., Dougal, R. A. (2002). Dynamic lithium-ion battery model for
system simulation. IEEE Transactions on Components and Packaging
Technologies 25(3), 495-505.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from evtms.params import Relation, ordered, param
from evtms.system.tables import BatteryCellTables, battery_cell_tables, bilinear_clamped


@dataclass(frozen=True)
class BatteryParams:
    """Pack parameters (defaults: the Simscape BEV example, MW P; FASTSim for the SOC window).

    Attributes
    ----------
    n_series, n_parallel : int
        Cells in series and in parallel [1] (96, 32).
    cell_capacity : float
        Cell capacity [Ah] (4.5: pack 144 Ah).
    cell_voltage_min : float
        Lowest cell terminal voltage [V] (2.25).
    r2, c2 : float
        RC branch [ohm], [F]; 0 = off (default).
    soc_min, soc_max : float
        Usable SOC window [1] (0.05, 0.98).
    soc_init : float
        State of charge at the start [1] (``SOC_start`` 0.9).
    heat_capacity : float
        Pack heat capacity [J/K] (760 J/(kg K) x 0.07 kg x 3072 cells = 163.4 kJ/K).
    g_cells_plate : float
        Conductance cells to cooling plate [W/K] (MW P ``CoolantResistance``: 1216).
    plate_channels, plate_channel_diameter, plate_channel_length : int, float, float
        The plate's coolant channels [1], [m], [m] (MW P: 12 x 9 mm x 1.3 m).
    g_coolant_fixed : float or None
        A constant pack-to-coolant conductance [W/K]; None (default): cells to
        plate in series with the channels' laminar convection at the step's
        pump flow (:func:`plate_conductance`).
    g_ambient : float
        Conductance pack to ambient [W/K] (15: the pack's 3.42 m2 of top and
        bottom at 5 W/(m2 K) behind 5 mm of foam, 10 W/K parked to 19 W/K
        driving; a time constant of 3.3 h with the coolant).
    T_init : float or None
        Initial pack temperature [K]; None = the ambient.
    """

    n_series: int = param(96, 1, 1000, whole=True, source="MW P `Battery.Ns`", slot="NS")
    n_parallel: int = param(32, 1, 1000, whole=True, source="MW P `Battery.Np`")
    cell_capacity: float = param(
        4.5, 0.01, 1000.0, "Ah", source="MW P `AHCell` (pack 144 Ah, 50.8 kWh; 47.5 kWh between SOC 0.05 and 0.98)"
    )
    cell_voltage_min: float = param(2.25, 0.5, 5.0, "V", source="MW P `V_rangeCell`", slot="VMIN")
    r2: float = param(0.0, 0.0, 10.0, "ohm", source="A (0: the RC branch is off; no source gives it)", slot="R2")
    c2: float = param(0.0, 0.0, 1e7, "F", source="A (0: the RC branch is off; no source gives it)", slot="C2")
    soc_min: float = param(0.05, 0.0, 1.0, source="FS `min_soc`", slot="SOC_MIN")
    soc_max: float = param(0.98, 0.0, 1.0, source="FS `max_soc`", slot="SOC_MAX")
    soc_init: float = param(0.9, 0.0, 1.0, source="MW P `SOC_start`")
    heat_capacity: float = param(
        163.4e3, 1.0, 1e8, "J/K", source="MW P 760 J/(kg K) x 0.07 kg x 3072 cells", slot="C_BAT"
    )
    g_cells_plate: float = param(
        1216.0, 1.0, 1e6, "W/K", source="MW P `CoolantResistance` (cells to plate)", slot="G_CP"
    )
    plate_channels: int = param(12, 1, 1000, whole=True, source="MW P cooling plate")
    plate_channel_diameter: float = param(0.009, 1e-4, 0.1, "m", source="MW P cooling plate")
    plate_channel_length: float = param(1.3, 0.01, 100.0, "m", source="MW P cooling plate")
    g_coolant_fixed: float | None = param(
        None,
        0.0,
        1e5,
        "W/K",
        optional=True,
        source=(
            "unset: `g_cells_plate` in series with the channels' convection at the step's pump flow, Hausen's "
            "developing laminar flow (Incropera eq. 8.57; Re 400-1330, Pr 33): 118 / 139 / 174 W/K at pump "
            "0.3 / 0.5 / 1, 36 W/K with the pump off (Nu = 2, natural convection, A); set it for a constant "
            "conductance"
        ),
    )
    g_ambient: float = param(
        15.0,
        0.0,
        1e5,
        "W/K",
        slot="G_BA",
        source=(
            "A: the pack's top and bottom (MW 1.343 x 1.274 m, 3.42 m2) at MW `battConv` 5 W/(m2 K) behind 5 mm "
            "of foam at 0.035 W/(m K): 10 W/K parked to 19 W/K driving; with the coolant a time constant of "
            "3.3 h. MW P `AmbientResistance` (45 K/W per cell, 68.3 W/K, 40 min) treats every cell as exposed"
        ),
    )
    T_init: float | None = param(None, 173.15, 373.15, "K", optional=True, source="MW S (unset: the ambient)")

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        ordered("soc_min", "<", "soc_init"),
        ordered("soc_init", "<=", "soc_max"),
    )

    @property
    def capacity_As(self) -> float:
        """Pack charge capacity [A s]."""
        return 3600.0 * self.n_parallel * self.cell_capacity


@dataclass(frozen=True)
class BatteryState:
    """The pack's electrical response to a power demand (arrays, SI).

    Attributes
    ----------
    current : numpy.ndarray
        Current [A] (> 0 discharging).
    voltage : numpy.ndarray
        Terminal voltage [V].
    emf : numpy.ndarray
        EMF ``E`` [V].
    resistance : numpy.ndarray
        Ohmic resistance ``R1`` [ohm].
    power : numpy.ndarray
        Power delivered [W]: the demand, or the cap where it binds.
    heat : numpy.ndarray
        Heat generated in the pack [W] (>= 0).
    limited : numpy.ndarray
        The demand was above the power cap.
    """

    current: np.ndarray
    voltage: np.ndarray
    emf: np.ndarray
    resistance: np.ndarray
    power: np.ndarray
    heat: np.ndarray
    limited: np.ndarray


class Battery:
    """The pack's equivalent circuit on the cell tables.

    Parameters
    ----------
    params : BatteryParams, optional
        Pack parameters.
    tables : BatteryCellTables, optional
        Cell OCV and R0 tables (default: the Simscape example's).
    """

    def __init__(self, params: BatteryParams | None = None, tables: BatteryCellTables | None = None) -> None:
        self.params = params or BatteryParams()
        self.tables = tables or battery_cell_tables()

    def emf(self, soc: np.ndarray) -> np.ndarray:
        """Pack EMF [V] at state of charge ``soc`` [1]."""
        t = self.tables
        return self.params.n_series * bilinear_clamped(t.soc, t.temperature_K, t.ocv_V, soc, t.temperature_K[0])

    def resistance(self, soc: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Pack ohmic resistance [ohm] at ``soc`` [1] and cell temperature ``T`` [K]."""
        t, p = self.tables, self.params
        return bilinear_clamped(t.soc, t.temperature_K, t.r0_ohm, soc, T) * p.n_series / p.n_parallel

    def power_cap(self, soc: np.ndarray, T: np.ndarray, v_rc: np.ndarray | float = 0.0) -> np.ndarray:
        """Largest discharge power [W]: the one that brings the terminal voltage to ``Ns v_min``."""
        v_min = self.params.n_series * self.params.cell_voltage_min
        return v_min * (self.emf(soc) - v_rc - v_min) / self.resistance(soc, T)

    def respond(
        self, power: np.ndarray, soc: np.ndarray, T: np.ndarray, v_rc: np.ndarray | float = 0.0
    ) -> BatteryState:
        """Current, voltage and heat at terminal power ``power`` [W] (> 0 discharging)."""
        E = np.asarray(self.emf(soc), float)
        R = np.asarray(self.resistance(soc, T), float)
        cap = self.power_cap(soc, T, v_rc)
        demand = np.asarray(power, float)
        limited = demand > cap
        P = np.where(limited, cap, demand)
        source = E - v_rc
        current = (source - np.sqrt(np.maximum(source**2 - 4.0 * R * P, 0.0))) / (2.0 * R)
        voltage = source - R * current
        heat = R * current**2
        if self.params.r2 > 0:
            heat = heat + np.asarray(v_rc, float) ** 2 / self.params.r2
        return BatteryState(current, voltage, E, R, P, heat, limited)
