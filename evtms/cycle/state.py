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
- :class:`WarmStart`: a solve's solution, per point, for the next solve of
  nearby points to start its closures from (the suction and discharge
  pressures, the closures' slopes there, the branches' drops and the flow
  split, and a saturated valve's floating superheat);
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
#: A warm-started search's first secant step overshoots the root its slope predicts this many times [1]
#: (a cold one's, on a typical slope, 1.5 times): the slope was measured near the previous root.
WARM_OVERSHOOT = 1.2
#: Half the width [1] of the flow split's bracket around the previous suction iterate's split: the
#: split moves less than this between late iterates, more between early ones.
SPLIT_HALF_WIDTH = 0.03
#: Least distance [K] in saturation temperature between two suction iterates whose secant gives the
#: closure's local slope (closer ones carry the inner closure's tolerance as noise in their slope).
SLOPE_SPAN = 2e-3


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
    mdot_coolant_h, T_coolant_h_in : array_like
        Heating-loop coolant entering the WCC [kg/s], [K].
    mdot_coolant, T_coolant_in : array_like
        Coolant entering the chiller [kg/s], [K].

    Inputs not given take the defaults of :data:`evtms.cycle.topology.INPUTS`;
    a circuit ignores the inputs of components it does not have.
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
    mdot_coolant_h: np.ndarray = field(default=0.2)
    T_coolant_h_in: np.ndarray = field(default=313.15)
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
    closure_kernel : bool
        Find the pressure roots in the compiled kernel where it serves the circuit and models
        (:mod:`evtms.cycle.compiled`), else on the vectorised Python path.
    """

    models: LutModels | DirectModels
    sat: SaturationCurve
    circuit: Topology
    closure_kernel: bool = False

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
    outer_slope : numpy.ndarray
        Secant slope of the suction closure [1/K] through each point's last
        two suction iterates at least :data:`SLOPE_SPAN` apart (NaN: none
        yet), the local slope near its root.
    warm : bool
        The closure starts from a previous solve's solution (:class:`WarmStart`):
        its searches take the tighter steps a measured slope allows
        (:data:`WARM_OVERSHOOT`), stop at a first guess already within the
        tolerance, and the discharge search extrapolates its first guess
        from the two latest suction iterates (``t_pairs``).
    t_pairs : numpy.ndarray
        ``(2, 2, n)``: the suction and discharge saturation temperatures [K]
        of the two latest suction iterates (row 0 the latest; NaN: none yet).
    split_slope : numpy.ndarray
        Slope of the flow split's residual in the share [about K] measured by
        its latest bracket (NaN: none yet), for a warm closure's secant step.
    par_pairs : numpy.ndarray
        ``(2, 2 + branches, n)``: of the two latest suction iterates of a warm
        closure (row 0 the latest), the suction saturation temperature [K], the
        split [1] and each parallel branch's drop [Pa], to extrapolate from.
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
    outer_slope: np.ndarray = field(default_factory=lambda: np.zeros(0))
    warm: bool = False
    t_pairs: np.ndarray = field(default_factory=lambda: np.zeros((2, 2, 0)))
    split_slope: np.ndarray = field(default_factory=lambda: np.zeros(0))
    par_pairs: np.ndarray = field(default_factory=lambda: np.zeros((2, 4, 0)))

    @classmethod
    def start(
        cls,
        n: int,
        limits: dict,
        branches: tuple[str, ...],
        p_B_guess: np.ndarray | None = None,
        dp_guess: np.ndarray | None = None,
        warm: WarmStart | None = None,
    ) -> SolveState:
        """A fresh state for ``n`` points within the models' ``limits``, from optional first guesses
        of the discharge pressure [Pa] and of a single branch's pressure drop [Pa] (default 0), or
        from a previous solve's solution ``warm`` (its discharge pressure, condenser-closure slope,
        drops and split, where they are finite; they take the place of the other guesses)."""
        state = cls(
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
            outer_slope=np.full(n, np.nan),
            warm=warm is not None,
            t_pairs=np.full((2, 2, n), np.nan),
            split_slope=np.full(n, np.nan),
            par_pairs=np.full((2, 2 + len(branches), n), np.nan),
        )
        if warm is not None:
            warm.seed(state)
        return state


def _finite_or(value: np.ndarray, default: np.ndarray) -> np.ndarray:
    """``value`` where finite, else ``default``."""
    return np.where(np.isfinite(value), value, default)


@dataclass
class WarmStart:
    """A solved closure, per point, for a solve of nearby points to start from (NaN: start cold).

    The closures are root-finds of residuals that fall monotonically in their
    unknowns: a warm start changes where the searches begin, not the roots
    they end on (to within the closures' tolerances, :data:`XTOL`,
    :data:`INNER_FTOL`, :data:`OUTER_FTOL`), and a search whose warm bracket
    holds no sign change falls back to the whole range as a cold one does.

    Attributes
    ----------
    t_A : numpy.ndarray
        Suction saturation temperature at the root [K].
    outer_slope : numpy.ndarray
        The suction closure's slope there [1/K] (NaN: the typical slope).
    p_B : numpy.ndarray
        Discharge pressure [Pa].
    inner_slope : numpy.ndarray
        The condenser closure's slope [1/K].
    dp : numpy.ndarray
        A single branch's pressure drop [Pa].
    dp_branch : dict of str to numpy.ndarray
        Each parallel branch's pressure drop [Pa].
    split : numpy.ndarray
        The second parallel branch's share of the flow [1].
    superheat : numpy.ndarray
        Where the valve was saturated, the floating superheat [K] (NaN elsewhere).
    floating : WarmStart or None
        Where the valve was saturated, the closure at the floating superheat,
        with ``opening_excess`` and ``opening_slope``.
    opening_excess : numpy.ndarray
        Of a floating solution: ln(opening needed at the setpoint over the maximum) [1].
    opening_slope : numpy.ndarray
        Of a floating solution: the slope of ln(opening) in the superheat near its root [1/K].
    mode : numpy.ndarray
        Of a floating solution: the parallel branch mode it floated in (``FIRST_FLOATS``,
        ``SECOND_FLOATS``; -1 for a single branch or none).
    """

    t_A: np.ndarray
    outer_slope: np.ndarray
    p_B: np.ndarray
    inner_slope: np.ndarray
    dp: np.ndarray
    dp_branch: dict[str, np.ndarray]
    split: np.ndarray
    superheat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    floating: WarmStart | None = None
    opening_excess: np.ndarray | None = None
    opening_slope: np.ndarray | None = None
    mode: np.ndarray | None = None

    #: The per-point arrays (besides the branches' drops).
    _ARRAYS = ("t_A", "outer_slope", "p_B", "inner_slope", "dp", "split", "superheat")
    _OPENING = ("opening_excess", "opening_slope", "mode")

    def __post_init__(self) -> None:
        n = self.t_A.size
        if self.superheat.size != n:
            self.superheat = np.full(n, np.nan)
        for name in self._OPENING:
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, -1.0 if name == "mode" else np.nan))

    def __len__(self) -> int:
        return self.t_A.size

    @classmethod
    def of(cls, sat: SaturationCurve, res: dict, state: SolveState) -> WarmStart:
        """The solution of a closure: its working arrays ``res`` (:func:`evtms.cycle.closure.solve_at`)
        and its ``state`` after the last suction iterate; NaN where a point failed."""
        ok = np.isfinite(res["p_A"]) & np.isfinite(res["p_B"])
        with np.errstate(invalid="ignore"):
            t_A = np.where(ok, sat.temperature(res["p_A"]), np.nan)
        return cls(
            t_A=t_A,
            outer_slope=np.where(ok, state.outer_slope, np.nan),
            p_B=np.where(ok, res["p_B"], np.nan),
            inner_slope=np.where(ok, state.slope, np.nan),
            dp=np.where(ok, state.dp, np.nan),
            dp_branch={c: np.where(ok, v, np.nan) for c, v in state.dp_branch.items()},
            split=np.where(ok, state.split, np.nan),
            superheat=np.full(t_A.size, np.nan),
        )

    @classmethod
    def blank(cls, n: int, branches: tuple[str, ...] = ()) -> WarmStart:
        """No solution for ``n`` points (each starts cold)."""
        nan = [np.full(n, np.nan) for _ in range(6)]
        return cls(*nan[:5], {c: np.full(n, np.nan) for c in branches}, nan[5])

    def put(self, idx: np.ndarray, other: WarmStart) -> None:
        """Write the warm starts ``other`` of the points ``idx`` into this one (in place)."""
        for name in (*self._ARRAYS, *self._OPENING):
            getattr(self, name)[idx] = getattr(other, name)
        for c, v in other.dp_branch.items():
            self.dp_branch.setdefault(c, np.full(self.t_A.size, np.nan))[idx] = v

    def take(self, idx: np.ndarray) -> WarmStart:
        """The warm starts of the points ``idx`` (indices or mask)."""
        return WarmStart(
            t_A=self.t_A[idx],
            outer_slope=self.outer_slope[idx],
            p_B=self.p_B[idx],
            inner_slope=self.inner_slope[idx],
            dp=self.dp[idx],
            dp_branch={c: v[idx] for c, v in self.dp_branch.items()},
            split=self.split[idx],
            superheat=self.superheat[idx],
            floating=None if self.floating is None else self.floating.take(idx),
            opening_excess=self.opening_excess[idx],
            opening_slope=self.opening_slope[idx],
            mode=self.mode[idx],
        )

    def seed(self, state: SolveState) -> None:
        """Start ``state``'s discharge search, drops and split from this solution where it has one."""
        state.p_B[:] = _finite_or(self.p_B, state.p_B)
        state.slope[:] = np.where(self.inner_slope < 0, self.inner_slope, state.slope)
        state.dp[:] = _finite_or(self.dp, state.dp)
        for c, v in state.dp_branch.items():
            if c in self.dp_branch:
                v[:] = _finite_or(self.dp_branch[c], v)
        state.split[:] = _finite_or(self.split, state.split)
