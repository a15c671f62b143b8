"""The circuits the cycle solver knows, and their operating inputs, declared once.

A circuit has one compressor, one condensing component with a receiver after
it (the air-cooled front condenser, or the water-cooled condenser, WCC, that
heats the heating loop's coolant), and one or two evaporating branches in
parallel, each behind its own thermostatic expansion valve (TXV) that holds
the superheat at that branch's outlet:

- ``cabin``: the evaporator cools the cabin air (the thesis' loop);
- ``chiller``: the chiller cools the battery coolant, the cabin blower off
  (battery cooling, mode BC);
- ``cabin+chiller``: both in parallel, one compressor (modes CC and BC at
  once): the valves split the condenser's liquid between the branches so
  that both outlets leave at the setpoint superheat, and their outlets mix at
  the compressor suction. A valve that would need more than its maximum
  opening sits at it, its branch's superheat floating while the other holds
  the setpoint; a branch that would need less than the least flow its model
  covers has its valve closed (no flow, no heat);
- ``hp``: the heat pump: the WCC heats the heating loop (H), the chiller
  draws on the e-drive loop (E); the front condenser and the cabin
  evaporator are shut, so no air input enters (system-v2 spec, section 6);
- ``cabin+wcc``: the cabin loop with the WCC ahead of the front condenser
  in series: the discharge gas gives heat to a coolant loop first (the
  e-drive loop rejecting, or the heating loop reheating), the condenser
  condenses the rest into the receiver. The discharge is searched from
  condensing above the air: with its coolant warmer than that, the WCC only
  desuperheats; not even colder than the discharge gas, it takes no heat.

:data:`INPUTS` declares every operating input once (units, meaning, allowed
range, how the command line takes it); a topology lists the ones it uses.
:func:`parse_inputs` turns command-line text into validated SI values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evtms.errors import EvtmsInputError


@dataclass(frozen=True)
class CycleInput:
    """One operating input of the cycle.

    Attributes
    ----------
    name : str
        Name in :class:`~evtms.cycle.solver.OperatingPoints` and in sweep files.
    units : str
        SI units (UDUNITS).
    long_name : str
        Meaning.
    lower, upper : float
        Allowed range [SI units], both ends included unless ``positive``.
    default : float
        Value when the command line does not give one [SI units].
    celsius : bool
        The command line takes it in degC.
    positive : bool
        The lower end 0 itself is not allowed.
    """

    name: str
    units: str
    long_name: str
    lower: float
    upper: float
    default: float
    celsius: bool = False
    positive: bool = False

    def allowed(self) -> str:
        """The allowed range in command-line units."""
        lo, hi = (self.lower - 273.15, self.upper - 273.15) if self.celsius else (self.lower, self.upper)
        unit = " degC" if self.celsius else ("" if self.units == "1" else f" {self.units}")
        if self.positive:
            return f"0 < {self.name} <= {hi:g}{unit}"
        return f"{lo:g} to {hi:g}{unit}"


#: Every operating input of the cycle, in the order of a sweep's dimensions.
INPUTS: dict[str, CycleInput] = {
    i.name: i
    for i in (
        CycleInput("speed", "1", "compressor speed, fraction of maximum", 0.0, 1.0, 0.6, positive=True),
        CycleInput("fan", "1", "condenser fan fraction", 0.0, 1.0, 0.5, positive=True),
        CycleInput("blower", "1", "evaporator blower fraction", 0.0, 1.0, 0.4, positive=True),
        CycleInput("T_amb", "K", "ambient air temperature at the condenser", 233.15, 333.15, 303.15, celsius=True),
        CycleInput("RH_amb", "1", "ambient relative humidity", 0.0, 1.0, 0.4),
        CycleInput("T_cabin", "K", "air temperature entering the evaporator", 253.15, 323.15, 300.15, celsius=True),
        CycleInput("RH_cabin", "1", "relative humidity of the air entering the evaporator", 0.0, 1.0, 0.5),
        # Heating loop: the same coolant through the WCC; 0.2 kg/s is the WCC's sizing flow. The range
        # is the heating loop's, from a cold soak to a warm heater core (the WCC LUT spans 5-75 degC).
        CycleInput(
            "mdot_coolant_h", "kg s-1", "heating-loop coolant mass flow through the WCC", 0.0, 2.0, 0.2, positive=True
        ),
        CycleInput(
            "T_coolant_h_in",
            "K",
            "heating-loop coolant temperature entering the WCC",
            253.15,
            363.15,
            313.15,
            celsius=True,
        ),
        # Battery loop: a 50 % ethylene-glycol coolant; 0.15 kg/s is about 8 l/min.
        CycleInput("mdot_coolant", "kg s-1", "coolant mass flow through the chiller", 0.0, 2.0, 0.15, positive=True),
        CycleInput(
            "T_coolant_in", "K", "coolant temperature entering the chiller", 253.15, 333.15, 303.15, celsius=True
        ),
        # The compressor takes its suction as (p, T): a state on the saturation line (0 K) is not
        # one, and no thermostatic valve holds less than its static superheat of a few kelvin.
        CycleInput("superheat", "K", "superheat setpoint of the expansion valves", 0.1, 50.0, 10.0),
        CycleInput("subcooling", "K", "subcooling at the condenser outlet (0 = saturated liquid)", 0.0, 30.0, 0.0),
    )
}


@dataclass(frozen=True)
class Branch:
    """An evaporating branch: its component and the secondary stream it cools.

    Attributes
    ----------
    component : str
        Bench name (``evaporator``, ``chiller``).
    inputs : tuple of str
        Operating inputs of its secondary stream.
    secondary_temperature : str
        The input that is the secondary stream's inlet temperature: the
        refrigerant must evaporate below it.
    label : str
        Short description for reports.
    """

    component: str
    inputs: tuple[str, ...]
    secondary_temperature: str
    label: str


CABIN = Branch("evaporator", ("blower", "T_cabin", "RH_cabin"), "T_cabin", "cabin evaporator")
BATTERY = Branch("chiller", ("mdot_coolant", "T_coolant_in"), "T_coolant_in", "battery chiller")
#: The same chiller with its valve V_ch on the e-drive loop (the heat pump's source).
EDRIVE = Branch("chiller", ("mdot_coolant", "T_coolant_in"), "T_coolant_in", "e-drive chiller")


@dataclass(frozen=True)
class Condensing:
    """The condensing component ahead of the receiver: its bench and the secondary stream it heats.

    Attributes
    ----------
    component : str
        Bench name (``condenser``, ``wcc``).
    inputs : tuple of str
        Operating inputs of its secondary stream.
    secondary_temperature : str
        The input that is the secondary stream's inlet temperature: the
        refrigerant must condense above it.
    label : str
        Short description for reasons and reports.
    """

    component: str
    inputs: tuple[str, ...]
    secondary_temperature: str
    label: str


#: The air-cooled front condenser (ambient air blown by the fan).
AIR_CONDENSER = Condensing("condenser", ("fan", "T_amb", "RH_amb"), "T_amb", "condenser")
#: The water-cooled condenser heating the heating loop's coolant.
WCC = Condensing("wcc", ("mdot_coolant_h", "T_coolant_h_in"), "T_coolant_h_in", "water-cooled condenser")

_COMMON_FRONT = ("speed",)
_COMMON_BACK = ("superheat", "subcooling")


@dataclass(frozen=True)
class Topology:
    """A refrigerant circuit: one compressor, a condensing chain of one or two components in series
    ahead of the receiver, one or two evaporating branches."""

    name: str
    branches: tuple[Branch, ...]
    description: str
    chain: tuple[Condensing, ...] = (AIR_CONDENSER,)

    @property
    def condensing(self) -> Condensing:
        """The chain's last component: the one whose outlet the receiver holds at its condition."""
        return self.chain[-1]

    @property
    def components(self) -> tuple[str, ...]:
        """Components whose models (LUTs) the circuit needs."""
        return (
            *(c.component for c in self.chain),
            *(b.component for b in self.branches),
            "expansion_valve",
            "compressor",
        )

    @property
    def inputs(self) -> tuple[str, ...]:
        """Its operating inputs, in :data:`INPUTS` order."""
        used = {
            *_COMMON_FRONT,
            *(i for c in self.chain for i in c.inputs),
            *_COMMON_BACK,
            *(i for b in self.branches for i in b.inputs),
        }
        return tuple(name for name in INPUTS if name in used)

    @property
    def parallel(self) -> bool:
        return len(self.branches) > 1


TOPOLOGIES: dict[str, Topology] = {
    t.name: t
    for t in (
        Topology("cabin", (CABIN,), "evaporator cooling the cabin air"),
        Topology("chiller", (BATTERY,), "chiller cooling the battery coolant, cabin blower off"),
        Topology("cabin+chiller", (CABIN, BATTERY), "evaporator and chiller in parallel behind their own valves"),
        Topology(
            "hp",
            (EDRIVE,),
            "heat pump: the WCC heats the heating loop, the chiller draws on the e-drive loop",
            chain=(WCC,),
        ),
        Topology(
            "cabin+wcc",
            (CABIN,),
            "evaporator cooling the cabin air, the WCC ahead of the condenser giving heat to a coolant loop",
            chain=(WCC, AIR_CONDENSER),
        ),
    )
}


def topology(name: str | Topology) -> Topology:
    """The topology called ``name``; an unknown name is an :class:`EvtmsInputError`."""
    if isinstance(name, Topology):
        return name
    if name not in TOPOLOGIES:
        raise EvtmsInputError(f"topology {name!r} is unknown; allowed: {', '.join(TOPOLOGIES)}")
    return TOPOLOGIES[name]


def parse_values(name: str, text: str, max_points: int, label: str | None = None) -> list[float]:
    """One input's values from command-line text: ``v``, ``v1,v2,...`` or ``start:stop:count``.

    degC inputs become K; values are rounded to 12 significant digits (-40
    degC is 233.15 K exactly, 0.3 is 0.3), checked against the input's
    range and must increase strictly. ``label`` names the text in messages
    (default: the input's name as a request field, ```name```).
    """
    spec = INPUTS[name]
    label = label or f"`{name}`"
    try:
        parts = [float(v) for v in text.split(":" if ":" in text else ",")]
    except ValueError:
        raise EvtmsInputError(f"{label} {text!r} is not a number, v1,v2,... or start:stop:count") from None
    if ":" in text:
        if len(parts) != 3:
            raise EvtmsInputError(f"{label} {text!r} is not start:stop:count")
        start, stop, count = parts
        if not count.is_integer() or count < 1:
            raise EvtmsInputError(f"{label} {text!r}: the count {count:g} must be a whole number >= 1")
        if count > max_points:
            raise EvtmsInputError(f"{label} {text!r}: {count:,.0f} values is above the limit of {max_points:,}")
        values = np.linspace(start, stop, int(count))
    else:
        values = np.array(parts)
    if spec.celsius:
        values = values + 273.15
    values = [float(f"{v:.12g}") for v in values]
    for v in values:
        if not spec.lower <= v <= spec.upper or (spec.positive and v == spec.lower):
            shown = f"{v - 273.15:g} degC" if spec.celsius else f"{v:g}"
            raise EvtmsInputError(f"{name} = {shown} is not allowed; allowed: {spec.allowed()}")
    if any(b <= a for a, b in zip(values, values[1:], strict=False)):
        raise EvtmsInputError(f"{name} values must be strictly increasing")
    return values


def parse_inputs(texts: dict[str, str | None], circuit: Topology, max_points: int) -> dict[str, list[float]]:
    """The operating grid of ``circuit`` from command-line texts (None: the input's default).

    Raises
    ------
    EvtmsInputError
        A value out of range or malformed, an input the circuit does not use
        given explicitly, or more points than ``max_points``.
    """
    unused = [f"`{k}`" for k, v in texts.items() if v is not None and k not in circuit.inputs]
    if unused:
        raise EvtmsInputError(
            f"{', '.join(unused)}: not an input of the {circuit.name} topology; its inputs: "
            + ", ".join(f"`{k}`" for k in circuit.inputs)
        )
    grid = {}
    for name in circuit.inputs:
        text = texts.get(name)
        if text is None:
            spec = INPUTS[name]
            grid[name] = [spec.default]
        else:
            grid[name] = parse_values(name, text, max_points)
    points = math.prod(len(v) for v in grid.values())
    if points > max_points:
        sizes = " x ".join(f"{k} {len(v)}" for k, v in grid.items() if len(v) > 1)
        raise EvtmsInputError(
            f"the sweep has {points:,} operating points ({sizes}), above the limit of {max_points:,}; "
            "raise it with `max_points` or sweep fewer values"
        )
    return grid
