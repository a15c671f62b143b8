"""Component parameters and the ambient-air boundary, in one place.

Defaults come from the blocks of MathWorks' Simscape "Electric Vehicle Thermal
Management" example (R2024a/R2025b), except where a class's docstring says
otherwise (the expansion valve is the example's chiller valve; the louvre
geometry is typical of automotive coils). All values are SI. A user overrides any of them with a TOML file whose tables
are named after the components, for example::

    [condenser]
    n_tubes = 44
    fan_flow_max = 0.95        # m3/s

    [environment]
    T = 308.15                 # K

Every parameter declares its physically sensible range once, beside its
default (``_param(default, lo, hi, units)``, kept as the field's
``metadata["range"]``, a :class:`Range`); a few relations between parameters
(``capacity_max >= capacity_nominal``, ...) are listed in ``_RELATIONS``.
:func:`load_parameters` and :meth:`Parameters.validate` refuse anything else
with one line naming the table, the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import sys
from collections.abc import Callable, Iterable
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


def _param(
    default: Any,
    lo: float,
    hi: float,
    units: str = "1",
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    whole: bool = False,
) -> Any:
    """A dataclass field with its default and its allowed range (``metadata["range"]``, ``metadata["units"]``)."""
    rng = Range(lo, hi, units, lo_open, hi_open, whole)
    return field(default=default, metadata={"range": rng, "units": units})


def _length(default: float, hi: float = 10.0) -> Any:
    """A geometric length [m]: 0 < value <= ``hi``."""
    return _param(default, 0.0, hi, "m", lo_open=True)


def _area(default: float) -> Any:
    """A heat-transfer or flow area [m2]: 0 < value <= 1000."""
    return _param(default, 0.0, 1000.0, "m2", lo_open=True)


def _fraction(default: float) -> Any:
    """An efficiency [1]: 0 < value <= 1."""
    return _param(default, 0.0, 1.0, lo_open=True)


def _fouling(default: float) -> Any:
    """A fouling factor [m2 K/W]: 0 <= value < 0.01."""
    return _param(default, 0.0, 0.01, "m2 K/W", hi_open=True)


def _count(default: int, hi: int = 1000) -> Any:
    """A count [1]: whole number, 1 <= value <= ``hi``."""
    return _param(default, 1, hi, whole=True)


def _temperature(default: float) -> Any:
    """A refrigerant temperature [K]: 150 <= value <= 500."""
    return _param(default, 150.0, 500.0, "K")


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

    p: float = _param(101325.0, 50e3, 200e3, "Pa")
    T: float = _param(303.15, 200.0, 400.0, "K")
    RH: float = _param(0.4, 0.0, 1.0)
    co2_fraction: float = _param(4e-4, 0.0, 0.05)


@dataclass(frozen=True)
class CoilParams:
    """Geometry and heat-transfer data shared by the two air-cooled coils.

    Flat multiport tubes with louvred fins, air in cross flow, refrigerant in
    all tubes in parallel. Areas as in the Simscape blocks.

    Attributes
    ----------
    n_tubes : int
        Number of flat tubes [1], 1 to 1000; ``n_tubes * tube_thickness < core_height``.
    core_length : float
        Tube length across the air stream [m], (0, 10].
    core_height : float
        Core height [m], (0, 10].
    tube_depth : float
        Tube width along the air flow [m], (0, 1].
    tube_thickness : float
        Tube outer thickness [m], (0, 0.1].
    n_channels : int
        Refrigerant channels per tube [1], 1 to 1000.
    fin_spacing : float
        Fin spacing [m], (0, 0.1].
    area_air_free : float
        Minimum free-flow area on the air side [m2], (0, 1000], at most the
        frontal area ``core_length * core_height``.
    area_air_primary : float
        Air-side primary (tube) area [m2], (0, 1000].
    area_air_fin : float
        Air-side fin area [m2], (0, 1000].
    area_ref : float
        Refrigerant-side heat-transfer area [m2], (0, 1000].
    fan_flow_max : float
        Air volume flow at fan/blower fraction 1 [m3/s], (0, 100].
    fin_efficiency : float
        Fin efficiency [1], (0, 1].
    fouling_air, fouling_ref : float
        Fouling factors [m2 K/W], [0, 0.01) (0.1 m2K/kW = 1e-4 m2K/W).
    wall_thickness : float
        Tube wall thickness [m], (0, 0.01], less than half the tube thickness and depth.
    wall_conductivity : float
        Tube wall conductivity [W/(m K)], (0, 2000].
    roughness : float
        Channel wall roughness for the friction factor [m], [0, 0.001].
    nu_laminar : float
        Fully developed laminar Nusselt number, constant wall temperature [1], (0, 100].
    louver_angle : float
        Louver angle of the fins [rad], (0, pi/2); 27 deg by default, typical of
        automotive louvred fins.
    louver_pitch : float
        Louver pitch along the air flow [m], (0, 0.1], less than ``tube_depth``.
    louver_length : float
        Louver length across the fin [m], (0, 1], less than the fin length
        ``core_height / n_tubes - tube_thickness`` (7.75 mm condenser, 8 mm evaporator).
    fin_thickness : float
        Fin thickness [m], (0, 0.01], less than ``fin_spacing``.

    Notes
    -----
    ``fin_spacing`` is the fin pitch: with the defaults the fin area
    ``n_tubes (core_length / fin_spacing) 2 (core_height / n_tubes - tube_thickness) tube_depth``
    is the Simscape block's 23.4 m2 (condenser) and 7.2 m2 (evaporator). The
    louvred-fin air side (Chang and Wang 1997, :func:`evtms.hx.fins.chang_wang_j`)
    takes the tube pitch ``core_height / n_tubes``, the fin length (tube pitch
    minus ``tube_thickness``) and the flow depth ``tube_depth`` from these
    parameters, and the louver geometry from the four above.
    """

    n_tubes: int = _count(40)
    core_length: float = _length(1.26)
    core_height: float = _length(0.39)
    tube_depth: float = _length(0.015, 1.0)
    tube_thickness: float = _length(0.002, 0.1)
    n_channels: int = _count(12)
    fin_spacing: float = _length(0.5e-3, 0.1)
    area_air_free: float = _area(0.391)
    area_air_primary: float = _area(1.48)
    area_air_fin: float = _area(23.4)
    area_ref: float = _area(2.22)
    fan_flow_max: float = _param(0.88, 0.0, 100.0, "m3/s", lo_open=True)
    fin_efficiency: float = _fraction(0.7)
    fouling_air: float = _fouling(1e-4)
    fouling_ref: float = _fouling(1e-4)
    wall_thickness: float = _length(0.1e-3, 0.01)
    wall_conductivity: float = _param(240.0, 0.0, 2000.0, "W/(m K)", lo_open=True)
    roughness: float = _param(15e-6, 0.0, 1e-3, "m")
    nu_laminar: float = _param(3.66, 0.0, 100.0, lo_open=True)
    louver_angle: float = _param(0.47123889803846897, 0.0, 1.5707963267948966, "rad", lo_open=True, hi_open=True)
    louver_pitch: float = _length(1.0e-3, 0.1)
    louver_length: float = _length(6.5e-3, 1.0)
    fin_thickness: float = _length(0.1e-3, 0.01)


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
        Swept volume per revolution [m3] (80 cm3), (0, 0.01].
    speed_max : float
        Shaft speed at speed fraction 1 [rev/min], (0, 100000].
    eta_isentropic : float
        Isentropic efficiency [1], (0, 1].
    eta_vol_nominal : float
        Volumetric efficiency at the nominal pressure ratio [1], (0, 1].
    pr_nominal : float
        Nominal pressure ratio [1], (1, 50].
    p_in_nominal : float
        Nominal suction pressure [Pa], 1 kPa to 10 MPa.
    T_in_nominal : float
        Nominal suction temperature [K], 150 K to 500 K.
    eta_mechanical : float
        Mechanical efficiency [1], (0, 1].
    polytropic_exponent : float
        Re-expansion exponent of the clearance gas [1], 1 to 2.
    suction_superheat : float
        Superheat that sets the suction pressure of the ``thesis`` grid [K], 0 K to 100 K.
    """

    displacement: float = _param(80e-6, 0.0, 0.01, "m3", lo_open=True)
    speed_max: float = _param(3600.0, 0.0, 100_000.0, "rev/min", lo_open=True)
    eta_isentropic: float = _fraction(0.65)
    eta_vol_nominal: float = _fraction(0.9)
    pr_nominal: float = _param(4.6, 1.0, 50.0, lo_open=True)
    p_in_nominal: float = _param(0.3e6, 1e3, 10e6, "Pa")
    T_in_nominal: float = _temperature(284.15)
    eta_mechanical: float = _fraction(0.95)
    polytropic_exponent: float = _param(1.2, 1.0, 2.0)
    suction_superheat: float = _param(10.0, 0.0, 100.0, "K")


@dataclass(frozen=True)
class ExpansionValveParams:
    """Thermostatic expansion valve, used at its nominal opening on the bench.

    The capacities set the valve's flow area: the nominal opening passes
    ``capacity_nominal`` at the nominal conditions below, the maximum opening
    ``capacity_max / capacity_nominal`` times that area (the cycle holds the
    superheat up to the maximum opening and lets it float beyond). Default
    sizing: the Simscape BEV example (``simscape/Optimize-BEV-Thermal-Management-with-Simscape``,
    block data of ``Models/BEV_Thermal_Management.slx``) feeds two valves from
    one compressor, the cabin evaporator's (2 kW nominal, 4 kW max) and the
    chiller's (4.5 kW nominal, 7 kW max); evtms's circuit passes the whole
    flow of the default 80 cm3 compressor through its one valve, so it takes
    the chiller valve's rating with the cabin valve's nominal conditions. With
    the cabin valve's rating 7 of the 9 points of ``evtms cycle sweep --speed
    0.2:1:9`` needed more than its maximum opening; with the chiller valve's,
    none does (the largest needs 90 % of it, at speed 1), and about 83 % of
    1000 random points over the cycle envelope (speed, fan and blower 0.1-1,
    ambient 15-45 degC, cabin air 15-35 degC) hold their superheat. The rest
    run with the valve saturated, mostly at high speed and a cool ambient (a
    quarter of the points below 25 degC ambient): a low condensing pressure
    leaves the valve a small pressure drop.

    Attributes
    ----------
    capacity_nominal : float
        Evaporator capacity at the nominal opening [W], (0, 1 MW].
    capacity_max : float
        Capacity at the maximum opening [W], (0, 1 MW], at least ``capacity_nominal``.
    T_cond_nominal : float
        Nominal condensing temperature [K], 150 K to 500 K, above ``T_evap_nominal``.
    T_evap_nominal : float
        Nominal evaporating temperature [K], 150 K to 500 K.
    subcooling_nominal : float
        Nominal liquid subcooling at the valve inlet [K], 0 K to 100 K.
    superheat_nominal : float
        Superheat at the nominal opening [K], (0, 100] K, above ``superheat_static``.
    superheat_static : float
        Superheat below which the valve is closed [K], 0 K to 100 K.
    port_diameter : float
        Port diameter [m], (0, 0.1]; the opening area cannot exceed the port area.
    """

    capacity_nominal: float = _param(4500.0, 0.0, 1e6, "W", lo_open=True)
    capacity_max: float = _param(7000.0, 0.0, 1e6, "W", lo_open=True)
    T_cond_nominal: float = _temperature(313.15)
    T_evap_nominal: float = _temperature(274.15)
    subcooling_nominal: float = _param(5.0, 0.0, 100.0, "K")
    superheat_nominal: float = _param(10.0, 0.0, 100.0, "K", lo_open=True)
    superheat_static: float = _param(5.0, 0.0, 100.0, "K")
    port_diameter: float = _length(0.010, 0.1)


@dataclass(frozen=True)
class PlateHXParams:
    """Brazed-plate refrigerant-to-coolant evaporator (the chiller).

    Chevron plates, refrigerant and coolant in alternate channels in counter
    flow, one pass each side. The plate pack has ``n_plates`` plates and so
    ``n_plates - 1`` channels, the refrigerant in ``(n_plates - 1) // 2`` of
    them and the coolant in the rest; the two end plates do not transfer heat,
    so the heat-transfer area is ``enlargement_factor * plate_width *
    plate_length * (n_plates - 2)``. Each channel is ``2 *
    corrugation_amplitude`` deep; the hydraulic diameter is ``4 *
    corrugation_amplitude / enlargement_factor`` (Martin 1996).

    Default sizing: the Simscape BEV example's chiller valve is rated 4.5 kW
    nominal (7 kW maximum) and ``system.md`` assumes a chiller UA of about
    175 W/K. The defaults (a 0.075 m x 0.25 m plate of 60 deg chevrons,
    2 mm channels, 0.4 mm stainless steel) take the plate count (20) at
    which 4.5 kW go into R134a entering at 1 degC saturation (0.304 MPa)
    as 35 degC liquid (the valve's nominal 40 degC condensing less 5 K
    subcooling) and leaving 10 K superheated, from MEG 50 % entering at
    30 degC at 0.15 kg/s: 4.53 kW at 0.0288 kg/s of refrigerant, UA 188 W/K,
    coolant leaving at 21.0 degC, 30 kPa refrigerant pressure drop (18
    plates give 4.19 kW, 22 plates 4.84 kW). ``tests/test_chiller.py``
    checks this sizing point.

    Attributes
    ----------
    n_plates : int
        Number of plates [1], 4 to 500.
    plate_width : float
        Channel width between the gaskets [m], (0, 2].
    plate_length : float
        Flow length, port centre to port centre [m], (0, 5].
    chevron_angle : float
        Angle of the corrugations to the main flow direction [deg], (0, 90)
        (Martin's phi; 60 deg is a "hard" plate).
    corrugation_pitch : float
        Corrugation wavelength [m], (0, 0.1].
    corrugation_amplitude : float
        Corrugation amplitude, half the channel depth [m], (0, 0.01], less
        than ``corrugation_pitch / 2``.
    plate_thickness : float
        Plate wall thickness [m], (0, 0.01].
    plate_conductivity : float
        Plate conductivity [W/(m K)], (0, 2000] (16 W/(m K), stainless steel).
    port_diameter : float
        Port diameter [m], (0, 0.5], less than ``plate_width``.
    fouling_ref, fouling_coolant : float
        Fouling factors [m2 K/W], [0, 0.01) (0.1 m2K/kW each, as the coils).
    coolant_mass_fraction : float
        Glycol (MEG) mass fraction of the coolant [1], [0.1, 0.6] (CoolProp's
        range for MEG); 0.5 freezes at -34 degC.
    """

    n_plates: int = _param(20, 4, 500, whole=True)
    plate_width: float = _length(0.075, 2.0)
    plate_length: float = _length(0.25, 5.0)
    chevron_angle: float = _param(60.0, 0.0, 90.0, "deg", lo_open=True, hi_open=True)
    corrugation_pitch: float = _length(7.0e-3, 0.1)
    corrugation_amplitude: float = _length(1.0e-3, 0.01)
    plate_thickness: float = _length(0.4e-3, 0.01)
    plate_conductivity: float = _param(16.0, 0.0, 2000.0, "W/(m K)", lo_open=True)
    port_diameter: float = _length(0.016, 0.5)
    fouling_ref: float = _fouling(1e-4)
    fouling_coolant: float = _fouling(1e-4)
    coolant_mass_fraction: float = _param(0.5, 0.1, 0.6)

    @property
    def enlargement_factor(self) -> float:
        """Developed over projected plate area [1], from the corrugation (Martin 1996, eq. 2).

        ``Phi = (1 + sqrt(1 + X^2) + 4 sqrt(1 + X^2 / 2)) / 6`` with the
        wavenumber ``X = 2 pi corrugation_amplitude / corrugation_pitch``:
        1.18 with the defaults.
        """
        X = 2.0 * math.pi * self.corrugation_amplitude / self.corrugation_pitch
        return (1.0 + math.sqrt(1.0 + X * X) + 4.0 * math.sqrt(1.0 + X * X / 2.0)) / 6.0


@dataclass(frozen=True)
class _Relation:
    """A relation ``left op right(obj)`` two or more parameters of one table must keep."""

    left: str
    op: str
    right: Callable[[Any], float]
    text: str
    keys: tuple[str, ...]

    def holds(self, obj: Any) -> bool:
        a, b = getattr(obj, self.left), self.right(obj)
        return {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[self.op]


#: Relations between the parameters of one table, checked after the ranges.
_RELATIONS: dict[type, tuple[_Relation, ...]] = {
    CoilParams: (
        _Relation("wall_thickness", "<", lambda c: c.tube_thickness / 2, "tube_thickness / 2", ("tube_thickness",)),
        _Relation("wall_thickness", "<", lambda c: c.tube_depth / 2, "tube_depth / 2", ("tube_depth",)),
        _Relation(
            "n_tubes",
            "<",
            lambda c: c.core_height / c.tube_thickness,
            "core_height / tube_thickness",
            ("core_height", "tube_thickness"),
        ),
        _Relation(
            "area_air_free",
            "<=",
            lambda c: c.core_length * c.core_height,
            "core_length * core_height",
            ("core_length", "core_height"),
        ),
        _Relation(
            "louver_length",
            "<",
            lambda c: c.core_height / c.n_tubes - c.tube_thickness,
            "core_height / n_tubes - tube_thickness",
            ("core_height", "n_tubes", "tube_thickness"),
        ),
        _Relation("louver_pitch", "<", lambda c: c.tube_depth, "tube_depth", ("tube_depth",)),
        _Relation("fin_thickness", "<", lambda c: c.fin_spacing, "fin_spacing", ("fin_spacing",)),
    ),
    PlateHXParams: (
        _Relation(
            "corrugation_amplitude",
            "<",
            lambda c: c.corrugation_pitch / 2,
            "corrugation_pitch / 2",
            ("corrugation_pitch",),
        ),
        _Relation("port_diameter", "<", lambda c: c.plate_width, "plate_width", ("plate_width",)),
    ),
    ExpansionValveParams: (
        _Relation("capacity_max", ">=", lambda v: v.capacity_nominal, "capacity_nominal", ("capacity_nominal",)),
        _Relation("T_cond_nominal", ">", lambda v: v.T_evap_nominal, "T_evap_nominal", ("T_evap_nominal",)),
        _Relation("superheat_nominal", ">", lambda v: v.superheat_static, "superheat_static", ("superheat_static",)),
    ),
}

_SECTIONS = ("environment", "condenser", "evaporator", "compressor", "expansion_valve", "chiller")


@dataclass(frozen=True)
class Parameters:
    """Every parameter a bench or a cycle uses, with the spec's defaults.

    Attributes
    ----------
    fluid : str
        CoolProp fluid name (checked when the fluid is loaded).
    backend : str
        CoolProp backend, one of :data:`BACKENDS`.
    environment, condenser, evaporator, compressor, expansion_valve, chiller
        The tables of a parameter file.
    """

    fluid: str = "R134a"
    backend: str = "HEOS"
    environment: Environment = field(default_factory=Environment)
    condenser: CoilParams = field(default_factory=CoilParams)
    evaporator: CoilParams = field(default_factory=_evaporator_coil)
    compressor: CompressorParams = field(default_factory=CompressorParams)
    expansion_valve: ExpansionValveParams = field(default_factory=ExpansionValveParams)
    chiller: PlateHXParams = field(default_factory=PlateHXParams)

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

    def validate(self) -> None:
        """Check every parameter against its range and the relations between them.

        Raises
        ------
        EvtmsInputError
            One line like ``[condenser] n_tubes = -3 is not allowed; allowed: 1 <= n_tubes <= 1000
            (whole number)``.
        """
        check_fluid_name(self.fluid)
        check_backend(self.backend)
        for section in _SECTIONS:
            obj = getattr(self, section)
            for f in dataclasses.fields(obj):
                _convert(f, getattr(obj, f.name), f"[{section}]")
            _check_relations(obj, f"[{section}]", set())

    def differences(self, other: Parameters, sections: Iterable[str] | None = None) -> list[str]:
        """Dotted names of the parameters whose values differ from ``other``'s.

        Parameters
        ----------
        other : Parameters
            The parameters to compare with.
        sections : iterable of str, optional
            Compare only these top-level names (``"fluid"``, ``"backend"``,
            ``"condenser"``, ...); all by default.

        Returns
        -------
        list of str
            For example ``["condenser.n_tubes", "fluid"]``, sorted.
        """
        a, b = _flatten(self), _flatten(other)
        keep = None if sections is None else set(sections)
        return sorted(
            k for k in a.keys() | b.keys() if (keep is None or k.split(".")[0] in keep) and a.get(k) != b.get(k)
        )

    def differences_from_lut(self, component: str, parameters_json: str) -> list[str]:
        """Dotted names where these parameters contradict a LUT's ``parameters`` attribute.

        Compares ``fluid``, ``backend`` and ``component``'s table with the
        values the LUT of ``component`` was computed with.

        Raises
        ------
        EvtmsInputError
            ``parameters_json`` is not a parameters attribute of ``component``.
        """
        component = component.replace("-", "_")
        lut = parameters_from_json(component, parameters_json)
        return self.differences(lut, ("fluid", "backend", component))


def _flatten(params: Parameters) -> dict[str, Any]:
    """``{"fluid": ..., "condenser.n_tubes": ..., ...}`` of ``params``."""
    out: dict[str, Any] = {}
    for key, value in dataclasses.asdict(params).items():
        if isinstance(value, dict):
            out.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            out[key] = value
    return out


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
    """``value`` of field ``f`` as the dataclass holds it, checked against the field's range."""
    rng: Range = f.metadata["range"]
    key = f.name
    if isinstance(value, dict):
        raise EvtmsInputError(f"{where} {key} is a table, not a value; allowed: {rng.describe(key)}")
    if not _is_number(value):
        raise EvtmsInputError(f"{where} {key} = {_show(value)} is not a number; allowed: {rng.describe(key)}")
    if not rng.contains(value):
        raise EvtmsInputError(f"{where} {key} = {_show(value)} is not allowed; allowed: {rng.describe(key)}")
    return int(value) if rng.whole else float(value)


def _check_relations(obj: Any, where: str, given: set[str]) -> None:
    """Refuse ``obj`` if it breaks a relation; blame a parameter the user gave (``given``) if any."""
    for rel in _RELATIONS.get(type(obj), ()):
        if rel.holds(obj):
            continue
        involved = (rel.left, *rel.keys)
        blamed = next((k for k in involved if k in given), rel.left)
        others = ", ".join(f"{k} = {_number(getattr(obj, k))}" for k in involved if k != blamed)
        raise EvtmsInputError(
            f"{where} {blamed} = {_number(getattr(obj, blamed))} is not allowed with {others}; "
            f"allowed: {rel.left} {rel.op} {rel.text}"
        )


def _override(obj: Any, values: dict[str, Any], where: str) -> Any:
    """Copy of dataclass ``obj`` with ``values`` replaced, each checked by name, type and range."""
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


def _apply(data: dict[str, Any], base: Parameters, sections: tuple[str, ...]) -> Parameters:
    """``base`` with the top-level keys and tables of ``data`` (parsed TOML or JSON) applied."""
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
            changes[section] = _override(getattr(base, section), values, f"[{section}]")
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


def _read_params_file(path: Path) -> str:
    """The text of a parameter file, refusing anything that is not a small regular UTF-8 text file.

    The file's type is checked with ``os.stat`` before it is opened (a named
    pipe would block, a device would never end), and again on the open file.
    """
    name = repr(str(path))
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise EvtmsInputError(f"params file {name} cannot be read: {reason}") from None
    kind = _not_regular(st.st_mode)
    if kind is not None:
        raise EvtmsInputError(f"params file {name} is {kind}; allowed: a TOML text file")
    if st.st_size > MAX_PARAMS_BYTES:
        raise EvtmsInputError(
            f"params file {name} has {st.st_size:,} bytes; allowed: at most {MAX_PARAMS_BYTES:,} bytes (1 MiB)"
        )
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
        with os.fdopen(fd, "rb") as fh:
            kind = _not_regular(os.fstat(fh.fileno()).st_mode)
            if kind is not None:  # replaced between the stat and the open
                raise EvtmsInputError(f"params file {name} is {kind}; allowed: a TOML text file")
            raw = fh.read(MAX_PARAMS_BYTES + 1)
    except OSError as exc:
        raise EvtmsInputError(f"params file {name} cannot be read: {exc.strerror or exc}") from None
    if len(raw) > MAX_PARAMS_BYTES:
        raise EvtmsInputError(f"params file {name} is larger than {MAX_PARAMS_BYTES:,} bytes (1 MiB); allowed: less")
    if b"\x00" in raw:
        raise EvtmsInputError(f"params file {name} is a binary file (it holds NUL bytes); allowed: a TOML text file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EvtmsInputError(
            f"params file {name} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
            "save it as UTF-8"
        ) from None
    return text.removeprefix("\ufeff")


def load_parameters(path: str | Path | None = None) -> Parameters:
    """Default parameters, overridden by a TOML file if ``path`` is given.

    Parameters
    ----------
    path : str or Path, optional
        A regular UTF-8 TOML file of at most :data:`MAX_PARAMS_BYTES` with
        top-level ``fluid``/``backend`` and tables named after the components.

    Raises
    ------
    EvtmsInputError
        One line naming the file and what is wrong: it is missing, not a
        regular file (a folder, a named pipe, a device), too large, empty,
        binary, not UTF-8 or not valid TOML; or it names an unknown table or
        parameter, or a value of the wrong type or outside its range, e.g.
        ``params file 'p.toml': [condenser] n_tubes = -3 is not allowed;
        allowed: 1 <= n_tubes <= 1000 (whole number)``.
    """
    params = Parameters()
    if path is None:
        return params
    path = Path(path)
    name = repr(str(path))
    text = _read_params_file(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        reason = " ".join(str(exc).split())
        raise EvtmsInputError(f"params file {name} is not valid TOML: {reason}") from None
    if not data:
        raise EvtmsInputError(f"params file {name} is empty; give at least one [table]")
    try:
        return _apply(data, params, _SECTIONS)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"params file {name}: {exc}") from None


def parameters_from_json(component: str, parameters_json: str, environment_json: str | None = None) -> Parameters:
    """The parameters a LUT of ``component`` records, the others at their defaults.

    Parameters
    ----------
    component : str
        The LUT's component (``condenser``, ``expansion_valve``, ...).
    parameters_json : str
        The LUT's ``parameters`` attribute (:meth:`Parameters.component_json`).
    environment_json : str, optional
        The LUT's ``environment`` attribute (:meth:`Parameters.environment_json`).

    Raises
    ------
    EvtmsInputError
        The text is not JSON of an object, or names another component, an
        unknown parameter or a value outside its range.
    """
    component = component.replace("-", "_")
    if component not in _SECTIONS or component == "environment":
        allowed = ", ".join(s for s in _SECTIONS if s != "environment")
        raise EvtmsInputError(f"unknown component {component!r}; allowed: {allowed}")
    params = Parameters()
    for attr, text, sections in (
        ("parameters", parameters_json, (component,)),
        ("environment", environment_json, ("environment",)),
    ):
        if text is None:
            continue
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise EvtmsInputError(f"LUT attribute {attr!r} is not JSON: {exc}") from None
        if not isinstance(data, dict):
            raise EvtmsInputError(f"LUT attribute {attr!r} is not a JSON object of parameters")
        if attr == "environment":
            data = {"environment": data}
        try:
            params = _apply(data, params, sections)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"LUT attribute {attr!r}: {exc}") from None
    return params
