"""The condenser's capacity ratio at two-phase inlets, scaled by what drives it (evtms.cycle.dome)."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.benches.parameters import Parameters
from evtms.cycle.dome import X_SCALED, capacity_scale, dome_capacity_ratio, scaled_weight
from evtms.cycle.models import DirectModels
from evtms.fluid import Fluid, SaturationCurve


@pytest.fixture(scope="module")
def fluid():
    return Fluid("R134a")


@pytest.fixture(scope="module")
def sat(fluid):
    return SaturationCurve(fluid)


def test_the_scaled_ratio_hardly_moves_where_the_ratio_changes_several_fold(fluid, sat):
    """Two-phase inlets from quality 0.05 to 0.75, the saturation 2-8 K above the air: the bench's
    capacity ratio spans more than 50x, the scaled one stays within 1 % (what its interpolation needs)."""
    models = DirectModels(Parameters(), fluid)
    T_air = 297.65
    T_sat = T_air + np.array([2.0, 4.0, 8.0])[:, None]
    x = np.array([0.05, 0.2, 0.4, 0.75])
    p = np.broadcast_to(sat.pressure(T_sat), (3, 4)).ravel()
    h = sat.liquid_enthalpy(p) + np.tile(x, 3) * (sat.vapour_enthalpy(p) - sat.liquid_enthalpy(p))
    n = p.size
    res = models.condenser(np.full(n, 0.028), np.full(n, 0.3), p, h, np.full(n, T_air), np.full(n, 0.4))
    ratio = res["capacity_ratio"]
    assert np.isfinite(ratio).all() and ratio.max() / ratio.min() > 50
    scaled = ratio * capacity_scale(p, h, np.full(n, T_air), res["p_out"], sat)
    assert scaled.max() / scaled.min() < 1.01


def test_the_blend_is_the_scaled_table_in_the_dome_and_the_plain_one_beyond(sat):
    p = np.full(5, 8e5)
    h_l, h_v = sat.liquid_enthalpy(p), sat.vapour_enthalpy(p)
    x = np.array([0.3, X_SCALED, 0.9, 1.0, 1.2])
    h = h_l + x * (h_v - h_l)
    np.testing.assert_allclose(scaled_weight(p, h, sat), [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-12)
    T_air, p_out = np.full(5, 295.0), p - 1e3
    factor = capacity_scale(p, h, T_air, p_out, sat)
    plain, scaled = np.full(5, 2.0), 3.0 * factor  # the scaled table giving a ratio of 3
    np.testing.assert_allclose(dome_capacity_ratio(plain, scaled, p, h, T_air, p_out, sat), [3, 3, 2.5, 2, 2])
    # A NaN of one table (a cell touching nodes that condense nothing): the other alone.
    out = dome_capacity_ratio(np.full(5, np.nan), scaled, p, h, T_air, p_out, sat)
    np.testing.assert_allclose(out[:3], 3.0)
    assert np.isnan(out[3:]).all()
