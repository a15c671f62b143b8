"""Thermal network stepped by backward Euler: exact ledgers, analytic limits, stability."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.system.network import ThermalNetwork


def battery_coolant_cabin():
    # Battery, coolant and cabin air with the spec's orders of magnitude (J/K, W/K).
    return ThermalNetwork(
        ("battery", "coolant", "cabin"),
        np.array([163.4e3, 16.5e3, 50e3]),
        links={("battery", "coolant"): 68.0},
        boundary={"battery": 68.3, "cabin": 64.0},
    )


@pytest.mark.parametrize("dt", [0.1, 1.0, 10.0])
def test_each_step_closes_every_node_ledger_exactly(dt):
    net = battery_coolant_cabin()
    T = np.array([308.15, 300.15, 313.15])
    Q = np.array([2000.0, -3000.0, -1500.0])  # heat generation, chiller, evaporator
    for _ in range(50):
        T_new = net.step(T, Q, 303.15, dt)
        flows = net.flows_in(T_new, 303.15)  # backward Euler: flows at the new temperatures
        assert np.allclose(net.capacity * (T_new - T), dt * (Q + flows), rtol=0, atol=1e-6 * dt)
        T = T_new


def test_one_node_decays_as_backward_euler_and_tends_to_the_exact_solution():
    C, G, T0, Tb = 1e5, 50.0, 320.0, 300.0
    net = ThermalNetwork(("n",), np.array([C]), boundary={"n": G})
    tau = C / G
    for dt, steps in ((1.0, 2000), (0.1, 20000)):
        T = np.array([T0])
        for _ in range(steps):
            T = net.step(T, np.zeros(1), Tb, dt)
        implicit = Tb + (T0 - Tb) * (1 + dt / tau) ** -steps
        exact = Tb + (T0 - Tb) * np.exp(-steps * dt / tau)
        assert T[0] == pytest.approx(implicit, rel=1e-12)
        assert T[0] == pytest.approx(exact, abs=0.05 * dt)  # first order in dt


def test_steady_state_is_the_conduction_balance_at_any_step():
    net = battery_coolant_cabin()
    T = np.full(3, 303.15)
    for _ in range(400):
        T = net.step(T, np.array([500.0, 0.0, 0.0]), 303.15, 100.0)
    # Heat generated in the battery leaves through its boundary (the coolant has no other way out).
    assert net.flows_in(T, 303.15)[0] == pytest.approx(-500.0, rel=1e-6)
    assert T[1] == pytest.approx(T[0], abs=1e-6) and T[2] == pytest.approx(303.15)


def test_bad_networks_are_refused():
    with pytest.raises(ValueError):
        ThermalNetwork(("a",), np.array([0.0]))
    with pytest.raises(ValueError):
        ThermalNetwork(("a", "b"), np.ones(2), links={("a", "b"): -1.0})
