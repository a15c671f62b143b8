"""The compiled compressor (evtms.benches._compressor_kernel) against the bench's NumPy path: on the
same property tables to round-off, on CoolProp within the tables' tolerance, with equal statuses."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.benches.compressor import (
    STATUS_LIQUID_SUCTION,
    STATUS_NO_VOLUMETRIC_FLOW,
    _compress_compiled,
    compressor_power,
)
from evtms.fluid_tables import TabulatedFluid


@pytest.fixture(scope="module")
def grid() -> dict[str, np.ndarray]:
    """Suction from wet (240 K at 10 bar) to 100 K of superheat, pressure ratios from 1.02 to 60
    (beyond the volumetric limit, about 52) and discharges beyond the tables (above 450 K or 36.5 bar)."""
    axes = np.meshgrid(
        [0.3, 1.0],
        np.linspace(240.0, 340.0, 11),
        [1.02, 2.0, 4.6, 8.0, 12.0, 60.0],
        [0.5e5, 1e5, 3e5, 6e5, 1e6],
        indexing="ij",
    )
    return {k: a.ravel() for k, a in zip(("speed", "T_in", "pr", "p_in"), axes, strict=True)}


@pytest.fixture(scope="module")
def compiled(grid, params, fluid):
    return compressor_power(grid, params, fluid, compiled=True)


def test_grid_holds_every_status(compiled):
    codes = set(np.unique(compiled["status"]))
    assert {0, STATUS_LIQUID_SUCTION, STATUS_NO_VOLUMETRIC_FLOW} <= codes


def test_kernel_equals_numpy_path_on_the_same_tables(grid, params, fluid):
    comp = params.compressor
    args = [grid[k] for k in ("speed", "pr", "p_in", "T_in")]
    out, fallback = _compress_compiled(comp, *args, False, fluid)
    ref = compressor_power(grid, params, TabulatedFluid(fluid), compiled=False)
    assert fallback.any() and not fallback.all()
    inside = ~fallback  # the rest the tables cannot answer (NaN there, CoolProp's in the bench)
    np.testing.assert_array_equal(out["status"][inside], ref["status"][inside])
    for key in ("W", "mdot", "h_in", "h_out", "T_out", "p_out", "eta_vol"):
        np.testing.assert_allclose(out[key][inside], ref[key][inside], rtol=1e-9, atol=0.0, err_msg=key)


def test_by_enthalpy_equals_numpy_path_on_the_same_tables(params, fluid):
    tab = TabulatedFluid(fluid)
    p = np.full(5, 3e5)
    sat = tab.saturation(p)
    # Wet (quality 0.5 and saturated vapour) and superheated suction enthalpies.
    h = sat["h_l"] + np.array([0.5, 1.0, 1.01, 1.05, 1.2]) * (sat["h_v"] - sat["h_l"])
    inputs = {"speed": np.full(5, 0.5), "h_in": h, "pr": np.full(5, 4.0), "p_in": p}
    got = compressor_power(inputs, params, fluid, compiled=True)
    ref = compressor_power(inputs, params, tab, compiled=False)
    assert list(got["status"]) == [STATUS_LIQUID_SUCTION] * 2 + [0] * 3
    np.testing.assert_array_equal(got["status"], ref["status"])
    for key in ("W", "mdot", "h_out", "T_out"):
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-9, atol=0.0, err_msg=key)


def test_kernel_within_table_tolerance_of_coolprop(grid, compiled, params, fluid):
    ref = compressor_power(grid, params, fluid, compiled=False)
    np.testing.assert_array_equal(compiled["status"], ref["status"])
    for key in ("W", "mdot", "h_in", "h_out", "p_out", "eta_vol"):
        np.testing.assert_allclose(compiled[key], ref[key], rtol=1e-5, atol=0.0, err_msg=key)
    np.testing.assert_allclose(compiled["T_out"], ref["T_out"], rtol=0.0, atol=1e-3)
    # Points beyond the tables are CoolProp's own.
    _, fallback = _compress_compiled(
        params.compressor, *(grid[k] for k in ("speed", "pr", "p_in", "T_in")), False, fluid
    )
    for key in ("W", "h_out", "T_out"):
        np.testing.assert_array_equal(compiled[key][fallback], ref[key][fallback])
