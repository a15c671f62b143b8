"""The typed cycle result reads as the mapping of result variables callers index (no solve needed)."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from evtms.cycle import BranchResult, CycleResult
from evtms.cycle.results import RESULT_KEYS
from evtms.cycle.status import STATUS_CONVERGED, STATUS_OUTSIDE_ENVELOPE
from evtms.cycle.topology import TOPOLOGIES

#: Each branch's own result variables (the evaporator's valve is also the circuit's first).
BRANCH_KEYS = {
    "evaporator": ("mdot_evap", "Q_evap", "Q_latent", "frost_risk"),
    "chiller": ("mdot_chiller", "Q_chiller", "valve_opening_chiller", "superheat_chiller"),
}


def working_arrays(n: int = 3) -> dict[str, np.ndarray]:
    """Every result variable as the solver keeps it: distinct numbers, the last point not solved."""
    arrays = {k: np.arange(n, dtype=float) + 10.0 * i for i, k in enumerate(RESULT_KEYS[:-2])}
    for v in arrays.values():
        v[-1] = np.nan
    arrays["status"] = np.array([STATUS_CONVERGED] * (n - 1) + [STATUS_OUTSIDE_ENVELOPE], np.int8)
    arrays["reason"] = np.array([""] * (n - 1) + ["outside"], dtype=object)
    return arrays


@pytest.mark.parametrize("name", list(TOPOLOGIES))
def test_a_result_lists_every_variable_in_order_with_its_branches(name):
    circuit = TOPOLOGIES[name]
    arrays = working_arrays()
    r = CycleResult.from_arrays(arrays, circuit)
    assert list(r) == list(RESULT_KEYS) and list(r.keys()) == list(RESULT_KEYS) and len(r) == len(RESULT_KEYS)
    assert list(r.branches) == [b.component for b in circuit.branches]
    assert all(isinstance(b, BranchResult) for b in r.branches.values())
    # The circuit's own variables are the solver's arrays themselves, not copies; a branch the
    # circuit lacks has no flow and no heat at solved points, and no valve or superheat.
    own = {k for c in r.branches for k in BRANCH_KEYS[c]}
    for k in RESULT_KEYS:
        if k in own or not any(k in keys for keys in BRANCH_KEYS.values()):
            assert r[k] is arrays[k], k
        elif k in ("valve_opening_chiller", "superheat_chiller"):
            assert np.isnan(r[k]).all(), k
        else:
            np.testing.assert_array_equal(r[k], [0.0, 0.0, np.nan])
    if "chiller" in r.branches:
        assert (
            r.branches["chiller"].Q is r["Q_chiller"]
            and r.branches["chiller"].valve_opening is r["valve_opening_chiller"]
        )
    if "evaporator" in r.branches:
        evaporator = r.branches["evaporator"]
        assert evaporator.valve_opening is r["valve_opening"] and evaporator.superheat is r["superheat_actual"]
        assert evaporator.Q_latent is r["Q_latent"] and evaporator.frost_risk is r["frost_risk"]


def test_a_result_is_a_read_only_mapping_with_its_balance_last():
    r = CycleResult.from_arrays(working_arrays(), TOPOLOGIES["cabin"])
    assert "p_A" in r and "balance_residual" not in r and r.get("balance_residual") is None
    with pytest.raises(KeyError):
        r["nothing"]
    with pytest.raises(TypeError):
        r["p_A"] = np.zeros(3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.p_A = np.zeros(3)
    d = r.to_dict()
    assert type(d) is dict and list(d) == list(RESULT_KEYS) and d["p_A"] is r["p_A"]
    b = r.with_balance(np.ones(3), np.full(3, 0.5))
    assert list(b)[-2:] == ["balance_residual", "balance_relative"] and list(b)[:-2] == list(RESULT_KEYS)
    assert b.balance_relative is b["balance_relative"] and b["p_A"] is r["p_A"]
    assert {**b}.keys() == dict(b.items()).keys()
    again = pickle.loads(pickle.dumps(b))  # a worker process hands its result back pickled
    assert list(again) == list(b) and np.array_equal(again["p_A"], b["p_A"], equal_nan=True)
    assert "3 points" in repr(r)
