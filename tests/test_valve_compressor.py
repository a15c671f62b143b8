"""Expansion-valve and compressor benches: conservation, status codes, trends, nominal point."""

from __future__ import annotations

import numpy as np
import pytest
from CoolProp.CoolProp import PropsSI

from evtms.benches import BENCHES
from evtms.benches.compressor import STATUS_LIQUID_SUCTION, clearance_volumetric_efficiency
from evtms.benches.expansion_valve import STATUS_CHOKED, STATUS_DP_EXCEEDS_INLET, ExpansionValveParams, nominal_opening
from evtms.benches.grid import build_grid
from evtms.benches.sweep import run_sweep

# --- expansion valve -------------------------------------------------------


@pytest.fixture(scope="module")
def valve(thesis):
    return thesis("expansion_valve")


def test_valve_is_isenthalpic_and_valid_points_finite(valve):
    ok = valve["status"].values == 0
    assert ok.sum() == 18
    np.testing.assert_array_equal(valve["h_out"].values[ok], valve["h_in"].values[ok])
    for name in ("dp", "h_in", "h_out", "T_out", "p_out", "x_out"):
        assert np.isfinite(valve[name].values[ok]).all()
        assert np.isnan(valve[name].values[~ok]).all()


def test_vapour_inlets_are_choked_with_their_own_code(valve, fluid):
    T_sat = fluid.saturation(valve["p_in"].values)["T"]
    vapour = valve["T_in"].values[:, None] > T_sat[None, :]
    status = valve["status"].values
    assert (status[vapour] == STATUS_CHOKED).all()
    assert (status[~vapour] == 0).all()
    assert "mass_flow_above_choked_limit" in valve["status"].attrs["flag_meanings"]


def test_valve_dp_goes_with_mdot_squared_over_density(valve, fluid):
    liq = valve.isel(T_in=0)  # 300 K: liquid at every thesis pressure
    dp = liq["dp"].values
    m = liq["mdot"].values
    np.testing.assert_allclose(dp / dp[:, :1], np.broadcast_to((m / m[0]) ** 2, dp.shape), rtol=1e-12)
    rho = fluid.state("PT", liq["p_in"].values, 300.0, ("D",))["D"]
    area = nominal_opening(ExpansionValveParams(), fluid)
    np.testing.assert_allclose(dp, (m[None, :] / area) ** 2 / (2 * rho[:, None]), rtol=1e-12)
    # Physics, not the thesis report: warmer liquid is lighter, so dp rises with T_in.
    both = valve["status"].values[:2] == 0
    d = valve["dp"].values
    assert (d[1][both[1]] > d[0][both[1]]).all()


def test_valve_two_phase_inlet_by_enthalpy(fluid, params):
    bench = BENCHES["expansion_valve"]
    sat = fluid.saturation(1.0e6)
    h = float(sat["h_l"] + 0.05 * (sat["h_v"] - sat["h_l"]))
    ds = run_sweep(
        bench, {"h_in": np.array([h]), "p_in": np.array([1.0e6]), "mdot": np.array([0.002, 0.004])}, params, fluid=fluid
    )
    assert (ds["status"].values == 0).all()
    assert (ds["x_out"].values > 0.05).all() and (ds["x_out"].values < 1).all()


def test_valve_drop_beyond_inlet_pressure_is_invalid(fluid, params):
    bench = BENCHES["expansion_valve"]
    grid = {"T_in": np.array([300.0]), "p_in": np.array([0.9e6]), "mdot": np.array([0.008, 0.05])}
    ds = run_sweep(bench, grid, params, fluid=fluid)
    assert list(ds["status"].values.ravel()) == [0, STATUS_DP_EXCEEDS_INLET]
    assert np.isnan(ds["dp"].values.ravel()[1])


# --- compressor ------------------------------------------------------------


@pytest.fixture(scope="module")
def comp(thesis):
    return thesis("compressor")


def test_compressor_energy_balance(comp, params):
    assert (comp["status"].values == 0).all()
    lhs = comp["W"].values * params.compressor.eta_mechanical
    rhs = comp["mdot"].values * (comp["h_out"].values - comp["h_in"].values)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-13)


def test_compressor_nominal_point_matches_hand_calculation(fluid, params):
    # Nominal point: 0.3 MPa, 11 degC suction, pressure ratio 4.6, full speed (3600 rpm).
    bench = BENCHES["compressor"]
    grid = {"speed": np.array([1.0]), "T_in": np.array([284.15]), "pr": np.array([4.6]), "p_in": np.array([0.3e6])}
    ds = run_sweep(bench, grid, params, fluid=fluid)
    rho = PropsSI("D", "P", 0.3e6, "T", 284.15, "R134a")  # 14.03 kg/m3
    h1 = PropsSI("H", "P", 0.3e6, "T", 284.15, "R134a")
    s1 = PropsSI("S", "P", 0.3e6, "T", 284.15, "R134a")
    h2s = PropsSI("H", "P", 1.38e6, "S", s1, "R134a")
    mdot = 0.9 * rho * 80e-6 * 3600 / 60  # eta_v is 0.9 at the nominal ratio by construction
    W = mdot * (h2s - h1) / 0.65 / 0.95
    assert float(ds["eta_vol"].squeeze()) == pytest.approx(0.9, rel=1e-12)
    # The bench runs on the tabulated properties (evtms.fluid_tables) where numba is: within 1e-5.
    assert float(ds["mdot"].squeeze()) == pytest.approx(mdot, rel=1e-5)
    assert float(ds["W"].squeeze()) == pytest.approx(W, rel=1e-5)
    # The numbers: 0.0606 kg/s and 3.30 kW.
    assert mdot == pytest.approx(0.0606, abs=1e-4) and W == pytest.approx(3298, abs=2)
    assert "p_in" not in ds.data_vars  # given as an axis


def test_liquid_suction_is_nan_with_its_code(fluid, params):
    bench = BENCHES["compressor"]
    grid = {
        "speed": np.array([0.5]),
        "T_in": np.array([250.0, 265.0, 280.0]),
        "pr": np.array([4.0]),
        "p_in": np.array([0.3e6]),
    }
    ds = run_sweep(bench, grid, params, fluid=fluid)
    status = ds["status"].values.ravel()
    assert list(status) == [STATUS_LIQUID_SUCTION, STATUS_LIQUID_SUCTION, 0]
    for name in ("W", "mdot", "h_out", "T_out"):
        assert np.isnan(ds[name].values.ravel()[:2]).all() and np.isfinite(ds[name].values.ravel()[2])


def test_compressor_trends(comp):
    W = comp["W"].values  # (speed, T_in, pr)
    speed = comp["speed"].values
    per_speed = W / speed[:, None, None]
    np.testing.assert_allclose(per_speed, np.broadcast_to(per_speed[:1], W.shape), rtol=1e-12)  # linear in speed
    assert (np.diff(W, axis=2) > 0).all()  # grows with pressure ratio
    assert (np.diff(W, axis=1) > 0).all()  # grows with suction temperature (and suction pressure)
    T_out = comp["T_out"].values
    assert (T_out > comp["T_in"].values[None, :, None]).all()


def test_volumetric_efficiency_model(params):
    eta = clearance_volumetric_efficiency(np.array([1.0, 4.6, 8.0, 60.0]), params.compressor)
    assert eta[0] == pytest.approx(1.0) and eta[1] == pytest.approx(0.9)
    assert eta[2] < eta[1] and eta[3] < 0


def test_thesis_grid_sizes():
    sizes = {}
    for name, bench in BENCHES.items():
        grid = build_grid(bench, "thesis", {})
        sizes[name] = int(np.prod([len(v) for v in grid.values()]))
    assert sizes == {
        "condenser": 768,
        "evaporator": 768,
        "expansion_valve": 36,
        "compressor": 36,
        "chiller": 288,
        "radiator": 192,
        "heater_core": 144,
        "wcc": 768,
    }
    assert sum(sizes.values()) == 3000
