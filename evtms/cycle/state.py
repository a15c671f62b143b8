"""What the steps of a cycle solve share: its inputs, the branch modes and the numerical settings.

- :class:`OperatingPoints`: the inputs, as equally long arrays;
- the branch modes of two parallel branches (``ops["branch_mode"]``) and the
  numerical settings the steps share.

``ops`` below is the dict of operating-input arrays of the points being
solved (:meth:`OperatingPoints.subset`, plus ``branch_mode`` and
``setpoint`` for parallel branches); the steps take subsets of it with
:func:`take`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evtms.cycle.topology import INPUTS as CYCLE_INPUTS

#: Operating-input arrays of the points being solved, by input name.
Ops = dict[str, np.ndarray]

#: Every operating input, in the order of a sweep's dimensions (declared in :mod:`evtms.cycle.topology`).
INPUTS = tuple(CYCLE_INPUTS)

#: Parallel branches (``ops["branch_mode"]``): both valves hold the setpoint; the first (second)
#: branch's valve at its maximum opening, its superheat floating; the first (second) branch's valve closed.
BOTH_HOLD, FIRST_FLOATS, SECOND_FLOATS, FIRST_CLOSED, SECOND_CLOSED = 0, 1, 2, 3, 4
#: Why a parallel split found no root: the first (second) branch would need less than its model's least
#: flow, or another bound (a branch would need more than its model's largest flow).
CLAMP_FIRST_LEAST, CLAMP_SECOND_LEAST, CLAMP_OTHER = 1, 2, 3

#: Scale [J/(kg K)] that turns the suction enthalpy residual into about kelvin of superheat.
CP_SCALE = 1000.0
#: Relative step in saturation temperature [1] below which a pressure root counts as found.
XTOL = 1e-8
#: Residual tolerances: condenser closure [1] and suction superheat [K].
INNER_FTOL = 1e-6
OUTER_FTOL = 1e-4
#: Fixed-point passes for an evaporating branch's inlet pressure per suction iterate (warm-started
#: from the previous iterate's drop), until the drop moves less than DP_TOL [Pa]. The residual must
#: be a function of the suction pressure alone: a drop left from a far iterate (the chiller's is
#: 10-40 kPa and moves kilopascals between iterates) shifted the outlet enthalpy by up to 0.3 K of
#: superheat and made a false bracket. One pass suffices at most cabin-evaporator points.
DP_PASSES = 6
DP_TOL = 2.0
#: Largest difference [J/kg] between the suction state and the branches' mixture at a solved parallel point.
MIX_TOL = 1.0


def take(ops: Ops, idx: np.ndarray) -> Ops:
    """The operating inputs of the points ``idx`` (indices or mask) of ``ops``."""
    return {k: v[idx] for k, v in ops.items()}


@dataclass
class OperatingPoints:
    """Operating points of the circuit, as equally long arrays (scalars broadcast).

    Attributes
    ----------
    speed : array_like
        Compressor speed, fraction of maximum [1].
    fan, blower : array_like
        Condenser fan and evaporator blower fractions [1].
    T_amb, RH_amb : array_like
        Ambient air at the condenser [K], [1].
    T_cabin, RH_cabin : array_like
        Air entering the evaporator [K], [1].
    mdot_coolant, T_coolant_in : array_like
        Coolant entering the chiller [kg/s], [K].

    Inputs not given take the defaults of :data:`evtms.cycle.topology.INPUTS`;
    a circuit ignores the inputs of branches it does not have.
    superheat : array_like
        Thermostatic-valve superheat setpoint at each evaporating branch's outlet [K].
    subcooling : array_like
        Condenser-outlet subcooling [K]; 0 = saturated liquid (receiver).
    """

    speed: np.ndarray
    fan: np.ndarray = field(default=0.5)
    blower: np.ndarray = field(default=0.4)
    T_amb: np.ndarray = field(default=303.15)
    RH_amb: np.ndarray = field(default=0.4)
    T_cabin: np.ndarray = field(default=300.15)
    RH_cabin: np.ndarray = field(default=0.5)
    mdot_coolant: np.ndarray = field(default=0.15)
    T_coolant_in: np.ndarray = field(default=303.15)
    superheat: np.ndarray = field(default=10.0)
    subcooling: np.ndarray = field(default=0.0)

    def __post_init__(self) -> None:
        arrays = np.broadcast_arrays(*[np.atleast_1d(np.asarray(getattr(self, k), float)) for k in INPUTS])
        for k, a in zip(INPUTS, arrays, strict=True):
            setattr(self, k, np.ascontiguousarray(a).reshape(-1))

    def __len__(self) -> int:
        return self.speed.size

    def subset(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {k: getattr(self, k)[idx] for k in INPUTS}
