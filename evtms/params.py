"""Parameter machinery shared by every component, and the ambient-air boundary.

Each component declares its own parameter table in its module (a frozen
dataclass: :class:`evtms.benches.coil.CoilParams`,
:class:`evtms.benches.compressor.CompressorParams`, ...) with the field
helpers of this module, and its :class:`~evtms.benches.base.Bench` names
the table's default; :mod:`evtms.benches.parameters` collects one table per
registered component into :class:`~evtms.benches.parameters.Parameters`.
Defaults come from the blocks of MathWorks' Simscape "Electric Vehicle
Thermal Management" example (R2024a/R2025b), except where a class's
docstring says otherwise. All values are SI. A user overrides any of them
with a TOML file whose tables are named after the components, for example::

    [condenser]
    n_tubes = 44
    fan_flow_max = 0.95        # m3/s

    [environment]
    T = 308.15                 # K

Every parameter declares its physically sensible range once, beside its
default (``param(default, lo, hi, units)``, kept as the field's
``metadata["range"]``, a :class:`Range`); a few relations between parameters
of one table (``capacity_max >= capacity_nominal``, ...) are the table
class's ``RELATIONS`` (:class:`Relation`). :func:`override` and
:func:`check_table` refuse anything else with one line naming the table, the
key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: CoolProp backends a parameter file or ``--backend`` may name.
BACKENDS = ("HEOS", "BICUBIC&HEOS")

#: Largest parameter file read [bytes]; a parameter file is a few hundred bytes.
MAX_PARAMS_BYTES = 1024 * 1024
#: Deepest nesting of tables and arrays a parameter or scenario file may have (theirs is 4 at most).
MAX_TOML_DEPTH = 32


@dataclass(frozen=True)
class Range:
    """The values one parameter may take.

    Attributes
    ----------
    lo, hi : float
        Bounds, in the parameter's units.
    units : str
        Units of the parameter (``"1"`` for a pure number).
    lo_open, hi_open : bool
        Whether the bound itself is excluded.
    whole : bool
        Whether only whole numbers are allowed (counts).
    """

    lo: float
    hi: float
    units: str = "1"
    lo_open: bool = False
    hi_open: bool = False
    whole: bool = False

    def contains(self, value: float) -> bool:
        """Whether ``value`` (a finite or non-finite number) is allowed."""
        if isinstance(value, float) and not math.isfinite(value):
            return False
        if self.whole and int(value) != value:
            return False
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        return above and below

    def describe(self, name: str) -> str:
        """The range in words, e.g. ``0 < fin_efficiency <= 1`` or ``1 <= n_tubes <= 1000 (whole number)``."""
        lo_op = "<" if self.lo_open else "<="
        hi_op = "<" if self.hi_open else "<="
        units = "" if self.units == "1" else f" {self.units}"
        whole = " (whole number)" if self.whole else ""
        return f"{_number(self.lo)} {lo_op} {name} {hi_op} {_number(self.hi)}{units}{whole}"


def param(
    default: Any,
    lo: float,
    hi: float,
    units: str = "1",
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    whole: bool = False,
    source: str = "",
    slot: str | None = None,
    optional: bool = False,
) -> Any:
    """A dataclass field with its default, allowed range, units and source, declared once.

    Parameters
    ----------
    default
        The value a table takes when a file does not give one (``None`` for an
        ``optional`` parameter whose absence means something, e.g. "the
        ambient").
    lo, hi : float
        Allowed range, in ``units``; ``lo_open``/``hi_open`` exclude the bound,
        ``whole`` allows whole numbers only.
    units : str
        Units of the value (``"1"`` for a pure number).
    source : str
        Where the default comes from (documentation tables are drawn from it).
    slot : str, optional
        Name of the slot the system's time loop reads the value from
        (``evtms.system.loop.P_<slot>``); the loop's packing is derived from it.
    optional : bool
        Whether ``None`` is allowed (only as the default: TOML has no null).

    Returns
    -------
    dataclasses.Field
        With ``metadata`` ``range`` (:class:`Range`), ``units``, ``source``,
        ``slot`` and ``optional``.
    """
    rng = Range(lo, hi, units, lo_open, hi_open, whole)
    return field(
        default=default,
        metadata={"range": rng, "units": units, "source": source, "slot": slot, "optional": optional},
    )


def choice(default: str, choices: tuple[str, ...], *, source: str = "", slot: str | None = None) -> Any:
    """A dataclass field that is one of ``choices`` (a name, not a number).

    Packed for the time loop (``slot``) as its index in ``choices``.
    """
    return field(
        default=default,
        metadata={"choices": tuple(choices), "units": "name", "source": source, "slot": slot, "optional": False},
    )


def length(default: float, hi: float = 10.0) -> Any:
    """A geometric length [m]: 0 < value <= ``hi``."""
    return param(default, 0.0, hi, "m", lo_open=True)


def area(default: float) -> Any:
    """A heat-transfer or flow area [m2]: 0 < value <= 1000."""
    return param(default, 0.0, 1000.0, "m2", lo_open=True)


def fraction(default: float) -> Any:
    """An efficiency [1]: 0 < value <= 1."""
    return param(default, 0.0, 1.0, lo_open=True)


def fouling(default: float) -> Any:
    """A fouling factor [m2 K/W]: 0 <= value < 0.01."""
    return param(default, 0.0, 0.01, "m2 K/W", hi_open=True)


def count(default: int, hi: int = 1000) -> Any:
    """A count [1]: whole number, 1 <= value <= ``hi``."""
    return param(default, 1, hi, whole=True)


def temperature(default: float) -> Any:
    """A refrigerant temperature [K]: 150 <= value <= 500."""
    return param(default, 150.0, 500.0, "K")


@dataclass(frozen=True)
class Relation:
    """A relation ``left op right(obj)`` two or more parameters of one table must keep.

    A parameter class lists its relations as ``RELATIONS: ClassVar[tuple[Relation, ...]]``;
    they are checked after the ranges.

    Attributes
    ----------
    left : str
        The parameter on the left.
    op : str
        ``"<"``, ``"<="``, ``">"`` or ``">="``.
    right : callable
        ``right(obj)``: the value ``left`` is compared with.
    text : str
        ``right`` in words, e.g. ``"tube_thickness / 2"``.
    keys : tuple of str
        The parameters ``right`` reads.
    """

    left: str
    op: str
    right: Callable[[Any], float]
    text: str
    keys: tuple[str, ...]

    def holds(self, obj: Any) -> bool:
        a, b = getattr(obj, self.left), self.right(obj)
        return {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[self.op]


def ordered(left: str, op: str, right: str) -> Relation:
    """The relation ``left op right`` between two parameters of one table (``ordered("soc_min", "<", "soc_init")``)."""
    return Relation(left, op, lambda obj: getattr(obj, right), right, (right,))


@dataclass(frozen=True)
class Environment:
    """Ambient air at the benches' boundaries.

    Attributes
    ----------
    p : float
        Air pressure [Pa], 50 kPa to 200 kPa.
    T : float
        Air temperature [K], 200 K to 400 K.
    RH : float
        Relative humidity [1], 0 to 1.
    co2_fraction : float
        CO2 mole fraction [1], 0 to 0.05; carried for parity with Simscape, no effect.
    """

    p: float = param(101325.0, 50e3, 200e3, "Pa")
    T: float = param(303.15, 200.0, 400.0, "K")
    RH: float = param(0.4, 0.0, 1.0)
    co2_fraction: float = param(4e-4, 0.0, 0.05)


def check_backend(backend: object) -> str:
    """``backend`` if it is one of :data:`BACKENDS`.

    Raises
    ------
    EvtmsInputError
        ``backend = "X" is not allowed; allowed: HEOS, BICUBIC&HEOS``.
    """
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise EvtmsInputError(f"backend = {_show(backend)} is not allowed; allowed: {', '.join(BACKENDS)}")
    return backend


def check_fluid_name(fluid: object) -> str:
    """``fluid`` if it can be a CoolProp fluid name: a short printable string.

    Whether CoolProp knows the fluid is checked when it is loaded.

    Raises
    ------
    EvtmsInputError
        Not a string, empty, longer than 100 characters or with control characters.
    """
    if not isinstance(fluid, str) or not fluid.strip() or len(fluid) > 100 or not fluid.isprintable():
        raise EvtmsInputError(f'fluid = {_show(fluid)} is not allowed; allowed: a CoolProp fluid name such as "R134a"')
    return fluid


def _number(v: float) -> str:
    """``v`` in the fewest digits that give it back (12 significant at most)."""
    if isinstance(v, int):
        return str(v)
    return f"{v:.12g}"


def _show(value: object) -> str:
    """``value`` as it would be written in TOML, on one line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return (
            "nan"
            if math.isnan(value)
            else ("inf" if value == math.inf else "-inf" if value == -math.inf else repr(value))
        )
    if isinstance(value, int):
        text = str(value)
        return text if len(text) <= 30 else f"{text[:12]}...({len(text)} digits)"
    if isinstance(value, str):
        return json.dumps(value if len(value) <= 60 else value[:60] + "...")
    if isinstance(value, (list, tuple)):
        shown = ", ".join(_show(v) for v in list(value)[:6])
        return f"[{shown}{', ...' if len(value) > 6 else ''}]"
    if isinstance(value, dict):
        return "{...}"
    return json.dumps(str(value))


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _convert(f: dataclasses.Field, value: Any, where: str) -> Any:
    """``value`` of field ``f`` as the dataclass holds it, checked against the field's range or choices."""
    key = f.name
    if value is None and f.metadata.get("optional"):
        return None
    choices = f.metadata.get("choices")
    if choices is not None:
        if not isinstance(value, str) or value not in choices:
            raise EvtmsInputError(f"{where} {key} = {_show(value)} is not allowed; allowed: {', '.join(choices)}")
        return value
    rng: Range = f.metadata["range"]
    if isinstance(value, dict):
        raise EvtmsInputError(f"{where} {key} is a table, not a value; allowed: {rng.describe(key)}")
    if not _is_number(value):
        raise EvtmsInputError(f"{where} {key} = {_show(value)} is not a number; allowed: {rng.describe(key)}")
    if not rng.contains(value):
        raise EvtmsInputError(f"{where} {key} = {_show(value)} is not allowed; allowed: {rng.describe(key)}")
    return int(value) if rng.whole else float(value)


def _check_relations(obj: Any, where: str, given: set[str]) -> None:
    """Refuse ``obj`` if it breaks a relation; blame a parameter the user gave (``given``) if any."""
    for rel in getattr(type(obj), "RELATIONS", ()):
        if rel.holds(obj):
            continue
        involved = (rel.left, *rel.keys)
        blamed = next((k for k in involved if k in given), rel.left)
        others = ", ".join(f"{k} = {_number(getattr(obj, k))}" for k in involved if k != blamed)
        raise EvtmsInputError(
            f"{where} {blamed} = {_number(getattr(obj, blamed))} is not allowed with {others}; "
            f"allowed: {rel.left} {rel.op} {rel.text}"
        )


def check_table(obj: Any, where: str) -> None:
    """Check every field of parameter dataclass ``obj`` against its range, then its class's ``RELATIONS``.

    Raises
    ------
    EvtmsInputError
        One line like ``[condenser] n_tubes = -3 is not allowed; allowed: 1 <= n_tubes <= 1000
        (whole number)`` (``where`` is ``[condenser]``).
    """
    for f in dataclasses.fields(obj):
        _convert(f, getattr(obj, f.name), where)
    _check_relations(obj, where, set())


def override(obj: Any, values: dict[str, Any], where: str) -> Any:
    """Copy of parameter dataclass ``obj`` with ``values`` replaced, each checked by name, type and range."""
    fields = {f.name: f for f in dataclasses.fields(obj)}
    changes: dict[str, Any] = {}
    for key, value in values.items():
        if key not in fields:
            allowed = ", ".join(sorted(fields))
            raise EvtmsInputError(f"{where} unknown parameter {key!r}; allowed: {allowed}")
        changes[key] = _convert(fields[key], value, where)
    new = dataclasses.replace(obj, **changes)
    _check_relations(new, where, set(changes))
    return new


def apply_tables(data: dict[str, Any], base: Any, sections: tuple[str, ...]) -> Any:
    """``base`` with the top-level keys and tables of ``data`` (parsed TOML or JSON) applied.

    ``base`` is a dataclass with ``fluid``, ``backend`` and one parameter
    dataclass per name of ``sections``; ``fluid``, ``backend`` and those
    tables are the only keys ``data`` may hold.
    """
    changes: dict[str, Any] = {}
    for section, values in data.items():
        if section == "fluid":
            changes[section] = check_fluid_name(values)
        elif section == "backend":
            changes[section] = check_backend(values)
        elif section in sections:
            if not isinstance(values, dict):
                raise EvtmsInputError(
                    f"{section} = {_show(values)} is not a table; allowed: a [{section}] table of parameters"
                )
            changes[section] = override(getattr(base, section), values, f"[{section}]")
        else:
            allowed = ", ".join(["fluid", "backend"] + [f"[{s}]" for s in sections])
            raise EvtmsInputError(f"unknown table or key {section!r}; allowed: {allowed}")
    return dataclasses.replace(base, **changes)


_KINDS = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _not_regular(mode: int) -> str | None:
    """What a non-regular file of ``mode`` is, or None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    return next((kind for test, kind in _KINDS if test(mode)), "not a regular file")


def _read_params_file(path: Path, what: str = "params file") -> str:
    """The text of a parameter file, refusing anything that is not a small regular UTF-8 text file.

    The file's type is checked with ``os.stat`` before it is opened (a named
    pipe would block, a device would never end), and again on the open file.
    ``what`` names the file in messages (``params file``, ``scenario file``).
    """
    name = repr(str(path))
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise EvtmsInputError(f"{what} {name} cannot be read: {reason}") from None
    kind = _not_regular(st.st_mode)
    if kind is not None:
        raise EvtmsInputError(f"{what} {name} is {kind}; allowed: a TOML text file")
    if st.st_size > MAX_PARAMS_BYTES:
        raise EvtmsInputError(
            f"{what} {name} has {st.st_size:,} bytes; allowed: at most {MAX_PARAMS_BYTES:,} bytes (1 MiB)"
        )
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
        with os.fdopen(fd, "rb") as fh:
            kind = _not_regular(os.fstat(fh.fileno()).st_mode)
            if kind is not None:  # replaced between the stat and the open
                raise EvtmsInputError(f"{what} {name} is {kind}; allowed: a TOML text file")
            raw = fh.read(MAX_PARAMS_BYTES + 1)
    except OSError as exc:
        raise EvtmsInputError(f"{what} {name} cannot be read: {exc.strerror or exc}") from None
    if len(raw) > MAX_PARAMS_BYTES:
        raise EvtmsInputError(f"{what} {name} is larger than {MAX_PARAMS_BYTES:,} bytes (1 MiB); allowed: less")
    if b"\x00" in raw:
        raise EvtmsInputError(f"{what} {name} is a binary file (it holds NUL bytes); allowed: a TOML text file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EvtmsInputError(
            f"{what} {name} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); save it as UTF-8"
        ) from None
    return text.removeprefix("\ufeff")


def _depth(value: Any) -> int:
    """How deeply tables (dicts) and arrays (lists) nest in ``value`` (0 for a plain value), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, level = stack.pop()
        if isinstance(v, dict | list):
            level += 1
            deepest = max(deepest, level)
            if level <= MAX_TOML_DEPTH:  # deeper is refused anyway: stop counting
                stack.extend((item, level) for item in (v.values() if isinstance(v, dict) else v))
    return deepest


def read_params_toml(path: str | Path, what: str = "params file") -> dict[str, Any]:
    """The tables of TOML parameter file ``path`` (read by :func:`_read_params_file`), parsed.

    Raises
    ------
    EvtmsInputError
        One line naming the file (as ``what``, default ``params file``) and
        what is wrong: it is missing, not a regular file, too large, binary,
        not UTF-8, not valid TOML, nested more than :data:`MAX_TOML_DEPTH`
        levels deep or empty.
    """
    path = Path(path)
    name = repr(str(path))
    text = _read_params_file(path, what)
    deep = f"{what} {name} nests tables or arrays more than {MAX_TOML_DEPTH} levels deep; allowed: at most that"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        reason = " ".join(str(exc).split())
        raise EvtmsInputError(f"{what} {name} is not valid TOML: {reason}") from None
    except RecursionError:  # the parser recurses once per level: deeper than Python's stack allows
        raise EvtmsInputError(deep) from None
    if _depth(data) > MAX_TOML_DEPTH:  # the checks and messages after this recurse as well
        raise EvtmsInputError(deep)
    if not data:
        raise EvtmsInputError(f"{what} {name} is empty; give at least one [table]")
    return data
