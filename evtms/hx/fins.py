"""Air side of louvred-fin coils: the Chang and Wang (1997) Colburn factor, with its validity range."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

#: Louver-pitch Reynolds numbers of the data behind :func:`chang_wang_j` (Chang and Wang 1997).
CHANG_WANG_RE_RANGE = (100.0, 3000.0)


@dataclass(frozen=True)
class LouveredFin:
    """Geometry of a flat-tube louvred-fin core, as Chang and Wang (1997) define it.

    Attributes
    ----------
    louver_angle : float
        Louver angle [rad].
    louver_pitch : float
        Louver pitch ``L_p`` [m].
    louver_length : float
        Louver length ``L_l`` [m].
    fin_pitch : float
        Fin pitch ``F_p`` [m].
    fin_length : float
        Fin length ``F_l``, tube pitch minus tube thickness [m].
    flow_depth : float
        Flow (fin) depth ``T_d`` [m].
    tube_pitch : float
        Tube pitch ``T_p`` [m].
    fin_thickness : float
        Fin thickness ``delta_f`` [m].
    """

    louver_angle: float
    louver_pitch: float
    louver_length: float
    fin_pitch: float
    fin_length: float
    flow_depth: float
    tube_pitch: float
    fin_thickness: float

    def geometry_factor(self) -> float:
        """The geometric part of :func:`chang_wang_j`, ``j Re_Lp^0.49`` [1] (kept per geometry:
        a cycle solver's one-point coil calls each asked for it again)."""
        return _geometry_factor(self)

    def _geometry_factor(self) -> float:
        Lp = self.louver_pitch
        return (
            (np.degrees(self.louver_angle) / 90.0) ** 0.27
            * (self.fin_pitch / Lp) ** -0.14
            * (self.fin_length / Lp) ** -0.29
            * (self.flow_depth / Lp) ** -0.23
            * (self.louver_length / Lp) ** 0.68
            * (self.tube_pitch / Lp) ** -0.28
            * (self.fin_thickness / Lp) ** -0.05
        )


@functools.lru_cache(maxsize=64)
def _geometry_factor(fin: LouveredFin) -> float:
    return fin._geometry_factor()


def chang_wang_j(Re_Lp: np.ndarray, fin: LouveredFin) -> np.ndarray:
    r"""Colburn factor [1] of a louvred fin on flat tubes, Chang and Wang (1997), eq. (9).

    .. math:: j = Re_{Lp}^{-0.49} \left(\frac{\theta}{90}\right)^{0.27}
              \left(\frac{F_p}{L_p}\right)^{-0.14} \left(\frac{F_l}{L_p}\right)^{-0.29}
              \left(\frac{T_d}{L_p}\right)^{-0.23} \left(\frac{L_l}{L_p}\right)^{0.68}
              \left(\frac{T_p}{L_p}\right)^{-0.28} \left(\frac{\delta_f}{L_p}\right)^{-0.05}

    with ``theta`` in degrees, ``Re_Lp = rho V_c L_p / mu`` on the louver
    pitch and the velocity ``V_c`` in the minimum free-flow area, and
    ``j = h Pr^(2/3) / (rho V_c c_p)``. Fitted to 91 dry louvred-fin samples
    (89.3 % of the corrugated-fin data within 15 %) for
    ``100 < Re_Lp < 3000`` (:data:`CHANG_WANG_RE_RANGE`); evaluated as
    published outside it, where :func:`chang_wang_outside_range` flags it.

    Parameters
    ----------
    Re_Lp : array_like
        Louver-pitch Reynolds number [1], > 0.
    fin : LouveredFin
        Fin geometry.

    References
    ----------
    Chang, Y.-J., Wang, C.-C. (1997). A generalized heat transfer correlation
    for louver fin geometry. Int. J. Heat Mass Transfer 40(3), 533-544.
    """
    return np.asarray(Re_Lp, float) ** -0.49 * fin.geometry_factor()


def chang_wang_outside_range(Re_Lp: np.ndarray) -> np.ndarray:
    """Whether ``Re_Lp`` [1] lies outside the range of :func:`chang_wang_j` (bounds inside)."""
    lo, hi = CHANG_WANG_RE_RANGE
    Re_Lp = np.asarray(Re_Lp, float)
    return (Re_Lp < lo) | (Re_Lp > hi)


def louvered_fin_htc(
    velocity: np.ndarray, rho: np.ndarray, mu: np.ndarray, k: np.ndarray, Pr: np.ndarray, fin: LouveredFin
) -> tuple[np.ndarray, np.ndarray]:
    r"""Air-side heat-transfer coefficient [W/(m2 K)] of a dry louvred fin, and its ``Re_Lp`` [1].

    From the Colburn factor of :func:`chang_wang_j`,

    .. math:: h = j\,\rho V_c c_p Pr^{-2/3}
              = j\,Re_{Lp}\,\frac{\mu c_p}{L_p} Pr^{-2/3},\quad c_p = Pr\,k/\mu,

    written in the second form so that ``h`` is 0, not NaN, at zero flow
    (``j Re_Lp`` goes with ``Re_Lp^0.51``). The same coefficient serves a wet
    evaporator surface (the enthalpy-potential method scales it by
    ``c_p``); Chang and Wang's data are for dry fins.

    Parameters
    ----------
    velocity : array_like
        Air velocity in the minimum free-flow area ``V_c`` [m/s], >= 0.
    rho : array_like
        Air density [kg/m3].
    mu : array_like
        Air viscosity [Pa s].
    k : array_like
        Air conductivity [W/(m K)].
    Pr : array_like
        Air Prandtl number [1].
    fin : LouveredFin
        Fin geometry.

    Returns
    -------
    tuple of numpy.ndarray
        ``h`` [W/(m2 K)] and ``Re_Lp`` [1].

    References
    ----------
    Chang, Y.-J., Wang, C.-C. (1997). A generalized heat transfer correlation
    for louver fin geometry. Int. J. Heat Mass Transfer 40(3), 533-544.
    """
    Re_Lp = rho * np.asarray(velocity, float) * fin.louver_pitch / mu
    cp = Pr * k / mu
    h = fin.geometry_factor() * Re_Lp**0.51 * mu * cp / fin.louver_pitch * Pr ** (-2.0 / 3.0)
    return h, Re_Lp
