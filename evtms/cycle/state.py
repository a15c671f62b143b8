"""What a cycle solve carries from step to step, explicitly.

- :class:`OperatingPoints`: the inputs, as equally long arrays;
- :class:`SolveContext`: what does not change during a solve (the component
  models, the saturation curve, the circuit);
- :class:`SolveState`: the warm starts of one closure on the two pressures
  (:func:`evtms.cycle.closure.solve_at`), which each suction iterate leaves
  for the next: the discharge pressure and its secant slope, the branches'
  pressure drops and the flow split. A closure solved again (a valve closed,
  a trial superheat of a saturated valve) starts a state of its own, so that
  no solve sees another's warm starts;
- the branch modes of two parallel branches (``ops["branch_mode"]``) and the
  numerical settings the steps share.

``ops`` below is the dict of operating-input arrays of the points being
solved (:meth:`OperatingPoints.subset`, plus ``branch_mode`` and
``setpoint`` for parallel branches); the steps take subsets of it with
:func:`take`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from evtms.cycle.topology import INPUTS as CYCLE_INPUTS
from evtms.cycle.topology import Topology
from evtms.fluid import SaturationCurve

if TYPE_CHECKING:
    from evtms.cycle.models import DirectModels, LutModels

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


@dataclass(frozen=True)
class SolveContext:
    """What every step of a solve uses and none changes.

    Attributes
    ----------
    models : LutModels or DirectModels
        Where the component responses come from.
    sat : SaturationCurve
        Tabulated saturation properties of the refrigerant.
    circuit : Topology
        The circuit solved.
    """

    models: LutModels | DirectModels
    sat: SaturationCurve
    circuit: Topology

    @property
    def names(self) -> tuple[str, ...]:
        """The evaporating branches' components, in the circuit's order."""
        return tuple(b.component for b in self.circuit.branches)

    @property
    def labels(self) -> tuple[str, ...]:
        """The evaporating branches' labels (as the reasons name them)."""
        return tuple(b.label for b in self.circuit.branches)

    @property
    def parallel(self) -> bool:
        return self.circuit.parallel

    @cached_property
    def max_opening(self) -> float:
        """The valve's maximum over nominal opening [1] (its maximum over nominal capacity); asked
        for once per solve (the direct models work out the valve's nominal area on each call)."""
        valve, _ = self.models.valve()
        return valve.capacity_max / valve.capacity_nominal


@dataclass
class SolveState:
    """Warm starts of one closure on the two pressures, per point of its batch.

    Each suction iterate writes what it found for the next one to start from;
    the final evaluation at the suction root reads the last iterate's.

    Attributes
    ----------
    p_discharge, pr : tuple of float
        The discharge-pressure range [Pa] and the compressor's pressure-ratio
        range [1] searched, a hair inside the models' own (the saturation
        temperature <-> pressure round trip must not step off a LUT's last node).
    axes : dict
        Which LUT axis each end of the models' ranges is (None: a physical bound).
    p_B : numpy.ndarray
        Discharge pressure at the previous suction iterate [Pa] (NaN: none yet).
    slope : numpy.ndarray
        Secant slope of the condenser closure found there [1/K] (NaN: none yet).
    dp : numpy.ndarray
        A single branch's pressure drop [Pa] at the previous suction iterate.
    dp_branch : dict of str to numpy.ndarray
        Each parallel branch's pressure drop [Pa] at the previous suction iterate.
    split : numpy.ndarray
        The second parallel branch's share of the flow there [1] (NaN: none yet).
    clamped : numpy.ndarray
        Why the split found no root there (``CLAMP_*``; 0: it found one).
    above_top : numpy.ndarray
        Points whose superheat stays above the setpoint up to the top of the
        suction search (set once the suction root is bracketed).
    """

    p_discharge: tuple[float, float]
    pr: tuple[float, float]
    axes: dict
    p_B: np.ndarray
    slope: np.ndarray
    dp: np.ndarray
    dp_branch: dict[str, np.ndarray]
    split: np.ndarray
    clamped: np.ndarray
    above_top: np.ndarray

    @classmethod
    def start(
        cls,
        n: int,
        limits: dict,
        branches: tuple[str, ...],
        p_B_guess: np.ndarray | None = None,
        dp_guess: np.ndarray | None = None,
    ) -> SolveState:
        """A fresh state for ``n`` points within the models' ``limits``, from optional first guesses
        of the discharge pressure [Pa] and of a single branch's pressure drop [Pa] (default 0)."""
        return cls(
            p_discharge=(limits["p_discharge"][0] * (1 + 1e-9), limits["p_discharge"][1] * (1 - 1e-9)),
            # A hair inside the compressor's pressure-ratio range, so that p_B/p_A stays on its grid.
            pr=(max(limits["pr"][0], 1.0) * (1 + 1e-9), limits["pr"][1] * (1 - 1e-9)),
            axes=limits["axes"],
            p_B=np.full(n, np.nan) if p_B_guess is None else np.asarray(p_B_guess, float).copy(),
            slope=np.full(n, np.nan),
            dp=np.zeros(n) if dp_guess is None else np.nan_to_num(np.asarray(dp_guess, float)),
            dp_branch={c: np.zeros(n) for c in branches},
            split=np.full(n, np.nan),
            clamped=np.zeros(n, np.int8),
            above_top=np.zeros(n, bool),
        )
