"""Drive cycles: the speed traces a vehicle simulation follows.

Four regulation cycles ship with evtms (``evtms/system/data/drive_cycles/``,
their sources and licences in ``SOURCE.md`` there): WLTC class 3b
(``wltc3b``), NEDC (``nedc``), EPA UDDS (``udds``) and HWFET (``hwfet``), 1 Hz.
A user trace is a CSV file in the same format (``docs/drive-cycle-format.md``):
a header ``time_s,speed_kmh`` or ``time_s,speed_kmh,grade``, ``#`` comment
lines, time in s increasing strictly from 0, speed in km/h >= 0, grade as
rise over run. Speed is linear between samples, so the distance is the
trapezoid integral of the samples. ``parked:SECONDS`` is a car standing
still for that long (the thesis's Table 12 mode experiments).

A file that breaks a rule is refused with one line naming the file, the line
and the value (:class:`~evtms.errors.EvtmsInputError`); sizes are bounded
before anything is allocated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.paths import csv_rows, read_small_text

#: Built-in cycles: name -> file in ``data/drive_cycles``.
BUILTIN = {
    "wltc3b": "wltc_class3b.csv",
    "nedc": "nedc.csv",
    "udds": "udds.csv",
    "hwfet": "hwfet.csv",
}
DATA = Path(__file__).parent / "data" / "drive_cycles"
#: Largest trace file read [bytes] (a 1 Hz trace of a day is about 2 MB).
MAX_FILE_BYTES = 50 * 1024 * 1024
#: Most samples a trace may hold (a week at 1 Hz).
MAX_SAMPLES = 604_800
#: Largest speed accepted [km/h] and largest grade magnitude [1] (35 % is a very steep road).
MAX_SPEED_KMH = 400.0
MAX_GRADE = 0.35
KMH = 1.0 / 3.6  # m/s per km/h


@dataclass(frozen=True)
class DriveCycle:
    """A speed trace.

    Attributes
    ----------
    name : str
        Built-in name or the file's name.
    time : numpy.ndarray
        Sample times [s], strictly increasing from 0.
    speed : numpy.ndarray
        Vehicle speed [m/s] at the samples, >= 0.
    grade : numpy.ndarray
        Road grade (rise over run) [1] at the samples.
    source : str
        Where the trace came from (file path).
    key_off : numpy.ndarray or None
        Per sample, True where the interval from this sample to the next is a
        key-off soak (propulsion, auxiliaries, HVAC, pumps and DC-DC off; the
        thermal network runs on). None: the key is on throughout. Range tests
        (SAE J1634 MCT) build their soaks with it.
    """

    name: str
    time: np.ndarray
    speed: np.ndarray
    grade: np.ndarray
    source: str
    key_off: np.ndarray | None = None

    @property
    def duration(self) -> float:
        """Length of the trace [s]."""
        return float(self.time[-1])

    @property
    def distance(self) -> float:
        """Distance driven [m]: the trapezoid integral of the speed (speed is linear between samples)."""
        return float(np.sum(0.5 * (self.speed[1:] + self.speed[:-1]) * np.diff(self.time)))


def _fail(where: str, rule: str) -> EvtmsInputError:
    return EvtmsInputError(f"{where}: {rule}")


def read_drive_cycle(path: str | Path, name: str | None = None) -> DriveCycle:
    """Read and check a drive-cycle CSV file (format in the module notes).

    Raises
    ------
    EvtmsInputError
        Not a regular readable file, too large, not UTF-8 text, a wrong header,
        a row that is not two or three numbers, a time that does not start at
        0 or does not increase, a speed below 0 or above 400 km/h, a grade
        beyond +-0.35, fewer than two samples or more than a week at 1 Hz.
    """
    path = Path(path)
    where = str(path)
    text = read_small_text(
        path,
        "drive cycle",
        MAX_FILE_BYTES,
        "a CSV drive cycle or one of " + ", ".join(BUILTIN),
        "a CSV drive cycle: time_s,speed_kmh[,grade]",
    )
    rows: list[tuple[float, ...]] = []
    header: list[str] | None = None
    for number, line, cells in csv_rows(text):
        if header is None:
            header = cells
            if header not in (["time_s", "speed_kmh"], ["time_s", "speed_kmh", "grade"]):
                raise _fail(
                    f"{where}:{number}", f"header {line!r}; expected time_s,speed_kmh or time_s,speed_kmh,grade"
                )
            continue
        if len(cells) != len(header):
            raise _fail(f"{where}:{number}", f"{len(cells)} values in {line!r}; expected {len(header)}")
        try:
            values = tuple(float(c) for c in cells)
        except ValueError:
            raise _fail(f"{where}:{number}", f"{line!r} is not {len(header)} numbers") from None
        if not all(math.isfinite(v) for v in values):
            raise _fail(f"{where}:{number}", f"{line!r} holds a value that is not finite")
        t, v = values[0], values[1]
        if not rows and t != 0.0:
            raise _fail(f"{where}:{number}", f"the first time is {t:g} s; a drive cycle starts at 0")
        if rows and t <= rows[-1][0]:
            raise _fail(f"{where}:{number}", f"time {t:g} s does not increase (previous {rows[-1][0]:g} s)")
        if not 0.0 <= v <= MAX_SPEED_KMH:
            raise _fail(f"{where}:{number}", f"speed {v:g} km/h is not allowed; allowed: 0 to {MAX_SPEED_KMH:g} km/h")
        if len(values) == 3 and abs(values[2]) > MAX_GRADE:
            raise _fail(
                f"{where}:{number}", f"grade {values[2]:g} is not allowed; allowed: -{MAX_GRADE} to {MAX_GRADE}"
            )
        rows.append(values)
        if len(rows) > MAX_SAMPLES:
            raise _fail(where, f"more than {MAX_SAMPLES:,} samples (a week at 1 Hz)")
    if header is None:
        raise _fail(where, "empty; a drive cycle has a header time_s,speed_kmh[,grade] and samples")
    if len(rows) < 2:
        raise _fail(where, f"{len(rows)} sample(s); a drive cycle needs at least 2")
    data = np.array(rows, dtype=float)
    grade = data[:, 2] if data.shape[1] == 3 else np.zeros(len(rows))
    return DriveCycle(name or path.stem, data[:, 0], data[:, 1] * KMH, grade, os.fspath(path))


def parked_cycle(seconds: float) -> DriveCycle:
    """The car standing still (key on) for ``seconds`` [s], 1 s to a week.

    Raises
    ------
    EvtmsInputError
        ``seconds`` not a finite number within 1 s to :data:`MAX_SAMPLES` s.
    """
    if isinstance(seconds, bool) or not isinstance(seconds, int | float) or not 1.0 <= seconds <= MAX_SAMPLES:
        raise EvtmsInputError(f"parked:{seconds} is not allowed; allowed: parked:SECONDS, 1 to {MAX_SAMPLES:,} s")
    t = np.array([0.0, float(seconds)])
    return DriveCycle(f"parked:{float(seconds):g}", t, np.zeros(2), np.zeros(2), "parked")


def drive_cycle(name_or_path: str | Path) -> DriveCycle:
    """A built-in cycle by name (``wltc3b``, ``nedc``, ``udds``, ``hwfet``), ``parked:SECONDS`` or a CSV file."""
    key = str(name_or_path)
    if key in BUILTIN:
        return read_drive_cycle(DATA / BUILTIN[key], key)
    if key.startswith("parked:"):
        try:
            seconds = float(key.removeprefix("parked:"))
        except ValueError:
            raise EvtmsInputError(
                f"drive cycle {key!r} is not parked:SECONDS; allowed: parked:SECONDS, 1 to {MAX_SAMPLES:,} s"
            ) from None
        return parked_cycle(seconds)
    path = Path(key)
    if not path.suffix.lower() == ".csv" and not path.exists():
        raise EvtmsInputError(
            f"drive cycle {key!r} is neither a built-in cycle ({', '.join(BUILTIN)}), parked:SECONDS nor a CSV file"
        )
    return read_drive_cycle(path)
