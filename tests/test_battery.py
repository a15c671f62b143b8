"""Battery pack equivalent circuit: power and energy closure, the voltage cap, sign conventions."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.system.battery import Battery, BatteryParams


@pytest.fixture(scope="module")
def pack():
    return Battery()


def test_current_delivers_the_power_and_energy_closes(pack):
    soc = np.linspace(0.1, 0.95, 12)
    T = np.linspace(253.15, 318.15, 12)
    P = np.linspace(-60e3, 80e3, 12)  # charging (regen) to hard discharge
    s = pack.respond(P, soc, T)
    assert not s.limited.any()
    assert np.allclose(s.voltage * s.current, P, rtol=1e-12, atol=1e-6)
    # E i = v i + heat: the source's power splits into terminal power and Joule heat.
    assert np.allclose(s.emf * s.current, s.voltage * s.current + s.heat, rtol=1e-12, atol=1e-6)
    assert (np.sign(s.current) == np.sign(P)).all() and (s.heat >= 0).all()


def test_pack_figures_from_the_cell_tables(pack):
    p = BatteryParams()
    assert p.capacity_As == pytest.approx(144 * 3600)
    # 96 cells of 4.05 V at SOC 0.9; pack R 0.0388 ohm at 23 degC and SOC 0.9 (spec section 10).
    assert float(pack.emf(0.9)) == pytest.approx(96 * 4.0538, rel=1e-3)
    assert float(pack.resistance(0.9, 296.15)) == pytest.approx(0.0388, rel=2e-3)


def test_the_terminal_voltage_caps_the_power(pack):
    cap = float(pack.power_cap(0.3, 263.15))
    s = pack.respond(np.array([0.5 * cap, 2.0 * cap]), 0.3, 263.15)
    assert s.limited.tolist() == [False, True]
    assert s.power[1] == pytest.approx(cap)
    assert s.voltage[1] == pytest.approx(96 * 2.25, rel=1e-9)  # the cell minimum binds
    assert s.voltage[0] > 96 * 2.25


def test_a_cold_pack_heats_more_for_the_same_power(pack):
    cold = pack.respond(30e3, 0.5, 253.15)
    warm = pack.respond(30e3, 0.5, 298.15)
    assert cold.resistance > warm.resistance and cold.heat > warm.heat
