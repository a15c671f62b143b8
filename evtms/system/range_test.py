"""Range the way it is measured: repeated cycles to break-off, and the steady consumption after warm-up.

Two depletion tests run as one drive cycle with key-off intervals
(:attr:`evtms.system.drive_cycles.DriveCycle.key_off`: propulsion,
auxiliaries and HVAC off, the thermal network runs on):

- ``mct``, the SAE J1634 multi-cycle test as 40 CFR 600.116-12 (a)(2)
  applies it: UDDS1, 15 s key-on pause, HWFET1, 10 min key-off soak, UDDS2,
  CSC_M, UDDS3, 15 s, HWFET2, 10 min, UDDS4, CSC_E to break-off. The
  constant-speed cycles (CSC) run at 65 mph in phases of at most 1 h with a
  5 min key-off soak between phases; CSC_M is sized by a predictor pass so
  that CSC_E takes about 15 % of the usable battery energy.
- ``ccp``, the consecutive-cycle procedure of UN GTR 15 Annex 8: WLTC class
  3b back to back to break-off.

Both start fully charged (``soc_max``; :class:`RangeSettings`). Break-off is
SOC below ``soc_min`` (the simulator stops there) or the trace missed, the
battery's power cap cutting traction, for at least 4 s. The results
(:class:`RangeResults`) follow the project's system spec (v2, section 7):
the usable battery energy UBE, per driven cycle its energy, distance and
consumption, the city, highway and combined ranges of the MCT, the
depletion distance, the steady consumption per cycle type after warm-up and
the range it gives, and the warm-up energy.

Sources and what is not verified (the spec's tags):

- 40 CFR 600.116-12 (a)(2)(i)-(iv): the 15 s key-on pauses between UDDS1 and
  HWFET1 and between UDDS3 and HWFET2; the 10 min key-off soaks between
  HWFET1 and UDDS2 and between HWFET2 and UDDS4; the optional soaks of up
  to 30 min around the CSC blocks (none here: the next segment starts at
  once); 5 to 30 min of key-off between constant-speed phases (5 min here).
- SAE J1634: the CSC speed of 65 mph, the rule that sizes CSC_M, J1634's
  end-of-test criterion and how it weights the four UDDS are not verified;
  here CSC_M follows the predictor (assumption), the UDDS and HWFET
  consumptions are distance-weighted means (assumption), and the break-off
  is the GTR 15-like 4 s rule (assumption).
- EPA's 55/45 city/highway weighting combines the consumptions,
  ``range_combined = UBE / (0.55 EC_UDDS + 0.45 EC_HWY)``; whether EPA
  combines the ranges this way or arithmetically is not verified (about
  1 %). The 0.7 label factor is reported separately (``label_range_km``),
  never applied to the other figures.
- UN GTR 15 Annex 8: ``range_depletion_km`` is the distance driven to
  break-off (the 2014 text); the amendments' PER = UBE_CCP / EC_DC,CCP is not
  verified and not computed.
- UBE is the integral of the terminal power v i over the test (DC: no
  charger model), key-on pauses included.

Ramps into and out of the CSC speed: 1 m/s2 (an assumption; J1634's ramp is
not verified), on whole seconds, so every phase boundary is a whole second.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812 - the loop's flag bits
from evtms.system.drive_cycles import MAX_SAMPLES, DriveCycle, drive_cycle
from evtms.system.params import SystemParams
from evtms.system.simulate import SimulationResult, simulate, usable_energy
from evtms.system.tables import battery_cell_tables

#: ``--range``: the v1 single trip, the J1634 multi-cycle test, the GTR 15 consecutive cycles.
RANGE_TESTS = ("single", "mct", "ccp")
#: Dynamic cycle kinds of each test (the ones with a steady consumption).
DYNAMIC = {"mct": ("udds", "hwfet"), "ccp": ("wltc3b",)}
#: The first dynamic cycle of each test: the soaked trip whose extrapolation is the v1 range.
FIRST_CYCLE = {"mct": "udds", "ccp": "wltc3b"}
MPH = 0.44704  # m/s per mph


@dataclass(frozen=True)
class RangeSettings:
    """How the depletion tests are built and evaluated (the spec's ``range.*`` values).

    Attributes
    ----------
    csc_speed : float
        Constant-speed cycle speed [m/s]: 65 mph = 29.06 m/s (SAE J1634; not verified).
    key_on_pause : float
        Key-on pause between UDDS1 and HWFET1, UDDS3 and HWFET2 [s] (15 s, 40 CFR 600.116-12 (a)(2)(i)).
    key_off_soak : float
        Key-off soak between HWFET1 and UDDS2, HWFET2 and UDDS4 [s] (600 s, 40 CFR 600.116-12 (a)(2)(ii)).
    csc_phase_max : float
        Longest constant-speed phase [s], ramps included (3600 s; assumption).
    csc_soak : float
        Key-off soak between constant-speed phases [s] (300 s; 40 CFR 600.116-12 (a)(2)(iv): 5-30 min).
    csc_e_share : float
        Share of the usable energy CSC_E is sized to take [1] (0.15; assumption, J1634's rule not verified).
    city_weight : float
        Weight of the city (UDDS) consumption in the combined one [1] (0.55, EPA 55/45).
    ramp_acceleration : float
        Acceleration into and out of the CSC speed [m/s2] (1.0; assumption).
    traction_cut_s : float
        Break-off: traction cut by the battery's power cap for at least this long [s] (4 s; assumption,
        GTR 15-like; J1634's end-of-test criterion not verified).
    steady_dT : float
        A cycle is steady when cabin and battery temperature change by less than this over it [K] (0.2).
    label_factor : float
        EPA label factor for ``label_range_km`` [1] (0.7; not applied elsewhere).
    soc_start : float or None
        SOC the test starts at [1]; None: the battery's ``soc_max`` (fully charged, as J1634 and GTR 15).
    predictor_csc : float
        Length of the constant-speed phase in the MCT's predictor pass [s] (1800).
    margin : float
        CSC_E (MCT) and the cycle count (CCP) cover this many times the predicted need [1] (2).
    """

    csc_speed: float = 65.0 * MPH
    key_on_pause: float = 15.0
    key_off_soak: float = 600.0
    csc_phase_max: float = 3600.0
    csc_soak: float = 300.0
    csc_e_share: float = 0.15
    city_weight: float = 0.55
    ramp_acceleration: float = 1.0
    traction_cut_s: float = 4.0
    steady_dT: float = 0.2
    label_factor: float = 0.7
    soc_start: float | None = None
    predictor_csc: float = 1800.0
    margin: float = 2.0

    def __post_init__(self) -> None:
        for name in ("csc_speed", "ramp_acceleration"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise EvtmsInputError(f"range setting {name} = {value!r} is not allowed; allowed: > 0")
        checks = {
            "csc_speed": 0.0 < self.csc_speed <= 60.0,
            "key_on_pause": 0.0 <= self.key_on_pause <= 3600.0,
            "key_off_soak": 0.0 <= self.key_off_soak <= 86400.0,
            "csc_phase_max": self.ramp_seconds * 2 + 1 <= self.csc_phase_max <= 86400.0,
            "csc_soak": 0.0 <= self.csc_soak <= 86400.0,
            "csc_e_share": 0.0 < self.csc_e_share < 1.0,
            "city_weight": 0.0 <= self.city_weight <= 1.0,
            "ramp_acceleration": 0.1 <= self.ramp_acceleration <= 5.0,
            "traction_cut_s": 0.0 < self.traction_cut_s <= 3600.0,
            "steady_dT": 0.0 < self.steady_dT <= 10.0,
            "label_factor": 0.0 < self.label_factor <= 1.0,
            "soc_start": self.soc_start is None or 0.0 < self.soc_start <= 1.0,
            "predictor_csc": self.ramp_seconds * 2 + 1 <= self.predictor_csc <= 86400.0,
            "margin": 1.0 <= self.margin <= 10.0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (ok and (value is None or math.isfinite(value))):
                raise EvtmsInputError(f"range setting {name} = {value!r} is not allowed")

    @property
    def ramp_seconds(self) -> int:
        """Whole seconds of a ramp between standstill and the CSC speed."""
        return math.ceil(self.csc_speed / self.ramp_acceleration - 1e-9)


@dataclass(frozen=True)
class Phase:
    """One segment of a test sequence.

    Attributes
    ----------
    name : str
        ``UDDS1`` ... ``UDDS4``, ``HWFET1``, ``HWFET2``, ``CSC_M1`` ..., ``CSC_E1`` ..., ``WLTC1`` ...,
        ``key-on pause``, ``key-off soak``, ``CSC soak``.
    kind : str
        ``udds``, ``hwfet``, ``wltc3b``, ``csc`` (driven), ``key_on`` or ``key_off`` (standing).
    start, end : float
        Start and end on the test's clock [s].
    """

    name: str
    kind: str
    start: float
    end: float

    @property
    def driven(self) -> bool:
        """A driven cycle or constant-speed phase (not a pause or a soak)."""
        return self.kind not in ("key_on", "key_off")


@dataclass(frozen=True)
class TestSequence:
    """A depletion test as one drive cycle and its phases.

    Attributes
    ----------
    test : str
        ``mct`` or ``ccp``.
    cycle : DriveCycle
        The whole speed trace with its key-off intervals.
    phases : tuple of Phase
        Its segments in order; they tile ``[0, cycle.duration]``.
    """

    __test__ = False  # not a pytest class

    test: str
    cycle: DriveCycle
    phases: tuple[Phase, ...]


@lru_cache(maxsize=8)
def _builtin(name: str) -> DriveCycle:
    return drive_cycle(name)


class _Builder:
    """Appends cycles, standing intervals and constant-speed phases on one clock."""

    def __init__(self) -> None:
        self.t: list[float] = [0.0]
        self.v: list[float] = [0.0]
        self.grade: list[float] = [0.0]
        self.off: list[bool] = [False]
        self.phases: list[Phase] = []

    def _append(self, t: np.ndarray, v: np.ndarray, grade: np.ndarray, name: str, kind: str) -> None:
        start = self.t[-1]
        self.t.extend((start + t[1:]).tolist())
        self.v.extend(v[1:].tolist())
        self.grade.extend(grade[1:].tolist())
        self.off.extend([False] * (t.size - 1))
        self.phases.append(Phase(name, kind, start, self.t[-1]))

    def cycle(self, name: str, kind: str) -> None:
        c = _builtin(kind)
        self._append(c.time, c.speed, c.grade, name, kind)

    def stand(self, seconds: float, name: str, key_off: bool) -> None:
        if seconds <= 0.0:
            return
        self.off[-1] = key_off  # the interval from the last sample on
        zeros = np.zeros(2)
        self._append(np.array([0.0, seconds]), zeros, zeros, name, "key_off" if key_off else "key_on")

    def csc(self, name: str, duration: float, s: RangeSettings) -> None:
        n = s.ramp_seconds
        up = np.minimum(s.ramp_acceleration * np.arange(n + 1.0), s.csc_speed)
        t = np.concatenate((np.arange(n + 1.0), duration - n + np.arange(n + 1.0)))
        v = np.concatenate((up, up[::-1]))
        self._append(t, v, np.zeros_like(t), name, "csc")

    def build(self, test: str, name: str) -> TestSequence:
        cycle = DriveCycle(
            name, np.array(self.t), np.array(self.v), np.array(self.grade), f"evtms {test} sequence",
            np.array(self.off, bool),
        )  # fmt: skip
        return TestSequence(test, cycle, tuple(self.phases))


def csc_phases(total: float, s: RangeSettings) -> list[float]:
    """Lengths [s] of the constant-speed phases that make ``total`` seconds of driving: as few as the
    1 h limit allows, equal, on whole seconds; none below the two ramps' length."""
    total = float(round(total))
    if total < 2 * s.ramp_seconds + 1:
        return []
    n = math.ceil(total / s.csc_phase_max - 1e-12)
    each = [float(math.floor(total / n))] * n
    each[-1] = total - sum(each[:-1])
    return each


def _csc_block(b: _Builder, prefix: str, lengths: list[float], s: RangeSettings) -> None:
    for k, length in enumerate(lengths, start=1):
        if k > 1:
            b.stand(s.csc_soak, "CSC soak", key_off=True)
        b.csc(f"{prefix}{k}", length, s)


def _check_length(seconds: float) -> None:
    if not (math.isfinite(seconds) and seconds <= MAX_SAMPLES):
        raise EvtmsInputError(
            f"the range test would last {seconds:,.0f} s; allowed: at most {MAX_SAMPLES:,} s (a week); "
            "use a smaller battery"
        )


def mct_sequence(csc_m: float, csc_e_phases: int, settings: RangeSettings | None = None) -> TestSequence:
    """The SAE J1634 multi-cycle test as one drive cycle (40 CFR 600.116-12 (a)(2)).

    Parameters
    ----------
    csc_m : float
        Driving time of the mid-test constant-speed cycle CSC_M [s] (ramps included, soaks between its
        phases not); below two ramps' length there is no CSC_M.
    csc_e_phases : int
        Number of full-length (``csc_phase_max``) phases of the end-of-test constant-speed cycle CSC_E,
        at least 1; the test breaks off somewhere in them.
    settings : RangeSettings, optional

    Returns
    -------
    TestSequence

    Raises
    ------
    EvtmsInputError
        A negative or non-finite CSC_M, fewer than one CSC_E phase, or a test longer than a week.
    """
    s = settings or RangeSettings()
    if not (math.isfinite(csc_m) and csc_m >= 0.0):
        raise EvtmsInputError(f"CSC_M length {csc_m!r} s is not allowed; allowed: >= 0 s")
    if int(csc_e_phases) != csc_e_phases or csc_e_phases < 1:
        raise EvtmsInputError(f"CSC_E phases {csc_e_phases!r} is not allowed; allowed: a whole number >= 1")
    m = csc_phases(csc_m, s)
    fixed = 4 * _builtin("udds").duration + 2 * _builtin("hwfet").duration + 2 * (s.key_on_pause + s.key_off_soak)
    _check_length(fixed + sum(m) + len(m) * s.csc_soak + csc_e_phases * (s.csc_phase_max + s.csc_soak))
    b = _Builder()
    b.cycle("UDDS1", "udds")
    b.stand(s.key_on_pause, "key-on pause", key_off=False)
    b.cycle("HWFET1", "hwfet")
    b.stand(s.key_off_soak, "key-off soak", key_off=True)
    b.cycle("UDDS2", "udds")
    _csc_block(b, "CSC_M", m, s)
    b.cycle("UDDS3", "udds")
    b.stand(s.key_on_pause, "key-on pause", key_off=False)
    b.cycle("HWFET2", "hwfet")
    b.stand(s.key_off_soak, "key-off soak", key_off=True)
    b.cycle("UDDS4", "udds")
    _csc_block(b, "CSC_E", [s.csc_phase_max] * int(csc_e_phases), s)
    return b.build("mct", "mct (SAE J1634 multi-cycle test)")


def ccp_sequence(n_cycles: int) -> TestSequence:
    """The UN GTR 15 Annex 8 consecutive-cycle procedure: ``n_cycles`` WLTC class 3b back to back.

    Raises
    ------
    EvtmsInputError
        Fewer than one cycle, or a test longer than a week.
    """
    if int(n_cycles) != n_cycles or n_cycles < 1:
        raise EvtmsInputError(f"WLTC count {n_cycles!r} is not allowed; allowed: a whole number >= 1")
    _check_length(n_cycles * _builtin("wltc3b").duration)
    b = _Builder()
    for k in range(1, int(n_cycles) + 1):
        b.cycle(f"WLTC{k}", "wltc3b")
    return b.build("ccp", "ccp (UN GTR 15 consecutive cycles)")


def _mct_predictor(s: RangeSettings) -> TestSequence:
    """UDDS1, pause, HWFET1, soak, UDDS2 and one constant-speed phase: the MCT's energies before CSC_M."""
    b = _Builder()
    b.cycle("UDDS1", "udds")
    b.stand(s.key_on_pause, "key-on pause", key_off=False)
    b.cycle("HWFET1", "hwfet")
    b.stand(s.key_off_soak, "key-off soak", key_off=True)
    b.cycle("UDDS2", "udds")
    b.csc("CSC_M1", s.predictor_csc, s)
    return b.build("mct", "mct predictor")


@dataclass(frozen=True)
class CycleResult:
    """One driven cycle or constant-speed phase of a test.

    Attributes
    ----------
    name, kind : str
        As :class:`Phase`.
    start_s, end_s : float
        Start and end [s]; ``end_s`` is the break-off for the cycle it interrupts.
    complete : bool
        Driven to its end before break-off.
    energy_kWh : float
        E_k, the integral of v i over the cycle [kWh].
    chemical_kWh : float
        The integral of E i (EMF times current) over it [kWh].
    distance_km : float
        d_k [km].
    EC_Wh_per_km : float or None
        EC_k = E_k / d_k [Wh/km].
    dT_cabin_K, dT_battery_K : float
        Change of cabin air and battery temperature over the cycle [K].
    """

    name: str
    kind: str
    start_s: float
    end_s: float
    complete: bool
    energy_kWh: float
    chemical_kWh: float
    distance_km: float
    EC_Wh_per_km: float | None
    dT_cabin_K: float
    dT_battery_K: float


@dataclass(frozen=True)
class RangeResults:
    """The figures of a depletion test (the project's system spec v2, section 7).

    Attributes
    ----------
    test : str
        ``mct`` or ``ccp``.
    break_off : str
        ``soc_min``, ``traction_cut`` (>= ``traction_cut_s`` of traction cut) or ``end of sequence`` (not
        depleted: the figures are then lower bounds).
    break_off_s : float
        Test time of the break-off [s].
    soc_start : float
        SOC at the start [1].
    ube_kWh : float
        Usable battery energy UBE, the integral of v i from the start to break-off [kWh].
    hvac_kWh, hvac_share : float
        HVAC electrical energy over the test [kWh] and its share of UBE [1].
    cycles : tuple of CycleResult
        Every driven cycle and constant-speed phase that started before break-off.
    EC_Wh_per_km : dict of str to float or None
        Per dynamic cycle kind (``udds``, ``hwfet``; ``wltc3b``) the distance-weighted consumption of its
        complete cycles, sum E_k / sum d_k [Wh/km].
    EC_ss_Wh_per_km : dict of str to float or None
        Per dynamic kind the steady consumption: EC of its last complete cycle over which cabin and battery
        temperatures changed by less than ``steady_dT``, else of its last complete one [Wh/km].
    not_steady : tuple of str
        The kinds whose EC_ss is of a cycle that was not steady.
    EC_ss_combined_Wh_per_km : float or None
        0.55 EC_ss,udds + 0.45 EC_ss,hwfet (mct) or EC_ss,wltc3b (ccp) [Wh/km].
    range_city_km, range_hwy_km, range_combined_km : float or None
        mct: UBE / EC_udds, UBE / EC_hwfet, UBE / (0.55 EC_udds + 0.45 EC_hwfet) [km] (UDDS and HWFET
        phases only: the CSC phases do not dilute them); None for ccp.
    label_range_km : float or None
        mct: 0.7 range_combined [km]; None for ccp.
    range_depletion_km : float
        Distance driven to break-off [km] (the ccp's range; for mct it includes the CSC phases).
    range_ss_km : float or None
        UBE / EC_ss_combined [km].
    warmup_kWh : float or None
        Sum over complete dynamic cycles of E_k - EC_ss,kind(k) d_k [kWh] (CSC phases excluded).
    single_trip_range_km : float or None
        The v1 figure for the first (soaked) cycle: usable energy between ``soc_max`` and ``soc_min`` over
        its chemical energy, times its distance [km] (``evtms simulate --cycle udds`` or ``wltc3b``'s
        ``range_km``).
    single_trip_cycle : str
        That cycle (``udds`` or ``wltc3b``).
    csc_m_s : float
        Driving time of CSC_M [s] (mct; 0 for ccp).
    csc_e_share : float or None
        Energy of the CSC_E phases over UBE [1] (mct; the predictor aims at ``csc_e_share``).
    """

    test: str
    break_off: str
    break_off_s: float
    soc_start: float
    ube_kWh: float
    hvac_kWh: float
    hvac_share: float
    cycles: tuple[CycleResult, ...]
    EC_Wh_per_km: dict[str, float | None]
    EC_ss_Wh_per_km: dict[str, float | None]
    not_steady: tuple[str, ...]
    EC_ss_combined_Wh_per_km: float | None
    range_city_km: float | None
    range_hwy_km: float | None
    range_combined_km: float | None
    label_range_km: float | None
    range_depletion_km: float
    range_ss_km: float | None
    warmup_kWh: float | None
    single_trip_range_km: float | None
    single_trip_cycle: str
    csc_m_s: float = 0.0
    csc_e_share: float | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The figures as JSON-ready values (lists for tuples, None where undefined)."""
        d = dataclasses.asdict(self)
        d["not_steady"] = list(self.not_steady)
        return d


class _Integrals:
    """Energies, distance and temperatures of a run at any time, from its records.

    Powers are the records' interval means, so the cumulative energy is exact at record times and linear
    between them; the states are linear between record times.
    """

    def __init__(self, records: dict[str, np.ndarray], c2: float) -> None:
        t = np.asarray(records["time"], float)
        span = np.diff(t)
        self.t = t

        def cumulative(p: np.ndarray) -> np.ndarray:
            return np.concatenate(([0.0], np.cumsum(np.asarray(p, float)[1:] * span)))

        self._battery = cumulative(records["P_battery"])
        self._hvac = cumulative(records["P_hvac"])
        rc = 0.5 * c2 * np.asarray(records["v_rc"], float) ** 2 if c2 > 0.0 else np.zeros_like(t)
        self._chemical = cumulative(np.asarray(records["P_battery"]) + np.asarray(records["Q_battery_gen"])) + rc
        self._distance = np.asarray(records["distance"], float)
        self._T_cabin = np.asarray(records["T_cabin"], float)
        self._T_battery = np.asarray(records["T_battery"], float)

    def _at(self, values: np.ndarray, a: float, b: float) -> float:
        return float(np.interp(b, self.t, values) - np.interp(a, self.t, values))

    def battery(self, a: float, b: float) -> float:
        """Integral of v i from a to b [J]."""
        return self._at(self._battery, a, b)

    def chemical(self, a: float, b: float) -> float:
        """Integral of E i from a to b [J]."""
        return self._at(self._chemical, a, b)

    def hvac(self, a: float, b: float) -> float:
        """HVAC electrical energy from a to b [J]."""
        return self._at(self._hvac, a, b)

    def distance(self, a: float, b: float) -> float:
        """Distance from a to b [m]."""
        return self._at(self._distance, a, b)

    def dT(self, a: float, b: float) -> tuple[float, float]:
        """Change of cabin air and battery temperature from a to b [K]."""
        return self._at(self._T_cabin, a, b), self._at(self._T_battery, a, b)


def break_off_time(time: np.ndarray, flags: np.ndarray, seconds: float) -> float | None:
    """First instant [s] at which traction has been cut for ``seconds`` without a break, else None.

    ``flags`` (per record, the events of its interval ``(t_k-1, t_k]``) carry
    :data:`evtms.system.loop.F_TRACTION_CUT`; a run of flagged records from
    ``t_j-1`` counts from there, so the break-off is ``t_j-1 + seconds``.
    """
    cut = (np.asarray(flags[1:]).astype(np.int64) & L.F_TRACTION_CUT) > 0
    start = None
    for k, on in enumerate(cut, start=1):
        if not on:
            start = None
            continue
        if start is None:
            start = time[k - 1]
        if time[k] - start >= seconds - 1e-9:
            return float(start + seconds)
    return None


def _ec(energy_J: float, distance_m: float) -> float | None:
    """Consumption [Wh/km] of ``energy_J`` over ``distance_m`` (None without distance)."""
    return energy_J / 3.6 / distance_m if distance_m > 0.0 else None


def range_figures(
    test: str,
    cycles: list[CycleResult],
    ube_kWh: float,
    settings: RangeSettings | None = None,
) -> dict[str, Any]:
    """The ranges and steady consumptions from the per-cycle figures (spec v2 section 7).

    Parameters
    ----------
    test : str
        ``mct`` or ``ccp``.
    cycles : list of CycleResult
        The test's driven cycles (complete or not).
    ube_kWh : float
        Usable battery energy [kWh].
    settings : RangeSettings, optional

    Returns
    -------
    dict
        The :class:`RangeResults` fields ``EC_Wh_per_km``, ``EC_ss_Wh_per_km``, ``not_steady``,
        ``EC_ss_combined_Wh_per_km``, ``range_city_km``, ``range_hwy_km``, ``range_combined_km``,
        ``label_range_km``, ``range_ss_km`` and ``warmup_kWh``.
    """
    s = settings or RangeSettings()
    kinds = DYNAMIC[test]
    done = [c for c in cycles if c.complete]
    ec: dict[str, float | None] = {}
    ec_ss: dict[str, float | None] = {}
    not_steady: list[str] = []
    for kind in kinds:
        mine = [c for c in done if c.kind == kind]
        ec[kind] = _ec(sum(c.energy_kWh for c in mine) * 3.6e6, sum(c.distance_km for c in mine) * 1e3)
        steady = [c for c in mine if abs(c.dT_cabin_K) < s.steady_dT and abs(c.dT_battery_K) < s.steady_dT]
        if steady:
            ec_ss[kind] = steady[-1].EC_Wh_per_km
        elif mine:
            ec_ss[kind] = mine[-1].EC_Wh_per_km
            not_steady.append(kind)
        else:
            ec_ss[kind] = None

    def combine(values: dict[str, float | None]) -> float | None:
        if any(values[k] is None for k in kinds):
            return None
        if test == "mct":
            return s.city_weight * values["udds"] + (1.0 - s.city_weight) * values["hwfet"]
        return values["wltc3b"]

    def rng(ec_wh_per_km: float | None) -> float | None:
        return ube_kWh * 1e3 / ec_wh_per_km if ec_wh_per_km else None

    ec_ss_combined = combine(ec_ss)
    out: dict[str, Any] = {
        "EC_Wh_per_km": ec,
        "EC_ss_Wh_per_km": ec_ss,
        "not_steady": tuple(not_steady),
        "EC_ss_combined_Wh_per_km": ec_ss_combined,
        "range_city_km": None,
        "range_hwy_km": None,
        "range_combined_km": None,
        "label_range_km": None,
        "range_ss_km": rng(ec_ss_combined),
        "warmup_kWh": None,
    }
    if test == "mct":
        combined = rng(combine(ec))
        out["range_city_km"] = rng(ec["udds"])
        out["range_hwy_km"] = rng(ec["hwfet"])
        out["range_combined_km"] = combined
        out["label_range_km"] = None if combined is None else s.label_factor * combined
    warm = [c for c in done if c.kind in kinds and ec_ss[c.kind] is not None]
    if warm:
        out["warmup_kWh"] = sum(c.energy_kWh - ec_ss[c.kind] * c.distance_km / 1e3 for c in warm)
    return out


def measure(
    sequence: TestSequence,
    records: dict[str, np.ndarray],
    flags: np.ndarray,
    termination: str,
    *,
    params: SystemParams,
    settings: RangeSettings | None = None,
    csc_m_s: float = 0.0,
) -> RangeResults:
    """Evaluate a simulated test: break-off, per-cycle figures and the ranges.

    Parameters
    ----------
    sequence : TestSequence
        The test that was simulated.
    records : dict of str to numpy.ndarray
        The run's records (:attr:`evtms.system.simulate.SimulationResult.records`): ``time``,
        ``P_battery``, ``P_hvac``, ``Q_battery_gen``, ``v_rc``, ``distance``, ``T_cabin``, ``T_battery``.
        Records before 0 (preconditioning) do not count. The figures are exact where the phase
        boundaries (whole seconds) fall on record times (any ``dt`` up to 1 s with the default record
        spacing) and linear between records otherwise.
    flags : numpy.ndarray
        Flag bits per record.
    termination : str
        The run's termination (``soc_min`` or ``end of cycle``).
    params : SystemParams
        The parameters the run used (battery limits, the RC branch's capacitance).
    settings : RangeSettings, optional
    csc_m_s : float
        Driving time of CSC_M [s], recorded.

    Returns
    -------
    RangeResults
    """
    s = settings or RangeSettings()
    b = params.battery
    t = np.asarray(records["time"], float)
    run = _Integrals(records, b.c2 if b.r2 > 0.0 else 0.0)
    t_cut = break_off_time(t, flags, s.traction_cut_s)
    if t_cut is not None:
        break_off, t_end = "traction_cut", min(t_cut, float(t[-1]))
    elif termination == "soc_min":
        break_off, t_end = "soc_min", float(t[-1])
    else:
        break_off, t_end = "end of sequence", float(t[-1])
    cycles = []
    for p in sequence.phases:
        if not p.driven or p.start >= t_end - 1e-9:
            continue
        end = min(p.end, t_end)
        energy, distance = run.battery(p.start, end), run.distance(p.start, end)
        dT_cab, dT_bat = run.dT(p.start, end)
        cycles.append(
            CycleResult(
                name=p.name,
                kind=p.kind,
                start_s=p.start,
                end_s=end,
                complete=p.end <= t_end + 1e-9,
                energy_kWh=energy / 3.6e6,
                chemical_kWh=run.chemical(p.start, end) / 3.6e6,
                distance_km=distance / 1e3,
                EC_Wh_per_km=_ec(energy, distance),
                dT_cabin_K=dT_cab,
                dT_battery_K=dT_bat,
            )
        )
    ube = run.battery(0.0, t_end)
    hvac = run.hvac(0.0, t_end)
    first = cycles[0] if cycles else None
    single = None
    if first is not None and first.complete and first.chemical_kWh > 0.0:
        single = usable_energy(params) / (first.chemical_kWh * 3.6e6) * first.distance_km
    csc_e = [c for c in cycles if c.name.startswith("CSC_E")]
    return RangeResults(
        test=sequence.test,
        break_off=break_off,
        break_off_s=t_end,
        soc_start=float(b.soc_init),
        ube_kWh=ube / 3.6e6,
        hvac_kWh=hvac / 3.6e6,
        hvac_share=hvac / ube if ube > 0.0 else 0.0,
        cycles=tuple(cycles),
        range_depletion_km=run.distance(0.0, t_end) / 1e3,
        single_trip_range_km=single,
        single_trip_cycle=FIRST_CYCLE[sequence.test],
        csc_m_s=float(csc_m_s),
        csc_e_share=(sum(c.energy_kWh for c in csc_e) * 3.6e6 / ube if ube > 0.0 else None) if csc_e else None,
        settings=dataclasses.asdict(s),
        **range_figures(sequence.test, cycles, ube / 3.6e6, s),
    )


def chemical_energy(params: SystemParams, soc_high: float, soc_low: float) -> float:
    """Chemical energy [J] between two SOCs: the integral of the pack EMF over the charge."""
    b = params.battery
    tables = battery_cell_tables()
    soc = np.linspace(soc_low, soc_high, 2001)
    emf = b.n_series * np.interp(soc, tables.soc, tables.ocv_V[:, 0])
    return float(np.sum(0.5 * (emf[1:] + emf[:-1]) * np.diff(soc)) * b.capacity_As)


def _truncated(cycle: DriveCycle, t_end: float) -> DriveCycle:
    """``cycle`` up to ``t_end`` [s] (speed interpolated at the cut)."""
    keep = cycle.time < t_end - 1e-9
    t = np.append(cycle.time[keep], t_end)
    v = np.append(cycle.speed[keep], np.interp(t_end, cycle.time, cycle.speed))
    g = np.append(cycle.grade[keep], np.interp(t_end, cycle.time, cycle.grade))
    off = None if cycle.key_off is None else np.append(cycle.key_off[keep], False)
    return DriveCycle(cycle.name, t, v, g, cycle.source, off)


def run_range_test(
    test: str,
    T_amb: float,
    refrigerant,
    params: SystemParams | None = None,
    *,
    settings: RangeSettings | None = None,
    dt: float = 1.0,
    precondition: float = 0.0,
    **simulate_options: Any,
) -> tuple[SimulationResult, RangeResults]:
    """Run a depletion test to break-off and evaluate it.

    The MCT first runs a predictor pass (UDDS1, pause, HWFET1, soak, UDDS2 and
    ``predictor_csc`` seconds at the CSC speed) from the same start. From it:
    the terminal-to-chemical efficiency eta, UBE_est = eta times the
    chemical energy between the start SOC and ``soc_min``, the energy of the
    eight dynamic cycles (UDDS3 and UDDS4 as UDDS2, HWFET2 as HWFET1), and the
    steady CSC power P_csc (the second half of the phase's cruise). CSC_M
    then lasts ((1 - csc_e_share) UBE_est - E_dynamic) / P_csc (none if that
    is negative), and CSC_E gets ``margin`` times its predicted need plus
    one phase. The CCP's predictor is two WLTCs; the test gets ``margin``
    times UBE_est over the second one's energy, plus one. A test that ends
    without break-off is run again with twice the CSC_E phases or cycles (at
    most twice); a traction-cut break-off is run again up to that instant, so
    the records end there.

    Parameters
    ----------
    test : str
        ``mct`` or ``ccp``.
    T_amb : float
        Ambient temperature [K].
    refrigerant : Refrigerant
        Cycle maps (as :func:`evtms.system.simulate.simulate`).
    params : SystemParams, optional
        Parameters; the battery starts at ``settings.soc_start`` (default ``soc_max``), not ``soc_init``.
    settings : RangeSettings, optional
    dt, precondition : float
        As :func:`~evtms.system.simulate.simulate` [s].
    **simulate_options
        Passed to :func:`~evtms.system.simulate.simulate` (``mode``, ``RH_amb``, ``sun``, ``T_init``, ...).

    Returns
    -------
    SimulationResult, RangeResults
        The run (its ``summary`` gains ``range``, its ``attrs`` ``range_test`` and ``range``) and the figures.

    Raises
    ------
    EvtmsInputError
        An unknown test, or a test longer than the simulator's step limit or a week.
    """
    if test not in DYNAMIC:
        raise EvtmsInputError(f"`range_test` {test!r} is not a depletion test; allowed: {', '.join(DYNAMIC)}")
    s = settings or RangeSettings()
    params = params or SystemParams()
    b = params.battery
    soc0 = b.soc_max if s.soc_start is None else s.soc_start
    if not b.soc_min < soc0 <= b.soc_max:
        raise EvtmsInputError(f"range test start SOC {soc0:g} is not allowed; allowed: above soc_min {b.soc_min:g}")
    params = dataclasses.replace(params, battery=dataclasses.replace(b, soc_init=soc0))

    def run(sequence: TestSequence) -> SimulationResult:
        return simulate(
            sequence.cycle, T_amb, refrigerant, params, dt=dt, precondition=precondition, **simulate_options
        )

    def phases(sequence: TestSequence, r: SimulationResult) -> dict[str, float]:
        """Terminal energy [J] per phase name (the first of a name), as far as the run went."""
        integrals = _Integrals(r.records, 0.0)
        end = float(r.records["time"][-1])
        out: dict[str, float] = {}
        for p in sequence.phases:
            if p.end <= end + 1e-9:
                out.setdefault(p.name, integrals.battery(p.start, p.end))
        return out

    pre = _mct_predictor(s) if test == "mct" else ccp_sequence(2)
    r = run(pre)
    chem = r.summary["battery_chemical_kWh"]
    eta = r.summary["battery_energy_kWh"] / chem if chem > 0.0 else 1.0
    ube_est = eta * chemical_energy(params, soc0, b.soc_min)
    energies = phases(pre, r)
    csc_m = 0.0
    if test == "mct":
        p_csc = None
        csc = pre.phases[-1]
        cruise = (csc.start + s.ramp_seconds, csc.end - s.ramp_seconds)
        half = 0.5 * (cruise[0] + cruise[1])
        if "CSC_M1" in energies:
            p_csc = _Integrals(r.records, 0.0).battery(half, cruise[1]) / (cruise[1] - half)
        dynamic = [energies.get(k) for k in ("UDDS1", "key-on pause", "HWFET1", "UDDS2")]
        if p_csc is not None and p_csc > 0.0 and None not in dynamic:
            e_u1, e_pause, e_h1, e_u2 = dynamic
            e_dyn = e_u1 + e_pause + e_h1 + e_u2 + e_u2 + e_pause + e_h1 + e_u2
            csc_m = max(((1.0 - s.csc_e_share) * ube_est - e_dyn) / p_csc, 0.0)
            need = s.csc_e_share * ube_est / p_csc
        else:
            need = s.csc_phase_max
        count = math.ceil(s.margin * need / s.csc_phase_max - 1e-9) + 1

        def build(n: int) -> TestSequence:
            return mct_sequence(csc_m, n, s)
    else:
        e_cycle = energies.get("WLTC2", energies.get("WLTC1"))
        count = math.ceil(s.margin * ube_est / e_cycle) + 1 if e_cycle and e_cycle > 0.0 else 2
        build = ccp_sequence
    for attempt in range(3):
        sequence = build(count)
        result = run(sequence)
        term = result.summary["termination"]
        t_cut = break_off_time(result.records["time"], result.flags, s.traction_cut_s)
        if term == "soc_min" or t_cut is not None or attempt == 2:
            break
        count *= 2
    if t_cut is not None:
        # The records end at the break-off: the same run, up to that instant.
        sequence = TestSequence(sequence.test, _truncated(sequence.cycle, t_cut), sequence.phases)
        result = run(sequence)
        result.summary["termination"] = result.attrs["termination"] = "traction_cut"
    figures = measure(
        sequence,
        result.records,
        result.flags,
        "traction_cut" if t_cut is not None else result.summary["termination"],
        params=params,
        settings=s,
        csc_m_s=float(sum(csc_phases(csc_m, s))),
    )
    if t_cut is not None:
        figures = dataclasses.replace(figures, break_off="traction_cut", break_off_s=t_cut)
    result.summary["range"] = figures.to_dict()
    result.attrs["range_test"] = test
    result.attrs["range"] = json.dumps(figures.to_dict())
    return result, figures
