"""The compiled coil march (evtms.hx._coil_kernels through evtms.benches.coil.solve_coil) against
the NumPy march: to round-off on the same tabulated properties, within the tables' tolerance on
CoolProp's; states beyond the tables fall back to CoolProp; a point's value does not depend on its batch."""

from __future__ import annotations

import numpy as np
import pytest

from evtms._jit import numba_enabled
from evtms.benches.coil import solve_coil
from evtms.benches.parameters import Parameters
from evtms.fluid import Fluid
from evtms.fluid_tables import TabulatedFluid

pytestmark = pytest.mark.skipif(not numba_enabled(), reason="the compiled march needs numba")

N = 240
FLOAT_KEYS = ("Q", "Q_latent", "h_out", "h_out_continued", "p_out", "dp", "T_out", "x_out", "T_air_out")
MORE_KEYS = ("capacity_ratio", "T_surface_min", "T_surface_eff", "m_condensate", "H_condensate", "w_air_out")
MASKS = ("bad_direction", "bad_dp", "bad_props", "air_outside_range")


@pytest.fixture(scope="module")
def fluids() -> tuple[Fluid, TabulatedFluid]:
    fluid = Fluid()
    return fluid, TabulatedFluid(fluid)


def _points(mode: str, fluid: Fluid, seed: int = 0) -> dict:
    """Random points over the cycle envelope, with a few distinct entering-air states (each costs
    a cached moist-air line)."""
    rng = np.random.default_rng(seed)
    if mode == "condenser":
        T_sat, h_in = rng.uniform(275.0, 360.0, N), rng.uniform(380e3, 520e3, N)
        mdot = np.exp(rng.uniform(np.log(0.002), np.log(0.15), N))
    else:
        T_sat, h_in = rng.uniform(238.0, 314.0, N), rng.uniform(185e3, 420e3, N)
        mdot = np.exp(rng.uniform(np.log(0.0014), np.log(0.15), N))
    return {
        "p_in": fluid.saturation_pressure(T_sat),
        "h_in": h_in,
        "mdot": mdot,
        "air_fraction": np.exp(rng.uniform(np.log(0.1), 0.0, N)),
        "T_air": rng.choice([268.15, 288.15, 298.15, 308.15, 318.15], N),
        "RH_air": rng.choice([0.3, 0.55, 0.8], N),
    }


def _solve(fluid, mode: str, pts: dict, compiled: bool) -> dict:
    params = Parameters()
    return solve_coil(
        fluid,
        getattr(params, mode),
        params.environment,
        pts["p_in"],
        pts["h_in"],
        pts["mdot"],
        pts["air_fraction"],
        mode,
        T_air=pts["T_air"],
        RH_air=pts["RH_air"],
        compiled=compiled,
    )


def _close(a: np.ndarray, b: np.ndarray, rtol: float, atol: float) -> None:
    np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b))
    ok = np.isfinite(a)
    np.testing.assert_allclose(a[ok], b[ok], rtol=rtol, atol=atol)


@pytest.mark.parametrize("mode", ["condenser", "evaporator"])
def test_compiled_march_is_the_numpy_march_on_the_same_tables(fluids, mode):
    fluid, tabulated = fluids
    pts = _points(mode, fluid)
    got, ref = _solve(fluid, mode, pts, True), _solve(tabulated, mode, pts, False)
    for key in FLOAT_KEYS + MORE_KEYS:
        _close(got[key], ref[key], rtol=1e-9, atol=1e-12)
    for key in MASKS:
        np.testing.assert_array_equal(got[key], ref[key])
    # The points move heat (and the evaporator's condense water): the comparison is not of zeros.
    assert (got["Q"] != 0).mean() > 0.6
    if mode == "evaporator":
        assert (got["m_condensate"] > 0).mean() > 0.2


@pytest.mark.parametrize("mode", ["condenser", "evaporator"])
def test_compiled_march_within_table_tolerance_of_coolprop(fluids, mode):
    fluid, _ = fluids
    pts = _points(mode, fluid, seed=1)
    got, ref = _solve(fluid, mode, pts, True), _solve(fluid, mode, pts, False)
    for key in MASKS:
        np.testing.assert_array_equal(got[key], ref[key])
    _close(got["Q"], ref["Q"], rtol=1e-4, atol=1e-3)
    _close(got["h_out"], ref["h_out"], rtol=0.0, atol=2.0)  # J/kg
    _close(got["T_out"], ref["T_out"], rtol=0.0, atol=2e-3)  # K
    _close(got["dp"], ref["dp"], rtol=1e-3, atol=1e-3)
    _close(got["capacity_ratio"], ref["capacity_ratio"], rtol=1e-3, atol=0.0)


@pytest.mark.parametrize("mode", ["condenser", "evaporator"])
def test_states_beyond_the_tables_take_coolprop(fluids, mode):
    fluid, _ = fluids
    pts = {k: v[:3].copy() for k, v in _points(mode, fluid, seed=2).items()}
    pts["p_in"][1] = 0.95 * fluid.p_crit  # above the tables' 0.9 p_crit
    pts["h_in"][1] = 460e3
    got, ref = _solve(fluid, mode, pts, True), _solve(fluid, mode, pts, False)
    for key in FLOAT_KEYS:
        assert got[key][1] == ref[key][1] or (np.isnan(got[key][1]) and np.isnan(ref[key][1])), key


@pytest.mark.parametrize("mode", ["condenser", "evaporator"])
def test_a_point_is_the_same_alone_and_in_a_batch(fluids, mode):
    fluid, _ = fluids
    pts = _points(mode, fluid, seed=3)
    batch = _solve(fluid, mode, pts, True)
    for i in (0, 17, N - 1):
        alone = _solve(fluid, mode, {k: v[i : i + 1] for k, v in pts.items()}, True)
        for key in FLOAT_KEYS + MORE_KEYS:
            assert alone[key][0] == batch[key][i] or (np.isnan(alone[key][0]) and np.isnan(batch[key][i])), key


@pytest.mark.parametrize("share", [0.0278156, 0.143346, 0.205142, 0.449325, 0.7])
def test_the_zone_search_closes_where_its_first_secant_hits_the_root(monkeypatch, share):
    """A dry two-phase zone's heat rate is linear in its coil fraction, so the search's first
    secant lands on the root: a step just inside that end closes the bracket, and the bisection's
    replay gives the 40-step bisection's fraction from a handful of heat rates (the midpoint
    there bisected the whole bracket: some 40)."""
    from evtms.hx import _coil_kernels as kernels

    dry = np.array([np.inf, 0.002, 400.0, 20.0])  # C_ref [W/K] (boiling), R_tot [K/W], C_air [W/K], dT [K]
    wet, moist = np.full(5, np.nan), np.full(6, np.nan)  # dry air: no wet model, no moisture
    sat = (np.array([250.0, 300.0]), np.array([1e4, 1e5]), np.array([1e-3, 2e-2]))  # unused here
    rate = kernels.zone_rate
    rate_hi = rate(1.0, dry, wet, moist, *sat)
    target = share * rate_hi
    bisected = kernels._bisect_plain(target, 1.0, dry, wet, moist, *sat)  # compiled before the patch below
    calls = []

    def counted(f, *args):
        calls.append(f)
        return rate(f, *args)

    monkeypatch.setattr(kernels, "zone_rate", counted)
    search = getattr(kernels._bisect, "py_func", kernels._bisect)  # Python, so that it calls the counter
    fraction = search(target, 1.0, rate_hi, dry, wet, moist, *sat)
    assert fraction == bisected
    assert abs(fraction - share) < 1e-9
    assert len(calls) <= 6
