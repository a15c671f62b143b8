"""Heat-exchanger core (evtms.hx): plate correlations against published values, the counter-flow
moving-boundary core against analytic effectiveness-NTU, and the coolant tables against CoolProp."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from evtms.fluid import coolant
from evtms.hx import plate
from evtms.hx.counterflow import RefrigerantPath, solve_counterflow_evaporator
from evtms.hx.effectiveness import counterflow_effectiveness
from evtms.hx.sides import CoolantSide

# --- correlations -------------------------------------------------------------------------


def test_martin_matches_published_example():
    # Martin (1996) as implemented in Caleb Bell's ht (Nu_plate_Martin, friction_plate_Martin_1999):
    # Nu(Re 2000, Pr 0.7, 45 deg) = 30.4276, xi(Re 20000, 45 deg) = 0.781892; the small
    # difference is ht's 1999 variant of the straight-channel factors.
    assert plate.martin_nusselt(2000.0, 0.7, 45.0) == pytest.approx(30.4276, rel=1e-3)
    assert plate.martin_friction_factor(20000.0, 45.0) == pytest.approx(0.781892, rel=1e-3)


def test_martin_limits_of_the_chevron_angle():
    # phi -> 0: straight channels along the flow, xi -> xi_0 (64/Re laminar);
    # phi -> 90 deg: flow across the corrugations, xi -> 3.8 xi_1 (Martin 1996, eq. 22).
    Re = np.array([100.0, 1000.0])
    assert plate.martin_friction_factor(Re, 1e-7) == pytest.approx(64.0 / Re, rel=1e-6)
    assert plate.martin_friction_factor(Re, 90.0 - 1e-7) == pytest.approx(3.8 * (597.0 / Re + 3.85), rel=1e-5)


def test_martin_nusselt_grows_with_reynolds_and_angle():
    Re = np.geomspace(50, 1e4, 30)
    assert np.all(np.diff(plate.martin_nusselt(Re, 20.0, 60.0)) > 0)
    assert plate.martin_nusselt(1000.0, 5.0, 60.0) > plate.martin_nusselt(1000.0, 5.0, 30.0)


def test_yan_lin_matches_published_example_and_heat_flux_exponent():
    # ht's h_boiling_Yan_Lin example (m 3e-5 kg/s through 3e-4 m2, x 0.4, ...) = 318.7228565961241.
    args = dict(x=0.4, G=3e-5 / 3e-4, D_h=0.002, h_lv=9e5, mu_l=156e-6, rho_l=567.0, rho_v=18.09, k_l=0.086)
    Pr_l = 2200.0 * 156e-6 / 0.086
    h = plate.yan_lin_boiling_htc(q=1e5, Pr_l=Pr_l, **args)
    assert h == pytest.approx(318.7228565961241, rel=1e-12)
    assert plate.yan_lin_boiling_htc(q=2e5, Pr_l=Pr_l, **args) / h == pytest.approx(2.0**0.3, rel=1e-12)


def test_correlation_range_flags():
    assert plate.martin_outside_range(np.array([100.0, 500.0, 2e4]), 60.0).tolist() == [True, False, True]
    assert plate.martin_outside_range(np.array([500.0]), 85.0).tolist() == [True]
    assert plate.yan_lin_outside_range(np.array([1000.0, 5000.0, 2e4])).tolist() == [True, False, True]


def test_yan_lin_friction_branches_meet_at_6000():
    lo = plate.yan_lin_friction_factor(6000.0 - 1e-6, 1000.0)
    hi = plate.yan_lin_friction_factor(6000.0, 1000.0)
    assert lo == pytest.approx(hi, rel=0.05)  # the published fits meet within 5 %


def test_yan_lin_friction_below_its_data_is_laminar_and_meets_the_fit_at_2000():
    """Below Re_eq 2000 the factor goes as 1/Re_eq at a fixed quality (Re_eq / Re fixed), so the
    frictional drop f G^2 falls in proportion to the flow, and it is the fit's at the range's end."""
    ratio = 8.0  # Re_eq / Re at one quality
    at_end = plate.yan_lin_friction_factor(2000.0, 2000.0 / ratio)
    assert plate.yan_lin_friction_factor(2000.0 * (1 - 1e-12), 2000.0 * (1 - 1e-12) / ratio) == pytest.approx(at_end)
    assert plate.yan_lin_friction_factor(3000.0, 3000.0 / ratio) == pytest.approx(
        6.947e5 * 3000.0**-1.109 * (3000.0 / ratio) ** -0.5, rel=1e-14
    )  # inside the data: the published fit
    for scale in (0.5, 0.1, 0.01):
        f = plate.yan_lin_friction_factor(2000.0 * scale, 2000.0 * scale / ratio)
        assert f == pytest.approx(at_end / scale, rel=1e-12)
        # the drop ~ f G^2 against the fit continued, which keeps it nearly flat in G (G^0.39)
        continued = 6.947e5 * (2000.0 * scale) ** -1.109 * (2000.0 * scale / ratio) ** -0.5
        assert f * scale**2 < continued * scale**2 and f * scale**2 == pytest.approx(at_end * scale)


# --- the counter-flow core against analytic effectiveness-NTU ----------------------------------


@dataclass
class LinearStream:
    """A secondary stream of constant heat capacity: h = cp (T - 273.15)."""

    mdot: np.ndarray
    T_in: np.ndarray
    R: np.ndarray
    cp: float = 3500.0

    @property
    def h_in(self) -> np.ndarray:
        return self.cp * (self.T_in - 273.15)

    def temperature(self, h):
        return 273.15 + np.asarray(h) / self.cp

    def capacity_rate(self):
        return self.mdot * self.cp


def _path(n, h_in, T_in, T_sat, h_l, h_v, h_at_secondary, R):
    full = lambda v: np.full(n, float(v))  # noqa: E731
    return RefrigerantPath(
        mdot=full(0.03),
        h_in=full(h_in),
        T_in=full(T_in),
        T_sat=full(T_sat),
        h_l=full(h_l),
        h_v=full(h_v),
        h_at_secondary=full(h_at_secondary),
        R=np.tile(R, (n, 1)).astype(float),
    )


def test_two_phase_core_is_one_minus_exp_minus_ntu():
    # A refrigerant that stays two-phase (C_r infinite): Q = C_s (1 - exp(-NTU)) (T_s,in - T_sat).
    n = 5
    R_total = np.array([1 / 50, 1 / 150, 1 / 300, 1 / 600, 1 / 1500])  # UA 50..1500 W/K
    ref = _path(n, 250e3, 275.0, 275.0, 200e3, 5e6, 5.1e6, [1.0, 0.0, 1.0])
    ref.R[:, 1] = R_total / 2
    sec = LinearStream(mdot=np.full(n, 0.15), T_in=np.full(n, 303.15), R=R_total / 2)
    res = solve_counterflow_evaporator(ref, sec)
    C = 0.15 * 3500.0
    expected = C * -np.expm1(-(1 / R_total) / C) * (303.15 - 275.0)
    np.testing.assert_allclose(res.Q, expected, rtol=1e-10)
    np.testing.assert_allclose(res.fractions[:, 1], 1.0, rtol=1e-10)


@pytest.mark.parametrize("m_s", [0.006, 0.01, 0.02, 0.05])  # C_r = C_min/C_max from 0.86 through 1 to 0.34
def test_single_phase_core_is_counterflow_effectiveness(m_s):
    # Superheated vapour (cp 1000 J/(kg K), 0.03 kg/s: 30 W/K) against a stream of 3500 m_s W/K:
    # Q = eps(NTU, C_r) C_min (T_s,in - T_in), Incropera eq. 11.29b.
    cp_r, T_in, T_s = 1000.0, 280.0, 320.0
    UA = np.array([5.0, 30.0, 100.0])
    n = UA.size
    ref = _path(n, 400e3, T_in, 270.0, 200e3, 390e3, 400e3 + cp_r * (T_s - T_in), [1.0, 1.0, 0.0])
    ref.R[:, 2] = 0.5 / UA
    sec = LinearStream(mdot=np.full(n, m_s), T_in=np.full(n, T_s), R=0.5 / UA)
    res = solve_counterflow_evaporator(ref, sec)
    C_r, C_s = 0.03 * cp_r, m_s * 3500.0
    C_min, C_max = min(C_r, C_s), max(C_r, C_s)
    expected = counterflow_effectiveness(UA / C_min, C_min / C_max) * C_min * (T_s - T_in)
    np.testing.assert_allclose(res.Q, expected, rtol=1e-9)
    # Energy balance of both streams to round-off, and the second law.
    np.testing.assert_allclose(0.03 * (res.h_out - 400e3), m_s * (sec.h_in - res.h_secondary_out), rtol=1e-13)
    assert np.all(res.T_secondary_out >= T_in) and np.all(ref.h_in + res.Q / 0.03 <= ref.h_at_secondary)


def test_counterflow_effectiveness_limits():
    assert counterflow_effectiveness(1e-9, 0.5) == pytest.approx(1e-9, rel=1e-6)
    assert counterflow_effectiveness(50.0, 0.5) == pytest.approx(1.0, abs=1e-9)
    assert counterflow_effectiveness(3.0, 1.0) == pytest.approx(0.75)  # NTU / (1 + NTU)
    assert counterflow_effectiveness(3.0, 0.0) == pytest.approx(1 - np.exp(-3.0))
    assert counterflow_effectiveness(3.0, 1.0 - 1e-6) == pytest.approx(0.75, rel=1e-5)  # continuous at C_r = 1


def test_core_refuses_a_secondary_not_warmer_and_pinches_at_the_second_law():
    ref = _path(3, 250e3, 275.0, 275.0, 200e3, 400e3, 410e3, [1e-3, 1e-3, 1e-3])
    sec = LinearStream(mdot=np.array([0.15, 0.15, 1e-3]), T_in=np.array([270.0, 275.0, 300.0]), R=np.full(3, 1e-4))
    res = solve_counterflow_evaporator(ref, sec)
    assert res.bad_direction.tolist() == [True, True, False]
    assert res.Q[:2].tolist() == [0.0, 0.0]
    # A tiny coolant flow over a huge area: the coolant leaves at (just above) the refrigerant temperature.
    assert res.T_secondary_out[2] == pytest.approx(275.0, abs=1e-3) and res.T_secondary_out[2] > 275.0


def test_coolant_side_capacity_rate():
    c = coolant()
    side = CoolantSide(c, np.array([0.1]), np.array([303.15]), np.array([0.0]))
    assert side.capacity_rate()[0] == pytest.approx(0.1 * c.properties(303.15)["CP"])
    assert side.temperature(side.h_in)[0] == pytest.approx(303.15, abs=1e-9)


# --- coolant properties ---------------------------------------------------------------------


def test_coolant_tables_match_coolprop_and_invert_exactly():
    import CoolProp.CoolProp as CP

    c = coolant()
    st = CP.AbstractState("INCOMP", "MEG")
    st.set_mass_fractions([0.5])
    T = np.array([240.0, 273.15, 303.157, 350.0])
    ref = []
    for t in T:
        st.update(CP.PT_INPUTS, c.p, float(t))
        ref.append((st.hmass(), st.cpmass(), st.viscosity()))
    ref = np.array(ref)
    np.testing.assert_allclose(c.enthalpy(T), ref[:, 0], atol=0.05)  # J/kg
    props = c.properties(T)
    np.testing.assert_allclose(props["CP"], ref[:, 1], rtol=1e-5)
    np.testing.assert_allclose(props["MU"], ref[:, 2], rtol=1e-3)
    np.testing.assert_allclose(c.temperature(c.enthalpy(T)), T, rtol=1e-14)
    # MEG 50 % freezes at about -34 degC (CoolProp's fit: 237.16 K).
    assert c.T_freeze == pytest.approx(237.16, abs=0.05)
    # Below freezing the enthalpy is continued (finite, increasing) for the caller to flag.
    below = c.enthalpy(np.array([220.0, 230.0]))
    assert np.all(np.isfinite(below)) and below[0] < below[1] < c.enthalpy(c.T_freeze)


# --- one coolant side, two cores -------------------------------------------------------------


def test_coolant_side_on_both_cores_gives_the_two_phase_limit(fluid):
    # Refrigerant that stays two-phase against MEG 50 %: in every flow arrangement
    # Q = C_c (1 - exp(-UA/C_c)) (T_c,in - T_sat). The cross-flow core (constant heat
    # capacity of the coolant at its inlet) meets it to round-off, and so does the
    # counter-flow core on a stream of that constant heat capacity; on the coolant's
    # tabulated enthalpy (its heat capacity falls by about 2 % over a 20 K span) within 1 %.
    from evtms.hx.crossflow import TubeSide, march_crossflow

    class ConstantBoiling(TubeSide):
        def boiling_htc(self, G, sat, q):
            return np.full(G.shape, 2000.0)

    tubes = ConstantBoiling(D_h=1e-3, flow_area=1e-4, length=0.5, area=0.2, roughness=0.0, nu_laminar=3.66, R_wall=1e-4)
    n = 3
    p = np.full(n, float(fluid.saturation_pressure(274.15)))
    h_in, mdot = np.full(n, 250e3), np.full(n, 0.1)
    side = CoolantSide(coolant(), np.array([0.05, 0.1, 0.2]), np.full(n, 303.15), np.full(n, 2e-3))
    res = march_crossflow(fluid, tubes, side, p, h_in, mdot, "evaporator")
    sat = fluid.saturation(p)
    R_tp = tubes.R_wall + 1.0 / (2000.0 * tubes.area)
    UA = 1.0 / (side.R + R_tp)
    expected = side.C * -np.expm1(-UA / side.C) * (303.15 - sat["T"])
    np.testing.assert_allclose(res.Q, expected, rtol=1e-12)
    assert np.all(res.h_out < sat["h_v"])  # still two-phase

    path = RefrigerantPath(
        mdot=mdot,
        h_in=h_in,
        T_in=sat["T"],
        T_sat=sat["T"],
        h_l=sat["h_l"],
        h_v=sat["h_v"],
        h_at_secondary=fluid.state("PT", p, side.T_in, ("H",))["H"],
        R=np.stack([np.full(n, R_tp)] * 3, axis=1),
    )
    counter = solve_counterflow_evaporator(path, side)
    np.testing.assert_allclose(counter.Q, expected, rtol=1e-2)
    cp_in = side.C / side.mdot
    constant = LinearStream(mdot=side.mdot, T_in=side.T_in, R=side.R, cp=cp_in)
    np.testing.assert_allclose(solve_counterflow_evaporator(path, constant).Q, expected, rtol=1e-10)


#: Random inputs per bench over its cycle envelope and beyond: flows from a pinch to 150 g/s,
#: wet and superheated outlets, vapour inlets, secondary streams on the wrong side.
_KERNEL_CASES = {
    "chiller": lambda rng, n: {
        "mdot": np.exp(rng.uniform(np.log(3e-4), np.log(0.15), n)),
        "p_in": rng.uniform(0.6e5, 7.5e5, n),
        "h_in": rng.uniform(180e3, 420e3, n),
        "mdot_coolant": rng.uniform(0.03, 0.5, n),
        "T_coolant_in": rng.uniform(260.0, 330.0, n),
    },
    "evaporator": lambda rng, n: {
        "mdot": np.exp(rng.uniform(np.log(1e-3), np.log(0.15), n)),
        "blower": rng.uniform(0.05, 1.0, n),
        "p_in": rng.uniform(0.8e5, 9e5, n),
        "h_in": rng.uniform(180e3, 420e3, n),
        "T_air_in": rng.choice([283.15, 298.15, 313.15], n),
        "RH_air_in": rng.choice([0.0, 0.2, 0.5, 0.8], n),  # 0: no dew point in the table
    },
    "condenser": lambda rng, n: {
        "mdot": np.exp(rng.uniform(np.log(1e-3), np.log(0.15), n)),
        "fan": rng.uniform(0.05, 1.0, n),
        "p_in": rng.uniform(4e5, 30e5, n),
        "h_in": rng.uniform(380e3, 480e3, n),
        "T_air_in": rng.choice([263.15, 298.15, 318.15], n),
        "RH_air_in": np.full(n, 0.4),
    },
}


@pytest.mark.parametrize("name", sorted(_KERNEL_CASES))
def test_compiled_searches_equal_the_array_bisections(name, monkeypatch):
    """The cores' compiled per-point searches (evtms.hx._kernels; the cross-flow one within
    crossflow.per_point_searches, as the cycle's direct models use it) are the array bisections'
    arithmetic: same statuses, every output equal to round-off."""
    import evtms.hx.counterflow as cf
    import evtms.hx.crossflow as xf
    from evtms.benches import BENCHES, chiller
    from evtms.benches.parameters import Parameters
    from evtms.fluid import Fluid
    from evtms.hx.crossflow import per_point_searches

    if not cf.numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set): only the array path exists")
    monkeypatch.setattr(chiller, "numba_enabled", lambda: False)  # its own compiled solve: test_chiller.py
    inputs = _KERNEL_CASES[name](np.random.default_rng(7), 300)
    bench, params, fluid = BENCHES[name], Parameters(), Fluid()
    with per_point_searches():  # as the cycle's direct models call the benches
        compiled = bench.evaluate({k: v.copy() for k, v in inputs.items()}, params, fluid)
    for module in (cf, xf):
        monkeypatch.setattr(module, "numba_enabled", lambda: False)
    arrays = bench.evaluate({k: v.copy() for k, v in inputs.items()}, params, fluid)
    np.testing.assert_array_equal(compiled["status"], arrays["status"])
    assert len(set(compiled["status"].tolist())) >= 3  # valid, outside a range, wrong side, ...
    for key, value in arrays.items():
        # Q_latent: a small difference of large enthalpy flows, so a few ulp of them relative to it.
        rtol = 1e-11 if key == "Q_latent" else 1e-12
        np.testing.assert_allclose(compiled[key], value, rtol=rtol, atol=0.0, equal_nan=True, err_msg=key)


def test_compiled_plate_correlations_equal_the_array_ones():
    """The scalar twins of evtms.hx.plate (evtms.hx._plate_kernels, the compiled chiller's) give the
    array functions' numbers on both sides of every branch, NaN where they give NaN."""
    from evtms.hx import _plate_kernels as pk

    rng = np.random.default_rng(3)
    Re = np.concatenate([np.exp(rng.uniform(np.log(1.0), np.log(3e4), 200)), [2000.0, 6000.0, np.nan, 0.0]])
    Pr = rng.uniform(0.7, 60.0, Re.size)
    for angle in (30.0, 60.0, 85.0):
        xi = plate.martin_friction_factor(Re, angle)
        nu = plate.martin_nusselt(Re, Pr, angle)
        out = plate.martin_outside_range(Re, angle)
        for i in range(Re.size):
            np.testing.assert_allclose(pk.martin_friction_factor(Re[i], angle), xi[i], rtol=1e-14, equal_nan=True)
            np.testing.assert_allclose(pk.martin_nusselt(Re[i], Pr[i], angle), nu[i], rtol=1e-14, equal_nan=True)
            assert pk.martin_outside_range(Re[i], angle) == out[i]
    Re_eq = 3.0 * Re
    f = plate.yan_lin_friction_factor(Re_eq, Re)
    x, G, q = rng.uniform(0, 1, Re.size), rng.uniform(5, 200, Re.size), rng.uniform(1e2, 3e4, Re.size)
    h = plate.yan_lin_boiling_htc(x, G, 0.003, q, 1.9e5, 2.5e-4, 1290.0, 14.0, 0.09, 3.5)
    out = plate.yan_lin_outside_range(Re_eq)
    for i in range(Re.size):
        np.testing.assert_allclose(pk.yan_lin_friction_factor(Re_eq[i], Re[i]), f[i], rtol=1e-14, equal_nan=True)
        got = pk.yan_lin_boiling_htc(x[i], G[i], 0.003, q[i], 1.9e5, 2.5e-4, 1290.0, 14.0, 0.09, 3.5)
        np.testing.assert_allclose(got, h[i], rtol=1e-14)
        assert pk.yan_lin_outside_range(Re_eq[i]) == out[i]


def test_bucket_table_interpolates_as_numpy():
    """The compiled cores' table look-up (evtms.hx._counterflow_kernels.table_interp) is np.interp
    with NaN outside: at the nodes, both ends, between, beyond and at NaN, to the last bit."""
    from evtms.hx._counterflow_kernels import bucket_table, table_interp

    c = coolant()
    rng = np.random.default_rng(5)
    for xp, fp in ((c.h, c.T), (c.T, c.h)):
        table = bucket_table(xp, fp)
        x = np.concatenate(
            [rng.uniform(xp[0] - 0.01 * np.ptp(xp), xp[-1] + 0.01 * np.ptp(xp), 2000), xp[::97], xp[[0, -1]]]
        )
        x = np.concatenate([x, np.nextafter(xp[[0, -1]], [-np.inf, np.inf]), [np.nan]])
        want = np.interp(x, xp, fp, left=np.nan, right=np.nan)
        got = np.array([table_interp(v, table) for v in x])
        np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError, match="strictly rising"):
        bucket_table(np.array([0.0, 1.0, 1.0]), np.zeros(3))
