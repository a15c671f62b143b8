"""Component parameters and the ambient-air boundary, in one place.

Defaults come from the blocks of MathWorks' Simscape "Electric Vehicle Thermal
Management" example (R2024a/R2025b), as listed in ``shared/spec/benches.md``.
All values are SI. A user overrides any of them with a TOML file whose tables
are named after the components, for example::

    [condenser]
    n_tubes = 44
    fan_flow_max = 0.95        # m3/s

    [environment]
    T = 308.15                 # K
"""

from __future__ import annotations

import dataclasses
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


@dataclass(frozen=True)
class Environment:
    """Ambient air at the benches' boundaries.

    Attributes
    ----------
    p : float
        Air pressure [Pa].
    T : float
        Air temperature [K].
    RH : float
        Relative humidity [1].
    co2_fraction : float
        CO2 mole fraction [1]; carried for parity with Simscape, no effect.
    """

    p: float = 101325.0
    T: float = 303.15
    RH: float = 0.4
    co2_fraction: float = 4e-4


@dataclass(frozen=True)
class CoilParams:
    """Geometry and heat-transfer data shared by the two air-cooled coils.

    Flat multiport tubes with louvred fins, air in cross flow, refrigerant in
    all tubes in parallel. Areas as in the Simscape blocks.

    Attributes
    ----------
    n_tubes : int
        Number of flat tubes [1].
    core_length : float
        Tube length across the air stream [m].
    core_height : float
        Core height [m].
    tube_depth : float
        Tube width along the air flow [m].
    tube_thickness : float
        Tube outer thickness [m].
    n_channels : int
        Refrigerant channels per tube [1].
    fin_spacing : float
        Fin spacing [m].
    area_air_free : float
        Minimum free-flow area on the air side [m2].
    area_air_primary : float
        Air-side primary (tube) area [m2].
    area_air_fin : float
        Air-side fin area [m2].
    area_ref : float
        Refrigerant-side heat-transfer area [m2].
    fan_flow_max : float
        Air volume flow at fan/blower fraction 1 [m3/s].
    fin_efficiency : float
        Fin efficiency [1].
    fouling_air, fouling_ref : float
        Fouling factors [m2 K/W] (0.1 m2K/kW = 1e-4 m2K/W).
    wall_thickness : float
        Tube wall thickness [m].
    wall_conductivity : float
        Tube wall conductivity [W/(m K)].
    roughness : float
        Channel wall roughness for the friction factor [m].
    nu_laminar : float
        Fully developed laminar Nusselt number, constant wall temperature [1].
    air_nu_coeffs : tuple of float
        (a, b, c) in the air-side Nu = a Re^b Pr^c [1].
    """

    n_tubes: int = 40
    core_length: float = 1.26
    core_height: float = 0.39
    tube_depth: float = 0.015
    tube_thickness: float = 0.002
    n_channels: int = 12
    fin_spacing: float = 0.5e-3
    area_air_free: float = 0.391
    area_air_primary: float = 1.48
    area_air_fin: float = 23.4
    area_ref: float = 2.22
    fan_flow_max: float = 0.88
    fin_efficiency: float = 0.7
    fouling_air: float = 1e-4
    fouling_ref: float = 1e-4
    wall_thickness: float = 0.1e-3
    wall_conductivity: float = 240.0
    roughness: float = 15e-6
    nu_laminar: float = 3.66
    air_nu_coeffs: tuple[float, float, float] = (0.27, 0.63, 0.36)


def _evaporator_coil() -> CoilParams:
    return CoilParams(
        n_tubes=20,
        core_length=0.75,
        core_height=0.20,
        area_air_free=0.120,
        area_air_primary=0.432,
        area_air_fin=7.2,
        area_ref=0.66,
        fan_flow_max=0.3,
    )


@dataclass(frozen=True)
class CompressorParams:
    """Positive-displacement compressor.

    Attributes
    ----------
    displacement : float
        Swept volume per revolution [m3] (80 cm3).
    speed_max : float
        Shaft speed at speed fraction 1 [rev/min].
    eta_isentropic : float
        Isentropic efficiency [1].
    eta_vol_nominal : float
        Volumetric efficiency at the nominal pressure ratio [1].
    pr_nominal : float
        Nominal pressure ratio [1].
    p_in_nominal : float
        Nominal suction pressure [Pa].
    T_in_nominal : float
        Nominal suction temperature [K].
    eta_mechanical : float
        Mechanical efficiency [1].
    polytropic_exponent : float
        Re-expansion exponent of the clearance gas [1].
    suction_superheat : float
        Superheat that sets the suction pressure of the ``thesis`` grid [K].
    """

    displacement: float = 80e-6
    speed_max: float = 3600.0
    eta_isentropic: float = 0.65
    eta_vol_nominal: float = 0.9
    pr_nominal: float = 4.6
    p_in_nominal: float = 0.3e6
    T_in_nominal: float = 284.15
    eta_mechanical: float = 0.95
    polytropic_exponent: float = 1.2
    suction_superheat: float = 10.0


@dataclass(frozen=True)
class ExpansionValveParams:
    """Thermostatic expansion valve, used at its nominal opening on the bench.

    Attributes
    ----------
    capacity_nominal : float
        Evaporator capacity at the nominal opening [W].
    capacity_max : float
        Capacity at the maximum opening [W].
    T_cond_nominal : float
        Nominal condensing temperature [K].
    T_evap_nominal : float
        Nominal evaporating temperature [K].
    subcooling_nominal : float
        Nominal liquid subcooling at the valve inlet [K].
    superheat_nominal : float
        Superheat at the nominal opening [K].
    superheat_static : float
        Superheat below which the valve is closed [K].
    port_diameter : float
        Port diameter [m]; the opening area cannot exceed the port area.
    """

    capacity_nominal: float = 2000.0
    capacity_max: float = 4000.0
    T_cond_nominal: float = 313.15
    T_evap_nominal: float = 274.15
    subcooling_nominal: float = 5.0
    superheat_nominal: float = 10.0
    superheat_static: float = 5.0
    port_diameter: float = 0.010


@dataclass(frozen=True)
class Parameters:
    """Every parameter a bench or a cycle uses, with the spec's defaults."""

    fluid: str = "R134a"
    backend: str = "HEOS"
    environment: Environment = field(default_factory=Environment)
    condenser: CoilParams = field(default_factory=CoilParams)
    evaporator: CoilParams = field(default_factory=_evaporator_coil)
    compressor: CompressorParams = field(default_factory=CompressorParams)
    expansion_valve: ExpansionValveParams = field(default_factory=ExpansionValveParams)

    def component_json(self, component: str) -> str:
        """The ``parameters`` attribute of a LUT of ``component``: its parameters as JSON."""
        return json.dumps(self.for_component(component), sort_keys=True)

    def environment_json(self) -> str:
        """The ``environment`` attribute of a LUT: the air boundary as JSON."""
        return json.dumps(dataclasses.asdict(self.environment), sort_keys=True)

    def for_component(self, component: str) -> dict[str, Any]:
        """The parameters one component's bench uses, as a plain dict."""
        return {
            "fluid": self.fluid,
            "backend": self.backend,
            component: dataclasses.asdict(getattr(self, component)),
        }


# Parameters that are fractions (0..1], and those that may be zero.
_FRACTIONS = {"RH", "co2_fraction", "fin_efficiency", "eta_isentropic", "eta_vol_nominal", "eta_mechanical"}
_MAY_BE_ZERO = {"RH", "co2_fraction", "fouling_air", "fouling_ref", "roughness"}

_SECTIONS = ("environment", "condenser", "evaporator", "compressor", "expansion_valve")


def _override(obj: Any, values: dict[str, Any], where: str) -> Any:
    """Copy of dataclass ``obj`` with ``values`` replaced, each checked by name and type."""
    fields = {f.name: f for f in dataclasses.fields(obj)}
    changes: dict[str, Any] = {}
    for key, value in values.items():
        if key not in fields:
            allowed = ", ".join(sorted(fields))
            raise EvtmsInputError(f"{where}: unknown parameter {key!r}; allowed: {allowed}")
        current = getattr(obj, key)
        if isinstance(current, tuple):
            if not isinstance(value, list) or len(value) != len(current):
                raise EvtmsInputError(f"{where}.{key}: {value!r} is not a list of {len(current)} numbers")
            value = tuple(float(v) for v in value)
        elif isinstance(current, bool) or not isinstance(value, (int, float)) or isinstance(value, bool):
            raise EvtmsInputError(f"{where}.{key}: {value!r} is not a number")
        elif isinstance(current, int) and not isinstance(current, bool):
            if int(value) != value or value <= 0:
                raise EvtmsInputError(f"{where}.{key}: {value!r} is not a positive whole number")
            value = int(value)
        else:
            value = float(value)
        if isinstance(value, float) and not (value > 0 or (key in _MAY_BE_ZERO and value == 0)):
            raise EvtmsInputError(f"{where}.{key}: {value!r} must be positive")
        if key in _FRACTIONS and value > 1:
            raise EvtmsInputError(f"{where}.{key}: {value!r} must be at most 1")
        changes[key] = value
    return dataclasses.replace(obj, **changes)


def load_parameters(path: str | Path | None = None) -> Parameters:
    """Default parameters, overridden by a TOML file if ``path`` is given.

    Raises
    ------
    EvtmsInputError
        The file is missing, is not valid TOML, or names an unknown table,
        parameter or a value of the wrong type.
    """
    params = Parameters()
    if path is None:
        return params
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise EvtmsInputError(f"params file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise EvtmsInputError(f"params file {str(path)!r} is not valid TOML: {exc}") from None
    changes: dict[str, Any] = {}
    for section, values in data.items():
        if section in ("fluid", "backend"):
            if not isinstance(values, str):
                raise EvtmsInputError(f"params file {str(path)!r}: {section} must be a string")
            changes[section] = values
            continue
        if section not in _SECTIONS or not isinstance(values, dict):
            allowed = ", ".join(("fluid", "backend") + _SECTIONS)
            raise EvtmsInputError(f"params file {str(path)!r}: unknown table {section!r}; allowed: {allowed}")
        changes[section] = _override(getattr(params, section), values, section)
    return dataclasses.replace(params, **changes)
