"""Scenario design for training the mode models: which LUT simulations supply the training and held-out steps.

A scenario is one run of :func:`evtms.system.simulate.simulate` on the LUT
model: a drive cycle, an ambient, initial temperatures (battery and coolant,
cabin soak), initial cabin humidity, a cabin setpoint, sun, humidity, initial state of charge and a
mode (forced, or ``auto`` for the controller's own choice). Each mode trains
on ambients in its physical range (cooling modes 20-45 degC, heating modes
-20-10 degC, ``off`` anywhere), one per equal slice of the range (both
ends covered), drawn by a seeded generator so that a design is reproducible.

Generalisation is measured on scenarios the networks never saw: the held-out
drive cycles (:data:`HELDOUT_CYCLES`, the regulation cycles of the comparison
report) at the held-out ambients (:data:`HELDOUT_AMBIENTS_C`); training
scenarios drive the other built-in cycles (UDDS, HWFET) and synthetic speed
traces (:func:`synthetic_cycle`), and their ambients keep at least
:data:`AMBIENT_GAP` from every held-out ambient.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from evtms.system.drive_cycles import KMH, DriveCycle, drive_cycle
from evtms.system.mode_model import MODE_CODES
from evtms.system.params import SystemParams

C0 = 273.15  # [K] at 0 degC
#: Built-in cycles used for training; the held-out ones never are.
TRAIN_CYCLES = ("udds", "hwfet")
HELDOUT_CYCLES = ("wltc3b", "nedc")
#: Ambients [degC] of the held-out runs (the comparison report's -10, 30 and 40 degC, and 5 degC for heating).
HELDOUT_AMBIENTS_C = (-10.0, 5.0, 30.0, 40.0)
#: Ambients [degC] of the held-out ``auto`` runs (the comparison report's), when every mode is trained.
AUTO_AMBIENTS_C = (-10.0, 30.0, 40.0)
#: Least distance [K] of a training ambient from every held-out ambient.
AMBIENT_GAP = 2.0
#: Names ``--mode`` accepts, besides ``all``.
MODE_NAMES = tuple(MODE_CODES)
COOLING = ("bc", "cc", "cc+bc")
HEATING = ("bh", "ch", "ch+bh")


@dataclass(frozen=True)
class ModeRanges:
    """Where a mode's scenarios are drawn from (uniformly).

    Attributes
    ----------
    T_amb : tuple of float
        Ambient range [degC].
    battery : tuple of float
        Initial battery and coolant temperature [K], absolute when ``battery_absolute`` else relative to the ambient.
    battery_absolute : bool
        Whether ``battery`` is absolute.
    cabin : tuple of float
        Initial cabin soak relative to the ambient [K].
    sun : tuple of float
        Solar irradiance [W/m2].
    RH : tuple of float
        Ambient relative humidity [1].
    """

    T_amb: tuple[float, float]
    battery: tuple[float, float]
    battery_absolute: bool
    cabin: tuple[float, float]
    sun: tuple[float, float]
    RH: tuple[float, float]


#: Per mode name, the ranges its training scenarios are drawn from.
RANGES: dict[str, ModeRanges] = {
    "off": ModeRanges((-20.0, 45.0), (-5.0, 15.0), False, (-5.0, 20.0), (0.0, 800.0), (0.2, 0.8)),
    "bh": ModeRanges((-20.0, 10.0), (-2.0, 8.0), False, (0.0, 20.0), (0.0, 400.0), (0.3, 0.9)),
    "bc": ModeRanges((20.0, 45.0), (303.15, 320.15), True, (-3.0, 20.0), (0.0, 900.0), (0.2, 0.7)),
    "cc": ModeRanges((20.0, 45.0), (-3.0, 10.0), False, (-3.0, 25.0), (0.0, 900.0), (0.2, 0.7)),
    "ch": ModeRanges((-20.0, 10.0), (0.0, 10.0), False, (0.0, 15.0), (0.0, 400.0), (0.3, 0.9)),
    "ch+bh": ModeRanges((-20.0, 10.0), (-2.0, 5.0), False, (0.0, 10.0), (0.0, 400.0), (0.3, 0.9)),
    "ch+bc": ModeRanges((-20.0, 15.0), (306.15, 318.15), True, (0.0, 10.0), (0.0, 400.0), (0.3, 0.9)),
    "cc+bc": ModeRanges((20.0, 45.0), (306.15, 320.15), True, (-3.0, 25.0), (0.0, 900.0), (0.2, 0.7)),
}
#: Cabin setpoint range [degC] drawn per scenario (excites the blower and compressor commands).
T_SET_C = (18.0, 27.0)
#: Share of training scenarios without sun (night, garage, overcast): sun 0 must lie inside the training range.
NO_SUN_SHARE = 0.3


def _sun(rng: np.random.Generator, span: tuple[float, float]) -> float:
    """A scenario's irradiance [W/m2]: 0 for :data:`NO_SUN_SHARE` of them, else uniform over ``span``."""
    draw = rng.uniform(*span)  # drawn either way: the other draws do not depend on the share
    if rng.random() < NO_SUN_SHARE:
        return 0.0
    return round(draw, 1)


#: Initial cabin relative humidity range [1].
RH_CABIN = (0.02, 0.8)
#: Initial state of charge range [1].
SOC_INIT = (0.35, 0.95)


@dataclass(frozen=True)
class Scenario:
    """One LUT simulation of the design.

    Attributes
    ----------
    name : str
        Unique name, e.g. ``train-bc-07``.
    role : str
        ``train`` or ``heldout``.
    target : str
        Mode name the scenario is for (``auto`` for the controller's choice over every mode).
    mode : str
        Mode passed to :func:`~evtms.system.simulate.simulate` (a forced mode or ``auto``).
    cycle : str
        Built-in cycle name, or ``synthetic-<seed>`` (:func:`synthetic_cycle`).
    T_amb : float
        Ambient temperature [K].
    RH_amb : float
        Ambient relative humidity [1].
    sun : float
        Solar irradiance [W/m2].
    T_battery0 : float or None
        Initial battery and coolant temperature [K] (None: the ambient).
    T_cabin0 : float or None
        Initial cabin air, wall and interior temperature [K] (None: the ambient).
    T_set : float
        Cabin setpoint [K].
    RH_cabin0 : float
        Initial cabin relative humidity [1] (recirculated air dries out while cooling; low values reach
        the humidity floor the loop clamps at 0).
    soc_init : float
        Initial state of charge [1].
    """

    name: str
    role: str
    target: str
    mode: str
    cycle: str
    T_amb: float
    RH_amb: float
    sun: float
    T_battery0: float | None
    T_cabin0: float | None
    T_set: float
    RH_cabin0: float
    soc_init: float

    def params(self, base: SystemParams | None = None) -> SystemParams:
        """``base`` (default: the defaults) with this scenario's setpoint, initial temperatures and SOC.

        Only the cabin setpoint and initial values change: the parameters the
        cycle maps depend on (the coolant flow) stay ``base``'s.
        """
        base = base or SystemParams()
        cabin = dataclasses.replace(base.cabin, T_set=self.T_set, rh_cabin=self.RH_cabin0)
        battery = dataclasses.replace(base.battery, T_init=self.T_battery0, soc_init=self.soc_init)
        coolant = dataclasses.replace(base.coolant, T_init=self.T_battery0)
        return dataclasses.replace(base, cabin=cabin, battery=battery, coolant=coolant)

    def drive_cycle(self) -> DriveCycle:
        """The scenario's speed trace."""
        if self.cycle.startswith("synthetic-"):
            return synthetic_cycle(int(self.cycle.split("-", 1)[1]))
        return drive_cycle(self.cycle)

    def to_dict(self) -> dict:
        """Plain values (recorded in the model file)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Design:
    """Training and held-out scenarios of one training run.

    Attributes
    ----------
    train, heldout : list of Scenario
    seed : int
        Seed of the draw.
    """

    train: list[Scenario]
    heldout: list[Scenario]
    seed: int

    def cycles(self, role: str) -> set[str]:
        """Cycle names used in ``role`` (``train`` or ``heldout``)."""
        return {s.cycle for s in (self.train if role == "train" else self.heldout)}

    def ambients(self, role: str) -> set[float]:
        """Ambients [K] used in ``role``."""
        return {s.T_amb for s in (self.train if role == "train" else self.heldout)}


def synthetic_cycle(seed: int, duration: float = 1800.0) -> DriveCycle:
    """A random urban/extra-urban speed trace of ``duration`` [s] at 1 Hz.

    Stops of 5-60 s alternate with trips: accelerate at 0.4-2.5 m/s2 to
    10-130 km/h, cruise 10-240 s with a slow +-5 % wave, brake at
    0.5-3 m/s2. Flat road. Deterministic in ``seed``.
    """
    rng = np.random.default_rng(10_000 + seed)
    v: list[float] = [0.0]
    while len(v) < duration + 1:
        v += [0.0] * int(rng.integers(5, 61))
        target = rng.uniform(10.0, 130.0) * KMH
        acc = rng.uniform(0.4, 2.5)
        v += list(np.minimum(acc * np.arange(1, int(np.ceil(target / acc)) + 1), target))
        n_cruise = int(rng.integers(10, 241))
        wave = 1.0 + 0.05 * np.sin(2 * np.pi * np.arange(n_cruise) / rng.uniform(20.0, 120.0))
        v += list(target * wave)
        dec = rng.uniform(0.5, 3.0)
        v += list(np.maximum(v[-1] - dec * np.arange(1, int(np.ceil(v[-1] / dec)) + 1), 0.0))
    speed = np.asarray(v[: int(duration)] + [0.0])
    t = np.arange(speed.size, dtype=float)
    return DriveCycle(f"synthetic-{seed}", t, speed, np.zeros_like(speed), f"evtms.surrogates.design seed {seed}")


def _train_ambient(rng: np.random.Generator, lo_c: float, hi_c: float) -> float:
    """An ambient [K] in ``[lo_c, hi_c]`` degC at least :data:`AMBIENT_GAP` from every held-out ambient."""
    for _ in range(1000):
        T = rng.uniform(lo_c, hi_c)
        if all(abs(T - h) >= AMBIENT_GAP for h in HELDOUT_AMBIENTS_C):
            return round(C0 + T, 3)
    raise RuntimeError(f"no training ambient in {lo_c}..{hi_c} degC away from the held-out ones")  # pragma: no cover


def _train_ambients(rng: np.random.Generator, lo_c: float, hi_c: float, n: int) -> list[float]:
    """``n`` ambients [K], one per equal slice of ``[lo_c, hi_c]`` degC (so both ends are covered), shuffled.

    A slice that lies within :data:`AMBIENT_GAP` of a held-out ambient draws from the whole range instead.
    """
    edges = np.linspace(lo_c, hi_c, n + 1)
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        try:
            out.append(_train_ambient(rng, a, b))
        except RuntimeError:
            out.append(_train_ambient(rng, lo_c, hi_c))
    return [out[i] for i in rng.permutation(n)]


def modes_for(names: list[str]) -> list[str]:
    """Mode names a ``--mode`` list stands for (``all``: every code of :data:`~evtms.system.mode_model.MODE_CODES`)."""
    out: list[str] = []
    for n in names:
        for m in MODE_NAMES if n == "all" else (n,):
            if m not in out:
                out.append(m)
    return out


def design(modes: list[str], *, seed: int = 0, runs_per_mode: int = 24, quick: bool = False) -> Design:
    """Training and held-out scenarios for ``modes`` (names of :data:`MODE_NAMES`).

    Parameters
    ----------
    modes : list of str
        Mode names to train.
    seed : int
        Seed of every draw.
    runs_per_mode : int
        Training runs per mode: two thirds forced to the mode, one third
        ``auto`` (the controller's own transitions and combined modes) in the
        mode's ranges.
    quick : bool
        A small design (3 training runs per mode on short synthetic traces,
        one held-out cycle) for tests.

    Returns
    -------
    Design
    """
    rng = np.random.default_rng(seed)
    n_runs = 3 if quick else runs_per_mode
    train: list[Scenario] = []
    synth = 0
    for m in modes:
        r = RANGES[m]
        ambients = _train_ambients(rng, *r.T_amb, n_runs)
        for k in range(n_runs):
            T_amb = ambients[k]
            lo, hi = r.battery
            Tb = rng.uniform(lo, hi) + (0.0 if r.battery_absolute else T_amb)
            if quick or k % 3 != 2:
                synth += 1
                cycle = f"synthetic-{seed * 1000 + synth}"
            else:
                cycle = TRAIN_CYCLES[(k // 3) % len(TRAIN_CYCLES)]
            run_mode = m if (quick or k % 3 != 1) else "auto"
            train.append(
                Scenario(
                    name=f"train-{m}-{k:02d}",
                    role="train",
                    target=m,
                    mode=run_mode,
                    cycle=cycle,
                    T_amb=T_amb,
                    RH_amb=round(rng.uniform(*r.RH), 3),
                    sun=_sun(rng, r.sun),
                    T_battery0=round(Tb, 3),
                    T_cabin0=round(T_amb + rng.uniform(*r.cabin), 3),
                    T_set=round(C0 + rng.uniform(*T_SET_C), 3),
                    RH_cabin0=round(rng.uniform(*RH_CABIN), 3),
                    soc_init=round(rng.uniform(*SOC_INIT), 3),
                )
            )
    return Design(train=train, heldout=heldout_scenarios(modes, quick=quick), seed=seed)


def heldout_scenarios(modes: list[str], *, quick: bool = False) -> list[Scenario]:
    """Held-out runs: each mode forced on :data:`HELDOUT_CYCLES` at the held-out ambients of its range.

    Initial conditions are fixed (no draw): the middle of the mode's ranges,
    the default setpoint 25 degC, SOC 0.9, RH 0.4, sun 300 W/m2 in cooling
    modes and 0 otherwise. When every mode is trained, the
    controller's own choice (``auto``, target ``auto``) is held out too on the
    same cycles at :data:`AUTO_AMBIENTS_C`, starting at the ambient.
    """
    cycles = HELDOUT_CYCLES[1:] if quick else HELDOUT_CYCLES
    out = []
    for m in modes:
        r = RANGES[m]
        ambients = [a for a in HELDOUT_AMBIENTS_C if r.T_amb[0] <= a <= r.T_amb[1]]
        if quick:
            ambients = ambients[:1]
        for a in ambients:
            T_amb = round(C0 + a, 3)
            mid = 0.5 * (r.battery[0] + r.battery[1])
            Tb = mid if r.battery_absolute else T_amb + mid
            for c in cycles:
                out.append(
                    Scenario(
                        name=f"heldout-{m}-{c}-{a:g}C",
                        role="heldout",
                        target=m,
                        mode=m,
                        cycle=c,
                        T_amb=T_amb,
                        RH_amb=0.4,
                        sun=300.0 if m in COOLING else 0.0,
                        T_battery0=round(Tb, 3),
                        T_cabin0=round(T_amb + 0.5 * (r.cabin[0] + r.cabin[1]), 3),
                        T_set=298.15,
                        RH_cabin0=0.5,
                        soc_init=0.9,
                    )
                )
    if set(modes) == set(MODE_NAMES):
        for a in AUTO_AMBIENTS_C[:1] if quick else AUTO_AMBIENTS_C:
            T_amb = round(C0 + a, 3)
            for c in cycles:
                out.append(
                    Scenario(
                        name=f"heldout-auto-{c}-{a:g}C",
                        role="heldout",
                        target="auto",
                        mode="auto",
                        cycle=c,
                        T_amb=T_amb,
                        RH_amb=0.4,
                        sun=300.0 if a > 20 else 0.0,
                        T_battery0=None,
                        T_cabin0=None,
                        T_set=298.15,
                        RH_cabin0=0.5,
                        soc_init=0.9,
                    )
                )
    return out
