"""Tabulated refrigerant properties (evtms.fluid_tables) against CoolProp HEOS on random states,
within the tolerances the module states, and its (p, h) inversion against its own (p, T) enthalpy."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.fluid import Fluid
from evtms.fluid_tables import SAT_COLUMNS, TabulatedFluid

N = 2000


@pytest.fixture(scope="module")
def fluids() -> tuple[Fluid, TabulatedFluid]:
    fluid = Fluid()
    return fluid, TabulatedFluid(fluid)


def _pressures(rng: np.random.Generator) -> np.ndarray:
    return np.exp(rng.uniform(np.log(0.5e5), np.log(30e5), N))


def test_saturation_within_stated_tolerance(fluids):
    fluid, tab = fluids
    p = _pressures(np.random.default_rng(0))
    ref, got = fluid.saturation(p), tab.saturation(p)
    assert np.abs(got["T"] - ref["T"]).max() < 1e-4
    assert np.abs(got["h_l"] - ref["h_l"]).max() < 0.2
    assert np.abs(got["h_v"] - ref["h_v"]).max() < 0.2
    for key in SAT_COLUMNS[3:]:
        assert np.abs(got[key] / ref[key] - 1.0).max() < 1e-4, key


@pytest.mark.parametrize("phase", ["vapour", "liquid"])
def test_single_phase_within_stated_tolerance(fluids, phase):
    fluid, tab = fluids
    rng = np.random.default_rng(1)
    p = _pressures(rng)
    T_sat = fluid.saturation(p)["T"]
    if phase == "vapour":
        T = rng.uniform(T_sat + 1e-3, np.minimum(400.0, T_sat + 150.0))
    else:
        T = rng.uniform(np.maximum(220.0, T_sat - 100.0), T_sat - 1e-3)
    keys = ("H", "D", "CP", "MU", "K", "S")
    ref, got = fluid.state("PT", p, T, keys), tab.state("PT", p, T, keys)
    assert np.abs(got["H"] - ref["H"]).max() < 0.2
    assert np.abs(got["S"] - ref["S"]).max() < 1e-3
    for key in keys[1:-1]:
        assert np.abs(got[key] / ref[key] - 1.0).max() < 1e-4, key
    # (p, h) -> T: CoolProp's enthalpy back to its temperature within 1e-3 K, and the
    # tables' own enthalpy back to the temperature it came from to round-off.
    assert np.abs(tab.state("PH", p, ref["H"], ("T",))["T"] - T).max() < 1e-3
    assert np.abs(tab.state("PH", p, got["H"], ("T",))["T"] - T).max() < 1e-9
    # (p, s) -> h: CoolProp's entropy to its enthalpy within 0.2 J/kg, the tables' own to round-off.
    assert np.abs(tab.state("PS", p, ref["S"], ("H",))["H"] - ref["H"]).max() < 0.2
    assert np.abs(tab.state("PS", p, got["S"], ("H",))["H"] - got["H"]).max() < 1e-6


def test_two_phase_enthalpy_gives_saturation_temperature(fluids):
    _, tab = fluids
    p = np.array([1e5, 1e6])
    sat = tab.saturation(p)
    h = 0.5 * (sat["h_l"] + sat["h_v"])
    assert tab.state("PH", p, h, ("T",))["T"] == pytest.approx(sat["T"], abs=0.0)


def test_two_phase_entropy_gives_the_mixture_enthalpy(fluids):
    fluid, tab = fluids
    p = np.array([1e5, 1e6, 2.5e6])
    sat = fluid.saturation(p)
    x = np.array([0.1, 0.5, 0.9])
    got = tab.state("PS", p, sat["s_l"] + x * (sat["s_v"] - sat["s_l"]), ("H",))["H"]
    np.testing.assert_allclose(got, sat["h_l"] + x * (sat["h_v"] - sat["h_l"]), atol=0.2)


def test_outside_the_tables_is_nan(fluids):
    _, tab = fluids
    got = tab.state("PT", np.array([1e3, 1e5, 1e5, 4e6]), np.array([300.0, 150.0, 500.0, 400.0]), ("H",))["H"]
    assert np.isnan(got).all()
    assert np.isnan(tab.state("PH", np.array([1e5]), np.array([1e7]), ("T",))["T"]).all()
    # Entropy beyond the vapour table's top (450 K) and a pressure below it.
    assert np.isnan(tab.state("PS", np.array([1e5, 1e3]), np.array([1e4, 1.7e3]), ("H",))["H"]).all()
