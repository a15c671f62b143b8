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


def test_the_approach_interpolates_a_superheated_chiller_outlet_better(cycle_luts_dir):
    """Off-node outlets 3-12 K superheated (the valve-controlled states): the LUT cycle's chiller
    outlet within a fifth of the error of the enthalpy interpolated itself (measured 152 against
    785 J/kg rms, 513 against 2,414 J/kg worst, on 91 of 400 random states)."""
    from evtms.benches.parameters import Parameters
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.models import DirectModels, LutModels

    luts = load_cycle_luts(cycle_luts_dir, "chiller")
    components = ("compressor", "condenser", "chiller")
    approach, plain = LutModels(luts, components, False), LutModels(luts, components, False, approach=False)
    fluid = Fluid()
    rng = np.random.default_rng(7)
    n = 400
    T_sat = rng.uniform(273.15, 288.15, n)
    inputs = (
        np.exp(rng.uniform(np.log(2e-3), np.log(20e-3), n)),  # mdot [kg/s]
        fluid.saturation_pressure(T_sat),
        rng.uniform(220e3, 280e3, n),  # h_in [J/kg]
        rng.uniform(0.12, 0.45, n),  # mdot_coolant [kg/s]
        T_sat + rng.uniform(6.0, 20.0, n),  # T_coolant_in [K]
    )
    direct = DirectModels(Parameters()).chiller(*inputs)
    T_out = fluid.state("PH", direct["p_out"], direct["h_out_continued"], ("T",))["T"]
    superheat = T_out - fluid.saturation(direct["p_out"])["T"]
    tail = (superheat > 3.0) & (superheat < 12.0)
    assert tail.sum() >= 50
    err = {
        name: np.abs(model.chiller(*inputs)["h_out_continued"] - direct["h_out_continued"])[tail]
        for name, model in (("approach", approach), ("plain", plain))
    }
    assert np.isfinite(err["approach"]).all() and np.isfinite(err["plain"]).all()
    assert np.sqrt(np.mean(err["approach"] ** 2)) < 0.4 * np.sqrt(np.mean(err["plain"] ** 2))
    assert err["approach"].max() < 0.4 * err["plain"].max()


def test_compiled_inverse_gives_the_numpy_numbers(vapour):
    """The cycle's compiled loop against the array path, inside, at the edges of and outside the table."""
    rng = np.random.default_rng(2)
    n = 2000
    p = np.exp(rng.uniform(np.log(1e4), np.log(4.2e6), n))  # beyond the table at both ends
    p[:3] = (vapour.p[0], vapour.p[-1], np.nan)
    T_sat, _ = vapour.saturation(np.clip(p, vapour.p[0], vapour.p[-1]))
    T_sec = T_sat + rng.uniform(-10.0, 130.0, n)  # colder than saturation up to beyond the table's superheats
    T_sec[3] = np.nan
    log_psi = rng.uniform(-12.0, 3.0, n)
    log_psi[4] = np.nan
    numpy_path = outlet_enthalpy(log_psi, p, T_sec, vapour)
    compiled = outlet_enthalpy(log_psi, p, T_sec, vapour, compiled=True)
    assert np.array_equal(np.isnan(numpy_path), np.isnan(compiled)) and np.isnan(numpy_path[2:5]).all()
    ok = ~np.isnan(numpy_path)
    assert ok.sum() > 1500
    assert np.allclose(compiled[ok], numpy_path[ok], rtol=1e-12, atol=1e-6)
    # Broadcast arguments (a scalar secondary temperature) take the same path.
    one = outlet_enthalpy(log_psi[5:9], p[5:9], 300.0, vapour, compiled=True)
    reference = outlet_enthalpy(log_psi[5:9], p[5:9], np.full(4, 300.0), vapour)
    assert np.allclose(one, reference, rtol=1e-12, equal_nan=True)


def test_round_trip_where_the_secondary_is_beyond_the_table_s_superheats(vapour):
    """A cold evaporation against a hot secondary (-35 degC against 50 degC at 22 kPa: over 100 K apart)
    still inverts exactly: the table's enthalpies continue linearly past its last superheat."""
    p = np.full(4, 2.2e4)
    T_sat, h_v = vapour.saturation(p)
    T_sec = T_sat + np.array([99.0, 105.0, 120.0, 140.0])
    span = vapour.enthalpy_above_saturation(p, T_sec - T_sat)
    assert np.all(np.diff(span) > 0)
    h = h_v + 0.97 * span  # outlets 3 % of the span short of the secondary temperature
    y = approach_log(h, p, T_sec, vapour)
    assert np.allclose(y, np.log(0.03), atol=1e-9)
    for compiled in (False, True):
        assert np.allclose(outlet_enthalpy(y, p, T_sec, vapour, compiled), h, rtol=0, atol=1e-6)
    # Scalars come back as scalars on both paths.
    assert np.shape(outlet_enthalpy(-1.0, 3e5, 300.0, vapour, compiled=True)) == ()
