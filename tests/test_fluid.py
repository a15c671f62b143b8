"""The fluid layer: agreement with CoolProp's high-level API, NaN on bad states."""

from __future__ import annotations

import numpy as np
import pytest
from CoolProp.CoolProp import PropsSI

from evtms.benches import BENCHES
from evtms.benches.grid import build_grid
from evtms.benches.sweep import run_sweep
from evtms.fluid import Fluid, SaturatedAir, humid_air_temperature, quality


def test_states_match_propssi_and_keep_shape(fluid):
    p = np.array([[0.3e6, 1.0e6], [1.0e6, 0.3e6]])  # repeated pairs exercise the de-duplication
    T = np.array([[280.0, 340.0], [340.0, 280.0]])
    out = fluid.state("PT", p, T, ("H", "D", "MU", "K", "CP"))
    assert out["H"].shape == (2, 2)
    for key, name in (("H", "H"), ("D", "D"), ("MU", "V"), ("K", "L"), ("CP", "C")):
        ref = PropsSI(name, "P", p.ravel(), "T", T.ravel(), "R134a").reshape(2, 2)
        np.testing.assert_allclose(out[key], ref, rtol=1e-10)


def test_failed_states_are_nan_not_exceptions(fluid):
    out = fluid.state("PT", [1e6, 1e6, 1e6, -5.0, np.nan], [340.0, 2000.0, 100.0, 300.0, 300.0], ("H", "T"))
    assert np.isfinite(out["H"][0])
    assert np.isnan(out["H"][1:]).all()  # above T_max, below T_triple, negative p, NaN input
    sat = fluid.saturation([1e6, 5e6, 100.0])
    assert np.isfinite(sat["T"][0]) and np.isnan(sat["T"][1:]).all()


def test_saturation_and_quality(fluid):
    sat = fluid.saturation(1e6)
    assert float(sat["T"]) == pytest.approx(PropsSI("T", "P", 1e6, "Q", 0, "R134a"), rel=1e-10)
    h_mid = 0.5 * (sat["h_l"] + sat["h_v"])
    assert float(quality(h_mid, sat["h_l"], sat["h_v"])) == pytest.approx(0.5)
    assert fluid.saturation_pressure(fluid.T_crit + 1) != fluid.saturation_pressure(fluid.T_crit + 1)  # NaN


def test_saturated_air_table_matches_haprops():
    from CoolProp.CoolProp import HAPropsSI

    air = SaturatedAir(101325.0)
    T = np.array([250.3, 273.2, 288.77, 305.01])
    ref = np.array([HAPropsSI("H", "T", t, "P", 101325.0, "R", 1.0) for t in T])
    np.testing.assert_allclose(air.enthalpy(T), ref, atol=2.0)  # J/kg, linear interpolation at 0.05 K
    np.testing.assert_allclose(air.temperature(air.enthalpy(T)), T, atol=1e-9)
    h = HAPropsSI("H", "T", 300.0, "P", 101325.0, "W", 0.01)
    assert float(humid_air_temperature(h, 0.01, 101325.0)) == pytest.approx(300.0, abs=1e-6)


def test_tabular_backend_within_half_a_percent_of_heos(thesis, params):
    """BICUBIC&HEOS builds its tables on first use (about 5 s, cached on disk)."""
    tab = Fluid(backend="BICUBIC&HEOS")
    bench = BENCHES["condenser"]
    ds = run_sweep(bench, build_grid(bench, "thesis", {}), params, fluid=tab)
    ref = thesis("condenser")
    np.testing.assert_array_equal(ds["status"].values, ref["status"].values)  # the same (valid) statuses
    assert np.isin(ds["status"].values, bench.valid_flags).all()
    np.testing.assert_allclose(ds["Q"].values, ref["Q"].values, rtol=5e-3)
    np.testing.assert_allclose(ds["T_out"].values, ref["T_out"].values, atol=0.05)


def test_vapour_table_matches_coolprop(fluid):
    from evtms.fluid import VapourTable

    table = VapourTable(fluid)
    rng = np.random.default_rng(4)
    p = np.exp(rng.uniform(np.log(3e4), np.log(3e6), 400))
    superheat = rng.uniform(0.01, 99.0, 400)
    T_sat, h_v = table.saturation(p)
    sat = fluid.saturation(p)
    assert np.abs(T_sat - sat["T"]).max() < 1e-3
    assert np.abs(h_v - sat["h_v"]).max() < 5.0
    h = fluid.state("PT", p, sat["T"] + superheat, ("H",))["H"]
    # Documented: within about 5 J/kg of CoolProp over the table.
    assert np.abs(h_v + table.enthalpy_above_saturation(p, superheat) - h).max() < 6.0
    # Clipped in superheat, NaN outside the pressures; a cached copy answers the same.
    assert table.enthalpy_above_saturation(p[:3], -5.0) == pytest.approx(0.0)
    assert np.isnan(table.saturation(np.array([1e3, 5e6]))[0]).all()
    # rise_to is the two lookups from one pressure cell.
    T_sec = sat["T"] + superheat - 3.0
    h_v_at, rise = table.rise_to(p, T_sec, 0.5)
    assert np.array_equal(h_v_at, h_v)
    assert np.allclose(rise, table.enthalpy_above_saturation(p, np.maximum(T_sec - T_sat, 0.5)), rtol=1e-12, atol=1e-9)
    copy = VapourTable.from_tables(table.tables())
    assert copy.digest() == table.digest()
    assert np.array_equal(copy.enthalpy_above_saturation(p, superheat), table.enthalpy_above_saturation(p, superheat))


def test_single_phase_ph_newton_matches_the_flash(fluid, monkeypatch):
    """(p, h) states solved by Newton on (p, T) equal CoolProp's own (p, h) flash: every output,
    the NaN pattern, and the two-phase, near-saturation, near-critical and out-of-range states
    the Newton path leaves to the flash."""
    import evtms.fluid as fluid_module

    curve = fluid.saturation_curve()
    rng = np.random.default_rng(7)
    n = 3000
    p = np.exp(rng.uniform(np.log(2e4), np.log(4.5e6), n))
    h_l, h_v = curve.liquid_enthalpy(p), curve.vapour_enthalpy(p)
    kind = rng.integers(0, 4, n)
    h = np.select(
        [kind == 0, kind == 1, kind == 2],
        [h_v + rng.uniform(0.0, 1.5e5, n), h_l - rng.uniform(0.0, 1.5e5, n), h_v + rng.uniform(-300, 300, n)],
        default=h_l + rng.uniform(-2e4, 2e4, n),
    )
    h = np.where(np.isfinite(h), h, rng.uniform(2e5, 5e5, n))  # above the critical pressure
    p[:3], h[:3] = (-1.0, np.nan, 3e5), (3e5, 3e5, np.nan)  # invalid inputs stay NaN
    outputs = ("T", "D", "H", "CP", "MU", "K", "Q", "S")
    # Hotter than the equation of state allows (T_max, 455 K) and colder than the triple point:
    # the flash refuses some of these; without "T" among the outputs the Newton path must too.
    T_out = np.r_[rng.uniform(440.0, 700.0, 300), rng.uniform(150.0, 175.0, 300)]
    p_out = rng.uniform(1e5, 3e6, 600)
    h_out = fluid.state("PT", p_out, np.clip(T_out, 170.0, 455.0), ("H",))["H"] + np.where(T_out > 300, 2e5, -2e4)
    p, h = np.r_[p, p_out], np.r_[h, h_out]
    fast = fluid.state("PH", p, h, outputs)
    fast_no_T = fluid.state("PH", p, h, ("D", "S", "CP"))
    calls = []
    no_newton = lambda self, uniq, *a: calls.append(1) or np.zeros(len(uniq), bool)  # noqa: E731
    monkeypatch.setattr(fluid_module.Fluid, "_single_phase_ph", no_newton)
    flash = fluid.state("PH", p, h, outputs)
    flash_no_T = fluid.state("PH", p, h, ("D", "S", "CP"))
    assert calls  # the reference did go through the flash alone
    for a, b in ((fast, flash), (fast_no_T, flash_no_T)):
        for name in b:
            assert np.array_equal(np.isnan(a[name]), np.isnan(b[name])), name
            ok = np.isfinite(b[name])
            np.testing.assert_allclose(a[name][ok], b[name][ok], rtol=2e-7, atol=1e-12, err_msg=name)
    assert np.nanmax(np.abs(fast["T"] - flash["T"])) < 1e-6
    assert np.isnan(fast["T"][:3]).all()
    # No phase is left imposed, even by a flash that failed near the critical point (CoolProp
    # leaves the liquid phase set then): vapour at 1 MPa and 330 K is vapour (44 kg/m3, not 1061).
    assert np.isnan(flash["T"][(p > 0.97 * fluid.p_crit) & (p < fluid.p_crit)]).any()
    assert fluid.state("PT", 1e6, 330.0, ("D",))["D"] < 100.0


def test_single_phase_ph_newton_solves_to_round_off_whatever_the_call(fluid):
    """The states the Newton path takes are solved to the energy balance's round-off (h(p, T) - h
    over cp below 1e-8 K), and a state's result does not depend on the call it came in: alone,
    or among thousands (a sweep gives the same numbers in one process or in many)."""
    import CoolProp.CoolProp as CP

    curve = fluid.saturation_curve()
    rng = np.random.default_rng(8)
    n = 2000
    p = np.exp(rng.uniform(np.log(5e4), np.log(3.5e6), n))
    liquid = rng.random(n) < 0.5
    rise = rng.uniform(1e3, 1e5, n)
    h = np.where(liquid, curve.liquid_enthalpy(p) - rise, curve.vapour_enthalpy(p) + rise)
    values = np.full((1, n), np.nan)
    solved = fluid._single_phase_ph(np.stack([p, h], axis=1), ("T",), [fluid._state.T], values)
    assert solved.mean() > 0.9
    st = CP.AbstractState("HEOS", "R134a")
    for i in np.nonzero(solved)[0][::10]:
        st.update(CP.PT_INPUTS, p[i], values[0, i])
        assert abs((st.hmass() - h[i]) / st.cpmass()) < 1e-8
    together = fluid.state("PH", p, h, ("T", "D"))
    fresh = Fluid()  # its guess table built anew
    for i in range(0, n, 97):
        alone = fresh.state("PH", p[i], h[i], ("T", "D"))
        assert alone["T"] == together["T"][i] and alone["D"] == together["D"][i]


def test_vapour_table_superheat_inverts_the_enthalpy_rise(fluid):
    from evtms.fluid import VapourTable

    table = VapourTable(fluid, n=120, superheat_max=120.0, step=3.0)
    rng = np.random.default_rng(9)
    p = np.exp(rng.uniform(np.log(3e4), np.log(3e6), 500))
    superheat = rng.uniform(0.0, 160.0, 500)  # beyond superheat_max: the linear continuation
    rise = table.enthalpy_above_saturation(p, superheat)
    ok = np.isfinite(rise)  # not beyond the equation of state's highest temperature
    assert ok.mean() > 0.9
    np.testing.assert_allclose(table.superheat_of(p[ok], rise[ok]), superheat[ok], atol=1e-9)
    assert np.isnan(table.superheat_of(np.array([1e3]), np.array([1e4]))).all()


def test_compiled_humid_air_inversion_is_the_numpy_one(monkeypatch):
    # The moist-air table inversion runs compiled per point where numba is enabled: the same
    # arithmetic as the NumPy loop, so the same numbers (a sweep's files do not depend on it).
    from evtms import fluid as fluid_module

    rng = np.random.default_rng(0)
    w = rng.uniform(0.0, 0.03, 500)
    T = rng.uniform(250.0, 330.0, 500)
    h = fluid_module.humid_air_enthalpy(T, w, 101325.0)
    h[:3] = (1e9, -1e9, np.nan)  # beyond the table, and not a number
    fluid_module._compiled_inversion.cache_clear()
    compiled = fluid_module._invert_humid_air_table(h, w, 101325.0)
    monkeypatch.setenv("EVTMS_NO_NUMBA", "1")
    fluid_module._compiled_inversion.cache_clear()
    try:
        reference = fluid_module._invert_humid_air_table(h, w, 101325.0)
    finally:
        fluid_module._compiled_inversion.cache_clear()
    np.testing.assert_array_equal(compiled, reference)
    assert np.isnan(compiled[:3]).all()
    assert np.abs(compiled[3:] - T[3:]).max() < 1e-4


def test_constant_humidity_line_computes_only_where_queries_land():
    # The leaving air of a coil at its inlet humidity is interpolated on a line of HAPropsSI states
    # that is computed block by block: the same temperatures as np.interp on the whole line.
    from evtms import fluid as fluid_module

    w, p = 0.0123, 101325.0
    T_nodes = np.arange(200.0, 460.0 + 0.025, 0.05)
    whole = fluid_module._haprops("H", "T", T_nodes, "W", w, "P", p)
    h = fluid_module.humid_air_enthalpy(np.array([291.3, 300.0, 309.99]), w, p)
    h = np.r_[h, whole[1000], -1e9, np.nan]  # a node, below the line, not a number
    got = humid_air_temperature(h, np.full(h.size, w), p, w_common=w)
    np.testing.assert_array_equal(got, np.interp(h, whole, T_nodes, left=np.nan, right=np.nan))
    line = fluid_module._constant_humidity_line(p, w)
    assert line.done.sum() < line.done.size  # not the whole line
    far = humid_air_temperature(whole[[0, -1]] + np.array([0.0, 1.0]), np.full(2, w), p, w_common=w)
    assert far[0] == 200.0 and np.isnan(far[1])  # the ends: the first node, and beyond the last
