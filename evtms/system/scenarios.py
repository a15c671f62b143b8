"""Scenarios: named operating cases of a system simulation, built in or read from a TOML file.

A scenario fixes everything a run of :func:`evtms.system.simulate.simulate`
needs besides the cycle maps: the drive cycle (a built-in one,
``parked:SECONDS`` or a CSV file), the mode (``auto`` or forced), the heating
option, the ambient (temperature, humidity, sun), the initial state (battery,
coolant, cabin, SOC), the external inputs of :mod:`evtms.system.inputs`
(Table 12's Qloss, Tin, SP_evap, SP_CoHX, blower) and parameter overrides
(any table of ``--params``). The file format is ``docs/scenario-format.md``:
one TOML table per scenario, every value checked when the file is read, an
unknown key or a bad value a one-line :class:`~evtms.errors.EvtmsInputError`.

Built-in scenarios (:data:`SCENARIOS`): the v1 cases (``hot-drive``,
``cooldown``, ``cold``, ``wltc``, ``nedc``), ``hot-sun`` (SC03 conditions)
and the 16 rows ``t12-*`` of the thesis's Table 12 as the project's system
spec v2, section 4, states them. They are declared in the file format itself
(:data:`BUILTIN_TABLES`) and read by the same checks as a user's file.

The initial state goes into the parameter tables' ``T_init`` and
``soc_init`` fields (``battery.T_init``, ``coolant.T_init``,
``cabin.T_init``, ``battery.soc_init``). The heating option goes into the
parameter ``hvac.heating``.

References
----------
Thesis Table 12 (mode experiments: inputs per mode); the project's system
spec v2, sections 2.3 (blower), 4 (inputs, scenario files, built-in rows) and
8 (``hot-sun``: 40 CFR 86.160-86.161 SC03 conditions).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError
from evtms.system.drive_cycles import BUILTIN, drive_cycle
from evtms.system.inputs import FIELD_LABELS, INPUT_NAMES, InputValue, Trace, check_blower, check_inputs
from evtms.system.mode_model import MODE_CODES
from evtms.system.params import SystemParams, system_params_from_dict

#: Keys of a scenario table, in file order.
SCENARIO_KEYS = ("cycle", "mode", "heating", "T_amb", "rh_amb", "sun", "initial", "inputs", "params")
#: Keys of its ``initial`` table and the parameter each one sets.
INITIAL_KEYS = {
    "T_battery": ("battery", "T_init"),
    "T_coolant": ("coolant", "T_init"),
    "T_cabin": ("cabin", "T_init"),
    "soc": ("battery", "soc_init"),
}
#: Modes a scenario may name (``auto`` or a forced one); ``ch-hp`` is cabin heating forced on the heat pump
#: (the mode ``ch`` with ``heating = "heat_pump"``).
SCENARIO_MODES = ("auto", *MODE_CODES, "ch-hp")
#: Heating options (``hvac.heating``).
HEATING = ("ptc_air", "ptc_coolant", "heat_pump")
#: Allowed ranges: ambient [K] (that of ``--t-amb``), humidity [1], sun [W/m2], initial temperatures [K].
T_AMB_RANGE = (233.15, 333.15)
RH_RANGE = (0.0, 1.0)
SUN_RANGE = (0.0, 1500.0)
T_INIT_RANGE = (173.15, 373.15)
#: A scenario's name.
NAME_PATTERN = re.compile(r"[a-z0-9-]{1,64}")
#: Most scenarios one file may hold.
MAX_SCENARIOS = 1000
#: Defaults of the keys a table leaves out.
DEFAULTS = {"mode": "auto", "rh_amb": 0.4, "sun": 0.0}


@dataclass(frozen=True)
class Initial:
    """A scenario's initial state; None: the parameters' value (temperatures: the ambient).

    Attributes
    ----------
    T_battery, T_coolant, T_cabin : float or None
        Battery, battery-coolant and cabin (air, walls, interior) temperature [K].
    soc : float or None
        Battery state of charge [1].
    """

    T_battery: float | None = None
    T_coolant: float | None = None
    T_cabin: float | None = None
    soc: float | None = None

    def to_dict(self) -> dict[str, float]:
        """The given fields only."""
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


@dataclass(frozen=True)
class Scenario:
    """One operating case (a table of a scenario file, ``docs/scenario-format.md``).

    Attributes
    ----------
    name : str
        ``[a-z0-9-]``, at most 64 characters.
    cycle : str
        ``parked:SECONDS``, a built-in cycle or a CSV file (path as read: absolute or from the working folder).
    mode : str
        ``auto`` or a forced mode (:data:`SCENARIO_MODES`).
    heating : str or None
        ``ptc_air``, ``ptc_coolant`` or ``heat_pump``; None: the parameters' ``[hvac] heating``.
    T_amb : float or None
        Ambient temperature [K] (None: the command line's ``--t-amb``).
    rh_amb : float
        Ambient relative humidity [1].
    sun : float
        Solar irradiance [W/m2].
    initial : Initial
        Initial state.
    inputs : dict of str to float or str
        External inputs (:data:`evtms.system.inputs.INPUT_NAMES`): numbers [SI] or ``FILE.csv:column``.
    params : dict
        Parameter tables (as ``--params``), applied over the run's parameters.
    source : str
        Where it comes from (thesis table row, spec, file).
    """

    name: str
    cycle: str
    mode: str = "auto"
    heating: str | None = None
    T_amb: float | None = None
    rh_amb: float = 0.4
    sun: float = 0.0
    initial: Initial = field(default_factory=Initial)
    inputs: dict[str, float | str] = field(default_factory=dict)
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The scenario's table (keys of :data:`SCENARIO_KEYS`; unset ones left out)."""
        out: dict[str, Any] = {"cycle": self.cycle, "mode": self.mode}
        if self.heating is not None:
            out["heating"] = self.heating
        if self.T_amb is not None:
            out["T_amb"] = self.T_amb
        out["rh_amb"], out["sun"] = self.rh_amb, self.sun
        for key, value in (("initial", self.initial.to_dict()), ("inputs", self.inputs), ("params", self.params)):
            if value:
                out[key] = json.loads(json.dumps(value))  # a deep copy of plain values
        return out

    def setup(
        self,
        base: SystemParams | None = None,
        *,
        mode: str | None = None,
        inputs: Mapping[str, InputValue] | None = None,
        labels: Mapping[str, str] | None = None,
    ) -> ScenarioSetup:
        """What a run of this scenario needs: the cycle read, parameters and inputs checked and applied.

        Parameters
        ----------
        base : SystemParams, optional
            Parameters the scenario's ``params`` and ``initial`` apply over (default: the defaults).
        mode : str, optional
            Replaces the scenario's mode (the command line's ``--mode``).
        inputs : mapping of str to float or Trace, optional
            Checked inputs (SI) that replace the scenario's of the same name (command-line options).
        labels : mapping of str to str, optional
            How ``inputs`` are named in messages (default: as a request's fields, ```blower```).

        Raises
        ------
        EvtmsInputError
            The cycle or a trace file cannot be read, a parameter or initial
            value is not allowed, or a blower of 0 meets a mode that runs the
            cabin coil or a heater.
        """
        mode = self.mode if mode is None else mode
        check_choice(f"scenario {self.name!r}: mode", mode, SCENARIO_MODES)
        where = f"scenario {self.name!r}" if self.name else "scenario"
        try:
            params = system_params_from_dict(self.params, base)
            params = system_params_from_dict(self._initial_tables(), params)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"{where}: {exc}") from None
        heating = self.heating if self.heating is not None else params.hvac.heating
        if mode == "ch-hp":  # forced cabin heating on the heat pump (spec v2 3): mode ch, heating heat_pump
            mode, heating = "ch", "heat_pump"
        params = apply_heating(params, heating)
        given = check_inputs(self.inputs, labels={n: f"{where}: input {n}" for n in INPUT_NAMES})
        extra = dict(inputs or {})
        merged = {n: extra[n] if n in extra else given[n] for n in INPUT_NAMES if n in extra or n in given}
        names = {n: f"{where}: input {n}" for n in given}
        names.update({n: (labels or FIELD_LABELS).get(n, n) for n in extra})
        check_blower(merged, mode, names)
        return ScenarioSetup(
            scenario=self,
            cycle=drive_cycle(self.cycle),
            T_amb=self.T_amb,
            params=params,
            mode=mode,
            RH_amb=self.rh_amb,
            sun=self.sun,
            inputs=merged,
            heating=heating,
        )

    def _initial_tables(self) -> dict[str, dict[str, float]]:
        tables: dict[str, dict[str, float]] = {}
        for key, value in self.initial.to_dict().items():
            section, name = INITIAL_KEYS[key]
            tables.setdefault(section, {})[name] = value
        return tables


@dataclass(frozen=True)
class ScenarioSetup:
    """A scenario made ready to run (:meth:`Scenario.setup`).

    Attributes
    ----------
    scenario : Scenario
        The scenario as declared.
    cycle : DriveCycle
        Its drive cycle, read.
    T_amb : float or None
        Ambient temperature [K] (None: to be given).
    params : SystemParams
        Parameters with the scenario's tables, initial state and heating applied.
    mode : str
        Mode of the run.
    RH_amb, sun : float
        Ambient relative humidity [1], solar irradiance [W/m2].
    inputs : dict of str to float or Trace
        External inputs, checked, SI.
    heating : str
        Heating option (set in ``params.hvac.heating``).
    """

    scenario: Scenario
    cycle: Any
    T_amb: float | None
    params: SystemParams
    mode: str
    RH_amb: float
    sun: float
    inputs: dict[str, InputValue]
    heating: str


def apply_heating(params: SystemParams, heating: str) -> SystemParams:
    """``params`` with ``hvac.heating`` set to the scenario's option."""
    return dataclasses.replace(params, hvac=dataclasses.replace(params.hvac, heating=heating))


def run_scenario(setup: ScenarioSetup, refrigerant, T_amb: float | None = None, **options):
    """Simulate a scenario (:func:`evtms.system.simulate.simulate`) and record it in the result.

    Parameters
    ----------
    setup : ScenarioSetup
        The scenario, ready (:meth:`Scenario.setup`).
    refrigerant : Refrigerant
        Cycle maps and saturation curve.
    T_amb : float, optional
        Ambient temperature [K] in place of the scenario's (required when it has none).
    **options
        More keyword arguments of ``simulate`` (``dt``, ``model``, ``output_every``, ``soak_cabin``...).

    Returns
    -------
    SimulationResult
        With ``attrs`` and ``summary`` holding ``scenario``, ``heating`` and
        ``inputs`` (numbers [SI], traces as ``FILE.csv:column``; JSON text in
        ``attrs``).
    """
    from evtms.system.inputs import describe_inputs
    from evtms.system.simulate import simulate

    T = setup.T_amb if T_amb is None else T_amb
    if T is None:
        raise EvtmsInputError(
            f"scenario {setup.scenario.name!r} has no ambient of its own; give one (`t_amb` DEGC, or T_amb in the file)"
        )
    result = simulate(
        setup.cycle,
        T,
        refrigerant,
        setup.params,
        mode=setup.mode,
        RH_amb=setup.RH_amb,
        sun=setup.sun,
        scenario=setup.scenario.name,
        inputs=setup.inputs,
        **options,
    )
    described = describe_inputs(setup.inputs)
    result.attrs["heating"] = result.summary["heating"] = setup.heating
    result.attrs["inputs"] = json.dumps(described)
    result.summary["inputs"] = described
    result.summary["scenario"] = setup.scenario.name
    result.summary["mode_request"] = setup.mode
    return result


# ---------------------------------------------------------------------------------------------- checks


def check_choice(what: str, value: Any, allowed: Iterable[str]) -> str:
    """``value`` if it is one of ``allowed``; else one line naming ``what`` and the choices."""
    allowed = tuple(allowed)
    if not isinstance(value, str) or value not in allowed:
        raise EvtmsInputError(f"{what} {value!r} is unknown; allowed: {', '.join(allowed)}")
    return value


def _number(what: str, value: Any, lo: float, hi: float, units: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise EvtmsInputError(f"{what} = {value!r} is not a finite number; allowed: {lo:g} to {hi:g} {units}")
    if not lo <= value <= hi:
        raise EvtmsInputError(f"{what} = {value!r} is not allowed; allowed: {lo:g} to {hi:g} {units}")
    return float(value)


def _resolve(path: str, base: Path | None) -> str:
    p = Path(path).expanduser()
    return str(base / p) if base is not None and not p.is_absolute() else str(p)


def scenario_from_dict(name: str, table: Any, *, base: str | Path | None = None, where: str = "") -> Scenario:
    """A scenario from its table (the TOML format of ``docs/scenario-format.md``), every value checked.

    Parameters
    ----------
    name : str
        The table's name, ``[a-z0-9-]`` (1 to 64 characters).
    table : dict
        Keys of :data:`SCENARIO_KEYS`: ``cycle`` (required), ``mode``,
        ``heating``, ``T_amb`` [K], ``rh_amb`` [1], ``sun`` [W/m2],
        ``initial`` (``T_battery``, ``T_coolant``, ``T_cabin`` [K], ``soc``
        [1]), ``inputs`` (numbers [SI] or ``FILE.csv:column``), ``params``
        (tables of ``--params``).
    base : str or Path, optional
        Folder relative file paths (cycle, traces) are read from (a scenario file's folder).
    where : str
        Prefix of messages (``scenario file 'x.toml': ``).

    Returns
    -------
    Scenario
        File paths made relative to the working folder (or absolute).

    Raises
    ------
    EvtmsInputError
        One line naming the scenario, the key and what is allowed: a bad
        name, not a table, an unknown or missing key, a value of the wrong
        type or out of range, an unknown mode or heating, a cycle or trace file that cannot be
        read, a blower of 0 with a mode that runs the cabin coil or a heater,
        a parameter not allowed, an initial value also set in ``params``.
    """
    at = f"{where}[{name}]"
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise EvtmsInputError(f"{where}scenario name {name!r} is not allowed; allowed: 1 to 64 of a-z, 0-9 and -")
    if not isinstance(table, dict):
        raise EvtmsInputError(f"{at} must be a table of {', '.join(SCENARIO_KEYS)}, not a value")
    for key in table:
        if key not in SCENARIO_KEYS:
            raise EvtmsInputError(f"{at} key {key!r} is unknown; allowed: {', '.join(SCENARIO_KEYS)}")
    if "cycle" not in table:
        raise EvtmsInputError(f'{at} has no cycle; give cycle = "parked:SECONDS", a built-in cycle or a CSV file')
    base = Path(base) if base is not None else None
    cycle = table["cycle"]
    if not isinstance(cycle, str):
        raise EvtmsInputError(f"{at} cycle = {cycle!r} is not a string; allowed: parked:SECONDS, a built-in, FILE.csv")
    if cycle not in BUILTIN:  # built-ins ship with the package; the others are read now, refused with the file
        if not cycle.startswith("parked:"):
            cycle = _resolve(cycle, base)
        try:
            drive_cycle(cycle)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"{at} cycle: {exc}") from None
    mode = check_choice(f"{at} mode", table.get("mode", DEFAULTS["mode"]), SCENARIO_MODES)
    heating = table.get("heating")
    if heating is not None:  # else the parameters' [hvac] heating
        heating = check_choice(f"{at} heating", heating, HEATING)
    T_amb = table.get("T_amb")
    if T_amb is not None:
        T_amb = _number(f"{at} T_amb", T_amb, *T_AMB_RANGE, "K (TOML temperatures are in K)")
    rh = _number(f"{at} rh_amb", table.get("rh_amb", DEFAULTS["rh_amb"]), *RH_RANGE, "(a fraction)")
    sun = _number(f"{at} sun", table.get("sun", DEFAULTS["sun"]), *SUN_RANGE, "W/m2")
    initial = _initial(at, table.get("initial", {}))
    inputs = _inputs(at, table.get("inputs", {}), mode, base)
    params = table.get("params", {})
    if not isinstance(params, dict):
        raise EvtmsInputError(
            f"{at} params must be a table of system-parameter tables, e.g. {{ cabin = {{ T_set = 295.15 }} }}"
        )
    try:
        checked = system_params_from_dict(params)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"{at} params: {exc}") from None
    for key, value in initial.to_dict().items():
        section, pname = INITIAL_KEYS[key]
        if pname in params.get(section, {}):
            raise EvtmsInputError(f"{at} sets initial.{key} and params.{section}.{pname}; give one of them")
        try:
            system_params_from_dict({section: {pname: value}}, checked)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"{at} initial.{key}: {exc}") from None
    return Scenario(
        name=name,
        cycle=cycle,
        mode=mode,
        heating=heating,
        T_amb=T_amb,
        rh_amb=rh,
        sun=sun,
        initial=initial,
        inputs=inputs,
        params=json.loads(json.dumps(params)),
        source=where.removesuffix(": ") or "",
    )


def _initial(at: str, table: Any) -> Initial:
    if not isinstance(table, dict):
        raise EvtmsInputError(f"{at} initial must be a table {{ T_battery, T_coolant, T_cabin, soc }}, not a value")
    values = {}
    for key, value in table.items():
        if key not in INITIAL_KEYS:
            raise EvtmsInputError(f"{at} initial.{key} is unknown; allowed: {', '.join(INITIAL_KEYS)}")
        if key == "soc":
            values[key] = _number(f"{at} initial.soc", value, 0.0, 1.0, "(a fraction)")
        else:
            values[key] = _number(f"{at} initial.{key}", value, *T_INIT_RANGE, "K (TOML temperatures are in K)")
    return Initial(**values)


def _inputs(at: str, table: Any, mode: str, base: Path | None) -> dict[str, float | str]:
    if not isinstance(table, dict):
        raise EvtmsInputError(f"{at} inputs must be a table of {', '.join(INPUT_NAMES)}, not a value")
    raw: dict[str, float | str] = {}
    for key, value in table.items():
        if isinstance(value, str) and value.lower().rpartition(":")[0].endswith(".csv"):
            file, _, column = value.rpartition(":")
            value = f"{_resolve(file, base)}:{column}"
        raw[key] = value
    try:
        checked = check_inputs(raw, mode=mode, labels={n: f"input {n}" for n in INPUT_NAMES})
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"{at} {exc}") from None
    return {k: (raw[k] if isinstance(v, Trace) else v) for k, v in checked.items()}


# ---------------------------------------------------------------------------------------------- files


def scenarios_from_toml_data(data: Mapping[str, Any], *, base: str | Path | None = None, where: str = "") -> dict:
    """Scenarios by name from a parsed scenario file (top-level tables), each checked."""
    if len(data) > MAX_SCENARIOS:
        raise EvtmsInputError(f"{where}{len(data):,} scenarios; allowed: at most {MAX_SCENARIOS:,}")
    return {name: scenario_from_dict(name, table, base=base, where=where) for name, table in data.items()}


def read_scenario_file(path: str | Path) -> dict[str, Scenario]:
    """The scenarios of a TOML scenario file (``docs/scenario-format.md``), by name, in file order.

    Relative file paths in it (cycle, traces) are read from the file's folder.

    Raises
    ------
    EvtmsInputError
        One line naming the file: it cannot be read or is not TOML (as a
        params file), or a scenario breaks :func:`scenario_from_dict`'s rules.
    """
    from evtms.params import read_params_toml

    path = Path(path)
    data = read_params_toml(path, "scenario file")
    return scenarios_from_toml_data(data, base=path.parent, where=f"scenario file {str(path)!r}: ")


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise EvtmsInputError(f"{value!r} cannot be written to a scenario file; give a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a TOML basic string
    if isinstance(value, Mapping):
        inner = ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items())
        return f"{{ {inner} }}" if inner else "{}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise EvtmsInputError(f"{value!r} cannot be written to a scenario file")


def scenarios_to_toml(scenarios: Iterable[Scenario]) -> str:
    """A scenario file holding ``scenarios`` (one table each; :func:`read_scenario_file` reads it back)."""
    blocks = []
    for sc in scenarios:
        lines = [f"[{sc.name}]"] + [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in sc.to_dict().items()]
        blocks.append("\n".join(lines) + "\n")
    return "\n".join(blocks)


def scenario_groups(available: Iterable[str]) -> list[str]:
    """Name prefixes (cut at a ``-``) that two or more scenarios share, such as ``t12`` and ``t12-cc``."""
    names = list(available)
    prefixes = {n.rsplit("-", k)[0] for n in names for k in range(1, n.count("-") + 1)}
    return sorted(p for p in prefixes if sum(n.startswith(f"{p}-") for n in names) >= 2)


def select_scenarios(text: str, available: Mapping[str, Scenario], most: int = 100) -> list[Scenario]:
    """Scenarios named by comma-separated names; a name that is the prefix of a group (``t12``) names its rows.

    Raises
    ------
    EvtmsInputError
        Nothing named, an unknown name, one named twice, or more than ``most``.
    """
    chosen: list[Scenario] = []
    for item in (t.strip() for t in text.split(",")):
        group = [sc for key, sc in available.items() if key.startswith(f"{item}-")] if item else []
        if item in available:
            group = [available[item]]
        if not group:
            raise EvtmsInputError(
                f"scenario {item!r} is unknown; allowed: {', '.join(available)} "
                f"(or a group of them: {', '.join(scenario_groups(available))})"
            )
        chosen.extend(group)
    names = [sc.name for sc in chosen]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise EvtmsInputError(f"scenario {twice[0]!r} is named twice")
    if len(chosen) > most:
        raise EvtmsInputError(f"{len(chosen)} scenarios; allowed: at most {most}")
    return chosen


# ---------------------------------------------------------------------------------------------- built-ins


def _k(celsius: float) -> float:
    """[K] from [degC], rounded to 12 significant digits (35 degC is 308.15 K exactly)."""
    return float(f"{celsius + 273.15:.12g}")


#: Thesis Table 12 as spec v2 section 4 gives it: name -> (mode, T_amb, Tbatt, Qloss [W], Tin, SP_evap, blower,
#: SP_CoHX), temperatures [degC], None where the table has no value (Tbatt None: = T_amb).
TABLE12: dict[str, tuple] = {
    "t12-bh-1": ("bh", 25.0, -20.0, 4000.0, None, None, None, None),
    "t12-bh-2": ("bh", 30.0, -10.0, 8000.0, None, None, None, None),
    "t12-bh-3": ("bh", -15.0, 20.0, 2000.0, None, None, None, None),
    "t12-bh-4": ("bh", 0.0, -5.0, 5000.0, None, None, None, None),
    "t12-bc-1": ("bc", 20.0, 30.0, 8000.0, None, None, None, None),
    "t12-bc-2": ("bc", 30.0, 15.5, 4000.0, None, None, None, None),  # Table 12: 15 (the bc_T_battery_min edge)
    "t12-bc-3": ("bc", 40.0, 15.5, 6000.0, None, None, None, None),  # Table 12: 15
    "t12-bc-4": ("bc", 15.0, 40.5, 0.0, None, None, None, None),  # Table 12: 40 (the crit relay's edge)
    "t12-cc-1": ("cc", 20.0, None, 0.0, 40.0, 15.0, None, None),
    "t12-cc-2": ("cc", 35.0, None, 0.0, 15.0, 5.0, None, None),
    "t12-cc-3": ("cc", 45.0, None, 0.0, 45.0, 5.0, None, None),
    "t12-cc-4": ("cc", 30.0, None, 0.0, 20.0, 10.0, None, None),
    "t12-ch-1": ("ch", 0.0, 0.0, 0.0, 0.0, None, 1.0, 45.0),
    "t12-ch-2": ("ch", 0.0, 0.0, 0.0, 0.0, None, 0.2, 35.0),
    "t12-ch-3": ("ch", 0.0, 0.0, 0.0, 0.0, None, 0.6, 85.0),
    "t12-ch-4": ("ch", 0.0, 0.0, 0.0, 0.0, None, 0.8, 55.0),
}
#: Every Table 12 row: parked 1800 s (A: the thesis gives no duration), RH 0.5 (MW S), sun 0, SOC 0.9, the
#: cabin at the ambient, the v2 cabin setpoint (spec section 8), the inlet air's RH 0.5 where Tin is given.
T12_DURATION_S = 1800.0
T12_RH = 0.5
T12_SOC = 0.9
T12_T_SET = 295.15


def _table12_row(mode, t_amb, t_batt, q_loss, t_in, sp_evap, blower, sp_cohx) -> dict[str, Any]:
    T_amb = _k(t_amb)
    T_b = T_amb if t_batt is None else _k(t_batt)
    inputs: dict[str, float] = {"Q_battery_ext": q_loss}
    if t_in is not None:
        inputs.update(hvac_inlet_T=_k(t_in), hvac_inlet_rh=T12_RH)
    if sp_evap is not None:
        inputs["SP_evap"] = _k(sp_evap)
    if blower is not None:
        inputs["blower"] = blower
    if sp_cohx is not None:
        inputs["SP_CoHX"] = _k(sp_cohx)
    return {
        "cycle": f"parked:{T12_DURATION_S:g}",
        "mode": mode,
        "heating": "ptc_coolant" if mode == "ch" else "ptc_air",
        "T_amb": T_amb,
        "rh_amb": T12_RH,
        "sun": 0.0,
        "initial": {"T_battery": T_b, "T_coolant": T_b, "T_cabin": T_amb, "soc": T12_SOC},
        "inputs": inputs,
        "params": {"cabin": {"T_set": T12_T_SET}},
    }


def _soaked(T: float) -> dict[str, float]:
    return {"T_battery": T, "T_coolant": T, "T_cabin": T}


#: The built-in scenarios in the file format, with their sources.
BUILTIN_TABLES: dict[str, tuple[dict[str, Any], str]] = {
    "hot-drive": (
        {"cycle": "udds", "T_amb": 303.15, "rh_amb": 0.4, "sun": 600.0},
        "thesis 3.5 (i); 30 degC, RH 0.4 as the benches",
    ),
    "cooldown": (
        {"cycle": "udds", "T_amb": 313.15, "rh_amb": 0.5, "sun": 600.0, "initial": _soaked(313.15)},
        "Simscape BEV example 'Summer'; thesis (ii)",
    ),
    "cold": (
        {"cycle": "hwfet", "T_amb": 268.15, "rh_amb": 0.65, "sun": 300.0, "initial": _soaked(268.15)},
        "Simscape BEV example 'Winter'; thesis (iii)",
    ),
    "wltc": ({"cycle": "wltc3b", "rh_amb": 0.4, "sun": 0.0}, "UN GTR 15"),
    "nedc": ({"cycle": "nedc", "rh_amb": 0.4, "sun": 0.0}, "UNECE R83"),
    "hot-sun": (
        {"cycle": "wltc3b", "T_amb": 308.15, "rh_amb": 0.4, "sun": 850.0, "initial": _soaked(308.15)},
        "SC03 conditions (40 CFR 86.160-86.161): 35 degC, RH 0.4, 850 W/m2, soaked; spec v2 section 8",
    ),
    **{
        name: (_table12_row(*row), f"thesis Table 12 row {name[4:].upper()}; spec v2 section 4")
        for name, row in TABLE12.items()
    },
}


def _builtins() -> dict[str, Scenario]:
    out = {}
    for name, (table, source) in BUILTIN_TABLES.items():
        out[name] = dataclasses.replace(scenario_from_dict(name, table, where="built-in scenario "), source=source)
    return out


#: Built-in scenarios by name.
SCENARIOS: dict[str, Scenario] = _builtins()
