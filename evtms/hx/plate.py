"""Chevron-plate channel correlations: single phase (Martin 1996), evaporation (Yan and Lin 1999), condensation
(Yan, Lio and Lin 1999).

Element-wise over NumPy arrays. Each correlation states the range of the
data it was fitted to or checked against; ``*_outside_range`` return the
points outside, which the benches flag (valid, status
``valid_correlation_outside_range``) and evaluate as published.

References
----------
Martin, H. (1996). A theoretical approach to predict the performance of
chevron-type plate heat exchangers. Chem. Eng. Process. 35(4), 301-310.
Yan, Y.-Y., Lin, T.-F. (1999). Evaporation heat transfer and pressure drop of
refrigerant R-134a in a plate heat exchanger. J. Heat Transfer 121(1), 118-127.
Yan, Y.-Y., Lio, H.-C., Lin, T.-F. (1999). Condensation heat transfer and
pressure drop of refrigerant R-134a in a plate heat exchanger. Int. J. Heat
Mass Transfer 42(6), 993-1006.
Shah, R. K., Focke, W. W. (1988). Plate heat exchangers and their design
theory. In: Heat Transfer Equipment Design, Hemisphere, 227-254.
"""

from __future__ import annotations

import numpy as np

#: Reynolds numbers of the data Martin (1996) compared his equations with [1].
MARTIN_RE_RANGE = (200.0, 1.0e4)
#: Chevron angles (to the main flow) of Martin's comparison [deg].
MARTIN_ANGLE_RANGE = (10.0, 80.0)
#: Yan and Lin's (1999) stated range of the equivalent Reynolds number [1].
YAN_LIN_RE_EQ_RANGE = (2000.0, 1.0e4)
#: Mass fluxes of Yan, Lio and Lin's (1999) condensation data [kg/(m2 s)] (as their abstract states them).
YAN_LIO_LIN_G_RANGE = (60.0, 120.0)
#: Pressure loss of one port, in velocity heads of the port flow (Shah and Focke 1988) [1].
PORT_VELOCITY_HEADS = 1.4


def martin_friction_factor(Re: np.ndarray, chevron_angle: float) -> np.ndarray:
    r"""Darcy friction factor [1] of a chevron-plate channel (Martin 1996).

    .. math::
        \frac{1}{\sqrt{\xi}} = \frac{\cos\varphi}{\sqrt{0.18\tan\varphi + 0.36\sin\varphi + \xi_0/\cos\varphi}}
        + \frac{1 - \cos\varphi}{\sqrt{3.8\,\xi_1}}

    with the straight-channel factors ``xi_0 = 64/Re`` and ``xi_1 = 597/Re +
    3.85`` below Re = 2000, ``xi_0 = (1.8 log10 Re - 1.5)^-2`` and ``xi_1 =
    39 Re^-0.289`` above (Martin's eqs. 18-21). The published form jumps at
    Re = 2000 (by about 6 % at 60 deg); it is kept as published.

    Parameters
    ----------
    Re : array_like
        Channel Reynolds number ``G d_h / mu`` [1], > 0.
    chevron_angle : float
        Angle of the corrugations to the main flow direction, ``phi`` [deg].

    Returns
    -------
    numpy.ndarray
        Darcy friction factor ``xi`` [1] (``dp = xi L / d_h G^2 / (2 rho)``).
    """
    Re = np.maximum(np.asarray(Re, float), 1e-12)
    phi = np.radians(chevron_angle)
    laminar = Re < 2000.0
    Re_t = np.maximum(Re, 2000.0)
    xi0 = np.where(laminar, 64.0 / Re, (1.8 * np.log10(Re_t) - 1.5) ** -2)
    xi1 = np.where(laminar, 597.0 / Re + 3.85, 39.0 * Re_t**-0.289)
    c = np.cos(phi)
    inv = c / np.sqrt(0.18 * np.tan(phi) + 0.36 * np.sin(phi) + xi0 / c) + (1.0 - c) / np.sqrt(3.8 * xi1)
    return inv**-2


def martin_nusselt(
    Re: np.ndarray, Pr: np.ndarray, chevron_angle: float, viscosity_ratio: np.ndarray | float = 1.0
) -> np.ndarray:
    r"""Nusselt number [1] of single-phase flow in a chevron-plate channel (Martin 1996).

    The generalised Leveque equation (Martin's eq. 24 with the constant of
    his eq. 25),

    .. math:: Nu = 0.122\,Pr^{1/3} (\mu/\mu_w)^{1/6} \left[\xi\,Re^2 \sin 2\varphi\right]^{0.374},

    with the friction factor of :func:`martin_friction_factor`, based on the
    hydraulic diameter ``d_h = 4 a / Phi``. Martin compared it with data of
    Re 200 to 10,000 and chevron angles 10 to 80 deg
    (:data:`MARTIN_RE_RANGE`, :data:`MARTIN_ANGLE_RANGE`).

    Parameters
    ----------
    Re, Pr : array_like
        Channel Reynolds and Prandtl numbers [1].
    chevron_angle : float
        Corrugation angle to the main flow ``phi`` [deg].
    viscosity_ratio : array_like or float
        Bulk over wall viscosity [1]; 1 where the wall state is not resolved.

    Returns
    -------
    numpy.ndarray
        Nusselt number ``h d_h / k`` [1].
    """
    xi = martin_friction_factor(Re, chevron_angle)
    Re = np.asarray(Re, float)
    drive = xi * Re * Re * np.sin(2.0 * np.radians(chevron_angle))
    return (
        0.122 * np.asarray(Pr, float) ** (1.0 / 3.0) * np.asarray(viscosity_ratio, float) ** (1.0 / 6.0) * drive**0.374
    )


def martin_outside_range(Re: np.ndarray, chevron_angle: float) -> np.ndarray:
    """Points whose Reynolds number or chevron angle lie outside Martin's comparison data."""
    Re = np.asarray(Re, float)
    angle_out = not (MARTIN_ANGLE_RANGE[0] <= chevron_angle <= MARTIN_ANGLE_RANGE[1])
    return (Re < MARTIN_RE_RANGE[0]) | (Re > MARTIN_RE_RANGE[1]) | angle_out


def equivalent_mass_flux(G: np.ndarray, x: np.ndarray, rho_l: np.ndarray, rho_v: np.ndarray) -> np.ndarray:
    """Equivalent all-liquid mass flux ``G_eq = G [1 - x + x (rho_l/rho_v)^0.5]`` [kg/(m2 s)] (Akers et al. 1959)."""
    return G * (1.0 - x + x * np.sqrt(rho_l / rho_v))


def yan_lin_boiling_htc(
    x: np.ndarray,
    G: np.ndarray,
    D_h: float,
    q: np.ndarray,
    h_lv: np.ndarray,
    mu_l: np.ndarray,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
    k_l: np.ndarray,
    Pr_l: np.ndarray,
) -> np.ndarray:
    r"""Evaporation heat-transfer coefficient [W/(m2 K)] of R134a in a chevron-plate channel (Yan and Lin 1999).

    .. math:: h = 1.926\,\frac{k_l}{D_h}\,Re_{eq}\,Pr_l^{1/3}\,Bo_{eq}^{0.3}\,Re^{-0.5},

    with ``Re_eq = G_eq D_h / mu_l``, ``Bo_eq = q / (G_eq h_lv)``, ``Re = G
    D_h / mu_l`` and ``G_eq`` of :func:`equivalent_mass_flux`. Fitted to
    their R134a data in a 60 deg plate (mass flux 55 and 70 kg/(m2 s), heat
    flux 11-15 kW/m2, mean quality 0.1-0.8, 675-800 kPa), stated for
    ``2000 < Re_eq < 10000`` (:data:`YAN_LIN_RE_EQ_RANGE`).

    Parameters
    ----------
    x : array_like
        Vapour quality [1].
    G : array_like
        Mass flux of one channel [kg/(m2 s)].
    D_h : float
        Hydraulic diameter [m].
    q : array_like
        Wall heat flux [W/m2], > 0.
    h_lv : array_like
        Latent heat [J/kg].
    mu_l, rho_l, rho_v, k_l, Pr_l : array_like
        Saturated liquid viscosity [Pa s], liquid and vapour densities
        [kg/m3], liquid conductivity [W/(m K)], liquid Prandtl number [1].

    Returns
    -------
    numpy.ndarray
        Heat-transfer coefficient [W/(m2 K)].
    """
    G_eq = equivalent_mass_flux(G, x, rho_l, rho_v)
    Re_eq = G_eq * D_h / mu_l
    Re = G * D_h / mu_l
    Bo_eq = q / (G_eq * h_lv)
    return 1.926 * (k_l / D_h) * Re_eq * Pr_l ** (1.0 / 3.0) * Bo_eq**0.3 * Re**-0.5


def yan_lin_friction_factor(Re_eq: np.ndarray, Re: np.ndarray) -> np.ndarray:
    r"""Two-phase Fanning-type friction factor [1] of evaporating R134a in a plate channel (Yan and Lin 1999).

    .. math::
        f_{tp} = 6.947\times10^5\,Re_{eq}^{-1.109}\,Re^{-0.5}\ (Re_{eq} < 6000),\qquad
        f_{tp} = 31.21\,Re_{eq}^{0.04557}\,Re^{-0.5}\ (Re_{eq} \ge 6000),

    for the frictional drop ``dp = 2 f_tp G^2 L / (rho_m D_h)`` with the
    homogeneous density ``1/rho_m = x/rho_v + (1 - x)/rho_l``.

    Below their data (``Re_eq`` under 2000, :data:`YAN_LIN_RE_EQ_RANGE`) the
    factor is the correlation's at ``Re_eq = 2000`` and the same quality
    (``Re`` scaled with ``Re_eq``), continued as laminar friction, ``f_tp ~
    1/Re_eq`` (A). Their low-``Re_eq`` branch falls as ``G^-1.61``, so
    continued it would hold the drop near ``G^0.39``: a heat pump's chiller at
    4 kg/(m2 s) and 0.1 MPa would lose some 35 kPa (7 K of saturation
    temperature), about what it loses at ten times the flow. The laminar
    continuation takes the drop to zero with the flow, as friction does, and
    meets the correlation at the end of its range.
    """
    Re_eq = np.maximum(np.asarray(Re_eq, float), 1e-12)
    Re = np.maximum(np.asarray(Re, float), 1e-12)
    below = np.maximum(YAN_LIN_RE_EQ_RANGE[0] / Re_eq, 1.0)  # 1 inside the range
    low = 6.947e5 * (Re_eq * below) ** -1.109 * below  # at the range's end, times the laminar 1/Re_eq
    high = 31.21 * np.maximum(Re_eq, 6000.0) ** 0.04557
    return np.where(Re_eq < 6000.0, low * (Re * below) ** -0.5, high * Re**-0.5)


def yan_lin_outside_range(Re_eq: np.ndarray) -> np.ndarray:
    """Points whose equivalent Reynolds number lies outside Yan and Lin's stated range."""
    Re_eq = np.asarray(Re_eq, float)
    return (Re_eq < YAN_LIN_RE_EQ_RANGE[0]) | (Re_eq > YAN_LIN_RE_EQ_RANGE[1])


def yan_lio_lin_condensation_htc(
    x: np.ndarray,
    G: np.ndarray,
    D_h: float,
    mu_l: np.ndarray,
    rho_l: np.ndarray,
    rho_v: np.ndarray,
    k_l: np.ndarray,
    Pr_l: np.ndarray,
) -> np.ndarray:
    r"""Condensation heat-transfer coefficient [W/(m2 K)] of R134a in a chevron-plate channel (Yan, Lio, Lin 1999).

    .. math:: Nu = \frac{h D_h}{k_l} = 4.118\,Re_{eq}^{0.4}\,Pr_l^{1/3},

    with ``Re_eq = G_eq D_h / mu_l`` and ``G_eq`` of :func:`equivalent_mass_flux`
    (local in the quality ``x``). Fitted to their R134a data in a 60 deg
    plate; points whose mass flux lies outside their data
    (:data:`YAN_LIO_LIN_G_RANGE`) are flagged by :func:`yan_lio_lin_outside_range`.

    Parameters
    ----------
    x : array_like
        Vapour quality [1].
    G : array_like
        Mass flux of one channel [kg/(m2 s)].
    D_h : float
        Hydraulic diameter [m].
    mu_l, rho_l, rho_v, k_l, Pr_l : array_like
        Saturated liquid viscosity [Pa s], liquid and vapour densities
        [kg/m3], liquid conductivity [W/(m K)], liquid Prandtl number [1].

    Returns
    -------
    numpy.ndarray
        Heat-transfer coefficient [W/(m2 K)].
    """
    Re_eq = equivalent_mass_flux(G, x, rho_l, rho_v) * D_h / mu_l
    return 4.118 * Re_eq**0.4 * np.asarray(Pr_l, float) ** (1.0 / 3.0) * k_l / D_h


def yan_lio_lin_outside_range(G: np.ndarray) -> np.ndarray:
    """Points whose channel mass flux [kg/(m2 s)] lies outside Yan, Lio and Lin's condensation data."""
    G = np.asarray(G, float)
    return (G < YAN_LIO_LIN_G_RANGE[0]) | (G > YAN_LIO_LIN_G_RANGE[1])
