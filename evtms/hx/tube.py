"""Refrigerant-side correlations of flat multiport tubes: friction, single phase, condensation, boiling.

Element-wise over NumPy arrays, each with its reference. The air-to-refrigerant
coils (:mod:`evtms.benches.coil`) use them through the cross-flow core
(:mod:`evtms.hx.crossflow`).
"""

from __future__ import annotations

import numpy as np

#: Reynolds numbers bounding the laminar-turbulent blend of single-phase flow.
RE_LAMINAR = 2300.0
RE_TURBULENT = 4000.0

#: Gauss-Legendre nodes and weights on [0, 1], for averages over quality.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
GAUSS_NODES = 0.5 * (_GL_X + 1.0)
GAUSS_WEIGHTS = 0.5 * _GL_W


def _turbulent_weight(Re: np.ndarray) -> np.ndarray:
    """0 below RE_LAMINAR, 1 above RE_TURBULENT, linear in between."""
    return np.clip((Re - RE_LAMINAR) / (RE_TURBULENT - RE_LAMINAR), 0.0, 1.0)


def haaland_friction_factor(Re: np.ndarray, relative_roughness: float | np.ndarray) -> np.ndarray:
    """Darcy friction factor [1] for laminar, transitional and turbulent pipe flow.

    Laminar ``f = 64 / Re`` below Re = 2300; Haaland's explicit turbulent
    formula above Re = 4000,

    .. math:: 1/\\sqrt{f} = -1.8 \\log_{10}[(\\epsilon/D/3.7)^{1.11} + 6.9/Re];

    linear blend in between (as Simscape's pipe blocks do). Validity: within
    about 1.5 % of the Colebrook equation for 4000 <= Re <= 1e8 (Haaland
    1983); the laminar branch is exact for fully developed flow.

    Parameters
    ----------
    Re : array_like
        Reynolds number [1].
    relative_roughness : float or array_like
        Roughness over hydraulic diameter [1].

    References
    ----------
    Haaland, S. E. (1983). Simple and explicit formulas for the friction factor
    in turbulent pipe flow. J. Fluids Eng. 105(1), 89-90.
    """
    Re = np.maximum(np.asarray(Re, float), 1e-12)
    laminar = 64.0 / Re
    Re_t = np.maximum(Re, RE_TURBULENT)
    turbulent = (-1.8 * np.log10((relative_roughness / 3.7) ** 1.11 + 6.9 / Re_t)) ** -2
    w = _turbulent_weight(Re)
    return (1.0 - w) * laminar + w * turbulent


def single_phase_nusselt(Re: np.ndarray, Pr: np.ndarray, friction_factor: np.ndarray, nu_laminar: float) -> np.ndarray:
    """Nusselt number [1] of single-phase flow in a channel.

    Constant ``nu_laminar`` (fully developed laminar flow) below Re = 2300;
    Gnielinski above Re = 4000,

    .. math:: Nu = \\frac{(f/8)(Re - 1000) Pr}{1 + 12.7\\sqrt{f/8}(Pr^{2/3} - 1)};

    linear blend in between, from ``nu_laminar`` to Gnielinski's value at
    Re = 4000 (the transition interpolation Gnielinski 2013 recommends; its
    ends are corners of the Nusselt number against the flow). Validity of
    Gnielinski's equation: 3000 <= Re <= 5e6 and 0.5 <= Pr <= 2000
    (Incropera et al. 2007, eq. 8.62).

    Parameters
    ----------
    Re, Pr : array_like
        Reynolds and Prandtl numbers [1].
    friction_factor : array_like
        Darcy friction factor [1] (from :func:`haaland_friction_factor`).
    nu_laminar : float
        Laminar Nusselt number [1], 3.66 for a round tube at constant wall
        temperature.

    References
    ----------
    Gnielinski, V. (1976). New equations for heat and mass transfer in
    turbulent pipe and channel flow. Int. Chem. Eng. 16(2), 359-368.
    Gnielinski, V. (2013). On heat transfer in tubes. Int. J. Heat Mass
    Transfer 63, 134-140.
    """
    Re = np.asarray(Re, float)
    Re_t = np.maximum(Re, RE_TURBULENT)
    f8 = np.asarray(friction_factor, float) / 8.0
    turbulent = f8 * (Re_t - 1000.0) * Pr / (1.0 + 12.7 * np.sqrt(f8) * (Pr ** (2.0 / 3.0) - 1.0))
    turbulent = np.maximum(turbulent, nu_laminar)
    w = _turbulent_weight(Re)
    return (1.0 - w) * nu_laminar + w * turbulent


def hausen_nusselt(Re: np.ndarray, Pr: np.ndarray, D_h: float, length: float, nu_developed: float) -> np.ndarray:
    """Mean Nusselt number [1] of laminar flow with a developing temperature profile (Hausen).

    .. math:: \\overline{Nu} = Nu_{fd} + \\frac{0.0668\\,Gz}{1 + 0.04\\,Gz^{2/3}},
              \\quad Gz = \\frac{D_h}{L} Re\\,Pr,

    Hausen's thermal-entry form at constant wall temperature (Incropera et al.
    2007, eq. 8.57) with its fully developed limit ``Nu_fd`` taken for the
    channel's own shape (3.66 for a round tube; :func:`shah_london_nu_t` for a
    rectangular duct). Valid for laminar flow (Re < 2300); it tends to
    ``Nu_fd`` in a long channel.

    Parameters
    ----------
    Re, Pr : array_like
        Reynolds and Prandtl numbers [1].
    D_h : float
        Hydraulic diameter [m].
    length : float
        Heated length [m].
    nu_developed : float
        Fully developed laminar Nusselt number [1].

    References
    ----------
    Hausen, H. (1943). Darstellung des Waermeueberganges in Rohren durch
    verallgemeinerte Potenzbeziehungen. Z. VDI Beih. Verfahrenstech. 4, 91-98.
    Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
    Fundamentals of Heat and Mass Transfer, 6th ed., Wiley, eq. 8.57.
    """
    Gz = D_h / length * np.maximum(np.asarray(Re, float), 0.0) * np.asarray(Pr, float)
    return nu_developed + 0.0668 * Gz / (1.0 + 0.04 * Gz ** (2.0 / 3.0))


def shah_london_nu_t(aspect_ratio: float) -> float:
    """Fully developed laminar Nusselt number [1] of a rectangular duct at constant wall temperature.

    .. math:: Nu_T = 7.541 (1 - 2.610\\alpha + 4.970\\alpha^2 - 5.119\\alpha^3
              + 2.702\\alpha^4 - 0.548\\alpha^5),

    with ``alpha`` the short over the long side (0 < alpha <= 1): 2.98 for a
    square duct, 7.54 between parallel plates, 6.08 for the 1:11.4 radiator
    tube. Shah and London give it within 0.1 % of their tabulated solutions.

    References
    ----------
    Shah, R. K., London, A. L. (1978). Laminar Flow Forced Convection in Ducts.
    Academic Press, eq. (341), ch. VII.
    """
    a = min(aspect_ratio, 1.0 / aspect_ratio)
    return 7.541 * (1.0 - 2.610 * a + 4.970 * a**2 - 5.119 * a**3 + 2.702 * a**4 - 0.548 * a**5)


def cavallini_zecchin_nusselt(
    x: np.ndarray,
    G: np.ndarray,
    D: float,
    mu_l: np.ndarray,
    mu_v: np.ndarray,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
    Pr_l: np.ndarray,
    nu_laminar: float,
) -> np.ndarray:
    """Local Nusselt number [1] of in-tube condensation, based on the liquid conductivity.

    .. math:: Nu = 0.05\\,Re_{eq}^{0.8} Pr_l^{0.33},\\quad
              Re_{eq} = Re_v (\\mu_v/\\mu_l)(\\rho_l/\\rho_v)^{0.5} + Re_l

    with ``Re_v = G x D / mu_v`` and ``Re_l = G (1 - x) D / mu_l``. At the low
    mass fluxes of a parallel-tube automotive coil Re_eq can fall into the
    laminar range, where the correlation would predict less than conduction
    through a laminar film; there the laminar Nusselt number is the floor
    (as Simscape's two-phase heat exchangers do).

    References
    ----------
    Cavallini, A., Zecchin, R. (1974). A dimensionless correlation for heat
    transfer in forced convection condensation. Proc. 5th Int. Heat Transfer
    Conf., Tokyo, vol. 3, 309-313.
    """
    Re_v = G * x * D / mu_v
    Re_l = G * (1.0 - x) * D / mu_l
    Re_eq = Re_v * (mu_v / mu_l) * np.sqrt(rho_l / rho_v) + Re_l
    return np.maximum(0.05 * Re_eq**0.8 * Pr_l**0.33, nu_laminar)


def chato_film_condensation_htc(
    q: np.ndarray,
    D: float,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
    k_l: np.ndarray,
    mu_l: np.ndarray,
    cp_l: np.ndarray,
    h_fg: np.ndarray,
    g: float = 9.80665,
) -> np.ndarray:
    r"""Gravity-driven film condensation coefficient [W/(m2 K)] in a horizontal tube.

    Chato's stratified-flow form of Nusselt's film theory,

    .. math:: h = 0.555 \left[\frac{g \rho_l (\rho_l - \rho_v) k_l^3 h'_{fg}}
              {\mu_l D \Delta T}\right]^{1/4},\quad
              h'_{fg} = h_{fg} + 0.375\,c_{p,l} \Delta T,

    written in terms of the wall heat flux ``q = h dT`` (eliminating the
    wall superheat ``dT``): ``h = (0.555^4 B / q)^{1/3}`` with ``B`` the
    bracket times ``dT``. The latent-heat correction is applied with ``dT``
    from the uncorrected solution. At the low mass fluxes of parallel-tube
    automotive coils condensation is stratified and this film term, not the
    shear-driven Cavallini-Zecchin term, sets the coefficient.

    Parameters
    ----------
    q : array_like
        Wall heat flux [W/m2], > 0.

    References
    ----------
    Chato, J. C. (1962). Laminar condensation inside horizontal and inclined
    tubes. ASHRAE J. 4, 52-60.
    Dobson, M. K., Chato, J. C. (1998). Condensation in smooth horizontal
    tubes. J. Heat Transfer 120(1), 193-213.
    """
    q = np.maximum(np.asarray(q, float), 1e-6)
    base = g * rho_l * (rho_l - rho_v) * k_l**3 / (mu_l * D)
    h = (0.555**4 * base * h_fg / q) ** (1.0 / 3.0)
    dT = q / h
    return (0.555**4 * base * (h_fg + 0.375 * cp_l * dT) / q) ** (1.0 / 3.0)


def gungor_winterton_htc(
    x: np.ndarray,
    G: np.ndarray,
    D: float,
    q: np.ndarray,
    h_fg: np.ndarray,
    mu_l: np.ndarray,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
    k_l: np.ndarray,
    Pr_l: np.ndarray,
    nu_laminar: float,
) -> np.ndarray:
    """Local flow-boiling heat-transfer coefficient [W/(m2 K)], simplified Gungor-Winterton.

    .. math:: h = E\\,h_l,\\quad E = 1 + 3000 Bo^{0.86}
              + 1.12 \\left(\\frac{x}{1-x}\\right)^{0.75}
              \\left(\\frac{\\rho_l}{\\rho_v}\\right)^{0.41}

    with boiling number ``Bo = q / (G h_fg)`` and the liquid-only
    Dittus-Boelter coefficient ``h_l = 0.023 Re_l^0.8 Pr_l^0.4 k_l / D``,
    ``Re_l = G (1 - x) D / mu_l``; ``h_l`` is floored at the laminar value
    ``nu_laminar k_l / D`` for the laminar liquid films of low mass flux.
    Gungor and Winterton fitted it to saturated boiling data of water,
    refrigerants and ethylene glycol in tubes and annuli of about 3 to 32 mm;
    the flat tubes' channels (about 1.5 mm) lie below that.

    Parameters
    ----------
    q : array_like
        Heat flux at the wall [W/m2].
    h_fg : array_like
        Latent heat [J/kg].

    References
    ----------
    Gungor, K. E., Winterton, R. H. S. (1987). Simplified general correlation
    for saturated flow boiling and comparisons of correlations with data.
    Chem. Eng. Res. Des. 65, 148-156.
    """
    x = np.clip(x, 0.0, 0.999)
    Re_l = G * (1.0 - x) * D / mu_l
    h_l = np.maximum(0.023 * Re_l**0.8 * Pr_l**0.4, nu_laminar) * k_l / D
    Bo = np.maximum(q, 0.0) / (G * h_fg)
    E = 1.0 + 3000.0 * Bo**0.86 + 1.12 * (x / (1.0 - x)) ** 0.75 * (rho_l / rho_v) ** 0.41
    return E * h_l


def muller_steinhagen_heck_gradient(
    x: np.ndarray,
    G: np.ndarray,
    D: float,
    relative_roughness: float,
    mu_l: np.ndarray,
    mu_v: np.ndarray,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
) -> np.ndarray:
    """Two-phase frictional pressure gradient [Pa/m], Mueller-Steinhagen and Heck.

    .. math:: \\frac{dp}{dz} = \\Lambda (1 - x)^{1/3} + B x^3,\\quad
              \\Lambda = A + 2 (B - A) x

    where ``A`` and ``B`` are the gradients of the whole flow as liquid and as
    vapour (Darcy factors from :func:`haaland_friction_factor`).

    References
    ----------
    Mueller-Steinhagen, H., Heck, K. (1986). A simple friction pressure drop
    correlation for two-phase flow in pipes. Chem. Eng. Process. 20, 297-308.
    """
    A = single_phase_gradient(G, D, relative_roughness, mu_l, rho_l)
    B = single_phase_gradient(G, D, relative_roughness, mu_v, rho_v)
    lam = A + 2.0 * (B - A) * x
    return lam * (1.0 - x) ** (1.0 / 3.0) + B * x**3


def single_phase_gradient(
    G: np.ndarray, D: float, relative_roughness: float, mu: np.ndarray, rho: np.ndarray
) -> np.ndarray:
    """Darcy-Weisbach frictional pressure gradient [Pa/m] of single-phase flow.

    .. math:: dp/dz = f(Re)\\, G^2 / (2 \\rho D),\\quad Re = G D / \\mu
    """
    Re = G * D / mu
    return haaland_friction_factor(Re, relative_roughness) * G**2 / (2.0 * rho * D)
