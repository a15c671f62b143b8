"""Evaporator bench: moist-air energy balance, second law, latent load, outlet saturation, flags, trends."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from CoolProp.CoolProp import HAPropsSI

from evtms.benches import BENCHES
from evtms.benches.coil import OUTLET_SATURATION_MAX, solve_coil
from evtms.benches.condenser import STATUS_AIR_CORRELATION_OUTSIDE_RANGE
from evtms.benches.evaporator import FROST_RISK_FLAGS, STATUS_FROST_RISK, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE
from evtms.benches.sweep import grid_points

VALID = (0, STATUS_FROST_RISK, STATUS_AIR_CORRELATION_OUTSIDE_RANGE, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE)


@pytest.fixture(scope="module")
def ds(thesis):
    return thesis("evaporator")


@pytest.fixture(scope="module")
def raw(ds, fluid, params):
    """The coil model's full result on the thesis grid (for air-side checks)."""
    grid = {name: ds[name].values for name in ds.dims}
    pts = grid_points(grid, 0, ds["Q"].size)
    h_in = fluid.state("PT", pts["p_in"], pts["T_in"], ("H",))["H"]
    res = solve_coil(
        fluid, params.evaporator, params.environment, pts["p_in"], h_in, pts["mdot"], pts["blower"], "evaporator"
    )
    return res


def test_all_thesis_points_valid_some_with_frost_risk(ds):
    status = ds["status"].values
    # Blower 0.2-0.5 gives Re_Lp 31-78, below Chang and Wang's 100: every point carries the
    # range flag, and those with a surface below 0 degC the combined frost flag.
    assert set(np.unique(status)) == {STATUS_AIR_CORRELATION_OUTSIDE_RANGE, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE}
    for name in ("Q", "Q_latent", "h_in", "h_out", "T_out", "p_out", "x_out", "T_air_out", "dp"):
        assert np.isfinite(ds[name].values).all(), name
    meanings = ds["status"].attrs["flag_meanings"].split()
    assert "valid_frost_risk_surface_below_0C" in meanings
    assert "valid_air_correlation_outside_range" in meanings
    assert "valid_frost_risk_air_correlation_outside_range" in meanings
    assert list(ds["status"].attrs["valid_flag_values"]) == list(VALID)


def test_frost_flag_matches_surface_temperature(ds, raw):
    frost = np.isin(ds["status"].values.ravel(), FROST_RISK_FLAGS)
    np.testing.assert_array_equal(frost, raw["T_surface_min"] < 273.15)
    outside = np.isin(
        ds["status"].values.ravel(), (STATUS_AIR_CORRELATION_OUTSIDE_RANGE, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE)
    )
    np.testing.assert_array_equal(outside, raw["air_outside_range"])
    np.testing.assert_array_equal(outside, (raw["Re_Lp"] < 100) | (raw["Re_Lp"] > 3000))


def test_blower_above_re_lp_100_clears_the_range_flag(fluid, params):
    # Re_Lp = 100 near blower 0.64 (core velocity 1.6 m/s at 30 degC), 156 at blower 1.
    n = 4
    inputs = {
        "mdot": np.full(n, 0.02),
        "blower": np.array([0.3, 0.6, 0.7, 1.0]),
        "p_in": np.full(n, 0.35e6),
        "h_in": np.full(n, 250e3),
        "T_res": np.full(n, 280.0),
    }
    out = BENCHES["evaporator"].evaluate(inputs, params, fluid)
    np.testing.assert_array_equal(out["status"], [STATUS_AIR_CORRELATION_OUTSIDE_RANGE] * 2 + [0, 0])


def test_refrigerant_gain_equals_air_loss_including_condensate(ds, raw, params):
    env = params.environment
    q = ds["Q"].values.ravel()
    mdot = ds["mdot"].broadcast_like(ds["Q"]).values.ravel()
    np.testing.assert_allclose(q, mdot * (ds["h_in"].values - ds["h_out"].values).ravel(), rtol=1e-12)
    assert (q < 0).all()
    # Independent air-side enthalpies from HAPropsSI at the reported outlet temperature.
    h_air_in = HAPropsSI("H", "T", env.T, "P", env.p, "R", env.RH)
    h_air_out = np.array(
        [
            HAPropsSI("H", "T", t, "P", env.p, "W", w)
            for t, w in zip(ds["T_air_out"].values.ravel(), raw["w_air_out"], strict=True)
        ]
    )
    air_loss = raw["m_dry_air"] * (h_air_in - h_air_out) - raw["H_condensate"]
    np.testing.assert_allclose(air_loss, -q, rtol=1e-6)


def test_latent_load_is_the_condensate_latent_heat(ds, raw, params):
    latent = ds["Q_latent"].values.ravel()
    q = ds["Q"].values.ravel()
    assert (latent <= 0).all() and (latent >= q).all()
    wet = raw["m_condensate"] > 0
    assert wet.sum() > 100
    h_fg = -latent[wet] / raw["m_condensate"][wet]
    assert ((h_fg > 2.45e6) & (h_fg < 2.6e6)).all()  # water's latent heat between -20 and 20 degC
    np.testing.assert_array_equal(latent[~wet], 0.0)


def test_latent_zero_above_dew_point_negative_below(ds, raw):
    latent = ds["Q_latent"].values.ravel()
    T_s, T_dew = raw["T_surface_eff"], raw["T_dew_air_in"]
    assert (latent[T_s > T_dew] == 0).all()
    below = T_s < T_dew - 0.01
    assert below.sum() > 100 and (latent[below] < 0).all()


@pytest.mark.parametrize(("RH", "expect_latent"), [(0.0, False), (0.1, False), (0.8, True)])
def test_latent_follows_air_humidity(fluid, params, RH, expect_latent):
    env = dataclasses.replace(params.environment, RH=RH)
    p = np.full(3, 0.35e6)  # saturation near 5 degC: a typical running evaporator
    sat = fluid.saturation(p)
    h_in = sat["h_l"] + 0.25 * (sat["h_v"] - sat["h_l"])  # two-phase inlet after the valve
    res = solve_coil(fluid, params.evaporator, env, p, h_in, np.full(3, 0.02), np.array([0.3, 0.6, 1.0]), "evaporator")
    assert np.isfinite(res["Q"]).all()
    if expect_latent:
        assert (res["Q_latent"] < -10).all()
        assert (res["T_surface_eff"] < res["T_dew_air_in"]).all()
    else:
        assert (res["Q_latent"] == 0).all()


def _coil_over_humidity(fluid, params, RH, p_in, h_in, mdot, blower, T_air):
    """The evaporator at one refrigerant and air state [SI] over the humidities ``RH``."""
    n = RH.size
    return solve_coil(
        fluid, params.evaporator, params.environment, np.full(n, p_in), np.full(n, h_in), np.full(n, mdot),
        np.full(n, blower), "evaporator", T_air=np.full(n, T_air), RH_air=RH,
    )  # fmt: skip


def test_wetting_sets_in_smoothly_with_humidity(fluid, params):
    """The two-phase zone wets from the air's exit side as the humidity rises (the partly wet
    coil): the heat rate's slope in humidity grows from zero over several steps, not at
    once (the larger of the dry and wet rates jumped from 0.03 to 3.1 W per step here,
    a corner a LUT interpolates poorly)."""
    RH = np.arange(0.30, 0.60, 0.0025)
    n = RH.size
    res = _coil_over_humidity(fluid, params, RH, p_in=4.8e5, h_in=294e3, mdot=0.0156, blower=0.46, T_air=301.8)
    latent, dQ = res["Q_latent"], np.diff(res["Q"])
    onset = int(np.argmax(latent < 0))
    assert 10 < onset < n - 40 and (latent[:onset] == 0).all() and (latent[onset:] < 0).all()
    assert np.abs(dQ[: onset - 2]).max() < 0.05  # dry: only the humid air's heat capacity moves
    assert np.abs(np.diff(dQ)).max() < 0.5 * np.abs(dQ).max()  # no step in the slope
    assert -dQ[onset - 1] < 0.3 * -dQ[onset + 8]  # the slope starts small


def test_bone_dry_air_gives_the_dry_rate(fluid, params):
    """Air drier than the saturated-air table's coldest state (RH 0, or w below ~6.7e-6) has its
    dew point below any surface: the two-phase zone is dry, not NaN nor another rate (it was
    2.9 % off on the array path once the partly wet coil needed a dew point)."""
    RH = np.array([0.0, 1e-7, 1e-4, 0.01])
    res = _coil_over_humidity(fluid, params, RH, p_in=3.5e5, h_in=250e3, mdot=0.02, blower=0.5, T_air=308.15)
    assert np.isfinite(res["Q"]).all() and (res["Q_latent"] == 0).all()
    # Only the vapour's heat capacity in the air moves the rate: a few parts in 1e5.
    np.testing.assert_allclose(res["Q"], res["Q"][-1], rtol=1e-4)


def test_second_law_refrigerant_never_warmer_than_air(ds, params, fluid):
    T_air = params.environment.T
    assert (ds["T_out"].values <= T_air + 1e-6).all()
    mdot = ds["mdot"].broadcast_like(ds["Q"]).values
    h_air_T = fluid.state("PT", ds["p_out"].values, T_air, ("H",))["H"]
    assert (-ds["Q"].values <= mdot * (h_air_T - ds["h_in"].values) * (1 + 1e-7)).all()
    assert (ds["T_air_out"].values < T_air).all()


def test_thesis_trends(ds):
    q = -ds["Q"].values  # |Q|
    # |Q| grows with mass flow, about linearly where the inlet boils (subcooled/two-phase inlet).
    assert (np.diff(q, axis=0) > 0).all()
    boiling = ds["x_out"].values > 1.0
    ratio = (ds["Q"].isel(mdot=-1) / ds["Q"].isel(mdot=0)).values
    m_ratio = float(ds["mdot"][-1] / ds["mdot"][0])
    liquid_in = ds["Q_latent"].isel(mdot=0).values < 0
    assert np.all(np.abs(ratio[liquid_in] / m_ratio - 1) < 0.1) and boiling.all()
    # Air flow: weaker and saturating effect.
    dq_air = np.diff(q, axis=1)
    assert (dq_air >= -1e-9).all()
    rel_air = (q[:, -1] - q[:, 0]) / q[:, -1]
    rel_mdot = (q[-1] - q[0]) / q[-1]
    assert rel_air.max() < 0.1 < np.median(rel_mdot)
    assert (dq_air[:, -1] <= dq_air[:, 0] + 1e-9).all()  # saturating
    # |Q| falls as the inlet temperature rises.
    assert (np.diff(q, axis=3) < 0).all()
    # The downstream reservoir has no effect.
    assert np.array_equal(q[..., 0], q[..., 1]) and np.array_equal(q[..., 0], q[..., 2])


@pytest.mark.parametrize(
    "component, mdot, air, h_in, p_range",
    [
        # Evaporator: the outlet turns from superheated to two-phase as p_in rises.
        (
            "evaporator",
            0.0222,
            {"blower": 0.76, "T_air_in": 297.8, "RH_air_in": 0.6},
            250e3,
            (380e3, 500e3),
        ),
        # Condenser: from two-phase to subcooled as p_in rises.
        ("condenser", 0.03, {"fan": 0.5, "T_air_in": 305.0}, 440e3, (0.95e6, 1.35e6)),
    ],
)
def test_h_out_continued_equals_h_out_in_the_last_zone_and_is_smooth_past_it(
    component, mdot, air, h_in, p_range, params, fluid
):
    p = np.linspace(*p_range, 41)
    n = p.size
    inputs = {"mdot": np.full(n, mdot), "p_in": p, "h_in": np.full(n, h_in), "T_res": np.full(n, 290.0)}
    inputs.update({k: np.full(n, v) for k, v in air.items()})
    out = BENCHES[component].evaluate(inputs, params, fluid)
    assert np.isin(out["status"], BENCHES[component].valid_flags).all()
    x = out["x_out"]
    in_last = (x > 1) if component == "evaporator" else (x < 0)  # superheated / subcooled outlet
    assert 5 < in_last.sum() < n - 5  # the sweep crosses the phase boundary
    np.testing.assert_array_equal(out["h_out_continued"][in_last], out["h_out"][in_last])
    assert (out["h_out_continued"][~in_last] != out["h_out"][~in_last]).all()
    # Across the boundary (between points b and b + 1) h_out's slope jumps by a factor
    # of 2.4-4; the continuation keeps it within 1.5 (C1; only its curvature jumps).
    b = np.nonzero(in_last[1:] != in_last[:-1])[0][0]

    def slope_jump(h):
        before, after = np.diff(h)[b - 1], np.diff(h)[b + 1]
        return max(before / after, after / before)

    assert slope_jump(out["h_out"]) > 2.0
    assert slope_jump(out["h_out_continued"]) < 1.5


def _degree_of_saturation(T, w, p):
    """w / w_sat(T) from HAPropsSI: above 1 the air is supersaturated (RH > 1)."""
    w_sat = np.array([HAPropsSI("W", "T", t, "P", p, "R", 1.0) for t in T])
    return w / w_sat


def _random_evaporator_points(fluid, n, seed):
    """Random points over the cycle envelope, RH up to 0.95, a few distinct air states (fast)."""
    rng = np.random.default_rng(seed)
    return {
        "p_in": fluid.saturation_pressure(rng.uniform(-35.0, 29.0, n) + 273.15),
        "h_in": rng.uniform(200e3, 350e3, n),
        "mdot": np.exp(rng.uniform(np.log(0.003), np.log(0.15), n)),
        "blower": np.exp(rng.uniform(np.log(0.1), 0.0, n)),
        "T_air": rng.choice([288.15, 298.15, 308.15], n),
        "RH_air": rng.choice([0.2, 0.6, 0.95], n),
    }


def test_thesis_outlet_air_never_supersaturated(raw, params):
    p = params.environment.p
    s = _degree_of_saturation(raw["T_air_out"], raw["w_air_out"], p)
    assert (s <= 1 + 1e-9).all(), s.max()
    # Two thesis points (mdot 7.43 and 7.7 g/s, blower 0.2, 0.1 MPa, 235 K) mixed to RH 1.003
    # and 1.033 before their excess water was condensed; they leave at the outlet limit.
    fog = raw["m_condensate_outlet"] > 0
    assert fog.sum() == 6  # two points times three T_res
    np.testing.assert_allclose(s[fog], OUTLET_SATURATION_MAX, atol=6e-6)
    rh = np.array(
        [HAPropsSI("R", "T", t, "P", p, "W", w) for t, w in zip(raw["T_air_out"], raw["w_air_out"], strict=True)]
    )
    assert (rh <= 1 + 1e-9).all()


@pytest.fixture(scope="module")
def random_points(fluid, params):
    pts = _random_evaporator_points(fluid, 600, seed=13)
    res = solve_coil(
        fluid,
        params.evaporator,
        params.environment,
        pts["p_in"],
        pts["h_in"],
        pts["mdot"],
        pts["blower"],
        "evaporator",
        T_air=pts["T_air"],
        RH_air=pts["RH_air"],
    )
    ok = ~(res["bad_direction"] | res["bad_dp"] | res["bad_props"])
    return pts, res, ok


def test_random_outlet_air_never_supersaturated_and_energy_closes(random_points, fluid, params):
    pts, res, ok = random_points
    assert ok.sum() > 400
    p = params.environment.p
    T, w = res["T_air_out"][ok], res["w_air_out"][ok]
    s = _degree_of_saturation(T, w, p)
    assert (s <= 1 + 1e-9).all(), s.max()
    # Humid air on a very cold coil mixes far beyond saturation (fog); those points leave saturated.
    fog = res["m_condensate_outlet"][ok] > 0
    assert fog.sum() > 50
    np.testing.assert_allclose(s[fog], OUTLET_SATURATION_MAX, atol=6e-6)
    # Energy: the air's loss (HAPropsSI at the reported outlet state) less the condensate's
    # enthalpy equals the refrigerant's gain, with the fog's condensate included.
    inlet = list(zip(pts["T_air"][ok], pts["RH_air"][ok], strict=True))
    h_in_air = np.array([HAPropsSI("H", "T", t, "P", p, "R", r) for t, r in inlet])
    h_out_air = np.array([HAPropsSI("H", "T", t, "P", p, "W", x) for t, x in zip(T, w, strict=True)])
    air_loss = res["m_dry_air"][ok] * (h_in_air - h_out_air) - res["H_condensate"][ok]
    np.testing.assert_allclose(air_loss, -res["Q"][ok], rtol=1e-6)
    # Moisture: the water removed is the condensate, and the latent load stays within Q.
    w_in = np.array([HAPropsSI("W", "T", t, "P", p, "R", r) for t, r in inlet])
    np.testing.assert_allclose(res["m_dry_air"][ok] * (w_in - w), res["m_condensate"][ok], rtol=1e-9, atol=1e-12)
    assert (res["Q_latent"][ok] >= res["Q"][ok]).all()


def test_random_outlet_air_between_refrigerant_and_inlet_air(random_points, fluid):
    pts, res, ok = random_points
    T_ref_in = fluid.state("PH", pts["p_in"], pts["h_in"], ("T",))["T"][ok]
    assert (res["T_air_out"][ok] > T_ref_in).all()
    assert (res["T_air_out"][ok] < pts["T_air"][ok]).all()


def test_fog_of_mixed_saturated_streams_condenses_with_the_energy_balance():
    """Saturated air at 5 and 25 degC, mixed 1:1, lies beyond saturation; its excess condenses."""
    from evtms.benches.coil import _condense_excess
    from evtms.fluid import humid_air_temperature, saturated_air, water_liquid_enthalpy

    p = 101325.0
    T1, T2 = 278.15, 298.15
    h = 0.5 * sum(HAPropsSI("H", "T", t, "P", p, "R", 1.0) for t in (T1, T2))
    w = 0.5 * sum(HAPropsSI("W", "T", t, "P", p, "R", 1.0) for t in (T1, T2))
    T_mix = float(humid_air_temperature(np.array([h]), np.array([w]), p)[0])
    assert w > HAPropsSI("W", "T", T_mix, "P", p, "R", 1.0)  # supersaturated as mixed
    dw, T_c = _condense_excess(np.array([h]), np.array([w]), saturated_air(p))
    dw, T_c = float(dw[0]), float(T_c[0])
    # The latent heat released warms the air: it settles between the streams, above the mixed state.
    assert T_mix < T_c < T2 and dw > 0
    w_out = w - dw
    assert w_out / HAPropsSI("W", "T", T_c, "P", p, "R", 1.0) == pytest.approx(OUTLET_SATURATION_MAX, abs=3e-6)
    # Energy: air leaving plus the condensate's enthalpy equals the mixture's.
    h_out = HAPropsSI("H", "T", T_c, "P", p, "W", w_out)
    assert h_out + dw * float(water_liquid_enthalpy(T_c)) == pytest.approx(h, abs=0.05)
