"""Chiller bench: sizing point, energy balance per point, second law, trends, closure variables, flags."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from evtms.benches import BENCHES
from evtms.benches.base import STATUS_OUTSIDE_FLUID_RANGE, STATUS_PROPERTY_FAILED
from evtms.benches.chiller import (
    STATUS_COOLANT_FREEZES,
    STATUS_CORRELATION_OUTSIDE_RANGE,
    STATUS_DP_EXCEEDS_INLET,
    STATUS_FLOW_NOT_POSITIVE,
    STATUS_NOT_COLDER_THAN_COOLANT,
    solve_chiller,
)
from evtms.benches.parameters import load_parameters
from evtms.errors import EvtmsInputError
from evtms.fluid import coolant

BENCH = BENCHES["chiller"]
VALID = (0, STATUS_CORRELATION_OUTSIDE_RANGE)
#: Sizing point of the default geometry (PlateHXParams docstring).
T_EVAP, T_COOLANT, M_COOLANT, M_REF = 274.15, 303.15, 0.15, 0.0288


@pytest.fixture(scope="module")
def nominal(fluid):
    """Inlet pressure (1 degC saturation) and enthalpy (35 degC liquid at 40 degC condensing)."""
    p = float(fluid.saturation_pressure(T_EVAP))
    h = float(fluid.state("PT", fluid.saturation_pressure(313.15), 308.15, ("H",))["H"])
    return p, h


def run(fluid, params, **inputs):
    """The bench at broadcast inputs (defaults: the sizing point)."""
    p, h = inputs.pop("nominal")
    base = {"mdot": M_REF, "p_in": p, "h_in": h, "mdot_coolant": M_COOLANT, "T_coolant_in": T_COOLANT}
    base.update(inputs)
    arrays = np.broadcast_arrays(*(np.asarray(v, float) for v in base.values()))
    return BENCH.evaluate({k: a.reshape(-1).copy() for k, a in zip(base, arrays, strict=True)}, params, fluid)


def test_sizing_point_moves_about_4_5_kW_with_10_K_superheat(fluid, params, nominal):
    res = solve_chiller(
        fluid,
        params.chiller,
        np.array([nominal[0]]),
        np.array([nominal[1]]),
        np.array([M_REF]),
        np.array([M_COOLANT]),
        np.array([T_COOLANT]),
    )
    superheat = res["T_out"] - fluid.saturation_curve().temperature(res["p_out"])
    assert res["Q"][0] == pytest.approx(-4500.0, rel=0.03)
    assert superheat[0] == pytest.approx(10.0, abs=0.5)
    assert 150.0 < res["UA"][0] < 230.0  # system.md assumes about 175 W/K
    assert res["T_coolant_out"][0] - 273.15 == pytest.approx(21.0, abs=0.5)


@pytest.fixture(scope="module")
def ds(thesis):
    return thesis("chiller")


def test_thesis_grid_valid_and_declared(ds):
    assert tuple(ds["status"].dims) == ("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in")
    assert np.isin(ds["status"].values, VALID).all()
    assert ds["T_coolant_out"].attrs["units"] == "K"
    assert ds["T_coolant_out"].attrs["long_name"] == "coolant temperature leaving the chiller"
    assert ds["Q"].attrs["long_name"] == "heat flow from refrigerant to coolant"
    assert (ds["Q"].values < 0).all()


def _random_points(n, seed=7):
    rng = np.random.default_rng(seed)
    pre = BENCH.presets["cycle"]
    return {
        "mdot": np.exp(rng.uniform(np.log(0.003), np.log(0.15), n)),
        "p_in": rng.uniform(min(pre["p_in"]), max(pre["p_in"]), n),
        "h_in": rng.uniform(200e3, 350e3, n),
        "mdot_coolant": np.exp(rng.uniform(np.log(0.02), np.log(0.5), n)),
        "T_coolant_in": rng.uniform(273.15, 323.15, n),
    }


@pytest.fixture(scope="module")
def envelope(fluid, params):
    pts = _random_points(3000)
    return pts, BENCH.evaluate({k: v.copy() for k, v in pts.items()}, params, fluid)


def test_energy_balance_per_point_to_round_off(envelope):
    pts, out = envelope
    valid = np.isin(out["status"], VALID)
    assert valid.mean() > 0.6
    c = coolant()
    h_c_in, h_c_out = c.enthalpy(pts["T_coolant_in"]), c.enthalpy(out["T_coolant_out"])
    balance = pts["mdot"] * (out["h_in"] - out["h_out"]) + pts["mdot_coolant"] * (h_c_in - h_c_out)
    # Round-off of the enthalpy differences: a few ulps of the enthalpy flows themselves.
    scale = pts["mdot"] * np.abs(out["h_in"]) + pts["mdot_coolant"] * np.abs(h_c_in)
    assert np.max(np.abs(balance[valid]) / scale[valid]) < 1e-13
    Q_ref = pts["mdot"] * (out["h_in"] - out["h_out"])
    assert np.max(np.abs(out["Q"] - Q_ref)[valid] / scale[valid]) < 1e-13


def test_second_law_per_point(envelope, fluid):
    pts, out = envelope
    valid = np.isin(out["status"], VALID)
    T_in = fluid.state("PH", pts["p_in"][valid], pts["h_in"][valid], ("T",))["T"]
    T_c_in, T_c_out = pts["T_coolant_in"][valid], out["T_coolant_out"][valid]
    # The coolant cools, never below the refrigerant's inlet temperature; the refrigerant
    # never leaves warmer than the coolant enters (counter-flow limit of both streams).
    assert np.all(T_c_out <= T_c_in)
    assert np.all(T_c_out > T_in)
    assert np.all(out["T_out"][valid] < T_c_in)


def test_trends_more_coolant_warmer_coolant_lower_pressure_more_heat(fluid, params, nominal):
    # At a refrigerant flow the exchanger cannot fully evaporate (two-phase outlet).
    m_c = run(fluid, params, nominal=nominal, mdot=0.05, mdot_coolant=[0.05, 0.1, 0.2, 0.4])
    assert np.all(np.diff(-m_c["Q"]) > 0)
    T_c = run(fluid, params, nominal=nominal, mdot=0.05, T_coolant_in=np.arange(283.15, 324.0, 10.0))
    assert np.all(np.diff(-T_c["Q"]) > 0)
    p = fluid.saturation_pressure(np.array([284.15, 279.15, 274.15, 269.15]))
    lower_p = run(fluid, params, nominal=nominal, mdot=0.05, p_in=p)
    assert np.all(np.diff(-lower_p["Q"]) > 0)
    # More refrigerant flow takes more heat.
    m_r = run(fluid, params, nominal=nominal, mdot=[0.01, 0.02, 0.04, 0.08])
    assert np.all(np.diff(-m_r["Q"]) > 0)


def test_capacity_ratio_and_continued_enthalpy_across_the_phase_boundary(fluid, params, nominal):
    mdot = np.linspace(0.025, 0.04, 301)
    out = run(fluid, params, nominal=nominal, mdot=mdot)
    cr, h, hc = out["capacity_ratio"], out["h_out"], out["h_out_continued"]
    assert cr[0] > 1 > cr[-1] and np.all(np.diff(cr) < 0)
    superheated = cr > 1
    np.testing.assert_array_equal(hc[superheated], h[superheated])
    assert np.all(h[~superheated] <= fluid.saturation(nominal[0])["h_v"] + 1e-6)  # two-phase outlets
    # Continuous: no step in h_out_continued larger than a few times its typical step.
    step = np.abs(np.diff(hc))
    assert step.max() < 3.0 * np.median(step)
    # h_out has a kink where the outlet reaches saturation; h_out_continued is smooth there:
    # its second differences stay small where h_out's jump.
    d2_h, d2_hc = np.abs(np.diff(h, 2)), np.abs(np.diff(hc, 2))
    assert d2_hc.max() < 0.1 * d2_h.max()


def test_invalid_inputs_get_nan_and_their_status(fluid, params, nominal):
    p, h = nominal
    out = run(
        fluid,
        params,
        nominal=nominal,
        p_in=[p, p, p, p, p, 5e6, 0.07e6, p],
        h_in=[h, h, h, h, h, h, 230e3, h],
        T_coolant_in=[270.0, 230.0, T_COOLANT, T_COOLANT, T_COOLANT, T_COOLANT, T_COOLANT, 380.0],
        mdot_coolant=[M_COOLANT, M_COOLANT, 0.0, M_COOLANT, M_COOLANT, M_COOLANT, M_COOLANT, M_COOLANT],
        mdot=[M_REF, M_REF, M_REF, -0.01, M_REF, M_REF, 0.15, M_REF],
    )
    status = out["status"].tolist()
    assert status[:5] == [
        STATUS_NOT_COLDER_THAN_COOLANT,
        STATUS_COOLANT_FREEZES,
        STATUS_FLOW_NOT_POSITIVE,
        STATUS_FLOW_NOT_POSITIVE,
        STATUS_CORRELATION_OUTSIDE_RANGE,
    ]
    assert status[5] == STATUS_OUTSIDE_FLUID_RANGE  # above the critical pressure: nothing evaporates
    assert status[6] in (STATUS_DP_EXCEEDS_INLET, STATUS_PROPERTY_FAILED)  # 0.15 kg/s at -35 degC
    assert status[7] == STATUS_OUTSIDE_FLUID_RANGE  # coolant above its property range (373.15 K)
    invalid = ~np.isin(out["status"], VALID)
    for name, value in out.items():
        if name != "status":
            assert np.all(np.isnan(value[invalid])), name
            assert np.all(np.isfinite(value[~invalid])), name


def test_chiller_parameters_load_and_are_checked(tmp_path):
    good = tmp_path / "good.toml"
    good.write_text("[chiller]\nn_plates = 30\ncoolant_mass_fraction = 0.4\n")
    params = load_parameters(good)
    assert params.chiller.n_plates == 30 and params.chiller.coolant_mass_fraction == 0.4
    for text, key in (
        ("[chiller]\nn_plates = 2\n", "n_plates"),
        ("[chiller]\nchevron_angle = 95.0\n", "chevron_angle"),
        ("[chiller]\ncorrugation_amplitude = 0.004\n", "corrugation_amplitude"),
    ):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(EvtmsInputError, match=key):
            load_parameters(bad)


def test_more_plates_more_heat(fluid, params, nominal):
    big = dataclasses.replace(params, chiller=dataclasses.replace(params.chiller, n_plates=30))
    a = run(fluid, params, nominal=nominal, mdot=0.05)
    b = run(fluid, big, nominal=nominal, mdot=0.05)
    assert -b["Q"][0] > -a["Q"][0]


def test_tiny_refrigerant_flows_fill_the_plate(fluid, params):
    # A flow split evaluates a branch at 0.1 g/s and less; there the exchanger is so large
    # that the refrigerant leaves within round-off of the coolant inlet temperature. The
    # zones must still fill the plate (the pressure drop runs over the whole length): the
    # bisection's last point once left up to 96 % of the area unassigned, or infinite
    # (status 4 with dp NaN at 1e-6 and 1e-5 kg/s).
    mdot = np.geomspace(1e-6, 1e-3, 13)
    h_in = np.array([200e3, 230e3, 260e3, 280e3, 320e3, 410e3])
    m, h = (a.reshape(-1) for a in np.meshgrid(mdot, h_in, indexing="xy"))
    n = m.size
    p, m_c, T_c = np.full(n, 263230.0), np.full(n, 0.3), np.full(n, 303.0)
    out = BENCH.evaluate(
        {"mdot": m.copy(), "p_in": p.copy(), "h_in": h.copy(), "mdot_coolant": m_c.copy(), "T_coolant_in": T_c.copy()},
        params,
        fluid,
    )
    assert np.isin(out["status"], VALID).all()
    dp = out["dp"].reshape(h_in.size, mdot.size)
    assert np.all(dp > 0)
    assert np.all(np.diff(dp, axis=1) > 0)  # more flow, more drop, at every inlet enthalpy
    c = coolant()
    h_c_in, h_c_out = c.enthalpy(T_c), c.enthalpy(out["T_coolant_out"])
    balance = m * (out["h_in"] - out["h_out"]) + m_c * (h_c_in - h_c_out)
    scale = m * np.abs(out["h_in"]) + m_c * np.abs(h_c_in)
    assert np.max(np.abs(balance) / scale) < 1e-13
    res = solve_chiller(fluid, params.chiller, p, h, m, m_c, T_c)
    np.testing.assert_allclose(res["fractions"].sum(axis=1), 1.0, rtol=0, atol=1e-12)


# --- the compiled solve ------------------------------------------------------------------------

#: Outputs of solve_chiller that are masks (compared exactly).
_MASKS = ("outside_range", "bad_direction", "bad_dp", "bad_flow", "coolant_freezes", "coolant_outside", "bad_props")


def _solver_inputs(n, seed=11):
    """Points over and beyond the cycle envelope (tiny flows, coolant colder than the refrigerant)."""
    rng = np.random.default_rng(seed)
    pts = _random_points(n, seed)
    pts["mdot"] = np.exp(rng.uniform(np.log(1e-5), np.log(0.2), n))
    return [pts[k] for k in ("p_in", "h_in", "mdot", "mdot_coolant", "T_coolant_in")]


@pytest.fixture(scope="module")
def compiled_and_references(fluid, params):
    """The compiled solve and solve_chiller on the same tables and on CoolProp, at 400 points."""
    from evtms._jit import numba_enabled
    from evtms.benches.chiller import solve_chiller_compiled
    from evtms.fluid_tables_dome import DomeTabulatedFluid

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set): only the array path exists")
    args = _solver_inputs(400)
    hx = params.chiller
    return (
        solve_chiller_compiled(fluid, hx, *args),
        solve_chiller(DomeTabulatedFluid(fluid), hx, *args),
        solve_chiller(fluid, hx, *args),
    )


def _valid(res):
    return ~np.any([res[k] for k in _MASKS if k != "outside_range"], axis=0)


def test_compiled_chiller_is_the_array_solve_on_the_same_tables(compiled_and_references):
    compiled, tabulated, _ = compiled_and_references
    for key in _MASKS:
        np.testing.assert_array_equal(compiled[key], tabulated[key], err_msg=key)
    valid = _valid(tabulated)
    assert 0.5 < valid.mean() < 1.0  # valid points and every kind of invalid one
    assert compiled["bad_direction"].any() and compiled["bad_flow"].sum() == 0
    for key, value in tabulated.items():
        if key not in _MASKS:
            np.testing.assert_allclose(compiled[key][valid], value[valid], rtol=1e-9, atol=0.0, err_msg=key)


def test_compiled_chiller_is_coolprop_within_the_tables_tolerance(compiled_and_references):
    compiled, _, coolprop = compiled_and_references
    valid = _valid(coolprop)
    np.testing.assert_array_equal(_valid(compiled), valid)
    for key in ("Q", "h_out", "dp", "h_out_continued", "T_coolant_out", "UA"):
        np.testing.assert_allclose(compiled[key][valid], coolprop[key][valid], rtol=1e-4, atol=0.0, err_msg=key)
    np.testing.assert_allclose(compiled["T_out"][valid], coolprop["T_out"][valid], rtol=0.0, atol=2e-3)


def test_compiled_chiller_hands_states_beyond_its_tables_to_coolprop(fluid, params):
    """Above the tables' 90 % of the critical pressure (and below the critical pressure) the
    compiled solve gives CoolProp's answer, point by point."""
    from evtms._jit import numba_enabled
    from evtms.benches.chiller import solve_chiller_compiled

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set): only the array path exists")
    p = np.array([0.95 * fluid.p_crit, 3.0e5])
    h, m, m_c, T_c = np.array([300e3, 230e3]), np.full(2, 0.03), np.full(2, 0.15), np.full(2, 363.15)
    got = solve_chiller_compiled(fluid, params.chiller, p, h, m, m_c, T_c)
    ref = solve_chiller(fluid, params.chiller, p, h, m, m_c, T_c)
    assert np.isfinite(ref["Q"][0]) and not ref["bad_props"][0]  # CoolProp has the state
    for key, value in ref.items():
        np.testing.assert_allclose(got[key][0], value[0], rtol=1e-12, err_msg=key)
    np.testing.assert_allclose(got["Q"][1], ref["Q"][1], rtol=1e-4)
