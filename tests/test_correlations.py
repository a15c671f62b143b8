"""Correlations against published forms and hand-computed values, the air-side range flag, trends."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from evtms.benches import correlations as corr
from evtms.benches.coil import coil_geometry
from evtms.fluid import humid_air_inlet

# Default condenser louvred fin (evtms.benches.coil.CoilParams): theta 27 deg, L_p 1 mm, F_p 0.5 mm,
# F_l 9.75 - 2 = 7.75 mm, T_d 15 mm, L_l 6.5 mm, T_p 390 mm / 40 = 9.75 mm, delta_f 0.1 mm.
FIN = corr.LouveredFin(
    louver_angle=math.radians(27.0),
    louver_pitch=1.0e-3,
    louver_length=6.5e-3,
    fin_pitch=0.5e-3,
    fin_length=7.75e-3,
    flow_depth=15e-3,
    tube_pitch=9.75e-3,
    fin_thickness=0.1e-3,
)


def test_coil_geometry_gives_the_louvred_fin_of_the_simscape_condenser(params):
    fin = coil_geometry(params.condenser).fin
    for name in ("louver_angle", "louver_pitch", "louver_length", "fin_pitch", "fin_length", "flow_depth"):
        assert getattr(fin, name) == pytest.approx(getattr(FIN, name), rel=1e-12), name
    assert fin.tube_pitch == pytest.approx(FIN.tube_pitch, rel=1e-12)
    assert fin.fin_thickness == FIN.fin_thickness
    # fin_spacing is the fin pitch: it reproduces the Simscape block's fin area.
    c = params.condenser
    fins = c.n_tubes * c.core_length / c.fin_spacing
    assert fins * 2 * fin.fin_length * fin.flow_depth == pytest.approx(c.area_air_fin, rel=2e-3)
    evap = coil_geometry(params.evaporator).fin
    assert evap.tube_pitch == pytest.approx(0.010) and evap.fin_length == pytest.approx(0.008)


def test_chang_wang_j_hand_computed_at_re_lp_500():
    # Chang and Wang (1997), eq. (9), term by term (calculator):
    # 500^-0.49 = 0.047589, (27/90)^0.27 = 0.722475, 0.5^-0.14 = 1.101905, 7.75^-0.29 = 0.552208,
    # 15^-0.23 = 0.536413, 6.5^0.68 = 3.570928, 9.75^-0.28 = 0.528541, 0.1^-0.05 = 1.122018.
    assert float(corr.chang_wang_j(500.0, FIN)) == pytest.approx(0.0237647, rel=1e-5)


@pytest.mark.parametrize(
    ("field", "exponent"),
    [
        ("louver_angle", 0.27),
        ("fin_pitch", -0.14),
        ("fin_length", -0.29),
        ("flow_depth", -0.23),
        ("louver_length", 0.68),
        ("tube_pitch", -0.28),
        ("fin_thickness", -0.05),
    ],
)
def test_chang_wang_exponents_are_the_published_ones(field, exponent):
    j0 = float(corr.chang_wang_j(300.0, FIN))
    doubled = dataclasses.replace(FIN, **{field: 2.0 * getattr(FIN, field)})
    assert float(corr.chang_wang_j(300.0, doubled)) / j0 == pytest.approx(2.0**exponent, rel=1e-12)


def test_chang_wang_reynolds_exponent_and_louver_pitch_scaling():
    j = corr.chang_wang_j(np.array([150.0, 300.0]), FIN)
    assert j[1] / j[0] == pytest.approx(2.0**-0.49, rel=1e-12)
    # Every length over L_p: scaling all lengths together changes nothing at a given Re_Lp.
    lengths = ("louver_pitch", "louver_length", "fin_pitch", "fin_length", "flow_depth", "tube_pitch", "fin_thickness")
    big = dataclasses.replace(FIN, **{k: 3.0 * getattr(FIN, k) for k in lengths})
    assert float(corr.chang_wang_j(700.0, big)) == pytest.approx(float(corr.chang_wang_j(700.0, FIN)), rel=1e-12)


def test_range_flag_set_exactly_outside_100_to_3000():
    Re = np.array([0.0, 7.0, 99.999, 100.0, 100.001, 1500.0, 2999.999, 3000.0, 3000.001, 1e4])
    expected = [True, True, True, False, False, False, False, False, True, True]
    np.testing.assert_array_equal(corr.chang_wang_outside_range(Re), expected)
    assert corr.CHANG_WANG_RE_RANGE == (100.0, 3000.0)


def test_louvred_fin_htc_is_j_rho_v_cp_pr_minus_two_thirds():
    air = humid_air_inlet(303.15, 101325.0, 0.4)
    V = np.array([0.0, 0.5, 2.0, 8.0])
    h, Re = corr.louvered_fin_htc(V, air["rho"], air["mu"], air["k"], air["Pr"], FIN)
    np.testing.assert_allclose(Re, air["rho"] * V * 1e-3 / air["mu"], rtol=1e-14)
    cp = air["Pr"] * air["k"] / air["mu"]  # per kg of humid air
    expected = corr.chang_wang_j(Re[1:], FIN) * air["rho"] * V[1:] * cp * air["Pr"] ** (-2.0 / 3.0)
    np.testing.assert_allclose(h[1:], expected, rtol=1e-12)
    assert h[0] == 0.0  # no flow, no convection (not NaN)
    assert cp == pytest.approx(air["cp"] / (1.0 + air["w"]), rel=1e-6)  # HAPropsSI's cp per kg dry air / (1 + w)


def test_air_side_htc_rises_with_fan_speed(params):
    """Higher fan speed, higher h: h goes with V^0.51 (j with Re_Lp^-0.49)."""
    for coil in (params.condenser, params.evaporator):
        fin = coil_geometry(coil).fin
        air = humid_air_inlet(303.15, 101325.0, 0.4)
        fan = np.array([0.05, 0.1, 0.2, 0.33, 0.5, 0.75, 1.0])
        h, Re = corr.louvered_fin_htc(
            fan * coil.fan_flow_max / coil.area_air_free, air["rho"], air["mu"], air["k"], air["Pr"], fin
        )
        assert (np.diff(h) > 0).all()
        np.testing.assert_allclose(h / h[-1], fan**0.51, rtol=1e-12)
        # The Simscape coils' air flows: Re_Lp about 7-8 at fan 0.05, 140-160 at fan 1.
        assert 5.0 < Re[0] < 20.0 and 100.0 < Re[-1] < 170.0


def test_haaland_against_colebrook_and_laminar():
    # Smooth tube, Re 1e5: Haaland 0.017825 (hand), Colebrook (iterated) 0.017990.
    f = corr.haaland_friction_factor(np.array([1e5]), 0.0)
    assert float(f[0]) == pytest.approx(0.017825, rel=1e-4)
    assert float(f[0]) == pytest.approx(0.017990, rel=0.02)
    np.testing.assert_allclose(corr.haaland_friction_factor(np.array([500.0, 2000.0]), 1e-3), [0.128, 0.032])
    # Blend: halfway between laminar and Haaland at Re 3150.
    lam, turb = 64.0 / 3150.0, (-1.8 * math.log10((1e-3 / 3.7) ** 1.11 + 6.9 / 4000.0)) ** -2
    assert float(corr.haaland_friction_factor(np.array([3150.0]), 1e-3)[0]) == pytest.approx(0.5 * (lam + turb))


def test_gnielinski_hand_computed():
    # Re 1e4, Pr 0.7, Petukhov f = (0.790 ln Re - 1.64)^-2 = 0.031480:
    # Nu = (f/8)(Re - 1000) Pr / (1 + 12.7 (f/8)^0.5 (Pr^(2/3) - 1)) = 29.817 (Incropera eq. 8.62).
    nu = corr.single_phase_nusselt(np.array([1e4]), 0.7, np.array([0.0314798]), 3.66)
    assert float(nu[0]) == pytest.approx(29.817, rel=1e-4)
    # Laminar below Re 2300; never below the laminar value in the blend.
    nu = corr.single_phase_nusselt(np.array([1000.0, 2300.0, 3000.0]), 3.0, np.array([0.064, 0.028, 0.043]), 3.66)
    assert nu[0] == nu[1] == 3.66 and nu[2] >= 3.66


def test_hagen_poiseuille_gradient():
    # Laminar (Re = 1863): dp/dz = 32 mu V / D^2 = 32 mu G / (rho D^2) = 1347.5 Pa/m.
    grad = corr.single_phase_gradient(np.array([300.0]), 1e-3, 0.0, np.array([1.61e-4]), np.array([1147.0]))
    assert float(grad[0]) == pytest.approx(32 * 1.61e-4 * 300.0 / (1147.0 * 1e-6), rel=1e-12)


# R134a-like saturated properties near 40 degC, as plain inputs.
RHO_L, RHO_V, MU_L, MU_V, K_L, CP_L, H_FG = 1147.0, 50.1, 1.61e-4, 1.25e-5, 0.0748, 1498.0, 163e3
PR_L = CP_L * MU_L / K_L  # 3.2243


def test_cavallini_zecchin_hand_computed():
    # G 200, x 0.5, D 1 mm: Re_v 8000, Re_l 621.1, Re_eq = 8000 (mu_v/mu_l)(rho_l/rho_v)^0.5 + Re_l = 3593.0,
    # Nu = 0.05 Re_eq^0.8 Pr_l^0.33 = 51.419.
    nu = corr.cavallini_zecchin_nusselt(0.5, 200.0, 1e-3, MU_L, MU_V, RHO_L, RHO_V, PR_L, 3.66)
    assert float(nu) == pytest.approx(51.419, rel=1e-4)
    # All vapour-free liquid at low flux: laminar floor.
    assert float(corr.cavallini_zecchin_nusselt(0.0, 1.0, 1e-3, MU_L, MU_V, RHO_L, RHO_V, PR_L, 3.66)) == 3.66


def test_gungor_winterton_hand_computed():
    # G 600, x 0.5, q 10 kW/m2: Re_l 1863.4, h_l (Dittus-Boelter) 1135.64 W/(m2 K), Bo 1.0225e-4,
    # E = 1 + 3000 Bo^0.86 + 1.12 (x/(1-x))^0.75 (rho_l/rho_v)^0.41 = 6.1533, h = 6987.9 W/(m2 K).
    h = corr.gungor_winterton_htc(0.5, 600.0, 1e-3, 1e4, H_FG, MU_L, RHO_L, RHO_V, K_L, PR_L, 3.66)
    assert float(h) == pytest.approx(6987.9, rel=1e-4)
    # Boiling enhances: more heat flux or more vapour, higher h.
    h_q = corr.gungor_winterton_htc(0.5, 600.0, 1e-3, 2e4, H_FG, MU_L, RHO_L, RHO_V, K_L, PR_L, 3.66)
    h_x = corr.gungor_winterton_htc(0.7, 600.0, 1e-3, 1e4, H_FG, MU_L, RHO_L, RHO_V, K_L, PR_L, 3.66)
    assert h_q > h and h_x > h


def test_chato_film_condensation_satisfies_nusselt_form():
    q, D = 1e4, 1e-3
    h = float(corr.chato_film_condensation_htc(q, D, RHO_L, RHO_V, K_L, MU_L, CP_L, H_FG))
    assert h == pytest.approx(3685.66, rel=1e-5)  # hand-computed
    # h = 0.555 [g rho_l (rho_l - rho_v) k_l^3 h'_fg / (mu_l D dT)]^(1/4) with dT = q/h and
    # h'_fg = h_fg + 0.375 cp_l dT0 (dT0 = 2.7217 K of the uncorrected solution).
    h_fg_mod = H_FG + 0.375 * CP_L * 2.72168
    chato = 0.555 * (9.80665 * RHO_L * (RHO_L - RHO_V) * K_L**3 * h_fg_mod / (MU_L * D * q / h)) ** 0.25
    assert h == pytest.approx(chato, rel=1e-5)


def test_muller_steinhagen_heck_ends_are_all_liquid_and_all_vapour():
    args = (100.0, 1e-3, 0.0, MU_L, MU_V, RHO_L, RHO_V)
    A = corr.single_phase_gradient(100.0, 1e-3, 0.0, MU_L, RHO_L)
    B = corr.single_phase_gradient(100.0, 1e-3, 0.0, MU_V, RHO_V)
    assert float(corr.muller_steinhagen_heck_gradient(0.0, *args)) == pytest.approx(float(A), rel=1e-12)
    assert float(corr.muller_steinhagen_heck_gradient(1.0, *args)) == pytest.approx(float(B), rel=1e-12)
    # Between them the gradient peaks above the all-vapour value (x about 0.8-0.9).
    x = np.linspace(0.0, 1.0, 101)
    g = corr.muller_steinhagen_heck_gradient(x, *args)
    assert g.max() > float(B) and 0.7 < x[np.argmax(g)] < 0.95


def test_crossflow_effectiveness_published_limits():
    # Both unmixed, Incropera eq. 11.32 at NTU 1, Cr 1: 1 - exp(exp(-1) - 1) = 0.468536.
    assert float(corr.crossflow_effectiveness(1.0, 1.0)) == pytest.approx(0.468536, rel=1e-6)
    ntu = np.array([0.1, 1.0, 5.0])
    np.testing.assert_allclose(corr.crossflow_effectiveness(ntu, 0.0), -np.expm1(-ntu), rtol=1e-14)
    # Never above 1, rises with NTU, falls with Cr.
    grid = corr.crossflow_effectiveness(np.linspace(0, 20, 41)[:, None], np.linspace(0, 1, 11)[None, :])
    assert (grid <= 1).all() and (np.diff(grid, axis=0) >= 0).all() and (np.diff(grid, axis=1) <= 1e-15).all()
