"""Compiled scalar twins of the chevron-plate correlations (:mod:`evtms.hx.plate`), for numba kernels.

One point per call, the same arithmetic as the array functions of
:mod:`evtms.hx.plate` (Martin 1996 single phase and friction, Yan and Lin
1999 evaporation and two-phase friction; the equations and their sources are
in that module's docstrings). The compiled chiller
(:mod:`evtms.benches._chiller_kernel`) calls them; ``tests/test_hx.py`` holds
each to its array twin to round-off. ``np.maximum``'s NaN is kept
(:func:`evtms.hx._kernels.nan_max`), so a point NumPy leaves NaN stays NaN.
"""

from __future__ import annotations

import math

from evtms._jit import jit
from evtms.hx._kernels import nan_max
from evtms.hx.plate import MARTIN_ANGLE_RANGE, MARTIN_RE_RANGE, YAN_LIN_RE_EQ_RANGE

_RE_LO, _RE_HI = MARTIN_RE_RANGE
_ANGLE_LO, _ANGLE_HI = MARTIN_ANGLE_RANGE
_RE_EQ_LO, _RE_EQ_HI = YAN_LIN_RE_EQ_RANGE


@jit(counted=False)
def martin_friction_factor(Re: float, chevron_angle: float) -> float:
    """One point of :func:`evtms.hx.plate.martin_friction_factor`: Darcy factor [1] at ``Re`` [1], angle [deg]."""
    Re = nan_max(Re, 1e-12)
    phi = math.radians(chevron_angle)
    if Re < 2000.0:
        xi0 = 64.0 / Re
        xi1 = 597.0 / Re + 3.85
    else:
        xi0 = (1.8 * math.log10(Re) - 1.5) ** -2
        xi1 = 39.0 * Re**-0.289
    c = math.cos(phi)
    inv = c / math.sqrt(0.18 * math.tan(phi) + 0.36 * math.sin(phi) + xi0 / c) + (1.0 - c) / math.sqrt(3.8 * xi1)
    return inv**-2


@jit(counted=False)
def martin_nusselt(Re: float, Pr: float, chevron_angle: float) -> float:
    """One point of :func:`evtms.hx.plate.martin_nusselt` (viscosity ratio 1): Nusselt number [1]."""
    xi = martin_friction_factor(Re, chevron_angle)
    drive = xi * Re * Re * math.sin(2.0 * math.radians(chevron_angle))
    return 0.122 * Pr ** (1.0 / 3.0) * drive**0.374


@jit(counted=False)
def martin_outside_range(Re: float, chevron_angle: float) -> bool:
    """One point of :func:`evtms.hx.plate.martin_outside_range` (NaN counts as inside, as NumPy's compares)."""
    angle_out = not (_ANGLE_LO <= chevron_angle <= _ANGLE_HI)
    return Re < _RE_LO or Re > _RE_HI or angle_out


@jit(counted=False)
def equivalent_mass_flux(G: float, x: float, rho_l: float, rho_v: float) -> float:
    """One point of :func:`evtms.hx.plate.equivalent_mass_flux` [kg/(m2 s)] (Akers et al. 1959)."""
    return G * (1.0 - x + x * math.sqrt(rho_l / rho_v))


@jit(counted=False)
def yan_lin_boiling_htc(
    x: float,
    G: float,
    D_h: float,
    q: float,
    h_lv: float,
    mu_l: float,
    rho_l: float,
    rho_v: float,
    k_l: float,
    Pr_l: float,
) -> float:
    """One point of :func:`evtms.hx.plate.yan_lin_boiling_htc`: evaporation coefficient [W/(m2 K)]."""
    G_eq = equivalent_mass_flux(G, x, rho_l, rho_v)
    Re_eq = G_eq * D_h / mu_l
    Re = G * D_h / mu_l
    Bo_eq = q / (G_eq * h_lv)
    return 1.926 * (k_l / D_h) * Re_eq * Pr_l ** (1.0 / 3.0) * Bo_eq**0.3 * Re**-0.5


@jit(counted=False)
def yan_lin_friction_factor(Re_eq: float, Re: float) -> float:
    """One point of :func:`evtms.hx.plate.yan_lin_friction_factor`: two-phase friction factor [1]."""
    Re_eq = nan_max(Re_eq, 1e-12)
    Re = nan_max(Re, 1e-12)
    below = nan_max(_RE_EQ_LO / Re_eq, 1.0)  # the laminar continuation below the data
    if Re_eq < 6000.0:
        f = 6.947e5 * (Re_eq * below) ** -1.109 * below * (Re * below) ** -0.5
    else:
        f = 31.21 * nan_max(Re_eq, 6000.0) ** 0.04557 * Re**-0.5
    return f


@jit(counted=False)
def yan_lin_outside_range(Re_eq: float) -> bool:
    """One point of :func:`evtms.hx.plate.yan_lin_outside_range`."""
    return Re_eq < _RE_EQ_LO or Re_eq > _RE_EQ_HI
