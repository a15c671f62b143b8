"""An air-cooled condenser's capacity ratio at a two-phase inlet, scaled by what drives it.

Behind a water-cooled condenser (the ``cabin+wcc`` chain) the front condenser
takes a partly condensed refrigerant and its air is often only a few kelvin
colder than the saturation. The cycle closes the discharge pressure on the
condenser's capacity ratio (coil length over the length that condenses to
saturated liquid, :func:`evtms.benches.condenser.condenser_heat_rate`). In the
two-phase zone the refrigerant stays at its saturation temperature, so against
an air stream of one inlet temperature each tube length rejects a heat
proportional to ``T_sat - T_air`` (the zone's effectiveness ``1 - exp(-NTU)``
with a capacity ratio of 0, Incropera et al. 2007, eq. 11.35a), and the
length needed grows with the heat to reject, ``mdot (h_in - h_l)``. The
capacity ratio therefore goes as ``(T_sat - T_air) / (h_in - h_l)``: across a
cell of the LUT's pressure axis a few kelvin above the air it changes several
times over, and linear interpolation put the chain's discharge pressure up to
6 % off the physics. The LUT cycle interpolates

    kappa = capacity_ratio * (h_in - h_l(p_in)) / (T_sat,m - T_air)    [1]

instead (``T_sat,m`` the mean of the inlet's and the outlet's saturation
temperatures, the drop's share of the driving difference; both differences
held above :data:`DT_MIN` and :data:`DH_MIN`), which depends mostly on the
flows, and multiplies the known factor back at the query (the interpolant
still passes through every node).

For a superheated inlet (every discharge of a circuit without such a chain)
the plain capacity ratio interpolates better (the desuperheating zone adds a
length that does not scale so); the two are blended linearly in the inlet's
quality between :data:`X_SCALED` and 1 (:func:`dome_capacity_ratio`), so the
response stays continuous across the saturated-vapour line.

References
----------
Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
Fundamentals of Heat and Mass Transfer, 6th ed., Wiley, section 11.4.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from evtms.fluid import SaturationCurve

#: Name of the scaled capacity ratio in the condenser's LUT tables.
SCALED = "capacity_scaled"
#: Smallest saturation-over-air difference [K] the scaling uses (the nodes' refrigerant is warmer).
DT_MIN = 0.5
#: Smallest enthalpy to condense [J/kg] the scaling uses (a liquid inlet's).
DH_MIN = 1e3
#: Inlet quality [1] at and below which the scaled table alone gives the capacity ratio.
X_SCALED = 0.8


def capacity_scale(p_in, h_in, T_air, p_out, sat: SaturationCurve) -> np.ndarray:
    """``(h_in - h_l(p_in)) / (T_sat,m - T_air)`` [J/(kg K)], each held above its floor (module notes).

    Parameters
    ----------
    p_in, h_in : numpy.ndarray
        Refrigerant inlet pressure [Pa] and enthalpy [J/kg].
    T_air : numpy.ndarray
        Air inlet temperature [K].
    p_out : numpy.ndarray
        Refrigerant outlet pressure [Pa].
    sat : SaturationCurve
        The refrigerant's saturation curve.
    """
    T_mean = 0.5 * (sat.temperature(p_in) + sat.temperature(p_out))
    dh = np.maximum(h_in - sat.liquid_enthalpy(p_in), DH_MIN)
    return dh / np.maximum(T_mean - T_air, DT_MIN)


def scaled_weight(p_in, h_in, sat: SaturationCurve) -> np.ndarray:
    """The scaled table's weight [1]: 1 at inlet qualities up to :data:`X_SCALED`, 0 from saturated vapour."""
    h_l = sat.liquid_enthalpy(p_in)
    x = (h_in - h_l) / (sat.vapour_enthalpy(p_in) - h_l)
    return np.clip((1.0 - x) / (1.0 - X_SCALED), 0.0, 1.0)


def dome_capacity_ratio(plain, scaled, p_in, h_in, T_air, p_out, sat: SaturationCurve) -> np.ndarray:
    """The capacity ratio [1] from its plain (``plain``) and scaled (``scaled``, :data:`SCALED`)
    interpolations, blended by the inlet's quality (:func:`scaled_weight`)."""
    w = scaled_weight(p_in, h_in, sat)
    from_scaled = scaled / capacity_scale(p_in, h_in, T_air, p_out, sat)
    blend = w * from_scaled + (1.0 - w) * plain
    # Where one of them is NaN (a cell touching nodes that condense nothing, which the scaled table
    # fills), the other alone: the blend is continuous wherever both are defined.
    return np.where(np.isfinite(blend), blend, np.where(w > 0.0, from_scaled, plain))
