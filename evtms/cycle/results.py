"""Typed results of a cycle solve, readable as the mapping of result variables they always were.

:class:`CycleResult` holds the states and figures of every operating point
of a batch; each evaporating branch of the circuit has its own
:class:`BranchResult` (flow, heat, valve opening, outlet superheat). A
result is also a read-only mapping from the result variables' names
(:data:`RESULT_KEYS`, the names of sweep files and ``evtms cycle run``) to
their arrays, so ``result["p_A"]``, ``result.items()`` and ``dict(result)``
read it as before; a branch the circuit lacks reads as 0 (NaN at the points
not solved) for its flow and heat, and NaN for its valve and superheat.

While it solves, the solver keeps the same variables as one flat dict of
working arrays, revised in place point by point (a valve's limits solved
again, a point marked invalid with :func:`mark_invalid`); a result is made
from them once, at the end (:meth:`CycleResult.from_arrays`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from evtms.cycle.status import valid_status
from evtms.cycle.topology import Topology

#: The result variables, in the order a result lists them (then ``balance_residual``,
#: ``balance_relative`` where the energy balance was added).
RESULT_KEYS = (
    *(f"{q}_{s}" for s in "ABCD" for q in "pTh"),
    "mdot",
    "mdot_evap",
    "mdot_chiller",
    "Q_evap",
    "Q_latent",
    "Q_chiller",
    "Q_cond",
    "Q_wcc",
    "W",
    "W_fluid",
    "h_A_evap",
    "dp_valve",
    "valve_opening",
    "valve_opening_chiller",
    "superheat_actual",
    "superheat_chiller",
    "frost_risk",
    "COP",
    "COP_heating",
    "status",
    "reason",
)
_BALANCE_KEYS = ("balance_residual", "balance_relative")


@dataclass(frozen=True)
class BranchResult:
    """One evaporating branch at the solved points (NaN where a point is not solved).

    Attributes
    ----------
    component : str
        ``evaporator`` or ``chiller``.
    mdot : numpy.ndarray
        Refrigerant flow through the branch [kg/s] (0 where its valve is closed).
    Q : numpy.ndarray
        Heat flow from the refrigerant to the branch's secondary stream [W] (< 0: cooling).
    valve_opening : numpy.ndarray
        The branch valve's opening over its nominal opening [1]
        (``capacity_max / capacity_nominal`` where it is saturated, 0 where closed).
    superheat : numpy.ndarray
        The branch's outlet superheat [K]: the setpoint, or floating where its
        valve is saturated (NaN where closed).
    Q_latent : numpy.ndarray or None
        The latent (dehumidification) part of ``Q`` [W]; the evaporator's only.
    frost_risk : numpy.ndarray or None
        Share of the interpolation weight on frost-risk nodes [1] (the direct
        models: 1 or 0); the evaporator's only.
    """

    component: str
    mdot: np.ndarray
    Q: np.ndarray
    valve_opening: np.ndarray
    superheat: np.ndarray
    Q_latent: np.ndarray | None = None
    frost_risk: np.ndarray | None = None


#: Each branch's result variable per field: the evaporator (always a circuit's first branch)
#: shares the circuit's ``valve_opening`` and ``superheat_actual``.
_BRANCH_KEYS = {
    "evaporator": {
        "mdot": "mdot_evap",
        "Q": "Q_evap",
        "valve_opening": "valve_opening",
        "superheat": "superheat_actual",
        "Q_latent": "Q_latent",
        "frost_risk": "frost_risk",
    },
    "chiller": {
        "mdot": "mdot_chiller",
        "Q": "Q_chiller",
        "valve_opening": "valve_opening_chiller",
        "superheat": "superheat_chiller",
    },
}
#: Variables of a branch the circuit lacks that read as 0 at solved points (the others read NaN).
_ZERO_WHEN_ABSENT = ("mdot_evap", "Q_evap", "Q_latent", "frost_risk", "mdot_chiller", "Q_chiller")
_BRANCH_ONLY = {key for keys in _BRANCH_KEYS.values() for key in keys.values()} - {"valve_opening", "superheat_actual"}
#: The variables a result holds itself (the others are its branches').
_CYCLE_KEYS = tuple(k for k in RESULT_KEYS if k not in _BRANCH_ONLY)


@dataclass(frozen=True, eq=False, repr=False)
class CycleResult(Mapping):
    """A solved batch of operating points, one array entry per point.

    Attributes
    ----------
    p_A, T_A, h_A ... p_D, T_D, h_D : numpy.ndarray
        States A (suction) to D (first branch's valve outlet) [Pa, K, J/kg].
    mdot : numpy.ndarray
        Compressor refrigerant flow [kg/s].
    Q_cond, W, W_fluid : numpy.ndarray
        Heat flow out of the condensing chain (to the air, to the WCC's
        coolant, or to both in series), compressor shaft power and
        ``mdot (h_B - h_A)`` [W].
    Q_wcc : numpy.ndarray
        The part of ``Q_cond`` the WCC gives its coolant [W] (0 in a circuit
        without one).
    COP : numpy.ndarray
        Cooling coefficient of performance (|Q_evap| + |Q_chiller|) / W [1].
    COP_heating : numpy.ndarray
        Heating coefficient of performance Q_cond / W [1] (the heat pump's).
    h_A_evap : numpy.ndarray
        The evaporating side's outlet (the branches' mixture) [J/kg].
    dp_valve, valve_opening, superheat_actual : numpy.ndarray
        The first branch's valve drop [Pa], opening over nominal [1] and outlet superheat [K].
    status, reason : numpy.ndarray
        :data:`~evtms.cycle.status.CYCLE_FLAGS` code (int8) and why a point
        failed, or what its flags mean.
    branches : dict of str to BranchResult
        The circuit's evaporating branches, by component, in the circuit's order.
    balance_residual, balance_relative : numpy.ndarray or None
        The energy balance [W], [1] (:func:`evtms.cycle.api.energy_balance`), where added.
    """

    p_A: np.ndarray
    T_A: np.ndarray
    h_A: np.ndarray
    p_B: np.ndarray
    T_B: np.ndarray
    h_B: np.ndarray
    p_C: np.ndarray
    T_C: np.ndarray
    h_C: np.ndarray
    p_D: np.ndarray
    T_D: np.ndarray
    h_D: np.ndarray
    mdot: np.ndarray
    Q_cond: np.ndarray
    Q_wcc: np.ndarray
    W: np.ndarray
    W_fluid: np.ndarray
    h_A_evap: np.ndarray
    dp_valve: np.ndarray
    valve_opening: np.ndarray
    superheat_actual: np.ndarray
    COP: np.ndarray
    COP_heating: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    branches: dict[str, BranchResult]
    balance_residual: np.ndarray | None = None
    balance_relative: np.ndarray | None = None
    _arrays: dict[str, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # The mapping view, built once: the same arrays, in RESULT_KEYS order.
        object.__setattr__(self, "_arrays", self._flatten())

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], circuit: Topology) -> CycleResult:
        """The result of the working arrays ``arrays`` (every :data:`RESULT_KEYS` entry) of ``circuit``."""
        branches = {}
        for b in circuit.branches:
            keys = _BRANCH_KEYS[b.component]
            branches[b.component] = BranchResult(b.component, **{f: arrays[k] for f, k in keys.items()})
        return cls(**{k: arrays[k] for k in _CYCLE_KEYS}, branches=branches)

    def _flatten(self) -> dict[str, np.ndarray]:
        own = {k: getattr(self, k) for k in _CYCLE_KEYS}
        for component, b in self.branches.items():
            for f, k in _BRANCH_KEYS[component].items():
                own.setdefault(k, getattr(b, f))  # the first branch's valve is the result's own
        valid = valid_status(self.status)
        out = {}
        for k in RESULT_KEYS:
            if k in own:
                out[k] = own[k]
            elif k in _ZERO_WHEN_ABSENT:
                out[k] = np.where(valid, 0.0, np.nan)
            else:
                out[k] = np.full(self.status.size, np.nan)
        for k in _BALANCE_KEYS:
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        return out

    def with_balance(self, residual: np.ndarray, relative: np.ndarray) -> CycleResult:
        """This result with its energy balance ``residual`` [W] and ``relative`` [1] added."""
        return dataclasses.replace(self, balance_residual=residual, balance_relative=relative)

    def to_dict(self) -> dict[str, np.ndarray]:
        """The result variables as a plain dict (the same arrays)."""
        return dict(self._arrays)

    def __getitem__(self, key: str) -> np.ndarray:
        return self._arrays[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._arrays)

    def __len__(self) -> int:
        return len(self._arrays)

    def __contains__(self, key: object) -> bool:
        return key in self._arrays

    def __repr__(self) -> str:
        codes, counts = np.unique(self.status, return_counts=True)
        statuses = ", ".join(f"{int(c)}: {int(k)}" for c, k in zip(codes, counts, strict=True))
        return f"CycleResult({self.status.size} points, branches {list(self.branches)}, statuses {{{statuses}}})"


def mark_invalid(res: dict, where: np.ndarray, status: int, reasons) -> None:
    """Mark the points ``where`` (mask or indices) of the working arrays ``res`` ``status`` with
    their ``reasons``, their states NaN (in place)."""
    res["status"][where] = status
    res["reason"][where] = reasons
    for v in res.values():
        if v.dtype.kind == "f":
            v[where] = np.nan
