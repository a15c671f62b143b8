"""Water-cooled condenser bench: sizing point, energy on both streams, second law, trends, closure
variables, the mirrored counter-flow solver against the closed form, flags and the command line."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.benches.base import STATUS_OUTSIDE_FLUID_RANGE
from evtms.benches.wcc import (
    DEFAULT_PLATES,
    STATUS_COOLANT_FREEZES,
    STATUS_COOLANT_NOT_BELOW_INLET,
    STATUS_CORRELATION_OUTSIDE_RANGE,
    STATUS_FLOW_NOT_POSITIVE,
    STATUS_INLET_SUBCOOLED,
    STATUS_SUPERCRITICAL,
    solve_wcc,
)
from evtms.cli import app
from evtms.fluid import coolant
from evtms.hx.counterflow import RefrigerantPath, solve_counterflow_condenser

BENCH = BENCHES["wcc"]
VALID = (0, STATUS_CORRELATION_OUTSIDE_RANGE)
#: Sizing point (spec 5.6): 45 degC condensing, 70 degC vapour in, MEG 50 % at 30 degC and 0.2 kg/s.
T_COND, T_VAPOUR, T_COOLANT, M_COOLANT, Q_SIZING = 318.15, 343.15, 303.15, 0.2, 5000.0


@pytest.fixture(scope="module")
def sizing(fluid):
    """Inlet pressure and enthalpy of the sizing point, and the flow that 5 kW takes to saturated liquid."""
    p = float(fluid.saturation_pressure(T_COND))
    h_in = float(fluid.state("PT", p, T_VAPOUR, ("H",))["H"])
    h_l = float(fluid.saturation(np.array([p]))["h_l"][0])
    return p, h_in, Q_SIZING / (h_in - h_l)


def run(fluid, params, **inputs):
    """The bench at broadcast inputs."""
    arrays = np.broadcast_arrays(*(np.asarray(v, float) for v in inputs.values()))
    return BENCH.evaluate({k: a.reshape(-1).copy() for k, a in zip(inputs, arrays, strict=True)}, params, fluid)


def test_default_plate_count_is_the_smallest_that_condenses_5_kW(fluid, params, sizing):
    p, h_in, mdot = sizing
    assert params.wcc.n_plates == DEFAULT_PLATES
    Q = {}
    for n in (DEFAULT_PLATES - 1, DEFAULT_PLATES):
        hx = dataclasses.replace(params.wcc, n_plates=n)
        res = solve_wcc(fluid, hx, [p], [h_in], [mdot], [M_COOLANT], [T_COOLANT])
        Q[n] = res["Q"][0]
        if n == DEFAULT_PLATES:
            # Saturated (within a kelvin) or slightly subcooled liquid at about 45 degC.
            assert res["capacity_ratio"][0] >= 1.0 and res["x_out"][0] <= 0.0
            assert res["T_out"][0] == pytest.approx(T_COND, abs=1.0)
            assert res["T_coolant_out"][0] - T_COOLANT == pytest.approx(
                Q_SIZING / (M_COOLANT * coolant().properties(T_COOLANT + 4)["CP"]), rel=0.02
            )
    assert Q[DEFAULT_PLATES] >= Q_SIZING > Q[DEFAULT_PLATES - 1]


def _random_points(fluid, n, seed=11):
    """Valid-looking inputs over the cycle envelope: coolant below the inlet saturation temperature."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0.6e6, 2.4e6, n)
    T_sat = fluid.saturation(p)["T"]
    superheat = rng.uniform(-5.0, 80.0, n)  # below 0: a two-phase inlet, x from its enthalpy below h_v
    sat = fluid.saturation(p)
    h_sh = fluid.state("PT", p, T_sat + np.maximum(superheat, 0.5), ("H",))["H"]
    h_in = np.where(superheat > 0, h_sh, sat["h_v"] + superheat * 2e3)
    return {
        "mdot": np.exp(rng.uniform(np.log(0.002), np.log(0.06), n)),
        "p_in": p,
        "h_in": h_in,
        "mdot_coolant": np.exp(rng.uniform(np.log(0.05), np.log(0.36), n)),
        "T_coolant_in": rng.uniform(278.15, T_sat - 1.0),
    }


@pytest.fixture(scope="module")
def envelope(fluid, params):
    pts = _random_points(fluid, 400)
    return pts, BENCH.evaluate({k: v.copy() for k, v in pts.items()}, params, fluid)


def test_energy_closes_on_both_streams(envelope):
    pts, out = envelope
    valid = np.isin(out["status"], VALID)
    assert valid.sum() >= 300
    c = coolant()
    Q_ref = pts["mdot"] * (out["h_in"] - out["h_out"])
    Q_cool = pts["mdot_coolant"] * (c.enthalpy(out["T_coolant_out"]) - c.enthalpy(pts["T_coolant_in"]))
    Q = out["Q"][valid]
    assert np.all(Q > 0)
    assert np.max(np.abs(Q_ref[valid] - Q) / Q) < 1e-9
    assert np.max(np.abs(Q_cool[valid] - Q) / Q) < 1e-9


def test_second_law_per_point(envelope, fluid):
    pts, out = envelope
    valid = np.isin(out["status"], VALID)
    T_in = fluid.state("PH", pts["p_in"][valid], pts["h_in"][valid], ("T",))["T"]
    T_c_in, T_c_out = pts["T_coolant_in"][valid], out["T_coolant_out"][valid]
    # The coolant warms, never above the refrigerant's inlet temperature; the refrigerant never
    # leaves colder than the coolant enters (counter-flow limits of both streams).
    assert np.all(T_c_out > T_c_in)
    assert np.all(T_c_out < T_in)
    assert np.all(out["T_out"][valid] > T_c_in)
    assert np.all(out["dp"][valid] > 0) and np.all(out["p_out"][valid] < pts["p_in"][valid])


def test_trends_more_coolant_colder_coolant_higher_pressure_more_heat(fluid, params, sizing):
    p, h_in, _ = sizing
    for mdot in (0.027, 0.045):  # a subcooled and a two-phase outlet at the base point
        base = {"mdot": mdot, "p_in": p, "h_in": h_in, "mdot_coolant": M_COOLANT, "T_coolant_in": T_COOLANT}
        m_c = run(fluid, params, **{**base, "mdot_coolant": np.array([0.05, 0.1, 0.2, 0.36])})
        assert np.all(np.diff(m_c["Q"]) > 0), m_c["Q"]
        T_c = run(fluid, params, **{**base, "T_coolant_in": np.arange(278.15, 314.0, 5.0)})
        assert np.all(np.diff(T_c["Q"]) < 0), T_c["Q"]
        # Higher discharge pressure at the same 25 K of inlet superheat.
        T_sat = np.arange(313.15, 339.0, 5.0)
        p_d = fluid.saturation_pressure(T_sat)
        h_d = fluid.state("PT", p_d, T_sat + 25.0, ("H",))["H"]
        hi_p = run(fluid, params, **{**base, "p_in": p_d, "h_in": h_d})
        assert np.all(np.isin(hi_p["status"], VALID)) and np.all(np.diff(hi_p["Q"]) > 0), hi_p["Q"]


def test_capacity_ratio_and_continued_enthalpy_across_saturated_liquid(fluid, params, sizing):
    p, h_in, _ = sizing
    mdot = np.linspace(0.02, 0.035, 301)
    out = run(fluid, params, mdot=mdot, p_in=p, h_in=h_in, mdot_coolant=M_COOLANT, T_coolant_in=T_COOLANT)
    cr, h, hc = out["capacity_ratio"], out["h_out"], out["h_out_continued"]
    assert cr[0] > 1 > cr[-1] and np.all(np.diff(cr) < 0)
    subcooled = cr > 1
    np.testing.assert_array_equal(hc[subcooled], h[subcooled])
    h_l = fluid.saturation(np.array([p]))["h_l"][0]
    # Two-phase outlets, and their continuation stays on the two-phase side of saturated liquid.
    assert np.all(h[~subcooled] >= h_l - 1e-6) and np.all(hc[~subcooled] >= h_l - 1e-6)
    step = np.abs(np.diff(hc))
    assert step.max() < 3.0 * np.median(step)
    assert np.abs(np.diff(hc, 2)).max() < 0.1 * np.abs(np.diff(h, 2)).max()


@dataclass
class _LinearStream:
    """A secondary stream of constant heat capacity: h = cp T, tabulated as the counter-flow core reads it."""

    cp: float
    mdot: np.ndarray
    T_in: np.ndarray
    R: np.ndarray

    @property
    def h_in(self) -> np.ndarray:
        return self.cp * self.T_in

    def temperature(self, h):
        return np.asarray(h, float) / self.cp

    def temperature_table(self):
        T = np.linspace(100.0, 1000.0, 10)
        return self.cp * T, T


@pytest.mark.parametrize("C_r", [0.3, 1.0, 2.5])
def test_mirrored_solver_matches_the_counterflow_effectiveness_for_one_vapour_zone(C_r):
    """A superheated vapour cooled against a liquid that stays above saturation: one single-phase
    zone of constant heat capacities, so Q = eps C_min (T_in - T_c,in) with Incropera's eq. 11.29a."""
    n = 4
    cp_r, cp_c = 1000.0, 3500.0
    mdot = np.full(n, 0.02)
    m_c = mdot * cp_r / (C_r * cp_c)  # C_ref / C_coolant = C_r
    UA = np.array([5.0, 20.0, 60.0, 150.0])
    T_in, T_c_in, T_sat = 400.0, 300.0, 250.0
    ref = RefrigerantPath(
        mdot=mdot,
        h_in=np.full(n, cp_r * T_in),
        T_in=np.full(n, T_in),
        T_sat=np.full(n, T_sat),
        h_l=np.full(n, cp_r * T_sat - 2e5),
        h_v=np.full(n, cp_r * T_sat),
        h_at_secondary=np.full(n, cp_r * T_c_in),
        R=np.tile(0.5 / UA[:, None], (1, 3)),
    )
    res = solve_counterflow_condenser(ref, _LinearStream(cp_c, m_c, np.full(n, T_c_in), 0.5 / UA))
    C_ref, C_c = mdot * cp_r, m_c * cp_c
    C_min, C_max = np.minimum(C_ref, C_c), np.maximum(C_ref, C_c)
    cr = C_min / C_max
    NTU = UA / C_min
    if C_r == 1.0:
        eps = NTU / (1.0 + NTU)
    else:
        e = np.exp(-NTU * (1.0 - cr))
        eps = (1.0 - e) / (1.0 - cr * e)
    np.testing.assert_allclose(res.Q, eps * C_min * (T_in - T_c_in), rtol=1e-9)
    np.testing.assert_allclose(res.fractions[:, 2], 1.0, rtol=1e-12)  # all vapour
    assert np.all(res.h_out > ref.h_v)


def test_states_the_condenser_cannot_take_are_nan_with_their_reason(fluid, params, sizing):
    p, h_in, mdot = sizing
    h_liquid = float(fluid.state("PT", p, 300.0, ("H",))["H"])
    cases = [  # (mdot, p_in, h_in, mdot_coolant, T_coolant_in) -> status
        ((mdot, p, h_in, M_COOLANT, T_COOLANT), VALID),
        ((mdot, p, h_liquid, M_COOLANT, T_COOLANT), (STATUS_INLET_SUBCOOLED,)),
        ((mdot, 4.2e6, 480e3, M_COOLANT, T_COOLANT), (STATUS_SUPERCRITICAL,)),
        ((mdot, p, h_in, M_COOLANT, 350.0), (STATUS_COOLANT_NOT_BELOW_INLET,)),  # warmer than the 70 degC inlet
        ((mdot, p, 400e3, M_COOLANT, 320.0), (STATUS_COOLANT_NOT_BELOW_INLET,)),  # warmer than a two-phase inlet
        ((mdot, p, h_in, 0.0, T_COOLANT), (STATUS_FLOW_NOT_POSITIVE,)),
        ((-0.01, p, h_in, M_COOLANT, T_COOLANT), (STATUS_FLOW_NOT_POSITIVE,)),
        ((mdot, p, h_in, M_COOLANT, 230.0), (STATUS_COOLANT_FREEZES,)),
        ((mdot, 3.9e6, 480e3, M_COOLANT, 380.0), (STATUS_OUTSIDE_FLUID_RANGE,)),
        ((mdot, p, np.nan, M_COOLANT, T_COOLANT), (STATUS_OUTSIDE_FLUID_RANGE,)),
    ]
    cols = np.array([c for c, _ in cases], float).T
    out = run(fluid, params, **dict(zip(BENCH.axes, cols, strict=True)))
    for k, (_, expected) in enumerate(cases):
        assert out["status"][k] in expected, (k, out["status"][k])
        if expected != VALID:
            assert all(np.isnan(out[v][k]) for v in ("Q", "h_out", "T_coolant_out", "capacity_ratio")), k


def test_coolant_above_saturation_only_desuperheats(fluid, params, sizing):
    # Coolant from 1 K below the 45 degC saturation to 1 K below the 70 degC vapour inlet.
    p, h_in, mdot = sizing
    T_c = T_COND + np.array([-1.0, -1e-6, 0.0, 1e-6, 5.0, 15.0, 24.0])
    out = run(fluid, params, mdot=mdot, p_in=p, h_in=h_in, mdot_coolant=M_COOLANT, T_coolant_in=T_c)
    above = T_c >= T_COND
    assert np.isin(out["status"], VALID).all()
    h_v = float(fluid.saturation(np.array([p]))["h_v"][0])
    # Vapour out, no area condenses it, never colder than the coolant entering (second law, at
    # the pressure the core is solved at; the drop cools the vapour by a few mK more).
    assert (out["h_out"][above] > h_v).all() and (out["capacity_ratio"][above] == 0.0).all()
    T_core = fluid.state("PH", np.full(7, p), out["h_out"], ("T",))["T"]
    assert (T_core[above] >= T_c[above]).all()
    np.testing.assert_allclose(out["Q"], mdot * (h_in - out["h_out"]), rtol=1e-12)
    # Less heat the warmer the coolant; continuous where it passes the saturation.
    assert (np.diff(out["Q"]) < 0).all()
    np.testing.assert_allclose(out["Q"][1:4], out["Q"][2], rtol=1e-5)
    assert out["Q"][-1] < 0.1 * out["Q"][-3]


def test_coolant_leaving_beyond_its_table_is_flagged_not_capped(fluid, params):
    # 60 g/s of 150 degC discharge at 2.4 MPa into 0.05 kg/s of 75 degC coolant would heat it past 100 degC.
    p = 2.4e6
    h = float(fluid.state("PT", p, 423.15, ("H",))["H"])
    out = run(fluid, params, mdot=0.06, p_in=p, h_in=h, mdot_coolant=0.05, T_coolant_in=348.15)
    assert out["status"][0] == STATUS_OUTSIDE_FLUID_RANGE and np.isnan(out["Q"][0])


def test_thesis_grid_declared(thesis):
    ds = thesis("wcc")
    assert tuple(ds["status"].dims) == ("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in")
    assert ds["T_coolant_out"].attrs["long_name"] == "coolant temperature leaving the water-cooled condenser"
    valid = np.isin(ds["status"].values, VALID)
    assert valid.mean() > 0.5
    assert (ds["Q"].values[valid] > 0).all()
    # The invalid points are exactly those whose coolant is not below the refrigerant's inlet temperature.
    assert set(np.unique(ds["status"].values[~valid])) == {STATUS_COOLANT_NOT_BELOW_INLET}


def test_cli_writes_a_lut_and_refuses_bad_input(tmp_path):
    runner = CliRunner()
    out = tmp_path / "w.nc"
    res = runner.invoke(
        app,
        ["bench", "wcc", "-a", "mdot=20,30g/s", "-a", "p_in=1.2MPa", "-a", "T_in=80degC"]
        + ["-a", "T_coolant_in=30,40degC", "-a", "mdot_coolant=0.2", "-o", str(out)],
    )
    assert res.exit_code == 0, res.output
    assert "wcc: 4 points, 0 invalid" in res.stdout
    import xarray as xr

    with xr.open_dataset(out) as ds:
        assert (ds["Q"].values > 0).all()
    bad = tmp_path / "bad"
    bad.mkdir()
    res = runner.invoke(app, ["bench", "wcc", "--axis", "T_coolant_in=500K", "-o", str(bad / "x.nc")])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "T_coolant_in" in lines[0]
    assert list(bad.iterdir()) == []


# --- the compiled solve ------------------------------------------------------------------------

#: Outputs of solve_wcc that are masks (compared exactly; outside_range on valid points only, where
#: the invalid points' zone fractions differ: 0 in the array solve, inf in the kernel).
_MASKS = (
    "inlet_subcooled",
    "supercritical",
    "not_below_inlet",
    "bad_dp",
    "bad_flow",
    "coolant_freezes",
    "coolant_outside",
    "bad_props",
)


@pytest.fixture(scope="module")
def compiled_and_references(fluid, params):
    """The compiled solve and solve_wcc on the same tables and on CoolProp, at 400 points over and
    beyond the envelope (tiny flows, two-phase and subcooled inlets, coolant warmer than saturation)."""
    from evtms._jit import numba_enabled
    from evtms.benches.wcc import solve_wcc_compiled
    from evtms.fluid_tables_dome import DomeTabulatedFluid

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set): only the array path exists")
    rng = np.random.default_rng(3)
    n = 400
    args = (
        np.exp(rng.uniform(np.log(5e5), np.log(3.4e6), n)),
        rng.uniform(300e3, 540e3, n),
        np.exp(rng.uniform(np.log(1e-4), np.log(0.2), n)),
        np.exp(rng.uniform(np.log(0.03), np.log(0.5), n)),
        rng.uniform(260.0, 350.0, n),
    )
    hx = params.wcc
    return (
        solve_wcc_compiled(fluid, hx, *args),
        solve_wcc(DomeTabulatedFluid(fluid), hx, *args),
        solve_wcc(fluid, hx, *args),
    )


def _valid(res):
    return ~np.any([res[k] for k in _MASKS], axis=0)


def test_compiled_wcc_is_the_array_solve_on_the_same_tables(compiled_and_references):
    compiled, tabulated, _ = compiled_and_references
    for key in _MASKS:
        np.testing.assert_array_equal(compiled[key], tabulated[key], err_msg=key)
    valid = _valid(tabulated)
    assert 0.5 < valid.mean() < 0.9  # valid points and several kinds of invalid one
    assert compiled["inlet_subcooled"].any() and compiled["not_below_inlet"].any()
    np.testing.assert_array_equal(compiled["outside_range"][valid], tabulated["outside_range"][valid])
    for key, value in tabulated.items():
        if key not in (*_MASKS, "outside_range"):
            np.testing.assert_allclose(compiled[key][valid], value[valid], rtol=1e-9, atol=0.0, err_msg=key)


def test_compiled_wcc_is_coolprop_within_the_tables_tolerance(compiled_and_references):
    compiled, _, coolprop = compiled_and_references
    valid = _valid(coolprop)
    np.testing.assert_array_equal(_valid(compiled), valid)
    for key in ("Q", "h_out", "dp", "h_out_continued", "T_coolant_out", "UA", "capacity_ratio"):
        np.testing.assert_allclose(compiled[key][valid], coolprop[key][valid], rtol=1e-4, atol=0.0, err_msg=key)
    np.testing.assert_allclose(compiled["T_out"][valid], coolprop["T_out"][valid], rtol=0.0, atol=2e-3)


def test_compiled_wcc_hands_states_beyond_its_tables_to_coolprop(fluid, params):
    """Between the tables' top (90 % of the critical pressure) and the critical pressure the
    compiled solve gives CoolProp's answer; at and above the critical pressure both refuse."""
    from evtms._jit import numba_enabled
    from evtms.benches.wcc import solve_wcc_compiled

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set): only the array path exists")
    p = np.array([0.95 * fluid.p_crit, 1.01 * fluid.p_crit, 1.2e6])
    h, m, m_c, T_c = np.array([440e3, 460e3, 440e3]), np.full(3, 0.03), np.full(3, 0.2), np.full(3, 303.15)
    got = solve_wcc_compiled(fluid, params.wcc, p, h, m, m_c, T_c)
    ref = solve_wcc(fluid, params.wcc, p, h, m, m_c, T_c)
    assert np.isfinite(ref["Q"][0]) and ref["Q"][0] > 0 and not ref["bad_props"][0]  # CoolProp has the state
    for key, value in ref.items():
        np.testing.assert_allclose(got[key][:2], value[:2], rtol=1e-12, err_msg=key)
    assert got["supercritical"][1] and not got["supercritical"][0]
    np.testing.assert_allclose(got["Q"][2], ref["Q"][2], rtol=1e-4)
