"""The evaporating branches' outlet interpolated as the log of its approach to the secondary inlet."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.cycle.approach import SUPERHEAT_MIN, approach_log, outlet_enthalpy
from evtms.fluid import Fluid, VapourTable


@pytest.fixture(scope="module")
def vapour():
    return VapourTable(Fluid())


def test_round_trip_from_two_phase_to_the_secondary_temperature(vapour):
    fluid = Fluid()
    p = np.full(6, 3.0e5)
    T_sat, h_v = vapour.saturation(p)
    T_sec = T_sat + 12.0
    h_max = h_v + vapour.enthalpy_above_saturation(p, 12.0)
    # Continued two-phase side, saturated vapour, 5 K superheat, 1, 1e-3 and 1e-4 J/kg short of h(p, T_sec).
    h_5K = fluid.state("PT", 3.0e5, T_sat[0] + 5.0, ("H",))["H"]
    h = np.array([h_v[0] - 80e3, h_v[0], h_5K, h_max[0] - 1.0, h_max[0] - 1e-3, h_max[0] - 1e-4])
    y = approach_log(h, p, T_sec, vapour)
    assert y[1] == pytest.approx(0.0, abs=1e-12)  # saturated vapour: psi = 1
    assert y[0] > 0 and np.all(np.diff(y) < 0)  # falls as the outlet nears the secondary temperature
    assert np.allclose(outlet_enthalpy(y, p, T_sec, vapour), h, rtol=0, atol=1e-6)
    # A 5 K superheat against a 12 K approach: psi is about (12 - 5) / 12.
    assert np.exp(y[2]) == pytest.approx(7.0 / 12.0, rel=0.03)


def test_a_secondary_colder_than_saturation_stays_finite_and_invertible(vapour):
    p = np.full(3, 3.0e5)
    T_sat, h_v = vapour.saturation(p)
    T_sec = T_sat + np.array([-5.0, 0.0, SUPERHEAT_MIN / 2])
    h = h_v - np.array([20e3, 5e3, 1e3])
    y = approach_log(h, p, T_sec, vapour)
    assert np.isfinite(y).all()
    assert np.allclose(outlet_enthalpy(y, p, T_sec, vapour), h, rtol=0, atol=1e-6)


def test_nan_outlets_stay_nan(vapour):
    y = approach_log(np.array([np.nan, 4e5]), np.array([3e5, np.nan]), np.array([290.0, 290.0]), vapour)
    assert np.isnan(y).all()
