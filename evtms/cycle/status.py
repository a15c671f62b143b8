"""Status codes of a solved cycle point and their CF flag meanings.

Every point of a cycle result carries one of these codes (``status``, int8)
and a ``reason``: why a point failed, or what the notes of a solved point
mean. The codes are written to sweep files as CF flags
(``flag_values`` / ``flag_meanings``), so a code keeps its number.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class CycleStatus(IntEnum):
    """Status of a solved operating point (the ``status`` of a cycle result).

    0, 5-7 and 10 are solved points (5-7 and 10 with a note); the others
    failed and their states are NaN, with the reason in ``reason``.
    """

    CONVERGED = 0
    OUTSIDE_ENVELOPE = 1
    CONDENSER_NO_ROOT = 2
    EVAPORATOR_NO_ROOT = 3
    NOT_CONVERGED = 4
    VALVE_SATURATED = 5
    FROST_RISK = 6
    VALVE_SATURATED_FROST_RISK = 7
    EVAPORATOR_WET = 8
    BRANCH_VALVE_SATURATED = 9
    BRANCH_CLOSED = 10


STATUS_CONVERGED = CycleStatus.CONVERGED
STATUS_OUTSIDE_ENVELOPE = CycleStatus.OUTSIDE_ENVELOPE
STATUS_CONDENSER_NO_ROOT = CycleStatus.CONDENSER_NO_ROOT
STATUS_EVAPORATOR_NO_ROOT = CycleStatus.EVAPORATOR_NO_ROOT
STATUS_NOT_CONVERGED = CycleStatus.NOT_CONVERGED
STATUS_VALVE_SATURATED = CycleStatus.VALVE_SATURATED
STATUS_FROST_RISK = CycleStatus.FROST_RISK
STATUS_VALVE_SATURATED_FROST_RISK = CycleStatus.VALVE_SATURATED_FROST_RISK
STATUS_EVAPORATOR_WET = CycleStatus.EVAPORATOR_WET
STATUS_BRANCH_VALVE_SATURATED = CycleStatus.BRANCH_VALVE_SATURATED
STATUS_BRANCH_CLOSED = CycleStatus.BRANCH_CLOSED

#: Status code -> CF flag meaning.
CYCLE_FLAGS = {
    int(STATUS_CONVERGED): "converged",
    int(STATUS_OUTSIDE_ENVELOPE): "outside_model_envelope",
    int(STATUS_CONDENSER_NO_ROOT): "condenser_outlet_condition_not_reachable",
    int(STATUS_EVAPORATOR_NO_ROOT): "superheat_setpoint_not_reachable",
    int(STATUS_NOT_CONVERGED): "not_converged",
    int(STATUS_VALVE_SATURATED): "converged_valve_saturated_superheat_floating",
    int(STATUS_FROST_RISK): "converged_frost_risk",
    int(STATUS_VALVE_SATURATED_FROST_RISK): "converged_valve_saturated_frost_risk",
    int(STATUS_EVAPORATOR_WET): "evaporator_outlet_wet",
    int(STATUS_BRANCH_VALVE_SATURATED): "branch_valve_beyond_max_opening",
    int(STATUS_BRANCH_CLOSED): "converged_branch_valve_closed",
}
#: Solved points: their states are valid (the flags 5-7 and 10 are notes on a valid point).
VALID_CYCLE_FLAGS = (
    STATUS_CONVERGED,
    STATUS_VALVE_SATURATED,
    STATUS_FROST_RISK,
    STATUS_VALVE_SATURATED_FROST_RISK,
    STATUS_BRANCH_CLOSED,
)
_VALID_TABLE = np.isin(np.arange(len(CYCLE_FLAGS)), VALID_CYCLE_FLAGS)


def valid_status(status: np.ndarray) -> np.ndarray:
    """Where ``status`` (codes of :data:`CYCLE_FLAGS`) is a solved point's (:data:`VALID_CYCLE_FLAGS`):
    ``np.isin`` by a table lookup, which costs a hundredth of it on the few points of a step."""
    codes = np.asarray(status, np.intp)
    known = (codes >= 0) & (codes < _VALID_TABLE.size)
    if known.all():
        return _VALID_TABLE[codes]
    return np.where(known, _VALID_TABLE[np.where(known, codes, 0)], False)


#: Solved points with the valve at its maximum opening and the superheat floating above its setpoint.
VALVE_SATURATED_FLAGS = (STATUS_VALVE_SATURATED, STATUS_VALVE_SATURATED_FROST_RISK)
#: Solved points with an evaporator surface below 0 degC under condensate (frost would build up).
FROST_RISK_FLAGS = (STATUS_FROST_RISK, STATUS_VALVE_SATURATED_FROST_RISK)
